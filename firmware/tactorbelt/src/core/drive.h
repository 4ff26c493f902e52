// Drive shaping (firmware 1.3): the signed ERM drive of src/tactorbelt/devices/erm.py
// (Shaper, shape_tick, drive_relax) in float32, one tactor at a time, and how a signed
// drive sits on the two inputs of a DRV8833 bridge. docs/protocol.md, "SET_DRIVE".
//
// Units: a drive is a fraction of the full PWM duty (1 = level 65535 = the motor supply).
// `rated` is the level of the motor's rated voltage (the host sends it: 1 when the supply
// is the rated voltage, 1/k when it gives k times as much); a shaped belt never holds a
// level above it, and drives above it only as a kick, bounded by the full duty. The
// motor's predicted speed w is in the same units (w = d is the steady speed of drive d).
//
// The bridge (DRV8833, both inputs wired): forward d = IN1 at duty d with IN2 low (drive
// and coast, as with IN2 grounded); reverse r (0 < r <= 1) = IN2 high and IN1 at duty
// 1 - r (reverse and short brake alternate, slow decay: the winding is always closed, so
// the motor slows with the brake time constant); short brake = both high. IN2 changes only
// where a brake pulse starts or ends, so a plain GPIO drives it.
// Portable C++17: no Arduino headers, no heap, no exceptions.
#pragma once

#include <stdint.h>

namespace tb {

// A signed drive: forward (reverse = false) at duty `mag`, or reverse at `mag` (0 = the
// short brake). Coast is forward 0.
struct Drive {
  float mag = 0.0f;
  bool reverse = false;
};

// One tactor's motor constants, as the host's shaper has them (erm.ErmParams, tuned or not).
struct DriveParams {
  float start = 0.25f;  // the dead zone: no spin below this forward drive
  float rated = 1.0f;   // the rated voltage's drive: the largest level a shaped belt holds
  float rise_tau_s = 0.040f;
  float fall_tau_s = 0.050f;
  float brake_tau_s = 0.040f;
  // exp(-tick / tau) for the decision tick (set by prepare()).
  float e_rise = 0.0f;
  float e_fall = 0.0f;
  float e_brake = 0.0f;
  // The bounds (set by prepare()): the longest a kick from rest to the rated drive lasts,
  // rise_tau * ln(1 / (1 - rated)), and a full reverse from full speed to rest,
  // brake_tau * ln(2), each plus a tick, in microseconds. A kick or a brake pulse that
  // lands on a fixed level never reaches them; a rendered level that keeps moving could
  // (each tick's landing drive chases it), so the controller holds neither longer.
  uint32_t over_bound_us = 0;
  uint32_t reverse_bound_us = 0;
  void prepare(float tick_s);
};

// The shaper's preview of a played stimulus (PLAY_TARGET), in 1 kHz ticks: it aims each
// tick at the amplitudes the stimulus has this many ticks later (zero from this long
// before its end), so the felt envelope tracks the intended one (erm.LEAD_TICKS).
// Streamed frames are not known ahead: a streamed level is shaped as it comes.
constexpr uint32_t kShapeLeadTicks = 3;

// A tactor counts as at its level when its predicted speed is this close (a level step is
// 1/65535 = 1.5e-5; float32 landing residues are ~1e-7).
constexpr float kSettled = 1e-4f;

// The drive for the next tick from the commanded level (0..1, already clamped to rated) and
// the predicted speed w: erm.shape_tick. brake: the bridge may reverse-drive.
Drive shape_tick(float level, float w, const DriveParams& p, bool brake);

// The predicted speed h_s after w under a constant drive: erm.drive_relax.
float drive_relax(const Drive& d, float w, float h_s, const DriveParams& p);

// The bridge inputs of a drive (IN1 level 0..65535, IN2 high?) and back.
void drive_to_bridge(const Drive& d, uint16_t* in1, bool* in2);
Drive bridge_to_drive(uint16_t in1, bool in2);

}  // namespace tb

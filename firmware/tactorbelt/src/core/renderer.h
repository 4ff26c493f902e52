// Amplitude laws and static/dynamic stimuli, float32, exactly as docs/conventions.md
// ("Amplitude laws", "Stimuli") and the Python reference tactorbelt.stimuli define
// them. Portable C++17: no Arduino headers, no heap, no exceptions.
#pragma once

#include <stdint.h>

#include "protocol.h"

namespace tb {

enum class Mode : uint8_t { kStatic = 0, kDynamic = 1 };
enum class Law : uint8_t { kPaper = 0, kLinear = 1, kEnergy = 2 };
constexpr uint8_t kModeCount = 2;
constexpr uint8_t kLawCount = 3;

// Two angles closer than this (degrees) are the same angle. Targets arrive in
// centidegrees, so no between-tactor target comes this close to a tactor.
constexpr float kAngleToleranceDeg = 1e-3f;

// Normalises an angle to [0, 360).
float normalize_deg(float a);
// Wraps an angle difference into (-180, 180].
float wrap_deg(float a);

// Where the tactors sit. Tactor k is index k; angles may be uneven and unsorted.
class Layout {
 public:
  // N tactors at 180/N + k*360/N. Returns false unless 2 <= n <= kMaxChannels.
  bool set_even(uint8_t n);
  // Explicit angles in degrees. Returns false for a count outside
  // [2, kMaxChannels], a non-finite angle or two tactors at the same angle.
  bool set(const float* angles_deg, uint8_t n);

  uint8_t size() const { return n_; }
  float angle(uint8_t k) const { return angle_[k]; }

  // Index of the tactor at angle x, or -1 when x is between tactors.
  int tactor_at(float x) const;
  // The nearest tactor at or counter-clockwise of x, and the next one clockwise.
  void bracket(float x, uint8_t* ccw, uint8_t* cw) const;
  // Amplitude in [0, 1] of every tactor for a felt location x (degrees).
  // D = |wrap(x - d_k)|; s = the gap from d_k to its neighbour on x's side (the
  // clockwise side when x is on d_k).
  void amplitudes(float x, Law law, float falloff_deg, float* out) const;

 private:
  float angle_[kMaxChannels] = {};
  float gap_cw_[kMaxChannels] = {};
  float gap_ccw_[kMaxChannels] = {};
  uint8_t n_ = 0;
};

// The PLAY_TARGET parameters as they come over the wire.
struct StimulusParams {
  uint16_t angle_cdeg = 0;
  uint8_t mode = 0;
  uint8_t law = 0;
  uint16_t falloff_cdeg = 1500;
  uint16_t period_ms = 1000;
  uint16_t transit_ms = 100;
};

// Limits the numeric parameters are clamped to.
constexpr uint16_t kMinFalloffCdeg = 1;
constexpr uint16_t kMinPeriodMs = 10;
constexpr uint16_t kMinTransitMs = 1;

class Stimulus {
 public:
  // Prepares a stimulus on layout (which must outlive it). Numeric values are
  // clamped: angle modulo 36000, falloff >= 1 cdeg, period >= 10 ms,
  // 1 ms <= transit <= (period - 1) / 2 (so 2 * transit < period).
  // Returns false, leaving the stimulus unchanged, for an unknown mode or law.
  bool set(const Layout& layout, const StimulusParams& p);

  // The felt location (degrees) t_us microseconds after the start.
  float location(uint64_t t_us) const;
  // Amplitudes in [0, 1] of every tactor t_us microseconds after the start.
  void amplitudes(uint64_t t_us, float* out) const;

  bool dynamic() const { return dynamic_; }
  uint8_t near_tactor() const { return near_; }
  uint8_t far_tactor() const { return far_; }

 private:
  const Layout* layout_ = nullptr;
  Law law_ = Law::kPaper;
  float target_deg_ = 0.0f;
  float falloff_deg_ = 15.0f;
  bool dynamic_ = false;
  uint8_t near_ = 0;
  uint8_t far_ = 0;
  float near_deg_ = 0.0f;
  float span_deg_ = 0.0f;  // signed, from near to far through the target
  // Phase and its boundaries in microseconds (float32 holds whole microseconds
  // exactly up to 16.7 s): a dwell that starts on a whole microsecond finds the
  // location exactly on its tactor, where the energy law's square root would
  // magnify any residue.
  uint32_t period_us_ = 1000000;
  float transit_us_ = 100000.0f;
  float t1_us_ = 0.0f;  // end of the dwell on near
  float t2_us_ = 0.0f;  // end of the transit to far
  float t3_us_ = 0.0f;  // end of the dwell on far
};

// Amplitude [0, 1] to a drive level 0..65535: floor(a * 65535 + 0.5), clamped;
// NaN gives 0.
uint16_t amplitude_to_level(float a);

}  // namespace tb

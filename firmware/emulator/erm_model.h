// The ERM motor model of src/tactorbelt/devices/erm.py in C++, and the board's
// accelerometer simulated from it: the emulator's IMU (docs/protocol.md, "The
// emulator"). Host code (double precision), never built into the firmware.
//
// Each motor's normalised speed w follows its drive level u (0..1) to the steady speed
// s(u) = u when u >= start_level, else 0 (the dead zone), as a first-order lag with the
// rise time constant while w < s and the fall one while w > s. The drive is piecewise
// constant (it changes when the controller writes new levels), so each stretch is solved
// in closed form: w' = s + (w - s) exp(-h / tau) (the speed moves monotonically towards
// s within a stretch, so the rise/fall choice is exact, as in erm.py). The vibration
// amplitude is w ** amplitude_exponent (2: the eccentric mass's centrifugal force goes
// with the square of the speed). firmware/test checks this against erm.py's erm_speed
// (the "erm" vectors of vectors_ext.json).
//
// Signed drive (firmware 1.3, drive shaping; erm.py drive_steady/drive_relax): each motor's
// bridge has two inputs. IN2 low: IN1's level is the forward drive above. IN2 high: the
// bridge alternates reverse and short brake (slow decay), a reverse drive of
// r = 1 - IN1/65535 (IN1 full: the short brake, r = 0); the speed relaxes towards -r with
// the brake time constant (the winding is closed all the time), and past 0 the motor would
// spin backwards: the amplitude is that of |w|. Overdrive is a forward level above the
// rated one: the model's speed is in units of the full duty, so it is just a higher level.
//
// The simulated IMU: the eccentric mass spinning at w * kRatedHz pushes the board with a
// force that rotates in the board's x-y plane, so the board's acceleration from tactor k
// is A_k (cos phi_k, sin phi_k, 0), A_k = kRatedAccelG * amplitude_k and phi_k the rotor's
// angle (the integral of its speed, also in closed form). The board senses the tactor
// SENSE_START names (or, for kSenseAnyTactor, the sum over every tactor: with one tactor
// on at a time, as in a validation run, its vibration), plus gravity (-1 g on y: the board
// upright on the belt of a standing wearer) and Gaussian noise of kNoiseG rms per axis,
// quantised to int16 at +-kFullScaleMg. So the magnitude of (x, y + 1 g) is the envelope
// A, and each axis alone is a sinusoid at the motor's speed-dependent frequency.
#pragma once

#include <math.h>
#include <stdint.h>

#include "../tactorbelt/src/core/protocol.h"
#include "../tactorbelt/src/core/sense.h"

namespace emu {

struct ErmParams {
  double rise_tau_s = 0.040;
  double fall_tau_s = 0.050;
  double start_level = 0.25;
  double amplitude_exponent = 2.0;
  double brake_tau_s = 0.040;  // reverse drive and short brake (erm.ErmParams.brake_tau_s)
};

// Every motor of the belt, advanced in device time (microseconds).
class ErmBank {
 public:
  static constexpr double kRatedHz = 200.0;  // rotation at full speed (12000 rpm)
  static constexpr double kTwoPi = 6.283185307179586;

  explicit ErmBank(uint8_t n = 0, ErmParams p = ErmParams()) : n_(n), p_(p) {}

  uint8_t size() const { return n_; }
  const ErmParams& params() const { return p_; }

  // New drive levels (0..65535) from t_us on; the motors first run up to t_us on the old.
  void set_levels(uint64_t t_us, const uint16_t* levels, uint8_t n) {
    advance(t_us);
    for (uint8_t k = 0; k < n && k < n_; ++k) level_[k] = levels[k];
  }
  // The bridges' second inputs from t_us on (bit k: channel k's IN2 high).
  void set_in2(uint64_t t_us, uint32_t mask) {
    advance(t_us);
    in2_ = mask;
  }

  // Runs every motor up to t_us (a time before the last one changes nothing).
  void advance(uint64_t t_us) {
    if (!started_) {
      started_ = true;
      t_us_ = t_us;
      return;
    }
    if (t_us <= t_us_) return;
    const double h = static_cast<double>(t_us - t_us_) * 1e-6;
    for (uint8_t k = 0; k < n_; ++k) {
      const bool reverse = ((in2_ >> k) & 1u) != 0;
      const double s = reverse ? -(65535.0 - level_[k]) / 65535.0 : steady(level_[k]);
      const double w = w_[k];
      const double tau = reverse ? p_.brake_tau_s : (s > w ? p_.rise_tau_s : p_.fall_tau_s);
      const double decay = exp(-h / tau);
      // the rotor angle: the integral of w * 2 pi * kRatedHz over the stretch
      phase_[k] += kTwoPi * kRatedHz * (s * h + (w - s) * tau * (1.0 - decay));
      phase_[k] = fmod(phase_[k], kTwoPi);
      w_[k] = s + (w - s) * decay;
    }
    t_us_ = t_us;
  }

  double steady(uint16_t level) const {
    const double u = static_cast<double>(level) / 65535.0;
    return u >= p_.start_level ? u : 0.0;
  }
  double speed(uint8_t k) const { return w_[k]; }
  double phase(uint8_t k) const { return phase_[k]; }
  double amplitude(uint8_t k) const {
    const double a = fabs(w_[k]);
    const double w = a > 1.0 ? 1.0 : a;
    return p_.amplitude_exponent == 2.0 ? w * w : pow(w, p_.amplitude_exponent);
  }

 private:
  uint8_t n_ = 0;
  ErmParams p_;
  bool started_ = false;
  uint64_t t_us_ = 0;
  uint16_t level_[tb::kMaxChannels] = {};
  uint32_t in2_ = 0;
  double w_[tb::kMaxChannels] = {};
  double phase_[tb::kMaxChannels] = {};
};

// The board's IMU on the ERM bank.
class SimImu : public tb::Accelerometer {
 public:
  static constexpr double kRatedAccelG = 2.0;  // vibration at full speed, on the board
  static constexpr double kNoiseG = 0.004;     // rms, per axis (the BMI270's, at 1600 Hz)
  static constexpr uint16_t kFullScaleMg = 8000;

  // period_us: the IMU's output data rate (625: the BMI270 at 1600 Hz; 1051: the
  // LSM9DS1 at 952 Hz). ready false: an IMU that did not start.
  SimImu(ErmBank& bank, uint16_t period_us, bool ready = true)
      : bank_(bank), period_us_(period_us), ready_(ready) {}

  bool ready() const override { return ready_; }
  uint16_t min_period_us() const override { return period_us_; }
  uint16_t full_scale_mg() const override { return kFullScaleMg; }
  void begin_sensing(uint8_t tactor) override { tactor_ = tactor; }
  // The model has every past time: a late poll (a loaded host) reads the slots it missed.
  bool reads_past() const override { return true; }

  bool read(uint64_t stamp_us, int16_t xyz[3]) override {
    bank_.advance(stamp_us);
    double a[3] = {0.0, -1.0, 0.0};
    for (uint8_t k = 0; k < bank_.size(); ++k) {
      if (tactor_ != tb::kSenseAnyTactor && k != tactor_) continue;
      const double amp = kRatedAccelG * bank_.amplitude(k);
      a[0] += amp * cos(bank_.phase(k));
      a[1] += amp * sin(bank_.phase(k));
    }
    for (int i = 0; i < 3; ++i) {
      const double g = a[i] + kNoiseG * gaussian();
      double raw = floor(g * 32768000.0 / kFullScaleMg + 0.5);
      if (raw > 32767.0) raw = 32767.0;
      if (raw < -32768.0) raw = -32768.0;
      xyz[i] = static_cast<int16_t>(raw);
    }
    return true;
  }

 private:
  // Standard normal deviates (Box-Muller on xorshift64*): the same noise every run.
  double uniform() {
    rng_ ^= rng_ >> 12;
    rng_ ^= rng_ << 25;
    rng_ ^= rng_ >> 27;
    const uint64_t r = rng_ * 2685821657736338717ull;
    return (static_cast<double>(r >> 11) + 0.5) / 9007199254740992.0;  // (0, 1)
  }
  double gaussian() {
    if (have_spare_) {
      have_spare_ = false;
      return spare_;
    }
    const double r = sqrt(-2.0 * log(uniform()));
    const double t = ErmBank::kTwoPi * uniform();
    spare_ = r * sin(t);
    have_spare_ = true;
    return r * cos(t);
  }

  ErmBank& bank_;
  uint16_t period_us_;
  bool ready_;
  uint8_t tactor_ = tb::kSenseAnyTactor;
  uint64_t rng_ = 0x9E3779B97F4A7C15ull;
  double spare_ = 0.0;
  bool have_spare_ = false;
};

}  // namespace emu

// Start and stop of one nRF52840 PWM peripheral, as the product specification
// asks: a STOP takes effect at the end of the current PWM period and is confirmed
// by EVENTS_STOPPED, so the next SEQSTART must wait for it. Here a stop clears
// EVENTS_STOPPED, triggers STOP, waits for EVENTS_STOPPED (bounded: kStopTimeoutUs,
// about 4 periods at 20 kHz), then disables the peripheral, which hands the pins
// back to the GPIO (configured by the driver as outputs driving low). A start
// enables the peripheral and triggers SEQSTART[0].
//
// Templated on the register block so that the host tests can run it against a
// fake one (test/test_extensions.cpp) and the sketch against NRF_PWM_Type. Portable C++17.
#pragma once

#include <stdint.h>

namespace tb {

// Level 0..65535 to a compare value 0..steps-1 (full level is steps-1 of steps: a
// compare value equal to COUNTERTOP is an edge case of the wave counter).
inline uint16_t level_to_duty(uint16_t level, uint16_t steps) {
  uint32_t duty = (static_cast<uint32_t>(level) * steps + 32767u) / 65535u;
  if (duty >= steps) duty = steps - 1u;
  return static_cast<uint16_t>(duty);
}

template <class Regs>
class PwmSequencer {
 public:
  using MicrosFn = uint32_t (*)();
  static constexpr uint32_t kStopTimeoutUs = 200;
  static constexpr uint32_t kEnabled = 1;
  static constexpr uint32_t kDisabled = 0;

  PwmSequencer(Regs* regs, MicrosFn micros) : regs_(regs), micros_(micros) {}

  // (Re)plays the sequence from RAM; the last values stay on after it ends.
  void start() {
    if (!running_) regs_->ENABLE = kEnabled;
    regs_->EVENTS_SEQEND[0] = 0;
    regs_->TASKS_SEQSTART[0] = 1;
    running_ = true;
  }

  // Stops (waiting for EVENTS_STOPPED, bounded) and disables: pins back to GPIO, low.
  void stop() {
    if (running_) {
      regs_->EVENTS_STOPPED = 0;
      regs_->TASKS_STOP = 1;
      const uint32_t t0 = micros_();
      while (regs_->EVENTS_STOPPED == 0) {
        if (micros_() - t0 > kStopTimeoutUs) {
          ++stop_timeouts_;  // disable anyway: ENABLE = 0 stops the generator at once
          break;
        }
      }
      regs_->EVENTS_STOPPED = 0;
    }
    regs_->ENABLE = kDisabled;
    running_ = false;
  }

  bool running() const { return running_; }
  uint32_t stop_timeouts() const { return stop_timeouts_; }

 private:
  Regs* regs_;
  MicrosFn micros_;
  bool running_ = false;
  uint32_t stop_timeouts_ = 0;
};

}  // namespace tb

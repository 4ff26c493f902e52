// Motor outputs for the Nano 33 BLE: the nRF52840 PWM peripheral, driven directly.
//
// analogWrite() on this board drives at most 4 pins at once, so it must not be
// used. NRF_PWM0 drives channels 0-3 and NRF_PWM1 channels 4-7, each in
// "individual" decoder mode (one compare value per output), counting up to 800 at
// 16 MHz: 20 kHz, above hearing, with 800 steps. Arduino-only (not in the core);
// the start/stop sequencing is the core's PwmSequencer (tested on the host).
//
// Pin levels (docs/hardware.md, "Pin levels"):
// - at reset and until begin(): every GPIO is an input with its buffer disconnected
//   (high impedance); the driver's pull-downs hold the motors off;
// - begin() makes every motor pin a GPIO output driving low (OUTCLR, then DIRSET)
//   before the PWM is configured, and leaves the PWM disabled;
// - a peripheral runs (ENABLE = 1) only while one of its channels is above 0; when
//   all are 0 it is stopped (waiting for EVENTS_STOPPED) and disabled, so its pins
//   are GPIO outputs driving low again.
// - IN2 (drive shaping, a board wired with both bridge inputs): plain GPIO outputs, driven
//   low by begin() before anything else and high only during a brake pulse (write_in2);
//   all_off() drives them low.
#pragma once

#include <Arduino.h>

#include "src/core/controller.h"

class NrfPwmMotors : public tb::MotorDriver {
 public:
  static constexpr uint16_t kSteps = 800;  // 16 MHz / 800 = 20 kHz
  static constexpr uint8_t kMaxOutputs = 8;

  // Drives pins (and in2_pins, when the board has them; else null) low, then configures
  // the PWM peripherals, disabled.
  void begin(const PinName* pins, uint8_t n, const PinName* in2_pins = nullptr);
  // Level 0..65535 to duty 0..kSteps per channel; a peripheral whose outputs are
  // all 0 is stopped and disabled, so its pins rest at the GPIO level (low).
  void write(const uint16_t* levels, uint8_t n) override;
  // IN2 of channel k high while bit k is set (a board without IN2 pins ignores it).
  void write_in2(uint32_t mask, uint8_t n) override;
  // Everything off, by construction: both peripherals stopped and disabled.
  void all_off();
  // Stops that did not see EVENTS_STOPPED within the bound (should stay 0).
  uint32_t stop_timeouts() const;

 private:
  uint8_t n_ = 0;
  uint32_t in2_pin_[kMaxOutputs] = {};
  bool has_in2_ = false;
};

// Motor outputs for the Nano 33 BLE: the nRF52840 PWM peripheral, driven directly.
//
// analogWrite() on this board drives at most 4 pins at once, so it must not be
// used. NRF_PWM0 drives channels 0-3 and NRF_PWM1 channels 4-7, each in
// "individual" decoder mode (one compare value per output), counting up to 800 at
// 16 MHz: 20 kHz, above hearing, with 800 steps. Arduino-only (not in the core).
#pragma once

#include <Arduino.h>

#include "src/core/controller.h"

class NrfPwmMotors : public tb::MotorDriver {
 public:
  static constexpr uint16_t kSteps = 800;  // 16 MHz / 800 = 20 kHz
  static constexpr uint8_t kMaxOutputs = 8;

  // Drives pins low, then hands them to the PWM peripherals with every output off.
  void begin(const pin_size_t* pins, uint8_t n);
  // Level 0..65535 to duty 0..kSteps per channel; a peripheral whose outputs are
  // all 0 is stopped, so its pins rest at the GPIO level (low).
  void write(const uint16_t* levels, uint8_t n) override;

 private:
  uint8_t n_ = 0;
  bool running_[2] = {false, false};
};

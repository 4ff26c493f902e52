// The board's IMU as the core's Accelerometer (SENSE_START, firmware 1.2): the
// accelerometer alone, on the board's internal I2C bus (Wire1), at its highest output
// data rate, +-8 g. Which IMU: imu_config.h. What it relies on in the libraries:
// docs/hardware.md, "What the firmware relies on in the core and libraries".
#pragma once

#include <stdint.h>

#include "src/core/sense.h"

class BoardImu : public tb::Accelerometer {
 public:
  // Starts the IMU; false when it does not answer (a board of the other revision, a bus
  // fault). In setup(), before the watchdog starts: the BMI270 loads its 8 KB
  // configuration over I2C first (about a second).
  bool begin();

  bool ready() const override { return ready_; }
  uint16_t min_period_us() const override;
  uint16_t full_scale_mg() const override { return 8000; }
  // One I2C transaction of 6 bytes at 400 kHz (about 0.25 ms, blocking).
  bool read(uint64_t stamp_us, int16_t xyz[3]) override;

 private:
  bool ready_ = false;
};

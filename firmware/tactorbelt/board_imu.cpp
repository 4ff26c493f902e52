// The board's IMU (board_imu.h). Both IMUs are set to their accelerometer's highest
// output data rate and +-8 g, and read as raw 16-bit values, which SENSE_DATA carries
// with the full scale (8000 mg). docs/hardware.md, "The IMU", says what each library does
// and what this file changes.
#include "board_imu.h"

#include <Arduino.h>
#include <Wire.h>

#include "imu_config.h"

namespace {

constexpr uint32_t kI2cHz = 400000;  // both IMUs take fast mode; the library leaves 100 kHz

}  // namespace

#if defined(TACTORBELT_IMU_BMI270)
#include <Arduino_BMI270_BMM150.h>

namespace {

// The library configures the accelerometer at 100 Hz, +-4 g, and the gyroscope, in
// BoschSensorClass::configure_sensor(bmi2_dev*), the hook it declares for "finer
// configuration by subclassing". This subclass configures the accelerometer alone: 1600 Hz
// (the BMI270's highest in performance mode), +-8 g, normal filter (no averaging).
class FastBmi270 : public BoschSensorClass {
 public:
  explicit FastBmi270(TwoWire& wire) : BoschSensorClass(wire) {}
  // The Bosch API's device, which the library keeps private; its registers are read
  // through it (bmi2_get_regs, over the library's own I2C functions).
  struct bmi2_dev* device() const { return dev_; }

 protected:
  using BoschSensorClass::configure_sensor;  // the magnetometer's stays the library's
  int8_t configure_sensor(struct bmi2_dev* dev) override {
    dev_ = dev;
    struct bmi2_sens_config cfg;
    cfg.type = BMI2_ACCEL;
    int8_t rslt = bmi2_get_sensor_config(&cfg, 1, dev);
    if (rslt != BMI2_OK) return rslt;
    cfg.cfg.acc.odr = BMI2_ACC_ODR_1600HZ;
    cfg.cfg.acc.range = BMI2_ACC_RANGE_8G;
    cfg.cfg.acc.bwp = BMI2_ACC_NORMAL_AVG4;
    cfg.cfg.acc.filter_perf = BMI2_PERF_OPT_MODE;
    rslt = bmi2_set_sensor_config(&cfg, 1, dev);
    if (rslt != BMI2_OK) return rslt;
    const uint8_t sensors[1] = {BMI2_ACCEL};
    return bmi2_sensor_enable(sensors, 1, dev);
  }

 private:
  struct bmi2_dev* dev_ = nullptr;
};

// Our own instance on the internal bus (the library's IMU_BMI270_BMM150 is never begun).
FastBmi270 g_bmi270(Wire1);

int16_t negated(int16_t v) { return v == INT16_MIN ? INT16_MAX : static_cast<int16_t>(-v); }

}  // namespace

bool BoardImu::begin() {
  ready_ = g_bmi270.begin(BOSCH_ACCELEROMETER_ONLY) != 0 && g_bmi270.device() != nullptr;
  if (ready_) Wire1.setClock(kI2cHz);
  return ready_;
}

uint16_t BoardImu::min_period_us() const { return 625; }  // 1600 Hz

bool BoardImu::read(uint64_t, int16_t xyz[3]) {
  uint8_t d[6];
  if (bmi2_get_regs(BMI2_ACC_X_LSB_ADDR, d, sizeof d, g_bmi270.device()) != BMI2_OK) return false;
  const int16_t ax = static_cast<int16_t>(d[0] | (d[1] << 8));
  const int16_t ay = static_cast<int16_t>(d[2] | (d[3] << 8));
  const int16_t az = static_cast<int16_t>(d[4] | (d[5] << 8));
  // the board's axes, as the library's readAcceleration() gives them on the Nano 33 BLE
  xyz[0] = negated(ay);
  xyz[1] = negated(ax);
  xyz[2] = az;
  return true;
}

#elif defined(TACTORBELT_IMU_LSM9DS1)
#include <Arduino_LSM9DS1.h>

namespace {

// LSM9DS1 accelerometer/gyroscope registers (ST DocID025715, section 7). The library
// starts both at 119 Hz (+-4 g, 2000 dps); with the gyroscope on, the accelerometer runs
// at the gyroscope's rate. This turns the gyroscope off (accelerometer-only mode, whose
// rate is CTRL_REG6_XL's) and sets 952 Hz, +-8 g, the anti-aliasing bandwidth by the rate.
constexpr uint8_t kAgAddress = 0x6B;
constexpr uint8_t kCtrlReg1G = 0x10;
constexpr uint8_t kCtrlReg6Xl = 0x20;
constexpr uint8_t kOutXXl = 0x28;
constexpr uint8_t kGyroOff = 0x00;
constexpr uint8_t kXl952HzFs8g = (6u << 5) | (3u << 3);  // ODR_XL 110, FS_XL 11: 0xD8

bool write_register(uint8_t reg, uint8_t value) {
  Wire1.beginTransmission(kAgAddress);
  Wire1.write(reg);
  Wire1.write(value);
  return Wire1.endTransmission() == 0;
}

}  // namespace

bool BoardImu::begin() {
  // the library's begin(): Wire1, the reset, WHO_AM_I of both dies, its configuration
  ready_ = IMU.begin() != 0 && write_register(kCtrlReg1G, kGyroOff) &&
           write_register(kCtrlReg6Xl, kXl952HzFs8g);
  if (ready_) Wire1.setClock(kI2cHz);
  return ready_;
}

uint16_t BoardImu::min_period_us() const { return 1051; }  // 952 Hz, rounded up

bool BoardImu::read(uint64_t, int16_t xyz[3]) {
  // as the library's readAcceleration(): the 6 output bytes in one read, the address
  // with bit 7 set as the library sends it (the die takes the 7 low bits as the register
  // and increments it by itself: CTRL_REG8 IF_ADD_INC, on after its reset)
  Wire1.beginTransmission(kAgAddress);
  Wire1.write(static_cast<uint8_t>(0x80 | kOutXXl));
  if (Wire1.endTransmission(false) != 0) return false;
  if (Wire1.requestFrom(kAgAddress, static_cast<size_t>(6)) != 6) return false;
  uint8_t d[6];
  for (uint8_t& b : d) b = static_cast<uint8_t>(Wire1.read());
  for (int a = 0; a < 3; ++a) xyz[a] = static_cast<int16_t>(d[2 * a] | (d[2 * a + 1] << 8));
  return true;
}

#endif

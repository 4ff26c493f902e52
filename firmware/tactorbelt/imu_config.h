// Which IMU the board carries: the two revisions of the Nano 33 BLE differ, and so do
// their libraries, which cannot both be linked into one sketch. Choose at compile time:
//
//   TACTORBELT_IMU_BMI270   Nano 33 BLE Rev2 (and Sense Rev2): Bosch BMI270 + BMM150,
//                           library Arduino_BMI270_BMM150. The default.
//   TACTORBELT_IMU_LSM9DS1  Nano 33 BLE Rev1 (and Sense Rev1): ST LSM9DS1, library
//                           Arduino_LSM9DS1.
//
// Uncomment the line below for a Rev1 board, or pass the define to the compiler:
//   arduino-cli compile --fqbn arduino:mbed_nano:nano33ble
//     --build-property compiler.cpp.extra_flags=-DTACTORBELT_IMU_LSM9DS1 firmware/tactorbelt
// A board whose IMU is not the one built for does not start it: INFO leaves the SENSE
// capability bit clear and SENSE_START is NAKed with code 6 (docs/hardware.md, "The IMU").
#pragma once

// #define TACTORBELT_IMU_LSM9DS1

#if defined(TACTORBELT_IMU_BMI270) && defined(TACTORBELT_IMU_LSM9DS1)
#error "define only one of TACTORBELT_IMU_BMI270 and TACTORBELT_IMU_LSM9DS1"
#endif
#if !defined(TACTORBELT_IMU_BMI270) && !defined(TACTORBELT_IMU_LSM9DS1)
#define TACTORBELT_IMU_BMI270
#endif

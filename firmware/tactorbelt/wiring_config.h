// How the motor drivers' inputs are wired (docs/hardware.md, "Wiring"). Choose at compile
// time:
//
//   (default)                IN1 of each motor's bridge on its PWM pin, IN2 to ground (or
//                            a low-side MOSFET per motor): the older wiring. Drive shaping
//                            overdrives (kicks) but cannot brake: a fall coasts. INFO
//                            reports the SHAPE capability bit, not BRAKE.
//   TACTORBELT_WIRING_BRAKE  both DRV8833 inputs wired: IN1 on the PWM pins as before, IN2
//                            on the GPIOs kBrakePins (tactorbelt.ino: D2, D3, D4, D5, D6,
//                            D10). Shaping reverse-drives and short-brakes each fall; INFO
//                            reports SHAPE and BRAKE.
//
// Uncomment the line below for a belt wired with both inputs, or pass the define:
//   arduino-cli compile --fqbn arduino:mbed_nano:nano33ble
//     --build-property compiler.cpp.extra_flags=-DTACTORBELT_WIRING_BRAKE firmware/tactorbelt
// Never define it for a belt wired the old way: IN2 would drive a pin tied to ground.
#pragma once

// #define TACTORBELT_WIRING_BRAKE

// Stub of the Arduino Mbed OS core API used by the sketch: declarations only,
// with the signatures of ArduinoCore-mbed (Nano 33 BLE), so that `make test` can
// compile-check the sketch without the board package. Not a simulation.
#pragma once

#include <stddef.h>
#include <stdint.h>

typedef uint8_t pin_size_t;
// PinName: mbed's nRF52840 names (targets/.../TARGET_NRF52840/PinNames.h), pin
// number = port * 32 + pin.
enum PinName : int { P0_4 = 4, P0_5 = 5, P0_13 = 13, P0_21 = 21, P0_23 = 23, P0_27 = 27,
                     P1_8 = 40, P1_11 = 43, P1_12 = 44, P1_13 = 45, P1_14 = 46, P1_15 = 47,
                     NC = -1 };
enum { D2 = 2, D3 = 3, D4 = 4, D5 = 5, D6 = 6, D7 = 7, LED_BUILTIN = 13 };
enum PinMode { INPUT = 0, OUTPUT = 1 };
enum PinStatus { LOW = 0, HIGH = 1 };

PinName digitalPinToPinName(pin_size_t pin);
void pinMode(pin_size_t pin, PinMode mode);
void digitalWrite(pin_size_t pin, PinStatus value);
unsigned long micros();
unsigned long millis();
void delay(unsigned long ms);

namespace arduino {
class USBSerial {
 public:
  void begin(unsigned long baud);
  int available();
  int read();
  size_t write(const uint8_t* buf, size_t size);
  // USBCDC::send_nb (USBSerial derives from USBCDC): copies what the CDC TX
  // buffer has room for, never waits.
  void send_nb(uint8_t* buffer, uint32_t size, uint32_t* actual, bool now = true);
  bool dtr();
  operator bool();
};
}  // namespace arduino
extern arduino::USBSerial _SerialUSB;
#define Serial _SerialUSB

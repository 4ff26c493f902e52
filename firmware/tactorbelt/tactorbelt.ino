// tactorbelt firmware for the Arduino Nano 33 BLE (nRF52840): protocol v1 over
// USB serial and BLE, 6 ERM tactors on the nRF PWM peripherals.
//
// A thin shell around the portable core in src/core (framing, decoder, renderer,
// controller with the heartbeat failsafe); see docs/protocol.md for the protocol
// and docs/hardware.md for wiring, parts and how to build and flash.
//
// Board: "Arduino Mbed OS Nano Boards" > Arduino Nano 33 BLE. Library: ArduinoBLE.

#include <Arduino.h>
#include <ArduinoBLE.h>

#include "nrf_pwm_motors.h"
#include "src/core/controller.h"

namespace {

// --- configuration ----------------------------------------------------------------
// Tactor k is driven from kMotorPins[k] and sits at 180/N + k*360/N degrees
// (30, 90, ..., 330: 0 = navel, clockwise seen from above).
constexpr uint8_t kChannels = 6;
const pin_size_t kMotorPins[kChannels] = {D2, D3, D4, D5, D6, D7};

// The GATT service: the host writes request packets (unframed, one per write,
// without response) to RX and gets replies as notifications on TX.
const char kDeviceName[] = "tactorbelt";
const char kServiceUuid[] = "7b1e0001-5c1a-4d8e-9f3b-6a2c74b0e1d5";
const char kRxUuid[] = "7b1e0002-5c1a-4d8e-9f3b-6a2c74b0e1d5";
const char kTxUuid[] = "7b1e0003-5c1a-4d8e-9f3b-6a2c74b0e1d5";

constexpr uint32_t kTickUs = 1000;         // the controller ticks at 1 kHz
constexpr uint32_t kMaxLagUs = 100000;     // further behind: skip ahead, do not burst
constexpr int kSerialChunk = 64;           // bytes read per loop() pass

// --- state -------------------------------------------------------------------------
tb::Layout g_layout;
NrfPwmMotors g_motors;
tb::Controller g_controller(g_layout, g_motors, NrfPwmMotors::kSteps);

BLEService g_service(kServiceUuid);
BLECharacteristic g_rx(kRxUuid, BLEWriteWithoutResponse | BLEWrite, tb::kMaxPacket);
BLECharacteristic g_tx(kTxUuid, BLENotify, tb::kMaxPacket);
bool g_ble_ok = false;
bool g_serial_open = false;
uint64_t g_next_tick_us = 0;

// micros() wraps every 71.6 minutes; the controller wants a monotonic 64-bit clock.
uint64_t micros64() {
  static uint32_t last = 0;
  static uint64_t high = 0;
  const uint32_t now = micros();
  if (now < last) high += 1ull << 32;
  last = now;
  return high | now;
}

// Serial replies: COBS + 0x00, written only while the host holds DTR.
class SerialSink : public tb::ReplySink {
 public:
  void send(const uint8_t* packet, size_t n) override {
    uint8_t frame[tb::kMaxFrame];
    const size_t len = tb::frame_packet(packet, n, frame, sizeof frame);
    if (len != 0 && Serial.dtr()) Serial.write(frame, len);
  }
} g_serial_sink;

// BLE replies: the packet as one notification (needs an ATT MTU of at least 67).
class BleSink : public tb::ReplySink {
 public:
  void send(const uint8_t* packet, size_t n) override {
    g_tx.writeValue(packet, static_cast<int>(n));
  }
} g_ble_sink;

void on_ble_written(BLEDevice, BLECharacteristic characteristic) {
  g_controller.receive_packet(characteristic.value(),
                              static_cast<size_t>(characteristic.valueLength()), micros64(),
                              g_ble_sink);
}

void on_ble_disconnected(BLEDevice) {
  g_controller.link_closed(micros64());  // BLE disconnect: outputs off
}

void begin_ble() {
  if (!BLE.begin()) return;  // no radio: serial only
  BLE.setLocalName(kDeviceName);
  BLE.setDeviceName(kDeviceName);
  BLE.setConnectionInterval(6, 12);  // 7.5 to 15 ms, if the central agrees
  BLE.setAdvertisedService(g_service);
  g_service.addCharacteristic(g_rx);
  g_service.addCharacteristic(g_tx);
  BLE.addService(g_service);
  g_rx.setEventHandler(BLEWritten, on_ble_written);
  BLE.setEventHandler(BLEDisconnected, on_ble_disconnected);
  BLE.advertise();
  g_ble_ok = true;
}

void poll_serial(uint64_t now_us) {
  // The port is open while the host holds DTR (pyserial sets it on open and
  // clears it on close). Closing the port stops the outputs.
  const bool open = Serial.dtr();
  if (g_serial_open && !open) g_controller.link_closed(now_us);
  g_serial_open = open;
  uint8_t buf[kSerialChunk];
  int n = 0;
  while (n < kSerialChunk && Serial.available() > 0) {
    const int c = Serial.read();
    if (c < 0) break;
    buf[n++] = static_cast<uint8_t>(c);
  }
  if (n > 0) g_controller.receive_bytes(buf, static_cast<size_t>(n), now_us, g_serial_sink);
}

}  // namespace

void setup() {
  // Outputs off before anything else: pins low, PWM idle.
  g_motors.begin(kMotorPins, kChannels);
  pinMode(LED_BUILTIN, OUTPUT);
  digitalWrite(LED_BUILTIN, LOW);
  g_layout.set_even(kChannels);
  g_controller.begin(micros64());
  Serial.begin(115200);  // USB CDC: the baud rate is ignored
  begin_ble();
  g_next_tick_us = micros64() + kTickUs;
}

void loop() {
  poll_serial(micros64());
  if (g_ble_ok) BLE.poll();
  const uint64_t now = micros64();
  if (now >= g_next_tick_us) {
    if (now - g_next_tick_us > kMaxLagUs) g_next_tick_us = now;
    g_next_tick_us += kTickUs;
    g_controller.tick(now);
    const tb::State s = g_controller.state();
    digitalWrite(LED_BUILTIN, s == tb::State::kStreaming || s == tb::State::kPlaying ? HIGH : LOW);
  }
}

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

#if __has_include("nrf.h")
#include "nrf.h"
#endif
#include "utility/ATT.h"  // ArduinoBLE: the negotiated ATT MTU

#include "nrf_pwm_motors.h"
#include "src/core/controller.h"
#include "src/core/links.h"

namespace {

// --- configuration ----------------------------------------------------------------
// Tactor k is driven from kMotorPins[k] and sits at 180/N + k*360/N degrees
// (30, 90, ..., 330: 0 = navel, clockwise seen from above). The PWM runs at
// 20 kHz, so only pins without the nRF52840's "Standard drive, low frequency I/O
// only" mark (which D2-D6, P1.11-P1.15, carry): docs/hardware.md, "Why these pins".
// Named by nRF52840 pin, so no board-variant table can move them: on the Nano 33
// BLE header they are D7, D8, D9, D12, A0, A1.
constexpr uint8_t kChannels = 6;
const PinName kMotorPins[kChannels] = {P0_23, P0_21, P0_27, P1_8, P0_4, P0_5};
const pin_size_t kStateLed = LED_BUILTIN;  // on while the outputs may be driven

// The GATT service: the host writes request packets (unframed, one per write,
// without response) to RX and gets replies as notifications on TX.
const char kDeviceName[] = "tactorbelt";
const char kServiceUuid[] = "7b1e0001-5c1a-4d8e-9f3b-6a2c74b0e1d5";
const char kRxUuid[] = "7b1e0002-5c1a-4d8e-9f3b-6a2c74b0e1d5";
const char kTxUuid[] = "7b1e0003-5c1a-4d8e-9f3b-6a2c74b0e1d5";

constexpr uint32_t kTickUs = 1000;         // the controller ticks at 1 kHz
constexpr uint32_t kMaxLagUs = 100000;     // further behind: skip ahead, do not burst
constexpr int kSerialChunk = 64;           // bytes read per loop() pass
constexpr uint32_t kWatchdogMs = tb::kWatchdogTimeoutMs;  // 300 ms

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
uint16_t g_ble_conn_handle = 0xFFFF;

// micros() wraps every 71.6 minutes; the controller wants a monotonic 64-bit clock.
uint64_t micros64() {
  static uint32_t last = 0;
  static uint64_t high = 0;
  const uint32_t now = micros();
  if (now < last) high += 1ull << 32;
  last = now;
  return high | now;
}

// The nRF52840 watchdog: started once in setup(), then it cannot be stopped or
// changed until a reset. Fed (RR[0]) only by the controller's tick, after it has
// updated the outputs: a loop() that stops ticking is reset within kWatchdogMs,
// and a reset leaves every pin an input (the drivers' pull-downs: motors off).
class NrfWatchdog : public tb::Watchdog {
 public:
  void start(uint32_t timeout_ms) {
    NRF_WDT->CONFIG = (WDT_CONFIG_SLEEP_Run << WDT_CONFIG_SLEEP_Pos) |
                      (WDT_CONFIG_HALT_Pause << WDT_CONFIG_HALT_Pos);
    NRF_WDT->CRV = timeout_ms * 32768u / 1000u - 1u;  // 32.768 kHz ticks
    NRF_WDT->RREN = WDT_RREN_RR0_Enabled << WDT_RREN_RR0_Pos;
    NRF_WDT->TASKS_START = 1;
  }
  void feed(uint64_t) override { NRF_WDT->RR[0] = WDT_RR_RR_Reload; }
} g_watchdog;

// RESETREAS says why the chip reset; it accumulates until cleared (write 1s), so
// read it once at boot and clear it.
uint8_t read_and_clear_reset_reason() {
  const uint32_t r = NRF_POWER->RESETREAS;
  NRF_POWER->RESETREAS = r;
  uint8_t flags = 0;
  if (r & POWER_RESETREAS_RESETPIN_Msk) flags |= tb::reset::kPin;
  if (r & POWER_RESETREAS_DOG_Msk) flags |= tb::reset::kWatchdog;
  if (r & POWER_RESETREAS_SREQ_Msk) flags |= tb::reset::kSoft;
  if (r & POWER_RESETREAS_LOCKUP_Msk) flags |= tb::reset::kLockup;
  if (r & ~(POWER_RESETREAS_RESETPIN_Msk | POWER_RESETREAS_DOG_Msk | POWER_RESETREAS_SREQ_Msk |
            POWER_RESETREAS_LOCKUP_Msk)) {
    flags |= tb::reset::kOther;
  }
  return flags;
}

// Serial replies: COBS frames into the core's bounded TX ring (whole frames or
// nothing; what does not fit is dropped and counted), drained here with
// USBCDC::send_nb, which copies what the CDC buffer has room for and never waits.
// (Serial.write ends in USBCDC::send, which waits until the host reads: a host
// that holds the port open and stops reading would stall loop(), the tick and the
// failsafe.)
tb::SerialTx g_serial_tx(g_controller.link_counters());

void drain_serial() {
  const uint8_t* data = nullptr;
  const size_t n = g_serial_tx.peek(&data);
  if (n == 0) return;
  uint32_t sent = 0;
  Serial.send_nb(const_cast<uint8_t*>(data), static_cast<uint32_t>(n), &sent, true);
  g_serial_tx.consume(sent);
}

// BLE replies: at most MTU - 3 bytes per notification (the core's BleTx splits
// framed replies or refuses an unframed one that does not fit with NAK 5).
class ArduinoBleNotifier : public tb::BleNotifier {
 public:
  uint16_t att_mtu() override {
    return g_ble_conn_handle == 0xFFFF ? tb::kDefaultAttMtu : ATT.mtu(g_ble_conn_handle);
  }
  bool notify(const uint8_t* data, size_t n) override {
    return g_tx.writeValue(data, static_cast<int>(n)) != 0;
  }
} g_ble_notifier;
tb::BleTx g_ble_tx(g_ble_notifier, g_controller, g_controller.link_counters());

void on_ble_written(BLEDevice, BLECharacteristic characteristic) {
  g_controller.receive_packet(characteristic.value(),
                              static_cast<size_t>(characteristic.valueLength()), micros64(),
                              g_ble_tx);
}

// ArduinoBLE does not expose the central's connection handle, which ATT.mtu()
// needs; Cordio numbers connections from 0, so look for the connected one once.
// Not found: 0xFFFF, and replies are held to the default MTU (23: 20 bytes).
void on_ble_connected(BLEDevice) {
  g_ble_conn_handle = 0xFFFF;
  for (uint16_t h = 0; h < 16; ++h) {
    if (ATT.connected(h)) {
      g_ble_conn_handle = h;
      break;
    }
  }
}

void on_ble_disconnected(BLEDevice) {
  g_ble_conn_handle = 0xFFFF;
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
  BLE.setEventHandler(BLEConnected, on_ble_connected);
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
  g_serial_tx.set_open(open);
  uint8_t buf[kSerialChunk];
  int n = 0;
  while (n < kSerialChunk && Serial.available() > 0) {
    const int c = Serial.read();
    if (c < 0) break;
    buf[n++] = static_cast<uint8_t>(c);
  }
  if (n > 0) g_controller.receive_bytes(buf, static_cast<size_t>(n), now_us, g_serial_tx);
}

}  // namespace

void setup() {
  // Outputs off before anything else: pins GPIO outputs low, PWM disabled.
  g_motors.begin(kMotorPins, kChannels);
  pinMode(kStateLed, OUTPUT);
  digitalWrite(kStateLed, LOW);
  g_layout.set_even(kChannels);
  g_controller.set_reset_flags(read_and_clear_reset_reason());
  g_controller.begin(micros64());
  Serial.begin(115200);  // USB CDC: the baud rate is ignored
  begin_ble();
  // Last, so that USB and BLE start-up (not fed) cannot trip it.
  g_controller.set_watchdog(&g_watchdog);
  g_watchdog.start(kWatchdogMs);
  g_watchdog.feed(0);
  g_next_tick_us = micros64() + kTickUs;
}

void loop() {
  poll_serial(micros64());
  drain_serial();
  if (g_ble_ok) BLE.poll();
  const uint64_t now = micros64();
  if (now >= g_next_tick_us) {
    if (now - g_next_tick_us > kMaxLagUs) g_next_tick_us = now;
    g_next_tick_us += kTickUs;
    g_controller.tick(now);
    const tb::State s = g_controller.state();
    digitalWrite(kStateLed, s == tb::State::kStreaming || s == tb::State::kPlaying ? HIGH : LOW);
  }
}

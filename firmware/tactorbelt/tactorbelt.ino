// tactorbelt firmware for the Arduino Nano 33 BLE (nRF52840): protocol v1 over
// USB serial and BLE, 6 ERM tactors on the nRF PWM peripherals, and the board's IMU
// streamed on request (SENSE_START, firmware 1.2).
//
// A thin shell around the portable core in src/core (framing, decoder, renderer,
// controller with the heartbeat failsafe); see docs/protocol.md for the protocol
// and docs/hardware.md for wiring, parts and how to build and flash.
//
// Board: "Arduino Mbed OS Nano Boards" > Arduino Nano 33 BLE. Libraries: ArduinoBLE, and
// the IMU's: Arduino_BMI270_BMM150 (Rev2, the default) or Arduino_LSM9DS1 (Rev1), chosen
// in imu_config.h.
// What this file relies on in the core and the libraries, with the header lines:
// docs/hardware.md, "What the firmware relies on in the core and libraries".

#include <Arduino.h>
#include <ArduinoBLE.h>
#include <USB/PluggableUSBSerial.h>  // the core's USB CDC device, _SerialUSB

#include "nrf.h"           // nRF52840 MDK: NRF_WDT, NRF_POWER
#include "utility/ATT.h"  // ArduinoBLE: the negotiated ATT MTU per connection

#include "board_imu.h"
#include "nrf_pwm_motors.h"
#include "wiring_config.h"
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
// The bridges' second inputs (IN2), with TACTORBELT_WIRING_BRAKE (wiring_config.h): plain
// GPIOs, switched only where a brake pulse starts or ends, so the "low frequency I/O only"
// pins serve (D2, D3, D4, D5, D6, D10). Without the define they stay inputs.
const PinName kBrakePins[kChannels] = {P1_11, P1_12, P1_15, P1_13, P1_14, P1_2};
#ifdef TACTORBELT_WIRING_BRAKE
constexpr bool kWiredBrake = true;
#else
constexpr bool kWiredBrake = false;
#endif
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
BoardImu g_imu;
uint64_t g_next_tick_us = 0;

// --- clock -------------------------------------------------------------------------
// micros() wraps every 71.6 minutes; the controller wants a monotonic 64-bit clock.
uint64_t micros64() {
  static uint32_t last = 0;
  static uint64_t high = 0;
  const uint32_t now = micros();
  if (now < last) high += 1ull << 32;
  last = now;
  return high | now;
}

// --- watchdog and reset reason -----------------------------------------------------
// The nRF52840 watchdog: started once in setup(), then it cannot be stopped or
// changed until a reset. Fed (RR[0]) only by the controller's tick, after it has
// updated the outputs: a loop() that stops ticking is reset within kWatchdogMs,
// and a reset leaves every pin an input (the drivers' pull-downs: motors off).
// A soft reset does not stop a running WDT: then CONFIG, CRV and RREN are read-only
// and these writes change nothing (they write the same values).
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

// --- USB serial link ----------------------------------------------------------------
// On this core `Serial` and `SerialUSB` are both `_UART_USB_`, an arduino::UART that
// forwards to the USB CDC device. The device itself is `_SerialUSB`, an
// arduino::USBSerial derived from USBCDC; the link uses it directly, since only
// USBCDC has send_nb. The core's main() calls _SerialUSB.begin() before setup(), so
// the sketch does not (a second begin() would attach its receive callback twice).
arduino::USBSerial& g_usb = _SerialUSB;

// Replies: COBS frames into the core's bounded TX ring (whole frames or nothing; what
// does not fit is dropped and counted), drained with USBCDC::send_nb, which copies
// what the CDC's 64-byte packet buffer takes and never waits. (Serial.write ends in
// USBCDC::send, which waits until the host reads: a host that holds the port open and
// stops reading would stall loop(), the tick and the failsafe.)
tb::SerialTx g_serial_tx(g_controller.link_counters());
bool g_serial_open = false;

// The port is open while USBCDC's terminal is connected: from the host's
// SET_CONTROL_LINE_STATE with DTR set (pyserial asserts DTR when it opens the port)
// until one with DTR clear, a USB bus reset, or the device leaving the Configured
// state. That is the very flag send_nb and receive_nb test, so "open" means "the core
// moves bytes"; dtr() alone is the last request's DTR bit, which a bus reset leaves
// set. While the port is closed (DTR low):
// - nothing arrives (receive_nb hands over no bytes); bytes of the last host still in
//   USBSerial's receive ring are read and discarded, not decoded, so a request sent
//   just before the close cannot start the motors after it;
// - nothing is sent: SerialTx is closed, so a reply is neither queued nor counted
//   (tx_dropped counts frames dropped for lack of room while the port is open; while
//   it is closed no request is decoded, so there is nothing to reply to), and what was
//   queued for the last host is discarded;
// - the open -> closed edge turns the outputs off (Controller::link_closed).
void poll_serial(uint64_t now_us) {
  const bool open = g_usb.connected();
  if (g_serial_open && !open) g_controller.link_closed(now_us);
  g_serial_open = open;
  g_serial_tx.set_open(open);
  uint8_t buf[kSerialChunk];
  int n = 0;
  while (n < kSerialChunk && g_usb.available() > 0) {
    const int c = g_usb.read();
    if (c < 0) break;
    buf[n++] = static_cast<uint8_t>(c);
  }
  if (n > 0 && open) g_controller.receive_bytes(buf, static_cast<size_t>(n), now_us, g_serial_tx);
}

void drain_serial() {
  const uint8_t* data = nullptr;
  const size_t n = g_serial_tx.peek(&data);
  if (n == 0) return;
  uint32_t sent = 0;
  // send_nb's buffer is not const, but it only reads it (a copy into the CDC buffer).
  g_usb.send_nb(const_cast<uint8_t*>(data), static_cast<uint32_t>(n), &sent, true);
  g_serial_tx.consume(sent);
}

// --- BLE link -----------------------------------------------------------------------
BLEService g_service(kServiceUuid);
BLECharacteristic g_rx(kRxUuid, BLEWriteWithoutResponse | BLEWrite, tb::kMaxPacket);
BLECharacteristic g_tx(kTxUuid, BLENotify, tb::kMaxPacket);
bool g_ble_ok = false;

// The central's connection handle, which ATT.mtu() needs. ArduinoBLE does not pass
// it to the connect handler, so loop() looks for it after BLE.poll(): the first
// handle ATT.connected() knows (Cordio numbers connections from 0; one central at a
// time, since advertising stops on a connection). Not inside the handler: ATT.connected()
// runs HCI.poll(), and a nested HCI.poll() would overwrite the HCI receive buffer
// that the connection event is still being read from. Until found, and when not
// found: kNoConnection, and replies are held to the default MTU (23: 20 bytes).
constexpr uint16_t kNoConnection = 0xFFFF;
constexpr uint16_t kConnectionHandles = 16;  // handles tried (DM_CONN_MAX is 5)
uint16_t g_ble_conn_handle = kNoConnection;
bool g_ble_find_handle = false;

// BLE replies: at most MTU - 3 bytes per notification (the core's BleTx splits
// framed replies or refuses an unframed one that does not fit with NAK 5).
class ArduinoBleNotifier : public tb::BleNotifier {
 public:
  uint16_t att_mtu() override {
    return g_ble_conn_handle == kNoConnection ? tb::kDefaultAttMtu : ATT.mtu(g_ble_conn_handle);
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

void on_ble_connected(BLEDevice) {
  g_ble_conn_handle = kNoConnection;
  g_ble_find_handle = true;  // in loop(), after BLE.poll() has returned
}

void on_ble_disconnected(BLEDevice) {
  g_ble_conn_handle = kNoConnection;
  g_ble_find_handle = false;
  g_controller.link_closed(micros64());  // BLE disconnect: outputs off
}

void find_ble_conn_handle() {
  g_ble_find_handle = false;
  for (uint16_t h = 0; h < kConnectionHandles; ++h) {
    if (ATT.connected(h)) {
      g_ble_conn_handle = h;
      return;
    }
  }
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

void poll_ble() {
  if (!g_ble_ok) return;
  BLE.poll();
  if (g_ble_find_handle) find_ble_conn_handle();
}

// --- the controller's tick ------------------------------------------------------------
void tick_if_due() {
  const uint64_t now = micros64();
  if (now < g_next_tick_us) return;
  if (now - g_next_tick_us > kMaxLagUs) g_next_tick_us = now;
  g_next_tick_us += kTickUs;
  g_controller.tick(now);
  const tb::State s = g_controller.state();
  digitalWrite(kStateLed, s == tb::State::kStreaming || s == tb::State::kPlaying ? HIGH : LOW);
}

}  // namespace

void setup() {
  // Outputs off before anything else: pins GPIO outputs low, PWM disabled.
  g_motors.begin(kMotorPins, kChannels, kWiredBrake ? kBrakePins : nullptr);
  pinMode(kStateLed, OUTPUT);
  digitalWrite(kStateLed, LOW);
  g_layout.set_even(kChannels);
  g_controller.set_reset_flags(read_and_clear_reset_reason());
  g_controller.set_drive_shaping(kWiredBrake);  // shapes on every board; brakes if wired
  g_controller.begin(micros64());
  // The IMU (SENSE_START): installed either way; one that does not start is reported as
  // unavailable (no INFO capability bit, NAK 6), not as a firmware without it.
  g_imu.begin();
  g_controller.set_accelerometer(&g_imu);
  // USB CDC: already started by the core's main() (any baud rate; see g_usb).
  begin_ble();
  // Last, so that BLE start-up (not fed) cannot trip it.
  g_controller.set_watchdog(&g_watchdog);
  g_watchdog.start(kWatchdogMs);
  g_watchdog.feed(0);
  g_next_tick_us = micros64() + kTickUs;
}

// One pass: each link's input (requests are answered as they are decoded), the 1 kHz
// tick, a SENSE sample when one is due (one I2C read, about 0.25 ms), then the serial
// replies out. Nothing here waits on a host.
void loop() {
  poll_serial(micros64());
  poll_ble();
  tick_if_due();
  g_controller.poll_sense(micros64());
  drain_serial();
}

// Protocol v1 constants and little-endian field helpers (see docs/protocol.md).
// Portable C++17: no Arduino headers, no heap, no exceptions.
#pragma once

#include <stddef.h>
#include <stdint.h>

namespace tb {

constexpr uint8_t kProtocolVersion = 1;
constexpr uint8_t kFirmwareMajor = 1;
constexpr uint8_t kFirmwareMinor = 3;
constexpr uint8_t kFirmwarePatch = 0;

// A packet is type u8, seq u8, payload, crc u16 LE: at most 64 bytes before framing.
constexpr size_t kMaxPacket = 64;
constexpr size_t kHeaderSize = 2;
constexpr size_t kCrcSize = 2;
constexpr size_t kMinPacket = kHeaderSize + kCrcSize;
constexpr size_t kMaxPayload = kMaxPacket - kMinPacket;
// COBS adds one byte per started run of 254 bytes: 64 bytes encode to at most 65.
constexpr size_t kMaxEncodedPacket = kMaxPacket + kMaxPacket / 254 + 1;

// Channel limit: INFO (10 + 2N payload bytes) must fit in kMaxPayload.
constexpr uint8_t kMaxChannels = 16;

// INFO capability bits. kCapWatchdogReset is a status bit: the last reset was the
// watchdog's. The extensions (GET_DIAG, ONSET events, the SET_CONFIG flags byte) are
// all opt-in, so a v1 host that never asks sees exactly v1.0 behaviour; a host finds
// them by sending GET_DIAG (a device without them NAKs it with code 2). kCapSense
// (firmware 1.2): the board's accelerometer started and SENSE_START streams it.
constexpr uint8_t kCapPlayTarget = 0x01;
constexpr uint8_t kCapSense = 0x02;
// Firmware 1.3, set only by a build that shapes (Controller::set_drive_shaping): SET_DRIVE is
// known (kCapShape), and the board has both bridge inputs wired, so it can reverse-drive and
// short-brake its motors (kCapBrake). A board wired the old way (IN2 to ground, MOSFETs)
// reports kCapShape alone: it overdrives but coasts.
constexpr uint8_t kCapShape = 0x04;
constexpr uint8_t kCapBrake = 0x08;
constexpr uint8_t kCapWatchdogReset = 0x80;

// SET_CONFIG flags (the optional 7th payload byte). Cleared when the link closes.
constexpr uint8_t kFlagOnsetEvents = 0x01;  // send ONSET when outputs start
constexpr uint8_t kFlagBleFramed = 0x02;    // BLE replies as a COBS stream in MTU chunks
constexpr uint8_t kKnownFlags = kFlagOnsetEvents | kFlagBleFramed;

// Reset causes (GET_DIAG reset_flags), from the nRF52840 RESETREAS register.
namespace reset {
constexpr uint8_t kPin = 0x01;       // RESETREAS.RESETPIN
constexpr uint8_t kWatchdog = 0x02;  // RESETREAS.DOG
constexpr uint8_t kSoft = 0x04;      // RESETREAS.SREQ
constexpr uint8_t kLockup = 0x08;    // RESETREAS.LOCKUP
constexpr uint8_t kOther = 0x80;     // any other bit (wake-ups, debug interface)
}  // namespace reset

namespace msg {
constexpr uint8_t kPing = 0x01;
constexpr uint8_t kGetInfo = 0x02;
constexpr uint8_t kSetAmplitudes = 0x10;
constexpr uint8_t kStopAll = 0x11;
constexpr uint8_t kPlayTarget = 0x12;
constexpr uint8_t kHeartbeat = 0x14;
constexpr uint8_t kSetConfig = 0x15;
constexpr uint8_t kGetStatus = 0x16;
constexpr uint8_t kGetDiag = 0x17;
constexpr uint8_t kSenseStart = 0x18;  // firmware 1.2: stream the accelerometer
constexpr uint8_t kSenseStop = 0x19;
constexpr uint8_t kSetDrive = 0x1A;  // firmware 1.3: plain or shaped drive, motor constants
constexpr uint8_t kAck = 0x80;
constexpr uint8_t kPong = 0x81;
constexpr uint8_t kInfo = 0x82;
constexpr uint8_t kStatus = 0x83;
constexpr uint8_t kDiag = 0x84;
constexpr uint8_t kOnset = 0x85;
constexpr uint8_t kSenseData = 0x86;  // firmware 1.2: accelerometer samples
constexpr uint8_t kNak = 0x8F;
// 0x70..0x7F: debug requests, handled only by a build that installs a DebugHook
// (the emulator with --debug-frames); the device NAKs them as unknown (code 2).
constexpr uint8_t kDebugFirst = 0x70;
constexpr uint8_t kDebugLast = 0x7F;
constexpr uint8_t kDebugHang = 0x7E;  // emulator: stop ticking (watchdog test)
}  // namespace msg

namespace nak {
constexpr uint8_t kUnknownType = 2;
constexpr uint8_t kBadLength = 3;
constexpr uint8_t kOutOfRange = 4;
constexpr uint8_t kReplyTooLong = 5;  // BLE: the reply does not fit the negotiated ATT MTU
constexpr uint8_t kUnavailable = 6;   // the request is known but its hardware did not start
}  // namespace nak

enum class State : uint8_t { kIdle = 0, kStreaming = 1, kPlaying = 2, kFailsafe = 3 };

// Payload sizes of fixed-size requests.
constexpr size_t kPingPayload = 4;
constexpr size_t kPlayTargetPayload = 14;
constexpr size_t kSetConfigPayload = 2;
constexpr size_t kSetConfigPayloadLong = 6;
constexpr size_t kSetConfigPayloadFlags = 7;
constexpr size_t kDiagPayload = 13;
constexpr size_t kOnsetPayload = 10;
constexpr size_t kSenseStartPayload = 7;
constexpr size_t kSetDrivePayloadShort = 1;  // mode
constexpr size_t kSetDrivePayload = 12;      // mode, tactor, start, rated, rise, fall, brake

// SET_DRIVE mode bits. Plain (0) is the power-up drive, and every link close returns to it.
constexpr uint8_t kDriveShaped = 0x01;   // shape every level change (kick, brake pulse)
constexpr uint8_t kDriveNoBrake = 0x02;  // shaped, but coast where a fall would brake
constexpr uint8_t kKnownDriveBits = kDriveShaped | kDriveNoBrake;
constexpr uint8_t kDriveAllTactors = 0xFF;
// Time constants in units of 100 us: 1 ms to 6 s.
constexpr uint16_t kMinDriveTau = 10;
constexpr uint16_t kMaxDriveTau = 60000;

// Configuration limits.
constexpr uint16_t kDefaultHeartbeatMs = 250;
constexpr uint16_t kMinHeartbeatMs = 50;
constexpr uint16_t kMaxHeartbeatMs = 2000;
constexpr uint32_t kDefaultMaxOnMs = 30000;
constexpr uint32_t kMinMaxOnMs = 100;
constexpr uint32_t kMaxMaxOnMs = 600000;

inline bool heartbeat_ms_ok(uint32_t ms) { return ms >= kMinHeartbeatMs && ms <= kMaxHeartbeatMs; }
inline bool max_on_ms_ok(uint32_t ms) { return ms >= kMinMaxOnMs && ms <= kMaxMaxOnMs; }

inline uint16_t get_u16(const uint8_t* p) {
  return static_cast<uint16_t>(p[0] | (p[1] << 8));
}

inline uint32_t get_u32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

inline void put_u16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}

inline void put_u32(uint8_t* p, uint32_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
  p[2] = static_cast<uint8_t>(v >> 16);
  p[3] = static_cast<uint8_t>(v >> 24);
}

inline void put_u64(uint8_t* p, uint64_t v) {
  put_u32(p, static_cast<uint32_t>(v));
  put_u32(p + 4, static_cast<uint32_t>(v >> 32));
}

inline uint64_t get_u64(const uint8_t* p) {
  return static_cast<uint64_t>(get_u32(p)) | (static_cast<uint64_t>(get_u32(p + 4)) << 32);
}

}  // namespace tb

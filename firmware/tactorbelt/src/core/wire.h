// Protocol v1 framing: CRC-16/CCITT-FALSE, COBS, packets and the incremental
// serial frame decoder. Portable C++17: no Arduino headers, no heap, no exceptions.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "protocol.h"

namespace tb {

// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor.
uint16_t crc16_ccitt_false(const uint8_t* data, size_t n);

// COBS-encodes n bytes into out (no trailing 0x00). Returns the encoded length,
// or 0 when out_cap is too small.
size_t cobs_encode(const uint8_t* in, size_t n, uint8_t* out, size_t out_cap);

// COBS-decodes n bytes (without the 0x00 delimiter) into out. Returns false on
// malformed input (a zero byte, a code running past the end) or when out_cap is
// too small.
bool cobs_decode(const uint8_t* in, size_t n, uint8_t* out, size_t out_cap, size_t* out_len);

struct Packet {
  uint8_t type = 0;
  uint8_t seq = 0;
  uint8_t len = 0;  // payload length
  uint8_t payload[kMaxPayload] = {};
};

enum class PacketStatus : uint8_t { kOk, kBadLength, kBadCrc };

// Checks length (4..64 bytes) and CRC of an unframed packet and fills out.
PacketStatus parse_packet(const uint8_t* raw, size_t n, Packet* out);

// Writes type, seq, payload and CRC into out (at least kMaxPacket bytes).
// Returns the packet length, or 0 when the payload is longer than kMaxPayload.
size_t build_packet(uint8_t type, uint8_t seq, const uint8_t* payload, size_t n, uint8_t* out);

// Writes COBS(packet) + 0x00 into out. Returns the frame length, or 0 when
// out_cap is too small.
size_t frame_packet(const uint8_t* packet, size_t n, uint8_t* out, size_t out_cap);

constexpr size_t kMaxFrame = kMaxEncodedPacket + 1;

enum class FeedResult : uint8_t { kNone, kPacket, kCrcError, kFramingError };

// Incremental decoder for the serial link: bytes in, packets out. A frame is
// everything up to a 0x00. Empty frames are ignored (a host may send 0x00 to
// flush). A frame that is too long, not valid COBS or shorter than 4 bytes is a
// framing error; a bad CRC is a CRC error. Either way the decoder resynchronises
// at the next 0x00.
class FrameDecoder {
 public:
  FeedResult feed(uint8_t byte, Packet* out);
  void reset();

 private:
  uint8_t buf_[kMaxEncodedPacket] = {};
  size_t len_ = 0;
  bool overflow_ = false;
};

}  // namespace tb

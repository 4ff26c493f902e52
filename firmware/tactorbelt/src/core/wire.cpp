#include "wire.h"

namespace tb {

uint16_t crc16_ccitt_false(const uint8_t* data, size_t n) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < n; ++i) {
    crc = static_cast<uint16_t>(crc ^ (data[i] << 8));
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000) ? static_cast<uint16_t>((crc << 1) ^ 0x1021)
                           : static_cast<uint16_t>(crc << 1);
    }
  }
  return crc;
}

size_t cobs_encode(const uint8_t* in, size_t n, uint8_t* out, size_t out_cap) {
  if (out_cap == 0) return 0;
  size_t code_at = 0;  // where the current block's code byte goes
  size_t o = 1;
  uint8_t code = 1;
  for (size_t i = 0; i < n; ++i) {
    if (in[i] == 0) {
      out[code_at] = code;
      code_at = o++;
      code = 1;
    } else {
      if (o >= out_cap) return 0;
      out[o++] = in[i];
      ++code;
      if (code == 0xFF && i + 1 < n) {
        out[code_at] = code;
        code_at = o++;
        code = 1;
      }
    }
    if (code_at >= out_cap) return 0;
  }
  out[code_at] = code;
  return o;
}

bool cobs_decode(const uint8_t* in, size_t n, uint8_t* out, size_t out_cap, size_t* out_len) {
  size_t i = 0;
  size_t o = 0;
  while (i < n) {
    const uint8_t code = in[i++];
    if (code == 0) return false;
    for (uint8_t k = 1; k < code; ++k) {
      if (i >= n || in[i] == 0 || o >= out_cap) return false;
      out[o++] = in[i++];
    }
    if (code != 0xFF && i < n) {
      if (o >= out_cap) return false;
      out[o++] = 0;
    }
  }
  *out_len = o;
  return true;
}

PacketStatus parse_packet(const uint8_t* raw, size_t n, Packet* out) {
  if (n < kMinPacket || n > kMaxPacket) return PacketStatus::kBadLength;
  const uint16_t crc = get_u16(raw + n - kCrcSize);
  if (crc16_ccitt_false(raw, n - kCrcSize) != crc) return PacketStatus::kBadCrc;
  out->type = raw[0];
  out->seq = raw[1];
  out->len = static_cast<uint8_t>(n - kMinPacket);
  for (size_t i = 0; i < out->len; ++i) out->payload[i] = raw[kHeaderSize + i];
  return PacketStatus::kOk;
}

size_t build_packet(uint8_t type, uint8_t seq, const uint8_t* payload, size_t n, uint8_t* out) {
  if (n > kMaxPayload) return 0;
  out[0] = type;
  out[1] = seq;
  for (size_t i = 0; i < n; ++i) out[kHeaderSize + i] = payload[i];
  const size_t body = kHeaderSize + n;
  put_u16(out + body, crc16_ccitt_false(out, body));
  return body + kCrcSize;
}

size_t frame_packet(const uint8_t* packet, size_t n, uint8_t* out, size_t out_cap) {
  if (out_cap < 2) return 0;
  const size_t len = cobs_encode(packet, n, out, out_cap - 1);
  if (len == 0) return 0;
  out[len] = 0;
  return len + 1;
}

void FrameDecoder::reset() {
  len_ = 0;
  overflow_ = false;
}

FeedResult FrameDecoder::feed(uint8_t byte, Packet* out) {
  if (byte != 0) {
    if (overflow_) return FeedResult::kNone;
    if (len_ == sizeof buf_) {
      overflow_ = true;
      return FeedResult::kNone;
    }
    buf_[len_++] = byte;
    return FeedResult::kNone;
  }
  const bool overflow = overflow_;
  const size_t len = len_;
  reset();
  if (overflow) return FeedResult::kFramingError;
  if (len == 0) return FeedResult::kNone;
  uint8_t raw[kMaxPacket];
  size_t raw_len = 0;
  if (!cobs_decode(buf_, len, raw, sizeof raw, &raw_len)) return FeedResult::kFramingError;
  switch (parse_packet(raw, raw_len, out)) {
    case PacketStatus::kOk:
      return FeedResult::kPacket;
    case PacketStatus::kBadCrc:
      return FeedResult::kCrcError;
    case PacketStatus::kBadLength:
      break;
  }
  return FeedResult::kFramingError;
}

}  // namespace tb

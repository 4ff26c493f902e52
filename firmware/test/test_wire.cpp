// CRC, COBS, packets and the frame decoder, against known values and the
// Python-generated vectors.
#include <string.h>

#include <algorithm>
#include <vector>

#include "../tactorbelt/src/core/wire.h"
#include "minitest.h"
#include "support.h"

using json::unhex;

namespace {

struct DecodeResult {
  std::vector<tb::Packet> packets;
  int crc_errors = 0;
  int framing_errors = 0;
};

DecodeResult decode_all(tb::FrameDecoder& dec, const std::vector<uint8_t>& bytes) {
  DecodeResult r;
  tb::Packet p;
  for (uint8_t b : bytes) {
    switch (dec.feed(b, &p)) {
      case tb::FeedResult::kPacket: r.packets.push_back(p); break;
      case tb::FeedResult::kCrcError: ++r.crc_errors; break;
      case tb::FeedResult::kFramingError: ++r.framing_errors; break;
      case tb::FeedResult::kNone: break;
    }
  }
  return r;
}

std::vector<uint8_t> frame_of(uint8_t type, uint8_t seq, const std::vector<uint8_t>& payload) {
  uint8_t packet[tb::kMaxPacket];
  const size_t n = tb::build_packet(type, seq, payload.data(), payload.size(), packet);
  uint8_t frame[tb::kMaxFrame];
  const size_t len = tb::frame_packet(packet, n, frame, sizeof frame);
  return std::vector<uint8_t>(frame, frame + len);
}

}  // namespace

TEST(crc_check_value) {
  const uint8_t data[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  CHECK_EQ(tb::crc16_ccitt_false(data, sizeof data), 0x29B1);
  CHECK_EQ(tb::crc16_ccitt_false(data, 0), 0xFFFF);
}

TEST(crc_vectors) {
  const auto& v = support::vectors()["crc"];
  CHECK(v.size() >= 5);
  for (const auto& c : v.arr) {
    const auto data = unhex(c["data"].str);
    CHECK_EQ(tb::crc16_ccitt_false(data.data(), data.size()), c["crc"].integer());
  }
}

TEST(cobs_known_values) {
  const uint8_t in[] = {0x11, 0x22, 0x00, 0x33};
  uint8_t out[8];
  CHECK_EQ(tb::cobs_encode(in, sizeof in, out, sizeof out), 5);
  const uint8_t want[] = {0x03, 0x11, 0x22, 0x02, 0x33};
  CHECK(memcmp(out, want, sizeof want) == 0);
  CHECK_EQ(tb::cobs_encode(in, 0, out, sizeof out), 1);
  CHECK_EQ(out[0], 0x01);
  // too small an output buffer is refused, not overrun
  CHECK_EQ(tb::cobs_encode(in, sizeof in, out, 4), 0);
}

TEST(cobs_vectors_and_round_trip) {
  const auto& v = support::vectors()["cobs"];
  CHECK(v.size() >= 10);
  for (const auto& c : v.arr) {
    const auto data = unhex(c["data"].str);
    const auto encoded = unhex(c["encoded"].str);
    std::vector<uint8_t> out(data.size() + data.size() / 254 + 2);
    const size_t n = tb::cobs_encode(data.data(), data.size(), out.data(), out.size());
    CHECK_EQ(n, encoded.size());
    CHECK(std::vector<uint8_t>(out.begin(), out.begin() + static_cast<long>(n)) == encoded);
    std::vector<uint8_t> back(data.size() + 1);
    size_t back_len = 0;
    CHECK(tb::cobs_decode(encoded.data(), encoded.size(), back.data(), back.size(), &back_len));
    CHECK_EQ(back_len, data.size());
    CHECK(std::equal(data.begin(), data.end(), back.begin()));
  }
}

TEST(cobs_decode_rejects_malformed) {
  uint8_t out[16];
  size_t n = 0;
  const uint8_t zero[] = {0x02, 0x00};
  CHECK(!tb::cobs_decode(zero, sizeof zero, out, sizeof out, &n));
  const uint8_t short_block[] = {0x05, 0x01, 0x02};
  CHECK(!tb::cobs_decode(short_block, sizeof short_block, out, sizeof out, &n));
  const uint8_t ok[] = {0x03, 0x01, 0x02, 0x01};
  CHECK(tb::cobs_decode(ok, sizeof ok, out, sizeof out, &n));
  CHECK_EQ(n, 3);
  CHECK(!tb::cobs_decode(ok, sizeof ok, out, 2, &n));  // no room
}

TEST(frames_match_python_byte_for_byte) {
  const auto& v = support::vectors()["frames"];
  CHECK(v.size() >= 15);
  for (const auto& f : v.arr) {
    const auto payload = unhex(f["payload"].str);
    uint8_t packet[tb::kMaxPacket];
    const size_t n = tb::build_packet(static_cast<uint8_t>(f["type"].integer()),
                                      static_cast<uint8_t>(f["seq"].integer()), payload.data(),
                                      payload.size(), packet);
    CHECK(std::vector<uint8_t>(packet, packet + n) == unhex(f["packet"].str));
    CHECK(frame_of(static_cast<uint8_t>(f["type"].integer()),
                   static_cast<uint8_t>(f["seq"].integer()), payload) == unhex(f["frame"].str));
    // and the decoder gets the packet back
    tb::FrameDecoder dec;
    const auto r = decode_all(dec, unhex(f["frame"].str));
    CHECK_EQ(r.packets.size(), 1);
    if (r.packets.size() == 1) {
      CHECK_EQ(r.packets[0].type, f["type"].integer());
      CHECK_EQ(r.packets[0].len, payload.size());
      CHECK(std::equal(payload.begin(), payload.end(), r.packets[0].payload));
    }
  }
}

TEST(decoder_streams_match_python) {
  const auto& v = support::vectors()["streams"];
  CHECK(v.size() >= 10);
  for (const auto& s : v.arr) {
    tb::FrameDecoder dec;
    const auto r = decode_all(dec, unhex(s["input"].str));
    const auto& want = s["packets"];
    if (r.packets.size() != want.size()) fprintf(stderr, "  stream: %s\n", s["name"].str.c_str());
    CHECK_EQ(r.packets.size(), want.size());
    CHECK_EQ(r.crc_errors, s["crc_errors"].integer());
    CHECK_EQ(r.framing_errors, s["framing_errors"].integer());
    for (size_t i = 0; i < r.packets.size() && i < want.size(); ++i) {
      const auto payload = unhex(want[i]["payload"].str);
      CHECK_EQ(r.packets[i].type, want[i]["type"].integer());
      CHECK_EQ(r.packets[i].seq, want[i]["seq"].integer());
      CHECK_EQ(r.packets[i].len, payload.size());
      CHECK(std::equal(payload.begin(), payload.end(), r.packets[i].payload));
    }
  }
}

TEST(packet_length_limits) {
  uint8_t raw[tb::kMaxPacket + 1] = {};
  tb::Packet p;
  CHECK(tb::parse_packet(raw, 3, &p) == tb::PacketStatus::kBadLength);
  CHECK(tb::parse_packet(raw, tb::kMaxPacket + 1, &p) == tb::PacketStatus::kBadLength);
  uint8_t payload[tb::kMaxPayload + 1] = {};
  CHECK_EQ(tb::build_packet(1, 0, payload, tb::kMaxPayload + 1, raw), 0);
  const size_t n = tb::build_packet(1, 0, payload, tb::kMaxPayload, raw);
  CHECK_EQ(n, tb::kMaxPacket);
  CHECK(tb::parse_packet(raw, n, &p) == tb::PacketStatus::kOk);
  raw[5] ^= 0x40;
  CHECK(tb::parse_packet(raw, n, &p) == tb::PacketStatus::kBadCrc);
}

TEST(decoder_resynchronises_after_random_garbage) {
  // deterministic pseudo-random garbage, then a delimiter and a good frame
  uint32_t x = 12345;
  auto next = [&x] {
    x = x * 1664525u + 1013904223u;
    return static_cast<uint8_t>(x >> 24);
  };
  const auto good = frame_of(0x16, 42, {});
  for (int round = 0; round < 200; ++round) {
    tb::FrameDecoder dec;
    std::vector<uint8_t> bytes;
    const int n = next() + next();
    for (int i = 0; i < n; ++i) bytes.push_back(next());
    bytes.push_back(0);
    bytes.insert(bytes.end(), good.begin(), good.end());
    const auto r = decode_all(dec, bytes);
    CHECK(!r.packets.empty());
    if (!r.packets.empty()) {
      CHECK_EQ(r.packets.back().type, 0x16);
      CHECK_EQ(r.packets.back().seq, 42);
    }
  }
}

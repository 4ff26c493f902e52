// libFuzzer target: the serial frame decoder and, behind it, the controller (with an
// accelerometer, so SENSE_START/SENSE_STOP and the sampling run too).
// Any input must leave both consistent: no crash, no sanitizer report, every
// decoded packet re-encodes to a frame that decodes to itself, the outputs
// are off whenever the state is not streaming or playing, and SENSE_DATA packets are
// whole batches (at most 7 samples) of the session that asked for them.
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "../tactorbelt/src/core/controller.h"

namespace {

class NullMotors : public tb::MotorDriver {
 public:
  void write(const uint16_t*, uint8_t) override {}
};

class FakeAccelerometer : public tb::Accelerometer {
 public:
  bool ready() const override { return true; }
  uint16_t min_period_us() const override { return 625; }
  uint16_t full_scale_mg() const override { return 8000; }
  bool read(uint64_t stamp_us, int16_t xyz[3]) override {
    if (stamp_us < last_) __builtin_trap();  // stamps never go back within a session
    last_ = stamp_us;
    xyz[0] = xyz[1] = xyz[2] = static_cast<int16_t>(stamp_us);
    return (stamp_us & 0xFF) != 0x42;  // now and then a failed read
  }
  void begin_sensing(uint8_t) override { last_ = 0; }

 private:
  uint64_t last_ = 0;
};

// Replies must be well-formed packets.
class CheckingSink : public tb::ReplySink {
 public:
  void send(const uint8_t* packet, size_t n) override {
    tb::Packet p;
    if (tb::parse_packet(packet, n, &p) != tb::PacketStatus::kOk) __builtin_trap();
    if (p.type < 0x80) __builtin_trap();
    if (p.type == tb::msg::kSenseData) {
      if (p.len < tb::kSenseDataHeader || (p.len - tb::kSenseDataHeader) % 6 != 0) __builtin_trap();
      if ((p.len - tb::kSenseDataHeader) / 6 > tb::kSenseMaxSamples) __builtin_trap();
      if (p.payload[0] != p.seq || tb::get_u16(p.payload + 14) < 625) __builtin_trap();
    }
  }
  // a link that is full now and then
  bool can_stream(size_t) override { return (++calls_ & 3) != 0; }

 private:
  unsigned calls_ = 0;
};

void check_decoder(const uint8_t* data, size_t size) {
  tb::FrameDecoder dec;
  tb::Packet p;
  for (size_t i = 0; i < size; ++i) {
    if (dec.feed(data[i], &p) != tb::FeedResult::kPacket) continue;
    uint8_t raw[tb::kMaxPacket];
    const size_t n = tb::build_packet(p.type, p.seq, p.payload, p.len, raw);
    uint8_t frame[tb::kMaxFrame];
    const size_t len = tb::frame_packet(raw, n, frame, sizeof frame);
    if (len == 0) __builtin_trap();
    tb::FrameDecoder again;
    tb::Packet q;
    tb::FeedResult r = tb::FeedResult::kNone;
    for (size_t k = 0; k < len; ++k) r = again.feed(frame[k], &q);
    if (r != tb::FeedResult::kPacket || q.type != p.type || q.seq != p.seq || q.len != p.len ||
        memcmp(q.payload, p.payload, p.len) != 0) {
      __builtin_trap();
    }
  }
}

void check_outputs(const tb::Controller& c) {
  const bool active = c.state() == tb::State::kStreaming || c.state() == tb::State::kPlaying;
  if (active) return;
  for (uint8_t k = 0; k < c.channels(); ++k) {
    if (c.levels()[k] != 0) __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  check_decoder(data, size);

  // The controller: the input is split into chunks at 0xFE bytes; the byte after
  // each 0xFE advances the clock by that many milliseconds (ticking every ms).
  static tb::Layout layout;
  static bool ready = layout.set_even(6);
  if (!ready) __builtin_trap();
  NullMotors motors;
  CheckingSink sink;
  FakeAccelerometer acc;
  tb::Controller c(layout, motors, 800);
  c.set_accelerometer(&acc);
  uint64_t now = 0;
  c.begin(now);
  size_t start = 0;
  for (size_t i = 0; i <= size; ++i) {
    if (i < size && data[i] != 0xFE) continue;
    c.receive_bytes(data + start, i - start, now, sink);
    // the same chunk as one BLE write
    c.receive_packet(data + start, i - start, now, sink);
    check_outputs(c);
    if (i + 1 < size) {
      const uint64_t until = now + static_cast<uint64_t>(data[i + 1]) * 1000u;
      while (now < until) {
        now += 1000;
        c.tick(now);
        c.poll_sense(now - 300);
        c.poll_sense(now);
        check_outputs(c);
      }
      ++i;
    }
    start = i + 1;
  }
  c.link_closed(now);
  check_outputs(c);
  return 0;
}

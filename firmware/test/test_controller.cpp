// The controller: the scripted exchange from vectors.json (replies byte for
// byte), the heartbeat failsafe, device-side rendering, the continuous-on limit.
#include <string.h>

#include <vector>

#include "../tactorbelt/src/core/controller.h"
#include "minitest.h"
#include "support.h"

using json::unhex;

namespace {

struct Rig {
  explicit Rig(uint8_t n = 6) {
    layout.set_even(n);
    controller.begin(0);
  }

  void send(uint8_t type, uint8_t seq, const std::vector<uint8_t>& payload = {}) {
    uint8_t packet[tb::kMaxPacket];
    const size_t n = tb::build_packet(type, seq, payload.data(), payload.size(), packet);
    uint8_t frame[tb::kMaxFrame];
    const size_t len = tb::frame_packet(packet, n, frame, sizeof frame);
    controller.receive_bytes(frame, len, now_us, sink);
  }
  void send_levels(uint8_t seq, std::vector<uint16_t> levels) {
    std::vector<uint8_t> payload;
    for (uint16_t v : levels) {
      payload.push_back(static_cast<uint8_t>(v));
      payload.push_back(static_cast<uint8_t>(v >> 8));
    }
    send(tb::msg::kSetAmplitudes, seq, payload);
  }
  void play(uint8_t seq, uint16_t cdeg, uint8_t mode, uint32_t duration_ms = 0) {
    std::vector<uint8_t> p(14);
    tb::put_u16(&p[0], cdeg);
    p[2] = mode;
    p[3] = 0;
    tb::put_u16(&p[4], 1500);
    tb::put_u16(&p[6], 1000);
    tb::put_u16(&p[8], 100);
    tb::put_u32(&p[10], duration_ms);
    send(tb::msg::kPlayTarget, seq, p);
  }
  // Ticks every millisecond up to and including t_ms.
  void run_to_ms(uint64_t t_ms) {
    while (now_us < t_ms * 1000u) {
      now_us += 1000;
      controller.tick(now_us);
    }
  }
  // The last reply's type and payload.
  uint8_t last_type() const { return sink.packets.empty() ? 0 : sink.packets.back()[0]; }
  std::vector<uint8_t> last_payload() const {
    const auto& p = sink.packets.back();
    return std::vector<uint8_t>(p.begin() + 2, p.end() - 2);
  }

  tb::Layout layout;
  support::FakeMotors motors;
  support::FramingSink sink;
  tb::Controller controller{layout, motors, 800};
  uint64_t now_us = 0;
};

}  // namespace

TEST(exchange_matches_python_byte_for_byte) {
  const auto& ex = support::vectors()["exchange"];
  Rig rig(static_cast<uint8_t>(ex["tactors"].integer()));
  CHECK_EQ(ex["pwm_steps"].integer(), 800);
  int step = 0;
  for (const auto& s : ex["steps"].arr) {
    const uint64_t t = static_cast<uint64_t>(s["t_us"].integer());
    while (rig.now_us + 1000 <= t) {
      rig.now_us += 1000;
      rig.controller.tick(rig.now_us);
    }
    rig.now_us = t;
    rig.sink.clear();
    const auto input = unhex(s["input"].str);
    rig.controller.receive_bytes(input.data(), input.size(), t, rig.sink);
    if (rig.sink.bytes != unhex(s["output"].str)) fprintf(stderr, "  exchange step %d\n", step);
    CHECK(rig.sink.bytes == unhex(s["output"].str));
    ++step;
  }
  CHECK(step >= 15);
}

TEST(outputs_off_at_power_up) {
  Rig rig;
  CHECK_EQ(rig.motors.writes, 1);
  CHECK(rig.motors.last == std::vector<uint16_t>(6, 0));
  CHECK(rig.controller.state() == tb::State::kIdle);
  rig.run_to_ms(5000);  // idle never trips the failsafe
  CHECK(rig.controller.state() == tb::State::kIdle);
  CHECK_EQ(rig.controller.counters().failsafe, 0);
}

TEST(failsafe_after_silence_and_recovery) {
  Rig rig;
  rig.send_levels(0, {100, 200, 300, 400, 500, 600});
  CHECK(rig.motors.last == std::vector<uint16_t>({100, 200, 300, 400, 500, 600}));
  CHECK(rig.controller.state() == tb::State::kStreaming);
  rig.run_to_ms(249);
  CHECK(rig.controller.state() == tb::State::kStreaming);
  CHECK_EQ(rig.motors.last[5], 600);
  rig.run_to_ms(250);  // the deadline is 250 ms after the last valid packet
  CHECK(rig.controller.state() == tb::State::kFailsafe);
  CHECK(rig.motors.last == std::vector<uint16_t>(6, 0));
  CHECK_EQ(rig.controller.counters().failsafe, 1);
  // heartbeats do not leave the failsafe, and it counts once
  rig.send(tb::msg::kHeartbeat, 1);
  rig.run_to_ms(1000);
  CHECK(rig.controller.state() == tb::State::kFailsafe);
  CHECK_EQ(rig.controller.counters().failsafe, 1);
  // the next SET_AMPLITUDES does
  rig.send_levels(2, {1, 1, 1, 1, 1, 1});
  CHECK(rig.controller.state() == tb::State::kStreaming);
  CHECK_EQ(rig.motors.last[0], 1);
  // heartbeats keep it alive
  for (uint64_t t = 1100; t <= 3000; t += 200) {
    rig.run_to_ms(t);
    rig.send(tb::msg::kHeartbeat, static_cast<uint8_t>(3 + t / 200));
  }
  CHECK(rig.controller.state() == tb::State::kStreaming);
  CHECK_EQ(rig.controller.counters().failsafe, 1);
}

TEST(stop_all_acks_and_stops) {
  Rig rig;
  rig.send_levels(0, {9, 9, 9, 9, 9, 9});
  rig.send(tb::msg::kStopAll, 1);
  CHECK_EQ(rig.last_type(), tb::msg::kAck);
  CHECK(rig.last_payload() == std::vector<uint8_t>({1, 0}));
  CHECK(rig.motors.last == std::vector<uint16_t>(6, 0));
  CHECK(rig.controller.state() == tb::State::kIdle);
}

TEST(link_closed_stops_outputs) {
  Rig rig;
  rig.play(0, 1500, 0);
  CHECK(rig.controller.state() == tb::State::kPlaying);
  CHECK(rig.motors.last[0] > 0);
  rig.controller.link_closed(rig.now_us);
  CHECK(rig.motors.last == std::vector<uint16_t>(6, 0));
  CHECK(rig.controller.state() == tb::State::kIdle);
}

TEST(play_target_dynamic_dwells_on_the_device) {
  Rig rig;
  rig.play(0, 1500, 1);  // 15 degrees: 600 ms on tactor 0, 200 ms on tactor 5
  CHECK_EQ(rig.last_type(), tb::msg::kAck);
  int on0 = 0;
  int on5_full = 0;
  uint16_t peak = 0;
  for (uint64_t t = 1; t <= 1000; ++t) {
    rig.run_to_ms(t);
    if (t % 100 == 0) rig.send(tb::msg::kHeartbeat, static_cast<uint8_t>(t / 100));
    const auto& l = rig.motors.last;
    if (l[0] > 0 && l[5] == 0) ++on0;
    if (l[5] > 60000 && l[0] == 0) ++on5_full;
    if (l[0] > peak) peak = l[0];
    CHECK_EQ(l[1] + l[2] + l[3] + l[4], 0);
  }
  CHECK_EQ(on0, 601);  // t = 1..600 ms, and t = 1000 ms (the next period)
  CHECK(on5_full >= 199 && on5_full <= 201);
  CHECK_EQ(peak, tb::amplitude_to_level(1.0f - expf(-4.0f)));
  CHECK(rig.controller.state() == tb::State::kPlaying);
}

TEST(play_target_duration_ends_in_idle) {
  Rig rig;
  rig.play(0, 9000, 0, 150);
  rig.run_to_ms(149);
  CHECK(rig.controller.state() == tb::State::kPlaying);
  CHECK(rig.motors.last[1] > 0);
  rig.run_to_ms(150);
  CHECK(rig.controller.state() == tb::State::kIdle);
  CHECK(rig.motors.last == std::vector<uint16_t>(6, 0));
  CHECK_EQ(rig.controller.counters().failsafe, 0);
}

TEST(continuous_on_limit_cuts_a_channel_until_it_is_commanded_off) {
  Rig rig;
  CHECK_EQ(rig.controller.max_on_ms(), 30000u);
  std::vector<uint8_t> cfg(6);
  tb::put_u16(&cfg[0], 2000);
  tb::put_u32(&cfg[2], 1000);
  rig.send(tb::msg::kSetConfig, 0, cfg);
  CHECK_EQ(rig.last_type(), tb::msg::kAck);
  CHECK_EQ(rig.controller.max_on_ms(), 1000u);
  uint8_t seq = 1;
  rig.send_levels(seq++, {500, 0, 0, 0, 0, 0});
  rig.run_to_ms(400);
  rig.send_levels(seq++, {500, 700, 0, 0, 0, 0});  // channel 1 starts at 400 ms
  rig.run_to_ms(999);
  rig.send_levels(seq++, {500, 700, 0, 0, 0, 0});
  CHECK_EQ(rig.motors.last[0], 500);
  rig.run_to_ms(1000);  // channel 0 has been on for 1000 ms
  CHECK_EQ(rig.motors.last[0], 0);
  CHECK_EQ(rig.motors.last[1], 700);
  rig.send_levels(seq++, {500, 700, 0, 0, 0, 0});  // streaming it again does not re-arm
  CHECK_EQ(rig.motors.last[0], 0);
  rig.run_to_ms(1400);
  rig.send_levels(seq++, {500, 700, 0, 0, 0, 0});
  CHECK_EQ(rig.motors.last[1], 0);
  CHECK(rig.controller.state() == tb::State::kStreaming);
  rig.send_levels(seq++, {0, 700, 0, 0, 0, 0});    // channel 0 commanded off: re-armed
  rig.send_levels(seq++, {500, 700, 0, 0, 0, 0});
  CHECK_EQ(rig.motors.last[0], 500);
  CHECK_EQ(rig.motors.last[1], 0);
  // out of range values are refused
  tb::put_u32(&cfg[2], 99);
  rig.send(tb::msg::kSetConfig, seq++, cfg);
  CHECK_EQ(rig.last_type(), tb::msg::kNak);
  CHECK_EQ(rig.controller.max_on_ms(), 1000u);
}

TEST(ble_packets_and_their_errors) {
  Rig rig;
  uint8_t packet[tb::kMaxPacket];
  const uint8_t nonce[4] = {1, 2, 3, 4};
  size_t n = tb::build_packet(tb::msg::kPing, 9, nonce, 4, packet);
  rig.now_us = 0x123456789ull;
  rig.controller.receive_packet(packet, n, rig.now_us, rig.sink);
  CHECK_EQ(rig.last_type(), tb::msg::kPong);
  const auto pong = rig.last_payload();
  CHECK_EQ(tb::get_u32(&pong[0]), 0x04030201u);
  CHECK_EQ(tb::get_u32(&pong[4]), 0x23456789u);  // the low 32 bits of the clock
  packet[2] ^= 1;
  rig.controller.receive_packet(packet, n, rig.now_us, rig.sink);
  rig.controller.receive_packet(packet, 3, rig.now_us, rig.sink);
  CHECK_EQ(rig.controller.counters().crc_errors, 1);
  CHECK_EQ(rig.controller.counters().framing_errors, 1);
  CHECK_EQ(rig.sink.packets.size(), 1);  // never acted on, never answered
}

TEST(set_config_heartbeat_range) {
  Rig rig;
  CHECK(!rig.controller.set_heartbeat_ms(49));
  CHECK(!rig.controller.set_heartbeat_ms(2001));
  CHECK(rig.controller.set_heartbeat_ms(50));
  CHECK(rig.controller.set_heartbeat_ms(2000));
  rig.send(tb::msg::kSetConfig, 0, {0x32, 0x00});  // 50 ms
  CHECK_EQ(rig.last_type(), tb::msg::kAck);
  CHECK_EQ(rig.controller.heartbeat_ms(), 50);
  rig.send_levels(1, {1, 2, 3, 4, 5, 6});
  rig.run_to_ms(49);
  CHECK(rig.controller.state() == tb::State::kStreaming);
  rig.run_to_ms(50);
  CHECK(rig.controller.state() == tb::State::kFailsafe);
  rig.send(tb::msg::kSetConfig, 2, {0x32});
  CHECK_EQ(rig.last_type(), tb::msg::kNak);
  CHECK(rig.last_payload() == std::vector<uint8_t>({2, tb::nak::kBadLength}));
}

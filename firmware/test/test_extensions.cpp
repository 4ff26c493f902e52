// The protocol extensions (GET_DIAG, ONSET, SET_CONFIG flags, NAK 5), the two link
// reply paths (serial TX ring, BLE MTU), the watchdog feed and the PWM start/stop
// sequence against a fake register block.
#include <string.h>

#include <string>
#include <vector>

#include "../tactorbelt/src/core/controller.h"
#include "../tactorbelt/src/core/links.h"
#include "../tactorbelt/src/core/pwm_sequencer.h"
#include "../tactorbelt/src/core/watchdog.h"
#include "minitest.h"
#include "support.h"

using json::unhex;

namespace {

std::vector<uint8_t> packet_of(uint8_t type, uint8_t seq, const std::vector<uint8_t>& payload) {
  uint8_t raw[tb::kMaxPacket];
  const size_t n = tb::build_packet(type, seq, payload.data(), payload.size(), raw);
  return std::vector<uint8_t>(raw, raw + n);
}

std::vector<uint8_t> frame_of(const std::vector<uint8_t>& packet) {
  uint8_t frame[tb::kMaxFrame];
  const size_t len = tb::frame_packet(packet.data(), packet.size(), frame, sizeof frame);
  return std::vector<uint8_t>(frame, frame + len);
}

// Records motor writes and watchdog feeds in one log, to check their order.
struct OrderLog : tb::MotorDriver, tb::Watchdog {
  void write(const uint16_t* levels, uint8_t n) override {
    last.assign(levels, levels + n);
    events.push_back('W');
  }
  void feed(uint64_t now_us) override {
    events.push_back('F');
    fed_at.push_back(now_us);
  }
  std::vector<uint16_t> last;
  std::string events;
  std::vector<uint64_t> fed_at;
};

struct Notifier : tb::BleNotifier {
  uint16_t att_mtu() override { return mtu; }
  bool notify(const uint8_t* data, size_t n) override {
    sent.emplace_back(data, data + n);
    return true;
  }
  uint16_t mtu = tb::kDefaultAttMtu;
  std::vector<std::vector<uint8_t>> sent;
};

std::string hex(const std::vector<uint8_t>& v) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (uint8_t b : v) {
    s += d[b >> 4];
    s += d[b & 15];
  }
  return s;
}

}  // namespace

TEST(extension_packets_match_the_vectors) {
  const auto& v = support::vectors_ext();
  CHECK_EQ(v["format"].integer(), 1);
  int n = 0;
  for (const auto& p : v["packets"].arr) {
    const auto packet = packet_of(static_cast<uint8_t>(p["type"].integer()),
                                  static_cast<uint8_t>(p["seq"].integer()), unhex(p["payload"].str));
    if (hex(packet) != p["packet"].str) fprintf(stderr, "  %s\n", p["name"].str.c_str());
    CHECK(hex(packet) == p["packet"].str);
    CHECK(hex(frame_of(packet)) == p["frame"].str);
    ++n;
  }
  CHECK(n >= 5);
}

TEST(extension_exchange_matches_the_vectors_byte_for_byte) {
  const auto& ex = support::vectors_ext()["exchange"];
  tb::Layout layout;
  layout.set_even(static_cast<uint8_t>(ex["tactors"].integer()));
  support::FakeMotors motors;
  tb::Controller c(layout, motors, static_cast<uint16_t>(ex["pwm_steps"].integer()));
  c.begin(0);
  support::FramingSink sink;
  uint64_t now = 0;
  for (const auto& s : ex["steps"].arr) {
    const uint64_t t = static_cast<uint64_t>(s["t_us"].integer());
    while (now + 1000 <= t) {
      now += 1000;
      c.tick(now);
    }
    now = t;
    sink.clear();
    const auto input = unhex(s["input"].str);
    c.receive_bytes(input.data(), input.size(), t, sink);
    if (hex(sink.bytes) != s["output"].str) {
      fprintf(stderr, "  step '%s': got %s\n", s["note"].str.c_str(), hex(sink.bytes).c_str());
    }
    CHECK(hex(sink.bytes) == s["output"].str);
  }
}

TEST(plain_v1_hosts_see_no_extension_frames) {
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  c.begin(0);
  support::FramingSink sink;
  const std::vector<uint8_t> levels(12, 1);
  auto in = frame_of(packet_of(tb::msg::kSetAmplitudes, 0, levels));
  c.receive_bytes(in.data(), in.size(), 1000, sink);
  std::vector<uint8_t> play(14, 0);
  tb::put_u16(&play[4], 1500);
  tb::put_u16(&play[6], 1000);
  tb::put_u16(&play[8], 100);
  in = frame_of(packet_of(tb::msg::kPlayTarget, 1, play));
  c.receive_bytes(in.data(), in.size(), 2000, sink);
  CHECK_EQ(sink.packets.size(), 1u);  // the ACK only
  CHECK_EQ(sink.packets[0][0], tb::msg::kAck);
  // the flags are per connection: a link close clears them
  in = frame_of(packet_of(tb::msg::kSetConfig, 2, {250, 0, 0x30, 0x75, 0, 0, 1}));
  c.receive_bytes(in.data(), in.size(), 3000, sink);
  CHECK_EQ(c.config_flags(), tb::kFlagOnsetEvents);
  c.link_closed(4000);
  CHECK_EQ(c.config_flags(), 0);
}

TEST(info_flags_a_watchdog_reset) {
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  c.set_reset_flags(tb::reset::kWatchdog | tb::reset::kPin);
  c.begin(0);
  support::FramingSink sink;
  auto in = frame_of(packet_of(tb::msg::kGetInfo, 0, {}));
  c.receive_bytes(in.data(), in.size(), 1000, sink);
  CHECK_EQ(sink.packets.back()[0], tb::msg::kInfo);
  CHECK_EQ(sink.packets.back()[2 + 9], tb::kCapPlayTarget | tb::kCapWatchdogReset);
  in = frame_of(packet_of(tb::msg::kGetDiag, 1, {}));
  c.receive_bytes(in.data(), in.size(), 0x1234567890ull, sink);
  const auto& d = sink.packets.back();
  CHECK_EQ(d[0], tb::msg::kDiag);
  CHECK_EQ(d.size(), 4u + tb::kDiagPayload);
  CHECK_EQ(tb::get_u64(&d[2]), 0x1234567890ull);
  CHECK_EQ(d[2 + 8], tb::reset::kWatchdog | tb::reset::kPin);
}

TEST(the_tick_feeds_the_watchdog_after_the_outputs) {
  tb::Layout layout;
  layout.set_even(6);
  OrderLog log;
  tb::Controller c(layout, log, 800);
  c.set_watchdog(&log);
  c.begin(0);
  log.events.clear();
  support::FramingSink sink;
  std::vector<uint8_t> play(14, 0);
  tb::put_u16(&play[0], 4500);
  play[2] = 1;
  tb::put_u16(&play[4], 1500);
  tb::put_u16(&play[6], 1000);
  tb::put_u16(&play[8], 100);
  const auto in = frame_of(packet_of(tb::msg::kPlayTarget, 0, play));
  c.receive_bytes(in.data(), in.size(), 0, sink);
  CHECK(log.events == "W");  // requests write the outputs but never feed
  for (uint64_t t = 1000; t <= 5000; t += 1000) c.tick(t);
  // every tick ends in a feed, and a write within a tick comes before it
  CHECK_EQ(log.fed_at.size(), 5u);
  CHECK_EQ(log.events.back(), 'F');
  CHECK(log.events.find("FW") != std::string::npos || log.events.find("WF") != std::string::npos);
  for (size_t i = 0; i + 1 < log.events.size(); ++i) {
    if (log.events[i] == 'W') CHECK_EQ(log.events[i + 1] == 'W', false);
  }
}

TEST(watchdog_model_expires_without_feeds) {
  tb::WatchdogModel wd(300);
  CHECK(!wd.expired(1000000));  // not started
  wd.start(1000);
  CHECK(!wd.expired(300999));
  CHECK(wd.expired(301000));
  wd.feed(300000);
  CHECK(!wd.expired(599999));
  CHECK(wd.expired(600000));
  // a controller that ticks keeps it alive; one that stops does not
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  tb::WatchdogModel model(300);
  c.set_watchdog(&model);
  c.begin(0);
  model.start(0);
  uint64_t t = 0;
  for (; t < 2000000; t += 1000) {
    c.tick(t);
    CHECK(!model.expired(t));
  }
  const uint64_t last_tick = t - 1000;
  CHECK(!model.expired(last_tick + 299999));
  CHECK(model.expired(last_tick + 300000));
}

TEST(serial_tx_keeps_whole_frames_and_counts_drops) {
  tb::Counters counters;
  tb::SerialTx tx(counters);
  const auto status = packet_of(tb::msg::kStatus, 1, std::vector<uint8_t>(21, 7));
  const auto frame = frame_of(status);
  size_t fitted = 0;
  while (tx.room() >= frame.size()) {
    tx.send(status.data(), status.size());
    ++fitted;
  }
  CHECK_EQ(fitted, tb::kSerialTxCapacity / frame.size());
  CHECK_EQ(counters.tx_dropped, 0);
  const size_t queued = tx.queued();
  tx.send(status.data(), status.size());  // does not fit: dropped whole, counted
  CHECK_EQ(tx.queued(), queued);
  CHECK_EQ(counters.tx_dropped, 1);
  // drain in odd pieces (what send_nb or write accepts) across the ring's wrap
  std::vector<uint8_t> out;
  for (int round = 0; round < 50; ++round) {
    const uint8_t* data = nullptr;
    size_t n = tx.peek(&data);
    if (n > 7) n = 7;
    out.insert(out.end(), data, data + n);
    tx.consume(n);
    if (tx.room() >= frame.size()) tx.send(status.data(), status.size());
  }
  while (tx.queued() > 0) {
    const uint8_t* data = nullptr;
    const size_t n = tx.peek(&data);
    out.insert(out.end(), data, data + n);
    tx.consume(n);
  }
  tb::FrameDecoder dec;
  tb::Packet p;
  int packets = 0;
  for (uint8_t b : out) {
    const auto r = dec.feed(b, &p);
    CHECK(r == tb::FeedResult::kNone || r == tb::FeedResult::kPacket);
    if (r == tb::FeedResult::kPacket) ++packets;
  }
  CHECK(packets > static_cast<int>(fitted));
  // a closed port queues nothing and counts nothing
  tx.set_open(false);
  tx.send(status.data(), status.size());
  CHECK_EQ(tx.queued(), 0u);
  CHECK_EQ(counters.tx_dropped, 1);
}

TEST(ble_replies_fit_the_mtu_or_are_refused_or_framed) {
  const auto& b = support::vectors_ext()["ble"];
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  c.begin(0);
  Notifier notifier;
  tb::BleTx ble(notifier, c, c.link_counters());
  const auto request = unhex(b["request"].str);
  auto expect = [&](const char* key) {
    const auto& want = b[key].arr;
    CHECK_EQ(notifier.sent.size(), want.size());
    for (size_t i = 0; i < want.size() && i < notifier.sent.size(); ++i) {
      CHECK(hex(notifier.sent[i]) == want[i].str);
      CHECK(notifier.sent[i].size() <= static_cast<size_t>(notifier.mtu) - 3u);
    }
    notifier.sent.clear();
  };
  c.receive_packet(request.data(), request.size(), 1000, ble);  // MTU 23: 26 bytes do not fit
  expect("mtu_23_unframed");
  CHECK_EQ(c.counters().ble_refused, 1);
  notifier.mtu = 33;
  c.receive_packet(request.data(), request.size(), 2000, ble);
  expect("mtu_33_unframed");
  CHECK_EQ(c.counters().ble_refused, 1);
  // framed replies (SET_CONFIG flag): the ACK already comes framed, then INFO in chunks
  notifier.mtu = 23;
  const auto cfg = packet_of(tb::msg::kSetConfig, 2, {250, 0, 0x30, 0x75, 0, 0, tb::kFlagBleFramed});
  c.receive_packet(cfg.data(), cfg.size(), 3000, ble);
  CHECK_EQ(notifier.sent.size(), 1u);
  CHECK(notifier.sent[0] == frame_of(packet_of(tb::msg::kAck, 2, {2, 0})));
  notifier.sent.clear();
  c.receive_packet(request.data(), request.size(), 4000, ble);
  expect("mtu_23_framed");
  // joined and split at 0x00 they are the INFO packet
  std::vector<uint8_t> stream;
  for (const auto& chunk : b["mtu_23_framed"].arr) {
    const auto bytes = unhex(chunk.str);
    stream.insert(stream.end(), bytes.begin(), bytes.end());
  }
  tb::FrameDecoder dec;
  tb::Packet p;
  tb::FeedResult r = tb::FeedResult::kNone;
  for (uint8_t x : stream) r = dec.feed(x, &p);
  CHECK(r == tb::FeedResult::kPacket);
  CHECK(hex(packet_of(p.type, p.seq, std::vector<uint8_t>(p.payload, p.payload + p.len))) ==
        b["info_packet"].str);
}

// --- PWM start/stop against a fake register block ---------------------------------

namespace {

// A register that logs every access, and a PWM model behind it: STOP raises
// EVENTS_STOPPED only after `stop_latency` reads of it (the end of the PWM period).
struct FakePwm;
struct Reg {
  FakePwm* pwm = nullptr;
  const char* name = "";
  uint32_t value = 0;
  Reg& operator=(uint32_t v);
  operator uint32_t();
};

struct FakePwm {
  FakePwm() {
    ENABLE = {this, "ENABLE"};
    TASKS_STOP = {this, "STOP"};
    TASKS_SEQSTART[0] = {this, "SEQSTART0"};
    TASKS_SEQSTART[1] = {this, "SEQSTART1"};
    EVENTS_STOPPED = {this, "STOPPED"};
    EVENTS_SEQEND[0] = {this, "SEQEND0"};
    EVENTS_SEQEND[1] = {this, "SEQEND1"};
  }
  Reg ENABLE, TASKS_STOP, TASKS_SEQSTART[2], EVENTS_STOPPED, EVENTS_SEQEND[2];
  std::vector<std::string> log;
  int stop_latency = 3;    // reads of EVENTS_STOPPED before it is set
  int reads_since_stop = -1;
  bool generating = false;
  bool start_while_stopping = false;  // SEQSTART between STOP and EVENTS_STOPPED

  void on_write(Reg& r, uint32_t v) {
    log.push_back(std::string(r.name) + "=" + std::to_string(v));
    if (&r == &TASKS_STOP && v == 1) reads_since_stop = 0;
    if (&r == &TASKS_SEQSTART[0] && v == 1) {
      if (reads_since_stop >= 0) start_while_stopping = true;
      generating = ENABLE.value == 1;
    }
    if (&r == &ENABLE && v == 0) generating = false;
  }
  void on_read(Reg& r) {
    log.push_back(std::string(r.name) + "?");
    if (&r == &EVENTS_STOPPED && reads_since_stop >= 0 && ++reads_since_stop >= stop_latency) {
      r.value = 1;
      reads_since_stop = -1;
      generating = false;
    }
  }
};

Reg& Reg::operator=(uint32_t v) {
  value = v;
  pwm->on_write(*this, v);
  return *this;
}
Reg::operator uint32_t() {
  pwm->on_read(*this);
  return value;
}

uint32_t g_fake_us = 0;
uint32_t fake_micros() { return g_fake_us += 10; }

}  // namespace

TEST(pwm_stop_waits_for_stopped_before_the_next_start) {
  FakePwm regs;
  tb::PwmSequencer<FakePwm> seq(&regs, fake_micros);
  seq.start();
  CHECK(regs.generating);
  CHECK(regs.log == std::vector<std::string>({"ENABLE=1", "SEQEND0=0", "SEQSTART0=1"}));
  regs.log.clear();
  seq.start();  // new values while running: restart, no re-enable
  CHECK(regs.log == std::vector<std::string>({"SEQEND0=0", "SEQSTART0=1"}));
  regs.log.clear();
  seq.stop();
  // clear the event, STOP, poll until STOPPED, clear it, disable
  CHECK(regs.log == std::vector<std::string>({"STOPPED=0", "STOP=1", "STOPPED?", "STOPPED?",
                                              "STOPPED?", "STOPPED=0", "ENABLE=0"}));
  CHECK(!regs.generating);
  CHECK(!seq.running());
  CHECK_EQ(regs.ENABLE.value, 0u);
  seq.start();
  CHECK(!regs.start_while_stopping);
  CHECK(regs.generating);
  CHECK_EQ(seq.stop_timeouts(), 0u);
}

TEST(pwm_stop_is_bounded_when_stopped_never_comes) {
  FakePwm regs;
  regs.stop_latency = 1000000;
  tb::PwmSequencer<FakePwm> seq(&regs, fake_micros);
  seq.start();
  const uint32_t t0 = g_fake_us;
  seq.stop();
  CHECK(g_fake_us - t0 <= tb::PwmSequencer<FakePwm>::kStopTimeoutUs + 30);
  CHECK_EQ(seq.stop_timeouts(), 1u);
  CHECK_EQ(regs.ENABLE.value, 0u);  // disabled anyway: pins back to GPIO, low
  CHECK(!regs.generating);
}

TEST(pwm_stop_when_idle_only_disables) {
  FakePwm regs;
  tb::PwmSequencer<FakePwm> seq(&regs, fake_micros);
  seq.stop();
  CHECK(regs.log == std::vector<std::string>({"ENABLE=0"}));
}

TEST(level_to_duty_rounds_and_caps_below_the_top) {
  CHECK_EQ(tb::level_to_duty(0, 800), 0);
  CHECK_EQ(tb::level_to_duty(65535, 800), 799);
  CHECK_EQ(tb::level_to_duty(32768, 800), 400);
  CHECK_EQ(tb::level_to_duty(41, 800), 1);  // 0.5005 steps rounds up
  CHECK_EQ(tb::level_to_duty(40, 800), 0);
}

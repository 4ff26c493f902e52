// SENSE_START / SENSE_STOP / SENSE_DATA (firmware 1.2): the scripted session of
// vectors_ext.json byte for byte, the timing rule (every sample read within half a period
// of its stamp), the serial link's reserve for replies, losses, link close; and the
// emulator's ERM model and IMU against tactorbelt.devices.erm.
#include <math.h>
#include <string.h>

#include <string>
#include <vector>

#include "../emulator/erm_model.h"
#include "../tactorbelt/src/core/controller.h"
#include "../tactorbelt/src/core/links.h"
#include "minitest.h"
#include "support.h"

using json::unhex;

namespace {

std::vector<uint8_t> frame_of(uint8_t type, uint8_t seq, const std::vector<uint8_t>& payload) {
  uint8_t raw[tb::kMaxPacket];
  const size_t n = tb::build_packet(type, seq, payload.data(), payload.size(), raw);
  uint8_t frame[tb::kMaxFrame];
  const size_t len = tb::frame_packet(raw, n, frame, sizeof frame);
  return std::vector<uint8_t>(frame, frame + len);
}

std::vector<uint8_t> sense_start_payload(uint16_t rate_hz, uint32_t duration_ms, uint8_t tactor) {
  std::vector<uint8_t> p(7);
  tb::put_u16(&p[0], rate_hz);
  tb::put_u32(&p[2], duration_ms);
  p[6] = tactor;
  return p;
}

std::string hex(const std::vector<uint8_t>& v) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (uint8_t b : v) {
    s += d[b >> 4];
    s += d[b & 15];
  }
  return s;
}

// The exchange's accelerometer: reads a function of the stamp, and records when it was
// read (the poll's time) against the stamp it was given.
struct FakeAccelerometer : tb::Accelerometer {
  bool ready() const override { return ok; }
  uint16_t min_period_us() const override { return period; }
  uint16_t full_scale_mg() const override { return 8000; }
  void begin_sensing(uint8_t t) override {
    tactor = t;
    ++sessions;
  }
  void end_sensing() override { ++ended; }
  bool read(uint64_t stamp_us, int16_t xyz[3]) override {
    stamps.push_back(stamp_us);
    reads_at.push_back(now);
    if (fail_next) {
      fail_next = false;
      return false;
    }
    const uint64_t k = stamp_us / 1000;
    xyz[0] = static_cast<int16_t>(k & 0x3FFF);
    xyz[1] = static_cast<int16_t>(-static_cast<int32_t>(k & 0x3FFF));
    xyz[2] = static_cast<int16_t>(4096 + (k & 0xF));
    return true;
  }
  bool ok = true;
  bool fail_next = false;
  uint16_t period = 1000;
  uint8_t tactor = 0;
  int sessions = 0;
  int ended = 0;
  uint64_t now = 0;
  std::vector<uint64_t> stamps;
  std::vector<uint64_t> reads_at;
};

struct Batch {
  uint8_t session, flags;
  uint32_t index;
  uint64_t t0;
  uint16_t period, full_scale;
  size_t n;
  std::vector<int16_t> values;
};

std::vector<Batch> batches_of(const std::vector<std::vector<uint8_t>>& packets) {
  std::vector<Batch> out;
  for (const auto& p : packets) {
    if (p[0] != tb::msg::kSenseData) continue;
    const uint8_t* q = p.data() + 2;
    Batch b;
    b.session = q[0];
    b.flags = q[1];
    b.index = tb::get_u32(q + 2);
    b.t0 = tb::get_u64(q + 6);
    b.period = tb::get_u16(q + 14);
    b.full_scale = tb::get_u16(q + 16);
    const size_t payload = p.size() - 4;
    b.n = (payload - tb::kSenseDataHeader) / 6;
    for (size_t i = 0; i < 3 * b.n; ++i) {
      b.values.push_back(static_cast<int16_t>(tb::get_u16(q + tb::kSenseDataHeader + 2 * i)));
    }
    out.push_back(b);
  }
  return out;
}

}  // namespace

TEST(sense_exchange_matches_the_vectors_byte_for_byte) {
  const auto& ex = support::vectors_ext()["sense"];
  tb::Layout layout;
  layout.set_even(static_cast<uint8_t>(ex["tactors"].integer()));
  support::FakeMotors motors;
  tb::Controller c(layout, motors, static_cast<uint16_t>(ex["pwm_steps"].integer()));
  FakeAccelerometer acc;
  acc.period = static_cast<uint16_t>(ex["accelerometer"]["min_period_us"].integer());
  c.set_accelerometer(&acc);
  c.begin(0);
  support::FramingSink sink;
  uint64_t now = 0;
  int steps = 0;
  for (const auto& s : ex["steps"].arr) {
    const uint64_t t = static_cast<uint64_t>(s["t_us"].integer());
    sink.clear();
    while (now + 1000 <= t) {
      now += 1000;
      acc.now = now;
      c.tick(now);
      c.poll_sense(now);
    }
    now = t;
    acc.now = t;
    const auto input = unhex(s["input"].str);
    c.receive_bytes(input.data(), input.size(), t, sink);
    c.poll_sense(t);
    if (hex(sink.bytes) != s["output"].str) {
      fprintf(stderr, "  step '%s':\n   got  %s\n   want %s\n", s["note"].str.c_str(),
              hex(sink.bytes).c_str(), s["output"].str.c_str());
    }
    CHECK(hex(sink.bytes) == s["output"].str);
    ++steps;
  }
  CHECK(steps >= 10);
  CHECK_EQ(acc.tactor, 1);  // the last session was for tactor 1
  CHECK_EQ(acc.sessions, acc.ended);
}

TEST(every_sample_is_read_within_half_a_period_of_its_stamp) {
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  FakeAccelerometer acc;
  acc.period = 625;
  c.set_accelerometer(&acc);
  c.begin(0);
  support::FramingSink sink;
  const auto start = frame_of(tb::msg::kSenseStart, 1, sense_start_payload(0, 500, 0xFF));
  c.receive_bytes(start.data(), start.size(), 1000, sink);
  CHECK_EQ(sink.packets.size(), 1u);
  CHECK_EQ(sink.packets[0][0], tb::msg::kAck);
  // polls at irregular times: mostly every 100-300 us, now and then a long pass
  uint64_t t = 1000;
  uint32_t x = 12345;
  while (t < 520000) {
    x = x * 1103515245u + 12345u;
    const uint32_t r = (x >> 16) % 1000;
    t += r < 20 ? 2000 + r * 50 : 100 + r % 200;
    acc.now = t;
    c.poll_sense(t);
  }
  CHECK(!c.sense().active());
  const auto batches = batches_of(sink.packets);
  CHECK(batches.size() > 50);
  // the stamps the sensor was given: each between read time - period/2 and read time
  for (size_t i = 0; i < acc.stamps.size(); ++i) {
    CHECK(acc.stamps[i] <= acc.reads_at[i]);
    CHECK(acc.reads_at[i] - acc.stamps[i] <= 312u);
  }
  // the batches: exact times t0 + i * period, consecutive indices, every sample sent once
  uint32_t next_index = 0;
  size_t k = 0;
  int reanchored = 0;
  for (size_t b = 0; b < batches.size(); ++b) {
    const Batch& batch = batches[b];
    CHECK_EQ(batch.session, 1);
    CHECK_EQ(batch.period, 625);
    CHECK_EQ(batch.full_scale, 8000);
    CHECK_EQ(batch.index, next_index);
    CHECK_EQ((batch.flags & tb::sense_flag::kLast) != 0, b + 1 == batches.size());
    for (size_t i = 0; i < batch.n; ++i, ++k) {
      CHECK_EQ(batch.t0 + 625u * i, acc.stamps[k]);
      CHECK_EQ(batch.values[3 * i], static_cast<int16_t>((acc.stamps[k] / 1000) & 0x3FFF));
    }
    if (b > 0 && batch.t0 != batches[b - 1].t0 + 625u * batches[b - 1].n) ++reanchored;
    next_index += static_cast<uint32_t>(batch.n);
  }
  CHECK_EQ(k, acc.stamps.size());
  CHECK(reanchored > 0);  // the long passes started new batches
  // 500 ms from 1000: nothing stamped at or after the end
  CHECK(acc.stamps.back() < 501000u);
  CHECK(acc.stamps.size() > 600u);  // of 800: the long passes skip slots
}

TEST(a_model_that_reads_the_past_catches_up_on_late_polls) {
  // the emulator's IMU (reads_past): a poll that comes late reads the slots it missed at
  // their own stamps, a batch at most per poll, so a loaded host loses no sample
  struct PastReader : FakeAccelerometer {
    bool reads_past() const override { return true; }
  };
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  PastReader acc;
  acc.period = 625;
  c.set_accelerometer(&acc);
  c.begin(0);
  support::FramingSink sink;
  const auto start = frame_of(tb::msg::kSenseStart, 2, sense_start_payload(0, 100, 0xFF));
  c.receive_bytes(start.data(), start.size(), 0, sink);
  for (uint64_t t = 0; t <= 200000; t += (t % 3 == 0 ? 7000 : 400)) {
    acc.now = t;
    c.poll_sense(t);
    while (c.next_sense_us() <= t) c.poll_sense(t);  // as the emulator's loop does
  }
  CHECK(!c.sense().active());
  CHECK_EQ(acc.stamps.size(), 160u);  // 100 ms at 625 us
  for (size_t i = 0; i < acc.stamps.size(); ++i) CHECK_EQ(acc.stamps[i], 625u * i);
  const auto batches = batches_of(sink.packets);
  uint64_t next_t = 0;
  uint32_t next_index = 0;
  for (const auto& b : batches) {
    CHECK_EQ(b.t0, next_t);  // one grid from start to end
    CHECK_EQ(b.index, next_index);
    next_t = b.t0 + 625u * b.n;
    next_index += static_cast<uint32_t>(b.n);
  }
  CHECK_EQ(next_index, 160u);
}

TEST(a_slow_serial_host_still_gets_its_replies_and_sees_the_losses) {
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  FakeAccelerometer acc;
  c.set_accelerometer(&acc);
  c.begin(0);
  tb::SerialTx tx(c.link_counters());
  const auto start = frame_of(tb::msg::kSenseStart, 3, sense_start_payload(0, 1000, 0xFF));
  c.receive_bytes(start.data(), start.size(), 0, tx);
  // the host reads nothing for 200 ms: the ring fills up to its reserve, the stream's
  // own queue fills, and the oldest batches are lost
  for (uint64_t t = 0; t <= 200000; t += 1000) c.poll_sense(t);
  CHECK(tx.room() >= tb::kSerialReplyReserve);
  CHECK_EQ(c.counters().tx_dropped, 0);
  const auto status = frame_of(tb::msg::kGetStatus, 4, {});
  c.receive_bytes(status.data(), status.size(), 200000, tx);
  CHECK_EQ(c.counters().tx_dropped, 0);  // the reply found room
  // now the host reads everything
  std::vector<uint8_t> bytes;
  auto drain = [&] {
    while (tx.queued() > 0) {
      const uint8_t* d = nullptr;
      const size_t n = tx.peek(&d);
      bytes.insert(bytes.end(), d, d + n);
      tx.consume(n);
    }
  };
  for (uint64_t t = 201000; t <= 1100000; t += 1000) {
    drain();
    c.poll_sense(t);
  }
  drain();
  tb::FrameDecoder dec;
  tb::Packet p;
  std::vector<std::vector<uint8_t>> packets;
  bool status_seen = false;
  for (uint8_t b : bytes) {
    if (dec.feed(b, &p) != tb::FeedResult::kPacket) continue;
    std::vector<uint8_t> raw{p.type, p.seq};
    raw.insert(raw.end(), p.payload, p.payload + p.len);
    raw.push_back(0);
    raw.push_back(0);
    packets.push_back(raw);
    if (p.type == tb::msg::kStatus) status_seen = true;
  }
  CHECK(status_seen);
  const auto batches = batches_of(packets);
  // indices: one gap (the lost batches), flagged on the batch after it; the rest whole
  int gaps = 0;
  uint32_t next = 0;
  for (const auto& b : batches) {
    if (b.index != next) {
      ++gaps;
      CHECK(b.index > next);
      CHECK((b.flags & tb::sense_flag::kDropped) != 0);
    }
    next = b.index + static_cast<uint32_t>(b.n);
  }
  CHECK_EQ(gaps, 1);
  CHECK((batches.back().flags & tb::sense_flag::kLast) != 0);
  CHECK_EQ(next, 1000u);  // 1000 samples of 1000 us in 1 s, lost ones counted
}

TEST(a_failed_read_is_a_lost_sample) {
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  FakeAccelerometer acc;
  c.set_accelerometer(&acc);
  c.begin(0);
  support::FramingSink sink;
  const auto start = frame_of(tb::msg::kSenseStart, 0, sense_start_payload(0, 10, 0xFF));
  c.receive_bytes(start.data(), start.size(), 0, sink);
  for (uint64_t t = 0; t <= 12000; t += 1000) {
    acc.fail_next = t == 3000;
    c.poll_sense(t);
  }
  const auto b = batches_of(sink.packets);
  CHECK_EQ(b.size(), 2u);
  CHECK_EQ(b[0].n, 3u);  // 0, 1000, 2000
  CHECK_EQ(b[1].index, 4u);  // 3000 lost
  CHECK_EQ(b[1].t0, 4000u);
  CHECK_EQ(b[1].n, 6u);
  CHECK_EQ(b[1].flags, tb::sense_flag::kDropped | tb::sense_flag::kLast);
}

TEST(sensing_needs_a_started_imu_and_ends_with_the_link) {
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors motors;
  tb::Controller c(layout, motors, 800);
  FakeAccelerometer acc;
  acc.ok = false;
  c.set_accelerometer(&acc);
  c.begin(0);
  support::FramingSink sink;
  auto in = frame_of(tb::msg::kGetInfo, 0, {});
  c.receive_bytes(in.data(), in.size(), 0, sink);
  CHECK_EQ(sink.packets.back()[2 + 9], tb::kCapPlayTarget);  // no kCapSense
  in = frame_of(tb::msg::kSenseStart, 1, sense_start_payload(0, 1000, 0xFF));
  c.receive_bytes(in.data(), in.size(), 0, sink);
  CHECK_EQ(sink.packets.back()[0], tb::msg::kNak);
  CHECK_EQ(sink.packets.back()[3], tb::nak::kUnavailable);
  acc.ok = true;
  in = frame_of(tb::msg::kGetInfo, 2, {});
  c.receive_bytes(in.data(), in.size(), 0, sink);
  CHECK_EQ(sink.packets.back()[2 + 9], tb::kCapPlayTarget | tb::kCapSense);
  in = frame_of(tb::msg::kSenseStart, 3, sense_start_payload(0, 1000, 0xFF));
  c.receive_bytes(in.data(), in.size(), 0, sink);
  CHECK_EQ(sink.packets.back()[0], tb::msg::kAck);
  for (uint64_t t = 0; t <= 3000; t += 1000) c.poll_sense(t);
  CHECK(c.sense().active());
  c.link_closed(3500);  // the port closed: sensing ends, nothing more is sent
  CHECK(!c.sense().active());
  CHECK_EQ(acc.ended, 1);
  sink.clear();
  for (uint64_t t = 4000; t <= 20000; t += 1000) c.poll_sense(t);
  CHECK_EQ(sink.packets.size(), 0u);
  CHECK_EQ(c.next_sense_us(), UINT64_MAX);
}

TEST(erm_model_matches_tactorbelt_devices_erm) {
  const auto& v = support::vectors_ext()["erm"];
  emu::ErmParams params;
  params.rise_tau_s = v["params"]["rise_tau_s"].number();
  params.fall_tau_s = v["params"]["fall_tau_s"].number();
  params.start_level = v["params"]["start_level"].number();
  params.amplitude_exponent = v["params"]["amplitude_exponent"].number();
  emu::ErmBank bank(2, params);
  double worst = 0.0;
  int n = 0;
  for (const auto& s : v["steps"].arr) {
    const uint64_t t = static_cast<uint64_t>(s["t_us"].integer());
    uint16_t levels[2];
    for (int k = 0; k < 2; ++k) levels[k] = static_cast<uint16_t>(s["levels"].arr[k].integer());
    bank.advance(t);
    for (uint8_t k = 0; k < 2; ++k) {
      const double ds = fabs(bank.speed(k) - s["speed"].arr[k].number());
      const double da = fabs(bank.amplitude(k) - s["amplitude"].arr[k].number());
      if (ds > worst) worst = ds;
      if (da > worst) worst = da;
    }
    bank.set_levels(t, levels, 2);
    ++n;
  }
  CHECK(n > 500);
  CHECK(worst < 2e-9);  // the vectors carry 9 decimals
}

TEST(the_simulated_imu_rises_like_the_erm_model) {
  // Full drive from rest on tactor 2: the envelope |(x, y + 1 g)| rises from 10 % to 90 %
  // of its steady value in tau * (ln(1 - sqrt(0.1)) - ln(1 - sqrt(0.9))), amplitude being
  // speed squared.
  emu::ErmBank bank(6);
  emu::SimImu imu(bank, 625);
  imu.begin_sensing(2);
  const uint16_t off[6] = {0, 0, 0, 0, 0, 0};
  const uint16_t on[6] = {0, 0, 65535, 0, 0, 0};
  bank.set_levels(0, off, 6);
  bank.set_levels(10000, on, 6);
  std::vector<double> t_s;
  std::vector<double> env;
  for (uint64_t t = 0; t < 600000; t += 625) {
    int16_t xyz[3];
    CHECK(imu.read(t, xyz));
    const double g = 8.0 / 32768.0;
    const double x = xyz[0] * g;
    const double y = xyz[1] * g + 1.0;
    t_s.push_back(static_cast<double>(t) * 1e-6);
    env.push_back(sqrt(x * x + y * y));
  }
  // a centred moving mean over 8 samples (5 ms), so that noise does not decide a crossing
  std::vector<double> raw = env;
  for (size_t i = 0; i < env.size(); ++i) {
    double sum = 0.0;
    int k = 0;
    for (size_t j = i < 4 ? 0 : i - 4; j < i + 4 && j < raw.size(); ++j, ++k) sum += raw[j];
    env[i] = sum / k;
  }
  const double steady = env[env.size() - 10];
  CHECK(fabs(steady - emu::SimImu::kRatedAccelG) < 0.05);
  auto crossing = [&](double level) {
    for (size_t i = 1; i < env.size(); ++i) {
      if (env[i] >= level * steady) {
        const double f = (level * steady - env[i - 1]) / (env[i] - env[i - 1]);
        return t_s[i - 1] + f * (t_s[i] - t_s[i - 1]);
      }
    }
    return -1.0;
  };
  const double tau = 0.040;
  const double want = tau * (log(1.0 - sqrt(0.1)) - log(1.0 - sqrt(0.9)));
  const double rise = crossing(0.9) - crossing(0.1);
  CHECK(fabs(rise - want) < 0.02 * want);
  // the 10 % point: -tau ln(1 - sqrt(0.1)) after the drive started
  CHECK(fabs(crossing(0.1) - 0.010 + tau * log(1.0 - sqrt(0.1))) < 0.001);
  // each axis is a sinusoid at the motor's frequency: 200 Hz at full speed, so 200 sign
  // changes of x in 0.5 s
  int sign_changes = 0;
  int16_t last[3];
  imu.read(600000, last);
  for (uint64_t t = 600625; t <= 1100000; t += 625) {
    int16_t a[3];
    imu.read(t, a);
    if ((a[0] < 0) != (last[0] < 0)) ++sign_changes;
    last[0] = a[0];
  }
  CHECK(sign_changes >= 198 && sign_changes <= 202);
}

// Drive shaping (firmware 1.3): SET_DRIVE, the capability bits, shaped rises and falls on
// the emulator's motor model, both bridge inputs low in every failsafe, and random command
// sequences that try to hold overdrive or reverse drive past their bounds.
#include <math.h>
#include <string.h>

#include <vector>

#include "../emulator/erm_model.h"
#include "../tactorbelt/src/core/controller.h"
#include "minitest.h"
#include "support.h"

namespace {

// The motors as the emulator has them: the bridge inputs drive the ERM model.
class BankMotors : public tb::MotorDriver {
 public:
  BankMotors(emu::ErmBank& bank, const uint64_t& now) : bank_(bank), now_(now) {}
  void write(const uint16_t* levels, uint8_t n) override {
    bank_.set_levels(now_, levels, n);
    last.assign(levels, levels + n);
  }
  void write_in2(uint32_t mask, uint8_t n) override {
    (void)n;
    bank_.set_in2(now_, mask);
    in2 = mask;
  }
  std::vector<uint16_t> last = std::vector<uint16_t>(6, 0);
  uint32_t in2 = 0;

 private:
  emu::ErmBank& bank_;
  const uint64_t& now_;
};

struct Rig {
  explicit Rig(bool can_brake = true, uint8_t n = 6)
      : bank(n), motors(bank, now_us), controller(layout, motors, 800) {
    layout.set_even(n);
    controller.set_drive_shaping(can_brake);
    controller.set_heartbeat_ms(2000);
    controller.begin(0);
  }
  void send(uint8_t type, const std::vector<uint8_t>& payload = {}) {
    uint8_t packet[tb::kMaxPacket];
    const size_t n = tb::build_packet(type, seq++, payload.data(), payload.size(), packet);
    uint8_t frame[tb::kMaxFrame];
    const size_t len = tb::frame_packet(packet, n, frame, sizeof frame);
    controller.receive_bytes(frame, len, now_us, sink);
  }
  void levels(uint16_t v0, uint16_t rest = 0) {
    std::vector<uint8_t> p;
    for (uint8_t k = 0; k < controller.channels(); ++k) {
      const uint16_t v = k == 0 ? v0 : rest;
      p.push_back(static_cast<uint8_t>(v));
      p.push_back(static_cast<uint8_t>(v >> 8));
    }
    send(tb::msg::kSetAmplitudes, p);
  }
  // SET_DRIVE mode [, tactor, start, rated, rise, fall, brake] (taus in 100 us).
  void drive(uint8_t mode) { send(tb::msg::kSetDrive, {mode}); }
  void drive(uint8_t mode, uint8_t tactor, uint16_t start, uint16_t rated, uint16_t rise,
             uint16_t fall, uint16_t brake) {
    std::vector<uint8_t> p(12);
    p[0] = mode;
    p[1] = tactor;
    tb::put_u16(&p[2], start);
    tb::put_u16(&p[4], rated);
    tb::put_u16(&p[6], rise);
    tb::put_u16(&p[8], fall);
    tb::put_u16(&p[10], brake);
    send(tb::msg::kSetDrive, p);
  }
  void tick_ms(int ms) {
    for (int i = 0; i < ms; ++i) {
      now_us += 1000;
      controller.tick(now_us);
    }
  }
  uint8_t last_type() const { return sink.packets.empty() ? 0 : sink.packets.back()[0]; }
  uint8_t last_code() const { return sink.packets.back()[3]; }

  // 10-90 % (or 90-10 %) of tactor 0's amplitude, in ms, ticking from now until it is
  // within 1 % of `to` (the steady amplitude of the new level) or `limit_ms` passed.
  double transition_ms(double from, double to, int limit_ms) {
    const double lo = from + 0.1 * (to - from);
    const double hi = from + 0.9 * (to - from);
    const uint64_t t0 = now_us;
    double t10 = -1.0;
    double t90 = -1.0;
    for (int i = 0; i < limit_ms * 10; ++i) {  // the model read every 0.1 ms
      if (i % 10 == 0 && i > 0) controller.tick(now_us);
      bank.advance(now_us);
      const double a = bank.amplitude(0);
      const bool past_lo = to > from ? a >= lo : a <= lo;
      const bool past_hi = to > from ? a >= hi : a <= hi;
      if (past_lo && t10 < 0.0) t10 = static_cast<double>(now_us - t0) * 1e-3;
      if (past_hi && t90 < 0.0) t90 = static_cast<double>(now_us - t0) * 1e-3;
      now_us += 100;
    }
    // tick on to a whole millisecond
    while (now_us % 1000 != 0) now_us += 100;
    return t10 >= 0.0 && t90 >= 0.0 ? t90 - t10 : 1e9;
  }

  uint64_t now_us = 0;
  tb::Layout layout;
  emu::ErmBank bank;
  BankMotors motors;
  tb::Controller controller;
  support::FramingSink sink;
  uint8_t seq = 0;
};

constexpr uint16_t kHalf = 32768;

}  // namespace

TEST(set_drive_is_unknown_unless_the_build_shapes_and_info_reports_the_wiring) {
  // a controller without set_drive_shaping answers as firmware 1.2
  tb::Layout layout;
  layout.set_even(6);
  support::FakeMotors fake;
  tb::Controller plain(layout, fake, 800);
  plain.begin(0);
  support::FramingSink sink;
  uint8_t packet[tb::kMaxPacket];
  const uint8_t mode = tb::kDriveShaped;
  size_t n = tb::build_packet(tb::msg::kSetDrive, 1, &mode, 1, packet);
  plain.receive_packet(packet, n, 0, sink);
  CHECK_EQ(sink.packets.back()[0], tb::msg::kNak);
  CHECK_EQ(sink.packets.back()[3], tb::nak::kUnknownType);
  n = tb::build_packet(tb::msg::kGetInfo, 2, nullptr, 0, packet);
  plain.receive_packet(packet, n, 0, sink);
  CHECK_EQ(sink.packets.back()[2 + 9], tb::kCapPlayTarget);

  for (int brake = 0; brake < 2; ++brake) {
    Rig rig(brake != 0);
    rig.send(tb::msg::kGetInfo);
    const uint8_t caps = rig.sink.packets.back()[2 + 9];
    CHECK_EQ(caps & (tb::kCapShape | tb::kCapBrake),
             brake != 0 ? tb::kCapShape | tb::kCapBrake : tb::kCapShape);
    rig.drive(tb::kDriveShaped);
    CHECK_EQ(rig.last_type(), tb::msg::kAck);
    CHECK_EQ(rig.controller.drive_mode(), tb::kDriveShaped);
    // bad values: nothing applies
    rig.drive(0x04);
    CHECK_EQ(rig.last_code(), tb::nak::kOutOfRange);
    rig.drive(0, 6, 0, 65535, 400, 500, 400);  // no tactor 6
    CHECK_EQ(rig.last_code(), tb::nak::kOutOfRange);
    rig.drive(0, 0, 100, 100, 400, 500, 400);  // start not below rated
    CHECK_EQ(rig.last_code(), tb::nak::kOutOfRange);
    rig.drive(0, 0, 0, 65535, 9, 500, 400);  // a tau below 1 ms
    CHECK_EQ(rig.last_code(), tb::nak::kOutOfRange);
    rig.send(tb::msg::kSetDrive, {1, 2});
    CHECK_EQ(rig.last_code(), tb::nak::kBadLength);
    CHECK_EQ(rig.controller.drive_mode(), tb::kDriveShaped);
    CHECK_NEAR(rig.controller.drive_params(0).rise_tau_s, 0.040f, 1e-6f);
    rig.drive(tb::kDriveShaped, 2, 1000, 50000, 300, 600, 200);
    CHECK_EQ(rig.last_type(), tb::msg::kAck);
    CHECK_NEAR(rig.controller.drive_params(2).rise_tau_s, 0.030f, 1e-6f);
    CHECK_NEAR(rig.controller.drive_params(2).rated, 50000.0f / 65535.0f, 1e-6f);
    CHECK_NEAR(rig.controller.drive_params(1).rise_tau_s, 0.040f, 1e-6f);
    // a link close returns to the plain drive and the power-up constants
    rig.controller.link_closed(rig.now_us);
    CHECK_EQ(rig.controller.drive_mode(), 0);
    CHECK_NEAR(rig.controller.drive_params(2).rise_tau_s, 0.040f, 1e-6f);
  }
}

TEST(plain_drive_is_the_levels_with_in2_low) {
  Rig rig;
  rig.levels(kHalf, 1000);
  rig.tick_ms(5);
  CHECK_EQ(rig.controller.in1()[0], kHalf);
  CHECK_EQ(rig.controller.in1()[1], 1000);
  CHECK_EQ(rig.controller.in2_mask(), 0u);
  rig.levels(0);
  rig.tick_ms(5);
  CHECK_EQ(rig.controller.in1()[0], 0);
  CHECK_EQ(rig.motors.in2, 0u);
}

TEST(a_shaped_rise_kicks_then_holds_the_level_and_is_faster_than_plain) {
  double rise[2] = {};
  double fall[2] = {};
  for (int shaped = 0; shaped < 2; ++shaped) {
    Rig rig;
    if (shaped != 0) rig.drive(tb::kDriveShaped);
    rig.tick_ms(1);
    rig.levels(kHalf);
    if (shaped != 0) {
      CHECK_EQ(rig.controller.in1()[0], 65535);  // the kick: full duty, twice the level
      CHECK_EQ(rig.controller.in2_mask(), 0u);
    }
    const double a = 0.5 * 0.5;
    rise[shaped] = rig.transition_ms(0.0, a, 400);
    CHECK_EQ(rig.controller.in1()[0], kHalf);  // then the level
    CHECK_NEAR(rig.bank.amplitude(0), a, 0.01 * a);
    CHECK_NEAR(rig.controller.predicted_speed(0), 0.5f, 1e-3f);
    rig.levels(0);
    if (shaped != 0) {
      CHECK_EQ(rig.controller.in2_mask(), 1u);  // the brake pulse
      CHECK(rig.controller.in1()[0] < 65535);   // reverse drive (IN1 below full)
    }
    fall[shaped] = rig.transition_ms(a, 0.0, 400);
    CHECK_EQ(rig.controller.in1()[0], 0);  // both inputs low after the pulse
    CHECK_EQ(rig.controller.in2_mask(), 0u);
    CHECK_EQ(rig.motors.in2, 0u);
    CHECK(rig.bank.amplitude(0) < 0.01 * a);
  }
  printf("  level 0.5, 10-90 %%: plain rise %.1f ms, fall %.1f ms; shaped rise %.1f ms, "
         "fall %.1f ms\n", rise[0], fall[0], rise[1], fall[1]);
  CHECK(rise[0] > 80.0);
  CHECK(fall[0] > 40.0);
  CHECK(rise[1] <= 30.0);
  CHECK(fall[1] <= 30.0);
}

// A played stimulus is known ahead: the shaper aims each tick at its amplitudes
// kShapeLeadTicks later, so the brake of its end starts that long before the end (the
// level still commanded), and plain plays the levels as they are.
TEST(a_played_stimulus_is_shaped_with_a_preview_of_its_end) {
  for (int shaped = 0; shaped < 2; ++shaped) {
    Rig rig;
    if (shaped != 0) rig.drive(tb::kDriveShaped);
    rig.tick_ms(1);
    std::vector<uint8_t> p(14);
    tb::put_u16(&p[0], 0);  // on tactor 0
    p[2] = 0;               // static
    p[3] = 0;               // the paper's law
    tb::put_u16(&p[4], 1500);
    tb::put_u16(&p[6], 1000);
    tb::put_u16(&p[8], 100);
    tb::put_u32(&p[10], 200);  // 200 ms
    rig.send(tb::msg::kPlayTarget, p);
    const uint64_t start = rig.now_us;
    bool braked_early = false;
    while (rig.now_us < start + 200000 - 1000) {
      rig.tick_ms(1);
      const uint64_t t = rig.now_us - start;
      if (rig.controller.in2_mask() != 0) {
        CHECK(shaped != 0);
        CHECK(t + tb::kShapeLeadTicks * 1000u >= 200000u);  // not before the preview
        CHECK(rig.controller.levels()[0] > 0);              // the level still on
        braked_early = true;
      } else if (shaped == 0) {
        CHECK_EQ(rig.controller.in1()[0], rig.controller.levels()[0]);
      }
    }
    CHECK_EQ(braked_early, shaped != 0);
  }
}

// The preview does not move what is played: a shaped board's levels of a dynamic
// stimulus (taken from the preview's ring on the 1 kHz tick) are the plain board's, tick
// by tick, also with a command between ticks; and its drive leads them.
TEST(a_previewed_stimulus_plays_the_same_levels_as_plain) {
  Rig plain;
  Rig shaped;
  shaped.drive(tb::kDriveShaped);
  std::vector<uint8_t> p(14);
  tb::put_u16(&p[0], 3000);  // between tactors 0 and 1
  p[2] = 1;                  // dynamic
  p[3] = 0;
  tb::put_u16(&p[4], 1500);
  tb::put_u16(&p[6], 400);
  tb::put_u16(&p[8], 100);
  tb::put_u32(&p[10], 1000);
  for (Rig* r : {&plain, &shaped}) {
    r->tick_ms(1);
    r->send(tb::msg::kPlayTarget, p);
  }
  int led = 0;
  for (int i = 0; i < 1100; ++i) {
    for (Rig* r : {&plain, &shaped}) {
      r->tick_ms(1);
      if (i % 97 == 0) {  // a heartbeat between ticks updates the outputs off the tick
        r->now_us += 300;
        r->send(tb::msg::kHeartbeat);
      }
    }
    for (uint8_t k = 0; k < 6; ++k) {
      CHECK_EQ(shaped.controller.levels()[k], plain.controller.levels()[k]);
      if (shaped.controller.in1()[k] > plain.controller.in1()[k] &&
          shaped.controller.in2_mask() == 0) {
        ++led;
      }
    }
  }
  CHECK(led > 0);
}

TEST(a_board_without_in2_overdrives_but_coasts) {
  Rig rig(false);
  rig.drive(tb::kDriveShaped);
  rig.levels(kHalf);
  CHECK_EQ(rig.controller.in1()[0], 65535);
  rig.tick_ms(200);
  rig.levels(0);
  for (int i = 0; i < 300; ++i) {
    CHECK_EQ(rig.controller.in2_mask(), 0u);
    CHECK_EQ(rig.controller.in1()[0], 0);
    rig.tick_ms(1);
  }
  CHECK_EQ(rig.motors.in2, 0u);
  // a brake-capable board told not to brake coasts too
  Rig r2(true);
  r2.drive(tb::kDriveShaped | tb::kDriveNoBrake);
  r2.levels(kHalf);
  r2.tick_ms(200);
  r2.levels(0);
  r2.tick_ms(1);
  CHECK_EQ(r2.controller.in2_mask(), 0u);
}

TEST(a_shaped_level_is_held_at_most_at_the_rated_drive) {
  Rig rig;
  const uint16_t rated = 54613;  // 1/1.2: a 3.6 V supply on a 3 V motor
  rig.drive(tb::kDriveShaped, tb::kDriveAllTactors, 16384, rated, 400, 500, 400);
  rig.levels(65535);
  CHECK_EQ(rig.controller.in1()[0], 65535);  // the kick
  rig.tick_ms(300);
  CHECK_EQ(rig.controller.in1()[0], rated);  // then the rated drive, not full duty
  CHECK_EQ(rig.controller.levels()[0], 65535);  // STATUS still says what was commanded
}

TEST(every_failsafe_leaves_both_inputs_low) {
  for (int which = 0; which < 3; ++which) {
    Rig rig;
    rig.controller.set_heartbeat_ms(50);
    // a 1 ms rise and a 2 s brake time constant: a brake pulse lasts over a second, so
    // each failsafe comes in the middle of one
    rig.drive(tb::kDriveShaped, tb::kDriveAllTactors, 16384, 65535, 10, 500, 20000);
    rig.levels(65535);
    for (int i = 0; i < 4; ++i) {
      rig.tick_ms(10);
      rig.send(tb::msg::kHeartbeat);
    }
    CHECK_NEAR(rig.controller.predicted_speed(0), 1.0f, 1e-3f);
    rig.levels(0);  // a brake pulse starts
    rig.tick_ms(45);
    CHECK_EQ(rig.controller.in2_mask(), 1u);  // still braking
    CHECK_EQ(rig.motors.in2, 1u);
    if (which == 0) {
      rig.tick_ms(10);  // no heartbeat for 55 ms: the failsafe, mid-pulse
      CHECK(rig.controller.state() == tb::State::kFailsafe);
    } else if (which == 1) {
      rig.controller.link_closed(rig.now_us);  // the port closes, BLE disconnects
    } else {
      rig.controller.begin(rig.now_us);  // a reset (the watchdog's included) boots again
    }
    CHECK_EQ(rig.controller.in2_mask(), 0u);
    CHECK_EQ(rig.motors.in2, 0u);
    CHECK_EQ(rig.controller.in1()[0], 0);
    CHECK_EQ(rig.motors.last[0], 0);
    rig.tick_ms(50);
    CHECK_EQ(rig.motors.in2, 0u);
    CHECK_EQ(rig.motors.last[0], 0);
  }
}

// Random command sequences against the bounds: with the shaper's prediction unable to
// pass its target, a drive above the rated level lasts at most rise_tau * ln(1 / (1 -
// rated)) plus a tick, and IN2 high (reverse drive or short brake) at most
// brake_tau * ln(2) plus a tick (from full speed to rest against a full reverse).
TEST(no_command_sequence_holds_overdrive_or_reverse_drive_past_its_bound) {
  uint64_t rng = 0x2545F4914F6CDD1Dull;
  auto next = [&rng](uint32_t m) {
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return static_cast<uint32_t>((rng * 2685821657736338717ull) >> 33) % m;
  };
  const uint16_t rateds[3] = {32768, 54613, 65535};
  const uint16_t taus[3] = {200, 400, 700};  // 20, 40, 70 ms
  double worst_over_ms = 0.0;
  double worst_rev_ms = 0.0;
  long commands = 0;
  for (int run = 0; run < 40; ++run) {
    Rig rig(true);
    rig.controller.set_heartbeat_ms(200);
    auto set_params = [&]() {
      const uint16_t rated = rateds[next(3)];
      const uint16_t start = static_cast<uint16_t>(next(rated / 2));
      rig.drive(static_cast<uint8_t>(next(4)), next(2) ? tb::kDriveAllTactors
                                                       : static_cast<uint8_t>(next(6)),
                start, rated, taus[next(3)], taus[next(3)], taus[next(3)]);
    };
    set_params();
    // the longest bound any tactor has had in this run (ms), plus the tick a command may
    // start a stretch before the tick that sees it
    uint32_t longest[2] = {};
    auto worst_bound = [&](uint32_t tb::DriveParams::*which) {
      return (which == &tb::DriveParams::over_bound_us ? longest[0] : longest[1]) * 1e-3 + 1.0;
    };
    uint64_t over_since[6] = {};
    uint64_t rev_since[6] = {};
    bool over[6] = {};
    bool rev[6] = {};
    for (int step = 0; step < 3000; ++step) {
      // a command at a random moment within the tick
      const uint32_t what = next(100);
      rig.now_us += next(1000);
      if (what < 25) {
        std::vector<uint8_t> p;
        for (int k = 0; k < 6; ++k) {
          const uint32_t r = next(4);
          const uint16_t v = r == 0 ? 0 : (r == 1 ? 65535 : static_cast<uint16_t>(next(65536)));
          p.push_back(static_cast<uint8_t>(v));
          p.push_back(static_cast<uint8_t>(v >> 8));
        }
        rig.send(tb::msg::kSetAmplitudes, p);
      } else if (what < 30) {
        std::vector<uint8_t> p(14);
        tb::put_u16(&p[0], static_cast<uint16_t>(next(36000)));
        p[2] = static_cast<uint8_t>(next(2));
        p[3] = static_cast<uint8_t>(next(3));
        tb::put_u16(&p[4], static_cast<uint16_t>(1 + next(6000)));
        tb::put_u16(&p[6], static_cast<uint16_t>(10 + next(600)));
        tb::put_u16(&p[8], static_cast<uint16_t>(1 + next(200)));
        tb::put_u32(&p[10], next(500));
        rig.send(tb::msg::kPlayTarget, p);
      } else if (what < 33) {
        rig.send(tb::msg::kStopAll);
      } else if (what < 36) {
        rig.drive(static_cast<uint8_t>(next(4)));
      } else if (what < 37) {
        set_params();
      } else if (what < 38) {
        rig.controller.link_closed(rig.now_us);
      } else if (what < 60) {
        rig.send(tb::msg::kHeartbeat);
      }
      ++commands;
      // then on to the next whole tick, ticking (sometimes a few, or a long silence)
      const int ticks = next(10) == 0 ? static_cast<int>(next(300)) : 1;
      rig.now_us = (rig.now_us / 1000 + 1) * 1000;
      for (int t = 0; t < ticks; ++t) {
        if (t > 0) rig.now_us += 1000;
        rig.controller.tick(rig.now_us);
        for (uint8_t k = 0; k < 6; ++k) {
          const tb::DriveParams& q = rig.controller.drive_params(k);
          if (q.over_bound_us > longest[0]) longest[0] = q.over_bound_us;
          if (q.reverse_bound_us > longest[1]) longest[1] = q.reverse_bound_us;
          // the bounds are the shaper's own: a kick from rest to rated, a full reverse from
          // full speed to rest, each plus a tick
          const double rated_d = static_cast<double>(q.rated);
          CHECK_NEAR(q.reverse_bound_us * 1e-3, static_cast<double>(q.brake_tau_s) * 1e3 * log(2.0) + 1.0, 0.01);
          if (rated_d < 1.0) {
            CHECK_NEAR(q.over_bound_us * 1e-3,
                       static_cast<double>(q.rise_tau_s) * 1e3 * log(1.0 / (1.0 - rated_d)) + 1.0, 0.02);
          }
          const uint16_t in1 = rig.motors.last[k];
          const bool in2 = ((rig.motors.in2 >> k) & 1u) != 0;
          const float rated = rig.controller.drive_params(k).rated;
          // the bridge as the motor sees it: written by the driver calls
          CHECK_EQ(in1, rig.controller.in1()[k]);
          const bool o = !in2 && in1 > rig.controller.levels()[k] &&
                         static_cast<float>(in1) / 65535.0f > rated + 1e-4f;
          if (o && !over[k]) over_since[k] = rig.now_us;
          if (in2 && !rev[k]) rev_since[k] = rig.now_us;
          over[k] = o;
          rev[k] = in2;
          if (o) {
            const double ms = static_cast<double>(rig.now_us - over_since[k]) * 1e-3;
            if (ms > worst_over_ms) worst_over_ms = ms;
            CHECK(ms <= worst_bound(&tb::DriveParams::over_bound_us));
          }
          if (in2) {
            const double ms = static_cast<double>(rig.now_us - rev_since[k]) * 1e-3;
            if (ms > worst_rev_ms) worst_rev_ms = ms;
            CHECK(ms <= worst_bound(&tb::DriveParams::reverse_bound_us));
          }
          if (rig.controller.state() == tb::State::kFailsafe) {
            CHECK(!in2);
            CHECK_EQ(in1, 0);
          }
        }
      }
    }
  }
  printf("  %ld random commands: longest overdrive %.0f ms, longest IN2 high %.0f ms\n",
         commands, worst_over_ms, worst_rev_ms);
  CHECK(worst_rev_ms > 0.0);
  CHECK(worst_over_ms > 0.0);
}

// The firmware's shaper against erm.shape_tick (the "shape" vectors of vectors_ext.json):
// the same decision at every tick, the same predicted speed, in float32.
TEST(the_shaper_matches_tactorbelt_devices_erm_shape_tick) {
  const auto& v = support::vectors_ext()["shape"];
  tb::DriveParams p;
  p.rise_tau_s = static_cast<float>(v["params"]["rise_tau_s"].number());
  p.fall_tau_s = static_cast<float>(v["params"]["fall_tau_s"].number());
  p.brake_tau_s = static_cast<float>(v["params"]["brake_tau_s"].number());
  p.start = static_cast<float>(v["params"]["start_level"].number());
  const float tick_s = static_cast<float>(v["params"]["tick_s"].number());
  p.prepare(tick_s);
  const auto& levels = v["levels"].arr;
  double worst_drive = 0.0;
  double worst_speed = 0.0;
  int reversed = 0;
  for (const auto& c : v["cases"].arr) {
    const bool brake = c["brake"].b;
    float w = 0.0f;
    for (size_t i = 0; i < levels.size(); ++i) {
      const float level = static_cast<float>(levels[i].number());
      const tb::Drive d = tb::shape_tick(level, w, p, brake);
      w = tb::drive_relax(d, w, tick_s, p);
      CHECK_EQ(d.reverse, c["reverse"].arr[i].b);
      if (d.reverse) ++reversed;
      const double dd = fabs(static_cast<double>(d.mag) - c["drive"].arr[i].number());
      const double dw = fabs(static_cast<double>(w) - c["speed"].arr[i].number());
      if (dd > worst_drive) worst_drive = dd;
      if (dw > worst_speed) worst_speed = dw;
    }
  }
  printf("  shape vectors: %zu ticks x 2, largest difference drive %.2e, speed %.2e\n",
         levels.size(), worst_drive, worst_speed);
  CHECK(reversed > 10);
  CHECK(worst_drive < 1e-4);
  CHECK(worst_speed < 1e-5);
}

#include "controller.h"

namespace tb {

namespace {
constexpr float kTickS = 0.001f;  // the shaper decides for one 1 kHz tick

// A bound's budget after dt us: used grows while the drive is what it bounds, else shrinks.
uint32_t budget(uint32_t used, uint32_t dt, bool driving) {
  if (driving) return used > 0xFFFFFFFFu - dt ? 0xFFFFFFFFu : used + dt;
  return used > dt ? used - dt : 0u;
}
}  // namespace

Controller::Controller(const Layout& layout, MotorDriver& motors, uint16_t pwm_steps)
    : layout_(layout), motors_(motors), pwm_steps_(pwm_steps) {
  reset_drive();
}

void Controller::reset_drive() {
  drive_mode_ = 0;
  for (uint8_t k = 0; k < kMaxChannels; ++k) {
    drive_[k] = DriveParams();
    drive_[k].prepare(kTickS);
  }
}

void Controller::begin(uint64_t now_us) {
  state_ = State::kIdle;
  sense_.abort();
  reset_drive();
  for (uint8_t k = 0; k < kMaxChannels; ++k) {
    out_[k] = 0;
    in1_[k] = 0;
    over_used_us_[k] = 0;
    reverse_used_us_[k] = 0;
    w_[k] = 0.0f;  // a reset lets the motors coast to rest (more than a watchdog period)
  }
  in2_mask_ = 0;
  model_started_ = false;
  motors_.write_in2(0, channels());  // both inputs low, whatever the driver did before
  motors_.write(out_, channels());
  update_outputs(now_us);
}

bool Controller::set_heartbeat_ms(uint16_t ms) {
  if (!heartbeat_ms_ok(ms)) return false;
  heartbeat_ms_ = ms;
  return true;
}

bool Controller::set_max_on_ms(uint32_t ms) {
  if (!max_on_ms_ok(ms)) return false;
  max_on_ms_ = ms;
  return true;
}

void Controller::receive_bytes(const uint8_t* data, size_t n, uint64_t now_us, ReplySink& reply) {
  Packet p;
  for (size_t i = 0; i < n; ++i) {
    switch (decoder_.feed(data[i], &p)) {
      case FeedResult::kNone:
        break;
      case FeedResult::kPacket:
        handle(p, now_us, reply);
        break;
      case FeedResult::kCrcError:
        counters_.crc_errors = saturating_inc(counters_.crc_errors);
        break;
      case FeedResult::kFramingError:
        counters_.framing_errors = saturating_inc(counters_.framing_errors);
        break;
    }
  }
}

void Controller::receive_packet(const uint8_t* raw, size_t n, uint64_t now_us, ReplySink& reply) {
  Packet p;
  switch (parse_packet(raw, n, &p)) {
    case PacketStatus::kOk:
      handle(p, now_us, reply);
      break;
    case PacketStatus::kBadCrc:
      counters_.crc_errors = saturating_inc(counters_.crc_errors);
      break;
    case PacketStatus::kBadLength:
      counters_.framing_errors = saturating_inc(counters_.framing_errors);
      break;
  }
}

void Controller::link_closed(uint64_t now_us) {
  decoder_.reset();
  have_seq_ = false;
  flags_ = 0;  // extensions are per connection: the next host starts with plain v1
  reset_drive();  // and with the plain drive: the outputs go off with both inputs low
  sense_.abort();  // and so is sensing: nothing more is sent to the closed link
  state_ = State::kIdle;
  update_outputs(now_us);
}

void Controller::reply(ReplySink& sink, uint8_t type, uint8_t seq, const uint8_t* payload, size_t n) {
  uint8_t packet[kMaxPacket];
  const size_t len = build_packet(type, seq, payload, n, packet);
  if (len != 0) sink.send(packet, len);
}

void Controller::ack(ReplySink& sink, uint8_t seq) {
  const uint8_t payload[2] = {seq, 0};
  reply(sink, msg::kAck, seq, payload, sizeof payload);
}

void Controller::nak(ReplySink& sink, uint8_t seq, uint8_t code) {
  const uint8_t payload[2] = {seq, code};
  reply(sink, msg::kNak, seq, payload, sizeof payload);
}

// ONSET: the device time at which the outputs took the new values. The motor
// registers are written by update_outputs() with this same now_us, before the call.
void Controller::onset(ReplySink& sink, uint8_t seq, uint8_t type, uint64_t now_us) {
  if ((flags_ & kFlagOnsetEvents) == 0) return;
  uint8_t payload[kOnsetPayload];
  payload[0] = seq;
  payload[1] = type;
  put_u64(payload + 2, now_us);
  reply(sink, msg::kOnset, seq, payload, sizeof payload);
}

void Controller::handle(const Packet& p, uint64_t now_us, ReplySink& sink) {
  const uint8_t n = channels();
  // Every valid packet pushes the failsafe deadline and is checked for a gap.
  deadline_us_ = now_us + static_cast<uint64_t>(heartbeat_ms_) * 1000u;
  if (have_seq_ && p.seq != static_cast<uint8_t>(last_seq_ + 1)) {
    counters_.seq_gaps = saturating_inc(counters_.seq_gaps);
  }
  have_seq_ = true;
  last_seq_ = p.seq;

  uint8_t payload[kMaxPayload];
  switch (p.type) {
    case msg::kPing: {
      if (p.len != kPingPayload) return nak(sink, p.seq, nak::kBadLength);
      for (size_t i = 0; i < 4; ++i) payload[i] = p.payload[i];
      put_u32(payload + 4, static_cast<uint32_t>(now_us));
      return reply(sink, msg::kPong, p.seq, payload, 8);
    }
    case msg::kGetInfo: {
      if (p.len != 0) return nak(sink, p.seq, nak::kBadLength);
      payload[0] = kProtocolVersion;
      payload[1] = kFirmwareMajor;
      payload[2] = kFirmwareMinor;
      payload[3] = kFirmwarePatch;
      payload[4] = n;
      put_u16(payload + 5, pwm_steps_);
      put_u16(payload + 7, heartbeat_ms_);
      payload[9] = kCapPlayTarget;
      if (sense_.ready()) payload[9] |= kCapSense;
      if (shaping_installed_) payload[9] |= kCapShape;
      if (shaping_installed_ && can_brake_) payload[9] |= kCapBrake;
      if (reset_flags_ & reset::kWatchdog) payload[9] |= kCapWatchdogReset;
      for (uint8_t k = 0; k < n; ++k) {
        uint32_t cdeg = static_cast<uint32_t>(layout_.angle(k) * 100.0f + 0.5f);
        if (cdeg >= 36000u) cdeg -= 36000u;
        put_u16(payload + 10 + 2 * k, static_cast<uint16_t>(cdeg));
      }
      return reply(sink, msg::kInfo, p.seq, payload, 10 + 2u * n);
    }
    case msg::kSetAmplitudes: {
      if (p.len != 2u * n) return nak(sink, p.seq, nak::kBadLength);
      for (uint8_t k = 0; k < n; ++k) stream_[k] = get_u16(p.payload + 2 * k);
      const bool starts = state_ != State::kStreaming;
      state_ = State::kStreaming;
      update_outputs(now_us);
      if (starts) onset(sink, p.seq, p.type, now_us);
      return;
    }
    case msg::kStopAll: {
      if (p.len != 0) return nak(sink, p.seq, nak::kBadLength);
      state_ = State::kIdle;
      update_outputs(now_us);
      return ack(sink, p.seq);
    }
    case msg::kPlayTarget: {
      if (p.len != kPlayTargetPayload) return nak(sink, p.seq, nak::kBadLength);
      StimulusParams sp;
      sp.angle_cdeg = get_u16(p.payload + 0);
      sp.mode = p.payload[2];
      sp.law = p.payload[3];
      sp.falloff_cdeg = get_u16(p.payload + 4);
      sp.period_ms = get_u16(p.payload + 6);
      sp.transit_ms = get_u16(p.payload + 8);
      if (!stimulus_.set(layout_, sp)) return nak(sink, p.seq, nak::kOutOfRange);
      play_duration_ms_ = get_u32(p.payload + 10);
      play_start_us_ = now_us;
      for (uint64_t& t : ahead_t_us_) t = ~0ull;
      state_ = State::kPlaying;
      update_outputs(now_us);
      ack(sink, p.seq);
      return onset(sink, p.seq, p.type, now_us);
    }
    case msg::kHeartbeat: {
      if (p.len != 0) return nak(sink, p.seq, nak::kBadLength);
      return;
    }
    case msg::kSetConfig: {
      if (p.len != kSetConfigPayload && p.len != kSetConfigPayloadLong &&
          p.len != kSetConfigPayloadFlags) {
        return nak(sink, p.seq, nak::kBadLength);
      }
      const uint16_t hb = get_u16(p.payload);
      const uint32_t max_on = p.len >= kSetConfigPayloadLong ? get_u32(p.payload + 2) : max_on_ms_;
      const uint8_t flags = p.len == kSetConfigPayloadFlags ? p.payload[6] : flags_;
      // every value is checked before any applies
      if (!heartbeat_ms_ok(hb) || !max_on_ms_ok(max_on) || (flags & ~kKnownFlags) != 0) {
        return nak(sink, p.seq, nak::kOutOfRange);
      }
      heartbeat_ms_ = hb;
      max_on_ms_ = max_on;
      flags_ = flags;
      deadline_us_ = now_us + static_cast<uint64_t>(heartbeat_ms_) * 1000u;
      return ack(sink, p.seq);
    }
    case msg::kGetStatus: {
      if (p.len != 0) return nak(sink, p.seq, nak::kBadLength);
      payload[0] = static_cast<uint8_t>(state_);
      put_u16(payload + 1, counters_.failsafe);
      put_u16(payload + 3, counters_.crc_errors);
      put_u16(payload + 5, counters_.framing_errors);
      put_u16(payload + 7, counters_.seq_gaps);
      for (uint8_t k = 0; k < n; ++k) put_u16(payload + 9 + 2 * k, out_[k]);
      return reply(sink, msg::kStatus, p.seq, payload, 9 + 2u * n);
    }
    case msg::kGetDiag: {
      if (p.len != 0) return nak(sink, p.seq, nak::kBadLength);
      put_u64(payload, now_us);
      payload[8] = reset_flags_;
      put_u16(payload + 9, counters_.tx_dropped);
      put_u16(payload + 11, counters_.ble_refused);
      return reply(sink, msg::kDiag, p.seq, payload, kDiagPayload);
    }
    case msg::kSenseStart: {
      if (!sense_.installed()) return nak(sink, p.seq, nak::kUnknownType);
      if (p.len != kSenseStartPayload) return nak(sink, p.seq, nak::kBadLength);
      const uint8_t code = sense_.start(p.seq, p.payload, n, now_us, sink);
      if (code != 0) return nak(sink, p.seq, code);
      return ack(sink, p.seq);  // the first sample is read on the next poll_sense()
    }
    case msg::kSenseStop: {
      if (!sense_.installed()) return nak(sink, p.seq, nak::kUnknownType);
      if (p.len != 0) return nak(sink, p.seq, nak::kBadLength);
      sense_.stop();  // the last batch (flag kLast) is queued, sent before or after the ACK
      return ack(sink, p.seq);
    }
    case msg::kSetDrive: {
      if (!shaping_installed_) return nak(sink, p.seq, nak::kUnknownType);
      const uint8_t code = set_drive(p);
      if (code != 0) return nak(sink, p.seq, code);
      update_outputs(now_us);  // the new drive from now on
      return ack(sink, p.seq);
    }
    default:
      if (debug_ != nullptr && p.type >= msg::kDebugFirst && p.type <= msg::kDebugLast &&
          debug_->handle(p)) {
        return ack(sink, p.seq);
      }
      return nak(sink, p.seq, nak::kUnknownType);
  }
}

// SET_DRIVE: mode [, tactor, start, rated, rise, fall, brake]; every value is checked
// before any applies. Returns 0 or a NAK code.
uint8_t Controller::set_drive(const Packet& p) {
  if (p.len != kSetDrivePayloadShort && p.len != kSetDrivePayload) return nak::kBadLength;
  const uint8_t mode = p.payload[0];
  if ((mode & ~kKnownDriveBits) != 0) return nak::kOutOfRange;
  if (p.len == kSetDrivePayload) {
    const uint8_t tactor = p.payload[1];
    const uint16_t start = get_u16(p.payload + 2);
    const uint16_t rated = get_u16(p.payload + 4);
    uint16_t tau[3];
    for (int i = 0; i < 3; ++i) {
      tau[i] = get_u16(p.payload + 6 + 2 * i);
      if (tau[i] < kMinDriveTau || tau[i] > kMaxDriveTau) return nak::kOutOfRange;
    }
    if ((tactor != kDriveAllTactors && tactor >= channels()) || rated == 0 || start >= rated) {
      return nak::kOutOfRange;
    }
    DriveParams q;
    q.start = static_cast<float>(start) / 65535.0f;
    q.rated = static_cast<float>(rated) / 65535.0f;
    q.rise_tau_s = static_cast<float>(tau[0]) * 1e-4f;
    q.fall_tau_s = static_cast<float>(tau[1]) * 1e-4f;
    q.brake_tau_s = static_cast<float>(tau[2]) * 1e-4f;
    q.prepare(kTickS);
    for (uint8_t k = 0; k < channels(); ++k) {
      if (tactor == kDriveAllTactors || tactor == k) drive_[k] = q;
    }
  }
  drive_mode_ = mode;
  return 0;
}

void Controller::tick(uint64_t now_us) {
  const bool active = state_ == State::kStreaming || state_ == State::kPlaying;
  if (active && now_us >= deadline_us_) {
    counters_.failsafe = saturating_inc(counters_.failsafe);
    state_ = State::kFailsafe;
  } else if (state_ == State::kPlaying && play_duration_ms_ != 0 &&
             now_us - play_start_us_ >= static_cast<uint64_t>(play_duration_ms_) * 1000u) {
    state_ = State::kIdle;
  }
  update_outputs(now_us);
  // Fed only here, after the outputs: a loop that stops ticking gets reset.
  if (watchdog_ != nullptr) watchdog_->feed(now_us);
}

void Controller::update_outputs(uint64_t now_us) {
  const uint8_t n = channels();
  // The shaper's model of each motor runs, in every mode, on the drive the bridges had
  // since the last update (so a switch to shaped starts from the motors' real state).
  if (model_started_ && now_us > model_us_) {
    const uint64_t dt_us = now_us - model_us_;
    const float h = static_cast<float>(dt_us) * 1e-6f;
    const uint32_t dt = dt_us > 0xFFFFFFFFu ? 0xFFFFFFFFu : static_cast<uint32_t>(dt_us);
    for (uint8_t k = 0; k < n; ++k) {
      const bool in2 = ((in2_mask_ >> k) & 1u) != 0;
      const Drive d = bridge_to_drive(in1_[k], in2);
      w_[k] = drive_relax(d, w_[k], h, drive_[k]);
      const bool over = !in2 && d.mag > drive_[k].rated;
      over_used_us_[k] = budget(over_used_us_[k], dt, over);
      reverse_used_us_[k] = budget(reverse_used_us_[k], dt, in2);
    }
  }
  if (!model_started_ || now_us > model_us_) model_us_ = now_us;
  model_started_ = true;
  // The drive: the levels themselves (plain, and always in the failsafe: IN2 low, so the
  // motors coast), or each shaped (a kick, a brake pulse, then the level).
  const bool shaped = (drive_mode_ & kDriveShaped) != 0 && state_ != State::kFailsafe;
  // The played levels now, and the shaper's preview of them: the stimulus's levels
  // kShapeLeadTicks ticks ahead (zero from that long before its end), as
  // erm.Shaper.lead_ticks on the host. A level previewed on an earlier tick is taken from
  // the ring instead of computed again.
  uint16_t now_lv[kMaxChannels] = {};
  uint16_t ahead_lv[kMaxChannels] = {};
  const bool preview = shaped && state_ == State::kPlaying;
  if (state_ == State::kPlaying) {
    float amps[kMaxChannels] = {};
    const uint64_t t_us = now_us - play_start_us_;
    if (preview) {
      const uint64_t t_ahead = t_us + kShapeLeadTicks * 1000u;
      if (play_duration_ms_ == 0 ||
          t_ahead < static_cast<uint64_t>(play_duration_ms_) * 1000u) {
        stimulus_.amplitudes(t_ahead, amps);
        for (uint8_t k = 0; k < n; ++k) ahead_lv[k] = amplitude_to_level(amps[k]);
      }
      const uint8_t slot = static_cast<uint8_t>((t_ahead / 1000u) % kAheadSlots);
      ahead_t_us_[slot] = t_ahead;
      for (uint8_t k = 0; k < n; ++k) ahead_[slot][k] = ahead_lv[k];
    }
    const uint8_t now_slot = static_cast<uint8_t>((t_us / 1000u) % kAheadSlots);
    if (preview && ahead_t_us_[now_slot] == t_us &&
        (play_duration_ms_ == 0 || t_us < static_cast<uint64_t>(play_duration_ms_) * 1000u)) {
      for (uint8_t k = 0; k < n; ++k) now_lv[k] = ahead_[now_slot][k];
    } else {
      stimulus_.amplitudes(t_us, amps);
      for (uint8_t k = 0; k < n; ++k) now_lv[k] = amplitude_to_level(amps[k]);
    }
  }
  const uint64_t max_on_us = static_cast<uint64_t>(max_on_ms_) * 1000u;
  bool changed = false;
  uint16_t target[kMaxChannels] = {};
  for (uint8_t k = 0; k < n; ++k) {
    uint16_t level = 0;
    if (state_ == State::kStreaming) level = stream_[k];
    if (state_ == State::kPlaying) level = now_lv[k];
    bool limited = false;
    // Continuous-on limit: a channel commanded on for max_onms without a break
    // goes off, and stays off until it is commanded to 0.
    if (level == 0) {
      on_[k] = false;
    } else if (!on_[k]) {
      on_[k] = true;
      on_since_us_[k] = now_us;
    } else if (now_us - on_since_us_[k] >= max_on_us) {
      level = 0;
      limited = true;
    }
    out_[k] = level;
    // what the shaper aims at: the level, or the preview (never past the on limit)
    target[k] = preview && !limited ? ahead_lv[k] : level;
  }
  // A shaped level is held at most at the rated drive; only a kick goes above it.
  const bool brake = can_brake_ && (drive_mode_ & kDriveNoBrake) == 0;
  uint16_t in1[kMaxChannels] = {};
  uint32_t in2 = 0;
  for (uint8_t k = 0; k < n; ++k) {
    if (!shaped) {
      in1[k] = out_[k];
      continue;
    }
    float level = static_cast<float>(target[k]) / 65535.0f;
    if (level > drive_[k].rated) level = drive_[k].rated;
    Drive d = shape_tick(level, w_[k], drive_[k], brake);
    // the bounds: a drive that would pass one is the level itself for this tick
    const uint32_t tick_us = 1000u;
    if (d.reverse && reverse_used_us_[k] + tick_us > drive_[k].reverse_bound_us) {
      d = Drive{level, false};
    } else if (!d.reverse && d.mag > level && d.mag > drive_[k].rated &&
               over_used_us_[k] + tick_us > drive_[k].over_bound_us) {
      d.mag = level;
    }
    bool high = false;
    drive_to_bridge(d, &in1[k], &high);
    if (high) in2 |= 1u << k;
  }
  for (uint8_t k = 0; k < n; ++k) {
    if (in1[k] != in1_[k]) changed = true;
    in1_[k] = in1[k];
  }
  // IN2 falls before IN1 changes and rises after: a bridge leaving a brake pulse coasts
  // for the moment between the writes, one entering it brakes.
  const uint32_t falling = in2_mask_ & ~in2;
  if (falling != 0) motors_.write_in2(in2_mask_ & in2, n);
  if (changed) motors_.write(in1_, n);
  if (in2 != in2_mask_) motors_.write_in2(in2, n);
  in2_mask_ = in2;
}

}  // namespace tb

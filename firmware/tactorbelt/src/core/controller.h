// The device side of protocol v1: request handling, the 1 kHz output tick, the
// heartbeat failsafe and the per-channel continuous-on limit. Time is passed in
// (microseconds, 64-bit, monotonic); motors and links are behind interfaces.
// Portable C++17: no Arduino headers, no heap, no exceptions.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "drive.h"
#include "protocol.h"
#include "renderer.h"
#include "sense.h"
#include "watchdog.h"
#include "wire.h"

namespace tb {

// Drives the motors. write() gets every channel's level (0 = off, 65535 = full)
// whenever one of them changes.
class MotorDriver {
 public:
  virtual void write(const uint16_t* levels, uint8_t n) = 0;
  // The bridges' second inputs (IN2), bit k for channel k (firmware 1.3, drive shaping):
  // written only by a controller told the board can brake (set_drive_shaping), whenever a
  // bit changes; write() then carries IN1. A driver without them ignores this.
  virtual void write_in2(uint32_t mask, uint8_t n) {
    (void)mask;
    (void)n;
  }

 protected:
  ~MotorDriver() = default;
};

// Sends one unframed reply packet on the link the request came from (the serial
// link COBS-frames it, BLE notifies it as is).
class ReplySink {
 public:
  virtual void send(const uint8_t* packet, size_t n) = 0;
  // Whether a streamed packet (SENSE_DATA) of n bytes may go now without crowding out
  // the replies to requests; a link that never drops says true (the default).
  virtual bool can_stream(size_t n) {
    (void)n;
    return true;
  }

 protected:
  ~ReplySink() = default;
};

// Debug requests (types 0x70..0x7F) go to a hook when one is installed (the
// emulator's --debug-frames); true means handled (the controller ACKs it).
class DebugHook {
 public:
  virtual bool handle(const Packet& p) = 0;

 protected:
  ~DebugHook() = default;
};

struct Counters {
  uint16_t failsafe = 0;
  uint16_t crc_errors = 0;
  uint16_t framing_errors = 0;
  uint16_t seq_gaps = 0;
  // Link counters (GET_DIAG), kept by the link sinks: reply frames dropped because
  // the serial TX buffer was full (a host not reading), and BLE replies refused
  // (NAK 5) because they did not fit the ATT MTU.
  uint16_t tx_dropped = 0;
  uint16_t ble_refused = 0;
};

inline uint16_t saturating_inc(uint16_t v) {
  return v == 0xFFFF ? v : static_cast<uint16_t>(v + 1);
}

class Controller {
 public:
  // layout must outlive the controller; its size is the channel count.
  // pwm_steps is reported in INFO.
  Controller(const Layout& layout, MotorDriver& motors, uint16_t pwm_steps);

  // Power-up: outputs off, state idle.
  void begin(uint64_t now_us);

  // Serial link: COBS-framed bytes.
  void receive_bytes(const uint8_t* data, size_t n, uint64_t now_us, ReplySink& reply);
  // BLE link: one unframed packet per write.
  void receive_packet(const uint8_t* raw, size_t n, uint64_t now_us, ReplySink& reply);
  // Call at 1 kHz: failsafe deadline, end of play, rendering, continuous-on limit.
  void tick(uint64_t now_us);
  // Call on every pass of the main loop: SENSE samples that are due, and their
  // batches out on the link SENSE_START came from (sense.h).
  void poll_sense(uint64_t now_us) { sense_.poll(now_us); }
  // When poll_sense() next has a sample to take (UINT64_MAX when not sensing).
  uint64_t next_sense_us() const { return sense_.next_due_us(); }
  // The USB port closed or BLE disconnected: outputs off, state idle.
  void link_closed(uint64_t now_us);

  // Settings that SET_CONFIG also changes; false when out of range.
  bool set_heartbeat_ms(uint16_t ms);
  bool set_max_on_ms(uint32_t ms);

  // Fed at the end of every tick, after the outputs are updated (may be null).
  void set_watchdog(Watchdog* w) { watchdog_ = w; }
  // Handles debug requests (emulator only; null on the device).
  void set_debug_hook(DebugHook* h) { debug_ = h; }
  // The accelerometer SENSE_START streams (firmware 1.2). Without one (null), SENSE_START
  // and SENSE_STOP are NAKed as unknown (code 2), as by firmware 1.1.
  void set_accelerometer(Accelerometer* a) { sense_.set_accelerometer(a); }
  // Drive shaping (firmware 1.3): SET_DRIVE becomes known and INFO reports kCapShape, and
  // kCapBrake when can_brake (the board has both bridge inputs wired: MotorDriver::
  // write_in2 drives IN2). Without this call SET_DRIVE is NAKed as unknown (code 2), as by
  // firmware 1.2, and the outputs are exactly the levels.
  void set_drive_shaping(bool can_brake) {
    shaping_installed_ = true;
    can_brake_ = can_brake;
  }
  // Why the device last reset (reset::* bits, from RESETREAS at boot): GET_DIAG
  // reports them, INFO sets kCapWatchdogReset when the watchdog did it.
  void set_reset_flags(uint8_t flags) { reset_flags_ = flags; }

  State state() const { return state_; }
  uint8_t channels() const { return layout_.size(); }
  const uint16_t* levels() const { return out_; }
  const Counters& counters() const { return counters_; }
  Counters& link_counters() { return counters_; }
  uint8_t config_flags() const { return flags_; }
  uint8_t reset_flags() const { return reset_flags_; }
  uint16_t heartbeat_ms() const { return heartbeat_ms_; }
  uint32_t max_on_ms() const { return max_on_ms_; }
  const SenseStream& sense() const { return sense_; }
  // The drive on the bridges: IN1 levels (the levels themselves when plain) and IN2 bits.
  const uint16_t* in1() const { return in1_; }
  uint32_t in2_mask() const { return in2_mask_; }
  uint8_t drive_mode() const { return drive_mode_; }
  // The shaper's predicted speed of channel k (units of full duty).
  float predicted_speed(uint8_t k) const { return w_[k]; }
  const DriveParams& drive_params(uint8_t k) const { return drive_[k]; }

 private:
  void handle(const Packet& p, uint64_t now_us, ReplySink& reply);
  void reply(ReplySink& sink, uint8_t type, uint8_t seq, const uint8_t* payload, size_t n);
  void ack(ReplySink& sink, uint8_t seq);
  void nak(ReplySink& sink, uint8_t seq, uint8_t code);
  void onset(ReplySink& sink, uint8_t seq, uint8_t type, uint64_t now_us);
  void update_outputs(uint64_t now_us);
  void reset_drive();
  uint8_t set_drive(const Packet& p);

  const Layout& layout_;
  MotorDriver& motors_;
  uint16_t pwm_steps_;
  FrameDecoder decoder_;

  State state_ = State::kIdle;
  Counters counters_;
  uint16_t heartbeat_ms_ = kDefaultHeartbeatMs;
  uint32_t max_on_ms_ = kDefaultMaxOnMs;
  uint64_t deadline_us_ = 0;
  bool have_seq_ = false;
  uint8_t last_seq_ = 0;
  uint8_t flags_ = 0;        // SET_CONFIG flags, per connection
  uint8_t reset_flags_ = 0;  // reset::*
  Watchdog* watchdog_ = nullptr;
  DebugHook* debug_ = nullptr;
  SenseStream sense_;

  uint16_t stream_[kMaxChannels] = {};  // the last SET_AMPLITUDES (state streaming)
  Stimulus stimulus_;
  uint64_t play_start_us_ = 0;
  uint32_t play_duration_ms_ = 0;
  // The shaper's preview of the played stimulus (levels kShapeLeadTicks ticks ahead), kept
  // for the ticks to come: on the 1 kHz tick a level computed as a preview is the level
  // when its time comes, so the stimulus is computed once a tick, not twice.
  static constexpr uint8_t kAheadSlots = 4;
  static_assert(kShapeLeadTicks < kAheadSlots && kShapeLeadTicks % kAheadSlots != 0,
                "the preview's ring holds the lead");
  uint64_t ahead_t_us_[kAheadSlots] = {};  // time from the start; ~0 = empty
  uint16_t ahead_[kAheadSlots][kMaxChannels] = {};

  uint16_t out_[kMaxChannels] = {};
  // drive shaping: the bridges' inputs, the shaper's model of each motor
  bool shaping_installed_ = false;
  bool can_brake_ = false;
  uint8_t drive_mode_ = 0;  // kDriveShaped, kDriveNoBrake; per connection
  DriveParams drive_[kMaxChannels];
  float w_[kMaxChannels] = {};
  uint64_t model_us_ = 0;
  bool model_started_ = false;
  uint16_t in1_[kMaxChannels] = {};
  uint32_t in2_mask_ = 0;
  // Time (us) each tactor has spent driven above its rated drive, and with IN2 high: it
  // grows while so driven and shrinks as fast while not. Neither may pass its bound
  // (DriveParams), so no command sequence holds overdrive or reverse drive longer.
  uint32_t over_used_us_[kMaxChannels] = {};
  uint32_t reverse_used_us_[kMaxChannels] = {};
  bool on_[kMaxChannels] = {};
  uint64_t on_since_us_[kMaxChannels] = {};
};

}  // namespace tb

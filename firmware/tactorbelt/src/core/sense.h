// SENSE_START / SENSE_STOP / SENSE_DATA (firmware 1.2, docs/protocol.md, "SENSE"): the
// board's accelerometer sampled on the device's microsecond clock and streamed in
// batches. Portable C++17: no Arduino headers, no heap, no exceptions.
//
// Sampling is timed by the device clock, not by the sensor: sample k of a session is
// due at start + k * period, and poll() (called every pass of the main loop) reads the
// sensor once it is due. A sample is stamped with its due time when it is read within
// half a period of it; a read later than that (a long loop pass) starts a new batch
// stamped with the time of the read. So every sample was read between its stamp and
// half a period after it, and the samples of one batch are exactly `period` apart. (A
// sensor model that can be read in the past, Accelerometer::reads_past, catches up on
// the slots it missed instead.)
// The sensor's own output (its last conversion at its output data rate) is what the
// read returns: at most one of its periods old, plus its filter's delay.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "protocol.h"

namespace tb {

class ReplySink;

// The sensor behind SENSE_START: the board's IMU (the sketch), a model of it (the
// emulator) or a fake (the tests).
class Accelerometer {
 public:
  // True when the sensor started (its begin() succeeded): INFO sets kCapSense, and
  // SENSE_START is NAKed with kUnavailable otherwise.
  virtual bool ready() const = 0;
  // The shortest sampling period the sensor supports (its output data rate), in us.
  virtual uint16_t min_period_us() const = 0;
  // The acceleration a raw value of 32768 stands for, in milli-g (8000: +-8 g).
  virtual uint16_t full_scale_mg() const = 0;
  // A session starts (tactor: the one under the board, kSenseAnyTactor when not given)
  // or ends.
  virtual void begin_sensing(uint8_t tactor) { (void)tactor; }
  virtual void end_sensing() {}
  // One sample of the three axes, read now; stamp_us is the device time it will carry
  // (at most half a period before now). False when the read failed.
  virtual bool read(uint64_t stamp_us, int16_t xyz[3]) = 0;
  // True for a sensor that gives the value at any time already past (the emulator's
  // model): a poll that comes late reads the slots it missed at their own stamps (up to a
  // batch per poll) instead of starting a new batch at the time of the read.
  virtual bool reads_past() const { return false; }

 protected:
  ~Accelerometer() = default;
};

constexpr uint8_t kSenseAnyTactor = 0xFF;
constexpr uint32_t kMaxSenseMs = 3600000;  // one hour
// SENSE_DATA: session seq u8, flags u8, first index u32, t0 u64, period u16, full
// scale u16, then N samples of x, y, z int16.
constexpr size_t kSenseDataHeader = 18;
constexpr size_t kSenseSampleSize = 6;
constexpr uint8_t kSenseMaxSamples =
    static_cast<uint8_t>((kMaxPayload - kSenseDataHeader) / kSenseSampleSize);  // 7
// Built batches waiting for room on the link.
constexpr size_t kSenseQueue = 8;

namespace sense_flag {
constexpr uint8_t kLast = 0x01;     // the session ended with this batch
constexpr uint8_t kDropped = 0x02;  // samples before this batch were lost on the device
}  // namespace sense_flag

class SenseStream {
 public:
  void set_accelerometer(Accelerometer* a) { acc_ = a; }
  bool installed() const { return acc_ != nullptr; }
  bool ready() const { return acc_ != nullptr && acc_->ready(); }
  bool active() const { return active_; }

  // SENSE_START with its 7-byte payload (the length is checked by the caller). Returns
  // 0 when the session started (the caller ACKs), else a NAK code: kOutOfRange for a
  // duration of 0 or above kMaxSenseMs or a tactor that is neither kSenseAnyTactor nor
  // below `channels`; kUnavailable when the sensor did not start. A session already
  // running ends first (its last batch goes to its own link).
  uint8_t start(uint8_t seq, const uint8_t* payload, uint8_t channels, uint64_t now_us,
                ReplySink& sink);
  // SENSE_STOP: the running session ends now (its last batch is queued).
  void stop();
  // The link closed, or the device (re)starts: everything dropped, nothing more sent.
  void abort();
  // Every pass of the main loop: reads a sample when one is due, ends the session at
  // its duration, and sends queued batches while the link has room.
  void poll(uint64_t now_us);
  // When poll() next has something to do (a sample due, the end), or UINT64_MAX.
  uint64_t next_due_us() const;

  uint16_t period_us() const { return period_us_; }
  uint32_t samples_taken() const { return index_; }
  size_t queued() const { return q_size_; }

 private:
  void take(uint64_t now_us, bool catch_up);
  void close_batch(uint8_t flags);
  void finish();
  void drain();

  Accelerometer* acc_ = nullptr;
  ReplySink* sink_ = nullptr;
  bool active_ = false;
  uint8_t session_ = 0;
  uint16_t period_us_ = 0;
  uint16_t full_scale_mg_ = 0;
  uint64_t next_us_ = 0;
  uint64_t end_us_ = 0;
  uint32_t index_ = 0;  // samples of this session so far (read or lost)

  // the batch being filled
  uint8_t batch_n_ = 0;
  uint32_t batch_index_ = 0;
  uint64_t batch_t0_ = 0;
  int16_t batch_[kSenseMaxSamples][3] = {};
  uint8_t pending_flags_ = 0;  // kDropped for the next batch

  // built SENSE_DATA packets, oldest first
  uint8_t queue_[kSenseQueue][kMaxPacket] = {};
  uint8_t queue_len_[kSenseQueue] = {};
  size_t q_head_ = 0;
  size_t q_size_ = 0;
};

}  // namespace tb

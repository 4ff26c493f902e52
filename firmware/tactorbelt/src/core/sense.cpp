#include "sense.h"

#include "controller.h"
#include "wire.h"

namespace tb {

uint8_t SenseStream::start(uint8_t seq, const uint8_t* payload, uint8_t channels,
                           uint64_t now_us, ReplySink& sink) {
  const uint16_t rate_hz = get_u16(payload);
  const uint32_t duration_ms = get_u32(payload + 2);
  const uint8_t tactor = payload[6];
  if (duration_ms == 0 || duration_ms > kMaxSenseMs) return nak::kOutOfRange;
  if (tactor != kSenseAnyTactor && tactor >= channels) return nak::kOutOfRange;
  if (!ready()) return nak::kUnavailable;
  if (active_) {
    finish();
    drain();
  }
  // Batches still queued for another link are dropped; for this one they go first.
  if (sink_ != &sink) {
    q_head_ = q_size_ = 0;
  }
  sink_ = &sink;
  // The period: the sensor's shortest, or longer for a lower rate (at most 65535 us).
  uint32_t period = acc_->min_period_us();
  if (rate_hz != 0) {
    const uint32_t want = (1000000u + rate_hz - 1u) / rate_hz;
    if (want > period) period = want;
  }
  if (period > 0xFFFFu) period = 0xFFFFu;
  if (period == 0) period = 1;
  period_us_ = static_cast<uint16_t>(period);
  full_scale_mg_ = acc_->full_scale_mg();
  session_ = seq;
  index_ = 0;
  batch_n_ = 0;
  pending_flags_ = 0;
  next_us_ = now_us;
  end_us_ = now_us + static_cast<uint64_t>(duration_ms) * 1000u;
  active_ = true;
  acc_->begin_sensing(tactor);
  return 0;
}

void SenseStream::stop() {
  if (active_) finish();
  drain();
}

void SenseStream::abort() {
  if (active_ && acc_ != nullptr) acc_->end_sensing();
  active_ = false;
  batch_n_ = 0;
  q_head_ = q_size_ = 0;
  sink_ = nullptr;
}

uint64_t SenseStream::next_due_us() const {
  if (!active_) return UINT64_MAX;
  return next_us_ < end_us_ ? next_us_ : end_us_;
}

void SenseStream::poll(uint64_t now_us) {
  const bool catch_up = acc_ != nullptr && acc_->reads_past();
  const uint8_t reads = catch_up ? kSenseMaxSamples : 1;
  for (uint8_t i = 0; i < reads && active_ && now_us >= next_us_; ++i) take(now_us, catch_up);
  if (active_ && now_us >= end_us_ && next_us_ > now_us) finish();
  drain();
}

// The sample due at next_us_ (now_us >= next_us_), or the end of the session.
void SenseStream::take(uint64_t now_us, bool catch_up) {
  uint64_t stamp = next_us_;
  if (!catch_up && stamp < end_us_ && now_us - stamp > period_us_ / 2u) {
    // Read too late for its slot: the batch so far keeps its exact times, and this
    // sample starts the next one at the time it is read.
    close_batch(0);
    stamp = now_us;
  }
  if (stamp >= end_us_) {
    finish();
    return;
  }
  int16_t xyz[3] = {0, 0, 0};
  if (acc_->read(stamp, xyz)) {
    if (batch_n_ == 0) {
      batch_t0_ = stamp;
      batch_index_ = index_;
    }
    for (int a = 0; a < 3; ++a) batch_[batch_n_][a] = xyz[a];
    ++batch_n_;
    if (batch_n_ == kSenseMaxSamples) close_batch(0);
  } else {
    // a failed read: the sample is lost (its index is skipped)
    close_batch(0);
    pending_flags_ |= sense_flag::kDropped;
  }
  ++index_;
  next_us_ = stamp + period_us_;
}

void SenseStream::finish() {
  close_batch(sense_flag::kLast);
  active_ = false;
  acc_->end_sensing();
}

// Builds the batch filled so far into the queue (an empty one only for the last).
void SenseStream::close_batch(uint8_t flags) {
  if (batch_n_ == 0 && (flags & sense_flag::kLast) == 0) return;
  if (batch_n_ == 0) {
    batch_index_ = index_;
    batch_t0_ = next_us_ < end_us_ ? next_us_ : end_us_;
  }
  if (q_size_ == kSenseQueue) {
    // No room: the oldest batch is lost, and this one says so.
    q_head_ = (q_head_ + 1) % kSenseQueue;
    --q_size_;
    pending_flags_ |= sense_flag::kDropped;
  }
  uint8_t payload[kMaxPayload];
  payload[0] = session_;
  payload[1] = static_cast<uint8_t>(flags | pending_flags_);
  put_u32(payload + 2, batch_index_);
  put_u64(payload + 6, batch_t0_);
  put_u16(payload + 14, period_us_);
  put_u16(payload + 16, full_scale_mg_);
  size_t n = kSenseDataHeader;
  for (uint8_t i = 0; i < batch_n_; ++i) {
    for (int a = 0; a < 3; ++a) {
      put_u16(payload + n, static_cast<uint16_t>(batch_[i][a]));
      n += 2;
    }
  }
  const size_t slot = (q_head_ + q_size_) % kSenseQueue;
  queue_len_[slot] =
      static_cast<uint8_t>(build_packet(msg::kSenseData, session_, payload, n, queue_[slot]));
  ++q_size_;
  pending_flags_ = 0;
  batch_n_ = 0;
}

void SenseStream::drain() {
  while (q_size_ > 0 && sink_ != nullptr) {
    const uint8_t* packet = queue_[q_head_];
    const size_t n = queue_len_[q_head_];
    if (!sink_->can_stream(n)) return;
    sink_->send(packet, n);
    q_head_ = (q_head_ + 1) % kSenseQueue;
    --q_size_;
  }
}

}  // namespace tb

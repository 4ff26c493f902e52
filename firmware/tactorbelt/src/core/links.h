// The reply paths of the two links, shared by the sketch and the emulator so that
// both behave alike. Portable C++17: no Arduino headers, no heap, no exceptions.
//
// SerialTx: replies are COBS-framed into a bounded ring buffer, whole frames only;
// a frame that does not fit is dropped and counted (Counters::tx_dropped). The link
// drains the ring without blocking (the sketch with USBCDC::send_nb, the emulator
// with a non-blocking write), so a host that holds the port open but stops reading
// can never stall the tick.
//
// BleTx: one notification carries at most MTU - 3 bytes. A packet that fits goes as
// one notification (protocol v1); one that does not is replaced by NAK 5 (reply too
// long) and counted (Counters::ble_refused), unless the host asked for framed replies
// (SET_CONFIG flag kFlagBleFramed): then every reply is COBS-framed with its 0x00
// and cut into MTU - 3 byte notifications that the host joins and splits at 0x00.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "controller.h"
#include "wire.h"

namespace tb {

constexpr size_t kSerialTxCapacity = 512;  // bytes: 7 INFO/STATUS frames and then some
// Streamed packets (SENSE_DATA) leave this much of the ring to replies: two of the
// longest frames.
constexpr size_t kSerialReplyReserve = 2 * kMaxFrame;

class SerialTx : public ReplySink {
 public:
  explicit SerialTx(Counters& counters) : counters_(counters) {}

  void send(const uint8_t* packet, size_t n) override {
    uint8_t frame[kMaxFrame];
    const size_t len = frame_packet(packet, n, frame, sizeof frame);
    if (len == 0) return;
    if (!open_ || len > kSerialTxCapacity - size_) {
      if (open_) counters_.tx_dropped = saturating_inc(counters_.tx_dropped);
      return;
    }
    for (size_t i = 0; i < len; ++i) {
      buf_[(head_ + size_) % kSerialTxCapacity] = frame[i];
      ++size_;
    }
  }

  // A streamed packet goes only while it leaves kSerialReplyReserve bytes free (a COBS
  // frame is at most 2 bytes longer than its packet), so a host that reads slowly still
  // gets its replies; the stream waits in its own queue.
  bool can_stream(size_t n) override {
    return open_ && n + 2u + kSerialReplyReserve <= kSerialTxCapacity - size_;
  }

  // The longest run of queued bytes that is contiguous in memory (0 when empty).
  size_t peek(const uint8_t** data) const {
    *data = buf_ + head_;
    const size_t to_end = kSerialTxCapacity - head_;
    return size_ < to_end ? size_ : to_end;
  }
  // n bytes of peek() went out.
  void consume(size_t n) {
    if (n > size_) n = size_;
    head_ = (head_ + n) % kSerialTxCapacity;
    size_ -= n;
  }
  // The port opened or closed: a closed port queues nothing (and counts nothing),
  // and what was queued for the last host is discarded.
  void set_open(bool open) {
    if (open != open_) clear();
    open_ = open;
  }
  void clear() { head_ = size_ = 0; }
  size_t queued() const { return size_; }
  size_t room() const { return kSerialTxCapacity - size_; }

 private:
  Counters& counters_;
  uint8_t buf_[kSerialTxCapacity] = {};
  size_t head_ = 0;
  size_t size_ = 0;
  bool open_ = true;
};

// What BleTx needs from the BLE stack.
class BleNotifier {
 public:
  // The negotiated ATT MTU of the connected central (23 until it asks for more).
  virtual uint16_t att_mtu() = 0;
  // Sends one notification of n <= att_mtu() - 3 bytes; false when it was not sent.
  virtual bool notify(const uint8_t* data, size_t n) = 0;

 protected:
  ~BleNotifier() = default;
};

constexpr uint16_t kDefaultAttMtu = 23;

class BleTx : public ReplySink {
 public:
  BleTx(BleNotifier& notifier, const Controller& controller, Counters& counters)
      : notifier_(notifier), controller_(controller), counters_(counters) {}

  void send(const uint8_t* packet, size_t n) override {
    uint16_t mtu = notifier_.att_mtu();
    if (mtu < kDefaultAttMtu) mtu = kDefaultAttMtu;
    const size_t chunk = static_cast<size_t>(mtu) - 3u;
    if ((controller_.config_flags() & kFlagBleFramed) != 0) {
      uint8_t frame[kMaxFrame];
      const size_t len = frame_packet(packet, n, frame, sizeof frame);
      for (size_t at = 0; at < len; at += chunk) {
        const size_t k = len - at < chunk ? len - at : chunk;
        if (!notifier_.notify(frame + at, k)) return;
      }
      return;
    }
    if (n <= chunk) {
      notifier_.notify(packet, n);
      return;
    }
    // Too long for this MTU and the host did not ask for framing: a NAK (6 bytes
    // fits any MTU) rather than a notification the stack would cut short.
    counters_.ble_refused = saturating_inc(counters_.ble_refused);
    const uint8_t seq = packet[1];
    const uint8_t payload[2] = {seq, nak::kReplyTooLong};
    uint8_t out[kMaxPacket];
    const size_t len = build_packet(msg::kNak, seq, payload, sizeof payload, out);
    notifier_.notify(out, len);
  }

 private:
  BleNotifier& notifier_;
  const Controller& controller_;
  Counters& counters_;
};

}  // namespace tb

// The watchdog, as the controller sees it: fed by the 1 kHz tick once the outputs
// are up to date, so a main loop that stops ticking (a blocked write, a hang) is
// reset before the motors can run unattended for long. The nRF52840 WDT implements
// it on the board (tactorbelt.ino); WatchdogModel is the same timer for the
// emulator and the tests. Portable C++17: no Arduino headers, no heap, no exceptions.
#pragma once

#include <stdint.h>

namespace tb {

// Default timeout: above the tick's worst lag (100 ms before it skips ahead) and the
// heartbeat's default (250 ms), well under a second.
constexpr uint32_t kWatchdogTimeoutMs = 300;

class Watchdog {
 public:
  virtual void feed(uint64_t now_us) = 0;

 protected:
  ~Watchdog() = default;
};

// A watchdog timer in software: expired once timeout_ms pass without a feed.
// expired() may be called from a signal handler (the emulator does): the last feed
// time is a volatile 64-bit word, written by the main loop only.
class WatchdogModel : public Watchdog {
 public:
  explicit WatchdogModel(uint32_t timeout_ms = kWatchdogTimeoutMs)
      : timeout_us_(static_cast<uint64_t>(timeout_ms) * 1000u) {}

  // Starts the timer (like TASKS_START): the first period begins now.
  void start(uint64_t now_us) {
    last_fed_us_ = now_us;
    running_ = true;
  }
  void feed(uint64_t now_us) override {
    last_fed_us_ = now_us;
    ++feeds_;
  }
  bool running() const { return running_; }
  bool expired(uint64_t now_us) const {
    return running_ && now_us >= last_fed_us_ && now_us - last_fed_us_ >= timeout_us_;
  }
  uint64_t last_fed_us() const { return last_fed_us_; }
  uint64_t timeout_us() const { return timeout_us_; }
  uint32_t feeds() const { return feeds_; }

 private:
  uint64_t timeout_us_;
  volatile uint64_t last_fed_us_ = 0;
  volatile bool running_ = false;
  uint32_t feeds_ = 0;
};

}  // namespace tb

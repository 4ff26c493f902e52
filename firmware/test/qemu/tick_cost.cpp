// The render tick's cost on the Cortex-M4F: instructions per Controller::tick, plain against
// shaped, counted on QEMU's mps2-an386 run with -icount shift=0 (one instruction per
// nanosecond of virtual time) by the SysTick timer on the processor clock
// (make -C firmware tick-cost). A calibration loop of a known instruction count converts
// SysTick counts to instructions. The worst case for shaping: 16 channels, a 5 V supply on
// 3 V motors (rated level 0.6, so every level change kicks at the full duty), every
// channel switched between full level and off every 30 ms, so each tick decides a kick or
// a brake pulse on every channel. Prints one line per drive; exits 1 when a shaped tick
// takes more than a tenth of the 1 ms tick at the board's 64 MHz (6,400 instructions).
#include <stdint.h>
#include <stdio.h>

#include "../../tactorbelt/src/core/controller.h"
#include "../../tactorbelt/src/core/protocol.h"
#include "../../tactorbelt/src/core/wire.h"

namespace {

volatile uint32_t* const kSystCsr = reinterpret_cast<volatile uint32_t*>(0xE000E010u);
volatile uint32_t* const kSystRvr = reinterpret_cast<volatile uint32_t*>(0xE000E014u);
volatile uint32_t* const kSystCvr = reinterpret_cast<volatile uint32_t*>(0xE000E018u);

void systick_start() {
  *kSystRvr = 0x00FFFFFFu;
  *kSystCvr = 0u;
  *kSystCsr = 0x5u;  // processor clock, no interrupt, enabled
}

uint32_t systick_now() { return *kSystCvr; }

uint32_t elapsed(uint32_t a, uint32_t b) { return (a - b) & 0x00FFFFFFu; }  // counts down

class NullMotors : public tb::MotorDriver {
 public:
  void write(const uint16_t* levels, uint8_t n) override {
    sum += levels[0] + levels[n - 1];
  }
  void write_in2(uint32_t mask, uint8_t n) override {
    (void)n;
    sum += mask;
  }
  uint32_t sum = 0;
};

class NullSink : public tb::ReplySink {
 public:
  void send(const uint8_t* packet, size_t n) override {
    (void)packet;
    (void)n;
  }
};

struct Rig {
  tb::Layout layout;
  NullMotors motors;
  tb::Controller controller{layout, motors, 800};
  NullSink sink;
  uint8_t seq = 0;
  uint64_t now_us = 0;

  Rig() {
    layout.set_even(tb::kMaxChannels);
    controller.set_drive_shaping(true);
    controller.set_heartbeat_ms(2000);
    controller.begin(0);
  }
  void send(uint8_t type, const uint8_t* payload, size_t n) {
    uint8_t packet[tb::kMaxPacket];
    const size_t len = tb::build_packet(type, seq++, payload, n, packet);
    uint8_t frame[tb::kMaxFrame];
    const size_t flen = tb::frame_packet(packet, len, frame, sizeof frame);
    controller.receive_bytes(frame, flen, now_us, sink);
  }
  void levels(uint16_t v) {
    uint8_t p[2 * tb::kMaxChannels];
    for (uint8_t k = 0; k < tb::kMaxChannels; ++k) tb::put_u16(&p[2 * k], v);
    send(tb::msg::kSetAmplitudes, p, sizeof p);
  }
};

// Instructions of `ticks` render ticks (the frames every 30 ms included) in `mode`.
uint32_t run(uint8_t mode, int ticks) {
  Rig rig;
  uint8_t drive[12] = {mode, 0xFF};
  tb::put_u16(&drive[2], 9830);   // start 0.15 (0.25 of the rated level)
  tb::put_u16(&drive[4], 39321);  // rated 0.6: 3 V motors on 5 V
  tb::put_u16(&drive[6], 400);
  tb::put_u16(&drive[8], 500);
  tb::put_u16(&drive[10], 400);
  rig.send(tb::msg::kSetDrive, drive, sizeof drive);
  const uint32_t t0 = systick_now();
  for (int i = 0; i < ticks; ++i) {
    if (i % 30 == 0) rig.levels((i / 30) % 2 == 0 ? 39321 : 0);
    rig.now_us += 1000;
    rig.controller.tick(rig.now_us);
  }
  return elapsed(t0, systick_now());
}

// Instructions of `ticks` render ticks of a dynamic PLAY_TARGET between two tactors (the
// shaper previews it: the stimulus's amplitudes are computed twice a tick) in `mode`.
uint32_t run_play(uint8_t mode, int ticks) {
  Rig rig;
  uint8_t drive[12] = {mode, 0xFF};
  tb::put_u16(&drive[2], 9830);
  tb::put_u16(&drive[4], 39321);
  tb::put_u16(&drive[6], 400);
  tb::put_u16(&drive[8], 500);
  tb::put_u16(&drive[10], 400);
  rig.send(tb::msg::kSetDrive, drive, sizeof drive);
  uint8_t p[14] = {};
  tb::put_u16(&p[0], 1125);  // between tactors 0 and 1 of 16
  p[2] = 1;                  // dynamic
  p[3] = 0;                  // the paper's law
  tb::put_u16(&p[4], 1500);
  tb::put_u16(&p[6], 200);   // a transit every 100 ms: the drive keeps changing
  tb::put_u16(&p[8], 50);
  tb::put_u32(&p[10], 0);    // until stopped
  rig.send(tb::msg::kPlayTarget, p, sizeof p);
  const uint32_t t0 = systick_now();
  for (int i = 0; i < ticks; ++i) {
    rig.now_us += 1000;
    rig.controller.tick(rig.now_us);
  }
  return elapsed(t0, systick_now());
}

// SysTick counts of a loop of `n` iterations of two instructions (subs, bne).
uint32_t calibrate(uint32_t n) {
  const uint32_t t0 = systick_now();
  __asm volatile(
      "1: subs %0, %0, #1\n"
      "   bne 1b\n"
      : "+r"(n)
      :
      : "cc");
  return elapsed(t0, systick_now());
}

}  // namespace

int main() {
  systick_start();
  const uint32_t loop_n = 1000000;
  const double per_count = 2.0 * loop_n / calibrate(loop_n);  // instructions per count
  const int ticks = 3000;
  const double plain = run(0, ticks) * per_count / ticks;
  const double shaped = run(tb::kDriveShaped, ticks) * per_count / ticks;
  printf("render tick, 16 channels: plain %.0f instructions, shaped %.0f instructions "
         "(%.1f %% of a 1 ms tick at 64 MHz, one cycle per instruction; %.1f instructions "
         "per SysTick count)\n",
         plain, shaped, shaped / 64000.0 * 100.0, per_count);
  const double play_plain = run_play(0, ticks) * per_count / ticks;
  const double play_shaped = run_play(tb::kDriveShaped, ticks) * per_count / ticks;
  printf("render tick, 16 channels, a dynamic PLAY_TARGET: plain %.0f instructions, shaped "
         "%.0f instructions (%.1f %% of a 1 ms tick at 64 MHz)\n",
         play_plain, play_shaped, play_shaped / 64000.0 * 100.0);
  return shaped <= 6400.0 && play_shaped <= 6400.0 ? 0 : 1;
}

#include "nrf_pwm_motors.h"

#if __has_include("nrf.h")
#include "nrf.h"
#endif

namespace {

// EasyDMA reads the compare values from RAM: one group of 4 per peripheral.
uint16_t g_sequence[2][4];

// POLARITY bit of a compare value: the output starts the period high and falls
// at COMPARE, so COMPARE counts of kSteps are "on" (active high).
constexpr uint16_t kFallingEdge = 0x8000;

NRF_PWM_Type* pwm(int i) { return i == 0 ? NRF_PWM0 : NRF_PWM1; }

}  // namespace

void NrfPwmMotors::begin(const pin_size_t* pins, uint8_t n) {
  n_ = n > kMaxOutputs ? kMaxOutputs : n;
  for (uint8_t k = 0; k < n_; ++k) {
    pinMode(pins[k], OUTPUT);
    digitalWrite(pins[k], LOW);
  }
  for (int i = 0; i < 2; ++i) {
    NRF_PWM_Type* p = pwm(i);
    p->ENABLE = PWM_ENABLE_ENABLE_Disabled << PWM_ENABLE_ENABLE_Pos;
    for (int c = 0; c < 4; ++c) {
      const uint8_t k = static_cast<uint8_t>(i * 4 + c);
      p->PSEL.OUT[c] = k < n_ ? static_cast<uint32_t>(digitalPinToPinName(pins[k]))
                              : (PWM_PSEL_OUT_CONNECT_Disconnected << PWM_PSEL_OUT_CONNECT_Pos);
      g_sequence[i][c] = kFallingEdge;  // duty 0
    }
    p->MODE = PWM_MODE_UPDOWN_Up << PWM_MODE_UPDOWN_Pos;
    p->PRESCALER = PWM_PRESCALER_PRESCALER_DIV_1 << PWM_PRESCALER_PRESCALER_Pos;
    p->COUNTERTOP = kSteps << PWM_COUNTERTOP_COUNTERTOP_Pos;
    p->LOOP = PWM_LOOP_CNT_Disabled << PWM_LOOP_CNT_Pos;
    p->DECODER = (PWM_DECODER_LOAD_Individual << PWM_DECODER_LOAD_Pos) |
                 (PWM_DECODER_MODE_RefreshCount << PWM_DECODER_MODE_Pos);
    p->SEQ[0].PTR = reinterpret_cast<uint32_t>(g_sequence[i]);
    p->SEQ[0].CNT = 4;
    p->SEQ[0].REFRESH = 0;
    p->SEQ[0].ENDDELAY = 0;
    p->SHORTS = 0;
    p->ENABLE = PWM_ENABLE_ENABLE_Enabled << PWM_ENABLE_ENABLE_Pos;
    running_[i] = false;
  }
}

void NrfPwmMotors::write(const uint16_t* levels, uint8_t n) {
  for (int i = 0; i < 2; ++i) {
    bool any = false;
    for (int c = 0; c < 4; ++c) {
      const uint8_t k = static_cast<uint8_t>(i * 4 + c);
      uint32_t duty = 0;
      if (k < n_ && k < n) duty = (static_cast<uint32_t>(levels[k]) * kSteps + 32767u) / 65535u;
      // COMPARE == COUNTERTOP is an edge case of the wave counter (Zephyr's nRF
      // driver avoids it too): full level runs at kSteps - 1 of kSteps.
      if (duty >= kSteps) duty = kSteps - 1u;
      g_sequence[i][c] = static_cast<uint16_t>(kFallingEdge | duty);
      any = any || duty != 0;
    }
    NRF_PWM_Type* p = pwm(i);
    if (any) {
      // Play the 4 values once; after the sequence the last values stay on.
      p->EVENTS_SEQEND[0] = 0;
      p->TASKS_SEQSTART[0] = 1;
      running_[i] = true;
    } else if (running_[i]) {
      p->TASKS_STOP = 1;
      running_[i] = false;
    }
  }
}

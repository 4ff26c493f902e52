#include "nrf_pwm_motors.h"

#include "nrf.h"  // nRF52840 MDK: NRF_PWM0/1, NRF_P0/1 and their bit fields

#include "src/core/pwm_sequencer.h"

namespace {

// EasyDMA reads the compare values from RAM: one group of 4 per peripheral.
uint16_t g_sequence[2][4];

// POLARITY bit of a compare value: the output starts the period high and falls
// at COMPARE, so COMPARE counts of kSteps are "on" (active high).
constexpr uint16_t kFallingEdge = 0x8000;

uint32_t micros32() { return static_cast<uint32_t>(micros()); }

tb::PwmSequencer<NRF_PWM_Type> g_pwm[2] = {
    tb::PwmSequencer<NRF_PWM_Type>(NRF_PWM0, micros32),
    tb::PwmSequencer<NRF_PWM_Type>(NRF_PWM1, micros32),
};

NRF_PWM_Type* pwm(int i) { return i == 0 ? NRF_PWM0 : NRF_PWM1; }

// A GPIO output driving low, by register: OUT cleared before the direction is set,
// so the pin never drives high on the way.
void gpio_output_low(uint32_t pin_name) {
  NRF_GPIO_Type* port = (pin_name >= 32) ? NRF_P1 : NRF_P0;
  const uint32_t bit = 1ul << (pin_name & 31u);
  port->OUTCLR = bit;
  port->PIN_CNF[pin_name & 31u] =
      (GPIO_PIN_CNF_DIR_Output << GPIO_PIN_CNF_DIR_Pos) |
      (GPIO_PIN_CNF_INPUT_Disconnect << GPIO_PIN_CNF_INPUT_Pos) |
      (GPIO_PIN_CNF_PULL_Disabled << GPIO_PIN_CNF_PULL_Pos) |
      (GPIO_PIN_CNF_DRIVE_S0S1 << GPIO_PIN_CNF_DRIVE_Pos);
  port->OUTCLR = bit;
}

// A GPIO output, by register: high or low.
void gpio_write(uint32_t pin_name, bool high) {
  NRF_GPIO_Type* port = (pin_name >= 32) ? NRF_P1 : NRF_P0;
  const uint32_t bit = 1ul << (pin_name & 31u);
  if (high) {
    port->OUTSET = bit;
  } else {
    port->OUTCLR = bit;
  }
}

}  // namespace

void NrfPwmMotors::begin(const PinName* pins, uint8_t n, const PinName* in2_pins) {
  n_ = n > kMaxOutputs ? kMaxOutputs : n;
  has_in2_ = in2_pins != nullptr;
  for (uint8_t k = 0; k < n_ && has_in2_; ++k) {
    in2_pin_[k] = static_cast<uint32_t>(in2_pins[k]);
    gpio_output_low(in2_pin_[k]);  // IN2 low first: the bridge can only coast or drive
  }
  for (uint8_t k = 0; k < n_; ++k) {
    gpio_output_low(static_cast<uint32_t>(pins[k]));
  }
  for (int i = 0; i < 2; ++i) {
    g_pwm[i].stop();  // disabled: the pins are the GPIO outputs above, low
    NRF_PWM_Type* p = pwm(i);
    for (int c = 0; c < 4; ++c) {
      const uint8_t k = static_cast<uint8_t>(i * 4 + c);
      p->PSEL.OUT[c] = k < n_ ? static_cast<uint32_t>(pins[k])
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
  }
}

void NrfPwmMotors::write(const uint16_t* levels, uint8_t n) {
  for (int i = 0; i < 2; ++i) {
    bool any = false;
    for (int c = 0; c < 4; ++c) {
      const uint8_t k = static_cast<uint8_t>(i * 4 + c);
      const uint16_t duty = (k < n_ && k < n) ? tb::level_to_duty(levels[k], kSteps) : 0;
      g_sequence[i][c] = static_cast<uint16_t>(kFallingEdge | duty);
      any = any || duty != 0;
    }
    // Play the 4 values once; after the sequence the last values stay on. All 0:
    // stop (bounded wait for EVENTS_STOPPED), then disable: pins low via GPIO.
    if (any) {
      g_pwm[i].start();
    } else {
      g_pwm[i].stop();
    }
  }
}

void NrfPwmMotors::write_in2(uint32_t mask, uint8_t n) {
  if (!has_in2_) return;
  for (uint8_t k = 0; k < n_ && k < n; ++k) gpio_write(in2_pin_[k], ((mask >> k) & 1u) != 0);
}

void NrfPwmMotors::all_off() {
  for (uint8_t k = 0; k < n_ && has_in2_; ++k) gpio_write(in2_pin_[k], false);
  for (int i = 0; i < 2; ++i) {
    for (int c = 0; c < 4; ++c) g_sequence[i][c] = kFallingEdge;
    g_pwm[i].stop();
  }
}

uint32_t NrfPwmMotors::stop_timeouts() const {
  return g_pwm[0].stop_timeouts() + g_pwm[1].stop_timeouts();
}

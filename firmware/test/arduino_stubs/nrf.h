// Stub of the nRF52840 MDK (nrf.h) for the registers and bit fields the motor
// driver uses, with the MDK's names and values: for the compile check only.
#pragma once

#include <stdint.h>

typedef struct {
  volatile uint32_t PTR;
  volatile uint32_t CNT;
  volatile uint32_t REFRESH;
  volatile uint32_t ENDDELAY;
  volatile const uint32_t RESERVED[4];
} PWM_SEQ_Type;

typedef struct {
  volatile uint32_t OUT[4];
} PWM_PSEL_Type;

typedef struct {
  volatile const uint32_t RESERVED0;
  volatile uint32_t TASKS_STOP;
  volatile uint32_t TASKS_SEQSTART[2];
  volatile uint32_t TASKS_NEXTSTEP;
  volatile const uint32_t RESERVED1[60];
  volatile uint32_t EVENTS_STOPPED;
  volatile uint32_t EVENTS_SEQSTARTED[2];
  volatile uint32_t EVENTS_SEQEND[2];
  volatile uint32_t EVENTS_PWMPERIODEND;
  volatile uint32_t EVENTS_LOOPSDONE;
  volatile const uint32_t RESERVED2[56];
  volatile uint32_t SHORTS;
  volatile const uint32_t RESERVED3[63];
  volatile uint32_t INTEN;
  volatile uint32_t INTENSET;
  volatile uint32_t INTENCLR;
  volatile const uint32_t RESERVED4[125];
  volatile uint32_t ENABLE;
  volatile uint32_t MODE;
  volatile uint32_t COUNTERTOP;
  volatile uint32_t PRESCALER;
  volatile uint32_t DECODER;
  volatile uint32_t LOOP;
  volatile const uint32_t RESERVED5[2];
  PWM_SEQ_Type SEQ[2];
  PWM_PSEL_Type PSEL;
} NRF_PWM_Type;

#define NRF_PWM0 ((NRF_PWM_Type*)0x4001C000UL)
#define NRF_PWM1 ((NRF_PWM_Type*)0x40021000UL)

#define PWM_ENABLE_ENABLE_Pos (0UL)
#define PWM_ENABLE_ENABLE_Disabled (0UL)
#define PWM_ENABLE_ENABLE_Enabled (1UL)
#define PWM_MODE_UPDOWN_Pos (0UL)
#define PWM_MODE_UPDOWN_Up (0UL)
#define PWM_COUNTERTOP_COUNTERTOP_Pos (0UL)
#define PWM_PRESCALER_PRESCALER_Pos (0UL)
#define PWM_PRESCALER_PRESCALER_DIV_1 (0UL)
#define PWM_DECODER_LOAD_Pos (0UL)
#define PWM_DECODER_LOAD_Individual (2UL)
#define PWM_DECODER_MODE_Pos (8UL)
#define PWM_DECODER_MODE_RefreshCount (0UL)
#define PWM_LOOP_CNT_Pos (0UL)
#define PWM_LOOP_CNT_Disabled (0UL)
#define PWM_PSEL_OUT_CONNECT_Pos (31UL)
#define PWM_PSEL_OUT_CONNECT_Disconnected (1UL)

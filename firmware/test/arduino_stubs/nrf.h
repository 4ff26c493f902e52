// Stub of the nRF52840 MDK (nrf.h) for the registers and bit fields the sketch
// uses (PWM, GPIO, WDT, POWER.RESETREAS), with the MDK's names, offsets and
// values: for the compile check only.
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

typedef struct {
  volatile const uint32_t RESERVED0[321];
  volatile uint32_t OUT;        // 0x504
  volatile uint32_t OUTSET;
  volatile uint32_t OUTCLR;
  volatile const uint32_t IN;
  volatile uint32_t DIR;
  volatile uint32_t DIRSET;
  volatile uint32_t DIRCLR;
  volatile uint32_t LATCH;
  volatile uint32_t DETECTMODE;
  volatile const uint32_t RESERVED1[118];
  volatile uint32_t PIN_CNF[32];  // 0x700
} NRF_GPIO_Type;

#define NRF_P0 ((NRF_GPIO_Type*)0x50000000UL)
#define NRF_P1 ((NRF_GPIO_Type*)0x50000300UL)

#define GPIO_PIN_CNF_DIR_Pos (0UL)
#define GPIO_PIN_CNF_DIR_Output (1UL)
#define GPIO_PIN_CNF_INPUT_Pos (1UL)
#define GPIO_PIN_CNF_INPUT_Disconnect (1UL)
#define GPIO_PIN_CNF_PULL_Pos (2UL)
#define GPIO_PIN_CNF_PULL_Disabled (0UL)
#define GPIO_PIN_CNF_DRIVE_Pos (8UL)
#define GPIO_PIN_CNF_DRIVE_S0S1 (0UL)

typedef struct {
  volatile uint32_t TASKS_START;  // 0x000
  volatile const uint32_t RESERVED0[63];
  volatile uint32_t EVENTS_TIMEOUT;  // 0x100
  volatile const uint32_t RESERVED1[128];
  volatile uint32_t INTENSET;  // 0x304
  volatile uint32_t INTENCLR;
  volatile const uint32_t RESERVED2[61];
  volatile const uint32_t RUNSTATUS;  // 0x400
  volatile const uint32_t REQSTATUS;
  volatile const uint32_t RESERVED3[63];
  volatile uint32_t CRV;  // 0x504
  volatile uint32_t RREN;
  volatile uint32_t CONFIG;
  volatile const uint32_t RESERVED4[60];
  volatile uint32_t RR[8];  // 0x600
} NRF_WDT_Type;

#define NRF_WDT ((NRF_WDT_Type*)0x40010000UL)

#define WDT_CONFIG_SLEEP_Pos (0UL)
#define WDT_CONFIG_SLEEP_Run (1UL)
#define WDT_CONFIG_HALT_Pos (3UL)
#define WDT_CONFIG_HALT_Pause (0UL)
#define WDT_RREN_RR0_Pos (0UL)
#define WDT_RREN_RR0_Enabled (1UL)
#define WDT_RR_RR_Reload (0x6E524635UL)

typedef struct {
  volatile const uint32_t RESERVED0[256];
  volatile uint32_t RESETREAS;  // 0x400
} NRF_POWER_Type;

#define NRF_POWER ((NRF_POWER_Type*)0x40000000UL)

#define POWER_RESETREAS_RESETPIN_Msk (0x1UL << 0)
#define POWER_RESETREAS_DOG_Msk (0x1UL << 1)
#define POWER_RESETREAS_SREQ_Msk (0x1UL << 2)
#define POWER_RESETREAS_LOCKUP_Msk (0x1UL << 3)

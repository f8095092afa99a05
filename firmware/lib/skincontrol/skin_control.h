/* Heater control, fault detection and the self-test of a skin board: plain C, no hardware.
 *
 * The board's sampling code calls skin_control_step once per sample with every taxel's count;
 * it returns the heater duties, the heater on/off bits for this sample and the status bits.
 * Being free of AVR registers, it compiles on the host, where tests drive it.
 */
#ifndef SKIN_CONTROL_H
#define SKIN_CONTROL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SKIN_COUNT_MAX 4095u      /* 12-bit scale */
#define SKIN_RAIL_LOW 4u          /* a count at or below this sits on the low rail */
#define SKIN_RAIL_HIGH 4091u      /* at or above: the high rail */
#define SKIN_RAIL_SAMPLES 20u     /* THERMISTOR_FAULT after this many samples on a rail */
#define SKIN_HEATER_FAULT_S 10u   /* HEATER_FAULT after this long at full duty below setpoint */
#define SKIN_SELFTEST_MIN_RISE 8  /* counts: a smaller rise is no response */

enum { SKIN_MODE_DUTY = 0, SKIN_MODE_SETPOINT = 1 };

typedef struct {
    uint8_t mode;      /* SKIN_MODE_DUTY or SKIN_MODE_SETPOINT */
    uint8_t duty;      /* commanded duty (DUTY mode) */
    uint8_t out;       /* duty applied at the last step */
    uint8_t sd;        /* sigma-delta accumulator */
    uint16_t setpoint; /* 12-bit count (SETPOINT mode) */
    int32_t integ;     /* PI integrator, duty << 16 */
    uint8_t latched;   /* latched fault bits: THERMISTOR_FAULT, HEATER_FAULT, OVER_TEMPERATURE */
    uint8_t rail_run;  /* consecutive samples on a rail */
    uint16_t full_run; /* consecutive samples at full duty below the setpoint */
} skin_heater_t;

typedef struct {
    /* settings */
    uint16_t n;
    skin_heater_t *heater;  /* n */
    uint32_t power_budget;  /* the sum of duties over all taxels may not exceed this */
    uint16_t over_temp;     /* count of the over-temperature cut-off */
    int16_t kp;             /* duty per count, << 8 */
    int16_t ki;             /* duty per count-sample, << 16 */
    uint16_t rate_hz;       /* sample rate (for time-based thresholds) */
    /* self-test */
    uint8_t st_active, st_done, st_token, st_duty;
    uint16_t st_taxel, st_samples, st_elapsed;
    uint16_t *st_base;      /* n: counts when the current pulse started */
    int16_t *st_response;   /* n */
    uint16_t *st_strongest; /* n */
} skin_control_t;

/* Set every heater off, in duty mode, with no faults. */
void skin_control_init(skin_control_t *c);

/* Commands; taxel SKIN_ALL_TAXELS (0xFFFF) means every taxel. */
void skin_control_set_duty(skin_control_t *c, uint16_t taxel, uint8_t duty);
void skin_control_set_setpoint(skin_control_t *c, uint16_t taxel, uint16_t count);
void skin_control_clear_faults(skin_control_t *c);
/* Start a self-test; returns 0, or 1 when one is already running. */
int skin_control_selftest(skin_control_t *c, uint8_t token, uint16_t pulse_ms, uint8_t duty);

/* One sample. counts: n 12-bit counts; saturated: n booleans (an oversample hit a rail).
 * Writes the taxel words (count + status), the duties applied and the heater bits
 * (bit j of bits[k] = heater 8k + j, ceil(n / 8) bytes). Returns the board flags of this
 * sample (the OR of the taxel status bits, POWER_LIMITED, SELFTEST). After the last pulse of
 * a self-test, st_done is set and st_response / st_strongest hold the result. */
uint16_t skin_control_step(skin_control_t *c, const uint16_t *counts, const uint8_t *saturated,
                           uint16_t *words, uint8_t *duty, uint8_t *bits);

#ifdef __cplusplus
}
#endif

#endif

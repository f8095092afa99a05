#if defined(__AVR__)
/* Speed over size here: this loop runs for every taxel of every sample. */
#pragma GCC optimize("O2")
#endif

#include "skin_control.h"

#include "skin_proto.h"

static const uint8_t LATCHING = SKIN_TAXEL_THERMISTOR_FAULT | SKIN_TAXEL_HEATER_FAULT |
                                SKIN_TAXEL_OVER_TEMPERATURE;

void skin_control_init(skin_control_t *c)
{
    for (uint16_t i = 0; i < c->n; i++) {
        skin_heater_t *h = &c->heater[i];
        h->mode = SKIN_MODE_DUTY;
        h->duty = h->out = h->sd = 0;
        h->setpoint = 0;
        h->integ = 0;
        h->latched = 0;
        h->rail_run = 0;
        h->full_run = 0;
    }
    c->st_active = c->st_done = 0;
}

void skin_control_set_duty(skin_control_t *c, uint16_t taxel, uint8_t duty)
{
    for (uint16_t i = 0; i < c->n; i++) {
        if (taxel != SKIN_ALL_TAXELS && taxel != i)
            continue;
        c->heater[i].mode = SKIN_MODE_DUTY;
        c->heater[i].duty = duty;
        c->heater[i].integ = 0;
    }
}

void skin_control_set_setpoint(skin_control_t *c, uint16_t taxel, uint16_t count)
{
    for (uint16_t i = 0; i < c->n; i++) {
        if (taxel != SKIN_ALL_TAXELS && taxel != i)
            continue;
        skin_heater_t *h = &c->heater[i];
        if (count == 0) {  /* 0 = off */
            h->mode = SKIN_MODE_DUTY;
            h->duty = 0;
        } else {
            h->mode = SKIN_MODE_SETPOINT;
            h->setpoint = count;
        }
        h->integ = 0;
        h->full_run = 0;
    }
}

void skin_control_clear_faults(skin_control_t *c)
{
    for (uint16_t i = 0; i < c->n; i++) {
        c->heater[i].latched = 0;
        c->heater[i].rail_run = 0;
        c->heater[i].full_run = 0;
    }
}

int skin_control_selftest(skin_control_t *c, uint8_t token, uint16_t pulse_ms, uint8_t duty)
{
    if (c->st_active)
        return 1;
    uint32_t samples = ((uint32_t)pulse_ms * c->rate_hz + 999u) / 1000u;
    c->st_samples = samples == 0 ? 1 : (samples > 0xFFFFu ? 0xFFFFu : (uint16_t)samples);
    c->st_active = 1;
    c->st_done = 0;
    c->st_token = token;
    c->st_duty = duty;
    c->st_taxel = 0;
    c->st_elapsed = 0;
    return 0;
}

/* The PI law: duty from the error (setpoint - count), with the integrator clamped to the
 * duty range so it cannot wind up while the output saturates. */
static uint8_t pi_step(const skin_control_t *c, skin_heater_t *h, uint16_t count)
{
    int32_t err = (int32_t)h->setpoint - (int32_t)count;
    int32_t integ = h->integ + (int32_t)c->ki * err;
    const int32_t top = (int32_t)255 << 16;
    if (integ < 0)
        integ = 0;
    if (integ > top)
        integ = top;
    h->integ = integ;
    int32_t u = ((int32_t)c->kp * err) / 256 + (integ >> 16);
    if (u < 0)
        u = 0;
    if (u > 255)
        u = 255;
    return (uint8_t)u;
}

static void selftest_step(skin_control_t *c, const uint16_t *counts)
{
    if (c->st_elapsed == 0) {
        for (uint16_t j = 0; j < c->n; j++)
            c->st_base[j] = counts[j];
    }
    if (++c->st_elapsed <= c->st_samples)
        return;
    /* The pulse is over: the response of the pulsed taxel and the taxel that rose most. */
    uint16_t i = c->st_taxel;
    int32_t best = SKIN_SELFTEST_MIN_RISE - 1;
    uint16_t strongest = SKIN_ALL_TAXELS;
    for (uint16_t j = 0; j < c->n; j++) {
        int32_t rise = (int32_t)counts[j] - (int32_t)c->st_base[j];
        if (rise > best) {
            best = rise;
            strongest = j;
        }
    }
    int32_t own = (int32_t)counts[i] - (int32_t)c->st_base[i];
    c->st_response[i] = (int16_t)own;
    c->st_strongest[i] = strongest;
    if (own < SKIN_SELFTEST_MIN_RISE)
        c->heater[i].latched |= SKIN_TAXEL_HEATER_FAULT;
    c->st_elapsed = 0;
    if (++c->st_taxel >= c->n) {
        c->st_active = 0;
        c->st_done = 1;
    }
}

uint16_t skin_control_step(skin_control_t *c, const uint16_t *counts, const uint8_t *saturated,
                           uint16_t *words, uint8_t *duty, uint8_t *bits)
{
    uint16_t flags = 0;
    uint32_t total = 0;
    const uint16_t n = c->n;
    const uint8_t st_active = c->st_active;
    if (st_active)
        selftest_step(c, counts);
    skin_heater_t *h = c->heater;
    for (uint16_t i = 0; i < n; i++, h++) {
        uint16_t count = counts[i];
        uint8_t status = saturated[i] ? SKIN_TAXEL_SATURATED : 0;
        if (count <= SKIN_RAIL_LOW || count >= SKIN_RAIL_HIGH) {
            if (h->rail_run < 255)
                h->rail_run++;
            if (h->rail_run >= SKIN_RAIL_SAMPLES)
                h->latched |= SKIN_TAXEL_THERMISTOR_FAULT;
        } else {
            h->rail_run = 0;
        }
        if (count >= c->over_temp && !(h->latched & SKIN_TAXEL_THERMISTOR_FAULT))
            h->latched |= SKIN_TAXEL_OVER_TEMPERATURE;
        uint8_t u;
        if (st_active) {
            u = (i == c->st_taxel) ? c->st_duty : 0;
        } else if (h->mode == SKIN_MODE_SETPOINT) {
            u = pi_step(c, h, count);
            if (u == 255 && count < h->setpoint) {
                if (h->full_run < 0xFFFFu)
                    h->full_run++;
                if ((uint32_t)h->full_run >= (uint32_t)SKIN_HEATER_FAULT_S * c->rate_hz)
                    h->latched |= SKIN_TAXEL_HEATER_FAULT;
            } else {
                h->full_run = 0;
            }
        } else {
            u = h->duty;
        }
        if (h->latched & LATCHING)
            u = 0;  /* a fault holds the heater off until CLEAR_FAULTS */
        status |= h->latched;
        h->out = u;
        total += u;
        words[i] = SKIN_WORD(count, status);
        flags |= status;
    }
    /* The power budget scales every duty by the same factor. */
    if (total > c->power_budget) {
        flags |= SKIN_FLAG_POWER_LIMITED;
        for (uint16_t i = 0; i < n; i++)
            c->heater[i].out = (uint8_t)(((uint32_t)c->heater[i].out * c->power_budget) / total);
    }
    /* First-order sigma-delta: on for `out` of every 255 samples; 255 is always on. */
    uint8_t byte = 0, mask = 1;
    h = c->heater;
    for (uint16_t i = 0; i < n; i++, h++) {
        uint8_t out = h->out;
        duty[i] = out;
        uint16_t acc = (uint16_t)h->sd + out;
        if (acc >= 255u) {
            acc -= 255u;
            byte |= mask;
        }
        h->sd = (uint8_t)acc;
        mask <<= 1;
        if (!mask) {
            *bits++ = byte;
            byte = 0;
            mask = 1;
        }
    }
    if (mask != 1)
        *bits = byte;
    if (c->st_active)
        flags |= SKIN_FLAG_SELFTEST;
    return flags;
}

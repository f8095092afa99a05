/* Sampling from a timer interrupt, heater output and command handling (see skin_board.h).
 *
 * Timer 1 ticks at the sample rate and starts a scan; the ADC interrupt then walks every taxel
 * (through the multiplexers) and the ambient sensor, SKIN_OVERSAMPLING conversions each, and
 * publishes the sums when the scan is done. The main loop turns a published scan into heater
 * duties and a SAMPLE. Nothing here blocks inside an interrupt.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <string.h>

#include "skin_board.h"
#include "skin_control.h"

#define N SKIN_TAXELS
#define F SKIN_FORCE_INPUTS
#define SLOTS (N + 1 + F) /* taxels, the ambient sensor, the force inputs */
/* GPIOR0 marks, for the emulator's timing (firmware/sim/skin_avr.c, `skin bench firmware`), in
 * builds with SKIN_TIMING_MARKS only (`make -C firmware timing`): bit 0 while the main loop works
 * on a sample, bit 1 while a scan converts. Two cycles each; other builds have none, so a
 * change here cannot move their conversions by a cycle. */
#define MARK_POLL 0
#define MARK_SCAN 1
#define GROUPS ((N + 7) / 8)
#define TIMER_HZ (F_CPU / 64UL) /* timer 1 runs at F_CPU / 64 */

uint8_t skin_transport_kind = 0;
uint16_t skin_transport_div = 0;
uint16_t skin_transport_max_rate = 0xFFFF;

/* ---- shared with the interrupts ---- */
static volatile uint16_t acc[SLOTS];      /* sums of the scan under way; [N] = ambient, then force */
static volatile uint8_t sat[N + 1];
static volatile uint16_t done_acc[SLOTS]; /* the last finished scan */
static volatile uint8_t done_sat[N + 1];
static volatile uint32_t done_seq, done_time;
static volatile uint8_t done_ready, lost, overrun;
static volatile uint8_t scan_busy, slot_os, slot;
/* The scan order, computed once: per slot, the ADC channel, the multiplexer select lines and
 * the input (taxel, or N for the ambient sensor). Multiplexer channel c of every multiplexer
 * is converted before the select lines move on, so they move 16 times per scan. */
static uint8_t slot_adc[SLOTS], slot_sel[SLOTS], slot_input[SLOTS];
static volatile uint32_t seq, now_us, scan_seq, scan_time;
static volatile uint32_t period_us;

/* ---- main loop state ---- */
static skin_heater_t heaters[N];
static uint16_t st_base[N], st_strongest[N];
static int16_t st_response[N];
static skin_control_t control;
static uint16_t counts[N], words[N];
#if F > 0
static uint16_t force_mn[N];
/* mN per 10-bit count, << 16: the force stage's output is linear, SKIN_FORCE_FULL_MN at 1.1 V */
#define FORCE_SCALE ((uint32_t)((SKIN_FORCE_FULL_MN * 65536UL + 511UL) / 1023UL))
#endif
static uint8_t saturated[N], duty[N], bits[GROUPS];
static uint8_t streaming = SKIN_STREAM_AT_BOOT;
static uint16_t rate_hz = SKIN_RATE_HZ;

static inline void adc_select(uint8_t ch)
{
#if defined(__AVR_ATmega2560__) || defined(__AVR_ATmega1280__)
    ADMUX = (1 << REFS1) | (ch & 7); /* internal 1.1 V */
    if (ch & 8)
        ADCSRB |= (1 << MUX5);
    else
        ADCSRB &= ~(1 << MUX5);
#else
    ADMUX = (1 << REFS1) | (1 << REFS0) | (ch & 7); /* internal 1.1 V */
#endif
}

static inline void mux_select(uint8_t c)
{
#if defined(__AVR_ATmega2560__) || defined(__AVR_ATmega1280__)
    PORTA = (PORTA & 0xF0) | (c & 0x0F);
#else
    PORTD = (PORTD & 0x0F) | (uint8_t)(c << 4);
#endif
}

static void build_scan(void)
{
    uint8_t k = 0;
#if SKIN_MUXES > 0
    for (uint8_t c = 0; c < 16; c++)
        for (uint8_t m = 0; m < SKIN_MUXES; m++)
            if (m * 16 + c < N) {
                slot_adc[k] = m;
                slot_sel[k] = c;
                slot_input[k++] = (uint8_t)(m * 16 + c);
            }
#else
    for (uint8_t t = 0; t < N; t++) {
        slot_adc[k] = t;
        slot_sel[k] = 0;
        slot_input[k++] = t;
    }
#endif
    slot_adc[k] = SKIN_AMBIENT_CHANNEL;
    slot_sel[k] = 15;
    slot_input[k++] = N;
#if F > 0
    /* the force inputs after the ambient sensor, one conversion each at the force prescaler */
#if SKIN_MUXES > 0
    for (uint8_t c = 0; c < 16; c++)
        for (uint8_t m = 0; m < SKIN_FORCE_MUXES; m++)
            if (m * 16 + c < F) {
                slot_adc[k] = (uint8_t)(SKIN_AMBIENT_CHANNEL + 1 + m);
                slot_sel[k] = c;
                slot_input[k++] = (uint8_t)(N + 1 + m * 16 + c);
            }
#else
    for (uint8_t f = 0; f < F; f++) {
        slot_adc[k] = (uint8_t)(SKIN_AMBIENT_CHANNEL + 1 + f);
        slot_sel[k] = 0;
        slot_input[k++] = (uint8_t)(N + 1 + f);
    }
#endif
#endif
}

static uint8_t adc_prescaler_bits(uint16_t div)
{
    return div == 128 ? 7 : div == 64 ? 6 : div == 32 ? 5 : div == 16 ? 4 : div == 8 ? 3 : 2;
}

ISR(TIMER1_COMPA_vect)
{
    uint32_t t = now_us;
    now_us = t + period_us;
    uint32_t s = seq++;
    if (scan_busy) {
        overrun = 1; /* the conversions outran the period: this sample is skipped */
        return;
    }
    scan_seq = s;
    scan_time = t;
    MARK_ON(MARK_SCAN);
    for (uint8_t i = 0; i <= N; i++) {
        acc[i] = 0;
        sat[i] = 0;
    }
#if F > 0
    for (uint8_t i = N + 1; i < SLOTS; i++)
        acc[i] = 0;
    ADCSRA = (1 << ADEN) | (1 << ADIE) | adc_prescaler_bits(SKIN_ADC_PRESCALER);
#endif
    scan_busy = 1;
    slot_os = 0;
    slot = 0;
#if SKIN_MUXES > 0
    mux_select(slot_sel[0]);
#endif
    adc_select(slot_adc[0]);
    ADCSRA |= (1 << ADSC);
}

ISR(ADC_vect)
{
    uint16_t v = ADC;
    uint8_t k = slot;
    uint8_t i = slot_input[k];
    acc[i] += v;
#if F > 0
    if (k > N) { /* a force input: one conversion */
        if (++k < SLOTS) {
            slot = k;
#if SKIN_MUXES > 0
            if (slot_sel[k] != slot_sel[k - 1])
                mux_select(slot_sel[k]);
#endif
            adc_select(slot_adc[k]);
            ADCSRA |= (1 << ADSC);
            return;
        }
        goto scan_done;
    }
#endif
    if (v == 0 || v >= 1023)
        sat[i] = 1;
    if (++slot_os < SKIN_OVERSAMPLING) {
        ADCSRA |= (1 << ADSC);
        return;
    }
    slot_os = 0;
    if (++k < SLOTS) {
        slot = k;
#if SKIN_MUXES > 0
        if (slot_sel[k] != slot_sel[k - 1])
            mux_select(slot_sel[k]);
#endif
        adc_select(slot_adc[k]);
#if F > 0
        if (k > N) { /* the first force input: the faster ADC clock */
            ADCSRA = (1 << ADEN) | (1 << ADIE) | (1 << ADSC)
                     | adc_prescaler_bits(SKIN_FORCE_PRESCALER);
            return;
        }
#endif
        ADCSRA |= (1 << ADSC);
        return;
    }
#if F > 0
scan_done:
#endif
    if (done_ready)
        lost = 1; /* the main loop did not take the previous scan in time */
    for (uint8_t k = 0; k <= N; k++) {
        done_acc[k] = acc[k];
        done_sat[k] = sat[k];
    }
#if F > 0
    for (uint8_t k = N + 1; k < SLOTS; k++)
        done_acc[k] = acc[k];
#endif
    done_seq = scan_seq;
    done_time = scan_time;
    done_ready = 1;
    scan_busy = 0;
    MARK_OFF(MARK_SCAN);
}

static void set_rate(uint16_t rate)
{
    uint16_t top = (uint16_t)(TIMER_HZ / rate - 1);
    uint8_t sreg = SREG;
    cli();
    OCR1A = top;
    TCNT1 = 0;
    period_us = (top + 1UL) * 64UL / (F_CPU / 1000000UL); /* exact for whole MHz */
    SREG = sreg;
    rate_hz = rate;
    control.rate_hz = rate;
}

static void heaters_out(void)
{
    for (int8_t k = GROUPS - 1; k >= 0; k--) {
        SPDR = bits[k];
        while (!(SPSR & (1 << SPIF))) {
        }
    }
    PORTB |= (1 << PB0); /* latch */
    PORTB &= ~(1 << PB0);
}

uint16_t skin_board_max_rate(void)
{
    uint16_t r = (uint16_t)SKIN_MAX_RATE_ADC;
    return skin_transport_max_rate < r ? skin_transport_max_rate : r;
}

void skin_board_begin(void)
{
    control.n = N;
    control.heater = heaters;
    control.power_budget = SKIN_POWER_BUDGET;
    control.over_temp = SKIN_OVER_TEMP_COUNT;
    control.kp = SKIN_KP;
    control.ki = SKIN_KI;
    control.rate_hz = rate_hz;
    control.st_base = st_base;
    control.st_response = st_response;
    control.st_strongest = st_strongest;
    skin_control_init(&control);
    build_scan();

    /* heaters: the 74HC595 chain on hardware SPI, latch on PB0; all off first */
#if defined(__AVR_ATmega2560__) || defined(__AVR_ATmega1280__)
    DDRB |= (1 << PB0) | (1 << PB1) | (1 << PB2);
    DDRA |= 0x0F; /* multiplexer select */
#else
    DDRB |= (1 << PB0) | (1 << PB2) | (1 << PB3) | (1 << PB5);
    PORTB |= (1 << PB2); /* SS high: stays SPI master */
    DDRD |= 0xF0;        /* multiplexer select */
#endif
    SPCR = (1 << SPE) | (1 << MSTR);
    SPSR = (1 << SPI2X);
    memset(bits, 0, sizeof bits);
    heaters_out();

    adc_select(0);
    ADCSRA = (1 << ADEN) | (1 << ADIE) | adc_prescaler_bits(SKIN_ADC_PRESCALER);

    TCCR1A = 0;
    TCCR1B = (1 << WGM12) | (1 << CS11) | (1 << CS10); /* CTC, F_CPU / 64 */
    set_rate(rate_hz <= skin_board_max_rate() ? rate_hz : skin_board_max_rate());
    TIMSK1 = (1 << OCIE1A);
    sei();
}

static int16_t ambient_centi(uint16_t count12, uint8_t *fault)
{
    if (count12 <= SKIN_RAIL_LOW || count12 >= SKIN_RAIL_HIGH) {
        *fault = 1;
        return SKIN_AMBIENT_UNKNOWN;
    }
    *fault = 0;
    /* LM35: 10 mV per deg C on the 1.1 V reference: 0.01 deg C = 110000 / 4095 per count */
    return (int16_t)(((uint32_t)count12 * 110000UL + 2047UL) / 4095UL / 10UL);
}

void skin_board_poll(void)
{
    static uint8_t body[5 + 4 * N];
    if (!done_ready)
        return;
    MARK_ON(MARK_POLL);
    uint32_t s, t;
    uint16_t amb;
    uint8_t was_lost, was_overrun;
    cli();
    for (uint8_t i = 0; i < N; i++) {
        counts[i] = (uint16_t)(((uint32_t)done_acc[i] * 4UL) / SKIN_OVERSAMPLING);
        saturated[i] = done_sat[i];
    }
    amb = (uint16_t)(((uint32_t)done_acc[N] * 4UL) / SKIN_OVERSAMPLING);
#if F > 0
    for (uint8_t f = 0; f < F; f++) /* the raw 10-bit counts, converted outside cli */
        force_mn[f] = done_acc[N + 1 + f];
#endif
    s = done_seq;
    t = done_time;
    was_lost = lost;
    was_overrun = overrun;
    lost = overrun = 0;
    done_ready = 0;
    sei();

    uint16_t flags = skin_control_step(&control, counts, saturated, words, duty, bits);
    heaters_out();
    uint8_t amb_fault;
    int16_t ambient = ambient_centi(amb, &amb_fault);
    if (amb_fault)
        flags |= SKIN_FLAG_AMBIENT_FAULT;
    if (was_lost)
        flags |= SKIN_FLAG_TX_OVERRUN;
    if (was_overrun)
        flags |= SKIN_FLAG_SAMPLE_OVERRUN;
    if (streaming) {
#if F > 0
        for (uint8_t f = 0; f < F; f++)
            force_mn[f] = (uint16_t)(((uint32_t)force_mn[f] * FORCE_SCALE + 32768UL) >> 16);
        for (uint8_t f = F; f < N; f++)
            force_mn[f] = SKIN_FORCE_NONE;
#endif
        skin_sample_t sample = {s, t, N, words, duty, ambient,
                                (uint16_t)(flags | SKIN_FLAG_STREAMING)};
#if F > 0
        skin_transport_send_sample_force(&sample, force_mn);
#else /* (a build without force keeps its code, and its cycles, as they were) */
        skin_transport_send_sample(&sample);
#endif
    }
    if (control.st_done) {
        control.st_done = 0;
        size_t len = skin_pack_selftest_result(control.st_token, N, st_response, st_strongest,
                                               body);
        skin_transport_send_reply(body, len);
    }
    MARK_OFF(MARK_POLL);
}

void skin_board_error(const skin_error_t *err)
{
    uint8_t body[8];
    skin_transport_send_reply(body, skin_pack_error(err, body));
}

static void ack(const skin_command_t *cmd)
{
    uint8_t body[4];
    skin_transport_send_reply(body, skin_pack_ack(cmd->token, cmd->type, body));
}

static void busy(const skin_command_t *cmd)
{
    skin_error_t e = {cmd->token, cmd->type, SKIN_ERR_BUSY, 0};
    skin_board_error(&e);
}

void skin_board_command(const skin_command_t *cmd)
{
    switch (cmd->type) {
    case SKIN_START:
        streaming = 1;
        ack(cmd);
        break;
    case SKIN_STOP:
        streaming = 0;
        ack(cmd);
        break;
    case SKIN_SET_RATE:
        set_rate(cmd->value);
        ack(cmd);
        break;
    case SKIN_SET_DUTY:
        if (control.st_active)
            return busy(cmd);
        skin_control_set_duty(&control, cmd->taxel, cmd->duty);
        ack(cmd);
        break;
    case SKIN_SET_SETPOINT:
        if (control.st_active)
            return busy(cmd);
        skin_control_set_setpoint(&control, cmd->taxel, cmd->value);
        ack(cmd);
        break;
    case SKIN_SELFTEST:
        if (skin_control_selftest(&control, cmd->token, cmd->value, cmd->duty))
            return busy(cmd);
        ack(cmd);
        break;
    case SKIN_CLEAR_FAULTS:
        skin_control_clear_faults(&control);
        ack(cmd);
        break;
    case SKIN_IDENTIFY: {
        skin_identity_t id;
        id.token = cmd->token;
        id.fw_major = SKIN_FW_MAJOR;
        id.fw_minor = SKIN_FW_MINOR;
        id.fw_patch = SKIN_FW_PATCH;
        id.board_id = SKIN_BOARD_ID;
#if defined(__AVR_ATmega2560__)
        id.mcu = 2;
#elif defined(__AVR_ATmega328P__)
        id.mcu = 1;
#else
        id.mcu = 0;
#endif
        id.transport = skin_transport_kind;
        id.options = (SKIN_MUXES > 0 ? 1 : 0) | 2 | (F > 0 ? SKIN_OPTION_FORCE : 0);
        id.taxels = N;
        id.adc_bits = 12;
        id.oversampling = SKIN_OVERSAMPLING;
        id.rate_hz = rate_hz;
        id.max_rate_hz = skin_board_max_rate();
        id.layout_hash = SKIN_LAYOUT_HASH;
        id.baud_div = skin_transport_div;
        uint8_t body[24];
        skin_transport_send_reply(body, skin_pack_identity(&id, body));
        break;
    }
    default: { /* the parser lets through only the types above */
        skin_error_t e = {cmd->token, cmd->type, SKIN_ERR_TYPE, cmd->type};
        skin_board_error(&e);
    }
    }
}

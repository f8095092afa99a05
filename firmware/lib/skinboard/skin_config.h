/* Build-time settings of a skin board. Every one can be overridden with -D (see firmware/Makefile). */
#ifndef SKIN_CONFIG_H
#define SKIN_CONFIG_H

#ifndef SKIN_TAXELS
#define SKIN_TAXELS 16
#endif
#ifndef SKIN_MUXES            /* 16-channel multiplexers; 0 = taxels on direct analog inputs */
#define SKIN_MUXES 1
#endif
#ifndef SKIN_OVERSAMPLING     /* conversions averaged per count: 1, 2, 4, 8 or 16 */
#define SKIN_OVERSAMPLING 4
#endif
#ifndef SKIN_RATE_HZ
#define SKIN_RATE_HZ 200
#endif
#ifndef SKIN_ADC_PRESCALER    /* 64: 250 kHz ADC clock at 16 MHz, 52 us per conversion */
#define SKIN_ADC_PRESCALER 64
#endif
#ifndef SKIN_BOARD_ID
#define SKIN_BOARD_ID 0
#endif
#ifndef SKIN_LAYOUT_HASH      /* skin.drivers.protocol.layout_hash of the board's taxel ids */
#define SKIN_LAYOUT_HASH 0UL
#endif
#ifndef SKIN_BAUD
#define SKIN_BAUD 1000000UL
#endif
#ifndef SKIN_OVER_TEMP_COUNT  /* 12-bit count of the cut-off: 3900 is about 59 deg C on the paper's divider */
#define SKIN_OVER_TEMP_COUNT 3900
#endif
#ifndef SKIN_POWER_BUDGET     /* sum of duties over all taxels; default: every heater may run full */
#define SKIN_POWER_BUDGET (255UL * SKIN_TAXELS)
#endif
#ifndef SKIN_KP               /* duty per count, << 8 */
#define SKIN_KP 346
#endif
#ifndef SKIN_KI               /* duty per count-sample, << 16 */
#define SKIN_KI 44
#endif
#ifndef SKIN_FORCE_INPUTS     /* taxels 0 .. F-1 have a force sensor (FSR stage); 0 = no force channel */
#define SKIN_FORCE_INPUTS 0
#endif
#ifndef SKIN_FORCE_FULL_MN    /* force at the ADC's full scale (1.1 V), mN; linear from 0 at 0 V */
#define SKIN_FORCE_FULL_MN 20000UL
#endif
#ifndef SKIN_FORCE_PRESCALER  /* ADC clock divider of a force conversion: 16 = 1 MHz, 13 us */
#define SKIN_FORCE_PRESCALER 16
#endif
#ifndef SKIN_TIMING_MARKS     /* 1: mark work in GPIOR0 for the emulator's timing (make timing) */
#define SKIN_TIMING_MARKS 0
#endif
#ifndef SKIN_STREAM_AT_BOOT
#define SKIN_STREAM_AT_BOOT 1
#endif

#define SKIN_FW_MAJOR 1
#define SKIN_FW_MINOR 0
#define SKIN_FW_PATCH 0

#if SKIN_MUXES > 0
#define SKIN_AMBIENT_CHANNEL SKIN_MUXES
#if SKIN_TAXELS > 16 * SKIN_MUXES
#error "SKIN_TAXELS exceeds 16 channels per multiplexer"
#endif
#else
#define SKIN_AMBIENT_CHANNEL SKIN_TAXELS
#endif

#if SKIN_FORCE_INPUTS > SKIN_TAXELS
#error "SKIN_FORCE_INPUTS exceeds SKIN_TAXELS"
#endif
#if SKIN_TAXELS + SKIN_FORCE_INPUTS > 254
#error "SKIN_TAXELS + SKIN_FORCE_INPUTS exceeds the 255 scan slots"
#endif
#if SKIN_FORCE_FULL_MN > 65534UL
#error "SKIN_FORCE_FULL_MN above 65534 mN does not fit a FORCE word"
#endif
/* Force inputs: with multiplexers, force multiplexer k (inputs 16k .. 16k+15, on the same select
 * lines) on ADC channel SKIN_AMBIENT_CHANNEL + 1 + k; without, input f on ADC channel
 * SKIN_AMBIENT_CHANNEL + 1 + f. */
#if SKIN_MUXES > 0
#define SKIN_FORCE_MUXES ((SKIN_FORCE_INPUTS + 15) / 16)
#define SKIN_FORCE_CHANNELS SKIN_FORCE_MUXES
#else
#define SKIN_FORCE_CHANNELS SKIN_FORCE_INPUTS
#endif

#if SKIN_TAXELS > 128
#error "one board carries at most 128 taxels (CAN groups); use several boards"
#endif

/* Conversions per sample and the highest rate they allow (95 % of the period): a conversion
 * takes 13 ADC clocks and, with its interrupt, about 16 (64 us at 250 kHz, measured in simavr:
 * a 72-taxel scan takes 4.65 ms). */
#define SKIN_CONVERSIONS ((SKIN_TAXELS + 1UL) * SKIN_OVERSAMPLING)
/* a force input: one conversion at the force prescaler, counted in thermistor conversions */
#define SKIN_FORCE_CONVERSIONS \
    ((SKIN_FORCE_INPUTS * (unsigned long)SKIN_FORCE_PRESCALER + SKIN_ADC_PRESCALER - 1) / SKIN_ADC_PRESCALER)
#define SKIN_ADC_HZ (F_CPU / SKIN_ADC_PRESCALER)
#define SKIN_MAX_RATE_ADC (SKIN_ADC_HZ * 95UL / (100UL * 16UL * (SKIN_CONVERSIONS + SKIN_FORCE_CONVERSIONS)))

#endif

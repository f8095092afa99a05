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

/* every ADC channel the board reads (taxel multiplexers or inputs, ambient, force) must be an
 * analog input the board brings out: the Arduino variant's NUM_ANALOG_INPUTS in an Arduino build
 * (an Uno's "standard" variant has A0-A5, a Nano's A0-A7), else the MCU's (the 328P's 8, its TQFP
 * package; channel 8 is its internal temperature sensor) */
#if defined(ARDUINO) && defined(__has_include)
#if __has_include(<pins_arduino.h>)
#include <pins_arduino.h>
#endif
#endif
#if defined(NUM_ANALOG_INPUTS)
#define SKIN_ADC_INPUTS NUM_ANALOG_INPUTS
#elif defined(__AVR_ATmega2560__) || defined(__AVR_ATmega1280__)
#define SKIN_ADC_INPUTS 16
#elif defined(__AVR_ATmega328P__) || defined(__AVR_ATmega328__) || defined(__AVR_ATmega168__)
#define SKIN_ADC_INPUTS 8
#endif
#if defined(SKIN_ADC_INPUTS) && SKIN_AMBIENT_CHANNEL + SKIN_FORCE_CHANNELS >= SKIN_ADC_INPUTS
#error "taxel, ambient and force channels exceed the board's analog inputs (SKIN_AMBIENT_CHANNEL + SKIN_FORCE_CHANNELS >= SKIN_ADC_INPUTS)"
#endif
#if SKIN_ADC_PRESCALER != 2 && SKIN_ADC_PRESCALER != 4 && SKIN_ADC_PRESCALER != 8 && \
    SKIN_ADC_PRESCALER != 16 && SKIN_ADC_PRESCALER != 32 && SKIN_ADC_PRESCALER != 64 && \
    SKIN_ADC_PRESCALER != 128
#error "SKIN_ADC_PRESCALER must be one of the ADC's dividers: 2, 4, 8, 16, 32, 64, 128"
#endif
#if SKIN_FORCE_PRESCALER != 2 && SKIN_FORCE_PRESCALER != 4 && SKIN_FORCE_PRESCALER != 8 && \
    SKIN_FORCE_PRESCALER != 16 && SKIN_FORCE_PRESCALER != 32 && SKIN_FORCE_PRESCALER != 64 && \
    SKIN_FORCE_PRESCALER != 128
#error "SKIN_FORCE_PRESCALER must be one of the ADC's dividers: 2, 4, 8, 16, 32, 64, 128"
#endif

#if SKIN_TAXELS > 128
#error "one board carries at most 128 taxels (CAN groups); use several boards"
#endif

/* The highest rate (95 % of the period), in CPU cycles per sample, fitted to `skin bench firmware`'s
 * measured costs (simavr; uno OS 4, mega OS 1, uno_force, OS-1 builds with and without force):
 * - the scan: a conversion takes 13 ADC clocks plus SKIN_CONV_CYCLES (its interrupt; measured
 *   ~80), each channel SKIN_SWITCH_CYCLES more (multiplexer select and settling; ~107), a force
 *   input 13 clocks at its prescaler plus SKIN_FORCE_EXTRA_CYCLES (measured 364 - 440 in all);
 * - the main loop: heater control, framing and the interrupts that land in it (ADC, UART) per
 *   sample, SKIN_LOOP_CYCLES + per taxel and per force input (16-taxel OS-1 build at 873 Hz:
 *   19840 measured; mega: 66454; a faster rate than this loses samples to TX_OVERRUN).
 * The link's own limit (bytes per sample at the baud rate) is the transport's. */
#define SKIN_CONV_CYCLES 88UL
#define SKIN_SWITCH_CYCLES 112UL
#define SKIN_FORCE_EXTRA_CYCLES 240UL
#define SKIN_LOOP_CYCLES 7000UL
#define SKIN_LOOP_TAXEL_CYCLES 850UL
#define SKIN_LOOP_FORCE_CYCLES 1100UL
#define SKIN_CONVERSIONS ((SKIN_TAXELS + 1UL) * SKIN_OVERSAMPLING)
#define SKIN_SCAN_CYCLES                                                                         \
    (SKIN_CONVERSIONS * (13UL * SKIN_ADC_PRESCALER + SKIN_CONV_CYCLES) +                          \
     (SKIN_TAXELS + 1UL) * SKIN_SWITCH_CYCLES +                                                   \
     SKIN_FORCE_INPUTS * (13UL * SKIN_FORCE_PRESCALER + SKIN_FORCE_EXTRA_CYCLES))
#define SKIN_LOOP_BUDGET_CYCLES                                                                  \
    (SKIN_LOOP_CYCLES + SKIN_TAXELS * SKIN_LOOP_TAXEL_CYCLES + SKIN_FORCE_INPUTS * SKIN_LOOP_FORCE_CYCLES)
#define SKIN_SAMPLE_CYCLES \
    (SKIN_SCAN_CYCLES > SKIN_LOOP_BUDGET_CYCLES ? SKIN_SCAN_CYCLES : SKIN_LOOP_BUDGET_CYCLES)
#define SKIN_MAX_RATE_ADC (F_CPU / 100UL * 95UL / SKIN_SAMPLE_CYCLES)

#endif

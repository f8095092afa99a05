/* A skin board's sampling, heaters and command handling on an ATmega328P or ATmega2560.
 *
 * The sketch gives the transport: it calls skin_board_begin once, skin_board_poll from loop(),
 * hands every received command to skin_board_command, and implements the two send hooks.
 */
#ifndef SKIN_BOARD_H
#define SKIN_BOARD_H

#include <stddef.h>
#include <stdint.h>

#include "skin_config.h"
#include "skin_proto.h"

/* GPIOR0 timing marks (bit b set while a stretch of work runs) in builds with
 * SKIN_TIMING_MARKS only (`make -C firmware timing`, read by firmware/sim/skin_avr.c for
 * `skin bench firmware`); nothing in the others. The board's bits are in skin_board.cpp, the
 * sketch's (2: waiting for the link) in skin_controller.ino. */
#if SKIN_TIMING_MARKS
#define MARK_ON(b) (GPIOR0 |= (1 << (b)))
#define MARK_OFF(b) (GPIOR0 &= ~(1 << (b)))
#else
#define MARK_ON(b) ((void)0)
#define MARK_OFF(b) ((void)0)
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* Implemented by the sketch: send one sample, or one reply body (without CRC). */
void skin_transport_send_sample(const skin_sample_t *s);
void skin_transport_send_reply(const uint8_t *body, size_t len);
/* Builds with SKIN_FORCE_INPUTS > 0 call this instead of skin_transport_send_sample: the sample
 * and its force, n words of 1 mN (SKIN_FORCE_NONE: no reading). */
void skin_transport_send_sample_force(const skin_sample_t *s, const uint16_t *force);

/* Filled in by the sketch before skin_board_begin. */
extern uint8_t skin_transport_kind;   /* 0 serial, 1 CAN */
extern uint16_t skin_transport_div;   /* IDENTITY.baud_div */
extern uint16_t skin_transport_max_rate;  /* highest rate the link carries */

void skin_board_begin(void);
/* Handle a finished sample, if any: control the heaters and send it when streaming. */
void skin_board_poll(void);
/* Carry out a command that parsed cleanly; sends its reply. */
void skin_board_command(const skin_command_t *cmd);
/* Send an ERROR reply. */
void skin_board_error(const skin_error_t *err);
uint16_t skin_board_max_rate(void);

#ifdef __cplusplus
}
#endif

#endif

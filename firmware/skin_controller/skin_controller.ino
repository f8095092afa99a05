/* thermoskin skin controller, serial variant: protocol v1 (firmware/PROTOCOL.md) over UART0.
 *
 * Samples SKIN_TAXELS taxels at 200 Hz, drives their heaters and streams SAMPLE frames; reads
 * commands framed the same way. Settings: lib/skinboard/skin_config.h; wiring: firmware/README.md.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <string.h>

#include "skin_board.h"
#include "skin_proto.h"

#define RX_MAX 32 /* the longest command body is 8 bytes; COBS and CRC add 3 */
#define WIRE_MAX(len) ((len) + 2 + ((len) + 2) / 254 + 2)
/* the longest body: a SELFTEST_RESULT (5 + 4n) or, below 11 taxels, a SAMPLE (16 + 3n); it was
 * 5 + 4n alone, which a SAMPLE of fewer than 9 taxels overran (with the CRC's 2 bytes) */
#define BODY_MAX SKIN_BODY_MAX(SKIN_TAXELS)
static_assert(BODY_MAX >= SKIN_SAMPLE_BODY_LEN(SKIN_TAXELS), "body holds a SAMPLE");
static_assert(BODY_MAX >= SKIN_FORCE_BODY_LEN(SKIN_TAXELS), "body holds a FORCE");

#if defined(USART0_UDRE_vect)
#define UDRE_VECT USART0_UDRE_vect
#define RX_VECT USART0_RX_vect
#else
#define UDRE_VECT USART_UDRE_vect
#define RX_VECT USART_RX_vect
#endif

static uint8_t body[BODY_MAX + 2];
static uint8_t wire[WIRE_MAX(BODY_MAX)];
static uint8_t rx[RX_MAX];
static uint8_t rx_len, rx_overflow;

/* UART0 driven directly rather than through Arduino's Serial: a whole packet leaves from `wire`
 * under the data-register-empty interrupt, so queuing it costs the main loop nothing (Serial's
 * per-byte write() took about half of a 72-taxel board's sample period). Received bytes go
 * through a small ring. */
static volatile uint16_t tx_pos, tx_len;
static volatile uint8_t rx_ring[64];
static volatile uint8_t rx_head, rx_tail;

#if SKIN_FORCE_INPUTS > 0
/* A FORCE is framed into wire2 while its SAMPLE leaves from wire, and queued behind it (tx_next),
 * so the main loop does not wait for the SAMPLE's bytes. */
static uint8_t wire2[WIRE_MAX(8 + 2 * SKIN_TAXELS)];
static const uint8_t *volatile tx_buf = wire;
static volatile uint16_t tx_next;

ISR(UDRE_VECT)
{
    uint16_t pos = tx_pos;
    UDR0 = tx_buf[pos++];
    if (pos >= tx_len) {
        if (tx_next) { /* the FORCE queued behind it */
            tx_buf = wire2;
            tx_len = tx_next;
            tx_next = 0;
            pos = 0;
        } else {
            UCSR0B &= ~(1 << UDRIE0);
        }
    }
    tx_pos = pos;
}
#else
ISR(UDRE_VECT)
{
    uint16_t pos = tx_pos;
    UDR0 = wire[pos++];
    tx_pos = pos;
    if (pos >= tx_len)
        UCSR0B &= ~(1 << UDRIE0);
}
#endif

ISR(RX_VECT)
{
    uint8_t b = UDR0;
    uint8_t next = (uint8_t)((rx_head + 1) & 63);
    if (next != rx_tail) { /* a full ring drops the byte: the packet then fails its CRC */
        rx_ring[rx_head] = b;
        rx_head = next;
    }
}

static void uart_begin(void)
{
    UCSR0A = (1 << U2X0);
    UBRR0 = (uint16_t)(F_CPU / 8UL / SKIN_BAUD - 1UL);
    UCSR0C = (1 << UCSZ01) | (1 << UCSZ00); /* 8N1 */
    UCSR0B = (1 << RXEN0) | (1 << TXEN0) | (1 << RXCIE0);
}

static void send_body(size_t len)
{
    MARK_ON(2); /* timing mark (skin_board.cpp, SKIN_TIMING_MARKS): waiting for the link */
    while (UCSR0B & (1 << UDRIE0)) {
        /* the previous packet is still leaving */
    }
    MARK_OFF(2);
    size_t n = skin_frame(body, len, wire);
#if SKIN_FORCE_INPUTS > 0
    tx_buf = wire;
#endif
    tx_pos = 0;
    tx_len = (uint16_t)n;
    UCSR0B |= (1 << UDRIE0);
}

void skin_transport_send_sample(const skin_sample_t *s)
{
    send_body(skin_pack_sample(s, body));
}

#if SKIN_FORCE_INPUTS > 0
void skin_transport_send_sample_force(const skin_sample_t *s, const uint16_t *force)
{
    send_body(skin_pack_sample(s, body));
    /* FORCE right after its SAMPLE (PROTOCOL.md): packed and framed while the SAMPLE leaves (the
     * last FORCE has left: send_body waited for the link), then queued behind it */
    size_t n = skin_frame(body, skin_pack_force(s->seq, s->n, force, body), wire2);
    uint8_t sreg = SREG;
    cli();
    if (UCSR0B & (1 << UDRIE0)) {
        tx_next = (uint16_t)n;
    } else {
        tx_buf = wire2;
        tx_pos = 0;
        tx_len = (uint16_t)n;
        UCSR0B |= (1 << UDRIE0);
    }
    SREG = sreg;
}
#endif

void skin_transport_send_reply(const uint8_t *reply, size_t len)
{
    memmove(body, reply, len);
    send_body(len);
}

static void packet_received(void)
{
    skin_command_t cmd;
    skin_error_t err;
    if (rx_overflow) {
        err.token = 0;
        err.command = 0;
        err.code = SKIN_ERR_TOO_LONG;
        err.detail = RX_MAX;
        skin_board_error(&err);
    } else if (skin_parse_command_packet(rx, rx_len, SKIN_TAXELS, skin_board_max_rate(), &cmd,
                                         &err)) {
        skin_board_error(&err);
    } else {
        skin_board_command(&cmd);
    }
    rx_len = 0;
    rx_overflow = 0;
}

void setup()
{
    uart_begin();
    skin_transport_kind = 0;
    skin_transport_div = (uint16_t)(SKIN_BAUD / 100UL);
    /* the link's limit: a sample's bytes at 10 bit times each, with 5 % left for replies */
    uint32_t sample_bytes = 18UL + 3UL * SKIN_TAXELS + (18UL + 3UL * SKIN_TAXELS) / 254UL + 2UL;
#if SKIN_FORCE_INPUTS > 0
    sample_bytes += 10UL + 2UL * SKIN_TAXELS + (10UL + 2UL * SKIN_TAXELS) / 254UL + 2UL; /* FORCE */
#endif
    skin_transport_max_rate = (uint16_t)(SKIN_BAUD / 10UL * 95UL / 100UL / sample_bytes);
    skin_board_begin();
}

void loop()
{
    skin_board_poll();
    while (rx_tail != rx_head) {
        uint8_t b = rx_ring[rx_tail];
        rx_tail = (uint8_t)((rx_tail + 1) & 63);
        if (b == 0) {
            if (rx_len > 0 || rx_overflow)
                packet_received();
        } else if (rx_len < RX_MAX) {
            rx[rx_len++] = b;
        } else {
            rx_overflow = 1;
        }
    }
}

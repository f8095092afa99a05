/* thermoskin skin controller, CAN node variant: protocol v1 section 2 through an MCP2515.
 *
 * The same sampling, heaters and commands as skin_controller; frames go out as classic CAN
 * frames with 11-bit identifiers through an MCP2515 on SPI (the common Arduino CAN shields:
 * chip select on D10, 16 MHz or 8 MHz crystal). Settings: SKIN_CAN_NODE (0-6), SKIN_CAN_KBPS
 * (500 or 1000), SKIN_CAN_OSC_MHZ (16 or 8).
 */
#include <avr/io.h>

#include "skin_board.h"
#include "skin_proto.h"

#ifndef SKIN_CAN_NODE
#define SKIN_CAN_NODE 0
#endif
#ifndef SKIN_CAN_KBPS
#define SKIN_CAN_KBPS 1000
#endif
#ifndef SKIN_CAN_OSC_MHZ
#define SKIN_CAN_OSC_MHZ 16
#endif

#if defined(__AVR_ATmega2560__) || defined(__AVR_ATmega1280__)
#define CS_BIT PB4 /* D10 on the Mega */
#else
#define CS_BIT PB2 /* D10 on the Uno */
#endif

/* MCP2515 instructions and registers (datasheet DS20001801) */
#define MCP_RESET 0xC0
#define MCP_READ 0x03
#define MCP_WRITE 0x02
#define MCP_READ_STATUS 0xA0
#define MCP_LOAD_TX0 0x40
#define MCP_RTS_TX0 0x81
#define MCP_READ_RX0 0x90
#define MCP_READ_RX1 0x94
#define REG_CANCTRL 0x0F
#define REG_CNF3 0x28
#define REG_CNF2 0x29
#define REG_CNF1 0x2A
#define REG_TXB0CTRL 0x30
#define REG_RXB0CTRL 0x60
#define REG_RXB1CTRL 0x70

static uint16_t tx_timeouts; /* frames dropped: no bus, or bus-off */

static uint8_t spi(uint8_t b)
{
    SPDR = b;
    while (!(SPSR & (1 << SPIF))) {
    }
    return SPDR;
}

static inline void select_chip(void) { PORTB &= ~(1 << CS_BIT); }
static inline void release_chip(void) { PORTB |= (1 << CS_BIT); }

static void mcp_write(uint8_t reg, uint8_t value)
{
    select_chip();
    spi(MCP_WRITE);
    spi(reg);
    spi(value);
    release_chip();
}

static uint8_t mcp_read(uint8_t reg)
{
    select_chip();
    spi(MCP_READ);
    spi(reg);
    uint8_t v = spi(0);
    release_chip();
    return v;
}

static void mcp_begin(void)
{
    DDRB |= (1 << CS_BIT);
    release_chip();
    select_chip();
    spi(MCP_RESET);
    release_chip();
    delay(5);
    /* bit timing: 16 or 8 TQ per bit with sync 1, propagation 1, phases equal */
#if SKIN_CAN_OSC_MHZ == 16 && SKIN_CAN_KBPS == 1000
    const uint8_t cnf1 = 0x00, cnf2 = 0xD0, cnf3 = 0x82;
#elif SKIN_CAN_OSC_MHZ == 16 && SKIN_CAN_KBPS == 500
    const uint8_t cnf1 = 0x00, cnf2 = 0xF0, cnf3 = 0x86;
#elif SKIN_CAN_OSC_MHZ == 8 && SKIN_CAN_KBPS == 500
    const uint8_t cnf1 = 0x00, cnf2 = 0x90, cnf3 = 0x82;
#elif SKIN_CAN_OSC_MHZ == 8 && SKIN_CAN_KBPS == 1000
    const uint8_t cnf1 = 0x00, cnf2 = 0x80, cnf3 = 0x80;
#else
#error "SKIN_CAN_KBPS must be 500 or 1000 and SKIN_CAN_OSC_MHZ 16 or 8"
#endif
    mcp_write(REG_CNF1, cnf1);
    mcp_write(REG_CNF2, cnf2);
    mcp_write(REG_CNF3, cnf3);
    mcp_write(REG_RXB0CTRL, 0x64); /* any message, roll over into RXB1 */
    mcp_write(REG_RXB1CTRL, 0x60);
    mcp_write(REG_CANCTRL, 0x00);  /* normal mode */
}

/* Send one frame from TXB0 (one buffer keeps a sample's frames in order). A frame that cannot
 * leave within 2 ms (no bus, bus-off) is dropped and counted rather than stalling sampling. */
static void can_send(const skin_can_frame_t *f)
{
    uint32_t t0 = micros();
    while (mcp_read(REG_TXB0CTRL) & 0x08) {
        if (micros() - t0 > 2000UL) {
            tx_timeouts++;
            return;
        }
    }
    select_chip();
    spi(MCP_LOAD_TX0);
    spi((uint8_t)(f->id >> 3));
    spi((uint8_t)((f->id & 7) << 5));
    spi(0);
    spi(0);
    spi(f->dlc);
    for (uint8_t i = 0; i < f->dlc; i++)
        spi(f->data[i]);
    release_chip();
    select_chip();
    spi(MCP_RTS_TX0);
    release_chip();
}

void skin_transport_send_sample(const skin_sample_t *s)
{
    skin_can_frame_t f;
    size_t n = skin_can_sample_frames(s->n);
    for (size_t k = 0; k < n; k++) {
        skin_can_sample_frame(s, SKIN_CAN_NODE, k, &f);
        can_send(&f);
    }
}

#if SKIN_FORCE_INPUTS > 0
/* The sample's frames with FORCE 0 .. G-1 between its DUTY frame and its STATUS (the last). */
void skin_transport_send_sample_force(const skin_sample_t *s, const uint16_t *force)
{
    skin_can_frame_t f;
    size_t n = skin_can_sample_frames(s->n);
    for (size_t k = 0; k + 1 < n; k++) {
        skin_can_sample_frame(s, SKIN_CAN_NODE, k, &f);
        can_send(&f);
    }
    for (uint16_t g = 0; g < (s->n + 3) / 4; g++) {
        skin_can_force_frame(force, s->n, SKIN_CAN_NODE, g, &f);
        can_send(&f);
    }
    skin_can_sample_frame(s, SKIN_CAN_NODE, n - 1, &f);
    can_send(&f);
}
#endif

void skin_transport_send_reply(const uint8_t *body, size_t len)
{
    skin_can_frame_t f;
    size_t n = skin_can_reply_frames(len);
    for (size_t k = 0; k < n; k++) {
        skin_can_reply_frame(body, len, SKIN_CAN_NODE, k, &f);
        can_send(&f);
    }
}

/* Read one received frame, if any; returns 1 with id, dlc and data filled. */
static uint8_t can_receive(uint16_t *id, uint8_t *dlc, uint8_t *data)
{
    select_chip();
    spi(MCP_READ_STATUS);
    uint8_t status = spi(0);
    release_chip();
    uint8_t cmd;
    if (status & 0x01)
        cmd = MCP_READ_RX0;
    else if (status & 0x02)
        cmd = MCP_READ_RX1;
    else
        return 0;
    select_chip();
    spi(cmd); /* reading the buffer this way clears its interrupt flag */
    uint8_t sidh = spi(0), sidl = spi(0);
    spi(0);
    spi(0);
    *dlc = spi(0) & 0x0F;
    if (*dlc > 8)
        *dlc = 8;
    for (uint8_t i = 0; i < *dlc; i++)
        data[i] = spi(0);
    release_chip();
    if (sidl & 0x08)
        return 0; /* extended identifier: not ours */
    *id = (uint16_t)(((uint16_t)sidh << 3) | (sidl >> 5));
    return 1;
}

void setup()
{
    skin_transport_kind = 1;
    skin_transport_div = SKIN_CAN_KBPS;
    /* the bus's limit: worst-case bits of one sample's frames (stuffing included), 5 % spare */
    uint32_t bits = 0;
#if SKIN_FORCE_INPUTS > 0 /* with the FORCE frames */
    for (uint16_t k = 0; k < skin_can_sample_frames(SKIN_TAXELS) + (SKIN_TAXELS + 3) / 4; k++)
#else
    for (uint16_t k = 0; k < skin_can_sample_frames(SKIN_TAXELS); k++)
#endif
        bits += 47UL + 64UL + (34UL + 64UL - 1UL) / 4UL;
    skin_transport_max_rate = (uint16_t)(SKIN_CAN_KBPS * 1000UL * 95UL / 100UL / bits);
    skin_board_begin(); /* sets up SPI, shared with the heaters' shift registers */
    mcp_begin();
}

void loop()
{
    skin_board_poll();
    uint16_t id;
    uint8_t dlc, data[8];
    while (can_receive(&id, &dlc, data)) {
        uint8_t type = (uint8_t)(id >> 8), node = (uint8_t)((id >> 5) & 7);
        if (type != SKIN_CAN_COMMAND || (node != SKIN_CAN_NODE && node != SKIN_CAN_BROADCAST))
            continue;
        skin_command_t cmd;
        skin_error_t err;
        if (skin_parse_command_body(data, dlc, SKIN_TAXELS, skin_board_max_rate(), &cmd, &err))
            skin_board_error(&err);
        else
            skin_board_command(&cmd);
    }
    /* Bus-off (EFLG.TXBO) needs nothing here: the MCP2515 rejoins by itself after 128 x 11
     * recessive bits, and can_send drops frames meanwhile. */
}

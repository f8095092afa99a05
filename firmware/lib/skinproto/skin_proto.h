/* thermoskin wire protocol v1 (firmware/PROTOCOL.md): framing, CRC and packing.
 *
 * Plain C99 with no dynamic memory, so that it compiles for the AVR (avr-gcc) and on the host
 * (gcc/g++), where tests check it against firmware/test_vectors.
 */
#ifndef SKIN_PROTO_H
#define SKIN_PROTO_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SKIN_PROTOCOL_VERSION 1
#define SKIN_MAX_BODY 1024

/* Message types. */
enum {
    SKIN_SAMPLE = 0x01,
    SKIN_IDENTITY = 0x02,
    SKIN_ACK = 0x03,
    SKIN_ERROR = 0x04,
    SKIN_SELFTEST_RESULT = 0x05,
    SKIN_FORCE = 0x06,
    SKIN_START = 0x10,
    SKIN_STOP = 0x11,
    SKIN_SET_RATE = 0x12,
    SKIN_SET_DUTY = 0x13,
    SKIN_SET_SETPOINT = 0x14,
    SKIN_IDENTIFY = 0x15,
    SKIN_SELFTEST = 0x16,
    SKIN_CLEAR_FAULTS = 0x17
};

/* Error codes of an ERROR reply. */
enum {
    SKIN_ERR_CRC = 1,
    SKIN_ERR_FRAMING = 2,
    SKIN_ERR_LENGTH = 3,
    SKIN_ERR_VERSION = 4,
    SKIN_ERR_TYPE = 5,
    SKIN_ERR_ARGUMENT = 6,
    SKIN_ERR_BUSY = 7,
    SKIN_ERR_TOO_LONG = 8
};

/* Taxel status bits (bits 12-15 of a taxel word) and board flags. */
#define SKIN_TAXEL_SATURATED 0x1u
#define SKIN_TAXEL_THERMISTOR_FAULT 0x2u
#define SKIN_TAXEL_HEATER_FAULT 0x4u
#define SKIN_TAXEL_OVER_TEMPERATURE 0x8u
#define SKIN_FLAG_AMBIENT_FAULT (1u << 4)
#define SKIN_FLAG_POWER_LIMITED (1u << 5)
#define SKIN_FLAG_TX_OVERRUN (1u << 6)
#define SKIN_FLAG_SAMPLE_OVERRUN (1u << 7)
#define SKIN_FLAG_SELFTEST (1u << 8)
#define SKIN_FLAG_STREAMING (1u << 9)
#define SKIN_AMBIENT_UNKNOWN 0x7FFF
#define SKIN_ALL_TAXELS 0xFFFFu
#define SKIN_FORCE_NONE 0xFFFFu /* a FORCE word: this taxel has no reading */
#define SKIN_OPTION_FORCE 0x04u /* IDENTITY options bit 2: sends FORCE after each SAMPLE */

/* A taxel word: a 12-bit count and 4 status bits. */
#define SKIN_WORD(count, status) ((uint16_t)(((count) & 0x0FFFu) | ((uint16_t)((status) & 0xFu) << 12)))

/* CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF. */
uint16_t skin_crc16_update(uint16_t crc, uint8_t byte);
uint16_t skin_crc16(const uint8_t *data, size_t len);

/* FNV-1a 32-bit; start with h = 0x811C9DC5. */
uint32_t skin_fnv1a(const uint8_t *data, size_t len, uint32_t h);

/* COBS-encode len bytes into out (room for len + len / 254 + 1); returns the encoded length,
 * without the 0x00 delimiter. */
size_t skin_cobs_encode(const uint8_t *in, size_t len, uint8_t *out);

/* COBS-decode (no delimiter in in); out may equal in. Returns the decoded length, or -1 - k
 * when the input is invalid at input offset k (a zero byte, or a code running past the end). */
long skin_cobs_decode(const uint8_t *in, size_t len, uint8_t *out);

/* Append the CRC of body[0..len) at body[len..len+2), COBS-encode it into out and append the
 * 0x00 delimiter. out needs len + 2 + (len + 2) / 254 + 2 bytes. Returns the wire length. */
size_t skin_frame(uint8_t *body, size_t len, uint8_t *out);

typedef struct {
    uint32_t seq;
    uint32_t time_us;
    uint16_t n;
    const uint16_t *words; /* n taxel words (SKIN_WORD) */
    const uint8_t *duty;   /* n heater duties */
    int16_t ambient;       /* 0.01 deg C, SKIN_AMBIENT_UNKNOWN */
    uint16_t flags;
} skin_sample_t;

/* Body lengths (without CRC) of a SAMPLE and a FORCE of n taxels. */
#define SKIN_SAMPLE_BODY_LEN(n) (16 + 3 * (n))
#define SKIN_FORCE_BODY_LEN(n) (8 + 2 * (n))
#define SKIN_SELFTEST_BODY_LEN(n) (5 + 4 * (n))
/* The longest body a board of n taxels sends: a SELFTEST_RESULT from 11 taxels up, a SAMPLE
 * below, an IDENTITY (24) below 3 (ACK and ERROR are shorter). Size a body buffer with it. */
#define SKIN_IDENTITY_BODY_LEN 24
#define SKIN_BODY_MAX2(a, b) ((a) > (b) ? (a) : (b))
#define SKIN_BODY_MAX(n) \
    SKIN_BODY_MAX2(SKIN_IDENTITY_BODY_LEN, SKIN_BODY_MAX2(SKIN_SELFTEST_BODY_LEN(n), SKIN_SAMPLE_BODY_LEN(n)))
/* Body of a SAMPLE (16 + 3n bytes, without CRC). Returns its length. */
size_t skin_pack_sample(const skin_sample_t *s, uint8_t *body);

/* Body of a FORCE (8 + 2n bytes, without CRC): the force of the SAMPLE `seq`, n words of 1 mN
 * (SKIN_FORCE_NONE: no reading). Returns its length. */
size_t skin_pack_force(uint32_t seq, uint16_t n, const uint16_t *mn, uint8_t *body);

typedef struct {
    uint8_t token;
    uint8_t fw_major, fw_minor, fw_patch;
    uint8_t board_id;
    uint8_t mcu;
    uint8_t transport;
    uint8_t options;
    uint16_t taxels;
    uint8_t adc_bits;
    uint8_t oversampling;
    uint16_t rate_hz;
    uint16_t max_rate_hz;
    uint32_t layout_hash;
    uint16_t baud_div;
} skin_identity_t;

/* Reply bodies (without CRC); each returns its length. */
size_t skin_pack_identity(const skin_identity_t *id, uint8_t *body);
size_t skin_pack_ack(uint8_t token, uint8_t command, uint8_t *body);

typedef struct {
    uint8_t token;
    uint8_t command;
    uint8_t code;
    uint16_t detail;
} skin_error_t;

size_t skin_pack_error(const skin_error_t *e, uint8_t *body);

/* SELFTEST_RESULT: 5 + 4n bytes. */
size_t skin_pack_selftest_result(uint8_t token, uint16_t n, const int16_t *response,
                                 const uint16_t *strongest, uint8_t *body);

/* A command decoded and checked. Fields not used by the type are 0. */
typedef struct {
    uint8_t type;
    uint8_t token;
    uint16_t taxel;    /* SET_DUTY, SET_SETPOINT */
    uint16_t value;    /* SET_RATE: rate_hz; SET_SETPOINT: count; SELFTEST: pulse_ms */
    uint8_t duty;      /* SET_DUTY, SELFTEST */
} skin_command_t;

/* Check a command body (version, type, length for the type, argument ranges: taxel < n_taxels
 * or SKIN_ALL_TAXELS, 4 <= rate <= max_rate_hz, count <= 4095, pulse_ms >= 1), in that order
 * after a first check that version, type and token are there. ERR_LENGTH has token and command
 * 0, the other errors those received. Returns 0 and fills cmd, or 1 and fills err. */
int skin_parse_command_body(const uint8_t *body, size_t len, uint16_t n_taxels,
                            uint16_t max_rate_hz, skin_command_t *cmd, skin_error_t *err);

/* The same for a whole packet as received (COBS-encoded, without the 0x00): decodes it in place
 * (packet is overwritten) and checks, before the body: COBS (ERR_FRAMING, detail = the decoded
 * length before the code byte of the invalid block), size (ERR_TOO_LONG past SKIN_MAX_BODY,
 * detail SKIN_MAX_BODY; ERR_LENGTH when no CRC fits, detail the decoded length), then the CRC
 * (ERR_CRC, detail the CRC received); token and command are 0 in all of these. A board whose
 * receive buffer is smaller than a packet replies ERR_TOO_LONG itself. */
int skin_parse_command_packet(uint8_t *packet, size_t len, uint16_t n_taxels,
                              uint16_t max_rate_hz, skin_command_t *cmd, skin_error_t *err);

/* Encode a command body (for host tools and tests). Returns its length. */
size_t skin_pack_command(const skin_command_t *cmd, uint8_t *body);

/* ---- CAN (classic, 11-bit identifiers) ---- */
enum {
    SKIN_CAN_SYNC = 0,
    SKIN_CAN_COMMAND = 1,
    SKIN_CAN_REPLY = 2,
    SKIN_CAN_DATA = 3,
    SKIN_CAN_DUTY = 4,
    SKIN_CAN_STATUS = 5,
    SKIN_CAN_FORCE = 6
};
#define SKIN_CAN_BROADCAST 7

typedef struct {
    uint16_t id;
    uint8_t dlc;
    uint8_t data[8];
} skin_can_frame_t;

uint16_t skin_can_id(uint8_t type, uint8_t node, uint8_t index);

/* Frames of one sample: SYNC, DATA 0..G-1, one DUTY group (seq mod ceil(n/8)), STATUS; n <= 128
 * (a node's 32 groups). With n = 0 there is no DUTY frame (SYNC and STATUS only). */
size_t skin_can_sample_frames(uint16_t n);
/* A board with a force channel sends FORCE g = 0 .. G-1 (the force of taxels 4g .. 4g+3, u16 mN
 * each, SKIN_FORCE_NONE: no reading) between the sample's DUTY frame and its STATUS. */
void skin_can_force_frame(const uint16_t *force, uint16_t n, uint8_t node, uint16_t g,
                          skin_can_frame_t *f);
void skin_can_sample_frame(const skin_sample_t *s, uint8_t node, size_t k, skin_can_frame_t *f);

/* Frames of a reply body cut into segments (u16 length first). */
size_t skin_can_reply_frames(size_t len);
void skin_can_reply_frame(const uint8_t *body, size_t len, uint8_t node, size_t k,
                          skin_can_frame_t *f);

#ifdef __cplusplus
}
#endif

#endif

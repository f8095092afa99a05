/* thermoskin wire protocol v1 (firmware/PROTOCOL.md): framing, CRC and packing.
 *
 * Plain C99: no dynamic memory, no floating point, no tables. Lengths that can exceed 16 bits
 * never occur (a body is at most SKIN_MAX_BODY = 1024 bytes), so size_t (16 bits on the AVR)
 * is enough for every length and offset; the 32-bit fields are written byte by byte.
 */
#include "skin_proto.h"

/* ---- little-endian stores and loads ---- */

/* Out of line, the stores are smaller than inlined at every call (flash matters more here). */
#if defined(__GNUC__)
#define SKIN_NOINLINE __attribute__((noinline))
#else
#define SKIN_NOINLINE
#endif

static SKIN_NOINLINE uint8_t *put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    return p + 2;
}

static SKIN_NOINLINE uint8_t *put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
    return p + 4;
}

static uint16_t get16(const uint8_t *p)
{
    return (uint16_t)(p[0] | ((uint16_t)p[1] << 8));
}

/* ---- CRC-16/CCITT-FALSE and FNV-1a ---- */

uint16_t skin_crc16_update(uint16_t crc, uint8_t byte)
{
    /* Bytewise, table-free form of the MSB-first CRC with polynomial 0x1021: the eight shift
     * steps of one byte collapse into x ^= x >> 4 and three shifted XORs. */
    uint8_t x = (uint8_t)((crc >> 8) ^ byte);
    x ^= (uint8_t)(x >> 4);
    return (uint16_t)((crc << 8) ^ ((uint16_t)x << 12) ^ ((uint16_t)x << 5) ^ x);
}

uint16_t skin_crc16(const uint8_t *data, size_t len)
{
    uint16_t crc = 0xFFFFu;
    while (len--)
        crc = skin_crc16_update(crc, *data++);
    return crc;
}

uint32_t skin_fnv1a(const uint8_t *data, size_t len, uint32_t h)
{
    while (len--) {
        h ^= *data++;
        h *= 0x01000193UL;
    }
    return h;
}

/* ---- COBS ---- */

size_t skin_cobs_encode(const uint8_t *in, size_t len, uint8_t *out)
{
    /* out[code_at] is the code of the open block, out[o] the next data byte. A block holding
     * 254 data bytes (code 0xFF) closes without an implied zero; at the end of the input the
     * last block closes without a new one after it (so 254 non-zero bytes take 255). */
    size_t code_at = 0, o = 1;
    uint8_t code = 1;
    const uint8_t *end = in + len;

    while (in != end) {
        uint8_t b = *in++;
        if (b == 0) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
        } else {
            out[o++] = b;
            if (++code == 0xFF) {
                out[code_at] = code;
                if (in == end)
                    return o;
                code_at = o++;
                code = 1;
            }
        }
    }
    out[code_at] = code;
    return o;
}

/* Decode; on failure return -1 - (the input offset of the bad byte) and store in *block_out the
 * decoded length before the code byte of the bad block (the ERR_FRAMING detail). */
static long cobs_decode(const uint8_t *in, size_t len, uint8_t *out, size_t *block_out)
{
    size_t i = 0, o = 0, block_o = 0;

    /* Reading in[i] always happens before writing out[o], and o <= i, so out may equal in. */
    while (i < len) {
        uint8_t code = in[i];
        size_t block_end;
        block_o = o;
        if (code == 0 || (size_t)(len - i) < code)
            goto bad;
        block_end = i + code;
        ++i;
        while (i < block_end) {
            uint8_t b = in[i];
            if (b == 0)
                goto bad;
            out[o++] = b;
            ++i;
        }
        /* a block shorter than 254 data bytes stands for a zero after it, except the last */
        if (code != 0xFF && i < len)
            out[o++] = 0;
    }
    return (long)o;

bad:
    if (block_out)
        *block_out = block_o;
    return -1L - (long)i;
}

long skin_cobs_decode(const uint8_t *in, size_t len, uint8_t *out)
{
    return cobs_decode(in, len, out, NULL);
}

size_t skin_frame(uint8_t *body, size_t len, uint8_t *out)
{
    size_t n;
    put16(body + len, skin_crc16(body, len));
    n = skin_cobs_encode(body, len + 2, out);
    out[n] = 0;
    return n + 1;
}

/* ---- board -> host bodies ---- */

static uint8_t *put_header(uint8_t *p, uint8_t type)
{
    p[0] = SKIN_PROTOCOL_VERSION;
    p[1] = type;
    return p + 2;
}

size_t skin_pack_sample(const skin_sample_t *s, uint8_t *body)
{
    uint8_t *p = put_header(body, SKIN_SAMPLE);
    uint16_t i, n = s->n;

    p = put32(p, s->seq);
    p = put32(p, s->time_us);
    p = put16(p, n);
    for (i = 0; i < n; ++i)
        p = put16(p, s->words[i]);
    for (i = 0; i < n; ++i)
        *p++ = s->duty[i];
    p = put16(p, (uint16_t)s->ambient);
    p = put16(p, s->flags);
    return (size_t)(p - body);
}

size_t skin_pack_force(uint32_t seq, uint16_t n, const uint16_t *mn, uint8_t *body)
{
    uint8_t *p = put_header(body, SKIN_FORCE);
    uint16_t i;

    p = put32(p, seq);
    p = put16(p, n);
    for (i = 0; i < n; ++i)
        p = put16(p, mn[i]);
    return (size_t)(p - body);
}

size_t skin_pack_identity(const skin_identity_t *id, uint8_t *body)
{
    uint8_t *p = put_header(body, SKIN_IDENTITY);

    *p++ = id->token;
    *p++ = id->fw_major;
    *p++ = id->fw_minor;
    *p++ = id->fw_patch;
    *p++ = id->board_id;
    *p++ = id->mcu;
    *p++ = id->transport;
    *p++ = id->options;
    p = put16(p, id->taxels);
    *p++ = id->adc_bits;
    *p++ = id->oversampling;
    p = put16(p, id->rate_hz);
    p = put16(p, id->max_rate_hz);
    p = put32(p, id->layout_hash);
    p = put16(p, id->baud_div);
    return (size_t)(p - body);
}

size_t skin_pack_ack(uint8_t token, uint8_t command, uint8_t *body)
{
    uint8_t *p = put_header(body, SKIN_ACK);
    p[0] = token;
    p[1] = command;
    return 4;
}

size_t skin_pack_error(const skin_error_t *e, uint8_t *body)
{
    uint8_t *p = put_header(body, SKIN_ERROR);
    p[0] = e->token;
    p[1] = e->command;
    p[2] = e->code;
    put16(p + 3, e->detail);
    return 7;
}

size_t skin_pack_selftest_result(uint8_t token, uint16_t n, const int16_t *response,
                                 const uint16_t *strongest, uint8_t *body)
{
    uint8_t *p = put_header(body, SKIN_SELFTEST_RESULT);
    uint16_t i;

    *p++ = token;
    p = put16(p, n);
    for (i = 0; i < n; ++i) {
        p = put16(p, (uint16_t)response[i]);
        p = put16(p, strongest[i]);
    }
    return (size_t)(p - body);
}

/* ---- commands ---- */

/* Argument bytes of a command type, or -1 for a type that is not a command. */
static int8_t command_args(uint8_t type)
{
    switch (type) {
    case SKIN_START:
    case SKIN_STOP:
    case SKIN_IDENTIFY:
    case SKIN_CLEAR_FAULTS:
        return 0;
    case SKIN_SET_RATE:
        return 2;
    case SKIN_SET_DUTY:
    case SKIN_SELFTEST:
        return 3;
    case SKIN_SET_SETPOINT:
        return 4;
    default:
        return -1;
    }
}

static int fail(skin_error_t *err, uint8_t token, uint8_t command, uint8_t code, uint16_t detail)
{
    err->token = token;
    err->command = command;
    err->code = code;
    err->detail = detail;
    return 1;
}

/* Checks in order: length (too short for version, type and token), version, type, length for
 * the type, then the arguments. Token and command of the ERROR are 0 for a length error (the
 * command could not be read), the received ones otherwise. */
int skin_parse_command_body(const uint8_t *body, size_t len, uint16_t n_taxels,
                            uint16_t max_rate_hz, skin_command_t *cmd, skin_error_t *err)
{
    uint8_t type, token;
    int8_t args;
    uint16_t a;

    if (len < 3)
        return fail(err, 0, 0, SKIN_ERR_LENGTH, (uint16_t)len);
    type = body[1];
    token = body[2];
    if (body[0] != SKIN_PROTOCOL_VERSION)
        return fail(err, token, type, SKIN_ERR_VERSION, body[0]);
    args = command_args(type);
    if (args < 0)
        return fail(err, token, type, SKIN_ERR_TYPE, type);
    if (len != (size_t)(3 + args))
        return fail(err, 0, 0, SKIN_ERR_LENGTH, (uint16_t)len);

    cmd->type = type;
    cmd->token = token;
    cmd->taxel = 0;
    cmd->value = 0;
    cmd->duty = 0;
    if (args == 0)
        return 0;

    a = get16(body + 3);
    switch (type) {
    case SKIN_SET_RATE:
        if (a < 4 || a > max_rate_hz)
            return fail(err, token, type, SKIN_ERR_ARGUMENT, 0);
        cmd->value = a;
        break;
    case SKIN_SET_DUTY:
    case SKIN_SET_SETPOINT:
        if (a >= n_taxels && a != SKIN_ALL_TAXELS)
            return fail(err, token, type, SKIN_ERR_ARGUMENT, 0);
        cmd->taxel = a;
        if (type == SKIN_SET_DUTY) {
            cmd->duty = body[5];
        } else {
            a = get16(body + 5);
            if (a > 4095)
                return fail(err, token, type, SKIN_ERR_ARGUMENT, 1);
            cmd->value = a;
        }
        break;
    default: /* SKIN_SELFTEST */
        if (a < 1)
            return fail(err, token, type, SKIN_ERR_ARGUMENT, 0);
        cmd->value = a;
        cmd->duty = body[5];
        break;
    }
    return 0;
}

/* Checks in order (as skin.drivers.protocol.parse_command_packet): framing (ERR_FRAMING, detail =
 * the decoded length before the code byte of the bad block), size (ERR_TOO_LONG past
 * SKIN_MAX_BODY, detail SKIN_MAX_BODY; ERR_LENGTH without room for a CRC, detail the decoded
 * length), the CRC (ERR_CRC, detail the CRC received), then the body. */
int skin_parse_command_packet(uint8_t *packet, size_t len, uint16_t n_taxels,
                              uint16_t max_rate_hz, skin_command_t *cmd, skin_error_t *err)
{
    size_t at = 0;
    long n = cobs_decode(packet, len, packet, &at);
    uint16_t crc;

    if (n < 0)
        return fail(err, 0, 0, SKIN_ERR_FRAMING, (uint16_t)at);
    if (n > SKIN_MAX_BODY + 2L)
        return fail(err, 0, 0, SKIN_ERR_TOO_LONG, SKIN_MAX_BODY);
    if (n < 2)
        return fail(err, 0, 0, SKIN_ERR_LENGTH, (uint16_t)n);
    len = (size_t)n - 2;
    crc = get16(packet + len);
    if (crc != skin_crc16(packet, len))
        return fail(err, 0, 0, SKIN_ERR_CRC, crc);
    return skin_parse_command_body(packet, len, n_taxels, max_rate_hz, cmd, err);
}

size_t skin_pack_command(const skin_command_t *cmd, uint8_t *body)
{
    uint8_t *p = put_header(body, cmd->type);

    *p++ = cmd->token;
    switch (cmd->type) {
    case SKIN_SET_RATE:
        p = put16(p, cmd->value);
        break;
    case SKIN_SET_DUTY:
        p = put16(p, cmd->taxel);
        *p++ = cmd->duty;
        break;
    case SKIN_SET_SETPOINT:
        p = put16(p, cmd->taxel);
        p = put16(p, cmd->value);
        break;
    case SKIN_SELFTEST:
        p = put16(p, cmd->value);
        *p++ = cmd->duty;
        break;
    default:
        break;
    }
    return (size_t)(p - body);
}

/* ---- CAN ---- */

uint16_t skin_can_id(uint8_t type, uint8_t node, uint8_t index)
{
    return (uint16_t)(((uint16_t)(type & 7u) << 8) | ((node & 7u) << 5) | (index & 31u));
}

/* Taxel groups of a sample: G = ceil(n / 4) DATA frames, ceil(n / 8) DUTY groups. */
#define DATA_GROUPS(n) ((uint16_t)(((uint32_t)(n) + 3u) >> 2))
#define DUTY_GROUPS(n) ((uint16_t)(((uint32_t)(n) + 7u) >> 3))

size_t skin_can_sample_frames(uint16_t n)
{
    /* SYNC, G x DATA, one DUTY (none when n = 0), STATUS. */
    return (size_t)DATA_GROUPS(n) + (n ? 3u : 2u);
}

void skin_can_force_frame(const uint16_t *force, uint16_t n, uint8_t node, uint16_t g,
                          skin_can_frame_t *f)
{
    uint16_t first = (uint16_t)(g << 2), rest = n - first;
    uint8_t *d = f->data;
    uint8_t dlc = rest < 4 ? (uint8_t)rest : 4, i;

    for (i = 0; i < dlc; ++i)
        d = put16(d, force[first + i]);
    f->id = skin_can_id(SKIN_CAN_FORCE, node, (uint8_t)g);
    f->dlc = (uint8_t)(dlc << 1);
}

void skin_can_sample_frame(const skin_sample_t *s, uint8_t node, size_t k, skin_can_frame_t *f)
{
    uint16_t n = s->n, groups = DATA_GROUPS(n), first, rest;
    uint8_t *d = f->data;
    uint8_t type, index = 0, dlc, i;

    if (k == 0) {
        type = SKIN_CAN_SYNC;
        dlc = 8;
        put32(put32(d, s->seq), s->time_us);
    } else if (k <= groups) {
        /* DATA group g = k - 1: taxels 4g .. 4g+3 */
        type = SKIN_CAN_DATA;
        index = (uint8_t)(k - 1);
        first = (uint16_t)(k - 1) << 2;
        rest = n - first;
        dlc = rest < 4 ? (uint8_t)rest : 4;
        for (i = 0; i < dlc; ++i)
            d = put16(d, s->words[first + i]);
        dlc <<= 1;
    } else if (k == (size_t)groups + 1 && n) {
        /* the DUTY group of this sample: seq mod ceil(n / 8) */
        type = SKIN_CAN_DUTY;
        index = (uint8_t)(s->seq % DUTY_GROUPS(n));
        first = (uint16_t)index << 3;
        rest = n - first;
        dlc = rest < 8 ? (uint8_t)rest : 8;
        for (i = 0; i < dlc; ++i)
            d[i] = s->duty[first + i];
    } else {
        type = SKIN_CAN_STATUS;
        dlc = 6;
        d[0] = (uint8_t)s->seq;
        put16(put16(d + 1, s->flags), (uint16_t)s->ambient);
        d[5] = (uint8_t)groups;
    }
    f->id = skin_can_id(type, node, index);
    f->dlc = dlc;
}

size_t skin_can_reply_frames(size_t len)
{
    /* the u16 length, then the body, in segments of 8 bytes */
    return (size_t)(((uint32_t)len + 2u + 7u) >> 3);
}

void skin_can_reply_frame(const uint8_t *body, size_t len, uint8_t node, size_t k,
                          skin_can_frame_t *f)
{
    /* Byte j of the segmented stream is the length's low byte, its high byte, then body[j - 2]. */
    size_t j = k << 3, end = len + 2;
    uint8_t i = 0;

    f->id = skin_can_id(SKIN_CAN_REPLY, node, (uint8_t)(k & 31u));
    for (; i < 8 && j < end; ++i, ++j)
        f->data[i] = j >= 2 ? body[j - 2] : (uint8_t)(j ? len >> 8 : len);
    f->dlc = i;
}

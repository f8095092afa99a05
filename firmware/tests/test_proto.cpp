// Host tests of the C protocol library (firmware/lib/skinproto) against firmware/PROTOCOL.md.
//
// First known values (CRC check value, the classic COBS examples, FNV-1a of short strings) and
// round trips; then every vector of firmware/test_vectors/serial.txt and can.txt (format in
// firmware/test_vectors/README.md): the values must encode to exactly the bytes, and the bytes
// must parse back to the values.
//
// Usage: test_proto [vector_dir]. Prints the vectors checked per kind; exits 1 on any failure,
// naming the vector and the first differing byte, and also when a vector file is missing or holds
// no vector of a kind it is expected to hold.
#include "skin_proto.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#ifndef SKIN_VECTOR_DIR
#define SKIN_VECTOR_DIR "test_vectors"
#endif

namespace {

using Bytes = std::vector<uint8_t>;

int g_failures = 0;
int g_builtin = 0;
std::map<std::string, int> g_checked;  // vectors checked per kind
std::string g_where;                    // the vector or built-in check being run

void fail(const std::string &what)
{
    ++g_failures;
    std::printf("FAIL %s: %s\n", g_where.c_str(), what.c_str());
}

std::string hex(const Bytes &b, size_t max = 64)
{
    std::string s;
    char buf[4];
    for (size_t i = 0; i < b.size() && i < max; ++i) {
        std::snprintf(buf, sizeof buf, "%02x", b[i]);
        s += buf;
    }
    if (b.size() > max)
        s += "...";
    return s;
}

// Compare bytes; report the first differing offset.
bool same_bytes(const std::string &what, const Bytes &got, const Bytes &want)
{
    size_t n = got.size() < want.size() ? got.size() : want.size();
    size_t i = 0;
    while (i < n && got[i] == want[i])
        ++i;
    if (i == n && got.size() == want.size())
        return true;
    char buf[200];
    if (i < n)
        std::snprintf(buf, sizeof buf,
                      "%s differs at byte %zu: got 0x%02x, expected 0x%02x (lengths %zu, %zu)",
                      what.c_str(), i, got[i], want[i], got.size(), want.size());
    else
        std::snprintf(buf, sizeof buf,
                      "%s differs at byte %zu: length %zu, expected %zu", what.c_str(), i,
                      got.size(), want.size());
    fail(std::string(buf) + "\n     got      " + hex(got) + "\n     expected " + hex(want));
    return false;
}

bool same_int(const std::string &what, long long got, long long want)
{
    if (got == want)
        return true;
    fail(what + ": got " + std::to_string(got) + ", expected " + std::to_string(want));
    return false;
}

// ---- encoders used by several checks ----

Bytes cobs_encode(const Bytes &raw)
{
    Bytes out(raw.size() + raw.size() / 254 + 1);  // the room the header asks for, exactly
    size_t n = skin_cobs_encode(raw.data(), raw.size(), out.data());
    if (n > out.size())
        fail("skin_cobs_encode wrote past its documented room");
    out.resize(n);
    return out;
}

// Body -> wire with skin_frame, in buffers of exactly the documented sizes.
Bytes frame(const Bytes &body)
{
    Bytes b(body.size() + 2);
    std::copy(body.begin(), body.end(), b.begin());
    size_t len = body.size();
    Bytes out(len + 2 + (len + 2) / 254 + 2);
    size_t n = skin_frame(b.data(), len, out.data());
    if (n > out.size())
        fail("skin_frame wrote past its documented room");
    out.resize(n);
    if (!same_int("CRC appended by skin_frame", b[len] | (b[len + 1] << 8),
                  skin_crc16(body.data(), body.size())))
        return out;
    return out;
}

// Wire -> body: split at the first 0x00 as a receiver does, COBS-decode, check and strip the CRC.
bool unframe(const Bytes &wire, Bytes &body)
{
    Bytes p;
    size_t i = 0;
    while (i < wire.size() && wire[i] != 0)
        p.push_back(wire[i++]);
    if (i != wire.size() - 1) {
        fail("wire does not end with its only 0x00");
        return false;
    }
    Bytes out(p.size());
    long n = skin_cobs_decode(p.data(), p.size(), out.data());
    if (n < 2) {
        fail("wire does not COBS-decode to a body and a CRC (skin_cobs_decode returned " +
             std::to_string(n) + ")");
        return false;
    }
    out.resize((size_t)n);
    body.assign(out.begin(), out.end() - 2);
    unsigned crc = out[n - 2] | (out[n - 1] << 8);
    return same_int("CRC on the wire", crc, skin_crc16(body.data(), body.size()));
}

// ---- a reader of little-endian fields (the tests' own parser of board -> host bodies) ----

struct Reader {
    const Bytes &b;
    size_t at = 0;
    bool bad = false;
    explicit Reader(const Bytes &bytes) : b(bytes) {}
    unsigned u8()
    {
        if (at + 1 > b.size()) {
            bad = true;
            return 0;
        }
        return b[at++];
    }
    unsigned u16()
    {
        unsigned lo = u8();
        return lo | (u8() << 8);
    }
    long long u32()
    {
        long long lo = u16();
        return lo | ((long long)u16() << 16);
    }
    int i16()
    {
        return (int16_t)(uint16_t)u16();
    }
    bool end(const std::string &what)
    {
        if (bad || at != b.size()) {
            fail(what + ": body length " + std::to_string(b.size()) + " does not match its fields");
            return false;
        }
        return true;
    }
};

// ---- vector files ----

struct Vector {
    std::string file;
    int line = 0;
    std::string kind;
    std::map<std::string, std::string> kv;

    std::string name() const
    {
        auto it = kv.find("name");
        return file + ":" + std::to_string(line) + " [" + kind + "] " +
               (it == kv.end() ? std::string("(no name)") : it->second);
    }
    bool has(const std::string &key) const { return kv.count(key) != 0; }
};

// A vector whose values cannot be read is a failure, not a skip.
struct BadVector {
    std::string what;
};

std::string trim(const std::string &s)
{
    size_t a = s.find_first_not_of(" \t\r\n");
    if (a == std::string::npos)
        return "";
    size_t b = s.find_last_not_of(" \t\r\n");
    return s.substr(a, b - a + 1);
}

const std::string &raw(const Vector &v, const std::string &key)
{
    auto it = v.kv.find(key);
    if (it == v.kv.end())
        throw BadVector{"missing key '" + key + "'"};
    return it->second;
}

long long parse_int(const std::string &tok, const std::string &key)
{
    const char *s = tok.c_str();
    char *end = nullptr;
    errno = 0;
    long long v = std::strtoll(s, &end, 0);  // decimal, or hex with 0x; a sign is allowed
    if (tok.empty() || *end != '\0' || errno)
        throw BadVector{"key '" + key + "': '" + tok + "' is not an integer"};
    return v;
}

long long get_int(const Vector &v, const std::string &key)
{
    return parse_int(trim(raw(v, key)), key);
}

std::vector<long long> get_list(const Vector &v, const std::string &key)
{
    std::string s = raw(v, key);
    for (char &c : s)
        if (c == ',' || c == '[' || c == ']')
            c = ' ';
    std::istringstream in(s);
    std::vector<long long> out;
    std::string tok;
    while (in >> tok)
        out.push_back(parse_int(tok, key));
    return out;
}

Bytes parse_hex(const std::string &text, const std::string &key)
{
    std::string s;
    for (char c : text)
        if (c != ' ' && c != '\t')
            s += c;
    if (s.size() >= 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X'))
        s = s.substr(2);
    if (s.size() % 2)
        throw BadVector{"key '" + key + "': odd number of hex digits"};
    Bytes out;
    for (size_t i = 0; i < s.size(); i += 2) {
        char pair[3] = {s[i], s[i + 1], 0};
        char *end = nullptr;
        long b = std::strtol(pair, &end, 16);
        if (*end != '\0' || !std::isxdigit((unsigned char)pair[0]))
            throw BadVector{"key '" + key + "': '" + pair + "' is not a hex byte"};
        out.push_back((uint8_t)b);
    }
    return out;
}

Bytes get_bytes(const Vector &v, const std::string &key)
{
    return parse_hex(trim(raw(v, key)), key);
}

std::vector<skin_can_frame_t> get_frames(const Vector &v, const std::string &key)
{
    std::istringstream in(raw(v, key));
    std::vector<skin_can_frame_t> out;
    std::string tok;
    while (in >> tok) {
        size_t colon = tok.find(':');
        if (colon == std::string::npos)
            throw BadVector{"key '" + key + "': frame '" + tok + "' is not ID:DATA"};
        skin_can_frame_t f{};
        char *end = nullptr;
        std::string id = tok.substr(0, colon);
        long n = std::strtol(id.c_str(), &end, 16);
        if (id.empty() || *end != '\0' || n < 0 || n > 0x7FF)
            throw BadVector{"key '" + key + "': bad identifier '" + id + "'"};
        f.id = (uint16_t)n;
        Bytes d = parse_hex(tok.substr(colon + 1), key);
        if (d.size() > 8)
            throw BadVector{"key '" + key + "': frame '" + tok + "' has more than 8 bytes"};
        f.dlc = (uint8_t)d.size();
        std::copy(d.begin(), d.end(), f.data);
        out.push_back(f);
    }
    return out;
}

bool read_vectors(const std::string &path, const std::string &file, std::vector<Vector> &out)
{
    std::ifstream in(path);
    if (!in) {
        g_where = file;
        fail("vector file " + path + " is missing");
        return false;
    }
    std::string line;
    int no = 0;
    Vector *cur = nullptr;
    while (std::getline(in, line)) {
        ++no;
        size_t hash = line.find('#');
        if (hash != std::string::npos)
            line = line.substr(0, hash);
        line = trim(line);
        if (line.empty())
            continue;
        if (line.front() == '[' && line.back() == ']') {
            out.push_back(Vector());
            cur = &out.back();
            cur->file = file;
            cur->line = no;
            cur->kind = trim(line.substr(1, line.size() - 2));
            continue;
        }
        size_t eq = line.find('=');
        g_where = file + ":" + std::to_string(no);
        if (eq == std::string::npos) {
            fail("line is neither [kind] nor key = value");
            continue;
        }
        if (!cur) {
            fail("key = value before the first [kind]");
            continue;
        }
        std::string key = trim(line.substr(0, eq));
        if (cur->kv.count(key))
            fail("key '" + key + "' given twice in one vector");
        cur->kv[key] = trim(line.substr(eq + 1));
    }
    return true;
}

// ---- checks of one vector per kind ----

std::vector<uint16_t> words_of(const Vector &v, size_t &n)
{
    std::vector<long long> counts = get_list(v, "counts");
    std::vector<long long> status = v.has("status") ? get_list(v, "status")
                                                    : std::vector<long long>(counts.size(), 0);
    n = counts.size();
    if (status.size() != n)
        throw BadVector{"counts and status differ in length"};
    std::vector<uint16_t> words;
    for (size_t i = 0; i < n; ++i) {
        if (counts[i] < 0 || counts[i] > 4095 || status[i] < 0 || status[i] > 15)
            throw BadVector{"a count or status is out of range"};
        words.push_back(SKIN_WORD(counts[i], status[i]));
    }
    return words;
}

struct SampleValues {
    std::vector<uint16_t> words;
    Bytes duty;
    skin_sample_t s{};
};

void sample_of(const Vector &v, SampleValues &sv)
{
    size_t n;
    sv.words = words_of(v, n);
    for (long long d : get_list(v, "duty"))
        sv.duty.push_back((uint8_t)d);
    if (sv.duty.size() != n)
        throw BadVector{"counts and duty differ in length"};
    sv.s.seq = (uint32_t)get_int(v, "seq");
    sv.s.time_us = (uint32_t)get_int(v, "time_us");
    sv.s.n = (uint16_t)n;
    sv.s.words = sv.words.data();
    sv.s.duty = sv.duty.data();
    sv.s.ambient = (int16_t)get_int(v, "ambient");
    sv.s.flags = (uint16_t)get_int(v, "flags");
}

// Encoded body and wire of a board -> host message; then the wire parsed back to the body.
void check_body_and_wire(const Vector &v, const Bytes &body)
{
    Bytes want = get_bytes(v, "body");
    same_bytes("body", body, want);
    if (v.has("crc"))
        same_int("crc", skin_crc16(want.data(), want.size()), get_int(v, "crc"));
    Bytes wire = get_bytes(v, "wire");
    same_bytes("wire", frame(want), wire);
    Bytes parsed;
    if (unframe(wire, parsed))
        same_bytes("body decoded from the wire", parsed, want);
}

void check_crc(const Vector &v)
{
    Bytes data = get_bytes(v, "data");
    long long want = get_int(v, "crc");
    same_int("skin_crc16", skin_crc16(data.data(), data.size()), want);
    uint16_t crc = 0xFFFF;
    for (uint8_t b : data)
        crc = skin_crc16_update(crc, b);
    same_int("skin_crc16_update", crc, want);
}

void check_cobs(const Vector &v)
{
    Bytes rawb = get_bytes(v, "raw"), enc = get_bytes(v, "encoded");
    same_bytes("encoded", cobs_encode(rawb), enc);
    Bytes out(enc.size());
    long n = skin_cobs_decode(enc.data(), enc.size(), out.data());
    if (same_int("skin_cobs_decode length", n, (long long)rawb.size())) {
        out.resize((size_t)n);
        same_bytes("decoded", out, rawb);
    }
    Bytes in_place = enc;
    n = skin_cobs_decode(in_place.data(), in_place.size(), in_place.data());
    if (n == (long)rawb.size()) {
        in_place.resize((size_t)n);
        same_bytes("decoded in place", in_place, rawb);
    }
}

void check_fnv(const Vector &v)
{
    std::string text;
    std::istringstream in(raw(v, "ids"));
    std::string tok;
    while (in >> tok)
        text += tok + "\n";
    uint32_t h = skin_fnv1a((const uint8_t *)text.data(), text.size(), 0x811C9DC5UL);
    same_int("layout hash", h, get_int(v, "hash"));
}

void check_sample(const Vector &v)
{
    SampleValues sv;
    sample_of(v, sv);
    size_t n = sv.s.n;
    Bytes body(16 + 3 * n);
    size_t len = skin_pack_sample(&sv.s, body.data());
    same_int("skin_pack_sample length", (long long)len, (long long)body.size());
    check_body_and_wire(v, body);

    Bytes wire = get_bytes(v, "wire");
    size_t m = 18 + 3 * n;
    if (wire.size() > m + (m + 253) / 254 + 1)
        fail("wire is longer than PROTOCOL.md's sample size");

    // The wire parsed field by field gives the values.
    Bytes parsed;
    if (!unframe(wire, parsed))
        return;
    Reader r(parsed);
    same_int("version", r.u8(), 1);
    same_int("type", r.u8(), SKIN_SAMPLE);
    same_int("seq", r.u32(), sv.s.seq);
    same_int("time_us", r.u32(), sv.s.time_us);
    same_int("n", r.u16(), (long long)n);
    for (size_t i = 0; i < n; ++i)
        same_int("taxel word " + std::to_string(i), r.u16(), sv.words[i]);
    for (size_t i = 0; i < n; ++i)
        same_int("duty " + std::to_string(i), r.u8(), sv.duty[i]);
    same_int("ambient", r.i16(), sv.s.ambient);
    same_int("flags", r.u16(), sv.s.flags);
    r.end("sample");
}

void check_force(const Vector &v)
{
    std::vector<long long> mn = get_list(v, "force_mn");
    std::vector<uint16_t> words(mn.begin(), mn.end());
    Bytes body(8 + 2 * words.size());
    size_t len = skin_pack_force((uint32_t)get_int(v, "seq"), (uint16_t)words.size(),
                                 words.data(), body.data());
    same_int("skin_pack_force length", (long long)len, (long long)body.size());
    check_body_and_wire(v, body);
}

skin_command_t command_of(const Vector &v)
{
    skin_command_t c{};
    c.type = (uint8_t)get_int(v, "type");
    c.token = (uint8_t)get_int(v, "token");
    switch (c.type) {
    case SKIN_SET_RATE:
        c.value = (uint16_t)get_int(v, "rate_hz");
        break;
    case SKIN_SET_DUTY:
        c.taxel = (uint16_t)get_int(v, "taxel");
        c.duty = (uint8_t)get_int(v, "duty");
        break;
    case SKIN_SET_SETPOINT:
        c.taxel = (uint16_t)get_int(v, "taxel");
        c.value = (uint16_t)get_int(v, "count");
        break;
    case SKIN_SELFTEST:
        c.value = (uint16_t)get_int(v, "pulse_ms");
        c.duty = (uint8_t)get_int(v, "duty");
        break;
    default:
        break;
    }
    return c;
}

bool same_command(const std::string &what, const skin_command_t &got, const skin_command_t &want)
{
    bool ok = same_int(what + " type", got.type, want.type);
    ok &= same_int(what + " token", got.token, want.token);
    ok &= same_int(what + " taxel", got.taxel, want.taxel);
    ok &= same_int(what + " value", got.value, want.value);
    ok &= same_int(what + " duty", got.duty, want.duty);
    return ok;
}

// Parse a received packet as the board does: the bytes up to the first 0x00.
int parse_wire(const Bytes &wire, uint16_t n_taxels, uint16_t max_rate, skin_command_t *cmd,
               skin_error_t *err)
{
    Bytes p;
    for (uint8_t b : wire) {
        if (b == 0)
            break;
        p.push_back(b);
    }
    return skin_parse_command_packet(p.data(), p.size(), n_taxels, max_rate, cmd, err);
}

std::string error_text(const skin_error_t &e)
{
    return "token " + std::to_string(e.token) + ", command " + std::to_string(e.command) +
           ", code " + std::to_string(e.code) + ", detail " + std::to_string(e.detail);
}

void check_command(const Vector &v)
{
    skin_command_t want = command_of(v);
    Bytes body(8);
    body.resize(skin_pack_command(&want, body.data()));
    check_body_and_wire(v, body);

    // Parsed as the board does, with room for every taxel and rate.
    skin_command_t got;
    skin_error_t err{};
    if (parse_wire(get_bytes(v, "wire"), 0xFFFF, 0xFFFF, &got, &err) != 0)
        fail("skin_parse_command_packet rejected it: " + error_text(err));
    else
        same_command("parsed packet", got, want);
    Bytes b = get_bytes(v, "body");
    if (skin_parse_command_body(b.data(), b.size(), 0xFFFF, 0xFFFF, &got, &err) != 0)
        fail("skin_parse_command_body rejected it: " + error_text(err));
    else
        same_command("parsed body", got, want);
}

void check_ack(const Vector &v)
{
    Bytes body(4);
    body.resize(skin_pack_ack((uint8_t)get_int(v, "token"), (uint8_t)get_int(v, "command"),
                              body.data()));
    check_body_and_wire(v, body);
    Bytes parsed;
    if (!unframe(get_bytes(v, "wire"), parsed))
        return;
    Reader r(parsed);
    same_int("version", r.u8(), 1);
    same_int("type", r.u8(), SKIN_ACK);
    same_int("token", r.u8(), get_int(v, "token"));
    same_int("command", r.u8(), get_int(v, "command"));
    r.end("ack");
}

skin_error_t error_of(const Vector &v)
{
    skin_error_t e{};
    e.token = (uint8_t)get_int(v, "token");
    e.command = (uint8_t)get_int(v, "command");
    e.code = (uint8_t)get_int(v, "code");
    e.detail = (uint16_t)get_int(v, "detail");
    return e;
}

void check_error_reply(const skin_error_t &e, const Bytes &wire, const std::string &what)
{
    Bytes parsed;
    if (!unframe(wire, parsed))
        return;
    Reader r(parsed);
    same_int(what + " version", r.u8(), 1);
    same_int(what + " type", r.u8(), SKIN_ERROR);
    same_int(what + " token", r.u8(), e.token);
    same_int(what + " command", r.u8(), e.command);
    same_int(what + " code", r.u8(), e.code);
    same_int(what + " detail", r.u16(), e.detail);
    r.end(what);
}

void check_error(const Vector &v)
{
    skin_error_t e = error_of(v);
    Bytes body(7);
    body.resize(skin_pack_error(&e, body.data()));
    check_body_and_wire(v, body);
    check_error_reply(e, get_bytes(v, "wire"), "error");
}

void check_identity(const Vector &v)
{
    skin_identity_t id{};
    id.token = (uint8_t)get_int(v, "token");
    id.fw_major = (uint8_t)get_int(v, "fw_major");
    id.fw_minor = (uint8_t)get_int(v, "fw_minor");
    id.fw_patch = (uint8_t)get_int(v, "fw_patch");
    id.board_id = (uint8_t)get_int(v, "board_id");
    id.mcu = (uint8_t)get_int(v, "mcu");
    id.transport = (uint8_t)get_int(v, "transport");
    id.options = (uint8_t)get_int(v, "options");
    id.taxels = (uint16_t)get_int(v, "taxels");
    id.adc_bits = (uint8_t)get_int(v, "adc_bits");
    id.oversampling = (uint8_t)get_int(v, "oversampling");
    id.rate_hz = (uint16_t)get_int(v, "rate_hz");
    id.max_rate_hz = (uint16_t)get_int(v, "max_rate_hz");
    id.layout_hash = (uint32_t)get_int(v, "layout_hash");
    id.baud_div = (uint16_t)get_int(v, "baud_div");
    Bytes body(24);
    same_int("skin_pack_identity length", (long long)skin_pack_identity(&id, body.data()), 24);
    check_body_and_wire(v, body);

    Bytes parsed;
    if (!unframe(get_bytes(v, "wire"), parsed))
        return;
    Reader r(parsed);
    same_int("version", r.u8(), 1);
    same_int("type", r.u8(), SKIN_IDENTITY);
    for (const char *k : {"token", "fw_major", "fw_minor", "fw_patch", "board_id", "mcu",
                          "transport", "options"})
        same_int(k, r.u8(), get_int(v, k));
    same_int("taxels", r.u16(), id.taxels);
    same_int("adc_bits", r.u8(), id.adc_bits);
    same_int("oversampling", r.u8(), id.oversampling);
    same_int("rate_hz", r.u16(), id.rate_hz);
    same_int("max_rate_hz", r.u16(), id.max_rate_hz);
    same_int("layout_hash", r.u32(), id.layout_hash);
    same_int("baud_div", r.u16(), id.baud_div);
    r.end("identity");
}

void check_selftest_result(const Vector &v)
{
    std::vector<long long> resp = get_list(v, "response"), strong = get_list(v, "strongest");
    if (resp.size() != strong.size())
        throw BadVector{"response and strongest differ in length"};
    size_t n = resp.size();
    std::vector<int16_t> response;
    std::vector<uint16_t> strongest;
    for (size_t i = 0; i < n; ++i) {
        response.push_back((int16_t)resp[i]);
        strongest.push_back((uint16_t)strong[i]);
    }
    Bytes body(5 + 4 * n);
    size_t len = skin_pack_selftest_result((uint8_t)get_int(v, "token"), (uint16_t)n,
                                           response.data(), strongest.data(), body.data());
    same_int("skin_pack_selftest_result length", (long long)len, (long long)body.size());
    check_body_and_wire(v, body);

    Bytes parsed;
    if (!unframe(get_bytes(v, "wire"), parsed))
        return;
    Reader r(parsed);
    same_int("version", r.u8(), 1);
    same_int("type", r.u8(), SKIN_SELFTEST_RESULT);
    same_int("token", r.u8(), get_int(v, "token"));
    same_int("n", r.u16(), (long long)n);
    for (size_t i = 0; i < n; ++i) {
        same_int("response " + std::to_string(i), r.i16(), response[i]);
        same_int("strongest " + std::to_string(i), r.u16(), strongest[i]);
    }
    r.end("selftest_result");
}

void check_bad_command(const Vector &v)
{
    skin_error_t want = error_of(v);
    skin_command_t cmd{};
    skin_error_t got{};
    int rc = parse_wire(get_bytes(v, "wire"), (uint16_t)get_int(v, "n_taxels"),
                        (uint16_t)get_int(v, "max_rate_hz"), &cmd, &got);
    if (rc != 1) {
        fail("skin_parse_command_packet accepted it");
        return;
    }
    if (got.token != want.token || got.command != want.command || got.code != want.code ||
        got.detail != want.detail)
        fail("ERROR " + error_text(got) + ", expected " + error_text(want));
    Bytes body(7);
    body.resize(skin_pack_error(&got, body.data()));
    Bytes reply = get_bytes(v, "reply_wire");
    same_bytes("reply_wire", frame(body), reply);
    check_error_reply(want, reply, "reply");
}

bool same_frame(const std::string &what, const skin_can_frame_t &got, const skin_can_frame_t &want)
{
    if (got.id != want.id) {
        char buf[120];
        std::snprintf(buf, sizeof buf, "%s: identifier 0x%03x, expected 0x%03x", what.c_str(),
                      got.id, want.id);
        fail(buf);
        return false;
    }
    return same_bytes(what + " data", Bytes(got.data, got.data + got.dlc),
                      Bytes(want.data, want.data + want.dlc));
}

void check_frames(const std::vector<skin_can_frame_t> &got,
                  const std::vector<skin_can_frame_t> &want)
{
    if (!same_int("frame count", (long long)got.size(), (long long)want.size()))
        return;
    for (size_t k = 0; k < got.size(); ++k)
        if (!same_frame("frame " + std::to_string(k), got[k], want[k]))
            return;
}

unsigned frame_type(const skin_can_frame_t &f) { return f.id >> 8; }
unsigned frame_node(const skin_can_frame_t &f) { return (f.id >> 5) & 7; }
unsigned frame_index(const skin_can_frame_t &f) { return f.id & 31; }

void check_can_sample(const Vector &v)
{
    SampleValues sv;
    sample_of(v, sv);
    uint8_t node = (uint8_t)get_int(v, "node");
    std::vector<skin_can_frame_t> want = get_frames(v, "frames"), got;
    size_t count = skin_can_sample_frames(sv.s.n);
    for (size_t k = 0; k < count; ++k) {
        skin_can_frame_t f;
        std::memset(&f, 0xA5, sizeof f);
        skin_can_sample_frame(&sv.s, node, k, &f);
        got.push_back(f);
    }
    check_frames(got, want);

    // The frames reassembled as the host does give the values.
    size_t n = sv.s.n, groups = (n + 3) / 4;
    if (want.size() < 2)
        return fail("fewer than two frames");
    for (const skin_can_frame_t &f : want)
        same_int("node of identifier", frame_node(f), node);
    const skin_can_frame_t &sync = want.front(), &status = want.back();
    same_int("first frame type", frame_type(sync), SKIN_CAN_SYNC);
    Bytes sb(sync.data, sync.data + sync.dlc);
    Reader rs(sb);
    same_int("SYNC seq", rs.u32(), sv.s.seq);
    same_int("SYNC time_us", rs.u32(), sv.s.time_us);
    rs.end("SYNC");
    std::vector<uint16_t> words(n, 0xFFFF);
    size_t k = 1;
    for (; k < want.size() && frame_type(want[k]) == SKIN_CAN_DATA; ++k) {
        size_t g = frame_index(want[k]);
        Bytes d(want[k].data, want[k].data + want[k].dlc);
        Reader r(d);
        for (size_t i = 4 * g; i < 4 * g + 4 && i < n; ++i)
            words[i] = (uint16_t)r.u16();
        r.end("DATA " + std::to_string(g));
    }
    same_int("DATA frames", (long long)k - 1, (long long)groups);
    for (size_t i = 0; i < n; ++i)
        same_int("taxel word " + std::to_string(i), words[i], sv.words[i]);
    if (n) {
        size_t dg = sv.s.seq % ((n + 7) / 8);
        if (k < want.size() && frame_type(want[k]) == SKIN_CAN_DUTY) {
            same_int("DUTY group", frame_index(want[k]), (long long)dg);
            for (size_t i = 0; i < want[k].dlc; ++i)
                if (8 * dg + i < n)
                    same_int("duty " + std::to_string(8 * dg + i), want[k].data[i],
                             sv.duty[8 * dg + i]);
            same_int("DUTY length", want[k].dlc, (long long)std::min<size_t>(8, n - 8 * dg));
            ++k;
        } else {
            fail("no DUTY frame after the DATA frames");
        }
    }
    same_int("frames before STATUS", (long long)k, (long long)want.size() - 1);
    same_int("last frame type", frame_type(status), SKIN_CAN_STATUS);
    Bytes st(status.data, status.data + status.dlc);
    Reader r(st);
    same_int("STATUS seq", r.u8(), sv.s.seq & 0xFF);
    same_int("STATUS flags", r.u16(), sv.s.flags);
    same_int("STATUS ambient", r.i16(), sv.s.ambient);
    same_int("STATUS groups", r.u8(), (long long)groups);
    r.end("STATUS");
}

void check_can_command(const Vector &v)
{
    uint8_t node = (uint8_t)get_int(v, "node");
    Bytes body = get_bytes(v, "body");
    std::vector<skin_can_frame_t> want = get_frames(v, "frames");
    if (body.size() > 8)
        throw BadVector{"a command body over CAN has at most 8 bytes"};
    skin_can_frame_t f{};
    f.id = skin_can_id(SKIN_CAN_COMMAND, node, 0);
    f.dlc = (uint8_t)body.size();
    std::copy(body.begin(), body.end(), f.data);
    check_frames({f}, want);
    if (want.size() != 1)
        return;
    // The frame's data parses as a command and packs back to the same body.
    skin_command_t cmd;
    skin_error_t err{};
    if (skin_parse_command_body(want[0].data, want[0].dlc, 0xFFFF, 0xFFFF, &cmd, &err) != 0)
        return fail("skin_parse_command_body rejected the frame's data: " + error_text(err));
    Bytes again(8);
    again.resize(skin_pack_command(&cmd, again.data()));
    same_bytes("command packed again", again, body);
}

void check_can_reply(const Vector &v)
{
    uint8_t node = (uint8_t)get_int(v, "node");
    Bytes body = get_bytes(v, "body");
    std::vector<skin_can_frame_t> want = get_frames(v, "frames"), got;
    size_t count = skin_can_reply_frames(body.size());
    for (size_t k = 0; k < count; ++k) {
        skin_can_frame_t f;
        std::memset(&f, 0xA5, sizeof f);
        skin_can_reply_frame(body.data(), body.size(), node, k, &f);
        got.push_back(f);
    }
    check_frames(got, want);

    // Reassembled as the host does.
    Bytes stream;
    for (size_t k = 0; k < want.size(); ++k) {
        same_int("REPLY type", frame_type(want[k]), SKIN_CAN_REPLY);
        same_int("REPLY node", frame_node(want[k]), node);
        same_int("REPLY segment", frame_index(want[k]), (long long)(k % 32));
        stream.insert(stream.end(), want[k].data, want[k].data + want[k].dlc);
    }
    if (stream.size() < 2)
        return fail("reply segments hold no length");
    size_t len = stream[0] | (stream[1] << 8);
    same_bytes("reassembled reply", Bytes(stream.begin() + 2, stream.end()), body);
    same_int("reply length field", (long long)len, (long long)body.size());
}

using Check = void (*)(const Vector &);

const std::map<std::string, Check> &checks()
{
    static const std::map<std::string, Check> m = {
        {"crc", check_crc},
        {"cobs", check_cobs},
        {"fnv", check_fnv},
        {"sample", check_sample},
        {"force", check_force},
        {"command", check_command},
        {"ack", check_ack},
        {"error", check_error},
        {"identity", check_identity},
        {"selftest_result", check_selftest_result},
        {"bad_command", check_bad_command},
        {"can_sample", check_can_sample},
        {"can_command", check_can_command},
        {"can_reply", check_can_reply},
    };
    return m;
}

// ---- built-in checks: known values and round trips ----

void builtin(const std::string &name)
{
    g_where = "builtin " + name;
    ++g_builtin;
}

Bytes seq_bytes(int from, int to)  // from .. to inclusive
{
    Bytes b;
    for (int i = from; i <= to; ++i)
        b.push_back((uint8_t)i);
    return b;
}

Bytes cat(Bytes a, const Bytes &b)
{
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

void builtin_checks()
{
    builtin("SKIN_BODY_MAX(n) holds every body a board of n taxels sends");
    for (uint16_t n = 1; n <= 128; ++n) {
        std::vector<uint16_t> words(n, 0x0FFF);
        std::vector<uint8_t> duty(n, 255);
        std::vector<int16_t> response(n, -1);
        std::vector<uint8_t> body(2 * SKIN_BODY_MAX(n) + 64);
        skin_sample_t s{};
        s.n = n;
        s.words = words.data();
        s.duty = duty.data();
        skin_identity_t id{};
        id.taxels = n;
        skin_error_t err{};
        const size_t len[] = {skin_pack_sample(&s, body.data()),
                              skin_pack_force(1, n, words.data(), body.data()),
                              skin_pack_selftest_result(1, n, response.data(), words.data(),
                                                        body.data()),
                              skin_pack_identity(&id, body.data()),
                              skin_pack_ack(1, 2, body.data()),
                              skin_pack_error(&err, body.data())};
        for (size_t l : len)
            if (l > (size_t)SKIN_BODY_MAX(n)) {
                fail("a body of " + std::to_string(l) + " bytes for " + std::to_string(n) +
                     " taxels exceeds SKIN_BODY_MAX " + std::to_string(SKIN_BODY_MAX(n)));
                n = 128;
                break;
            }
    }
    builtin("crc16 check value");
    const char *check = "123456789";
    same_int("crc", skin_crc16((const uint8_t *)check, 9), 0x29B1);
    builtin("crc16 of nothing");
    same_int("crc", skin_crc16(nullptr, 0), 0xFFFF);
    builtin("crc16 bytewise equals bitwise");
    for (unsigned crc = 0; crc < 0x10000; crc += 0x0101)
        for (unsigned b = 0; b < 256; ++b) {
            unsigned r = crc ^ (b << 8);
            for (int i = 0; i < 8; ++i)
                r = (r & 0x8000) ? ((r << 1) ^ 0x1021) & 0xFFFF : (r << 1) & 0xFFFF;
            if (skin_crc16_update((uint16_t)crc, (uint8_t)b) != r) {
                fail("skin_crc16_update(" + std::to_string(crc) + ", " + std::to_string(b) + ")");
                crc = 0x10000;
                break;
            }
        }

    builtin("fnv1a known values");
    same_int("fnv ''", skin_fnv1a(nullptr, 0, 0x811C9DC5UL), 0x811C9DC5LL);
    same_int("fnv 'a'", skin_fnv1a((const uint8_t *)"a", 1, 0x811C9DC5UL), 0xE40C292CLL);
    same_int("fnv 'foobar'", skin_fnv1a((const uint8_t *)"foobar", 6, 0x811C9DC5UL), 0xBF9CF968LL);
    same_int("fnv chained", skin_fnv1a((const uint8_t *)"bar", 3,
                                       skin_fnv1a((const uint8_t *)"foo", 3, 0x811C9DC5UL)),
             0xBF9CF968LL);

    // The examples of Cheshire and Baker's COBS (as listed on Wikipedia).
    struct Example {
        Bytes raw, enc;
    };
    const Example examples[] = {
        {{0x00}, {0x01, 0x01}},
        {{0x00, 0x00}, {0x01, 0x01, 0x01}},
        {{0x00, 0x11, 0x00}, {0x01, 0x02, 0x11, 0x01}},
        {{0x11, 0x22, 0x00, 0x33}, {0x03, 0x11, 0x22, 0x02, 0x33}},
        {{0x11, 0x22, 0x33, 0x44}, {0x05, 0x11, 0x22, 0x33, 0x44}},
        {{0x11, 0x00, 0x00, 0x00}, {0x02, 0x11, 0x01, 0x01, 0x01}},
        {seq_bytes(1, 254), cat({0xFF}, seq_bytes(1, 254))},
        {seq_bytes(0, 254), cat({0x01, 0xFF}, seq_bytes(1, 254))},
        {seq_bytes(1, 255), cat(cat({0xFF}, seq_bytes(1, 254)), {0x02, 0xFF})},
        {cat(seq_bytes(2, 255), {0x00}), cat(cat({0xFF}, seq_bytes(2, 255)), {0x01, 0x01})},
        {cat(seq_bytes(3, 255), {0x00, 0x01}), cat(cat({0xFE}, seq_bytes(3, 255)), {0x02, 0x01})},
        {{}, {0x01}},
    };
    int k = 0;
    for (const Example &e : examples) {
        builtin("cobs example " + std::to_string(++k));
        same_bytes("encoded", cobs_encode(e.raw), e.enc);
        Bytes out(e.enc.size());
        long n = skin_cobs_decode(e.enc.data(), e.enc.size(), out.data());
        if (same_int("decoded length", n, (long long)e.raw.size())) {
            out.resize((size_t)n);
            same_bytes("decoded", out, e.raw);
        }
    }

    builtin("cobs round trips");
    uint32_t rng = 12345;
    auto rand8 = [&rng]() {
        rng = rng * 1103515245u + 12345u;
        return (uint8_t)(rng >> 16);
    };
    for (size_t len = 0; len <= 1100; len += (len < 600 ? 1 : 37)) {
        for (int zeros = 0; zeros < 3; ++zeros) {  // none, some, many zero bytes
            Bytes raw(len);
            for (uint8_t &b : raw) {
                b = rand8();
                if (zeros == 0 && b == 0)
                    b = 1;
                if (zeros == 2 && (b & 1))
                    b = 0;
            }
            Bytes enc = cobs_encode(raw);
            bool any_zero = false;
            for (uint8_t b : enc)
                any_zero |= b == 0;
            size_t bound = len + (len + 253) / 254 + (len == 0);
            if (any_zero || enc.size() > bound ||
                (zeros == 0 && len && enc.size() != bound)) {
                fail("encoding of " + std::to_string(len) + " bytes: length " +
                     std::to_string(enc.size()) + " or a zero byte");
                continue;
            }
            Bytes in_place = enc;
            long n = skin_cobs_decode(in_place.data(), in_place.size(), in_place.data());
            if (!same_int("decoded length", n, (long long)len))
                continue;
            in_place.resize((size_t)n);
            same_bytes("round trip of " + std::to_string(len) + " bytes", in_place, raw);
        }
    }

    builtin("cobs invalid input");
    {
        Bytes out(16);
        const Bytes zero_code = {0x02, 0x11, 0x00, 0x22};     // a zero byte at offset 2
        const Bytes past_end = {0x02, 0x11, 0x05, 0x22};      // the code at 2 runs past the end
        const Bytes zero_first = {0x00};
        same_int("zero byte", skin_cobs_decode(zero_code.data(), 4, out.data()), -1 - 2);
        same_int("code past end", skin_cobs_decode(past_end.data(), 4, out.data()), -1 - 2);
        same_int("zero first", skin_cobs_decode(zero_first.data(), 1, out.data()), -1 - 0);
    }

    builtin("frame and command round trips");
    const skin_command_t cmds[] = {
        {SKIN_START, 1, 0, 0, 0},
        {SKIN_STOP, 2, 0, 0, 0},
        {SKIN_SET_RATE, 3, 0, 200, 0},
        {SKIN_SET_DUTY, 4, 7, 0, 128},
        {SKIN_SET_DUTY, 5, SKIN_ALL_TAXELS, 0, 0},
        {SKIN_SET_SETPOINT, 6, 15, 4095, 0},
        {SKIN_IDENTIFY, 7, 0, 0, 0},
        {SKIN_SELFTEST, 8, 0, 500, 200},
        {SKIN_CLEAR_FAULTS, 0, 0, 0, 0},
    };
    const size_t cmd_len[] = {3, 3, 5, 6, 6, 7, 3, 6, 3};
    k = 0;
    for (const skin_command_t &c : cmds) {
        Bytes body(8);
        body.resize(skin_pack_command(&c, body.data()));
        same_int("command length", (long long)body.size(), (long long)cmd_len[k++]);
        Bytes wire = frame(body);
        skin_command_t got;
        skin_error_t err{};
        if (parse_wire(wire, 16, 400, &got, &err) != 0)
            fail("command rejected: " + error_text(err));
        else
            same_command("round trip", got, c);
    }

    // Command errors: (body, n_taxels, max_rate) -> expected ERROR.
    struct Bad {
        const char *name;
        Bytes body;
        skin_error_t err;
    };
    const Bad bads[] = {
        {"empty", {}, {0, 0, SKIN_ERR_LENGTH, 0}},
        {"no token", {1, SKIN_START}, {0, 0, SKIN_ERR_LENGTH, 2}},
        {"version 2", {2, SKIN_START, 9}, {9, SKIN_START, SKIN_ERR_VERSION, 2}},
        {"reply type", {1, SKIN_ACK, 9}, {9, SKIN_ACK, SKIN_ERR_TYPE, SKIN_ACK}},
        {"unknown type", {1, 0x18, 9}, {9, 0x18, SKIN_ERR_TYPE, 0x18}},
        {"START too long", {1, SKIN_START, 9, 0}, {0, 0, SKIN_ERR_LENGTH, 4}},
        {"SET_RATE short", {1, SKIN_SET_RATE, 9, 200}, {0, 0, SKIN_ERR_LENGTH, 4}},
        {"rate 3", {1, SKIN_SET_RATE, 9, 3, 0}, {9, SKIN_SET_RATE, SKIN_ERR_ARGUMENT, 0}},
        {"rate 401", {1, SKIN_SET_RATE, 9, 0x91, 1}, {9, SKIN_SET_RATE, SKIN_ERR_ARGUMENT, 0}},
        {"duty taxel 16", {1, SKIN_SET_DUTY, 9, 16, 0, 1}, {9, SKIN_SET_DUTY, SKIN_ERR_ARGUMENT, 0}},
        {"setpoint taxel 0xFFFE", {1, SKIN_SET_SETPOINT, 9, 0xFE, 0xFF, 0, 0},
         {9, SKIN_SET_SETPOINT, SKIN_ERR_ARGUMENT, 0}},
        {"setpoint 4096", {1, SKIN_SET_SETPOINT, 9, 0xFF, 0xFF, 0, 0x10},
         {9, SKIN_SET_SETPOINT, SKIN_ERR_ARGUMENT, 1}},
        {"pulse 0", {1, SKIN_SELFTEST, 9, 0, 0, 50}, {9, SKIN_SELFTEST, SKIN_ERR_ARGUMENT, 0}},
    };
    for (const Bad &b : bads) {
        builtin(std::string("command error: ") + b.name);
        skin_command_t cmd;
        skin_error_t err{};
        Bytes wire = frame(b.body);
        if (parse_wire(wire, 16, 400, &cmd, &err) != 1)
            fail("accepted");
        else if (err.token != b.err.token || err.command != b.err.command ||
                 err.code != b.err.code || err.detail != b.err.detail)
            fail("ERROR " + error_text(err) + ", expected " + error_text(b.err));
    }
    builtin("command error: bad CRC");
    {
        Bytes body = {1, SKIN_START, 9, 0x34, 0x12};  // a CRC of 0x1234
        Bytes wire = cobs_encode(body);
        skin_command_t cmd;
        skin_error_t err{};
        skin_error_t want = {0, 0, SKIN_ERR_CRC, 0x1234};
        if (skin_parse_command_packet(wire.data(), wire.size(), 16, 400, &cmd, &err) != 1 ||
            err.code != want.code || err.detail != want.detail || err.token || err.command)
            fail("ERROR " + error_text(err) + ", expected " + error_text(want));
    }
    builtin("command error: bad COBS");
    {
        // The detail is the decoded length before the code byte of the bad block.
        const struct {
            Bytes wire;
            uint16_t detail;
        } cases[] = {
            {{0x04, 0x01, 0x10, 0x09, 0x09}, 4},        // the code at 4 runs past the end
            {{0x04, 0x01, 0x10, 0x09, 0x03, 0x05}, 4},  // so does the one at 4 here
            {{0x02, 0x01, 0x04, 0x09, 0x00, 0x01}, 2},  // a zero inside the block at 2
            {{0x00, 0x01}, 0},                          // a zero code
        };
        for (const auto &c : cases) {
            Bytes wire = c.wire;
            skin_command_t cmd;
            skin_error_t err{};
            skin_error_t want = {0, 0, SKIN_ERR_FRAMING, c.detail};
            if (skin_parse_command_packet(wire.data(), wire.size(), 16, 400, &cmd, &err) != 1 ||
                err.code != want.code || err.detail != want.detail || err.token || err.command)
                fail("ERROR " + error_text(err) + ", expected " + error_text(want) + " for " +
                     hex(c.wire));
        }
    }
    builtin("command error: too short for a CRC, too long");
    {
        Bytes one = {0x02, 0x01};  // decodes to 1 byte
        skin_command_t cmd;
        skin_error_t err{};
        if (skin_parse_command_packet(one.data(), one.size(), 16, 400, &cmd, &err) != 1 ||
            err.code != SKIN_ERR_LENGTH || err.detail != 1)
            fail("one byte: ERROR " + error_text(err));
        Bytes body(SKIN_MAX_BODY + 1, 0x55);
        body[0] = 1;
        body[1] = SKIN_START;
        Bytes wire = frame(body);
        if (parse_wire(wire, 16, 400, &cmd, &err) != 1 || err.code != SKIN_ERR_TOO_LONG ||
            err.detail != SKIN_MAX_BODY || err.token || err.command)
            fail("too long: ERROR " + error_text(err));
        body.resize(SKIN_MAX_BODY);  // the longest body is read (and its length refused)
        wire = frame(body);
        if (parse_wire(wire, 16, 400, &cmd, &err) != 1 || err.code != SKIN_ERR_LENGTH ||
            err.detail != SKIN_MAX_BODY)
            fail("longest: ERROR " + error_text(err));
    }

    builtin("sample size on the wire");
    for (uint16_t n = 0; n <= 400; ++n) {
        std::vector<uint16_t> words(n);
        Bytes duty(n);
        for (uint16_t i = 0; i < n; ++i) {
            words[i] = SKIN_WORD(1000 + i, i & 15);
            duty[i] = (uint8_t)(i | 1);
        }
        skin_sample_t s = {0x01020304UL, 0xA1B2C3D4UL, n, words.data(), duty.data(), 2512,
                           SKIN_FLAG_STREAMING | 1};
        Bytes body(16 + 3 * (size_t)n);
        if (skin_pack_sample(&s, body.data()) != body.size()) {
            fail("sample length");
            break;
        }
        Bytes wire = frame(body);
        size_t m = 18 + 3 * (size_t)n;
        if (wire.size() > m + (m + 253) / 254 + 1)
            fail("sample of " + std::to_string(n) + " taxels: " + std::to_string(wire.size()) +
                 " bytes on the wire");
        Bytes back;
        if (unframe(wire, back))
            same_bytes("sample decoded", back, body);
    }

    builtin("CAN identifiers");
    same_int("SYNC node 0", skin_can_id(SKIN_CAN_SYNC, 0, 0), 0x000);
    same_int("COMMAND broadcast", skin_can_id(SKIN_CAN_COMMAND, SKIN_CAN_BROADCAST, 0), 0x1E0);
    same_int("DATA node 3 group 31", skin_can_id(SKIN_CAN_DATA, 3, 31), 0x37F);
    same_int("STATUS node 6", skin_can_id(SKIN_CAN_STATUS, 6, 0), 0x5C0);

    builtin("CAN sample frame counts");
    const uint16_t ns[] = {1, 4, 5, 8, 9, 127, 128};
    const size_t counts[] = {4, 4, 5, 5, 6, 35, 35};
    for (size_t i = 0; i < sizeof ns / sizeof ns[0]; ++i)
        same_int("frames of " + std::to_string(ns[i]) + " taxels", (long long)skin_can_sample_frames(ns[i]),
                 (long long)counts[i]);

    builtin("CAN force frames");
    {
        const uint16_t force[10] = {0, 250, 500, 750, 1000, SKIN_FORCE_NONE, 1500, 1750, 2000, 2250};
        skin_can_frame_t f;
        skin_can_force_frame(force, 10, 2, 1, &f);
        same_int("FORCE node 2 group 1", f.id, 0x641);
        same_int("dlc", f.dlc, 8);
        same_bytes("data", Bytes(f.data, f.data + f.dlc),
                   Bytes({0xE8, 0x03, 0xFF, 0xFF, 0xDC, 0x05, 0xD6, 0x06}));
        skin_can_force_frame(force, 10, 2, 2, &f);  // the last group: 2 taxels
        same_int("dlc of the last group", f.dlc, 4);
        same_bytes("last data", Bytes(f.data, f.data + f.dlc), Bytes({0xD0, 0x07, 0xCA, 0x08}));
    }

    builtin("CAN reply segments");
    {
        Bytes body(300);
        for (size_t i = 0; i < body.size(); ++i)
            body[i] = (uint8_t)(i * 7);
        size_t count = skin_can_reply_frames(body.size());
        same_int("segments", (long long)count, (302 + 7) / 8);
        Bytes stream;
        for (size_t k2 = 0; k2 < count; ++k2) {
            skin_can_frame_t f;
            skin_can_reply_frame(body.data(), body.size(), 2, k2, &f);
            same_int("identifier", f.id, skin_can_id(SKIN_CAN_REPLY, 2, (uint8_t)(k2 % 32)));
            stream.insert(stream.end(), f.data, f.data + f.dlc);
        }
        same_bytes("stream", stream, cat({44, 1}, body));
    }
}

}  // namespace

int main(int argc, char **argv)
{
    std::string dir = argc > 1 ? argv[1] : SKIN_VECTOR_DIR;

    builtin_checks();

    // The kinds each file must hold at least one vector of.
    const std::vector<std::pair<std::string, std::vector<std::string>>> files = {
        {"serial.txt", {"crc", "cobs", "fnv", "sample", "command", "ack", "error", "identity",
                        "selftest_result", "bad_command"}},
        {"can.txt", {"can_sample", "can_command", "can_reply"}},
        {"serial_force.txt", {"force"}},
    };
    for (const auto &file : files) {
        std::vector<Vector> vectors;
        if (!read_vectors(dir + "/" + file.first, file.first, vectors))
            continue;
        std::map<std::string, int> here;
        for (const Vector &v : vectors) {
            g_where = v.name();
            auto it = checks().find(v.kind);
            if (it == checks().end()) {
                fail("unknown kind '" + v.kind + "' (no check for it)");
                continue;
            }
            try {
                it->second(v);
            } catch (const BadVector &e) {
                fail("cannot read the vector: " + e.what);
            }
            ++g_checked[v.kind];
            ++here[v.kind];
        }
        for (const std::string &kind : file.second)
            if (here[kind] == 0) {
                g_where = file.first;
                fail("no vector of kind '" + kind + "'");
            }
    }

    std::printf("built-in checks: %d\n", g_builtin);
    int total = 0;
    for (const auto &kv : g_checked) {
        std::printf("vectors %s: %d\n", kv.first.c_str(), kv.second);
        total += kv.second;
    }
    std::printf("vectors total: %d\n", total);
    if (g_failures) {
        std::printf("FAILED: %d failures\n", g_failures);
        return 1;
    }
    std::printf("OK\n");
    return 0;
}

"""Wire protocol, version 1 (``firmware/PROTOCOL.md``, the single source of truth).

Serial: every message, in both directions, is ``COBS(body || crc16(body)) || 0x00``; a body
starts with ``u8 version, u8 type``. Board -> host: SAMPLE and the replies (ACK, ERROR,
IDENTITY, SELFTEST_RESULT); host -> board: the commands (`Command`).

CAN (classic, 11-bit identifiers ``type << 8 | node << 5 | index``): a sample is sent as SYNC,
DATA groups of 4 taxels, one DUTY group of 8 and STATUS (`can_sample_frames`); a reply body is
cut into REPLY segments (`can_reply_frames`); `CanReassembler` puts both together again.

Decoders never raise on what they receive: bad bytes are counted in `LinkStats` and skipped.
Encoders raise ``ValueError`` for values the wire cannot carry.

Counts are 12-bit (0-4095); each taxel word carries the count in bits 0-11 and the taxel's
status (``skin.frame.FLAG_ADC_SATURATED`` .. ``FLAG_OVER_TEMPERATURE``) in bits 12-15.
"""

from __future__ import annotations

import binascii
import dataclasses
import math
import struct
import time
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from skin._optional import require
from skin.errors import ProtocolError
from skin.frame import Frame

VERSION = 1
#: Longest body in either direction, bytes.
MAX_BODY = 1024
#: Most taxels one SAMPLE carries (its body is 16 + 3n bytes).
MAX_TAXELS = (MAX_BODY - 16) // 3
#: Most taxels one CAN node carries (32 DATA groups of 4).
CAN_MAX_TAXELS = 128
#: Ambient value meaning "unknown".
AMBIENT_UNKNOWN = 0x7FFF
#: Taxel argument of SET_DUTY and SET_SETPOINT meaning every taxel.
ALL_TAXELS = 0xFFFF
#: Lowest sample rate SET_RATE accepts, Hz.
MIN_RATE_HZ = 4
#: Largest count (12 bits).
MAX_COUNT = 0x0FFF
#: IDENTITY ``options`` bit: the board sends a FORCE after each SAMPLE.
OPTION_FORCE = 1 << 2
#: A FORCE value meaning "this taxel has no reading".
FORCE_NONE = 0xFFFF
#: FORCE values are in this many newtons per unit (1 mN).
FORCE_UNIT = 1e-3
#: Largest force a FORCE message carries, N (0xFFFE mN).
MAX_FORCE = (FORCE_NONE - 1) * FORCE_UNIT


class MsgType(IntEnum):
    """Message types: the second byte of every body."""

    SAMPLE = 0x01
    IDENTITY = 0x02
    ACK = 0x03
    ERROR = 0x04
    SELFTEST_RESULT = 0x05
    FORCE = 0x06
    START = 0x10
    STOP = 0x11
    SET_RATE = 0x12
    SET_DUTY = 0x13
    SET_SETPOINT = 0x14
    IDENTIFY = 0x15
    SELFTEST = 0x16
    CLEAR_FAULTS = 0x17


class ErrorCode(IntEnum):
    """Codes of an ERROR reply."""

    ERR_CRC = 1
    ERR_FRAMING = 2
    ERR_LENGTH = 3
    ERR_VERSION = 4
    ERR_TYPE = 5
    ERR_ARGUMENT = 6
    ERR_BUSY = 7
    ERR_TOO_LONG = 8


class CanType(IntEnum):
    """CAN frame types: bits 8-10 of the identifier."""

    SYNC = 0
    COMMAND = 1
    REPLY = 2
    DATA = 3
    DUTY = 4
    STATUS = 5
    FORCE = 6


#: CAN node address of a command for every node.
CAN_BROADCAST = 7

_HEADER = struct.Struct("<BBIIH")  # version, type, seq, time_us, n
_TAIL = struct.Struct("<hH")  # ambient, flags
_U16 = struct.Struct("<H")
_CMD = struct.Struct("<BBB")  # version, type, token
_ACK = struct.Struct("<BBBB")
_ERROR = struct.Struct("<BBBBBH")
_IDENTITY = struct.Struct("<BBBBBBBBBBHBBHHIH")
_SELFTEST = struct.Struct("<BBBH")
_PER_TAXEL = np.dtype([("response", "<i2"), ("strongest", "<u2")])  # of a SELFTEST_RESULT
_FORCE_HEAD = struct.Struct("<BBIH")  # version, type, seq, n
_SYNC = struct.Struct("<II")
_STATUS = struct.Struct("<BHhB")  # seq & 0xFF, flags, ambient, groups

# Argument layout of each command: (struct after the token, names of the Command fields)
_ARGS: dict[int, tuple[struct.Struct | None, tuple[str, ...]]] = {
    MsgType.START: (None, ()),
    MsgType.STOP: (None, ()),
    MsgType.SET_RATE: (struct.Struct("<H"), ("rate_hz",)),
    MsgType.SET_DUTY: (struct.Struct("<HB"), ("taxel", "duty")),
    MsgType.SET_SETPOINT: (struct.Struct("<HH"), ("taxel", "count")),
    MsgType.IDENTIFY: (None, ()),
    MsgType.SELFTEST: (struct.Struct("<HB"), ("pulse_ms", "duty")),
    MsgType.CLEAR_FAULTS: (None, ()),
}
_U8_FIELDS = {"token", "duty"}


def argument_names(kind: int) -> tuple[str, ...]:
    """Return the `Command` fields a command type sends, in wire order (``()`` for none)."""
    return _ARGS[kind][1]


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), computed in C by binascii."""
    return binascii.crc_hqx(data, 0xFFFF)


def layout_hash(ids: Iterable[int | str]) -> int:
    r"""Hash taxel ids with FNV-1a (32 bit): their text in address order, each followed by ``\n``.

    Parameters
    ----------
    ids : iterable of int or str
        Taxel ids of one board, in address order.

    Returns
    -------
    int
        The hash an IDENTITY reply carries as ``layout_hash``.
    """
    h = 0x811C9DC5
    for byte in "".join(f"{i}\n" for i in ids).encode("ascii"):
        h = ((h ^ byte) * 0x01000193) & 0xFFFFFFFF
    return h


def _cobs():
    return require("cobs.cobs", "the serial wire protocol")


def cobs_encode(data: bytes) -> bytes:
    """COBS-encode ``data`` (no 0x00 delimiter appended)."""
    return _cobs().encode(data)


def cobs_decode(data: bytes) -> bytes:
    """COBS-decode ``data`` (without its delimiter); raises ``ValueError`` if it is invalid."""
    cobs = _cobs()
    try:
        return cobs.decode(data)
    except cobs.DecodeError as exc:
        raise ValueError(f"invalid COBS: {exc}") from None


def cobs_error_offset(data: bytes) -> int | None:
    """Where COBS decoding of ``data`` fails, as an offset in the decoded body; None if valid.

    The offset is the length decoded before the code byte whose block is invalid (a zero byte,
    or a block running past the end): the ``detail`` of an ``ERR_FRAMING`` reply.
    """
    i = out = 0
    while i < len(data):
        code = data[i]
        if code == 0 or i + code > len(data) or 0 in data[i + 1 : i + code]:
            return out
        i += code
        # a block shorter than 254 bytes stands for a zero, except the last one
        out += code - 1 + (code < 0xFF and i < len(data))
    return None


def frame_packet(body: bytes) -> bytes:
    """Frame a body for the serial link: ``COBS(body || crc16(body)) || 0x00``."""
    return cobs_encode(body + _U16.pack(crc16(body))) + b"\x00"


def _u(value: int, bits: int, what: str) -> int:
    value = int(value)
    if not 0 <= value < 1 << bits:
        raise ValueError(f"{what} = {value} does not fit in {bits} bits")
    return value


def _ambient_raw(ambient: float | None) -> int:
    if ambient is None or math.isnan(ambient):
        return AMBIENT_UNKNOWN
    # 0x7FFF is reserved for unknown: a reading that high clips just below it
    return min(max(round(ambient * 100), -0x8000), AMBIENT_UNKNOWN - 1)


def _taxel_words(counts: Sequence[int] | np.ndarray,
                 status: Sequence[int] | np.ndarray | None) -> np.ndarray:
    counts = np.asarray(counts)
    if counts.ndim != 1:
        raise ValueError("counts must be one-dimensional")
    if counts.size and (counts.min() < 0 or counts.max() > MAX_COUNT):
        raise ValueError(f"counts must be 12-bit (0-{MAX_COUNT})")
    words = counts.astype("<u2")
    if status is not None:
        status = np.asarray(status)
        if status.shape != counts.shape:
            raise ValueError(f"status has {status.size} values for {counts.size} counts")
        if status.size and (status.min() < 0 or status.max() > 0xF):
            raise ValueError("taxel status must be 4-bit (0-15)")
        words |= status.astype("<u2") << 12
    return words


def _duty_bytes(duty: Sequence[int] | np.ndarray, n: int) -> np.ndarray:
    duty = np.asarray(duty)
    if duty.shape != (n,):
        raise ValueError(f"duty has {duty.size} values for {n} taxels")
    if n and (duty.min() < 0 or duty.max() > 255):
        raise ValueError("duty must be 0-255")
    return duty.astype(np.uint8)


def sample_body(
    seq: int,
    device_time_us: int,
    counts: Sequence[int] | np.ndarray,
    ambient: float | None,
    duty: Sequence[int] | np.ndarray,
    flags: int = 0,
    status: Sequence[int] | np.ndarray | None = None,
) -> bytes:
    """Body of a SAMPLE (16 + 3n bytes, without CRC); see `encode_sample`."""
    words = _taxel_words(counts, status)
    n = words.size
    if n > MAX_TAXELS:
        raise ValueError(f"{n} taxels; a v1 SAMPLE carries at most {MAX_TAXELS}")
    return b"".join((
        _HEADER.pack(VERSION, MsgType.SAMPLE, seq % (1 << 32), device_time_us % (1 << 32), n),
        words.tobytes(),
        _duty_bytes(duty, n).tobytes(),
        _TAIL.pack(_ambient_raw(ambient), _u(flags, 16, "flags")),
    ))


def encode_sample(
    seq: int,
    device_time_us: int,
    counts: Sequence[int] | np.ndarray,
    ambient: float | None,
    duty: Sequence[int] | np.ndarray,
    flags: int = 0,
    status: Sequence[int] | np.ndarray | None = None,
) -> bytes:
    """Encode one SAMPLE packet, COBS-framed and 0x00-terminated.

    Parameters
    ----------
    seq : int
        Sequence number (taken modulo 2**32).
    device_time_us : int
        Device time in microseconds (taken modulo 2**32).
    counts : array_like of int
        12-bit counts (0-4095), one per taxel; at most `MAX_TAXELS`.
    ambient : float or None
        Ambient temperature, deg C; None (or NaN) for unknown.
    duty : array_like of int
        Heater duty per taxel, 0-255.
    flags : int
        Board flags, written as given (a board sets bits 0-3 to the OR of the taxel status
        bits and `skin.frame.FLAG_STREAMING`).
    status : array_like of int, optional
        4 status bits per taxel (0 by default).

    Returns
    -------
    bytes
        The packet as sent on the wire.
    """
    return frame_packet(sample_body(seq, device_time_us, counts, ambient, duty, flags, status))


def force_body(seq: int, force: Sequence[float] | np.ndarray) -> bytes:
    """Body of a FORCE message (8 + 2n bytes, without CRC); see `encode_force`."""
    values = np.asarray(force, dtype=float).ravel()
    n = values.size
    if n > MAX_TAXELS:
        raise ValueError(f"{n} taxels; a v1 FORCE carries at most {MAX_TAXELS}")
    known = ~np.isnan(values)
    if np.any(values[known] < 0) or np.any(values[known] > MAX_FORCE) or np.any(
            np.isinf(values)):
        bad = int(np.flatnonzero(known & ((values < 0) | (values > MAX_FORCE)))[0])
        raise ValueError(f"force of channel {bad} is {values[bad]!r} N; the wire carries "
                         f"0 - {MAX_FORCE:g} N (or NaN: no reading)")
    raw = np.full(n, FORCE_NONE, dtype="<u2")
    raw[known] = np.rint(values[known] / FORCE_UNIT).astype(np.uint16)
    return _FORCE_HEAD.pack(VERSION, MsgType.FORCE, seq % (1 << 32), n) + raw.tobytes()


def encode_force(seq: int, force: Sequence[float] | np.ndarray) -> bytes:
    """Encode one FORCE packet, COBS-framed and 0x00-terminated.

    A board with a force or contact sensor sends it right after the SAMPLE of the same
    ``seq``; `StreamDecoder` attaches it to that sample's frame (``Frame.force``).

    Parameters
    ----------
    seq : int
        Sequence number of the SAMPLE it belongs to (taken modulo 2**32).
    force : array_like of float
        Normal force per channel, N, 0 - `MAX_FORCE`, rounded to 1 mN; NaN: that channel
        has no reading. A contact switch sends 0 or 1.

    Returns
    -------
    bytes
        The packet as sent on the wire.
    """
    return frame_packet(force_body(seq, force))


def force_newtons(raw: np.ndarray) -> np.ndarray:
    """Return the force, N, of FORCE words (mN; `FORCE_NONE` -> NaN).

    The one decoding of a force word, shared by the serial FORCE message and the CAN FORCE
    frame, so that a code gives the same float on both links: ``k / 1000.0`` is the float
    `force_body` rounded to ``k`` (``k * 1e-3`` differs from it by one ulp for about 14 % of
    the codes).

    Parameters
    ----------
    raw : numpy.ndarray
        Unsigned 16-bit words.

    Returns
    -------
    numpy.ndarray
        Float64 force, N, NaN where a word is `FORCE_NONE`.
    """
    force = raw / 1000.0  # 1 / FORCE_UNIT
    force[raw == FORCE_NONE] = np.nan
    return force


def _force_of(body: bytes) -> tuple[int, np.ndarray] | None:
    """Return (seq, force per channel, N) of a FORCE body; None when its length is wrong."""
    if len(body) < _FORCE_HEAD.size:
        return None
    _, _, seq, n = _FORCE_HEAD.unpack_from(body)
    if len(body) != _FORCE_HEAD.size + 2 * n:
        return None
    raw = np.frombuffer(body, dtype="<u2", count=n, offset=_FORCE_HEAD.size)
    return seq, force_newtons(raw)


# ---- commands ----

@dataclass(frozen=True)
class Command:
    """A command from host to board.

    Only the fields the type uses are sent; the others stay 0 (and decode as 0).

    Attributes
    ----------
    type : int
        A command type (`MsgType.START` .. `MsgType.CLEAR_FAULTS`).
    token : int
        Echoed in the reply, to match it to the command (0-255).
    taxel : int
        SET_DUTY, SET_SETPOINT: the taxel address, `ALL_TAXELS` for every taxel.
    duty : int
        SET_DUTY, SELFTEST: heater duty 0-255.
    count : int
        SET_SETPOINT: the 12-bit count to regulate to (0 = heater off).
    rate_hz : int
        SET_RATE: the sample rate.
    pulse_ms : int
        SELFTEST: the length of each heater's pulse.
    """

    type: int
    token: int = 0
    taxel: int = 0
    duty: int = 0
    count: int = 0
    rate_hz: int = 0
    pulse_ms: int = 0

    def body(self) -> bytes:
        """Return the body (without CRC); the only range checks are the fields' widths."""
        if self.type not in _ARGS:
            raise ValueError(f"0x{self.type:02X} is not a command type")
        args, names = _ARGS[self.type]
        head = _CMD.pack(VERSION, self.type, _u(self.token, 8, "token"))
        if args is None:
            return head
        values = [_u(getattr(self, k), 8 if k in _U8_FIELDS else 16, k) for k in names]
        return head + args.pack(*values)

    def encode(self) -> bytes:
        """Return the serial packet, framed and 0x00-terminated."""
        return frame_packet(self.body())


# ---- replies ----

@dataclass(frozen=True)
class Ack:
    """ACK: the command ``command`` with token ``token`` was carried out."""

    token: int
    command: int

    def body(self) -> bytes:
        """Return the body (without CRC)."""
        return _ACK.pack(VERSION, MsgType.ACK, _u(self.token, 8, "token"),
                         _u(self.command, 8, "command"))

    def encode(self) -> bytes:
        """Return the serial packet, framed and 0x00-terminated."""
        return frame_packet(self.body())


@dataclass(frozen=True)
class ErrorReply:
    """ERROR: the command was not carried out; ``code`` says why (`ErrorCode`)."""

    token: int
    command: int
    code: int
    detail: int = 0

    @property
    def name(self) -> str:
        """The code's name (``ERR_CRC`` ...), ``ERR_<code>`` for a code this host does not know."""
        try:
            return ErrorCode(self.code).name
        except ValueError:
            return f"ERR_{self.code}"

    def body(self) -> bytes:
        """Return the body (without CRC)."""
        return _ERROR.pack(VERSION, MsgType.ERROR, _u(self.token, 8, "token"),
                           _u(self.command, 8, "command"), _u(self.code, 8, "code"),
                           _u(self.detail, 16, "detail"))

    def encode(self) -> bytes:
        """Return the serial packet, framed and 0x00-terminated."""
        return frame_packet(self.body())


@dataclass(frozen=True)
class Identity:
    """IDENTITY: who the board is (reply to IDENTIFY); the fields of PROTOCOL.md."""

    token: int
    fw_major: int
    fw_minor: int
    fw_patch: int
    board_id: int
    mcu: int
    transport: int
    options: int
    taxels: int
    adc_bits: int
    oversampling: int
    rate_hz: int
    max_rate_hz: int
    layout_hash: int
    baud_div: int

    _FIELDS = ("token", "fw_major", "fw_minor", "fw_patch", "board_id", "mcu", "transport",
               "options", "taxels", "adc_bits", "oversampling", "rate_hz", "max_rate_hz",
               "layout_hash", "baud_div")

    def body(self) -> bytes:
        """Return the body (24 bytes, without CRC)."""
        widths = (8, 8, 8, 8, 8, 8, 8, 8, 16, 8, 8, 16, 16, 32, 16)
        values = [_u(getattr(self, k), w, k) for k, w in zip(self._FIELDS, widths, strict=True)]
        return _IDENTITY.pack(VERSION, MsgType.IDENTITY, *values)

    def encode(self) -> bytes:
        """Return the serial packet, framed and 0x00-terminated."""
        return frame_packet(self.body())


@dataclass(frozen=True)
class SelftestResult:
    """SELFTEST_RESULT: per taxel, the count change over its own pulse and the taxel that rose most.

    ``strongest`` is 0xFFFF where no taxel rose by 8 counts or more.
    """

    token: int
    response: tuple[int, ...]
    strongest: tuple[int, ...]

    def body(self) -> bytes:
        """Return the body (5 + 4n bytes, without CRC)."""
        n = len(self.response)
        if len(self.strongest) != n:
            raise ValueError(f"{n} responses but {len(self.strongest)} strongest taxels")
        if 5 + 4 * n > MAX_BODY:
            raise ValueError(f"{n} taxels do not fit in a body of {MAX_BODY} bytes")
        resp = np.asarray(self.response, dtype=np.int64)
        strongest = np.asarray(self.strongest, dtype=np.int64)
        if n and (resp.min() < -0x8000 or resp.max() > 0x7FFF):
            raise ValueError("response must fit in an i16")
        if n and (strongest.min() < 0 or strongest.max() > 0xFFFF):
            raise ValueError("strongest must fit in a u16")
        per = np.empty(n, dtype=_PER_TAXEL)
        per["response"] = resp
        per["strongest"] = strongest
        return _SELFTEST.pack(VERSION, MsgType.SELFTEST_RESULT, _u(self.token, 8, "token"),
                              n) + per.tobytes()

    def encode(self) -> bytes:
        """Return the serial packet, framed and 0x00-terminated."""
        return frame_packet(self.body())


Reply = Ack | ErrorReply | Identity | SelftestResult


def parse_reply(body: bytes) -> Reply:
    """Decode a reply body (without CRC).

    Raises
    ------
    ValueError
        If the body is not a v1 reply of a valid length.
    """
    if len(body) < 3:
        raise ValueError(f"a reply body of {len(body)} bytes")
    version, kind = body[0], body[1]
    if version != VERSION:
        raise ValueError(f"version {version}")
    if kind == MsgType.ACK and len(body) == _ACK.size:
        return Ack(*_ACK.unpack(body)[2:])
    if kind == MsgType.ERROR and len(body) == _ERROR.size:
        return ErrorReply(*_ERROR.unpack(body)[2:])
    if kind == MsgType.IDENTITY and len(body) == _IDENTITY.size:
        return Identity(*_IDENTITY.unpack(body)[2:])
    if kind == MsgType.SELFTEST_RESULT and len(body) >= _SELFTEST.size:
        token, n = _SELFTEST.unpack_from(body)[2:]
        if len(body) == _SELFTEST.size + 4 * n:
            per = np.frombuffer(body, dtype=_PER_TAXEL, count=n, offset=_SELFTEST.size)
            return SelftestResult(token, tuple(per["response"].tolist()),
                                  tuple(per["strongest"].tolist()))
    raise ValueError(f"type 0x{kind:02X} with a body of {len(body)} bytes is not a reply")


def parse_command_body(body: bytes, n_taxels: int, max_rate_hz: int) -> Command | ErrorReply:
    """Check a command body as a board does; return the command, or the ERROR to reply.

    The checks run in PROTOCOL.md's order: version, type, length for the type, then each
    argument's range (taxel < ``n_taxels`` or `ALL_TAXELS`, 4 <= rate <= ``max_rate_hz``,
    count <= 4095, pulse_ms >= 1); before them, a body too short to hold version, type and
    token is ``ERR_LENGTH``, as a command that could not be read at all (the firmware's
    reading too). Length errors get token and command 0; the others echo them.

    Parameters
    ----------
    body : bytes
        The command body, without CRC.
    n_taxels : int
        The board's taxel count.
    max_rate_hz : int
        The board's highest sample rate.
    """
    if len(body) < _CMD.size:
        return ErrorReply(0, 0, ErrorCode.ERR_LENGTH, len(body))
    version, kind, token = _CMD.unpack_from(body)
    if version != VERSION:
        return ErrorReply(token, kind, ErrorCode.ERR_VERSION, version)
    if kind not in _ARGS:
        return ErrorReply(token, kind, ErrorCode.ERR_TYPE, kind)
    args, names = _ARGS[kind]
    if len(body) != _CMD.size + (0 if args is None else args.size):
        return ErrorReply(0, 0, ErrorCode.ERR_LENGTH, len(body))
    values = dict(zip(names, args.unpack_from(body, _CMD.size), strict=True)) if args else {}
    for index, name in enumerate(names):
        v = values[name]
        ok = {"taxel": v < n_taxels or v == ALL_TAXELS,
              "rate_hz": MIN_RATE_HZ <= v <= max_rate_hz,
              "count": v <= MAX_COUNT,
              "pulse_ms": v >= 1}.get(name, True)
        if not ok:
            return ErrorReply(token, kind, ErrorCode.ERR_ARGUMENT, index)
    return Command(kind, token, **values)


def parse_command_packet(packet: bytes, n_taxels: int, max_rate_hz: int,
                         max_body: int = MAX_BODY) -> Command | ErrorReply:
    """Check a command packet as received (COBS-encoded, without its 0x00), as a board does.

    COBS first (``ERR_FRAMING``, detail the offset in the decoded body), then the size
    (``ERR_TOO_LONG`` past ``max_body``, ``ERR_LENGTH`` without room for a CRC), the CRC
    (``ERR_CRC``, detail the CRC received), then `parse_command_body`.
    """
    bad = cobs_error_offset(packet)
    if bad is not None:
        return ErrorReply(0, 0, ErrorCode.ERR_FRAMING, bad)
    raw = cobs_decode(packet)
    if len(raw) - 2 > max_body:
        return ErrorReply(0, 0, ErrorCode.ERR_TOO_LONG, max_body)
    if len(raw) < 2:
        return ErrorReply(0, 0, ErrorCode.ERR_LENGTH, len(raw))
    body, (crc,) = raw[:-2], _U16.unpack(raw[-2:])
    if crc16(body) != crc:
        return ErrorReply(0, 0, ErrorCode.ERR_CRC, crc)
    return parse_command_body(body, n_taxels, max_rate_hz)


# ---- serial stream decoding ----

@dataclass
class LinkStats:
    """What a decoder has seen on a link.

    Attributes
    ----------
    bytes : int
        Bytes received (serial).
    frames : int
        Valid sample frames decoded.
    crc_errors : int
        Packets whose CRC did not match.
    malformed : int
        Packets or CAN frames that were not valid COBS, or had an impossible length, version
        or type.
    resyncs : int
        Times the decoder discarded bytes to find the next frame boundary.
    replies : int
        Valid replies decoded.
    missing : int
        CAN: samples opened by a SYNC and dropped incomplete.
    lost_groups : int
        CAN: DATA groups that were missing from those samples.
    orphans : int
        CAN: DATA, STATUS or REPLY frames that arrived with nothing open to add them to.
    lost_samples : int
        Samples lost whole: gaps in seq between the frames decoded (CAN: between complete
        samples, beyond those counted in ``missing``); serial: also a sample held for its
        FORCE when the driver is closed.
    lost_replies : int
        CAN: replies dropped because a segment was skipped.
    duplicates : int
        Frames whose seq equals the newest one of their board or is at most
        `DUPLICATE_WINDOW` behind it (they are still returned); a jump further back is taken
        as the board restarting.
    forces : int
        Serial: FORCE messages attached to their sample's frame. CAN: samples whose every
        FORCE group arrived.
    force_orphans : int
        Serial: valid FORCE messages that matched no waiting sample (their SAMPLE was lost,
        or already handed on: the first FORCE of a link is, unless it came in the same read
        as its SAMPLE or an IDENTITY announced it), or whose taxel count differs from it;
        skipped. CAN: FORCE frames with no sample open (a lost SYNC), repeated, beyond the
        sample's groups, or of a sample dropped incomplete.
    force_missing : int
        Serial: frames of a board that sends FORCE handed on without one (its FORCE was
        lost): their ``force`` is all NaN. CAN: frames of a node that sends FORCE frames
        with at least one FORCE group lost (its taxels NaN) or of the wrong size (also
        counted ``malformed``).
    """

    bytes: int = 0
    frames: int = 0
    crc_errors: int = 0
    malformed: int = 0
    resyncs: int = 0
    replies: int = 0
    missing: int = 0
    lost_groups: int = 0
    orphans: int = 0
    lost_samples: int = 0
    lost_replies: int = 0
    duplicates: int = 0
    forces: int = 0
    force_orphans: int = 0
    force_missing: int = 0


#: A frame at most this many samples behind the newest of its board is a duplicate; further
#: back, the board restarted (its seq began again at 0).
DUPLICATE_WINDOW = 1024


def _follow(stats: LinkStats, last: int | None, seq: int, dropped: int = 0) -> bool:
    """Count the gap or duplicate from the newest seq ``last`` to ``seq``; True if it advances.

    ``dropped`` samples since ``last`` were already counted elsewhere (CAN's ``missing``).
    """
    if last is None:
        return True
    step = (seq - last) % (1 << 32)
    if step == 0 or step > (1 << 32) - DUPLICATE_WINDOW:
        stats.duplicates += 1
        return False
    if step < 1 << 31:  # forward; a jump far back is a restart, not a loss
        stats.lost_samples += max(0, step - 1 - dropped)
    return True


def _continues(last: int | None, seq: int) -> bool:
    """Whether ``seq`` follows ``last`` within `DUPLICATE_WINDOW` samples (CAN's gap check)."""
    return last is not None and 0 < (seq - last) % (1 << 32) <= DUPLICATE_WINDOW


#: Longest packet on the serial wire, delimiter included.
MAX_PACKET = MAX_BODY + 2 + -(-(MAX_BODY + 2) // 254) + 1


def _sample_frame(body: bytes, board: int, host_time: float | None = None) -> Frame | None:
    if len(body) < _HEADER.size + _TAIL.size:
        return None
    _, _, seq, t_us, n = _HEADER.unpack_from(body)
    if len(body) != _HEADER.size + 3 * n + _TAIL.size:
        return None
    words = np.frombuffer(body, dtype="<u2", count=n, offset=_HEADER.size)
    duty = np.frombuffer(body, dtype=np.uint8, count=n, offset=_HEADER.size + 2 * n).copy()
    ambient, flags = _TAIL.unpack_from(body, _HEADER.size + 3 * n)
    return Frame(seq, t_us * 1e-6, time.monotonic() if host_time is None else host_time,
                 (words & MAX_COUNT).astype(np.uint16),
                 math.nan if ambient == AMBIENT_UNKNOWN else ambient / 100.0, duty, flags,
                 board, (words >> 12).astype(np.uint8))


def _attach(frame: Frame, force: np.ndarray) -> None:
    """Set the force of a frame this decoder made and has not handed on yet.

    In place (the frame is frozen for its users; none has seen it yet): a copy by
    ``dataclasses.replace`` cost as much as decoding the sample.
    """
    object.__setattr__(frame, "force", force)


class StreamDecoder:
    """Turn a serial byte stream into frames and replies; bad bytes are counted, never raised.

    A reader that starts in the middle of a packet sees one malformed packet, then locks on.
    Gaps in seq count ``stats.lost_samples``, repeats ``stats.duplicates`` (see `LinkStats`).
    Sample frames are returned by `feed`; replies (`Ack`, `ErrorReply`, `Identity`,
    `SelftestResult`) are appended to ``replies``.

    Force channel: once a FORCE message has arrived (``has_force``), each SAMPLE is held until
    the next SAMPLE, and the FORCE of the same seq that follows it becomes its
    ``Frame.force``; a sample whose FORCE does not come is handed on with an all-NaN force
    (``stats.force_missing``), a FORCE that matches no held sample is counted
    (``stats.force_orphans``) and skipped; before the first, a FORCE is attached to the
    frame of the same read it follows. A held sample waits at most until the next
    SAMPLE or `flush` (a driver flushes when its link goes quiet, a replay at its end). A
    board that never sends FORCE costs nothing: its frames are handed on at once, with
    ``force`` None.

    Parameters
    ----------
    board : int
        Board id given to the decoded frames.
    force : bool
        Hold samples for their FORCE from the first one (the board is known to send FORCE);
        else from the first FORCE, or from an IDENTITY with `OPTION_FORCE` set.
    """

    def __init__(self, board: int = 0, force: bool = False) -> None:
        self.board = board
        self.stats = LinkStats()
        self.replies: deque[Reply] = deque()
        self._buffer = b""
        self._cobs = _cobs()
        self._last_seq: int | None = None
        self._held: Frame | None = None  # a sample waiting for its FORCE
        self._forced: Frame | None = None  # the held sample, its FORCE just attached
        self._late: tuple[int, np.ndarray] | None = None  # a FORCE no held sample matched
        self.has_force = force

    def flush(self, older_than: float | None = None, now: float | None = None) -> list[Frame]:
        """Hand on the sample held for its FORCE (all-NaN force: none came); [] if none.

        ``older_than``: only a sample held longer than this, s, since its SAMPLE arrived
        (its ``host_time``, against ``now``, ``time.monotonic()`` by default): a FORCE a few
        ms behind its SAMPLE (another USB frame) still finds it.
        """
        if self._held is None:
            return []
        if older_than is not None and (
                (time.monotonic() if now is None else now) - self._held.host_time < older_than):
            return []
        frame, self._held = self._held, None
        self.stats.force_missing += 1
        return [dataclasses.replace(frame, force=np.full(frame.counts.size, np.nan))]

    def discard(self) -> int:
        """Drop the sample held for its FORCE (the link is closed); return 0 or 1.

        A dropped sample is counted in ``stats.lost_samples``.
        """
        if self._held is None:
            return 0
        self._held = None
        self.stats.lost_samples += 1
        return 1

    def reset(self) -> None:
        """Drop a partly received packet (the link was cut); counted as a resync."""
        if self._buffer:
            self._buffer = b""
            self.stats.resyncs += 1

    def feed(self, data: bytes, host_time: float | None = None) -> list[Frame]:
        """Add received bytes; return the sample frames completed by them.

        ``host_time``: the arrival time the frames of these bytes get (a replay's recorded
        time); now (``time.monotonic``) by default.
        """
        self.stats.bytes += len(data)
        *packets, self._buffer = (self._buffer + bytes(data)).split(b"\x00")
        if len(self._buffer) > 2 * MAX_PACKET:  # no delimiter for too long: drop
            self._buffer = b""
            self.stats.resyncs += 1
        frames: list[Frame] = []
        for packet in packets:
            if packet:  # empty: two delimiters in a row
                frame = self._decode(packet, host_time)
                if self._forced is not None:  # the held sample, its FORCE attached
                    frames.append(self._forced)
                    self._forced = None
                elif frame is not None:
                    if self._held is not None:  # a sample still held: its FORCE did not come
                        frames += self.flush()
                    if self.has_force:
                        self._held = frame
                    else:
                        frames.append(frame)
                elif self._late is not None:  # a FORCE that no held sample waited for
                    seq, force = self._late
                    self._late = None
                    last = frames[-1] if frames else None
                    if (last is not None and last.force is None and last.seq == seq
                            and last.counts.size == force.size):  # the first, in the same read
                        _attach(last, force)
                        self.stats.forces += 1
                    else:
                        self.stats.force_orphans += 1
        return frames

    def _force(self, body: bytes) -> None:
        parsed = _force_of(body)
        if parsed is None:
            return self._bad("malformed")
        self.has_force = True
        seq, force = parsed
        held = self._held
        if held is None or held.seq != seq or held.counts.size != force.size:
            self._late = (seq, force)
            return None
        self._held = None
        _attach(held, force)
        self._forced = held
        self.stats.forces += 1
        return None

    def _decode(self, packet: bytes, host_time: float | None = None) -> Frame | None:
        try:
            raw = self._cobs.decode(packet)
        except self._cobs.DecodeError:
            raw = b""
        if len(raw) < 4:  # not COBS, or no room for version, type and CRC
            return self._bad("malformed")
        body = raw[:-2]
        if crc16(body) != _U16.unpack(raw[-2:])[0]:
            return self._bad("crc_errors")
        if body[0] != VERSION:
            return self._bad("malformed")
        if body[1] == MsgType.SAMPLE:
            frame = _sample_frame(body, self.board, host_time)
            if frame is None:
                return self._bad("malformed")
            self.stats.frames += 1
            if _follow(self.stats, self._last_seq, frame.seq):
                self._last_seq = frame.seq
            return frame
        if body[1] == MsgType.FORCE:
            return self._force(body)
        try:
            reply = parse_reply(body)
        except ValueError:
            return self._bad("malformed")
        if isinstance(reply, Identity) and reply.options & OPTION_FORCE:
            self.has_force = True
        self.replies.append(reply)
        self.stats.replies += 1
        return None

    def _bad(self, counter: str) -> None:
        setattr(self.stats, counter, getattr(self.stats, counter) + 1)
        self.stats.resyncs += 1  # skipped to the next delimiter


# ---- CAN ----

CanFrame = tuple[int, bytes]


def can_id(kind: int, node: int, index: int) -> int:
    """Return the 11-bit identifier ``kind << 8 | node << 5 | index``."""
    return _u(kind, 3, "CAN type") << 8 | _u(node, 3, "node") << 5 | _u(index, 5, "index")


def can_sample_frames(
    node: int,
    seq: int,
    device_time_us: int,
    counts: Sequence[int] | np.ndarray,
    ambient: float | None,
    duty: Sequence[int] | np.ndarray,
    flags: int = 0,
    status: Sequence[int] | np.ndarray | None = None,
    force: Sequence[float] | np.ndarray | None = None,
) -> list[CanFrame]:
    """Cut one sample into CAN frames: SYNC, DATA 0 .. G-1, DUTY group seq mod ceil(n/8), STATUS.

    Parameters are those of `encode_sample`, after the ``node`` (0-6); a node carries
    1 - `CAN_MAX_TAXELS` taxels. With ``force`` (N per taxel, NaN: no reading; as
    `encode_force`) the frames FORCE 0 .. G-1 (u16 mN of taxels 4g .. 4g+3) come between the
    DUTY frame and STATUS, as a board with a force channel sends them.

    Returns
    -------
    list of (int, bytes)
        (identifier, data) of each frame, in sending order.
    """
    words = _taxel_words(counts, status)
    n = words.size
    if not 1 <= n <= CAN_MAX_TAXELS:
        raise ValueError(f"{n} taxels; a CAN node carries 1 to {CAN_MAX_TAXELS}")
    if node == CAN_BROADCAST:
        raise ValueError(f"node {CAN_BROADCAST} is the broadcast address, not a node")
    duty = _duty_bytes(duty, n).tobytes()
    seq %= 1 << 32
    data = words.tobytes()
    groups = -(-n // 4)
    d = seq % -(-n // 8)
    forces: list[CanFrame] = []
    if force is not None:
        raw = force_body(seq, force)[_FORCE_HEAD.size:]
        if len(raw) != 2 * n:
            raise ValueError(f"force has {len(raw) // 2} channels, the sample {n}")
        forces = [(can_id(CanType.FORCE, node, g), raw[8 * g : 8 * g + 8])
                  for g in range(groups)]
    return [
        (can_id(CanType.SYNC, node, 0), _SYNC.pack(seq, device_time_us % (1 << 32))),
        *((can_id(CanType.DATA, node, g), data[8 * g : 8 * g + 8]) for g in range(groups)),
        (can_id(CanType.DUTY, node, d), duty[8 * d : 8 * d + 8]),
        *forces,
        (can_id(CanType.STATUS, node, 0),
         _STATUS.pack(seq & 0xFF, _u(flags, 16, "flags"), _ambient_raw(ambient), groups)),
    ]


def can_command_frame(node: int, command: Command) -> CanFrame:
    """Return the COMMAND frame of a command to ``node`` (`CAN_BROADCAST`: every node)."""
    return can_id(CanType.COMMAND, node, 0), command.body()


_CAN_RECORD = struct.Struct("<HB")
#: Set in a `can_record`'s identifier when the message was not a standard data frame.
CAN_RECORD_FOREIGN = 0x8000


def can_record(ident: int, data: bytes, foreign: bool = False) -> bytes:
    """Pack one CAN message as the raw record a driver's tap and a recording hold.

    The record is u16 identifier (bit 15 set for extended, remote or error frames: not ours),
    u8 length, then the data bytes.
    """
    if not 0 <= len(data) <= 64:
        raise ValueError(f"a CAN message of {len(data)} bytes")
    return _CAN_RECORD.pack((ident & 0x7FF) | (CAN_RECORD_FOREIGN if foreign else 0),
                            len(data)) + bytes(data)


def split_can_records(raw: bytes) -> list[tuple[int, bytes, bool]]:
    """Unpack records written by `can_record`: a list of (identifier, data, foreign).

    Raises
    ------
    ProtocolError
        If ``raw`` ends inside a record (the byte offset is named).
    """
    out = []
    offset = 0
    while offset < len(raw):
        if offset + _CAN_RECORD.size > len(raw):
            raise ProtocolError(f"a CAN record truncated at byte {offset}")
        ident, length = _CAN_RECORD.unpack_from(raw, offset)
        end = offset + _CAN_RECORD.size + length
        if end > len(raw):
            raise ProtocolError(f"a CAN record at byte {offset} claims {length} bytes; "
                                f"{len(raw) - offset - _CAN_RECORD.size} remain")
        out.append((ident & 0x7FF, raw[offset + _CAN_RECORD.size : end],
                    bool(ident & CAN_RECORD_FOREIGN)))
        offset = end
    return out


def can_reply_frames(node: int, body: bytes) -> list[CanFrame]:
    """Cut a reply body into REPLY segments of up to 8 bytes, the u16 body length first."""
    if len(body) > MAX_BODY:
        raise ValueError(f"a reply body of {len(body)} bytes; at most {MAX_BODY}")
    data = _U16.pack(len(body)) + body
    return [(can_id(CanType.REPLY, node, k % 32), data[8 * k : 8 * k + 8])
            for k in range(-(-len(data) // 8))]


@dataclass
class _Node:
    """Reassembly state of one CAN node."""

    seq: int | None = None  # the open sample's seq (None: no sample open)
    time_us: int = 0
    sync_host: float | None = None  # host arrival time of the open sample's SYNC
    groups: dict[int, bytes] = field(default_factory=dict)
    forces: dict[int, bytes] = field(default_factory=dict)  # the open sample's FORCE groups
    has_force: bool = False  # the node has sent a FORCE frame: its samples carry force
    n_groups: int = 0  # G of the last STATUS seen, to count the groups of a dropped sample
    duty: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.uint8))
    heard: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))  # duty known
    last_seq: int | None = None  # seq of the last complete sample
    dropped: int = 0  # samples dropped incomplete since then
    # a gap waiting for the next sample to confirm it: (seq before it, dropped then, gap)
    pending: tuple[int, int, int] | None = None
    trusted: bool = False  # last_seq continued from the sample before it
    reply: bytearray | None = None
    reply_len: int = 0
    reply_next: int = 0


class CanReassembler:
    """Put the CAN frames of every node back together into frames and replies.

    Per node: SYNC opens a sample, DATA fills its groups, STATUS closes it; an incomplete
    sample is dropped (``stats.missing``, ``stats.lost_groups``), DATA or STATUS with no sample
    open is ignored (``stats.orphans``), seq gaps count the samples lost whole
    (``stats.lost_samples``; a gap longer than `DUPLICATE_WINDOW` once the next sample
    confirms it, and a sample whose successor continues from before it had a damaged seq) and
    repeats ``stats.duplicates``. Duties are the last received per taxel. FORCE frames
    (between DUTY and STATUS) fill the open sample's force groups: once a node has sent one,
    its frames carry ``force`` (N, NaN for a lost group or 0xFFFF; ``stats.forces``,
    ``force_missing``, ``force_orphans``); a node that never sent one gives ``force`` None.
    REPLY segments are
    concatenated per node into ``replies``, as (node, reply). COMMAND frames (the host's own)
    are ignored.

    Parameters
    ----------
    boards : dict of int to int, optional
        Board id of each node's frames (the node number by default).
    """

    def __init__(self, boards: dict[int, int] | None = None) -> None:
        self.boards = dict(boards or {})
        self.stats = LinkStats()
        self.replies: deque[tuple[int, Reply]] = deque()
        self._nodes: dict[int, _Node] = {}

    def feed(self, frames: Iterable[CanFrame]) -> list[Frame]:
        """Add received (identifier, data) frames; return the samples completed by them."""
        out = []
        for ident, data in frames:
            frame = self.push(ident, data)
            if frame is not None:
                out.append(frame)
        return out

    def push(self, ident: int, data: bytes, host_time: float | None = None) -> Frame | None:
        """Add one received frame; return the sample it completes, if any.

        ``host_time`` is the frame's arrival on the host (``time.monotonic`` clock; python-can's
        message timestamp, mapped); a sample's ``Frame.host_time`` is its SYNC's, or the time
        of the push that completes it when none was given.
        """
        data = bytes(data)
        if not 0 <= ident < 0x800 or len(data) > 8:
            self.stats.malformed += 1
            return None
        kind, node_id, index = ident >> 8, ident >> 5 & 7, ident & 31
        node = self._nodes.get(node_id)
        if node is None:  # not setdefault: a _Node costs more than the rest of a push
            node = self._nodes[node_id] = _Node()
        if kind == CanType.SYNC and len(data) == _SYNC.size and index == 0:
            if node.seq is not None:
                self._drop(node, node.n_groups)
            node.seq, node.time_us = _SYNC.unpack(data)
            node.sync_host = host_time
            node.groups = {}
            node.forces = {}
        elif kind == CanType.DATA and data and len(data) % 2 == 0:
            if node.seq is None:
                self.stats.orphans += 1
            else:
                node.groups[index] = data
        elif kind == CanType.DUTY and data:
            end = 8 * index + len(data)
            if node.duty.size < end:
                node.duty = np.concatenate([node.duty, np.zeros(end - node.duty.size, np.uint8)])
                node.heard = np.concatenate([node.heard, np.zeros(end - node.heard.size, bool)])
            node.duty[8 * index : end] = np.frombuffer(data, dtype=np.uint8)
            node.heard[8 * index : end] = True
        elif kind == CanType.STATUS and len(data) == _STATUS.size and index == 0:
            if node.seq is None:
                self.stats.orphans += 1
                return None
            return self._close(node_id, node, *_STATUS.unpack(data))
        elif kind == CanType.FORCE and data and len(data) % 2 == 0:
            node.has_force = True
            if node.seq is None or index in node.forces:
                self.stats.force_orphans += 1  # its SYNC was lost, or a repeat
            else:
                node.forces[index] = data
        elif kind == CanType.REPLY:
            self._segment(node_id, node, index, data)
        elif kind != CanType.COMMAND:
            self.stats.malformed += 1
        return None

    def _drop(self, node: _Node, n_groups: int) -> None:
        self.stats.force_orphans += len(node.forces)  # their sample is lost
        node.forces = {}
        self.stats.missing += 1
        self.stats.lost_groups += max(0, n_groups - sum(g < n_groups for g in node.groups))
        node.dropped += 1
        node.seq = None

    def _close(self, node_id: int, node: _Node, seq8: int, flags: int, ambient: int,
               n_groups: int) -> Frame | None:
        node.n_groups = n_groups
        groups = [node.groups.get(g) for g in range(n_groups)]
        if (seq8 != node.seq & 0xFF or len(node.groups) != n_groups or None in groups
                or any(len(g) != 8 for g in groups[:-1])):
            self._drop(node, n_groups)
            return None
        seq = node.seq
        node.seq = None
        # A SYNC's seq has no check of its own beyond the bus CRC (STATUS repeats its low 8
        # bits): a damaged one would count up to 2^31 samples lost. So a gap longer than
        # DUPLICATE_WINDOW is counted only once the next sample continues from it (never from
        # a sample nothing led up to: the first, or one after a jump, whose own seq may be the
        # damaged one), and a shorter gap is taken back when the next sample continues from
        # before it (the sample that jumped had a damaged seq).
        if node.pending is not None:
            before, dropped, gap = node.pending
            node.pending = None
            if _continues(node.last_seq, seq):  # confirmed
                if gap > DUPLICATE_WINDOW:
                    self.stats.lost_samples += gap
            elif _continues(before, seq):  # the jump was a damaged seq: take it back
                if gap <= DUPLICATE_WINDOW:
                    self.stats.lost_samples -= gap
                # and it took one sample's place: not a gap
                node.last_seq, node.dropped = before, dropped + node.dropped + 1
        counted = self.stats.lost_samples
        last, dropped = node.last_seq, node.dropped
        if _follow(self.stats, node.last_seq, seq, node.dropped):
            gap = self.stats.lost_samples - counted
            follows = _continues(last, seq)
            if gap > DUPLICATE_WINDOW:  # held until the next sample confirms it
                self.stats.lost_samples = counted
                gap = gap if node.trusted else 0
            if last is not None and (gap or not follows):  # the next sample may take it back
                node.pending = (last, dropped, gap)
            node.trusted = follows
            node.last_seq, node.dropped = seq, 0
        words = np.frombuffer(b"".join(groups), dtype="<u2")  # type: ignore[arg-type]
        n = words.size
        duty = np.zeros(n, dtype=np.uint8)
        known = min(n, node.duty.size)
        duty[:known] = node.duty[:known]
        # the duties not heard yet read 0: say so, until every one has come
        heard = None if known == n and node.heard[:n].all() else np.zeros(n, dtype=bool)
        if heard is not None:
            heard[:known] = node.heard[:known]
        self.stats.frames += 1
        host = time.monotonic() if node.sync_host is None else node.sync_host
        frame = Frame(seq, node.time_us * 1e-6, host,
                      (words & MAX_COUNT).astype(np.uint16),
                      math.nan if ambient == AMBIENT_UNKNOWN else ambient / 100.0, duty, flags,
                      self.boards.get(node_id, node_id), (words >> 12).astype(np.uint8))
        if node.has_force:
            _attach(frame, self._force(node, n))
        if heard is not None:
            object.__setattr__(frame, "duty_known", heard)  # as `_attach`: not handed on yet
        return frame

    def _force(self, node: _Node, n: int) -> np.ndarray:
        """Return the open sample's force, N (NaN where its FORCE group did not arrive)."""
        force = np.full(n, math.nan)
        complete = True
        for g in range((n + 3) // 4):
            data = node.forces.pop(g, None)
            width = min(4, n - 4 * g)
            if data is None or len(data) != 2 * width:
                complete = False
                if data is not None:
                    self.stats.malformed += 1  # a group of the wrong size
                continue
            raw = np.frombuffer(data, dtype="<u2")
            force[4 * g : 4 * g + width] = force_newtons(raw)
        self.stats.force_orphans += len(node.forces)  # groups beyond the sample's taxels
        node.forces = {}
        if complete:
            self.stats.forces += 1
        else:
            self.stats.force_missing += 1
        return force

    def _segment(self, node_id: int, node: _Node, index: int, data: bytes) -> None:
        if node.reply is not None and index == node.reply_next % 32:
            node.reply += data
            node.reply_next += 1
        else:
            if node.reply is not None:
                self.stats.lost_replies += 1  # a segment was skipped
                node.reply = None
            if index != 0:
                self.stats.orphans += 1
                return
            if len(data) < 2:
                self.stats.malformed += 1
                return
            (node.reply_len,) = _U16.unpack_from(data)
            if not 3 <= node.reply_len <= MAX_BODY:
                self.stats.malformed += 1
                return
            node.reply, node.reply_next = bytearray(data[2:]), 1
        done = len(node.reply) >= node.reply_len
        if (len(data) != 8 and not done) or len(node.reply) > node.reply_len:
            self.stats.malformed += 1  # only the last segment is short
            node.reply = None
            return
        if done:
            body, node.reply = bytes(node.reply), None
            try:
                self.replies.append((node_id, parse_reply(body)))
            except ValueError:
                self.stats.malformed += 1
                return
            self.stats.replies += 1

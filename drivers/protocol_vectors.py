"""Test vectors of wire protocol v1, shared by the firmware's tests and the driver's.

``python -m skin.drivers.protocol_vectors [DIR]`` writes ``serial.txt``, ``can.txt`` and
``serial_force.txt`` (the optional FORCE message, which firmware built with force inputs sends;
the C host test checks ``skin_pack_force`` against it)
(``firmware/test_vectors`` of the source tree by default) from the values below; the format is
described in ``firmware/test_vectors/README.md``. `read_vectors` parses them back.

The values are explicit; the bytes come from this package's encoders, checked on the way
against the values that have an outside reference (the CRC's catalogued check value, the
classic COBS examples) and, for the commands a board must refuse, against the ERROR expected.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

from skin.drivers.protocol import (
    ALL_TAXELS,
    AMBIENT_UNKNOWN,
    Ack,
    Command,
    ErrorCode,
    ErrorReply,
    Identity,
    MsgType,
    SelftestResult,
    argument_names,
    can_command_frame,
    can_reply_frames,
    can_sample_frames,
    cobs_encode,
    crc16,
    encode_force,
    encode_sample,
    force_body,
    frame_packet,
    layout_hash,
    parse_command_packet,
    sample_body,
)
from skin.frame import (
    FLAG_ADC_SATURATED,
    FLAG_AMBIENT_FAULT,
    FLAG_HEATER_FAULT,
    FLAG_OVER_TEMPERATURE,
    FLAG_POWER_LIMITED,
    FLAG_SAMPLE_OVERRUN,
    FLAG_SELFTEST,
    FLAG_STREAMING,
    FLAG_THERMISTOR_FAULT,
    FLAG_TX_OVERRUN,
)

#: Where the vectors live in the source tree.
DEFAULT_DIR = Path(__file__).resolve().parents[1] / "firmware" / "test_vectors"

BYTES_KEYS = frozenset({"body", "wire", "raw", "encoded", "data", "reply_wire"})
#: The keys whose value is a list, per kind (``duty`` is one int in a command).
LIST_KEYS = {"fnv": frozenset({"ids"}),
             "sample": frozenset({"counts", "status", "duty"}),
             "can_sample": frozenset({"counts", "status", "duty"}),
             "selftest_result": frozenset({"response", "strongest"}),
             "force": frozenset({"force_mn"})}
_HEX_DIGITS = {"crc": 4, "hash": 8, "type": 2, "command": 2, "flags": 4, "layout_hash": 8}

Block = dict[str, object]

# ---- values ----

CRC = [  # (name, data, CRC-16/CCITT-FALSE from the catalogue or worked by hand)
    ("check value", b"123456789", 0x29B1),
    ("one zero byte", b"\x00", 0xE1F0),
    ("ASCII A", b"A", 0xB915),
    ("256 bytes 0x00 to 0xff", bytes(range(256)), 0x3FBD),
]

COBS = [  # (name, raw, encoded): Cheshire and Baker's examples, as on Wikipedia's COBS page
    ("one zero", b"\x00", bytes.fromhex("0101")),
    ("two zeros", b"\x00\x00", bytes.fromhex("010101")),
    ("zero data zero", bytes.fromhex("001100"), bytes.fromhex("01021101")),
    ("zero in the middle", bytes.fromhex("11220033"), bytes.fromhex("0311220233")),
    ("no zero", bytes.fromhex("11223344"), bytes.fromhex("0511223344")),
    ("trailing zeros", bytes.fromhex("11000000"), bytes.fromhex("0211010101")),
    ("254 non-zero bytes", bytes(range(1, 255)), b"\xff" + bytes(range(1, 255))),
    ("255 bytes from zero", bytes(range(255)), b"\x01\xff" + bytes(range(1, 255))),
    ("255 non-zero bytes", bytes(range(1, 256)), b"\xff" + bytes(range(1, 255)) + b"\x02\xff"),
    ("254 non-zero then a zero", bytes(range(2, 256)) + b"\x00",
     b"\xff" + bytes(range(2, 256)) + b"\x01\x01"),
    ("253 non-zero, zero, one", bytes(range(3, 256)) + b"\x00\x01",
     b"\xfe" + bytes(range(3, 256)) + b"\x02\x01"),
    ("600 non-zero bytes", bytes(1 + i % 255 for i in range(600)), None),  # None: encoder's
]

FNV = [
    ("ids 0 1 2", [0, 1, 2]),
    ("ids 0 to 15", list(range(16))),
    ("ids out of order", [101, 7, 42, 1000]),
]

_ALL_FLAGS = (FLAG_ADC_SATURATED | FLAG_THERMISTOR_FAULT | FLAG_HEATER_FAULT
              | FLAG_OVER_TEMPERATURE | FLAG_AMBIENT_FAULT | FLAG_POWER_LIMITED | FLAG_TX_OVERRUN
              | FLAG_SAMPLE_OVERRUN | FLAG_SELFTEST | FLAG_STREAMING)


def _long_counts(n: int) -> list[int]:
    # no zero byte in any taxel word: COBS then needs one code byte per 254 bytes
    counts = [0x101 + (i * 37) % 0xE00 for i in range(n)]
    return [c + 1 if c & 0xFF == 0 else c for c in counts]


SAMPLES: list[Block] = [  # ambient in 0.01 deg C as on the wire
    {"name": "no taxels", "seq": 0, "time_us": 0, "counts": [], "status": [], "duty": [],
     "ambient": 2500, "flags": FLAG_STREAMING},
    {"name": "one taxel, negative ambient", "seq": 1, "time_us": 5000, "counts": [2048],
     "status": [0], "duty": [128], "ambient": -512, "flags": FLAG_STREAMING},
    {"name": "rails, ambient unknown, seq and time at their last value", "seq": 0xFFFFFFFF,
     "time_us": 0xFFFFFFFF, "counts": [0, 4095, 1234],
     "status": [FLAG_ADC_SATURATED | FLAG_THERMISTOR_FAULT, FLAG_ADC_SATURATED, 0],
     "duty": [0, 0, 77], "ambient": AMBIENT_UNKNOWN,
     "flags": FLAG_ADC_SATURATED | FLAG_THERMISTOR_FAULT | FLAG_AMBIENT_FAULT | FLAG_STREAMING},
    {"name": "16 taxels, every status and every flag", "seq": 123456789, "time_us": 4000000000,
     "counts": [i * 273 for i in range(16)], "status": list(range(16)),
     "duty": [i * 17 for i in range(16)], "ambient": 2537, "flags": _ALL_FLAGS},
    {"name": "72 taxels", "seq": 987654, "time_us": 4938270000 % (1 << 32),
     "counts": [(i * 611) % 4096 for i in range(72)],
     "status": [(0, 0, 0, FLAG_HEATER_FAULT, 0, FLAG_OVER_TEMPERATURE)[i % 6] for i in range(72)],
     "duty": [(i * 29) % 256 for i in range(72)], "ambient": 2215,
     "flags": FLAG_HEATER_FAULT | FLAG_OVER_TEMPERATURE | FLAG_POWER_LIMITED | FLAG_STREAMING},
    {"name": "336 taxels, the longest body (1024 bytes): COBS adds a byte per 254",
     "seq": 0x01020304, "time_us": 0x05060708, "counts": _long_counts(336),
     "status": [i % 2 for i in range(336)], "duty": [1 + i % 255 for i in range(336)],
     "ambient": 0x0909, "flags": FLAG_ADC_SATURATED | FLAG_STREAMING},
]

COMMANDS = [
    Command(MsgType.START, 1),
    Command(MsgType.START, 0),
    Command(MsgType.STOP, 2),
    Command(MsgType.SET_RATE, 3, rate_hz=200),
    Command(MsgType.SET_RATE, 4, rate_hz=4),
    Command(MsgType.SET_DUTY, 5, taxel=5, duty=128),
    Command(MsgType.SET_DUTY, 6, taxel=ALL_TAXELS, duty=0),
    Command(MsgType.SET_SETPOINT, 7, taxel=15, count=3000),
    Command(MsgType.SET_SETPOINT, 8, taxel=ALL_TAXELS, count=0),
    Command(MsgType.IDENTIFY, 9),
    Command(MsgType.SELFTEST, 10, pulse_ms=500, duty=255),
    Command(MsgType.CLEAR_FAULTS, 0xFF),
]

MEGA = Identity(token=9, fw_major=1, fw_minor=0, fw_patch=0, board_id=2, mcu=2, transport=0,
                options=3, taxels=72, adc_bits=12, oversampling=4, rate_hz=200, max_rate_hz=500,
                layout_hash=layout_hash(range(72)), baud_div=10000)
UNO_CAN = Identity(token=0x80, fw_major=1, fw_minor=2, fw_patch=3, board_id=5, mcu=1,
                   transport=1, options=1, taxels=16, adc_bits=12, oversampling=16, rate_hz=100,
                   max_rate_hz=200, layout_hash=0, baud_div=500)
SELFTEST_16 = SelftestResult(
    11, tuple(100 + 5 * i for i in range(16)),
    tuple(i if i not in (6, 9) else {6: 7, 9: 0xFFFF}[i] for i in range(16)))

REPLIES: list[tuple[str, Ack | ErrorReply | Identity | SelftestResult]] = [
    ("ack of SET_RATE", Ack(3, MsgType.SET_RATE)),
    ("ack of START with token 0", Ack(0, MsgType.START)),
    ("error: argument 0 of SET_DUTY", ErrorReply(5, MsgType.SET_DUTY, ErrorCode.ERR_ARGUMENT, 0)),
    ("error: busy with a self-test", ErrorReply(12, MsgType.SET_DUTY, ErrorCode.ERR_BUSY, 0)),
    ("error: too long for a 64-byte buffer", ErrorReply(0, 0, ErrorCode.ERR_TOO_LONG, 64)),
    ("identity of a Mega on serial", MEGA),
    ("identity of an Uno on CAN", UNO_CAN),
    ("selftest result, no taxels", SelftestResult(0, (), ())),
    ("selftest result, 3 taxels", SelftestResult(10, (120, -3, 0), (0, 0, 0xFFFF))),
    ("selftest result, 16 taxels", SELFTEST_16),
]

#: The board the bad commands are sent to.
BAD_BOARD = {"n_taxels": 16, "max_rate_hz": 500}


def _bad_crc() -> bytes:
    body = Command(MsgType.SET_RATE, 3, rate_hz=200).body()
    return cobs_encode(body + ((crc16(body) ^ 0xFFFF).to_bytes(2, "little"))) + b"\x00"


_BAD_COBS_LONG = b"\xff" + bytes(1 + i % 255 for i in range(254)) + b"\x05\x01\x00"

BAD_COMMANDS = [  # (name, wire, expected ERROR: token, command, code, detail)
    ("bad CRC", _bad_crc(), (0, 0, ErrorCode.ERR_CRC,
                             crc16(Command(MsgType.SET_RATE, 3, rate_hz=200).body()) ^ 0xFFFF)),
    ("bad COBS: the first code runs past the end", bytes.fromhex("0501100100"),
     (0, 0, ErrorCode.ERR_FRAMING, 0)),
    ("bad COBS after a full block: offset 254 in the decoded body (input offset 255)",
     _BAD_COBS_LONG, (0, 0, ErrorCode.ERR_FRAMING, 254)),
    ("too short for a CRC: the decoded length", bytes.fromhex("020100"),
     (0, 0, ErrorCode.ERR_LENGTH, 1)),
    ("truncated body: no token", frame_packet(bytes.fromhex("0112")),
     (0, 0, ErrorCode.ERR_LENGTH, 2)),
    ("truncated body: SET_RATE without its high byte", frame_packet(bytes.fromhex("011203c8")),
     (0, 0, ErrorCode.ERR_LENGTH, 4)),
    ("wrong version", frame_packet(bytes.fromhex("021007")), (7, 0x10, ErrorCode.ERR_VERSION, 2)),
    ("wrong version in a 1-byte body: too short to read, a length error first",
     frame_packet(bytes.fromhex("02")), (0, 0, ErrorCode.ERR_LENGTH, 1)),
    ("unknown type", frame_packet(bytes.fromhex("012008")), (8, 0x20, ErrorCode.ERR_TYPE, 0x20)),
    ("a reply type sent as a command", frame_packet(bytes.fromhex("01030910")),
     (9, 0x03, ErrorCode.ERR_TYPE, 0x03)),
    ("START with an extra byte", frame_packet(bytes.fromhex("01100a00")),
     (0, 0, ErrorCode.ERR_LENGTH, 4)),
    ("SET_SETPOINT one byte short", frame_packet(bytes.fromhex("01140b0f00b8")),
     (0, 0, ErrorCode.ERR_LENGTH, 6)),
    ("taxel out of range (16 of 16)", Command(MsgType.SET_DUTY, 12, taxel=16, duty=9).encode(),
     (12, MsgType.SET_DUTY, ErrorCode.ERR_ARGUMENT, 0)),
    ("taxel 0xFFFE", Command(MsgType.SET_SETPOINT, 13, taxel=0xFFFE, count=100).encode(),
     (13, MsgType.SET_SETPOINT, ErrorCode.ERR_ARGUMENT, 0)),
    ("rate 0", Command(MsgType.SET_RATE, 14, rate_hz=0).encode(),
     (14, MsgType.SET_RATE, ErrorCode.ERR_ARGUMENT, 0)),
    ("rate 3", Command(MsgType.SET_RATE, 15, rate_hz=3).encode(),
     (15, MsgType.SET_RATE, ErrorCode.ERR_ARGUMENT, 0)),
    ("rate above max_rate_hz", Command(MsgType.SET_RATE, 16, rate_hz=501).encode(),
     (16, MsgType.SET_RATE, ErrorCode.ERR_ARGUMENT, 0)),
    ("count 4096", Command(MsgType.SET_SETPOINT, 17, taxel=3, count=4096).encode(),
     (17, MsgType.SET_SETPOINT, ErrorCode.ERR_ARGUMENT, 1)),
    ("bad taxel and bad count: the first is reported",
     Command(MsgType.SET_SETPOINT, 18, taxel=99, count=0xFFFF).encode(),
     (18, MsgType.SET_SETPOINT, ErrorCode.ERR_ARGUMENT, 0)),
    ("pulse_ms 0", Command(MsgType.SELFTEST, 19, pulse_ms=0, duty=200).encode(),
     (19, MsgType.SELFTEST, ErrorCode.ERR_ARGUMENT, 0)),
]

CAN_SAMPLES: list[Block] = [
    {"name": "1 taxel", "node": 0, "seq": 0, "time_us": 0, "counts": [1000], "status": [0],
     "duty": [200], "ambient": 2400, "flags": FLAG_STREAMING},
    {"name": "4 taxels: one full group", "node": 1, "seq": 1, "time_us": 5000,
     "counts": [1, 2, 3, 4095], "status": [0, 0, 0, FLAG_ADC_SATURATED], "duty": [10, 20, 30, 40],
     "ambient": -1, "flags": FLAG_ADC_SATURATED | FLAG_STREAMING},
    {"name": "5 taxels: a short last group", "node": 2, "seq": 2, "time_us": 10000,
     "counts": [500, 600, 700, 800, 900], "status": [0, FLAG_HEATER_FAULT, 0, 0, 0],
     "duty": [1, 2, 3, 4, 5], "ambient": 2501,
     "flags": FLAG_HEATER_FAULT | FLAG_TX_OVERRUN | FLAG_STREAMING},
    {"name": "16 taxels, duty group 1", "node": 3, "seq": 7, "time_us": 35000,
     "counts": [i * 255 for i in range(16)], "status": list(range(16)),
     "duty": [255 - i for i in range(16)], "ambient": 2600, "flags": _ALL_FLAGS},
    {"name": "72 taxels, duty group 6, ambient unknown", "node": 6, "seq": 12345,
     "time_us": 61725000, "counts": [(i * 57) % 4096 for i in range(72)],
     "status": [FLAG_OVER_TEMPERATURE if i == 70 else 0 for i in range(72)],
     "duty": [(i * 3) % 256 for i in range(72)], "ambient": AMBIENT_UNKNOWN,
     "flags": FLAG_OVER_TEMPERATURE | FLAG_AMBIENT_FAULT | FLAG_STREAMING},
    {"name": "128 taxels: 32 groups, duty group 15", "node": 5, "seq": 0x1234567F,
     "time_us": 0xFFFFFF00, "counts": [(i * 32) % 4096 for i in range(128)],
     "status": [0] * 128, "duty": list(range(128)), "ambient": 1999, "flags": FLAG_STREAMING},
]

CAN_COMMANDS = [
    ("START to node 0", 0, Command(MsgType.START, 1)),
    ("SET_RATE to node 2", 2, Command(MsgType.SET_RATE, 2, rate_hz=100)),
    ("SET_SETPOINT of every taxel to every node", 7,
     Command(MsgType.SET_SETPOINT, 3, taxel=ALL_TAXELS, count=2000)),
    ("SET_DUTY to node 6", 6, Command(MsgType.SET_DUTY, 4, taxel=127, duty=64)),
    ("SELFTEST to node 3", 3, Command(MsgType.SELFTEST, 5, pulse_ms=2000, duty=180)),
    ("IDENTIFY to node 4", 4, Command(MsgType.IDENTIFY, 6)),
    ("CLEAR_FAULTS to every node", 7, Command(MsgType.CLEAR_FAULTS, 7)),
]

CAN_REPLIES = [
    ("ack: one segment", 0, Ack(1, MsgType.START)),
    ("error", 6, ErrorReply(4, MsgType.SET_DUTY, ErrorCode.ERR_ARGUMENT, 0)),
    ("identity: 4 segments", 1, UNO_CAN),
    ("selftest result of 16 taxels: 9 segments", 2, SELFTEST_16),
    ("selftest result of 72 taxels: 37 segments, the index wraps at 32", 3,
     SelftestResult(12, tuple(80 - i for i in range(72)), tuple(range(72)))),
]

FORCES: list[Block] = [  # force in mN as on the wire; 65535 (FORCE_NONE): no reading
    {"name": "no taxels", "seq": 0, "force_mn": []},
    {"name": "3 taxels, the middle one without a sensor", "seq": 7,
     "force_mn": [0, 65535, 1500]},
    {"name": "contact switch of 4 taxels (0 / 1 N), seq wraps", "seq": 0xFFFFFFFF,
     "force_mn": [1000, 0, 0, 1000]},
    {"name": "largest force, and a value with a zero byte", "seq": 256,
     "force_mn": [65534, 256, 1]},
]

# ---- blocks ----


def _sample_args(v: Block) -> tuple:
    ambient = None if v["ambient"] == AMBIENT_UNKNOWN else v["ambient"] / 100  # type: ignore[operator]
    return (v["seq"], v["time_us"], v["counts"], ambient, v["duty"], v["flags"], v["status"])


def _reply_block(kind_name: str, reply: Ack | ErrorReply | Identity | SelftestResult) -> Block:
    kind = {Ack: "ack", ErrorReply: "error", Identity: "identity",
            SelftestResult: "selftest_result"}[type(reply)]
    fields = {k: (list(v) if isinstance(v, tuple) else int(v))
              for k, v in reply.__dict__.items()}
    return {"kind": kind, "name": kind_name, **fields, "body": reply.body(),
            "wire": reply.encode()}


def serial_blocks() -> Iterator[Block]:
    """Yield the blocks of ``serial.txt``, bytes computed from the values above."""
    for name, data, crc in CRC:
        if crc16(data) != crc:
            raise AssertionError(f"crc {name}: 0x{crc16(data):04X}, expected 0x{crc:04X}")
        yield {"kind": "crc", "name": name, "data": data, "crc": crc}
    for name, raw, encoded in COBS:
        got = cobs_encode(raw)
        if encoded is not None and got != encoded:
            raise AssertionError(f"cobs {name}: {got.hex()}")
        yield {"kind": "cobs", "name": name, "raw": raw, "encoded": got}
    for name, ids in FNV:
        yield {"kind": "fnv", "name": name, "ids": ids, "hash": layout_hash(ids)}
    for v in SAMPLES:
        body = sample_body(*_sample_args(v))
        yield {"kind": "sample", **v, "body": body, "crc": crc16(body),
               "wire": encode_sample(*_sample_args(v))}
    for cmd in COMMANDS:
        args = {k: getattr(cmd, k) for k in argument_names(cmd.type)}
        name = " ".join([MsgType(cmd.type).name, f"token {cmd.token}",
                         *(f"{k} {v}" for k, v in args.items())])
        yield {"kind": "command", "name": name, "type": int(cmd.type),
               "token": cmd.token, **args, "body": cmd.body(), "wire": cmd.encode()}
    for name, reply in REPLIES:
        yield _reply_block(name, reply)
    for name, wire, (token, command, code, detail) in BAD_COMMANDS:
        expected = ErrorReply(token, int(command), int(code), detail)
        got = parse_command_packet(wire[:-1], **BAD_BOARD)
        if got != expected:
            raise AssertionError(f"bad_command {name}: {got}, expected {expected}")
        yield {"kind": "bad_command", "name": name, "wire": wire, **BAD_BOARD, "token": token,
               "command": int(command), "code": int(code), "detail": detail,
               "reply_wire": expected.encode()}


def _newtons(force_mn: list[int]) -> list[float]:
    return [float("nan") if v == 0xFFFF else v / 1000 for v in force_mn]


def force_blocks() -> Iterator[Block]:
    """Yield the blocks of ``serial_force.txt``: FORCE messages (PROTOCOL.md)."""
    for v in FORCES:
        force = _newtons(v["force_mn"])  # type: ignore[arg-type]
        body = force_body(v["seq"], force)  # type: ignore[arg-type]
        yield {"kind": "force", **v, "body": body, "crc": crc16(body),
               "wire": encode_force(v["seq"], force)}  # type: ignore[arg-type]


def can_blocks() -> Iterator[Block]:
    """Yield the blocks of ``can.txt``."""
    for v in CAN_SAMPLES:
        yield {"kind": "can_sample", **v,
               "frames": can_sample_frames(v["node"], *_sample_args(v))}  # type: ignore[arg-type]
    for name, node, cmd in CAN_COMMANDS:
        yield {"kind": "can_command", "name": name, "node": node, "body": cmd.body(),
               "frames": [can_command_frame(node, cmd)]}
    for name, node, reply in CAN_REPLIES:
        yield {"kind": "can_reply", "name": name, "node": node, "body": reply.body(),
               "frames": can_reply_frames(node, reply.body())}


# ---- text ----

_HEADER = """\
# thermoskin wire protocol v1: {what} test vectors (firmware/PROTOCOL.md).
# Written by `python -m skin.drivers.protocol_vectors`; do not edit by hand.
# Format: firmware/test_vectors/README.md.
"""


def _value(kind: str, key: str, value: object) -> str:
    if key == "name":
        return str(value)
    if key in BYTES_KEYS:
        return bytes(value).hex()  # type: ignore[arg-type]
    if key == "frames":
        return " ".join(f"{ident:03X}:{data.hex()}" for ident, data in value)  # type: ignore[attr-defined]
    if key in LIST_KEYS.get(kind, ()):
        return " ".join(str(int(x)) for x in value)  # type: ignore[attr-defined]
    value = int(value)  # type: ignore[call-overload]
    if key in _HEX_DIGITS:
        return f"0x{value:0{_HEX_DIGITS[key]}X}"
    if key == "ambient" and value == AMBIENT_UNKNOWN:
        return f"0x{value:X}"
    return str(value)


def render(blocks: Iterator[Block], what: str) -> str:
    """Format blocks as the text of a vector file."""
    out = [_HEADER.format(what=what)]
    for block in blocks:
        kind = str(block["kind"])
        lines = [f"[{kind}]"]
        lines += [f"{k} = {_value(kind, k, v)}".rstrip() for k, v in block.items() if k != "kind"]
        out.append("\n".join(lines) + "\n")
    return "\n".join(out)


def read_vectors(path: str | Path) -> list[dict]:
    """Parse a vector file into one dict per block.

    Parameters
    ----------
    path : str or pathlib.Path
        A file in the format of ``firmware/test_vectors/README.md``.

    Returns
    -------
    list of dict
        Each with ``kind`` and the block's keys: ``name`` a str, the byte keys bytes, the
        list keys lists of int, ``frames`` a list of (identifier, bytes), the rest int.
    """
    blocks: list[dict] = []
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("[") and line.endswith("]"):
            blocks.append({"kind": line[1:-1]})
            continue
        key, eq, value = (s.strip() for s in line.partition("="))
        if not eq or not blocks:
            raise ValueError(f"{path}:{number}: expected [kind] or key = value")
        if key == "name":
            blocks[-1][key] = value
        elif key in BYTES_KEYS:
            blocks[-1][key] = bytes.fromhex(value)
        elif key == "frames":
            blocks[-1][key] = [(int(i, 16), bytes.fromhex(d))
                               for i, _, d in (f.partition(":") for f in value.split())]
        elif key in LIST_KEYS.get(blocks[-1]["kind"], ()):
            blocks[-1][key] = [int(x, 0) for x in value.split()]
        else:
            blocks[-1][key] = int(value, 0)
    return blocks


def write(directory: str | Path = DEFAULT_DIR) -> list[Path]:
    """Write ``serial.txt``, ``can.txt`` and ``serial_force.txt``; return their paths."""
    directory = Path(directory)
    paths = []
    for file, blocks, what in (("serial.txt", serial_blocks(), "serial"),
                               ("can.txt", can_blocks(), "CAN"),
                               ("serial_force.txt", force_blocks(), "serial FORCE")):
        path = directory / file
        path.write_text(render(blocks, what))
        paths.append(path)
    return paths


def main(argv: list[str] | None = None) -> int:
    """Write the vectors (into the directory given, or `DEFAULT_DIR`)."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m skin.drivers.protocol_vectors",
        description="Write the test vectors of wire protocol v1 (serial.txt and can.txt).")
    parser.add_argument("directory", nargs="?", default=str(DEFAULT_DIR),
                        help=f"an existing folder to write into (default: {DEFAULT_DIR})")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    directory = Path(args.directory)
    if not directory.is_dir():
        parser.error(f"{directory} is not an existing folder")
    for path in write(directory):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

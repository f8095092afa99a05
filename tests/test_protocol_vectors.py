"""The shared vectors of firmware/test_vectors: every one decodes to its values, every value
encodes to its bytes, and regenerating the files changes nothing."""

import math
from pathlib import Path

import numpy as np
import pytest

from skin.drivers.protocol import (
    ALL_TAXELS,
    AMBIENT_UNKNOWN,
    Ack,
    CanReassembler,
    Command,
    ErrorReply,
    Identity,
    SelftestResult,
    StreamDecoder,
    can_command_frame,
    can_reply_frames,
    can_sample_frames,
    cobs_decode,
    cobs_encode,
    crc16,
    encode_sample,
    layout_hash,
    parse_command_body,
    parse_command_packet,
    parse_reply,
    sample_body,
)
from skin.drivers.protocol_vectors import read_vectors, write

VECTORS = Path(__file__).resolve().parents[1] / "firmware" / "test_vectors"
SERIAL = read_vectors(VECTORS / "serial.txt")
CAN = read_vectors(VECTORS / "can.txt")
REPLY_TYPES = {"ack": Ack, "error": ErrorReply, "identity": Identity,
               "selftest_result": SelftestResult}


def blocks(vectors, *kinds):
    chosen = [v for v in vectors if v["kind"] in kinds]
    return pytest.mark.parametrize("v", chosen, ids=[f"{v['kind']}: {v['name']}" for v in chosen])


def ambient(v) -> float | None:
    return None if v["ambient"] == AMBIENT_UNKNOWN else v["ambient"] / 100


def reply_of(v):
    cls = REPLY_TYPES[v["kind"]]
    fields = {k: tuple(v[k]) if isinstance(v[k], list) else v[k]
              for k in cls.__dataclass_fields__}
    return cls(**fields)


def test_the_vectors_cover_what_the_firmware_must_handle():
    kinds = {v["kind"] for v in SERIAL} | {v["kind"] for v in CAN}
    assert kinds == {"crc", "cobs", "fnv", "sample", "command", "ack", "error", "identity",
                     "selftest_result", "bad_command", "can_sample", "can_command", "can_reply"}
    sizes = {len(v["counts"]) for v in SERIAL if v["kind"] == "sample"}
    assert {0, 1, 3, 16, 72} <= sizes
    samples = [v for v in SERIAL if v["kind"] == "sample"]
    assert np.bitwise_or.reduce([v["flags"] for v in samples]) == 0x3FF
    assert {s for v in samples for s in v["status"]} == set(range(16))
    assert any(v["ambient"] == AMBIENT_UNKNOWN for v in samples)
    assert any(len(cobs_encode(v["body"] + v["crc"].to_bytes(2, "little")))
               - len(v["body"]) - 2 > 1 for v in samples)
    commands = [v for v in SERIAL if v["kind"] == "command"]
    assert {v["type"] for v in commands} == set(range(0x10, 0x18))
    assert any(v.get("taxel") == ALL_TAXELS for v in commands)
    assert {v["code"] for v in SERIAL if v["kind"] == "bad_command"} == {1, 2, 3, 4, 5, 6}
    can = [v for v in CAN if v["kind"] == "can_sample"]
    assert {1, 4, 5, 16, 72} <= {len(v["counts"]) for v in can}
    assert any(v["seq"] % -(-len(v["counts"]) // 8) for v in can)  # a duty group other than 0
    assert any(len(v["frames"]) > 32 for v in CAN if v["kind"] == "can_reply")


@blocks(SERIAL, "crc")
def test_crc(v):
    assert crc16(v["data"]) == v["crc"]


@blocks(SERIAL, "cobs")
def test_cobs(v):
    assert cobs_encode(v["raw"]) == v["encoded"]
    assert cobs_decode(v["encoded"]) == v["raw"]
    assert 0 not in v["encoded"]


@blocks(SERIAL, "fnv")
def test_fnv(v):
    assert layout_hash(v["ids"]) == v["hash"]


@blocks(SERIAL, "sample")
def test_sample(v):
    assert sample_body(v["seq"], v["time_us"], v["counts"], ambient(v), v["duty"], v["flags"],
                       v["status"]) == v["body"]
    assert encode_sample(v["seq"], v["time_us"], v["counts"], ambient(v), v["duty"], v["flags"],
                         v["status"]) == v["wire"]
    assert crc16(v["body"]) == v["crc"]
    assert cobs_decode(v["wire"][:-1]) == v["body"] + v["crc"].to_bytes(2, "little")
    dec = StreamDecoder(board=4)
    (frame,) = dec.feed(v["wire"])
    assert frame.seq == v["seq"] and frame.board == 4
    assert frame.device_time == pytest.approx(v["time_us"] * 1e-6)
    assert frame.counts.tolist() == v["counts"] and frame.status.tolist() == v["status"]
    assert frame.duty.tolist() == v["duty"] and frame.flags == v["flags"]
    if v["ambient"] == AMBIENT_UNKNOWN:
        assert math.isnan(frame.ambient)
    else:
        assert frame.ambient == pytest.approx(v["ambient"] / 100)
    assert dec.stats.frames == 1 and dec.stats.malformed == dec.stats.crc_errors == 0


@blocks(SERIAL, "command")
def test_command(v):
    args = {k: v[k] for k in ("taxel", "duty", "count", "rate_hz", "pulse_ms") if k in v}
    command = Command(v["type"], v["token"], **args)
    assert command.body() == v["body"] and command.encode() == v["wire"]
    board = {"n_taxels": 0xFFFF, "max_rate_hz": 0xFFFF}  # a board that takes every value
    assert parse_command_packet(v["wire"][:-1], **board) == command
    assert parse_command_body(v["body"], **board) == command


@blocks(SERIAL, "ack", "error", "identity", "selftest_result")
def test_reply(v):
    reply = reply_of(v)
    assert reply.body() == v["body"] and reply.encode() == v["wire"]
    assert parse_reply(v["body"]) == reply
    dec = StreamDecoder()
    assert dec.feed(v["wire"]) == []
    assert list(dec.replies) == [reply] and dec.stats.replies == 1


@blocks(SERIAL, "bad_command")
def test_bad_command(v):
    expected = ErrorReply(v["token"], v["command"], v["code"], v["detail"])
    assert parse_command_packet(v["wire"][:-1], v["n_taxels"], v["max_rate_hz"]) == expected
    assert expected.encode() == v["reply_wire"]
    dec = StreamDecoder()
    dec.feed(v["reply_wire"])
    assert list(dec.replies) == [expected]


@blocks(CAN, "can_sample")
def test_can_sample(v):
    assert can_sample_frames(v["node"], v["seq"], v["time_us"], v["counts"], ambient(v),
                             v["duty"], v["flags"], v["status"]) == v["frames"]
    can = CanReassembler()
    (frame,) = can.feed(v["frames"])
    assert frame.board == v["node"] and frame.seq == v["seq"]
    assert frame.device_time == pytest.approx(v["time_us"] * 1e-6)
    assert frame.counts.tolist() == v["counts"] and frame.status.tolist() == v["status"]
    assert frame.flags == v["flags"]
    if v["ambient"] == AMBIENT_UNKNOWN:
        assert math.isnan(frame.ambient)
    else:
        assert frame.ambient == pytest.approx(v["ambient"] / 100)
    # one duty group per sample; the others are not known yet
    n = len(v["counts"])
    d = v["seq"] % -(-n // 8)
    expected = np.zeros(n, dtype=int)
    expected[8 * d : 8 * d + 8] = v["duty"][8 * d : 8 * d + 8]
    assert frame.duty.tolist() == expected.tolist()
    assert can.stats.frames == 1
    assert can.stats.missing == can.stats.orphans == can.stats.malformed == 0


@blocks(CAN, "can_command")
def test_can_command(v):
    ((ident, data),) = v["frames"]
    assert ident >> 8 == 1 and (ident >> 5) & 7 == v["node"] and data == v["body"]
    command = parse_command_body(v["body"], n_taxels=0xFFFF, max_rate_hz=0xFFFF)
    assert isinstance(command, Command)
    assert [can_command_frame(v["node"], command)] == v["frames"]


@blocks(CAN, "can_reply")
def test_can_reply(v):
    assert can_reply_frames(v["node"], v["body"]) == v["frames"]
    can = CanReassembler()
    assert can.feed(v["frames"]) == []
    assert list(can.replies) == [(v["node"], parse_reply(v["body"]))]
    assert can.stats.replies == 1 and can.stats.lost_replies == 0


def test_regenerating_the_vector_files_reproduces_them(tmp_path):
    for path in write(tmp_path):
        assert path.read_bytes() == (VECTORS / path.name).read_bytes(), path.name


def test_the_writer_prints_help_and_refuses_a_missing_folder(tmp_path):
    # issue 20 item 16: --help was taken for the output folder and crashed
    import subprocess
    import sys

    run = [sys.executable, "-m", "skin.drivers.protocol_vectors"]
    out = subprocess.run([*run, "--help"], capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0
    assert "usage:" in out.stdout and "serial.txt" in out.stdout
    assert not (tmp_path / "--help").exists()
    out = subprocess.run([*run, str(tmp_path / "nowhere")], capture_output=True, text=True)
    assert out.returncode == 2 and "is not an existing folder" in out.stderr
    out = subprocess.run([*run, str(tmp_path)], capture_output=True, text=True)
    assert out.returncode == 0
    assert (tmp_path / "serial.txt").is_file() and (tmp_path / "can.txt").is_file()

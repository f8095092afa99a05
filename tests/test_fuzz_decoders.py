"""Fuzzing every decoder with hypothesis: damaged streams, random chunks, the documented errors.

The damage and the oracle (which packets came through intact and so must be decoded) live in
`skin.bench.fuzz`, shared with ``skin bench fuzz``; the properties are asserted here.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skin.bench.fuzz import (
    BYTE_DAMAGE,
    FRAME_DAMAGE,
    Damage,
    can_case,
    can_crc15,
    can_crc15_syndromes,
    check_can,
    check_command_packet,
    check_records,
    check_reply_body,
    check_serial,
    chunk_sizes,
    damage_bytes,
    damage_frames,
    random_reply,
    sequence_stats,
    serial_case,
)
from skin.drivers.protocol import (
    MAX_PACKET,
    Command,
    ErrorReply,
    MsgType,
    StreamDecoder,
    can_record,
    parse_command_body,
)

pytest.importorskip("cobs")

FAST = settings(max_examples=200, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
MORE = settings(FAST, max_examples=600)

seeds = st.integers(0, 2**32 - 1)
positions = st.integers(0, 1 << 16)
byte_damage = st.one_of(
    st.builds(Damage, st.sampled_from(BYTE_DAMAGE), positions, st.integers(0, 64),
              st.binary(max_size=40), positions),
    # long runs without a delimiter: the decoder's buffer overflows and must let go
    st.builds(lambda at, n, b: Damage("insert", at, n, bytes([b]) * n), positions,
              st.integers(MAX_PACKET, 3 * MAX_PACKET), st.integers(1, 255)),
)
frame_damage = st.builds(Damage, st.sampled_from(FRAME_DAMAGE), positions, st.integers(0, 80),
                         st.binary(min_size=8, max_size=8), st.integers(0, 0x7FF))


def assert_clean(verdict):
    assert verdict.crash is None, verdict.crash
    assert verdict.inconsistent == []
    assert verdict.missed == 0  # every intact packet came out: resync within one frame
    assert verdict.unexplained == 0  # corrupt items only where damage passed the checks


# ---- serial: StreamDecoder ----

@MORE
@given(seeds, st.lists(byte_damage, min_size=1, max_size=4), seeds)
def test_serial_stream_survives_any_damage(seed, damages, chunk_seed):
    case = serial_case(np.random.default_rng(seed), packets=6)
    damaged, origin = damage_bytes(case.stream, damages)
    verdict = check_serial(case, damaged, origin,
                           chunk_sizes(np.random.default_rng(chunk_seed), len(damaged)))
    assert_clean(verdict)
    assert verdict.out >= verdict.intact


@FAST
@given(seeds, st.lists(byte_damage, max_size=3), st.lists(st.integers(1, 700), max_size=30))
def test_serial_frames_do_not_depend_on_how_the_stream_is_cut(seed, damages, cuts):
    case = serial_case(np.random.default_rng(seed), packets=5)
    damaged, _ = damage_bytes(case.stream, damages)
    whole = StreamDecoder()
    expected = [(f.seq, f.counts.tobytes()) for f in whole.feed(damaged)]
    parts = StreamDecoder()
    got, pos = [], 0
    for n in [*cuts, len(damaged)]:
        got += [(f.seq, f.counts.tobytes()) for f in parts.feed(damaged[pos : pos + n])]
        pos += n
    assert got == expected
    assert list(parts.replies) == list(whole.replies)


@FAST
@given(st.binary(max_size=3000), seeds)
def test_serial_pure_garbage_never_raises(garbage, seed):
    case = serial_case(np.random.default_rng(seed), packets=3)
    damaged = garbage + case.stream
    origin = [-1] * len(garbage) + list(range(len(case.stream)))
    verdict = check_serial(case, damaged, origin, chunk_sizes(np.random.default_rng(seed),
                                                              len(damaged)))
    assert_clean(verdict)


def test_the_oracle_sees_damage_and_intact_packets():
    case = serial_case(np.random.default_rng(3), packets=6, sizes=(8,))
    start, end = case.bounds[2]
    damaged, origin = damage_bytes(case.stream, [Damage("flip", start + 5, 3)])
    verdict = check_serial(case, damaged, origin, [len(damaged)])
    assert verdict.intact == 5 and verdict.out == 5 and verdict.missed == 0
    # a deleted delimiter merges two packets: both are lost, the rest survive
    damaged, origin = damage_bytes(case.stream, [Damage("delete", end, 1)])
    verdict = check_serial(case, damaged, origin, [7] * (len(damaged) // 7 + 1))
    assert verdict.intact == 4 and verdict.out == 4 and verdict.missed == 0
    # a spliced copy of a whole packet, delimiter before it included, is decoded twice
    s0, e0 = case.bounds[0]
    damaged, origin = damage_bytes(case.stream, [Damage("splice", s0, e0 - s0 + 1, to=e0 + 1)])
    verdict = check_serial(case, damaged, origin, [len(damaged)])
    assert verdict.intact == 7 and verdict.out == 7
    assert verdict.stats.duplicates == 1 and verdict.inconsistent == []


# ---- CAN: CanReassembler ----

@MORE
@given(seeds, st.integers(1, 3), st.lists(frame_damage, min_size=1, max_size=5), seeds)
def test_can_stream_survives_any_damage(seed, nodes, damages, batch_seed):
    case = can_case(np.random.default_rng(seed), samples=3, nodes=nodes, sizes=(1, 4, 13, 64))
    frames, origin = damage_frames(case.frames, damages)
    assert_clean(check_can(case, frames, origin, np.random.default_rng(batch_seed)))


@FAST
@given(seeds, st.lists(st.builds(Damage, st.sampled_from(("drop", "duplicate")), positions),
                       min_size=1, max_size=6))
def test_can_lost_or_repeated_frames_never_make_a_corrupt_sample(seed, damages):
    # what a bus with its CRC can still do: lose frames (overruns) or deliver one twice
    case = can_case(np.random.default_rng(seed), samples=4, nodes=2, sizes=(1, 4, 13, 64))
    frames, origin = damage_frames(case.frames, damages)
    verdict = check_can(case, frames, origin)
    assert_clean(verdict)
    assert verdict.corrupt == 0


@FAST
@given(st.lists(st.tuples(st.integers(-5, 0x900), st.binary(max_size=12)), max_size=60))
def test_can_random_frames_never_raise(frames):
    case = can_case(np.random.default_rng(0), samples=1, nodes=1)
    verdict = check_can(case, frames + case.frames, None)
    assert verdict.crash is None and verdict.inconsistent == []


# ---- CAN records, replies, commands ----

@FAST
@given(st.binary(max_size=400))
def test_split_can_records_raises_only_protocol_error(raw):
    assert check_records(raw) is None


@FAST
@given(seeds, st.lists(byte_damage, min_size=1, max_size=3))
def test_damaged_can_records_raise_only_protocol_error(seed, damages):
    case = can_case(np.random.default_rng(seed), samples=2, nodes=2, sizes=(4, 13))
    raw = b"".join(can_record(i, d) for i, d in case.frames)
    damaged, _ = damage_bytes(raw, damages)
    assert check_records(damaged) is None


@FAST
@given(st.one_of(st.binary(max_size=120),
                 st.tuples(seeds, byte_damage).map(lambda a: damage_bytes(
                     random_reply(np.random.default_rng(a[0]), 7).body(), [a[1]])[0])))
def test_parse_reply_raises_value_error_only_and_round_trips(body):
    assert check_reply_body(body) is None


@FAST
@given(st.one_of(st.binary(max_size=80).map(lambda b: b.replace(b"\x00", b"")),
                 st.tuples(st.sampled_from([t for t in MsgType if t >= MsgType.START]),
                           st.integers(0, 255),
                           st.integers(0, 0xFFFF), byte_damage).map(
                     lambda a: damage_bytes(Command(a[0], a[1], taxel=a[2] % 64,
                                                    rate_hz=a[2]).encode()[:-1],
                                            [a[3]])[0].replace(b"\x00", b""))))
def test_parse_command_packet_never_raises(packet):
    assert check_command_packet(packet) is None


@FAST
@given(st.binary(max_size=16), st.integers(0, 400), st.integers(4, 2000))
def test_parse_command_body_never_raises_and_commands_round_trip(body, taxels, rate):
    result = parse_command_body(body, taxels, rate)
    assert isinstance(result, Command | ErrorReply)
    if isinstance(result, Command):
        assert result.body() == body


# ---- the tools themselves ----

def test_sequence_stats_follow_linkstats():
    assert sequence_stats([5, 6, 6, 4, 9, 10]) == (2, 2)
    assert sequence_stats([2**32 - 1, 0, 1]) == (0, 0)
    assert sequence_stats([5000, 0, 1]) == (0, 0)  # a restart


def test_can_crc15_is_the_catalogue_crc():
    bits = [(b >> (7 - k)) & 1 for b in b"123456789" for k in range(8)]
    assert can_crc15(bits) == 0x059E  # CRC-15/CAN check value


def test_crc15_syndromes_detect_every_error_of_up_to_five_bits():
    rng = np.random.default_rng(0)
    for dlc in (0, 6, 8):
        synd = can_crc15_syndromes(dlc)
        assert synd.size == 11 + 8 * dlc + 15 and synd.all()
        pos = np.array([rng.choice(synd.size, size=rng.integers(1, 6), replace=False)
                        for _ in range(3000)], dtype=object)
        assert all(np.bitwise_xor.reduce(synd[p]) != 0 for p in pos)


def test_clopper_pearson():
    from skin.bench.intervals import clopper_pearson

    lo, hi = clopper_pearson(0, 100)
    assert lo == 0 and hi == pytest.approx(1 - 0.025 ** (1 / 100), rel=1e-9)
    lo, hi = clopper_pearson(25, 1_500_000)
    assert lo < 25 / 1_500_000 < hi and lo < 2**-16 < hi


def test_poisson_interval():
    from skin.bench.intervals import poisson_interval

    # none seen in 4 taxel-hours: up to -ln(0.025) / 4 per taxel-hour (the exact bound)
    lo, hi = poisson_interval(0, 4.0)
    assert lo == 0 and hi == pytest.approx(-np.log(0.025) / 4.0, rel=1e-9)
    # one in 4 taxel-hours: 0.25 measured, the interval wide enough to hold 0.1 and 1
    lo, hi = poisson_interval(1, 4.0)
    assert lo < 0.1 < 0.25 < 1.0 < hi
    lo, hi = poisson_interval(400, 1000.0)
    assert lo < 0.4 < hi and hi - lo < 0.1
    assert poisson_interval(3, 0.0) == (0.0, float("inf"))

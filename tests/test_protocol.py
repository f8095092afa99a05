import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skin.drivers.protocol import MAX_TAXELS, StreamDecoder, crc16, encode_sample


def frame_bytes(seq: int, n: int = 8, seed: int = 0) -> tuple[bytes, np.ndarray]:
    rng = np.random.default_rng(seed + seq)
    counts = rng.integers(0, 1024, n).astype(np.uint16)
    return encode_sample(seq, seq * 5000, counts, 25.37, np.full(n, 200), 0b101), counts


def test_crc16_ccitt_false_check_value():
    assert crc16(b"123456789") == 0x29B1  # the catalogued check value of CRC-16/CCITT-FALSE


def test_round_trip():
    data, counts = frame_bytes(7)
    assert data.endswith(b"\x00") and data.count(0) == 1
    (frame,) = StreamDecoder(board=3).feed(data)
    assert frame.seq == 7
    assert frame.device_time == pytest.approx(0.035)
    assert np.array_equal(frame.counts, counts)
    assert frame.ambient == pytest.approx(25.37)
    assert frame.flags == 0b101 and frame.board == 3
    assert np.all(frame.duty == 200)


def test_split_anywhere_gives_the_same_frames():
    stream = b"".join(frame_bytes(s)[0] for s in range(5))
    for cut in range(1, len(stream)):
        dec = StreamDecoder()
        frames = dec.feed(stream[:cut]) + dec.feed(stream[cut:])
        assert [f.seq for f in frames] == list(range(5))


def test_corrupt_byte_is_counted_and_skipped():
    frames = [frame_bytes(s)[0] for s in range(3)]
    bad = bytearray(frames[1])
    bad[10] ^= 0x40
    dec = StreamDecoder()
    out = dec.feed(frames[0] + bytes(bad) + frames[2])
    assert [f.seq for f in out] == [0, 2]
    assert dec.stats.crc_errors + dec.stats.malformed == 1
    assert dec.stats.frames == 2


def test_starting_mid_frame_locks_on_next_frame():
    stream = b"".join(frame_bytes(s)[0] for s in range(3))
    dec = StreamDecoder()
    out = dec.feed(stream[7:])
    assert [f.seq for f in out] == [1, 2]
    assert dec.stats.malformed + dec.stats.crc_errors == 1


def test_endless_garbage_without_delimiter_is_dropped():
    dec = StreamDecoder()
    assert dec.feed(b"\x55" * 20000) == []
    assert dec.stats.resyncs >= 1
    assert len(dec._buffer) < 20000
    data, _ = frame_bytes(1)
    assert [f.seq for f in dec.feed(b"\x00" + data)] == [1]


def test_too_many_channels_is_an_error():
    with pytest.raises(ValueError, match="at most"):
        encode_sample(0, 0, np.zeros(MAX_TAXELS + 1), 25.0, np.zeros(MAX_TAXELS + 1))


@settings(max_examples=200, deadline=None)
@given(st.data())
def test_random_corruption_never_raises_and_valid_frames_survive(data):
    frames = [frame_bytes(s)[0] for s in range(6)]
    stream = bytearray(b"".join(frames))
    n_flips = data.draw(st.integers(0, 6))
    for _ in range(n_flips):
        pos = data.draw(st.integers(0, len(stream) - 1))
        stream[pos] = data.draw(st.integers(0, 255))
    dec = StreamDecoder()
    out = dec.feed(bytes(stream))
    seqs = [f.seq for f in out]
    # every decoded frame is one that was sent, unchanged, in order
    assert seqs == sorted(set(seqs)) and set(seqs) <= set(range(6))
    for f in out:
        assert np.array_equal(f.counts, frame_bytes(f.seq)[1])
    # frames whose bytes were not touched still arrive (a flip hits at most two frames)
    assert len(out) >= 6 - 2 * n_flips

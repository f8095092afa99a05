"""The force channel over CAN (FORCE frames, type 6): encoding, the DBC, and the CAN driver over
python-can's virtual bus with lost, orphan and damaged FORCE frames; a node without force
unchanged."""

import math

import numpy as np
import pytest

from skin.drivers.protocol import CanReassembler, CanType, can_sample_frames

can = pytest.importorskip("can")

from conftest import send_can  # noqa: E402

N = 10  # 3 groups: 4, 4, 2 taxels


def force_of(seq: int) -> np.ndarray:
    force = 0.25 * np.arange(N) + 0.001 * seq
    force[5] = math.nan  # a taxel without a sensor
    return force


def frames_of(seq: int, node: int = 2, force: bool = True) -> list:
    counts = (np.arange(N) * 37 + seq) % 4096
    return can_sample_frames(node, seq, seq * 5000, counts, 24.5, np.full(N, 200),
                             force=force_of(seq) if force else None)


def test_force_frames_come_between_duty_and_status():
    kinds = [ident >> 8 for ident, _ in frames_of(7)]
    assert kinds == [CanType.SYNC, *[CanType.DATA] * 3, CanType.DUTY, *[CanType.FORCE] * 3,
                     CanType.STATUS]
    forces = [(ident & 31, data) for ident, data in frames_of(7) if ident >> 8 == CanType.FORCE]
    assert [len(d) for _, d in forces] == [8, 8, 4]
    raw = np.frombuffer(b"".join(d for _, d in forces), "<u2")
    assert raw[5] == 0xFFFF and raw[9] == round(1000 * (2.25 + 0.007))
    # without force: the frames of before, byte for byte
    assert frames_of(7, force=False) == [f for f in frames_of(7) if f[0] >> 8 != CanType.FORCE]


def test_the_driver_attaches_force_and_counts_lost_orphan_and_damaged_frames(node_bus):
    bus, driver = node_bus
    send_can(bus, frames_of(0))
    send_can(bus, frames_of(1, force=False))  # every FORCE frame of sample 1 lost
    lossy = frames_of(2)
    send_can(bus, [f for f in lossy if f[0] != (CanType.FORCE << 8 | 2 << 5 | 1)])  # group 1 lost
    orphan = frames_of(3)
    send_can(bus, orphan[1:])  # its SYNC lost: the sample is dropped, its FORCE frames orphans
    damaged = frames_of(4)
    k = next(i for i, f in enumerate(damaged) if f[0] >> 8 == CanType.FORCE)
    damaged[k + 2] = (damaged[k + 2][0], damaged[k + 2][1][:2])  # group 2: 1 taxel of 2
    send_can(bus, damaged)
    send_can(bus, [(CanType.FORCE << 8 | 2 << 5 | 0, b"\x01\x02\x03")])  # odd length: not ours
    send_can(bus, frames_of(5))
    frames = [driver.recv(timeout=1.0) for _ in range(5)]
    assert [f.seq for f in frames] == [0, 1, 2, 4, 5]
    for f in (frames[0], frames[-1]):
        assert np.allclose(f.force, force_of(f.seq), equal_nan=True, atol=5e-4)
    assert np.all(np.isnan(frames[1].force))  # FORCE lost: no reading on any taxel
    assert np.all(np.isnan(frames[2].force[4:8]))  # group 1 lost
    assert np.allclose(frames[2].force[:4], force_of(2)[:4], atol=5e-4)
    assert np.allclose(frames[2].force[8:], force_of(2)[8:], atol=5e-4)
    assert np.all(np.isnan(frames[3].force[8:]))  # the damaged group
    s = driver.stats
    assert (s.forces, s.force_missing) == (2, 3), s
    assert s.force_orphans == 3, s  # sample 3's three FORCE frames (its SYNC lost)
    assert s.lost_samples == 1 and s.missing == 0, s
    assert s.malformed == 2, s  # the short group and the odd-length frame


def test_a_node_without_force_is_unchanged(node_bus):
    bus, driver = node_bus
    for seq in range(3):
        send_can(bus, frames_of(seq, node=4, force=False))
    frames = [driver.recv(timeout=1.0) for _ in range(3)]
    assert all(f.force is None for f in frames)
    s = driver.stats
    assert (s.forces, s.force_missing, s.force_orphans, s.malformed) == (0, 0, 0, 0)


def test_garbage_force_frames_never_raise():
    rng = np.random.default_rng(5)
    r = CanReassembler()
    for seq in range(200):
        for ident, data in frames_of(seq):
            if rng.random() < 0.1:
                data = rng.bytes(int(rng.integers(0, 9)))
            if rng.random() < 0.05:
                ident = CanType.FORCE << 8 | int(rng.integers(0, 256))
            r.push(ident, data)
    assert r.stats.frames > 0
    assert 0 < r.stats.forces + r.stats.force_missing <= r.stats.frames
    assert r.stats.force_orphans > 0 and r.stats.malformed > 0


def test_the_dbc_describes_the_force_frames():
    cantools = pytest.importorskip("cantools")
    from skin.drivers.dbc import dbc_text

    db = cantools.database.load_string(dbc_text(), "dbc")
    for ident, data in frames_of(9):
        if ident >> 8 == CanType.FORCE:
            g = ident & 31
            msg = db.get_message_by_frame_id(ident)
            assert msg.name == f"FORCE_N2_G{g}"
            values = db.decode_message(ident, data + bytes(8 - len(data)))
            for i in range(min(4, N - 4 * g)):
                expect = force_of(9)[4 * g + i]
                got = values[f"force_{4 * g + i}"]
                if math.isnan(expect):
                    assert got == pytest.approx(65.535)
                else:
                    assert got == pytest.approx(expect, abs=5e-4)



def test_every_force_code_decodes_to_the_same_float_over_can_and_serial():
    """Each of the 65535 force codes: the CAN reassembler's float is the serial decoder's,
    bit for bit (both go through `force_newtons`; ``k * 1e-3`` and ``k / 1000`` differ by one
    ulp for 9146 codes)."""
    from skin.drivers.protocol import FORCE_NONE, _force_of, force_body

    codes = np.arange(FORCE_NONE, dtype=np.uint16)
    frames, serial = [], []
    for seq, chunk in enumerate(np.array_split(codes, len(codes) // 128 + 1)):
        force = chunk / 1000.0
        n = len(chunk)
        body = force_body(seq, force)
        assert np.array_equal(np.frombuffer(body[8:], "<u2"), chunk)  # the codes on the wire
        serial.append(_force_of(body)[1])
        frames += can_sample_frames(3, seq, seq * 5000, np.arange(n), 24.0, np.full(n, 10), 0,
                                    None, force)
    got = CanReassembler().feed(frames)
    assert len(got) == len(serial)
    for frame, want in zip(got, serial, strict=True):
        assert np.array_equal(frame.force, want)

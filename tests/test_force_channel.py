"""The optional force channel: FORCE messages (firmware/PROTOCOL.md), attached to their sample's
frame by the serial decoder, over a real pseudo-terminal, through the simulator, recording and
replay; frames and recordings without one behave as before."""

import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import skin.drivers
from skin.drivers.protocol import (
    FORCE_NONE,
    MAX_FORCE,
    OPTION_FORCE,
    Identity,
    StreamDecoder,
    crc16,
    encode_force,
    encode_sample,
    force_body,
    frame_packet,
)
from skin.drivers.protocol_vectors import read_vectors

VECTORS = Path(__file__).resolve().parents[1] / "firmware" / "test_vectors"
FORCE_VECTORS = read_vectors(VECTORS / "serial_force.txt")


@pytest.fixture(scope="module")
def force_sim():
    from skin.drivers.sim import SkinSimulator
    from skin.formats.scene import load_scene

    return SkinSimulator(replace(load_scene("default"), force="force"), duration=3.0)


def sample(seq: int, n: int = 3) -> bytes:
    return encode_sample(seq, seq * 5000, [100 + seq % 50] * n, 21.0, [255] * n)


def newtons(force_mn: list[int]) -> list[float]:
    return [math.nan if v == FORCE_NONE else v / 1000 for v in force_mn]


@pytest.mark.parametrize("v", FORCE_VECTORS, ids=[v["name"] for v in FORCE_VECTORS])
def test_force_vectors(v):
    force = newtons(v["force_mn"])
    assert force_body(v["seq"], force) == v["body"]
    assert crc16(v["body"]) == v["crc"]
    assert encode_force(v["seq"], force) == v["wire"]
    n = len(force)
    dec = StreamDecoder(force=True)
    (frame,) = dec.feed(encode_sample(v["seq"], 0, [1] * n, None, [0] * n) + v["wire"])
    assert frame.force is not None and frame.force.shape == (n,)
    np.testing.assert_array_equal(frame.force, np.array(force, dtype=float))
    assert dec.stats.forces == 1 and dec.stats.force_orphans == dec.stats.force_missing == 0


@pytest.mark.parametrize("force, message", [([-0.001], "channel 0"),
                                            ([0.0, MAX_FORCE + 0.001], "channel 1"),
                                            ([math.inf], "inf")])
def test_forces_the_wire_cannot_carry_are_errors(force, message):
    with pytest.raises(ValueError, match=message):
        encode_force(0, force)


def test_a_board_without_force_is_unchanged_and_frames_come_at_once():
    dec = StreamDecoder()
    frames = dec.feed(sample(1) + sample(2))
    assert [f.seq for f in frames] == [1, 2] and all(f.force is None for f in frames)
    assert dec.flush() == [] and not dec.has_force


def test_force_attaches_to_its_sample_split_anywhere():
    stream = b"".join(sample(k) + encode_force(k, [0.1 * k, math.nan, 1.0]) for k in range(1, 6))
    whole = StreamDecoder(force=True).feed(stream)
    for size in (1, 7, 31):
        dec = StreamDecoder(force=True)
        got = []
        for i in range(0, len(stream), size):
            got += dec.feed(stream[i:i + size])
        got += dec.flush()
        assert [f.seq for f in got] == [1, 2, 3, 4, 5]
        for a, b in zip(got, whole, strict=True):
            np.testing.assert_array_equal(a.force, b.force)
        assert dec.stats.forces == 5 and dec.stats.force_missing == 0


def test_the_first_force_of_an_unannounced_board_attaches_within_its_read_only():
    dec = StreamDecoder()
    frames = dec.feed(sample(1) + encode_force(1, [1, 1, 1]) + sample(2)
                      + encode_force(2, [0, 0.5, 1]))
    assert [f.seq for f in frames] == [1, 2]
    np.testing.assert_array_equal(frames[0].force, [1, 1, 1])
    np.testing.assert_array_equal(frames[1].force, [0, 0.5, 1])
    assert dec.stats.force_orphans == 0 and dec.stats.forces == 2
    late = StreamDecoder()  # the read ends between the first SAMPLE and its FORCE
    (first,) = late.feed(sample(1))
    assert late.feed(encode_force(1, [1, 1, 1])) == [] and first.force is None
    assert late.stats.force_orphans == 1 and late.has_force


def test_an_identity_with_the_force_option_announces_the_channel():
    ident = Identity(0, 0, 0, 0, 0, 0, 0, OPTION_FORCE, 3, 12, 1, 200, 200, 0, 10000)
    dec = StreamDecoder()
    (frame,) = dec.feed(ident.encode() + sample(1) + encode_force(1, [2, 2, 2]))
    np.testing.assert_array_equal(frame.force, [2, 2, 2])
    assert dec.stats.force_orphans == 0 and len(dec.replies) == 1


def test_lost_corrupt_and_orphaned_forces_are_counted_never_raised():
    bad_crc = bytearray(encode_force(2, [1, 1, 1]))
    bad_crc[-3] ^= 0x10  # a CRC byte (COBS keeps it non-zero here)
    short = frame_packet(force_body(3, [1, 1, 1])[:-1])  # n says 3, 2.5 values follow
    wrong_n = encode_force(4, [1, 1])
    stream = (sample(1) + encode_force(1, [0, 0, 0])
              + sample(2) + bytes(bad_crc)
              + sample(3) + short
              + sample(4) + wrong_n
              + encode_force(99, [1, 1, 1])  # no sample 99
              + sample(5) + encode_force(5, [3, 3, 3]))
    dec = StreamDecoder(force=True)
    frames = dec.feed(stream) + dec.flush()
    assert [f.seq for f in frames] == [1, 2, 3, 4, 5]
    assert [np.isnan(f.force).all() for f in frames] == [False, True, True, True, False]
    np.testing.assert_array_equal(frames[4].force, [3, 3, 3])
    s = dec.stats
    assert (s.forces, s.force_missing, s.force_orphans, s.crc_errors, s.malformed) == (
        2, 3, 2, 1, 1)


def test_a_sample_held_at_the_end_is_handed_on_by_flush():
    dec = StreamDecoder(force=True)
    assert dec.feed(sample(1)) == []
    (frame,) = dec.flush()
    assert frame.seq == 1 and np.isnan(frame.force).all()
    assert dec.flush() == []


def test_serial_driver_reads_a_force_channel_over_a_real_pty(force_sim):
    from skin.drivers.sim import PtySerialDevice

    expected = list(force_sim.frames())
    assert all(f.force is not None for f in expected)
    with PtySerialDevice(force_sim, speed=0) as device, skin.drivers.open(
        f"serial://{device.port}"
    ) as driver:
        device.start()
        got = []
        while len(got) < len(expected):
            frame = driver.recv(timeout=2.0)
            assert frame is not None, f"stalled after {len(got)} frames"
            got.append(frame)
        stats = driver.stats
    assert stats.crc_errors == stats.malformed == 0
    assert [f.seq for f in got] == [f.seq for f in expected]
    # no IDENTITY was asked for: the first FORCE attaches when it came in its sample's read
    # (the device writes 10 samples with their FORCEs at a time; a read may still cut them)
    start = 0 if got[0].force is not None else 1
    assert stats.force_orphans == start
    for a, b in zip(got[start:], expected[start:], strict=True):
        np.testing.assert_array_equal(a.force, b.force)
        assert np.array_equal(a.counts, b.counts)
    assert stats.forces == len(expected) - start and stats.force_missing == 0


def test_the_simulated_force_follows_the_scene_touches(force_sim):
    frames = list(force_sim.frames())
    layout = force_sim.layout
    idx, addr = layout.channel_map(force_sim.board.id)
    force = np.array([f.force[addr] for f in frames])  # (samples, taxels in idx order)
    fs = force_sim.sample_rate
    touched = np.zeros(force.shape, dtype=bool)
    where = {int(i): j for j, i in enumerate(idx)}
    for touch in force_sim.scene.touches:
        k0, k1 = round(touch.start * fs), round(touch.end * fs)
        for t in touch.taxels:
            touched[k0:k1, where[layout.index(t)]] = True
    assert touched.any()
    assert np.all(force[~touched] < 0.05)  # noise of 5 mN, clipped at 0
    settled = force[touched & np.roll(touched, 10, axis=0)]  # past the 20 ms rise
    assert abs(np.median(settled) - 2.0) < 0.01
    assert np.all(np.isfinite(force))
    # a contact switch: 1 exactly while touched
    switch = simulator_with(force_sim, "contact")
    sw = np.array([f.force[addr] for f in switch.frames()])
    np.testing.assert_array_equal(sw, touched.astype(float))
    # no force channel: no force, and the same frames as before
    plain = simulator_with(force_sim, "")
    for a, b in zip(plain.frames(), frames, strict=True):
        assert a.force is None and np.array_equal(a.counts, b.counts)


def simulator_with(sim, force: str):
    from skin.drivers.sim import SkinSimulator

    return SkinSimulator(replace(sim.scene, force=force), duration=sim.duration)


def test_recording_and_replay_round_trip_the_force_channel_exactly(force_sim, tmp_path):
    from skin.drivers.recording import Recorder
    from skin.drivers.sim import SimDriver

    path = tmp_path / "force.mcap"
    with Recorder(path, force_sim.layout) as recorder, SimDriver(force_sim, speed=0) as source:
        recorder.add_driver(source)
        live = list(source)
    with skin.drivers.open(f"replay://{path}?speed=0") as replay:
        again = list(replay)
        stats = replay.stats
    assert [f.seq for f in again] == [f.seq for f in live]
    for a, b in zip(again, live, strict=True):
        np.testing.assert_array_equal(a.force, b.force)
        assert np.array_equal(a.counts, b.counts)
        assert a.device_time == pytest.approx(b.device_time, abs=1e-6)
    assert stats.forces == len(live) and stats.force_missing == stats.force_orphans == 0


def test_a_recording_without_force_replays_as_before(tmp_path):
    from skin.drivers.recording import Recorder

    path = tmp_path / "plain.mcap"
    layout = skin.drivers.open("sim://default?speed=0&duration=0.2")
    with Recorder(path, layout.simulator.layout) as recorder, layout as source:
        recorder.add_driver(source)
        live = list(source)
    with skin.drivers.open(f"replay://{path}?speed=0") as replay:
        again = list(replay)
        stats = replay.stats
    assert len(again) == len(live) == 40
    assert all(f.force is None for f in again) and stats.forces == stats.force_orphans == 0
    for a, b in zip(again, live, strict=True):
        assert a.seq == b.seq and np.array_equal(a.counts, b.counts)


def test_force_contacts_date_a_ramp_where_it_starts_and_a_switch_at_its_first_sample():
    from skin.models.commission import force_contacts

    fs = 200.0
    t = np.arange(2000) / fs
    rng = np.random.default_rng(3)
    ramp = np.clip((t - 2.0013) / 0.02, 0, 1) * 2.0 * ((t >= 2.0013) & (t < 6.0))
    noisy = np.maximum(ramp + rng.normal(0, 0.005, t.size), 0.0)
    ((on, off),) = force_contacts(t, noisy)
    assert abs(on - 2.0013) < 0.002 and abs(off - 6.0) <= 1 / fs + 1e-9
    switch = ((t >= 3.0) & (t < 5.5)).astype(float)
    switch[100:110] = np.nan  # no reading for a while: not a contact
    ((on, off),) = force_contacts(t, switch)
    assert on == 3.0 - 0.5 / fs and off == 5.5  # closed between 2.995 and 3.0 s
    assert force_contacts(t, rng.normal(0, 0.005, t.size).clip(0)) == []  # noise alone
    assert force_contacts(t, np.full(t.size, np.nan)) == []
    assert force_contacts(t, switch * 0) == []
    (_, end) = force_contacts(t, (t >= 9.0).astype(float))[0]
    assert end == math.inf  # still on at the end


def test_skin_commission_dates_reference_touches_by_a_recorded_force_channel(tmp_path,
                                                                           capsys):
    """A recording of reference touches with a force channel (MCAP, replayed): the touches are
    dated by the force, the report says so, and the fit is as close as the detector's."""
    import json

    from skin.cli import main as skin_main
    from skin.drivers.recording import Recorder
    from skin.drivers.sim import SimDriver, SkinSimulator
    from skin.formats.calibration_file import load_calibration
    from skin.formats.scene import load_scene

    n = 4
    scene = load_scene("reference-touches")
    scene = replace(scene, force="force", touches=tuple(
        replace(tc, taxels=tuple(range(n))) for tc in scene.touches))
    sim = SkinSimulator(scene)
    path = tmp_path / "touches.mcap"
    with Recorder(path, scene.layout) as recorder, SimDriver(sim, speed=0) as source:
        recorder.add_driver(source)
        for _ in source:
            pass
    docs = {}
    for name, port in (("force", f"replay://{path}?speed=0"),
                       ("detector", f"sim://{tmp_path / 'plain.toml'}?speed=0")):
        if name == "detector":  # the same touches, no force channel
            text = (Path(__file__).resolve().parents[1] / "skin" / "data" / "scenes"
                    / "reference-touches.toml").read_text()
            text = re.sub(r"^taxels = \[[0-9, ]+\]$", f"taxels = {list(range(n))}", text,
                          flags=re.M)
            (tmp_path / "plain.toml").write_text(text)
        cal = tmp_path / f"{name}.json"
        assert skin_main(["commission", "--port", port, "--touches", "water,neoprene",
                          "-o", str(cal), "--json"]) == 0
        out = capsys.readouterr()
        docs[name] = json.loads(out.out)
        _, fitted = load_calibration(cal).apply(scene.layout)
        truth = sim.taxel_sensor
        eff = np.array([s.effusivity for s in fitted[:n]])
        docs[name]["eff_error"] = float(np.median(np.abs(eff / truth.effusivity[:n] - 1)))
        if name == "force":
            assert "force channel" in out.err
    f, d = docs["force"], docs["detector"]
    assert f["force_taxels"] == len(scene.layout) and f["force_dated"] == n * 6
    assert d.get("force_dated", 0) == 0 and "force_taxels" in d and d["force_taxels"] == 0
    assert f["fitted"] == d["fitted"] == n and f["ambiguous"] == 0
    assert f["eff_error"] < 0.02 and d["eff_error"] < 0.02
    assert "force channel" in json.loads((tmp_path / "force.json").read_text())[
        "references"]["thermal"]


def test_touches_where_the_force_has_no_reading_or_no_contact_go_to_the_detector():
    """Force lost after mid-recording on every taxel (FORCE messages lost), or present but
    stuck at 0: the touches there are found by the onset detector, and the counts say so."""
    from skin.bench.commission import REFERENCES, commission_unit
    from skin.models import load_materials
    from skin.models.commission import commission_response

    u = commission_unit("paper", 7, force="force")
    t, y, force = u["times"], u["readings"], u["force"]
    table = load_materials()
    mats = {m: table[m] for m in REFERENCES}
    run = lambda f: commission_response(t, y, u["layout"], mats, u["nominal"],  # noqa: E731
                                        u["scene"].ambient, force=f)[1]
    lost = force.copy()
    lost[t > t[0] + 0.5 * (t[-1] - t[0]), :] = np.nan
    c = run(lost)
    assert c["detected"] == 48 and c["force_dated"] == 24
    assert any(n.startswith("taxel 3: its force had no reading for 28") for n in c["force_notes"])
    c = run(np.zeros_like(force))
    assert c["detected"] == 48 and c["force_dated"] == 0
    assert c["force_notes"][0].startswith(f"taxels 0-{force.shape[1] - 1}: the force showed no")


def test_a_force_stuck_at_zero_partway_hands_its_touches_to_the_detector():
    """Every taxel's force stuck at 0 after mid-recording (a cable failing): its touches were
    taken as untouched (24 of 48 lost, silently); now found by the detector, with a note."""
    from skin.bench.commission import REFERENCES, commission_unit
    from skin.models import load_materials
    from skin.models.commission import commission_response

    u = commission_unit("paper", 7, force="force")
    t, y, force = u["times"], u["readings"], u["force"].copy()
    force[t > t[0] + 0.5 * (t[-1] - t[0]), :] = 0.0
    table = load_materials()
    c = commission_response(t, y, u["layout"], {m: table[m] for m in REFERENCES}, u["nominal"],
                            u["scene"].ambient, force=force)[1]
    assert c["detected"] == 48 and c["force_dated"] == 24
    assert any(n.startswith("taxel 3: its force read one value for 2") for n in c["force_notes"])


def test_no_touch_with_a_force_channel_says_what_the_force_showed():
    """A recording without touches whose force channel reads only noise: the error says what
    the force channel showed and what to check, not only that the detector found nothing."""
    from skin.bench.commission import REFERENCES, commission_unit
    from skin.models import load_materials
    from skin.models.commission import CommissioningError, commission_response

    u = commission_unit("paper", 7, force="force")
    t = u["times"]
    rng = np.random.default_rng(3)
    y = u["readings"][:1] + rng.normal(0, 0.002, u["readings"].shape)
    force = np.round(np.maximum(rng.normal(0, 0.005, u["force"].shape), 0), 3)
    table = load_materials()
    with pytest.raises(CommissioningError) as err:
        commission_response(t, y, u["layout"], {m: table[m] for m in REFERENCES},
                            u["nominal"], u["scene"].ambient, force=force)
    said = str(err.value)
    assert f"force channel showed no contact on the {force.shape[1]} taxels" in said
    assert "check the force sensor" in said and "--labels" in said


def test_zero_timeout_polls_between_a_sample_and_its_force_keep_the_force():
    """A FORCE written 2 ms after its SAMPLE over a real pty, recv(timeout=0) polls between
    the two: every frame comes with its force (the quiet poll does not hand it on early)."""
    import os
    import time
    import tty

    main, sub = os.openpty()
    tty.setraw(sub)
    got = []
    try:
        with skin.drivers.open(f"serial://{os.ttyname(sub)}") as d:
            os.write(main, sample(0, 8) + encode_force(0, [0.5] * 8))
            got.append(d.recv(timeout=0.5))
            for k in range(1, 6):
                os.write(main, sample(k, 8))
                time.sleep(0.002)
                got += [d.recv(timeout=0.0), d.recv(timeout=0.0)]
                os.write(main, encode_force(k, [0.5] * 8))
                time.sleep(0.002)
                got.append(d.recv(timeout=0.0))
            got.append(d.recv(timeout=0.2))
            stats = d.stats
    finally:
        os.close(main)
        os.close(sub)
    frames = [f for f in got if f is not None]
    assert [f.seq for f in frames] == list(range(6))
    assert all(f.force[0] == 0.5 for f in frames)
    assert stats.force_orphans == 0 and stats.force_missing == 0


@pytest.mark.parametrize("rise, noise, within", [(0.1, 0.005, 1e-3), (0.3, 0.005, 1e-3),
                                                 (0.3, 0.03, 4e-3), (0.6, 0.005, 1e-3)])
def test_force_contacts_date_slow_ramps_where_they_start(rise, noise, within):
    """A press ramping up over many samples (100-600 ms at 200 Hz, 2 N, noise clipped at 0 and
    rounded to 1 mN): its onset is dated where the ramp starts, not one sample before the
    threshold (the old clamp dated a 300 ms ramp 14 ms late at 5 mN, 39 ms at 30 mN)."""
    from skin.models.commission import force_contacts

    t = np.arange(4000) / 200.0
    errors = []
    for seed in range(12):
        rng = np.random.default_rng(100 + seed)
        start = 5.0 + rng.uniform(0, 0.005)
        f = np.clip((t - start) / rise, 0, 1) * 2.0 * ((t >= start) & (t < 12.0))
        f = np.round(np.maximum(f + rng.normal(0, noise, t.size), 0), 3)
        (onset, _), = force_contacts(t, f)
        errors.append(onset - start)
    assert abs(np.median(errors)) < within


def test_force_contacts_ignore_a_glitch_and_count_a_faint_touch():
    """One 40 N glitch sample beside 2 N touches does not raise the threshold over them; a
    0.3 N touch beside an 8 N one (under 5 % of it, lasting 4 s of 20: a fifth of the free
    samples, which the noise floor's 84th percentile took as noise) is left out but counted,
    not silently."""
    from skin.models.commission import force_contacts

    t = np.arange(4000) / 200.0
    rng = np.random.default_rng(5)

    def press(start: float, end: float, peak: float) -> np.ndarray:
        return np.clip((t - start) / 0.02, 0, 1) * peak * ((t >= start) & (t < end))

    noise = rng.normal(0, 0.005, t.size)
    f = np.round(np.maximum(press(5.0, 12.0, 2.0) + noise, 0), 3)
    f[3500] = 40.0
    (onset, end), = force_contacts(t, f)
    assert abs(onset - 5.0) < 0.003 and end == pytest.approx(12.0, abs=0.006)
    f = np.round(np.maximum(press(2.0, 6.0, 0.3) + press(10.0, 15.0, 8.0) + noise, 0), 3)
    weak = []
    (onset, _), = force_contacts(t, f, weak)
    assert abs(onset - 10.0) < 0.003
    assert len(weak) == 1 and abs(weak[0][0] - 2.0) < 0.01


def test_a_short_stretch_without_a_reading_inside_a_contact_does_not_split_it():
    """A contact switch losing its reading for 20 ms (4 samples, under FORCE_CONTACT_HELD)
    inside a contact: one contact, the stretch counted; a 200 ms one too when the switch is
    still closed after it (it used to cut the touch into a short one and a false one whose
    onset was the gap's end); one across which the switch opened ends the contact there."""
    from skin.models.commission import force_contacts

    t = np.arange(4000) / 200.0
    s = (((t >= 3) & (t < 8)) | ((t >= 12) & (t < 16))).astype(float)
    s[1300:1304] = np.nan
    bridged = []
    assert np.allclose(force_contacts(t, s, bridged=bridged), [(2.9975, 8.0), (11.9975, 16.0)])
    assert np.allclose(bridged, [(6.5, 6.52)])
    s[1300:1340] = np.nan
    bridged = []
    assert np.allclose(force_contacts(t, s, bridged=bridged), [(2.9975, 8.0), (11.9975, 16.0)])
    assert np.allclose(bridged, [(6.5, 6.7)])
    s[1580:1640] = np.nan  # 7.9-8.2 s: opened within it
    assert np.allclose(force_contacts(t, s), [(2.9975, 7.9), (11.9975, 16.0)])


def test_a_replay_hands_on_the_samples_held_at_its_end_before_it_is_finished(force_sim,
                                                                              tmp_path):
    """A recording of two boards ending on a SAMPLE each whose FORCE never came: a reader that
    stops once the replay is ``finished`` (as the stream's board workers do) still gets both."""
    from skin.drivers.recording import Recorder
    from skin.drivers.sim import SimDriver

    n = len(force_sim.layout)
    path = tmp_path / "cut.mcap"
    with (Recorder(path, force_sim.layout) as recorder, SimDriver(force_sim, speed=0) as a,
          SimDriver(force_sim, speed=0) as b):
        channels = recorder.add_driver(a) + recorder.add_driver(b)
        for k in range(5):
            for channel in channels:
                recorder.wire(channel, 1.0 + 0.005 * k, sample(k, n)
                              + (encode_force(k, [0.25] * n) if k < 4 else b""))
    got = []
    with skin.drivers.open(f"replay://{path}?speed=0") as replay:
        while not replay.finished:
            frame = replay.recv(timeout=0.05)
            if frame is not None:
                got.append(frame)
        stats = replay.stats
    assert sorted(f.seq for f in got) == sorted(2 * list(range(5)))
    assert sum(np.all(np.isnan(f.force)) for f in got) == 2 and stats.force_missing == 2


def test_closing_a_serial_driver_counts_the_sample_it_held():
    """A sample held for its FORCE when the driver is closed is counted lost, not dropped
    silently."""
    import os
    import tty

    main, sub = os.openpty()
    tty.setraw(sub)
    try:
        d = skin.drivers.open(f"serial://{os.ttyname(sub)}")
        os.write(main, sample(0, 8) + encode_force(0, [0.5] * 8) + sample(1, 8))
        assert d.recv(timeout=0.5).seq == 0  # sample 1, in the same read, held for its FORCE
        d.close()
    finally:
        os.close(main)
        os.close(sub)
    assert d.stats.lost_samples == 1 and d.stats.frames == 2


def test_the_force_notes_name_taxels_by_their_layout_ids():
    """A layout whose ids are not its columns (ids 100-107): the notes name the ids."""
    from skin.bench.commission import REFERENCES, commission_unit
    from skin.formats.layout import Layout
    from skin.models import load_materials
    from skin.models.commission import commission_response

    u = commission_unit("paper", 7, force="force")
    t, y, force = u["times"], u["readings"], u["force"]
    old = u["layout"]
    layout = Layout([replace(tx, id=tx.id + 100) for tx in old.taxels],
                    list(old.boards.values()))
    table = load_materials()
    mats = {m: table[m] for m in REFERENCES}
    lost = force.copy()
    lost[t > t[0] + 0.5 * (t[-1] - t[0]), 3] = np.nan
    lost[:, 5] = 0.0
    notes = commission_response(t, y, layout, mats, u["nominal"], u["scene"].ambient,
                                force=lost)[1]["force_notes"]
    assert notes[0].startswith("taxels 105, 108-") and "the force showed no contact" in notes[0]
    assert any(n.startswith("taxel 103: its force had no reading for 28") for n in notes)
    assert not any(n.startswith(("taxel 3:", "taxel 5:")) for n in notes)


def test_a_long_gap_in_the_force_is_not_bridged_into_one_touch():
    """Touches 1-2.6 s and 7.9-9 s, no reading 2.5-8.0 s: a bridge of any length made them one
    contact (1-9 s); a gap over FORCE_BRIDGE_MAX ends the first at the gap's start."""
    from skin.models.commission import force_contacts

    rng = np.random.default_rng(1)
    t = np.arange(1500) / 100.0
    f = np.round(np.clip(rng.normal(0, 0.005, t.size), 0, None), 3)
    f[(t >= 1) & (t < 2.6)] += 2
    f[(t >= 7.9) & (t < 9)] += 2
    f[(t >= 2.5) & (t < 8.0)] = np.nan
    got = force_contacts(t, f)
    assert len(got) == 2
    assert got[0] == pytest.approx((1.0, 2.5), abs=0.011)
    assert got[1] == pytest.approx((8.0, 9.0), abs=0.011)


def test_a_quiet_quantised_force_is_not_taken_as_stuck():
    """A working sensor with 2-3 mN noise and a 10 mN step repeats 0.00 for long stretches:
    force_stuck took 41 % of its samples as no reading (100 samples of one value); runs are
    now compared with the channel's own (ten times the longest in a typical stretch)."""
    from skin.models.commission import force_stuck

    rng = np.random.default_rng(5)
    t = np.arange(6000) / 100.0
    for sigma in (0.002, 0.003):
        f = np.round(rng.normal(0, sigma, (t.size, 1)), 2)
        for s in range(5, 60, 10):
            f[(t >= s) & (t < s + 2), 0] += 2.0
        out, notes = force_stuck(t, f)
        assert not np.isnan(out).any() and not notes
        g = f.copy()
        g[3000:, 0] = 0.0  # now really stuck at its free level for 30 s
        out, notes = force_stuck(t, g)
        assert np.isnan(out[3000:, 0]).mean() > 0.9 and notes

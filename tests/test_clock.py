"""Device time -> host time: offset and drift, wraps, resets, several boards on one time base."""

import numpy as np
import pytest

from skin import drivers
from skin.drivers.clock import DEVICE_WRAP, ClockMap
from skin.drivers.sim import PtySerialDevice, SkinSimulator
from skin.formats.scene import load_scene


def feed(clock, device, host):
    return np.array([clock.update(d, h) for d, h in zip(device, host, strict=True)])


def stream(seconds, drift=50e-6, offset=1000.0, start=0.0, seed=0):
    rng = np.random.default_rng(seed)
    t = start + np.arange(round(seconds * 200)) / 200
    true = offset + t * (1 + drift)  # host time at sampling
    arrival = true + 1e-3 + rng.exponential(2e-3, len(t))  # at least 1 ms on the way
    return t, true, arrival


def test_drift_and_offset_are_found_under_jittered_delays():
    t, true, arrival = stream(120)
    clock = ClockMap()
    mapped = feed(clock, t, arrival)
    est = clock.estimate
    assert est.drift == pytest.approx(50e-6, abs=3e-6)
    # the map gives sampling time plus the smallest delay (1 ms), within 0.3 ms once settled
    late = slice(len(t) // 2, None)
    assert np.abs(mapped[late] - true[late] - 1e-3).max() < 3e-4
    assert 0 < est.latency < 5e-3
    # far smoother than the arrival times it came from
    assert np.std(np.diff(mapped[late])) < 0.05 * np.std(np.diff(arrival[late]))


def test_the_first_block_uses_the_smallest_delay_so_far():
    t, true, arrival = stream(0.5, drift=0.0)
    mapped = feed(ClockMap(), t, arrival)
    assert np.all(mapped <= arrival + 1e-12)
    assert mapped[-1] - true[-1] < 5e-3


def test_the_u32_microsecond_wrap_is_unwrapped():
    t, true, arrival = stream(30, start=DEVICE_WRAP - 10.0)
    wrapped = np.mod(t, DEVICE_WRAP)
    clock = ClockMap()
    mapped = feed(clock, wrapped, arrival)
    assert np.all(np.diff(mapped) > 0)
    assert np.abs(mapped[-100:] - true[-100:] - 1e-3).max() < 1e-3
    assert clock.estimate.resets == 0


def test_a_board_reset_restarts_the_estimate():
    t, true, arrival = stream(10)
    clock = ClockMap()
    feed(clock, t, arrival)
    # the board reboots: its clock starts from 0 again, the host's goes on
    t2, true2, arrival2 = stream(10, offset=true[-1] + 0.5)
    mapped = feed(clock, t2, arrival2)
    assert clock.estimate.resets == 1
    assert np.abs(mapped[-100:] - true2[-100:] - 1e-3).max() < 1e-3


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="block"):
        ClockMap(block=0)


def test_two_boards_on_two_ports_share_one_time_base():
    scene = load_scene("default")
    devices = [PtySerialDevice(SkinSimulator(scene, duration=2.0), speed=1.0) for _ in range(2)]
    try:
        with drivers.open([f"serial://{devices[0].port}",
                           f"serial://{devices[1].port}?board=7"]) as skin:
            for device in devices:
                device.start()
            frames = []
            while len(frames) < 800:
                frame = skin.recv(timeout=3.0)
                assert frame is not None, f"only {len(frames)} frames"
                frames.append(frame)
            assert set(skin.clocks) == {0, 7}
    finally:
        for device in devices:
            device.close()
    by_board = {b: {f.seq: f.host_time for f in frames if f.board == b} for b in (0, 7)}
    common = sorted(set(by_board[0]) & set(by_board[7]))
    assert len(common) > 300
    # the same sample of both boards, played at the same moment, maps to the same host time
    late = [s for s in common if s >= 200]
    skew = np.array([by_board[0][s] - by_board[7][s] for s in late])
    assert np.abs(skew).max() < 0.03
    for board in (0, 7):  # and each board's times advance at the sample rate
        times = np.array([by_board[board][s] for s in sorted(by_board[board])])
        assert np.median(np.diff(times)) == pytest.approx(0.005, abs=2e-4)


def test_bench_clock_prints_error_and_cost_per_method(capsys):
    import json

    from skin.cli import main

    assert main(["bench", "clock", "--seconds", "40", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    rows = {(r["scenario"], r["method"]): r for r in doc["rows"]}
    for scenario in ("USB serial", "loaded host", "CAN over UDP"):
        mapped, arrival = rows[scenario, "ClockMap, 1 s blocks"], rows[scenario, "arrival time"]
        assert mapped["p99_abs_error_ms"] < 0.2 * arrival["p99_abs_error_ms"]
        assert abs(mapped["drift_error_ppm"]) < 2
        assert mapped["us_per_frame"] > 0
    assert abs(rows["USB serial", "running min, no drift"]["drift_error_ppm"] + 50) < 1
    assert main(["bench", "clock", "--seconds", "5"]) == 2


def test_a_skin_read_across_the_device_clock_wrap_keeps_its_contacts():
    from skin.models import JointClassifier
    from skin.stream.pipeline import Pipeline

    class WrappingSimulator(SkinSimulator):
        """The same board, its clock started 3 s before the u32 microsecond wrap."""

        def frames(self):
            for f in super().frames():
                yield dataclasses.replace(f, device_time=f.device_time + DEVICE_WRAP - 3.0)

    import dataclasses

    scene = load_scene("default")
    contacts = []
    for simulator in (SkinSimulator(scene, duration=12.0),
                      WrappingSimulator(scene, duration=12.0)):
        device = PtySerialDevice(simulator, speed=0)
        try:
            with drivers.open(f"serial://{device.port}") as skin:
                device.start()
                pipe = Pipeline(scene.layout, JointClassifier(scene.layout))
                times, found = [], []
                while (frame := skin.recv(timeout=5.0)) is not None:
                    times.append(frame.device_time)
                    found += [r for r in pipe.process([frame]) if r.contact.final]
                    if len(times) == device.frames_sent and device.done.is_set():
                        break
                found += [r for r in pipe.flush() if r.contact.final]
        finally:
            device.close()
        assert len(times) == 12 * 200 and np.all(np.diff(times) > 0)  # no jump back
        contacts.append([(r.contact.taxels, r.contact.onset - times[0], r.estimate.label)
                         for r in found])
    assert len(contacts[0]) >= 5 and len(contacts[1]) == len(contacts[0])
    for (taxels, onset, label), (taxels1, onset1, label1) in zip(*contacts, strict=True):
        assert (taxels1, label1) == (taxels, label) and onset1 == pytest.approx(onset, abs=2e-3)

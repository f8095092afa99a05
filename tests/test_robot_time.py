"""Robot time: host time beside device time from the driver, through the pipeline, into events."""

import json
import time

import numpy as np
import pytest

from skin.drivers.base import Driver
from skin.drivers.clock import wall_time
from skin.drivers.sim import SkinSimulator
from skin.formats.scene import load_scene, match_touches
from skin.models import HistogramClassifier
from skin.stream.pipeline import HostTimeline, Pipeline
from skin.stream.sinks import JsonLinesSink

DRIFT = 80e-6  # the board's crystal runs 80 ppm fast against the host
HOST_START = 5000.0  # host time at device time 0, s
FLOOR = 1e-3  # smallest transport delay, s


class ClockedSim(Driver):
    """The simulated skin as a driver whose frames reach the host after a random delay."""

    def __init__(self, frames, seed=0):
        super().__init__()
        rng = np.random.default_rng(seed)
        t = np.array([f.device_time for f in frames])
        self.true_host = HOST_START + t * (1 + DRIFT)  # host time at sampling
        # a USB link with jitter and an occasional stall (the reader got the CPU late)
        arrival = self.true_host + FLOOR + rng.exponential(1e-3, len(t))
        arrival[rng.random(len(t)) < 0.01] += 0.03
        self.arrival = np.maximum.accumulate(arrival)
        self.frames = frames
        self.k = 0

    def _recv_internal(self, timeout):
        if self.k >= len(self.frames):
            self.finished = True
            return None
        f = self.frames[self.k]
        self.k += 1
        return type(f)(f.seq, f.device_time, float(self.arrival[self.k - 1]), f.counts,
                       f.ambient, f.duty, f.flags, f.board, f.status)


def test_events_line_up_with_a_robot_log_within_the_clock_maps_error(tmp_path):
    scene = load_scene("default")
    frames = list(SkinSimulator(scene, duration=14.0).frames())
    driver = ClockedSim(frames)
    stamped = list(driver)
    assert len(stamped) == len(frames)
    # the clock map's own error, once settled: mapped host time against the true one
    mapped = np.array([f.host_time for f in stamped])
    settled = np.array([f.device_time for f in stamped]) >= 3.0
    clock_error = np.abs(mapped - driver.true_host)[settled].max()
    assert clock_error < 5e-3  # the map removes the jitter and the stalls

    path = tmp_path / "events.jsonl"
    with JsonLinesSink(path) as sink:
        pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout), sinks=[sink])
        for k in range(0, len(stamped), 20):
            pipe.process(stamped[k : k + 20])
        pipe.flush()
    events = [json.loads(line) for line in path.read_text().splitlines()]
    assert events and all(e["host_onset"] is not None for e in events)

    # the robot's log: when it touched, on its (the host's) wall clock
    robot_log = {t.start: wall_time(HOST_START + t.start * (1 + DRIFT)) for t in scene.touches}
    matches, _ = match_touches(scene, [e["taxels"] for e in events],
                               [e["onset"] for e in events])
    checked = 0
    for m in matches:
        if m.contact_index is None or m.touch.start < 3.0:
            continue
        e = events[m.contact_index]
        # the contact's onset error in device time, carried over to host time
        onset_error = (e["onset"] - m.touch.start) * (1 + DRIFT)
        aligned = e["host_onset"] - robot_log[m.touch.start] - onset_error
        assert abs(aligned) <= clock_error + 1e-5, (e, aligned, clock_error)
        decided = e["host_decided_at"] - e["host_onset"]
        assert decided == pytest.approx((e["decided_at"] - e["onset"]) * (1 + DRIFT), abs=2e-5)
        checked += 1
    assert checked >= 4


def test_timeline_interpolates_and_restarts_on_a_reset():
    line = HostTimeline(capacity=100)
    assert np.isnan(line.to_host(1.0))
    t = np.arange(0, 1, 0.01)
    line.append(t, 100 + t * 1.001)
    assert line.to_host(0.5) == pytest.approx(100.5005)
    assert line.to_host(2.0) == pytest.approx(2.0 + 100 + 0.99 * 0.001)  # held beyond the end
    line.append(np.array([0.0, 0.01]), np.array([300.0, 300.01]))  # the board reset
    assert line.to_host(0.005) == pytest.approx(300.005)


def test_samples_without_host_times_give_no_host_times_in_events():
    from skin.stream.pipeline import ContactResult
    from skin.stream.sinks import event_record

    scene = load_scene("default")
    frames = list(SkinSimulator(scene, duration=6.0).frames())
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout))
    results = pipe.process(frames) + pipe.flush()
    rec = event_record(ContactResult(results[0].contact, results[0].estimate, 1.0))
    assert rec["host_onset"] is None and rec["host_decided_at"] is None


def test_can_samples_carry_the_message_timestamp_of_their_sync(request):
    can = pytest.importorskip("can")
    from skin import drivers
    from skin.drivers.protocol import can_sample_frames

    channel = f"skin-test-{request.node.name}"
    bus = can.Bus(interface="virtual", channel=channel)
    with drivers.open(f"can://virtual/{channel}") as driver:
        frames = can_sample_frames(1, 7, 35000, np.arange(10), 24.5, np.full(10, 200))
        sync, rest = frames[0], frames[1:]
        sent = time.monotonic()
        bus.send(can.Message(arbitration_id=sync[0], data=sync[1], is_extended_id=False))
        time.sleep(0.3)  # the rest of the sample comes late; the reader reads later still
        for ident, data in rest:
            bus.send(can.Message(arbitration_id=ident, data=data, is_extended_id=False))
        time.sleep(0.2)
        frame = driver.recv(timeout=1.0)
    bus.shutdown()
    assert frame is not None and frame.seq == 7
    # the first frame of a board maps to its arrival: the SYNC's timestamp, not the read
    assert abs(frame.host_time - sent) < 0.05

from dataclasses import fields

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skin.drivers.sim import SkinSimulator
from skin.formats.scene import load_scene
from skin.stream.calibration import Calibration
from skin.stream.onset import OnsetDetector
from skin.stream.onset_refine import refine_onset


@pytest.fixture(scope="module")
def stream():
    scene = load_scene("default")
    sim = SkinSimulator(scene)
    frames = list(sim.frames())
    cal = Calibration.from_layout(scene.layout)
    temps, _ = cal.temperature(np.array([f.counts for f in frames], dtype=float))
    times = np.array([f.device_time for f in frames])
    return scene, times, temps


def run_chunks(times, temps, sizes):
    det = OnsetDetector(temps.shape[1])
    state = det.initial_state()
    events = []
    i = 0
    for size in sizes:
        ev, state = det.process(times[i : i + size], temps[i : i + size], state)
        events += ev
        i += size
    ev, state = det.process(times[i:], temps[i:], state)
    return events + ev, state


def test_detects_every_scene_touch_without_false_alarms(stream):
    scene, times, temps = stream
    events, _ = run_chunks(times, temps, [])
    onsets = [e for e in events if e.kind == "onset"]
    touched = set()
    for touch in scene.touches:
        for tid in touch.taxels:
            k = scene.layout.index(tid)
            hits = [e for e in onsets if e.taxel == k and 0 <= e.time - touch.start < 0.35]
            assert hits, f"taxel {tid} touch at {touch.start} s not detected"
            touched.add((k, hits[0].time))
    assert len(onsets) == len(touched), "onsets that match no touch (false alarms)"


def test_release_follows_each_touch(stream):
    scene, times, temps = stream
    events, _ = run_chunks(times, temps, [])
    for touch in scene.touches:
        k = scene.layout.index(touch.taxels[0])
        rel = [e for e in events if e.kind == "release" and e.taxel == k
               and touch.start < e.time <= touch.end + 0.2]
        if touch.end < scene.duration - 1.0:
            assert rel, f"no release for taxel {touch.taxels[0]} after {touch.start} s"
            assert abs(rel[0].time - touch.end) < 0.15


@pytest.fixture(scope="module")
def warm_stream():
    # four quiet taxels, contacts every few seconds, most of them with objects hotter than
    # the taxel: in its first 20 s two rises and their releases
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials

    mats = load_materials()
    s = simulate_stream([mats["aluminium"], mats["glass"]], n_taxels=4, duration=40.0,
                        contacts_per_minute=6.0, disturbances=False, warm=0.7, seed=1)
    times, temps = s.times[:4000], s.temperature[:4000]
    return times, temps, run_chunks(times, temps, [])


def assert_same_state(a, b):
    for f in fields(a):
        assert np.allclose(getattr(a, f.name), getattr(b, f.name), equal_nan=True), f.name


@settings(max_examples=10, deadline=None)
@given(st.lists(st.integers(1, 400), min_size=1, max_size=12))
def test_chunk_size_does_not_change_events(stream, sizes):
    _, times, temps = stream
    n = 1000  # the first 5 s hold four contacts
    whole, s_whole = run_chunks(times[:n], temps[:n], [])
    parts, s_parts = run_chunks(times[:n], temps[:n], sizes)
    assert parts == whole
    assert_same_state(s_parts, s_whole)


def test_trace_gives_the_events_and_state_of_process_and_the_slope_per_sample(stream):
    _, times, temps = stream
    n = 600
    det = OnsetDetector(temps.shape[1])
    events, state = det.process(times[:n], temps[:n], det.initial_state())
    # resumed from the state after 400 samples, as a stream would be
    _, head = det.process(times[:400], temps[:400], det.initial_state())
    tr = det.trace(times[400:n], temps[400:n], head)
    assert tr.events == [e for e in events if e.detected_at >= times[400]]
    assert_same_state(tr.state, state)
    assert tr.slope.shape == tr.smooth.shape == (n - 400, temps.shape[1])
    # each row is the state after that sample
    _, after = det.process(times[400:450], temps[400:450], head)
    assert np.array_equal(tr.slope[49], after.slope)
    assert np.array_equal(tr.smooth[49], after.smooth, equal_nan=True)


def test_trace_margins_reach_1_exactly_where_a_fall_test_raises_an_onset():
    # a described sensor's stream with disturbances: each free, armed taxel-sample whose
    # CUSUM, slow channel or gust-envelope margin exceeds 1 raises a fall onset there, and
    # every fall onset is raised where one does (the margins are the tests themselves)
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials
    from skin.models.sensors import load_sensor
    from skin.stream.onset import MARGIN_TESTS

    table = load_materials()
    s = simulate_stream([table["aluminium"], table["pine"], table["cardboard"]], n_taxels=4,
                        duration=180.0, contacts_per_minute=3.0, seed=4,
                        sensor=load_sensor("paper"))
    det = OnsetDetector(4, sensor="paper")
    tr = det.trace(s.times, s.temperature, margins=True)
    assert tr.margins.shape == (s.times.size, len(MARGIN_TESTS), 4)
    events, _ = det.process(s.times, s.temperature, det.initial_state())
    assert tr.events == events
    firing = tr.margins[:, [0, 2, 3], :] > 1.0
    fired = {(i, k) for i, k in zip(*np.nonzero(np.any(firing, axis=1)), strict=True)}
    falls = {(int(np.searchsorted(s.times, e.detected_at)), e.taxel) for e in events
             if e.kind == "onset" and e.direction < 0}
    assert len(falls) >= 10
    assert fired == falls
    # a stale CUSUM is reset, not raised: its margin is apart from the live one's
    assert np.all(np.isnan(tr.margins[:, 0]) | (tr.margins[:, 0] == 0.0)
                  | (tr.margins[:, 1] == 0.0))
    assert det.trace(s.times[:10], s.temperature[:10]).margins is None


@settings(max_examples=6, deadline=None)
@given(st.lists(st.integers(1, 900), min_size=1, max_size=12))
def test_chunk_size_does_not_change_rises(warm_stream, sizes):
    times, temps, (whole, s_whole) = warm_stream
    assert [(e.kind, e.direction) for e in whole] == [("onset", 1), ("onset", 1),
                                                      ("release", 1), ("release", 1)]
    parts, s_parts = run_chunks(times, temps, sizes)
    assert parts == whole
    assert_same_state(s_parts, s_whole)


def _heated_taxel_trace(t, t_on, t_off, t_object, h, material="aluminium", free=38.963):
    """A quiet heated taxel touched once: the contact response, then back to ``free``."""
    from skin.models import load_materials
    from skin.models.physics import SensorConstants, contact_trace

    sensor = SensorConstants()
    e = load_materials()[material].effusivity
    y = np.full(t.size, free)
    on = (t > t_on) & (t <= t_off)
    y[on] = contact_trace(t[on] - t_on, free, t_object, e, sensor, h)
    end = float(contact_trace(t_off - t_on, free, t_object, e, sensor, h))
    after = t[t > t_off] - t_off
    y[t > t_off] = free + (end - free) * (0.5 * np.exp(-after / 2.0) + 0.5 * np.exp(-after / 62.5))
    return y


@pytest.mark.parametrize(("t_object", "h", "direction"), [(55.0, 5000.0, 1), (45.0, 3000.0, 1),
                                                          (25.0, 5000.0, -1)])
def test_warm_contact_is_a_rise_and_is_released(t_object, h, direction):
    fs = 200.0
    t = np.arange(0, 30, 1 / fs)
    y = _heated_taxel_trace(t, 10.0, 13.0, t_object, h)
    y = y + np.random.default_rng(2).normal(0, 0.02, t.size)
    det = OnsetDetector(1)
    events, state = det.process(t, y[:, None], det.initial_state())
    onsets = [e for e in events if e.kind == "onset"]
    releases = [e for e in events if e.kind == "release"]
    assert len(onsets) == 1 and len(releases) == 1, events
    (on,), (off,) = onsets, releases
    assert on.direction == direction == off.direction
    assert 10.0 - 0.05 <= on.time <= 10.35 and on.detected_at < 10.6
    assert on.baseline == pytest.approx(38.963, abs=0.05)
    assert abs(off.time - 13.0) < 0.15 and off.detected_at < 13.4
    # a release's baseline is its contact's extreme: the in-contact maximum of a rise
    near = y[(t > 12.5) & (t < 13.3)]
    extreme = near.max() if direction > 0 else near.min()
    assert off.baseline == pytest.approx(extreme, abs=0.06)
    assert not state.in_contact[0] and state.direction[0] == 0


def test_warm_touch_on_a_taxel_still_reheating_is_released():
    # the taxel was cooled by a contact and is still reheating towards 38.96 C when a warmer
    # object touches it briefly: after release the reading keeps rising (the rise stops short,
    # it never falls back below its maximum), and the release must still be found
    fs = 200.0
    t = np.arange(0, 40, 1 / fs)
    y = _heated_taxel_trace(t, 5.0, 8.0, 20.0, 20000.0)  # a cold aluminium block: -8 K or so
    k = t > 25.0
    touch = _heated_taxel_trace(t[k] - 25.0, 0.0, 0.4, 52.0, 20000.0, free=0.0)
    y[k] += touch * 0.15  # a brief, weak warm touch on top of the reheat
    y = y + np.random.default_rng(3).normal(0, 0.015, t.size)
    det = OnsetDetector(1)
    events, state = det.process(t, y[:, None], det.initial_state())
    kinds = [(e.kind, e.direction) for e in events]
    assert kinds == [("onset", -1), ("release", -1), ("onset", 1), ("release", 1)], events
    assert 25.0 - 0.05 <= events[2].time <= 25.35
    assert 25.2 <= events[3].time <= 25.7 and events[3].detected_at < 26.5
    assert not state.in_contact[0]


def test_heater_steps_up_and_reheats_after_contacts_raise_no_rise():
    # disturbed streams with no warm object: heater duty steps up and down, drift, gusts and
    # every contact's reheat; the rising channel must stay silent (falls are all contacts)
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials

    mats = load_materials()
    s = simulate_stream([mats[m] for m in ("aluminium", "glass", "neoprene", "pine")],
                        n_taxels=16, duration=240.0, fs=100.0, contacts_per_minute=2.0, seed=6)
    assert all(c.direction == -1 for c in s.contacts)
    # the free reading climbs by kelvins where the heater steps up (the 63 s mode)
    assert np.max(s.temperature[-100:].mean(axis=0) - s.temperature[:100].mean(axis=0)) > 1.0 \
        or np.max(np.ptp(s.temperature, axis=0)) > 3.0
    det = OnsetDetector(16)
    events, _ = det.process(s.times, s.temperature, det.initial_state())
    onsets = [e for e in events if e.kind == "onset"]
    assert onsets and all(e.direction == -1 for e in onsets)
    inside = [any(c.taxel == e.taxel and c.onset - 0.1 <= e.time <= c.release + 0.1
                  for c in s.contacts) for e in onsets]
    assert sum(not x for x in inside) <= 1


def test_quiet_reheating_taxel_raises_no_alarm():
    # a free taxel warming from 31 C towards 38.96 C with tau = 20.6 s, quantised, 4 minutes:
    # 11.7 tau, the rest of the climb (0.07 mK) far below a count (about 70 mK); 10 minutes
    # took 2 min of the suite, and noise alone is tests/test_onset_noise.py's
    rng = np.random.default_rng(0)
    fs = 200.0
    t = np.arange(0, 240, 1 / fs)
    true = 38.963 + (31.0 - 38.963) * np.exp(-t / 20.6)
    from skin.formats.layout import load_layout

    full = Calibration.from_layout(load_layout("arm"))
    cal = Calibration(full.c0[:1], full.c1[:1], full.divider_resistor[:1],
                      full.supply_voltage[:1], full.adc_reference[:1], full.adc_max[:1])
    counts = np.rint(cal.counts(true[:, None] + rng.normal(0, 0.02, (t.size, 1))))
    temps, _ = cal.temperature(counts)
    det = OnsetDetector(1)
    events, _ = det.process(t, temps, det.initial_state())
    assert events == []


def test_missing_samples_are_skipped_not_fatal(stream):
    _, times, temps = stream
    holes = temps[:400].copy()
    holes[100:120, 3] = np.nan
    det = OnsetDetector(temps.shape[1])
    _events, state = det.process(times[:400], holes, det.initial_state())
    assert np.all(np.isfinite(state.level))


def test_refine_onset_recovers_the_true_onset():
    from skin.models.physics import SensorConstants, contact_temperature, thermistor_temperature

    s = SensorConstants()
    fs = 200.0
    t = np.arange(0, 3.0, 1 / fs)
    t_on = 1.2345
    ts = contact_temperature(37.0, 25.0, s.effusivity, 331.3)
    y = np.where(t < t_on, 37.0, thermistor_temperature(t - t_on, 37.0, ts, s))
    y = y + np.random.default_rng(1).normal(0, 0.02, t.size)
    onset, initial = refine_onset(t, y, coarse=t_on + 0.2, baseline=37.0, slope=0.0,
                                  depth=s.depth, diffusivity=s.diffusivity)
    assert abs(onset - t_on) <= 0.015
    assert initial == pytest.approx(37.0)


@pytest.mark.parametrize("h", [np.inf, 3000.0])
def test_refine_onset_dates_a_rise(h):
    # a warm object: heat flows into the sensor, the reading rises; refine_onset fits a signed
    # amplitude, so it dates the rise as it dates a fall
    from skin.models.physics import SensorConstants, contact_trace

    s = SensorConstants()
    fs = 200.0
    t = np.arange(0, 3.0, 1 / fs)
    rng = np.random.default_rng(4)
    errors = []
    for _ in range(10):
        t_on = 1.2 + rng.uniform(0, 0.01)
        y = np.where(t < t_on, 37.0, contact_trace(t - t_on, 37.0, 52.0, 13427.0, s, h))
        y = y + rng.normal(0, 0.02, t.size)
        assert y[-1] > 38.0
        onset, initial = refine_onset(t, y, coarse=t_on + 0.2, baseline=37.0, slope=0.0,
                                      depth=s.depth, diffusivity=s.diffusivity)
        errors.append(onset - t_on)
        assert initial == pytest.approx(37.0)
    assert abs(np.median(errors)) <= 0.012 and np.max(np.abs(errors)) <= 0.03


def test_slow_channel_finds_more_contacts_among_air_currents_without_false_alarms():
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials

    mats = load_materials()
    stream = simulate_stream([mats[m] for m in ("brick", "cardboard", "pine", "human_skin")],
                             n_taxels=16, duration=420.0, seed=0, contacts_per_minute=2.0)
    truth = [(c.taxel, c.onset, c.release) for c in stream.contacts if c.duration >= 0.3]

    def score(**kw):
        det = OnsetDetector(16, **kw)
        events, _ = det.process(stream.times, stream.temperature, det.initial_state())
        onsets = [e for e in events if e.kind == "onset"]
        hits = sum(any(e.taxel == k and on - 0.1 <= e.time <= off + 0.1 for e in onsets)
                   for k, on, off in truth)
        false = sum(not any(e.taxel == k and on - 0.1 <= e.time <= off + 0.1
                            for k, on, off in ((c.taxel, c.onset, c.release)
                                               for c in stream.contacts)) for e in onsets)
        return hits, false

    hits_cusum, false_cusum = score(slow_threshold=np.inf, gust_envelope=False)
    hits, false = score(gust_envelope=False)  # the slow channel alone beside the CUSUM
    assert hits > hits_cusum + 5 and false <= false_cusum + 2
    hits_all, false_all = score()  # and the gust envelope beside both
    assert hits_all >= hits and false_all <= false + 2


def test_a_low_cost_streams_first_reading_raises_no_slow_alarm():
    # the slow channel's average was seeded with the first reading, which carries the readout
    # noise before any averaging (a low-cost stream's: 0.14-0.24 K sd over its taxels, up to
    # 0.52 K above the next seconds): it stayed there for slow_tau while the medium average
    # settled, and at arming the difference was a fall past the slow threshold (quiet streams
    # of seeds 2 and 3: one onset each, at 2.0 / 1.75 s, no contact, no disturbance)
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials
    from skin.models.sensors import load_sensor

    sensor = load_sensor("low-cost")
    glass = load_materials()["glass"]
    seeded = 0
    for seed in (2, 3):
        s = simulate_stream([glass], n_taxels=16, duration=20.0, contacts_per_minute=1e-6,
                            disturbances=False, seed=seed, sensor=sensor)
        assert s.contacts == []
        det = OnsetDetector(16, sensor=sensor)
        first = s.temperature[0] - s.temperature[int(s.fs):int(3 * s.fs)].mean(axis=0)
        seeded += int(np.any(first > det.slow_threshold))  # the case happened
        events, _ = det.process(s.times, s.temperature, det.initial_state())
        assert events == []
    assert seeded == 2


def _heater_stepping_down(seed: int = 0, seconds: float = 35.0):
    """16 fast-film taxels, their heater duty stepping down by 0.3 at 20 s (taxels 0-7).

    Two thirds of the largest step (`HEATER_STEP`), through the body's slowest mode (the
    detector's ``heater_rate`` at the largest step): on fast-film (a mode of 11 s) its fall
    outruns the gust envelope, and only the heater's allowance holds it. 20 s is past the
    detector's warm-up; a detector told the duty held raises its onsets within 3 s of the
    step, and the 15 s after it are over a mode of the fall.
    """
    from skin.models.sensors import load_sensor
    from skin.stream.onset import HEATER_STEP

    sensor = load_sensor("fast-film")
    det = OnsetDetector(16, sensor=sensor)
    mode = HEATER_STEP * sensor.heated_rise / det.heater_rate
    rng = np.random.default_rng(seed)
    fs = sensor.sample_rate
    t = np.arange(0, seconds, 1 / fs)
    duty = np.ones((t.size, 16))
    duty[t >= 20.0, :8] = 0.7
    fall = 0.3 * sensor.heated_rise * -np.expm1(-np.clip(t - 20.0, 0, None) / mode)
    y = 25.0 + sensor.heated_rise + np.zeros((t.size, 16))
    y[:, :8] -= fall[:, None]
    y += rng.normal(0.0, sensor.delivered_noise(25.0 + sensor.heated_rise), y.shape)
    return det, t, y, duty


def test_a_heater_step_down_the_duty_shows_is_no_contact():
    # (chunks, in place and trace with a duty: tests/test_onset_pinned.py's "paper-duty")
    det, t, y, duty = _heater_stepping_down()
    events, state = det.process(t, y, det.initial_state(), duty=duty)
    assert [e for e in events if e.kind == "onset"] == []
    assert [e for e in det.process(t, y, det.initial_state())[0] if e.kind == "onset"] == []
    # told the duty held, the same fall is a contact on the stepped taxels: the allowance
    # is what holds it (dated within 0.2 s of the step, raised within 3 s)
    k = np.searchsorted(t, 25.0)
    held, _ = det.process(t[:k], y[:k], det.initial_state(), duty=np.ones_like(duty[:k]))
    assert {e.taxel for e in held if e.kind == "onset"} == set(range(8))
    # the duty through the body's slowest mode, the first one taken as the steepest step
    # down just then (from 1 / (1 - HEATER_STEP)): the closed form of a first-order lag,
    # sample by sample
    from skin.stream.onset import HEATER_STEP

    decay = np.exp(-1.0 / (det.sensor.sample_rate * det.heater_mode))
    before = 1.0 / (1.0 - HEATER_STEP) - 1.0
    held = 1.0 + before * decay ** t.size
    np.testing.assert_allclose(state.duty_lag[8:], held, rtol=1e-9)
    k = np.searchsorted(t, 20.0)
    stepped = 0.7 + (1.0 + before * decay**k - 0.7) * decay ** (t.size - k)
    np.testing.assert_allclose(state.duty_lag[:8], stepped, rtol=1e-9)
    assert np.all(state.duty_top == 1.0)  # the largest duty given: the heated rise's


def test_without_the_duty_every_fall_keeps_the_heaters_allowance():
    # a duty of NaN (not known) is no duty: the same events and state as none given
    det, t, y, duty = _heater_stepping_down(1, seconds=22.0)
    none, s0 = det.process(t, y, det.initial_state())
    nan, s1 = det.process(t, y, det.initial_state(), duty=np.full_like(duty, np.nan))
    assert none == nan
    assert np.all(np.isnan(s1.duty_lag)) and np.all(np.isnan(s1.duty))
    assert np.all(np.isnan(s1.duty_top))
    for f in fields(s0):
        if not f.name.startswith("duty"):
            np.testing.assert_array_equal(getattr(s1, f.name), getattr(s0, f.name))


def test_a_brief_touch_during_a_heaters_fall_is_released_with_the_duty():
    """A touch of 0.5 s, 8 s after the heater stepped down by 0.3 (fast-film, a mode of
    11 s): once the object has left, the reading goes on falling with the heater, so it never
    came back from its in-contact extreme and the contact was held past the stream's end (on
    paper seed 5's long stream, 3 of its 4 contacts missed as still in contact: 10-40 s after
    brief touches). With the duty the extreme and the return are judged with the heater's own
    fall put back: every taxel is released as the held-duty ones are, within 0.5 s."""
    from skin.models.sensors import load_sensor

    sensor = load_sensor("fast-film")
    det = OnsetDetector(16, sensor=sensor)
    rise, mode = sensor.heated_rise, det.heater_mode
    t = np.arange(0.0, 34.0, 1.0 / sensor.sample_rate)
    duty = np.ones((t.size, 16))
    duty[t >= 20.0, :8] = 0.7
    y = 25.0 + rise + np.zeros((t.size, 16))
    y[:, :8] -= 0.3 * rise * -np.expm1(-np.clip(t - 20.0, 0.0, None) / mode)[:, None]
    on, off = 28.0, 28.5  # the touch: 3 % of the heated rise, approached with 0.2 s
    touch = np.where(t < on, 0.0, np.where(t < off, -np.expm1(-(t - on) / 0.2),
                                            -np.expm1(-(off - on) / 0.2) * np.exp(-(t - off))))
    y -= 0.03 * rise * touch[:, None]
    y += np.random.default_rng(0).normal(0.0, sensor.delivered_noise(25.0 + rise), y.shape)
    events, state = det.process(t, y, det.initial_state(), duty=duty)
    assert sorted((e.taxel, e.kind) for e in events) == sorted(
        (k, kind) for k in range(16) for kind in ("onset", "release"))
    for e in events:
        assert (on - 0.1 < e.time < on + 0.2) if e.kind == "onset" else (
            off - 0.3 < e.time < off + 0.1 and e.detected_at < off + 0.5), e
    assert not state.in_contact.any()
    assert np.all(state.heater_fall == 0.0) and np.all(state.extreme_fall == 0.0)


def test_a_heater_switched_off_long_ago_has_no_fall_to_allow():
    """The heater's allowance is the lag's excess over the duty in units of the largest duty
    (the heated rise's): a heater off for many of the body's modes has none left, so a slow
    contact fall is found as it is with the duty held; divided by the lag itself (the
    review's reproducer), the share stayed 1 and the fall was allowed past the contact."""
    from skin.models.sensors import load_sensor

    sensor = load_sensor("fast-film")
    det = OnsetDetector(8, sensor=sensor, common_mode=False)
    fs = sensor.sample_rate
    t = np.arange(0.0, 30.0, 1.0 / fs)
    rng = np.random.default_rng(3)
    y = 25.0 + sensor.heated_rise + rng.normal(0.0, sensor.delivered_noise(), (t.size, 8))
    # a smooth contact fall of 2-6 K from 20 s, approached with 3 s: a slow conductor
    depth = np.linspace(2.0, 6.0, 8)
    y -= depth * -np.expm1(-np.clip(t - 20.0, 0.0, None) / 3.0)[:, None]
    state = det.initial_state()
    # the heater went off long ago: what a stream of 12 modes off left in the state
    off = state.copy()
    off.duty[:], off.duty_top[:] = 0.0, 200.0
    off.duty_lag[:] = 200.0 * np.exp(-12.0)
    held = state.copy()
    held.duty[:], held.duty_top[:], held.duty_lag[:] = 200.0, 200.0, 200.0
    got = {}
    for name, start, duty in (("off", off, 0.0), ("held", held, 200.0)):
        events, end = det.process(t, y, start, duty=np.full(y.shape, duty))
        got[name] = {e.taxel for e in events if e.kind == "onset" and e.time > 19.0}
        assert np.all(end.duty == duty) and np.all(end.duty_top == 200.0)
    assert got["off"] == got["held"] == set(range(8))
    # and a first duty of 0 (never heated as far as known): no allowance either
    first = det.initial_state()
    _, s0 = det.process(t[:2], y[:2], first, duty=np.zeros((2, 8)))
    assert np.all(s0.duty_lag == 0.0) and np.all(s0.duty_top == 0.0)


def test_a_streams_duty_follows_its_switches_and_evaluate_onset_can_tell_the_detector(capsys):
    import json

    from skin.bench.streams import simulate_stream
    from skin.cli import main as skin_main
    from skin.models import load_materials

    mats = load_materials()
    s = simulate_stream([mats["pine"]], n_taxels=3, duration=200.0, fs=50.0, seed=2)
    duty = s.duty()
    assert duty.shape == s.temperature.shape and np.isfinite(duty).all()  # each from 0 s
    for t, taxel, value in s.switches:
        k = np.searchsorted(s.times, t)
        assert duty[k, taxel] == value
    assert len(s.switches) > 3  # some taxel switched after its first
    assert skin_main(["evaluate-onset", "--sensor", "paper", "--seed", "3", "--minutes", "2",
                      "--taxels", "4", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert 0.0 <= doc["detected_5sigma"] <= 1.0 and doc["false_alarms"] >= 0
    # told by default on a simulated stream, as the pipeline tells it; --no-duty: not
    assert doc["duty"] is True and "heater duty told" in doc["source"]
    assert skin_main(["evaluate-onset", "--sensor", "paper", "--seed", "3", "--minutes", "2",
                      "--taxels", "4", "--json", "--no-duty"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["duty"] is False and "heater duty" not in doc["source"]
    # a trial dataset carries no duty: refused, not ignored
    assert skin_main(["evaluate-onset", "--data", "trials.npz", "--duty"]) == 2
    assert "--duty" in capsys.readouterr().err

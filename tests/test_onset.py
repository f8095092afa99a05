import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skin.calibration import Calibration
from skin.drivers.sim import SkinSimulator
from skin.onset import OnsetDetector
from skin.onset_refine import refine_onset
from skin.scene import load_scene


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


@settings(max_examples=10, deadline=None)
@given(st.lists(st.integers(1, 400), min_size=1, max_size=12))
def test_chunk_size_does_not_change_events(stream, sizes):
    _, times, temps = stream
    n = 1000  # the first 5 s hold four contacts
    whole, s_whole = run_chunks(times[:n], temps[:n], [])
    parts, s_parts = run_chunks(times[:n], temps[:n], sizes)
    assert parts == whole
    assert np.allclose(s_parts.level, s_whole.level, equal_nan=True)


def test_quiet_reheating_taxel_raises_no_alarm():
    # a free taxel warming from 31 C towards 38.96 C with tau = 20.6 s, quantised, 10 minutes
    rng = np.random.default_rng(0)
    fs = 200.0
    t = np.arange(0, 600, 1 / fs)
    true = 38.963 + (31.0 - 38.963) * np.exp(-t / 20.6)
    from skin.layout import load_layout

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


def test_slow_channel_finds_more_contacts_among_air_currents_without_false_alarms():
    from skin.models import load_materials
    from skin.models.streams import simulate_stream

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

    hits_cusum, false_cusum = score(slow_threshold=np.inf)
    hits, false = score()
    assert hits > hits_cusum + 5 and false <= false_cusum + 2

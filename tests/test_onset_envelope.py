"""The onset detector's gust-envelope test (`skin.stream.onset`, channel 2)."""

import numpy as np
import pytest
from scipy.signal import lfilter

from skin.models.sensors import load_sensor, smooth
from skin.stream.onset import GUST_DEPTH, GUST_RISE, HEATER_STEP, OnsetDetector


def _worst_disturbance(sensor, n_taxels: int, seed: int, duration: float = 40.0,
                       heater: bool = True):
    """The deepest, fastest gust and the steepest heater step down, together, in white noise."""
    fs = sensor.sample_rate
    t = np.arange(round(duration * fs)) / fs
    rise = sensor.heated_rise
    mode = 62.5 * sensor.reheat_time_constant / load_sensor("paper").reheat_time_constant
    start = 15.0 + np.linspace(0.0, 1.0, n_taxels)  # a spread of phases against the samples
    s = np.maximum(t[:, None] - start[None, :], 0.0)
    gust = GUST_DEPTH * rise * np.where(s < 8.0, -np.expm1(-s / GUST_RISE),
                                        -np.expm1(-8.0 / GUST_RISE) * np.exp(-(s - 8.0)
                                                                            / GUST_RISE))
    heater = HEATER_STEP * rise * -np.expm1(-s / mode) if heater else 0.0
    noise = smooth(np.random.default_rng(seed).normal(0.0, sensor.noise_kelvin(25.0 + rise),
                                                      (t.size, n_taxels)), sensor, axis=0)
    return t, 25.0 + rise - gust - heater + noise


@pytest.mark.parametrize("preset", ["paper", "low-cost"])
def test_the_worst_gust_raises_no_onset_and_with_a_heater_step_no_envelope_onset(preset):
    sensor = load_sensor(preset)
    t, y = _worst_disturbance(sensor, 16, seed=5, heater=False)
    det = OnsetDetector(16, sensor=sensor)
    events, _ = det.process(t, y, det.initial_state())
    assert [e for e in events if e.kind == "onset"] == []
    # the steepest heater step at the same instant: the CUSUM, set against gusts alone, may
    # take the kink for a contact; the envelope test, set against both, does not
    t, y = _worst_disturbance(sensor, 16, seed=5)
    events, _ = det.process(t, y, det.initial_state())
    assert [e for e in events if e.kind == "onset" and e.channel == 2] == []


def test_a_smooth_fall_beyond_the_gust_envelope_is_an_onset_the_cusum_misses():
    # a contact through the paper sensor's 80 um: the reading bends down smoothly, and the
    # trend-following baseline takes most of it; the air's flutter (0.01 K over 0.5 s) raises
    # the noise the CUSUM's allowance follows, and the CUSUM alone misses it. 0.9 K within
    # 3 s is deeper than any gust (0.4 K) and heater step can make in that time
    sensor = load_sensor("paper")
    fs = sensor.sample_rate
    t = np.arange(round(30.0 * fs)) / fs
    on = 20.0 + np.linspace(0.0, 1.0, 16)
    s = np.maximum(t[:, None] - on[None, :], 0.0)
    fall = 0.9 * (1.0 - (1.0 + s / 0.7) * np.exp(-s / 0.7))  # starts with zero slope
    rng = np.random.default_rng(2)
    a = np.exp(-1.0 / (0.5 * fs))
    flutter = lfilter([1.0 - a], [1.0, -a], rng.normal(0.0, 0.01, (t.size, 16)), axis=0)
    noise = rng.normal(0.0, sensor.noise_kelvin(39.0), (t.size, 16))
    y = 39.0 - fall + noise + flutter * np.sqrt(fs)
    found = {}
    for envelope in (False, True):
        det = OnsetDetector(16, sensor=sensor, gust_envelope=envelope)
        events, _ = det.process(t, y, det.initial_state())
        found[envelope] = {e.taxel: e for e in events if e.kind == "onset"}
    assert len(found[False]) <= 2
    assert len(found[True]) >= 12
    for k, e in found[True].items():
        assert on[k] - 0.5 <= e.time <= on[k] + 1.0 and e.direction == -1
        assert e.detected_at - on[k] < 3.0


@pytest.mark.parametrize("preset", ["paper", "low-cost"])  # low-cost: its own medium average
@pytest.mark.parametrize("sizes", [[1] * 50 + [333, 7], [4000, 1]])
def test_gust_envelope_is_chunk_invariant(sizes, preset):
    sensor = load_sensor(preset)
    t, y = _worst_disturbance(sensor, 4, seed=9)
    s = np.maximum(t - 30.0, 0.0)
    y[:, 1] -= 1.0 * (1.0 - (1.0 + s / 0.4) * np.exp(-s / 0.4))
    det = OnsetDetector(4, sensor=sensor)
    whole, last = det.process(t, y, det.initial_state())
    state, events, i = det.initial_state(), [], 0
    for size in [*sizes, len(t)]:
        ev, state = det.process(t[i:i + size], y[i:i + size], state)
        events += ev
        i += size
    assert events == whole and any(e.kind == "onset" for e in whole)
    for name in ("ref_level", "ref_slope", "ref_t", "cusum", "slow", "medium"):
        np.testing.assert_array_equal(getattr(state, name), getattr(last, name))


@pytest.mark.parametrize("preset", ["paper", "low-cost", "pid-logger", "fast-film"])
def test_average_noise_matches_the_noise_of_averaged_smoothed_readings(preset):
    # the slow channel's and the envelope's margins: the noise of the detector's average of a
    # reading the sensor smoothed (correlated noise: an average removes less than of white)
    from skin.stream.onset import _average_noise

    sensor = load_sensor(preset)
    fs = sensor.sample_rate
    delivered = smooth(np.random.default_rng(4).normal(0.0, 1.0, (60 * round(fs), 8)), sensor,
                       axis=0)
    for tau in (0.03, 0.5):
        g = 1.0 - np.exp(-1.0 / (fs * tau))
        averaged = lfilter([g], [1.0, g - 1.0], delivered - delivered.mean(axis=0), axis=0)
        measured = averaged[round(20 * tau * fs):].std() / delivered.std()
        assert _average_noise(sensor, tau) == pytest.approx(measured, rel=0.1)
    if sensor.smoothing == "none":
        g = 1.0 - np.exp(-1.0 / (fs * 0.03))
        assert _average_noise(sensor, 0.03) == pytest.approx(np.sqrt(g / (2.0 - g)))


def test_an_envelope_onset_as_the_slow_window_runs_out_re_bases_from_where_the_fall_began():
    # the envelope's reference slides to now on the sample its age passes the slow channel's
    # window; an onset raised on that very sample re-based the in-contact baseline from now
    # (over one sample: a steep rise for a fall) instead of from where the fall began
    sensor = load_sensor("paper")
    fs = sensor.sample_rate
    det = OnsetDetector(2, sensor=sensor)
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 10.0, 1 / fs)
    _, state = det.process(t, 39.0 + 0.01 * rng.standard_normal((t.size, 2)),
                           det.initial_state())
    now = t[-1] + 1 / fs
    state = state.copy()
    state.ref_level[:] = state.smooth + 2.0  # a fall of 2 K, deeper than any gust
    state.ref_t[:] = [now - det.slow_tau - 0.5 / fs, now - 1.0]  # taxel 0: at the window's end
    events, after = det.process(np.array([now]), np.array([[39.0, 39.0]]), state)
    onsets = {e.taxel: e for e in events if e.kind == "onset"}
    assert sorted(onsets) == [0, 1] and all(e.channel == 2 for e in onsets.values())
    assert onsets[0].time == pytest.approx(now - det.slow_tau - 0.5 / fs)
    # the in-contact trend of a fall, re-based over seconds: small and not rising
    assert np.all(after.slope <= 0.0) and np.all(np.abs(after.slope) < 0.1)

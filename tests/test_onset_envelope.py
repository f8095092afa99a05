"""The onset detector's gust-envelope test (`skin.stream.onset`, channel 2)."""

from itertools import pairwise

import numpy as np
import pytest
from scipy.signal import lfilter

from skin.models.sensors import load_sensor, smooth
from skin.stream.onset import GUST_DEPTH, GUST_RISE, HEATER_STEP, OnsetDetector, drop_noise


def _mode(sensor) -> float:
    """The sensor body's slowest mode, s (62.5 s for the paper's), as the detector takes it."""
    return 62.5 * sensor.reheat_time_constant / load_sensor("paper").reheat_time_constant


def _worst_disturbance(sensor, n_taxels: int, seed: int, duration: float = 40.0,
                       heater: bool = True):
    """The deepest, fastest gust and the steepest heater step down, together, in white noise."""
    fs = sensor.sample_rate
    t = np.arange(round(duration * fs)) / fs
    rise = sensor.heated_rise
    mode = _mode(sensor)
    start = 15.0 + np.linspace(0.0, 1.0, n_taxels)  # a spread of phases against the samples
    s = np.maximum(t[:, None] - start[None, :], 0.0)
    gust = GUST_DEPTH * rise * np.where(s < 8.0, -np.expm1(-s / GUST_RISE),
                                        -np.expm1(-8.0 / GUST_RISE) * np.exp(-(s - 8.0)
                                                                            / GUST_RISE))
    heater = HEATER_STEP * rise * -np.expm1(-s / mode) if heater else 0.0
    noise = smooth(np.random.default_rng(seed).normal(0.0, sensor.noise_kelvin(25.0 + rise),
                                                      (t.size, n_taxels)), sensor, axis=0)
    return t, 25.0 + rise - gust - heater + noise


@pytest.mark.parametrize("preset", ["paper", "low-cost", "fast-film"])
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


# low-cost: its own medium average; pid-logger: the loop's envelope; fast-film: the faster
# reading (``DetectorState.fast``) carried across chunks, holes and a late start
@pytest.mark.parametrize("preset", ["paper", "low-cost", "pid-logger", "fast-film"])
@pytest.mark.parametrize("sizes", [[1] * 50 + [333, 7], [4000, 1]])
def test_gust_envelope_is_chunk_invariant(sizes, preset):
    sensor = load_sensor(preset)
    t, y = _worst_disturbance(sensor, 4, seed=9)
    s = np.maximum(t - 30.0, 0.0)
    y[:, 1] -= 1.0 * (1.0 - (1.0 + s / 0.4) * np.exp(-s / 0.4))
    fs = sensor.sample_rate
    y[: round(7.3 * fs), 3] = np.nan  # a taxel that starts late (inside the noise's running mean)
    y[round(12.1 * fs): round(12.4 * fs), 2] = np.nan  # and holes
    y[round(31.0 * fs), 1] = np.nan
    det = OnsetDetector(4, sensor=sensor)
    whole, last = det.process(t, y, det.initial_state())
    state, events, i = det.initial_state(), [], 0
    for size in [*sizes, len(t)]:
        ev, state = det.process(t[i:i + size], y[i:i + size], state)
        events += ev
        i += size
    assert events == whole and any(e.kind == "onset" for e in whole)
    for name in ("ref_level", "ref_slope", "ref_t", "cusum", "slow", "medium", "var",
                 "t_first", "fast"):
        np.testing.assert_array_equal(getattr(state, name), getattr(last, name))
    assert np.all(np.isfinite(state.fast)) == (det.envelope_tau is not None)


@pytest.mark.parametrize("preset", ["paper", "low-cost", "pid-logger", "fast-film"])
def test_average_noise_matches_the_noise_of_averaged_smoothed_readings(preset):
    # the slow channel's and the envelope's margins: the noise of the detector's average of a
    # reading the sensor smoothed (correlated noise: an average removes less than of white)
    from skin.stream.onset import average_noise

    sensor = load_sensor(preset)
    fs = sensor.sample_rate
    delivered = smooth(np.random.default_rng(4).normal(0.0, 1.0, (60 * round(fs), 8)), sensor,
                       axis=0)
    for tau in (0.03, 0.5):
        g = 1.0 - np.exp(-1.0 / (fs * tau))
        averaged = lfilter([g], [1.0, g - 1.0], delivered - delivered.mean(axis=0), axis=0)
        measured = averaged[round(20 * tau * fs):].std() / delivered.std()
        assert average_noise(sensor, tau) == pytest.approx(measured, rel=0.1)
    if sensor.smoothing == "none":
        g = 1.0 - np.exp(-1.0 / (fs * 0.03))
        assert average_noise(sensor, 0.03) == pytest.approx(np.sqrt(g / (2.0 - g)))


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


def _through_loop(x, sensor):
    """What a loop-held sensor reads of ``x`` (n_samples, n) at its face: loop, lag, smoothing."""
    from skin.models.sensors import apply_dynamics

    return smooth(apply_dynamics(x, sensor, axis=0), sensor, axis=0)


def test_a_heater_step_at_a_loop_held_thermistor_stays_below_its_closed_form_bound():
    # through a first-order mode (tau) and the loop's high-pass (tc) a step A peaks at
    # A tc / (tau - tc) (exp(-t*/tau) - exp(-t*/tc)), t* = ln(tau / tc) tau tc / (tau - tc):
    # 0.1 K on pid-logger, where a constant-power heater keeps falling by A / tau per second
    from dataclasses import replace

    from skin.stream.onset import loop_envelope

    sensor = replace(load_sensor("pid-logger"), lag=0.0, smoothing="none")
    tau, tc = _mode(sensor), sensor.control_time
    a = HEATER_STEP * sensor.heated_rise
    peak_t = np.log(tau / tc) * tau * tc / (tau - tc)
    peak = a * tc / (tau - tc) * (np.exp(-peak_t / tau) - np.exp(-peak_t / tc))
    _, fall, drift = loop_envelope(sensor, 40.0, 0.0, tau, 0.1)
    assert fall[-1] == pytest.approx(peak, rel=0.01)
    assert np.all(np.diff(fall) >= 0) and np.all(np.diff(drift) >= 0)
    assert fall[-1] < 0.15 * a / tau * 12.0  # the old allowance over the slow window: 0.86 K


def test_the_loop_envelope_bounds_every_gust_and_heater_step_the_stream_draws():
    # each gust of the simulator's family (depth, rise 1-4 s, hold 1-8 s) with a heater step
    # down at the same instant, through pid-logger's loop, lag and smoothing: its fall over
    # any span stays within the envelope's (the room's drift aside)
    from skin.stream.onset import loop_envelope

    sensor = load_sensor("pid-logger")
    fs = sensor.sample_rate
    det = OnsetDetector(1, sensor=sensor)
    step, fall, _ = loop_envelope(sensor, det.slow_tau, float(det.gust_depth), _mode(sensor),
                                   0.1)
    t = np.arange(round(40.0 * fs)) / fs
    s = np.maximum(t - 5.0, 0.0)
    cases = []
    for rise in (1.0, 1.7, 2.5, 4.0):
        for hold in (1.0, 3.3, 5.2, 8.0):
            gust = np.where(s < hold, -np.expm1(-s / rise),
                            -np.expm1(-hold / rise) * np.exp(-(s - hold) / rise))
            cases.append(-det.gust_depth * gust
                         - HEATER_STEP * sensor.heated_rise * -np.expm1(-s / _mode(sensor)))
    y = _through_loop(np.array(cases).T, sensor)
    for n in range(1, round(det.slow_tau * fs)):
        worst = float(np.max(y[:-n] - y[n:]))
        assert worst <= fall[int(np.ceil(n / fs / step - 1e-9))] + 1e-9


def test_loop_held_contacts_in_the_rooms_drift_are_found_by_the_envelope_and_dated_late():
    # contacts through pid-logger (0.42 K at their deepest) in its readout noise and the
    # room's random walk through the loop (0.03 K sd): the CUSUM finds half; the envelope,
    # set by the loop's own bounds on gusts and heater steps and the room's fall over any
    # span at 0.1 false alarms per taxel-hour, more (11 of 16; 14 with the room's quantile of
    # one span, which let 4.4 false alarms per taxel-hour through); an envelope onset is
    # dated when raised (its reference may date from long before), and `refine_onset`, which
    # searches before it, dates it (median 0.2 s in this strong drift). With the old
    # envelope (a heater step falling at 0.07 K/s on a loop-held sensor) 8 of 16 were found
    from skin.models.physics import SensorConstants
    from skin.stream.onset import AMBIENT_DRIFT
    from skin.stream.onset_refine import refine_onset, refine_span, sensor_response

    sensor = load_sensor("pid-logger")
    fs = sensor.sample_rate
    n = 16
    t = np.arange(round(40.0 * fs)) / fs
    on = 25.0 + np.linspace(0.0, 1.0, n)
    body = SensorConstants(depth=sensor.depth, diffusivity=sensor.diffusivity)
    response = np.stack([sensor_response(t - o, np.array([np.inf]), body, sensor)[0]
                         for o in on], axis=1)
    rng = np.random.default_rng(3)
    room = np.cumsum(rng.normal(0.0, np.sqrt(AMBIENT_DRIFT / fs), (t.size, n)), axis=0)
    y = (35.0 - 4.0 * response + _through_loop(room, sensor)
         + smooth(rng.normal(0.0, sensor.noise_kelvin(35.0), (t.size, n)), sensor, axis=0))
    det = OnsetDetector(n, sensor=sensor)
    events, _ = det.process(t, y, det.initial_state())
    falls = {e.taxel: e for e in events if e.kind == "onset" and e.direction == -1
             and on[e.taxel] - 0.1 <= e.time <= on[e.taxel] + 4.0}
    assert len(falls) >= 10
    envelope = [e for e in falls.values() if e.channel == 2]
    assert envelope and all(e.time == e.detected_at >= on[e.taxel] for e in envelope)
    search, horizon = refine_span(sensor)
    errors = []
    for e in envelope:
        keep = (t >= e.time - search) & (t <= e.time + horizon)
        onset, _ = refine_onset(t[keep], y[keep, e.taxel], e.time, e.baseline, e.slope,
                                sensor.depth, sensor.diffusivity, sensor=sensor)
        errors.append(onset - on[e.taxel])
    assert np.median(np.abs(errors)) < 0.3


def test_the_worst_loop_held_disturbance_raises_no_envelope_onset():
    # the deepest, fastest gusts held 1-8 s and the steepest heater step through pid-logger's
    # loop, with the room's random walk through it (the binding term: without its allowance
    # the same readings raise envelope onsets)
    from skin.stream.onset import AMBIENT_DRIFT

    sensor = load_sensor("pid-logger")
    fs = sensor.sample_rate
    n = 32
    det = OnsetDetector(n, sensor=sensor)
    t = np.arange(round(40.0 * fs)) / fs
    start = 15.0 + np.linspace(0.0, 1.0, n)
    s = np.maximum(t[:, None] - start[None, :], 0.0)
    hold = np.linspace(1.0, 8.0, n)[None, :]
    gust = np.where(s < hold, -np.expm1(-s / GUST_RISE),
                    -np.expm1(-hold / GUST_RISE) * np.exp(-(s - hold) / GUST_RISE))
    heater = HEATER_STEP * sensor.heated_rise * -np.expm1(-s / _mode(sensor))
    rng = np.random.default_rng(6)
    room = np.cumsum(rng.normal(0.0, np.sqrt(AMBIENT_DRIFT / fs), (t.size, n)), axis=0)
    y = (35.0 + _through_loop(-det.gust_depth * gust - heater + room, sensor)
         + smooth(rng.normal(0.0, sensor.noise_kelvin(35.0), (t.size, n)), sensor, axis=0))
    events, _ = det.process(t, y, det.initial_state())
    assert [e for e in events if e.kind == "onset" and e.channel == 2] == []
    step, fall, drift = det.envelope
    det.envelope = (step, fall, np.zeros_like(drift))
    events, _ = det.process(t, y, det.initial_state())
    assert [e for e in events if e.kind == "onset" and e.channel == 2]


def test_the_loop_envelope_is_read_only_and_a_zero_false_alarm_rate_is_finite():
    from skin.stream.onset import loop_envelope

    sensor = load_sensor("pid-logger")
    _, fall, drift = loop_envelope(sensor, 4.0, 0.1, _mode(sensor), 0.0)
    assert np.all(np.isfinite(drift)) and drift[-1] > 0.0
    with pytest.raises(ValueError):
        fall[0] = 1.0
    with pytest.raises(ValueError):
        drift[0] = 1.0


def _smooth_falls(n_taxels: int, seed: int):
    """fast-film taxels whose reading falls 1.5 K (a critically damped 70 ms approach) from
    onsets spread over 4.0-4.1 s, in the sensor's smoothed readout noise, 6 s in all."""
    sensor = load_sensor("fast-film")
    fs = sensor.sample_rate
    t = np.arange(round(6.0 * fs)) / fs
    on = 4.0 + np.linspace(0.0, 0.1, n_taxels)
    s = np.maximum(t[:, None] - on[None, :], 0.0)
    fall = 1.5 * (1.0 - (1.0 + s / 0.07) * np.exp(-s / 0.07))
    noise = smooth(np.random.default_rng(seed).normal(0.0, sensor.noise_kelvin(35.0),
                                                      (t.size, n_taxels)), sensor, axis=0)
    return sensor, t, on, 35.0 - fall + noise


def test_the_envelope_margin_sets_when_a_smooth_fall_is_raised():
    # the same smooth fall on fast-film, without gusts: the envelope test's noise margin is
    # what the fall must clear beyond the gust and heater allowance, so a smaller margin
    # raises every onset no later, and most earlier (the margin is most of fast-film's delay)
    sensor, t, on, y = _smooth_falls(16, seed=4)
    raised = {}
    for z in (8.0, 5.0):
        det = OnsetDetector(16, sensor=sensor, envelope_sigmas=z, envelope_noise=False)
        assert det.envelope_sigmas == z
        events, _ = det.process(t, y, det.initial_state())
        raised[z] = {e.taxel: e.detected_at for e in events if e.kind == "onset"}
        assert sorted(raised[z]) == list(range(16))
        assert all(0.0 < raised[z][k] - on[k] < 0.3 for k in range(16))
    assert all(raised[5.0][k] <= raised[8.0][k] for k in range(16))
    assert sum(raised[5.0][k] < raised[8.0][k] for k in range(16)) >= 12


@pytest.mark.parametrize("preset", ["paper", "low-cost", "fast-film"])
def test_the_falls_noise_table_matches_the_filters_run_on_noise(preset):
    # the fall from the reference (prediction + trend x since - smoothed reading), measured on
    # white readout noise run through the sensor's smoothing, the detector's smoothing and
    # its level/trend filter, step by step: its sd at each time since is the table's (on
    # fast-film, the fall read on the detector's faster reading: its own table)
    sensor = load_sensor(preset)
    det = OnsetDetector(4, sensor=sensor, envelope_noise=True)
    assert (det.envelope_tau is not None) == (preset == "fast-film")
    step, sd, resid = drop_noise(sensor, det.smooth_tau, det.level_tau, det.slope_tau,
                                 det.slow_tau, det.envelope_tau)
    assert sd[0] == 1.0 and np.all(np.diff(sd[1:]) > -1e-9)  # grows with the time since
    fs = sensor.sample_rate
    dt = 1.0 / fs
    n, m = round(40.0 * det.slope_tau * fs) + sd.size, 400
    noise = np.random.default_rng(3).normal(0.0, 1.0, (n, m))
    y = smooth(noise, sensor, axis=0) / sensor.smoothing_noise_factor()  # delivered sd 1
    g_s, g_l, g_b = (-np.expm1(-dt / tau) for tau in (det.smooth_tau, det.level_tau,
                                                        det.slope_tau))
    a = lfilter([g_s], [1.0, g_s - 1.0], y, axis=0)
    b = a
    if det.envelope_tau is not None:
        g_f = -np.expm1(-dt / det.envelope_tau)
        b = lfilter([g_f], [1.0, g_f - 1.0], y, axis=0)
    level, slope = np.zeros(m), np.zeros(m)
    pred, trend = np.empty_like(a), np.empty_like(a)
    for i in range(n):
        pred[i], trend[i] = level + slope * dt, slope
        err = g_l * (a[i] - pred[i])
        level = pred[i] + err
        slope = slope + g_b * err / dt
    start = n - sd.size - round(5.0 * det.slope_tau * fs)  # the filters settled
    refs = np.arange(start - 200, start)
    assert np.std(b[refs] - pred[refs]) == pytest.approx(resid, rel=0.08)
    for since in (0.1, 1.0, det.slow_tau):
        k = round(since / step)
        fall = pred[refs] + trend[refs] * k * dt - b[refs + k]
        assert np.std(fall) == pytest.approx(resid * sd[k], rel=0.08)


def test_the_noise_margin_is_smaller_early_and_larger_late_and_chunk_invariant():
    # fast-film: 40 ms after the reference the fall's noise is a fraction of the flat 8 sigmas
    # (the margin was most of its delay); seconds after, on low-cost, more than 8 sigmas
    for preset, since, smaller in (("fast-film", 0.04, True), ("low-cost", 5.0, False)):
        det = OnsetDetector(4, sensor=preset, envelope_noise=True)
        k = int(np.ceil(since / det._drop_step))
        margin = det.envelope_sigmas * det._drop_sd[k] * det._resid_sigma[0]
        assert (margin < 8.0 * det.smoothed_sigma[0]) == smaller
    sensor, t, _, y = _smooth_falls(8, seed=5)
    det = OnsetDetector(8, sensor=sensor, envelope_noise=True)
    whole, _ = det.process(t, y, det.initial_state())
    assert sorted(e.taxel for e in whole if e.kind == "onset") == list(range(8))
    state, parts = det.initial_state(), []
    for lo, hi in ((0, 1), (1, 777), (777, 4100), (4100, 4101), (4101, t.size)):
        ev, state = det.process(t[lo:hi], y[lo:hi], state)
        parts += ev
    assert parts == whole


def test_a_sensor_faster_than_the_papers_has_its_fall_read_sooner_on_a_faster_reading():
    # fast-film (10x the paper's speed): the envelope test also reads the fall on the reading
    # smoothed over a tenth of the 30 ms, against that reading's own noise (`drop_noise`'s
    # fast table, 8 of its sigmas flat); a fast contact's fall is raised sooner, a slow one
    # as before (the smoothed reading's test still runs); the worst gust raises nothing
    # (`test_the_worst_gust_raises_no_onset_and_with_a_heater_step_no_envelope_onset`)
    sensor, t, on, y = _smooth_falls(16, seed=6)
    raised = {}
    for tau in (None, 0.0):
        det = OnsetDetector(16, sensor=sensor, envelope_tau=tau)
        assert (det.envelope_tau is None) == (tau == 0.0)
        events, _ = det.process(t, y, det.initial_state())
        raised[tau] = {e.taxel: e.detected_at for e in events if e.kind == "onset"}
        assert sorted(raised[tau]) == list(range(16))
        assert all(0.0 < raised[tau][k] - on[k] < 0.1 for k in range(16))
    assert all(raised[None][k] <= raised[0.0][k] for k in range(16))
    assert sum(raised[None][k] < raised[0.0][k] for k in range(16)) >= 12
    with pytest.raises(ValueError, match="envelope_tau"):
        OnsetDetector(4, sensor=sensor, envelope_tau=-1.0)
    # asked where it cannot read: a clear error, not a reading silently left out
    for kind in ({"envelope_noise": False}, {"gust_envelope": False}):
        with pytest.raises(ValueError, match="needs the gust-envelope test"):
            OnsetDetector(4, sensor=sensor, envelope_tau=0.003, **kind)
        assert OnsetDetector(4, sensor=sensor, **kind).envelope_tau is None
    with pytest.raises(ValueError, match="pid-logger: pid"):
        OnsetDetector(4, sensor="pid-logger", envelope_tau=0.01)


def _start_up(n_taxels: int, seed: int, duration: float = 4.0):
    """fast-film taxels whose reading begins to fall (0.6 K/s, easing off over 1 s) 0.25 s in.

    The baseline, seated with no trend at the first sample, is still catching that trend when
    the warm-up ends (0.5 s): the start-up transient, not noise (the kind of fast-film's
    evaluate-onset seed 4 false alarm with the table applied from the warm-up on).
    """
    sensor = load_sensor("fast-film")
    fs = sensor.sample_rate
    t = np.arange(round(duration * fs)) / fs
    noise = smooth(np.random.default_rng(seed).normal(0.0, sensor.noise_kelvin(35.0),
                                                      (t.size, n_taxels)), sensor, axis=0)
    return sensor, t, 35.0 - 0.6 * -np.expm1(-np.maximum(t[:, None] - 0.25, 0.0) / 1.0) + noise


def test_the_noise_table_waits_for_the_baseline_to_settle_after_the_first_sample():
    sensor, t, y = _start_up(64, 1)
    det = OnsetDetector(64, sensor=sensor, envelope_noise=True)
    assert det._settle == pytest.approx(3.0 * det.slope_tau)
    settled, _ = det.process(t, y, det.initial_state())
    flat = OnsetDetector(64, sensor=sensor, envelope_noise=False)
    default, _ = flat.process(t, y, flat.initial_state())
    # the CUSUM's own start-up onsets (channel 0) are the default's; no envelope onset
    assert [e for e in settled if e.kind == "onset" and e.channel == 2] == []
    assert settled == default
    # the table applied from the warm-up on (before the settle rule) took the start-up
    # transient for a fall beyond the noise: envelope onsets within 50 ms of the arming
    det._settle = 0.0
    early, _ = det.process(t, y, det.initial_state())
    raised = [e for e in early if e.kind == "onset" and e.channel == 2]
    assert raised and all(e.detected_at < det.warmup + 0.05 for e in raised)


def test_the_noise_margin_is_chunk_invariant_across_the_settle_and_finite_from_the_first_sample():
    sensor, t, y = _start_up(16, 2, duration=6.0)
    on = 3.0 + np.linspace(0.0, 0.1, 16)  # contacts after the settle
    s = np.maximum(t[:, None] - on[None, :], 0.0)
    y = y - 1.5 * (1.0 - (1.0 + s / 0.07) * np.exp(-s / 0.07))
    det = OnsetDetector(16, sensor=sensor, envelope_noise=True)
    tr = det.trace(t[:3], y[:3])  # the margin at since 0 and on the first samples
    assert np.all(np.isfinite(tr.smooth)) and np.all(np.isfinite(tr.slope))
    whole, _ = det.process(t, y, det.initial_state())
    assert all(np.isfinite([e.time, e.detected_at, e.baseline, e.slope]).all() for e in whole)
    flat = OnsetDetector(16, sensor=sensor, envelope_noise=False)
    default, _ = flat.process(t, y, flat.initial_state())

    def found(events):  # {taxel: when raised} of the contacts, within 0.2 s of their onset
        return {e.taxel: e.detected_at for e in events if e.kind == "onset"
                and on[e.taxel] < e.detected_at < on[e.taxel] + 0.2}

    # the table applies after the settle: every contact the default finds, found no later
    assert len(found(default)) >= 12
    assert all(found(whole).get(k, np.inf) <= d for k, d in found(default).items())
    # the boundary, split: the seat is the first sample (`armed_at - warmup`), the table
    # applies from `_settle` after it
    settle = round((t[0] + det._settle) * sensor.sample_rate)
    state, parts = det.initial_state(), []
    for lo, hi in ((0, 1), (1, 2), (2, settle - 1), (settle - 1, settle + 1),
                   (settle + 1, 3001), (3001, t.size)):
        ev, state = det.process(t[lo:hi], y[lo:hi], state)
        parts += ev
    assert parts == whole


def _holed_noise(n_taxels: int, seed: int, duration: float):
    """Paper taxels of readout noise alone, every taxel's readings lost 0.1 s every 2 s."""
    sensor = load_sensor("paper")
    fs = sensor.sample_rate
    t = np.arange(round(duration * fs)) / fs
    y = 35.0 + smooth(np.random.default_rng(seed).normal(0.0, sensor.noise_kelvin(35.0),
                                                         (t.size, n_taxels)), sensor, axis=0)
    y[(t % 2.0) >= 1.9] = np.nan  # shorter than the warm-up: the baseline is kept
    return sensor, t, y


def test_a_hole_shorter_than_the_warm_up_restarts_the_settle_clock():
    sensor, t, y = _holed_noise(128, 0, 60.0)
    det = OnsetDetector(128, sensor=sensor, envelope_noise=True)
    assert 0.1 < det.warmup
    tr = det.trace(t[:420], y[:420])  # across the first hole (1.9-2.0 s)
    back = np.flatnonzero(t >= 2.0)[0]
    assert np.all(tr.state.t_seated == t[back])
    assert np.all(tr.state.settle_restarts == 1)  # the hole, counted: a user sees it
    events, _ = det.process(t, y, det.initial_state())
    flat = OnsetDetector(128, sensor=sensor, envelope_noise=False)
    default, _ = flat.process(t, y, flat.initial_state())
    # the smoothing and the baseline run again after a hole: not the settled filters the table
    # models, the flat margin holds (the default's own onsets here are its CUSUM's)
    assert [e for e in events if e.channel == 2] == []
    assert events == default
    # with the clock kept across the hole (as the seat was before), the table alone took the
    # noise after the hole for falls
    det._hole = np.inf
    kept, _ = det.process(t, y, det.initial_state())
    raised = [e for e in kept if e.kind == "onset" and e.channel == 2]
    assert raised and all(e.detected_at % 2.0 < det._settle
                          for e in raised)


def test_a_release_restarts_the_settle_clock_and_the_flat_margin_holds_until_settled():
    sensor = load_sensor("fast-film")
    fs = sensor.sample_rate
    t = np.arange(round(8.0 * fs)) / fs
    n = 32
    on, off = 2.0, 2.6
    s_on = np.maximum(t - on, 0.0)
    s_off = np.maximum(t - off, 0.0)
    # a touch that falls 1.5 K and then is released: the reading recovers, decelerating
    touch = 1.5 * (1.0 - np.exp(-s_on / 0.07)) - 1.5 * (1.0 - np.exp(-s_off / 0.3))
    noise = smooth(np.random.default_rng(7).normal(0.0, sensor.noise_kelvin(35.0),
                                                   (t.size, n)), sensor, axis=0)
    y = 35.0 - touch[:, None] + noise
    det = OnsetDetector(n, sensor=sensor, envelope_noise=True)
    tr = det.trace(t, y)
    releases = {e.taxel: e.detected_at for e in tr.events if e.kind == "release"}
    assert len(releases) == n
    assert all(tr.state.t_seated[k] == pytest.approx(r) for k, r in releases.items())
    # until the settle after the release the margin is the flat one's or more; the same
    # detector with the table applied at once (no settle) is compared sample by sample
    env = 3  # MARGIN_TESTS: "envelope", its fall over its threshold
    det0 = OnsetDetector(n, sensor=sensor, envelope_noise=True)
    det0._settle = 0.0
    tr0 = det0.trace(t, y, margins=True)
    tr = det.trace(t, y, margins=True)
    assert tr.events == tr0.events  # nothing raised on the recovery either way
    young = np.zeros_like(tr.margins[:, env], dtype=bool)
    for k, r in releases.items():
        young[:, k] = (t >= r + det.warmup) & (t < r + det._settle)
    with_rule, table = tr.margins[:, env][young], tr0.margins[:, env][young]
    ok = np.isfinite(with_rule) & (table > 0)
    assert ok.sum() > 1000
    assert np.all(with_rule[ok] <= table[ok] + 1e-12)
    assert np.mean(with_rule[ok] < table[ok]) > 0.5  # the flat margin, larger, holds
    late = t >= max(releases.values()) + det._settle + 0.5
    assert late.sum() > 100
    assert np.array_equal(tr.margins[late, env], tr0.margins[late, env], equal_nan=True)


@pytest.mark.parametrize("preset", ["fast-film", "low-cost"])
def test_once_settled_the_margin_is_the_smaller_of_the_table_and_the_flat_one(preset):
    # readout noise alone: no event either way, so both detectors' states are the same on
    # every sample, and their envelope statistics (fall over what it must clear) compare
    sensor = load_sensor(preset)
    fs = sensor.sample_rate
    n = 16
    t = np.arange(round((12.0 if preset == "fast-film" else 60.0) * fs)) / fs
    y = 35.0 + smooth(np.random.default_rng(11).normal(0.0, sensor.noise_kelvin(35.0),
                                                       (t.size, n)), sensor, axis=0)
    det = OnsetDetector(n, sensor=sensor, envelope_noise=True)
    flat = OnsetDetector(n, sensor=sensor, envelope_noise=False)
    env = 3  # MARGIN_TESTS: "envelope"
    a, b = det.trace(t, y, margins=True), flat.trace(t, y, margins=True)
    assert a.events == b.events == []
    settled = t >= det._settle + det.warmup + 1.0
    x, f = a.margins[settled, env], b.margins[settled, env]
    ok = np.isfinite(x) & (f > 0)
    assert ok.sum() > 1000
    assert np.all(x[ok] >= f[ok] * (1 - 1e-12))  # never a larger margin than the flat one
    if preset == "fast-film":
        assert np.mean(x[ok] > f[ok]) > 0.9  # tens of ms after the reference: the table's


@pytest.mark.parametrize("preset", ["paper", "fast-film"])
def test_a_gap_in_the_timestamps_between_two_chunks_gives_the_one_runs_events(preset):
    """Rows missing (no NaN: the timestamps jump) where one chunk ends and the next begins."""
    sensor = load_sensor(preset)
    fs = sensor.sample_rate
    t = np.arange(0.0, 20.0, 1.0 / fs)
    noise = np.random.default_rng(3).normal(0.0, sensor.noise_kelvin(35.0), (t.size, 6))
    y = 35.0 + smooth(noise, sensor, axis=0)
    after = t >= 12.0  # a fall on taxel 4, after the gap
    y[after, 4] -= 2.0 * -np.expm1(-(t[after] - 12.0) / 0.5)
    keep = ~((t >= 8.0) & (t < 8.1))  # 0.1 s of every taxel's rows lost
    t, y = t[keep], y[keep]
    det = OnsetDetector(6, sensor=sensor)
    assert det.envelope_noise and 0.1 < det.warmup
    whole, state = det.process(t, y, det.initial_state())
    assert any(e.kind == "onset" and e.taxel == 4 for e in whole)
    assert np.all(state.settle_restarts == 1)
    b = int(np.flatnonzero(t >= 8.1)[0])  # the first sample after the gap
    for cuts in ([b], [b - 1], [b + 1], list(range(7, t.size, 7))):
        s, events = det.initial_state(), []
        edges = [0, *cuts, t.size]
        for lo, hi in pairwise(edges):
            e, s = det.process(t[lo:hi], y[lo:hi], s)
            events += e
        assert events == whole
        assert np.array_equal(s.t_seated, state.t_seated)
        assert np.array_equal(s.settle_restarts, state.settle_restarts)

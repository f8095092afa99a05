"""The oracle detector's delay at a false-alarm target (skin bench delay-bound)."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
from scipy.stats import invgauss, norm

from skin.bench.delay_bound import (
    _detector_figures,
    _json_ratio,
    _quartiles,
    contact_delays,
    count_alarms,
    detection_probability,
    false_alarm_counts,
    fit_thresholds,
    lookahead,
    measure_delay_bound,
    noise_counts,
    oracle_delay,
    oracle_threshold,
)
from skin.bench.onset_why import MISS_CAUSES
from skin.bench.streams import BOUND_FALSE_ALARMS, delay_bound, simulate_stream
from skin.cli import main as skin_main
from skin.models import load_materials
from skin.models.sensors import load_sensor


def _siegmund_arl(h: float, delta: float) -> float:
    """Siegmund's approximation to the CUSUM's average run length on noise (samples)."""
    b = h + 1.166 * delta
    return (math.exp(b) - b - 1.0) / (delta**2 / 2.0)


def test_a_step_template_is_the_cusum_and_alarms_at_siegmunds_rate() -> None:
    # a constant template over every onset in the window is the CUSUM of a mean shift
    sigma, delta, h, lags = 0.5, 1.0, 3.0, 100
    rng = np.random.default_rng(3)
    samples = 200_000
    (alarms,) = false_alarm_counts(np.full(lags, delta * sigma), sigma, samples, lags, [h], rng)
    expected = samples / _siegmund_arl(h, delta)  # about 1700
    assert abs(alarms - expected) < 0.1 * expected


def test_the_threshold_set_on_noise_gives_the_target_rate_on_fresh_noise() -> None:
    # a step of 0.5 sigma at 10 Hz: the threshold for 100 false alarms per hour (so that an
    # hour of fresh noise shows the rate), checked against Siegmund's approximation too
    sigma, delta, fs = 1.0, 0.5, 10.0
    template = np.full(400, delta * sigma)
    rng = np.random.default_rng(5)
    h, lags, _ = oracle_threshold(template, sigma, fs, rng, false_alarms=100.0, budget=2e6)
    per_hour = fs * 3600.0 / _siegmund_arl(h, delta)
    assert 60.0 < per_hour < 160.0
    hours = 4.0
    (alarms,) = false_alarm_counts(template, sigma, int(hours * fs * 3600), lags, [h], rng)
    assert 0.6 * 100 * hours < alarms < 1.6 * 100 * hours


def test_a_ramp_is_found_about_when_its_information_reaches_the_threshold() -> None:
    # a ramp a j in white noise: at its true onset the log-likelihood ratio, in information
    # time u = sum(m^2) / sigma^2, is a Brownian motion with drift 1/2, which first reaches h
    # at an inverse-Gaussian time (mean 2 h, shape h^2); the GLR over onsets alarms no later
    sigma, a, h = 1.0, 0.05, 12.0
    template = a * np.arange(1, 2001)
    info = np.cumsum(template**2) / sigma**2
    u_median = float(invgauss.median(2.0 * h / h**2, scale=h**2))
    known = int(np.searchsorted(info, u_median))
    rng = np.random.default_rng(7)
    lags = int(np.searchsorted(info, 8 * h))
    delays = oracle_delay(template, sigma, h, lags, rng, repeats=200)
    assert (delays >= 0).all()
    median = float(np.median(delays))
    assert 0.8 * known <= median <= known + 1
    lorden = int(np.searchsorted(info / 2.0, h))  # information sum(m^2) / (2 sigma^2) = h
    assert abs(median - lorden) < 0.2 * lorden


def test_a_template_that_never_reaches_the_threshold_is_not_detectable_not_nan() -> None:
    sigma = 1.0
    template = np.full(50, 0.01)  # 0.0025 nats in all
    rng = np.random.default_rng(0)
    assert (oracle_delay(template, sigma, 10.0, 50, rng, repeats=5) == -1).all()
    assert _json_ratio(float("inf")) == "not detectable"
    assert _json_ratio(1.23456) == 1.235


def test_a_restarted_test_counts_each_alarm_once() -> None:
    # onsets 0..9; onset 1 alarms at 4, onset 2 at 3 (earliest), onset 6 at 8, onset 7 at 7
    alarms = np.array([-1, 4, 3, -1, -1, -1, 8, 7, -1, -1])
    assert count_alarms(alarms) == 2  # at 3, then (onsets after 3) at 7
    assert count_alarms(np.full(5, -1)) == 0
    fit = fit_thresholds([])  # a stream without a contact with a floor
    assert fit.thresholds.size == 0 and fit.b is None and fit.fitted.size == 0


def test_the_fit_carries_counts_of_an_exact_tail_to_its_threshold() -> None:
    # counts exactly hours exp(a - h) h^b: the threshold for the target comes back
    a, b, hours = 9.0, 0.5, 2.0
    hs = np.arange(3.0, 12.0, 0.5)
    runs = [{"thresholds": hs, "counts": np.round(hours * np.exp(a - hs) * hs**b * 1e3),
             "hours": hours * 1e3, "samples_per_hour": 1e6}]
    fit = fit_thresholds(runs, false_alarms=0.1)
    (h,) = fit.thresholds
    assert abs(fit.b - b) < 0.05 and fit.fitted.all()
    assert abs(a - h + b * math.log(h) - math.log(0.1)) < 0.05


def test_the_streams_templates_are_the_contacts_own_change() -> None:
    sensor = load_sensor("pid-logger")
    table = load_materials()
    stream = simulate_stream([table["aluminium"], table["pine"]], n_taxels=2, duration=120.0,
                             contacts_per_minute=2.0, seed=1, sensor=sensor)
    assert len(stream.templates) == len(stream.contacts) > 0
    sigma = stream.raw_noise * sensor.smoothing_noise_factor()
    for c, m in zip(stream.contacts, stream.templates, strict=True):
        first = math.ceil(c.onset * stream.fs)
        when = np.arange(first, first + m.size) / stream.fs - c.onset
        inside = when < c.duration
        moved = np.abs(m[inside])
        seen = float(when[np.argmax(moved >= 3 * sigma)]) if (moved >= 3 * sigma).any() \
            else float("inf")
        assert seen == c.visible_after
        assert math.isclose(float(moved.max()), c.peak_change, rel_tol=1e-9)
        # Lorden's bound recomputed from the template at the stream's rate is the contact's
        fs = stream.fs
        assert delay_bound(np.abs(m[inside]), when[inside], stream.raw_noise, fs,
                           BOUND_FALSE_ALARMS) == c.bound_after
    assert stream.raw_noise == sensor.noise_kelvin(25.0 + sensor.heated_rise)
    assert lookahead(sensor) == 7 and lookahead(load_sensor("fast-film")) == 0
    which = [k for k, c in enumerate(stream.contacts) if np.isfinite(c.visible_after)][:2]
    out = contact_delays(stream, sensor, which, np.random.default_rng(2), budget=5e5)
    assert len(out["delay_s"]) == len(which) and not np.isnan(out["delay_s"]).any()
    # one code path: the thresholds and tails it reports are `fit_thresholds`' of its runs
    fit = fit_thresholds(out["runs"])
    np.testing.assert_array_equal(out["threshold"], fit.thresholds)
    np.testing.assert_array_equal(out["tail_a"], fit.a)
    np.testing.assert_array_equal(out["tail_b"], fit.b_each)
    np.testing.assert_array_equal(out["fitted"], fit.fitted)
    assert out["b"] == fit.b
    # the smoothed sample that has seen the alarming raw sample is stamped 7 samples earlier
    np.testing.assert_allclose(
        out["delay_s"], np.maximum(out["delay_no_lookahead_s"] - 7 / stream.fs, 0.0),
        rtol=0, atol=1e-9)


def test_the_threshold_at_the_real_target_is_siegmunds() -> None:
    # a step template at 200 Hz, 0.1 false alarms per hour: the CUSUM, whose threshold for
    # ARL = 200 x 3600 / 0.1 samples Siegmund's approximation gives in closed form. Eight
    # contacts' noise runs pooled (as the bench pools a preset's contacts for b): their median
    # threshold lands within 0.5 nats of it, each within 1 (seeds 1, 2: median 0.03-0.44 off)
    fs, sigma, target = 200.0, 1.0, 0.1
    arl = fs * 3600.0 / target
    for delta in (0.5, 1.0):
        lo, hi = 1.0, 40.0
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _siegmund_arl(mid, delta) < arl else (lo, mid)
        template = np.full(int(4 * math.log(arl) / (delta**2 / 2)) + 10, delta * sigma)
        rng = np.random.default_rng(11)
        runs = [noise_counts(template, sigma, fs, rng, target) for _ in range(8)]
        hs = fit_thresholds(runs, target).thresholds
        assert abs(float(np.median(hs)) - lo) < 0.5, (delta, hs, lo)
        assert np.all(np.abs(hs - lo) < 1.0), (delta, hs, lo)


def test_the_figures_never_give_nan_when_a_quarter_of_contacts_are_not_detectable() -> None:
    values = [0.9, 1.0, 1.1, float("inf"), float("inf")]
    assert _quartiles(values) == [1.0, "not detectable"]
    assert _quartiles([]) is None
    # the detector over the oracle: over the pairs the oracle detected, the others counted
    contacts = [SimpleNamespace(visible_after=0.1) for _ in range(4)]
    res = {"detected_flags": [True, True, True, False], "delay_s": [0.2, 0.3, 0.4, None],
           "false_alarms_per_taxel_hour": 0.0}
    ratio = {0: 1.0, 1: 1.5, 2: float("inf"), 3: 1.0}
    out = _detector_figures(SimpleNamespace(contacts=contacts), res, [0, 1, 2, 3], ratio)
    assert out["detector_over_oracle_median"] == 2.0  # median of 2.0 / 1.0 and 3.0 / 1.5
    assert out["detector_over_oracle_pairs"] == 2
    assert out["oracle_not_detectable_same_contacts"] == 1
    assert out["detector_contacts"] == 3


def test_the_oracle_detects_at_least_whenever_the_known_onset_ratio_crosses() -> None:
    # a step of 0.5 sigma for 64 samples gives exactly h = 8 nats of information by its end.
    # At the true onset the log-likelihood ratio is a random walk with drift 1/8 and variance
    # 1/4 per sample, which reaches h by then with probability Phi(0) + e^h Phi(-sqrt(2 h))
    # (Brownian first passage, 0.594); the GLR maximises over onsets that include the true
    # one, so on every noise draw where that ratio crosses, the oracle alarms too
    sigma, delta, h = 1.0, 0.5, 8.0
    n = round(2.0 * h / delta**2)
    template, lags, repeats = np.full(n, delta), n, 400
    alarmed = oracle_delay(template, sigma, h, lags, np.random.default_rng(5), repeats) >= 0
    rng = np.random.default_rng(5)  # the same draws, in the order oracle_delay takes them
    known = np.zeros(repeats, dtype=bool)
    for r in range(repeats):
        x = template + rng.normal(0.0, sigma, lags - 1 + n)[lags - 1:]
        known[r] = np.max(np.cumsum(template * x - template**2 / 2.0) / sigma**2) >= h
    assert not np.any(known & ~alarmed)
    brownian = 0.5 + math.exp(h) * norm.cdf(-math.sqrt(2.0 * h))
    assert abs(known.mean() - brownian) < 0.075  # 3 standard errors of 400 draws
    assert alarmed.mean() > known.mean()
    assert detection_probability(template, sigma, h, lags, np.random.default_rng(5),
                                 repeats) == alarmed.mean()
    # far below the threshold's information: never; far above: always
    assert detection_probability(template * 0.2, sigma, h, lags, np.random.default_rng(1)) == 0
    assert detection_probability(template * 3.0, sigma, h, lags, np.random.default_rng(1)) == 1


def test_the_oracles_5sigma_contacts_are_evaluate_onsets(capsys) -> None:
    # the same stream, the same 5-sigma contacts and the same detector as `skin
    # evaluate-onset --sensor`: its detected_5sigma comes back exactly
    out = measure_delay_bound(load_sensor("paper"), seed=3, minutes=3.0, taxels=4,
                              check_hours=0.002, detector=True, budget=2e5,
                              detection_repeats=5)
    assert skin_main(["evaluate-onset", "--sensor", "paper", "--seed", "3", "--minutes", "3",
                      "--taxels", "4", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert out["contacts_5sigma"] == doc["contacts_5sigma"] > 0
    assert out["detector_detected_5sigma"] == doc["detected_5sigma"]
    # the rates with their exact intervals around them
    lo, hi = doc["detected_5sigma_ci95"]
    assert lo <= doc["detected_5sigma"] <= hi and hi - lo > 0
    lo, hi = doc["false_alarms_per_taxel_hour_ci95"]
    assert lo <= doc["false_alarms_per_taxel_hour"] < hi
    assert 0.0 <= out["oracle_detected_5sigma"] <= 1.0
    assert out["oracle_5sigma_detected_under_99"] >= out["oracle_5sigma_detected_under_half"]
    missed = out["detector_missed_5sigma"]
    assert len(missed) == round((1.0 - doc["detected_5sigma"]) * doc["contacts_5sigma"])
    assert sum(v["missed"] for v in out["detector_misses_5sigma_by_cause"].values()) \
        == len(missed)
    for row in missed:
        assert row["cause"] in MISS_CAUSES and 0.0 <= row["oracle_detection"] <= 1.0
        assert row["peak_sigmas"] > 5.0


def test_a_pid_streams_contacts_swing_from_the_setpoint() -> None:
    # The loop (`apply_dynamics`, over the whole stream) holds a PID sensor's reading at its
    # setpoint whatever moves the un-looped temperature (heater switches, room, gusts): a
    # contact's own change is eq. 5 from the setpoint through the loop and lag. It used to
    # swing from the un-looped value (median 1.6 K under the setpoint on evaluate-onset's
    # seed 0: swings a median 19 % too small).
    from dataclasses import replace

    from skin.models.sensors import apply_dynamics, contact_reading

    table = load_materials()
    # one air gap, so one contact conductance, that the test knows (as the stream draws it)
    mats = [replace(table[n], gap=(5.0, 5.0)) for n in ("aluminium", "pine", "glass")]
    h = 10.0 ** np.log10(mats[0].conductance_range[0])
    table = {m.name: m for m in mats}
    sensor = load_sensor("pid-logger")
    setpoint = 25.0 + sensor.heated_rise
    # warm: the warm-object rule (object = setpoint + margin) swings up from the setpoint too
    for disturbances, warm in ((True, 0.0), (False, 0.0), (True, 0.3)):
        stream = simulate_stream(mats, n_taxels=3, duration=240.0, seed=4, sensor=sensor,
                                 disturbances=disturbances, warm=warm)
        assert stream.contacts
        assert any(c.object_temperature > setpoint for c in stream.contacts) == (warm > 0)
        for c, m in zip(stream.contacts, stream.templates, strict=True):
            mat = table[c.material]
            since = np.arange(math.ceil(c.onset * stream.fs) - 1,
                              math.ceil(c.release * stream.fs)) / stream.fs - c.onset
            raw = contact_reading(np.maximum(since, 0.0), setpoint, c.object_temperature,
                                  mat.effusivity, sensor, h) - setpoint
            want = apply_dynamics(raw, sensor, stream.fs)[1:]
            np.testing.assert_allclose(m[:want.size], want, rtol=0, atol=1e-9)

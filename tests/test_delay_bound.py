"""The oracle detector's delay at a false-alarm target (skin bench delay-bound)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from scipy.stats import invgauss

from skin.bench.delay_bound import (
    _detector_figures,
    _json_ratio,
    _quartiles,
    contact_delays,
    count_alarms,
    false_alarm_counts,
    fit_thresholds,
    lookahead,
    noise_counts,
    oracle_delay,
    oracle_threshold,
)
from skin.bench.streams import BOUND_FALSE_ALARMS, delay_bound, simulate_stream
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

"""The oracle detector's delay at a false-alarm target (skin bench delay-bound)."""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import invgauss

from skin.bench.delay_bound import (
    _json_ratio,
    contact_delays,
    count_alarms,
    delay_bound,
    false_alarm_counts,
    fit_thresholds,
    lookahead,
    oracle_delay,
    oracle_threshold,
)
from skin.bench.streams import simulate_stream
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
    thresholds, b = fit_thresholds([])  # a stream without a contact with a floor
    assert thresholds.size == 0 and b == 0.0


def test_the_fit_carries_counts_of_an_exact_tail_to_its_threshold() -> None:
    # counts exactly hours exp(a - h) h^b: the threshold for the target comes back
    a, b, hours = 9.0, 0.5, 2.0
    hs = np.arange(3.0, 12.0, 0.5)
    runs = [{"thresholds": hs, "counts": np.round(hours * np.exp(a - hs) * hs**b * 1e3),
             "hours": hours * 1e3, "samples_per_hour": 1e6}]
    (h,), fitted = fit_thresholds(runs, false_alarms=0.1)
    assert abs(fitted - b) < 0.05
    assert abs(a - h + b * math.log(h) - math.log(0.1)) < 0.05


def test_the_streams_templates_are_the_contacts_own_change() -> None:
    sensor = load_sensor("pid-logger")
    table = load_materials()
    stream = simulate_stream([table["aluminium"], table["pine"]], n_taxels=2, duration=120.0,
                             contacts_per_minute=2.0, seed=1, sensor=sensor)
    assert len(stream.templates) == len(stream.contacts) > 0
    sigma = sensor.noise_kelvin(25.0 + sensor.heated_rise) * sensor.smoothing_noise_factor()
    for c, m in zip(stream.contacts, stream.templates, strict=True):
        first = math.ceil(c.onset * stream.fs)
        when = np.arange(first, first + m.size) / stream.fs - c.onset
        inside = when < c.duration
        moved = np.abs(m[inside])
        seen = float(when[np.argmax(moved >= 3 * sigma)]) if (moved >= 3 * sigma).any() \
            else float("inf")
        assert seen == c.visible_after
        assert math.isclose(float(moved.max()), c.peak_change, rel_tol=1e-9)
    assert lookahead(sensor) == 7 and lookahead(load_sensor("fast-film")) == 0
    which = [k for k, c in enumerate(stream.contacts) if np.isfinite(c.visible_after)][:2]
    out = contact_delays(stream, sensor, which, np.random.default_rng(2), budget=5e5)
    assert len(out["delay_s"]) == len(which) and not np.isnan(out["delay_s"]).any()


def test_a_stream_without_contacts_gives_none_figures_not_an_error() -> None:
    # one minute on two taxels of the paper sensor, seed 0: no contact at all
    out = delay_bound(load_sensor("paper"), seed=0, minutes=1.0, taxels=2, check_hours=0.01,
                      detector=True)
    assert out["contacts"] == 0 and out["contacts_with_floor"] == 0
    assert out["oracle_ratio_median"] is None and out["oracle_ratio_p25_p75"] is None
    assert out["false_alarm_check"] is None and out["detector_ratio_median"] is None
    assert out["raw_noise_k"] > 0

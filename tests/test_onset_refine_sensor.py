"""Onset refinement with the sensor's own response (loop, lag, smoothing)."""

from __future__ import annotations

import numpy as np
import pytest

from skin.models import load_materials
from skin.models.sensors import apply_dynamics, contact_reading, load_sensor, smooth
from skin.stream.onset_refine import heater_basis, refine_onset, refine_span, sensor_response


def _contact(sensor_name: str, t_on: float) -> tuple[np.ndarray, np.ndarray, object]:
    sensor = load_sensor(sensor_name)
    fs = sensor.sample_rate
    t = np.arange(0.0, t_on + 6.0, 1.0 / fs)
    alu = load_materials()["aluminium"]
    y = np.where(t > t_on, contact_reading(np.maximum(t - t_on, 0.0), 35.0, 25.0, alu.effusivity,
                                           sensor, 3000.0, 25.0), 35.0)
    return t, smooth(apply_dynamics(y, sensor, fs), sensor, fs=fs), sensor


@pytest.mark.parametrize("name", ["pid-logger", "low-cost"])
def test_the_sensor_response_dates_a_slow_sensor_contact(name: str) -> None:
    t_on = 3.0
    t, y, sensor = _contact(name, t_on)
    coarse = t_on + 0.8  # a slow sensor's detector dates the departure late
    search, horizon = refine_span(sensor)
    near = (t >= coarse - search) & (t <= coarse + horizon)
    own, _ = refine_onset(t[near], y[near], coarse, 35.0, 0.0, sensor.depth, sensor.diffusivity,
                          sensor=sensor)
    plain, _ = refine_onset(t[near], y[near], coarse, 35.0, 0.0, sensor.depth,
                            sensor.diffusivity)
    assert abs(own - t_on) < 0.03
    assert abs(plain - t_on) > 3 * abs(own - t_on)


def test_the_paper_sensor_keeps_eq_5_and_the_span() -> None:
    paper = load_sensor("paper")
    assert refine_span(paper) == (0.6, 0.6)
    assert refine_span(load_sensor("fast-film")) == (0.6, 0.6)
    assert refine_span(None) == (0.6, 0.6)
    t = np.linspace(30.0, 31.2, 241)
    rng = np.random.default_rng(3)
    y = 37.0 + 0.01 * rng.standard_normal(t.size)
    y[t > 30.4] -= 2.0 * (1 - np.exp(-(t[t > 30.4] - 30.4) / 0.3))
    a = refine_onset(t, y, 30.6, 37.0, 0.0, paper.depth, paper.diffusivity)
    b = refine_onset(t, y, 30.6, 37.0, 0.0, paper.depth, paper.diffusivity, sensor=paper)
    assert a == b


def test_the_sensor_response_is_the_step_through_loop_and_lag() -> None:
    sensor = load_sensor("pid-logger")
    lags = np.array([0.0, 0.5, 2.0, 5.0, 20.0])
    r = sensor_response(lags, np.array([np.inf]), sensor, sensor)[0]
    assert np.all(np.isfinite(r)) and r[0] == pytest.approx(0.0, abs=1e-3)
    assert r[2] > r[1] > 0  # the contact arrives through the body, the lag and the smoothing
    assert r[4] < r[3]  # and the loop takes the deviation back


@pytest.mark.parametrize("material,h", [("aluminium", 1000.0), ("pine", 3000.0),
                                        ("polyurethane_foam", 3000.0)])
@pytest.mark.parametrize("noise", [0.0, 0.3])
def test_a_heater_switched_off_at_contact_is_dated_on_time(material: str, h: float,
                                                           noise: float) -> None:
    # fast-film's heater drains the body from the contact's first instant, linearly in t,
    # while eq. 5 starts flat: eq. 5 alone dates such a contact early
    sensor = load_sensor("fast-film")
    fs = sensor.sample_rate
    t_on = 3.0004
    t = np.arange(0.0, t_on + 2.0, 1.0 / fs)
    t0, ambient = 25.0 + sensor.heated_rise, 25.0
    e = load_materials()[material].effusivity
    y = np.where(t > t_on, contact_reading(np.maximum(t - t_on, 0.0), t0, 22.0, e, sensor, h,
                                           ambient), t0)
    y = y + noise * sensor.noise_kelvin() * np.random.default_rng(4).standard_normal(t.size)
    y = smooth(apply_dynamics(y, sensor, fs), sensor, fs=fs)
    coarse = t_on + 0.05
    near = (t >= coarse - 0.6) & (t <= coarse + 0.6)
    own, _ = refine_onset(t[near], y[near], coarse, t0, 0.0, sensor.depth, sensor.diffusivity,
                          sensor=sensor)
    plain, _ = refine_onset(t[near], y[near], coarse, t0, 0.0, sensor.depth,
                            sensor.diffusivity)
    assert abs(own - t_on) <= 0.005
    if noise == 0.0:
        assert plain - t_on < -0.005


def test_the_heater_basis_is_the_drain_and_the_response() -> None:
    sensor = load_sensor("fast-film")
    lags = np.array([-0.01, 0.0, 0.05, 0.5, 3.0])
    cols = heater_basis(lags, np.array([np.inf, 30.0]), sensor, sensor)
    assert cols.shape == (2, 2, 5) and np.all(np.isfinite(cols))
    assert np.all(cols[:, :, :2] == 0.0)  # nothing before the contact (a causal average)
    # the drain, through the 8-sample average, against 1 - exp(-t / tau) averaged
    tau = sensor.reheat_time_constant
    k = np.arange(8) / sensor.sample_rate  # the average's samples back from 0.5 s
    expect = np.mean(-np.expm1(-(0.5 - k) / tau))
    assert cols[1, 0, 3] == pytest.approx(expect, rel=1e-3)
    assert cols[0, 0, 4] > cols[0, 1, 4] > 0  # a finite rate closes more slowly
    with pytest.raises(ValueError, match="off-at-contact"):
        heater_basis(lags, np.array([np.inf]), load_sensor("paper"), load_sensor("paper"))


def _heated_contact(sensor: object, material: str, h: float, t_on: float,
                    noise: float = 0.0, rng: np.random.Generator | None = None,
                    ) -> tuple[np.ndarray, np.ndarray, float]:
    """A contact with an object at the room's temperature, through the sensor's readout.

    ``noise`` scales the sensor's reading noise, drawn from ``rng`` (default: seed 5).
    """
    fs = sensor.sample_rate
    t = np.arange(0.0, t_on + 8.0, 1.0 / fs)
    t0, ambient = 25.0 + sensor.heated_rise, 25.0
    e = load_materials()[material].effusivity
    y = np.where(t > t_on, contact_reading(np.maximum(t - t_on, 0.0), t0, ambient, e, sensor, h,
                                           ambient), t0)
    rng = np.random.default_rng(5) if rng is None else rng
    y = y + noise * sensor.noise_kelvin() * rng.standard_normal(t.size)
    return t, smooth(apply_dynamics(y, sensor, fs), sensor, fs=fs), t0


@pytest.mark.parametrize("material,h", [("cardboard", 300.0), ("pine", 3000.0),
                                        ("neoprene", 3000.0), ("aluminium", 3000.0)])
def test_a_heater_left_on_during_contact_is_dated_on_time(material: str, h: float) -> None:
    # low-cost's heater stays on: its flux warms the thermistor against the contact's fall,
    # most against a foam-like object; eq. 5 through the lag alone dated these up to 80 ms
    # off, and its coarse onset, 2.5 s late, lay beyond the span the refinement searched
    sensor = load_sensor("low-cost")
    t_on = 20.013
    t, y, t0 = _heated_contact(sensor, material, h, t_on)
    coarse = t_on + 2.5
    search, horizon = refine_span(sensor)
    assert search >= 3.0  # the span covers a slow sensor's late coarse onset
    near = (t >= coarse - search) & (t <= coarse + horizon)
    onset, initial = refine_onset(t[near], y[near], coarse, t0, 0.0, sensor.depth,
                                  sensor.diffusivity, sensor=sensor)
    assert abs(onset - t_on) <= 0.015
    assert np.isfinite(initial)


def test_the_heater_basis_of_a_heater_left_on_is_its_flux() -> None:
    # the second column is the heater's flux into the sensor alone (the object's share 0),
    # in K: finite at t -> 0, nothing before the contact, growing as the flux reaches the
    # thermistor; the fit scales it by the sensor's share e_s / (e_s + e_o), within [0, 1]
    from dataclasses import replace

    from skin.models.sensors import heater_term

    sensor = load_sensor("low-cost")
    bare = replace(sensor, lag=0.0, smoothing="none")
    lags = np.array([-0.5, 0.0, 1e-9, 0.05, 1.0, 4.0])
    cols = heater_basis(lags, np.array([np.inf, 3.0]), bare, bare)
    assert cols.shape == (2, 2, 6) and np.all(np.isfinite(cols))
    assert np.all(cols[:, :, :3] == pytest.approx(0.0, abs=1e-12))
    flux = heater_term(np.array([1.0, 4.0]), 0.0, 0.0, bare)
    assert cols[1, 0, 4:] == pytest.approx(flux, rel=1e-6)
    assert 0 < cols[1, 0, 4] < cols[1, 0, 5]
    filtered = heater_basis(lags, np.array([np.inf]), sensor, sensor)
    assert np.all(np.isfinite(filtered)) and filtered[1, 0, 5] < flux[1]  # the lag holds it back


def test_a_pid_held_sensor_is_dated_without_the_detectors_slope() -> None:
    # the detector's slope at a slow sensor's coarse onset is the contact's own early
    # departure; the loop holds the sensor at its setpoint, so the refinement fits none
    sensor = load_sensor("pid-logger")
    t_on = 20.011
    t, y, t0 = _heated_contact(sensor, "glass", 3000.0, t_on)
    coarse = t_on + 0.9
    before = (t > coarse - 1.0) & (t <= coarse)
    slope = float(np.polyfit(t[before], y[before], 1)[0])  # what a smoother there reads
    assert slope < -0.01
    search, horizon = refine_span(sensor)
    near = (t >= coarse - search) & (t <= coarse + horizon)
    with_slope, _ = refine_onset(t[near], y[near], coarse, t0, slope, sensor.depth,
                                 sensor.diffusivity, sensor=sensor)
    flat, _ = refine_onset(t[near], y[near], coarse, t0, 0.0, sensor.depth, sensor.diffusivity,
                           sensor=sensor)
    assert abs(with_slope - t_on) <= 0.015
    assert with_slope == flat


@pytest.mark.parametrize("name", ["low-cost", "pid-logger", "fast-film", "paper"])
def test_a_sensor_at_ambient_with_no_contact_gives_a_finite_onset(name: str) -> None:
    # a flat reading (the sensor at the room's temperature, nothing touching): no NaN, and
    # the onset stays within the span searched
    sensor = load_sensor(name)
    t = np.arange(0.0, 30.0, 1.0 / sensor.sample_rate)
    y = np.full(t.size, 25.0)
    search, horizon = refine_span(sensor)
    coarse = 20.0
    near = (t >= coarse - search) & (t <= coarse + horizon)
    onset, initial = refine_onset(t[near], y[near], coarse, 25.0, 0.0, sensor.depth,
                                  sensor.diffusivity, sensor=sensor)
    assert np.isfinite(onset) and coarse - search - 0.005 <= onset <= coarse  # a grid step
    assert initial == pytest.approx(25.0)


def _through_a_gust(t: np.ndarray, y: np.ndarray, t_on: float, depth: tuple[float, float],
                    flutter: float, sensor: object, rng: np.random.Generator) -> np.ndarray:
    """Return ``y`` with a gust (depth drawn in ``depth``, K, starting 0-2 s before ``t_on``,
    rising over 1-4 s) and the air's flutter (sd ``flutter`` before the 0.5 s low-pass),
    both through the sensor's dynamics and smoothing."""
    from scipy.signal import lfilter

    fs = sensor.sample_rate
    gust = -rng.uniform(*depth) * -np.expm1(-np.maximum(t - t_on - rng.uniform(-2.0, 0.0),
                                                         0.0) / rng.uniform(1.0, 4.0))
    a = np.exp(-1.0 / (0.5 * fs))
    air = lfilter([1 - a], [1, -a], rng.normal(0, flutter, t.size)) * np.sqrt(fs)
    return y + smooth(apply_dynamics(gust + air, sensor, fs), sensor, fs=fs)


def test_a_slow_sensor_is_dated_through_a_gust() -> None:
    # a gust cooling the face over seconds, and the air's flutter, during a pid-logger
    # contact: fitted as white noise the slow cooling passes for the contact's own slow
    # departure and dates it 100-350 ms early; whitened by the residual's own lag-1
    # autocorrelation it is dated within tens of ms
    sensor = load_sensor("pid-logger")
    fs = sensor.sample_rate
    rng = np.random.default_rng(7)
    search, horizon = refine_span(sensor)
    errors, holed = [], []
    for _ in range(10):
        t_on = 20.0 + rng.uniform(0, 1 / fs)
        t, y, t0 = _heated_contact(sensor, "glass", 3000.0, t_on)
        y = _through_a_gust(t, y, t_on, (0.04, 0.2), 0.0072, sensor, rng)
        coarse = t_on + 0.9
        near = (t >= coarse - search) & (t <= coarse + horizon)
        onset, _ = refine_onset(t[near], y[near], coarse, t0, 0.0, sensor.depth,
                                sensor.diffusivity, sensor=sensor)
        errors.append(onset - t_on)
        # a fifth of the samples lost: the whitening pairs no sample across a hole
        y = y.copy()
        y[rng.random(t.size) < 0.2] = np.nan
        onset, _ = refine_onset(t[near], y[near], coarse, t0, 0.0, sensor.depth,
                                sensor.diffusivity, sensor=sensor)
        holed.append(onset - t_on)
    assert np.median(np.abs(errors)) < 0.07
    assert np.median(np.abs(holed)) < 0.07


@pytest.mark.parametrize("material,h,within", [("glass", 3000.0, 0.25), ("brick", 173.0, 0.7)])
def test_a_slow_heated_sensor_is_dated_through_a_gust(material: str, h: float,
                                                      within: float) -> None:
    # low-cost's heater stays on during contact (its flux a second column): a gust and the
    # air's flutter through its lag and low-pass leave a residual far from white, and a free
    # closing rate trades with the onset and dates it early (before: median |error| 661 ms on
    # glass, 1072 ms on brick, whose contact does close slowly, each contact with its own
    # noise draw); whitened by the residual's lag-1 autocorrelation, the rate kept only when
    # Schwarz's criterion asks on the whitened samples: 172 and 432 ms
    sensor = load_sensor("low-cost")
    fs = sensor.sample_rate
    rng = np.random.default_rng(11)
    search, horizon = refine_span(sensor)
    errors = []
    for _ in range(12):
        t_on = 20.0 + rng.uniform(0, 1 / fs)
        t, y, t0 = _heated_contact(sensor, material, h, t_on, noise=1.0, rng=rng)
        y = _through_a_gust(t, y, t_on, (0.1, 0.5), 0.02, sensor, rng)
        coarse = t_on + 2.0
        near = (t >= coarse - search) & (t <= coarse + horizon)
        onset, _ = refine_onset(t[near], y[near], coarse, t0, 0.0, sensor.depth,
                                sensor.diffusivity, sensor=sensor)
        errors.append(onset - t_on)
    assert np.median(np.abs(errors)) < within

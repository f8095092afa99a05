"""Onset refinement with the sensor's own response (loop, lag, smoothing)."""

from __future__ import annotations

import numpy as np
import pytest

from skin.models import load_materials
from skin.models.sensors import apply_dynamics, contact_reading, load_sensor, smooth
from skin.stream.onset_refine import refine_onset, refine_span, sensor_response


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


@pytest.mark.parametrize("name", ["paper", "fast-film"])
def test_a_fast_sensor_keeps_eq_5_and_the_span(name: str) -> None:
    paper = load_sensor(name)  # fast-film's 8 ms moving average is below the grid's scale
    assert refine_span(paper) == (0.6, 0.6)
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

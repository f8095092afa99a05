"""Release dating after the fact (`skin.stream.release_refine.refine_release`)."""

from __future__ import annotations

import numpy as np
import pytest

from skin.models.sensors import apply_dynamics, contact_reading, load_sensor, smooth
from skin.stream.release_refine import filter_delay, refine_release

GLASS, STEEL, FOAM, COPPER = 1500.0, 7000.0, 30.0, 37000.0


def touch(sensor, duration, e_obj=GLASS, t_obj=25.0, noise=0.0, seed=0, after=1.0):
    """A contact from t = 0 to ``duration`` as the simulator makes it, then the free response.

    In contact the thermistor follows eq. 5 (with the heater's own term); from the release
    on (its first sample read free) the body relaxes towards its heated state with its own
    time constant (the PID loop's for a held heater); then the sensor's loop, lag and
    smoothing.
    """
    fs = sensor.sample_rate
    t = np.arange(round(-0.5 * fs), round((duration + after) * fs)) / fs
    heated = 25.0 + sensor.heated_rise
    y = np.full(t.size, heated)
    k1 = round(duration * fs)
    inside = (t >= 0) & (np.arange(t.size) < np.searchsorted(t, 0) + k1)
    y[inside] = contact_reading(t[inside], heated, t_obj, e_obj, sensor, ambient=25.0)
    last = y[inside][-1]
    tau = sensor.control_time if sensor.heater == "pid" else sensor.reheat_time_constant
    free = np.flatnonzero(t >= 0)[k1:]
    y[free] = heated + (last - heated) * np.exp(-(np.arange(free.size) + 1) / (fs * tau))
    y = smooth(apply_dynamics(y, sensor), sensor)
    return t, y + np.random.default_rng(seed).normal(0.0, noise, t.size)


def noise(sensor):
    """The sensor's reading noise at its heated temperature, K."""
    return sensor.noise_kelvin(25.0 + sensor.heated_rise)


def refined(sensor, t, y, coarse):
    return refine_release(t, y, 0.0, coarse, sensor.depth, sensor.diffusivity, sensor=sensor)


@pytest.mark.parametrize("duration", [0.3, 0.6, 1.5])
@pytest.mark.parametrize("e_obj", [GLASS, STEEL])
def test_clean_release_within_a_sample(duration, e_obj):
    s = load_sensor("paper")
    t, y = touch(s, duration, e_obj)
    for late in (0.05, 0.08, 0.12):
        assert abs(refined(s, t, y, duration + late) - duration) <= 1.01 / s.sample_rate
    # a date already close: kept, or moved closer
    assert abs(refined(s, t, y, duration + 0.02) - duration) <= 0.0201


def test_noisy_release_within_a_few_samples():
    s = load_sensor("paper")
    errors = []
    for seed in range(12):
        duration = (0.3, 0.6, 1.0)[seed % 3]
        t, y = touch(s, duration, (GLASS, STEEL)[seed % 2], noise=noise(s), seed=seed)
        errors.append(refined(s, t, y, duration + 0.085) - duration)
    errors = np.abs(errors)
    assert np.median(errors) <= 1.01 / s.sample_rate  # the detector's was 0.085 s
    assert errors.max() <= 3.01 / s.sample_rate


@pytest.mark.parametrize("preset", ["fast-film", "pid-logger", "low-cost"])
def test_other_sensors_no_worse_than_the_detector(preset):
    # the detector dates the release after the filters' delay, and later still
    s = load_sensor(preset)
    stretch = max(1.0, s.response_time / load_sensor("paper").response_time)
    late = filter_delay(s) + 0.08 * stretch
    errors = []
    for seed in range(4):
        duration = 1.0 * stretch
        t, y = touch(s, duration, STEEL, noise=noise(s), seed=seed, after=2 * late + 1.0)
        got = refined(s, t, y, duration + late)
        assert np.isfinite(got)
        errors.append(abs(got - duration))
    assert np.median(errors) <= late


def test_cannot_tell_keeps_the_detectors_date():
    s = load_sensor("paper")
    # too short: a handful of samples
    t, y = touch(s, 0.02, GLASS)
    assert refined(s, t, y, 0.03) == 0.03
    # no change: the contact goes on through the coarse release and after it
    t, y = touch(s, 5.0, GLASS, noise=noise(s))
    assert refined(s, t, y, 1.2) == 1.2
    # a flat reading (an object at the sensor's temperature), noisy
    t = np.arange(0, 400) / s.sample_rate
    y = 40.0 + np.random.default_rng(1).normal(0.0, noise(s), t.size)
    assert refined(s, t, y, 1.0) == 1.0
    # release before the onset, NaN dates
    assert refined(s, t, y, -1.0) == -1.0
    assert np.isnan(refine_release(t, y, 0.0, np.nan, s.depth, s.diffusivity))


def test_extreme_inputs_give_no_nan():
    s = load_sensor("paper")
    for e_obj in (FOAM, COPPER):
        t, y = touch(s, 0.5, e_obj, t_obj=-20.0)
        assert np.isfinite(refined(s, t, y, 0.6))
    t, y = touch(s, 0.5, COPPER)
    y[::3] = np.nan  # lost samples
    assert np.isfinite(refined(s, t, y, 0.58))
    assert np.isfinite(refined(s, t, np.full(t.size, 1e6), 0.6))  # ADC at full scale
    assert np.isfinite(refined(s, t, np.zeros(t.size), 0.6))
    assert refined(s, t[:0], y[:0], 0.6) == 0.6


def test_filter_delay():
    assert filter_delay(load_sensor("paper")) == 0.0
    fast = load_sensor("fast-film")
    assert filter_delay(fast) == pytest.approx((fast.smoothing_window - 1) / 2 / 1000.0)
    assert filter_delay(load_sensor("low-cost")) > load_sensor("low-cost").lag


def test_a_short_touch_onset_is_fitted_again_up_to_the_refined_release():
    # the detector dates a short touch's release late; the samples past the contact that the
    # onset's fit then sees pull the onset early. `refine_member` fits it again up to the
    # refined release.
    from skin.stream.onset_refine import refine_onset
    from skin.stream.tracking import TaxelSamples, refine_member

    s = load_sensor("paper")
    fs = s.sample_rate
    depth, alpha = np.array([s.depth]), np.array([s.diffusivity])
    first, again = [], []
    for seed in range(12):
        duration = (0.3, 0.4, 0.5)[seed % 3]
        t, y = touch(s, duration, noise=noise(s), seed=seed)
        coarse, late = 0.07, duration + 0.09  # the detector's onset and release
        keep = t >= coarse - 0.6
        member = TaxelSamples(index=0, coarse=coarse, baseline=25.0 + s.heated_rise,
                              slope=0.0, release=late, end=late, time=t[keep],
                              temperature=y[keep], ambient=np.full(keep.sum(), 25.0))
        upto = t[keep] <= late
        onset, _ = refine_onset(t[keep][upto], y[keep][upto], coarse, 25.0 + s.heated_rise,
                                0.0, s.depth, s.diffusivity, sensor=s)
        first.append(onset)
        onset, _, end = refine_member(member, depth, alpha, sensor=s)
        assert end < late and np.isfinite(onset)
        again.append(onset)
    assert np.median(np.abs(again)) <= 1.5 / fs
    assert np.median(np.abs(again)) < np.median(np.abs(first))

import numpy as np
import pytest

from skin.formats.layout import Board
from skin.models.physics import (
    SensorConstants,
    contact_temperature,
    contact_trace,
    depth_response,
    effusivity,
    effusivity_estimates,
    heated_temperature,
    thermistor_temperature,
)

AMBIENT = 25.0
SENSOR = SensorConstants()
E_ALUMINIUM = 80 / np.sqrt(3.55e-5)
E_PINE = 0.15 / np.sqrt(2.05e-7)
E_COPPER = float(effusivity(401, 8933, 385))
E_FOAM = float(effusivity(0.026, 50, 1450))


def reading(t, e_object, t_object=AMBIENT, t_sensor=None):
    """Noise-free thermistor reading t seconds after touching an object of effusivity e_object."""
    if t_sensor is None:
        t_sensor = heated_temperature(AMBIENT, SENSOR)
    surface = contact_temperature(t_sensor, t_object, SENSOR.effusivity, e_object)
    return thermistor_temperature(t, t_sensor, surface, SENSOR)


def test_heated_temperature():
    assert heated_temperature(AMBIENT, SENSOR) == pytest.approx(38.963, abs=1e-3)
    assert heated_temperature(np.array([20.0, 30.0]), SENSOR) == pytest.approx(
        [33.963, 43.963], abs=1e-3
    )


def test_sensor_constants_match_board_defaults():
    assert SensorConstants.from_board(Board()) == SENSOR
    assert SENSOR.effusivity == pytest.approx(0.0349 / np.sqrt(2.796e-9))


@pytest.mark.parametrize(
    ("e_object", "t", "expected"),
    [(E_ALUMINIUM, 0.5, 37.229), (E_ALUMINIUM, 2.5, 32.327), (E_PINE, 2.5, 36.636)],
)
def test_paper_readings(e_object, t, expected):
    assert reading(t, e_object) == pytest.approx(expected, abs=1e-3)


def test_contact_temperature_lies_between():
    t_sensor = heated_temperature(AMBIENT, SENSOR)
    for e in (E_FOAM, E_PINE, E_ALUMINIUM, E_COPPER):
        surface = contact_temperature(t_sensor, AMBIENT, SENSOR.effusivity, e)
        assert AMBIENT < surface < t_sensor
    equal = contact_temperature(t_sensor, AMBIENT, SENSOR.effusivity, SENSOR.effusivity)
    assert equal == pytest.approx((t_sensor + AMBIENT) / 2)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("h", [np.inf, 3000.0, 0.0])
def test_an_object_of_infinite_effusivity_takes_the_limit(h):
    # issue 20 item 8: eq. 3 was inf / inf = NaN; the limit holds the surface at T_obj
    t_sensor = float(heated_temperature(AMBIENT, SENSOR))
    assert contact_temperature(t_sensor, AMBIENT, SENSOR.effusivity, np.inf) == AMBIENT
    assert contact_temperature(t_sensor, AMBIENT, SENSOR.effusivity, 0.0) == t_sensor
    t = np.array([0.0, 1e-3, 0.1, 1.0, 10.0])
    limit = contact_trace(t, t_sensor, AMBIENT, np.inf, SENSOR, h)
    assert np.all(np.isfinite(limit))
    near = contact_trace(t, t_sensor, AMBIENT, 1e15, SENSOR, h)
    np.testing.assert_allclose(limit, near, atol=1e-9)
    # and per trial, an infinite effusivity beside finite ones
    batch = contact_trace(t, t_sensor, AMBIENT, np.array([[E_PINE], [np.inf]]), SENSOR, h)
    np.testing.assert_allclose(batch[1], limit, atol=0)
    np.testing.assert_allclose(batch[0], contact_trace(t, t_sensor, AMBIENT, E_PINE, SENSOR, h))


def test_depth_response_before_contact_is_zero():
    assert np.all(depth_response(np.array([-1.0, -1e-9, 0.0]), SENSOR) == 0.0)


def test_depth_response_at_zero_is_not_nan():
    with np.errstate(all="raise"):
        value = depth_response(0.0, SENSOR)
    assert value == 0.0


def test_depth_response_tends_to_one_and_is_monotonic():
    t = np.logspace(-5, 4, 500)
    r = depth_response(t, SENSOR)
    assert np.all(np.isfinite(r))
    assert np.all((r >= 0) & (r <= 1))
    assert np.all(np.diff(r) >= 0)
    assert r[-1] > 0.99
    assert depth_response(1e9, SENSOR) == pytest.approx(1.0, abs=1e-4)


@pytest.mark.parametrize(
    "e_object", [E_ALUMINIUM, E_PINE, E_COPPER, E_FOAM], ids=["aluminium", "pine", "copper", "foam"]
)
def test_estimates_recover_effusivity(e_object):
    t = np.arange(1, 501) / 200.0
    t_sensor = float(heated_temperature(AMBIENT, SENSOR))
    t_valid, e = effusivity_estimates(t, reading(t, e_object), t_sensor, AMBIENT, SENSOR)
    assert len(e) > 400
    assert np.all(np.isin(t_valid, t))
    assert np.all(np.isfinite(e))
    assert np.max(np.abs(e / e_object - 1)) < 1e-6


def test_estimates_drop_early_samples():
    t = np.array([0.0, 1e-4, 0.5, 1.0])
    t_sensor = float(heated_temperature(AMBIENT, SENSOR))
    t_valid, e = effusivity_estimates(t, reading(t, E_PINE), t_sensor, AMBIENT, SENSOR)
    assert 1e-4 not in t_valid and 0.0 not in t_valid
    assert list(t_valid) == [0.5, 1.0]
    assert np.all(np.isfinite(e))


def test_estimates_drop_non_finite_readings():
    t = np.arange(1, 201) / 200.0
    t_sensor = float(heated_temperature(AMBIENT, SENSOR))
    y = reading(t, E_PINE)
    y[10], y[20] = np.nan, np.inf
    t_valid, e = effusivity_estimates(t, y, t_sensor, AMBIENT, SENSOR)
    assert t[10] not in t_valid and t[20] not in t_valid
    assert np.all(np.isfinite(e)) and np.all(e > 0)


def test_estimates_empty_when_sensor_at_object_temperature():
    t = np.arange(1, 501) / 200.0
    y = np.full_like(t, AMBIENT)
    t_valid, e = effusivity_estimates(t, y, AMBIENT, AMBIENT, SENSOR)
    assert t_valid.size == 0 and e.size == 0


def test_noisy_pine_median_is_close():
    rng = np.random.default_rng(1234)
    t = np.arange(1, 501) / 200.0  # 2.5 s at 200 Hz
    t_sensor = float(heated_temperature(AMBIENT, SENSOR))
    y = reading(t, E_PINE) + rng.normal(0.0, 0.02, t.size)
    _, e = effusivity_estimates(t, y, t_sensor, AMBIENT, SENSOR)
    assert e.size > 100
    assert np.all(np.isfinite(e)) and np.all(e > 0)
    assert abs(np.median(np.log10(e)) - np.log10(E_PINE)) < 0.05

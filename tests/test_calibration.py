import math

import numpy as np
import pytest

from skin.formats.layout import load_layout
from skin.stream.calibration import (
    KELVIN,
    TAXEL_OPEN,
    TAXEL_SATURATED,
    Calibration,
    ambient_from_counts,
    ambient_to_counts,
)

N_TAXELS = 72


@pytest.fixture(scope="module")
def cal() -> Calibration:
    return Calibration.from_layout(load_layout("arm"))


def test_from_layout_has_one_value_per_taxel(cal):
    for field in ("c0", "c1", "divider_resistor", "supply_voltage", "adc_reference", "adc_max"):
        assert getattr(cal, field).shape == (N_TAXELS,)
    assert np.all(cal.adc_max == 1023)
    assert "arm.toml" in cal.source


def test_round_trip_temperature_counts_temperature(cal):
    temps = np.linspace(20.0, 60.0, 401)[:, None] * np.ones(N_TAXELS)
    back, status = cal.temperature(cal.counts(temps))
    assert np.all(status == 0)
    assert np.max(np.abs(back - temps)) < 1e-9


def test_paper_equations_at_25_c(cal):
    resistance = math.exp((1 / 298.15 - 9.5594e-4) / 2.6181e-4)
    volts = 5.06 * 668 / (668 + resistance)
    expected = 1023 * volts / 1.1
    counts = cal.counts(np.full(N_TAXELS, 25.0))
    assert counts == pytest.approx(np.full(N_TAXELS, expected), rel=1e-12)
    temp, status = cal.temperature(np.full(N_TAXELS, expected))
    assert temp == pytest.approx(np.full(N_TAXELS, 25.0), abs=1e-9)
    assert np.all(status == 0)


def test_paper_equations_from_counts(cal):
    counts = 512
    volts = counts / 1023 * 1.1
    resistance = 668 * (5.06 / volts - 1)
    expected = 1 / (9.5594e-4 + 2.6181e-4 * math.log(resistance)) - 273.15
    temp, _ = cal.temperature(np.full(N_TAXELS, counts))
    assert temp == pytest.approx(np.full(N_TAXELS, expected), rel=1e-12)
    assert KELVIN == 273.15


def test_zero_counts_is_open(cal):
    counts = np.full(N_TAXELS, 500)
    counts[3] = 0
    temp, status = cal.temperature(counts)
    assert np.isnan(temp[3])
    assert status[3] == TAXEL_OPEN
    assert np.all(np.isfinite(np.delete(temp, 3)))
    assert np.all(np.delete(status, 3) == 0)


def test_full_scale_is_saturated(cal):
    counts = np.full(N_TAXELS, 500)
    counts[7] = 1023
    temp, status = cal.temperature(counts)
    assert np.isnan(temp[7])
    assert status[7] == TAXEL_SATURATED
    assert np.all(np.isfinite(np.delete(temp, 7)))
    assert np.all(np.delete(status, 7) == 0)


def test_status_dtype_and_flags_are_distinct(cal):
    _, status = cal.temperature(np.zeros(N_TAXELS))
    assert status.dtype == np.uint8
    assert TAXEL_OPEN != TAXEL_SATURATED
    assert TAXEL_OPEN & TAXEL_SATURATED == 0


def test_every_inner_count_is_finite_and_monotonic(cal):
    counts = np.arange(1, 1023)[:, None] * np.ones(N_TAXELS)
    temp, status = cal.temperature(counts)
    assert np.all(np.isfinite(temp))
    assert np.all(status == 0)
    assert np.all(np.diff(temp, axis=0) > 0)


def test_vectorised_over_samples_and_taxels(cal):
    rng = np.random.default_rng(0)
    counts = rng.integers(0, 1024, size=(50, N_TAXELS))
    counts[0, 0], counts[1, 1] = 0, 1023
    temp, status = cal.temperature(counts)
    assert temp.shape == status.shape == (50, N_TAXELS)
    assert np.array_equal(np.isnan(temp), status != 0)
    assert np.array_equal(status == TAXEL_OPEN, counts == 0)
    assert np.array_equal(status == TAXEL_SATURATED, counts == 1023)
    for i, j in [(2, 5), (10, 40), (49, 71)]:
        if status[i, j] == 0:
            single, _ = cal.temperature(np.full(N_TAXELS, counts[i, j]))
            assert temp[i, j] == single[j]
    assert cal.counts(np.full((4, N_TAXELS), 30.0)).shape == (4, N_TAXELS)


def test_range_spans_the_round_trip_interval(cal):
    lo, hi = cal.range()
    assert np.all(lo < 20.0)
    assert np.all(hi > 60.0)


@pytest.mark.parametrize("temp", [0.0, 18.5, 25.0, 37.2, 99.0])
def test_ambient_round_trip(temp):
    counts = ambient_to_counts(temp)
    assert isinstance(counts, int)
    assert abs(ambient_from_counts(counts) - temp) <= 0.5 * 110.0 / 1023 + 1e-12


def test_ambient_counts_values():
    assert ambient_from_counts(0) == 0.0
    assert ambient_from_counts(1023) == pytest.approx(110.0)
    assert ambient_to_counts(25.0) == round(0.25 / 1.1 * 1023)
    for counts in (0, 1, 232, 1023):
        assert ambient_to_counts(ambient_from_counts(counts)) == counts


def test_ambient_to_counts_clips():
    assert ambient_to_counts(-10.0) == 0
    assert ambient_to_counts(500.0) == 1023

"""Per-taxel calibration: ADC counts to deg C through the thermistor divider (paper eqs. 7-8).

The thermistor ``Rth`` and the reference resistor ``R_REF`` form a divider from ``V+``; the
ADC reads the voltage across ``R_REF``::

    V = counts / adc_max * V_REF,  Rth = R_REF (V+ / V - 1),  1/T = C0 + C1 ln Rth + C2 ln^3 Rth.

The paper's two-term Steinhart-Hart form is the default; a per-taxel calibration
(`skin.formats.calibration_file`) may add the full form's cubic term C2.

Counts at 0 (no current: open thermistor or wire) and at full scale (ADC saturated: shorted
thermistor, or hotter than the range) have no temperature: they are flagged per taxel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skin.formats.layout import Layout

KELVIN = 273.15

# Per-taxel status bits returned by Calibration.temperature
TAXEL_OPEN = 1 << 0
TAXEL_SATURATED = 1 << 1
TAXEL_MISSING = 1 << 2


@dataclass(frozen=True)
class Calibration:
    """Vectorised counts <-> temperature conversion for all taxels of a layout.

    Each attribute is an array with one value per taxel, in layout order.
    """

    c0: np.ndarray
    c1: np.ndarray
    divider_resistor: np.ndarray
    supply_voltage: np.ndarray
    adc_reference: np.ndarray
    adc_max: np.ndarray
    source: str = "nominal board constants"
    c2: np.ndarray | float = 0.0

    @classmethod
    def from_layout(cls, layout: Layout) -> Calibration:
        """Build the nominal calibration from each taxel's board constants."""
        return cls(
            c0=layout.board_array("thermistor_c0"),
            c1=layout.board_array("thermistor_c1"),
            divider_resistor=layout.board_array("divider_resistor"),
            supply_voltage=layout.board_array("supply_voltage"),
            adc_reference=layout.board_array("adc_reference"),
            adc_max=layout.board_array("adc_max"),
            source=f"nominal constants of {layout.source}",
        )

    def temperature(self, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Convert ADC counts to deg C.

        Parameters
        ----------
        counts : array_like, shape (..., n_taxels)
            Raw ADC counts.

        Returns
        -------
        temperature : numpy.ndarray
            deg C; NaN exactly where ``status`` is non-zero.
        status : numpy.ndarray of uint8
            ``TAXEL_OPEN`` where counts <= 0, ``TAXEL_SATURATED`` where counts >= full scale,
            ``TAXEL_MISSING`` where counts are NaN (the taxel's board sent no frame).
        """
        c = np.asarray(counts, dtype=float)
        status = (np.where(c <= 0, TAXEL_OPEN, 0) | np.where(c >= self.adc_max, TAXEL_SATURATED, 0)
                  | np.where(np.isnan(c), TAXEL_MISSING, 0))
        status = status.astype(np.uint8)
        ok = status == 0
        v = np.where(ok, c, 1.0) / self.adc_max * self.adc_reference
        r = self.divider_resistor * (self.supply_voltage / v - 1.0)
        ok &= r > 0  # V above V+ cannot come from the divider
        status = np.where(ok | (status != 0), status, TAXEL_SATURATED).astype(np.uint8)
        ln_r = np.log(np.where(ok, r, 1.0))
        inv_t = self.c0 + self.c1 * ln_r + self.c2 * ln_r**3
        temp = np.where(ok, 1.0 / inv_t - KELVIN, np.nan)
        return temp, status

    def counts(self, temperature: np.ndarray) -> np.ndarray:
        """Convert deg C to (real-valued, unrounded) ADC counts: the inverse of `temperature`."""
        t = np.asarray(temperature, dtype=float) + KELVIN
        ln_r = (1.0 / t - self.c0) / self.c1
        c2 = np.asarray(self.c2, dtype=float)
        if np.any(c2 != 0):  # Newton on the cubic; the two-term root is a close start
            for _ in range(20):
                f = self.c0 + self.c1 * ln_r + c2 * ln_r**3 - 1.0 / t
                ln_r = ln_r - f / (self.c1 + 3.0 * c2 * ln_r**2)
        r = np.exp(ln_r)
        v = self.supply_voltage * self.divider_resistor / (self.divider_resistor + r)
        return v / self.adc_reference * self.adc_max

    def range(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the (lowest, highest) measurable temperature per taxel, deg C."""
        lo, _ = self.temperature(np.ones_like(self.adc_max))
        hi, _ = self.temperature(self.adc_max - 1)
        return lo, hi


def ambient_from_counts(counts: float, adc_max: int = 1023, adc_reference: float = 1.1) -> float:
    """Convert an LM35 reading (10 mV per deg C) to deg C."""
    return float(counts) / adc_max * adc_reference * 100.0


def ambient_to_counts(temperature: float, adc_max: int = 1023, adc_reference: float = 1.1) -> int:
    """Convert deg C to the LM35's ADC counts (rounded, clipped to the ADC range)."""
    return int(np.clip(round(temperature / 100.0 / adc_reference * adc_max), 0, adc_max))


def fit_steinhart_hart(resistance: np.ndarray, temperature: np.ndarray,
                       terms: int = 2) -> np.ndarray:
    """Fit Steinhart-Hart coefficients to thermistor readings at reference temperatures.

    Parameters
    ----------
    resistance : array_like
        Thermistor resistance at each reference, ohm.
    temperature : array_like
        The reference temperatures, deg C.
    terms : int
        2: ``1/T = C0 + C1 ln R`` (the paper's form; at least two references); 3: the full
        form with ``C2 ln^3 R`` (at least three references).

    Returns
    -------
    numpy.ndarray
        ``[C0, C1, C2]`` (C2 = 0 for two terms).

    Raises
    ------
    ValueError
        Too few distinct references for the form, or a non-positive resistance.
    """
    r = np.asarray(resistance, dtype=float)
    t = np.asarray(temperature, dtype=float) + KELVIN
    if terms not in (2, 3):
        raise ValueError(f"terms must be 2 or 3, got {terms}")
    if r.shape != t.shape or r.ndim != 1:
        raise ValueError("resistance and temperature must be 1-D arrays of one length")
    if np.any(~np.isfinite(r)) or np.any(r <= 0):
        raise ValueError("every resistance must be positive and finite")
    distinct = np.unique(np.round(t, 2)).size
    if distinct < terms:
        raise ValueError(f"the {terms}-term form needs at least {terms} distinct reference "
                         f"temperatures, got {distinct}")
    ln_r = np.log(r)
    cols = [np.ones_like(ln_r), ln_r] + ([ln_r**3] if terms == 3 else [])
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), 1.0 / t, rcond=None)
    return np.concatenate([coef, np.zeros(3 - coef.size)])


def resistance_from_counts(counts: np.ndarray, divider_resistor: float, supply_voltage: float,
                           adc_reference: float, adc_max: float) -> np.ndarray:
    """Thermistor resistance from ADC counts through the divider (eq. 8), ohm."""
    v = np.asarray(counts, dtype=float) / adc_max * adc_reference
    return divider_resistor * (supply_voltage / v - 1.0)


def thermistor_recovery(n_taxels: int = 20, references: tuple[float, ...] = (20.0, 30.0, 40.0),
                        readings: int = 8, r25_tolerance: float = 0.03,
                        b_tolerance: float = 0.01, terms: int = 2, seed: int = 0) -> dict:
    """Run simulated thermistor calibrations: how well `fit_steinhart_hart` recovers them.

    Each taxel's thermistor differs from the paper's by up to ``r25_tolerance`` in its
    resistance at 25 C and ``b_tolerance`` in its B value (typical NTC tolerances). At each
    reference the skin is read ``readings`` times through the paper's divider and 10-bit ADC
    (0.5 LSB of noise, rounded) and the mean counts are fitted.

    Returns
    -------
    dict
        Median and p95 over taxels of the largest temperature error over 25-45 C, K, with the
        nominal coefficients and with the fitted ones.
    """
    from skin.summary import median_p95

    rng = np.random.default_rng(seed)
    one = np.ones(1)
    board = dict(divider_resistor=668.0 * one, supply_voltage=5.06 * one,
                 adc_reference=1.1 * one, adc_max=1023.0 * one)
    c0, c1 = 9.5594e-4, 2.6181e-4
    r25 = np.exp((1.0 / (25.0 + KELVIN) - c0) / c1)
    check = np.linspace(25.0, 45.0, 41)
    nominal_err, fitted_err = [], []
    for _ in range(n_taxels):
        b = (1.0 / c1) * (1.0 + rng.uniform(-b_tolerance, b_tolerance))
        r = r25 * (1.0 + rng.uniform(-r25_tolerance, r25_tolerance))
        t1 = 1.0 / b
        true = Calibration(c0=(1.0 / (25.0 + KELVIN) - t1 * np.log(r)) * one, c1=t1 * one,
                           **board)
        counts = []
        for ref in references:
            raw = true.counts(np.full(readings, ref)) + rng.normal(0.0, 0.5, readings)
            counts.append(np.mean(np.rint(raw)))
        res = resistance_from_counts(np.array(counts), 668.0, 5.06, 1.1, 1023.0)
        coef = fit_steinhart_hart(res, np.array(references), terms)
        fitted = Calibration(c0=coef[0] * one, c1=coef[1] * one, c2=coef[2] * one, **board)
        nominal = Calibration(c0=c0 * one, c1=c1 * one, **board)
        x = true.counts(check)
        nominal_err.append(float(np.max(np.abs(nominal.temperature(x)[0] - check))))
        fitted_err.append(float(np.max(np.abs(fitted.temperature(x)[0] - check))))

    return {"taxels": n_taxels, "references": list(references), "readings": readings,
            "terms": terms, "nominal_max_error_k": median_p95(nominal_err),
            "fitted_max_error_k": median_p95(fitted_err)}

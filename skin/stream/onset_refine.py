"""Date a contact onset precisely by fitting the heated sensor's contact response.

The streaming detector (`skin.stream.onset`) recognises a contact some hundred milliseconds after it
began and dates it coarsely; the classifiers align each taxel's window on its onset, so
`refine_onset` fits the thermistor's response (the paper's eq. 5, or a contact that closes at
a finite rate) to the samples around the coarse onset.
"""

from __future__ import annotations

import numpy as np

#: Contact closing rates H = h (1/e_s + 1/e_o) tried by `refine_onset`, s^-0.5 (inf: perfect).
RATES = (np.inf, 300.0, 100.0, 30.0, 10.0, 3.0, 1.0, 0.3)


def refine_onset(
    times: np.ndarray,
    temperature: np.ndarray,
    coarse: float,
    baseline: float,
    slope: float,
    depth: float,
    diffusivity: float,
    search: float = 0.6,
    step: float = 0.005,
    rates: tuple[float, ...] = RATES,
    horizon: float = 0.6,
) -> tuple[float, float]:
    """Date a contact onset by fitting the heated sensor's contact response.

    Before the onset the reading follows the baseline ``baseline + slope (t - coarse)``; after
    it, ``T0 + D R(t - t0; H)`` with T0 the baseline at t0, ``R`` the thermistor's response to
    a contact whose conductance closes at rate H (`skin.models.physics.contact_response`; eq.
    5's ``erfc`` for perfect contact) and D fitted by least squares. Candidate onsets lie on a
    grid from ``coarse - search`` to ``coarse``, candidate rates in ``rates``; the pair with
    the smallest squared error over the samples up to ``coarse + horizon`` wins. Fitting the
    rate matters: a contact through an air gap starts slowly, and perfect-contact fits date it
    tens of milliseconds late.

    Parameters
    ----------
    times, temperature : numpy.ndarray
        The taxel's samples around the contact (NaN samples are ignored).
    coarse : float
        Coarse onset from the detector, s.
    baseline, slope : float
        Baseline temperature at ``coarse`` and its slope before contact.
    depth, diffusivity : float
        Thermistor depth (m) and sensor diffusivity (m^2/s).
    search, step : float
        Search span before ``coarse`` and grid step, s.
    rates : tuple of float
        Contact closing rates tried, s^-0.5 (``inf`` is perfect contact).
    horizon : float
        Samples later than ``coarse + horizon`` are not used, s.

    Returns
    -------
    onset : float
        Refined onset time, s.
    initial : float
        Sensor temperature at the onset (the baseline there), deg C.
    """
    from skin.models.physics import SensorConstants, contact_response

    t = np.asarray(times, dtype=float)
    y = np.asarray(temperature, dtype=float)
    ok = np.isfinite(y) & (t <= coarse + horizon)
    t, y = t[ok], y[ok]
    grid = coarse - np.arange(0.0, search + step / 2, step)[::-1]
    if t.size < 3:
        return coarse, baseline
    sensor = SensorConstants(depth=depth, diffusivity=diffusivity)
    pre_model = baseline + slope * (t - coarse)
    # the response is tabulated once per rate on a lag grid a fifth of a step fine and read by
    # linear interpolation: exact at the grid's lags, and far fewer erfcx calls than lags
    dl = step / 5
    lags = np.arange(int(np.ceil((t[-1] - grid[0]) / dl)) + 2) * dl

    def best_fit(onsets: np.ndarray, rate_grid: np.ndarray,
                 table: np.ndarray) -> tuple[float, float]:
        base_at = baseline + slope * (onsets - coarse)  # (m,)
        lag = t[None, :] - onsets[:, None]  # (m, n)
        after = lag > 0
        x = np.maximum(lag, 0.0) / dl
        i = np.minimum(x.astype(np.int64), len(lags) - 2)
        f = x - i
        basis = table[:, i] * (1 - f) + table[:, i + 1] * f  # (rates, m, n); R(0) = 0
        target = np.where(after, y[None, :] - base_at[:, None], 0.0)  # (m, n)
        before = np.where(after, 0.0, y - pre_model)
        # least squares in D for each (rate, onset): sse = |target|^2 - (basis.target)^2/|basis|^2
        den = np.einsum("rmn,rmn->rm", basis, basis)
        num = np.einsum("rmn,mn->rm", basis, target)
        explained = np.divide(num**2, den, out=np.zeros_like(den), where=den > 0)
        sse = ((target**2).sum(-1) + (before**2).sum(-1))[None, :] - explained  # (rates, m)
        r, m = np.unravel_index(int(np.argmin(sse)), sse.shape)
        return float(onsets[m]), float(rate_grid[r])

    def tabulate(rate_grid: np.ndarray) -> np.ndarray:
        return contact_response(lags[None, :], rate_grid[:, None], sensor)  # (rates, lags)

    # coarse to fine: every rate on a 4-step grid over the whole span, then every rate on
    # the step grid around the best, then finer rates and fifths of a step around that
    rate_grid = np.asarray(rates, dtype=float)
    table = tabulate(rate_grid)
    onset, rate = best_fit(grid[::-4][::-1], rate_grid, table)
    near = grid[np.abs(grid - onset) <= 4 * step + 1e-9]
    onset, rate = best_fit(near, rate_grid, table)
    fine_rates = np.array([rate]) if np.isinf(rate) else rate * 2.0 ** np.arange(-1.0, 1.01, 0.25)
    fine = np.clip(onset + np.arange(-step, step + 1e-9, step / 5), grid[0], grid[-1])
    onset, _ = best_fit(fine, fine_rates, tabulate(fine_rates))
    return onset, float(baseline + slope * (onset - coarse))

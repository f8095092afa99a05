"""Commissioning from a quiet stretch: each taxel's noise, its spectrum, its drift, the jitter.

Record the skin for up to a minute with nothing touching it (heaters on, as in use). Per taxel,
`quiet_figures` measures

- ``noise_sigma``: the reading's noise per sample, K: the standard deviation of what is left
  after a straight line is fitted to each 2 s block (drift and slow heater moves removed);
- ``noise_lowfreq``: the noise of sums over many samples, K per sample (white-equivalent):
  sqrt(PSD(0.2-2 Hz) fs / 2) from Welch's periodogram of the same residual. Equal to
  ``noise_sigma`` for white noise; larger when the hardware or a logger smoothed the readings
  (their ratio is the smoothing's noise factor, `SensorDescription.smoothing_noise_factor`);
- ``drift``: the slope of a straight line over the whole stretch, K/s;

A sample more than 12 robust sigmas off its block's line is a touch, not noise: the stretch is
refused.

and for the skin the sample interval's jitter (rms deviation from its median, s).

The onset detector takes ``noise_sigma`` per taxel (`skin.stream.onset.OnsetDetector` ``sigma``)
from the calibration file these go into. A stretch that is not quiet (a taxel's reading moved
more than a contact-free taxel can in that time) or too short is refused with what to record.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skin.errors import SkinError

#: Shortest and longest quiet stretch accepted, s.
QUIET_SECONDS = (10.0, 600.0)
_BLOCK = 2.0  # s, the blocks whose straight lines take out drift and slow moves


class CommissioningError(SkinError):
    """A recording cannot pin what commissioning measures; the message says what to record."""


@dataclass(frozen=True)
class QuietFigures:
    """What a quiet stretch says about each taxel (arrays in layout order)."""

    noise_sigma: np.ndarray
    noise_lowfreq: np.ndarray
    drift: np.ndarray
    jitter: float
    seconds: float
    fs: float


def quiet_figures(times: np.ndarray, temperature: np.ndarray,
                  ids: np.ndarray | None = None) -> QuietFigures:
    """Measure a quiet stretch (see the module docstring).

    Parameters
    ----------
    times : numpy.ndarray
        Sample times, s, (n,).
    temperature : numpy.ndarray
        Readings, deg C, (n, n_taxels); NaN where a sample is missing.
    ids : numpy.ndarray, optional
        Taxel ids for messages (default: the column numbers).

    Raises
    ------
    CommissioningError
        Too short, a taxel without readings, or not quiet: the message says what to record.
    """
    from scipy.signal import welch

    t = np.asarray(times, dtype=float)
    y = np.array(temperature, dtype=float)  # a copy: missing samples get filled
    if y.ndim != 2 or y.shape[0] != t.size:
        raise ValueError("temperature must be (n_samples, n_taxels) with one time per sample")
    ids = np.arange(y.shape[1]) if ids is None else np.asarray(ids)
    seconds = float(t[-1] - t[0]) if t.size > 1 else 0.0
    lo, hi = QUIET_SECONDS
    if seconds < lo:
        raise CommissioningError(f"the quiet stretch lasts {seconds:.1f} s; record {lo:g}-60 s "
                                 f"with nothing touching the skin and the heaters on")
    dt = np.diff(t)
    step = float(np.median(dt))
    fs = 1.0 / step
    jitter = float(np.sqrt(np.mean((dt - step) ** 2)))
    missing = np.isnan(y).mean(axis=0)
    if np.any(missing > 0.5):
        k = int(np.argmax(missing))
        raise CommissioningError(f"taxel {ids[k]} has no reading in {missing[k]:.0%} of the "
                                 f"stretch: check its wiring, then record again")
    # fill the odd missing sample so that the block fits and the periodogram run
    for k in np.flatnonzero(missing > 0):
        ok = np.isfinite(y[:, k])
        y[:, k] = np.interp(t, t[ok], y[ok, k])
    per = max(round(_BLOCK * fs), 8)
    n_blocks = t.size // per
    resid = np.empty((n_blocks * per, y.shape[1]))
    means = np.empty((n_blocks, y.shape[1]))
    for b in range(n_blocks):
        sl = slice(b * per, (b + 1) * per)
        x = t[sl] - t[sl].mean()
        coef = np.polynomial.polynomial.polyfit(x, y[sl], 1)
        resid[sl] = y[sl] - (coef[0] + np.outer(x, coef[1]))
        means[b] = coef[0]
    sigma = resid.std(axis=0, ddof=2)
    f, psd = welch(resid, fs=fs, nperseg=per, axis=0, detrend="linear")
    band = (f >= 0.2) & (f <= 2.0)
    low = np.sqrt(np.median(psd[band], axis=0) * fs / 2.0) if band.any() else sigma
    slope = np.polynomial.polynomial.polyfit(t - t.mean(), y, 1)[1]
    # a contact-free taxel's residual is noise; a touch leaves a burst far outside it
    robust = 1.4826 * np.median(np.abs(resid), axis=0)
    peak = np.abs(resid).max(axis=0)
    if n_blocks >= 3:  # a touch filling whole blocks: a kink in the blocks' means
        peak = np.maximum(peak, np.abs(np.diff(means, 2, axis=0)).max(axis=0) / 2)
    loud = peak > 12.0 * np.maximum(robust, 1e-9)
    if loud.any():
        k = int(np.argmax(np.where(loud, peak / np.maximum(robust, 1e-9), 0.0)))
        raise CommissioningError(
            f"the stretch is not quiet: taxel {ids[k]} jumped {peak[k]:.3g} K off its trend "
            f"(its noise is {robust[k]:.3g} K); record {lo:g}-60 s with nothing touching the "
            f"skin")
    if seconds > hi:
        raise CommissioningError(f"the quiet stretch lasts {seconds:.0f} s; at most {hi:g} s "
                                 f"(the room drifts): cut it")
    return QuietFigures(sigma, low, slope, jitter, seconds, fs)

"""Whether a force-dated contact shows a thermal response at all: a likelihood-ratio test.

The force channel dates a contact whether or not heat flowed: a glitch of the force on a taxel
nothing touches (2 N for 1 s), a press through something that does not reach the sensor. Its
window then holds the free taxel's own trajectory and noise, and the classifier still weighs
the materials against it: the one whose response is smallest (cardboard) explains a flat
reading best, at p = 1.00. Whether the window shows a response at all is a question of its own,
answered here by a likelihood-ratio test between two models of each taxel's samples around
the force's onset:

- no contact: the free sensor's trajectory continues through the onset: a level, a linear
  trend (the room) and the relaxation towards its heated steady state with the sensor's own
  time constant (``reheat_time_constant``; a PID loop's ``control_time``), each free;
- contact: the same, plus the sensor's response to an object at rest in the room from the
  onset on (`skin.models.sensors.contact_basis`: the physics the joint classifier fits, with
  the sensor's heater term, lag and smoothing), of any amplitude (the object's temperature),
  for each material's effusivity of the table and each contact conductance of the pipeline's
  range.

Each taxel's gain in chi-square (its fitted response's amplitude over its standard error,
squared) is summed over the contact's taxels for each (material, conductance) and the best is
set against the chi-square quantile of as many degrees of freedom at `RESPONSE_SIGMAS` (a
two-sided 5-sigma tail; the F quantile where the noise is measured on few samples,
`threshold`). The noise is measured on each taxel's own samples before the onset, with the free
trajectory taken off (`measured_noise`; the detector's ``OnsetDetector.sigma`` over the sensor's
smoothing factor where fewer than `NOISE_SAMPLES` are there). The 5-sigma tail is nominal: with
independent samples and white noise a window of noise passes about once in two million; a
sensor whose reading is smoothed has correlated samples, so its measured noise reads low and
its degrees of freedom are fewer than counted (on pid-logger, a review's draws: contact-free
windows passed a 3-sigma test 4-6x as often as nominal). The samples before the onset come from
the tracker's search span (up to 4 s on low-cost), which can hold an earlier touch's reheat.
Nothing is tuned to a sensor: the models, their time constants and the noise come from each
taxel's description and samples.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2, norm
from scipy.stats import f as f_dist

#: How many standard errors (two-sided) a contact's fitted response must stand clear of none.
RESPONSE_SIGMAS = 5.0
#: Within a contact that shows a response, a force-dated taxel is left out of the
#: classification only when its own response stays under this many standard errors and its
#: samples reject the response the contact's object predicts for it by as many (a glitch
#: beside a real touch); a weak taxel of a real touch is kept.
LEAVE_OUT_SIGMAS = 3.0
#: Contact conductances tried per material (log-spaced over the pipeline's range).
H_POINTS = 4


@dataclass(frozen=True)
class ResponseVerdict:
    """The test's outcome for one contact.

    Attributes
    ----------
    gain : float
        The best (material, conductance) response's likelihood gain (2 log of the likelihood
        ratio at the measured noise), summed over the taxels: a chi-square gain where the
        heater's part is not known, and it can be negative where it is (fast-film).
    threshold : float
        The chi-square quantile it had to pass (`RESPONSE_SIGMAS`, ``taxels`` degrees of
        freedom).
    taxels : int
        Taxels tested (those with samples enough on both sides of the onset).
    silent : tuple of int
        Indices (into the members given) of the tested taxels with no response of their own
        whose samples reject the response the contact's object would give them (`_silent`:
        a glitch beside a real touch).
    """

    gain: float
    threshold: float
    taxels: int
    silent: tuple[int, ...] = ()

    @property
    def responded(self) -> bool:
        """Whether the data show a thermal response (True when no taxel could be tested)."""
        return self.taxels == 0 or self.gain > self.threshold


def threshold(taxels: int, sigmas: float = RESPONSE_SIGMAS, noise_dof: int = 0) -> float:
    """Return the gain a contact of ``taxels`` taxels must pass: a two-sided ``sigmas`` tail.

    The chi-square quantile with ``taxels`` degrees of freedom; with the noise measured on
    ``noise_dof`` degrees of freedom (`noise_dof`: the fewest of the measured taxels'),
    ``taxels`` times the F quantile (the measured noise's own spread widens the tail). 0: the
    noise is known.
    """
    tail = 2.0 * norm.sf(sigmas)
    if noise_dof > 0:
        return float(taxels * f_dist.isf(tail, taxels, noise_dof))
    return float(chi2.isf(tail, taxels))


def noise_dof(dofs: Sequence[int]) -> int:
    """Return the degrees of freedom a contact's threshold takes from its taxels' noise.

    The fewest of the taxels whose noise was measured (> 0); 0 (known noise) only when none
    was: a taxel on the detector's noise must not turn the small-sample correction off for a
    taxel measured on a few samples (a plain chi-square threshold let ~1000x the claimed rate
    of contact-free windows through).
    """
    return min((d for d in dofs if d > 0), default=0)


def free_columns(tau: np.ndarray, relax: float) -> np.ndarray:
    """Return the no-contact model's columns at ``tau`` (s from the onset): level, trend, relax.

    Returns an orthonormal basis (n, <= 3) of their span (a relaxation much slower than the
    window is a trend already: the rank drops, not the fit).
    """
    span = max(float(np.ptp(tau)), 1e-9)
    x = np.stack([np.ones_like(tau), tau / span, np.expm1(-tau / relax)], axis=1)
    u, s, _ = np.linalg.svd(x, full_matrices=False)
    return u[:, s > 1e-9 * s[0]]


#: The responses are computed on whole samples from the onset, in blocks of this many, and
#: kept per sensor (a contact's window is a slice of them: no filter runs per contact).
BLOCK = 256


@functools.lru_cache(maxsize=16)
def _basis(sensor: object, effusivities: tuple[float, ...], h_points: int, lo: int, hi: int,
           ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """`skin.models.sensors.contact_basis` at samples ``lo`` .. ``hi`` from the onset.

    (materials x conductances, samples) each.
    """
    from skin.models.joint import CONDUCTANCE_RANGE
    from skin.models.sensors import contact_basis

    e = np.asarray(effusivities, dtype=float)[:, None]
    h = np.geomspace(*CONDUCTANCE_RANGE, h_points)[None, :]
    lags = np.arange(lo, hi + 1) / float(sensor.sample_rate)
    p, q, a = contact_basis(lags, e, h, sensor)
    if a is not None:
        a = np.broadcast_to(a, p.shape)
    return tuple(None if x is None else np.ascontiguousarray(x.reshape(-1, lags.size))
                 for x in (p, q, a))


def templates(tau: np.ndarray, sensor: object, effusivities: Sequence[float],
              ambient: float, t0: float, h_points: int = H_POINTS,
              ) -> tuple[np.ndarray, np.ndarray | None]:
    """Return the contact model's parts at ``tau``: (materials x conductances, n) each.

    ``(T_obj - T0) P + (T_amb - T0) Q + A`` (`skin.models.sensors.contact_basis`) for a taxel
    at ``t0`` in a room at ``ambient``: ``P`` scales with the object's temperature (free),
    the heater's part ``(T_amb - T0) Q + A`` is known (None for a heater that has none); 0
    before the onset but for a non-causal smoothing's spread. ``tau`` is read at the nearest
    whole sample of the sensor's rate (at most half a sample off: the force's onset need not
    fall on one), from responses kept per sensor (`BLOCK`).
    """
    k = np.rint(np.asarray(tau, dtype=float) * float(sensor.sample_rate)).astype(int)
    lo = int(np.floor(k.min() / BLOCK)) * BLOCK
    hi = int(np.ceil((k.max() + 1) / BLOCK)) * BLOCK
    p, q, a = _basis(sensor, tuple(float(v) for v in effusivities), h_points, lo, hi)
    at = k - lo
    known = None if q is None else (ambient - t0) * q[:, at]
    if a is not None:
        known = a[:, at] if known is None else known + a[:, at]
    return p[:, at], known


@dataclass(frozen=True)
class _Fit:
    """One taxel's samples against the contact model's grid (`fit_taxel`)."""

    gain: np.ndarray  # (g,) chi-square gain over the free model
    free: np.ndarray  # (g, n) each P less what the free trajectory makes
    known: np.ndarray | None  # (g, n) the heater's known part, likewise
    resid: np.ndarray  # (n,) the samples less the free trajectory's fit
    norm2: np.ndarray  # (g,) |free|^2
    proj: np.ndarray  # (g,) free . (resid - known)
    sigma: float
    t0: float


def fit_taxel(tau: np.ndarray, y: np.ndarray, sigma: float, relax: float, t0: float,
              shapes: np.ndarray, known: np.ndarray | None = None) -> _Fit:
    """Fit one taxel's samples with the free model and with each grid point's contact model.

    The contact model adds ``c shapes[g] + known[g]`` (``c`` free) to the free trajectory;
    ``sigma`` is the white-equivalent noise per sample, K. A gain may be negative (the known
    part fits worse than nothing).
    """
    base = free_columns(tau, relax)

    def off(x: np.ndarray) -> np.ndarray:  # the part the free trajectory cannot make
        return x - (x @ base) @ base.T

    resid = off(y[None, :])[0]
    free = off(shapes)
    norm2 = np.einsum("gn,gn->g", free, free)
    k = None
    if known is None:
        rest, drop = resid[None, :], 0.0
    else:
        k = off(known)
        rest = resid[None, :] - k  # what is left for c P after the known part
        drop = np.einsum("gn,gn->g", rest, rest) - resid @ resid
    proj = np.einsum("gn,gn->g", free, np.broadcast_to(rest, free.shape))
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(norm2 > 0.0, proj**2 / norm2, 0.0) - drop
    return _Fit(gain / sigma**2, free, k, resid, norm2, proj, sigma, t0)


#: Fewest samples before the onset from which a taxel's noise is measured (else the detector's).
NOISE_SAMPLES = 12


@functools.lru_cache(maxsize=256)
def _step(sensor: object, temperature: float) -> float:
    """One ADC count of ``sensor`` near ``temperature`` deg C, K (cached to 0.5 K)."""
    return float(sensor.kelvin_per_count(temperature))


def measured_noise(tau: np.ndarray, y: np.ndarray, relax: float, sensor: object,
                   ) -> tuple[float, int] | None:
    """Return a taxel's white-equivalent noise measured before the onset, K, and its dof.

    The samples at ``tau <= 0`` less the free trajectory (`free_columns`) give the reading's
    noise per sample; over the sensor's smoothing factor it is the noise of sums over many
    samples (as `skin.stream.onset.OnsetDetector` takes its ``sigma``), and never under the
    rounding of one ADC count (a reading steady within a count shows nothing finer). None
    with fewer than `NOISE_SAMPLES` samples.
    """
    pre = tau <= 0
    n = int(pre.sum())
    if n < NOISE_SAMPLES:
        return None
    base = free_columns(tau[pre], relax)
    resid = y[pre] - base @ (base.T @ y[pre])
    dof = n - base.shape[1]
    per_sample = math.sqrt(float(resid @ resid) / dof)
    floor = _step(sensor, round(2.0 * float(np.median(y[pre]))) / 2.0) / math.sqrt(12.0)
    return max(per_sample / sensor.smoothing_noise_factor(), floor), dof


def check_contact(members: Sequence[object], refined: Sequence[tuple[float, float, float]],
                  sensors: Sequence[object], sigma: np.ndarray, ambient: float,
                  effusivities: Sequence[float], window: float = 2.5,
                  sigmas: float = RESPONSE_SIGMAS) -> ResponseVerdict:
    """Test a decided contact's members for a thermal response (see the module docstring).

    Parameters
    ----------
    members : sequence of skin.stream.tracking.TaxelSamples
        The contact's taxels with their samples from before the onset.
    refined : sequence of (float, float, float)
        Each member's (onset, initial, end) from `skin.stream.tracking.refine_member`.
    sensors : sequence of SensorDescription
        Each member's sensor description.
    sigma : numpy.ndarray
        Each member's white-equivalent noise per sample as the detector has it, K: used
        where too few samples before the onset measure it (`measured_noise`).
    ambient : float
        Room temperature, deg C.
    effusivities : sequence of float
        The candidate materials' effusivities.
    window : float
        Longest span after the onset used, s (the classifier's window).
    sigmas : float
        Two-sided tail of the test, in normal deviates.
    """
    total, tested, dofs, fits = None, 0, [], []
    for i, (m, (onset, initial, end), sensor, s) in enumerate(zip(members, refined, sensors,
                                                                   sigma, strict=True)):
        ok = (np.isfinite(m.temperature) & (m.time <= min(end, onset + window)))
        tau, y = m.time[ok] - onset, m.temperature[ok]
        if (tau > 0).sum() < 3 or (tau <= 0).sum() < 3:
            continue
        relax = (sensor.control_time if sensor.heater == "pid"
                 else sensor.reheat_time_constant)
        noise = measured_noise(tau, y, relax, sensor)
        if noise is None:
            if not s > 0:
                continue
            noise = (float(s), 0)
        t0 = float(initial) if math.isfinite(initial) else float(y[tau <= 0][-1])
        fit = fit_taxel(tau, y, noise[0], relax, t0,
                        *templates(tau, sensor, effusivities, ambient, t0))
        total = fit.gain if total is None else total + fit.gain
        tested += 1
        dofs.append(noise[1])
        fits.append((i, fit, noise[1]))
    if total is None:
        return ResponseVerdict(0.0, 0.0, 0)
    return ResponseVerdict(float(total.max()), threshold(tested, sigmas, noise_dof(dofs)), tested,
                           _silent(fits, sigmas))


def _silent(fits: list[tuple[int, _Fit, int]], sigmas: float) -> tuple[int, ...]:
    """Return the taxels whose samples contradict the contact's object (glitches beside it).

    At each grid point (material, conductance), each taxel's fitted amplitude is an estimate
    of the object's temperature less its own starting one, with a standard error; the taxels
    that show a response of their own (past `LEAVE_OUT_SIGMAS`) give the object's temperature
    (precision-weighted). A taxel without one of its own is silent when, at every grid point,
    its estimate differs from that by more than `LEAVE_OUT_SIGMAS` of the two errors
    together: the response the object would give it should have shown and did not. Where
    that response is too small to tell from none at some grid point (a low-contrast touch:
    skin on a taxel near its temperature, a slow sensor), it is kept.
    """
    bar = min(sigmas, LEAVE_OUT_SIGMAS)
    loud = [f for _, f, dof in fits if f.gain.max() > threshold(1, bar, dof)]
    if not loud:
        return ()
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.array([f.norm2 / f.sigma**2 for f in loud])  # (loud, g)
        est = np.array([f.t0 + f.proj / f.norm2 for f in loud])
        t_obj = np.nansum(w * est, axis=0) / w.sum(axis=0)
        out = []
        for i, f, dof in fits:
            if f.gain.max() > threshold(1, bar, dof):
                continue
            var = f.sigma**2 / f.norm2 + 1.0 / w.sum(axis=0)
            z2 = (f.t0 + f.proj / f.norm2 - t_obj) ** 2 / var
            z2 = z2[np.isfinite(z2)]
            if z2.size and float(z2.min()) > threshold(1, bar, dof):
                out.append(i)
    return tuple(out)

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
  time constant (``reheat_time_constant``; a PID loop's ``control_time`` and the body's
  ``reheat_time_constant`` both: `relaxations`), each free;
- contact: the same, plus the sensor's response to an object at rest in the room from the
  onset on (`skin.models.sensors.contact_basis`: the physics the joint classifier fits, with
  the sensor's heater term, lag and smoothing), of any amplitude (the object's temperature),
  for each material's effusivity of the table and each contact conductance of the pipeline's
  range.

Each taxel's gain (its fitted response's amplitude over its standard error, squared) is
summed over the contact's taxels for each (material, conductance), and the best is set
against the F quantile (`threshold`) at `RESPONSE_SIGMAS` (two-sided) of as many degrees of
freedom and the noise's, Šidák-corrected for the grid's effective number of tests. What makes
the tail honest (`skin bench response-noise` counts contact-free windows that pass at 2 and 3
sigma against their nominal rate, per sensor preset):

- the noise is white before the sensor's smoothing and correlated after it: its
  autocovariance is the smoothing impulse's autocorrelation (`noise_autocovariance`), and a
  response's standard error is taken along its tested direction ``r`` (the shape less what
  the free model makes), ``sigma^2 r^T A r``, not as if the samples were independent;
- the noise ``sigma`` is measured on the taxel's samples before the onset since it was last
  quiet (`skin.stream.tracking.TaxelSamples.quiet_since`: an earlier touch's own change is no
  noise), with the free trajectory taken off and the correlation accounted for
  (`measured_noise`), on Satterthwaite's degrees of freedom (fewer than the samples on a
  smoothed sensor); where fewer than `NOISE_SAMPLES` samples or `NOISE_DOF` degrees of
  freedom measure it, the detector's ``OnsetDetector.sigma`` over the sensor's smoothing
  factor, on `NOISE_DOF`; never under one ADC count's rounding (white before the smoothing,
  as the readout's noise), and a reading that does not change at all (stuck on one count)
  reads as white at that rounding;
- a room that drifts moves the reading with it: where the samples' room channel moves beyond
  its own noise, the room through the sensor's loop, lag and smoothing joins the free model
  (`room_column`);
- the grid of (material, conductance) responses is many correlated tests: the best of them is
  held to the tail of Li & Ji's effective number of tests (`grid_tests`).

Measured (`skin bench response-noise --seeds 0 1 2 3 --duration 60 --taxels 72`: the
heater's switches, the room's drift, earlier touches; CHANGELOG), contact-free windows pass at
2 sigma under the nominal rate on every preset (0.4-0.8x, where they passed 8-16x before on
the smoothed and drifting ones), and at 3 sigma at 0.1-0.8x on paper and low-cost, 1.6x on
fast-film and 1.1x on pid-logger (from 90-220x; pid-logger 2.0x before its free model took
the body's mode). Its cost, the streams' real contacts (each force-dated at its onset on its
own taxel) that show a response at 5 sigma: paper 131 of 173, fast-film 218 of 221,
pid-logger 70 of 184, low-cost none of 168 (a single taxel of that 20 Hz, very noisy sensor
does not show a touch at 5 sigma within the window; not counted for several taxels). The
bench's "one point" column (each grid point alone at the single test's threshold) tells where
an excess lies, and it differs:

- pid-logger: in the single test. With the loop's relaxation alone in the free model,
  every point alone passed 2 sigma at 1.2x and 3 sigma at 3.1x (the best, under Li & Ji's
  count of several tests where the points are nearly one: 0.70x / 1.96x). The body's slow
  mode, which the loop's high-pass leaves in the reading, is free as well now: points 1.16x
  / 1.89x, the best 0.66x / 1.09x (held-out seeds 4-7: points 1.25x / 2.65x -> 1.11x /
  0.98x, the best 0.71x / 2.18x -> 0.57x / 0.65x). The cost is power (the body's mode is
  part of a contact's response through the loop too): of the streams' real contacts, each
  force-dated at its onset on its own taxel, 73 -> 70 of 184 show a response at 5 sigma
  (seeds 4-7: 85 -> 77 of 174).
- fast-film: in the grid. Each point alone stays under nominal (3 sigma: 0.67x median, 1.6x
  the largest of 48 noisy rates), their best passes at 1.6x. Its gain, with the heater's
  drain known, is no chi-square, and the count taken from its points' correlation falls
  short.

Not modelled: air currents (a gust cools a taxel as a contact does, and their flutter is
slow noise: ``--air`` counts what they add), and a room the skin does not read. Nothing is
tuned to a sensor: the models, their time constants and the noise come from each taxel's
description and samples.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import fftconvolve
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
#: The room channel enters the free model where it moves this many sigmas (two-sided) beyond
#: its own noise (`room_column`).
ROOM_SIGMAS = 3.0
#: Fewest samples before the onset from which a taxel's noise is measured (else the detector's).
NOISE_SAMPLES = 12
#: Degrees of freedom given to the detector's noise where a taxel's own is not measured (it is
#: itself measured, by commissioning or the sensor's description, and the room's drift over
#: the window is not in it: not a known noise).
NOISE_DOF = 12


@dataclass(frozen=True)
class ResponseVerdict:
    """The test's outcome for one contact.

    Attributes
    ----------
    gain : float
        The best (material, conductance) response's likelihood gain (2 log of the likelihood
        ratio at the measured noise, each taxel's over the variance of its tested direction
        under the noise's covariance), summed over the taxels: a chi-square gain where the
        heater's part is not known, and it can be negative where it is (fast-film).
    threshold : float
        The quantile it had to pass (`threshold`: `RESPONSE_SIGMAS` two-sided, ``taxels``
        degrees of freedom, the noise's ``dof``, Šidák-corrected for ``tests`` effective
        tests).
    taxels : int
        Taxels tested (those with samples enough on both sides of the onset).
    silent : tuple of int
        Indices (into the members given) of the tested taxels with no response of their own
        whose samples reject the response the contact's object would give them (`_silent`:
        a glitch beside a real touch).
    dof : float
        The noise's degrees of freedom the threshold took (`noise_dof`: the fewest of the
        taxels'; Satterthwaite's where measured, `NOISE_DOF` on the detector's noise).
    tests : float
        The effective number of the grid's (material, conductance) tests (`grid_tests`).
    gains : numpy.ndarray or None
        Each grid point's gain summed over the taxels (``gain`` is the largest), materials
        in the order given, `H_POINTS` conductances each; None where no taxel was tested.
        Each held to ``threshold(taxels, sigmas, dof)`` alone is one test, without the grid
        (`skin bench response-noise` counts them to tell the single test's tail from the
        grid's).
    """

    gain: float
    threshold: float
    taxels: int
    silent: tuple[int, ...] = ()
    dof: float = 0.0
    tests: float = 1.0
    gains: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def responded(self) -> bool:
        """Whether the data show a thermal response (True when no taxel could be tested)."""
        return self.taxels == 0 or self.gain > self.threshold


def threshold(taxels: int, sigmas: float = RESPONSE_SIGMAS, noise_dof: float = 0,
              tests: float = 1.0) -> float:
    """Return the gain a contact of ``taxels`` taxels must pass: a two-sided ``sigmas`` tail.

    The chi-square quantile with ``taxels`` degrees of freedom; with the noise measured on
    ``noise_dof`` degrees of freedom (`noise_dof`: the fewest of the measured taxels'),
    ``taxels`` times the F quantile (the measured noise's own spread widens the tail). 0: the
    noise is known. The best of ``tests`` effective tests (`grid_tests`) is held to the
    Šidák tail ``1 - (1 - tail)^(1 / tests)``, so that the best passes at the nominal rate.
    """
    tail = 2.0 * norm.sf(sigmas)
    if tests > 1.0:
        tail = -math.expm1(math.log1p(-tail) / tests)
    if noise_dof > 0:
        return float(taxels * f_dist.isf(tail, taxels, noise_dof))
    return float(chi2.isf(tail, taxels))


def noise_dof(dofs: Sequence[float]) -> float:
    """Return the degrees of freedom a contact's threshold takes from its taxels' noise.

    The fewest of the taxels' (> 0); 0 (known noise) only when none has any: a taxel on a
    noise of many degrees of freedom must not turn the small-sample correction off for a
    taxel measured on a few samples (a plain chi-square threshold let ~1000x the claimed rate
    of contact-free windows through).
    """
    return min((d for d in dofs if d > 0), default=0)


def grid_tests(correlations: Sequence[np.ndarray]) -> float:
    """Return the effective number of a grid's correlated tests (Li & Ji 2005).

    ``correlations`` holds, per taxel, the correlation matrix (g, g) of its grid points'
    fitted responses under the noise (their tested directions' covariance). The contact's
    statistic at a grid point sums the taxels' chi-square gains, whose correlation is the
    taxels' mean squared correlation; its root is the grid's correlation, and from the
    eigenvalues ``l`` of its absolute value the effective number is
    ``sum(I(l >= 1) + l - floor(l))`` (Li, J. & Ji, L., Heredity 95, 221-227, 2005): 1 for a
    grid of one test or of identical ones, g for independent ones.
    """
    if not correlations:
        return 1.0
    rho2 = np.mean([np.square(c) for c in correlations], axis=0)
    lam = np.clip(np.linalg.eigvalsh(np.sqrt(np.clip(rho2, 0.0, 1.0))), 0.0, None)
    lam = np.round(lam, 9)  # an eigenvalue k - 1e-15 is k: the count jumps at whole numbers
    return max(1.0, float(np.sum((lam >= 1.0) + lam - np.floor(lam))))


def relaxations(sensor: object) -> tuple[float, ...]:
    """Return the time constants a free taxel's reading relaxes with, s.

    The body's ``reheat_time_constant``; with a PID-held heater the loop's ``control_time``
    as well: the loop takes the body's slow reheating off the reading only in part (its
    high-pass leaves the body's mode in the reading, most in the seconds after a release).
    With the loop's mode alone the free model left it as a misfit: pid-logger's contact-free
    windows passed 3 sigma at about 2x nominal (`skin bench response-noise`; CHANGELOG).
    """
    if sensor.heater == "pid":
        return float(sensor.control_time), float(sensor.reheat_time_constant)
    return (float(sensor.reheat_time_constant),)


def free_columns(tau: np.ndarray, relax: float | Sequence[float],
                 room: np.ndarray | None = None) -> np.ndarray:
    """Return the no-contact model's columns at ``tau`` (s from the onset): level, trend, relax.

    ``relax``: the time constant of the relaxation towards the heated steady state, or
    several (a relaxation each: `relaxations` gives a sensor's).

    With ``room`` (the room's temperature as the sensor reads it and the sensor's start-up
    transients, `room_column`: (n,) or (n, k)), those too (a room that drifts moves the
    reading with it). Returns an orthonormal basis (n, <= 2 + len(relax) + k) of
    their span (a relaxation much slower than the window is a trend already, a steady room a
    level: the rank drops, not the fit).
    """
    span = max(float(np.ptp(tau)), 1e-9)
    cols = [np.ones_like(tau), tau / span,
            *(np.expm1(-tau / r) for r in np.atleast_1d(np.asarray(relax, dtype=float)))]
    x = np.stack(cols, axis=1)
    if room is not None:
        x = np.concatenate([x, np.reshape(room, (tau.size, -1))], axis=1)
    u, s, _ = np.linalg.svd(x, full_matrices=False)
    return u[:, s > 1e-9 * s[0]]


def room_column(ambient: np.ndarray, sensor: object) -> np.ndarray | None:
    """Return the room's temperature as the sensor's reading follows it, K from its first.

    The samples' ambient (the skin's room channel) through the sensor's loop, lag and
    smoothing (`skin.models.sensors.apply_dynamics`, `skin.models.sensors.smooth`), from
    rest at the first sample; the room before it leaves the filters' states unknown: the
    loop's decays with its ``control_time`` (the free model's relaxation), the lag's with
    ``lag``, a column of its own. (n, 1 or 2); None where the room is not read (not finite)
    or shows no drift beyond its own noise: the room channel's white noise (measured by its
    successive differences) would leave its samples less a level and a trend with a sum of
    squares under the chi-square quantile at `ROOM_SIGMAS` (a steady room read by a noisy
    thermometer: its noise fitted as a column would take the response's place).
    """
    from skin.models.sensors import apply_dynamics, smooth

    amb = np.asarray(ambient, dtype=float)
    n = amb.size
    if n < 4 or not np.isfinite(amb).all() or np.ptp(amb) == 0.0:
        return None
    white = float(np.sum(np.diff(amb) ** 2)) / (2.0 * (n - 1))  # the channel's noise, K²
    x = np.arange(n, dtype=float)
    rest = amb - np.polyval(np.polyfit(x, amb, 1), x)
    if float(rest @ rest) <= white * chi2.isf(2.0 * norm.sf(ROOM_SIGMAS), n - 2):
        return None
    fs = float(sensor.sample_rate)
    cols = [smooth(apply_dynamics(amb - amb[0], sensor, fs), sensor, fs=fs)]
    if sensor.lag > 0:
        cols.append(smooth(np.exp(-np.arange(amb.size) / (fs * sensor.lag)), sensor, fs=fs))
    return np.stack(cols, axis=1)


# -- the noise's covariance ------------------------------------------------------------------
@functools.lru_cache(maxsize=16)
def noise_autocovariance(sensor: object) -> np.ndarray:
    """Return the autocovariance of the sensor's reading noise per unit white noise, lags 0, 1, ...

    The noise is white before the sensor's smoothing (the thermistor's and the ADC's, the
    rounding: the smoothing runs on the counts); after it, its autocovariance at lag ``l`` is
    the smoothing impulse's autocorrelation ``sum_k h[k] h[k + l]``
    (`skin.models.sensors.SensorDescription.smoothing_impulse`), ``[1.0]`` without smoothing.
    Lag 0 is the square of `smoothing_noise_factor`. Trimmed where it vanishes.
    """
    h = np.asarray(sensor.smoothing_impulse(), dtype=float)
    full = np.correlate(h, h, mode="full")[h.size - 1:]
    big = np.flatnonzero(np.abs(full) > 1e-12 * full[0])
    return np.ascontiguousarray(full[: big[-1] + 1])


def _positions(tau: np.ndarray, sensor: object) -> np.ndarray:
    """Whole samples of the sensor's rate from the first of ``tau``, (n,) int."""
    k = np.rint(np.asarray(tau, dtype=float) * float(sensor.sample_rate)).astype(int)
    return k - int(k.min())


def _apply_cov(sensor: object, pos: np.ndarray, x: np.ndarray, white: bool) -> np.ndarray:
    """Return ``A x`` for rows ``x`` (g, n) at sample positions ``pos``.

    ``A`` the smoothed white noise's covariance per unit white variance
    (`noise_autocovariance`), the identity where ``white``.
    """
    if white:
        return x
    acov = noise_autocovariance(sensor)
    if acov.size == 1:
        return acov[0] * x
    span = int(pos[-1]) + 1
    z = np.zeros((x.shape[0], span))
    z[:, pos] = x
    sym = np.concatenate([acov[:0:-1], acov])[None, :]
    la = acov.size
    return fftconvolve(z, sym, axes=1)[:, la - 1: la - 1 + span][:, pos]


@functools.lru_cache(maxsize=8)
def _dense(sensor: object, pos: tuple[int, ...]) -> np.ndarray:
    """Return the smoothed white noise's covariance per unit variance at ``pos``, (n, n).

    Few kept: each is n^2 floats (a 4 s span at 200 Hz: 5 MB), and a long run meets many
    spans (an O(n^2) build is a millisecond's work).
    """
    p = np.asarray(pos)
    acov = noise_autocovariance(sensor)
    lag = np.abs(p[:, None] - p[None, :])
    return np.where(lag < acov.size, acov[np.minimum(lag, acov.size - 1)], 0.0)


@dataclass(frozen=True)
class Noise:
    """A taxel's noise (`measured_noise`).

    Attributes
    ----------
    sigma : float
        White noise per sample before the sensor's smoothing, K (where ``white``: per
        sample as read).
    dof : float
        Its degrees of freedom (Satterthwaite's; `NOISE_DOF` for the detector's).
    white : bool
        The reading is read as white (``sigma`` the rounding of one ADC count: a reading
        that does not change at all, stuck on one count, shows no smoothing's correlation).
    """

    sigma: float
    dof: float
    white: bool = False


@functools.lru_cache(maxsize=256)
def _step(sensor: object, temperature: float) -> float:
    """One ADC count of ``sensor`` near ``temperature`` deg C, K (cached to 0.5 K)."""
    return float(sensor.kelvin_per_count(temperature))


def measured_noise(tau: np.ndarray, y: np.ndarray, relax: float | Sequence[float],
                   sensor: object,
                   room: np.ndarray | None = None) -> Noise | None:
    """Return a taxel's noise measured on its samples before the onset (``tau``, ``y``).

    The samples less the free trajectory (`free_columns`, with the ``room`` where read;
    projector ``M``) hold the smoothed white noise, of covariance ``sigma^2 A``
    (`noise_autocovariance`): their sum of squares has the mean ``sigma^2 tr(M A)``, whence
    ``sigma``, and its degrees of freedom are Satterthwaite's, ``2 E^2 / var`` of that
    quadratic form, ``tr(M A)^2 / tr((M A)^2)`` (n - p for white noise: fewer for a smoothed
    reading, whose samples are correlated). ``sigma`` is never under the rounding of one ADC
    count, which is white before the smoothing as the readout's noise is (a reading steady
    within a count shows nothing finer); a reading that does not change at all (stuck on one
    count) shows no smoothing either and is read as white at that rounding, on n - p. None
    with fewer than `NOISE_SAMPLES` samples.
    """
    n = int(np.size(tau))
    if n < NOISE_SAMPLES:
        return None
    base = free_columns(np.asarray(tau, dtype=float), relax, room)
    resid = y - base @ (base.T @ y)
    a = _dense(sensor, tuple(int(v) for v in _positions(tau, sensor)))
    ma = a - base @ (base.T @ a)
    tr = float(np.trace(ma))
    sigma2 = float(resid @ resid) / max(tr, 1e-300)
    floor = _step(sensor, round(2.0 * float(np.median(y))) / 2.0) / math.sqrt(12.0)
    if not np.ptp(y) > 0.0:  # stuck
        return Noise(floor, float(n - base.shape[1]), True)
    dof = tr**2 / max(float(np.sum(ma * ma.T)), 1e-300)
    return Noise(max(math.sqrt(sigma2), floor), float(dof), False)


# -- the contact model -----------------------------------------------------------------------
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

    gain: np.ndarray  # (g,) likelihood gain over the free model, in units of its variance
    free: np.ndarray  # (g, n) each P less what the free trajectory makes
    known: np.ndarray | None  # (g, n) the heater's known part, likewise
    resid: np.ndarray  # (n,) the samples less the free trajectory's fit
    norm2: np.ndarray  # (g,) |free|^2
    proj: np.ndarray  # (g,) free . (resid - known)
    var: np.ndarray  # (g,) the noise's variance of proj: sigma^2 free^T A free, K²
    corr: np.ndarray  # (g, g) the correlation of the grid points' proj under the noise
    t0: float


def fit_taxel(tau: np.ndarray, y: np.ndarray, relax: float | Sequence[float], t0: float,
              shapes: np.ndarray, known: np.ndarray | None,
              cov: Callable[[np.ndarray], np.ndarray], room: np.ndarray | None = None) -> _Fit:
    """Fit one taxel's samples with the free model and with each grid point's contact model.

    The contact model adds ``c shapes[g] + known[g]`` (``c`` free) to the free trajectory
    (`free_columns`, with the ``room``). ``cov(x)`` returns the noise's covariance times
    rows ``x`` (g, n), K². The tested direction ``r`` (the shape less what the free
    trajectory makes) has the noise's variance ``r^T K r`` along it: each gain
    (least-squares) is taken over ``r^T K r / |r|^2``, not over a variance per sample, which
    holds for correlated samples (for white noise it is that variance). A gain may be
    negative (the known part fits worse than nothing).
    """
    base = free_columns(tau, relax, room)

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
    kf = cov(free)
    var = np.einsum("gn,gn->g", free, kf)
    ok = (norm2 > 1e-300) & (var > 1e-300)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        gain = np.where(ok, (proj**2 / norm2 - drop) * norm2 / var, 0.0)
        sd = np.sqrt(np.where(ok, var, 1.0))
        corr = np.where(ok[:, None] & ok[None, :], (free @ kf.T) / np.outer(sd, sd), 0.0)
    np.fill_diagonal(corr, 1.0)
    return _Fit(gain, free, k, resid, norm2, proj, np.where(ok, var, np.inf), corr, t0)


def check_contact(members: Sequence[object], refined: Sequence[tuple[float, float, float]],
                  sensors: Sequence[object], sigma: np.ndarray, ambient: float,
                  effusivities: Sequence[float], window: float = 2.5,
                  sigmas: float = RESPONSE_SIGMAS) -> ResponseVerdict:
    """Test a decided contact's members for a thermal response (see the module docstring).

    Parameters
    ----------
    members : sequence of skin.stream.tracking.TaxelSamples
        The contact's taxels with their samples from before the onset (the noise is measured
        on those since ``quiet_since``; their ``ambient``, where it moves, is the room's).
    refined : sequence of (float, float, float)
        Each member's (onset, initial, end) from `skin.stream.tracking.refine_member`.
    sensors : sequence of SensorDescription
        Each member's sensor description.
    sigma : numpy.ndarray
        Each member's white-equivalent noise per sample as the detector has it, K: used
        (on `NOISE_DOF` degrees of freedom) where too few samples before the onset measure
        it (`measured_noise`: fewer than `NOISE_SAMPLES`, or fewer degrees of freedom than
        `NOISE_DOF`).
    ambient : float
        Room temperature, deg C.
    effusivities : sequence of float
        The candidate materials' effusivities.
    window : float
        Longest span after the onset used, s (the classifier's window).
    sigmas : float
        Two-sided tail of the test, in normal deviates.
    """
    total, tested, dofs, fits, corrs = None, 0, [], [], []
    for i, (m, (onset, initial, end), sensor, s) in enumerate(zip(members, refined, sensors,
                                                                   sigma, strict=True)):
        ok = (np.isfinite(m.temperature) & (m.time <= min(end, onset + window)))
        tau, y = m.time[ok] - onset, m.temperature[ok]
        if (tau > 0).sum() < 3 or (tau <= 0).sum() < 3:
            continue
        relax = relaxations(sensor)
        room = room_column(np.asarray(m.ambient)[ok], sensor)
        quiet = (tau <= 0) & (m.time[ok] >= m.quiet_since)
        noise = measured_noise(tau[quiet], y[quiet], relax, sensor,
                               None if room is None else room[quiet])
        if noise is None or (noise.dof < NOISE_DOF and s > 0):
            # too few samples, or too few independent ones (a smoothed reading): the
            # detector's noise is known better
            if not s > 0:
                continue
            noise = Noise(float(s), float(NOISE_DOF))
        t0 = float(initial) if math.isfinite(initial) else float(y[tau <= 0][-1])
        pos = _positions(tau, sensor)

        def cov(x: np.ndarray, sensor: object = sensor, pos: np.ndarray = pos,
                noise: Noise = noise) -> np.ndarray:
            return noise.sigma**2 * _apply_cov(sensor, pos, x, noise.white)

        fit = fit_taxel(tau, y, relax, t0, *templates(tau, sensor, effusivities, ambient, t0),
                        cov=cov, room=room)
        total = fit.gain if total is None else total + fit.gain
        tested += 1
        dofs.append(noise.dof)
        fits.append((i, fit, noise.dof))
        corrs.append(fit.corr)
    if total is None:
        return ResponseVerdict(0.0, 0.0, 0)
    dof, tests = noise_dof(dofs), grid_tests(corrs)
    return ResponseVerdict(float(total.max()), threshold(tested, sigmas, dof, tests), tested,
                           _silent(fits, sigmas), float(dof), tests, total)


def _silent(fits: list[tuple[int, _Fit, float]], sigmas: float) -> tuple[int, ...]:
    """Return the taxels whose samples contradict the contact's object (glitches beside it).

    At each grid point (material, conductance), each taxel's fitted amplitude is an estimate
    of the object's temperature less its own starting one, with a standard error (its
    tested direction's variance under the noise's covariance); the taxels that show a
    response of their own (past `LEAVE_OUT_SIGMAS`) give the object's temperature
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
        w = np.array([f.norm2**2 / f.var for f in loud])  # (loud, g)
        est = np.array([f.t0 + f.proj / f.norm2 for f in loud])
        t_obj = np.nansum(w * est, axis=0) / w.sum(axis=0)
        out = []
        for i, f, dof in fits:
            if f.gain.max() > threshold(1, bar, dof):
                continue
            var = f.var / f.norm2**2 + 1.0 / w.sum(axis=0)
            z2 = (f.t0 + f.proj / f.norm2 - t_obj) ** 2 / var
            z2 = z2[np.isfinite(z2)]
            if z2.size and float(z2.min()) > threshold(1, bar, dof):
                out.append(i)
    return tuple(out)

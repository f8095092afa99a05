"""How close physics lets any unbiased estimator date a contact's onset: Cramér-Rao bounds.

Issue 16 asks for a refined-onset error median of at most ``max(15 ms, 10 % of the physical
floor)`` per sensor (`skin.bench.onset_eval.onset_error_target`; the floor is when a contact's
noise-free reading first moves 3 sigma). This module measures how far the sensor's own noise
lets any estimator get, on the streams `skin bench delay-bound` and ``skin evaluate-onset
--sensor`` simulate (`skin.bench.delay_bound.onset_stream`).

For each contact with a floor the samples are modelled as a Gaussian signal in correlated
noise: ``y = H (b + A m(t - t0) + e)``, ``m`` the contact's noise-free change of the reading
through the sensor's loop and lag (``Stream.templates``), ``e`` the sensor's raw noise before
smoothing, white (``Stream.raw_noise``: its noise, ADC noise and rounding), ``H`` the
sensor's smoothing (a linear time-invariant filter: the smoothed noise's covariance is
``sigma^2 H H^T``, banded), ``b`` a baseline offset, ``A`` the response's amplitude (1 in
truth) and ``t0`` the onset. The derivative of the mean with respect to ``t0`` is minus the
response's time derivative (``numpy.gradient`` of the template on its sample grid, 0 before
the onset). The Fisher information is ``J = D^T (H H^T)^-1 D / sigma^2`` with ``D`` the
smoothed derivatives ``H dmu/dtheta`` as columns; the bound on the standard deviation of the
onset is ``1 / sqrt`` of the efficient information on ``t0`` (the Schur complement of the
nuisances' block: the nuisances projected out). Five variants (`VARIANTS`):

``known``
    everything but the onset known (``A`` and ``b``): the lowest bound;
``gain``
    the amplitude unknown too;
``gain_offset``
    the amplitude and the baseline offset unknown: the closest of the noise-only ones to what the
    library's refinement estimates (it fits a level and the response's size, and more: a
    closing rate, a heater term, a slope; unknown shape only raises the bound);
``gain_offset_drift``
    as ``gain_offset``, with the room's random walk (`skin.stream.onset.AMBIENT_DRIFT`, the
    simulator's and the detector's) and the air's flutter (`skin.bench.streams.FLUTTER`)
    through the sensor's loop, lag and smoothing added to the noise, as the streams put them
    on the reading (`drift_covariance`): the Gaussian part of the streams' disturbances (the
    gusts and heater switches, neither Gaussian nor stationary, still left out). Dense
    covariances: not computed where the window and its history exceed `DRIFT_MAX_SAMPLES`;
``known_credited``
    as ``known``, on the window in which `skin evaluate-onset` credits an alarm to the
    contact (``EARLY`` before the onset to the end of `skin.bench.onset_eval.release_window`
    after the release): the samples after the release add information on the onset too.

The other four use the samples the library's refinement can use when it dates the onset
(`skin.stream.onset_refine.refine_span`: the span ``search`` before the coarse onset and the
``horizon`` after it, and no sample past the release, `skin.stream.tracking.refine_member`):
from ``search`` before the onset to ``search + horizon`` after it (its grid puts the onset
at most ``search`` before the coarse onset, so no refinement that finds the onset sees
further) or the release, whichever comes first. That is the most the refinement can see, so
the bound on it is at most the bound on the library's own window.

Then, per seed, ``draws`` Monte-Carlo medians: each contact's error drawn as ``|N(0, sd)|``
(an efficient, unbiased, Gaussian estimate reaching its bound), the median taken over the
contacts; given per variant are the median of those medians, their 5-95 % interval, and the
share of them at or under the target: how likely an estimator at the bound meets the target on
that stream. The same over the contacts the library detected (its median is over those) sits
beside it, and the library's own refined-onset error median (the detector and the refinement
run as evaluate-onset runs them, `skin.bench.delay_bound._run_detector`) and its per-contact
|error| in units of the ``gain_offset`` bound (median; 0.6745 for an efficient estimate).

These bound *unbiased* estimators only. A biased estimator, or one with a prior on the onset
(a Bayesian one, or a fit that shrinks towards the coarse onset), can beat them; the library's
refinement is a least-squares fit over a grid and need not be unbiased. The bound is the
information the samples carry under the model's assumptions (the template exact, no
disturbances but ``gain_offset_drift``'s drift and flutter: no gusts or heater switching, the
noise Gaussian); it is a local bound
(small errors), not a global one: ambiguity between far-apart onsets is not in it. A median
under the target by the bound says physics does not rule the target out; one over it says no
unbiased estimator meets it on that stream at that probability.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

#: The bound's variants, in order.
VARIANTS = ("known", "gain", "gain_offset", "gain_offset_drift", "known_credited")
#: ``gain_offset_drift``: the room's walk and the air's flutter start this many of the slowest
#: time constant they pass through (the sensor's loop, lag, smoothing, the flutter's own)
#: before the window; what came earlier moves the window by a near constant, which the
#: bound's offset takes.
DRIFT_HISTORY = 8.0
#: ... and the variant is not computed (None) where the window and that history span more
#: samples than this (its covariances are dense: fast-film's 1 kHz windows).
DRIFT_MAX_SAMPLES = 3000
#: Monte-Carlo medians drawn at a time (memory: this times the contacts).
_CHUNK = 2000


def smoothing_kernel(sensor: object) -> tuple[np.ndarray, int]:
    """Return the sensor's smoothing as a convolution kernel and the index of its sample 0.

    The impulse response `skin.models.sensors.SensorDescription.smoothing_impulse`, trimmed
    of the taps under 1e-12 of its largest (an IIR filter's tail). A smoothed sample ``i`` is
    ``sum_j kernel[j] x[i + center - j]``; ``([1.0], 0)`` for no smoothing.
    """
    h = np.asarray(sensor.smoothing_impulse(), dtype=float)
    middle = h.size // 2
    keep = np.flatnonzero(np.abs(h) > 1e-12 * np.max(np.abs(h)))
    lo, hi = int(keep[0]), int(keep[-1]) + 1
    return h[lo:hi], middle - lo


def _smoothed(x: np.ndarray, kernel: np.ndarray, center: int) -> np.ndarray:
    """Return ``x`` smoothed by ``kernel`` (same length; its edges see zeros beyond)."""
    return np.convolve(x, kernel)[center:center + x.size]


def fisher_matrix(columns: np.ndarray, sigma: float, kernel: np.ndarray | None = None,
                  center: int = 0, pad: int = 0, extra: np.ndarray | None = None) -> np.ndarray:
    """Return the Fisher information of a Gaussian signal in smoothed white noise.

    Parameters
    ----------
    columns : numpy.ndarray
        (n_raw, p): the derivatives of the raw (unsmoothed) mean with respect to each
        parameter, at ``pad`` raw samples before the window, the window's samples and ``pad``
        after (enough for the smoothing to see: its kernel's reach either way).
    sigma : float
        The raw noise, white, K.
    kernel, center
        The smoothing (`smoothing_kernel`); None: no smoothing.
    pad : int
        Raw samples each side of the window.
    extra : numpy.ndarray, optional
        (n, n): a further noise covariance on the window's (smoothed) samples, K^2
        (`drift_covariance`); then the information is ``D^T (sigma^2 H H^T + extra)^-1 D``,
        solved densely.

    Returns
    -------
    numpy.ndarray
        (p, p): ``D^T (H H^T)^-1 D / sigma^2``, ``D`` the smoothed columns on the window.
    """
    from scipy.linalg import solveh_banded

    if not sigma > 0:
        raise ValueError("sigma must be positive")
    cols = np.atleast_2d(np.asarray(columns, dtype=float).T).T
    n = cols.shape[0] - 2 * pad
    if n < 1:
        raise ValueError("the window holds no sample")
    if extra is None and (kernel is None or np.asarray(kernel).size == 1):
        gain = 1.0 if kernel is None else float(np.asarray(kernel)[0])
        d = gain * cols[pad:pad + n]
        return d.T @ d / (gain**2 * sigma**2)
    h = np.ones(1) if kernel is None else np.asarray(kernel, dtype=float)
    d = np.column_stack([_smoothed(c, h, center) for c in cols.T])[pad:pad + n]
    r = np.correlate(h, h, "full")[h.size - 1:]  # the smoothed noise's autocovariance
    if extra is not None:
        from scipy.linalg import cho_factor, cho_solve, toeplitz

        if np.shape(extra) != (n, n):
            raise ValueError(f"extra must be ({n}, {n}), got {np.shape(extra)}")
        lags = np.zeros(n)
        lags[:min(r.size, n)] = r[:n]
        cov = sigma**2 * toeplitz(lags) + np.asarray(extra, dtype=float)
        return d.T @ cho_solve(cho_factor(cov), d)
    band = min(r.size - 1, n - 1)
    ab = np.zeros((band + 1, n))
    for k in range(band + 1):
        ab[band - k, k:] = r[k]
    return d.T @ solveh_banded(ab, d) / sigma**2


def efficient_sd(info: np.ndarray) -> float:
    """Return the bound on the first parameter's sd: the others' block projected out.

    ``1 / sqrt(J00 - J0n Jnn^-1 Jn0)`` (the Schur complement); ``inf`` where it is not
    positive (the samples say nothing of the first parameter apart from the others).
    """
    j = np.atleast_2d(np.asarray(info, dtype=float))
    eff = float(j[0, 0])
    if j.shape[0] > 1:
        eff -= float(j[0, 1:] @ np.linalg.lstsq(j[1:, 1:], j[1:, 0], rcond=None)[0])
    return 1.0 / math.sqrt(eff) if eff > 1e-12 * max(float(j[0, 0]), 1e-300) else math.inf


def onset_crb(template: np.ndarray, fs: float, sigma: float, start: int, stop: int,
              kernel: np.ndarray | None = None, center: int = 0,
              drift: np.ndarray | None = None) -> dict[str, float]:
    """Return the Cramér-Rao bounds on an onset's sd from the raw samples ``start..stop-1``.

    Parameters
    ----------
    template : numpy.ndarray
        The noise-free change of the raw reading, K, at its sample 0 (the first at or after
        the onset) and on; 0 before it, held at its last value past its end.
    fs : float
        Sampling rate, Hz.
    sigma : float
        The raw noise, white, K.
    start, stop : int
        The window, raw samples relative to the template's sample 0 (``start`` < 0: samples
        before the onset).
    kernel, center
        The smoothing (`smoothing_kernel`); None: none.
    drift : numpy.ndarray, optional
        The disturbances' covariance on the window's samples (`drift_covariance`, at least
        ``stop - start`` square: its leading block is taken); adds ``gain_offset_drift``.

    Returns
    -------
    dict
        ``known``, ``gain`` and ``gain_offset`` (s; see the module docstring), and with
        ``drift`` ``gain_offset_drift``.
    """
    m = np.asarray(template, dtype=float)
    if stop <= start:
        raise ValueError("the window holds no sample")
    h = None if kernel is None else np.asarray(kernel, dtype=float)
    pad = 0 if h is None else max(center, h.size - 1 - center)
    idx = np.arange(start - pad, stop + pad)
    grid = np.arange(start - pad - 1, stop + pad + 1)  # a sample more each side: gradient
    if m.size:
        mean = np.where(grid < 0, 0.0, m[np.clip(grid, 0, m.size - 1)])
    else:
        mean = np.zeros(grid.size)
    slope = np.gradient(mean, 1.0 / fs)
    slope[grid < 0] = 0.0  # nothing moves before the onset, whatever the shift
    mu = mean[1:-1]
    deriv = -slope[1:-1]  # d mu / d t0 = -m'(t - t0)
    cols = np.column_stack([deriv, mu, np.ones(idx.size)])
    info = fisher_matrix(cols, sigma, h, center, pad)
    out = {"known": efficient_sd(info[:1, :1]), "gain": efficient_sd(info[:2, :2]),
           "gain_offset": efficient_sd(info)}
    if drift is not None:
        n = stop - start
        out["gain_offset_drift"] = efficient_sd(
            fisher_matrix(cols, sigma, h, center, pad, np.asarray(drift)[:n, :n]))
    return out


def drift_covariance(sensor: object, n: int) -> np.ndarray | None:
    """Return the room's walk and the air's flutter as the sensor reads them: (n, n), K^2.

    On ``n`` consecutive samples at the sensor's rate: the room's random walk at
    `skin.stream.onset.AMBIENT_DRIFT` K^2/s and the air's flutter (white noise of
    `skin.bench.streams.FLUTTER` K, scaled by the sensor's heated rise over the paper's,
    through a first-order lag of `skin.bench.streams.FLUTTER_TAU` s, at that sd), each through
    the sensor's loop and lag (`skin.models.sensors.apply_dynamics`) and its smoothing, as
    `skin.bench.streams` puts them on the reading; both begin `DRIFT_HISTORY` of the slowest
    time constant involved before the window (a non-causal smoothing sees past its end too).
    None where that spans more than `DRIFT_MAX_SAMPLES`.
    """
    from scipy.signal import lfilter

    from skin.bench.streams import FLUTTER, FLUTTER_TAU
    from skin.models.sensors import apply_dynamics, load_sensor, smooth
    from skin.stream.onset import AMBIENT_DRIFT

    fs = float(sensor.sample_rate)
    span = {"none": 0.0, "moving-average": sensor.smoothing_window / fs,
            "savgol": sensor.smoothing_window / fs,
            "low-pass": 1.0 / (2.0 * math.pi * sensor.smoothing_cutoff)}[sensor.smoothing]
    slowest = max(FLUTTER_TAU, sensor.lag, span,
                  sensor.control_time if sensor.heater == "pid" else 0.0)
    history = math.ceil(DRIFT_HISTORY * slowest * fs)
    after = sensor.smoothing_impulse().size // 2
    total = history + n + after
    if total > DRIFT_MAX_SAMPLES:
        return None
    unit = np.zeros((total + 1, total))  # a zero first row: the filters start settled at 0
    unit[1:] = np.eye(total)

    def read(x: np.ndarray) -> np.ndarray:  # the reading's rows of the window
        y = smooth(apply_dynamics(x, sensor, fs, axis=0), sensor, axis=0, fs=fs)
        return y[1 + history:1 + history + n]

    room = read(np.cumsum(unit, axis=0))  # a unit step from each sample on
    cov = (AMBIENT_DRIFT / fs) * (room @ room.T)
    del room
    a = math.exp(-1.0 / (FLUTTER_TAU * fs))
    flutter = read(lfilter([1.0 - a], [1.0, -a], unit, axis=0)
                   * math.sqrt(2.0 * FLUTTER_TAU * fs))
    scale = sensor.heated_rise / load_sensor("paper").heated_rise
    cov += (FLUTTER * scale) ** 2 * (flutter @ flutter.T)
    return cov


def contact_bounds(stream: object, sensor: object, which: Sequence[int],
                   progress: Callable[[int, int], None] | None = None) -> dict[str, np.ndarray]:
    """Return each variant's bound (s) for the contacts ``which`` of a described stream.

    The windows of the module docstring: the refinement's (`skin.stream.onset_refine.
    refine_span` about the true onset, up to the release) for ``known``, ``gain`` and
    ``gain_offset``, evaluate-onset's credit window for ``known_credited`` (the template's
    whole length: it ends there).
    """
    from skin.bench.onset_eval import EARLY
    from skin.stream.onset_refine import refine_span

    fs, sigma = stream.fs, float(stream.raw_noise)
    if not sigma > 0:
        from skin.errors import SkinError

        raise SkinError("the stream carries no raw noise: simulate it with a sensor")
    kernel, center = smoothing_kernel(sensor)
    search, horizon = refine_span(sensor)
    out = {v: np.full(len(which), np.inf) for v in VARIANTS}
    windows = []
    for k in which:
        c, m = stream.contacts[k], stream.templates[k]
        first = math.ceil(c.onset * fs)  # the template's sample 0
        start = math.ceil((c.onset - search) * fs) - first
        stop = min(math.ceil(c.release * fs), math.ceil((c.onset + search + horizon) * fs))
        windows.append((first, start, min(max(stop - first, 1), max(m.size, 1))))
    # one covariance for the longest window: a shorter one's is its leading block
    drift = drift_covariance(sensor, max(b - a for _, a, b in windows)) if windows else None
    if drift is None:
        out["gain_offset_drift"][:] = np.nan  # not computed
    for i, (k, (first, start, stop)) in enumerate(zip(which, windows, strict=True)):
        c, m = stream.contacts[k], stream.templates[k]
        for name, sd in onset_crb(m, fs, sigma, start, stop, kernel, center, drift).items():
            out[name][i] = sd
        early = math.ceil((c.onset - EARLY) * fs) - first
        out["known_credited"][i] = onset_crb(m, fs, sigma, early, max(m.size, 1), kernel,
                                             center)["known"]
        if progress is not None:
            progress(i + 1, len(which))
    return out


def median_draws(sd: np.ndarray, draws: int, rng: np.random.Generator) -> np.ndarray:
    """Return ``draws`` medians over the contacts of ``|N(0, sd_k)|`` errors, s."""
    sd = np.asarray(sd, dtype=float)
    out = np.empty(draws)
    if sd.size == 0:
        out[:] = np.nan
        return out
    for a in range(0, draws, _CHUNK):
        b = min(a + _CHUNK, draws)
        errors = np.abs(rng.standard_normal((b - a, sd.size))) * sd
        out[a:b] = np.median(errors, axis=1)
    return out


def summarise(medians: np.ndarray, target_ms: float) -> dict:
    """Return the median of the drawn medians, their 5-95 % interval (ms) and P(<= target)."""
    m = 1e3 * np.asarray(medians, dtype=float)
    if m.size == 0 or np.all(np.isnan(m)):
        return {"median_ms": None, "p5_p95_ms": None, "p_meets_target": None}
    lo, mid, hi = np.percentile(m, [5, 50, 95], method="lower")
    return {"median_ms": _ms(mid), "p5_p95_ms": [_ms(lo), _ms(hi)],
            "p_meets_target": round(float(np.mean(m <= target_ms)), 4)}


def _ms(value: float) -> float | str:
    return "inf" if not np.isfinite(value) else round(float(value), 2)


def measure_refine_bound(sensor: object, seed: int = 0, minutes: float = 15.0,
                         taxels: int = 16, draws: int = 20000,
                         progress: Callable[[int, int, str], None] | None = None) -> dict:
    """Measure the onset's Cramér-Rao bounds and the library's refined onset on one stream.

    Parameters
    ----------
    sensor : skin.models.sensors.SensorDescription
        The stream's sensor.
    seed, minutes, taxels
        As for ``skin evaluate-onset`` (`skin.bench.delay_bound.onset_stream`).
    draws : int
        Monte-Carlo medians per variant (`median_draws`; generator seeded ``seed + 15485863``).
    progress : callable, optional
        Called as ``progress(done, total, label)``.

    Returns
    -------
    dict
        The figures (see ``skin bench refine-bound --help``).
    """
    from skin.bench.delay_bound import _run_detector, onset_stream
    from skin.bench.onset_eval import onset_error_target

    if draws < 1:
        raise ValueError(f"draws must be >= 1, got {draws}")
    stream = onset_stream(sensor, seed, minutes, taxels)
    contacts = stream.contacts
    which = [k for k, c in enumerate(contacts) if np.isfinite(c.visible_after)]
    target = onset_error_target([contacts[k].visible_after for k in which])
    tick = None if progress is None else (lambda d, n: progress(d, n, "samples"))
    res, _ = _run_detector(stream, sensor, tick)
    if tick is not None:
        tick(stream.times.size, stream.times.size)
    flags, errors = res["detected_flags"], res["onset_error_s"]
    # evaluate-onset's refined_onset_error_ms_median: over every detected contact
    dated = np.abs([errors[k] for k in range(len(contacts)) if flags[k]])
    tick = None if progress is None else (lambda d, n: progress(d, n, "contacts"))
    sds = contact_bounds(stream, sensor, which, tick)
    found = np.array([bool(flags[k]) for k in which], dtype=bool)
    rng = np.random.default_rng(seed + 15485863)
    variants = {}
    for name in VARIANTS:
        sd = sds[name]
        if sd.size and np.all(np.isnan(sd)):  # not computed (`drift_covariance`: too long)
            none = {"median_ms": None, "p5_p95_ms": None, "p_meets_target": None}
            variants[name] = {"sd_ms_median": None, "contacts_inf": 0, **none,
                              "detected": dict(none)}
            continue
        variants[name] = {
            "sd_ms_median": _ms(1e3 * float(np.median(sd))) if sd.size else None,
            "contacts_inf": int(np.sum(~np.isfinite(sd))),
            **summarise(median_draws(sd, draws, rng), target),
            "detected": summarise(median_draws(sd[found], draws, rng), target),
        }
    lib = np.array([abs(errors[k]) for k in which if flags[k]], dtype=float)
    ratio = lib / sds["gain_offset"][found] if lib.size else np.zeros(0)
    drifted = lib / sds["gain_offset_drift"][found] if lib.size else np.zeros(0)
    return {
        "sensor": sensor.name, "seed": seed, "fs": stream.fs, "minutes": minutes,
        "taxels": taxels, "raw_noise_k": round(float(stream.raw_noise), 6),
        "contacts": len(contacts), "contacts_with_floor": len(which),
        "detected_with_floor": int(found.sum()),
        "floor_ms_median": (round(1e3 * float(np.median([contacts[k].visible_after
                                                        for k in which])), 1)
                            if which else None),
        "refined_onset_target_ms": target,
        "library_refined_onset_error_ms_median": (round(1e3 * float(np.median(dated)), 1)
                                                  if dated.size else None),
        "library_detected": res["detected"],
        "library_error_ms_median_with_floor": (round(1e3 * float(np.median(lib)), 1)
                                               if lib.size else None),
        "library_error_over_gain_offset_sd_median": (round(float(np.median(ratio)), 3)
                                                     if ratio.size else None),
        # ... and of the bound with the room's drift and the air's flutter (None: not computed)
        "library_error_over_gain_offset_drift_sd_median": (
            round(float(np.median(drifted)), 3)
            if drifted.size and not np.all(np.isnan(drifted)) else None),
        "draws": draws, "bounds": variants,
    }

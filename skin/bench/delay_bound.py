"""The delay an oracle detector reaches at a false-alarm target: a near-optimal reference.

Issue 16 asks for a median detection delay within 1.5 times the physical floor (when a
contact's noise-free reading first moves 3 sigma) at 0.1 false alarms per taxel-hour. Whether
that is reachable at all is a question of the sensor, not of a detector: this module measures
it with a detector that is told more than any real one can know.

For each contact of a simulated stream (`skin.bench.streams.simulate_stream` with a sensor),
the oracle is told

- the contact's exact noise-free change of the reading (``Stream.templates``: through the
  sensor's loop and lag, as `skin.bench.streams.StreamContact.visible_after` measures the
  floor), sign and size included;
- the sensor's raw noise, white and Gaussian (``noise_kelvin``: its noise, ADC noise and
  rounding), and its smoothing: it reads the samples *before* the smoothing, which carry all
  the information of the smoothed ones, and with a non-causal smoothing (Savitzky-Golay) the
  samples up to half the window ahead of the time stamp, as the smoothed sample there has
  seen them;
- that nothing else happens: no gusts, room drift or heater switching, the baseline known.

It is the window-limited generalised likelihood ratio test (Lai 1998): at every sample ``n``,
``max_k L_k(n)`` over the candidate onsets ``n - W < k <= n``, ``L_k(n) = sum_{i=k..n}
(m_{i-k} x_i - m_{i-k}^2 / 2) / sigma^2`` (``m`` the template, ``x`` the reading less the
baseline), alarmed at the first ``n`` where it reaches a threshold ``h``, and restarted after
an alarm. The threshold is set *by simulation*, per contact: the test is run with the
contact's own template on pure noise of the sensor (`false_alarm_counts`), its alarms are
counted at a ladder of thresholds, and the rate is carried to the target along its
large-threshold form ``rate(h) = exp(a - h) h^b`` (each ``L_k`` is a likelihood ratio, whose
tail is ``exp(-h)``; ``b`` fitted, clipped to [-1, 2]; `oracle_threshold`).
`false_alarm_check` then runs the test at that threshold on a longer stretch of noise and
reports the rate it actually gave.

The oracle's delay (the first alarm at or after the onset, on fresh noise; ``inf`` if none by
the end of the window in which `skin evaluate-onset` still credits an alarm to the contact)
over the contact's floor is reported per contact. The oracle knows more than a real detector
and meets no disturbance, but it is near-optimal, not provably optimal: the GLR is
asymptotically optimal for the mean delay (Lai 1998), not for the median at a finite
threshold, and the threshold is an extrapolation (checked against Siegmund's closed form for
a step and by the noise-only runs). So a median above 1.5 makes issue 16's target very
unlikely for the sensor, not provably impossible; a median below it says the target is not
ruled out.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

#: Issue 16's false-alarm target, per taxel-hour.
TARGET_FALSE_ALARMS = 0.1
#: Matrix elements (onsets x lags) handled at a time.
_BLOCK = 1 << 21


def max_lag(template: np.ndarray, sigma: float, level: float, cap: int = 2000) -> int:
    """Return how many lags the test weighs: until the template's information is ``level``.

    Lags beyond the one where ``sum(m**2) / (2 sigma**2)`` reaches ``level`` add nothing a
    detection needs (by then the true onset's ratio has crossed, bar a rare noise draw),
    and a pure-noise ratio with that much information rarely reaches the threshold. At most
    ``cap`` and the template's length.
    """
    m = np.asarray(template, dtype=float)
    info = np.cumsum(m**2) / (2.0 * sigma**2)
    reach = int(np.searchsorted(info, level)) + 1
    return max(1, min(reach, m.size, cap))


def _ratios(x: np.ndarray, template: np.ndarray, sigma: float, lags: int,
            first: int, last: int) -> np.ndarray:
    """Return ``L[k, j] = L_{first + k}(first + k + j)`` for the onsets first..last-1.

    ``x`` must hold samples up to ``last - 1 + lags``.
    """
    from numpy.lib.stride_tricks import sliding_window_view

    m = np.asarray(template[:lags], dtype=float)
    view = sliding_window_view(x[first:last - 1 + lags], lags)
    return np.cumsum(view * (m / sigma**2) - (m**2 / (2.0 * sigma**2)), axis=1)


def _running_max(x: np.ndarray, template: np.ndarray, sigma: float, lags: int,
                 first: int, last: int) -> np.ndarray:
    """Return ``R[k, j] = max_{i <= j} L_{first + k}(first + k + i)`` (see `_ratios`)."""
    return np.maximum.accumulate(_ratios(x, template, sigma, lags, first, last), axis=1)


def first_alarms(x: np.ndarray, template: np.ndarray, sigma: float, lags: int,
                 thresholds: Sequence[float]) -> np.ndarray:
    """Return, for each threshold and each candidate onset k, the sample of its first alarm.

    Onsets ``k = 0 .. len(x) - lags``; the alarm of onset k is ``k + j`` for the first lag
    ``j < lags`` at which ``L_k`` reaches the threshold, ``-1`` if none.

    Returns
    -------
    numpy.ndarray
        (n_thresholds, n_onsets), int64.
    """
    hs = np.asarray(thresholds, dtype=float)
    n_onsets = len(x) - lags + 1
    out = np.full((hs.size, max(n_onsets, 0)), -1, dtype=np.int64)
    step = max(1, _BLOCK // lags)
    for a in range(0, n_onsets, step):
        b = min(a + step, n_onsets)
        run = _running_max(x, template, sigma, lags, a, b)
        top = run[:, -1]
        for i, h in enumerate(hs):
            hit = top >= h
            if hit.any():
                j = np.sum(run[hit] < h, axis=1)
                out[i, a:b][hit] = np.arange(a, b)[hit] + j
    return out


def count_alarms(alarms: np.ndarray) -> int:
    """Return how many alarms a restarted test raises, given each onset's first alarm.

    ``alarms[k]`` is onset k's alarm sample (-1: none). The test alarms at the earliest of
    them; after an alarm at ``n`` it restarts and weighs only onsets after ``n``.
    """
    a = np.where(alarms < 0, np.iinfo(np.int64).max, alarms)
    if a.size == 0:
        return 0
    suffix = np.minimum.accumulate(a[::-1])[::-1]  # earliest alarm of the onsets >= k
    count, k = 0, 0
    big = np.iinfo(np.int64).max
    while k < a.size and suffix[k] < big:
        n = int(suffix[k])
        count += 1
        k = n + 1
    return count


def false_alarm_counts(template: np.ndarray, sigma: float, samples: int, lags: int,
                       thresholds: Sequence[float], rng: np.random.Generator) -> np.ndarray:
    """Count the test's alarms on ``samples`` of white noise of ``sigma``, per threshold."""
    x = rng.normal(0.0, sigma, samples + lags - 1)
    alarms = first_alarms(x, template, sigma, lags, thresholds)
    return np.array([count_alarms(row) for row in alarms])


def noise_counts(template: np.ndarray, sigma: float, fs: float, rng: np.random.Generator,
                 false_alarms: float = TARGET_FALSE_ALARMS, budget: float = 4e6,
                 min_seconds: float = 60.0) -> dict:
    """Count the test's alarms on pure noise at a ladder of thresholds (3 nats up by 0.5).

    The noise runs as long as ``budget`` matrix elements (onsets x lags) allow, at least
    ``min_seconds``. The test's window is `max_lag` at 4 ln ARL (ARL: the samples per false
    alarm at the target).

    Returns
    -------
    dict
        ``lags``, ``hours`` of noise, ``thresholds`` (nats), ``counts``.
    """
    if not (sigma > 0 and fs > 0 and false_alarms > 0):
        raise ValueError("sigma, fs and false_alarms must be positive")
    log_arl = math.log(fs * 3600.0 / false_alarms)
    lags = max_lag(template, sigma, 4.0 * log_arl)
    samples = int(max(budget / lags, min_seconds * fs))
    hs = np.arange(3.0, log_arl + 4.0, 0.5)
    counts = false_alarm_counts(template, sigma, samples, lags, hs, rng)
    return {"lags": lags, "hours": samples / fs / 3600.0, "thresholds": hs, "counts": counts,
            "samples_per_hour": fs * 3600.0}


def fit_tails(runs: Sequence[dict],
              least: int = 10) -> tuple[np.ndarray, np.ndarray, float | None, np.ndarray]:
    """Fit each run's alarm counts (`noise_counts`) with ``rate(h) = exp(a_i - h) h^b_i``.

    Each run's count at threshold h is taken as ``hours exp(a_i - h) h^b``: ``exp(-h)`` the
    tail of a likelihood ratio, ``a_i`` the run's own (how many nearly independent onsets its
    template's test weighs per hour), ``b`` shared by the runs (the templates of one sensor
    differ in size and speed, not in kind) and clipped to [-1, 2]; fitted by least squares on
    ``log count + h`` over the thresholds with at least ``least`` alarms. A run with none
    there (no alarm even at 3 nats) falls back to ``a_i = log`` of its samples per hour and
    ``b_i = 0``: the bound ``exp(-h)`` per onset (ln ARL), which can only set its threshold
    too high.

    Returns
    -------
    a : numpy.ndarray
        ``a_i``, one per run (per hour).
    b_each : numpy.ndarray
        The exponent each run uses (``b``, or 0 where it fell back).
    b : float or None
        The shared exponent; None if no run had two thresholds with ``least`` alarms.
    fitted : numpy.ndarray of bool
        False where the run fell back to the ln ARL bound.
    """
    xs, ys, groups = [], [], []
    for i, run in enumerate(runs):
        ok = np.asarray(run["counts"]) >= least
        h = np.asarray(run["thresholds"], dtype=float)[ok]
        xs.append(np.log(h))
        ys.append(np.log(np.asarray(run["counts"], dtype=float)[ok]) + h)
        groups.append(np.full(h.size, i))
    if not runs:
        return np.zeros(0), np.zeros(0), None, np.zeros(0, dtype=bool)
    x, y, g = np.concatenate(xs), np.concatenate(ys), np.concatenate(groups)
    num = den = 0.0
    for i in range(len(runs)):
        sel = g == i
        if sel.sum() >= 2:
            dx, dy = x[sel] - x[sel].mean(), y[sel] - y[sel].mean()
            num += float(dx @ dy)
            den += float(dx @ dx)
    b = float(np.clip(num / den, -1.0, 2.0)) if den > 0 else None
    a = np.empty(len(runs))
    b_each = np.zeros(len(runs))
    fitted = np.zeros(len(runs), dtype=bool)
    for i, run in enumerate(runs):
        sel = g == i
        if sel.any():
            bb = b if b is not None else 0.0
            a[i] = float(np.mean(y[sel] - bb * x[sel])) - math.log(run["hours"])
            b_each[i], fitted[i] = bb, True
        else:
            a[i] = math.log(run["samples_per_hour"])
    return a, b_each, b, fitted


def tail_rate(a: float, b: float, h: float) -> float:
    """Return the fitted false alarms per hour at threshold ``h``: ``exp(a - h) h^b``."""
    return math.exp(a - h + b * math.log(h))


class TailFit(NamedTuple):
    """The thresholds `fit_thresholds` carries each run to, and the tails it fitted."""

    #: Nats, one per run: where its fitted tail reaches the target rate.
    thresholds: np.ndarray
    #: The shared exponent (None: nothing fitted, every run on the ln ARL bound).
    b: float | None
    #: Each run's ``a_i`` (per hour) and the exponent it uses (`fit_tails`).
    a: np.ndarray
    b_each: np.ndarray
    #: False where the run fell back to the ln ARL bound.
    fitted: np.ndarray


def fit_thresholds(runs: Sequence[dict], false_alarms: float = TARGET_FALSE_ALARMS,
                   least: int = 10) -> TailFit:
    """Carry each run's alarm counts (`noise_counts`) to the threshold of the target rate.

    Along the tail `fit_tails` fits (``a_i - h + b_i ln h = ln false_alarms``). The one
    place the bench sets thresholds: `contact_delays` and `oracle_threshold` both use it.

    Returns
    -------
    TailFit
        ``thresholds`` (nats, one per run), ``b`` (the shared exponent, None if nothing was
        fitted), and `fit_tails`' ``a``, ``b_each`` and ``fitted``.
    """
    a, b_each, b, fitted = fit_tails(runs, least)
    out = np.array([_solve(float(ai), float(bi), math.log(false_alarms))
                    for ai, bi in zip(a, b_each, strict=True)])
    return TailFit(out, b, a, b_each, fitted)


def _solve(a: float, b: float, target: float) -> float:
    """Return the h > max(b, 0.5) with ``a - h + b ln h = target`` (bisection)."""
    lo, hi = max(b, 0.5), 500.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if a - mid + b * math.log(mid) > target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def oracle_threshold(template: np.ndarray, sigma: float, fs: float, rng: np.random.Generator,
                     false_alarms: float = TARGET_FALSE_ALARMS,
                     budget: float = 4e6) -> tuple[float, int, dict]:
    """Set one template's threshold for ``false_alarms`` per hour.

    `noise_counts`, then `fit_thresholds` on that run alone.

    Returns
    -------
    threshold : float
        Nats.
    lags : int
        The test's window W, samples.
    run : dict
        `noise_counts`' figures and the fitted ``b``.
    """
    run = noise_counts(template, sigma, fs, rng, false_alarms, budget)
    fit = fit_thresholds([run], false_alarms)
    return float(fit.thresholds[0]), run["lags"], {**run, "b": fit.b}


def false_alarm_check(template: np.ndarray, sigma: float, fs: float, threshold: float,
                      lags: int, hours: float, rng: np.random.Generator,
                      below: Sequence[float] = (0.0, 2.0, 4.0)) -> list[dict]:
    """Run the test on ``hours`` of pure noise and count its alarms at the threshold.

    Also at the threshold lowered by each of ``below`` nats, where the fitted tail
    (`tail_rate`) says the rate is about ``exp(below)`` times the target's (a check of the
    extrapolation with more alarms than the target rate gives). The noise comes in blocks,
    so memory stays bounded.

    Returns
    -------
    list of dict
        ``threshold``, ``alarms``, ``hours``, ``per_hour`` for each.
    """
    hs = [threshold - d for d in below]
    total = round(hours * fs * 3600.0)
    block = max(int(5e7 // lags), 10 * lags)
    counts = np.zeros(len(hs), dtype=int)
    done = 0
    while done < total:
        n = min(block, total - done)
        counts += false_alarm_counts(template, sigma, n, lags, hs, rng)
        done += n
    h_real = done / fs / 3600.0
    return [{"threshold": round(h, 3), "alarms": int(c), "hours": round(h_real, 3),
             "per_hour": round(c / h_real, 4) if h_real > 0 else None}
            for h, c in zip(hs, counts, strict=True)]


def oracle_delay(template: np.ndarray, sigma: float, threshold: float, lags: int,
                 rng: np.random.Generator, repeats: int = 1) -> np.ndarray:
    """Return the sample index (since the onset) of the test's first alarm, per noise draw.

    The reading is ``template`` from sample 0 on (0 before) plus white noise of ``sigma``;
    candidate onsets start ``lags - 1`` samples before the onset, so every window the test
    weighs at or after the onset is full. An alarm before the onset (a false alarm, at the
    target rate) is not counted; ``-1`` if no alarm by the template's end (not detectable
    within the window in which an alarm still counts as the contact's).
    """
    m = np.asarray(template, dtype=float)
    out = np.full(repeats, -1, dtype=np.int64)
    pre = lags - 1
    end = pre + m.size
    never = np.iinfo(np.int64).max
    step = max(1, _BLOCK // lags)
    for r in range(repeats):
        x = np.concatenate([np.zeros(pre), m]) + rng.normal(0.0, sigma, end)
        x = np.concatenate([x, np.zeros(lags - 1)])  # past the data: masked below
        best = never
        for a in range(0, end, step):
            if a > best:  # no later onset alarms earlier
                break
            b = min(a + step, end)
            ratio = _ratios(x, m, sigma, lags, a, b)
            n = np.arange(a, b)[:, None] + np.arange(lags)[None, :]
            hit = (ratio >= threshold) & (n >= pre) & (n < end)
            if hit.any():
                best = min(best, int(np.min(np.where(hit, n, never))))
        if best < never:
            out[r] = best - pre
    return out


def detection_probability(template: np.ndarray, sigma: float, threshold: float, lags: int,
                          rng: np.random.Generator, repeats: int = 20) -> float:
    """Return the share of ``repeats`` noise draws in which the test alarms on the contact.

    `oracle_delay`'s alarm at or after the onset, by the template's end (the end of the
    window in which `skin evaluate-onset` still credits an alarm to the contact).
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    return float(np.mean(oracle_delay(template, sigma, threshold, lags, rng, repeats) >= 0))


def lookahead(sensor: object) -> int:
    """Return how many raw samples past its time stamp a smoothed sample has seen.

    Half the window of a non-causal Savitzky-Golay smoothing; 0 for none or a causal one.
    """
    if getattr(sensor, "smoothing", "none") == "savgol":
        return int(sensor.smoothing_window) // 2
    return 0


def contact_delays(stream: object, sensor: object, which: Sequence[int],
                   rng: np.random.Generator, false_alarms: float = TARGET_FALSE_ALARMS,
                   budget: float = 4e6,
                   progress: object | None = None) -> dict:
    """Return the oracle's threshold and delay for the contacts ``which`` of a stream.

    Parameters
    ----------
    stream : skin.bench.streams.Stream
        A described sensor's stream (its ``templates``).
    sensor : skin.models.sensors.SensorDescription
        Its sensor: the smoothing's look-ahead (`lookahead`). The raw noise is the stream's
        own (``Stream.raw_noise``: ``noise_kelvin`` at the heated taxel over the stream's
        ambient, as the stream draws it).
    which : sequence of int
        Indices of ``stream.contacts``.
    rng : numpy.random.Generator
        The noise of the threshold runs and of the oracle's own readings.
    false_alarms, budget
        As for `noise_counts`.
    progress : callable, optional
        Called as ``progress(done, total)``.

    Returns
    -------
    dict
        ``delay_s`` (one per contact of ``which``; ``inf``: no alarm by the end of the window
        in which an alarm still counts as the contact's; at the time stamp of the smoothed
        sample that has seen the raw sample it alarmed on), ``delay_no_lookahead_s`` (at the
        raw sample's own time), ``delay_plus_1_s`` (the threshold 1 nat higher, on the
        same noise: how much the figure hangs on the threshold), ``threshold`` (nats),
        ``lags``, ``b`` (the shared tail exponent, None if nothing was fitted), ``tail_a``
        and ``tail_b`` (each contact's fitted tail, `fit_tails`), ``fitted`` (False: the
        contact fell back to the ln ARL threshold), ``runs`` (`noise_counts` per contact),
        ``sigma``.
    """
    if stream.contacts and len(stream.templates) != len(stream.contacts):
        from skin.errors import SkinError

        raise SkinError(f"the stream has {len(stream.contacts)} contacts but "
                        f"{len(stream.templates)} templates: simulate it with a sensor "
                        "(skin.bench.streams.simulate_stream(..., sensor=...))")
    sigma = float(stream.raw_noise)
    if not sigma > 0:
        from skin.errors import SkinError

        raise SkinError("the stream carries no raw noise: simulate it with a sensor")
    fs = stream.fs
    ahead = lookahead(sensor)
    runs = []
    for i, k in enumerate(which):
        runs.append(noise_counts(stream.templates[k], sigma, fs, rng, false_alarms, budget))
        if progress is not None:
            progress(i + 1, 2 * len(which))
    fit = fit_thresholds(runs, false_alarms)
    thresholds = fit.thresholds
    delays = np.full(len(which), np.inf)
    seen = np.full(len(which), np.inf)  # at the raw sample's own time, no look-ahead
    higher = np.full(len(which), np.inf)  # the threshold 1 nat higher, the same noise
    for i, k in enumerate(which):
        c = stream.contacts[k]
        first = math.ceil(c.onset * fs)  # the template's sample 0
        noise = int(rng.integers(2**62))
        for extra, into in ((0.0, delays), (1.0, higher)):
            j = int(oracle_delay(stream.templates[k], sigma, float(thresholds[i]) + extra,
                                 runs[i]["lags"], np.random.default_rng(noise))[0])
            if j >= 0:
                into[i] = max((first + j - ahead) / fs - c.onset, 0.0)
                if extra == 0.0:
                    seen[i] = (first + j) / fs - c.onset
        if progress is not None:
            progress(len(which) + i + 1, 2 * len(which))
    return {"delay_s": delays, "delay_no_lookahead_s": seen, "delay_plus_1_s": higher,
            "threshold": thresholds,
            "lags": [r["lags"] for r in runs], "b": fit.b, "tail_a": fit.a,
            "tail_b": fit.b_each, "fitted": fit.fitted, "runs": runs, "sigma": sigma}


def _median_ratio(values: Sequence[float]) -> float | None:
    """Median of ratios that may be ``inf`` (not detectable); None if there are none.

    ``inf`` when more than half are not detectable (the caller says so, never NaN).
    """
    if len(values) == 0:
        return None
    return float(np.median(np.asarray(values, dtype=float)))


def _quartiles(values: Sequence[float]) -> list | None:
    """Return the 25th and 75th percentiles of ratios for JSON (`_json_ratio`); None if none.

    Order statistics (numpy's ``method="lower"``): with ``inf`` among the ratios (not
    detectable) an interpolated percentile is NaN; an order statistic is a ratio or
    ``"not detectable"``.
    """
    if len(values) == 0:
        return None
    return [_json_ratio(float(np.percentile(np.asarray(values, dtype=float), q,
                                            method="lower"))) for q in (25, 75)]


def _json_ratio(value: float | None) -> float | str | None:
    """Return a ratio for JSON: rounded, ``"not detectable"`` for ``inf``."""
    if value is None:
        return None
    return "not detectable" if not np.isfinite(value) else round(value, 3)


def measure_delay_bound(sensor: object, seed: int = 0, minutes: float = 15.0,
                        taxels: int = 16, false_alarms: float = TARGET_FALSE_ALARMS,
                        check_hours: float | None = None, detector: bool = False,
                        budget: float = 4e6, min_duration: float = 0.3,
                        detection_repeats: int = 20, disturbances: bool = False,
                        null_hours: float = 40.0, grid_factor: float = 1.0,
                        pre: float = 2.0, freeze: bool = True,
                        progress: object | None = None) -> dict:
    """Measure the oracle's delay against the floor on `skin evaluate-onset`'s own stream.

    The stream is the one ``skin evaluate-onset --sensor S --seed N`` simulates (the same
    materials, taxels, minutes and contact rate, disturbances on: the same contacts; the
    oracle sees none of the disturbances). Every contact with a finite floor is given the
    oracle (`contact_delays`; its noise from a generator seeded ``seed + 7919``).

    Parameters
    ----------
    sensor : skin.models.sensors.SensorDescription
        The stream's sensor.
    seed, minutes, taxels
        As for ``skin evaluate-onset``.
    false_alarms : float
        The target, per taxel-hour.
    check_hours : float, optional
        Hours of pure noise for `false_alarm_check` on each of the contacts of lowest, median
        and highest threshold (default: as many as 1e8 matrix elements take, at least 1).
    detector : bool
        Also run the real detector over the stream as ``skin evaluate-onset --sensor``
        does, and give its delay / floor beside the oracle's on the same contacts.
    budget : float
        Matrix elements per contact's threshold run (`noise_counts`).
    min_duration : float
        Contacts this long count towards the 5-sigma figures, whose noise sigma is the
        detector's (median over taxels): exactly the contacts of evaluate-onset's
        ``detected_5sigma`` (`skin.bench.onset_eval.five_sigma`).
    detection_repeats : int
        Noise draws per 5-sigma contact for the oracle's detection probability
        (``oracle_detected_5sigma``: the mean over the 5-sigma contacts of the share of draws
        in which the oracle, at its own threshold for ``false_alarms``, alarms by the end of
        the window in which evaluate-onset still credits an alarm to the contact).
    disturbances : bool
        Also give the disturbance-aware oracle's detection of the 5-sigma contacts
        (`skin.bench.gust_oracle.measure_gust_oracle`: the contact told from the best-fitting
        gust or heater switch of the streams' own family, drift and flutter in its noise,
        its thresholds set on ``null_hours`` taxel-hours of disturbance-only streams;
        200 draws for a contact whose threshold is found, ``detection_repeats`` for one
        below every null level; the ``disturbance_oracle_*`` figures).
    null_hours, grid_factor, pre, freeze
        As for `skin.bench.gust_oracle.measure_gust_oracle`.
    progress : callable, optional
        Called as ``progress(done, total)``.

    Returns
    -------
    dict
        The figures (see ``skin bench delay-bound --help``).
    """
    import time

    from skin.bench.streams import delay_bound as lorden_bound

    cpu = time.process_time()
    stream = onset_stream(sensor, seed, minutes, taxels)
    contacts = stream.contacts
    fs = stream.fs
    from skin.bench.onset_eval import five_sigma
    from skin.stream.onset import OnsetDetector

    if detection_repeats < 1:
        raise ValueError(f"detection_repeats must be >= 1, got {detection_repeats}")
    which = [k for k, c in enumerate(contacts)
             if np.isfinite(c.visible_after) and c.visible_after > 0]
    # evaluate-onset's 5-sigma contacts: its detector's noise sigma, its duration rule
    plain = OnsetDetector(taxels, sensor=sensor)
    noise5 = float(np.median(plain.sigma))
    noise5_from = ("the detector's noise sigma, median over taxels (as evaluate-onset's "
                   "detected_5sigma)")
    five = [k for k, big in enumerate(five_sigma(contacts, plain, min_duration)) if big]
    # a 5-sigma contact has a floor (3 sigma) unless its reading moved on the onset's own
    # sample; the oracle weighs those too, after the others (their figures unchanged)
    extra = [k for k in five if k not in set(which)]
    weighed = which + extra
    rng = np.random.default_rng(seed + 7919)
    out = contact_delays(stream, sensor, weighed, rng, false_alarms, budget, progress)
    higher = [out["delay_plus_1_s"][i] / contacts[k].visible_after
              for i, k in enumerate(which)]
    ratio = {k: out["delay_s"][i] / contacts[k].visible_after for i, k in enumerate(which)}
    at = {k: i for i, k in enumerate(weighed)}
    # the oracle's detection of the 5-sigma contacts: its own generator, so the delay
    # figures are those of the same seed without it
    rng_detect = np.random.default_rng(seed + 104729)
    chance = {k: detection_probability(stream.templates[k], out["sigma"],
                                       float(out["threshold"][at[k]]), out["lags"][at[k]],
                                       rng_detect, detection_repeats) for k in five}
    run = _run_detector(stream, sensor) if detector else None
    # Lorden's bound at the requested rate, on the contact's change while it lasts (as
    # StreamContact.bound_after, which is at BOUND_FALSE_ALARMS)
    lorden = []
    for k in which:
        c, m = contacts[k], stream.templates[k]
        when = np.arange(math.ceil(c.onset * fs), math.ceil(c.onset * fs) + m.size) / fs \
            - c.onset
        inside = when < c.duration
        lorden.append(lorden_bound(np.abs(m[inside]), when[inside], out["sigma"], fs,
                                   false_alarms) / c.visible_after)
    log_arl = math.log(fs * 3600.0 / false_alarms)
    check = []
    if weighed:
        order = np.argsort(out["threshold"], kind="stable")
        picks = {"lowest": int(order[0]), "median": int(order[len(weighed) // 2]),
                 "highest": int(order[-1])}
        done: dict[int, dict] = {}
        for name, i in picks.items():
            if i in done:
                done[i]["threshold_rank"] += f", {name}"
                continue
            lags = out["lags"][i]
            hours = (check_hours if check_hours is not None
                     else max(1.0, 1e8 / (lags * fs * 3600.0)))
            rows = false_alarm_check(stream.templates[weighed[i]], out["sigma"], fs,
                                     float(out["threshold"][i]), lags, hours, rng)
            a, b = float(out["tail_a"][i]), float(out["tail_b"][i])
            for row, below in zip(rows, (0.0, 2.0, 4.0), strict=True):
                h = float(out["threshold"][i]) - below
                row["expected"] = float(f"{row['hours'] * tail_rate(a, b, h):.3g}")
            done[i] = {"contact": weighed[i], "threshold_rank": name,
                       "tail_fitted": bool(out["fitted"][i]), "runs": rows}
        check = list(done.values())
    values = list(ratio.values())
    result = {
        "sensor": sensor.name, "seed": seed, "fs": fs,
        "raw_noise_k": round(out["sigma"], 6),
        "smoothed_noise_k": round(out["sigma"] * sensor.smoothing_noise_factor(), 6),
        "lookahead_samples": lookahead(sensor), "false_alarms_target": false_alarms,
        "contacts": len(contacts), "contacts_with_floor": len(which),
        "contacts_5sigma": len(five), "five_sigma_noise_k": round(noise5, 6),
        "five_sigma_noise": noise5_from,
        "contacts_5sigma_without_floor": len(extra),
        "oracle_detected_5sigma": (round(float(np.mean(list(chance.values()))), 4)
                                   if five else None),
        "oracle_detected_5sigma_one_draw": (
            round(float(np.mean([np.isfinite(out["delay_s"][at[k]]) for k in five])), 4)
            if five else None),
        # how far the least informative 5-sigma contact clears its own threshold: its
        # template's whole information sum(m^2) / (2 sigma^2) less the threshold, nats (a
        # detector that must cover many templates pays a few nats more than the oracle)
        "oracle_5sigma_information_over_threshold_min": (
            round(min(float(np.sum(stream.templates[k] ** 2)) / (2.0 * out["sigma"] ** 2)
                      - float(out["threshold"][at[k]]) for k in five), 2) if five else None),
        "oracle_5sigma_detected_under_half": int(sum(p < 0.5 for p in chance.values())),
        "oracle_5sigma_detected_under_99": int(sum(p < 0.99 for p in chance.values())),
        "detection_repeats": detection_repeats,
        "oracle_ratio_median": _json_ratio(_median_ratio(values)),
        "oracle_ratio_median_no_lookahead": _json_ratio(_median_ratio(
            [out["delay_no_lookahead_s"][i] / contacts[k].visible_after
             for i, k in enumerate(which)])),
        "oracle_ratio_median_threshold_plus_1": _json_ratio(_median_ratio(higher)),
        "oracle_ratio_median_5sigma": _json_ratio(_median_ratio([ratio[k] for k in five])),
        "oracle_ratio_p25_p75": _quartiles(values),
        "oracle_not_detectable": int(sum(not np.isfinite(r) for r in values)),
        "oracle_over_1_5": round(float(np.mean([r > 1.5 for r in values])), 4)
        if which else None,
        "lorden_ratio_median": _json_ratio(_median_ratio(lorden)),
        "floor_ms_median": round(1e3 * float(np.median([contacts[k].visible_after
                                                        for k in which])), 1) if which else None,
        # every threshold below and the checks: over the contacts the oracle weighs
        # (``which`` and the 5-sigma ones without a floor)
        "threshold_nats_median": (round(float(np.median(out["threshold"])), 3) if weighed
                                  else None),
        "threshold_nats_range": [round(float(np.min(out["threshold"])), 3),
                                 round(float(np.max(out["threshold"])), 3)] if weighed
        else None,
        "ln_arl_nats": round(log_arl, 3),
        "tail_exponent_b": round(out["b"], 3) if out["b"] is not None else None,
        "thresholds_at_ln_arl_bound": int(np.sum(~np.asarray(out["fitted"], dtype=bool))),
        "window_lags_median": int(np.median(out["lags"])) if weighed else None,
        "threshold_noise_hours_per_contact": round(float(np.median([r["hours"]
                                                                   for r in out["runs"]])), 3)
        if weighed else None,
        "false_alarm_check": check,
    }
    gust = None
    if disturbances:
        # CPU seconds of everything before (the stream, the plain oracle and its checks, the
        # detector if asked) and of the disturbance-aware oracle: a cost ratio in one run
        before = time.process_time()
        gust = _disturbance_figures(stream, sensor, five, seed, false_alarms,
                                    detection_repeats, null_hours, grid_factor, pre, freeze)
        result.update(gust[0])
        result["cpu_s_before_disturbances"] = round(before - cpu, 1)
        result["disturbance_oracle_cpu_s"] = round(time.process_time() - before, 1)
    if run is not None:
        result.update(_detector_figures(stream, run[0], which, ratio))
        result.update(_detector_misses(stream, sensor, run, five, chance, ratio))
        if gust is not None:
            _misses_against_disturbances(result, gust[1])
    return result


def _disturbance_figures(stream: object, sensor: object, five: Sequence[int], seed: int,
                         false_alarms: float, repeats: int, null_hours: float,
                         grid_factor: float, pre: float,
                         freeze: bool = True) -> tuple[dict, dict]:
    """Return the disturbance-aware oracle's figures and its per-contact rows by contact."""
    from skin.bench.gust_oracle import measure_gust_oracle

    if not five:
        return {"disturbance_oracle_detected_5sigma": None}, {}
    g = measure_gust_oracle(stream, sensor, five, seed, false_alarms, repeats, null_hours,
                            pre=pre, grid_factor=grid_factor, freeze=freeze)
    det = np.asarray(g["detection"])
    draws = np.asarray(g["draws"])
    # the share's standard error over the draws (binomial per contact; 0 where every
    # draw is detected at a level the null streams do not reach, "below")
    se = float(np.sqrt(np.sum(det * (1.0 - det) / draws))) / det.size
    h = np.asarray(g["threshold"])
    found = np.asarray([s == "found" for s in g["threshold_status"]])
    nf = np.asarray(g["noise_free"])
    # a contact the family mimics: its noise-free statistic under the threshold (for a
    # contact whose threshold was not needed, "below", it is above every draw's, so not)
    mimic = found & (nf < h)
    rows = {k: {"detection": round(float(det[i]), 3),
                "threshold": round(float(h[i]), 2), "threshold_status": g["threshold_status"][i],
                "noise_free_statistic": round(float(nf[i]), 2),
                "information": round(float(g["information"][i]), 1),
                "mimicked": bool(mimic[i]), "draws": int(draws[i])}
            for i, k in enumerate(five)}
    statuses = {s: g["threshold_status"].count(s) for s in sorted(set(g["threshold_status"]))}
    figures = {
        "disturbance_oracle_detected_5sigma": round(float(det.mean()), 4),
        "disturbance_oracle_detected_5sigma_se": round(se, 4),
        "disturbance_oracle_draws_found": (int(draws[found].min()) if found.any() else None),
        "disturbance_oracle_under_half": int(np.sum(det < 0.5)),
        "disturbance_oracle_under_99": int(np.sum(det < 0.99)),
        "disturbance_oracle_mimicked": int(mimic.sum()),
        "disturbance_oracle_threshold_status": statuses,
        "disturbance_oracle_threshold_found_range": (
            [round(float(h[found].min()), 2), round(float(h[found].max()), 2)]
            if found.any() else None),
        "disturbance_oracle_information_5sigma_min": round(float(np.min(g["information"])), 1),
        "disturbance_oracle_block_information_kept_min": round(float(np.min(g["block_kept"])),
                                                               5),
        "disturbance_oracle_block": g["block"],
        "disturbance_oracle_null_taxel_hours": round(g["null_taxel_hours"], 2),
        "disturbance_oracle_alarms_needed": g["alarms_needed"],
        "disturbance_oracle_null_windows": g["windows"],
        "disturbance_oracle_grid_factor": grid_factor,
        "disturbance_oracle_pre_s": pre,
        "disturbance_oracle_freeze": freeze,
        "disturbance_oracle_family_members_median": int(np.median(
            list(g["family_members"].values()))),
        "disturbance_oracle_contacts": [{"contact": k, **rows[k]} for k in five
                                        if rows[k]["detection"] < 0.99],
    }
    return figures, rows


def _misses_against_disturbances(result: dict, rows: dict) -> None:
    """Add the disturbance-aware oracle's view of each detector miss to ``result``."""
    misses = result.get("detector_missed_5sigma", [])
    for row in misses:
        d = rows.get(row["contact"])
        if d is not None:
            row["disturbance_oracle_detection"] = d["detection"]
            row["disturbance_oracle_mimicked"] = d["mimicked"]
    result["detector_misses_5sigma_disturbance_oracle"] = {
        "missed": len(misses),
        "oracle_detects_half": int(sum(rows[r["contact"]]["detection"] >= 0.5
                                       for r in misses if r["contact"] in rows)),
        "oracle_detects_99": int(sum(rows[r["contact"]]["detection"] >= 0.99
                                     for r in misses if r["contact"] in rows)),
        "mimicked": int(sum(rows[r["contact"]]["mimicked"] for r in misses
                            if r["contact"] in rows)),
    }


def onset_stream(sensor: object, seed: int = 0, minutes: float = 15.0,
                 taxels: int = 16) -> object:
    """Return the stream ``skin evaluate-onset --sensor S --seed N`` simulates.

    Its materials, taxels, minutes and contact rate, disturbances on: the same contacts
    (`skin.bench.streams.simulate_stream` with the sensor: the contacts' templates and the
    raw noise come with it).
    """
    from skin.bench.streams import simulate_stream
    from skin.commands.evaluate_onset import MATERIALS
    from skin.models import load_materials

    table = load_materials()
    return simulate_stream([table[n] for n in MATERIALS.split(",")], n_taxels=taxels,
                           duration=60.0 * minutes, seed=seed, sensor=sensor)


def _run_detector(stream: object, sensor: object,
                  progress: Callable[[int, int], None] | None = None) -> tuple[dict, object]:
    """Run the real detector over the stream as ``skin evaluate-onset --sensor`` does.

    The heater duty told, as evaluate-onset and the pipeline tell it. ``progress`` is called
    as ``progress(done, total)`` with the samples processed.
    """
    from skin.bench.onset_eval import evaluate_onsets
    from skin.stream.onset import OnsetDetector

    truth = [(c.taxel, c.onset, c.release, c.visible_after) for c in stream.contacts]
    det = OnsetDetector(stream.temperature.shape[1], sensor=sensor)
    res = evaluate_onsets(stream.times, stream.temperature, truth, stream.fs, detector=det,
                          depth=sensor.depth, diffusivity=sensor.diffusivity, sensor=sensor,
                          progress=progress, duty=stream.duty())
    return res, det


def _detector_figures(stream: object, res: dict, which: Sequence[int], ratio: dict) -> dict:
    """Return the detector's delay / floor (`_run_detector`'s ``res``) beside the oracle's."""
    contacts = stream.contacts
    flags, delays = res["detected_flags"], res["delay_s"]
    same = [k for k in which if flags[k]]
    det_ratio = np.array([delays[k] / contacts[k].visible_after for k in same], dtype=float)
    ours = np.array([ratio[k] for k in same], dtype=float)
    pairs = np.isfinite(ours) & np.isfinite(det_ratio)
    return {
        "detector_ratio_median": _json_ratio(_median_ratio(list(det_ratio))),
        "oracle_ratio_median_same_contacts": _json_ratio(_median_ratio(list(ours))),
        "detector_contacts": len(same),
        "detector_false_alarms_per_taxel_hour": res["false_alarms_per_taxel_hour"],
        # over the pairs where the oracle too alarmed in the window; the others counted
        "detector_over_oracle_median": (round(float(np.median(det_ratio[pairs]
                                                              / ours[pairs])), 3)
                                        if pairs.any() else None),
        "detector_over_oracle_pairs": int(pairs.sum()),
        "oracle_not_detectable_same_contacts": int(np.sum(~np.isfinite(ours))),
    }


def _detector_misses(stream: object, sensor: object, run: tuple[dict, object],
                     five: Sequence[int], chance: dict, ratio: dict) -> dict:
    """Return the detector's 5-sigma detection and its misses beside the oracle's.

    ``detector_detected_5sigma`` is evaluate-onset's; each 5-sigma contact the detector
    missed gets its cause (`skin.bench.onset_why.explain_outcomes`, as ``evaluate-onset
    --why``), the oracle's detection probability (``chance``), its delay / floor, and how
    near each of the detector's fall tests came to firing from the onset to the end of the
    window in which an alarm still counts as the contact's (`miss_margins`).
    """
    from skin.bench.onset_eval import release_window
    from skin.bench.onset_why import MISS_CAUSES, explain_outcomes
    from skin.bench.streams import GUST_DEPTH
    from skin.models.sensors import load_sensor

    res, det = run
    contacts = stream.contacts
    flags = res["detected_flags"]
    counted = [False] * len(contacts)
    for k in five:
        counted[k] = True
    scale = sensor.heated_rise / load_sensor("paper").heated_rise
    why = explain_outcomes(res["events"], contacts, counted, stream.gusts, stream.switches,
                           warmup=det.warmup, gust_size=GUST_DEPTH[1] * scale,
                           after=release_window(sensor),
                           settle=det.slow_tau)
    index = {(c.taxel, round(c.onset, 3)): k for k, c in enumerate(contacts)}
    missed = [index[(row["taxel"], row["onset"])] for row in why["missed_contacts"]]
    near = miss_margins(stream, sensor, missed, release_window(sensor))
    closest: dict[str, int] = {}
    rows = []
    by_cause = {c: {"missed": 0, "oracle_detects": 0} for c in MISS_CAUSES}
    sigma = float(np.median(det.sigma))
    for row in why["missed_contacts"]:
        k = index[(row["taxel"], row["onset"])]
        p = chance[k]
        by_cause[row["cause"]]["missed"] += 1
        by_cause[row["cause"]]["oracle_detects"] += int(p >= 0.5)
        closest[near[k]["closest"]] = closest.get(near[k]["closest"], 0) + 1
        rows.append({**row, "contact": k,
                     "peak_sigmas": round(contacts[k].peak_change / sigma, 2),
                     "oracle_detection": round(p, 3),
                     "oracle_ratio": _json_ratio(ratio.get(k)), **near[k]})
    return {
        "detector_detected_5sigma": (round(sum(flags[k] for k in five) / len(five), 4)
                                     if five else None),
        "detector_misses_5sigma_by_cause": {c: v for c, v in by_cause.items() if v["missed"]},
        "detector_misses_5sigma_closest_test": closest,
        "detector_missed_5sigma": rows,
    }


def miss_margins(stream: object, sensor: object, which: Sequence[int],
                 after: float) -> dict[int, dict]:
    """Return how near each of the detector's fall tests came to firing on each contact.

    The detector (as evaluate-onset sets it for the sensor, but without the board common
    mode: the traced columns are a subset of the board, no board themselves; a miss the
    common mode caused or delayed is measured here without it) is traced
    (`skin.stream.onset.OnsetDetector.trace` with ``margins``) over the columns of the
    contacts ``which``, from the stream's start to the end of the last one's window.

    Returns
    -------
    dict
        For each contact of ``which``: ``margins``, each test of
        `skin.stream.onset.MARGIN_TESTS`' largest statistic over its threshold from the onset
        to ``after`` s after the release, while the taxel was free and armed (None if it
        never was: in contact or warming up all along; >= 1 would have fired, ``cusum_stale``
        excepted, which is reset instead); ``closest``, the test with the largest, or
        ``"not armed"``; ``armed_share``, the share of those samples on which the taxel was
        free and armed.
    """
    from skin.stream.onset import MARGIN_TESTS, OnsetDetector

    contacts = stream.contacts
    if not which:
        return {}
    cols = sorted({contacts[k].taxel for k in which})
    end = max(contacts[k].release for k in which) + after
    n = int(np.searchsorted(stream.times, end, side="right"))
    det = OnsetDetector(len(cols), sensor=sensor, common_mode=False)  # columns apart: no board
    trace = det.trace(stream.times[:n], stream.temperature[:n, cols], margins=True,
                      duty=stream.duty()[:n, cols])  # told the duty, as `_run_detector`'s
    out = {}
    for k in which:
        c = contacts[k]
        lo, hi = np.searchsorted(stream.times[:n], [c.onset, c.release + after])
        span = trace.margins[lo:hi, :, cols.index(c.taxel)]
        ready = np.isfinite(span[:, 0])
        best = {name: (round(float(np.max(span[ready, i])), 3) if ready.any() else None)
                for i, name in enumerate(MARGIN_TESTS)}
        firing = {name: v for name, v in best.items() if v is not None}
        out[k] = {"margins": best,
                  "closest": max(firing, key=firing.get) if firing else "not armed",
                  "armed_share": round(float(np.mean(ready)), 3) if ready.size else 0.0}
    return out

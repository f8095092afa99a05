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

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Any

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


# --- reference touches: the sensor response ------------------------------------------------

#: Least touches of each material, and least materials, that pin a sensor response.
MIN_TOUCHES, MIN_MATERIALS = 3, 2
#: Least named touches of each of `MIN_MATERIALS` references that fit a taxel alone (one
#: asked for but left out or ambiguous). Its board's pooled fit is the alternative, and it
#: carries the spread between the board's taxels (+-10 % in depth and diffusivity: up to
#: 20 % in response time). Measured (`skin bench commission --classify --sensor pid-logger`,
#: T 40, 2.5 s, on the scene simulator before its PID swing was fixed): seed 7's taxels 4 and
#: 6, each with one of 6 touches ambiguous, pooled: response time -12 / +16 % off, classified
#: at chance (.091; true constants .364); alone from 2 + 3 touches: -6 / -3 % (effusivity
#: +11 / -17 %), .255 / .236.
MIN_TAXEL_TOUCHES = 2
#: Seconds of each touch fitted after its onset (the touch must last this long) on the
#: paper's sensor; a slower sensor's window is longer by its half-response time's ratio to
#: the paper's (`touch_seconds`).
TOUCH_SECONDS = 2.5
#: Seconds before the detected onset fitted too: they pin the baseline, so that the fit can
#: date the onset itself (`ONSET_SEARCH`).
TOUCH_BEFORE = 0.4
#: How far each touch's onset may move from the detected one in the fit, s. `refine_onset`
#: dates reference touches to some -20..+80 ms with the nominal constants (10-bit readings;
#: up to +140 ms for soft contacts); a late onset left fixed passes for a faster sensor with a
#: softer contact (response-time error 0.11 both before and after such a fit, seed 11).
#: A faster sensor's search is shorter by its half-response time's ratio to the paper's
#: (`onset_search`): on fast-film (0.25 s) +-0.25 s is its whole response, and an early
#: onset passed for a slower sensor.
ONSET_SEARCH = 0.25
#: A release and a new onset of the same taxel closer than this are one touch, s (a heater
#: switched off at contact can make the detector see a release early in a touch).
MERGE_GAP = 0.5
#: Upper bound of a touch's fitted conductance, W/(m^2 K): a firm touch may be near perfect.
CONDUCTANCE_MAX = 1e6
#: Why a detected touch is left out (`find_touches`).
LEFT_OUT = ("unended", "short", "rising", "incomplete")


@dataclass(frozen=True)
class ReferenceTouch:
    """One detected touch of a taxel with a reference material at room temperature.

    Attributes
    ----------
    column : int
        The taxel's column (layout order).
    onset : float
        Refined onset, s.
    initial : float
        The taxel's temperature at the onset (its baseline there), deg C.
    material : str
        The reference the touch fits best (`assign_materials`).
    t, y : numpy.ndarray
        Time since the onset and reading, from `TOUCH_BEFORE` s before the onset to
        `TOUCH_SECONDS` after it.
    room : float, optional
        The reference's temperature, deg C (default: the room's, as given to the fit).
    """

    column: int
    onset: float
    initial: float
    material: str
    t: np.ndarray
    y: np.ndarray
    room: float | None = None  # the reference's temperature when not the recording's room


@dataclass(frozen=True)
class ResponseFit:
    """A fitted sensor response: whose touches, and the fit (`skin.models.sensor_fit`)."""

    columns: np.ndarray
    scope: str  # "taxel" or "board"
    touches: int
    materials: dict
    fit: object


def touch_seconds(sensors: list) -> float:
    """Seconds fitted after each onset: `TOUCH_SECONDS`, longer for a slower sensor.

    Scaled by the slowest taxel's half-response time (`SensorDescription.response_time`)
    against the paper's sensor's, never shorter: a low-cost sensor (8.6 s) read for the
    paper's 2.5 s shows only the start of its response (measured on the low-cost preset,
    seed 7, 6 labelled touches per taxel: effusivity error 0.061 nominal -> 0.63 fitted).
    """
    from skin.models.sensors import SensorDescription

    paper = SensorDescription().response_time
    slow = max((_response_time(s) for s in sensors), default=paper)
    return TOUCH_SECONDS * max(1.0, slow / paper)


def onset_search(sensor: object) -> float:
    """How far the fit may move a touch's onset, s: `ONSET_SEARCH`, shorter on a faster sensor."""
    from skin.models.sensors import SensorDescription

    return ONSET_SEARCH * min(1.0, _response_time(sensor) / SensorDescription().response_time)


def _response_time(sensor: object) -> float:
    from skin.models.sensors import SensorDescription

    if isinstance(sensor, SensorDescription):
        return float(sensor.response_time)
    return SensorDescription(depth=sensor.depth, diffusivity=sensor.diffusivity).response_time


def find_touches(times: np.ndarray, temperature: np.ndarray, layout: object,
                 sensors: list, noise: np.ndarray | None = None,
                 skip: np.ndarray | None = None,
                 within: dict[int, list[tuple[float, float]]] | None = None,
                 ) -> tuple[list[tuple[int, float, float, np.ndarray, np.ndarray]],
                            dict[str, int]]:
    """Detect touches with the pipeline's onset detector and date them with `refine_onset`.

    Each touch is dated with its taxel's sensor description (``sensors``: its heater mode,
    loop, lag and smoothing, `skin.stream.onset_refine.refine_onset`'s ``sensor``).

    A release followed within `MERGE_GAP` by a new onset of the same taxel is one touch.
    ``skip``: columns (bool, per taxel) whose touches are left alone (dated elsewhere), but
    for the stretches ``within`` gives a skipped taxel ((start, end) s each): its touches the
    detector finds starting in one of them are taken (a force channel's gaps, `force_gaps`).

    Returns
    -------
    touches : list of tuple
        (column, onset, initial temperature, time since onset, readings) of each falling
        touch lasting at least `TOUCH_SECONDS` with every sample of its window present; the
        window runs from `TOUCH_BEFORE` s before the onset to `TOUCH_SECONDS` after it.
    left_out : dict
        Touches left out, by reason (`LEFT_OUT`): ``unended`` (no release before the
        recording ends: the reading never recovered), ``short`` (released less than
        `touch_seconds` after the refined onset), ``rising`` (a warm object) and ``incomplete``
        (missing samples, or the window runs past the recording or the release).
    """
    from skin.stream.onset_refine import refine_onset, refine_span
    from skin.stream.pipeline import _detector_for

    t = np.asarray(times, dtype=float)
    y = np.asarray(temperature, dtype=float)
    step = float(np.median(np.diff(t)))
    seconds = touch_seconds(sensors)
    n_before, n_after = round(TOUCH_BEFORE / step), round(seconds / step)
    detector = _detector_for(layout, noise)
    events, _ = detector.process(t, y, detector.initial_state())
    spans: dict[int, list] = {}  # per taxel: [onset event, release time] of each touch
    for ev in events:
        held = spans.setdefault(ev.taxel, [])
        if sensors[ev.taxel].heater == "pid":
            _pid_span(held, ev)
        elif ev.kind == "onset":
            if held and held[-1][1] is not None and ev.time - held[-1][1] < MERGE_GAP \
                    and ev.direction == held[-1][0].direction:
                held[-1][1] = None  # the same touch goes on
            elif not held or held[-1][1] is not None:
                held.append([ev, None])
        elif held and held[-1][1] is None:
            held[-1][1] = ev.time
    out, left = [], dict.fromkeys(LEFT_OUT, 0)
    for k, held in sorted(spans.items()):
        if skip is not None and skip[k] and k not in (within or {}):
            continue
        for on, off in held:
            if skip is not None and skip[k] and not any(
                    a <= on.time <= b for a, b in within[k]):
                continue
            why = "rising" if on.direction != -1 else "unended" if off is None else ""
            if why:
                left[why] += 1
                continue
            # the taxel's own sensor: its loop, lag, smoothing and heater (a heater switched
            # off at contact drains the body from the first instant: without it fast-film's
            # touches were dated 6 ms early, median, up to 20 ms: seed 7, 48 touches), over its span
            search, _ = refine_span(sensors[k])
            near = (t >= on.time - max(1.0, search)) & (t <= off)
            onset, initial = refine_onset(t[near], y[near, k], on.time, on.baseline, on.slope,
                                          sensors[k].depth, sensors[k].diffusivity,
                                          sensor=sensors[k])
            if off - onset < seconds:  # from the refined onset: the detector's comes late
                left["short"] += 1
                continue
            window = _touch_window(t, y[:, k], onset, off, n_before, n_after)
            if window is None:
                left["incomplete"] += 1
                continue
            out.append((k, float(onset), float(initial), window[0] - onset, window[1]))
    return out, left


#: A force channel's contact: the force exceeds the free level by this many noise levels...
FORCE_CONTACT_SNR = 10.0
#: ... and by this share of the taxel's strongest touch (`force_touches`).
FORCE_CONTACT_SHARE = 0.05
#: A contact (or a release) counts when it holds this long, s: a noise sample does not.
FORCE_CONTACT_HELD = 0.05
#: A force that reads one value this long at its free level, where it is noisy, is stuck, s.
FORCE_STUCK = 1.0
#: A gap without a reading inside a contact is bridged (the contact goes on across it) only
#: up to this long, s; a longer one ends it there (the onset detector looks inside it).
FORCE_BRIDGE_MAX = 1.0
#: The force's noise is taken per stretch of this many samples (their median: `force_noise`).
FORCE_NOISE_SPAN = 100


def force_contacts(times: np.ndarray, force: np.ndarray,
                   weak: list[tuple[float, float]] | None = None,
                   bridged: list[tuple[float, float]] | None = None,
                   ) -> list[tuple[float, float]]:
    """Date one taxel's contacts from its force channel: (onset, release) of each, s.

    The free level is the median of the samples below halfway to the strongest one held
    `FORCE_CONTACT_HELD` (a one-sample glitch is not the strongest touch), the
    noise their scaled median absolute deviation, or their 84th percentile's distance above
    the level, or the smallest step between two of them, whichever is largest (a force
    reading clipped at 0, or a quantised or switched one, has a MAD of 0). A contact begins
    where the force first exceeds the level by `FORCE_CONTACT_SNR` noise levels and
    `FORCE_CONTACT_SHARE` of the strongest rise, staying over it `FORCE_CONTACT_HELD`, and
    ends where it stays under it as long. The onset is taken back to where the rise left
    the free level, along the line through the rise's samples between 10 noise levels and
    half the contact's peak (`force_onset`: a linear ramp is dated where it starts); a rise done
    within one sample (a switch) is dated midway between its last open and first closed
    sample (within half a sample). A NaN sample (no reading) counts as under the threshold,
    but for a run inside a contact that is shorter than `FORCE_CONTACT_HELD` or after which
    the force is still held over the threshold `FORCE_CONTACT_HELD` and it lasts at most
    `FORCE_BRIDGE_MAX` (it goes on across it; a longer gap ends the contact at its start).

    Parameters
    ----------
    times : numpy.ndarray
        Sample times, s, (n,).
    force : numpy.ndarray
        The taxel's force channel, N (or 0/1 for a contact switch), (n,).
    weak : list, optional
        Given, gets (onset, release) of each contact over the noise that stays under the
        `FORCE_CONTACT_SHARE` of the strongest one (left out: counted by `force_touches`).
    bridged : list, optional
        Given, gets (start, end) of each stretch without a reading inside a contact that the
        contact goes on across (shorter than `FORCE_CONTACT_HELD`, or the force held after it).

    Returns
    -------
    list of tuple
        (onset, release) of each contact, in time order; a contact still on at the end has
        release ``inf``. Empty when the channel has no reading or no contact stands out.
    """
    t = np.asarray(times, dtype=float)
    f = np.asarray(force, dtype=float)
    ok = np.isfinite(f)
    if ok.sum() < 3:
        return []
    step = float(np.median(np.diff(t)))
    held = max(2, round(FORCE_CONTACT_HELD / step))
    level, noise = force_noise(f, held)
    rise = _held_peak(f, held) - level
    if not rise > FORCE_CONTACT_SNR * noise or not rise > 0:
        return []
    threshold = level + max(FORCE_CONTACT_SNR * noise, FORCE_CONTACT_SHARE * rise)
    over = ok & (f > threshold)
    gone = np.flatnonzero(np.diff(np.r_[0, (~ok).astype(np.int8), 0]))
    for a, b in zip(gone[::2], gone[1::2], strict=True):  # no reading in samples a..b-1
        if 0 < a and b < f.size and over[a - 1] and (
                b - a < held or (over[b:b + held].all() and t[b] - t[a] <= FORCE_BRIDGE_MAX)):
            # shorter than a release can be, or the force still held after it: the contact
            # goes on (a longer gap cut a touch into a short one and a false one)
            over[a:b] = True
            if bridged is not None:
                bridged.append((float(t[a]), float(t[b])))
    out = []
    for k, end in _held_runs(over, held):
        stop = end if end is not None else f.size
        on = force_onset(t, f, k, level, noise, float(np.nanmax(f[k:stop])))
        out.append((on, float(t[end]) if end is not None else math.inf))
    if weak is not None and threshold > level + FORCE_CONTACT_SNR * noise:
        # the contacts over the noise alone that the share of the strongest one left out
        spans = [(k, end if end is not None else f.size)
                 for k, end in _held_runs(ok & (f > level + FORCE_CONTACT_SNR * noise), held)]
        weak += [(float(t[k]), float(t[e]) if e < f.size else math.inf) for k, e in spans
                 if not over[k:e].any()]
    return out


def _held_runs(over: np.ndarray, held: int) -> list[tuple[int, int | None]]:
    """Return the (first, end) samples of each run of ``over`` (end None: on at the end).

    A change of state counts when it holds ``held`` samples.
    """
    out, on, k, n = [], None, 0, over.size
    while k < n:
        if on is None:
            k = k + int(np.argmax(over[k:])) if over[k:].any() else n
            if k >= n:
                break
            if over[k:k + held].all():
                on = k
                k += held
            else:
                k += 1
        else:
            rest = ~over[k:]
            k = k + int(np.argmax(rest)) if rest.any() else n
            if k >= n:
                break
            if (~over[k:k + held]).all():
                out.append((on, k))
                on = None
                k += held
            else:
                k += 1
    if on is not None:
        out.append((on, None))
    return out


def _held_peak(f: np.ndarray, held: int) -> float:
    """Return the strongest force held ``held`` samples (a one-sample glitch is not a touch)."""
    g = np.where(np.isfinite(f), f, -np.inf)
    if g.size < held:
        return float(np.nanmax(f))
    peak = float(np.lib.stride_tricks.sliding_window_view(g, held).min(axis=1).max())
    return peak if math.isfinite(peak) else float(np.nanmax(f))


def force_gaps(times: np.ndarray, force: np.ndarray, forced: np.ndarray,
               ids: np.ndarray | None = None,
               ) -> tuple[dict[int, list[tuple[float, float]]], list[str]]:
    """Find the stretches of the taxels with a force reading that their force cannot date.

    A taxel whose force shows no contact at all (`force_contacts` finds none: a sensor stuck
    or unplugged) gives its whole recording; the others each stretch longer than
    `FORCE_CONTACT_HELD` where the force has no reading (NaN: FORCE messages lost, the
    sensor not read). The touches starting there are left to the onset detector.

    Parameters
    ----------
    times : numpy.ndarray
        Sample times, s.
    force : numpy.ndarray
        Force, N, (samples, taxels); NaN where a taxel has no reading.
    forced : numpy.ndarray
        bool (taxels,): the taxels with a force reading.
    ids : numpy.ndarray, optional
        The taxels' ids, to name them in the notes (default their columns).

    Returns
    -------
    within : dict
        Per taxel (column), its stretches, (start, end) s each.
    notes : list of str
        What happened, per taxel (named by its id), to report.
    """
    t = np.asarray(times, dtype=float)
    ids = np.arange(force.shape[1]) if ids is None else np.asarray(ids)
    within: dict[int, list[tuple[float, float]]] = {}
    notes, silent = [], []
    for k in np.flatnonzero(forced):
        f = force[:, k]
        if not force_contacts(t, f):
            within[int(k)] = [(-math.inf, math.inf)]
            silent.append(int(ids[k]))
            continue
        gone = np.r_[False, ~np.isfinite(f), False].astype(np.int8)
        edges = np.flatnonzero(np.diff(gone))
        spans = []
        for a, b in zip(edges[::2], edges[1::2], strict=True):  # samples a..b-1 have none
            start = float(t[a - 1]) if a > 0 else -math.inf
            end = float(t[b]) if b < t.size else math.inf
            if min(end, float(t[-1])) - max(start, float(t[0])) > FORCE_CONTACT_HELD:
                spans.append((start, end))
        if spans:
            within[int(k)] = spans
            lost = sum(min(b, float(t[-1])) - max(a, float(t[0])) for a, b in spans)
            notes.append(f"taxel {ids[k]}: its force had no reading for {lost:.3g} s; its touches "
                         "there dated by the onset detector")
    if silent:
        notes.insert(0, f"taxel{'s' if len(silent) > 1 else ''} {_runs_said(silent)}: the "
                        "force showed no contact (untouched, or its sensor not working): the "
                        "onset detector looked for touches there")
    return within, notes


def force_stuck(times: np.ndarray, force: np.ndarray, ids: np.ndarray | None = None,
                ) -> tuple[np.ndarray, list[str]]:
    """Take the stretches where a taxel's force is stuck as having no reading (NaN).

    A force whose free readings vary (at least three values within 3 noise levels of its
    free level, `force_noise`) and that reads one value at that level for `FORCE_STUCK` s
    and 100 samples or more, and ten times the longest run of one value in a typical stretch of
    `FORCE_NOISE_SPAN` samples (the median over stretches: a quiet quantised sensor repeats
    its values for long), is stuck there (a sensor or cable failing partway): a free
    sensor would not be read that long without noise, and a touch there would be lost as
    "no contact". `force_gaps` then hands those stretches to the onset detector. A channel
    without noise at rest (a switch, a quantised force under its resolution) is left as it is.

    Returns
    -------
    force : numpy.ndarray
        A copy, NaN where stuck (the array itself when nothing is).
    notes : list of str
        Per taxel stuck (named by its id, ``ids``; default its column), how long.
    """
    t = np.asarray(times, dtype=float)
    ids = np.arange(force.shape[1]) if ids is None else np.asarray(ids)
    least = max(100, math.ceil(FORCE_STUCK / float(np.median(np.diff(t)))))
    out, notes = force, []
    for k in np.flatnonzero(np.isfinite(force).any(axis=0)):
        f = force[:, k]
        level, noise = force_noise(f)
        near = f[np.isfinite(f) & (np.abs(f - level) <= 3 * noise)]
        if np.unique(near).size < 3:
            continue
        same = np.r_[False, f[1:] == f[:-1]]  # NaN never equal
        edges = np.flatnonzero(np.diff(np.r_[0, same.astype(np.int8), 0]))
        runs = np.zeros(f.size, dtype=np.int64)  # each run's length at its first sample
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            runs[a - 1] = b - a + 1
        spans = [int(runs[i:i + FORCE_NOISE_SPAN].max(initial=1))
                 for i in range(0, f.size, FORCE_NOISE_SPAN)]
        longest = max(least, 10 * int(np.median(spans)))
        lost = 0.0
        for a, b in zip(edges[::2], edges[1::2], strict=True):  # f[a-1..b-1] one value
            if b - a + 1 >= longest and abs(f[a - 1] - level) <= 3 * noise:
                if out is force:
                    out = force.copy()
                out[a - 1:b, k] = np.nan
                lost += float(t[b - 1] - t[a - 1])
        if lost:
            notes.append(f"taxel {ids[k]}: its force read one value for {lost:.3g} s (stuck?): "
                         "taken as no reading")
    return out, notes


def _runs_said(taxels: list[int]) -> str:
    """Taxel ids as runs: ``[0, 1, 2, 5]`` -> ``"0-2, 5"``."""
    out, start = [], taxels[0]
    for a, b in zip(taxels, [*taxels[1:], None], strict=True):
        if b != a + 1:
            out.append(f"{start}" if start == a else f"{start}-{a}")
            start = b
    return ", ".join(out)


def force_noise(force: np.ndarray, held: int = 1) -> tuple[float, float]:
    """Return one taxel's free force level and noise, N (`force_contacts`; NaN: no reading).

    The free samples are those below half way to the ``held``-th strongest sample (a glitch
    shorter than ``held`` samples does not count).
    """
    f = np.asarray(force, dtype=float)
    ok = np.isfinite(f)
    if not ok.any():
        return math.nan, math.nan
    lo = float(np.min(f[ok]))
    hi = float(np.partition(f[ok], -min(held, int(ok.sum())))[-min(held, int(ok.sum()))])
    is_free = ok & (f <= 0.5 * (lo + hi))
    free = f[is_free]
    level = float(np.median(free))
    steps = np.diff(np.unique(free))
    # the spread above the level too: a force sensor's noise clipped at 0 has a MAD of 0;
    # per stretch of `FORCE_NOISE_SPAN` samples, their median: a faint touch (under half the
    # strongest) lasting a few stretches does not count as noise
    span = FORCE_NOISE_SPAN
    upper = float(np.percentile(free, 84.13))
    if f.size >= 3 * span:
        cut = np.where(is_free, f, np.nan)[:f.size // span * span].reshape(-1, span)
        cut = cut[np.isfinite(cut).sum(axis=1) >= span // 2]
        if cut.shape[0] >= 3:
            upper = float(np.median(np.nanpercentile(cut, 84.13, axis=1)))
    noise = max(1.4826 * float(np.median(np.abs(free - level))), upper - level,
                float(steps.min()) if steps.size else 0.0)
    return level, noise


def span_noise(free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Free level and noise of force stretches, column by column (`ForceOnsets`' stretches).

    As `force_noise` for one stretch: the level is the median of the free samples, the noise
    their scaled median absolute deviation, their 84th percentile's distance above the level
    (a force clipped at 0 has a MAD of 0) or the smallest step between two of them, whichever
    is largest.

    Parameters
    ----------
    free : numpy.ndarray
        (samples, columns), NaN where a sample is not free (or has no reading); a column
        without any free sample gives NaN.

    Returns
    -------
    level, noise : numpy.ndarray
        (columns,) each, N.
    """
    f = np.asarray(free, dtype=float)
    srt = np.sort(f, axis=0)  # NaN last
    count = np.isfinite(f).sum(axis=0)
    level = sorted_quantile(srt, count, 0.5)
    dev = np.sort(np.abs(f - level), axis=0)
    mad = 1.4826 * sorted_quantile(dev, count, 0.5)
    upper = sorted_quantile(srt, count, 0.8413) - level
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        steps = np.diff(srt, axis=0)
        step = np.nanmin(np.where(steps > 0, steps, np.inf), axis=0) if len(f) > 1 else \
            np.full(f.shape[1], np.inf)
    noise = np.fmax(np.fmax(mad, upper), np.where(np.isfinite(step), step, 0.0))
    return level, np.where(np.isfinite(level), noise, np.nan)


def sorted_quantile(srt: np.ndarray, count: np.ndarray, q: float) -> np.ndarray:
    """Each column's ``q`` quantile (linear, as numpy's) of its ``count`` sorted finite values.

    NaN where a column has none. Vectorised over the columns (numpy's nanpercentile loops).
    """
    pos = q * np.maximum(count - 1, 0)
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, np.maximum(count - 1, 0))
    cols = np.arange(srt.shape[1])
    if srt.shape[0] == 0:
        return np.full(srt.shape[1], np.nan)
    a, b = srt[lo, cols], srt[hi, cols]
    out = a + (b - a) * (pos - lo)
    return np.where(count > 0, out, np.nan)


def force_onset(t: np.ndarray, f: np.ndarray, k: int, level: float, noise: float,
                 top: float) -> float:
    """Where the rise through sample ``k`` (the first over the threshold) left ``level``.

    A rise the samples resolve is taken back along the line fitted through its samples
    between 10 noise levels over ``level`` and half way to ``top`` (the contact's peak), not
    after sample ``k`` nor before a sample within 3 noise levels of the level where the line
    is 6 over it: a linear ramp is dated where it starts, however many samples it lasts. A
    rise completed within one sample (a switch, a press faster than the sampling) began
    somewhere after the sample before: the middle of that interval (half a sample either
    way).
    """
    if k == 0:
        return float(t[0])
    base = k - 1  # the last sample still at the free level
    while base > 0 and not (np.isfinite(f[base]) and f[base] <= level + 3 * noise):
        base -= 1
    half = level + 0.5 * (top - level)
    end = k
    while end < f.size and np.isfinite(f[end]) and f[end] <= half:
        end += 1
    if end < f.size and np.isfinite(f[end]) and end == k:
        end += 1  # the first sample is already past half way: the two around it
    seg = np.arange(base + 1, min(end + (end == k + 1), f.size))
    seg = seg[np.isfinite(f[seg]) & (f[seg] >= level + 10 * noise)]
    if seg.size >= 2 and (seg.size > 2 or f[seg[-1]] < top - 3 * noise):  # not a switch
        slope, icpt = np.polynomial.polynomial.polyfit(t[seg] - t[k], f[seg], 1)[::-1]
        if slope > 0:
            onset = float(min(t[k] + (level - icpt) / slope, t[k]))
            # not before a sample the line puts 6 noise levels over the level found at it
            back = np.arange(np.searchsorted(t, onset), k)
            back = back[np.isfinite(f[back])]
            line = icpt + slope * (t[back] - t[k])
            wrong = back[(f[back] <= level + 3 * noise) & (line > f[back] + 6 * noise)]
            return float(max(onset, t[wrong[-1]])) if wrong.size else onset
    return float(0.5 * (t[k - 1] + t[k]))


def force_touches(times: np.ndarray, temperature: np.ndarray, force: np.ndarray,
                  sensors: list, columns: np.ndarray, weak: dict[int, int] | None = None,
                  bridged: dict[int, int] | None = None,
                  ) -> tuple[list[tuple[int, float, float, np.ndarray, np.ndarray]],
                             dict[str, int]]:
    """Touches of the taxels ``columns`` dated by their force channel (as `find_touches`).

    Each contact of `force_contacts` gives a touch: its onset the force's, its end the
    force's release (a PID-held taxel's lift-off too), its initial temperature the line
    through the `TOUCH_BEFORE` s before the onset, evaluated at it. Left out as
    `find_touches` does: ``unended`` (still on at the end), ``short`` (released before
    `touch_seconds`), ``rising`` (the reading rose: a warm object), ``incomplete`` (the
    window runs past the recording or misses a sample). ``weak``, given, gets per taxel the
    contacts `force_contacts` left out as under `FORCE_CONTACT_SHARE` of its strongest one,
    ``bridged`` the short stretches without a reading inside its contacts.

    Returns
    -------
    touches : list of tuple
        (column, onset, initial temperature, time since onset, readings) of each touch.
    left_out : dict
        Touches left out, by reason (`LEFT_OUT`).
    """
    t = np.asarray(times, dtype=float)
    y = np.asarray(temperature, dtype=float)
    step = float(np.median(np.diff(t)))
    seconds = touch_seconds(sensors)
    n_before, n_after = round(TOUCH_BEFORE / step), round(seconds / step)
    out, left = [], dict.fromkeys(LEFT_OUT, 0)
    for k in columns:
        faint: list[tuple[float, float]] = []
        gaps: list[tuple[float, float]] = []
        contacts = force_contacts(t, force[:, k], faint, gaps)
        if faint and weak is not None:
            weak[int(k)] = len(faint)
        if gaps and bridged is not None:
            bridged[int(k)] = len(gaps)
        for onset, off in contacts:
            if not math.isfinite(off):
                left["unended"] += 1
                continue
            if off - onset < seconds:
                left["short"] += 1
                continue
            window = _touch_window(t, y[:, k], onset, off, n_before, n_after)
            if window is None:
                left["incomplete"] += 1
                continue
            tt, yy = window[0] - onset, window[1]
            line = np.polynomial.polynomial.polyfit(tt[:n_before], yy[:n_before], 1)
            initial = float(line[0])  # the line before the onset, at the onset
            if np.median(yy[n_before:]) > initial:
                left["rising"] += 1
                continue
            out.append((int(k), float(onset), initial, tt, yy))
    return out, left


def _touch_window(t: np.ndarray, y: np.ndarray, onset: float, off: float, n_before: int,
                  n_after: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Cut a touch's fitting window out of one taxel's recording.

    Parameters
    ----------
    t, y : numpy.ndarray
        The recording's times, s, and this taxel's readings, deg C.
    onset, off : float
        The touch's onset and its end, s.
    n_before, n_after : int
        Samples kept before the onset and from it on.

    Returns
    -------
    tuple of numpy.ndarray or None
        The window's times and a copy of its readings; None where it runs past the
        recording or past the touch's end, or misses a sample (NaN).
    """
    first = int(np.searchsorted(t, onset, side="right")) - n_before
    last = first + n_before + n_after
    if first < 0 or last > t.size or t[last - 1] > off or not np.all(np.isfinite(y[first:last])):
        return None
    return t[first:last], y[first:last].copy()


def _pid_span(held: list, ev: object) -> None:
    """Add one detector event to a PID-held taxel's touches (`find_touches`).

    The loop restores the reading while the object still rests on the taxel, so the
    detector's release marks the loop's recovery, not the lift-off (pid-logger, seed 7:
    released 1.1-3.3 s after every onset, all 48 touches held 13 s). The lift-off shows as
    the next onset, rising (the loop's raised power overshoots once the object is gone): a
    touch ends where the taxel's next onset begins, and a rising onset that ends a falling
    touch is its lift-off, not a touch of its own.
    """
    if ev.kind != "onset":
        return
    if held and held[-1][1] is None:
        held[-1][1] = ev.time
        if held[-1][0].direction == -1 and ev.direction == 1:
            return
    held.append([ev, None])


def labelled_touches(times: np.ndarray, temperature: np.ndarray, layout: object,
                     labels: list[Any], seconds: float = TOUCH_SECONDS,
                     ) -> tuple[list[ReferenceTouch], int]:
    """Cut each labelled touch's window (as `find_touches`) from the recording.

    The initial temperature is the median of the `TOUCH_BEFORE` s before the label's time;
    the fit dates the onset within `ONSET_SEARCH`. A touch whose window runs past the
    recording or has a missing sample is left out (counted). ``seconds``: fitted after each
    label's time (`touch_seconds`).
    """
    t = np.asarray(times, dtype=float)
    y = np.asarray(temperature, dtype=float)
    step = float(np.median(np.diff(t)))
    n_before, n_after = round(TOUCH_BEFORE / step), round(seconds / step)
    out, short = [], 0
    for lab in labels:
        first = int(np.searchsorted(t, lab.time, side="right")) - n_before
        window = slice(first, first + n_before + n_after)
        for tid in lab.taxels or tuple(int(i) for i in layout.ids):  # not said: every taxel
            k = layout.index(tid)
            if first < 0 or first + n_before + n_after > t.size or not np.all(
                    np.isfinite(y[window, k])):
                short += 1
                continue
            yy = y[window, k].copy()
            out.append(ReferenceTouch(k, lab.time, float(np.median(yy[:n_before])),
                                      lab.material, t[window] - lab.time, yy))
    return out, short


def dataset_touches(trials: object, layout: object) -> tuple[list[ReferenceTouch], int]:
    """Take reference touches from a trial dataset (version 2: `skin.formats.dataset`).

    Each trial's heated, present channels with a taxel id of the layout give one touch of
    the trial's labelled material, dated by its ``onset`` (an unknown one by its ``force``
    channel: `skin.formats.dataset.force_onsets`), at its ``object_temperature`` (else its
    ``ambient``); the window is `find_touches`'s. Trials without an onset, or too
    short around it (`TOUCH_BEFORE` s before, `TOUCH_SECONDS` after), are left out (counted).

    Raises
    ------
    CommissioningError
        If the dataset has no taxel ids or no room temperature, or if no channel's taxel id
        is in the layout.
    """
    if trials.taxel is None or trials.ambient is None:
        raise CommissioningError(f"{trials.source}: commissioning needs each trial's taxel ids "
                                 f"and ambient temperature (dataset version 2 'taxel' and "
                                 f"'ambient')")
    temp = trials.temperature if trials.temperature.ndim == 3 else trials.temperature[:, None]
    taxel = np.asarray(trials.taxel).reshape(len(trials), -1)
    heated = (np.ones(taxel.shape, dtype=bool) if trials.heated is None
              else np.asarray(trials.heated).reshape(taxel.shape))
    obj = (trials.ambient if trials.object_temperature is None
           else np.where(np.isfinite(trials.object_temperature), trials.object_temperature,
                         trials.ambient))
    from skin.formats.dataset import force_onsets

    onsets = np.where(trials.onset < 0, force_onsets(trials), trials.onset)
    ids = {int(t): i for i, t in enumerate(layout.ids)}
    n_before = round(TOUCH_BEFORE * trials.fs)
    n_after = round(TOUCH_SECONDS * trials.fs)
    lag = (np.arange(n_before + n_after) - n_before) / trials.fs
    out, short, known = [], 0, 0
    for i in range(len(trials)):
        on = int(onsets[i])
        for c in range(temp.shape[1]):
            if not heated[i, c] or int(taxel[i, c]) not in ids:
                continue
            known += 1
            y = temp[i, c, max(on - n_before, 0):on + n_after]
            if on < n_before or y.size < n_before + n_after or not np.all(np.isfinite(y)):
                short += 1
                continue
            out.append(ReferenceTouch(ids[int(taxel[i, c])], 0.0,
                                      float(np.median(y[:n_before])), str(trials.label[i]),
                                      lag, y.copy(), float(obj[i])))
    if not known:
        raise CommissioningError(f"{trials.source}: no heated channel has a taxel id of layout "
                                 f"{layout.name}: give --layout, or record the taxel ids")
    return out, short


#: Response times (relative to the taxel's current constants) each reference is tried at
#: when naming a touch (`assign_materials`). The range follows from units within +-10 % of
#: their board's design in depth and diffusivity (the simulated scenes' ``taxel_spread =
#: 0.1``): the response time depth^2 / diffusivity then lies within 0.9^2 / 1.1 = 0.74 and
#: 1.1^2 / 0.9 = 1.34 x nominal. Real hardware may spread more; a taxel outside the range
#: again fits its two references alike, and its touches are left out as ambiguous (not
#: mislabelled: a touch is named only when one reference fits twice as close), so it takes
#: its board's pooled fit or, with too few, none. Measured with a spread of 0.20 (`skin
#: bench commission --spread 0.2`, paper seed 19): 5 of 48 touches ambiguous, none named
#: wrong (at the nominal response time alone: 9 ambiguous, 3 wrong), 6 of 8 taxels fitted
#: alone.
ASSIGN_RESPONSE_SCALES = (0.7, 0.8, 0.9, 1.0, 1.12, 1.25, 1.4)


def assign_materials(touches: list, materials: dict, sensors: list, room: float,
                     scales: tuple[float, ...] = ASSIGN_RESPONSE_SCALES,
                     noise: np.ndarray | None = None,
                     ) -> tuple[list[ReferenceTouch], list[tuple[int, float]]]:
    """Name each touch's reference: the material whose contact response fits it best.

    Each candidate's response (`skin.models.sensor_fit.reference_reading`: with a sensor
    description, its heater mode and smoothing) is tried over its contact conductance range
    and over response times ``scales`` x the taxel's current one (``sensors``: nominal before
    commissioning; the depth scaled, the effusivity kept), since the unit's own response time
    is what commissioning is to find; a touch whose best fit is not at least twice as close
    as the runner-up is ambiguous and left out (the references must differ clearly in
    effusivity). Closeness is the misfit beyond the reading's own noise,
    sqrt(rms^2 - noise^2), and the runner-up's must reach the noise: on a noisy sensor the
    noise fills both residuals, and the raw ratio could not reach 2 (low-cost, seed 7, noise
    0.09 K: every neoprene touch ambiguous, though the closer reference was right in all 26).

    Parameters
    ----------
    touches : list
        (column, onset, initial temperature, times since onset, readings) of each touch
        (`find_touches`).
    materials : dict
        The candidate references by name.
    sensors : list of SensorConstants
        Each column's current constants.
    room : float
        Room (and references') temperature, deg C.
    scales : tuple of float
        Response times tried, relative to the current one (`ASSIGN_RESPONSE_SCALES`).
    noise : numpy.ndarray, optional
        Each column's reading noise per sample, K (`skin commission`'s ``noise_sigma``);
        default: its sensor description's, after smoothing (as the onset detector's; none
        for bare `SensorConstants`).

    Returns
    -------
    assigned : list of ReferenceTouch
    ambiguous : list of tuple
        (column, onset) of the touches left out.
    """
    from skin.models.sensor_fit import reference_reading
    from skin.models.sensors import SensorDescription

    names = list(materials)
    if noise is None:  # bare constants (no description) read noise-free
        noise = [s.delivered_noise(room + s.heated_rise)
                 if isinstance(s, SensorDescription) else 0.0 for s in sensors]
    noise = np.asarray(noise, dtype=float)
    assigned, ambiguous = [], []
    for k, onset, initial, tt, yy in touches:
        after = tt > 0
        # the unit's response time is not yet known: each candidate is tried over the
        # plausible spread of it (depth scaled, effusivity kept), so that a taxel faster
        # or slower than nominal does not blur the references apart
        units = [dataclasses.replace(sensors[k], depth=sensors[k].depth * np.sqrt(f))
                 for f in scales]
        rms = []
        for name in names:
            m = materials[name]
            h = np.logspace(*np.log10(m.conductance_range), 24)[:, None]
            rms.append(min(float(np.sqrt(np.mean(
                (reference_reading(tt[None, :], initial, room, m.effusivity, unit, h)[:, after]
                 - yy[after]) ** 2, axis=1)).min()) for unit in units))
        order = np.argsort(rms)
        beyond = np.sqrt(np.maximum(np.square(rms) - noise[k] ** 2, 0.0))
        if len(names) > 1 and (beyond[order[1]] < 2.0 * beyond[order[0]]
                               or beyond[order[1]] < noise[k]):
            ambiguous.append((k, onset))
            continue
        assigned.append(ReferenceTouch(k, onset, initial, names[order[0]], tt, yy))
    return assigned, ambiguous


def _pins(touches: list[ReferenceTouch], least: int = MIN_TOUCHES) -> bool:
    counts: dict[str, int] = {}
    for tc in touches:
        counts[tc.material] = counts.get(tc.material, 0) + 1
    return sum(c >= least for c in counts.values()) >= MIN_MATERIALS


def fit_responses(touches: list[ReferenceTouch], layout: object, materials: dict,
                  sensors: list, room: float, left_out: dict | None = None,
                  ) -> list[ResponseFit]:
    """Fit each taxel's response, or its board's where the taxel has too few touches.

    A taxel needs `MIN_TAXEL_TOUCHES` touches of each of `MIN_MATERIALS` references, a board
    (pooling the touches of its taxels short of them) `MIN_TOUCHES`; the fit is
    `skin.models.sensor_fit.fit_sensor_constants`. Where the taxels short of them hold too
    few touches to pool (one taxel with 1 + 1 beside taxels fitted alone), those of them
    with named touches take the board's fit from all its named touches, the fitted taxels'
    too ("board" scope; `touches_wanted` says what they lack): no touched taxel of a board
    with enough touches is left to be read as nominal. Untouched taxels get a board fit
    only when the leftovers' own touches pin one (as before).

    ``left_out``: the touches left out before the fit, by reason (`find_touches`, with
    ``ambiguous``): they name what to record instead when the rest cannot pin the response.

    Raises
    ------
    CommissioningError
        If no taxel and no board has enough touches: the message says what to record.
    """
    by_taxel: dict[int, list[ReferenceTouch]] = {}
    for tc in touches:
        by_taxel.setdefault(tc.column, []).append(tc)
    groups = [(np.array([k]), "taxel", tcs) for k, tcs in sorted(by_taxel.items())
              if _pins(tcs, MIN_TAXEL_TOUCHES)]
    done = {int(g[0][0]) for g in groups}
    for b in layout.boards:
        board = [i for i, tx in enumerate(layout.taxels) if tx.board == b]
        cols = [i for i in board if i not in done]
        pool = [tc for k in cols for tc in by_taxel.get(k, [])]
        if cols and not _pins(pool):
            # the leftovers' own touches are too few to pool: those with named touches
            # take the board's fit from all its named touches (the fitted taxels' too), so
            # that no touched taxel of a board that pins its response is left without
            # constants (untouched ones are left as before)
            cols = [k for k in cols if k in by_taxel]
            pool = [tc for k in board for tc in by_taxel.get(k, [])]
        if cols and _pins(pool):
            groups.append((np.array(cols), "board", pool))
    if not groups:
        hold, rest = hold_and_rest(sensors)
        found = {}
        for tc in touches:
            found[tc.material] = found.get(tc.material, 0) + 1
        raise CommissioningError(
            f"the recording cannot pin the sensor response: it holds {len(touches)} usable "
            f"touches ({', '.join(f'{v} of {k}' for k, v in found.items()) or 'none'})"
            f"{_left_out_said(left_out or {}, sensors)}; record at least {MIN_TOUCHES} "
            f"touches of at least {MIN_MATERIALS} of {', '.join(materials)} at room "
            f"temperature, each held {hold:g} s or more with {rest:g} s or more between "
            f"them, on every taxel (or, pooled per board, on each board)")
    out = []
    for cols, scope, tcs in groups:
        fit = _fit_group(tcs, materials, sensors[int(cols[0])], room, pooled=scope == "board")
        counts: dict[str, int] = {}
        for tc in tcs:
            counts[tc.material] = counts.get(tc.material, 0) + 1
        out.append(ResponseFit(cols, scope, len(tcs), counts, fit))
    return out


def touches_wanted(fits: list[ResponseFit], touches: list[ReferenceTouch], layout: object,
                   materials: dict) -> dict[int, dict[str, int]]:
    """Return, per taxel given its board's pooled fit, the touches it lacks to be fitted alone.

    A taxel left to its board's pool (too few of its own touches named: left out, ambiguous
    or never recorded) takes the board's constants, and with them the spread between the
    board's taxels (pid-logger, `skin bench commission --classify`, seed 7: two such taxels
    12-16 % off in response time, classified at chance at 2.5 s where the true constants
    give 36 %). What it lacks: `MIN_TAXEL_TOUCHES` named touches of each of `MIN_MATERIALS`
    of ``materials``, the references it already has most of first.

    Returns
    -------
    dict
        Taxel id -> {reference: further touches of it}, for the board-pooled taxels only.
    """
    wanted = {}
    for f in fits:
        if f.scope == "taxel":
            continue
        for k in f.columns:
            have = {m: sum(int(tc.column) == int(k) and tc.material == m for tc in touches)
                    for m in materials}
            lack = sorted(((max(MIN_TAXEL_TOUCHES - n, 0), m) for m, n in have.items()),
                          key=lambda v: v[0])[:MIN_MATERIALS]
            wanted[int(layout.ids[int(k)])] = {m: n for n, m in lack if n}
    return wanted


def wanted_said(wanted: dict[int, dict[str, int]]) -> str:
    """Say which taxels took their board's pooled fit and what to record to fit them alone.

    Taxels with some named touches are listed with what each lacks; those without a named
    touch of their own (never touched, or every touch left out or ambiguous) are counted,
    with their first ids, rather than listed one by one.
    """
    if not wanted:
        return ""
    full = MIN_TAXEL_TOUCHES * MIN_MATERIALS
    none = sorted(k for k, w in wanted.items() if sum(w.values()) >= full)
    some = sorted(k for k in wanted if k not in set(none))
    parts = []
    if some:
        parts.append("taxel" + ("s " if len(some) > 1 else " ")
                     + "; ".join(f"{k} (touch again: "
                                 + ", ".join(f"{n} x {m}" for m, n in wanted[k].items()) + ")"
                                 for k in some)
                     + (" have" if len(some) > 1 else " has")
                     + " too few of its own touches named (the rest left out or ambiguous)")
    if none:
        ids = ", ".join(str(k) for k in none[:10]) + (", ..." if len(none) > 10 else "")
        parts.append(f"{len(none)} taxel{'s' if len(none) > 1 else ''} without a named touch "
                     f"of {'their' if len(none) > 1 else 'its'} own ({ids}: "
                     f"{MIN_TAXEL_TOUCHES} x each of two references on each)")
    return ("; ".join(parts) + ": the board's pooled fit, and with it the board's spread, "
            "stands for their constants; record those touches on them, at room temperature, "
            "to fit each alone")


def hold_and_rest(sensors: list) -> tuple[float, float]:
    """How long to hold each reference touch and to rest between them, s.

    The detector dates a touch some fraction of the sensor's half-response time late and
    `TOUCH_SECONDS` are fitted after the onset; the reading must recover between touches.
    """
    slow = max((_response_time(s) for s in sensors), default=TOUCH_SECONDS)
    return (float(np.ceil(2 * (touch_seconds(sensors) + slow / 4)) / 2),
            float(max(5.0, round(2 * slow))))


def _left_out_said(left: dict, sensors: list) -> str:
    """Say why touches were left out, and what to record instead for each reason."""
    rest = hold_and_rest(sensors)[1]
    said = {
        "unended": "never ended (the reading did not recover before the next touch or the "
                   f"end: rest {rest:.0f} s or more between touches and after the last, or "
                   "give their times with --labels)",
        "short": f"ended less than {touch_seconds(sensors):.3g} s after their detected onset (the "
                 "detector dates the onset late on a slow sensor)",
        "rising": "warmed the taxel (the reference must rest at room temperature)",
        "incomplete": "had missing samples or ran past the recording's end",
        "ambiguous": "fitted two references alike (choose references that differ in "
                     "effusivity and conform, such as water in a thin bag and neoprene, or "
                     "give their times with --labels)"}
    parts = [f"{left[k]} {said[k]}" for k in said if left.get(k)]
    return (", and of the touches left out " + "; ".join(parts)) if parts else ""


def _fit_group(tcs: list[ReferenceTouch], materials: dict, nominal: object,
               room: float, pooled: bool = False) -> object:
    """Fit one taxel's (or board's) touches: one conductance per material or one per touch.

    Both are fitted, each touch's onset with them; the one per material is kept unless one
    per touch lowers the residual by more than the Bayesian information criterion asks for
    its extra parameters. Touches of one material held alike share one conductance, and
    then a free one per touch lets a late onset, a faster sensor and a softer contact pass
    for each other (measured, seed 7: response-time error p90 0.09 free, 0.02 shared); a
    skin touched more or less firmly needs one per touch (light touches drawn from the
    material's range: 0.06 per touch, 0.14 shared).
    """
    from skin.models.sensor_fit import fit_sensor_constants

    mats = [materials[tc.material] for tc in tcs]
    t = np.array([tc.t for tc in tcs])
    y = np.array([tc.y for tc in tcs])
    # a board's pool mixes taxels that differ: a free depth absorbs their differences
    # (fast-film, seed 7, 21 pooled taxels: response-time error median 0.52 with it, 0.12
    # held as before)
    kw = dict(nominal=nominal, onset_search=onset_search(nominal),
              fit_depth=False if pooled else None,
              conductance_range=([m.conductance_range[0] for m in mats],
                                 [CONDUCTANCE_MAX] * len(mats)))
    args = (t, y, [tc.initial for tc in tcs],
            [room if tc.room is None else tc.room for tc in tcs],
            [m.effusivity for m in mats])
    names = sorted({tc.material for tc in tcs})
    shared = fit_sensor_constants(*args, **kw,
                                  conductance_groups=[names.index(tc.material) for tc in tcs])
    each = fit_sensor_constants(*args, **kw)
    n = y.size

    def bic(fit: object, conductances: int) -> float:
        return n * np.log(max(fit.rms, 1e-12) ** 2) + (2 + conductances + 3 * len(tcs)) * np.log(n)

    return each if bic(each, len(tcs)) < bic(shared, len(names)) else shared


def described(layout: object, sensors: list) -> list:
    """Return each taxel's sensor description with its own thermal constants.

    The description (heater mode, lag, smoothing: `skin sensors`) is the taxel's board's;
    depth, diffusivity and conductivity come from ``sensors``.
    """
    from skin.models.sensors import SensorDescription

    boards = {bid: SensorDescription.from_board(b) for bid, b in layout.boards.items()}
    return [dataclasses.replace(boards[tx.board], depth=s.depth, diffusivity=s.diffusivity,
                                conductivity=s.conductivity)
            for tx, s in zip(layout.taxels, sensors, strict=True)]


def commission_response(times: np.ndarray, temperature: np.ndarray, layout: object,
                        materials: dict, sensors: list, room: float,
                        noise: np.ndarray | None = None,
                        labels: list[Any] | None = None,
                        force: np.ndarray | None = None,
                        ) -> tuple[list[ResponseFit], dict]:
    """Detect, date, name and fit reference touches (see `fit_responses`).

    With ``labels`` (`skin.formats.touch_labels.read_touch_labels`) the touches are those
    labelled, not detected. With ``force`` (the recording's force channel, N, (n, taxels),
    NaN where a taxel has no reading: `skin.frame.Frame.force`), the touches of each taxel
    with a reading are found and dated by it (`force_touches`), the others' by the onset
    detector as without it; so are those starting where a taxel's force has no reading for
    longer than `FORCE_CONTACT_HELD`, and all of a taxel whose force shows no contact
    (`force_gaps`: ``counts["force_notes"]`` says, by taxel).

    The detector's onsets (refined with the taxels' current constants) only start the fit:
    it dates each touch's onset again, within `ONSET_SEARCH`, with the constants it fits.

    Returns
    -------
    fits : list of ResponseFit
    counts : dict
        Touches ``detected``, ``left_out`` (short, warm or incomplete) and ``ambiguous``;
        ``wanted``: the touches each board-pooled taxel lacks to be fitted alone
        (`touches_wanted`).
    """
    sensors = described(layout, sensors)
    if labels is not None:
        touches, short = labelled_touches(times, temperature, layout, labels,
                                          touch_seconds(sensors))
        counts = {"detected": len(touches) + short, "left_out": short, "ambiguous": 0}
        fits = fit_responses(touches, layout, materials, sensors, room)
        counts["wanted"] = touches_wanted(fits, touches, layout, materials)
        return fits, counts
    forced = np.zeros(len(layout), dtype=bool)
    within: dict[int, list[tuple[float, float]]] = {}
    notes: list[str] = []
    if force is not None:
        force, notes = force_stuck(times, np.asarray(force, dtype=float), layout.ids)
        forced = np.isfinite(force).any(axis=0)
        within, gap_notes = force_gaps(times, force, forced, layout.ids)
        notes += gap_notes
    n_forced = n_weak = 0
    touches, left = [], dict.fromkeys(LEFT_OUT, 0)
    if not forced.all() or within:
        touches, left = find_touches(times, temperature, layout, sensors, noise,
                                     skip=forced, within=within)
    if forced.any():
        weak: dict[int, int] = {}
        bridged: dict[int, int] = {}
        by_force, left_force = force_touches(times, temperature, force, sensors,
                                             np.flatnonzero(forced), weak, bridged)
        ids = layout.ids
        notes += [f"taxel {ids[k]}: its force had no reading {n} time{'s' if n > 1 else ''} "
                  f"within a contact, each under {FORCE_CONTACT_HELD:g} s: bridged"
                  for k, n in bridged.items()]
        notes += [f"taxel {ids[k]}: its force left out {n} contact{'s' if n > 1 else ''} under "
                  f"{FORCE_CONTACT_SHARE:.0%} of its strongest" for k, n in weak.items()]
        n_weak = sum(weak.values())
        n_forced = len(by_force)
        touches += by_force
        left = {k: left[k] + left_force[k] for k in left}
    if not touches and not any(left.values()):
        hold, rest = hold_and_rest(sensors)
        found = "the onset detector found no touch in it"
        if forced.any():
            noises = [force_noise(force[:, k])[1] for k in np.flatnonzero(forced)]
            found = (f"its force channel showed no contact on the {int(forced.sum())} taxels "
                     f"it read (none above {FORCE_CONTACT_SNR:g} times its noise, "
                     f"{np.nanmedian(noises):.3g} N median) and the onset detector found no "
                     f"touch either; check the force sensor and its cable")
        raise CommissioningError(
            f"the recording cannot pin the sensor response: {found}; record at least "
            f"{MIN_TOUCHES} touches of at least {MIN_MATERIALS} "
            f"of {', '.join(materials)} at room temperature, each held {hold:g} s or more "
            f"with {rest:g} s or more between them, or give their times with --labels")
    assigned, ambiguous = assign_materials(touches, materials, sensors, room, noise=noise)
    short = sum(left.values())
    counts = {"detected": len(touches) + short, "left_out": short, "ambiguous": len(ambiguous),
              "force_dated": n_forced, "force_taxels": int(forced.sum())}
    if n_weak:
        counts["force_weak"] = n_weak
    if notes:
        counts["force_notes"] = notes
    fits = fit_responses(assigned, layout, materials, sensors, room,
                         {**left, "ambiguous": len(ambiguous)})
    counts["wanted"] = touches_wanted(fits, assigned, layout, materials)
    return fits, counts

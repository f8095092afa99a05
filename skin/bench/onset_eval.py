"""Judge the streaming onset detector against streams whose contacts are known.

`evaluate_onsets` runs `skin.stream.onset.OnsetDetector` over a multi-taxel stream in chunks, dates
every detected onset as the pipeline does (`skin.stream.tracking.refine_member`: the onset
on the samples up to the taxel's detected release, the release dated again, the onset
refitted up to it when earlier), and matches the detections to the true
contacts of the same taxel: a detection whose coarse onset falls between 0.1 s before a
contact's onset and 0.1 s after its release (plus the sensor's lag and smoothing delay,
`release_window`) belongs to that contact, and so does one raised while the object touches
the taxel (or within that window after release) whose coarse onset was
dated earlier (a gust or the air's flutter just before the contact started its CUSUM); the
first one detects it, any further one in the same contact (a split touch) and any that
belongs to none is a false alarm. Given
each contact's direction (a cool object: the reading falls; a warm one: it rises), the figures
are also given for each direction apart.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from skin.bench.intervals import poisson_interval
from skin.stream.onset import OnsetDetector, OnsetEvent
from skin.stream.onset_refine import refine_span
from skin.stream.tracking import TaxelSamples, refine_member
from skin.summary import median_p95

#: A detection may start this much before the true onset and still belong to the contact, s.
EARLY = 0.1


def release_window(sensor: object | None = None) -> float:
    """Return how long after a release an alarm may still be the contact's own, s.

    `EARLY`, plus the time the sensor's reading takes to show what happened at its face:
    three time constants of its thermistor lag (95 % of a step) and the delay of its
    smoothing (the centroid of the filter's impulse response). A 1 s lag shows most of a
    brief touch after the object has left; the alarm it raises then is that touch's, not a
    false one. `EARLY` alone for a sensor without lag or smoothing (the paper's).
    """
    if sensor is None:
        return EARLY
    from skin.models.sensors import smooth

    delay = 3.0 * sensor.lag
    if sensor.smoothing != "none":
        n = 8 * max(sensor.smoothing_window,
                    int(sensor.sample_rate / sensor.smoothing_cutoff)) + 1
        impulse = np.zeros(n)
        impulse[n // 2] = 1.0
        h = smooth(impulse, sensor)
        delay += max(0.0, float(np.sum(np.arange(n) * h) / np.sum(h)) - n // 2) \
            / sensor.sample_rate
    return EARLY + delay


#: Issue 16's refined-onset target: the median |error| at most this, s, or
#: `TARGET_FLOOR_SHARE` of the median physical floor if that is more (`onset_error_target`).
TARGET_ONSET_ERROR = 0.015
TARGET_FLOOR_SHARE = 0.1


def onset_error_target(floors: Sequence[float]) -> float:
    """Return issue 16's target for the refined onset's median |error|, ms.

    ``max(15 ms, 10 % of the median physical floor)``; the floor of a contact is when its
    noise-free reading first moves 3 sigma (`skin.bench.streams.StreamContact.visible_after`).

    Parameters
    ----------
    floors : sequence of float
        The contacts' floors, s; the infinite ones (never visible) are left out. With none
        left the target is 15 ms.

    Returns
    -------
    float
        The target, ms (rounded to 0.1 ms).
    """
    f = np.asarray(floors, dtype=float)
    f = f[np.isfinite(f)]
    share = TARGET_FLOOR_SHARE * float(np.median(f)) if f.size else 0.0
    return round(1e3 * max(TARGET_ONSET_ERROR, share), 1)


def five_sigma(contacts: list, detector: object, min_duration: float) -> list[bool]:
    """Whether each contact counts towards issue 16's 5-sigma figures.

    It lasts ``min_duration`` s or more and moves the noise-free reading by more than 5 of
    the detector's noise sigmas (median over its taxels); `skin evaluate-onset`'s
    ``detected_5sigma`` and `skin bench delay-bound` count the same contacts.
    """
    sigma = float(np.median(detector.sigma))
    return [c.duration >= min_duration and c.peak_change > 5 * sigma for c in contacts]


def evaluate_onsets(times: np.ndarray, temperature: np.ndarray,
                    truth: Sequence[tuple[int, float, float]], fs: float,
                    min_duration: float = 0.3, chunk: int = 20,
                    depth: float = 8e-5, diffusivity: float = 2.796e-9,
                    progress: Callable[[int, int], None] | None = None,
                    directions: Sequence[int] | None = None,
                    detector: OnsetDetector | None = None,
                    sensor: object | None = None, duty: np.ndarray | None = None) -> dict:
    """Measure the detector's detection rate, false alarms, delay, onset error and cost.

    Parameters
    ----------
    times : numpy.ndarray
        Sample times, s, (n_samples,).
    temperature : numpy.ndarray
        Readings, deg C, (n_samples, n_taxels).
    truth : sequence of (taxel, onset, release) or (taxel, onset, release, visible_after)
        Every true contact; ``visible_after`` (s after onset) is when its reading first stood
        out of the noise (`skin.bench.streams.StreamContact.visible_after`), the floor of any
        detector's delay.
    fs : float
        Sampling rate, Hz.
    min_duration : float
        Contacts at least this long count towards ``detection_rate`` (all contacts are
        reported under ``detection_rate_all``).
    chunk : int
        Samples handed to the detector at a time (the result does not depend on it).
    depth, diffusivity : float
        Sensor constants for the onset refinement.
    progress : callable, optional
        Called as ``progress(done, total)`` with samples processed.
    directions : sequence of int, optional
        For each contact of ``truth``, -1 if the object was cooler than the taxel (its reading
        falls) or +1 if warmer (it rises); adds ``by_direction``.
    detector : OnsetDetector, optional
        The detector judged (default: the paper sensor's).
    sensor : skin.models.sensors.SensorDescription, optional
        The stream's sensor: the refinement fits its own response (loop, lag, smoothing) over
        a span stretched with its response time (`skin.stream.onset_refine.refine_span`), and
        an alarm may come `release_window` after a release and still be the contact's.
    duty : numpy.ndarray, optional
        Each taxel's heater duty at each sample, as frames carry it (`OnsetDetector.process`'s
        ``duty``; `skin.bench.streams.Stream.duty`); None: the detector is not told it.

    Returns
    -------
    dict
        ``contacts``, ``detected``, ``detection_rate`` (contacts >= ``min_duration``),
        ``detection_rate_all``, ``false_alarms``, ``taxel_hours``,
        ``false_alarms_per_taxel_hour`` (and its exact 95 % interval,
        ``false_alarms_per_taxel_hour_ci95``), ``delay_ms``, ``visible_ms`` (the floor, for the
        detected contacts) and ``onset_error_ms`` (median and p95 of the absolute values; the
        signed median too), the detector's and the refinement's cost,
        ``false_alarms_by_direction`` (``"fall"`` and ``"rise"``: the direction the detector
        gave them), ``events`` (the detector's, in order; `skin.bench.onset_why` explains
        them), ``detected_flags``: for each contact of ``truth``, whether it was detected,
        and with ``directions``, ``by_direction``: for ``"cool"`` and ``"warm"`` contacts,
        ``contacts_counted``, ``detection_rate``, ``detection_rate_all``, ``right_direction``
        (the share of the detected ones whose onset had the contact's direction), ``delay_ms``
        and ``onset_error_ms``.
    """
    if directions is not None and len(directions) != len(truth):
        raise ValueError("directions needs one entry per contact of truth")
    y = np.asarray(temperature, dtype=float)
    n, n_taxels = y.shape
    detector = OnsetDetector(n_taxels) if detector is None else detector
    state = detector.initial_state()
    events = []
    started = time.perf_counter()
    for k in range(0, n, chunk):
        new, state = detector.process(times[k:k + chunk], y[k:k + chunk], state, in_place=True,
                                      duty=None if duty is None else duty[k:k + chunk])
        events += new
        if progress is not None and (k // chunk) % 500 == 0:
            progress(min(k + chunk, n), n)
    detect_s = time.perf_counter() - started
    onsets = [e for e in events if e.kind == "onset"]
    by_taxel: dict[int, list[tuple[float, float]]] = {}
    keys: list[tuple[int, int]] = []  # (taxel, its contact number) of each row of truth
    visible: dict[tuple[int, int], float] = {}
    for row in truth:
        taxel, on, off = int(row[0]), float(row[1]), float(row[2])
        spans = by_taxel.setdefault(taxel, [])
        keys.append((taxel, len(spans)))
        if len(row) > 3:
            visible[(taxel, len(spans))] = float(row[3])
        spans.append((on, off))
    found: dict[tuple[int, int], OnsetEvent] = {}
    false_alarms = {"fall": 0, "rise": 0}
    after = release_window(sensor)
    for ev in onsets:
        hit = contact_of(ev, by_taxel.get(ev.taxel, []), after)
        if hit is None or (ev.taxel, hit) in found:
            false_alarms["rise" if ev.direction > 0 else "fall"] += 1
        else:
            found[(ev.taxel, hit)] = ev
    started = time.perf_counter()
    search, horizon = refine_span(sensor)
    delay: dict[tuple[int, int], float] = {}
    error: dict[tuple[int, int], float] = {}
    floor = []
    releases: dict[int, list[OnsetEvent]] = {}
    for ev in events:
        if ev.kind == "release":
            releases.setdefault(ev.taxel, []).append(ev)
    for (taxel, i), ev in found.items():
        on, _ = by_taxel[taxel][i]
        # refined as the pipeline refines (`skin.stream.tracking.refine_member`), on the
        # samples it would hold: from the span before the coarse onset to the release's
        # detection, if a release was detected (the onset on those up to the release, the
        # release dated again, the onset refitted up to it when earlier)
        rel = next((r for r in releases.get(taxel, []) if r.detected_at > ev.detected_at),
                   None)
        end = np.inf if rel is None else rel.time
        stop = ev.time + horizon if rel is None else max(rel.detected_at, end)
        lo, hi = np.searchsorted(times, [ev.time - search, stop], side="right")
        member = TaxelSamples(0, ev.time, ev.baseline, ev.slope, None if rel is None else end,
                              end, times[lo:hi], y[lo:hi, taxel],
                              np.full(hi - lo, np.nan))
        refined, _, _ = refine_member(member, np.array([depth]), np.array([diffusivity]),
                                      sensor=sensor)
        delay[(taxel, i)] = ev.detected_at - on
        error[(taxel, i)] = refined - on
        if (taxel, i) in visible:
            floor.append(visible[(taxel, i)])
    refine_s = time.perf_counter() - started
    hours = n_taxels * n / fs / 3600.0
    spans_of = {key: by_taxel[key[0]][key[1]] for key in keys}
    n_false = sum(false_alarms.values())
    result = {
        **_figures(keys, spans_of, found, delay, error, min_duration),
        "min_duration": min_duration, "detected": len(found),
        # the detector's events: one onset per contact found, one release per contact ended
        # (more: a contact released and found again)
        "onsets": len(onsets), "releases": sum(len(r) for r in releases.values()),
        "false_alarms": n_false, "false_alarms_by_direction": false_alarms,
        "taxel_hours": round(hours, 3),
        "false_alarms_per_taxel_hour": round(n_false / hours, 3),
        # exact 95 % interval: a few taxel-hours cannot tell 0.1 from 0.4 per taxel-hour
        "false_alarms_per_taxel_hour_ci95": [round(v, 3) for v in poisson_interval(n_false,
                                                                                  hours)],
        "visible_ms": (median_p95(np.asarray(floor)[np.isfinite(floor)], 1e3, 1) if floor
                       else None),
        "detector_us_per_taxel_sample": round(1e6 * detect_s / (n * n_taxels), 4),
        "refine_ms_per_onset": round(1e3 * refine_s / max(len(found), 1), 3),
        # holes (gaps over 1.5 nominal sample periods) that restarted the envelope margin's
        # settle clock, summed over taxels: many mean the flat margin ran
        "settle_restarts": int(state.settle_restarts.sum()),
        "detected_flags": [k in found for k in keys],
        "events": events,
        "delay_s": [delay.get(k) for k in keys],
        "onset_error_s": [error.get(k) for k in keys],
    }
    if directions is not None:
        result["by_direction"] = {}
        for name, sign in (("cool", -1), ("warm", 1)):
            group = [k for k, d in zip(keys, directions, strict=True) if (d > 0) == (sign > 0)]
            figures = _figures(group, spans_of, found, delay, error, min_duration)
            got = [found[k] for k in group if k in found]
            figures["right_direction"] = (round(sum(e.direction == sign for e in got) / len(got), 4)
                                          if got else None)
            result["by_direction"][name] = figures
    return result


def contact_of(ev: OnsetEvent, spans: Sequence[tuple[float, float]],
               after: float = EARLY) -> int | None:
    """Return which of a taxel's contacts ``(onset, release)`` the onset ``ev`` belongs to.

    The one whose span (widened by `EARLY` before and ``after`` after, see `release_window`)
    holds the coarse onset; failing that, the one the object still touched (or left less
    than ``after`` before) when the alarm was raised: a coarse onset dated early by a gust or
    the air's flutter before the contact does not make its alarm a false one. None if
    neither.
    """
    hit = next((i for i, (on, off) in enumerate(spans)
                if on - EARLY <= ev.time <= off + after), None)
    if hit is None:
        hit = next((i for i, (on, off) in enumerate(spans)
                    if on <= ev.detected_at <= off + after), None)
    return hit


def _figures(keys: Sequence[tuple[int, int]], spans: dict, found: dict, delay: dict,
             error: dict, min_duration: float) -> dict:
    """Return the detection rates, delay and onset error of the contacts ``keys``."""
    counted = [k for k in keys if spans[k][1] - spans[k][0] >= min_duration]
    err = np.asarray([error[k] for k in keys if k in found])
    dly = np.asarray([delay[k] for k in keys if k in found])
    return {
        "contacts": len(keys), "contacts_counted": len(counted),
        "detection_rate": round(sum(k in found for k in counted) / max(len(counted), 1), 4),
        "detection_rate_all": round(sum(k in found for k in keys) / max(len(keys), 1), 4),
        "delay_ms": median_p95(np.abs(dly), 1e3, 1),
        "onset_error_ms": {**median_p95(np.abs(err), 1e3, 1), "signed_median": None if err.size == 0
                           else round(1e3 * float(np.median(err)), 1)},
    }

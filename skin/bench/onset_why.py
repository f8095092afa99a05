"""Why the onset detector missed a contact or raised a false alarm, on a simulated stream.

`explain_outcomes` takes the detector's events of `skin.bench.onset_eval.evaluate_onsets`, the
stream's contacts and its schedules of gusts and heater switches (`skin.bench.streams.Stream`)
and gives every missed contact and every false alarm one cause, the first that applies in the
orders below. The causes are read off the truth and the events, not off the detector's
internals, so that any detector can be judged the same way.

Missed contacts:

- ``in_contact``: the detector was still in contact at the onset (its last event on the
  taxel before it was an onset: an earlier alarm or contact not released);
- ``warming_up``: a release was detected less than the detector's warm-up before the onset
  (or in the contact's first 0.3 s): the CUSUMs do not accumulate then;
- ``alarm_after_release``: the alarm came, but after the object had left (later than
  `skin.bench.onset_eval.release_window` after the release);
- ``gust``: a gust on the taxel was under way at the onset (its cooling and the contact's
  share the baseline);
- ``heater_switch``: the heater's duty switched within `SWITCH_WINDOW` s before the onset
  or during the contact;
- ``late_5sigma``: the contact's own change reached 5 of the sensor's sigmas only in its
  last 0.3 s (brief contacts of poor conductors; streams with a sensor description);
- ``gust_sized``: its change stays within what a gust does (the stream's deepest gust,
  scaled to the sensor): size cannot tell it from one;
- ``unflagged``: none of those: the detector's thresholds or its baseline, which follows a
  slow fall as a trend, let it pass.

False alarms:

- ``split``: inside a contact already detected (its reading turned, the detector released,
  then fell again: one touch reported twice);
- ``after_release``: within `RECOVERY_WINDOW` s after a contact's release window (the taxel
  reheating, or a contact's tail after a release the detector dated too early);
- ``before_onset``: within 2 s before a contact's onset (what the contact started, dated too
  early to belong to it);
- ``gust``: during a gust on the taxel (from its start to its end plus two rise times);
- ``heater_switch``: within `SWITCH_WINDOW` s after a heater duty switch on the taxel;
- ``warm_up``: in the stream's first `WARM_UP` s, or longer when the detector's slow average
  takes longer to settle (``settle``: its ``slow_tau``; low-cost's is 10.3 s);
- ``free``: none of those (the readout noise and the air's flutter).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from skin.bench.onset_eval import EARLY, contact_of

#: A heater duty switch this recent (s) may explain an alarm or a miss.
SWITCH_WINDOW = 10.0
#: An alarm this soon after a release (s) is put down to the taxel's recovery.
RECOVERY_WINDOW = 10.0
#: A contact that reaches 5 sigma only this close to its release (s) is too late to alarm on.
LATE = 0.3
#: An alarm this early in a stream (s) is put down to the detector's warm-up, at least.
WARM_UP = 5.0

MISS_CAUSES = ("in_contact", "warming_up", "alarm_after_release", "gust", "heater_switch",
               "late_5sigma", "gust_sized", "unflagged")
ALARM_CAUSES = ("split", "after_release", "before_onset", "gust", "heater_switch", "warm_up",
                "free")


def explain_outcomes(events: Sequence, contacts: Sequence, counted: Sequence[bool],
                     gusts: Sequence[tuple] = (), switches: Sequence[tuple] = (),
                     warmup: float = 0.5, gust_size: float = np.inf,
                     after: float = EARLY, settle: float = WARM_UP) -> dict:
    """Give each missed counted contact and each false alarm its cause (module docstring).

    Parameters
    ----------
    events : sequence of skin.stream.onset.OnsetEvent
        The detector's events, in time order.
    contacts : sequence of skin.bench.streams.StreamContact
        The stream's contacts.
    counted : sequence of bool
        For each contact, whether its miss is explained (e.g. the 5-sigma ones).
    gusts, switches : sequence of tuple
        The stream's schedules (`skin.bench.streams.Stream.gusts` and ``switches``).
    warmup : float
        The detector's warm-up after a release, s.
    gust_size : float
        A change no larger than this (K) is one a gust can make.
    after : float
        How long after a release an alarm is still the contact's
        (`skin.bench.onset_eval.release_window`), s.
    settle : float
        How long the detector's averages take to settle from the stream's start (its
        ``slow_tau``), s: alarms before ``max(WARM_UP, settle)`` are ``warm_up``.

    Returns
    -------
    dict
        ``misses``: {cause: count} over the counted contacts not detected, ``missed``: their
        total; ``false_alarms``: {cause: count}, ``false_alarm_total``; ``missed_contacts``:
        one row per miss (taxel, onset, duration, material, peak change in K, cause).
    """
    spans: dict[int, list[tuple[float, float]]] = {}
    index: dict[tuple[int, int], int] = {}
    for k, c in enumerate(contacts):
        rows = spans.setdefault(c.taxel, [])
        index[(c.taxel, len(rows))] = k
        rows.append((c.onset, c.release))
    by_taxel: dict[int, list] = {}
    for ev in events:
        by_taxel.setdefault(ev.taxel, []).append(ev)
    gusts_of: dict[int, list[tuple[float, float]]] = {}
    for start, j, _depth, rise, hold in gusts:
        gusts_of.setdefault(j, []).append((start, start + hold + 2.0 * rise))
    switches_of: dict[int, list[float]] = {}
    for t, j, _duty in switches:
        if t > 0:  # the first duty of each taxel is no switch
            switches_of.setdefault(j, []).append(t)

    found: set[int] = set()
    alarms = dict.fromkeys(ALARM_CAUSES, 0)
    for ev in events:
        if ev.kind != "onset":
            continue
        rows = spans.get(ev.taxel, [])
        hit = contact_of(ev, rows, after)
        if hit is not None and index[(ev.taxel, hit)] not in found:
            found.add(index[(ev.taxel, hit)])
            continue
        alarms[_alarm_cause(ev, rows, hit, gusts_of.get(ev.taxel, []),
                            switches_of.get(ev.taxel, []), after,
                            max(WARM_UP, settle))] += 1
    misses = dict.fromkeys(MISS_CAUSES, 0)
    rows_out = []
    for k, c in enumerate(contacts):
        if not counted[k] or k in found:
            continue
        cause = _miss_cause(c, by_taxel.get(c.taxel, []), gusts_of.get(c.taxel, []),
                            switches_of.get(c.taxel, []), warmup, gust_size, after)
        misses[cause] += 1
        rows_out.append({"taxel": c.taxel, "onset": round(c.onset, 3),
                         "duration": round(c.duration, 3), "material": c.material,
                         "peak_change_k": round(c.peak_change, 4), "cause": cause})
    return {"missed": sum(misses.values()), "misses": misses,
            "false_alarm_total": sum(alarms.values()), "false_alarms": alarms,
            "missed_contacts": rows_out}


def _alarm_cause(ev: object, rows: list[tuple[float, float]], hit: int | None,
                 gusts: list[tuple[float, float]], switches: list[float], after: float,
                 warm_up: float) -> str:
    t = ev.time
    if hit is not None:
        return "split"
    if any(off + after < t <= off + after + RECOVERY_WINDOW for _, off in rows):
        return "after_release"
    if any(on - 2.0 <= t < on for on, _ in rows):
        return "before_onset"
    if any(a - 0.5 <= t <= b for a, b in gusts):
        return "gust"
    if any(0.0 <= t - w <= SWITCH_WINDOW for w in switches):
        return "heater_switch"
    if t < warm_up:
        return "warm_up"
    return "free"


def _miss_cause(c: object, events: list, gusts: list[tuple[float, float]],
                switches: list[float], warmup: float, gust_size: float, after: float) -> str:
    before = [e for e in events if e.detected_at < c.onset]
    if before and before[-1].kind == "onset":
        return "in_contact"
    if any(e.kind == "release" and c.onset - warmup < e.detected_at <= c.onset + LATE
           for e in events):
        return "warming_up"
    if any(e.kind == "onset" and c.release + after < e.detected_at <= c.release + after + 3.0
           for e in events):
        return "alarm_after_release"
    if any(a <= c.onset <= b for a, b in gusts):
        return "gust"
    if any(c.onset - SWITCH_WINDOW <= w <= c.release for w in switches):
        return "heater_switch"
    if np.isfinite(c.five_sigma_after) and c.five_sigma_after > c.duration - LATE:
        return "late_5sigma"
    if c.peak_change <= gust_size:
        return "gust_sized"
    return "unflagged"

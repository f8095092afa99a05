"""Labelled contacts cut out of a recording: an MCAP file and a label file -> a trial dataset.

``skin dataset import run.mcap --labels touches.csv -o contacts.npz`` turns what a skin
recorded (`skin run --record`: calibrated temperatures and the contact events) into a
version 2 trial dataset (`skin.formats.dataset`), one trial per labelled contact:

- each contact's final event gives its taxels and onset; the label is the touch of the label
  file (`skin.formats.touch_labels`) whose start lies within ``tolerance`` s of the onset (and,
  when the label names taxels, shares at least one with the contact); the nearest one wins, and
  one label names at most one contact;
- the trial holds the ``pre`` s before the onset and ``duration`` s after it, from the
  recording's calibrated temperatures, one channel per taxel of the contact (at most
  ``channels``; the taxel that cooled most first, the others NaN-padded), ``onset`` at sample
  ``pre * fs``; ``heated`` from the taxel's board (a board with no heater voltage is passive);
  ``ambient`` from the event; ``group`` from the label (else one per trial); and, to trace a
  trial back, ``contact`` (the event's contact id) and ``onset_time`` (device time, s).

Contacts without a label, labels without a contact, and contacts too close to either end of
the recording are reported (`Skipped`), never silently dropped.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skin.formats.dataset import DatasetError, TrialSet
from skin.formats.touch_labels import TouchLabel


@dataclass(frozen=True)
class Skipped:
    """A contact or a label that did not become a trial, and why."""

    kind: str  # "contact" or "label"
    ident: str
    reason: str

    def __str__(self) -> str:
        return f"{self.kind} {self.ident}: {self.reason}"


def _final_events(events: list[dict]) -> list[dict]:
    """Return the last record of every contact (its final answer), in onset order."""
    last: dict[int, dict] = {}
    for rec in events:
        last[int(rec["contact"])] = rec
    return sorted(last.values(), key=lambda r: r["onset"])


def _match(events: list[dict], labels: list[TouchLabel], tolerance: float
           ) -> dict[int, int]:
    """Pair contacts (index into events) with labels (index into labels), nearest first."""
    pairs = []
    for i, rec in enumerate(events):
        for j, lab in enumerate(labels):
            gap = abs(rec["onset"] - lab.time)
            if gap <= tolerance and (not lab.taxels or set(lab.taxels) & set(rec["taxels"])):
                pairs.append((gap, i, j))
    matched: dict[int, int] = {}
    used: set[int] = set()
    for _, i, j in sorted(pairs):
        if i not in matched and j not in used:
            matched[i] = j
            used.add(j)
    return matched


def contacts_from_recording(path: str | Path, labels: list[TouchLabel], *, pre: float = 0.5,
                            duration: float = 3.0, tolerance: float = 0.5,
                            channels: int | None = None) -> tuple[TrialSet, list[Skipped]]:
    """Cut the labelled contacts of a recording into a version 2 `TrialSet`.

    Parameters
    ----------
    path : str or Path
        The MCAP recording (`skin.drivers.recording`), with temperatures and events.
    labels : list of TouchLabel
        The touches (`skin.formats.touch_labels.read_touch_labels`).
    pre, duration : float
        Seconds kept before and after each contact's onset.
    tolerance : float
        Largest distance between a contact's onset and its label's time, s.
    channels : int, optional
        Channels per trial (taxels kept per contact); default: the most any contact has.

    Returns
    -------
    (TrialSet, list of Skipped)

    Raises
    ------
    DatasetError
        A recording without temperatures or events, bad parameters, or no labelled contact.
    skin.drivers.recording.RecordingError
        A file that is not a recording, or a corrupt one (with the byte offset).
    """
    from skin.drivers.recording import read_recording

    if not (pre >= 0 and duration > 0 and tolerance > 0):
        raise DatasetError(f"pre ({pre}) must be >= 0, duration ({duration}) and tolerance "
                           f"({tolerance}) > 0")
    if channels is not None and channels < 1:
        raise DatasetError(f"channels must be at least 1, got {channels}")
    rec = read_recording(path)
    src = str(rec.path)
    if rec.temperature.shape[0] < 2:
        raise DatasetError(f"{src}: the recording holds no temperatures (record with `skin run "
                           f"--record FILE.mcap`)")
    if not rec.events:
        raise DatasetError(f"{src}: the recording holds no contact events (record with `skin "
                           f"run --record FILE.mcap`, which keeps the events)")
    times = rec.times
    steps = np.diff(times)
    fs = 1.0 / float(np.median(steps))
    n_pre, n_post = round(pre * fs), round(duration * fs)
    layout = rec.layout
    events = _final_events(rec.events)
    matched = _match(events, labels, tolerance)
    skipped = [Skipped("label", f"line {lab.line} (t={lab.time:g} s, {lab.material})",
                       f"no contact within {tolerance:g} s")
               for j, lab in enumerate(labels) if j not in set(matched.values())]
    width = channels or max(len(e["taxels"]) for e in events)
    temps, lab_names, onsets, ambient, group, taxel, heated = [], [], [], [], [], [], []
    contact_ids, onset_times = [], []
    for i, ev in enumerate(events):
        ident = f"{ev['contact']} (t={ev['onset']:g} s, taxels {ev['taxels']})"
        if i not in matched:
            skipped.append(Skipped("contact", ident, f"no label within {tolerance:g} s (the "
                                   f"run called it {ev.get('label')})"))
            continue
        k = int(np.searchsorted(times, ev["onset"]))
        lo, hi = k - n_pre, k + n_post
        if lo < 0 or hi > len(times):
            skipped.append(Skipped("contact", ident, f"the {pre:g} s before or {duration:g} s "
                                   f"after its onset run past the recording"))
            continue
        if np.any(steps[lo:hi - 1] > 1.5 / fs):
            skipped.append(Skipped("contact", ident, "samples are missing in its window"))
            continue
        cols = [layout.index(int(t)) for t in ev["taxels"]]
        x = rec.temperature[lo:hi, cols].T  # (taxels, samples)
        if not np.all(np.isfinite(x)):
            bad = [int(ev["taxels"][c]) for c in np.flatnonzero(~np.isfinite(x).all(axis=1))]
            skipped.append(Skipped("contact", ident, f"taxel(s) {bad} without a reading in "
                                   f"its window"))
            continue
        drop = x[:, :n_pre].mean(axis=1) - x[:, n_pre:].min(axis=1) if n_pre else -x.min(axis=1)
        order = np.argsort(-drop, kind="stable")[:width]
        trial = np.full((width, n_pre + n_post), np.nan)
        trial[: len(order)] = x[order]
        ids = np.full(width, -1, dtype=np.int64)
        ids[: len(order)] = [int(ev["taxels"][c]) for c in order]
        heat = np.ones(width, dtype=bool)
        heat[: len(order)] = [layout.board_of(cols[c]).heater_voltage > 0 for c in order]
        lab = labels[matched[i]]
        temps.append(trial)
        lab_names.append(lab.material)
        onsets.append(n_pre)
        ambient.append(float(ev.get("ambient", np.nan)))
        group.append(lab.group)
        taxel.append(ids)
        heated.append(heat)
        contact_ids.append(int(ev["contact"]))
        onset_times.append(float(ev["onset"]))
    if not temps:
        first = f"; first: {skipped[0]}" if skipped else ""
        raise DatasetError(f"{src}: no labelled contact to cut{first}")
    given = [g for g in group if g is not None]
    own = iter(range(max(given, default=-1) + 1, 2**62))  # a touch without one: its own group
    groups = np.array([g if g is not None else next(own) for g in group], dtype=np.int64)
    amb = np.array(ambient)
    data = TrialSet(np.array(temps), fs, np.array(lab_names), np.array(onsets, dtype=np.int64),
                    ambient=amb if np.all(np.isfinite(amb)) else None, group=groups,
                    taxel=np.array(taxel), heated=np.array(heated), source=src,
                    extra={"contact": np.array(contact_ids, dtype=np.int64),
                           "onset_time": np.array(onset_times)})
    return data, skipped

"""Contact tracking: group taxel onsets into contacts and cut each taxel's window.

Onsets of neighbouring taxels (by the layout's geometry) within ``join_window`` seconds of each
other form one contact.  A contact is decided, and handed on for classification, when all its
taxels are released or when ``window`` seconds have passed since its first onset, whichever
comes first; each taxel's window then runs from its refined onset to its release or the cut.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from skin.contact import Contact, TaxelWindow
from skin.layout import Layout
from skin.onset import OnsetEvent
from skin.onset_refine import refine_onset


@dataclass
class _Member:
    coarse: float
    baseline: float
    slope: float
    release: float | None = None  # when the temperature stopped falling
    released_at: float | None = None  # when the release was recognised


@dataclass
class _OpenContact:
    id: int
    first: float
    members: dict[int, _Member] = field(default_factory=dict)


class _History:
    """A ring buffer of the last ``capacity`` samples of every taxel."""

    def __init__(self, capacity: int, n_taxels: int) -> None:
        self.t = np.full(capacity, np.nan)
        self.y = np.full((capacity, n_taxels), np.nan)
        self.ambient = np.full(capacity, np.nan)
        self.head = 0  # total samples written

    def append(self, t: np.ndarray, y: np.ndarray, ambient: np.ndarray) -> None:
        cap = len(self.t)
        n = len(t)
        if n >= cap:
            t, y, ambient = t[-cap:], y[-cap:], ambient[-cap:]
            self.head += n - cap
            n = cap
        idx = (self.head + np.arange(n)) % cap
        self.t[idx] = t
        self.y[idx] = y
        self.ambient[idx] = ambient
        self.head += n

    def between(self, start: float, end: float) -> np.ndarray:
        """Ring indices of the samples with start <= t <= end, in time order."""
        cap = len(self.t)
        n = min(self.head, cap)
        order = (self.head - n + np.arange(n)) % cap
        tt = self.t[order]
        return order[(tt >= start) & (tt <= end)]


class ContactTracker:
    """Group onsets into contacts and emit them, with their windows, once decided.

    Parameters
    ----------
    layout : Layout
        Taxel geometry (for neighbours) and sensor constants (for onset refinement).
    sample_rate : float
        Samples per second.
    window : float
        Longest window handed to the classifier, s.
    join_window : float
        Onsets of neighbours at most this far apart join one contact, s.
    search : float
        How far before the coarse onset the refinement looks, s.
    """

    def __init__(
        self,
        layout: Layout,
        sample_rate: float,
        *,
        window: float = 2.5,
        join_window: float = 0.5,
        search: float = 0.6,
    ) -> None:
        self.layout = layout
        self.window = window
        self.join_window = join_window
        self.search = search
        self.neighbours = layout.neighbours()
        self.depth = layout.board_array("sensor_depth")
        self.diffusivity = layout.board_array("sensor_diffusivity")
        capacity = int(np.ceil((window + search + join_window + 2.0) * sample_rate))
        self._piece = int(sample_rate)  # a chunk is taken in pieces of at most 1 s
        self._history = _History(capacity + self._piece, len(layout))
        self._open: list[_OpenContact] = []
        self._owner: dict[int, _OpenContact] = {}
        self._next_id = 0
        self.now = -np.inf

    @property
    def open_contacts(self) -> int:
        """Number of contacts not yet decided."""
        return len(self._open)

    def update(
        self, times: np.ndarray, temperature: np.ndarray, ambient: np.ndarray,
        events: list[OnsetEvent],
    ) -> list[Contact]:
        """Take a chunk of samples and the detector's events for it; return decided contacts.

        Contacts are decided at instants fixed by the events (never by where a chunk ends),
        so any chunking of a stream gives the same contacts.
        """
        times = np.asarray(times, float)
        temperature = np.asarray(temperature, float)
        ambient = np.asarray(ambient, float)
        decided: list[Contact] = []
        step = self._piece
        for i in range(0, len(times), step):  # pieces keep the history long enough
            t_end = float(times[min(i + step, len(times)) - 1])
            t_begin = float(times[i])
            self._history.append(times[i : i + step], temperature[i : i + step],
                                 ambient[i : i + step])
            for ev in events:
                if t_begin <= ev.detected_at <= t_end:
                    decided += self._decide(before=ev.detected_at, inclusive=False)
                    self._on_event(ev)
            self.now = t_end
            decided += self._decide(before=t_end, inclusive=True)
        return decided

    def flush(self) -> list[Contact]:
        """Decide every open contact now (end of stream)."""
        return self._decide(before=np.inf, inclusive=True, at=self.now)

    def _on_event(self, ev: OnsetEvent) -> None:
        if ev.kind == "onset":
            self._on_onset(ev)
        elif ev.kind == "release" and (owner := self._owner.get(ev.taxel)) is not None:
            owner.members[ev.taxel].release = ev.time
            owner.members[ev.taxel].released_at = ev.detected_at

    def _on_onset(self, ev: OnsetEvent) -> None:
        member = _Member(ev.time, ev.baseline, ev.slope)
        for contact in self._open:
            if any(
                self.neighbours[ev.taxel, k] and abs(ev.time - m.coarse) <= self.join_window
                for k, m in contact.members.items()
            ):
                contact.members[ev.taxel] = member
                self._owner[ev.taxel] = contact
                return
        contact = _OpenContact(self._next_id, ev.time, {ev.taxel: member})
        self._next_id += 1
        self._open.append(contact)
        self._owner[ev.taxel] = contact

    def _decision_time(self, contact: _OpenContact) -> float:
        """When a contact is decided: all taxels released (and joining over), or the window cut."""
        cut = contact.first + self.window
        released = [m.released_at for m in contact.members.values()]
        if all(r is not None for r in released):
            return min(cut, max(contact.first + self.join_window, max(released)))
        return cut

    def _decide(self, before: float, inclusive: bool, at: float | None = None) -> list[Contact]:
        due = []
        for contact in self._open:
            when = self._decision_time(contact)
            if when < before or (inclusive and when <= before):
                due.append((when if at is None else min(when, at), contact))
        due.sort(key=lambda item: (item[0], item[1].id))
        done = []
        for when, contact in due:
            done.append(self._finish(contact, when))
            self._open.remove(contact)
            for k in contact.members:
                if self._owner.get(k) is contact:
                    del self._owner[k]
        return done

    def _finish(self, contact: _OpenContact, when: float) -> Contact:
        h = self._history
        windows, onsets, ambients = [], [], []
        for k, m in sorted(contact.members.items()):
            end = min(m.release if m.release is not None else when, m.coarse + self.window)
            idx = h.between(m.coarse - self.search, end)
            onset, initial = refine_onset(h.t[idx], h.y[idx, k], m.coarse, m.baseline, m.slope,
                                          self.depth[k], self.diffusivity[k], search=self.search)
            end = min(end, onset + self.window)
            sel = idx[(h.t[idx] >= onset) & (h.t[idx] <= end)]
            windows.append(TaxelWindow(
                taxel=int(self.layout.ids[k]), onset=onset, initial=initial,
                time=h.t[sel] - onset, temperature=h.y[sel, k].copy(),
                released=m.release is not None,
            ))
            onsets.append(onset)
            ambients.append(h.ambient[sel])
        releases = [m.release for m in contact.members.values()]
        amb = np.concatenate(ambients) if ambients else np.array([])
        amb = amb[np.isfinite(amb)]
        return Contact(
            id=contact.id,
            taxels=[w.taxel for w in windows],
            onset=float(np.median(onsets)),
            release=max(releases) if all(r is not None for r in releases) else None,
            ambient=float(amb.mean()) if amb.size else float("nan"),
            windows=windows,
            decided_at=when,
        )

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
from skin.onset import OnsetEvent, refine_onset


@dataclass
class _Member:
    coarse: float
    baseline: float
    slope: float
    release: float | None = None


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
        self._history = _History(capacity, len(layout))
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
        """Take a chunk of samples and the detector's events for it; return decided contacts."""
        if len(times):
            self._history.append(np.asarray(times, float), np.asarray(temperature, float),
                                 np.asarray(ambient, float))
            self.now = float(times[-1])
        for ev in events:
            if ev.kind == "onset":
                self._on_onset(ev)
            elif ev.kind == "release":
                owner = self._owner.get(ev.taxel)
                if owner is not None:
                    owner.members[ev.taxel].release = ev.time
        return self._decide(force=False)

    def flush(self) -> list[Contact]:
        """Decide every open contact now (end of stream)."""
        return self._decide(force=True)

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

    def _decide(self, force: bool) -> list[Contact]:
        done = []
        for contact in list(self._open):
            all_released = all(m.release is not None for m in contact.members.values())
            joined = self.now >= contact.first + self.join_window
            due = self.now >= contact.first + self.window
            if force or (all_released and joined) or due:
                done.append(self._finish(contact))
                self._open.remove(contact)
                for k in contact.members:
                    if self._owner.get(k) is contact:
                        del self._owner[k]
        return done

    def _finish(self, contact: _OpenContact) -> Contact:
        h = self._history
        windows, onsets, ambients = [], [], []
        for k, m in sorted(contact.members.items()):
            end = min(m.release if m.release is not None else self.now, m.coarse + self.window)
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
            decided_at=self.now,
        )

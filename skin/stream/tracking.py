"""Contact tracking: group taxel onsets into contacts and cut each taxel's samples.

A contact is a connected group of onsets: an onset joins every open contact that holds a
neighbour of its taxel (by the layout's geometry) whose onset lies within ``join_window``
seconds of it and which has not been released before it (the two overlap in time); when it
joins several, they become one (an onset can bridge two pieces of one touch that began apart:
taxels diagonal to each other, then the taxel between them). ``join_window`` follows from
the sensor (`join_window_for`): the coarse onsets of one touch's taxels lie within a fraction
of it. A contact is decided when all its taxels are released or when
``window`` seconds have passed since its first onset, whichever comes first; the tracker then
hands on a `DecidedContact` holding, per taxel, the samples from ``search`` seconds before its
coarse onset to its release or the cut (a released taxel's to the decision: the free
response after its release). `refine_member` dates each taxel's onset on those samples, and
a released taxel's release again (`skin.stream.release_refine`: the detector dates it at the
reading's extreme, tens of milliseconds late), and `finish_contact` cuts the windows at the
refined release: steps of their own, so that the pipeline can
spread the costly refinements of many contacts decided at once over the frames that follow.

The tracker's work per sample does not grow with the number of open contacts: decisions wait
in a heap ordered by their instant, and an onset looks only at its own taxel's neighbours.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from skin.contact import Contact, TaxelWindow
from skin.formats.layout import Layout
from skin.stream.onset import OnsetEvent
from skin.stream.onset_refine import refine_onset
from skin.stream.release_refine import refine_release

#: Onsets of neighbours at most this far apart join one contact with the paper's sensor, s.
#: The coarse onsets of one touch's taxels lie within 0.15 s of each other (median 0.015 s,
#: scene seeds 7-13, 15 touches each); two touches of one spot a second apart stay two.
JOIN_WINDOW = 0.5
#: The heap key of a contact's final decision (provisional snapshots count 0, 1, ...).
FINAL = 1 << 30


@dataclass(frozen=True)
class TaxelSamples:
    """One taxel of a decided contact, before its onset is refined.

    Attributes
    ----------
    index : int
        Array index of the taxel (layout order).
    coarse, baseline, slope : float
        The detector's coarse onset (s), baseline there (deg C) and slope before it (K/s).
    release : float or None
        When the temperature stopped falling, s; None if still touching at the decision.
    end : float
        Last instant of the taxel's window (release, decision or cut), s.
    time, temperature, ambient : numpy.ndarray
        The samples from ``coarse - search`` to ``end`` (copies); past a release, to the
        decision (the free response after it, for `refine_member`).
    dated_by : str
        ``"thermal"`` (the onset detector's coarse onset, refined by `refine_member`) or
        ``"force"`` (the force channel's onset and release, exact: `refine_member` keeps
        them; ``baseline`` is then the temperature at the onset).
    quiet_since : float
        When the taxel was last quiet from: its earlier activity's end (the release of its
        last contact before this one, or that contact's decision where it was not released),
        or the start of its samples; -inf where not known. The samples before the onset
        from then on hold no earlier touch's own change (its reheat aside, which the free
        trajectory follows): `skin.stream.response` measures the noise on them.
    """

    index: int
    coarse: float
    baseline: float
    slope: float
    release: float | None
    end: float
    time: np.ndarray
    temperature: np.ndarray
    ambient: np.ndarray
    dated_by: str = "thermal"
    quiet_since: float = -math.inf


@dataclass(frozen=True)
class DecidedContact:
    """A contact whose taxels are known and whose samples are cut, not yet refined.

    Attributes
    ----------
    id : int
        Running number.
    decided_at : float
        Device time of the decision, s.
    members : list of TaxelSamples
        In layout order.
    final : bool
        False for a provisional snapshot of a contact still open (its final decision follows).
    """

    id: int
    decided_at: float
    members: list[TaxelSamples]
    final: bool = True


@dataclass
class _Member:
    coarse: float
    baseline: float
    slope: float
    release: float | None = None  # when the temperature stopped falling
    released_at: float | None = None  # when the release was recognised
    dated_by: str = "thermal"
    quiet: float = -np.inf  # when the taxel's activity before this contact ended


@dataclass
class _OpenContact:
    id: int
    first: float
    members: dict[int, _Member] = field(default_factory=dict)
    when: float = np.inf  # current decision time (heap entries that differ are stale)
    snapshots: int = 0  # provisional snapshots handed on


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
    """Group onsets into contacts and hand them on, with their samples, once decided.

    Parameters
    ----------
    layout : Layout
        Taxel geometry (for neighbours).
    sample_rate : float
        Samples per second.
    window : float
        Longest window handed to the classifier, s.
    join_window : float
        Onsets of neighbours at most this far apart join one contact, s (`join_window_for`
        gives the sensor's).
    search : float
        How far before the coarse onset the samples reach (the refinement's span), s.
    provisional : sequence of float
        Seconds after a contact's first onset at which a provisional snapshot of it is handed
        on while it is still open (an anytime answer before the final one); empty: none.
        A contact that has handed one on is never merged into another (its final follows);
        a merged contact keeps the snapshot instants of the one it was merged into.
    """

    def __init__(
        self,
        layout: Layout,
        sample_rate: float,
        *,
        window: float = 2.5,
        join_window: float = JOIN_WINDOW,
        search: float = 0.6,
        provisional: Sequence[float] = (),
    ) -> None:
        if not window > 0:
            raise ValueError(f"the window must be positive, got {window} s")
        if any(not 0 < p < window for p in provisional):
            raise ValueError(f"provisional instants must lie between 0 and the window "
                             f"({window} s), got {list(provisional)}")
        self.window = window
        self.join_window = join_window
        self.search = search
        self.provisional = tuple(sorted(provisional))
        self.neighbours = layout.neighbour_lists()
        capacity = int(np.ceil((window + search + join_window + 2.0) * sample_rate))
        self._piece = int(sample_rate)  # a chunk is taken in pieces of at most 1 s
        self._history = _History(capacity + self._piece, len(layout))
        self._open: dict[int, _OpenContact] = {}
        # (instant, contact id, k): the k-th provisional snapshot, or the final decision (FINAL)
        self._heap: list[tuple[float, int, int]] = []
        self._owner: dict[int, _OpenContact] = {}
        self._ended: dict[int, float] = {}  # per taxel, when its last activity ended
        self._next_id = 0
        self.now = -np.inf

    @property
    def open_contacts(self) -> int:
        """Number of contacts not yet decided."""
        return len(self._open)

    def update(
        self, times: np.ndarray, temperature: np.ndarray, ambient: np.ndarray,
        events: list[OnsetEvent],
    ) -> list[DecidedContact]:
        """Take a chunk of samples and the detector's events for it; return decided contacts.

        Contacts are decided at instants fixed by the events (never by where a chunk ends),
        so any chunking of a stream gives the same contacts.
        """
        times = np.asarray(times, float)
        temperature = np.asarray(temperature, float)
        ambient = np.asarray(ambient, float)
        decided: list[DecidedContact] = []
        step = self._piece
        pending = sorted(events, key=lambda ev: ev.detected_at)
        e = 0
        for i in range(0, len(times), step):  # pieces keep the history long enough
            t_end = float(times[min(i + step, len(times)) - 1])
            self._history.append(times[i : i + step], temperature[i : i + step],
                                 ambient[i : i + step])
            while e < len(pending) and pending[e].detected_at <= t_end:
                ev = pending[e]
                decided += self._decide(before=ev.detected_at, inclusive=False)
                self._on_event(ev)
                e += 1
            self.now = t_end
            decided += self._decide(before=t_end, inclusive=True)
        return decided

    def flush(self) -> list[DecidedContact]:
        """Decide every open contact now (end of stream)."""
        return self._decide(before=np.inf, inclusive=True, at=self.now)

    def _on_event(self, ev: OnsetEvent) -> None:
        if ev.kind == "onset":
            self._on_onset(ev)
        elif ev.kind == "release":
            # the taxel's activity ends here, whether or not its contact is still open (one
            # longer than the window was decided while touching: its release comes after)
            self._ended[ev.taxel] = max(self._ended.get(ev.taxel, -np.inf), ev.time)
            if (owner := self._owner.get(ev.taxel)) is not None:
                owner.members[ev.taxel].release = ev.time
                owner.members[ev.taxel].released_at = ev.detected_at
                self._schedule(owner, ev.detected_at)

    def _on_onset(self, ev: OnsetEvent) -> None:
        quiet = self._ended.get(ev.taxel, -np.inf)
        before = self._owner.get(ev.taxel)
        if before is not None and before.members[ev.taxel].release is None:
            # its contact still open and not released: nothing quiet since, but where this
            # onset joins that contact (a force onset confirming a thermal one): its quiet
            quiet = before.members[ev.taxel].quiet
            if abs(ev.time - before.members[ev.taxel].coarse) > self.join_window:
                quiet = ev.time
        member = _Member(ev.time, ev.baseline, ev.slope, dated_by=ev.dated_by, quiet=quiet)
        joined: list[_OpenContact] = []
        # a force onset confirming a thermal one of its taxel replaces it (one contact)
        own = (ev.taxel,) if ev.dated_by == "force" else ()
        for k in (*own, *self.neighbours[ev.taxel]):
            c = self._owner.get(int(k))
            if c is None or any(c is j for j in joined):
                continue
            m = c.members[int(k)]
            if (abs(ev.time - m.coarse) <= self.join_window
                    and (m.release is None or m.release >= ev.time)):  # they overlap in time
                joined.append(c)
        if joined:
            # one contact: the oldest, or the one already reported provisionally; a contact
            # with a provisional answer out is not merged into another (its final must follow)
            contact = min(joined, key=lambda c: (c.snapshots == 0, c.id))
            for other in joined:
                if other is not contact and other.snapshots == 0:
                    self._merge(contact, other)
        else:
            contact = _OpenContact(self._next_id, ev.time)
            self._next_id += 1
            self._open[contact.id] = contact
            for k, p in enumerate(self.provisional):
                heapq.heappush(self._heap, (max(contact.first + p, ev.detected_at),
                                            contact.id, k))
        contact.members[ev.taxel] = member
        self._owner[ev.taxel] = contact
        self._schedule(contact, ev.detected_at)

    def _merge(self, into: _OpenContact, other: _OpenContact) -> None:
        """Make ``other`` (open, no snapshot taken) part of ``into``; its queue entries go stale.

        ``into`` keeps its snapshot instants; its decision is rescheduled by the caller.
        """
        del self._open[other.id]
        for k, m in other.members.items():
            if self._owner.get(k) is other:
                self._owner[k] = into
                into.members[k] = m
            elif k not in into.members:  # touched again since, now another contact's
                into.members[k] = m
        into.first = min(into.first, other.first)

    def _schedule(self, contact: _OpenContact, now: float) -> None:
        """(Re)compute when a contact is decided and queue it; older queue entries go stale.

        Never before ``now``, the detection of the event that changed it: an onset dated
        long before it was recognised does not make a decision in the past.
        """
        cut = contact.first + self.window
        released = [m.released_at for m in contact.members.values()]
        when = cut
        if all(r is not None for r in released):
            when = min(cut, max(contact.first + self.join_window, max(released)))
        when = max(when, now)
        if when != contact.when:
            contact.when = when
            heapq.heappush(self._heap, (when, contact.id, FINAL))

    def _decide(self, before: float, inclusive: bool,
                at: float | None = None) -> list[DecidedContact]:
        done = []
        heap = self._heap
        while heap and (heap[0][0] < before or (inclusive and heap[0][0] <= before)):
            when, cid, k = heapq.heappop(heap)
            contact = self._open.get(cid)
            if contact is None:
                continue  # decided already
            instant = when if at is None else min(when, at)
            if k != FINAL:
                if when < contact.when:  # a snapshot after the final decision is not taken
                    contact.snapshots += 1
                    done.append(self._cut(contact, instant, final=False))
                continue
            if contact.when != when:
                continue  # stale entry: the decision moved
            del self._open[cid]
            for m, member in contact.members.items():
                if self._owner.get(m) is contact:
                    del self._owner[m]
                if member.release is None:  # decided while touching: its activity ends here
                    self._ended[m] = max(self._ended.get(m, -np.inf), instant)
            done.append(self._cut(contact, instant))
        return done

    def _cut(self, contact: _OpenContact, when: float, final: bool = True) -> DecidedContact:
        h = self._history
        members = []
        for k, m in sorted(contact.members.items()):
            end = min(m.release if m.release is not None else when, m.coarse + self.window)
            # past a release: the samples up to the decision (the free response after it,
            # for `refine_member` to date the release; the window still ends at ``end``),
            # short of the taxel's next contact
            stop = end if m.release is None else when
            other = self._owner.get(k)
            if m.release is not None and other is not None and other is not contact:
                stop = max(end, min(stop, other.members[k].coarse))
            idx = h.between(m.coarse - self.search, stop)
            first = float(h.t[idx[0]]) if idx.size else m.coarse - self.search
            members.append(TaxelSamples(k, m.coarse, m.baseline, m.slope, m.release, end,
                                        h.t[idx], h.y[idx, k], h.ambient[idx], m.dated_by,
                                        max(first, min(m.quiet, m.coarse))))
        return DecidedContact(contact.id, when, members, final)


def join_window_for(sensor: object | None) -> float:
    """Return the tracker's ``join_window`` for a sensor description (None: the paper's), s.

    `JOIN_WINDOW`, stretched with the sensor's response time when it is slower than the
    paper's, as the onset detector's time constants are: a slow sensor's contact departs
    slowly and its coarse onsets scatter as much more (the low-cost preset's slow channel
    dates one touch's taxels 0.55 s apart).
    """
    if sensor is None:
        return JOIN_WINDOW
    from skin.models.sensors import SensorDescription

    return JOIN_WINDOW * max(1.0, sensor.response_time / SensorDescription().response_time)


def refine_member(member: TaxelSamples, depth: np.ndarray, diffusivity: np.ndarray,
                  search: float = 0.6, sensor: object | None = None,
                  ) -> tuple[float, float, float]:
    """Refined onset, initial temperature and window end of one taxel of a decided contact.

    ``search`` is the paper sensor's span; with a ``sensor`` description the refinement fits
    its own response over a span stretched with its response time
    (`skin.stream.onset_refine.refine_span`: the tracker's ``search`` should be that). The
    onset is fitted on the samples up to ``member.end``; a released taxel's release is then
    dated again on its samples past it (`skin.stream.release_refine.refine_release`), the
    window ends there (``member.end`` otherwise), and when that is earlier the onset is
    fitted again on the samples up to it. A force-dated member (``member.dated_by``
    ``"force"``) keeps its onset, initial temperature (its ``baseline``) and end as they are.
    """
    if member.dated_by == "force":  # the force's release is its first sample read free
        end = member.end
        if member.release is not None and member.end >= member.release:
            before = member.time[member.time < member.release]
            end = float(before[-1]) if before.size else member.release
        return member.coarse, member.baseline, end
    k = member.index
    upto = member.time <= member.end
    onset, initial = refine_onset(member.time[upto], member.temperature[upto], member.coarse,
                                  member.baseline, member.slope, depth[k], diffusivity[k],
                                  search=search, sensor=sensor)
    end = member.end
    if member.release is not None and member.end >= member.release:
        release = refine_release(member.time, member.temperature, onset, member.release,
                                 depth[k], diffusivity[k], sensor=sensor)
        end = min(member.end, release)
        if end < member.end:
            # the onset fitted again without the samples past the contact: they pulled a
            # short contact's fitted onset early (default scene, touches <= 0.6 s: -9 ms
            # median, -51 ms at 5 %)
            upto = member.time <= end
            onset, initial = refine_onset(member.time[upto], member.temperature[upto],
                                          member.coarse, member.baseline, member.slope,
                                          depth[k], diffusivity[k], search=search,
                                          sensor=sensor)
    return onset, initial, end


def finish_contact(decided: DecidedContact, layout: Layout,
                   refined: list[tuple[float, float, float]], window: float = 2.5) -> Contact:
    """Build the `Contact` from a decided contact and its members' refined onsets.

    ``refined`` holds each member's (onset, initial, end) from `refine_member`: the window
    ends at ``end`` (the refined release, or the member's own end).
    """
    windows, onsets, ambients, releases = [], [], [], []
    for m, (onset, initial, last) in zip(decided.members, refined, strict=True):
        end = min(last, onset + window)
        releases.append(None if m.release is None else min(m.release, last))
        sel = (m.time >= onset) & (m.time <= end)
        windows.append(TaxelWindow(
            taxel=int(layout.ids[m.index]), onset=onset, initial=initial,
            time=m.time[sel] - onset, temperature=m.temperature[sel],
            released=m.release is not None, dated_by=m.dated_by,
        ))
        onsets.append(onset)
        ambients.append(m.ambient[sel])
    amb = np.concatenate(ambients) if ambients else np.array([])
    amb = amb[np.isfinite(amb)]
    return Contact(
        id=decided.id,
        taxels=[w.taxel for w in windows],
        onset=float(np.median(onsets)),
        release=max(releases) if all(r is not None for r in releases) else None,
        ambient=float(amb.mean()) if amb.size else float("nan"),
        windows=windows,
        decided_at=decided.decided_at,
        final=decided.final,
    )

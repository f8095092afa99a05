"""Contact onsets and releases dated by a force (or contact-switch) channel, streaming.

A taxel whose frames carry a force reading (`skin.frame.Frame.force`) may be dated by it: its
contact begins where the force first exceeds its free level by `FORCE_CONTACT_SNR` noise
levels and stays over that `FORCE_CONTACT_HELD`, and ends where it stays under it as long. The
onset is the dating core of `skin.models.commission.force_contacts`
(`skin.models.commission.force_onset`, shared): for a fast press, back along the rise to
where it left the free level; for a slow one (a rise longer than the held time) near where it
crosses the threshold. It is never put before the ring's start nor the taxel's last release.

The free level and noise are each taxel's `skin.models.commission.span_noise` per stretch of
`FORCE_NOISE_SPAN` samples or `SPAN_SECONDS`, whichever is shorter (but 20 samples; counted
from the stream's first sample), the median of the last `SPANS` stretches that were at least
half free and quiet (their free readings spread over at most twice the threshold): a touch
begun in the first stretch is not learnt as the free level. A quiet stretch far under the
level once the readings have been held there `FRESH_SECONDS` (a taxel pressed since the
stream began, released) replaces it, and is not learnt before (nor is a press of an
inverted channel); a contact flat near its
threshold for `LOCK_SECONDS` (a drifting free level) is ended there and the level re-learnt,
with a note (`ForceOnsets.notes`).

The force overrules the onset detector on a taxel (drops the detector's events where it shows
no contact) only once it has dated a contact there (onset and release); until then the
detector's events are kept but for those within `CONFIRM_SECONDS` of a force contact (the same
touch). Where the force's level is not known yet (the first quiet stretch: 0.5 s at 200 Hz, 1
s at 100 Hz or slower), where it has had no reading for `FORCE_CONTACT_HELD`, where it is
stuck (one value at its free level for `FORCE_STUCK` s and 100 samples on a taxel whose free
readings have varied, as `skin.models.commission.force_stuck`) and during a contact it did not
date (a rise after a gap of more than `FORCE_CONTACT_HELD` or the stream's start: force coming
back mid-contact; `GRACE_SECONDS` after it), the detector's events are kept. A dead channel
(never a contact) thus never hides the detector's touches; detector onsets the force did not
see are counted (`ForceOnsets.unseen`) and noted. A run of readings restarts after a gap: a
release inside a gap is dated at the first reading after it.

An inverted channel (a miswired sensor, an active-low switch: high at rest, falling when
pressed) would date contacts at the touches' releases. Each of the detector's onsets is
matched with the taxel's force edge within `CONFIRM_SECONDS` of it: a rise (a force onset)
is a vote for the channel's polarity, a fall (the readings held as far under the free level
as the threshold is over it; not a release, which a late detector onset after a short touch
would meet) a vote against. While a taxel's votes
against outnumber those for, its force dates nothing (onsets withheld, the detector's events
kept); once there are `INVERT_VOTES` against and none for (`INVERT_VOTES` more for each
vote for), at the close of a stretch, its readings are taken negated from there on, its free
level negated and its votes counted afresh, with a note naming it (`ForceOnsets.polarity`;
a wrong turn is turned back by the same rule). A taxel whose force the detector never
confirms (a dead channel, or a sensor too noisy for the detector) is never turned.

Unlike the whole-recording `force_contacts`, the threshold has no share of the strongest touch
(that needs the recording's end): a force whose free level drifts by more than ten noise
levels within `SPANS` stretches still starts false contacts (ended by the lock rule).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from skin.models.commission import (
    FORCE_CONTACT_HELD,
    FORCE_CONTACT_SNR,
    FORCE_NOISE_SPAN,
    FORCE_STUCK,
    force_onset,
    sorted_quantile,
    span_noise,
)
from skin.stream.onset import OnsetEvent

#: The free level and noise: the median over this many of the last stretches.
SPANS = 9
#: A stretch of the noise lasts at most this long (and `FORCE_NOISE_SPAN` samples), s.
SPAN_SECONDS = 1.0
#: How far before a force-dated onset the taxel's temperature is averaged for its
#: initial temperature, s.
BASELINE_SECONDS = 0.1
#: How far back a rise is followed to date its onset, s (the ring kept per taxel).
RISE_SECONDS = 0.5
#: The `OnsetEvent.channel` of the force's events.
FORCE_CHANNEL = 4
#: On a taxel whose force has not dated a contact yet, the detector's events this close to
#: a force contact are that contact's (dropped: the force dates it), s.
CONFIRM_SECONDS = 0.5
#: After a contact the force did not date (it began in a gap or unconfirmed), the taxel's
#: thermal events are kept this long, s (the detector's release comes late).
GRACE_SECONDS = 2.0
#: A contact whose force sits flat within `FORCE_CONTACT_SNR` noise levels of its threshold
#: this long is a drifting free level: it is ended and the level re-learnt, s.
LOCK_SECONDS = 5.0
#: A taxel's force is read inverted once this many of the detector's onsets met a fall of
#: the force (and this many more for each that met a rise): see `ForceOnsets.polarity`.
INVERT_VOTES = 3
#: A quiet stretch far under the free level replaces it once the readings have been held
#: under it this long, s (a taxel pressed since the stream's start, released; not a press of
#: an inverted channel).
FRESH_SECONDS = 3.0


class ForceOnsets:
    """Onset and release events of the taxels with a force reading (see the module docstring).

    Parameters
    ----------
    n_taxels : int
        Taxels (layout order).
    sample_rate : float
        Samples per second.
    start : int
        The stream's index of the first sample given (stretches are counted from the
        stream's first sample, so a force channel appearing mid-stream gives the same
        stretches whatever the chunking).
    ids : sequence of int, optional
        The taxels' layout ids, by which `notes` name them (default: their columns).
    """

    def __init__(self, n_taxels: int, sample_rate: float, start: int = 0,
                 ids: Sequence[int] | None = None) -> None:
        self.n = int(n_taxels)
        self.ids = list(range(self.n)) if ids is None else [int(i) for i in ids]
        if len(self.ids) != self.n:
            raise ValueError(f"ForceOnsets: {len(self.ids)} ids for {self.n} taxels")
        self.rate = float(sample_rate)
        self.held = max(2, round(FORCE_CONTACT_HELD * self.rate))
        self.held_s = self.held / self.rate
        # as force_stuck: 100 samples too (a clipped noise reads 0 half the time)
        self.stuck_s = max(FORCE_STUCK, 100 / self.rate)
        # a slow board's stretch is 1 s, not 100 samples (5 s at 20 Hz undated at the start)
        self.span = int(min(FORCE_NOISE_SPAN, max(20, round(SPAN_SECONDS * self.rate))))
        self.keep = self.span + self.held + math.ceil(RISE_SECONDS * self.rate)
        n = self.n
        self.level = np.full(n, np.nan)
        self.noise = np.full(n, np.nan)
        self._spans = np.full((SPANS, 2, n), np.nan)  # the last stretches' (level, noise)
        self._span_count = 0
        self._span_f = np.full((self.span, n), np.nan)
        self._span_free = np.zeros((self.span, n), dtype=bool)
        self._in_span = int(start) % self.span
        self.on = np.zeros(n, dtype=bool)
        self._run = np.zeros(n, dtype=np.int64)  # consecutive readings against the state
        self._run_start = np.zeros(n, dtype=np.int64)  # their first sample (stream index)
        self._run_t = np.full(n, np.nan)  # ... and its time, s
        self._after_gap = np.zeros(n, dtype=bool)  # the rise began after a gap (or the start)
        self._gap_s = max(self.held_s, 1.5 / self.rate) + 1e-9
        self.trusted = np.zeros(n, dtype=bool)  # its force has dated a contact
        self._trusted_from = np.full(n, np.inf)
        self._emitted = np.zeros(n, dtype=bool)  # the current force contact was reported
        self._on_since = np.full(n, np.nan)  # the current force contact's onset, s
        self._peak = np.full(n, np.nan)  # ... and its highest reading so far (per stretch)
        self._released = np.full(n, -np.inf)  # each taxel's last force release, s
        self._silent = np.full((2, n), np.nan)  # a contact the force did not date: from, until
        self._span = np.full((2, n), np.nan)  # the last reported force contact +- CONFIRM, s
        self.unseen = np.zeros(n, dtype=np.int64)  # detector onsets the force did not see
        self.notes: list[str] = []
        self._t = np.full(self.keep, np.nan)
        self._f = np.full((self.keep, n), np.nan)
        self._y = np.full((self.keep, n), np.nan)
        self._head = self._start = int(start)  # the stream's index of the next sample
        self.last_reading = np.full(n, -np.inf)  # each taxel's last force reading, s
        self.known_from = np.full(n, np.inf)  # when each taxel's free level was first known
        self._threshold = np.full(n, np.nan)  # NaN: its free level not known yet
        self._value = np.full(n, np.nan)  # each taxel's last reading
        self._same_from = np.full(n, -np.inf)  # since when it has read that value, s
        self._noisy = np.zeros(n, dtype=bool)  # its free readings have varied
        self._unknown = np.ones(n, dtype=bool)
        self.onsets = 0
        self.releases = 0
        # polarity: -1 where the readings are taken negated (an inverted channel)
        self.polarity = np.ones(n)
        self._low_run = np.zeros(n, dtype=np.int64)  # readings held under the mirrored threshold
        self._low_t = np.full(n, np.nan)  # ... since
        self._edge = np.full((2, 2, n), np.nan)  # (rise, fall) x (time, detected at), unmatched
        self._onset_seen = np.full((2, n), np.nan)  # the detector's last unmatched onset
        self._votes: list[list[tuple[float, int, int]]] = [[] for _ in range(n)]
        self._against = np.zeros(n, dtype=bool)  # has had a vote against (folded or not)
        self._pending: set[int] = set()  # taxels with votes not folded yet
        self._base = np.zeros((3, n), dtype=np.int64)  # folded votes: for, against, epoch
        self._turns: list[list[float]] = [[] for _ in range(n)]  # when each taxel was turned
        self._retrusted = np.full(n, np.inf)  # trusted again after its last turn
        self._closing: set[int] = set()  # releases closing a contact at a turn (no trust)

    def merge(self, times: np.ndarray, force: np.ndarray, temperature: np.ndarray,
              thermal: list[OnsetEvent]) -> list[OnsetEvent]:
        """Take a block; return the force's events and the thermal events it leaves.

        A thermal event of a taxel is kept when, at its ``detected_at``, the taxel's free
        force level is not known yet or its force has had no reading for
        `FORCE_CONTACT_HELD`; otherwise the force dates that taxel and it is dropped.

        Parameters
        ----------
        times : numpy.ndarray
            Sample times, s, (n,).
        force : numpy.ndarray
            Force, N (or a switch's 0/1), (n, taxels); NaN where a taxel has no reading.
        temperature : numpy.ndarray
            deg C, (n, taxels) (a force-dated onset's initial temperature).
        thermal : list of OnsetEvent
            The onset detector's events for the block.
        """
        times = np.asarray(times, dtype=float)
        force = np.array(force, dtype=float)  # a copy: taken negated where turned
        events: list[OnsetEvent] = []
        start = 0
        before = (self.last_reading.copy(), self.known_from.copy(), self._value.copy(),
                  self._same_from.copy())
        if len(times):
            self._fold(float(times[0]))
        seen = sorted((ev.detected_at, ev.taxel, ev.time) for ev in thermal
                      if ev.kind == "onset")
        at = 0
        while start < len(times):  # pieces end where a stretch of the noise ends
            stop = min(len(times), start + self.span - self._in_span)
            force[start:stop] *= self.polarity
            events += self._piece(times[start:stop], force[start:stop],
                                  temperature[start:stop])
            while at < len(seen) and seen[at][0] <= times[stop - 1]:
                self._seen_onset(*seen[at])  # the detector's onsets, before the stretch closes
                at += 1
            if self._in_span == self.span:
                events += self._close_span(float(times[stop - 1]))
            start = stop
        for item in seen[at:]:
            self._seen_onset(*item)
        events, thermal = self._confirm(events, thermal)
        if len(times):
            prev = np.vstack([self._value[None], force[:-1]])
            changed = ~(force == prev)  # NaN: a change
            rows = len(times) - 1 - np.argmax(changed[::-1], axis=0)
            self._same_from = np.where(changed.any(axis=0), times[rows], self._same_from)
            self._value = force[-1].copy()
        if thermal:
            events += self._kept(times, force, thermal, *before)
        return events

    def _confirm(self, raw: list[OnsetEvent], thermal: list[OnsetEvent]
                 ) -> tuple[list[OnsetEvent], list[OnsetEvent]]:
        """Report the force's events; say which detector events it leaves to judge.

        A taxel's force overrules the detector only once it has dated a contact (its onset
        and release: `trusted`); until then the detector's events are kept, but those dated
        within `CONFIRM_SECONDS` of a force contact the force reports (the same touch: one
        contact, the force's; a detector onset come before it is replaced in the tracker).
        A dead channel (never a contact) thus never hides the detector's touches.
        """
        out: list[OnsetEvent] = []
        for ev in raw:
            k = ev.taxel
            if ev.kind == "silent":
                continue
            if ev.kind == "onset":
                if self._suspect(k, ev.detected_at):
                    continue  # its force falls where the detector sees touches: withheld
                self._emitted[k] = True
                self._span[:, k] = (ev.time - CONFIRM_SECONDS, np.inf)
                out.append(ev)
            elif self._emitted[k]:
                self._emitted[k] = False
                self._span[1, k] = ev.time + CONFIRM_SECONDS
                out.append(ev)
                if not self.trusted[k] and id(ev) not in self._closing:
                    self.trusted[k] = True
                    if self._turns[k]:
                        self._retrusted[k] = ev.detected_at
                    else:
                        self._trusted_from[k] = ev.detected_at
        self._closing.clear()
        keep = []
        for ev in thermal:
            k = ev.taxel
            if (self._untrusted(k, ev.detected_at) and not self._suspect(k, ev.detected_at)
                    and self._span[0, k] <= ev.time <= self._span[1, k]):
                continue  # the force's contact, not trusted yet: the force dates it
            keep.append(ev)
        return out, keep

    # --- polarity: the detector's onsets against the force's rises and falls -----------------
    def _untrusted(self, k: int, when: float) -> bool:
        """Whether taxel ``k``'s force had not dated a contact at ``when`` (or since a turn)."""
        turns = self._turns[k]
        if turns and turns[-1] <= when:  # since its last turn
            return bool(when < self._retrusted[k])
        return bool(when < self._trusted_from[k])

    def _fold(self, start: float) -> None:
        """Fold the votes cast before ``start`` into counts (no later question goes back)."""
        for k in sorted(self._pending):
            epoch = len(self._turns[k])
            if self._base[2, k] != epoch:
                self._base[:, k] = (0, 0, epoch)
            rest = []
            for vote in self._votes[k]:
                if vote[2] == epoch and vote[0] < start:
                    self._base[0 if vote[1] > 0 else 1, k] += 1
                elif vote[2] == epoch:
                    rest.append(vote)
            self._votes[k] = rest
            if not rest:
                self._pending.discard(k)

    def _tally(self, k: int, when: float) -> tuple[int, int]:
        """Taxel ``k``'s votes (for, against its polarity) cast by ``when``, since its last turn."""
        epoch = sum(t <= when for t in self._turns[k])
        up = down = 0
        if self._base[2, k] == epoch:
            up, down = int(self._base[0, k]), int(self._base[1, k])
        for at, sign, ep in self._votes[k]:
            if ep == epoch and at <= when:
                up += sign > 0
                down += sign < 0
        return up, down

    def _suspect(self, k: int, when: float) -> bool:
        """Whether taxel ``k``'s force fell at more of the detector's onsets than it rose."""
        if not self._against[k]:
            return False
        up, down = self._tally(k, when)
        return down > up

    def _seen_onset(self, detected: float, k: int, time: float) -> None:
        """Register one of the detector's onsets (at its detection) and match it."""
        self._onset_seen[:, k] = (time, detected)
        self._match(k)

    def _add_edge(self, k: int, fall: bool, time: float, detected: float) -> None:
        """Register a rise or fall of taxel ``k``'s force (at its detection) and match it."""
        self._edge[int(fall), :, k] = (time, detected)
        self._match(k)

    def _match(self, k: int) -> None:
        """Vote where a detector onset lies within `CONFIRM_SECONDS` of a force edge (nearer)."""
        seen, seen_at = self._onset_seen[:, k]
        if not math.isfinite(seen):
            return
        gaps = np.abs(self._edge[:, 0, k] - seen)  # NaN: no edge
        if not (gaps <= CONFIRM_SECONDS).any():
            return
        fall = int(np.nanargmin(gaps))
        at = max(float(seen_at), float(self._edge[fall, 1, k]))
        self._votes[k].append((at, -1 if fall else 1, len(self._turns[k])))
        self._pending.add(k)
        self._against[k] |= bool(fall)
        self._edge[fall, :, k] = np.nan
        self._onset_seen[:, k] = np.nan

    def _turn(self, end: float) -> list[OnsetEvent]:
        """Turn the taxels whose votes say their force reads inverted (module docstring)."""
        events: list[OnsetEvent] = []
        for k in np.flatnonzero(self._against).tolist():
            up, down = self._tally(k, end)
            if down < INVERT_VOTES * (1 + up):
                continue
            if self._emitted[k] or self.on[k]:  # close what it reported (the tracker's)
                ev = OnsetEvent("release", k, end, end, float("nan"), 0.0, -1,
                                channel=FORCE_CHANNEL, dated_by="force")
                self._closing.add(id(ev))
                events.append(ev)
            # its free level stays (stretches far under it were not learnt): negated
            self.polarity[k] *= -1
            self._f[:, k] *= -1
            self._value[k] *= -1
            self._spans[:, 0, k] *= -1
            margin = self._threshold[k] - self.level[k]
            self.level[k] *= -1
            self._threshold[k] = self.level[k] + margin
            pressed = self._low_run[k] >= self.held
            self.on[k], self._run[k], self._low_run[k] = pressed, 0, 0
            self._edge[:, :, k] = np.nan
            self._onset_seen[:, k] = np.nan
            self._silent[:, k] = self._span[:, k] = np.nan
            self._on_since[k] = self._peak[k] = np.nan
            if pressed:  # turned mid-press: a contact the force did not date (the detector's)
                self._silent[:, k] = (self._low_t[k], np.inf)
                self._on_since[k] = self._low_t[k]
            self.trusted[k] = False
            self._retrusted[k] = np.inf
            self._turns[k].append(end)
            self.notes.append(
                f"taxel {self.ids[k]}: its force fell at {down} of the detector's onsets and "
                f"rose at {up} (wired inverted, or an active-low switch?): read "
                f"{'negated' if self.polarity[k] < 0 else 'as it comes again'} from "
                f"{end:.3f} s")
        return events

    def _kept(self, times: np.ndarray, force: np.ndarray, thermal: list[OnsetEvent],
              last_before: np.ndarray, known_before: np.ndarray, value_before: np.ndarray,
              same_before: np.ndarray) -> list[OnsetEvent]:
        """Return the thermal events of taxels the force does not date at their detection.

        Nor where it is stuck: one value at its free level for `FORCE_STUCK` s on a taxel
        whose free readings have varied (a sensor or cable failing partway; as
        `skin.models.commission.force_stuck`).
        """
        taxels = np.unique([ev.taxel for ev in thermal])
        f = force[:, taxels]
        fin = np.isfinite(f)
        # each sample's last reading, per taxel of an event (the block's or before it)
        last = np.maximum.accumulate(np.where(fin, times[:, None], -np.inf), axis=0)
        last = np.maximum(last, last_before[taxels])
        # since when each has read the value it reads at each sample
        changed = ~(f == np.vstack([value_before[taxels][None], f[:-1]]))
        since = np.maximum(np.maximum.accumulate(np.where(changed, times[:, None], -np.inf),
                                                 axis=0), same_before[taxels])
        col = {int(k): j for j, k in enumerate(taxels)}
        kept = []
        for ev in thermal:
            j = col[ev.taxel]
            row = int(np.searchsorted(times, ev.detected_at, side="right")) - 1
            seen = last[row, j] if row >= 0 else last_before[ev.taxel]
            known = min(known_before[ev.taxel], self.known_from[ev.taxel])
            value = f[row, j] if row >= 0 else value_before[ev.taxel]
            stuck = (self._noisy[ev.taxel]
                     and ev.detected_at - (since[row, j] if row >= 0 else same_before[ev.taxel])
                     >= self.stuck_s
                     and abs(value - self.level[ev.taxel]) <= 3 * self.noise[ev.taxel])
            k = ev.taxel
            silent = self._silent[0, k] <= ev.detected_at <= self._silent[1, k]
            suspect = self._suspect(k, ev.detected_at)
            untrusted = suspect or self._untrusted(k, ev.detected_at)
            if (stuck or silent or untrusted
                    or not (known <= ev.detected_at and ev.detected_at - seen <= self.held_s)):
                kept.append(ev)
                if (ev.kind == "onset" and known <= ev.detected_at and not silent
                        and not suspect):
                    self.unseen[k] += 1
                    if self.unseen[k] == 2:
                        self.notes.append(
                            f"taxel {self.ids[k]}: the onset detector reports onsets its "
                            "force channel did not see (a dead or miswired force?): dated by "
                            "the detector")
        return kept

    def _piece(self, t: np.ndarray, f: np.ndarray, y: np.ndarray) -> list[OnsetEvent]:
        """One piece within one noise stretch: ring, state, stretch statistics."""
        m = len(t)
        first = self._head
        idx = (first + np.arange(m)) % self.keep
        self._t[idx], self._f[idx], self._y[idx] = t, f, y
        self._head += m
        fin = np.isfinite(f)
        prev_reading = self.last_reading.copy()
        if m == 1:
            self.last_reading[fin[0]] = t[0]
        elif fin.any():
            seen = np.flatnonzero(fin.any(axis=0))
            rows = m - 1 - np.argmax(fin[::-1, seen], axis=0)
            self.last_reading[seen] = t[rows]
        threshold = self._threshold
        over = f > threshold  # NaN (no reading, or the threshold not known yet): neither
        under = f <= threshold
        low = f < 2 * self.level - threshold  # as far under the level as the threshold is over
        # only the taxels that may change state walk their samples
        walk = np.flatnonzero((self.on & under.any(axis=0)) | (~self.on & over.any(axis=0))
                              | (self._run > 0) | (~self.on & low.any(axis=0))
                              | (self._low_run > 0))
        events = [ev for k in walk for ev in self._walk(int(k), t, f, over[:, k],
                                                        under[:, k], low[:, k], first,
                                                        float(prev_reading[k]))]
        # the stretch's free samples: under the threshold, or every reading before it is known
        free = np.where(self._unknown, fin, under)
        self._span_f[self._in_span:self._in_span + m] = f
        self._span_free[self._in_span:self._in_span + m] = free
        self._in_span += m
        return events

    def _walk(self, k: int, t: np.ndarray, f: np.ndarray, over: np.ndarray, under: np.ndarray,
              low: np.ndarray, first: int, prev: float) -> list[OnsetEvent]:
        """Step one taxel through a piece: its held crossings, as events.

        A run of readings restarts after a gap of more than `FORCE_CONTACT_HELD` (a
        release inside a gap is dated at the first reading after it); a rise whose last
        reading before it precedes such a gap (or the stream's start) is force coming back
        mid-contact: no force onset, the detector dates that contact (kind "silent"). Free,
        readings held ``low`` (under the level by the threshold's margin) are a fall of the
        force (`_add_edge`: no event).
        """
        out = []
        on, run, run_start = bool(self.on[k]), int(self._run[k]), int(self._run_start[k])
        run_t, after_gap = float(self._run_t[k]), bool(self._after_gap[k])
        low_run, low_t = int(self._low_run[k]), float(self._low_t[k])
        held = self.held
        for i, (o, u, lo) in enumerate(zip(over.tolist(), under.tolist(), low.tolist(),
                                           strict=True)):
            if lo and not on:
                if low_run == 0:
                    low_t = float(t[i])
                low_run += 1
                if low_run == held:
                    self._add_edge(k, True, low_t, float(t[i]))
            else:
                low_run = 0
            gap = False
            if o or u:
                gap = float(t[i]) - prev > self._gap_s
                prev = float(t[i])
            if on:
                if u:
                    if run == 0 or gap:
                        run, run_t = 0, float(t[i])
                    run += 1
                    if run >= held:
                        out.append(self._release(k, run_t, float(t[i])))
                        on, run = False, 0
                elif o:
                    run = 0
            elif o:
                if run == 0:
                    run_start, run_t, after_gap = first + i, float(t[i]), gap
                run += 1
                if run >= held:
                    out.append(self._onset(k, run_start, first + i, silent=after_gap))
                    on, run = True, 0
            else:
                run = 0  # a reading under it, or none: the rise was not held
        self.on[k], self._run[k], self._run_start[k] = on, run, run_start
        self._run_t[k], self._after_gap[k] = run_t, after_gap
        self._low_run[k], self._low_t[k] = low_run, low_t
        return out

    def _ring(self, upto: int) -> tuple[np.ndarray, int]:
        """Ring indices of the kept samples up to stream index ``upto``, in time order."""
        lo = max(self._start, self._head - self.keep)
        return np.arange(lo, upto + 1) % self.keep, lo

    def _onset(self, k: int, start: int, now: int, silent: bool = False) -> OnsetEvent:
        idx, lo = self._ring(now)
        t, f = self._t[idx], self._f[idx, k]
        j = max(0, start - lo)
        top = float(np.nanmax(f[j:]))
        onset = force_onset(t, f, j, float(self.level[k]), float(self.noise[k]), top)
        # never before the ring's start nor the taxel's last release (a drifting level)
        onset = max(onset, float(np.nanmin(t)), float(self._released[k]))
        self._on_since[k] = onset
        self._peak[k] = float(np.nanmax(f))
        if silent:
            self._silent[:, k] = (float(t[j]), np.inf)
            return OnsetEvent("silent", k, onset, float(t[-1]), float("nan"), 0.0, -1,
                              channel=FORCE_CHANNEL, dated_by="force")
        before = (t > onset - BASELINE_SECONDS) & (t <= onset)
        y = self._y[idx, k]
        base = y[before & np.isfinite(y)]
        baseline = float(base.mean()) if base.size else float(y[j])
        self.onsets += 1
        self._add_edge(k, False, onset, float(t[-1]))
        return OnsetEvent("onset", k, onset, float(t[-1]), baseline, 0.0, -1,
                          channel=FORCE_CHANNEL, dated_by="force")

    def _release(self, k: int, when: float, now: float) -> OnsetEvent:
        self.releases += 1
        self._released[k] = when
        if self._silent[1, k] == np.inf:  # the contact the force did not date ends
            self._silent[1, k] = now + GRACE_SECONDS
            return OnsetEvent("silent", k, when, now, float("nan"), 0.0, -1,
                              channel=FORCE_CHANNEL, dated_by="force")
        return OnsetEvent("release", k, when, now, float("nan"), 0.0, -1,
                          channel=FORCE_CHANNEL, dated_by="force")

    def _close_span(self, end: float) -> list[OnsetEvent]:
        """Close a noise stretch: its free level and noise join the last `SPANS`.

        Only a quiet stretch counts (its free readings spread over at most twice the
        threshold's `FORCE_CONTACT_SNR` noise levels): a touch begun inside the first
        stretch does not make its force the free level. A quiet stretch far under the
        level (a taxel pressed since the stream's start, released) replaces the level's
        stretches; so does a contact flat near its threshold for `LOCK_SECONDS` (a drifting
        free level), which is ended there with a note.
        """
        events: list[OnsetEvent] = []
        f = np.where(self._span_free, self._span_f, np.nan)
        enough = self._span_free.sum(axis=0) >= self.span // 2
        level, noise = span_noise(f[:, enough])
        with np.errstate(invalid="ignore"):
            spread = np.nanmax(f[:, enough], axis=0) - np.nanmin(f[:, enough], axis=0)
        tiny = 1e-9 * (1.0 + np.abs(level))
        quiet = spread <= 2 * FORCE_CONTACT_SNR * noise + tiny
        cols = np.flatnonzero(enough)
        old_level = self.level[cols]
        margin = self._threshold[cols] - old_level
        # released after a start pressed (not a press of a taxel whose force falls at touches)
        low_for = np.where(self._low_run[cols] >= self.held, end - self._low_t[cols], 0.0)
        far_under = level < old_level - margin
        fresh_level = quiet & far_under & (low_for >= FRESH_SECONDS)
        for j in np.flatnonzero(fresh_level & self._against[cols]).tolist():
            fresh_level[j] = not self._suspect(int(cols[j]), end)
        # a contact flat near its threshold for long: the free level drifted
        if self.on.any():
            allf = self._span_f
            fin = np.isfinite(allf).sum(axis=0) >= self.span // 2
            lock = np.flatnonzero(self.on & fin & (end - self._on_since >= LOCK_SECONDS))
            if lock.size:
                a = allf[:, lock]
                lv, nz = span_noise(a)
                with np.errstate(invalid="ignore"):
                    sp = np.nanmax(a, axis=0) - np.nanmin(a, axis=0)
                thr = self._threshold[lock]
                base = self.level[lock]
                self._peak[lock] = np.fmax(self._peak[lock], np.nanmax(a, axis=0))
                # near its threshold, or a small share of the contact's peak (drifted after it)
                near = (sp <= 2 * FORCE_CONTACT_SNR * np.maximum(nz, self.noise[lock]) + 1e-9
                        ) & ((lv <= thr + 2 * FORCE_CONTACT_SNR * self.noise[lock])
                             | (lv - base <= 0.25 * (self._peak[lock] - base)))
                for k, lvk, nzk in zip(lock[near].tolist(), lv[near], nz[near], strict=True):
                    self.on[k], self._run[k] = False, 0
                    self._spans[:, :, k] = np.nan
                    self._spans[0, :, k] = (lvk, nzk)
                    self.notes.append(
                        f"taxel {self.ids[k]}: force flat near its threshold for "
                        f"{LOCK_SECONDS:g} s "
                        f"(a drifting free level?) at {end:.3f} s: contact ended, level re-learnt")
                    events.append(self._release(k, end, end))
        self._spans[:, :, cols[fresh_level]] = np.nan
        row = self._spans[self._span_count % SPANS]
        row[:] = np.nan
        # a quiet stretch far under the level is no free level (a press of an inverted
        # channel) unless it replaces it
        quiet = quiet & (fresh_level | ~far_under)
        good = cols[quiet]
        row[0, good], row[1, good] = level[quiet], noise[quiet]
        self._noisy[good] |= noise[quiet] > 0
        self._span_count += 1
        count = np.isfinite(self._spans[:, 0]).sum(axis=0)  # a taxel without one yet: NaN
        lv = sorted_quantile(np.sort(self._spans[:, 0], axis=0), count, 0.5)
        nz = sorted_quantile(np.sort(self._spans[:, 1], axis=0), count, 0.5)
        fresh = np.isfinite(lv) & ~np.isfinite(self.known_from)
        self.known_from[fresh] = end
        self.level = np.where(np.isfinite(lv), lv, self.level)
        self.noise = np.where(np.isfinite(nz), nz, self.noise)
        self._threshold = self.level + np.maximum(FORCE_CONTACT_SNR * self.noise,
                                                  1e-9 * (1.0 + np.abs(self.level)))
        self._unknown = np.isnan(self._threshold)
        self._span_f[:] = np.nan
        self._span_free[:] = False
        self._in_span = 0
        return events + self._turn(end)

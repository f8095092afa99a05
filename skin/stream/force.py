"""Contact onsets and releases dated by a force (or contact-switch) channel, streaming.

A taxel whose frames carry a force reading (`skin.frame.Frame.force`) is dated by it: its
contact begins where the force first exceeds its free level by `FORCE_CONTACT_SNR` noise
levels and stays over that `FORCE_CONTACT_HELD`, and ends where it stays under it as long;
the onset is taken back along the rise to where it left the free level (the dating core of
`skin.models.commission.force_contacts`, `skin.models.commission._force_onset`, shared).
The free level and noise are each taxel's `skin.models.commission.span_noise` per stretch
of `FORCE_NOISE_SPAN` samples or `SPAN_SECONDS`, whichever is shorter (but 20 samples;
counted from the stream's first sample, so any chunking gives the same stretches), the
median of the last `SPANS` stretches that were at least half free. Until a taxel's first
stretch is done, or while its force has had no reading for `FORCE_CONTACT_HELD`, the onset
detector dates it (`ForceOnsets.merge` keeps the thermal events there and drops them
elsewhere); so it does while the force is stuck (one value at its free level for
`FORCE_STUCK` s and 100 samples on a taxel whose free readings have varied: a sensor or
cable failing partway, as `skin.models.commission.force_stuck`; a switch or a noise-free
force is never taken as stuck).

Unlike the whole-recording `force_contacts`, the threshold has no share of the strongest
touch (that needs the recording's end): a force whose free level drifts by more than ten
noise levels within `SPANS` stretches would start a contact. A stretch without a reading
inside a contact carries the contact (a release needs `FORCE_CONTACT_HELD` of readings under
the threshold: a release inside the gap is dated at the first reading after it).
"""

from __future__ import annotations

import math

import numpy as np

from skin.models.commission import (
    FORCE_CONTACT_HELD,
    FORCE_CONTACT_SNR,
    FORCE_NOISE_SPAN,
    FORCE_STUCK,
    _force_onset,
    _sorted_quantile,
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


class ForceOnsets:
    """Onset and release events of the taxels with a force reading (see the module docstring).

    Parameters
    ----------
    n_taxels : int
        Taxels (layout order).
    sample_rate : float
        Samples per second.
    """

    def __init__(self, n_taxels: int, sample_rate: float) -> None:
        self.n = int(n_taxels)
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
        self._in_span = 0
        self.on = np.zeros(n, dtype=bool)
        self._run = np.zeros(n, dtype=np.int64)  # consecutive readings against the state
        self._run_start = np.zeros(n, dtype=np.int64)  # their first sample (stream index)
        self._t = np.full(self.keep, np.nan)
        self._f = np.full((self.keep, n), np.nan)
        self._y = np.full((self.keep, n), np.nan)
        self._head = 0  # samples seen
        self.last_reading = np.full(n, -np.inf)  # each taxel's last force reading, s
        self.known_from = np.full(n, np.inf)  # when each taxel's free level was first known
        self._threshold = np.full(n, np.nan)  # NaN: its free level not known yet
        self._value = np.full(n, np.nan)  # each taxel's last reading
        self._same_from = np.full(n, -np.inf)  # since when it has read that value, s
        self._noisy = np.zeros(n, dtype=bool)  # its free readings have varied
        self._unknown = np.ones(n, dtype=bool)
        self.onsets = 0
        self.releases = 0

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
        force = np.asarray(force, dtype=float)
        events: list[OnsetEvent] = []
        start = 0
        before = (self.last_reading.copy(), self.known_from.copy(), self._value.copy(),
                  self._same_from.copy())
        while start < len(times):  # pieces end where a stretch of the noise ends
            stop = min(len(times), start + self.span - self._in_span)
            events += self._piece(times[start:stop], force[start:stop],
                                  temperature[start:stop])
            start = stop
        if len(times):
            prev = np.vstack([self._value[None], force[:-1]])
            changed = ~(force == prev)  # NaN: a change
            rows = len(times) - 1 - np.argmax(changed[::-1], axis=0)
            self._same_from = np.where(changed.any(axis=0), times[rows], self._same_from)
            self._value = force[-1].copy()
        if thermal:
            events += self._kept(times, force, thermal, *before)
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
            if stuck or not (known <= ev.detected_at and ev.detected_at - seen <= self.held_s):
                kept.append(ev)
        return kept

    def _piece(self, t: np.ndarray, f: np.ndarray, y: np.ndarray) -> list[OnsetEvent]:
        """One piece within one noise stretch: ring, state, stretch statistics."""
        m = len(t)
        first = self._head
        idx = (first + np.arange(m)) % self.keep
        self._t[idx], self._f[idx], self._y[idx] = t, f, y
        self._head += m
        fin = np.isfinite(f)
        if m == 1:
            self.last_reading[fin[0]] = t[0]
        elif fin.any():
            seen = np.flatnonzero(fin.any(axis=0))
            rows = m - 1 - np.argmax(fin[::-1, seen], axis=0)
            self.last_reading[seen] = t[rows]
        threshold = self._threshold
        over = f > threshold  # NaN (no reading, or the threshold not known yet): neither
        under = f <= threshold
        # only the taxels that may change state walk their samples
        walk = np.flatnonzero((self.on & under.any(axis=0)) | (~self.on & over.any(axis=0))
                              | (self._run > 0))
        events = [ev for k in walk for ev in self._walk(int(k), t, f, over[:, k],
                                                        under[:, k], first)]
        # the stretch's free samples: under the threshold, or every reading before it is known
        free = np.where(self._unknown, fin, under)
        self._span_f[self._in_span:self._in_span + m] = f
        self._span_free[self._in_span:self._in_span + m] = free
        self._in_span += m
        if self._in_span == self.span:
            self._close_span(float(t[-1]))
        return events

    def _walk(self, k: int, t: np.ndarray, f: np.ndarray, over: np.ndarray, under: np.ndarray,
              first: int) -> list[OnsetEvent]:
        """Step one taxel through a piece: its held crossings, as events."""
        out = []
        on, run, run_start = bool(self.on[k]), int(self._run[k]), int(self._run_start[k])
        held = self.held
        for i, (o, u) in enumerate(zip(over.tolist(), under.tolist(), strict=True)):
            if on:
                if u:
                    if run == 0:
                        run_start = first + i
                    run += 1
                    if run >= held:
                        out.append(self._release(k, run_start, float(t[i])))
                        on, run = False, 0
                elif o:
                    run = 0
            elif o:
                if run == 0:
                    run_start = first + i
                run += 1
                if run >= held:
                    out.append(self._onset(k, run_start, first + i))
                    on, run = True, 0
            else:
                run = 0  # a reading under it, or none: the rise was not held
        self.on[k], self._run[k], self._run_start[k] = on, run, run_start
        return out

    def _ring(self, upto: int) -> tuple[np.ndarray, int]:
        """Ring indices of the kept samples up to stream index ``upto``, in time order."""
        lo = max(0, self._head - self.keep)
        return np.arange(lo, upto + 1) % self.keep, lo

    def _onset(self, k: int, start: int, now: int) -> OnsetEvent:
        idx, lo = self._ring(now)
        t, f = self._t[idx], self._f[idx, k]
        j = max(0, start - lo)
        top = float(np.nanmax(f[j:]))
        onset = _force_onset(t, f, j, float(self.level[k]), float(self.noise[k]), top)
        before = (t > onset - BASELINE_SECONDS) & (t <= onset)
        y = self._y[idx, k]
        base = y[before & np.isfinite(y)]
        baseline = float(base.mean()) if base.size else float(y[j])
        self.onsets += 1
        return OnsetEvent("onset", k, onset, float(t[-1]), baseline, 0.0, -1,
                          channel=FORCE_CHANNEL, dated_by="force")

    def _release(self, k: int, start: int, now: float) -> OnsetEvent:
        self.releases += 1
        when = float(self._t[start % self.keep])
        return OnsetEvent("release", k, when, now, float("nan"), 0.0, -1,
                          channel=FORCE_CHANNEL, dated_by="force")

    def _close_span(self, end: float) -> None:
        """Close a noise stretch: its free level and noise join the last `SPANS`."""
        f = np.where(self._span_free, self._span_f, np.nan)
        enough = self._span_free.sum(axis=0) >= self.span // 2
        level, noise = span_noise(f[:, enough])
        row = self._spans[self._span_count % SPANS]
        row[:] = np.nan
        row[0, enough], row[1, enough] = level, noise
        self._noisy[enough] |= noise > 0
        self._span_count += 1
        count = np.isfinite(self._spans[:, 0]).sum(axis=0)  # a taxel without one yet: NaN
        lv = _sorted_quantile(np.sort(self._spans[:, 0], axis=0), count, 0.5)
        nz = _sorted_quantile(np.sort(self._spans[:, 1], axis=0), count, 0.5)
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

"""Frames of one or more boards -> blocks of skin-wide samples in layout order.

The first stage of the pipeline. Each board sends a `Frame` per sample; a skin of several
boards is sampled in step (the boards share a sync, so one sample carries one sequence number
on every board) and the assembler puts each sample's frames together into one row of counts
in layout order (its device and host times are those of the lowest board id present). A
sample is complete once every board has sent its frame. An incomplete sample waits for the
boards behind on the host clock: boards read in threads or over several buses deliver in
bursts, one board's frames well behind another's, and a frame that could still be merged
must not be thrown away. It leaves incomplete once ``wait`` seconds have passed since its
first frame came (a board dead or far behind), or once more than ``max_skew`` samples wait
behind it (the memory bound). Its missing boards' taxels are NaN (calibration flags them);
a frame that still comes for a sample already out is counted late (``stats.late``) and
dropped: samples leave in order, so the onset detector's time never runs backwards. A
complete sample leaves at once: with one board, or boards in step, nothing waits.
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.frame import Frame

_WRAP = 1 << 32


@dataclass(frozen=True)
class Samples:
    """A block of skin-wide samples.

    Attributes
    ----------
    times : numpy.ndarray
        Device time of each sample, s, (n,).
    counts : numpy.ndarray
        ADC counts in layout order, float, NaN where the taxel's board sent nothing, (n, taxels).
    ambient : numpy.ndarray
        Ambient temperature, deg C (mean over the boards that sent the sample), (n,).
    duty : numpy.ndarray
        Heater duty 0-255 in layout order, NaN where missing or not known yet
        (`skin.frame.Frame.duty_known`), (n, taxels).
    host_times : numpy.ndarray
        Host time of each sample, s (``time.monotonic`` clock): the ``Frame.host_time`` of the
        frame whose device time it keeps, (n,).
    force : numpy.ndarray or None
        Force channel, N, in layout order, NaN where a taxel has no reading or its board sent
        none (`skin.frame.Frame.force`), (n, taxels); None when no frame of the block has one.
    """

    times: np.ndarray
    counts: np.ndarray
    ambient: np.ndarray
    duty: np.ndarray
    host_times: np.ndarray
    force: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.times)


@dataclass
class AssemblyStats:
    """Counts kept by `FrameAssembler`.

    Attributes
    ----------
    frames : int
        Frames taken.
    samples : int
        Samples put out.
    gaps : dict
        Board id -> frames missing according to its sequence numbers.
    missing : dict
        Board id -> samples put out without that board's frame.
    late : int
        Frames that came after their sample had left (dropped).
    """

    frames: int = 0
    samples: int = 0
    gaps: dict[int, int] = field(default_factory=dict)
    missing: dict[int, int] = field(default_factory=dict)
    late: int = 0


class FrameAssembler:
    """Put the frames of a layout's boards together into samples (see the module docstring).

    Parameters
    ----------
    layout : Layout
        The skin: which board and channel each taxel is on.
    max_skew : int
        Most samples that wait behind an incomplete one before it leaves (the memory bound:
        at most ``max_skew + 1`` samples' frames are held).
    wait : float
        Host seconds an incomplete sample waits for its missing boards after its first frame
        came; 0: none waits.
    clock : callable
        The host clock, s (``time.monotonic``).
    """

    def __init__(self, layout: Layout, max_skew: int = 2000, wait: float = 1.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if max_skew < 0 or wait < 0:
            raise ValueError(f"max_skew and wait must be >= 0, got {max_skew} and {wait}")
        self.layout = layout
        self.max_skew = int(max_skew)
        self.wait = float(wait)
        self.clock = clock
        self._maps = {b: layout.channel_map(b) for b in layout.boards}
        self._n = len(layout)
        self._last_seq: dict[int, int] = {}  # per board: last raw sequence number
        self._newest: dict[int, int] = {}  # per board: newest unwrapped sequence number
        self._wraps: dict[int, int] = {b: 0 for b in layout.boards}
        self._pending: dict[int, dict[int, Frame]] = {}  # unwrapped seq -> board -> frame
        self._arrived: dict[int, float] = {}  # unwrapped seq -> host time of its first frame
        self._order: list[int] = []  # heap of the pending sequence numbers
        self._next: int | None = None  # the next sample to put out
        #: Unwrapped sequence numbers of the samples the last `push` or `flush` put out.
        self.last_seqs = np.zeros(0, dtype=np.int64)
        self.stats = AssemblyStats(gaps={b: 0 for b in layout.boards},
                                   missing={b: 0 for b in layout.boards})

    def push(self, frames: Sequence[Frame]) -> Samples:
        """Take frames (any boards, any order); return the samples ready to leave (see above).

        Raises
        ------
        SkinError
            A frame from a board the layout does not have, or with fewer channels than the
            layout addresses on its board.
        """
        for f in frames:
            self._take(f)
        return self._complete(flush=False)

    def flush(self) -> Samples:
        """Put out every sample still waiting, its missing boards' taxels NaN."""
        return self._complete(flush=True)

    def _take(self, f: Frame) -> None:
        if f.board not in self._maps:
            raise SkinError(f"frame seq {f.seq} comes from board {f.board}, which is not in "
                            f"the layout {self.layout.source}")
        addr = self._maps[f.board][1]
        if addr.size and len(f.counts) <= addr.max():
            raise SkinError(f"frame seq {f.seq} of board {f.board} has {len(f.counts)} "
                            f"channels; the layout addresses channel {int(addr.max())}")
        self.stats.frames += 1
        last = self._last_seq.get(f.board)
        if last is not None:
            step = (f.seq - last) % _WRAP
            if 1 < step < (1 << 31):  # a forward jump; repeats and restarts are not gaps
                self.stats.gaps[f.board] += step - 1
            if f.seq < last and step < (1 << 31):
                self._wraps[f.board] += 1
        self._last_seq[f.board] = f.seq
        seq = self._wraps[f.board] * _WRAP + f.seq
        if self._next is not None and seq < self._next:
            self.stats.late += 1
            return
        self._newest[f.board] = max(seq, self._newest.get(f.board, seq))
        if seq not in self._pending:
            self._pending[seq] = {}
            self._arrived[seq] = self.clock()
            heapq.heappush(self._order, seq)
        self._pending[seq][f.board] = f
        if self._next is None:
            self._next = seq

    def _complete(self, flush: bool) -> Samples:
        ready = []
        seqs = []
        everyone = len(self._maps)
        newest = max(self._newest.values(), default=-1)
        now = self.clock()
        while self._order:
            seq = self._order[0]
            if not (flush or len(self._pending[seq]) == everyone
                    or newest - seq > self.max_skew or now - self._arrived[seq] >= self.wait):
                break
            heapq.heappop(self._order)
            del self._arrived[seq]
            ready.append(self._pending.pop(seq))
            seqs.append(seq)
            self._next = seq + 1
        self.last_seqs = np.array(seqs, dtype=np.int64)
        return self._assemble(ready)

    def _assemble(self, ready: list[dict[int, Frame]]) -> Samples:
        n = len(ready)
        counts = np.full((n, self._n), np.nan)
        duty = np.full((n, self._n), np.nan)
        times = np.empty(n)
        host = np.empty(n)
        ambient = np.empty(n)
        force = None
        for i, got in enumerate(ready):
            for board, (idx, addr) in self._maps.items():
                f = got.get(board)
                if f is None:
                    self.stats.missing[board] += 1
                    continue
                counts[i, idx] = f.counts[addr]
                duty[i, idx] = f.duty[addr]
                if f.duty_known is not None:  # a duty not heard yet is not known (NaN)
                    duty[i, idx[~f.duty_known[addr]]] = np.nan
                if f.force is not None:
                    if force is None:
                        force = np.full((n, self._n), np.nan)
                    force[i, idx] = f.force[addr]
            first = got[min(got)]  # the lowest board id present keeps the time
            times[i] = first.device_time
            host[i] = first.host_time
            # in board order, whatever order the frames came in (the same sum every time)
            ambient[i] = float(np.mean([got[b].ambient for b in sorted(got)]))
        self.stats.samples += n
        return Samples(times, counts, ambient, duty, host, force)

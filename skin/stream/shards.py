"""Onset detection sharded across worker processes (``skin run --workers N``).

Onset detection is the per-taxel streaming stage that costs most (`skin.bench.pipeline`'s
stages), and each taxel's detector is independent of the others' but for its board's common
mode (`skin.stream.onset.OnsetDetector`'s ``common_mode``). `OnsetShards` splits the taxels
into ``workers`` shards - whole boards when there are at least as many boards as workers or the
common mode runs (then no more shards than boards), else even runs of taxels - and runs one
`skin.stream.onset.OnsetDetector` per shard in a process of its own (the standard library's
``multiprocessing``, ``spawn`` start method: safe with the drivers' reader threads) - except
shard 0, which the pipeline's process detects itself while the workers detect theirs. The
pipeline's process keeps everything else: assembling frames, calibrating (so observers such as
a recording have every block before it is sent), tracking, refining and classifying. Each
block's events come back and are merged in the detector's own order (sample,
`OnsetEvent.channel`, taxel), so the results are those of one process by construction, and
contacts that span shards are tracked in the parent as always.

A worker that dies or fails raises `skin.errors.SkinError` naming it (its number, process id,
exit code and taxels); the block it was given has already been calibrated and observed.
"""

from __future__ import annotations

import copy
import multiprocessing
import time
import traceback
from multiprocessing.connection import Connection, wait
from typing import Any

import numpy as np

from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.stream.onset import DetectorState, OnsetDetector, OnsetEvent

#: Seconds `OnsetShards.close` waits for a worker to end before terminating it.
JOIN_TIMEOUT = 5.0


def shard_taxels(layout: Layout, workers: int, whole_boards: bool = False) -> list[np.ndarray]:
    """Split the layout's taxel indices into ``workers`` shards (see the module docstring).

    With ``whole_boards`` a board is never split, even when there are fewer boards than
    ``workers`` (then as many shards as boards): the detector's board common mode needs
    every taxel of its board in one shard to give the results of one process.

    Returns
    -------
    list of numpy.ndarray
        Increasing layout indices of each shard; none is empty (fewer shards than ``workers``
        only when the skin has fewer taxels).
    """
    n = len(layout)
    boards = np.array([t.board for t in layout.taxels])
    ids = sorted(set(boards.tolist()))
    if whole_boards:
        workers = min(workers, len(ids))
    if len(ids) >= workers:  # whole boards, each to the shard with the fewest taxels so far
        sizes = {b: int((boards == b).sum()) for b in ids}
        load = [0] * workers
        owner: dict[Any, int] = {}
        for b in sorted(ids, key=lambda b: -sizes[b]):
            w = int(np.argmin(load))
            owner[b] = w
            load[w] += sizes[b]
        shards = [np.flatnonzero([owner[b] == w for b in boards]) for w in range(workers)]
    else:
        shards = np.array_split(np.arange(n), workers)
    return [s for s in shards if s.size]


def sub_detector(detector: OnsetDetector, taxels: np.ndarray) -> OnsetDetector:
    """Return a copy of ``detector`` for ``taxels`` only.

    Its per-taxel arrays (`OnsetDetector.PER_TAXEL`) are sliced; every other attribute is
    shared, even an array that happens to be ``n_taxels`` long (the noise table).
    """
    n = detector.n_taxels
    sub = copy.copy(detector)
    for name in detector.PER_TAXEL:
        value = getattr(detector, name, None)
        if value is None:
            continue
        if not (isinstance(value, np.ndarray) and value.shape == (n,)):
            raise TypeError(f"OnsetDetector.{name} is not one value per taxel ({n}): "
                            f"{getattr(value, 'shape', type(value).__name__)}")
        part = value[taxels].copy()
        part.flags.writeable = value.flags.writeable  # the board stays read-only (`_groups`)
        setattr(sub, name, part)
    sub.n_taxels = int(taxels.size)
    return sub


def _serve(conn: Connection, detector: OnsetDetector, taxels: np.ndarray) -> None:
    """Worker loop: ``(times, temperature, duty)`` in, ``("ok", events, in_contact, busy)`` out."""
    detector.board.flags.writeable = False  # as in the parent: unpickled arrays are writeable
    state: DetectorState = detector.initial_state()
    try:
        while True:
            job = conn.recv()
            if job is None:
                return
            times, temperature, duty = job
            wall, cpu = time.perf_counter(), time.process_time()
            events, state = detector.process(times, temperature, state, in_place=True,
                                             duty=duty)
            busy = (time.perf_counter() - wall, time.process_time() - cpu)
            # layout indices, so the parent merges without knowing the shard
            conn.send(("ok", [_relabel(e, int(taxels[e.taxel])) for e in events],
                       state.in_contact, busy))
    except (EOFError, KeyboardInterrupt):  # the parent went away
        return
    except Exception:  # the parent reports it, naming this worker
        conn.send(("error", traceback.format_exc(), None, None))


def _relabel(event: OnsetEvent, taxel: int) -> OnsetEvent:
    return OnsetEvent(event.kind, taxel, event.time, event.detected_at, event.baseline,
                      event.slope, event.direction, event.channel)


class OnsetShards:
    """Onset detection of a skin in ``workers`` processes; `process` is `OnsetDetector`'s.

    Parameters
    ----------
    detector : OnsetDetector
        The whole skin's detector; each worker gets its shard's part.
    layout : Layout
        The skin (its boards decide the shards).
    workers : int
        Processes for onset detection, this one included (``workers - 1`` are started; shard
        0 is detected here while the workers detect theirs), >= 1.

    Attributes
    ----------
    busy : numpy.ndarray, shape (shards, 2)
        Each shard's seconds inside its detector so far, wall and CPU (row 0: this process's
        own shard; CPU below wall is a process waiting for a core).
    """

    def __init__(self, detector: OnsetDetector, layout: Layout, workers: int) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.n_taxels = detector.n_taxels
        # a board's common mode is taken over the whole board: never split one then
        self.shards = shard_taxels(layout, workers, whole_boards=detector.common_active)
        self.in_contact = np.zeros(self.n_taxels, dtype=bool)
        self.busy = np.zeros((len(self.shards), 2))
        context = multiprocessing.get_context("spawn")
        # shard 0 is this process's own: it would otherwise idle while the workers run
        self._conns: list[Connection | None] = [None]
        self._procs: list[Any] = [None]
        self._local = sub_detector(detector, self.shards[0])
        self._local_state = self._local.initial_state()
        boards = np.array([t.board for t in layout.taxels])
        self.boards = [sorted(set(boards[taxels].tolist())) for taxels in self.shards]
        for i, taxels in enumerate(self.shards[1:], start=1):
            parent, child = context.Pipe()
            proc = context.Process(target=_serve, name=f"skin-onset-{i}", daemon=True,
                                   args=(child, sub_detector(detector, taxels), taxels))
            proc.start()
            child.close()  # so a dead worker reads as end of file here
            self._conns.append(parent)
            self._procs.append(proc)

    def describe(self, i: int) -> str:
        """Name worker ``i``: its number, process id, taxels and boards."""
        boards = ", ".join(str(b) for b in self.boards[i])
        return (f"worker {i} (pid {self._procs[i].pid}, {self.shards[i].size} taxels of "
                f"board{'s' if len(self.boards[i]) > 1 else ''} {boards})")

    def process(self, times: np.ndarray, temperature: np.ndarray,
                duty: np.ndarray | None = None) -> list[OnsetEvent]:
        """Detect onsets in a block; return its events in the one-process detector's order.

        ``duty``: the taxels' heater duty (`skin.stream.onset.OnsetDetector.process`), or None.

        Raises
        ------
        SkinError
            If a worker died or failed (naming it).
        """
        if not self._conns:
            raise SkinError("the onset workers are closed")
        for i in range(1, len(self.shards)):
            try:
                part = self.shards[i]
                self._conns[i].send((times, np.ascontiguousarray(temperature[:, part]),
                                     None if duty is None else np.ascontiguousarray(duty[:, part])))
            except (BrokenPipeError, ConnectionResetError, EOFError):
                raise self._died(i) from None
        wall, cpu = time.perf_counter(), time.process_time()
        taxels = self.shards[0]
        events, self._local_state = self._local.process(
            times, temperature[:, taxels], self._local_state, in_place=True,
            duty=None if duty is None else duty[:, taxels])
        events = [_relabel(e, int(taxels[e.taxel])) for e in events]
        self.in_contact[taxels] = self._local_state.in_contact
        self.busy[0] += (time.perf_counter() - wall, time.process_time() - cpu)
        for i in range(1, len(self.shards)):
            conn, taxels = self._conns[i], self.shards[i]
            wait([conn, self._procs[i].sentinel])
            try:
                status, got, in_contact, busy = conn.recv()
            except (EOFError, ConnectionResetError, OSError):
                raise self._died(i) from None
            if status != "ok":
                raise SkinError(f"onset {self.describe(i)} failed:\n{got}")
            events += got
            self.in_contact[taxels] = in_contact
            self.busy[i] += busy
        events.sort(key=lambda e: (e.detected_at, e.channel, e.taxel))
        return events

    def _died(self, i: int) -> SkinError:
        proc = self._procs[i]
        proc.join(1.0)
        return SkinError(f"onset {self.describe(i)} died (exit code {proc.exitcode}); the "
                         "results given so far stand and every block received was calibrated "
                         "and recorded before it went to the workers")

    def close(self) -> None:
        """Stop the workers (idempotent): ask each to end, then terminate any that hangs."""
        stop_workers(self._conns[1:], self._procs[1:], None)
        self._conns, self._procs = [], []

    def __del__(self) -> None:  # a pipeline dropped without close() leaves no process behind
        try:
            self.close()
        except Exception:  # interpreter shutdown
            pass


def stop_workers(conns: list[Any], procs: list[Any], message: Any) -> None:
    """Send each worker ``message`` (its stop word), wait for it, terminate one that hangs.

    A worker already gone (a broken pipe) is only joined; every connection is closed.
    """
    for conn in conns:
        try:
            conn.send(message)
        except (BrokenPipeError, ConnectionResetError, OSError):
            pass
    for conn, proc in zip(conns, procs, strict=True):
        proc.join(JOIN_TIMEOUT)
        if proc.is_alive():
            proc.terminate()
            proc.join(JOIN_TIMEOUT)
        conn.close()

"""Boards read, decoded, assembled, calibrated and onset-detected in worker processes.

A skin of many boards is split into shards of whole boards, one per worker process (the
standard library's ``multiprocessing``, ``spawn`` start method). Each worker opens its own
boards' source - serial or CAN ports by URL (`UrlSource`), a recorded list of frames
(`FramesSource`) or files of wire bytes (`WireSource`, the benchmark's) - and runs the
per-taxel stages on its taxels: decoding (in the drivers), assembling its boards' frames into
samples (`skin.stream.assembly.FrameAssembler`), calibrating and onset detection. It sends
each block of samples to the parent as compact arrays through a pipe: the sequence numbers,
times, each board's ambient reading, the temperatures (deg C, NaN where flagged), the onset
and release events (layout indices), the force channel where its frames carry one and its
taxels in contact.

The parent (`BoardWorkers`) joins the shards' samples by sequence number into skin-wide
blocks of ``block`` samples - a sample missing from a shard (all its boards lost that frame)
has its taxels NaN, as the one-process assembler would - and hands them to
`skin.stream.pipeline.Pipeline.process_calibrated`, which observes (a recording), tracks,
refines, classifies and writes the sinks; a block's force is merged there with the onset
detector's events (`skin.stream.force.ForceOnsets`), as in one process. A sample's time is
that of its lowest board present and its ambient the mean over its boards in board order, as
in one process; the events of a block are merged in the detector's own order (sample,
`OnsetEvent.channel`, taxel). Contacts that span shards are tracked in the parent with the
whole skin's samples, so with boards in step and no frame lost the results are those of one
process taking blocks of the same size (tests/test_shards.py).

A worker that dies or fails raises `skin.errors.SkinError` naming it (its number, process id,
exit code and boards); the results given before stand.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.frame import Frame
from skin.stream.assembly import FrameAssembler
from skin.stream.calibration import Calibration
from skin.stream.onset import OnsetDetector, OnsetEvent
from skin.stream.shards import shard_taxels, stop_workers, sub_detector

#: The worker-side stages timed (CPU seconds: on a shared machine a stage's wall time counts
#: the waits for a core), in `BoardWorkers.seconds`.
WORKER_STAGES = ("read", "assemble", "calibrate", "onset", "send")


@dataclass(frozen=True)
class CalibratedBlock:
    """Skin-wide samples already assembled, calibrated and onset-detected.

    Attributes
    ----------
    times, host_times, ambient : numpy.ndarray
        Per sample: device time (s), host time (s), ambient (deg C), (n,).
    temperature : numpy.ndarray
        Deg C in layout order, NaN where flagged or missing, (n, taxels).
    events : list of OnsetEvent
        The onset and release events recognised in these samples, in the detector's order.
    force : numpy.ndarray or None
        The force channel, N, in layout order, NaN where a taxel has no reading or its board
        sent none, (n, taxels); None when no frame of these samples has one (as
        `skin.stream.assembly.Samples.force`).
    """

    times: np.ndarray
    host_times: np.ndarray
    ambient: np.ndarray
    temperature: np.ndarray
    events: list[OnsetEvent]
    force: np.ndarray | None = None


# --- sources: what a worker opens ------------------------------------------------------------
class Reader(Protocol):
    """A worker's open source of frames."""

    finished: bool

    def read(self, timeout: float) -> list[Frame]:  # noqa: D102
        ...

    def crc_errors(self) -> int:  # noqa: D102
        ...

    def close(self) -> None:  # noqa: D102
        ...


@dataclass(frozen=True)
class UrlSource:
    """Devices opened by URL in the worker (`skin.drivers.open`), read a frame each in turn.

    Reading the boards in turn is what a shared sync gives real boards; simulated boards
    (`skin.drivers.sim.PtySerialDevice` at full speed) wait for their reader, so nothing is
    dropped and no board runs ahead of the others.
    """

    urls: tuple[str, ...]

    def reader(self) -> Reader:  # noqa: D102
        return _UrlReader(self.urls)


class _UrlReader:
    def __init__(self, urls: Sequence[str]) -> None:
        from skin import drivers

        self.drivers: list[Any] = []
        try:
            for url in urls:
                self.drivers.append(drivers.open(url))
        except BaseException:
            self.close()
            raise
        self.finished = False

    def read(self, timeout: float) -> list[Frame]:
        frames = []
        for d in self.drivers:
            if not d.finished:
                frame = d.recv(timeout=timeout)
                if frame is not None:
                    frames.append(frame)
        self.finished = all(d.finished for d in self.drivers)
        return frames

    def crc_errors(self) -> int:
        return sum(d.stats.crc_errors for d in self.drivers)

    def close(self) -> None:
        for d in self.drivers:
            d.close()


@dataclass(frozen=True)
class FramesSource:
    """Frames given in full (a recording read back), handed on ``step`` at a time."""

    frames: tuple[Frame, ...]
    step: int = 20

    def reader(self) -> Reader:  # noqa: D102
        return _FramesReader(self)


class _FramesReader:
    def __init__(self, source: FramesSource) -> None:
        self.source, self.at, self.finished = source, 0, not source.frames

    def read(self, timeout: float) -> list[Frame]:
        got = list(self.source.frames[self.at : self.at + self.source.step])
        self.at += len(got)
        self.finished = self.at >= len(self.source.frames)
        return got

    def crc_errors(self) -> int:
        return 0

    def close(self) -> None:
        pass


@dataclass(frozen=True)
class WireSource:
    """Files of wire bytes, one per board, decoded ``step`` samples at a time in the worker.

    Board ``b``'s bytes are ``board<b>.bin`` and the byte offset of each sample's packet
    ``board<b>.npy``. `WireWriter` writes them; `skin.bench.pipeline` serves its boards
    this way, so the benchmark's workers decode their boards as they would read their ports.
    """

    folder: str
    boards: tuple[int, ...]
    step: int = 1

    def reader(self) -> Reader:  # noqa: D102
        return _WireReader(self)


class _WireReader:
    def __init__(self, source: WireSource) -> None:
        from skin.drivers.protocol import StreamDecoder

        folder = Path(source.folder)
        self.step = source.step
        self.offsets = [np.load(folder / f"board{b}.npy") for b in source.boards]
        self.files = [(folder / f"board{b}.bin").open("rb") for b in source.boards]
        self.decoders = [StreamDecoder(board=b) for b in source.boards]
        self.n = min(len(o) - 1 for o in self.offsets)
        self.at = 0
        self.finished = self.n <= 0

    def read(self, timeout: float) -> list[Frame]:
        k0, k1 = self.at, min(self.at + self.step, self.n)
        frames = []
        for off, file, dec in zip(self.offsets, self.files, self.decoders, strict=True):
            frames += dec.feed(file.read(int(off[k1] - off[k0])))
        self.at = k1
        self.finished = self.at >= self.n
        return frames

    def crc_errors(self) -> int:
        return sum(d.stats.crc_errors for d in self.decoders)

    def close(self) -> None:
        for f in self.files:
            f.close()


class WireWriter:
    """Write boards' wire bytes for `WireSource`: `add` each sample's packets, then `close`."""

    def __init__(self, folder: str | Path, boards: Sequence[int]) -> None:
        self.folder = Path(folder)
        self.boards = list(boards)
        self.files = [(self.folder / f"board{b}.bin").open("wb") for b in self.boards]
        self.offsets: list[list[int]] = [[0] for _ in self.boards]

    def add(self, packets: Sequence[bytes]) -> None:
        """Append one sample's packet of each board (in `boards` order)."""
        for file, off, p in zip(self.files, self.offsets, packets, strict=True):
            file.write(p)
            off.append(off[-1] + len(p))

    def close(self) -> None:  # noqa: D102
        for b, file, off in zip(self.boards, self.files, self.offsets, strict=True):
            file.close()
            np.save(self.folder / f"board{b}.npy", np.array(off, dtype=np.int64))


# --- the worker --------------------------------------------------------------------------------
class _BoardAssembler(FrameAssembler):
    """The assembler, also keeping each sample's per-board ambient and force presence.

    ``has_force``: whether any frame of the sample carried a force channel.
    """

    def _assemble(self, ready: list[dict[int, Frame]]) -> Any:
        boards = sorted(self.layout.boards)
        col = {b: i for i, b in enumerate(boards)}
        self.board_ambient = np.full((len(ready), len(boards)), np.nan)
        self.present = np.zeros((len(ready), len(boards)), dtype=bool)
        self.first = np.empty(len(ready), dtype=np.int64)
        self.has_force = np.zeros(len(ready), dtype=bool)
        for i, got in enumerate(ready):
            for b, f in got.items():
                self.board_ambient[i, col[b]] = f.ambient
                self.present[i, col[b]] = True
                self.has_force[i] |= f.force is not None
            self.first[i] = min(got)
        return super()._assemble(ready)


@dataclass
class _Spec:
    index: int
    layout: Layout  # the shard's boards and taxels
    taxels: np.ndarray  # their layout indices
    calibration: Calibration
    detector: OnsetDetector
    source: Any
    max_skew: int


def _work(conn: Connection, spec: _Spec) -> None:
    """Worker loop: read, assemble, calibrate, detect; send each block (module docstring)."""
    try:
        reader = spec.source.reader()
    except Exception as exc:  # a dead port: reported by the parent before the first frame
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    try:
        assembler = _BoardAssembler(spec.layout, max_skew=spec.max_skew)
        state = spec.detector.initial_state()
        seconds = dict.fromkeys(WORKER_STAGES, 0.0)
        cpu0 = time.process_time()
        flagged = np.zeros(len(spec.taxels), dtype=np.int64)

        def ship(samples: Any, kind: str) -> None:
            nonlocal state
            t0 = time.process_time()
            temperature, status = spec.calibration.temperature(samples.counts)
            t1 = time.process_time()
            events, state = spec.detector.process(samples.times, temperature, state,
                                                  in_place=True, duty=samples.duty)
            t2 = time.process_time()
            seqs = assembler.last_seqs
            rows = np.searchsorted(samples.times, [e.detected_at for e in events])
            tagged = [(int(seqs[r]), e.channel, int(spec.taxels[e.taxel]),
                       dataclasses.replace(e, taxel=int(spec.taxels[e.taxel])))
                      for r, e in zip(rows, events, strict=True)]
            bad = (status != 0).sum(axis=0)
            flagged[:] += bad
            conn.send((kind, {
                "seqs": seqs, "times": samples.times, "host": samples.host_times,
                "first": assembler.first, "ambient": assembler.board_ambient,
                "present": assembler.present, "temperature": temperature, "events": tagged,
                "force": samples.force, "has_force": assembler.has_force,
                "in_contact": state.in_contact, "frames": assembler.stats.frames,
                "gaps": sum(assembler.stats.gaps.values()), "late": assembler.stats.late,
                "crc_errors": reader.crc_errors(), "flagged": flagged,
                "seconds": seconds, "cpu": time.process_time() - cpu0,
                "peak_mb": _peak_mb() if kind == "end" else None}))
            seconds["calibrate"] += t1 - t0
            seconds["onset"] += t2 - t1
            seconds["send"] += time.process_time() - t2

        conn.send(("ready", None))
        while True:
            if conn.poll():  # the parent asks to stop: what was read is put out, then "end"
                conn.recv()
                ship(assembler.flush(), "end")
                return
            if reader.finished:
                ship(assembler.flush(), "end")
                conn.recv()  # the parent's stop
                return
            t0 = time.process_time()
            frames = reader.read(0.05)
            t1 = time.process_time()
            seconds["read"] += t1 - t0
            if frames:
                samples = assembler.push(frames)
                seconds["assemble"] += time.process_time() - t1
                if len(samples):
                    ship(samples, "data")
    except (EOFError, BrokenPipeError, ConnectionResetError, KeyboardInterrupt):
        return  # the parent went away
    except Exception:  # the parent reports it, naming this worker
        try:
            conn.send(("error", traceback.format_exc()))
        except OSError:
            pass
    finally:
        reader.close()


def _peak_mb() -> float:
    """Return the worker's peak resident memory, MB (VmHWM: its own, not the parent's)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


# --- the parent --------------------------------------------------------------------------------
def sub_calibration(calibration: Calibration, taxels: np.ndarray) -> Calibration:
    """Return ``calibration`` for ``taxels`` only (each per-taxel array sliced)."""
    def part(value: Any) -> Any:
        return np.asarray(value)[taxels] if np.ndim(value) else value

    return dataclasses.replace(calibration, **{
        f.name: part(getattr(calibration, f.name)) for f in dataclasses.fields(calibration)
        if f.name != "source"})


def shard_boards(layout: Layout, workers: int) -> list[list[int]]:
    """Split the layout's boards into shards of whole boards, balanced by taxels.

    As many shards as ``workers``, or as boards when there are fewer
    (`skin.stream.shards.shard_taxels`).
    """
    boards = np.array([t.board for t in layout.taxels])
    shards = shard_taxels(layout, min(workers, len(layout.boards)))
    return [sorted(set(boards[s].tolist())) for s in shards]


class _Shard:
    """What the parent holds of one worker: its taxels, boards and samples not yet joined."""

    def __init__(self, taxels: np.ndarray, boards: list[int], columns: np.ndarray) -> None:
        self.taxels, self.boards, self.columns = taxels, boards, columns
        self.parts: list[dict] = []  # messages' arrays not yet joined
        self.events: list[tuple] = []
        self.newest = -1
        self.missing = 0  # samples joined without this shard (all its boards lost them)
        self.ended = False
        self.last: dict = {}

    def take(self, msg: dict) -> None:
        if len(msg["seqs"]):
            self.parts.append(msg)
            self.newest = int(msg["seqs"][-1])
        self.events += msg["events"]
        self.last = msg

    def seqs(self) -> np.ndarray:
        return np.concatenate([p["seqs"] for p in self.parts]) if self.parts else np.zeros(
            0, dtype=np.int64)

    def pop(self, upto: int) -> dict[str, np.ndarray]:
        """Remove and return the rows with seq <= ``upto`` (a prefix), arrays joined.

        ``force`` is NaN in the rows of a message that carried none (``has_force`` False);
        absent when no message did (a skin without force: nothing allocated).
        """
        keys = ("seqs", "times", "host", "first", "ambient", "present", "temperature",
                "has_force")
        joined = {k: np.concatenate([p[k] for p in self.parts]) for k in keys} if self.parts \
            else None
        if joined is None:
            return {}
        if any(p.get("force") is not None for p in self.parts):
            joined["force"] = np.concatenate([
                np.full((len(p["seqs"]), self.taxels.size), np.nan) if p.get("force") is None
                else p["force"] for p in self.parts])
        c = int(np.searchsorted(joined["seqs"], upto, side="right"))
        rest = {k: v[c:] for k, v in joined.items()}
        self.parts = [rest] if len(rest["seqs"]) else []
        return {k: v[:c] for k, v in joined.items()}


class BoardWorkers:
    """A skin's boards read and processed in worker processes (see the module docstring).

    Parameters
    ----------
    pipeline : Pipeline
        The one-process chain whose layout, calibration, detector and ``max_skew`` the workers
        take; the parent feeds it the joined blocks (`feed`).
    shards : sequence of (boards, source)
        Each worker's board ids and the source that gives their frames (`UrlSource`,
        `FramesSource`, `WireSource`); every board of the layout in exactly one shard.
    block : int
        Samples per block handed to the pipeline (the last may be shorter).

    Attributes
    ----------
    frames, gaps, late, crc_errors : int
        Over all workers, as last reported.
    flagged : numpy.ndarray
        Per taxel (layout order): samples without a temperature, as last reported.
    in_contact : numpy.ndarray
        Taxels in contact at each worker's newest sample.
    seconds : numpy.ndarray, shape (workers, len(WORKER_STAGES) + 1)
        Each worker's CPU seconds per stage (`WORKER_STAGES`; "read": reading and decoding
        its ports) and in all since its source opened.
    peak_mb : list of float
        Each worker's peak resident memory, MB, once it has ended (NaN before).
    """

    def __init__(self, pipeline: Any, shards: Sequence[tuple[Sequence[int], Any]],
                 block: int = 10) -> None:
        if block < 1:
            raise ValueError(f"block must be >= 1, got {block}")
        layout: Layout = pipeline.layout
        self.pipeline, self.layout, self.block = pipeline, layout, int(block)
        owner: dict[int, int] = {}
        for i, (boards, _) in enumerate(shards):
            for b in boards:
                if b not in layout.boards:
                    raise SkinError(f"worker {i}: board {b} is not in {layout.source}")
                if b in owner:
                    raise SkinError(f"board {b} is given to workers {owner[b]} and {i}")
                owner[b] = i
        left = sorted(set(layout.boards) - set(owner))
        if left:
            raise SkinError(f"board{'s' if len(left) > 1 else ''} {left} of {layout.source} "
                            "given to no worker")
        board_of = np.array([t.board for t in layout.taxels])
        self.all_boards = sorted(layout.boards)
        self.shards: list[_Shard] = []
        specs = []
        for i, (boards, source) in enumerate(shards):
            boards = sorted(boards)
            taxels = np.flatnonzero(np.isin(board_of, boards))
            sub = Layout([layout.taxels[k] for k in taxels], [layout.boards[b] for b in boards],
                         name=f"{layout.name}, worker {i}", source=layout.source)
            self.shards.append(_Shard(taxels, boards, np.searchsorted(self.all_boards, boards)))
            specs.append(_Spec(i, sub, taxels, sub_calibration(pipeline.calibration, taxels),
                               sub_detector(pipeline.detector, taxels), source,
                               pipeline.assembler.max_skew))
        n = len(layout)
        self.frames = self.gaps = self.late = self.crc_errors = 0
        self.flagged = np.zeros(n, dtype=np.int64)
        self.in_contact = np.zeros(n, dtype=bool)
        self.seconds = np.zeros((len(specs), len(WORKER_STAGES) + 1))
        self.peak_mb = [float("nan")] * len(specs)
        self._pending: list[dict] = []
        self._next_block: list[CalibratedBlock] = []
        context = multiprocessing.get_context("spawn")
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        try:
            for spec in specs:
                parent, child = context.Pipe()
                proc = context.Process(target=_work, name=f"skin-boards-{spec.index}",
                                       daemon=True, args=(child, spec))
                proc.start()
                child.close()  # so a dead worker reads as end of file here
                self._conns.append(parent)
                self._procs.append(proc)
            for i in range(len(specs)):  # every source open before the first frame
                kind, what = self._recv(i)
                if kind == "error":
                    raise SkinError(f"{self.describe(i)} could not open its boards: {what}")
        except BaseException:
            self.close()
            raise

    @property
    def done(self) -> bool:
        """Whether every worker has ended (its source finished, or `stop`)."""
        return all(s.ended for s in self.shards)

    def describe(self, i: int) -> str:
        """Name worker ``i``: its number, process id, taxels and boards."""
        s = self.shards[i]
        return (f"board worker {i} (pid {self._procs[i].pid}, {s.taxels.size} taxels of "
                f"board{'s' if len(s.boards) > 1 else ''} {', '.join(map(str, s.boards))})")

    def _recv(self, i: int) -> tuple[str, Any]:
        conn, proc = self._conns[i], self._procs[i]
        wait([conn, proc.sentinel])
        try:
            kind, what = conn.recv()
        except (EOFError, ConnectionResetError, OSError):
            proc.join(1.0)
            raise SkinError(f"{self.describe(i)} died (exit code {proc.exitcode}); the results "
                            "given so far stand") from None
        return kind, what

    def blocks(self, timeout: float = 0.2) -> list[CalibratedBlock]:
        """Wait up to ``timeout`` s for the workers; return the whole blocks now joined.

        Raises
        ------
        SkinError
            If a worker died or failed (naming it).
        """
        live = [i for i, s in enumerate(self.shards) if not s.ended]
        if live:
            ready = wait([self._conns[i] for i in live]
                         + [self._procs[i].sentinel for i in live], timeout)
            for i in live:
                if self._conns[i] in ready or self._procs[i].sentinel in ready:
                    self._take(i)
                    while not self.shards[i].ended and self._conns[i].poll():
                        self._take(i)
        return self._join(final=self.done)

    def stop(self) -> list[CalibratedBlock]:
        """Ask every worker to put out what it has read and end; return the last blocks."""
        for i, s in enumerate(self.shards):
            try:
                self._conns[i].send("stop")
            except (BrokenPipeError, ConnectionResetError, OSError):
                if not s.ended:
                    raise SkinError(f"{self.describe(i)} died (exit code "
                                    f"{self._procs[i].exitcode})") from None
        out = []
        while not self.done:
            out += self.blocks(1.0)
        return out + self._join(final=True)

    def _take(self, i: int) -> None:
        kind, msg = self._recv(i)
        if kind == "error":
            raise SkinError(f"{self.describe(i)} failed:\n{msg}")
        s = self.shards[i]
        s.take(msg)
        s.ended = kind == "end"
        self.in_contact[s.taxels] = msg["in_contact"]
        self.flagged[s.taxels] = msg["flagged"] + s.missing
        self.seconds[i, :-1] = [msg["seconds"][k] for k in WORKER_STAGES]
        self.seconds[i, -1] = msg["cpu"]
        if msg["peak_mb"] is not None:
            self.peak_mb[i] = msg["peak_mb"]
        last = [x.last for x in self.shards if x.last]
        self.frames = sum(m["frames"] for m in last)
        self.gaps = sum(m["gaps"] for m in last)
        self.late = sum(m["late"] for m in last)
        self.crc_errors = sum(m["crc_errors"] for m in last)

    def _join(self, final: bool) -> list[CalibratedBlock]:
        """Join the samples every shard has given (or will never give) into blocks."""
        have = [s.seqs() for s in self.shards]
        cands = np.unique(np.concatenate(have)) if have else np.zeros(0, dtype=np.int64)
        ok = np.ones(cands.size, dtype=bool)
        for s, seqs in zip(self.shards, have, strict=True):
            ok &= np.isin(cands, seqs) | (cands < s.newest) | s.ended
        m = int(np.argmin(ok)) if not ok.all() else cands.size
        if not final:
            m -= m % self.block
        if m == 0:
            return []
        ready = cands[:m]
        n_all, nb = len(self.layout), len(self.all_boards)
        temperature = np.full((m, n_all), np.nan)
        first = np.full((m, len(self.shards)), np.iinfo(np.int64).max)
        times = np.zeros((m, len(self.shards)))
        host = np.zeros((m, len(self.shards)))
        ambient = np.full((m, nb), np.nan)
        present = np.zeros((m, nb), dtype=bool)
        force = None  # made when a shard has a force channel in these samples
        has_force = np.zeros(m, dtype=bool)
        events = []
        for j, s in enumerate(self.shards):
            got = s.pop(int(ready[-1]))
            lost = m - (len(got["seqs"]) if got else 0)
            if lost:  # its taxels have no temperature there, as in one process
                s.missing += lost
                self.flagged[s.taxels] += lost
            if got:
                rows = np.searchsorted(ready, got["seqs"])
                if rows.size == m:
                    temperature[:, s.taxels] = got["temperature"]
                else:
                    temperature[np.ix_(rows, s.taxels)] = got["temperature"]
                first[rows, j] = got["first"]
                times[rows, j] = got["times"]
                host[rows, j] = got["host"]
                ambient[np.ix_(rows, s.columns)] = got["ambient"]
                present[np.ix_(rows, s.columns)] = got["present"]
                if got["has_force"].any():
                    if force is None:
                        force = np.full((m, n_all), np.nan)
                    force[np.ix_(rows, s.taxels)] = got["force"]
                    has_force[rows] |= got["has_force"]
            keep = [e for e in s.events if e[0] > ready[-1]]
            events += [e for e in s.events if e[0] <= ready[-1]]
            s.events = keep
        events.sort(key=lambda e: e[:3])  # sample, channel, taxel: the detector's order
        at = np.searchsorted(ready, [e[0] for e in events])  # each event's row
        pick = np.argmin(first, axis=1)
        rows = np.arange(m)
        times, host = times[rows, pick], host[rows, pick]
        # the mean over the boards present, in board order (as FrameAssembler)
        amb = np.array([np.mean(ambient[i, present[i]]) for i in range(m)])
        out = []
        for a in range(0, m, self.block):
            b = min(a + self.block, m)
            # None where no frame of the block had a force channel, as in one process
            out.append(CalibratedBlock(times[a:b], host[a:b], amb[a:b], temperature[a:b],
                                       [e[3] for e, k in zip(events, at, strict=True)
                                        if a <= k < b],
                                       force[a:b] if force is not None and has_force[a:b].any()
                                       else None))
        return out

    def feed(self, blocks: Sequence[CalibratedBlock]) -> list:
        """Hand ``blocks`` to the pipeline, keeping its counts; return the results given."""
        results = []
        stats = self.pipeline.stats
        for block in blocks:
            results += self.pipeline.process_calibrated(block)
        stats.frames, stats.gaps, stats.late = self.frames, self.gaps, self.late
        stats.flagged[:] = self.flagged
        return results

    def finish(self) -> list:
        """End of stream: `stop` the workers, feed their last blocks, flush the pipeline.

        Returns the results given.
        """
        results = self.feed(self.stop())
        results += self.pipeline.flush()
        stats = self.pipeline.stats  # the pipeline's own assembler took no frame
        stats.frames, stats.gaps, stats.late = self.frames, self.gaps, self.late
        return results

    def close(self) -> None:
        """Stop the workers (idempotent): ask each to end, then terminate any that hangs."""
        stop_workers(self._conns, self._procs, "stop")
        self._conns, self._procs = [], []

    def __enter__(self) -> BoardWorkers:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # dropped without close(): no process left behind
        try:
            self.close()
        except Exception:  # interpreter shutdown
            pass

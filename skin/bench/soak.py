"""Soak: the whole chain for hours of simulated time, as fast as it goes, watching for drift.

`run` builds a skin of ``n`` taxels (`skin.bench.pipeline.cylinder_layout`: rings of 16,
boards of 256), gives each board its own simulated board (`skin.drivers.sim.SkinSimulator`
served as wire bytes on a real pseudo-terminal by `skin.drivers.sim.PtySerialDevice`; the
boards run in a process of their own, `SimulatedBoards`, as real boards are devices of their
own, so the chain under test has its process to itself), reads each through its serial
driver (`skin.drivers.open`), a frame from each in turn, and pushes the
frames through `skin.stream.pipeline.Pipeline` with the joint classifier, a JSON-lines sink
and an MCAP recording (`skin.drivers.recording.Recorder`: wire bytes, temperatures, events).

The touches repeat the same pattern every simulated minute (`PERIOD`), moved to other taxels,
so a chain that does not drift gives the same contacts every hour. Every ``every`` simulated
seconds it notes the chain's resident memory (and the boards' process's, apart), its open
file descriptors, and the frames, results and contacts so far. It reports memory over time
and its growth after the first simulated hour (or after the first tenth of a shorter run),
contacts and results per simulated hour, lost frames (sequence gaps, frames sent but never
read or dropped late by the assembler, CRC errors), the
simulated seconds per wall second and the size of what was written.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from skin.formats.layout import Layout

#: The touch pattern repeats every PERIOD simulated seconds.
PERIOD = 60.0
#: Touches per board and period, and the objects they use in turn.
TOUCHES = 6
OBJECTS = ("aluminium", "pine", "glass", "neoprene")
RING = 16  # taxels per ring of `cylinder_layout`


def soak_scenes(n_taxels: int, seconds: float, seed: int = 0) -> tuple[Layout, list[Any]]:
    """Return the skin's layout and one scene per board, its touches repeating every PERIOD.

    In each period, each board is touched `TOUCHES` times, 0.4-2.4 s long, by each object in
    turn, on a patch of four neighbouring taxels (two in a ring, the same two in the next
    ring) that moves from one period to the next; the last touches end before ``seconds``.
    The boards are touched at the same instants, so a board's last ring is never touched: it
    keeps every board's patch off the next board's first ring, where two simultaneous touches
    would be one patch on the skin, one contact (`touches_apart` checks it).
    """
    from skin.bench.pipeline import cylinder_layout
    from skin.formats.scene import Scene, SceneObject, Touch

    layout = cylinder_layout(n_taxels)
    objects = {m: SceneObject(m, m, None) for m in OBJECTS}
    scenes = []
    for board in sorted(layout.boards):
        taxels = [t for t in layout.taxels if t.board == board]
        ids = [t.id for t in taxels]
        rings = max(1, len(ids) // RING - 1)  # the rings touched: all but the last
        touches = []
        for period in range(int(np.ceil(seconds / PERIOD))):
            for slot in range(TOUCHES):
                start = period * PERIOD + 2.0 + slot * (PERIOD - 4.0) / TOUCHES
                length = 0.4 + 2.0 * slot / max(TOUCHES - 1, 1)
                if start + length >= seconds - 0.5:
                    break
                ring = (3 * period + 5 * slot) % rings
                k = (7 * period + 3 * slot) % RING
                patch = [ring * RING + k, ring * RING + (k + 1) % RING]
                if ring + 1 < rings:
                    patch += [p + RING for p in patch]
                patch = [ids[p] for p in patch if p < len(ids)]
                touches.append(Touch(OBJECTS[slot % len(OBJECTS)], tuple(patch), start, length))
        sub = Layout(taxels, [layout.boards[board]], name=f"{layout.name}, board {board}",
                     source=layout.source)
        scenes.append(Scene(name=f"soak-{board}", source=f"<soak board {board}>", layout=sub,
                            duration=seconds, ambient=25.0, noise=0.02, seed=seed + board,
                            initial_temperature=(31.0, 38.9), objects=objects,
                            touches=tuple(touches)))
    return layout, scenes


def touches_apart(layout: Layout, scenes: list[Any], join_window: float = 0.5) -> list[tuple]:
    """Return the pairs of touches that the tracker would take for one contact.

    Two touches whose taxels are the same or neighbours (`Layout.neighbour_lists`) and whose
    starts lie at most ``join_window`` s apart (`skin.stream.tracking.ContactTracker`) are
    one patch on the skin. Returns ``(start, board, taxels, other board, other taxels)`` per
    such pair; empty when every scripted touch can be told apart.
    """
    near = layout.neighbour_lists()
    touches = sorted((t.start, b, tuple(layout.index(i) for i in t.taxels))
                     for b, scene in enumerate(scenes) for t in scene.touches)
    joined = []
    for i, (start, board, idx) in enumerate(touches):
        reach = set(idx).union(*(near[k].tolist() for k in idx))
        for other, board2, idx2 in touches[i + 1:]:
            if other - start > join_window:
                break
            if reach.intersection(idx2):
                joined.append((start, board, tuple(int(layout.ids[k]) for k in idx),
                               board2, tuple(int(layout.ids[k]) for k in idx2)))
    return joined


def _rss_mb(pid: int | str = "self") -> float:
    """Resident memory of a process now (default: this one; 0 once it ended), MB."""
    try:
        with open(f"/proc/{pid}/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except FileNotFoundError:
        return 0.0


def _open_fds() -> int:
    """Open file descriptors of this process."""
    return len(os.listdir("/proc/self/fd"))


class SimulatedBoards:
    """The soak's simulated boards, served on pseudo-terminals from a process of their own.

    The boards are the hardware's side of the chain: in their own process
    (``multiprocessing``, ``spawn``), as real boards are their own devices, the chain under
    test (drivers, pipeline, sinks) has this process to itself. Each board is a
    `skin.drivers.sim.PtySerialDevice` at full speed (it waits for its reader).

    Parameters
    ----------
    scenes : list of Scene
        One per board (`soak_scenes`).

    Attributes
    ----------
    ports : list of (str, int)
        Each board's pseudo-terminal and board id, in scene order; open them, then `start`.
    sent : list of int
        Frames each board has written so far (as last reported; final once ``done``).
    done : list of bool
        Whether each board has written its last frame.
    """

    def __init__(self, scenes: list[Any]) -> None:
        import multiprocessing

        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self._proc = context.Process(target=_serve_boards, args=(child, scenes),
                                     name="skin-soak-boards", daemon=True)
        self._proc.start()
        child.close()
        try:
            self.ports: list[tuple[str, int]] = self._recv()
        except BaseException:
            self.close()
            raise
        self.sent = [0] * len(scenes)
        self.done = [False] * len(scenes)

    def _recv(self) -> Any:
        try:
            kind, what = self._conn.recv()
        except (EOFError, OSError):
            self._proc.join(1.0)
            raise RuntimeError(f"the simulated boards' process (pid {self._proc.pid}) died "
                               f"(exit code {self._proc.exitcode})") from None
        if kind == "error":
            raise RuntimeError(f"the simulated boards' process failed:\n{what}")
        return what

    @property
    def pid(self) -> int:
        """The boards' process id."""
        return self._proc.pid

    def start(self) -> None:
        """Start every board writing (after the ports are open)."""
        self._conn.send("start")

    def update(self) -> None:
        """Take the boards' latest counts, without waiting."""
        while self._conn.poll():
            self.sent, self.done = self._recv()

    def stop(self) -> None:
        """Stop the boards; ``sent`` is then what each wrote in all.

        Raises
        ------
        RuntimeError
            If the boards' process ended before it was asked to (its counts would be stale).
        """
        if not self._proc.is_alive():
            self.close()
            raise RuntimeError(f"the simulated boards' process (pid {self._proc.pid}) ended "
                               f"before the run did (exit code {self._proc.exitcode})")
        self._conn.send("stop")
        while True:
            what = self._recv()
            if what is None:
                break
            self.sent, self.done = what
        self.close()

    def close(self) -> None:
        """End the process (idempotent): its end of the pipe closes, so it stops at once."""
        self._conn.close()
        self._proc.join(5.0)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)


def _counts(devices: list[Any]) -> tuple[list[int], list[bool]]:
    """Return each board's frames sent and whether it is done.

    ``done`` is read first: a board counts its last frames before it says it is done, so a
    board said done has all its frames counted.
    """
    done = [d.done.is_set() for d in devices]
    return [d.frames_sent for d in devices], done


def _serve_boards(conn: Any, scenes: list[Any]) -> None:
    """`SimulatedBoards`' process: serve the boards, report their counts every 0.2 s.

    Ctrl-C is the chain's to handle (it stops reading and reports): the boards ignore it.
    """
    import signal
    import traceback

    signal.signal(signal.SIGINT, signal.SIG_IGN)

    from skin.drivers.sim import PtySerialDevice, SkinSimulator

    devices = []
    try:
        devices = [PtySerialDevice(SkinSimulator(scene), speed=0) for scene in scenes]
        conn.send(("ports", [(d.port, d.simulator.board.id) for d in devices]))
        if conn.recv() != "start":
            return
        for d in devices:
            d.start()
        while not conn.poll(0.2):
            conn.send(("counts", _counts(devices)))
        conn.recv()  # stop
        for d in devices:
            d.close()
        conn.send(("counts", _counts(devices)))
        conn.send(("stopped", None))
    except (EOFError, BrokenPipeError, KeyboardInterrupt):
        pass
    except Exception:
        try:
            conn.send(("error", traceback.format_exc()))
        except OSError:
            pass
    finally:
        for d in devices:
            d.close()


def run(hours: float, n_taxels: int, seed: int = 0, every: float | None = None,
        record: bool = True, folder: str | Path | None = None,
        progress: Callable[[str], None] | None = None,
        wall_limit: float | None = None) -> dict:
    """Run the soak (see the module docstring) and return its figures.

    Parameters
    ----------
    hours : float
        Simulated hours.
    n_taxels : int
        Skin size (boards of 256 taxels).
    seed : int
        Seed of the simulated boards (board b uses ``seed + b``).
    every : float, optional
        Simulated seconds between samples of memory and counts (default: 60 samples).
    record : bool
        Also record everything to MCAP.
    folder : str or Path, optional
        Where the events and the recording go (default: a temporary folder, removed after).
    progress : callable, optional
        Called with a status line at each sample.
    wall_limit : float, optional
        Stop reading after this many wall seconds (also on Ctrl-C) and report the simulated
        time reached; ``stopped_early`` says so, and frames still on their way are counted as
        ``in_flight``, not lost.

    Returns
    -------
    dict
        ``samples`` (per sample: simulated s, wall s, ``rss_mb``, ``open_fds``, frames,
        results, contacts; the last is taken after the boards ended); ``rss_growth`` and
        ``rss_growth_max`` (relative, from the first simulated hour, or the first tenth of a
        shorter run, to the run's last sample and to its largest); ``contacts_per_bin``
        (final contacts by onset, per whole simulated hour, or per `PERIOD` for a run
        shorter than two hours, as ``per`` says), ``touches_per_bin`` (the scripted
        touches by start, to compare) and ``labels_per_bin`` (their labels, counted;
        ``same_labels_every_bin``); ``lost_frames`` (``gaps``, ``late`` and
        frames sent but not read), ``crc_errors``, ``speed`` (simulated seconds per wall
        second), ``written_mb``, ``stopped_early``.
    """
    import shutil

    from skin import drivers
    from skin.models import JointClassifier
    from skin.stream.calibration import Calibration
    from skin.stream.pipeline import Pipeline
    from skin.stream.sinks import JsonLinesSink

    if hours <= 0 or n_taxels < 1:
        raise ValueError("hours and n_taxels must be positive")
    seconds = hours * 3600.0
    every = seconds / 60 if every is None else every
    layout, scenes = soak_scenes(n_taxels, seconds, seed)
    temporary = folder is None
    out = Path(tempfile.mkdtemp(prefix="skin-soak-") if folder is None else folder)
    out.mkdir(parents=True, exist_ok=True)
    boards = SimulatedBoards(scenes)
    closers: list[Any] = [boards]
    opened: list[Any] = []  # the boards' drivers, read here (one process)
    try:
        calibration = Calibration.from_layout(layout)
        pipe = Pipeline(layout, JointClassifier(layout), calibration=calibration)
        for port, board in boards.ports:
            opened.append(drivers.open(f"serial://{port}?board={board}"))
            closers.insert(0, opened[-1])
        events = JsonLinesSink(out / "events.jsonl")
        closers.insert(0, events)
        pipe.sinks.append(events)
        if record:
            from skin.drivers.recording import Recorder

            recorder = Recorder(out / "soak.mcap", layout, calibration=calibration,
                                metadata={"command": f"skin bench soak --hours {hours:g} "
                                                     f"--taxels {n_taxels}"})
            closers.insert(0, recorder)
            for one in opened:
                recorder.add_driver(one)
            pipe.sinks.append(recorder)
            pipe.observers.append(recorder.temperature)
        boards.start()  # after the ports are open: opening one empties its buffer
        samples = []
        onsets: list[float] = []  # onset of every final contact, simulated s
        labels: list[str] = []  # and its label
        results = 0
        received = 0
        now = 0.0
        next_sample = 0.0
        started = time.monotonic()
        idle_since = started

        def note() -> None:
            samples.append({"simulated_s": round(now, 1),
                            "wall_s": round(time.monotonic() - started, 1),
                            "rss_mb": round(_rss_mb(), 1), "open_fds": _open_fds(),
                            "boards_rss_mb": round(_rss_mb(boards.pid), 1),
                            "frames": received, "results": results,
                            "contacts": len(onsets)})
            if progress is not None:
                s = samples[-1]
                progress(f"[{now / 3600:6.3f}/{hours:g} h] RSS {s['rss_mb']:.0f} MB, "
                         f"{s['open_fds']} fds, {received} frames, {len(onsets)} contacts")

        def take(given: list) -> None:
            nonlocal results
            for r in given:
                results += 1
                if r.contact.final:
                    onsets.append(r.contact.onset)
                    labels.append(r.estimate.label)

        def all_read(frames: int) -> bool:
            boards.update()
            return all(boards.done) and frames >= sum(boards.sent)

        stopped_early = False
        batch: list = []
        latest: dict[int, float] = {}
        per_board = [0] * len(boards.ports)
        try:
            while True:
                if wall_limit is not None and time.monotonic() - started > wall_limit:
                    stopped_early = True
                    break
                # the boards are read in turn, a frame each, as a sync keeps real boards in
                # step (the assembler takes a board more than 20 samples behind as missing);
                # each simulated board waits for its reader, so nothing is dropped at full speed
                got = 0
                for i, one in enumerate(opened):
                    if boards.done[i] and per_board[i] >= boards.sent[i]:
                        continue
                    frame = one.recv(timeout=1.0)
                    if frame is None:
                        continue
                    got += 1
                    per_board[i] += 1
                    batch.append(frame)
                    latest[frame.board] = frame.device_time
                received += got
                if got:
                    idle_since = time.monotonic()
                    if len(latest) == len(opened):
                        now = min(latest.values())  # the skin's time: its slowest board's
                done = all_read(received) or time.monotonic() - idle_since > 30.0
                if batch and (len(batch) >= 20 * len(opened) or done):
                    todo, batch = batch, []
                    take(pipe.process(todo))
                if now >= next_sample:
                    note()
                    next_sample += every
                if done:
                    break
        except KeyboardInterrupt:  # Ctrl-C: stop here and report (the boards ignore it)
            stopped_early = True
        take(pipe.process(batch) if batch else [])  # stopped early: what was read
        take(pipe.flush())
        now = min(latest.values(), default=0.0)
        crc = sum(one.stats.crc_errors for one in opened)
        late = pipe.assembler.stats.late
        note()
        wall = time.monotonic() - started
        boards.stop()
        sent = sum(boards.sent)
        for c in closers:
            c.close()
        closers = []
        written = sum(p.stat().st_size for p in out.iterdir() if p.is_file())
    finally:
        for c in closers:
            c.close()
        if temporary:
            shutil.rmtree(out, ignore_errors=True)
    during = samples[:-1] if len(samples) > 2 else samples  # the last: after the boards ended
    rss = np.array([s["rss_mb"] for s in during])
    sim_t = np.array([s["simulated_s"] for s in during])
    base_t = 3600.0 if seconds >= 2 * 3600.0 else seconds / 10
    i_base = min(int(np.searchsorted(sim_t, base_t)), rss.size - 1)
    base = rss[i_base]
    bin_s = 3600.0 if seconds >= 2 * 3600.0 else PERIOD
    bins = int((now if stopped_early else seconds) // bin_s)  # whole bins reached
    which = (np.array(onsets) // bin_s).astype(int)
    per_bin = [int(np.sum(which == b)) for b in range(bins)]
    starts = np.array([t.start for s in scenes for t in s.touches]) // bin_s
    touches_per_bin = [int(np.sum(starts == b)) for b in range(bins)]
    # the same touches every bin: the labels given should not drift either
    labels_per_bin = [dict(sorted(Counter(lab for lab, w in zip(labels, which, strict=True)
                                          if w == b).items())) for b in range(bins)]
    return {"hours": hours, "taxels": n_taxels, "boards": len(scenes),
            "seconds_simulated": round(now, 1), "wall_s": round(wall, 1),
            "speed": round(now / wall, 2) if wall > 0 else None,
            "taxel_samples_per_s": round(received / len(scenes) * n_taxels / wall)
            if wall > 0 else None,
            "frames_sent": sent, "frames_received": received,
            "lost_frames": int((0 if stopped_early else sent - received)
                               + pipe.stats.gaps + late),
            "in_flight": int(sent - received) if stopped_early else 0,
            "stopped_early": stopped_early,
            "gaps": int(pipe.stats.gaps), "late": int(late),
            "crc_errors": int(crc), "results": results, "contacts": len(onsets),
            "touches": sum(1 for s in scenes for t in s.touches
                           if not stopped_early or t.start + t.duration < now),
            "per": "hour" if bin_s == 3600.0 else f"{PERIOD:g} s",
            "contacts_per_bin": per_bin, "touches_per_bin": touches_per_bin,
            "labels_per_bin": labels_per_bin,
            "same_labels_every_bin": all(x == labels_per_bin[0] for x in labels_per_bin),
            "rss_mb": {"start": float(rss[0]), "baseline": float(base),
                       "end": float(rss[-1]), "max": float(rss.max()),
                       "after_run": samples[-1]["rss_mb"]},
            "rss_growth": round(float(rss[-1] / base - 1.0), 4),
            "rss_growth_max": round(float(rss[i_base:].max() / base - 1.0), 4),
            "rss_growth_baseline_at_s": base_t,
            "open_fds": {"start": samples[0]["open_fds"], "end": samples[-1]["open_fds"],
                         "max": max(s["open_fds"] for s in samples)},
            "recorded": record, "written_mb": round(written / 2**20, 1),
            "samples": samples}

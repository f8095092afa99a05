"""Throughput of the streaming chain: decode, assemble, calibrate, onset, track, refine, classify.

`run` builds a skin of ``n`` taxels (a cylinder of rings) wired to boards of at most
`BOARD_CHANNELS` channels sampled in step, simulates its stream (`skin.bench.streams`:
disturbances and contacts with known materials), turns the readings into ADC counts and
wire-protocol bytes per board, and pushes them through the chain one sample at a time, as a
live skin would arrive: each board's serial decoder, then `skin.stream.pipeline.Pipeline` with the
joint classifier and a per-sample ``budget`` for refining and classifying (the work of
contacts decided together is spread over the samples that follow). It reports taxel-samples
per second of the whole chain and of each stage (timed inside the pipeline), the real-time
factor at the boards' rate, the latency of each sample (p50, p99), how long results wait for
their share of the budget, and the process's peak memory and its growth. The stream is
simulated, encoded and decoded in chunks of ``chunk`` samples, so memory does not grow with
the run's length or hold the whole stream.
"""

from __future__ import annotations

import resource
import time
from typing import Any

import numpy as np

from skin.formats.layout import Board, Layout, Taxel

#: Channels per board in the benchmark's skins: an ATmega2560's 16 analog inputs behind 16-channel
#: multiplexers (a v1 SAMPLE carries at most `skin.drivers.protocol.MAX_TAXELS`, 336).
BOARD_CHANNELS = 256


def cylinder_layout(n: int, radius: float = 0.05, pitch: float = 0.02) -> Layout:
    """``n`` taxels in rings of 16 around one link, wired in order to boards of 256."""
    taxels = []
    per_ring = 16
    for i in range(n):
        ring, k = divmod(i, per_ring)
        a = 2 * np.pi * k / per_ring
        normal = (float(np.cos(a)), float(np.sin(a)), 0.0)
        board, address = divmod(i, BOARD_CHANNELS)
        taxels.append(Taxel(i, board, address, "forearm",
                            (radius * normal[0], radius * normal[1], pitch * ring), normal))
    boards = [Board(id=b) for b in range(-(-n // BOARD_CHANNELS))]
    return Layout(taxels, boards, name=f"cylinder of {n}", source=f"<{n} taxels>")


def run(n_taxels: int, duration: float = 20.0, seed: int = 0, contacts_per_minute: float = 6.0,
        budget: float | None = 0.001, chunk: int = 200, workers: int = 1,
        keep_results: bool = False, block: int = 1, envelope_noise: bool | None = None,
        common_mode: bool | None = None, force: bool = False) -> dict:
    """Push ``duration`` s of a simulated ``n_taxels`` skin through the chain; see the module.

    Parameters
    ----------
    n_taxels : int
        Skin size.
    duration : float
        Simulated seconds.
    seed : int
        Seed of the stream.
    contacts_per_minute : float
        Contacts per taxel and minute (`skin.bench.streams.simulate_stream` starts none
        in the last 10 s).
    budget : float or None
        The pipeline's per-sample budget for refining and classifying, s (None: none).
    chunk : int
        Samples simulated and encoded at a time: the memory is that of one chunk, whatever
        ``duration`` (the boards' wire bytes go to a temporary folder, before timing).
    force : bool
        Every taxel carries a force channel (a FORCE packet after each SAMPLE: 2 N while
        touched, else 0), which the pipeline dates its contacts by (`skin.stream.force`).
    workers : int
        1: one process decodes and runs the whole chain. More: the boards are shared out to
        that many worker processes (`skin.stream.board_workers`; as many as boards, ``shards``,
        when the skin has fewer), each decoding, assembling,
        calibrating and detecting onsets on its own boards, and this process joins, tracks,
        refines and classifies; ``worker_seconds`` gives each worker's seconds per stage and
        its CPU, ``parent_cpu_s`` this process's.
    block : int
        Samples the pipeline takes per call (1: each as it comes; a live `skin.Skin` takes
        what has arrived, up to 20 frames); ``latency_ms`` is then per call.
    keep_results : bool
        Also return the `ContactResult` objects given, in order, under ``results`` (not JSON).
    envelope_noise : bool, optional
        The onset detector's gust-envelope margin (`skin.stream.onset.OnsetDetector`'s
        ``envelope_noise``; None: its default); one process only (``workers`` 1).
    common_mode : bool, optional
        The onset detector's board common mode (``common_mode``; None: its default, on
        where the heater is not PID-held);
        one process only (``workers`` 1).

    Returns
    -------
    dict
        ``taxel_samples_per_s`` (whole chain), ``stages`` (taxel-samples per second of each
        stage's wall time; with workers, decode to onset: their CPU seconds, summed over the
        workers), ``stages_cpu`` (the same per CPU second of the process that ran the stage:
        on a loaded machine the wall time counts what other processes ran meanwhile),
        ``realtime_factor``, ``latency_ms`` (p50, p99 per call of the pipeline after
        decoding), ``result_wait_ms`` (p50, p99 of device time from a contact's decision to
        its result), ``contacts``
        decided, ``peak_memory_mb_growth`` and ``peak_memory_mb`` (this process's peak
        resident set, MB; ``workers_peak_memory_mb``: each worker's), ``wall_s`` and
        ``cpu_s`` (the chain's seconds, wall and CPU, the workers' CPU included).
    """
    import tempfile

    from skin.bench.streams import stream_chunks
    from skin.drivers.protocol import encode_force, encode_sample
    from skin.models import JointClassifier, load_materials
    from skin.stream.board_workers import WireSource, WireWriter
    from skin.stream.calibration import Calibration
    from skin.stream.pipeline import Pipeline, _detector_for

    if (envelope_noise is not None or common_mode is not None) and workers != 1:
        raise ValueError("envelope_noise and common_mode are set in one process only (workers "
                         "1): the board workers build their own detectors")
    peak0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    layout = cylinder_layout(n_taxels)
    table = load_materials()
    cal = Calibration.from_layout(layout)
    boards = sorted(layout.boards)
    wires = {b: layout.channel_map(b)[0] for b in boards}
    duty = np.full(BOARD_CHANNELS, 255)
    fs = float(layout.boards[boards[0]].sample_rate)  # the boards sample in step
    n = round(duration * fs)
    samples = n * n_taxels
    with tempfile.TemporaryDirectory(prefix="skin-bench-wire-") as folder:
        # not timed: the boards' wire bytes, one chunk of the stream at a time
        writer = WireWriter(folder, boards)
        for part in stream_chunks([table[m] for m in ("aluminium", "pine", "glass",
                                                      "neoprene")],
                                  n_taxels=n_taxels, duration=duration,
                                  contacts_per_minute=contacts_per_minute, fs=fs, seed=seed,
                                  chunk=chunk):
            counts = np.clip(np.rint(cal.counts(part.temperature)), 1, 1022).astype(np.int64)
            pressed = np.zeros(part.temperature.shape)
            if force:  # 2 N while touched, else 0 (a FORCE packet after each SAMPLE)
                for c in part.contacts:
                    pressed[(part.times >= c.onset) & (part.times < c.release), c.taxel] = 2.0
            for i, t in enumerate(part.times):
                writer.add([encode_sample(part.start + i, int(t * 1e6), counts[i, wires[b]],
                                          float(part.ambient[i]), duty[: wires[b].size])
                            + (encode_force(part.start + i, pressed[i, wires[b]])
                               if force else b"")
                            for b in boards])
        writer.close()
        detector = (None if envelope_noise is None and common_mode is None
                    else _detector_for(layout, envelope_noise=envelope_noise,
                                       common_mode=common_mode))
        pipe = Pipeline(layout, JointClassifier(layout), budget=budget, detector=detector)
        if workers == 1:
            timed = _one_process(pipe, WireSource(folder, tuple(boards)), n, block)
        else:
            timed = _board_workers(pipe, folder, workers, block)
    results, total, latency = timed.pop("results"), timed.pop("wall"), timed.pop("latency")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    waits = np.array([r.reported_at - r.contact.decided_at for r in results]) * 1e3
    # with workers, the parent's assemble, calibrate and onset are the workers' (summed)
    stages = {"decode": 0.0, **pipe.stats.seconds, **timed.pop("stages")}
    # the same in CPU seconds of the process that ran each stage (the workers' are CPU already)
    stages_cpu = {"decode": 0.0, **pipe.stats.cpu_seconds, **timed.pop("stages_cpu")}
    doc = {"taxels": n_taxels, "boards": len(boards), "workers": workers, "block": block,
           "frames": n * len(boards),
           "seconds_simulated": duration, "contacts_per_minute": contacts_per_minute,
           "budget_ms": None if budget is None else budget * 1e3,
           # the margin that ran (the default detector's too)
           "envelope": "noise" if pipe.detector.envelope_noise else "flat",
           "common_mode": pipe.detector.common_active,
           "taxel_samples_per_s": round(samples / total),
           "stages": _per_second(samples, stages),
           "stages_cpu": _per_second(samples, stages_cpu),
           "stage_share": {k: round(v / total, 3) for k, v in stages.items()},
           "realtime_factor": round(duration / total, 2),
           "latency_ms": {"p50": round(1e3 * float(np.percentile(latency, 50)), 3),
                          "p99": round(1e3 * float(np.percentile(latency, 99)), 3)},
           "result_wait_ms": {"p50": round(float(np.percentile(waits, 50)), 1) if waits.size
                              else None,
                              "p99": round(float(np.percentile(waits, 99)), 1) if waits.size
                              else None},
           "contacts": len(results),
           "peak_memory_mb_growth": round((peak - peak0) / 1024.0, 1),
           "peak_memory_mb": round(peak / 1024.0, 1), **timed}
    if keep_results:
        doc["results"] = results
    return doc


def _per_second(samples: int, seconds: dict[str, float]) -> dict[str, int | None]:
    """Taxel-samples per second of each stage (None for a stage that took no time)."""
    return {k: round(samples / v) if v > 0 else None for k, v in seconds.items()}


def _one_process(pipe: Any, source: Any, n: int, block: int) -> dict:
    """Run the whole chain in this process: decode each sample's packets, process blocks."""
    reader = source.reader()
    cpu = time.process_time()  # with the file reads: a sliver more than the chain's
    latency = np.empty(n)
    results: list = []
    t_decode = t_chain = c_decode = 0.0
    waiting: list = []  # the frames of the samples since ``since``, for the next call
    since = 0
    try:
        for k in range(n):
            since = k if not waiting else since
            t0, c0 = time.perf_counter(), time.process_time()
            waiting += reader.read(0.0)
            t1 = time.perf_counter()
            t_decode += t1 - t0
            c_decode += time.process_time() - c0
            if (k + 1) % block and k + 1 < n:
                continue
            results += pipe.process(waiting)
            waiting = []
            t2 = time.perf_counter()
            latency[since : k + 1] = t2 - t1
            t_chain += t2 - t1
    finally:
        reader.close()
    started = time.perf_counter()
    results += pipe.flush()  # the contacts still open or waiting at the end
    t_chain += time.perf_counter() - started
    return {"results": results, "wall": t_decode + t_chain, "latency": latency,
            "stages": {"decode": t_decode}, "stages_cpu": {"decode": c_decode},
            "wall_s": round(t_decode + t_chain, 3),
            "cpu_s": round(time.process_time() - cpu, 3)}


def _board_workers(pipe: Any, folder: str, workers: int, block: int) -> dict:
    """Run the boards in ``workers`` processes (`skin.stream.board_workers`), join here."""
    from skin.stream.board_workers import WORKER_STAGES, BoardWorkers, WireSource, shard_boards

    shards = [(b, WireSource(folder, tuple(b), step=20)) for b in shard_boards(pipe.layout,
                                                                              workers)]
    latency = []
    results: list = []
    with BoardWorkers(pipe, shards, block=block) as bw:  # started, every source open
        wall, cpu = time.perf_counter(), time.process_time()
        while not bw.done:
            got = bw.blocks(0.05)
            t0 = time.perf_counter()
            results += bw.feed(got)
            if got:
                latency.append((time.perf_counter() - t0) / len(got))
        results += bw.finish()
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        seconds, peaks = bw.seconds.copy(), list(bw.peak_mb)
    per = dict(zip(WORKER_STAGES, seconds[:, :-1].T, strict=True))
    worker_stages = {"decode": float(per["read"].sum()),
                     "assemble": float(per["assemble"].sum()),
                     "calibrate": float(per["calibrate"].sum()),
                     "onset": float(per["onset"].sum())}
    return {"results": results, "wall": wall, "latency": np.array(latency or [0.0]),
            # the workers' stages, summed over the workers (decode: reading their bytes);
            # their seconds are CPU seconds already
            "stages": worker_stages, "stages_cpu": worker_stages,
            "worker_seconds": {**{k: [round(float(x), 3) for x in v] for k, v in per.items()},
                               "cpu": [round(float(x), 3) for x in seconds[:, -1]]},
            "shards": len(shards), "parent_cpu_s": round(cpu, 3), "wall_s": round(wall, 3),
            "cpu_s": round(cpu + float(seconds[:, -1].sum()), 3),
            "workers_peak_memory_mb": [round(p, 1) for p in peaks]}


def workers_on_paper(one: dict, two: dict, workers: int) -> dict:
    """Speed-up of ``workers`` board workers over one process, on paper, from measured runs.

    CPU seconds, not wall seconds: on a shared machine the wall time measures the load of
    the others as much as the chain.

    Parameters
    ----------
    one, two : dict
        `run`'s rows of the same skin and stream with 1 and with 2 workers (same run).
    workers : int
        Workers to extrapolate to (at most one per board), each with a core of its own, and
        one core for this process.

    Returns
    -------
    dict
        ``parent_share``: this process's CPU seconds in the 2-worker run (joining, tracking,
        refining, classifying) over the 1-worker chain's CPU seconds; ``workers_share``: the
        workers' CPU seconds, summed, over the same (above 1 - ``parent_share``: what sharding
        costs); ``pipelined``: the speed-up when the parent and the workers run at once, each
        on its own core (the slower of the parent and a worker's share of the work sets the
        pace); ``two_cores``: the best two cores of their own can give the 2-worker run (all
        its CPU seconds spread over two cores).
    """
    workers = min(workers, one["boards"])  # a worker has whole boards
    t_one = one["cpu_s"]
    parent = two["parent_cpu_s"]
    work = sum(two["worker_seconds"]["cpu"])
    return {"workers": workers, "parent_share": round(parent / t_one, 3),
            "workers_share": round(work / t_one, 3),
            "pipelined": round(t_one / max(parent, work / workers), 2),
            "two_cores": round(t_one / ((parent + work) / 2), 2)}

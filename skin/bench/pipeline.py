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
        keep_results: bool = False, block: int = 1) -> dict:
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
        Samples simulated, encoded and decoded at a time: the memory is that of one chunk,
        whatever ``duration``.
    workers : int
        The pipeline's onset worker processes (`skin.stream.shards`), started before timing;
        with more than one, ``worker_seconds`` gives each worker's seconds in its detector
        (wall, CPU) and the parent's wait for them.
    block : int
        Samples the pipeline takes per call (1: each as it comes; a live `skin.Skin` takes
        what has arrived, up to 20 frames); ``latency_ms`` is then per call.
    keep_results : bool
        Also return the `ContactResult` objects given, in order, under ``results`` (not JSON).

    Returns
    -------
    dict
        ``taxel_samples_per_s`` (whole chain), ``stages`` (taxel-samples per second of each
        stage), ``realtime_factor``, ``latency_ms`` (p50, p99 per sample after decoding),
        ``result_wait_ms`` (p50, p99 of device time from a contact's decision to its result),
        ``contacts`` decided, ``peak_memory_mb_growth`` and ``peak_memory_mb`` (the process's
        peak resident set, MB; the workers' are not counted).
    """
    from skin.bench.streams import stream_chunks
    from skin.drivers.protocol import StreamDecoder, encode_sample
    from skin.models import JointClassifier, load_materials
    from skin.stream.calibration import Calibration
    from skin.stream.pipeline import Pipeline

    peak0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    layout = cylinder_layout(n_taxels)
    table = load_materials()
    cal = Calibration.from_layout(layout)
    boards = sorted(layout.boards)
    wires = {b: layout.channel_map(b)[0] for b in boards}
    duty = np.full(BOARD_CHANNELS, 255)
    decoders = [StreamDecoder(board=b) for b in boards]
    pipe = Pipeline(layout, JointClassifier(layout), budget=budget, workers=workers).start()
    fs = float(layout.boards[boards[0]].sample_rate)  # the boards sample in step
    n = round(duration * fs)
    samples = n * n_taxels
    latency = np.empty(n)
    results = []
    t_decode = t_chain = 0.0
    waiting: list = []  # the frames of the samples since ``since``, for the next call
    since = 0
    # bounded memory: one chunk of the stream, its packets and frames at a time
    for part in stream_chunks([table[m] for m in ("aluminium", "pine", "glass", "neoprene")],
                              n_taxels=n_taxels, duration=duration,
                              contacts_per_minute=contacts_per_minute, fs=fs, seed=seed,
                              chunk=chunk):
        counts = np.clip(np.rint(cal.counts(part.temperature)), 1, 1022).astype(np.int64)
        for i, t in enumerate(part.times):
            k = part.start + i
            packets = [encode_sample(k, int(t * 1e6), counts[i, wires[b]],
                                     float(part.ambient[i]), duty[: wires[b].size])
                       for b in boards]
            since = k if not waiting else since
            t0 = time.perf_counter()
            waiting += [f for dec, p in zip(decoders, packets, strict=True) for f in dec.feed(p)]
            t1 = time.perf_counter()
            t_decode += t1 - t0
            if (k + 1) % block and k + 1 < n:
                continue
            results += pipe.process(waiting)
            waiting = []
            t2 = time.perf_counter()
            latency[since : k + 1] = t2 - t1
            t_chain += t2 - t1
    started = time.perf_counter()
    results += pipe.flush()  # the contacts still open or waiting at the end
    t_chain += time.perf_counter() - started
    busy = None if pipe.onset_workers is None else pipe.onset_workers.busy
    pipe.close()
    total = t_decode + t_chain
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    waits = np.array([r.reported_at - r.contact.decided_at for r in results]) * 1e3
    stages = {"decode": t_decode, **pipe.stats.seconds}
    doc = {"taxels": n_taxels, "boards": len(boards), "workers": workers, "block": block,
           "frames": n * len(boards),
           "seconds_simulated": duration, "contacts_per_minute": contacts_per_minute,
           "budget_ms": None if budget is None else budget * 1e3,
           "taxel_samples_per_s": round(samples / total),
           "stages": {k: round(samples / v) if v > 0 else None for k, v in stages.items()},
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
           "peak_memory_mb": round(peak / 1024.0, 1)}
    if busy is not None:  # the workers' own seconds in their detectors: wall, CPU
        doc["worker_seconds"] = {"wall": [round(float(v), 3) for v in busy[:, 0]],
                                 "cpu": [round(float(v), 3) for v in busy[:, 1]],
                                 "parent_onset_wait": round(pipe.stats.seconds["onset"], 3)}
    if keep_results:
        doc["results"] = results
    return doc


def workers_on_paper(one: dict, two: dict, workers: int) -> dict:
    """Speed-up of ``workers`` onset workers over one process, on paper, from two measured runs.

    Parameters
    ----------
    one, two : dict
        `run`'s rows of the same skin and stream with 1 and with 2 workers (same run).
    workers : int
        Workers to extrapolate to, each with a core of its own.

    Returns
    -------
    dict
        ``onset_share`` p (of the 1-worker chain's time), ``amdahl`` (1 / (1 - p + p / N):
        the onset stage divided evenly, free transfers), and ``measured_parts``: the rest of
        the 1-worker chain, plus the 2-worker run's detector CPU seconds (both workers) / N,
        plus its transfer cost (the parent's wait beyond the slower worker's wall time: send,
        receive, merge), taken as not growing with N.
    """
    p = one["stage_share"]["onset"]
    samples = one["frames"] // one["boards"] * one["taxels"]  # the same in both runs
    t_one = samples / one["taxel_samples_per_s"]  # the 1-worker chain's seconds
    ws = two["worker_seconds"]
    transfer = max(ws["parent_onset_wait"] - max(ws["wall"]), 0.0)
    parts = (1.0 - p) * t_one + sum(ws["cpu"]) / workers + transfer
    return {"workers": workers, "onset_share": p,
            "amdahl": round(1.0 / (1.0 - p + p / workers), 2),
            "measured_parts": round(t_one / parts, 2),
            "transfer_share": round(transfer / t_one, 3),
            "worker_cpu_over_onset": round(sum(ws["cpu"]) / (p * t_one), 2)}

"""Throughput of the streaming chain: decode, calibrate, onset, contact and classify.

`run` builds a skin of ``n`` taxels on one board (a cylinder of rings), simulates its stream
(`skin.models.streams`: disturbances and contacts with known materials), turns the readings
into ADC counts and wire-protocol bytes, and pushes them through the chain one frame at a
time, as a live skin would arrive: the serial decoder, then `skin.pipeline.Pipeline` with the
joint classifier. It reports taxel-samples per second of the whole chain and of each stage,
the real-time factor at the board's rate, the per-frame latency (p50, p99) and the growth of
the process's peak memory.
"""

from __future__ import annotations

import resource
import time

import numpy as np

from skin.layout import Board, Layout, Taxel


def cylinder_layout(n: int, radius: float = 0.05, pitch: float = 0.02) -> Layout:
    """``n`` taxels in rings of 16 around one link, wired to one board in order."""
    taxels = []
    per_ring = 16
    for i in range(n):
        ring, k = divmod(i, per_ring)
        a = 2 * np.pi * k / per_ring
        normal = (float(np.cos(a)), float(np.sin(a)), 0.0)
        taxels.append(Taxel(i, 0, i, "forearm",
                            (radius * normal[0], radius * normal[1], pitch * ring), normal))
    return Layout(taxels, [Board(id=0)], name=f"cylinder of {n}", source=f"<{n} taxels>")


def run(n_taxels: int, duration: float = 20.0, seed: int = 0) -> dict:
    """Push ``duration`` s of a simulated ``n_taxels`` skin through the chain; see the module.

    Returns
    -------
    dict
        ``taxel_samples_per_s`` (whole chain), ``stages`` (taxel-samples per second of decode,
        calibrate, onset, and contact + classify; the last is the chain's time less the other
        stages timed alone), ``realtime_factor``, ``latency_ms`` (p50, p99 per frame, after
        decoding), ``contacts`` decided and ``peak_memory_mb_growth``.
    """
    from skin.calibration import Calibration
    from skin.drivers.protocol import StreamDecoder, encode_sample
    from skin.models import JointClassifier, load_materials
    from skin.models.streams import simulate_stream
    from skin.pipeline import Pipeline

    peak0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    layout = cylinder_layout(n_taxels)
    table = load_materials()
    stream = simulate_stream([table[m] for m in ("aluminium", "pine", "glass", "neoprene")],
                             n_taxels=n_taxels, duration=duration, contacts_per_minute=6.0,
                             seed=seed)
    cal = Calibration.from_layout(layout)
    counts = np.clip(np.rint(cal.counts(stream.temperature)), 1, 1022).astype(np.int64)
    duty = np.full(n_taxels, 255)
    wire = [encode_sample(k, int(t * 1e6), counts[k], float(stream.ambient[k]), duty)
            for k, t in enumerate(stream.times)]
    n = len(wire)
    samples = n * n_taxels

    decoder = StreamDecoder(board=0)
    started = time.perf_counter()
    frames = []
    for packet in wire:
        frames += decoder.feed(packet)
    t_decode = time.perf_counter() - started

    temps, _ = cal.temperature(counts)
    started = time.perf_counter()
    for k in range(n):
        cal.temperature(counts[k:k + 1])
    t_calibrate = time.perf_counter() - started

    pipe = Pipeline(layout, JointClassifier(layout))
    started = time.perf_counter()
    state = pipe.detector.initial_state()
    for k in range(n):
        _, state = pipe.detector.process(stream.times[k:k + 1], temps[k:k + 1], state)
    t_onset = time.perf_counter() - started

    latency = np.empty(n)
    results = []
    started = time.perf_counter()
    for k, frame in enumerate(frames):
        t0 = time.perf_counter()
        results += pipe.process([frame])
        latency[k] = time.perf_counter() - t0
    results += pipe.flush()
    t_chain = time.perf_counter() - started
    t_contact = max(t_chain - t_calibrate - t_onset, 1e-9)
    total = t_decode + t_chain
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return {"taxels": n_taxels, "frames": n, "seconds_simulated": duration,
            "taxel_samples_per_s": round(samples / total),
            "stages": {"decode": round(samples / t_decode),
                       "calibrate": round(samples / t_calibrate),
                       "onset": round(samples / t_onset),
                       "contact_and_classify": round(samples / t_contact)},
            "realtime_factor": round(duration / total, 2),
            "latency_ms": {"p50": round(1e3 * float(np.percentile(latency, 50)), 3),
                           "p99": round(1e3 * float(np.percentile(latency, 99)), 3)},
            "contacts": len(results),
            "peak_memory_mb_growth": round((peak - peak0) / 1024.0, 1)}

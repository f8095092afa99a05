"""``skin bench publish``: what publishing costs the skin, and how late its samples arrive.

A simulated skin of ``n`` taxels (`skin.bench.pipeline.cylinder_layout`, boards of 256, with
contacts of known materials: `skin.bench.streams`) is pushed through
`skin.stream.pipeline.Pipeline` twice per publisher, with a subscriber in another process:

- throughput: the whole stream as fast as the pipeline takes it, without publishing, with the
  publisher attached (its subscriber listening, so that every message is encoded and sent),
  and without again (the baseline is the mean of the two runs around it); the ratio of the
  rates is what publishing leaves of the pipeline, by the wall time of the pipeline's calls
  (the subscriber competes for the same cores) and by the CPU time of the skin's process
  (its publisher threads included);
- latency: the stream at its real rate (one block of ``chunk`` samples every ``chunk / rate``
  seconds, each sample stamped with the host time it was handed over); the subscriber takes
  its arrival time minus the newest sample's host time, per message (both Unix time on one
  machine), and reports the percentiles, with how many samples reached it.

Subscribers: ``skin subscribe`` for Zenoh (explicit TCP endpoints on localhost), and
`foxglove_client` (a plain WebSocket client speaking the Foxglove protocol) for Foxglove.
"""

from __future__ import annotations

import asyncio
import json
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from skin.frame import Frame


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _frames(n_taxels: int, seconds: float, seed: int) -> tuple[object, list[list[Frame]]]:
    """Return the layout and, per sample, one frame per board (host times set later)."""
    from skin.bench.pipeline import cylinder_layout
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials
    from skin.stream.calibration import Calibration

    layout = cylinder_layout(n_taxels)
    table = load_materials()
    stream = simulate_stream([table[m] for m in ("aluminium", "pine", "glass", "neoprene")],
                             n_taxels=n_taxels, duration=seconds, contacts_per_minute=6.0,
                             seed=seed)
    counts = np.clip(np.rint(Calibration.from_layout(layout).counts(stream.temperature)),
                     1, 1022).astype(np.uint16)
    out = []
    for k, t in enumerate(stream.times):
        per_board = []
        for b in sorted(layout.boards):
            idx, addr = layout.channel_map(b)
            c = np.zeros(int(addr.max()) + 1, dtype=np.uint16)
            c[addr] = counts[k, idx]
            per_board.append(Frame(k, float(t), 0.0, c, float(stream.ambient[k]),
                                   np.full(c.size, 255, dtype=np.uint8), 0, b))
        out.append(per_board)
    return layout, out


def _stamp(frames: list[Frame], host: float) -> list[Frame]:
    import dataclasses

    return [dataclasses.replace(f, host_time=host) for f in frames]


def _push(layout: object, samples: list[list[Frame]], chunk: int, attach: Callable | None,
          rate: float | None) -> tuple[float, float, int]:
    """Run the stream through a pipeline.

    Returns the wall seconds of the pipeline's work, the process's CPU seconds over the run
    (the publisher's own threads included) and the results given.
    """
    from skin.models import HistogramClassifier
    from skin.stream.pipeline import Pipeline

    pipe = Pipeline(layout, HistogramClassifier(layout), budget=0.002)
    if attach is not None:
        attach(pipe)
    work = 0.0
    results = 0
    start = time.monotonic()
    cpu = time.process_time()
    for k in range(0, len(samples), chunk):
        if rate is not None:  # the real pace: the block is complete at its last sample's time
            due = start + (k + chunk) / rate
            time.sleep(max(0.0, due - time.monotonic()))
        now = time.monotonic()
        block = [f for s in samples[k : k + chunk] for f in _stamp(s, now)]
        t0 = time.perf_counter()
        results += len(pipe.process(block))
        work += time.perf_counter() - t0
    t0 = time.perf_counter()
    results += len(pipe.flush())
    return work + time.perf_counter() - t0, time.process_time() - cpu, results


def foxglove_client(port: int, seconds: float) -> dict:
    """Subscribe to ``/temperature`` and ``/contacts`` on a Foxglove server for ``seconds``.

    Returns messages per topic, samples (distinct device times) and the latency percentiles
    of the temperature messages (arrival minus their sample's ``host_time``), ms.
    """
    import websockets

    async def main() -> dict:
        deadline = time.monotonic() + 30
        while True:
            try:
                ws = await websockets.connect(f"ws://127.0.0.1:{port}", max_size=None,
                                              subprotocols=["foxglove.sdk.v1"])
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                await asyncio.sleep(0.01)
        print("ready", file=sys.stderr, flush=True)
        topics: dict[int, str] = {}
        counts: dict[str, int] = {}
        lat: list[float] = []
        times: set[float] = set()
        end = time.monotonic() + seconds
        async with ws:
            while time.monotonic() < end:
                try:
                    data = await asyncio.wait_for(ws.recv(), max(0.01, end - time.monotonic()))
                except TimeoutError:
                    break
                except websockets.ConnectionClosed:
                    break
                arrived = time.time()
                if isinstance(data, str):
                    msg = json.loads(data)
                    if msg.get("op") == "advertise":
                        new = {c["id"]: c["topic"] for c in msg["channels"]}
                        topics.update(new)
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                            {"id": c, "channelId": c} for c, t in new.items()
                            if t in ("/temperature", "/contacts")]}))
                    continue
                _, sub, _ = struct.unpack_from("<BIQ", data)
                topic = topics.get(sub, "?")
                counts[topic] = counts.get(topic, 0) + 1
                if topic == "/temperature":  # the two times lead the message (fields 1, 2)
                    host, device = struct.unpack_from("<xdxd", data, 13)
                    lat.append(arrived - host)
                    times.add(device)
        lat.sort()
        return {"messages": counts, "samples": len(times),
                "p50_latency_ms": round(lat[len(lat) // 2] * 1e3, 3) if lat else None,
                "p99_latency_ms": round(lat[int(0.99 * (len(lat) - 1))] * 1e3, 3)
                if lat else None}

    return asyncio.run(main())


def _subscriber(kind: str, port: int, seconds: float) -> subprocess.Popen:
    if kind == "zenoh":
        skin = Path(sys.executable).with_name("skin")
        cmd = [str(skin), "subscribe", f"zenoh://bench?listen=tcp/127.0.0.1:{port}",
               "--duration", f"{seconds}", "--idle", "2", "--json"]
    else:
        cmd = [sys.executable, "-c", "import json, sys; from skin.bench.publish import "
               f"foxglove_client; print(json.dumps(foxglove_client({port}, {seconds})))"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return proc


def run(n_taxels: int = 1000, seconds: float = 10.0, rate: float = 200.0, chunk: int = 1,
        publishers: tuple[str, ...] = ("zenoh", "foxglove"), seed: int = 0,
        progress: Callable[[str], None] | None = None) -> dict:
    """Measure each publisher (see the module docstring); return a JSON-ready document."""
    from skin.stream.publish import open_publisher

    say = progress or (lambda text: None)
    say(f"simulating {n_taxels} taxels x {seconds:g} s")
    layout, samples = _frames(n_taxels, seconds, seed)
    say("throughput without publishing (after a warm-up pass)")
    _push(layout, samples[: len(samples) // 4], chunk, None, None)
    first, _, contacts = _push(layout, samples, chunk, None, None)
    rows = []
    for kind in publishers:
        for mode in ("throughput", "latency"):
            say(f"{kind}: {mode}")
            port = _free_port()
            listen = seconds + 20 if mode == "latency" else 5 * first + 20
            if kind == "zenoh":
                sub = _subscriber(kind, port, listen)
                sub.stderr.readline()  # "ready": subscribed
                pub = open_publisher(f"zenoh://bench?connect=tcp/127.0.0.1:{port}", layout)
            else:
                pub = open_publisher(f"foxglove://127.0.0.1:{port}", layout)
                sub = _subscriber(kind, port, listen)
                sub.stderr.readline()  # "ready": connected
            time.sleep(0.5)  # the subscription reaches the publisher
            try:
                if mode == "throughput":  # baselines on either side: the load drifts
                    before = _push(layout, samples, chunk, None, None)
                work, cpu, _ = _push(layout, samples, chunk, pub.attach,
                                     rate if mode == "latency" else None)
                if mode == "throughput":
                    after = _push(layout, samples, chunk, None, None)
                    base, base_cpu = (before[0] + after[0]) / 2, (before[1] + after[1]) / 2
                sent = dict(pub.sent)
            finally:
                pub.close()
            out, err = sub.communicate(timeout=listen + 30)
            try:
                got = json.loads(out.strip().splitlines()[-1])
            except (ValueError, IndexError):
                raise RuntimeError(f"the {kind} subscriber failed: {err[-2000:]}") from None
            row = {"publisher": kind, "mode": mode, "pipeline_s": round(work, 3),
                   "sent": sent, "received_samples": got["samples"],
                   "received_share": round(got["samples"] / len(samples), 5)}
            if mode == "throughput":
                row["baseline_pipeline_s"] = round(base, 3)
                row["throughput_ratio"] = round(base / work, 3)
                row["cpu_ratio"] = round(base_cpu / cpu, 3)
            else:
                row["p50_latency_ms"] = got["p50_latency_ms"]
                row["p99_latency_ms"] = got["p99_latency_ms"]
            rows.append(row)
    return {"taxels": n_taxels, "rate_hz": rate, "seconds": seconds, "chunk": chunk,
            "samples": len(samples), "contacts": contacts,
            "baseline_samples_per_s": round(len(samples) / first, 1), "rows": rows}

"""``skin bench map``: the shared map under the load of several robots, and its box query.

Live part: a map service (``skin map serve`` in its own process, listening on a free local TCP
port, multicast scouting off) and ``robots`` publisher processes (`publish`, run as ``python -m
skin.bench.map``), each a `skin.stream.publish_zenoh.ZenohPublisher` of a ``taxels``-taxel
cylinder (`skin.bench.pipeline.cylinder_layout`) sending contacts at ``rate`` per taxel and
minute (issue 7's 6), Poisson arrivals, each decided as it is sent (``host_decided_at`` = now).
This process listens to the service's acknowledgements (``<prefix>/map/acks/<robot>``); a
contact is visible to queries once its ack has arrived (the service commits before it acks), so
the latency is ack arrival minus the contact's ``host_decided_at`` (read back from the map).
Lost = published minus held by the map (asked over Zenoh, ``map/acks``).

Query part: a map of ``voxels`` voxels (1 cm) built synthetically with the store's own tables
(uniform in a 20 x 20 x 2.5 m hall, 11 materials' evidence each), then ``repeats`` random 1 m^3
boxes through `skin.world.map_store.MapStore.query_json` (the service's reply without the
network), `MapStore.query` (Python objects) and over Zenoh from ``skin map serve`` (a
`skin.world.shared_map.SharedMap` client), against a full scan of the voxel table for the last
box in the same run as the baseline.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np


def free_port() -> int:
    """Return a TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def publish(prefix: str, robot: str, connect: str, taxels: int = 1000, rate: float = 6.0,
            seconds: float | None = 10.0, count: int | None = None, first: int = 0,
            epoch: float | None = None, seed: int = 0, pose: str | None = None,
            spacing: float = 0.0, resend: float | None = None) -> dict[str, Any]:
    """Publish synthetic contacts of one robot through the real Zenoh publisher.

    Parameters
    ----------
    prefix, robot, connect : str
        Key prefix, robot name, the service's endpoint (``tcp/127.0.0.1:PORT``).
    taxels : int
        Taxels of the robot's skin (a cylinder on the default arm's forearm).
    rate : float
        Contacts per taxel and minute (Poisson arrivals), unless ``spacing`` is given.
    seconds, count : float, int
        Stop after this long, or after this many contacts.
    first : int
        Id of the first contact (ids count up from it).
    epoch : float, optional
        Host onset (Unix s) of contact 0; contact k's is ``epoch + k * 0.01``, so another
        process re-sending contact k sends the same key. Default: now.
    seed : int
        Seed of taxels and materials (contact k's depend on ``seed`` and k alone).
    pose : str, optional
        The robot's base in the map frame, ``x,y,z,roll,pitch,yaw`` (m, rad).
    spacing : float
        Seconds between contacts (instead of ``rate``).
    resend : float, optional
        The publisher's ``resend=`` (re-send what the map has not acknowledged).

    Returns
    -------
    dict
        ``robot``, ``published`` and the ids ``first`` and ``last``.
    """
    from skin.bench.pipeline import cylinder_layout
    from skin.contact import Contact, MaterialEstimate
    from skin.drivers.clock import WALL_OFFSET
    from skin.stream.pipeline import ContactResult, HostTimes
    from skin.stream.publish import open_publisher
    from skin.world.kinematics import transform

    layout = cylinder_layout(taxels)
    robot_pose = None
    if pose:
        v = [float(x) for x in pose.split(",")]
        robot_pose = transform(v[:3], v[3:])
    materials = ["aluminium", "steel", "glass", "pine", "polypropylene", "foam"]
    url = f"zenoh://{prefix}?robot={robot}&connect={connect}"
    pub = open_publisher(url + (f"&resend={resend}" if resend else ""), layout,
                         robot_pose=robot_pose)
    epoch = time.time() if epoch is None else epoch
    per_second = taxels * rate / 60.0
    arrivals = random.Random(f"{seed}/{robot}/arrivals")
    started = time.monotonic()
    next_at = started
    k = first
    sent = 0
    try:
        while True:
            if count is not None and sent >= count:
                break
            if seconds is not None and time.monotonic() - started >= seconds:
                break
            now = time.monotonic()
            if now < next_at:
                time.sleep(min(next_at - now, 0.05))
                continue
            pick = random.Random(f"{seed}/{k}")
            t = pick.randrange(taxels)
            near = [t] + ([t + 1] if t + 1 < taxels else [])
            label = pick.choice(materials)
            probs = {m: (0.6 if m == label else 0.4 / (len(materials) - 1)) for m in materials}
            onset = epoch + 0.01 * k - WALL_OFFSET  # host (monotonic) time of the onset
            contact = Contact(id=k, taxels=near, onset=0.01 * k, release=0.01 * k + 0.5,
                              ambient=25.0, windows=[], decided_at=0.01 * k + 0.5, final=True)
            estimate = MaterialEstimate(label, probs, 0.6, None, "bench")
            decided = time.monotonic()
            host = HostTimes(onset=onset, release=onset + 0.5, decided_at=decided,
                             reported_at=decided)
            pub.write(ContactResult(contact, estimate, 0.01 * k + 0.5, host))
            sent += 1
            k += 1
            next_at += spacing if spacing > 0 else arrivals.expovariate(per_second)
    finally:
        pub.close()
    return {"robot": robot, "published": sent, "first": first, "last": k - 1,
            "resent": pub.sent["resent"],
            "unacknowledged_at_close": pub.sent["unacknowledged_at_close"]}


def _main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m skin.bench.map",
                                description="publish synthetic contacts of one robot")
    p.add_argument("--prefix", default="thermoskin")
    p.add_argument("--robot", required=True)
    p.add_argument("--connect", required=True)
    p.add_argument("--taxels", type=int, default=1000)
    p.add_argument("--rate", type=float, default=6.0)
    p.add_argument("--seconds", type=float, default=None)
    p.add_argument("--count", type=int, default=None)
    p.add_argument("--first", type=int, default=0)
    p.add_argument("--epoch", type=float, default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--pose", default=None)
    p.add_argument("--spacing", type=float, default=0.0)
    p.add_argument("--resend", type=float, default=None)
    p.add_argument("--wait", type=float, default=0.5,
                   help="seconds to let the session connect before the first contact")
    a = p.parse_args(argv)
    from skin.stream.publish_zenoh import open_session  # noqa: F401 (fail early if missing)

    time.sleep(a.wait)
    out = publish(a.prefix, a.robot, a.connect, a.taxels, a.rate, a.seconds, a.count, a.first,
                  a.epoch, a.seed, a.pose, a.spacing, a.resend)
    print(json.dumps(out), flush=True)
    return 0


def start_service(db: Path, port: int, prefix: str = "bench", *extra: str
                  ) -> subprocess.Popen:
    """Start ``skin map serve`` on ``tcp/127.0.0.1:PORT``; return once it is ready."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "skin", "map", "serve", "--db", str(db), "--prefix", prefix,
         "--listen", f"tcp/127.0.0.1:{port}", "--status", "0", *extra],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    line = proc.stderr.readline()
    if line.strip() != "ready":
        proc.kill()
        raise RuntimeError(f"the map service did not start: {line}{proc.stderr.read()}")
    threading.Thread(target=proc.stderr.read, daemon=True).start()  # keep the pipe drained
    return proc


def live(robots: int = 3, taxels: int = 1000, minutes: float = 1.0, rate: float = 6.0,
         progress: bool = True, synchronous: str = "full") -> dict[str, Any]:
    """Run the live part (see the module docstring); return its figures."""
    from skin.stream.publish_zenoh import open_session
    from skin.world.shared_map import SharedMap

    prefix = "bench"
    port = free_port()
    folder = Path(tempfile.mkdtemp(prefix="skin-bench-map-"))
    service = start_service(folder / "map.sqlite", port, prefix, "--synchronous", synchronous)
    endpoint = f"tcp/127.0.0.1:{port}"
    arrived: dict[tuple[str, int, float], float] = {}
    lock = threading.Lock()

    def on_ack(sample: Any) -> None:
        now = time.time()
        msg = json.loads(sample.payload.to_bytes())
        with lock:
            for contact, onset in msg["contacts"]:
                arrived.setdefault((msg["robot"], contact, onset), now)

    session = open_session(connect=[endpoint])
    sub = session.declare_subscriber(f"{prefix}/map/acks/*", on_ack)
    procs = []
    env = dict(os.environ)
    try:
        for r in range(robots):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "skin.bench.map", "--prefix", prefix,
                 "--robot", f"robot{r}", "--connect", endpoint, "--taxels", str(taxels),
                 "--rate", str(rate), "--seconds", str(minutes * 60), "--seed", str(r),
                 "--pose", f"{2.0 * r},0,0,0,0,0"],
                stdout=subprocess.PIPE, text=True, env=env))
        started = time.monotonic()
        while any(p.poll() is None for p in procs):
            if progress:
                with lock:
                    n = len(arrived)
                print(f"\r{time.monotonic() - started:6.1f} s  {n} contacts acknowledged",
                      end="", file=sys.stderr, flush=True)
            time.sleep(1.0)
        published = {}
        for p in procs:
            out = json.loads(p.communicate()[0].strip().splitlines()[-1])
            published[out["robot"]] = out["published"]
        time.sleep(1.0)  # the last acks
        if progress:
            print(file=sys.stderr)
        with SharedMap(f"zenoh://{prefix}?connect={endpoint}") as shared:
            held = {r: len(shared.acks(r)) for r in published}
    finally:
        sub.undeclare()
        session.close()
        for p in procs:
            if p.poll() is None:
                p.kill()
        service.terminate()
        service.wait(timeout=30)
    import sqlite3

    db = sqlite3.connect(folder / "map.sqlite")
    latency = []
    for robot, contact, onset, decided in db.execute(
            "SELECT robot, contact, onset, host_decided_at FROM contacts"):
        at = arrived.get((robot, contact, onset))
        if at is not None and decided is not None:
            latency.append(at - decided)
    db.close()
    shutil.rmtree(folder, ignore_errors=True)
    latency.sort()
    total = sum(published.values())

    def pct(q: float) -> float | None:
        return round(latency[min(len(latency) - 1, int(q * len(latency)))] * 1e3, 2) \
            if latency else None

    return {"robots": robots, "taxels": taxels, "minutes": minutes, "synchronous": synchronous,
            "rate_per_taxel_minute": rate, "published": total, "held": sum(held.values()),
            "lost": total - sum(held.values()), "per_robot": {"published": published,
                                                              "held": held},
            "acks_timed": len(latency), "p50_visible_ms": pct(0.5), "p99_visible_ms": pct(0.99),
            "max_visible_ms": pct(1.0)}


def build_synthetic(path: Path, voxels: int, seed: int = 0, progress: bool = True) -> None:
    """Fill a new map database with ``voxels`` random voxels (see the module docstring)."""
    from skin.models.materials import hierarchical_answer
    from skin.world.map_store import MapStore, posterior_of

    store = MapStore(path, voxel=0.01, synchronous="OFF")
    rng = np.random.default_rng(seed)
    materials = ["aluminium", "steel", "copper", "glass", "granite", "pine", "oak",
                 "polypropylene", "nylon", "rubber", "foam"]
    # unique cells in 2000 x 2000 x 250 (20 x 20 x 2.5 m)
    cells = np.unique(np.column_stack([rng.integers(0, 2000, int(voxels * 1.05)),
                                       rng.integers(0, 2000, int(voxels * 1.05)),
                                       rng.integers(0, 250, int(voxels * 1.05))]), axis=0)
    cells = cells[rng.permutation(len(cells))[:voxels]]
    db = store.db
    evidence = [json.dumps({m: [math.log(0.6 if m == best else 0.04), 1] for m in materials})
                for best in materials]
    answers = []  # each voxel named as the store names it (one contact's evidence)
    for best in materials:
        post = posterior_of({m: (math.log(0.6 if m == best else 0.04), 1) for m in materials}, 1)
        answers.append((*hierarchical_answer(post, store.threshold),
                        json.dumps({k: round(v, 6) for k, v in post.items()})))
    chunk = 50_000
    now = time.time()
    for start in range(0, len(cells), chunk):
        part = cells[start:start + chunk]
        ids = range(start + 1, start + 1 + len(part))
        db.execute("BEGIN")
        db.executemany("INSERT INTO voxels VALUES (?, ?, ?, ?, 1, 1, ?, ?, 'synthetic', ?, "
                       "?, ?, ?, ?)",
                       [(i, int(x), int(y), int(z), now, now, *answers[i % len(materials)])
                        for i, (x, y, z) in zip(ids, part, strict=True)])
        db.executemany("INSERT INTO evidence VALUES (?, ?)",
                       [(i, evidence[i % len(materials)]) for i in ids])
        if store.rtree:
            db.executemany("INSERT INTO voxel_box VALUES (?, ?, ?, ?, ?, ?, ?)",
                           [(i, int(x), int(x), int(y), int(y), int(z), int(z))
                            for i, (x, y, z) in zip(ids, part, strict=True)])
        db.execute("COMMIT")
        if progress:
            print(f"\rbuilding the map: {start + len(part)} / {len(cells)} voxels", end="",
                  file=sys.stderr, flush=True)
    if progress:
        print(file=sys.stderr)
    store.close()


def query_time(voxels: int = 1_000_000, repeats: int = 20, seed: int = 0,
               db: Path | None = None, progress: bool = True) -> dict[str, Any]:
    """Time 1 m^3 box queries over a synthetic map (see the module docstring)."""
    path = db or Path(tempfile.mkdtemp(prefix="skin-bench-map-")) / "big.sqlite"
    try:
        return _query_time(path, voxels, repeats, seed, progress)
    finally:
        if db is None:
            shutil.rmtree(path.parent, ignore_errors=True)


def _query_time(path: Path, voxels: int, repeats: int, seed: int, progress: bool
                ) -> dict[str, Any]:
    from skin.world.map_store import MapStore

    built = time.perf_counter()
    if not path.exists():
        build_synthetic(path, voxels, seed, progress)
    built = time.perf_counter() - built
    store = MapStore(path)
    rng = random.Random(seed)
    times, objects, found = [], [], []
    for _ in range(repeats):
        x, y, z = rng.uniform(0, 19), rng.uniform(0, 19), rng.uniform(0, 1.5)
        box = (x, y, z, x + 1, y + 1, z + 1)
        t = time.perf_counter()
        text = store.query_json(box)  # the service's reply, built
        times.append(time.perf_counter() - t)
        found.append(len(json.loads(text)))
        x, y, z = rng.uniform(0, 19), rng.uniform(0, 19), rng.uniform(0, 1.5)
        t = time.perf_counter()  # another box: neither finds the other's pages in the cache
        store.query((x, y, z, x + 1, y + 1, z + 1))  # the Python objects (MapStore.query)
        objects.append(time.perf_counter() - t)
    t = time.perf_counter()  # the baseline: the last box by a full pass over the table
    c = store.cells((x, y, z, x + 1, y + 1, z + 1))
    scanned = store.db.execute("SELECT count(*) FROM voxels NOT INDEXED WHERE ix BETWEEN ? AND ? "
                               "AND iy BETWEEN ? AND ? AND iz BETWEEN ? AND ?",
                               (c[0], c[3], c[1], c[4], c[2], c[5])).fetchone()[0]
    scan = time.perf_counter() - t
    n = store.stats()["voxels"]
    index = store.stats()["index"]
    store.close()
    zenoh_times = _over_zenoh(path, seed, repeats)
    times.sort()
    objects.sort()
    return {"voxels": n, "index": index, "build_s": round(built, 1), "repeats": repeats,
            "voxels_per_box_median": sorted(found)[len(found) // 2],
            "query_p50_ms": round(times[len(times) // 2] * 1e3, 2),
            "query_max_ms": round(times[-1] * 1e3, 2),
            "objects_query_p50_ms": round(objects[len(objects) // 2] * 1e3, 2),
            "zenoh_query_p50_ms": round(zenoh_times[len(zenoh_times) // 2] * 1e3, 2)
            if zenoh_times else None,
            "zenoh_query_max_ms": round(zenoh_times[-1] * 1e3, 2) if zenoh_times else None,
            "full_scan_ms": round(scan * 1e3, 2), "scan_matches": scanned,
            "query_p50_over_scan": round(times[len(times) // 2] / scan, 4) if scan else None}


def _over_zenoh(path: Path, seed: int, repeats: int) -> list[float]:
    """Time the same boxes asked of ``skin map serve`` over Zenoh (empty without zenoh)."""
    try:
        import zenoh  # noqa: F401
    except ImportError:
        return []
    from skin.world.shared_map import SharedMap

    port = free_port()
    service = start_service(path, port, "bench")
    rng = random.Random(seed)
    times = []
    try:
        with SharedMap(f"zenoh://bench?connect=tcp/127.0.0.1:{port}") as shared:
            shared.stats()  # the session has found the service
            for _ in range(repeats):
                x, y, z = rng.uniform(0, 19), rng.uniform(0, 19), rng.uniform(0, 1.5)
                t = time.perf_counter()
                shared.query((x, y, z, x + 1, y + 1, z + 1))
                times.append(time.perf_counter() - t)
    finally:
        service.terminate()
        service.wait(timeout=30)
    return sorted(times)


if __name__ == "__main__":
    sys.exit(_main())

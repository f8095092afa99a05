"""Decode throughput of each driver backend, beside the physical frame rate of its bus.

`run` (``skin bench drivers``) measures, for skins of 64 and 1000 taxels sampled at 200 Hz:

- **serial decode**: `StreamDecoder` fed pre-encoded SAMPLE packets in reads of 64 bytes (a
  USB full-speed packet, what a reader polling a 1 Mbaud link often gets) and of 4 KiB (a
  backlog);
- **CAN reassembly**: `CanReassembler.push`, one CAN frame at a time as the CAN driver calls it,
  the nodes of a bus interleaved sample by sample;
- **serial over a pty**: `SerialDriver` on real pseudo-terminals, one per board, a writer thread
  per board writing the packets as fast as the pty takes them, the frames taken with ``recv``
  (clock mapping included);
- **CAN over python-can's virtual bus**: `CanDriver` per bus, the bus's queue filled before
  the clock starts (python-can's virtual ``send`` deep-copies every message, which would
  otherwise be what is measured), the frames taken with ``recv``.

A v1 SAMPLE carries at most 336 taxels and a serial link at 1 Mbaud streams at most
``bus_load(...).max_taxels`` of them at 200 Hz; a CAN node carries at most 128 taxels (fewer
at 500 kbit/s) and a bus has at most 7 nodes. So a skin is cut into boards (and buses) that
each fit at 200 Hz, and the layout is printed: ``7 boards x 142-143``, ``3 buses, 18 nodes x
55-56``. The physical rate is what the links carry at 100 % with those samples (CAN with
worst-case stuffing), summed over the links: decode frames/s over it is the margin, the skin
rate (frames/s over boards) over 200 Hz the margin against the need.

A baseline measured in the same run gives the figures a scale: copying the serial stream
(memcpy), cutting it into the same reads in a Python loop that does nothing else,
``np.frombuffer`` of each packet's taxel words, and `StreamDecoder` on random bytes of the same
length (a 0x00 every 256 bytes on average).
"""

from __future__ import annotations

import math
import os
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from skin.drivers.bus_load import bus_load
from skin.drivers.protocol import (
    MAX_TAXELS,
    CanReassembler,
    StreamDecoder,
    can_sample_frames,
    encode_sample,
)

#: Sample rate the margins are given against, Hz.
RATE_HZ = 200.0
#: Nodes one CAN bus carries (node 7 is the broadcast address).
CAN_NODES = 7
#: Skin sizes and buses measured by default.
SIZES = (64, 1000)
BUSES = (("serial", 1_000_000), ("can", 500_000), ("can", 1_000_000))


@dataclass(frozen=True)
class Wiring:
    """A skin cut into boards that each fit on their link at `RATE_HZ`.

    Attributes
    ----------
    bus : str
        ``"serial"`` or ``"can"``.
    bit_rate : int
        Baud rate or CAN bit rate.
    taxels : int
        Taxels of the skin.
    boards : tuple of int
        Taxels per board (per CAN node).
    links : tuple of tuple of int
        The boards on each link: one per serial link, up to 7 nodes per CAN bus.
    """

    bus: str
    bit_rate: int
    taxels: int
    boards: tuple[int, ...]
    links: tuple[tuple[int, ...], ...]

    def describe(self) -> str:
        """Say how the skin is cut: ``7 boards x 142-143``, ``3 buses, 18 nodes x 55-56``."""
        lo, hi = min(self.boards), max(self.boards)
        size = f"{lo}" if lo == hi else f"{lo}-{hi}"
        if self.bus == "serial":
            return f"{len(self.boards)} board{'s' * (len(self.boards) > 1)} x {size}"
        buses = f"{len(self.links)} bus{'es' * (len(self.links) > 1)}, "
        return f"{buses}{len(self.boards)} node{'s' * (len(self.boards) > 1)} x {size}"

    def physical(self, rate_hz: float = RATE_HZ) -> tuple[float, float]:
        """Return the frames/s all links carry at 100 % and the skin rate they allow, Hz."""
        frames = 0.0
        skin = math.inf
        for link in self.links:
            bits = sum(bus_load(self.bus, self.bit_rate, self.boards[b], rate_hz).bits_per_sample
                       for b in link)
            rate = self.bit_rate / bits  # samples per second of every board on the link
            frames += rate * len(link)
            skin = min(skin, rate)
        return frames, skin


def _split(total: int, parts: int) -> tuple[int, ...]:
    base, extra = divmod(total, parts)
    return tuple(base + (k < extra) for k in range(parts))


def wiring(bus: str, bit_rate: int, taxels: int, rate_hz: float = RATE_HZ) -> Wiring:
    """Cut a skin of ``taxels`` into the fewest boards that each fit their link at ``rate_hz``.

    A board (CAN node) gets at most what one link carries alone at ``rate_hz`` in 95 % of
    its bit rate (`skin.drivers.bus_load`); CAN nodes then share a bus, up to 7, as long as
    their samples together still fit in 95 % of it.
    """
    per = bus_load(bus, bit_rate, 1, rate_hz).max_taxels
    if bus == "serial":
        per = min(per, MAX_TAXELS)
    if per < 1:
        raise ValueError(f"{bus} at {bit_rate} bit/s carries no taxel at {rate_hz:g} Hz")
    boards = _split(taxels, -(-taxels // per))
    if bus == "serial":
        return Wiring(bus, bit_rate, taxels, boards, tuple((b,) for b in range(len(boards))))
    links: list[list[int]] = []
    load = 0.0
    for b, n in enumerate(boards):
        more = bus_load(bus, bit_rate, n, rate_hz).load
        if links and len(links[-1]) < CAN_NODES and load + more <= 0.95:
            links[-1].append(b)
            load += more
        else:
            links.append([b])
            load = more
    return Wiring(bus, bit_rate, taxels, boards, tuple(tuple(link) for link in links))


# ---- streams ----

def _samples(rng: np.random.Generator, n: int, count: int) -> tuple[np.ndarray, np.ndarray]:
    counts = rng.integers(200, 1000, (count, n))
    duty = rng.integers(0, 256, n)
    return counts, duty


def serial_stream(n: int, count: int, seed: int = 0) -> bytes:
    """Return ``count`` SAMPLE packets of ``n`` taxels, as a board sends them."""
    rng = np.random.default_rng(seed)
    counts, duty = _samples(rng, n, count)
    return b"".join(encode_sample(k, k * 5000, counts[k], 24.5, duty, 0x200)
                    for k in range(count))


def can_bus_frames(w: Wiring, link: int, count: int, seed: int = 0) -> list[tuple[int, bytes]]:
    """Return the CAN frames of ``count`` samples of every node on one bus, node after node."""
    rng = np.random.default_rng(seed)
    nodes = w.links[link]
    data = {b: _samples(rng, w.boards[b], count) for b in nodes}
    out = []
    for k in range(count):
        for node, b in enumerate(nodes):
            counts, duty = data[b]
            out += can_sample_frames(node, k, k * 5000, counts[k], 24.5, duty, 0x200)
    return out


# ---- measurements ----

def _row(backend: str, w: Wiring, frames: int, seconds: float, extra: dict | None = None,
         rate_hz: float = RATE_HZ) -> dict:
    physical, skin_max = w.physical(rate_hz)
    fps = frames / seconds
    skin = fps / len(w.boards)
    return {"backend": backend, "bus": w.bus, "bit_rate": w.bit_rate, "taxels": w.taxels,
            "layout": w.describe(), "boards": len(w.boards), "links": len(w.links),
            "taxels_per_board": list(w.boards), "frames": frames,
            "seconds": round(seconds, 4), "frames_per_s": round(fps),
            "taxel_samples_per_s": round(fps * w.taxels / len(w.boards)),
            "us_per_frame": round(1e6 / fps, 2),
            "physical_frames_per_s": round(physical, 1),
            "physical_skin_hz": round(skin_max, 1),
            "margin_physical": round(fps / physical, 1),
            "skin_hz": round(skin, 1), "margin_200hz": round(skin / rate_hz, 1),
            **(extra or {})}


def bench_serial_decode(w: Wiring, count: int, chunk: int) -> dict:
    """`StreamDecoder` per board, fed ``count`` samples in reads of ``chunk`` bytes."""
    streams = [serial_stream(n, count, seed=b) for b, n in enumerate(w.boards)]
    decoders = [StreamDecoder(board=b) for b in range(len(w.boards))]
    got = 0
    started = time.perf_counter()
    for dec, stream in zip(decoders, streams, strict=True):
        for pos in range(0, len(stream), chunk):
            got += len(dec.feed(stream[pos : pos + chunk]))
    seconds = time.perf_counter() - started
    if got != count * len(w.boards):
        raise RuntimeError(f"serial decode lost frames: {got} of {count * len(w.boards)}")
    size = sum(len(s) for s in streams)
    return _row(f"serial decode, {chunk} B reads", w, got, seconds,
                {"bytes_per_s": round(size / seconds), "read_bytes": chunk})


def bench_can_decode(w: Wiring, count: int) -> dict:
    """`CanReassembler` per bus, one CAN frame at a time."""
    buses = [can_bus_frames(w, k, count, seed=k) for k in range(len(w.links))]
    got = 0
    started = time.perf_counter()
    for frames in buses:
        can = CanReassembler()
        push = can.push
        for ident, data in frames:
            if push(ident, data) is not None:
                got += 1
    seconds = time.perf_counter() - started
    if got != count * len(w.boards):
        raise RuntimeError(f"CAN reassembly lost frames: {got} of {count * len(w.boards)}")
    messages = sum(len(f) for f in buses)
    return _row("CAN reassembly", w, got, seconds,
                {"can_frames_per_s": round(messages / seconds)})


def bench_serial_pty(w: Wiring, count: int) -> dict:
    """`SerialDriver` per board on a pseudo-terminal, fed by a writer thread per board."""
    from skin.drivers.serial_port import SerialDriver

    streams = [serial_stream(n, count, seed=b) for b, n in enumerate(w.boards)]
    ptys = []
    drivers = []
    stop = threading.Event()
    try:
        for b in range(len(w.boards)):
            master, slave = os.openpty()
            tty.setraw(slave)
            ptys.append((master, slave))
            drivers.append(SerialDriver(os.ttyname(slave), board=b))

        def write(master: int, data: bytes) -> None:
            view = memoryview(data)
            while view and not stop.is_set():
                view = view[os.write(master, view[:4096]) :]

        threads = [threading.Thread(target=write, args=(m, s), daemon=True)
                   for (m, _), s in zip(ptys, streams, strict=True)]
        want = count * len(w.boards)
        got = 0
        deadline = time.monotonic() + 60.0
        started = time.perf_counter()
        for t in threads:
            t.start()
        while got < want:
            for d in drivers:
                if d.recv(timeout=0.0) is not None:
                    got += 1
            if time.monotonic() > deadline:
                raise RuntimeError(f"pty: {got} of {want} frames after 60 s")
        seconds = time.perf_counter() - started
        bad = sum(d.stats.crc_errors + d.stats.malformed for d in drivers)
    finally:
        stop.set()
        for d in drivers:
            d.close()
        for master, slave in ptys:
            for fd in (master, slave):
                try:
                    os.close(fd)
                except OSError:
                    pass
    return _row("SerialDriver over a pty", w, got, seconds, {"bad_packets": bad})


def bench_can_virtual(w: Wiring, count: int) -> dict:
    """`CanDriver` per bus on python-can's virtual interface, its queue filled beforehand."""
    import can

    from skin.drivers.can_bus import CanDriver

    drivers = []
    senders = []
    try:
        for k in range(len(w.links)):
            channel = f"skin-bench-{os.getpid()}-{k}-{time.monotonic_ns()}"
            drivers.append(CanDriver("virtual", channel))
            senders.append(can.Bus(interface="virtual", channel=channel))
        for k, sender in enumerate(senders):
            for ident, data in can_bus_frames(w, k, count, seed=k):
                sender.send(can.Message(arbitration_id=ident, data=data, is_extended_id=False))
        want = count * len(w.boards)
        got = 0
        started = time.perf_counter()
        while got < want:
            idle = True
            for d in drivers:
                if d.recv(timeout=0.0) is not None:
                    got += 1
                    idle = False
            if idle and time.perf_counter() - started > 60.0:
                raise RuntimeError(f"virtual CAN: {got} of {want} frames")
        seconds = time.perf_counter() - started
    finally:
        for d in drivers:
            d.close()
        for s in senders:
            s.shutdown()
    return _row("CanDriver over virtual CAN", w, got, seconds)


def baseline(count: int = 4000, n: int = 64, chunk: int = 64) -> dict:
    """Measure reference costs on the 64-taxel serial stream, measured in the same run."""
    stream = serial_stream(n, count)
    size = len(stream)
    reps = max(1, (64 << 20) // size)
    started = time.perf_counter()
    for _ in range(reps):
        copy = bytearray(stream)
    memcpy = reps * size / (time.perf_counter() - started)
    del copy
    started = time.perf_counter()
    for pos in range(0, size, chunk):
        stream[pos : pos + chunk]  # the cost of the read loop alone
    loop = size / (time.perf_counter() - started)
    packets = stream.split(b"\x00")[:-1]
    started = time.perf_counter()
    for p in packets:
        np.frombuffer(p, dtype="<u2", count=n, offset=12)
    frombuffer = (time.perf_counter() - started) / len(packets)
    rng = np.random.default_rng(1)
    garbage = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
    dec = StreamDecoder()
    started = time.perf_counter()
    for pos in range(0, size, chunk):
        dec.feed(garbage[pos : pos + chunk])
    junk = size / (time.perf_counter() - started)
    return {"stream_bytes": size, "read_bytes": chunk, "memcpy_bytes_per_s": round(memcpy),
            "read_loop_bytes_per_s": round(loop),
            "frombuffer_us_per_frame": round(frombuffer * 1e6, 3),
            "garbage_decode_bytes_per_s": round(junk),
            "garbage_packets": dec.stats.malformed + dec.stats.crc_errors}


def run(quick: bool = False, sizes: tuple[int, ...] = SIZES, rate_hz: float = RATE_HZ,
        progress: Callable[[str], None] | None = None) -> dict:
    """Measure every backend at every skin size (see the module docstring).

    Parameters
    ----------
    quick : bool
        A smoke run: few samples per measurement (a second or two in all).
    sizes : tuple of int
        Skin sizes, taxels.
    rate_hz : float
        The sample rate the skins are cut for and the margins are given against.
    progress : callable, optional
        Called with the name of each measurement as it starts.

    Returns
    -------
    dict
        ``baseline`` and ``results`` (one row per backend and size: frames/s, taxel-samples/s,
        us per frame, the physical frames/s and the margins).
    """
    # work per measurement: bytes of serial stream, CAN frames, end-to-end frames
    budget = {"decode": 1 << 19, "can": 5_000, "e2e": 400} if quick else \
        {"decode": 8 << 20, "can": 150_000, "e2e": 6_000}
    say = progress or (lambda text: None)
    started = time.monotonic()
    say("baseline")
    doc: dict = {"rate_hz": rate_hz, "quick": quick,
                 "baseline": baseline(400 if quick else 4000)}
    rows = []
    for bus, bit_rate in BUSES:
        for taxels in sizes:
            w = wiring(bus, bit_rate, taxels, rate_hz)
            name = f"{bus} {bit_rate // 1000} kbit/s, {taxels} taxels ({w.describe()})"
            if bus == "serial":
                per_sample = sum(len(encode_sample(0, 0, np.zeros(n, int), None,
                                                   np.zeros(n, int))) for n in w.boards)
                count = max(10, budget["decode"] // per_sample)
                for chunk in (64, 4096):
                    say(f"serial decode, {chunk} B reads: {name}")
                    rows.append(bench_serial_decode(w, count, chunk))
                say(f"SerialDriver over a pty: {name}")
                rows.append(bench_serial_pty(w, max(10, budget["e2e"] // len(w.boards))))
            else:
                per_sample = sum(len(can_bus_frames(w, k, 1)) for k in range(len(w.links)))
                count = max(10, budget["can"] // per_sample)
                say(f"CAN reassembly: {name}")
                rows.append(bench_can_decode(w, count))
                say(f"CanDriver over virtual CAN: {name}")
                rows.append(bench_can_virtual(w, max(10, budget["e2e"] // len(w.boards))))
    base = doc["baseline"]

    def ratio(a: float, b: float) -> float:  # 3 significant figures: a slow run is not 0.0
        return float(f"{a / b:.3g}")

    for r in rows:
        if "bytes_per_s" in r:
            r["x_memcpy"] = ratio(r["bytes_per_s"], base["memcpy_bytes_per_s"])
            r["x_garbage"] = ratio(r["bytes_per_s"], base["garbage_decode_bytes_per_s"])
        r["x_frombuffer"] = ratio(r["us_per_frame"], base["frombuffer_us_per_frame"])
    doc["results"] = rows
    doc["wall_time"] = round(time.monotonic() - started, 2)
    return doc

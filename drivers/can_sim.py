"""A simulated skin as protocol-v1 CAN nodes: the CAN counterpart of `PtySerialDevice`.

`CanSimNode` sends a `SkinSimulator`'s frames on a python-can bus as a real node does
(`skin.drivers.protocol.can_sample_frames`: SYNC, DATA, one DUTY group, STATUS per sample) and
answers the COMMAND frames addressed to it (or to every node) with REPLY frames
(`skin.drivers.protocol.can_reply_frames`), so that ``skin.drivers.open("can://virtual/x")``
or ``can://udp_multicast/<group>`` reads it exactly as it reads a board. A node carries at
most `skin.drivers.protocol.CAN_MAX_TAXELS` taxels: a board with more channels is served by
consecutive nodes, 128 channels each, as several nodes would wire it.

Run it as a separate process (the bus is then shared over UDP multicast)::

    python -m skin.drivers.can_sim --channel 239.74.163.2 --scene default --duration 20

which prints one line, ``ready <url> ...``, once it is on the bus, streams the scene, keeps
answering commands after the last frame, and ends on SIGTERM or Ctrl-C (or ``--linger``
seconds after the last frame).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import signal
import sys
import threading
import time
from collections.abc import Sequence
from typing import Any
from urllib.parse import parse_qs, urlsplit

import numpy as np

from skin._optional import require
from skin.drivers.protocol import (
    ALL_TAXELS,
    CAN_BROADCAST,
    CAN_MAX_TAXELS,
    Ack,
    CanType,
    Command,
    ErrorReply,
    Identity,
    MsgType,
    Reply,
    SelftestResult,
    can_reply_frames,
    can_sample_frames,
    layout_hash,
    parse_command_body,
)
from skin.drivers.sim import SkinSimulator, _Pacer
from skin.errors import DeviceError
from skin.frame import FLAG_STREAMING, TAXEL_STATUS_BITS

#: python-can's default group for ``udp_multicast`` (an IPv6 site-local address).
UDP_MULTICAST_DEFAULT_GROUP = "ff15:7079:7468:6f6e:6465:6d6f:6d63:6173"

BusSpec = str | tuple[str, str] | Any  # a can:// URL, (interface, channel), or a can.BusABC


def parse_can_url(url: str) -> tuple[str, str, dict[str, int]]:
    """Split ``can://<interface>/<channel>?bitrate=N&port=N`` into its parts.

    Returns
    -------
    interface, channel : str
    options : dict of str to int
        ``bitrate`` and ``port`` when given.

    Raises
    ------
    DeviceError
        If the URL is not of that form.
    """
    parts = urlsplit(url)
    channel = parts.path.lstrip("/")
    if parts.scheme != "can" or not parts.netloc or not channel:
        raise DeviceError(f"{url}: write can://<interface>/<channel>, e.g. can://virtual/ch0")
    options = {}
    for key, values in parse_qs(parts.query, keep_blank_values=True).items():
        if key not in ("bitrate", "port"):
            raise DeviceError(f"{url}: unknown option {key!r} (known: bitrate, port)")
        try:
            options[key] = int(values[-1])
        except ValueError:
            raise DeviceError(f"{url}: option {key!r} must be an integer, "
                              f"got {values[-1]!r}") from None
    return parts.netloc, channel, options


@dataclasses.dataclass
class _Node:
    """One node of the simulated board: its number and its slice of the board's channels."""

    number: int
    lo: int
    hi: int
    identity: Identity


class CanSimNode:
    """Serve a simulator's frames as protocol-v1 CAN frames on a python-can bus, like a node.

    Once `start` is called a background thread sends the samples at ``speed`` x real time
    (speed <= 0: as fast as the bus takes them; only for buses that queue without loss, such
    as ``virtual``) and, between them, answers commands as a node does: IDENTIFY with an
    IDENTITY (`SkinSimulator.identity` for the node's channels, transport CAN), STOP and
    START pause and resume the stream (the sequence number goes on where it stopped),
    SET_DUTY sets the duties the samples report, SELFTEST is acknowledged and then reports that
    no heater responded; SET_RATE, SET_SETPOINT and CLEAR_FAULTS are acknowledged and change
    nothing (the scene fixes the rate; the simulator has no heater control). Malformed commands
    get the ERROR of `skin.drivers.protocol.parse_command_body`. COMMAND frames to other nodes
    are ignored. The node keeps answering after its last frame, until closed.

    Parameters
    ----------
    simulator : SkinSimulator
        Source of frames (one board).
    bus : str, (str, str) or can.BusABC
        The bus: a URL (``"can://virtual/ch0"``, ``"can://udp_multicast/239.74.163.2?port=N"``),
        an ``(interface, channel)`` pair, or a bus opened by the caller (who shuts it down).
    node : int
        Node number (0-6) of the board's first 128 channels; a board with more channels also
        takes the next numbers, 128 channels each.
    speed : float
        Pacing relative to real time.
    streaming : bool
        Stream from `start` (True), or wait for a START command, as a node that boots
        stopped.
    bitrate : int, optional
        Bit rate: passed to the bus when it is opened here, and reported in IDENTITY
        (1 Mbit/s if not given).

    Attributes
    ----------
    nodes : list of int
        The node numbers served.
    url : str
        The bus, as ``skin.drivers.open`` takes it (when known).
    frames_sent : int
        Samples sent (each on every node).
    commands : list of Command
        The valid commands received, in order.
    send_errors : int
        CAN messages the bus refused (a full transmit queue); a sample missing one of its
        messages is dropped by the host.
    streaming : bool
        Whether the node streams (START/STOP).
    done : threading.Event
        Set once the last sample is out.
    """

    def __init__(self, simulator: SkinSimulator, bus: BusSpec, node: int = 0,
                 speed: float = 1.0, streaming: bool = True,
                 bitrate: int | None = None) -> None:
        self._can = require("can", "the simulated CAN node")
        self.simulator = simulator
        self.speed = speed
        self.streaming = streaming
        n = simulator._channels
        count = -(-n // CAN_MAX_TAXELS)
        if node < 0 or node + count - 1 >= CAN_BROADCAST:
            raise ValueError(f"{n} channels take {count} node(s) from node {node}; nodes are "
                             f"0-{CAN_BROADCAST - 1} ({CAN_MAX_TAXELS} taxels each)")
        options: dict[str, int] = {} if bitrate is None else {"bitrate": bitrate}
        if isinstance(bus, str | tuple):
            if isinstance(bus, str):
                interface, channel, parsed = parse_can_url(bus)
                options = {**parsed, **options}
            else:
                interface, channel = bus
            query = "&".join(f"{k}={v}" for k, v in sorted(options.items()))
            self.url = f"can://{interface}/{channel}" + (f"?{query}" if query else "")
            try:
                self._bus = self._can.Bus(interface=interface, channel=channel,
                                          can_filters=self._filters(), **options)
            except Exception as exc:  # python-can raises per backend; name the bus either way
                raise DeviceError(f"{self.url}: cannot open the bus ({exc})") from exc
            self._owned = True
        else:
            self._bus = bus
            self._owned = False
            self.url = ""
        self._bitrate = options.get("bitrate", bitrate or 1_000_000)
        self._nodes = []
        for k in range(count):
            lo, hi = k * CAN_MAX_TAXELS, min(n, (k + 1) * CAN_MAX_TAXELS)
            self._nodes.append(_Node(node + k, lo, hi, self._identity(lo, hi)))
        self.nodes = [one.number for one in self._nodes]
        self.frames_sent = 0
        self.send_errors = 0
        self.commands: list[Command] = []
        self.done = threading.Event()
        self._stop = threading.Event()
        self._duty: np.ndarray | None = None  # set by SET_DUTY
        self._thread = threading.Thread(target=self._serve, name="can-skin", daemon=True)

    @staticmethod
    def _filters() -> list[dict[str, int | bool]]:
        """Only COMMAND frames reach the node (in the kernel where the interface can)."""
        return [{"can_id": CanType.COMMAND << 8, "can_mask": 0x700, "extended": False}]

    def _identity(self, lo: int, hi: int) -> Identity:
        sim = self.simulator
        base = sim.identity()
        order = np.argsort(sim._addr)
        addr = sim._addr[order]
        ids = sim.layout.ids[sim._idx[order]][(addr >= lo) & (addr < hi)].tolist()
        return dataclasses.replace(base, transport=1, taxels=hi - lo,
                                   layout_hash=layout_hash(ids),
                                   baud_div=min(0xFFFF, self._bitrate // 1000))

    def start(self) -> None:
        """Start serving: samples (if streaming) and replies to commands.

        The simulation's first chunk is computed here, before the thread starts, so that the
        first samples go out on time rather than in a burst (`SkinSimulator.frames`).
        """
        frames = self.simulator.frames()
        first = next(frames, None)
        self._frames = itertools.chain([] if first is None else [first], frames)
        self._thread.start()

    # ---- sending ----

    def _send(self, frames: Sequence[tuple[int, bytes]]) -> bool:
        for ident, data in frames:
            msg = self._can.Message(arbitration_id=ident, data=data, is_extended_id=False)
            for _ in range(20):  # a full transmit queue empties within a few frame times
                if self._stop.is_set():
                    return False
                try:
                    self._bus.send(msg, timeout=0.05)
                    break
                except self._can.CanError:
                    self.send_errors += 1
                    self._stop.wait(0.002)
        return True

    def _send_sample(self, frame: Any) -> bool:
        duty = frame.duty if self._duty is None else self._duty
        status = frame.status if frame.status is not None else np.zeros_like(frame.counts,
                                                                             np.uint8)
        t_us = round(frame.device_time * 1e6)
        out = []
        for node in self._nodes:
            sl = slice(node.lo, node.hi)
            own = int(np.bitwise_or.reduce(status[sl])) & TAXEL_STATUS_BITS
            flags = (frame.flags & ~TAXEL_STATUS_BITS) | own | FLAG_STREAMING
            force = None if frame.force is None else frame.force[sl]
            out += can_sample_frames(node.number, frame.seq, t_us, frame.counts[sl],
                                     frame.ambient, duty[sl], flags, status[sl], force)
        return self._send(out)

    # ---- commands ----

    def _poll(self, timeout: float) -> None:
        """Answer the commands that arrive within ``timeout`` s (at least one read)."""
        deadline = time.monotonic() + timeout
        while not self._stop.is_set():
            try:
                msg = self._bus.recv(timeout=max(0.0, deadline - time.monotonic()))
            except self._can.CanError:
                msg = None
            if msg is not None:
                self._command(msg)
            elif time.monotonic() >= deadline:
                return

    def _command(self, msg: Any) -> None:
        ident = msg.arbitration_id
        if (msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame
                or ident >> 8 != CanType.COMMAND):
            return
        to = ident >> 5 & 7
        for node in self._nodes:
            if to in (node.number, CAN_BROADCAST):
                for reply in self._answer(node, bytes(msg.data)):
                    self._send(can_reply_frames(node.number, reply.body()))

    def _answer(self, node: _Node, body: bytes) -> list[Reply]:
        n = node.hi - node.lo
        command = parse_command_body(body, n, node.identity.max_rate_hz)
        if isinstance(command, ErrorReply):
            return [command]
        self.commands.append(command)
        ack = Ack(command.token, command.type)
        if command.type == MsgType.IDENTIFY:
            return [dataclasses.replace(node.identity, token=command.token)]
        if command.type in (MsgType.START, MsgType.STOP):
            self.streaming = command.type == MsgType.START
        elif command.type == MsgType.SET_DUTY:
            if self._duty is None:
                self._duty = np.full(self.simulator._channels, 255, dtype=np.uint8)
            if command.taxel == ALL_TAXELS:
                self._duty[node.lo : node.hi] = command.duty
            else:
                self._duty[node.lo + command.taxel] = command.duty
        elif command.type == MsgType.SELFTEST:
            return [ack, SelftestResult(command.token, (0,) * n, (0xFFFF,) * n)]
        return [ack]

    # ---- the thread ----

    def _serve(self) -> None:
        pacer = _Pacer(self.speed)
        try:
            for frame in self._frames:
                while True:
                    paused = time.monotonic()
                    while not self.streaming and not self._stop.is_set():
                        self._poll(0.05)
                    pacer.t0 += time.monotonic() - paused  # a pause does not make a backlog
                    if self.speed > 0:  # answer commands while waiting for the sample's time
                        self._poll(pacer.t0 + frame.device_time / self.speed
                                   - time.monotonic())
                    else:
                        self._poll(0.0)
                    if self.streaming or self._stop.is_set():
                        break
                    # a STOP answered meanwhile: the sample waits for the next START (sent
                    # now, it would follow the acknowledgement of the STOP)
                if self._stop.is_set() or not self._send_sample(frame):
                    return
                self.frames_sent += 1
        finally:
            self.done.set()
        while not self._stop.is_set():  # the last sample is out: answer commands until closed
            self._poll(0.1)

    def close(self) -> None:
        """Stop serving; shut the bus down if it was opened here. Calling it again does nothing."""
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        if self._owned:
            self._bus.shutdown()

    def __enter__(self) -> CanSimNode:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def main(argv: Sequence[str] | None = None) -> int:
    """Run a simulated CAN node until the scene is served and SIGTERM or Ctrl-C arrives."""
    from skin.formats.scene import load_scene

    parser = argparse.ArgumentParser(
        prog="python -m skin.drivers.can_sim",
        description="Serve a simulated skin as protocol-v1 CAN node(s) on a python-can bus.")
    parser.add_argument("--interface", default="udp_multicast",
                        help="python-can interface (default: udp_multicast)")
    parser.add_argument("--channel", default=None,
                        help=f"the interface's channel (udp_multicast: a multicast group, "
                             f"default {UDP_MULTICAST_DEFAULT_GROUP})")
    parser.add_argument("--port", type=int, default=None,
                        help="UDP port (udp_multicast; python-can's default 43113)")
    parser.add_argument("--bitrate", type=int, default=None, help="bit rate, bit/s")
    parser.add_argument("--scene", default="default", help="scene name or file")
    parser.add_argument("--duration", type=float, default=None,
                        help="simulated seconds (the scene's by default)")
    parser.add_argument("--node", type=int, default=0, help="node number 0-6 (default 0)")
    parser.add_argument("--speed", type=float, default=1.0,
                        help="pace, x real time (0: as fast as possible; loses frames on UDP)")
    parser.add_argument("--stopped", action="store_true",
                        help="boot stopped: stream after a START command")
    parser.add_argument("--linger", type=float, default=None,
                        help="exit this many seconds after the last sample (default: run until "
                             "SIGTERM or Ctrl-C)")
    args = parser.parse_args(argv)
    channel = args.channel
    if channel is None:
        if args.interface != "udp_multicast":
            parser.error(f"--channel is required for the {args.interface} interface")
        channel = UDP_MULTICAST_DEFAULT_GROUP
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    try:
        sim = SkinSimulator(load_scene(args.scene), duration=args.duration)
        options = {k: v for k, v in (("bitrate", args.bitrate), ("port", args.port))
                   if v is not None}
        query = "&".join(f"{k}={v}" for k, v in options.items())
        url = f"can://{args.interface}/{channel}" + (f"?{query}" if query else "")
        node = CanSimNode(sim, url, node=args.node, speed=args.speed,
                          streaming=not args.stopped)
    except Exception as exc:
        print(f"can_sim: {exc}", file=sys.stderr)
        return 1
    with node:
        node.start()
        nodes = ", ".join(map(str, node.nodes))
        print(f"ready {node.url} node {nodes}: scene {sim.scene.name!r}, {sim._channels} taxels "
              f"at {sim.sample_rate:g} Hz, {sim.n_samples} samples"
              f"{', stopped' if args.stopped else ''}", flush=True)
        while not stop.is_set() and not node.done.is_set():
            stop.wait(0.1)
        if args.linger is not None:
            stop.wait(args.linger)
        else:
            while not stop.wait(0.2):  # short waits: the signal handler runs between them
                pass
    print(f"can_sim: {node.frames_sent} samples sent, {len(node.commands)} commands answered, "
          f"{node.send_errors} send errors", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

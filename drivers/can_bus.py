"""The CAN driver: protocol-v1 nodes on a CAN bus, through python-can's ``can.Bus``.

Any python-can interface works (``socketcan``, ``pcan``, ``virtual``, ``udp_multicast`` ...):
``can://virtual/ch0``, ``can://socketcan/can0``. Frames of every node are put back together by
`skin.drivers.protocol.CanReassembler`; a node's samples come out as frames of board = node
(unless ``boards`` maps it). Frames that are not ours (extended identifiers, remote and error
frames) are counted as ``malformed`` and skipped, never raised.

Faults: a bus-off (an error frame with SocketCAN's ``CAN_ERR_BUSOFF`` class bit, or the
interface raising) is a fault: with ``reconnect`` the bus is shut down and opened again with
back-off (`skin.drivers.base`). Samples are stamped with python-can's message timestamp
(kernel or hardware time) of their SYNC frame, not the time they are read. A node that has
sent samples and then stays silent for ``silent_after`` seconds is reported
(``health.silent``, a warning) until it speaks again.
"""

from __future__ import annotations

import collections
import dataclasses
import logging
import time

from skin._optional import require
from skin.drivers.base import Driver
from skin.drivers.clock import WALL_OFFSET
from skin.drivers.protocol import (
    CAN_BROADCAST,
    CanReassembler,
    Command,
    ErrorReply,
    Reply,
    can_command_frame,
    can_record,
)
from skin.errors import DeviceError, ProtocolError
from skin.frame import Frame

log = logging.getLogger("skin.drivers")

#: SocketCAN's error class bit for bus-off, in an error frame's identifier (linux/can/error.h).
CAN_ERR_BUSOFF = 0x40


class CanDriver(Driver):
    """Frames from protocol-v1 nodes on one CAN bus.

    Parameters
    ----------
    interface : str
        python-can interface name (``"virtual"``, ``"socketcan"``, ...).
    channel : str
        The interface's channel.
    bitrate : int, optional
        Bit rate, for interfaces that set it.
    boards : dict of int to int, optional
        Board id of each node (the node number by default).
    reconnect : float
        Seconds to keep reopening the bus after a fault (0: raise at once).
    silent_after : float
        Seconds without a frame after which a node that was sending is reported silent.
    port : int, optional
        The IP port, for interfaces that take one (``udp_multicast``: 43113 by default; on
        Linux a bus hears every group joined on its port, so separate buses take separate
        ports).
    context : str, optional
        With no ``interface``: the section of python-can's configuration to use.

    With ``interface`` None the bus comes from python-can's own configuration
    (``can.util.load_config``: the environment's ``CAN_INTERFACE``, ``CAN_CHANNEL``,
    ``CAN_BITRATE``, ``CAN_CONFIG``, then ``~/can.conf``, ``/etc/can.conf``, ``~/.can``,
    ``~/.canrc``), as ``can.Bus()`` would; ``bitrate`` and ``port`` given here win.
    """

    wire = "can"

    def __init__(self, interface: str | None, channel: str | None, bitrate: int | None = None,
                 boards: dict[int, int] | None = None, reconnect: float = 0.0,
                 silent_after: float = 0.5, port: int | None = None,
                 context: str | None = None) -> None:
        super().__init__(reconnect)
        self._can = require("can", "the CAN driver")
        self._kwargs: dict = {}
        if interface is None:
            self._kwargs = self._configured(context)
            interface, channel = self._kwargs["interface"], self._kwargs["channel"]
        self.url = f"can://{interface}/{channel}" + ("" if port is None else f"?port={port}")
        self._kwargs.update({"interface": interface, "channel": channel})
        if bitrate is not None:
            self._kwargs["bitrate"] = bitrate
        if port is not None:
            self._kwargs["port"] = port
        self._bus = self._open()
        self.silent_after = float(silent_after)
        self._last_seen: dict[int, float] = {}
        self._next_check = 0.0
        self._reassembler = CanReassembler(boards)
        self.stats = self._reassembler.stats
        self._frames: collections.deque[Frame] = collections.deque()
        self._token = 0

    def _configured(self, context: str | None) -> dict:
        """Return the bus of python-can's configuration (see the class docstring)."""
        where = "python-can's configuration" + (f" (section {context!r})" if context else "")
        util = self._can.util
        named = {**util.load_file_config(None, context or "default"),
                 **util.load_environment_config(context)}
        if named.get("interface"):
            try:
                config = dict(util.load_config(context=context))
            except Exception as exc:  # python-can raises CanInterfaceNotImplementedError & co
                raise DeviceError(f"can://: {where} cannot be used ({exc})") from None
        else:
            config = {}
        if not config.get("interface"):
            raise DeviceError(f"can://: {where} names no interface: set CAN_INTERFACE and "
                              f"CAN_CHANNEL, or write one of "
                              f"{', '.join(self._can.util.CONFIG_FILES)}; or give the bus as "
                              "can://<interface>/<channel>")
        if config.get("channel") is None:
            raise DeviceError(f"can://: {where} names interface {config['interface']!r} but no "
                              "channel (CAN_CHANNEL)")
        return config

    @property
    def replies(self) -> collections.deque[tuple[int, Reply]]:
        """Replies received and not yet taken, as (node, reply)."""
        return self._reassembler.replies

    def _open(self) -> object:
        try:
            return self._can.Bus(**self._kwargs)
        except Exception as exc:  # python-can raises per backend; name the bus either way
            raise DeviceError(f"{self.url}: cannot open the bus ({exc})") from exc

    def _reopen(self) -> None:
        self._bus = self._open()
        self._last_seen.clear()

    def _read(self, timeout: float | None) -> None:
        try:
            msg = self._bus.recv(timeout=timeout)
        except (self._can.CanError, OSError) as exc:
            raise DeviceError(f"{self.url}: the bus failed ({exc}); "
                              f"{self.stats.frames} frames were received before") from exc
        now = time.monotonic()
        if now >= self._next_check:
            self._check_silent(now)
        if msg is None:
            return
        self.stats.bytes += len(msg.data)
        arrival = self._arrival(msg.timestamp, time.monotonic())
        if self.tap is not None:
            self.tap(arrival, can_record(msg.arbitration_id, bytes(msg.data),
                                                  msg.is_extended_id or msg.is_remote_frame
                                                  or msg.is_error_frame))
        if msg.is_error_frame and msg.arbitration_id & CAN_ERR_BUSOFF:
            raise DeviceError(f"{self.url}: the controller went bus-off; "
                              f"{self.stats.frames} frames were received before")
        if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            self.stats.malformed += 1
            return
        frame = self._reassembler.push(msg.arbitration_id, bytes(msg.data), arrival)
        if frame is not None:
            self._frames.append(frame)
            self._last_seen[frame.board] = now
            if frame.board in self.health.silent:
                self.health.silent.discard(frame.board)
                log.warning("%s: board %d is sending again", self.url, frame.board)

    @staticmethod
    def _arrival(timestamp: float, now: float) -> float:
        """Host arrival time (``time.monotonic`` clock) of a message stamped ``timestamp``.

        python-can stamps messages with Unix time, taken by the kernel or the interface's
        hardware where it can: the better arrival time. A stamp that cannot be Unix time
        (some interfaces count from their own start) is not used: the time of reading is.
        """
        arrival = timestamp - WALL_OFFSET
        return arrival if now - 60.0 < arrival <= now + 0.01 else now

    def _check_silent(self, now: float) -> None:
        """Report the boards that were sending and have been silent for ``silent_after``."""
        self._next_check = now + self.silent_after / 4
        for board, seen in self._last_seen.items():
            if now - seen > self.silent_after and board not in self.health.silent:
                self.health.silent.add(board)
                log.warning("%s: board %d silent for %.2f s", self.url, board, now - seen)

    def _recv_internal(self, timeout: float | None) -> Frame | None:
        if not self._frames:
            self._read(timeout)
        return self._frames.popleft() if self._frames else None

    def send(self, command: Command, node: int = CAN_BROADCAST) -> Command:
        """Send a command to a node (`CAN_BROADCAST`: every node); token 0 gets the next one."""
        if command.token == 0:
            self._token = self._token % 255 + 1
            command = dataclasses.replace(command, token=self._token)
        if not self.health.connected:
            raise DeviceError(f"{self.url}: disconnected ({self.health.last_fault})")
        ident, data = can_command_frame(node, command)
        try:
            self._bus.send(self._can.Message(arbitration_id=ident, data=data,
                                             is_extended_id=False))
        except self._can.CanError as exc:
            raise DeviceError(f"{self.url}: cannot send ({exc})") from exc
        return command

    def request(self, command: Command, node: int, timeout: float = 1.0) -> Reply:
        """Send a command to one node and wait for its reply, keeping every frame meanwhile.

        Raises
        ------
        ProtocolError
            If the node answers with an ERROR, or not within ``timeout`` seconds.
        """
        sent = self.send(command, node)
        deadline = time.monotonic() + timeout
        while True:
            for item in self.replies:
                who, reply = item
                if who == node and reply.token == sent.token:
                    self.replies.remove(item)
                    if isinstance(reply, ErrorReply):
                        raise ProtocolError(f"{self.url}: node {node} refused command "
                                            f"0x{sent.type:02X}: {reply.name}, "
                                            f"detail {reply.detail}")
                    return reply
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ProtocolError(f"{self.url}: no reply from node {node} to command "
                                    f"0x{sent.type:02X} within {timeout:g} s")
            self._read(min(remaining, 0.05))

    def _close_internal(self) -> None:
        self._bus.shutdown()

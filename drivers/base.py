"""The base class every driver shares (after python-can's ``BusABC``).

A backend implements ``_recv_internal(timeout)`` (and ``_reopen`` if it can reconnect); the
base gives ``recv``, iteration, an idempotent ``close``, context management, statistics, the
mapping of device time to host time (`skin.drivers.clock`) and recovery from faults.

Faults: when the backend raises `DeviceError` (a USB board unplugged, a CAN bus gone bus-off),
a driver opened with ``reconnect`` > 0 reports it (``health``, a warning on the
``skin.drivers`` logger), closes the backend and reopens it with exponential back-off
(0.05 s doubling to 2 s), for up to ``reconnect`` seconds, after which `recv` raises. While it
waits, `recv` returns None at its timeout, as on a quiet link. The frames decoded before the
fault were already handed over or wait in the driver's queue: none is lost.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from skin.drivers.clock import ClockMap
from skin.drivers.protocol import Command, LinkStats
from skin.errors import DeviceError
from skin.frame import Frame

log = logging.getLogger("skin.drivers")

#: Back-off between reconnection attempts: first and longest wait, s.
BACKOFF = (0.05, 2.0)


@dataclass
class Health:
    """A driver's faults and recoveries.

    Attributes
    ----------
    connected : bool
        False from a fault until the device is back.
    faults : int
        Faults seen (the device vanished, the bus went bus-off ...).
    reconnects : int
        Successful reconnections.
    attempts : int
        Reconnection attempts, failed ones included.
    last_fault : str
        The last fault's message ("" if none).
    overflows : int
        Frames dropped because a bounded queue was full (`skin.drivers.reader`).
    silent : set of int
        Boards (CAN nodes) that stopped sending and have not come back.
    """

    connected: bool = True
    faults: int = 0
    reconnects: int = 0
    attempts: int = 0
    last_fault: str = ""
    overflows: int = 0
    silent: set[int] = dataclasses.field(default_factory=set)


class Driver:
    """A source of `Frame` objects.

    Attributes
    ----------
    stats : LinkStats
        Counts of bytes, frames and errors seen.
    health : Health
        Faults, reconnections and queue overflows.
    clocks : dict of int to ClockMap
        Per board, the map from device time to host time that stamps ``Frame.host_time``.
    finished : bool
        True once a finite source (a simulation, a replay) has delivered its last frame.
    reconnect : float
        Seconds to keep trying to reopen the device after a fault (0: raise at once).
    wire : str
        The format of the bytes handed to ``tap``: ``"serial"`` (the serial protocol's byte
        stream) or ``"can"`` (one record per CAN message: `skin.drivers.protocol.can_record`).
    tap : callable or None
        If set, called as ``tap(host_time, data)`` with every chunk of raw bytes the driver
        takes off its wire, before decoding (``host_time``: ``time.monotonic()`` on arrival).
        Recordings use it (`skin.drivers.recording`).
    """

    url: str = ""
    wire: str = "serial"

    def __init__(self, reconnect: float = 0.0) -> None:
        if reconnect < 0:
            raise ValueError(f"reconnect must be >= 0 s, got {reconnect}")
        self.stats = LinkStats()
        self.health = Health()
        self.clocks: dict[int, ClockMap] = {}
        self.finished = False
        self.reconnect = float(reconnect)
        self.tap: Callable[[float, bytes], None] | None = None
        self._closed = False
        self._fault_at = 0.0
        self._next_attempt = 0.0
        self._backoff = BACKOFF[0]

    def _recv_internal(self, timeout: float | None) -> Frame | None:
        """Return the next frame, or None if none arrived within ``timeout`` seconds."""
        raise NotImplementedError

    def _close_internal(self) -> None:
        """Release the backend's resources."""

    def _reopen(self) -> None:
        """Open the backend again after a fault (`_close_internal` was called)."""
        raise DeviceError(f"{self.url}: this source cannot reconnect")

    def send(self, command: Command) -> Command:
        """Send a command to the device; return it as sent (with its token).

        Raises
        ------
        DeviceError
            If the source takes no commands (a replay), or the device cannot be written.
        """
        raise DeviceError(f"{self.url}: this source takes no commands")

    def recv(self, timeout: float | None = None) -> Frame | None:
        """Return the next frame, or None if none arrived within ``timeout`` seconds.

        ``timeout`` None waits until a frame comes or the source is finished.

        Raises
        ------
        DeviceError
            If the driver is closed, or the device failed and did not come back within
            ``reconnect`` seconds.
        """
        if self._closed:
            raise DeviceError(f"{self.url}: the driver is closed")
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = 0.1 if deadline is None else max(0.0, deadline - time.monotonic())
            frame = None
            if self.health.connected or self._try_reopen(left):
                try:
                    frame = self._recv_internal(left)
                except DeviceError as exc:
                    self._fault(exc)
                    continue
            if frame is not None:
                return self._stamp(frame)
            if self.finished or (deadline is not None and time.monotonic() >= deadline):
                return None

    def _stamp(self, frame: Frame) -> Frame:
        """Give ``frame`` its host sampling time from its board's clock map.

        The frame's device time comes out unwrapped (the board's u32 microsecond clock wraps
        every 71.6 min; the pipeline's time axis must not jump back).
        """
        clock = self.clocks.get(frame.board)
        if clock is None:
            clock = self.clocks[frame.board] = ClockMap()
        host = clock.update(frame.device_time, frame.host_time)
        return dataclasses.replace(frame, device_time=clock.device_time, host_time=host)

    def _fault(self, exc: DeviceError) -> None:
        """Record a fault; close the backend; raise unless reconnecting is allowed."""
        self.health.faults += 1
        self.health.last_fault = str(exc)
        if self.reconnect <= 0:
            raise exc
        log.warning("%s; reconnecting for up to %g s", exc, self.reconnect)
        self.health.connected = False
        self._fault_at = self._next_attempt = time.monotonic()
        self._backoff = BACKOFF[0]
        try:
            self._close_internal()
        except Exception:  # the backend is already broken; closing it is best effort
            pass

    def _try_reopen(self, timeout: float) -> bool:
        """Try to reopen the backend within ``timeout`` s, with back-off; True once it is back.

        Raises
        ------
        DeviceError
            Once ``reconnect`` seconds have passed since the fault.
        """
        deadline = time.monotonic() + timeout
        while True:
            now = time.monotonic()
            if now - self._fault_at > self.reconnect:
                raise DeviceError(f"{self.health.last_fault}; not back within "
                                  f"{self.reconnect:g} s ({self.health.attempts} attempts); "
                                  f"{self.stats.frames} frames were received before")
            if now >= self._next_attempt:
                self.health.attempts += 1
                try:
                    self._reopen()
                except DeviceError:
                    self._next_attempt = now + self._backoff
                    self._backoff = min(2 * self._backoff, BACKOFF[1])
                else:
                    self.health.connected = True
                    self.health.reconnects += 1
                    log.warning("%s: reconnected after %.2f s", self.url, now - self._fault_at)
                    return True
            wait = min(self._next_attempt, deadline, self._fault_at + self.reconnect) - now
            if time.monotonic() >= deadline:
                return False
            time.sleep(max(0.0, min(wait, deadline - time.monotonic())) + 1e-4)

    def __iter__(self) -> Iterator[Frame]:
        """Yield frames until the source is finished or the driver is closed."""
        while not self._closed:
            frame = self.recv(timeout=0.1)
            if frame is not None:
                yield frame
            elif self.finished:
                return

    def close(self) -> None:
        """Release the device; calling it again does nothing."""
        if not self._closed:
            self._closed = True
            try:
                self._close_internal()
            except Exception:
                if self.health.connected:  # after a fault the backend may be half closed
                    raise

    def __enter__(self) -> Driver:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass

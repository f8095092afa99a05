"""The base class every driver shares (after python-can's ``BusABC``).

A backend implements ``_recv_internal(timeout)``; the base gives ``recv``, iteration, an
idempotent ``close``, context management and statistics.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

from skin.drivers.protocol import Command, LinkStats
from skin.errors import DeviceError
from skin.frame import Frame


class Driver:
    """A source of `Frame` objects.

    Attributes
    ----------
    stats : LinkStats
        Counts of bytes, frames and errors seen.
    finished : bool
        True once a finite source (a simulation, a replay) has delivered its last frame.
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

    def __init__(self) -> None:
        self.stats = LinkStats()
        self.finished = False
        self.tap: Callable[[float, bytes], None] | None = None
        self._closed = False

    def _recv_internal(self, timeout: float | None) -> Frame | None:
        """Return the next frame, or None if none arrived within ``timeout`` seconds."""
        raise NotImplementedError

    def _close_internal(self) -> None:
        """Release the backend's resources."""

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

        Raises
        ------
        DeviceError
            If the driver is closed.
        """
        if self._closed:
            raise DeviceError(f"{self.url}: the driver is closed")
        if timeout is None:
            while (frame := self._recv_internal(0.1)) is None and not self.finished:
                pass
            return frame
        deadline = time.monotonic() + timeout
        while True:
            frame = self._recv_internal(max(0.0, deadline - time.monotonic()))
            if frame is not None or self.finished or time.monotonic() >= deadline:
                return frame

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
            self._close_internal()

    def __enter__(self) -> Driver:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass

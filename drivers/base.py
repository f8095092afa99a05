"""The base class every driver shares (after python-can's ``BusABC``).

A backend implements ``_recv_internal(timeout)``; the base gives ``recv``, iteration, an
idempotent ``close``, context management and statistics.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

from skin.drivers.protocol import LinkStats
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
    """

    url: str = ""

    def __init__(self) -> None:
        self.stats = LinkStats()
        self.finished = False
        self._closed = False

    def _recv_internal(self, timeout: float | None) -> Frame | None:
        """Return the next frame, or None if none arrived within ``timeout`` seconds."""
        raise NotImplementedError

    def _close_internal(self) -> None:
        """Release the backend's resources."""

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

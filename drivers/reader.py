"""A background reader: one or more drivers read in threads into one bounded queue.

`BackgroundReader` keeps reading while the caller is busy (classifying, rendering), so the
operating system's buffers never overflow unseen. Its queue is bounded: when the caller falls
``maxsize`` frames behind, the oldest frame is dropped and counted (``health.overflows``, a
warning on the ``skin.drivers`` logger at most once a second), and the pipeline sees the gap
in the sequence numbers. Several drivers (boards on several ports or buses) read into the same
queue make one skin; every frame's ``host_time`` is on the host clock
(`skin.drivers.clock`), the time base they share.

A driver that fails for good (its ``reconnect`` time ran out) raises its `DeviceError` from
`BackgroundReader.recv` once, after every frame it delivered before; the other drivers go on.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence

from skin.drivers.base import Driver, Health
from skin.drivers.clock import ClockMap
from skin.drivers.protocol import Command, LinkStats
from skin.errors import DeviceError
from skin.frame import Frame

log = logging.getLogger("skin.drivers")


class BackgroundReader(Driver):
    """Read ``drivers`` in background threads into one bounded queue.

    Parameters
    ----------
    drivers : Driver or sequence of Driver
        The sources; closed with the reader.
    maxsize : int
        Frames the queue holds before the oldest is dropped.

    Notes
    -----
    Commands go through `send` (to every driver). A driver's own ``request`` reads its
    device and must not be used while the reader runs; wait for replies in its ``replies``.
    """

    def __init__(self, drivers: Driver | Sequence[Driver], maxsize: int = 2000) -> None:
        self.drivers = [drivers] if isinstance(drivers, Driver) else list(drivers)
        if not self.drivers:
            raise ValueError("a BackgroundReader needs at least one driver")
        if maxsize < 1:
            raise ValueError(f"maxsize must be >= 1, got {maxsize}")
        super().__init__()
        self.url = " + ".join(d.url for d in self.drivers)
        self.wire = self.drivers[0].wire
        self.maxsize = int(maxsize)
        self._queue: deque[Frame | DeviceError] = deque()
        self._cond = threading.Condition()
        self._running = len(self.drivers)
        self._overflows = 0
        self._warned_at = -1.0
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._read, args=(d,), daemon=True,
                                          name=f"skin-reader-{k}")
                         for k, d in enumerate(self.drivers)]
        for thread in self._threads:
            thread.start()

    # the statistics are those of the drivers read, summed over them
    @property
    def stats(self) -> LinkStats:  # type: ignore[override]
        """The drivers' link statistics, summed."""
        total = LinkStats()
        for f in dataclasses.fields(LinkStats):
            setattr(total, f.name, sum(getattr(d.stats, f.name) for d in self.drivers))
        return total

    @stats.setter
    def stats(self, value: LinkStats) -> None:  # the base class's __init__ sets it
        pass

    @property
    def health(self) -> Health:  # type: ignore[override]
        """The drivers' health, summed; ``overflows`` counts this reader's queue."""
        hs = [d.health for d in self.drivers]
        return Health(all(h.connected for h in hs), sum(h.faults for h in hs),
                      sum(h.reconnects for h in hs), sum(h.attempts for h in hs),
                      next((h.last_fault for h in reversed(hs) if h.last_fault), ""),
                      self._overflows + sum(h.overflows for h in hs),
                      set().union(*(h.silent for h in hs)))

    @health.setter
    def health(self, value: Health) -> None:
        pass

    @property
    def clocks(self) -> dict[int, ClockMap]:  # type: ignore[override]
        """Every board's clock map."""
        return {b: c for d in self.drivers for b, c in d.clocks.items()}

    @clocks.setter
    def clocks(self, value: dict[int, ClockMap]) -> None:
        pass

    @property
    def tap(self) -> Callable[[float, bytes], None] | None:  # type: ignore[override]
        """The first driver's tap; setting it sets every driver's."""
        return self.drivers[0].tap

    @tap.setter
    def tap(self, value: Callable[[float, bytes], None] | None) -> None:
        for d in self.drivers:
            d.tap = value

    @property
    def pending(self) -> int:
        """Frames waiting in the queue."""
        return len(self._queue)

    def _read(self, driver: Driver) -> None:
        try:
            while not self._stop.is_set():
                frame = driver.recv(timeout=0.05)
                if frame is None:
                    if driver.finished:
                        return
                    continue
                self._put(frame)
        except DeviceError as exc:
            if not self._stop.is_set():
                self._put(exc)
        finally:
            with self._cond:
                self._running -= 1
                self._cond.notify_all()

    def _put(self, item: Frame | DeviceError) -> None:
        with self._cond:
            if len(self._queue) >= self.maxsize:
                # drop the oldest frame; an error waiting in the queue is never dropped
                k = next((i for i, x in enumerate(self._queue) if isinstance(x, Frame)), None)
                if k is not None:
                    del self._queue[k]
                    self._overflows += 1
                    now = time.monotonic()
                    if now - self._warned_at >= 1.0:
                        self._warned_at = now
                        log.warning("%s: the reader's queue is full (%d frames): %d frames "
                                    "dropped so far", self.url, self.maxsize, self._overflows)
            self._queue.append(item)
            self._cond.notify()

    def recv(self, timeout: float | None = None) -> Frame | None:
        """Return the next frame, or None if none came within ``timeout`` s (see the class).

        Raises
        ------
        DeviceError
            If the reader is closed, or a driver failed for good (once, in its place among
            the frames).
        """
        if self._closed:
            raise DeviceError(f"{self.url}: the driver is closed")
        with self._cond:
            self._cond.wait_for(lambda: self._queue or not self._running, timeout)
            if self._queue:
                item = self._queue.popleft()
                if isinstance(item, DeviceError):
                    raise item
                return item
            self.finished = self._running == 0 and all(d.finished for d in self.drivers)
            return None

    def send(self, command: Command) -> Command:
        """Send ``command`` to every driver; return it as the last one sent it."""
        if self._closed:
            raise DeviceError(f"{self.url}: the driver is closed")
        for d in self.drivers:
            sent = d.send(command)
        return sent

    def _close_internal(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=2.0)
        for d in self.drivers:
            d.close()

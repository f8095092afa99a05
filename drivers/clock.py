"""Device time -> host time: an offset and drift estimate per board.

A board stamps each sample with its own clock (u32 microseconds, wrapping every 71.6 min); the
host sees the frame some transport delay later. The delay is never negative, so the lower
envelope of ``host arrival - device time`` is the clock offset, and its slope the drift of the
board's crystal against the host clock. `ClockMap` keeps the smallest difference in each block
of device time (1 s by default), fits a line through the last blocks' minima, and lowers it
until no minimum lies below it: host time at sampling = device time + offset + drift x device
time. Several boards and buses mapped this way share one time base, the host's
``time.monotonic()``.

Every driver maps the frames it gives (`skin.drivers.base.Driver.recv`): ``Frame.host_time``
is the host time at which the sample was taken, estimated; ``Driver.clocks`` holds the maps.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import numpy as np

#: The device clock's period: u32 microseconds.
DEVICE_WRAP = 2.0**32 * 1e-6


@dataclass(frozen=True)
class ClockEstimate:
    """A board's clock as estimated so far.

    Attributes
    ----------
    offset : float
        Host time minus device time at device time 0 (unwrapped), s.
    drift : float
        Relative rate error of the device clock against the host's (1e-6 = 1 ppm).
    latency : float
        Median transport delay of the last block above the envelope, s.
    blocks : int
        Blocks the estimate rests on.
    resets : int
        Times the device clock jumped backwards (a board reset) and the estimate restarted.
    """

    offset: float
    drift: float
    latency: float
    blocks: int
    resets: int


class ClockMap:
    """Map one board's device time to host time (see the module docstring).

    Parameters
    ----------
    block : float
        Device seconds per block whose smallest delay is kept.
    blocks : int
        Blocks the line is fitted through (the estimate follows a drift that changes over
        about ``block * blocks`` seconds).
    """

    def __init__(self, block: float = 1.0, blocks: int = 60) -> None:
        if block <= 0 or blocks < 2:
            raise ValueError(f"block must be > 0 s and blocks >= 2, got {block}, {blocks}")
        self.block = float(block)
        self._minima: deque[tuple[float, float]] = deque(maxlen=blocks)
        self._resets = 0
        self.device_time = float("nan")  # the last device time taken, unwrapped, s
        self._restart()

    def _restart(self) -> None:
        self._minima.clear()
        self._wraps = 0
        self._last_raw: float | None = None
        self._block_start = 0.0
        self._block_min = (np.inf, 0.0)  # (delay, device time)
        self._delays: list[float] = []
        self._offset = np.nan
        self._drift = 0.0
        self._latency = 0.0

    def unwrap(self, device_time: float) -> float:
        """Return ``device_time`` with the u32 wraps counted (advances the map's state)."""
        if self._last_raw is not None:
            step = device_time - self._last_raw
            if step < -DEVICE_WRAP / 2:
                self._wraps += 1
            elif step < -1.0:  # backwards by more than a second, not a wrap: the board reset
                self._resets += 1
                self._restart()
        self._last_raw = device_time
        return device_time + self._wraps * DEVICE_WRAP

    def update(self, device_time: float, host_arrival: float) -> float:
        """Take one frame's device time and host arrival time; return its host sampling time."""
        t = self.device_time = self.unwrap(device_time)
        delay = host_arrival - t
        if np.isnan(self._offset):
            self._offset, self._block_start = delay, t
        if t - self._block_start >= self.block:
            self._close_block()
            self._block_start = t
        if delay < self._block_min[0]:
            self._block_min = (delay, t)
        self._delays.append(delay)
        if not self._minima:  # first block: the smallest delay so far, no drift yet
            self._offset = min(self._offset, delay)
        return t + self._offset + self._drift * t

    def _close_block(self) -> None:
        self._minima.append((self._block_min[1], self._block_min[0]))
        times = np.array([m[0] for m in self._minima])
        lows = np.array([m[1] for m in self._minima])
        if len(self._minima) >= 3:
            centre = times.mean()
            slope = float(np.polyfit(times - centre, lows, 1)[0])
        else:
            slope = 0.0
        # lower the line until no block's minimum lies below it
        offset = float(np.min(lows - slope * times))
        self._latency = float(np.median(self._delays)) - (offset + slope * self._block_min[1])
        self._offset, self._drift = offset, slope
        self._block_min = (np.inf, 0.0)
        self._delays = []

    def to_host(self, device_time: float) -> float:
        """Return the host time of an (unwrapped) device time, by the current estimate."""
        return device_time + self._offset + self._drift * device_time

    @property
    def estimate(self) -> ClockEstimate:
        """The current estimate."""
        return ClockEstimate(float(self._offset), self._drift, self._latency,
                             len(self._minima), self._resets)


#: Unix time minus ``time.monotonic()``, taken once when this module is first imported: host
#: times (``Frame.host_time``) plus this are wall-clock (Unix) times, s.
WALL_OFFSET = time.time() - time.monotonic()


def wall_time(host_time: float) -> float:
    """Return the Unix time of a host time (``time.monotonic`` clock), s."""
    return host_time + WALL_OFFSET

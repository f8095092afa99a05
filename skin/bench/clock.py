"""``skin bench clock``: how well device time is mapped to host time, against the cost.

A board's clock runs ``drift`` fast against the host's; each frame reaches the host after a
transport delay drawn from a scenario (a USB serial link, a loaded host with stalls, CAN over
UDP). Each method maps every frame's device time to a host time; its error is taken against
the true host time at sampling plus the smallest delay (a constant no method can observe), once
the first ``settle`` seconds have passed. Methods: the arrival time itself (what a driver
without a clock map gives), a running minimum offset without drift, and `ClockMap` with blocks
of 0.5, 1 and 2 s.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from skin.drivers.clock import ClockMap


@dataclass(frozen=True)
class Scenario:
    """A transport: the smallest delay, an exponential jitter, and stalls."""

    name: str
    floor: float  # s
    jitter: float  # s, mean of the exponential part
    stall_every: float  # s between stalls (0: none)
    stall: float  # s, longest stall


SCENARIOS = (
    Scenario("USB serial", 1e-3, 0.5e-3, 0.0, 0.0),
    Scenario("loaded host", 1e-3, 5e-3, 2.0, 0.05),
    Scenario("CAN over UDP", 0.5e-3, 1e-3, 10.0, 0.02),
)


def _arrivals(s: Scenario, t: np.ndarray, true: np.ndarray, rng: np.random.Generator
              ) -> np.ndarray:
    arrival = true + s.floor + rng.exponential(s.jitter, len(t))
    if s.stall_every > 0:  # a stalled reader gets the frames of the stall at its end
        for start in np.arange(rng.uniform(0, s.stall_every), t[-1], s.stall_every):
            end = start + rng.uniform(0.2, 1.0) * s.stall
            inside = (true >= start) & (true < end)
            arrival[inside] = np.maximum(arrival[inside], end)
    return np.maximum.accumulate(arrival)  # a link delivers in order


def _running_min(t: np.ndarray, arrival: np.ndarray) -> np.ndarray:
    offset = np.inf
    out = np.empty_like(t)
    for k in range(len(t)):
        offset = min(offset, arrival[k] - t[k])
        out[k] = t[k] + offset
    return out


def _clock_map(block: float) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    def run(t: np.ndarray, arrival: np.ndarray) -> np.ndarray:
        clock = ClockMap(block=block)
        return np.array([clock.update(d, h) for d, h in zip(t, arrival, strict=True)])
    return run


METHODS: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    "arrival time": lambda t, arrival: arrival.copy(),
    "running min, no drift": _running_min,
    "ClockMap, 0.5 s blocks": _clock_map(0.5),
    "ClockMap, 1 s blocks": _clock_map(1.0),
    "ClockMap, 2 s blocks": _clock_map(2.0),
}


def run(seconds: float = 300.0, drift: float = 50e-6, rate: float = 200.0,
        settle: float = 10.0, seed: int = 0,
        progress: Callable[[str], None] | None = None) -> dict:
    """Run every method on every scenario; return a JSON-ready document."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds * rate)) / rate
    true = 12345.0 + t * (1 + drift)
    rows = []
    for s in SCENARIOS:
        arrival = _arrivals(s, t, true, rng)
        late = t >= settle
        for name, method in METHODS.items():
            if progress is not None:
                progress(f"{s.name}: {name}")
            t0 = time.perf_counter()
            mapped = method(t, arrival)
            cost = (time.perf_counter() - t0) / len(t)
            err = mapped[late] - true[late] - s.floor
            slope = np.polyfit(t[late], mapped[late] - t[late], 1)[0]
            rows.append({
                "scenario": s.name, "method": name,
                "median_error_ms": round(float(np.median(err)) * 1e3, 4),
                "p99_abs_error_ms": round(float(np.percentile(np.abs(err), 99)) * 1e3, 4),
                "max_abs_error_ms": round(float(np.abs(err).max()) * 1e3, 4),
                "step_jitter_ms": round(float(np.std(np.diff(mapped[late]))) * 1e3, 4),
                "drift_error_ppm": round(float(slope - drift) * 1e6, 3),
                "us_per_frame": round(cost * 1e6, 3),
            })
    return {"seconds": seconds, "rate_hz": rate, "drift_ppm": drift * 1e6, "settle_s": settle,
            "scenarios": [s.__dict__ for s in SCENARIOS], "rows": rows}

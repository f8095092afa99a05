"""The onset detector's events and state on fixed streams, pinned (tests/data/onset_pinned.json).

A speed-up of `skin.stream.onset.OnsetDetector` must not change a single event: each preset's
detector (the board common mode as it runs by default: the gated form on the constant-power
presets; the loop form on pid-logger, opt-in; and none) runs over a fixed stream of three
boards (16, 16 and 8 taxels) that passes through every branch the common mode has - each
taxel warming up its own way, the room falling and rising on every board, touches of a few
taxels, of all but one of a board and during the room's fall, a gust over one board, a hole
longer than the warm-up and one of a sample - and its events (every field, floats exactly) and
final state (every array, byte for byte) are those pinned.

The stream is plain numpy (a seeded generator), not the library's simulator: a change there
does not move it. A change meant to move the detector's events re-pins them::

    python tests/test_onset_pinned.py --write

and says so in its commit (the file was last written on 2026-11-29, when the heater duty
case came and the state's ``t_switch`` became ``duty_lag``: the other cases' events unchanged).
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from skin.models.sensors import load_sensor
from skin.stream.onset import OnsetDetector

PINNED = Path(__file__).with_name("data") / "onset_pinned.json"
BOARDS = (16, 16, 8)
#: case: (preset, common_mode, simulated seconds): about 8000 samples each
CASES = {
    "paper": ("paper", None, 40.0),
    "low-cost": ("low-cost", None, 200.0),
    "fast-film": ("fast-film", None, 8.0),
    "pid-logger-loop": ("pid-logger", True, 160.0),
    "paper-off": ("paper", False, 40.0),
    "paper-duty": ("paper", None, 40.0),
}
#: The cases whose detector is told the heater duty (`heater_duty`), as the pipeline tells it.
WITH_DUTY = {"paper-duty"}


def stream(preset: str, seconds: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Return the fixed stream of a preset: times (n,), readings (n, 40), deg C, NaN holes.

    Every change is set in the sensor's own units (its heated rise, its response time, its
    delivered noise), at fractions ``f`` of the stream, so every preset meets each branch.
    """
    s = load_sensor(preset)
    rng = np.random.default_rng(seed)
    fs = s.sample_rate
    t = np.arange(round(seconds * fs)) / fs
    f = t / seconds
    n = sum(BOARDS)
    rise = s.heated_rise
    heated = 25.0 + rise
    # each taxel warming up its own way over the first tenth
    y = heated - (0.02 * rise * rng.uniform(0.5, 1.5, n)
                  * np.exp(-f[:, None] / rng.uniform(0.02, 0.06, n)))
    # the room: a fall of 4 % of the rise from 0.35, faster and faster, half of it back from 0.7
    room = -0.04 * rise * (np.clip((f - 0.35) / 0.1, 0.0, 1.0) ** 3
                           - 0.5 * np.clip((f - 0.7) / 0.2, 0.0, 1.0))
    y += room[:, None]
    tau = s.response_time / np.log(2.0)

    def touch(taxels: list[int], at: float, depth: float = 0.25) -> None:
        """A touch from ``at`` for 6 % of the stream: a first-order fall and recovery."""
        t0, t1 = at * seconds, (at + 0.06) * seconds
        inside = (t >= t0) & (t < t1)
        after = t >= t1
        fall = depth * rise * -np.expm1(-(t - t0) / tau)
        shape = np.where(inside, fall, 0.0)
        shape[after] = fall[after][0] * np.exp(-(t[after] - t1) / tau) if after.any() else 0.0
        for k in taxels:
            y[:, k] -= shape * rng.uniform(0.7, 1.3)

    touch([2, 3, 4], 0.2)  # a few taxels of board 0
    touch([k for k in range(16, 32) if k != 23], 0.5)  # all but one of board 1
    touch([33], 0.42)  # board 2, during the room's fall
    # a gust over board 1: 2 % of the rise, a raised cosine over 2 % of the stream
    g = np.clip((f - 0.85) / 0.02, 0.0, 1.0)
    y[:, 16:32] -= (0.02 * rise * 0.5 * (1.0 - np.cos(2.0 * np.pi * g)))[:, None]
    y += rng.normal(0.0, s.delivered_noise(heated), y.shape)
    y[(f >= 0.6) & (f < 0.63), 5] = np.nan  # a hole longer than the warm-up
    y[np.flatnonzero(f >= 0.3)[:2], 20] = np.nan  # and one of two samples
    return t, y


def heater_duty(t: np.ndarray) -> np.ndarray:
    """Return the duty of the duty cases, (n, 40): board 0 steps down from 1 to 0.7 at 15 %
    of the stream (before its touch), board 1 up from 0.85 to 1 at 40 %, board 2 not known
    (NaN) but for a stretch from 60 % to 80 %: every branch of the heater's allowance."""
    f = t / t[-1]
    duty = np.ones((t.size, sum(BOARDS)))
    duty[f >= 0.15, :16] = 0.7
    duty[f < 0.4, 16:32] = 0.85
    duty[:, 32:] = np.nan
    duty[(f >= 0.6) & (f < 0.8), 32:] = 0.5
    return duty


def detector(case: str) -> OnsetDetector:
    """Return the case's detector: the preset, its common mode setting, three boards."""
    preset, common_mode, _ = CASES[case]
    boards = np.repeat(np.arange(len(BOARDS)), BOARDS)
    return OnsetDetector(boards.size, sensor=preset, boards=boards, common_mode=common_mode)


def run(case: str, chunk: int, in_place: bool = False) -> tuple[list[list], str, int]:
    """Return the case's events (each as a list of its fields), its final state's hash and
    after how many chunks some taxel's board common mode was not 0 (``in_place``: the
    state updated in place, as the pipeline runs it)."""
    d = detector(case)
    t, y = stream(CASES[case][0], CASES[case][2])
    duty = heater_duty(t) if case in WITH_DUTY else None
    state = d.initial_state()
    events = []
    engaged = 0
    for k in range(0, t.size, chunk):
        got, state = d.process(t[k:k + chunk], y[k:k + chunk], state, in_place=in_place,
                               duty=None if duty is None else duty[k:k + chunk])
        events += got
        engaged += bool(np.any(state.common != 0.0))
    rows = [[e.kind, e.taxel, e.time, e.detected_at, e.baseline, e.slope, e.direction,
             e.channel] for e in events]
    digest = hashlib.sha256()
    for name, value in sorted(vars(state).items()):
        digest.update(name.encode() + np.ascontiguousarray(value).tobytes())
    return rows, digest.hexdigest(), engaged


def _same(rows: list[list], pinned: list[list]) -> bool:
    """Whether two event lists are equal, floats to the bit (NaN equal to NaN)."""
    return json.dumps(rows) == json.dumps(pinned)


@pytest.mark.parametrize("case", list(CASES))
def test_the_events_and_state_are_the_pinned_ones_sample_by_sample(case):
    pinned = json.loads(PINNED.read_text())[case]
    rows, digest, engaged = run(case, 1)  # as the pipeline calls it: a sample at a time
    assert len(rows) == len(pinned["events"])
    assert _same(rows, pinned["events"])
    assert digest == pinned["state_sha256"]
    # worth pinning: onsets and releases, and the common mode engaged where it runs (some
    # taxel's ``common`` not 0: the room taken off), not where it is off
    assert {r[0] for r in rows} == {"onset", "release"}
    assert (engaged > 0) == (CASES[case][1] is not False), engaged


@pytest.mark.parametrize("case", ["low-cost", "pid-logger-loop", "paper-duty"])
def test_chunks_give_the_pinned_events(case):
    pinned = json.loads(PINNED.read_text())[case]
    for chunk in (13, 10**6):
        rows, digest, _ = run(case, chunk)
        assert _same(rows, pinned["events"]) and digest == pinned["state_sha256"], chunk


@pytest.mark.parametrize("case", ["paper", "pid-logger-loop"])
def test_a_state_updated_in_place_gives_the_pinned_events(case):
    # the pipeline's way (`Pipeline._onsets`): no copy of the state per call
    pinned = json.loads(PINNED.read_text())[case]
    for chunk in (1, 13):
        rows, digest, _ = run(case, chunk, in_place=True)
        assert _same(rows, pinned["events"]) and digest == pinned["state_sha256"], chunk


def main(argv: list[str]) -> int:
    """``--write``: pin the events and state this code gives (a change meant to move them)."""
    if argv != ["--write"]:
        print(__doc__)
        return 2
    doc = {}
    for case in CASES:
        rows, digest, _ = run(case, 1)
        doc[case] = {"events": rows, "state_sha256": digest}
        print(f"{case}: {len(rows)} events")
    PINNED.parent.mkdir(exist_ok=True)
    PINNED.write_text(json.dumps(doc, indent=0) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

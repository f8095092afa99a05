"""One contact per touch, two for two touches: the tracker on simulated scenes.

`skin bench tracking`: `run` plays random scenes on the arm through the pipeline (the
simulator, the onset detector of the scene's sensor, the tracker; a cheap classifier, since
the labels do not matter here) and compares the contacts with the touches:

- single touches of 2-4 neighbouring taxels (their onsets are dated in any order: taxels
  diagonal to each other can start apart and be bridged later);
- pairs of touches on neighbouring taxels that must stay two: a second object touching
  while the first still does, 0.6-1.5 s (stretched with the sensor's response time) later,
  and a short tap followed, after it ended, by a touch of the neighbour.

Figures per scene: touches, whole (one contact holding exactly the touch's taxels), split
(the touch's taxels spread over several contacts), merged (one contact holding taxels of two
touches), missed (no contact on the touch's taxels), other contacts (on no touch's taxels,
or later pieces: false alarms and artefacts), and the tracker's cost: microseconds per
sample, and the stage's share of the pipeline's time.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from skin.formats.scene import Scene, parse_scene


def random_scene(pairs: int = 20, sensor: str = "", seed: int = 0) -> Scene:
    """Build a scene on the arm: ``pairs`` rounds, each a single touch, then a pair, 4 s apart.

    Each round is a touch of 2-4 neighbouring taxels (one object), then two touches of
    neighbouring taxels by two objects: a second touch while the first lasts (0.6-1.5 s
    after it, times the sensor's slowness), or a 0.2-0.3 s tap and, after it, a touch of a
    neighbour (every other round). Rounds are 9 s apart (the slow presets recover in time).
    """
    from skin.formats.layout import load_layout
    from skin.models.sensors import SensorDescription, load_sensor

    stretch = 1.0
    if sensor:
        stretch = max(1.0, load_sensor(sensor).response_time / SensorDescription().response_time)
    rng = np.random.default_rng([seed, 17])
    layout = load_layout("arm")
    near = layout.neighbour_lists()
    period = 9.0 * stretch
    lines = ['name = "tracking"', 'layout = "arm"', f"duration = {period * pairs + 2.0}",
             "ambient = 25.0", "noise = 0.02", f"seed = {seed}",
             "initial_temperature = [31.0, 38.9]"]
    if sensor:
        lines.append(f'sensor = "{sensor}"')
    for m in ("glass", "pine", "aluminium", "neoprene"):
        lines += ["[[objects]]", f'name = "{m}"', f'material = "{m}"']

    def touch(obj: str, ids: list[int], start: float, duration: float) -> None:
        nonlocal lines
        lines += ["[[touches]]", f'object = "{obj}"', f"taxels = {ids}",
                  f"start = {start:.3f}", f"duration = {duration:.3f}"]

    for k in range(pairs):
        t0 = 1.0 + period * k
        # a single touch: a connected group of 2-4 taxels
        group = [int(rng.integers(len(layout)))]
        size = int(rng.integers(2, 5))
        while len(group) < size:
            free = [int(j) for g in group for j in near[g] if int(j) not in group]
            group.append(free[int(rng.integers(len(free)))])
        touch("pine", [int(layout.ids[j]) for j in group], t0, float(rng.uniform(0.8, 2.0)))
        # a pair: two objects on two neighbouring taxels
        a = int(rng.integers(len(layout)))
        b = int(near[a][int(rng.integers(len(near[a])))])
        t1 = t0 + 3.5 * stretch
        if k % 2 == 0:  # the second while the first lasts
            late = float(rng.uniform(0.6, 1.5)) * stretch
            touch("glass", [int(layout.ids[a])], t1, late + 1.5 * stretch)
            touch("aluminium", [int(layout.ids[b])], t1 + late, 1.5 * stretch)
        else:  # a tap, then the neighbour after it ended
            tap = float(rng.uniform(0.2, 0.3)) * stretch
            touch("glass", [int(layout.ids[a])], t1, tap)
            touch("neoprene", [int(layout.ids[b])], t1 + tap + 0.05 * stretch, 1.5 * stretch)
    return parse_scene("\n".join(lines) + "\n", "tracking-scene.toml")


def score(scene: Scene, contacts: list[dict[int, float]]) -> dict:
    """Compare final contacts (each taxel id's onset, s) with the scene's touches.

    A contact is on a touch when one of its taxels is the touch's with an onset between 0.5 s
    before the touch's start and the touch's end (a release artefact of the same taxel later,
    or a later touch of it, is not).
    """
    on = [[i for i, taxels in enumerate(contacts)
           if any(k in touch.taxels and touch.start - 0.5 <= t < touch.end
                  for k, t in taxels.items())]
          for touch in scene.touches]
    owners: dict[int, int] = {}
    for pieces in on:
        for i in pieces:
            owners[i] = owners.get(i, 0) + 1
    whole = sum(len(p) == 1 and sorted(contacts[p[0]]) == sorted(t.taxels)
                and owners[p[0]] == 1 for p, t in zip(on, scene.touches, strict=True))
    return {
        "touches": len(scene.touches),
        "whole": int(whole),
        "split": sum(len(p) > 1 for p in on),
        "merged": sum(n > 1 for n in owners.values()),
        "missed": sum(not p for p in on),
        "other_contacts": len(contacts) - len(owners),
    }


def play(scene: Scene) -> dict:
    """Run the scene through the pipeline; return `score`'s figures and the tracker's cost."""
    from skin.drivers.sim import SkinSimulator
    from skin.models import HistogramClassifier
    from skin.stream.pipeline import Pipeline

    pipeline = Pipeline(scene.layout, HistogramClassifier(scene.layout))
    results, block = [], []
    for frame in SkinSimulator(scene).frames():  # generated in chunks: memory stays bounded
        block.append(frame)
        if len(block) == 20:  # as `skin run` takes them
            results += pipeline.process(block)
            block = []
    results += pipeline.process(block) + pipeline.flush()
    results = [r for r in results if r.contact.final]
    out = score(scene, [{w.taxel: w.onset for w in r.contact.windows} for r in results])
    stats = pipeline.stats
    track = stats.seconds["track"]
    total = sum(stats.seconds.values())
    out.update({
        "samples": int(stats.samples),
        "onsets": int(stats.onsets),
        "track_us_per_sample": round(1e6 * track / max(stats.samples, 1), 2),
        "track_share": round(track / total, 4) if total > 0 else 0.0,
    })
    return out


def run(pairs: int, sensors: list[str], seeds: list[int],
        progress: Callable[[int, int], None] | None = None) -> list[dict]:
    """Play one scene per sensor and seed; return a row of figures each."""
    rows = []
    todo = [(s, k) for s in sensors for k in seeds]
    for n, (sensor, seed) in enumerate(todo):
        scene = random_scene(pairs, "" if sensor == "paper" else sensor, seed)
        rows.append({"sensor": sensor, "seed": seed, **play(scene)})
        if progress is not None:
            progress(n + 1, len(todo))
    return rows

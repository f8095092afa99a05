"""What reading each sensor preset as it reads is worth to the joint classifier.

For each preset, a simulated trial dataset (the paper's 11 materials, every contact seen by
two heated taxels of a unit, `skin.models.trials.simulate_trials`) is classified by
`skin.models.joint.JointContactModel`, told each channel's true taxel constants, twice:

- ``paper_model``: the readings taken for eq. 5 of the constants (the classifier before
  sensor descriptions reached it);
- ``forward``: each channel read as its sensor reads (`skin.models.sensors.contact_basis`:
  heater switched off or left on at contact, PID loop, lag, smoothing).

The window is read from the recorded onset (the contact within +-10 ms of it) for each
duration; ``object_std`` is the prior on the object's temperature about ambient (10 K: the
classifier's default, which two taxels a few tenths of a kelvin apart barely narrow; 1 K:
objects known to rest near room temperature). The cost is CPU ms per contact, both methods in
the same run. On the paper preset both are the same computation.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np


def run(presets: Sequence[str], seeds: Sequence[int], durations: Sequence[float],
        trials: int = 8, object_std: float = 10.0,
        progress: Callable[[int, int], None] | None = None) -> list[dict]:
    """Return one row per preset, seed and duration (module docstring)."""
    from skin.bench.ceiling import _joint_log_evidence
    from skin.models import load_materials
    from skin.models.joint import JointContactModel
    from skin.models.sensors import load_sensor
    from skin.models.trials import PAPER_MATERIALS, Protocol, simulate_trials

    table = load_materials()
    rows = []
    done = 0
    for name in presets:
        sensor = load_sensor(name)
        for seed in seeds:
            data = simulate_trials([table[m] for m in PAPER_MATERIALS],
                                   replace(Protocol(), trials=trials,
                                           duration=max(durations) + 0.2,
                                           channels=("heated", "heated")),
                                   sensor=sensor, seed=seed)
            truth = np.searchsorted(data.classes, data.label)
            model = JointContactModel([table[c] for c in data.classes], noise=0.1,
                                      object_std=object_std,
                                      onset_shifts=(-0.01, -0.005, 0.0, 0.005, 0.01))
            for read in (None, sensor):  # warm up: imports and the first basis not timed
                _joint_log_evidence(model, data.subset(np.arange(1)), min(durations), "true",
                                    None, read)
            for d in durations:
                row = {"sensor": sensor.name, "seed": seed, "duration": d,
                       "contacts": len(data), "object_std": object_std}
                for key, read in (("paper_model", None), ("forward", sensor)):
                    started = time.process_time()
                    ev, _ = _joint_log_evidence(model, data, d, "true", None, read)
                    row[key] = round(float(np.mean(np.argmax(ev, axis=1) == truth)), 4)
                    row[f"{key}_ms"] = round(
                        (time.process_time() - started) / len(data) * 1e3, 3)
                rows.append(row)
                done += 1
                if progress is not None:
                    progress(done, len(presets) * len(seeds) * len(durations))
    return rows

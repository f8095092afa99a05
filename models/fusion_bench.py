"""Cold and warm objects touched by one or several taxels: what sharing the object buys.

Each simulated contact is one object (a material of the list, its temperature drawn around
ambient) touched by ``n`` taxels at once. Every taxel has its own constants (+-10 % about the
paper's), its own contact conductance from the material's range, its own onset error
(+-10 ms), and reads through the paper's divider and 10-bit ADC. The taxels start either at
one temperature (a uniformly heated skin) or staggered over 31-40 C (heater setpoints that
alternate across the skin). `skin.models.joint.JointContactModel` names the material twice
on the same contacts: knowing only the paper's nominal constants, and knowing each taxel's
own (as per-taxel calibration would give). Accuracy and cost per contact are reported for
each object temperature range, arrangement and contact duration.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from skin.models.joint import JointContactModel
from skin.models.materials import Material
from skin.models.physics import SensorConstants, contact_trace
from skin.models.trials import _adc

#: (label, taxels, how their initial temperatures are set)
ARRANGEMENTS = (("1 taxel", 1, "one"), ("2 taxels, one temperature", 2, "one"),
                ("2 taxels, 31 and 40 C", 2, "staggered"),
                ("4 taxels, 31-40 C", 4, "staggered"))
FS = 200.0


def _initial(n: int, mode: str, rng: np.random.Generator) -> np.ndarray:
    if mode == "staggered":
        return np.linspace(31.0, 40.0, n) + rng.normal(0.0, 0.3, n)
    return rng.uniform(30.0, 40.0) + rng.normal(0.0, 0.2, n)


def simulate_contact(material: Material, n: int, mode: str, duration: float,
                     object_offset: tuple[float, float], ambient: float,
                     rng: np.random.Generator,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[SensorConstants]]:
    """One object touched by ``n`` taxels.

    Returns sample times, readings (n, samples), initial temperatures (n,) and each taxel's
    constants.
    """
    base = SensorConstants()
    t = np.arange(1, round(duration * FS) + 1) / FS
    t0 = _initial(n, mode, rng)
    t_obj = ambient + rng.uniform(*object_offset)
    lo, hi = np.log10(material.conductance_range)
    y = np.empty((n, t.size))
    sensors = []
    for i in range(n):
        f = 1.0 + rng.uniform(-0.1, 0.1, 3)
        s = SensorConstants(depth=base.depth * f[0], diffusivity=base.diffusivity * f[1],
                            conductivity=base.conductivity * f[2])
        since = t - rng.uniform(-0.01, 0.01)
        h = 10 ** rng.uniform(lo, hi)
        y[i] = contact_trace(since, t0[i], t_obj, material.effusivity, s, h)
        sensors.append(s)
    return t, _adc(y, rng, 0.5), t0, sensors


def run(materials: Sequence[Material], trials: int = 40,
        durations: Sequence[float] = (0.5, 1.0, 2.5),
        offsets: Sequence[tuple[float, float]] = ((0.0, 0.0), (-8.0, 8.0)),
        ambient: float = 25.0, seed: int = 0,
        progress: Callable[[int, int], None] | None = None) -> list[dict]:
    """Accuracy and cost of the joint model per object temperature, arrangement and duration.

    Parameters
    ----------
    materials : sequence of Material
        The objects, each touched ``trials`` times per case.
    trials : int
        Contacts per material and case.
    durations : sequence of float
        Contact durations, s.
    offsets : sequence of tuple
        Ranges of the object's temperature above ambient, K.
    ambient : float
        Room temperature, deg C.
    seed : int
        Seed of the scene.
    progress : callable, optional
        Called as ``progress(done, total)`` per case.

    Returns
    -------
    list of dict
        One row per (offset, arrangement, duration): ``accuracy`` (nominal constants),
        ``accuracy_calibrated`` (each taxel's own) and ``ms_per_contact``.
    """
    model = JointContactModel(materials)
    rng = np.random.default_rng(seed)
    cases = [(o, a, d) for o in offsets for a in ARRANGEMENTS for d in durations]
    rows = []
    for k, (offset, (label, n, mode), duration) in enumerate(cases):
        right, right_cal, spent = 0, 0, 0.0
        for m in materials:
            for _ in range(trials):
                t, y, t0, sensors = simulate_contact(m, n, mode, duration, offset, ambient, rng)
                started = time.perf_counter()
                p = model.probabilities(t, y, t0, ambient)
                spent += time.perf_counter() - started
                right += model.classes[int(np.argmax(p))] == m.name
                p = model.probabilities(t, y, t0, ambient, sensors)
                right_cal += model.classes[int(np.argmax(p))] == m.name
        total = trials * len(materials)
        rows.append({"object_offset": list(offset), "arrangement": label, "taxels": n,
                     "initial": mode, "duration": duration,
                     "accuracy": round(right / total, 4),
                     "accuracy_calibrated": round(right_cal / total, 4),
                     "ms_per_contact": round(1e3 * spent / total, 3)})
        if progress is not None:
            progress(k + 1, len(cases))
    return rows

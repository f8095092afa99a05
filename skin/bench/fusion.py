"""Cold and warm objects touched by one or several taxels: what sharing the object buys.

Each simulated contact is one object (a material of the list, its temperature drawn around
ambient) touched by ``n`` taxels at once. Every taxel has its own constants (+-10 % about the
paper's), its own contact conductance from the material's range, its own onset error
(+-10 ms), and reads through the paper's divider and 10-bit ADC. The taxels start either at
one temperature (a uniformly heated skin) or staggered over 31-40 C (heater setpoints that
alternate across the skin). The taxels come from a pool of 16, each calibrated once from four
simulated contacts with water (`skin.models.sensor_fit`). `skin.models.joint.JointContactModel`
names the material three times on the same contacts: knowing only the paper's nominal
constants, with each taxel's fitted constants, and with its true ones. Accuracy and cost per
contact are reported for each object temperature range, arrangement and contact duration.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from skin.models.joint import JointContactModel
from skin.models.materials import Material
from skin.models.physics import SensorConstants, contact_trace
from skin.models.trials import adc_readings, spread_sensors

#: (label, taxels, how their initial temperatures are set)
ARRANGEMENTS = (("1 taxel", 1, "one"), ("2 taxels, one temperature", 2, "one"),
                ("2 taxels, 31 and 40 C", 2, "staggered"),
                ("4 taxels, 31-40 C", 4, "staggered"))
FS = 200.0


def _initial(n: int, mode: str, rng: np.random.Generator) -> np.ndarray:
    if mode == "staggered":
        return np.linspace(31.0, 40.0, n) + rng.normal(0.0, 0.3, n)
    return rng.uniform(30.0, 40.0) + rng.normal(0.0, 0.2, n)


def calibrate_pool(pool: list[SensorConstants], rng: np.random.Generator,
                   reference: str = "water", contacts: int = 4) -> list[SensorConstants]:
    """Fit each taxel's constants as a calibration would find them.

    Four simulated contacts with ``reference`` at 25 C per taxel (`skin.models.sensor_fit`).
    """
    from skin.models.materials import load_materials
    from skin.models.sensor_fit import fit_sensor_constants, reference_contacts

    ref = load_materials()[reference]
    fitted = []
    for s in pool:
        t, y, ts, to = reference_contacts(s, ref, rng, contacts, duration=2.0, fs=FS)
        fitted.append(fit_sensor_constants(t, y, ts, to, ref.effusivity,
                                           conductance_range=ref.conductance_range).sensor)
    return fitted


def simulate_contact(material: Material, taxels: list[SensorConstants], mode: str,
                     duration: float, object_offset: tuple[float, float], ambient: float,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One object touched by ``taxels`` at once.

    Returns sample times, readings (n, samples) and initial temperatures (n,).
    """
    n = len(taxels)
    t = np.arange(1, round(duration * FS) + 1) / FS
    t0 = _initial(n, mode, rng)
    t_obj = ambient + rng.uniform(*object_offset)
    lo, hi = np.log10(material.conductance_range)
    y = np.empty((n, t.size))
    for i, s in enumerate(taxels):
        since = t - rng.uniform(-0.01, 0.01)
        h = 10 ** rng.uniform(lo, hi)
        y[i] = contact_trace(since, t0[i], t_obj, material.effusivity, s, h)
    return t, adc_readings(y, rng, 0.5), t0


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
        ``accuracy_fitted`` (each taxel's constants fitted from four simulated contacts with
        water), ``accuracy_calibrated`` (each taxel's true constants) and ``ms_per_contact``.
    """
    model = JointContactModel(materials)
    rng = np.random.default_rng(seed)
    pool = spread_sensors(16, 0.1, rng)
    fitted = calibrate_pool(pool, rng)
    cases = [(o, a, d) for o in offsets for a in ARRANGEMENTS for d in durations]
    rows = []
    for k, (offset, (label, n, mode), duration) in enumerate(cases):
        right = {"nominal": 0, "fitted": 0, "true": 0}
        spent = 0.0
        for m in materials:
            for _ in range(trials):
                pick = rng.choice(len(pool), n, replace=False)
                t, y, t0 = simulate_contact(m, [pool[i] for i in pick], mode, duration,
                                            offset, ambient, rng)
                for kind, sensors in (("nominal", None), ("fitted", [fitted[i] for i in pick]),
                                      ("true", [pool[i] for i in pick])):
                    started = time.perf_counter()
                    p = model.probabilities(t, y, t0, ambient, sensors)
                    if kind == "nominal":
                        spent += time.perf_counter() - started
                    right[kind] += model.classes[int(np.argmax(p))] == m.name
        total = trials * len(materials)
        rows.append({"object_offset": list(offset), "arrangement": label, "taxels": n,
                     "initial": mode, "duration": duration,
                     "accuracy": round(right["nominal"] / total, 4),
                     "accuracy_fitted": round(right["fitted"] / total, 4),
                     "accuracy_calibrated": round(right["true"] / total, 4),
                     "ms_per_contact": round(1e3 * spent / total, 3)})
        if progress is not None:
            progress(k + 1, len(cases))
    return rows

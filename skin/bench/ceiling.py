"""How well any classifier could do on a simulated dataset: the known-nuisance ceiling.

A simulated trial's reading is fixed by its material's effusivity and by nuisances the
classifier is not told: the sensor's and the object's temperatures, the contact conductance,
the true contact instant and the taxel's own constants. `simulate_trials` stores all of them
(the ``true_`` keys). Given them, the only unknowns left are the material and the ADC noise,
so the material whose closed-form trace lies nearest the reading (least squares, which is the
maximum-likelihood choice under Gaussian noise) is the best any method can do *from the
trace*. Its accuracy is a practical ceiling for classifiers that must infer the nuisances:
when it is below a target, no method meets the target on that dataset.

It is not a strict Bayes bound: it ignores what the nuisances' distributions say about the
class (a metal's contact conductance range, a rubber's conforming gap), which a learned
classifier may exploit.

``unknown`` takes nuisances back out of what the ceiling is told, to show what each one is
worth: ``"object_temperature"`` (fitted per material by least squares, the reading being
linear in it: what one heated channel can do when the object may be warmed by earlier
touches) and ``"taxel_constants"`` (the sensor's nominal constants instead of the taxel's
own: a skin without commissioning).
"""

from __future__ import annotations

import numpy as np

from skin.errors import SkinError
from skin.formats.dataset import TrialSet

NEEDED = ("true_onset_time", "true_sensor_temperature", "true_object_temperature",
          "true_effusivity", "true_conductance", "true_sensor_depth",
          "true_sensor_diffusivity", "true_sensor_conductivity")


UNKNOWABLE = ("object_temperature", "taxel_constants")


def check_ceiling(data: TrialSet) -> None:
    """Raise SkinError unless `known_nuisance_ceiling` applies to ``data``.

    It needs the simulation's ``true_`` keys and readings that are the closed form of the
    taxel's constants: a sensor with a heater on during contact, a lag, a PID loop or
    smoothing reads otherwise, and a least-squares choice against the closed form would
    report a meaningless figure (0.09 on the low-cost preset, below chance).
    """
    missing = [k for k in NEEDED if k not in data.extra]
    if missing:
        raise SkinError(f"{data.source}: the ceiling needs a simulated dataset; missing "
                        f"{', '.join(missing)}")
    closed = data.extra.get("true_closed_form")
    if closed is not None and not np.all(closed):
        raise SkinError(f"{data.source}: the ceiling models the paper's reading chain "
                        f"(constant heater, no lag, no smoothing); this dataset's sensor reads "
                        f"otherwise, so it has no ceiling")
    if np.any(data.onset < 0):
        raise SkinError(f"{data.source}: the ceiling needs recorded onsets, not -1")


def known_nuisance_ceiling(data: TrialSet, duration: float,
                           unknown: tuple[str, ...] = ()) -> dict:
    """Accuracy of the least-squares material choice when every nuisance is known.

    Parameters
    ----------
    data : TrialSet
        A simulated dataset with the ``true_`` keys (`skin.models.trials.simulate_trials`)
        and recorded onsets.
    duration : float
        Seconds after the recorded onset that are used.
    unknown : tuple of str
        Nuisances not told (`UNKNOWABLE`; module docstring).

    Returns
    -------
    dict
        ``method`` (``"ceiling"``), ``duration``, ``accuracy``, ``recall`` per class,
        ``confusion`` and ``classes`` (the layout `skin evaluate` reports).

    Raises
    ------
    SkinError
        If a ``true_`` key is missing (recorded data has no ceiling), the dataset's sensor
        does not read the closed form (`check_ceiling`), or the window does not fit the
        recording.
    """
    from skin.models.physics import SensorConstants, contact_trace

    bad = [u for u in unknown if u not in UNKNOWABLE]
    if bad:
        raise ValueError(f"unknown nuisance(s) {', '.join(bad)}; choose from "
                         f"{', '.join(UNKNOWABLE)}")
    check_ceiling(data)
    x = data.extra
    classes = data.classes
    effusivity = np.array([x["true_effusivity"][data.label == c][0] for c in classes])
    n = round(duration * data.fs)
    if n < 1 or np.any(data.onset + n > data.temperature.shape[-1]):
        raise SkinError(f"{data.source}: a {duration} s window does not fit the recording")
    k = np.arange(n)
    nominal = SensorConstants()
    chosen = np.empty(len(data), dtype=int)
    for i in range(len(data)):
        sensor = nominal if "taxel_constants" in unknown else SensorConstants(
            depth=float(x["true_sensor_depth"][i]),
            diffusivity=float(x["true_sensor_diffusivity"][i]),
            conductivity=float(x["true_sensor_conductivity"][i]))
        since = (data.onset[i] + k) / data.fs - x["true_onset_time"][i]
        t0 = x["true_sensor_temperature"][i]
        observed = data.primary[i, data.onset[i] + k]
        if "object_temperature" in unknown:
            # reading = T0 + (T_obj - T0) phi: the best T_obj per material, closed form
            phi = contact_trace(since[None, :], 0.0, 1.0, effusivity[:, None], sensor,
                                x["true_conductance"][i])
            d = observed[None, :] - t0
            gain = np.sum(d * phi, axis=1) / np.maximum(np.sum(phi * phi, axis=1), 1e-300)
            predicted = t0 + gain[:, None] * phi
        else:
            predicted = contact_trace(since[None, :], t0, x["true_object_temperature"][i],
                                      effusivity[:, None], sensor, x["true_conductance"][i])
        chosen[i] = int(np.argmin(np.sum((predicted - observed) ** 2, axis=1)))
    truth = np.searchsorted(classes, data.label)
    conf = np.zeros((len(classes), len(classes)), dtype=int)
    np.add.at(conf, (truth, chosen), 1)
    recall = conf.diagonal() / np.maximum(conf.sum(axis=1), 1)
    return {"method": "ceiling" + "".join(f" ({u} unknown)" for u in unknown), "duration": duration,
            "accuracy": round(float(np.mean(chosen == truth)), 4), "accuracy_std": 0.0,
            "recall": {c: round(float(r), 4) for c, r in zip(classes, recall, strict=True)},
            "confusion": conf.tolist(), "classes": classes, "unknown": 0,
            "fit_ms_per_trial": 0.0, "predict_ms_per_trial": 0.0}

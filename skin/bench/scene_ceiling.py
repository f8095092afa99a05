"""What a scene's touches allow: the known-nuisance ceiling per touch, and the run's gap to it.

`skin bench scene --ceiling` plays a scene as `skin run` does (`skin.bench.scene_seeds.play`)
and, beside what the run named, asks of each of the scene's touches:

- **ceiling**: would the best classifier told everything but the material name it right?
  Each touch becomes one simulated trial (`touch_trial`: one channel per taxel of the touch,
  the readings the pipeline saw from the true contact instant to the touch's end, at most
  the run's window; each taxel's true starting temperature and constants, the object's
  temperature, the perfect contact) and `skin.bench.ceiling.known_nuisance_ceiling` chooses
  among the run's classifier's candidates (least squares against the closed form: the
  maximum-likelihood choice under Gaussian noise; the ADC's quantisation, 0.05-0.08 K a
  count against 0.02 K of noise, makes it a near-optimal choice rather than a strict bound).
- **the gap, in steps** (`ladder`): the run's own classifier (a fresh copy, the contacts
  replayed in the run's order, so that its learned object prior grows as in the run) fed
  contacts that are more and more true:

  ``run``       the run as it was (a touch not detected is a miss);
  ``initial``   the run's taxels and windows, each taxel's starting temperature the truth;
  ``onset``     the run's taxels, each window from the true contact instant (with the true
                starting temperature) to where the run's ended: the onset's dating alone;
  ``end``       the run's taxels and windows, each cut at the touch's true end: the
                release's dating alone;
  ``dating``    the run's taxels, each window cut from the true contact instant to the true
                end (at most the window), with the true starting temperature;
  ``taxels``    every taxel of the touch, windows as ``dating``;
  ``ceiling``   as above.

  With the joint classifier, two more: ``run+noise`` and ``taxels+noise``, the ``run`` and
  ``taxels`` steps with the classifier's reading noise integrated over a grid
  (`NOISE_GRID` times its own, `skin.models.joint.JointContactModel`) rather than fixed:
  what a sharper classifier gains where the windows are right, and what it costs (confident
  mistakes) where they are not.

  Each step is counted twice: named right (``label``, what the run reports) and most
  probable right (``best``): their difference is what the threshold leaves "unknown".

Only a perfect contact with a sensor that reads the closed form (constant heater, no lag, no
smoothing) has this ceiling: another sensor or contact raises SkinError.
"""

from __future__ import annotations

import copy
from dataclasses import replace
from typing import Any

import numpy as np

from skin.bench.scene_seeds import SURE
from skin.errors import SkinError

#: The gap's steps (module docstring), from the run to the truth.
STEPS = ("run", "initial", "onset", "end", "dating", "taxels")
#: The joint classifier's noise grid of the ``+noise`` steps, times its own noise.
NOISE_GRID = (0.3, 0.5, 1.0, 2.0)
#: Steps with the joint classifier's noise integrated over `NOISE_GRID` (module docstring).
NOISE_STEPS = ("run+noise", "taxels+noise")


def touch_truth(scene, duration: float | None = None,
                contact: str | None = None) -> list[dict[str, Any]]:
    """Return what the simulation drew for each touch that begins within ``duration``.

    ``contact`` is the run's contact model (`skin.drivers.sim.SkinSimulator`'s); None: the
    scene's (``Scene.contact``).

    Each: ``index`` (in the scene), ``touch`` (the `Touch`), ``material``, ``family``,
    ``effusivity``, ``t_object`` (deg C), ``k0`` and ``k1`` (first sample in contact and first
    free again, the latter at most the run's end), ``rows`` (the taxels' layout indices),
    ``taxels`` (ids), ``t0`` (each taxel's temperature at the contact instant) and
    ``sensors`` (each taxel's `SensorConstants`).

    Raises
    ------
    SkinError
        If the scene's sensor does not read the closed form (heater switched at contact, PID
        loop, lag or smoothing), or the contact is not perfect: the ceiling is not defined
        (the simulator does not keep the conductances it draws).
    """
    from skin.drivers.sim import SkinSimulator
    from skin.models.materials import load_materials
    from skin.models.physics import SensorConstants
    from skin.models.sensors import has_dynamics

    contact = scene.contact if contact is None else contact
    if contact != "perfect":
        raise SkinError(f"{scene.source}: a {contact} contact has no ceiling (the conductances "
                        f"drawn are not kept); run the scene with a perfect contact")
    sim = SkinSimulator(scene, duration=duration, contact=contact)
    sensor = sim.sensor
    if has_dynamics(sensor):
        raise SkinError(f"{scene.source}: the scene's sensor ({sensor.heater} heater, with its "
                        f"dynamics) does not read the closed form: it has no ceiling")
    table = load_materials()
    clean = sim.temperatures()  # noise-free; a taxel reads its start at the contact instant
    fs = sim.sample_rate
    each = sim.taxel_sensor
    const = [np.broadcast_to(np.asarray(v, dtype=float), len(scene.layout))
             for v in (each.depth, each.diffusivity, each.conductivity)]
    out = []
    for i, touch in enumerate(scene.touches):
        k0 = round(touch.start * fs)
        if k0 >= sim.n_samples:
            continue
        mat = table[scene.material_of(touch)]
        obj = scene.objects[touch.object]
        rows = np.array([scene.layout.index(t) for t in touch.taxels])
        out.append({
            "index": i, "touch": touch, "material": mat.name, "family": mat.family,
            "effusivity": float(mat.effusivity),
            "t_object": float(mat.resting_temperature(scene.ambient) if obj.temperature is None
                              else obj.temperature),
            "k0": k0, "k1": min(round(touch.end * fs), sim.n_samples), "rows": rows,
            "taxels": [int(t) for t in touch.taxels], "t0": clean[k0, rows].copy(),
            "sensors": [SensorConstants(depth=float(const[0][r]), diffusivity=float(const[1][r]),
                                        conductivity=float(const[2][r])) for r in rows]})
    return out


def touch_trial(truth: dict[str, Any], readings: np.ndarray, fs: float, ambient: float,
                window: float):
    """Return one touch as a one-trial simulated `TrialSet` with the ``true_`` keys.

    One channel per taxel, the ``readings`` (n_samples, n_taxels, as the pipeline saw them)
    from the contact instant (the trial's onset, sample 0) to the touch's end, at most
    ``window`` s; the trial's duration in s is its sample count over ``fs``.
    """
    from skin.formats.dataset import TrialSet

    k0 = truth["k0"]
    n = min(truth["k1"] - k0, round(window * fs))
    y = readings[k0:k0 + n, truth["rows"]].T[None]  # (1, channels, n)
    sens = truth["sensors"]
    per_channel = {"true_channel_sensor_temperature": truth["t0"],
                   "true_channel_sensor_depth": [s.depth for s in sens],
                   "true_channel_sensor_diffusivity": [s.diffusivity for s in sens],
                   "true_channel_sensor_conductivity": [s.conductivity for s in sens],
                   "true_channel_conductance": [np.inf] * len(sens)}
    extra = {k: np.asarray(v, dtype=float)[None] for k, v in per_channel.items()}
    first = {"true_onset_time": 0.0, "true_sensor_temperature": truth["t0"][0],
             "true_object_temperature": truth["t_object"], "true_effusivity": truth["effusivity"],
             "true_conductance": np.inf, "true_sensor_depth": sens[0].depth,
             "true_sensor_diffusivity": sens[0].diffusivity,
             "true_sensor_conductivity": sens[0].conductivity}
    extra.update({k: np.array([v], dtype=float) for k, v in first.items()})
    return TrialSet(y, fs, np.array([truth["material"]]), np.array([0]),
                    ambient=np.array([ambient]), taxel=np.array([truth["taxels"]]),
                    extra=extra, source=f"touch {truth['index']}")


def touch_ceiling(truth: dict[str, Any], readings: np.ndarray, fs: float, ambient: float,
                  window: float, candidates: dict[str, float]) -> str:
    """Return the material the known-nuisance ceiling chooses for one touch."""
    from skin.bench.ceiling import known_nuisance_ceiling

    trial = touch_trial(truth, readings, fs, ambient, window)
    n = trial.temperature.shape[-1]
    if n < 1:
        raise SkinError(f"touch {truth['index']}: no sample in contact")
    out = known_nuisance_ceiling(trial, n / fs, candidates=candidates)
    row = out["classes"].index(truth["material"])
    return out["classes"][int(np.argmax(out["confusion"][row]))]


def _true_window(truth: dict[str, Any], j: int, readings: np.ndarray, fs: float,
                 window: float, end: float | None = None):
    """Taxel ``j`` of a touch (its position in ``truth['rows']``) cut at the true instants.

    ``end``: the window's last instant, s, in place of the touch's true end.
    """
    from skin.contact import TaxelWindow

    k0 = truth["k0"]
    last = truth["k1"] if end is None else round(end * fs) + 1
    n = max(min(last - k0, round(window * fs) + 1), 0)
    return TaxelWindow(taxel=truth["taxels"][j], onset=k0 / fs, initial=float(truth["t0"][j]),
                       time=np.arange(n) / fs,
                       temperature=readings[k0:k0 + n, truth["rows"][j]].copy(), released=True)


def step_contact(step: str, truth: dict[str, Any] | None, contact, readings: np.ndarray,
                 fs: float, ambient: float, window: float):
    """Return the contact the classifier is fed at ``step`` (`STEPS`), or None (a miss).

    ``contact`` is the run's final contact matched to the touch (None: not detected);
    ``truth`` the touch's (`touch_truth`).
    """
    from skin.contact import Contact

    if step == "taxels":
        windows = [_true_window(truth, j, readings, fs, window)
                   for j in range(len(truth["taxels"]))]
        return Contact(id=truth["index"], taxels=list(truth["taxels"]), onset=truth["k0"] / fs,
                       release=truth["k1"] / fs, ambient=ambient, windows=windows,
                       decided_at=truth["k1"] / fs)
    if contact is None or step == "run":
        return contact
    where = {t: j for j, t in enumerate(truth["taxels"])}
    windows = []
    for w in contact.windows:
        j = where.get(w.taxel)
        if j is None:  # a taxel of another touch merged in: kept as the run had it
            windows.append(w)
        elif step == "initial":
            windows.append(replace(w, initial=float(truth["t0"][j])))
        elif step == "end":
            keep = w.onset + w.time <= truth["k1"] / fs - 0.5 / fs
            windows.append(replace(w, time=w.time[keep], temperature=w.temperature[keep]))
        elif step == "onset":
            end = w.onset + (float(w.time[-1]) if w.time.size else 0.0)
            windows.append(_true_window(truth, j, readings, fs, window, end))
        else:  # "dating"
            windows.append(_true_window(truth, j, readings, fs, window))
    return replace(contact, windows=windows)


def ladder(classifier, matches: list, contacts: list, truths: list[dict[str, Any]],
           readings: np.ndarray, fs: float, ambient: float, window: float) -> dict[str, dict]:
    """Count the touches named right at each step of `STEPS`, by fresh copies of ``classifier``.

    Per step: named right (``label``) and most probable right (``best``), at material and
    family level (``family``, ``best_family``), wrong at p >= `SURE` (``sure_wrong``) and
    ``misses`` (each touch not named right).

    ``matches`` are `skin.formats.scene.match_touches`'s (one per touch), ``contacts`` the
    run's final contacts (with their windows); a step's contacts are replayed in the order of
    their decision (touches the run missed at their true end), the run's false contacts too,
    so that the classifier's learned object prior sees what it saw in the run.
    """
    from skin.models.joint import JointContactModel
    from skin.models.materials import load_materials

    by_touch = {m.touch: i for i, m in enumerate(matches)}
    truth_of = {t["touch"]: t for t in truths}
    table = getattr(classifier, "table", None) or load_materials()
    out = {}
    joint = isinstance(getattr(classifier, "model", None), JointContactModel)
    for name in STEPS + (NOISE_STEPS if joint else ()):
        clf = copy.deepcopy(classifier)
        step = name.removesuffix("+noise")
        if step != name:
            clf.model.noises = clf.model.noise * np.array(NOISE_GRID)
            clf.model.noise = float(clf.model.noises.max())
            clf.calibration = None  # the run's temperature is fitted to the fixed noise
        queue = []  # (decision instant, run order, contact, touch position or None)
        matched = {m.contact_index: m for m in matches if m.contact_index is not None}
        for i, c in enumerate(contacts):
            m = matched.get(i)
            if m is None:
                queue.append((c.decided_at, i, c, None))
                continue
            truth = truth_of[m.touch]
            queue.append((c.decided_at, i, step_contact(step, truth, c, readings, fs, ambient,
                                                        window), by_touch[m.touch]))
        if step == "taxels":  # the touches the run missed come too
            for m in matches:
                if m.contact_index is None:
                    truth = truth_of[m.touch]
                    queue.append((truth["k1"] / fs, len(contacts), step_contact(
                        step, truth, None, readings, fs, ambient, window), by_touch[m.touch]))
        counts: dict[str, Any] = {"label": 0, "best": 0, "family": 0, "best_family": 0,
                                  "sure_wrong": 0}
        wrong = []
        for _, _, c, k in sorted(queue, key=lambda q: (q[0], q[1])):
            est = clf.classify(c)
            if k is None:
                continue
            truth = matches[k].material
            best = max(est.probabilities, key=est.probabilities.get) if est.probabilities else ""
            counts["label"] += est.label == truth
            counts["best"] += best == truth
            counts["family"] += est.family == table[truth].family
            counts["best_family"] += bool(best) and table[best].family == table[truth].family
            counts["sure_wrong"] += est.label not in (truth, "unknown") and est.confidence >= SURE
            if est.label != truth:
                wrong.append({"touch": k, "truth": truth, "label": est.label, "best": best,
                              "p_best": round(est.confidence, 3),
                              "p_truth": round(est.probabilities.get(truth, 0.0), 3),
                              "taxels": len(c.windows)})
        out[name] = {**counts, "misses": wrong}
    return out

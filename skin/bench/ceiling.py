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
    if data.temperature.shape[1] > 1 and "true_channel_sensor_depth" not in data.extra:
        raise SkinError(f"{data.source}: the ceiling of a contact seen by several channels "
                        f"needs each channel's taxel constants (true_channel_...), which "
                        f"datasets simulated before they were stored lack: simulate it again")


def channel_truth(data: TrialSet) -> dict[str, np.ndarray]:
    """Each channel's simulated truth, (n_trials, n_channels) arrays, and ``present``.

    Multi-channel simulations store every channel's taxel constants, starting temperature
    and contact conductance (``true_channel_...``); a dataset without them (one channel, or
    made before they were stored) gives its primary channel's alone.
    """
    x = data.extra
    keys = {"sensor_temperature": "true_channel_sensor_temperature",
            "depth": "true_channel_sensor_depth",
            "diffusivity": "true_channel_sensor_diffusivity",
            "conductivity": "true_channel_sensor_conductivity",
            "conductance": "true_channel_conductance"}
    if all(v in x for v in keys.values()):
        out = {k: np.asarray(x[v], dtype=float) for k, v in keys.items()}
        out["present"] = np.all(np.isfinite(data.temperature), axis=2)
        return out
    primary = {"sensor_temperature": "true_sensor_temperature", "depth": "true_sensor_depth",
               "diffusivity": "true_sensor_diffusivity",
               "conductivity": "true_sensor_conductivity", "conductance": "true_conductance"}
    out = {k: np.asarray(x[v], dtype=float)[:, None] for k, v in primary.items()}
    out["present"] = np.ones((len(data), 1), dtype=bool)
    return out


def known_nuisance_ceiling(data: TrialSet, duration: float,
                           unknown: tuple[str, ...] = (),
                           candidates: dict[str, float] | None = None,
                           per_trial: bool = False) -> dict:
    """Accuracy of the least-squares material choice when every nuisance is known.

    Every channel of a contact is used where the simulation stored each channel's truth
    (`channel_truth`); with ``"object_temperature"`` unknown it is fitted once, shared by
    the channels.

    Parameters
    ----------
    data : TrialSet
        A simulated dataset with the ``true_`` keys (`skin.models.trials.simulate_trials`)
        and recorded onsets.
    duration : float
        Seconds after the recorded onset that are used.
    unknown : tuple of str
        Nuisances not told (`UNKNOWABLE`; module docstring).
    candidates : dict of str to float, optional
        Material name -> effusivity to choose among: a classifier's candidates, of which the
        dataset may hold a few (a scene's touches, `skin.bench.scene_ceiling`). Default: the
        dataset's classes, each with its simulated effusivity.
    per_trial : bool
        Also return ``correct``: whether each trial's choice is right (paired errors).

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
    if candidates is None:
        classes = data.classes
        effusivity = np.array([x["true_effusivity"][data.label == c][0] for c in classes])
    else:
        classes = sorted(candidates)
        effusivity = np.array([float(candidates[c]) for c in classes])
        missing = sorted(set(data.classes) - set(classes))
        if missing:
            raise SkinError(f"{data.source}: {', '.join(missing)} is not among the candidates")
    n = round(duration * data.fs)
    if n < 1 or np.any(data.onset + n > data.temperature.shape[-1]):
        raise SkinError(f"{data.source}: a {duration} s window does not fit the recording")
    k = np.arange(n)
    nominal = SensorConstants()
    truth_of = channel_truth(data)
    chosen = np.empty(len(data), dtype=int)
    for i in range(len(data)):
        since = (data.onset[i] + k) / data.fs - x["true_onset_time"][i]
        phi, t0, observed = [], [], []
        for c in np.flatnonzero(truth_of["present"][i]):
            sensor = nominal if "taxel_constants" in unknown else SensorConstants(
                depth=float(truth_of["depth"][i, c]),
                diffusivity=float(truth_of["diffusivity"][i, c]),
                conductivity=float(truth_of["conductivity"][i, c]))
            phi.append(contact_trace(since[None, :], 0.0, 1.0, effusivity[:, None], sensor,
                                     truth_of["conductance"][i, c]))
            t0.append(truth_of["sensor_temperature"][i, c])
            observed.append(data.temperature[i, c, data.onset[i] + k])
        phi = np.stack(phi, axis=1)  # (materials, channels, samples)
        t0 = np.array(t0)[None, :, None]
        observed = np.array(observed)[None]
        if "object_temperature" in unknown:
            # reading_c = T0_c + (T_obj - T0_c) phi_c, T_obj shared: closed form per material
            z = observed - t0 + t0 * phi
            t_obj = (np.sum(z * phi, axis=(1, 2))
                     / np.maximum(np.sum(phi * phi, axis=(1, 2)), 1e-300))[:, None, None]
        else:
            t_obj = x["true_object_temperature"][i]
        predicted = t0 + (t_obj - t0) * phi
        chosen[i] = int(np.argmin(np.sum((predicted - observed) ** 2, axis=(1, 2))))
    truth = np.searchsorted(classes, data.label)
    conf = np.zeros((len(classes), len(classes)), dtype=int)
    np.add.at(conf, (truth, chosen), 1)
    recall = conf.diagonal() / np.maximum(conf.sum(axis=1), 1)
    out = {"method": "ceiling" + "".join(f" ({u} unknown)" for u in unknown),
           "duration": duration,
           "accuracy": round(float(np.mean(chosen == truth)), 4), "accuracy_std": 0.0,
           "recall": {c: round(float(r), 4) for c, r in zip(classes, recall, strict=True)},
           "confusion": conf.tolist(), "classes": classes, "unknown": 0,
           "fit_ms_per_trial": 0.0, "predict_ms_per_trial": 0.0}
    if per_trial:
        out["correct"] = chosen == truth
    return out


def joint_fit_accuracy(data: TrialSet, duration: float, constants: str = "true",
                       calibration: dict | None = None, train: TrialSet | None = None,
                       sensor: object = None) -> dict:
    """Accuracy of the joint physics fit of all channels, told (or not) the taxels' constants.

    The fit is `skin.models.joint.JointContactModel` over the dataset's materials (one object
    temperature shared by the channels, 10 K prior about ambient; each material's contact
    conductance range; onsets up to 10 ms either side), on what a classifier sees (each
    channel's temperature before the recorded onset and its window). With ``constants=
    "true"`` each channel gets its taxel's own depth, diffusivity and conductivity, as a
    per-taxel calibration would give them; with ``"nominal"`` the sensor's; with
    ``"calibrated"`` those of ``calibration`` (taxel id -> `SensorConstants`, e.g. from
    `skin calibrate thermal`; taxels it lacks keep the nominal ones), which needs no
    simulated truth, only the dataset's ``taxel`` column. It answers "what does calibrating
    the taxels buy", not "what can no method beat" (`known_nuisance_ceiling`). With ``train``
    (labelled contacts of the same materials) the log evidence is divided by the temperature
    that makes it calibrated on them (`skin.models.contact.fit_temperature`): the fit's
    noise (0.1 K) leaves out the taxels' and the contacts' own errors, and is overconfident.
    With ``sensor`` (the dataset's `skin.models.sensors.SensorDescription`) every channel is
    read as that sensor reads (heater mode, PID loop, lag, smoothing; the constants as above),
    and a dataset of a sensor whose reading is not eq. 5's closed form is accepted.

    Returns
    -------
    dict
        The layout of `known_nuisance_ceiling`, plus ``confident`` (share of answers at
        p >= 0.9) and ``confident_right`` (share of those right, None if none) and the
        predict cost per contact.
    """
    from skin.models.joint import JointContactModel
    from skin.models.materials import load_materials

    if constants not in ("true", "nominal", "calibrated"):
        raise ValueError(f"constants must be 'true', 'nominal' or 'calibrated', got "
                         f"{constants!r}")
    if constants == "calibrated":
        if calibration is None or data.taxel is None:
            raise SkinError(f"{data.source}: calibrated constants need a calibration and the "
                            f"dataset's 'taxel' column")
    elif sensor is None:
        check_ceiling(data)
    else:
        missing = [k for k in NEEDED if k not in data.extra]
        if missing:
            raise SkinError(f"{data.source}: the true constants need a simulated dataset; "
                            f"missing {', '.join(missing)}")
    table = load_materials()
    missing = [c for c in data.classes if c not in table]
    if missing:
        raise SkinError(f"{data.source}: the joint fit needs materials of the table; "
                        f"{', '.join(missing)} is not one")
    classes = data.classes
    model = JointContactModel([table[c] for c in classes], noise=0.1, object_std=10.0,
                              onset_shifts=(-0.01, -0.005, 0.0, 0.005, 0.01))
    temperature, fit_ms = 1.0, 0.0  # nothing is fitted without ``train``
    if train is not None:  # the physics' confidence, scaled on the labelled training contacts
        import time

        from skin.models.contact import fit_temperature

        known = np.isin(train.label, classes)
        if not known.any():
            raise SkinError(f"{train.source}: no training contact of the test's materials")
        sub = train.subset(np.flatnonzero(known))
        started = time.perf_counter()
        temperature = fit_temperature(
            _joint_log_evidence(model, sub, duration, constants, calibration, sensor)[0],
            np.searchsorted(classes, sub.label))
        fit_ms = (time.perf_counter() - started) / len(sub) * 1e3
    log_ev, cost = _joint_log_evidence(model, data, duration, constants, calibration, sensor)
    z = log_ev / temperature
    p = np.exp(z - z.max(axis=1, keepdims=True))
    p /= p.sum(axis=1, keepdims=True)
    chosen, top = np.argmax(p, axis=1), np.max(p, axis=1)
    truth = np.searchsorted(classes, data.label)
    conf = np.zeros((len(classes), len(classes)), dtype=int)
    np.add.at(conf, (truth, chosen), 1)
    recall = conf.diagonal() / np.maximum(conf.sum(axis=1), 1)
    sure = top >= 0.9
    return {"method": f"joint fit ({constants} taxel constants"
                      + (", confidence scaled on the training set)" if train is not None
                         else ")"), "duration": duration,
            "accuracy": round(float(np.mean(chosen == truth)), 4), "accuracy_std": 0.0,
            "recall": {c: round(float(r), 4) for c, r in zip(classes, recall, strict=True)},
            "confusion": conf.tolist(), "classes": classes, "unknown": 0,
            "confident": round(float(np.mean(sure)), 4),
            "confident_right": (round(float(np.mean(chosen[sure] == truth[sure])), 4)
                                if sure.any() else None),
            "temperature": round(float(temperature), 4),
            **_probability_scores(top, chosen == truth),
            "fit_ms_per_trial": round(fit_ms, 4), "predict_ms_per_trial": round(cost, 4)}


def _probability_scores(top: np.ndarray, right: np.ndarray) -> dict:
    """Return the calibration figures `skin evaluate` prints for methods with probabilities."""
    from skin.bench.reliability import EVALUATE_BINS, expected_calibration_error
    from skin.commands.evaluate import confident_wrong, selective

    return {"calibration_error": round(expected_calibration_error(top, right, EVALUATE_BINS),
                                       4),
            "confident_wrong": round(confident_wrong(top, right), 4),
            "selective": selective(top, right)}


def _joint_log_evidence(model, data: TrialSet, duration: float, constants: str,
                        calibration: dict | None, sensor: object = None,
                        ) -> tuple[np.ndarray, float]:
    """Return each contact's log evidence per material (n, classes) and the ms per contact."""
    import time

    from skin.models.contact import split_contact_rows
    from skin.models.features import contact_matrix
    from skin.models.joint import with_constants
    from skin.models.physics import SensorConstants

    rows = contact_matrix(data, duration)
    amb, t0, w = split_contact_rows(rows, data.temperature.shape[1])
    t = (np.arange(w.shape[2]) + 1e-6) / data.fs
    truth_of = channel_truth(data) if constants == "true" else None
    nominal = SensorConstants() if sensor is None else sensor
    read = (lambda s: s) if sensor is None else (lambda s: with_constants(sensor, s))
    out = np.empty((len(data), len(model.classes)))
    started = time.perf_counter()
    for i in range(len(data)):
        c = np.flatnonzero(np.all(np.isfinite(w[i]), axis=1))
        sensors = None
        if constants == "true":
            if c.size > truth_of["depth"].shape[1]:
                raise SkinError(f"{data.source}: the taxel constants of channels other than "
                                f"the primary are not stored (simulate it again)")
            sensors = [read(SensorConstants(depth=float(truth_of["depth"][i, j]),
                                            diffusivity=float(truth_of["diffusivity"][i, j]),
                                            conductivity=float(truth_of["conductivity"][i, j])))
                       for j in c]
        elif constants == "calibrated":
            sensors = [read(calibration.get(int(data.taxel[i, j]), nominal)) for j in c]
        elif sensor is not None:
            sensors = [sensor] * c.size
        out[i] = model.log_evidence(t, w[i, c], t0[i, c], float(amb[i]), sensors)
    return out, (time.perf_counter() - started) / max(len(data), 1) * 1e3


def ceilings(data: TrialSet, duration: float) -> list[dict]:
    """Return what `skin evaluate --ceiling` reports for ``data`` at one window.

    One channel: `known_nuisance_ceiling`. Several channels (a contact seen by taxels at
    different starting temperatures): also the ceiling with the object's temperature fitted
    (shared by the channels), and the joint physics fit told the taxels' true constants and
    the nominal ones (`joint_fit_accuracy`): what no method beats on objects of unknown
    temperature, and what a per-taxel calibration buys the physics.
    """
    out = [known_nuisance_ceiling(data, duration)]
    if data.temperature.shape[1] > 1:
        out.append(known_nuisance_ceiling(data, duration, ("object_temperature",)))
        out += [joint_fit_accuracy(data, duration, c) for c in ("true", "nominal")]
    return out


#: Nuisances `told_less_ceiling` can leave untold (fitted within their declared range).
PROFILABLE = ("object_temperature", "taxel_constants", "conductance", "onset")


def reading_noise(data: TrialSet) -> float:
    """Return the reading noise of the primary channel, K, from its stretch before contact.

    The median over trials of the standard deviation about a straight line (the taxel may
    still be reheating) of the samples 60-10 before the recorded onset: what any classifier
    can measure, and the weight `told_less_ceiling` gives the trace against its priors.
    """
    lo = np.maximum(data.onset - 60, 0)
    out = []
    for i in range(len(data)):
        y = data.temperature[i, 0, lo[i]:max(data.onset[i] - 10, lo[i])]
        if y.size >= 5 and np.all(np.isfinite(y)):
            k = np.arange(y.size)
            out.append(np.std(y - np.polyval(np.polyfit(k, y, 1), k)))
    if not out:
        raise SkinError(f"{data.source}: no trial has 15 samples before its onset to measure "
                        f"the reading noise")
    return max(float(np.median(out)), 1e-3)


def _taxel_grid(spread: float, points: int) -> list:
    """Sensors spanning +-``spread`` of each of depth, diffusivity and conductivity.

    The trace depends on them through two combinations alone, the response time's root
    x / sqrt(alpha) and the effusivity k / sqrt(alpha), so a ``points`` x ``points`` grid of
    those (each over the range the +-``spread`` box gives it) covers every taxel.
    """
    from skin.models.physics import SensorConstants

    nominal = SensorConstants()
    lo, hi = (1 - spread) / np.sqrt(1 + spread), (1 + spread) / np.sqrt(1 - spread)
    f = np.geomspace(lo, hi, points)
    return [SensorConstants(depth=nominal.depth * a, conductivity=nominal.conductivity * b)
            for a in f for b in f]


def _taxel_weights(spread: float, points: int, cells: int = 64) -> np.ndarray:
    """Return the prior mass of each `_taxel_grid` sensor when the constants are uniform.

    `skin.models.trials.spread_sensors` draws depth, diffusivity and conductivity uniformly
    within +-``spread``; the two combinations the trace depends on then crowd the middle of
    their range (the corners need all three at an extreme). Each grid point gets the mass of
    the box that lies nearest it in (log root, log effusivity), from a ``cells``^3 midpoint
    rule over the box (deterministic). Order: `_taxel_grid`'s (root outer, effusivity inner).
    """
    u = -spread + (np.arange(cells) + 0.5) * (2 * spread / cells)
    d, a, c = np.meshgrid(u, u, u, indexing="ij")
    lo, hi = (1 - spread) / np.sqrt(1 + spread), (1 + spread) / np.sqrt(1 - spread)
    step = np.log(hi / lo) / max(points - 1, 1)

    def cell(v: np.ndarray) -> np.ndarray:
        return np.clip(np.rint((np.log(v) - np.log(lo)) / step), 0, points - 1).astype(int)

    root, effusivity = cell((1 + d) / np.sqrt(1 + a)), cell((1 + c) / np.sqrt(1 + a))
    mass = np.bincount((root * points + effusivity).ravel(), minlength=points * points)
    return mass / mass.sum()


def _log_density(sample: np.ndarray):
    """Return a function: the log density of a Gaussian kernel estimate of ``sample``.

    ``own`` marks values that are themselves in the sample: each is left out of its own
    estimate once (leave-one-out: a classifier's prior comes from other contacts than the
    one it names). Values of other trials equal to it stay (rested taxels start alike).
    """
    sample = np.asarray(sample, dtype=float)
    width = max(1.06 * float(np.std(sample)) * sample.size ** -0.2, 1e-3)

    def log_p(v: np.ndarray, own: np.ndarray | None = None) -> np.ndarray:
        d = (np.asarray(v, dtype=float)[:, None] - sample[None]) / width
        d2 = d * d
        kept = np.full(d.shape[0], sample.size)
        if own is not None and np.any(own):
            if sample.size < 2:
                raise ValueError("leaving a value out of a sample of one leaves no estimate")
            rows = np.flatnonzero(own)
            self_at = np.argmin(np.abs(d[rows]), axis=1)
            if np.any(d[rows, self_at] != 0):
                raise ValueError("a value marked own is not in the sample")
            d2[rows, self_at] = np.inf
            kept[rows] = sample.size - 1
        low = np.min(d2, axis=1, keepdims=True)
        return (-low[:, 0] / 2 + np.log(np.sum(np.exp(-(d2 - low) / 2), axis=1) / kept)
                - np.log(width * np.sqrt(2 * np.pi)))

    return log_p


def told_less_ceiling(data: TrialSet, duration: float, unknown: tuple[str, ...] = (),
                     sensors: dict | None = None, taxel_spread: float = 0.10,
                     points: int = 9, taxel_prior: str | np.ndarray = "box",
                     per_trial: bool = False, part_cells: int = 4_000_000) -> dict:
    """Accuracy of the best material choice when some nuisances are only known by their range.

    `known_nuisance_ceiling` told less by plugging in a guess (the nominal constants, an
    unconstrained object temperature) falls below methods that learned the nuisances'
    ranges, so it bounds nothing. Here each untold nuisance is integrated over what a
    classifier could know of it, jointly with the others, for every material (marginal
    likelihood, Gaussian reading noise measured before contact, `reading_noise`):

    - ``"object_temperature"``: a Gaussian prior per material, integrated exactly: the
      dataset's object temperatures above ambient for that material (touches warm it) as a
      straight line in the sensor's starting temperature (the same touches cool it) and
      the spread about it;
    - ``"taxel_constants"``: anywhere in the +-``taxel_spread`` box of the taxels' depth,
      diffusivity and conductivity (``points`` x ``points`` grid, `_taxel_grid`), each
      point weighted by the mass the box uniform gives it (``taxel_prior="box"``, how the
      simulation draws taxels, `_taxel_weights`) or all alike (``"range"``: uniform over
      the combinations' range, which overweights the corners: lower), or by given weights
      (``points`` x ``points`` values, root-time index major, as `_taxel_weights` returns);
    - ``"conductance"``: anywhere in the material's range of contact conductance in the
      dataset (``points`` log-spaced values);
    - ``"onset"``: anywhere in the dataset's range of onset error (``max(points, 9)``
      shifts).

    What is told is the simulation's truth, except the taxel constants when ``sensors``
    (taxel id -> `SensorConstants`, e.g. a calibration file's) is given: then each taxel has
    those, as a commissioned skin does. The primary channel alone is read; the sensor's
    starting temperature above ambient adds its per-material density (a kernel estimate,
    each trial left out of its own: `_log_density`).

    It is the accuracy of one decision rule under these priors, a floor of unknown slack
    rather than the Bayes accuracy or a bound: it is told the sensor's true starting
    temperature and fits the object-temperature prior on the dataset's truth (a little
    optimistic), but its priors are simplified (Gaussian object warmth, a kernel density of
    the start) and it ignores what else the stretch before contact shows (the reheating
    slope), so a learned model may do better. Its figures are not even monotone in what is
    told: seed 7, 0.25 s, only the taxel constants untold gives .219 (9 points) / .206 (17),
    below all four untold (.308) and all told (.345), which a Bayes rule could not. Its grid
    has converged (seed 7, 0.25 s, all four untold: .308 / .308 / .309 with 9 / 13 / 17
    points, `skin bench gap --durations 0.25 --seeds 7 --reach-only --points 9|13|17`);
    that says nothing of its priors. Main's code before the box weights and the
    leave-one-out start density gave .314 / .321 / .325 there (reproducible only by running
    that code, not by an option here: ``taxel_prior="range"`` keeps the old weights but not
    the in-sample start); of the difference, some 4 points came from each trial's own
    kernel (measured on seed 7 alone: .354 -> .308 with the box weights, 9 points).

    ``part_cells``: trials are scored in parts of at most this many (trial, combination)
    cells (memory); the answers do not depend on it.

    Raises ValueError for an unknown nuisance or prior, or a material with fewer than 2
    trials (the start density leaves each trial's own kernel out).

    Returns
    -------
    dict
        The layout of `known_nuisance_ceiling`, with ``unknown`` (the untold nuisances) as
        ``told_less`` and ``noise`` (K); with ``per_trial``, ``correct`` (bool per trial).
    """
    from skin.models.physics import SensorConstants, conductance_rate, contact_response

    bad = [u for u in unknown if u not in PROFILABLE]
    if bad:
        raise ValueError(f"unknown nuisance(s) {', '.join(bad)}; choose from "
                         f"{', '.join(PROFILABLE)}")
    if isinstance(taxel_prior, str):
        if taxel_prior not in ("box", "range"):
            raise ValueError(f"taxel_prior {taxel_prior!r}: choose box or range")
        taxel_mass = (_taxel_weights(taxel_spread, points) if taxel_prior == "box"
                      else np.full(points * points, 1.0 / points**2))
    else:
        taxel_mass = np.asarray(taxel_prior, dtype=float).ravel()
        if (taxel_mass.size != points * points or not np.all(np.isfinite(taxel_mass))
                or np.any(taxel_mass < 0) or taxel_mass.sum() <= 0):
            raise ValueError(f"taxel_prior weights: give {points * points} non-negative "
                             f"finite values (points x points), not all zero")
    check_ceiling(data)
    if sensors is not None and data.taxel is None:
        raise SkinError(f"{data.source}: commissioned constants need the 'taxel' column")
    x = data.extra
    classes = data.classes
    truth = np.searchsorted(classes, data.label)
    effusivity = np.array([x["true_effusivity"][data.label == c][0] for c in classes])
    n = round(duration * data.fs)
    if n < 1 or np.any(data.onset + n > data.temperature.shape[-1]):
        raise SkinError(f"{data.source}: a {duration} s window does not fit the recording")
    k = np.arange(n)
    noise = reading_noise(data)
    h_true = np.asarray(x["true_conductance"], dtype=float)
    shift_true = np.asarray(x["true_onset_time"]) - data.onset / data.fs
    rise = np.asarray(x["true_object_temperature"]) - data.ambient
    t0 = np.asarray(x["true_sensor_temperature"], dtype=float)
    start = t0 - data.ambient
    # the object's warmth above ambient, as the sensor's start predicts it (both come from the
    # touches before): a straight line per material, and the spread about it
    few = [f"{c} ({int(np.sum(truth == m))})" for m, c in enumerate(classes)
           if np.sum(truth == m) < 2]
    if few:  # each trial's start density leaves its own kernel out: one trial leaves none
        raise ValueError(f"{data.source}: the ceiling told less needs at least 2 trials per "
                         f"material, got {', '.join(few)}")
    prior_mean, prior_slope, prior_std = (np.empty(len(classes)) for _ in range(3))
    for m in range(len(classes)):
        a, b = start[truth == m], rise[truth == m]
        slope = float(np.cov(a, b)[0, 1] / max(np.var(a, ddof=1), 1e-12)) if a.size > 2 else 0.0
        prior_slope[m], prior_mean[m] = slope, float(b.mean() - slope * a.mean())
        prior_std[m] = max(float(np.std(b - prior_mean[m] - slope * a)), 0.05)
    start_density = [_log_density(start[truth == m]) for m in range(len(classes))]
    taxel_grid = _taxel_grid(taxel_spread, points) if "taxel_constants" in unknown else None
    shift_grid = np.linspace(shift_true.min(), shift_true.max(), max(points, 9))
    h_grid = np.array([np.geomspace(h_true[truth == m].min(), h_true[truth == m].max(), points)
                       if np.all(np.isfinite(h_true[truth == m])) else np.full(points, np.inf)
                       for m in range(len(classes))])

    def options(i: int) -> tuple:
        if taxel_grid is not None:
            sens = taxel_grid
        elif sensors is not None:
            sens = [sensors.get(int(data.taxel[i, 0]), SensorConstants())]
        else:
            sens = [SensorConstants(depth=float(x["true_sensor_depth"][i]),
                                    diffusivity=float(x["true_sensor_diffusivity"][i]),
                                    conductivity=float(x["true_sensor_conductivity"][i]))]
        h = h_grid if "conductance" in unknown else np.full((len(classes), 1), h_true[i])
        shifts = shift_grid if "onset" in unknown else shift_true[i:i + 1]
        return sens, h, shifts

    keys: dict = {}
    for i in range(len(data)):
        sens, h, shifts = options(i)
        key = (tuple((s.depth, s.diffusivity, s.conductivity) for s in sens), h.tobytes(),
               shifts.tobytes())
        keys.setdefault(key, []).append(i)
    chosen = np.empty(len(data), dtype=int)
    t_obj = np.asarray(x["true_object_temperature"], dtype=float)
    for members in keys.values():
        sens, h, shifts = options(members[0])
        rows = np.array(members)
        t = k[None, :] / data.fs - shifts[:, None]  # (shifts, n) since the true contact
        z = np.stack([data.temperature[i, 0, data.onset[i] + k] for i in rows]) - t0[rows, None]
        zz = np.sum(z * z, axis=1)[:, None] / noise**2
        # -2 log evidence per material: the grids' combinations averaged (a uniform prior
        # over each range), and what the sensor's starting temperature says of the material
        # (its history of touches), which every classifier sees
        evidence = np.empty((rows.size, len(classes)))
        for m in range(len(classes)):
            e_o = effusivity[m]
            # the reading's share of the step to the object: the contact surface's, times
            # the thermistor's response (`skin.models.physics.contact_trace`, T0 0, T_obj 1)
            phi = np.stack([e_o / (s.effusivity + e_o) * contact_response(
                t[None], conductance_rate(h[m], s.effusivity, e_o)[:, None, None], s)
                for s in sens]).reshape(-1, n)  # (sensors x h x shifts, n)
            # each combination's prior mass: the taxel grid's (the rest uniform)
            mass = np.repeat(taxel_mass if taxel_grid is not None else [1.0],
                             h.shape[1] * shifts.size)
            log_w = np.log(np.maximum(mass / mass.sum(), 1e-300))[None]
            pp = np.sum(phi * phi, axis=1)[None] / noise**2
            # the trials in parts, so that a fine grid's (trials x combinations) fits memory
            step = max(1, int(part_cells // phi.shape[0]))
            for lo in range(0, rows.size, step):
                part = rows[lo:lo + step]
                dot = z[lo:lo + step] @ phi.T / noise**2  # (trials, combinations)
                if "object_temperature" in unknown:  # integrated over its Gaussian prior
                    a0 = (data.ambient[part] + prior_mean[m] + prior_slope[m] * start[part]
                          - t0[part])[:, None]
                    w = 1.0 / prior_std[m] ** 2
                    cost = (zz[lo:lo + step] + a0 * a0 * w - (dot + a0 * w) ** 2 / (pp + w)
                            + np.log((pp + w) / w))
                else:
                    a = (t_obj[part] - t0[part])[:, None]
                    cost = zz[lo:lo + step] - 2 * a * dot + a * a * pp
                cost = cost - 2 * log_w  # the combinations summed under their prior mass
                low = cost.min(axis=1, keepdims=True)
                evidence[lo:lo + step, m] = (
                    low[:, 0] - 2 * np.log(np.sum(np.exp(-(cost - low) / 2), axis=1))
                    - 2 * start_density[m](start[part], truth[part] == m))
        chosen[rows] = np.argmin(evidence, axis=1)
    conf = np.zeros((len(classes), len(classes)), dtype=int)
    np.add.at(conf, (truth, chosen), 1)
    recall = conf.diagonal() / np.maximum(conf.sum(axis=1), 1)
    told = "commissioned taxel constants" if sensors is not None and taxel_grid is None else ""
    name = "ceiling" + (f" ({told})" if told else "") + (
        f" ({'+'.join(unknown)} fitted)" if unknown else "")
    return {"method": name, "duration": duration, "told_less": list(unknown),
            "accuracy": round(float(np.mean(chosen == truth)), 4), "accuracy_std": 0.0,
            "recall": {c: round(float(r), 4) for c, r in zip(classes, recall, strict=True)},
            "confusion": conf.tolist(), "classes": classes, "unknown": 0,
            "noise": round(noise, 5), "fit_ms_per_trial": 0.0, "predict_ms_per_trial": 0.0,
            **({"correct": chosen == truth} if per_trial else {})}

"""``skin bench commission``: how close commissioning comes to a simulated unit's true constants.

A skin of one sensor preset whose taxels differ (+-``spread``, as the ``spread`` scene) is
touched by two reference materials at room temperature (by default a bag of water and a
neoprene pad, as the shipped ``reference-touches`` scene), alternately, over its first
``taxels`` taxels at once, held as long as `skin commission` asks for that sensor (or
``hold``). Each touch meets the skin through the material's air gap (``contact="finite"``,
a conductance from its range, as issue 4's benchmark and real hardware do). The readings go
through the preset's ADC and smoothing as `sim://` gives them;
`skin.models.commission.commission_response` fits each taxel's response from the touches the
onset detector finds (or, with ``labelled``, from the scripted touch times, as
``skin commission --labels`` does). Reported per fitted taxel against the simulator's truth:
the relative error of the response time (depth^2 / diffusivity) and of the effusivity, with
the preset's nominal constants and with the fitted ones, and what the fit cost.

``references`` names other materials and ``contact="perfect"`` touches without an air gap
(the paper's eq. 5; the bench's default before it followed real contacts). An air gap's
conductance and the response time trade against each other (both add a 1/sqrt(t) tail to
the reading), so touches of aluminium and pine through their gaps leave the response time
some 10 % off on the paper's sensor (20-25 % on fast-film), where conforming references
(water, neoprene: gaps under 2 um) pin it as a perfect contact does.

`classify` measures issue 16's classification target with it: the same classifier told the
true and the commissioned constants on issue 4's benchmark recorded by the same taxels.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

#: The reference materials touched, alternately: both conform (`skin commission`'s advice).
REFERENCES = ("water", "neoprene")

#: The references' contact: through each material's air gap, as on real hardware.
CONTACT = "finite"


def scene_text(sensor: str, seed: int, taxels: int, touches: int, hold: float, rest: float,
               spread: float, references: tuple[str, ...] = REFERENCES,
               force: str = "") -> str:
    """Return the reference-touch scene (TOML) for one sensor preset.

    ``force``: the taxels' force channel (the scene's ``force``: "", "force" or "contact").
    """
    ids = list(range(taxels))
    period = hold + rest
    lines = [f'name = "commission-{sensor}"', 'layout = "arm"',
             f"duration = {3.0 + touches * period + 2.0}", "ambient = 25.0", f"seed = {seed}",
             f"taxel_spread = {spread}", "initial_temperature = [34.0, 38.9]",
             f'sensor = "{sensor}"', f'force = "{force}"']
    for name in references:
        lines += ["[[objects]]", f'name = "{name}"', f'material = "{name}"']
    for k in range(touches):
        lines += ["[[touches]]", f'object = "{references[k % len(references)]}"',
                  f"taxels = {ids}",
                  f"start = {3.0 + k * period}", f"duration = {hold}"]
    return "\n".join(lines) + "\n"


def _errors(got: np.ndarray, want: np.ndarray) -> dict[str, float]:
    rel = got / want - 1.0
    return {"median": round(float(np.median(np.abs(rel))), 4),
            "p90": round(float(np.percentile(np.abs(rel), 90)), 4),
            "signed_median": round(float(np.median(rel)), 4)}


def commission_unit(sensor: str = "paper", seed: int = 7, taxels: int = 8, touches: int = 6,
                    hold: float | None = None, rest: float | None = None,
                    spread: float = 0.10, labelled: bool = False,
                    contact: str = CONTACT, references: tuple[str, ...] = REFERENCES,
                    force: str = "") -> dict[str, Any]:
    """Simulate one unit's reference touches and commission them (`run`'s work).

    ``force``: the taxels' force channel ("" none, "force" or "contact": the scene's), which
    then dates the touches (`skin.models.commission.force_touches`) unless ``labelled``.

    ``contact``: the touches' contact, ``"perfect"`` or ``"finite"`` (each touch a
    conductance from its material's range, as issue 4's benchmark draws them:
    `SkinSimulator`'s ``contact``). ``references``: the materials touched, in turn.

    Returns
    -------
    dict
        ``sim`` (the `SkinSimulator`, its truth in ``taxel_sensor``), ``scene``, ``times``
        and ``readings`` (deg C, as read), ``layout``, ``fits``
        and ``counts`` (`commission_response`), ``nominal`` (the layout's sensors),
        ``quiet_noise`` (the touched taxels' median reading noise about a straight line
        before the first touch, K), ``hold``, ``rest``, ``recording_seconds``,
        ``fit_seconds`` and ``fit_cpu_seconds``.
    """
    from skin.drivers.sim import SkinSimulator
    from skin.formats.calibration_file import CalibrationFile
    from skin.formats.scene import parse_scene
    from skin.formats.touch_labels import TouchLabel
    from skin.models import load_materials
    from skin.models.commission import commission_response, hold_and_rest
    from skin.models.sensors import load_sensor

    preset = load_sensor(sensor)
    advised = hold_and_rest([preset])
    hold = advised[0] if hold is None else hold
    rest = advised[1] if rest is None else rest
    scene = parse_scene(scene_text(preset.name, seed, taxels, touches, hold, rest, spread,
                                   tuple(references), force), f"commission-{preset.name}.toml")
    sim = SkinSimulator(scene, contact=contact)
    frames = list(sim.frames())
    y, _ = sim.calibration.temperature(np.array([f.counts for f in frames])[:, sim._addr])
    t = np.array([f.device_time for f in frames])
    channel = np.array([f.force for f in frames])[:, sim._addr] if force else None
    _, nominal = CalibrationFile().apply(scene.layout)
    table = load_materials()
    labels = None
    if labelled:
        labels = [TouchLabel(tc.start, scene.objects[tc.object].material, tuple(tc.taxels))
                  for tc in scene.touches]
    started, cpu = time.perf_counter(), time.process_time()
    fits, counts = commission_response(t, y, scene.layout, {m: table[m] for m in references},
                                       nominal, scene.ambient, labels=labels, force=channel)
    quiet = t < scene.touches[0].start - 0.5  # before the first touch: the quiet stretch
    x = t[quiet] - t[quiet].mean()
    line = np.polynomial.polynomial.polyfit(x, y[quiet][:, :taxels], 1)
    resid = y[quiet][:, :taxels] - (line[0] + np.outer(x, line[1]))
    return {"sim": sim, "layout": scene.layout, "fits": fits, "counts": counts,
            "times": t, "readings": y, "scene": scene, "force": channel,
            "quiet_noise": float(np.median(resid.std(axis=0, ddof=2))),
            "nominal": nominal, "hold": hold, "rest": rest,
            "recording_seconds": round(float(t[-1] - t[0]), 1),
            "fit_seconds": round(time.perf_counter() - started, 2),
            "fit_cpu_seconds": round(time.process_time() - cpu, 2)}


def run(sensor: str = "paper", seed: int = 7, taxels: int = 8, touches: int = 6,
        hold: float | None = None, rest: float | None = None, spread: float = 0.10,
        labelled: bool = False, contact: str = CONTACT,
        references: tuple[str, ...] = REFERENCES, force: str = "") -> dict[str, Any]:
    """Simulate the reference touches, commission them, compare with the truth.

    ``contact``, ``references`` and ``force``: the touches' contact and materials, the
    taxels' force channel (`commission_unit`).

    Returns
    -------
    dict
        ``counts`` (touches detected, left out, ambiguous; taxels fitted of those touched),
        ``response_time`` and ``effusivity``: ``nominal`` and ``fitted`` relative errors
        (median, p90, signed median over the fitted taxels), and ``fit_seconds`` and
        ``fit_cpu_seconds`` (the commissioning's wall and CPU time) beside
        ``recording_seconds``; with detected touches, ``assignment``: each touch's reference
        named (`assign_materials`) over `ASSIGN_RESPONSE_SCALES` (``swept``) and at the
        nominal response time alone (``nominal``), each with its touches ``ambiguous``,
        ``wrong`` (named another reference than the scene touched) and ``cpu_seconds``, and
        ``onset_error_ms``: the touches' onsets (before the fit dates them again) against
        the scene's touch starts, median and p90 of the absolute error and signed median.
    """
    from skin.models.commission import described
    from skin.models.sensors import load_sensor

    unit = commission_unit(sensor, seed, taxels, touches, hold, rest, spread, labelled,
                           contact, references, force)
    layout, fits, truth = unit["layout"], unit["fits"], unit["sim"].taxel_sensor
    columns = np.array(sorted(int(k) for f in fits if f.scope == "taxel" for k in f.columns))
    got_tau = np.full(len(layout), np.nan)
    got_e = np.full(len(layout), np.nan)
    for f in fits:
        if f.scope == "taxel":
            got_tau[f.columns] = f.fit.sensor.depth**2 / f.fit.sensor.diffusivity
            got_e[f.columns] = f.fit.sensor.effusivity
    doc: dict[str, Any] = {
        "sensor": load_sensor(sensor).name, "seed": seed, "spread": spread,
        "hold": unit["hold"], "rest": unit["rest"],
        "touches": touches, "taxels_touched": taxels, "labelled": labelled,
        "contact": contact, "references": list(references), "force": force,
        "counts": {**unit["counts"], "taxels_fitted": int(columns.size)},
        **{k: unit[k] for k in ("recording_seconds", "fit_seconds", "fit_cpu_seconds")}}
    if not labelled:
        doc["assignment"] = _assignment(unit, references)
    if columns.size == 0:
        return doc
    ref = described(layout, unit["nominal"])
    want_tau = truth.depth[columns] ** 2 / truth.diffusivity[columns]
    nom_tau = np.array([ref[k].depth**2 / ref[k].diffusivity for k in columns])
    nom_e = np.array([ref[k].effusivity for k in columns])
    doc["response_time"] = {"nominal": _errors(nom_tau, want_tau),
                            "fitted": _errors(got_tau[columns], want_tau)}
    doc["effusivity"] = {"nominal": _errors(nom_e, truth.effusivity[columns]),
                         "fitted": _errors(got_e[columns], truth.effusivity[columns])}
    return doc


def _assignment(unit: dict, references: tuple[str, ...]) -> dict[str, Any]:
    """Name the unit's detected touches with and without the response-time sweep (`run`)."""
    from skin.models import load_materials
    from skin.models.commission import (
        ASSIGN_RESPONSE_SCALES,
        assign_materials,
        described,
        find_touches,
        force_touches,
    )

    scene, layout = unit["scene"], unit["layout"]
    sensors = described(layout, unit["nominal"])
    if unit["force"] is not None:  # as commission_response: every touched taxel has one
        columns = np.flatnonzero(np.isfinite(unit["force"]).any(axis=0))
        touches, _ = force_touches(unit["times"], unit["readings"], unit["force"], sensors,
                                   columns)
    else:
        touches, _ = find_touches(unit["times"], unit["readings"], layout, sensors)
    table = load_materials()
    mats = {m: table[m] for m in references}
    out = {}
    for key, scales in (("swept", ASSIGN_RESPONSE_SCALES), ("nominal", (1.0,))):
        cpu = time.process_time()
        assigned, ambiguous = assign_materials(touches, mats, sensors, scene.ambient, scales)
        cpu = time.process_time() - cpu
        wrong = 0
        for a in assigned:  # the scene's touch of that taxel that began nearest the onset
            of = [tc for tc in scene.touches if layout.ids[a.column] in tc.taxels]
            if not of:  # named, on a taxel the scene never touched
                wrong += 1
                continue
            near = min(of, key=lambda tc, a=a: abs(tc.start - a.onset))
            wrong += scene.material_of(near) != a.material
        out[key] = {"ambiguous": len(ambiguous), "wrong": int(wrong),
                    "cpu_seconds": round(cpu, 3)}
    errors, false = [], 0
    for k, onset, *_ in touches:
        of = [tc for tc in scene.touches if layout.ids[k] in tc.taxels]
        if not of:  # a touch found on a taxel the scene never touched
            false += 1
            continue
        errors.append(onset - min(of, key=lambda tc: abs(tc.start - onset)).start)
    if errors:
        ms = 1e3 * np.array(errors)
        out["onset_error_ms"] = {"median": round(float(np.median(np.abs(ms))), 2),
                                 "p90": round(float(np.percentile(np.abs(ms), 90)), 2),
                                 "signed_median": round(float(np.median(ms)), 2),
                                 "touches": len(errors), "on_untouched_taxels": false}
    return out


def _paired(right_a: np.ndarray, right_b: np.ndarray) -> dict[str, float]:
    """Accuracy gap a - b on the same contacts and its standard error (paired, McNemar's).

    One discordant contact is added to the count the error is computed from, so that a few
    contacts that happen to agree everywhere do not claim a gap known to zero.
    """
    n = right_a.size
    b = float(np.sum(right_a & ~right_b))
    c = float(np.sum(~right_a & right_b))
    return {"gap": round((b - c) / n, 4),
            "std": round(float(np.sqrt(max(b + c + 1 - (b - c) ** 2 / n, 0.0))) / n, 4)}


#: The target: classification with commissioned constants within 3 points of the true ones.
TARGET = 0.03


def _verdict(gap: float, std: float, target: float = TARGET) -> str:
    """Say whether a gap is within ``target`` either way, from its 95 % interval (1.96 std).

    ``"met"`` when the whole interval lies within +-``target``, ``"not met"`` when it lies
    wholly outside, else ``"unresolved"`` (the contacts cannot tell).
    """
    half = 1.96 * std
    if abs(gap) + half <= target:
        return "met"
    if abs(gap) - half > target:
        return "not met"
    return "unresolved"


#: The joint classifier's reading noise when it is not told the sensor's, K (its default).
MODEL_NOISE = 0.1

#: Where `classify` takes the classifier's reading noise from (the first is the default).
NOISE_SOURCES = ("described", "measured", "model")


def white_equivalent(delivered: float, sensor: Any) -> float:
    """Return the white-equivalent noise per sample of a reading whose delivered noise is given.

    The joint classifier's likelihood takes the samples as independent. A sensor's smoothing
    (its description's moving average, low-pass or Savitzky-Golay) shrinks the noise per
    sample by `SensorDescription.smoothing_noise_factor` but keeps its low-frequency power,
    which is what a contact's slow trace is weighed against: the noise measured on the
    smoothed reading, divided by that factor, is the noise per independent sample (the
    pid-logger preset's 1.4 mK delivered is 3.6 mK white; the paper's sensor, unsmoothed,
    keeps its own). At least 0.1 mK.
    """
    return max(float(delivered) / float(sensor.smoothing_noise_factor()), 1e-4)


def noise_grid(white: float, model: float = MODEL_NOISE, points: int = 5) -> np.ndarray:
    """Return the classifier's noise grid: the sensor's white-equivalent noise to ``model``.

    `JointContactModel` integrates over it (each contact judged at the noise its model
    explains it to, log-uniform): a sensor quieter than ``model`` is read down to its own
    noise, one noisier (low-cost: 0.2 K) up to it; ``model`` stays on the grid for what the
    model leaves out (onset error, reheat history).
    """
    return np.geomspace(min(white, model), max(white, model), points)


def _calibration_for(data: Any, fitted: dict[int, object], arm: str) -> dict[int, object]:
    """Return ``fitted`` after checking it holds every taxel the trials were recorded by.

    The classifier would read a taxel it is not told as nominal: refused instead, naming them.
    """
    from skin.errors import SkinError

    used = sorted({int(k) for k in np.asarray(data.taxel, dtype=float).ravel()
                   if np.isfinite(k) and k >= 0})
    missing = [k for k in used if k not in fitted]
    if missing:
        raise SkinError(f"the {arm} constants hold no taxel {', '.join(map(str, missing))} "
                        f"of the {len(used)} the trials were recorded by")
    return fitted


def _constants_of(fits: list, layout: object, own_only: bool = False) -> dict[int, object]:
    """Taxel id -> fitted constants (``own_only``: the taxels fitted from their own touches)."""
    out = {}
    for f in fits:
        if own_only and f.scope != "taxel":
            continue
        for k in f.columns:
            out[int(layout.ids[int(k)])] = f.fit.sensor
    return out


def _per_taxel(data: Any, right: dict[str, np.ndarray], unit: dict) -> list[dict[str, Any]]:
    """Each recording taxel's contacts, true and commissioned accuracy and its constants' errors.

    ``fit`` says where the taxel's commissioned constants came from: ``"taxel"`` (its own
    reference touches) or ``"board"`` (its board's pooled fit: too few of its own touches
    were named); ``response_time_error`` and ``effusivity_error`` are the commissioned
    constants' relative errors against the simulator's truth (`classify`'s diagnosis).
    """
    layout, truth = unit["layout"], unit["sim"].taxel_sensor
    scope = {int(layout.ids[int(k)]): (f.scope, f.fit.sensor) for f in unit["fits"]
             for k in f.columns}
    tax = np.asarray(data.taxel, dtype=float)[:, 0]
    out = []
    for k in sorted({int(v) for v in tax if np.isfinite(v) and v >= 0}):
        on = tax == k
        i = layout.index(k)
        fit, got = scope[k]
        want_tau = truth.depth[i] ** 2 / truth.diffusivity[i]
        out.append({"taxel": k, "fit": fit, "contacts": int(on.sum()),
                    "true": round(float(right["true"][on].mean()), 4),
                    "commissioned": round(float(right["commissioned"][on].mean()), 4),
                    "response_time_error": round(float(
                        got.depth ** 2 / got.diffusivity / want_tau - 1.0), 4),
                    "effusivity_error": round(float(
                        got.effusivity / truth.effusivity[i] - 1.0), 4)})
    return out


def classify(sensor: str = "paper", seed: int = 7, other_seed: int | None = None,
             trials: int = 40, durations: tuple[float, ...] = (0.5, 1.0, 2.5),
             taxels: int = 8, touches: int = 6, spread: float = 0.10,
             labelled: bool = False, object_std: float = 10.0, noise: str = "described",
             contact: str = CONTACT, references: tuple[str, ...] = REFERENCES,
             hold: float | None = None, rest: float | None = None,
             noiseless: bool = False, progress: Any = None,
             force: str = "") -> dict[str, Any]:
    """Issue 16's classification target: the same classifier, true against commissioned constants.

    The unit ``seed`` (its first ``taxels`` taxels, spread +-``spread`` as `SkinSimulator`
    draws them) is commissioned from ``touches`` reference touches (`commission_unit`, as
    `run`); the unit ``other_seed`` (default ``seed + 1``) likewise. Issue 4's synthetic
    benchmark (`skin.models.trials.simulate_trials`: the paper's 11 materials, ``trials``
    each, one heated channel, the protocol's finite contacts and reheat history) is then
    recorded by the taxels of unit ``seed`` (``skin_seed`` = the simulator's stream of that
    seed: the same constants taxel by taxel) through the preset, and classified by
    `skin.models.joint.JointContactModel` reading each taxel as its sensor reads (heater
    mode, dynamics, smoothing), from the recorded onset, at each of ``durations``, told:

    - ``true``: each taxel's true constants;
    - ``commissioned``: the constants commissioned on this unit;
    - ``other_unit``: every taxel the median of the constants commissioned on unit
      ``other_seed`` (the design: all that a different unit's commissioning carries over,
      it knows nothing of this unit's own taxels);
    - ``nominal``: the preset's constants.

    ``contact``, ``references`` and ``force``: the reference touches' contact and materials
    and the taxels' force channel, which dates them (`commission_unit`; the benchmark's
    contacts are finite either way and dated by their recorded onset), ``hold`` and
    ``rest`` their timing (default: what `skin commission` asks for). ``noise``: the
    classifier's reading noise, ``"described"`` (default): `noise_grid` from the sensor
    description's white noise at its heated temperature
    (`SensorDescription.noise_kelvin`: noise and ADC, before any smoothing) to 0.1 K,
    integrated over (`JointContactModel`'s ``noise`` grid); ``"measured"``: the same from
    the noise measured on the commissioning recording's quiet stretch (the 2.5 s before its
    first touch: ``quiet_noise``), made white-equivalent by the description's smoothing
    (`white_equivalent`) -- 2.5 s is short: a PID loop still settling there reads as noise
    (pid-logger unit 11: 12 mK, unit 7: 1.4 mK); or ``"model"``: the joint classifier's own 0.1 K
    whatever the sensor (the default before; on a quiet sensor such as pid-logger's it
    hides part of what the reading says).
    ``noiseless``: the benchmark recorded without the sensor's reading noise (no white
    noise, no ADC noise, a 24-bit ADC; the commissioning and the classifier's noise grid
    keep the sensor's): what the reading noise costs each arm, the rest being the physics
    (response time, heater control, smoothing) and the nuisances.

    Returns
    -------
    dict
        ``commissioning``: per unit (``own``, ``other``) the taxels fitted from their own
        touches, those given their board's pooled fit (``board_fitted``, their ids
        ``board_taxels``), the touch counts, the fit's CPU time
        and the response-time error of the taxels fitted from their own touches.
        Per duration (``rows``): each arm's accuracy and binomial standard error, and the
        gap ``true - commissioned`` (and ``true - other_unit``) on the same contacts with
        its paired standard error (McNemar's: from the contacts one arm names right and the
        other wrong) and its ``verdict`` against 3 points either way (a classifier told
        biased constants can beat the true ones at one window and lose at another): ``met``
        when gap +- 1.96 standard errors lies within, ``not met`` when wholly outside, else
        ``unresolved`` (`_verdict`); the classification's CPU ms per contact; ``taxels``:
        per recording taxel its contacts, true and commissioned accuracy, whether its
        constants are its own fit or its board's pooled one and their errors (`_per_taxel`).
        ``hold`` and ``rest``: the reference touches' (default: what `skin commission`
        asks for).
    """
    from dataclasses import replace

    from skin.bench.ceiling import _joint_log_evidence, reading_noise
    from skin.bench.spread import design
    from skin.drivers.sim import SPREAD_STREAM
    from skin.errors import SkinError
    from skin.models import load_materials
    from skin.models.joint import JointContactModel
    from skin.models.sensors import load_sensor
    from skin.models.trials import PAPER_MATERIALS, Protocol, simulate_trials

    preset = load_sensor(sensor)
    if noise not in NOISE_SOURCES:
        raise SkinError(f"noise must be one of {', '.join(NOISE_SOURCES)}, not {noise!r}")
    other_seed = seed + 1 if other_seed is None else other_seed
    if other_seed == seed:
        raise SkinError(f"--other-seed {other_seed} is the unit itself (--seed): another unit "
                        f"must have another seed")
    say = progress or (lambda _: None)
    say(f"commissioning unit {seed}")
    own = commission_unit(preset.name, seed, taxels, touches, hold, rest, spread=spread,
                          labelled=labelled, contact=contact, references=references,
                          force=force)
    say(f"commissioning unit {other_seed}")
    other = commission_unit(preset.name, other_seed, taxels, touches, hold, rest,
                            spread=spread, labelled=labelled, contact=contact,
                            references=references, force=force)
    layout = own["layout"]
    fitted = _constants_of(own["fits"], layout)
    theirs = _constants_of(other["fits"], layout, own_only=True) or _constants_of(
        other["fits"], layout)
    doc: dict[str, Any] = {
        "sensor": preset.name, "seed": seed, "other_seed": other_seed, "trials": trials,
        "taxels": taxels, "touches": touches, "labelled": labelled, "spread": spread,
        "object_std": object_std, "noiseless": noiseless, "contact": contact,
        "references": list(references), "force": force,
        "hold": own["hold"], "rest": own["rest"], "commissioning": {}}
    for key, unit in (("own", own), ("other", other)):
        truth = unit["sim"].taxel_sensor
        got = _constants_of(unit["fits"], unit["layout"], own_only=True)
        cols = np.array([unit["layout"].index(i) for i in sorted(got)], dtype=int)
        tau = np.array([got[i].depth ** 2 / got[i].diffusivity for i in sorted(got)])
        pooled = sorted(int(unit["layout"].ids[int(k)]) for f in unit["fits"]
                        if f.scope != "taxel" for k in f.columns)
        doc["commissioning"][key] = {
            "taxels_fitted": int(cols.size), "board_fitted": len(pooled),
            "board_taxels": pooled, **unit["counts"],
            "fit_cpu_seconds": unit["fit_cpu_seconds"],
            **({"response_time": _errors(tau, truth.depth[cols] ** 2
                                         / truth.diffusivity[cols])} if cols.size else {})}
    if not fitted or not theirs:
        doc["rows"] = []
        return doc
    table = load_materials()
    say(f"simulating {trials} trials of each of {len(PAPER_MATERIALS)} materials")
    data = simulate_trials([table[m] for m in PAPER_MATERIALS],
                           replace(Protocol(), trials=trials, duration=max(durations) + 0.2,
                                   n_taxels=taxels, taxel_spread=spread),
                           sensor=replace(preset, noise=0.0, adc_noise=0.0, adc_bits=24)
                           if noiseless else preset, seed=seed, skin_seed=[seed, SPREAD_STREAM])
    nominal = own["nominal"]
    mid = design(nominal + [theirs[i] for i in sorted(theirs)],
                 list(range(len(nominal), len(nominal) + len(theirs))))[0]
    arms = {"true": ("true", None),
            "commissioned": ("calibrated", _calibration_for(data, fitted, "commissioned")),
            "other_unit": ("calibrated", {int(i): mid for i in layout.ids}),
            "nominal": ("nominal", None)}
    # the benchmark's own reading noise before contact (`reading_noise`, at least 1 mK; None
    # when its trials start too close to the onset, as low-cost's 20 Hz ones do)
    try:
        doc["benchmark_noise"] = round(reading_noise(data), 6)
    except SkinError:
        doc["benchmark_noise"] = None
    truth = np.searchsorted(data.classes, data.label)
    measured = own["quiet_noise"]
    doc["quiet_noise"] = round(measured, 6)
    white = (white_equivalent(measured, preset) if noise == "measured"
             else preset.noise_kelvin(25.0 + preset.heated_rise))
    doc["white_noise"] = round(white, 6)
    grid = MODEL_NOISE if noise == "model" else noise_grid(white)
    doc["noise"] = noise
    doc["noise_grid"] = [round(float(v), 6) for v in np.atleast_1d(grid)]
    model = JointContactModel([table[c] for c in data.classes], noise=grid,
                              object_std=object_std,
                              onset_shifts=(-0.01, -0.005, 0.0, 0.005, 0.01))
    rows = []
    for d in durations:
        say(f"classifying at {d:g} s")
        row: dict[str, Any] = {"duration": d, "contacts": len(data)}
        right = {}
        cpu = time.process_time()
        for name, (mode, cal) in arms.items():
            ev, _ = _joint_log_evidence(model, data, d, mode, cal, preset)
            right[name] = np.argmax(ev, axis=1) == truth
            acc = float(right[name].mean())
            row[name] = {"accuracy": round(acc, 4),
                         "std": round(float(np.sqrt(acc * (1 - acc) / right[name].size)), 4)}
        row["ms_per_contact"] = round((time.process_time() - cpu) / len(arms) / len(data)
                                      * 1e3, 3)
        for name in ("commissioned", "other_unit"):
            gap = _paired(right["true"], right[name])
            row[f"{name}_gap"] = {**gap, "verdict": _verdict(gap["gap"], gap["std"])}
        row["taxels"] = _per_taxel(data, right, own)
        rows.append(row)
    doc["rows"] = rows
    return doc

"""Does calibration matter in simulation? The per-taxel spread against ``--calibration``.

Every real taxel differs from its board's nominal constants (thermistor depth, diffusivity and
conductivity of its body; the trial generator draws +-10 %). `run` plays one random scene of
many short touches on the arm three times through the pipeline with the joint classifier:

1. ``nominal``: every taxel has the nominal constants (no spread), classified with them;
2. ``spread``: each taxel's constants spread by ``spread`` (`SkinSimulator` with the scene's
   ``taxel_spread``), classified with the nominal constants (no calibration file);
3. ``calibrated``: the same skin, classified with a calibration file holding each taxel's
   true constants (`SkinSimulator.true_calibration`: what a perfect commissioning fits);
4. ``commissioned`` (with a calibration file given): the same skin classified with that
   file's constants, for example those `skin commission --touches` fitted on the same unit
   (the scene ``reference-touches`` with the same seed and sensor);
5. ``design`` (with a calibration file given): every taxel classified with the median of the
   file's constants, the sensor design the commissioning found. This is what carries over to
   another unit of the same design: a file commissioned on another unit (another seed) knows
   nothing of this unit's own taxels, so its per-taxel constants (run 4) are those of other
   taxels.

A file that commissioned only some taxels has the scenes touch those alone (every run).
With ``durations`` every touch is held exactly that long (one scene per duration, the same
taxels and objects): the classifier answers from that much contact, as issue 4's benchmark
reads a window of that length.

It reports each run's accuracy, detections and the classification time, so that the gap
between 2 and 3 is what ``skin run --calibration`` can win back.

With ``model`` (a file from ``skin train``) every run classifies with it in place of the
joint classifier (`skin.models.learned.LearnedClassifier`, most probable class named) and the
scenes touch only the materials it knows. A
model trained on warped traces (``skin train --calibration``) reads each run's taxel
constants to warp every contact, as ``skin run`` does: run 1 gives it the nominal skin's
true constants (the design's: no warp) and run 2, which has no constants, is left out.
"""

from __future__ import annotations

import time

import numpy as np

from skin.formats.scene import Scene, match_touches, parse_scene


def scene_materials() -> list[str]:
    """Return the materials `random_scene` draws from: every classifiable one at ambient."""
    from skin.models import load_materials

    return [m.name for m in load_materials().values() if m.classify and m.temperature is None]


def random_scene(touches: int = 120, spread: float = 0.10, seed: int = 0,
                 sensor: str = "", materials: list[str] | None = None,
                 hold: float | None = None, taxels: list[int] | None = None) -> Scene:
    """Build a scene on the arm: ``touches`` touches of 1.5-3 s, one every 3 s.

    Each touch presses one object of a random classifiable material (at ambient) on a random
    taxel and one or two of its neighbours. ``hold``: every touch lasts that long instead
    (the same taxels and objects; touches start every max(3, hold + 1.5) s). ``taxels``:
    touch only these taxel ids (for example those a calibration file commissioned).
    """
    from skin.formats.layout import load_layout

    rng = np.random.default_rng([seed, 3])
    every = 3.0 if hold is None else max(3.0, hold + 1.5)
    layout = load_layout("arm")
    near = layout.neighbour_lists()
    mats = materials or scene_materials()
    lines = ['name = "spread"', 'layout = "arm"', f"duration = {every * touches + 2.0}",
             "ambient = 25.0", "noise = 0.02", f"seed = {seed}", f"taxel_spread = {spread}",
             "initial_temperature = [31.0, 38.9]"]
    if sensor:
        lines.append(f'sensor = "{sensor}"')
    for m in mats:
        lines += ["[[objects]]", f'name = "{m}"', f'material = "{m}"']
    pool = np.arange(len(layout)) if taxels is None else np.array(
        [layout.index(int(i)) for i in taxels])
    for k in range(touches):
        i = int(pool[rng.integers(pool.size)])
        extra = [j for j in rng.permutation(near[i])[: int(rng.integers(1, 3))] if j in pool]
        ids = [int(layout.ids[j]) for j in (i, *extra)]
        obj = mats[int(rng.integers(len(mats)))]
        drawn = float(rng.uniform(1.5, 3.0))  # drawn either way: the same touches
        held = drawn if hold is None else hold
        lines += ["[[touches]]", f'object = "{obj}"', f"taxels = {ids}",
                  f"start = {1.0 + every * k}", f"duration = {held:.3f}"]
    return parse_scene("\n".join(lines) + "\n", "spread-scene.toml")


def play(scene: Scene, calibrated: object, model: object = None,
         contact: str = "perfect") -> dict:
    """Run the scene through the pipeline; return accuracy and detections.

    ``calibrated``: False (nominal constants), True (the simulation's true constants), a
    `skin.formats.calibration_file.CalibrationFile` whose constants are used, or a tuple
    ``("design", file)``: the median of the file's constants for every taxel (`design`).
    ``model``: a model file (or `skin.models.modelfile.load_model`'s dictionary) to classify
    with in place of the joint classifier; one trained on warped traces warps each taxel
    with the constants of the file (the true ones, or the design's). ``contact``: the
    simulated contact, "perfect" or "finite" (`SkinSimulator`'s; ``skin simulate trials``
    simulates a finite one).
    """
    from skin.drivers.sim import SkinSimulator
    from skin.models import JointClassifier, load_materials
    from skin.stream.pipeline import Pipeline

    sim = SkinSimulator(scene, contact=contact)
    layout = scene.layout
    calibration, sensors, warp = None, None, None
    if calibrated is True:
        cal = sim.true_calibration()
        calibration, sensors = cal.apply(layout)
        warp = cal
    elif isinstance(calibrated, tuple):
        calibration, sensors = calibrated[1].apply(layout)
        fitted = [layout.index(i) for i in commissioned_taxels(calibrated[1])]
        sensors = design(sensors, fitted)
    elif calibrated:
        calibration, sensors = calibrated.apply(layout)
        warp = calibrated
    by_id = None if sensors is None else {int(t.id): s for t, s in
                                          zip(layout.taxels, sensors, strict=True)}
    if model is None:
        classifier: object = JointClassifier(layout, load_materials(), sensors=by_id)
    else:
        from skin.models.learned import LearnedClassifier
        from skin.models.timescale import taxel_constants

        if isinstance(calibrated, tuple):  # the design's constants where the file fitted any
            constants = {int(layout.ids[k]): sensors[k] for k in fitted}
        else:
            constants = None if warp is None else taxel_constants(warp, "calibration")
        classifier = LearnedClassifier(model, sensors=constants)
    pipeline = Pipeline(layout, classifier, calibration=calibration, sensors=sensors)
    started = time.monotonic()
    results = []
    frames = list(sim.frames())
    for k in range(0, len(frames), 50):
        results += pipeline.process(frames[k: k + 50])
    results += pipeline.flush()
    wall = time.monotonic() - started
    matches, unmatched = match_touches(scene, [r.contact.taxels for r in results],
                                       [r.contact.onset for r in results])
    detected = [m for m in matches if m.contact_index is not None]
    correct = [m for m in detected if results[m.contact_index].estimate.label == m.material]
    unknown = [m for m in detected if results[m.contact_index].estimate.label == "unknown"]
    return {"touches": len(matches), "detected": len(detected), "correct": len(correct),
            "unknown": len(unknown),
            "false_contacts": len(unmatched),
            "accuracy": round(len(correct) / len(matches), 4),
            "wall_time": round(wall, 2)}


def commissioned_taxels(cal: object) -> list[int]:
    """Ids of the taxels a calibration file fitted from their own touches.

    Taxels given their board's pooled fit (``thermal_scope`` "board": too few touches of
    their own, or none) count only when no taxel has its own fit.
    """
    fitted = {int(i): v for i, v in cal.taxels.items() if "diffusivity" in v}
    own = [i for i, v in fitted.items() if v.get("thermal_scope", "taxel") == "taxel"]
    return sorted(own or fitted)


def design(sensors: list, fitted: list[int] | None = None) -> list:
    """Return every taxel with the median depth, diffusivity and conductivity of ``sensors``.

    ``fitted``: the columns whose constants were commissioned (default all); the others,
    left at their board's nominal constants, do not count.
    """
    import dataclasses

    pick = [sensors[k] for k in (range(len(sensors)) if fitted is None else fitted)]
    if not pick:
        raise ValueError("the calibration file fits no taxel's thermal constants")
    mid = {k: float(np.median([getattr(s, k) for s in pick]))
           for k in ("depth", "diffusivity", "conductivity")}
    return [dataclasses.replace(s, **mid) for s in sensors]


def run(touches: int = 120, spread: float = 0.10, seed: int = 0, sensor: str = "",
        progress=None, commissioned: object = None,
        durations: list[float] | None = None, model: str | None = None,
        contact: str = "perfect") -> dict:
    """Play the runs of the module docstring; return their figures.

    ``commissioned``: a `skin.formats.calibration_file.CalibrationFile` for runs 4 and 5.
    ``durations``: hold every touch this long, one set of runs each (default: one set with
    touches of 1.5-3 s); the figures of each are under ``by_duration`` keyed by seconds.
    ``model``: a model file to classify with in place of the joint classifier. ``contact``:
    the simulated contact (`play`).
    """
    out = {"touches": touches, "taxel_spread": spread, "seed": seed, "sensor": sensor or "paper",
           "contact": contact}
    plan = [("nominal", 0.0, False), ("spread", spread, False), ("calibrated", spread, True)]
    doc, materials = None, None
    if model is not None:
        from skin.models.modelfile import load_model, reads_nominal_time

        doc = load_model(model)
        materials = [m for m in scene_materials() if m in {str(c) for c in doc["classes"]}]
        if not materials:
            from skin.errors import SkinError

            raise SkinError(f"{model}: the model knows none of the materials the scenes touch "
                            f"({', '.join(scene_materials())})")
        out["materials"] = materials  # the scenes touch those the model knows
        out["model"] = {"file": str(model), "method": str(doc["method"]),
                        "time_scale": "nominal" if reads_nominal_time(doc) else "taxel"}
        if reads_nominal_time(doc):  # warps with constants: the nominal skin's true ones
            plan = [("nominal", 0.0, True), ("calibrated", spread, True)]
    if commissioned is not None:
        plan += [("commissioned", spread, commissioned), ("design", spread,
                                                          ("design", commissioned))]
    holds = list(durations) if durations else [None]
    only = None  # a file that commissioned some taxels: touch those alone
    if commissioned is not None:
        fitted = commissioned_taxels(commissioned)
        from skin.formats.layout import load_layout

        only = fitted if len(fitted) < len(load_layout("arm")) else None
        out["taxels"] = fitted if only else "all"
    done = 0
    for hold in holds:
        figures: dict = {}
        for name, s, cal in plan:
            figures[name] = play(random_scene(touches, s, seed, sensor, materials, hold=hold,
                                              taxels=only), cal, doc, contact)
            done += 1
            if progress is not None:
                progress(done, len(plan) * len(holds))
        if "spread" in figures:
            figures["calibration_gain"] = round(figures["calibrated"]["accuracy"]
                                                - figures["spread"]["accuracy"], 4)
            figures["spread_loss"] = round(figures["nominal"]["accuracy"]
                                           - figures["spread"]["accuracy"], 4)
        if commissioned is not None:
            for name in ("commissioned", "design"):
                figures[f"{name}_gap"] = round(figures["calibrated"]["accuracy"]
                                               - figures[name]["accuracy"], 4)
        if hold is None:
            out.update(figures)
        else:
            out.setdefault("by_duration", {})[f"{hold:g}"] = figures
    return out

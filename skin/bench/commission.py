"""``skin bench commission``: how close commissioning comes to a simulated unit's true constants.

A skin of one sensor preset whose taxels differ (+-``spread``, as the ``spread`` scene) is
touched by an aluminium bar and a pine board at room temperature, alternately, over its
first ``taxels`` taxels at once, held as long as `skin commission` asks for that sensor
(or ``hold``). The readings go through the preset's ADC and smoothing as `sim://` gives them;
`skin.models.commission.commission_response` fits each taxel's response from the touches the
onset detector finds (or, with ``labelled``, from the scripted touch times, as
``skin commission --labels`` does). Reported per fitted taxel against the simulator's truth:
the relative error of the response time (depth^2 / diffusivity) and of the effusivity, with
the preset's nominal constants and with the fitted ones, and what the fit cost.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

#: The reference materials touched, alternately.
REFERENCES = ("aluminium", "pine")


def scene_text(sensor: str, seed: int, taxels: int, touches: int, hold: float, rest: float,
               spread: float) -> str:
    """Return the reference-touch scene (TOML) for one sensor preset."""
    ids = list(range(taxels))
    period = hold + rest
    lines = [f'name = "commission-{sensor}"', 'layout = "arm"',
             f"duration = {3.0 + touches * period + 2.0}", "ambient = 25.0", f"seed = {seed}",
             f"taxel_spread = {spread}", "initial_temperature = [34.0, 38.9]",
             f'sensor = "{sensor}"']
    for name in REFERENCES:
        lines += ["[[objects]]", f'name = "{name}"', f'material = "{name}"']
    for k in range(touches):
        lines += ["[[touches]]", f'object = "{REFERENCES[k % 2]}"', f"taxels = {ids}",
                  f"start = {3.0 + k * period}", f"duration = {hold}"]
    return "\n".join(lines) + "\n"


def _errors(got: np.ndarray, want: np.ndarray) -> dict[str, float]:
    rel = got / want - 1.0
    return {"median": round(float(np.median(np.abs(rel))), 4),
            "p90": round(float(np.percentile(np.abs(rel), 90)), 4),
            "signed_median": round(float(np.median(rel)), 4)}


def run(sensor: str = "paper", seed: int = 7, taxels: int = 8, touches: int = 6,
        hold: float | None = None, rest: float | None = None, spread: float = 0.10,
        labelled: bool = False) -> dict[str, Any]:
    """Simulate the reference touches, commission them, compare with the truth.

    Returns
    -------
    dict
        ``counts`` (touches detected, left out, ambiguous; taxels fitted of those touched),
        ``response_time`` and ``effusivity``: ``nominal`` and ``fitted`` relative errors
        (median, p90, signed median over the fitted taxels), and ``fit_seconds`` and
        ``fit_cpu_seconds`` (the commissioning's wall and CPU time) beside
        ``recording_seconds``.
    """
    from skin.drivers.sim import SkinSimulator
    from skin.formats.calibration_file import CalibrationFile
    from skin.formats.scene import parse_scene
    from skin.formats.touch_labels import TouchLabel
    from skin.models import load_materials
    from skin.models.commission import commission_response, described, hold_and_rest
    from skin.models.sensors import load_sensor

    preset = load_sensor(sensor)
    advised = hold_and_rest([preset])
    hold = advised[0] if hold is None else hold
    rest = advised[1] if rest is None else rest
    scene = parse_scene(scene_text(preset.name, seed, taxels, touches, hold, rest, spread),
                        f"commission-{preset.name}.toml")
    sim = SkinSimulator(scene)
    frames = list(sim.frames())
    y, _ = sim.calibration.temperature(np.array([f.counts for f in frames])[:, sim._addr])
    t = np.array([f.device_time for f in frames])
    _, nominal = CalibrationFile().apply(scene.layout)
    table = load_materials()
    labels = None
    if labelled:
        labels = [TouchLabel(tc.start, scene.objects[tc.object].material, tuple(tc.taxels))
                  for tc in scene.touches]
    started, cpu = time.perf_counter(), time.process_time()
    fits, counts = commission_response(t, y, scene.layout, {m: table[m] for m in REFERENCES},
                                       nominal, scene.ambient, labels=labels)
    fit_seconds, fit_cpu = time.perf_counter() - started, time.process_time() - cpu
    truth = sim.taxel_sensor
    columns = np.array(sorted(int(k) for f in fits if f.scope == "taxel" for k in f.columns))
    got_tau = np.full(len(scene.layout), np.nan)
    got_e = np.full(len(scene.layout), np.nan)
    for f in fits:
        if f.scope == "taxel":
            got_tau[f.columns] = f.fit.sensor.depth**2 / f.fit.sensor.diffusivity
            got_e[f.columns] = f.fit.sensor.effusivity
    doc: dict[str, Any] = {
        "sensor": preset.name, "seed": seed, "spread": spread, "hold": hold, "rest": rest,
        "touches": touches, "taxels_touched": taxels, "labelled": labelled,
        "counts": {**counts, "taxels_fitted": int(columns.size)},
        "recording_seconds": round(float(t[-1] - t[0]), 1),
        "fit_seconds": round(fit_seconds, 2), "fit_cpu_seconds": round(fit_cpu, 2)}
    if columns.size == 0:
        return doc
    ref = described(scene.layout, nominal)
    want_tau = truth.depth[columns] ** 2 / truth.diffusivity[columns]
    nom_tau = np.array([ref[k].depth**2 / ref[k].diffusivity for k in columns])
    nom_e = np.array([ref[k].effusivity for k in columns])
    doc["response_time"] = {"nominal": _errors(nom_tau, want_tau),
                            "fitted": _errors(got_tau[columns], want_tau)}
    doc["effusivity"] = {"nominal": _errors(nom_e, truth.effusivity[columns]),
                         "fitted": _errors(got_e[columns], truth.effusivity[columns])}
    return doc

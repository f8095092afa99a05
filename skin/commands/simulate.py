"""``skin simulate``: thermistor traces and trial datasets from the physics.

``skin simulate trace --material NAME`` prints one contact's thermistor trace at 200 Hz;
``skin simulate trials -o trials.npz`` writes a dataset that follows the paper's protocol.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import TYPE_CHECKING

import numpy as np

from skin.errors import SkinError
from skin.progress import Progress

if TYPE_CHECKING:
    from skin.models.trials import Protocol

TRACE_MODELS = ("semi-infinite", "contact", "multilayer")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin simulate trace`` and ``skin simulate trials``."""
    sim = sub.add_parser("simulate", help="simulate contact traces and trial datasets",
                         description=__doc__)
    kinds = sim.add_subparsers(dest="kind", required=True)

    trace = kinds.add_parser("trace", help="one contact's thermistor trace at 200 Hz")
    trace.add_argument("--material", required=True, help="a name from the materials table")
    trace.add_argument("--t-sensor", type=float, default=None,
                       help="sensor temperature at contact, C (default: eq. 2's heated value)")
    trace.add_argument("--t-object", type=float, default=None,
                       help="object temperature, C (default: ambient, or the material's own)")
    trace.add_argument("--ambient", type=float, default=25.0, help="ambient, C (default 25)")
    trace.add_argument("--duration", type=float, default=2.5, help="seconds (default 2.5)")
    trace.add_argument("--model", choices=TRACE_MODELS, default="semi-infinite",
                       help="semi-infinite (the paper), contact (finite conductance) or "
                            "multilayer (finite volumes); default semi-infinite")
    trace.add_argument("--conductance", type=float, default=3000.0,
                       help="contact conductance h, W/(m^2 K), for contact and multilayer "
                            "(default 3000)")
    trace.add_argument("--fs", type=float, default=200.0, help="sampling rate, Hz")
    trace.add_argument("--json", action="store_true", help="print one JSON document")
    trace.set_defaults(func=main_trace)

    trials = kinds.add_parser("trials", help="a trial dataset following the paper's protocol")
    trials.add_argument("-o", "--out", required=True, help="output .npz")
    trials.add_argument("--trials", type=int, default=500, help="trials per material (500)")
    trials.add_argument("--ambient", type=float, default=25.0, help="room temperature, C")
    trials.add_argument("--human", action="store_true", help="add human skin as a 12th class")
    trials.add_argument("--materials", default=None,
                        help="comma-separated materials (default: the paper's 11)")
    trials.add_argument("--model", choices=("contact", "semi-infinite", "multilayer"),
                        default="contact", help="contact physics (default: contact)")
    trials.add_argument("--duration", type=float, default=3.0,
                        help="seconds recorded after onset (default 3)")
    trials.add_argument("--object-offset", default="0,0", metavar="K|LOW,HIGH",
                        help="a resting object's temperature above ambient, K, drawn per "
                             "recording run: K puts it at -K or +K, LOW,HIGH anywhere between "
                             "(default 0,0: at ambient; e.g. 8 for cold and warm objects)")
    trials.add_argument("--channels", default="heated", metavar="C1,C2,...",
                        help="taxels that see each contact: heated (constant power), passive "
                             "(unheated) or heated@+D (held D K above ambient), e.g. "
                             "heated,passive or heated,heated@+10; the first must be heated "
                             "(default: heated)")
    trials.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    trials.add_argument("--skin-seed", type=int, default=None, metavar="N",
                        help="seed of the taxels' constants alone: datasets with one N come "
                             "from the same skin (default: from --seed)")
    trials.add_argument("--sensor", default=None, metavar="PRESET|FILE",
                        help="sensor description: a preset (`skin sensors`) or a sensor file "
                             "(default: the paper's)")
    trials.add_argument("--run-length", type=int, default=None, metavar="N",
                        help="trials per recording run, one unit of taxels each (default: a "
                             "material's trials split into one run per unit)")
    trials.add_argument("--decimate", type=int, default=1, metavar="N",
                        help="keep 1 sample in N (point samples): the recording of a logger at the "
                             "sensor's rate / N, onsets at the kept sample at or before them "
                             "(default 1: all; an unsmoothed sensor, the slower rate within "
                             "20-1000 Hz)")
    trials.add_argument("--json", action="store_true", help="print one JSON summary")
    trials.set_defaults(func=main_trials)

    truth = kinds.add_parser("calibration", help="the simulated skin's true per-taxel constants "
                                                 "as a calibration file")
    truth.add_argument("--scene", default="default", help="scene (default: default)")
    truth.add_argument("-o", "--out", required=True, help="calibration file to write (JSON)")
    truth.add_argument("--json", action="store_true", help="print one JSON summary")
    truth.set_defaults(func=main_calibration)

    labels = kinds.add_parser("labels", help="a scene's touches as a label file (time, material, "
                                             "taxels), for `skin dataset import`")
    labels.add_argument("--scene", default="default", help="scene (default: default)")
    labels.add_argument("--duration", type=float, default=None,
                        help="only touches starting before this many seconds (default: all)")
    labels.add_argument("-o", "--out", required=True, help="label file to write (CSV)")
    labels.add_argument("--json", action="store_true", help="print one JSON summary")
    labels.set_defaults(func=main_labels)


def main_calibration(args: argparse.Namespace) -> int:
    """Write the calibration file of a simulated skin's true constants."""
    from skin.drivers.sim import SkinSimulator
    from skin.formats.scene import load_scene

    scene = load_scene(args.scene)
    path = SkinSimulator(scene, duration=0.0).true_calibration().save(args.out)
    if args.json:
        print(json.dumps({"path": str(path), "taxels": len(scene.layout), "scene": scene.name,
                          "taxel_spread": scene.taxel_spread}))
    else:
        print(f"wrote {path}: the true thermal constants of {len(scene.layout)} taxels "
              f"(scene {scene.name}, taxel spread {scene.taxel_spread:g})")
    return 0


def main_labels(args: argparse.Namespace) -> int:
    """Write the label file of a scene's touches."""
    from skin.formats.scene import load_scene
    from skin.formats.touch_labels import scene_labels, write_touch_labels

    scene = load_scene(args.scene)
    labels = scene_labels(scene, args.duration)
    if not labels:
        raise SkinError(f"scene {scene.name} has no touch starting before {args.duration} s")
    path = write_touch_labels(args.out, labels)
    if args.json:
        print(json.dumps({"path": str(path), "scene": scene.name, "labels": len(labels)}))
    else:
        print(f"wrote {path}: {len(labels)} touches of scene {scene.name}")
    return 0


def main_trace(args: argparse.Namespace) -> int:
    """Print one contact's trace."""
    from skin.models import load_materials
    from skin.models.physics import SensorConstants, heated_temperature, material_trace

    materials = load_materials()
    if args.material not in materials:
        raise SkinError(f"unknown material {args.material!r}; known: {', '.join(materials)}")
    if not (args.duration > 0 and args.fs > 0):
        raise SkinError("--duration and --fs must be positive")
    if not args.conductance > 0:
        raise SkinError(f"--conductance must be positive (W/(m^2 K)), got {args.conductance}")
    mat = materials[args.material]
    s = SensorConstants()
    t_sensor = float(heated_temperature(args.ambient, s)) if args.t_sensor is None \
        else args.t_sensor
    t_object = mat.resting_temperature(args.ambient) if args.t_object is None \
        else args.t_object
    t, y = material_trace(mat, t_sensor, t_object, duration=args.duration, fs=args.fs,
                          model=args.model, conductance=args.conductance, ambient=args.ambient,
                          sensor=s)
    doc = {"material": mat.name, "model": args.model, "fs": args.fs,
           "t_sensor": t_sensor, "t_object": t_object, "ambient": args.ambient,
           "effusivity": mat.effusivity,
           "conductance": None if args.model == "semi-infinite" else args.conductance,
           "t": [round(float(v), 6) for v in t], "temperature": [round(float(v), 5) for v in y]}
    if args.json:
        print(json.dumps(doc))
    else:
        print(f"# {mat.name}: {args.model}, T_sens(0) = {t_sensor:.3f} C, "
              f"T_obj = {t_object:.3f} C, e = {mat.effusivity:.0f}")
        print("t_s,temperature_C")
        for ti, yi in zip(t, y, strict=True):
            print(f"{ti:.4f},{yi:.5f}")
    return 0


def _check_decimate(factor: int, protocol: Protocol, sensor: object | None) -> None:
    """Refuse a ``--decimate`` factor before the trials are simulated.

    Raises
    ------
    SkinError
        The factor below 1, a rate outside the sensor descriptions' `SAMPLE_RATE_RANGE` or
        fewer than two samples of a trial kept, or a smoothed sensor (its smoothing is
        counted in samples of its own rate: a logger's point samples of it are not a reading
        the detector, judging at the recording's rate, can describe).
    """
    from skin.models.sensors import SAMPLE_RATE_RANGE, load_sensor

    described = load_sensor("paper") if sensor is None else sensor
    fs = described.sample_rate
    n = round(protocol.pre * fs) + round(protocol.duration * fs)
    if factor < 1:
        raise SkinError(f"--decimate must be at least 1, got {factor}")
    lo, hi = SAMPLE_RATE_RANGE
    most = min(n - 1, int(fs // lo))  # two samples of a trial at least (`TrialSet.decimated`)
    if not (lo <= fs / factor <= hi and factor <= n - 1):
        raise SkinError(f"--decimate {factor}: {fs:g} Hz / {factor} = {fs / factor:g} Hz, "
                        f"{-(-n // factor)} of a trial's {n} samples: a sensor description takes "
                        f"{lo:g}-{hi:g} Hz and a trial at least two samples (at most "
                        f"{most} for {fs:g} Hz)")
    if described.smoothing != "none":
        raise SkinError(f"--decimate {factor}: sensor {described.name!r} smooths its reading "
                        f"({described.smoothing}, counted in samples of its {fs:g} Hz): "
                        f"a slower recording of it needs its own description (a sensor file "
                        f"with sample_rate = {fs / factor:g}), not --decimate")


def main_trials(args: argparse.Namespace) -> int:
    """Write a trial dataset."""
    from skin.models import load_materials
    from skin.models.trials import PAPER_MATERIALS, Protocol, parse_channel, simulate_trials

    materials = load_materials()
    names = list(PAPER_MATERIALS) if args.materials is None \
        else [m.strip() for m in args.materials.split(",") if m.strip()]
    if args.human and "human_skin" not in names:
        names.append("human_skin")
    unknown = [m for m in names if m not in materials]
    if unknown:
        raise SkinError(f"unknown material(s) {', '.join(unknown)}; known: {', '.join(materials)}")
    if args.trials < 1:
        raise SkinError("--trials must be at least 1")
    offset = _offset(args.object_offset)
    if args.model == "multilayer" and np.any(np.asarray(offset) != 0.0):
        raise SkinError("--object-offset needs --model contact or semi-infinite")
    channels = tuple(c.strip() for c in args.channels.split(",") if c.strip())
    try:
        kinds = [parse_channel(c) for c in channels]
    except ValueError as exc:
        raise SkinError(f"--channels: {exc}") from None
    if not kinds or not kinds[0][0]:
        raise SkinError(f"--channels {args.channels!r}: the first channel must be heated")
    if args.model == "multilayer" and len(kinds) > 1:
        raise SkinError("--channels with several channels needs --model contact or "
                        "semi-infinite")
    if args.run_length is not None and args.run_length < 1:
        raise SkinError("--run-length must be at least 1")
    protocol = Protocol(trials=args.trials, ambient=args.ambient, duration=args.duration,
                        object_offset=offset, channels=channels, run_length=args.run_length)
    sensor = None
    if args.sensor is not None:
        from skin.models.sensors import load_sensor

        sensor = load_sensor(args.sensor)  # a bad file fails before the work starts
        if args.model == "multilayer" and sensor.heater != "constant":
            raise SkinError(f"--model multilayer runs a constant-power heater; sensor "
                            f"{sensor.name!r} has heater {sensor.heater!r}")
    if args.decimate != 1:
        _check_decimate(args.decimate, protocol, sensor)
    progress = Progress()
    started = time.monotonic()
    ds = simulate_trials([materials[m] for m in names], protocol, model=args.model,
                         seed=args.seed, sensor=sensor, skin_seed=args.skin_seed,
                         progress=lambda d, n: progress.bar(d, n, "trials", started))
    progress.done()
    wall = time.monotonic() - started
    ds = ds.decimated(args.decimate)  # a factor leaving under two samples is refused
    path = ds.save(args.out)
    t0 = ds.extra["true_sensor_temperature"]
    summary = {"out": str(path), "trials": len(ds), "classes": names, "model": args.model,
               "channels": list(channels),
               "samples": ds.temperature.shape[-1], "fs": ds.fs, "seed": args.seed,
               "sensor": "paper" if sensor is None else sensor.name,
               "wall_time": round(wall, 3), "trials_per_second": round(len(ds) / wall, 1),
               "initial_temperature": {"min": round(float(t0.min()), 2),
                                       "mean": round(float(t0.mean()), 2),
                                       "max": round(float(t0.max()), 2)}}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {path}: {len(ds)} trials of {len(names)} materials, "
              f"{ds.temperature.shape[-1]} samples at {ds.fs:g} Hz ({summary['trials_per_second']}"
              f" trials/s); initial sensor temperature {t0.min():.1f}-{t0.max():.1f} C, "
              f"mean {t0.mean():.1f} C", file=sys.stdout)
    return 0


def _offset(text: str) -> tuple[float, float] | float:
    """Parse ``--object-offset``: one K >= 0 (objects at -K or +K) or ``LOW,HIGH``."""
    if "," in text:
        return _pair(text, "--object-offset")
    try:
        k = float(text)
    except ValueError:
        raise SkinError(f"--object-offset wants K or LOW,HIGH, got {text!r}") from None
    if not (np.isfinite(k) and k >= 0):
        raise SkinError(f"--object-offset K must be a finite K >= 0, got {text!r}")
    return k


def _pair(text: str, option: str) -> tuple[float, float]:
    """Parse ``"LOW,HIGH"`` into two ordered floats, naming ``option`` when it is not."""
    parts = text.split(",")
    try:
        low, high = (float(v) for v in parts)
    except ValueError:
        raise SkinError(f"{option} wants LOW,HIGH (two numbers), got {text!r}") from None
    if not (np.isfinite(low) and np.isfinite(high)) or low > high:
        raise SkinError(f"{option} wants finite LOW <= HIGH, got {text!r}")
    return low, high

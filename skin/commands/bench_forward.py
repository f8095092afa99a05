"""``skin bench forward``: the joint classifier reading each sensor preset as it reads.

The measurement is `skin.bench.forward.run` (loaded only when run).
"""

from __future__ import annotations

import argparse


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench forward``."""
    fwd = kinds.add_parser("forward", help="joint classifier accuracy per sensor preset with "
                           "the paper's reading model and the sensor's own (true constants)")
    fwd.add_argument("--sensors", default="paper,fast-film,pid-logger,low-cost",
                     metavar="PRESET,...", help="sensor presets (all four)")
    fwd.add_argument("--seeds", default="11", help="dataset seeds, e.g. 11,23 (11)")
    fwd.add_argument("--durations", default="0.5,1,2.5", help="windows, s (0.5,1,2.5)")
    fwd.add_argument("--trials", type=int, default=8, help="trials per material (8)")
    fwd.add_argument("--object-std", type=float, default=10.0,
                     help="prior std of the object's temperature about ambient, K (10)")
    fwd.add_argument("--json", action="store_true", help="print one JSON document")
    fwd.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.forward.run` and print its figures (or JSON)."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.forward import run
    from skin.errors import SkinError
    from skin.models.sensors import load_sensor
    from skin.progress import Progress

    sensors = [s.strip() for s in args.sensors.split(",") if s.strip()]
    try:
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
        durations = [float(s) for s in args.durations.split(",") if s.strip()]
    except ValueError:
        raise SkinError("--seeds must be integers and --durations seconds, separated by "
                        "commas") from None
    if args.trials < 1 or not sensors or not seeds or not durations \
            or any(not 0.05 <= d <= 30 for d in durations) or not args.object_std > 0:
        raise SkinError("--trials must be at least 1, --durations within 0.05-30 s and "
                        "--object-std positive; give at least one sensor and one seed")
    for s in sensors:
        load_sensor(s)  # an unknown preset is named before the work
    progress = Progress()
    started = time.monotonic()
    rows = run(sensors, seeds, durations, args.trials, args.object_std,
               progress=lambda d, n: progress.bar(d, n, "windows", started))
    progress.done()
    if args.json:
        print(json.dumps({"machine": machine(), "rows": rows,
                          "wall_time": round(time.monotonic() - started, 2)}))
        return 0
    print(f"joint classifier, true taxel constants, two heated taxels per contact, object "
          f"prior {args.object_std:g} K ({machine()['cpus']} cores)")
    print(f"{'sensor':<12} {'seed':>4} {'window s':>8} {'contacts':>8} {'paper model':>11} "
          f"{'forward':>8} {'ms paper':>8} {'ms fwd':>7}")
    for r in rows:
        print(f"{r['sensor']:<12} {r['seed']:>4} {r['duration']:>8g} {r['contacts']:>8} "
              f"{r['paper_model']:>11.3f} {r['forward']:>8.3f} {r['paper_model_ms']:>8.3f} "
              f"{r['forward_ms']:>7.3f}")
    return 0

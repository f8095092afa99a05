"""``skin bench onset-shape``: can a template test tell contacts from gusts, per sensor.

The measurement is `skin.bench.onset_shape.shape_separability` (loaded only when run).
"""

from __future__ import annotations

import argparse


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench onset-shape``."""
    shape = kinds.add_parser("onset-shape", help="can a template test tell contacts from gusts "
                             "(per sensor, at a false-alarm target)")
    shape.add_argument("--sensor", default="paper", metavar="PRESET|FILE",
                       help="the stream's sensor (default paper)")
    shape.add_argument("--seed", type=int, default=0, help="seed of the stream (0)")
    shape.add_argument("--minutes", type=float, default=15.0, help="simulated minutes (15)")
    shape.add_argument("--taxels", type=int, default=16, help="simulated taxels (16)")
    shape.add_argument("--window", type=float, default=None,
                       help="test window, s (default: twice the sensor's response time, "
                            "0.4-8 s)")
    shape.add_argument("--false-alarms", type=float, default=0.1,
                       help="alarms per contact-free taxel-hour allowed (0.1)")
    shape.add_argument("--common-mode", action="store_true",
                       help="test the detector's reading with its board's common mode taken "
                            "off (OnsetDetector common_mode; the room through a PID loop)")
    shape.add_argument("--json", action="store_true", help="print one JSON document")
    shape.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.onset_shape.shape_separability` and print its figures (or JSON)."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.onset_shape import WINDOW_RANGE, shape_separability
    from skin.errors import SkinError
    from skin.models.sensors import load_sensor
    from skin.progress import Progress

    sensor = load_sensor(args.sensor)
    if args.minutes <= 0 or args.taxels < 1 or args.false_alarms < 0:
        raise SkinError("--minutes and --taxels must be positive, --false-alarms >= 0")
    if args.window is not None and not WINDOW_RANGE[0] / 4 <= args.window <= 60.0:
        raise SkinError(f"--window must lie within {WINDOW_RANGE[0] / 4:g}-60 s")
    from skin.stream.onset import COMMON_MIN

    if args.common_mode and args.taxels < COMMON_MIN:
        raise SkinError(f"--common-mode needs a board of at least {COMMON_MIN} taxels (the "
                        f"stream is one board) and --taxels is {args.taxels}: with fewer the "
                        f"detector has no common mode; give --taxels {COMMON_MIN} or more, or "
                        f"leave --common-mode out")
    progress = Progress()
    started = time.monotonic()
    out = shape_separability(sensor, args.seed, args.minutes, args.taxels, args.window,
                             args.false_alarms,
                             progress=lambda d, n: progress.bar(d, n, "rows", started),
                             common_mode=args.common_mode)
    progress.done()
    out = {"machine": machine(), **out, "wall_time": round(time.monotonic() - started, 2)}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"sensor {out['sensor']} seed {out['seed']}"
          + (", board common mode taken off" if out["common_mode"] else "")
          + f": window {out['window_s']} s, "
          f"{out['contacts_5sigma']} contacts > 5 sigma ({out['noise_sigma_k']} K), "
          f"{out['free_taxel_hours']} contact-free taxel-hours")
    for name in ("energy", "versus"):
        r = out[name]
        found = ", ".join(f"{v:.1%} within {d} s" for d, v in r["detected_within_s"].items())
        print(f"{name}: threshold {r['threshold']} ({r['free_alarms_per_taxel_hour']} alarms "
              f"per free taxel-hour): {found}")
    return 0

"""``skin bench tracking``: one contact per touch, two for two touches, and the tracker's cost.

The measurement is `skin.bench.tracking.run` (loaded only when run).
"""

from __future__ import annotations

import argparse

_COLUMNS = ("touches", "whole", "split", "merged", "missed", "other_contacts",
            "track_us_per_sample", "track_share")


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench tracking``."""
    track = kinds.add_parser("tracking", help="touches made one contact each (not split, "
                             "not merged with a neighbour's), with the tracker's cost")
    track.add_argument("--pairs", type=int, default=20,
                       help="rounds per scene: a touch of 2-4 taxels and a pair of touches "
                            "on neighbours (20)")
    track.add_argument("--sensors", default="paper", metavar="PRESET,...",
                       help="sensor presets, one scene each (paper)")
    track.add_argument("--seeds", default="0", help="scene seeds, e.g. 0,1 (0)")
    track.add_argument("--json", action="store_true", help="print one JSON document")
    track.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.tracking.run` and print its figures (or JSON)."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.tracking import run
    from skin.errors import SkinError
    from skin.models.sensors import load_sensor
    from skin.progress import Progress

    sensors = [s.strip() for s in args.sensors.split(",") if s.strip()]
    try:
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    except ValueError:
        raise SkinError(f"--seeds must be integers separated by commas, got {args.seeds!r}"
                        ) from None
    if args.pairs < 1 or not sensors or not seeds:
        raise SkinError("--pairs must be at least 1; give at least one sensor and one seed")
    for s in sensors:
        load_sensor(s)  # an unknown preset is named before the work
    progress = Progress()
    started = time.monotonic()
    rows = run(args.pairs, sensors, seeds,
               progress=lambda d, n: progress.bar(d, n, "scenes", started))
    progress.done()
    if args.json:
        print(json.dumps({"machine": machine(), "pairs": args.pairs, "rows": rows,
                          "wall_time": round(time.monotonic() - started, 2)}))
        return 0
    print(f"{'sensor':<12} {'seed':>4} " + " ".join(f"{c:>{max(len(c), 6)}}" for c in _COLUMNS))
    for r in rows:
        print(f"{r['sensor']:<12} {r['seed']:>4} "
              + " ".join(f"{r[c]:>{max(len(c), 6)}}" for c in _COLUMNS))
    return 0

"""``skin bench envelope-rate``: the gust-envelope noise margin's false alarms on noise alone.

The measurement is `skin.bench.envelope_rate.envelope_false_alarms` (loaded only when run):
the detector's restarted envelope test (the default detector's noise-table margin, ``z`` x
the fall's noise at the time since its reference) run on the sensor's settled readout noise, its
crossings counted per taxel-hour at a ladder of ``z``, against one test a sample (the bound the
detector's ``z`` is the quantile of), and with the flat margin too (the detector's margin once
settled is the smaller of the two: their union, counted).
"""

from __future__ import annotations

import argparse


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench envelope-rate``."""
    p = kinds.add_parser("envelope-rate", help="the envelope test's noise margin: crossings "
                         "per taxel-hour on noise alone, per sensor", description=__doc__)
    p.add_argument("--sensor", default="paper", metavar="PRESET|FILE",
                   help="the sensor (default paper)")
    p.add_argument("--hours", type=float, default=1.0, help="hours of noise per taxel (1)")
    p.add_argument("--taxels", type=int, default=64, help="noise series side by side (64)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise (0)")
    p.add_argument("--false-alarms", type=float, default=0.1,
                   help="the target, per taxel-hour (0.1)")
    p.add_argument("--json", action="store_true", help="print one JSON document")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.envelope_rate.envelope_false_alarms` and print its figures (or JSON)."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.envelope_rate import envelope_false_alarms
    from skin.errors import SkinError
    from skin.models.sensors import load_sensor
    from skin.progress import Progress

    sensor = load_sensor(args.sensor)
    if not args.hours > 0 or args.taxels < 1 or not args.false_alarms > 0:
        raise SkinError("--hours, --taxels and --false-alarms must be positive")
    progress = Progress()
    started = time.monotonic()
    out = envelope_false_alarms(sensor, args.hours, args.taxels, args.seed, args.false_alarms,
                                progress=lambda d, n: progress.bar(d, n, "samples", started))
    progress.done()
    out = {"machine": machine(), **out, "wall_time": round(time.monotonic() - started, 2)}
    if args.json:
        print(json.dumps(out))
        return 0
    tests = ("one test a sample" if out["envelope_tau"] is None else
             f"two tests a sample: the smoothed reading and one over "
             f"{1e3 * out['envelope_tau']:.1f} ms")
    print(f"sensor {out['sensor']}: {out['taxel_hours']} taxel-hours of noise; detector's z "
          f"{out['z_per_sample']:.3f} ({tests}), counted there "
          f"{out['rate_at_z_per_sample']:.3g} per taxel-hour (target {out['false_alarm_rate']})"
          + ("" if out["z_fit"] is None else f"; fitted z for the target {out['z_fit']:.3f}"))
    print(f"  with the flat margin too ({out['flat_sigmas']:.2f} residual sigmas; the smaller "
          f"of the two, the detector's once settled): {out['rate_at_z_per_sample_with_flat']:.3g}"
          f" per taxel-hour at its z; the flat margin alone {out['rate_flat_alone']:.3g}")
    for z, r in out["rate"].items():
        print(f"  z {z:5.2f}: {r:10.4g} per taxel-hour (one test a sample: "
              f"{out['per_sample_bound'][z]:.4g})")
    return 0

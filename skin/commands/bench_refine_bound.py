"""``skin bench refine-bound``: how close physics lets any unbiased estimator date an onset.

The measurement is `skin.bench.refine_bound.measure_refine_bound` (loaded only when run): on
``skin evaluate-onset --sensor S --seed N``'s stream (the streams of `skin bench delay-bound`),
for every contact with a floor (when its noise-free reading first moves 3 sigma), the
Cramér-Rao bound on the onset's standard deviation from the contact's noise-free response and
the sensor's raw noise through its smoothing (a Gaussian signal in correlated noise), in five
variants: ``known`` (all but the onset known), ``gain`` (the amplitude unknown too),
``gain_offset`` (and a baseline offset) on the samples the library's refinement can use,
``gain_offset_drift`` (the same with the room's random walk and the air's flutter, as the
streams put them on the reading, added to the noise; not computed where its dense covariance
would span over 3000 samples: fast-film) and ``known_credited`` on the window evaluate-onset
credits a contact's alarm in. From each,
Monte-Carlo medians of ``|N(0, sd)|`` errors over the contacts: their median, 5-95 % interval and
the share at or under issue 16's target (``max(15 ms, 10 % of the median floor)``), over all the
contacts with a floor and over the ones the library detected; beside them the library's own
refined-onset error median (its detector and refinement as evaluate-onset runs them) and its
|error| in units of the ``gain_offset`` bound (median; 0.67 for an efficient estimate).

The bounds hold for unbiased estimators only: a biased one, or one using a prior on the
onset, can beat them. Under the target with a high share: physics does not rule the target
out; a low share even for ``known``: no unbiased estimator meets it on that stream.
"""

from __future__ import annotations

import argparse


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench refine-bound``."""
    p = kinds.add_parser("refine-bound", help="Cramer-Rao bounds on the refined onset against "
                         "issue 16's target, per sensor and seed", description=__doc__)
    p.add_argument("--sensors", nargs="+", default=None, metavar="PRESET|FILE",
                   help="the streams' sensors (default: every shipped preset, `skin sensors`)")
    p.add_argument("--seeds", nargs="+", type=int, default=[0],
                   help="seeds of the streams (0)")
    p.add_argument("--minutes", type=float, default=15.0, help="simulated minutes (15)")
    p.add_argument("--taxels", type=int, default=16, help="simulated taxels (16)")
    p.add_argument("--draws", type=int, default=20000,
                   help="Monte-Carlo medians per variant (20000)")
    p.add_argument("--json", action="store_true", help="print one JSON document")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.refine_bound.measure_refine_bound` per sensor and seed and print it."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.refine_bound import measure_refine_bound
    from skin.errors import SkinError
    from skin.models.sensors import load_sensor, load_sensors
    from skin.progress import Progress

    names = args.sensors if args.sensors else list(load_sensors())
    sensors = [load_sensor(n) for n in names]  # a bad name fails before the work starts
    if args.minutes * 60.0 < 1.0 or args.taxels < 1 or args.draws < 1:
        raise SkinError("--minutes must cover at least a second, --taxels and --draws must be "
                        "positive")
    if min(args.seeds) < 0:
        raise SkinError("--seeds must be non-negative")
    progress = Progress()
    started = time.monotonic()
    runs = []
    for sensor in sensors:
        for seed in args.seeds:
            progress.message(f"{sensor.name} seed {seed}")
            clock = time.monotonic()
            runs.append(measure_refine_bound(
                sensor, seed, args.minutes, args.taxels, args.draws,
                progress=lambda d, n, label, c=clock: progress.bar(d, n, label, c)))
            progress.done()
    doc = {"machine": machine(), "runs": runs,
           "wall_time": round(time.monotonic() - started, 2)}
    if args.json:
        print(json.dumps(doc))
        return 0
    print_runs(runs, args.draws)
    return 0


def print_runs(runs: list, draws: int) -> None:
    """Print `skin.bench.refine_bound.measure_refine_bound`'s figures, one table per run."""
    from skin.bench.refine_bound import VARIANTS

    print("Cramer-Rao bounds on the onset (unbiased estimators only); medians over contacts "
          f"with a floor, {draws} Monte-Carlo draws of |N(0, sd)| per contact")
    for r in runs:
        print(f"{r['sensor']} seed {r['seed']}: {r['contacts_with_floor']} contacts with a "
              f"floor (median {r['floor_ms_median']} ms), {r['detected_with_floor']} detected; "
              f"target {r['refined_onset_target_ms']} ms; library refined onset error median "
              f"{r['library_refined_onset_error_ms_median']} ms ({r['library_detected']} "
              f"detected; {r['library_error_ms_median_with_floor']} ms on those with a "
              f"floor), |error| / gain_offset sd median "
              f"{r['library_error_over_gain_offset_sd_median']} (gain_offset_drift: "
              f"{r['library_error_over_gain_offset_drift_sd_median']})")
        print(f"  {'variant':<18}{'sd med ms':>10}{'inf':>5}{'median ms':>11}"
              f"{'5-95 % ms':>19}{'P<=target':>10}   detected: {'median ms':>9}"
              f"{'P<=target':>10}")
        for name in VARIANTS:
            b = r["bounds"][name]
            d = b["detected"]
            span = "-" if b["p5_p95_ms"] is None else f"{b['p5_p95_ms'][0]}-{b['p5_p95_ms'][1]}"
            print(f"  {name:<18}{b['sd_ms_median']!s:>10}{b['contacts_inf']:>5}"
                  f"{b['median_ms']!s:>11}{span:>19}{b['p_meets_target']!s:>10}"
                  f"   detected: {d['median_ms']!s:>9}{d['p_meets_target']!s:>10}")

"""``skin bench gap``: issue 17's first target, the default against svm-pca and the ceilings.

The measurement is `skin.bench.gap.gap_table` (loaded only when run): per seed and duration,
svm-pca and the default (plain, and with the taxels commissioned from a reference set of the
same skin), the known-nuisance ceiling, the target line svm + 2/3 (ceiling - svm), and the
ceiling told less - what the information available allows without and with commissioning.
"""

from __future__ import annotations

import argparse


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench gap``."""
    gap = kinds.add_parser("gap", help="default vs svm-pca vs the known-nuisance ceiling and "
                                       "the ceiling told less (issue 17's target)")
    gap.add_argument("--trials", type=int, default=100, help="trials per material (100)")
    gap.add_argument("--seeds", default="7,13", help="comma-separated seeds (7,13)")
    gap.add_argument("--durations", default="0.25,0.5,1,1.5,2.5",
                     help="contact durations, s (0.25,0.5,1,1.5,2.5)")
    gap.add_argument("--cv", type=int, default=3, help="folds (3)")
    gap.add_argument("--reference-trials", type=int, default=20,
                     help="trials per material of the commissioning reference set (20)")
    gap.add_argument("--points", type=int, default=9,
                     help="grid points over each untold nuisance's range in the ceiling told "
                          "less (9; fewer is faster and lower)")
    gap.add_argument("--taxel-prior", choices=("box", "range"), default="box",
                     help="weights of the taxel grid in the ceiling told less: the mass the "
                          "simulated +-10%% box of constants gives each point (box, default) or "
                          "all alike (range: overweights extreme taxels, lower)")
    gap.add_argument("--reach-only", action="store_true",
                     help="only svm-pca, default, the ceiling and the two reaches (no "
                          "commissioned evaluations, no other told-less ceilings): faster")
    gap.add_argument("--json", action="store_true", help="print one JSON document")
    gap.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.gap.gap_table` and print the table (or JSON)."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.gap import (
        ALL_UNKNOWN,
        COMMISSIONED_UNKNOWN,
        TOLD_LESS,
        gap_table,
        pooled_margins,
    )
    from skin.errors import SkinError
    from skin.progress import Progress

    try:
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
        durations = [float(d) for d in args.durations.split(",") if d.strip()]
    except ValueError:
        raise SkinError("--seeds must be integers and --durations numbers") from None
    if not seeds or not durations or min(durations) <= 0:
        raise SkinError("give at least one seed and positive durations")
    if args.points < 2:
        raise SkinError("--points must be at least 2")
    if args.cv < 2 or args.trials * (args.cv - 1) // args.cv < 3 or args.reference_trials < 1:
        raise SkinError("--cv must be at least 2, --trials enough for 3 trials per material in "
                        "each training fold (trials x (cv - 1) / cv >= 3: the default "
                        "classifier calibrates on them), --reference-trials at least 1")
    progress = Progress()
    started = time.monotonic()
    rows = gap_table(args.trials, seeds, durations, args.cv, args.reference_trials,
                     args.points, progress=progress.message, reach_only=args.reach_only,
                     taxel_prior=args.taxel_prior)
    wall = time.monotonic() - started
    progress.done()
    pooled = pooled_margins(rows)
    if args.json:
        print(json.dumps({"machine": machine(), "trials": args.trials, "cv": args.cv,
                          "reference_trials": args.reference_trials,
                          "points": args.points, "taxel_prior": args.taxel_prior,
                          "reachable_unknown": list(ALL_UNKNOWN),
                          "reachable_commissioned_unknown": list(COMMISSIONED_UNKNOWN),
                          "wall_s": round(wall, 1), "rows": rows, "pooled": pooled}))
        return 0
    print(f"accuracy, {args.cv}-fold grouped, {args.trials} trials per material, 11 "
          f"materials, one heated channel; commissioned: {args.reference_trials} reference "
          f"trials per material by the same skin; target = svm + 2/3 (ceiling - svm); "
          f"reach = ceiling told less ({'+'.join(ALL_UNKNOWN)} integrated over their ranges), "
          f"reach-c = the same told the commissioned constants; {wall:.0f} s")
    head = ("seed", "dur s", "svm", "default", "svm-c", "default-c", "ceiling", "target",
            "met", "met-c", "reach", "reach-target", "+-", "reach-c", "out", "out-c")
    width = [max(10, len(h) + 2) for h in head]

    def cell(v) -> str:
        return "-" if v is None else ("yes" if v is True else "no" if v is False
                                      else f"{v:.3f}")

    print("".join(f"{h:>{w}}" for h, w in zip(head, width, strict=True)))
    for r in rows:
        cells = [r["seed"], f"{r['duration']:g}", *(cell(r[k]) for k in (
            "svm", "default", "svm_commissioned", "default_commissioned", "ceiling", "target",
            "met", "met_commissioned", "reachable", "margin", "margin_se",
            "reachable_commissioned", "ruled_out", "ruled_out_commissioned"))]
        print("".join(f"{c:>{w}}" for c, w in zip(cells, width, strict=True)))
    worst = max(v for r in rows for v in r["se"].values())
    t = max(r["margin_t"] for r in rows)
    print(f"+- : sampling error of reach - target (paired: the same contacts; clustered by "
          f"taxel, the contacts of one taxel are not independent); out: reach - target below "
          f"-{t:.2f} times it (Student's t, taxels - 1 degrees of freedom); out-c: the same "
          f"with reach-c; one accuracy's binomial error <= {worst:.3f}")
    for p in pooled:
        print(f"pooled over {p['seeds']} seeds, {p['duration']:g} s: reach - target "
              f"{p['margin']:+.3f} +- {max(p['se_within'], p['se_between']):.3f} (within "
              f"seeds {p['se_within']:.3f}, between {p['se_between']:.3f}), "
              f"{'ruled out' if p['ruled_out'] else 'not ruled out'} at t({p['seeds'] - 1}) "
              f"= {p['t']:.2f}; reach-c - target {p['margin_commissioned']:+.3f} +- "
              f"{p['se_commissioned']:.3f}; default - target {p['default_minus_target']:+.3f}"
              f" +- {p['default_se']:.3f}, met on {p['met_seeds']} of {p['seeds']} seeds")
    if any(r["told_less"] for r in rows):
        print("ceiling told less (untold nuisances integrated over their ranges):")
    names = ["+".join(u) for u in TOLD_LESS]
    for r in rows:
        if not r["told_less"]:
            continue
        print(f"  seed {r['seed']} {r['duration']:g} s: " + ", ".join(
            f"{n} {r['told_less'][n]:.3f}" for n in names))
    return 0

"""``skin bench response-noise``: how often contact-free windows pass the response check.

The measurement is `skin.bench.response_noise.measure_response_noise` (loaded only when run):
for each sensor preset and seed, a simulated stream (the heater's switches, the room's
drift, the sensor's loop, lag, noise, ADC and smoothing, contacts at ``--rate`` per taxel and
minute; the air's gusts and flutter only with ``--air``) gets phantom force onsets where
nothing touches, on single taxels and on groups of ``--group`` taxels; each window is tested
as the pipeline tests a force-dated contact (`skin.stream.response.check_contact`) at 2 and 3
sigma (the 5-sigma tail is too rare to count). Printed per preset: the pass rate over the
nominal two-sided rate, with a 95 % Clopper-Pearson interval; an honest tail reads <= 1
within it. Beside it, "one point": each grid point (material, conductance) alone at the single
test's threshold, the least, median and largest of their rates over nominal (the largest is the
top of as many noisy rates as there are points): above 1, the single test's tail is heavy for
that shape; all under 1 with the best above, the grid's correction falls short.
"""

from __future__ import annotations

import argparse

#: Shortest stream, s: a phantom window needs the tracker's search span before its onset (up
#: to 4 s) and the classifier's window after it (2.5 s).
MIN_DURATION = 10.0


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench response-noise``."""
    p = kinds.add_parser("response-noise", help="contact-free windows passing the response "
                         "check at 2 and 3 sigma, against the nominal rate, per sensor",
                         description=__doc__)
    p.add_argument("--sensors", nargs="+", default=None, metavar="PRESET|FILE",
                   help="sensor presets or files (default: every preset, `skin sensors`)")
    p.add_argument("--seeds", nargs="+", type=int, default=[0], help="stream seeds (0)")
    p.add_argument("--duration", type=float, default=60.0, help="seconds per stream (60)")
    p.add_argument("--taxels", type=int, default=72, help="taxels per stream (72)")
    p.add_argument("--group", type=int, default=4,
                   help="taxels of the multi-taxel phantom contacts (4; 1: single only)")
    p.add_argument("--rate", type=float, default=1.0,
                   help="real contacts per taxel and minute in the streams, which phantoms "
                        "avoid (1; their reheat is in the samples before later onsets)")
    p.add_argument("--air", action="store_true",
                   help="also the streams' air currents (gusts and flutter: thermal changes "
                        "outside the test's noise model; a gust is a response without contact)")
    p.add_argument("--json", action="store_true", help="print one JSON document")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.response_noise.measure_response_noise` per sensor and seed; print."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.response_noise import measure_response_noise, summarise, summarise_real
    from skin.errors import SkinError
    from skin.models.sensors import load_sensor, load_sensors
    from skin.progress import Progress
    from skin.stream.response import RESPONSE_SIGMAS

    if args.duration <= 0 or args.taxels < 1 or args.group < 1 or args.rate < 0:
        raise SkinError("--duration, --taxels and --group must be positive, --rate >= 0")
    if args.group > args.taxels:
        raise SkinError(f"--group {args.group} is more than --taxels {args.taxels}")
    if args.duration < MIN_DURATION:
        raise SkinError(f"--duration {args.duration:g} s is too short: a phantom window needs "
                        f"the tracker's search span before it and the classifier's window "
                        f"after it (at least {MIN_DURATION:g} s)")
    if min(args.seeds) < 0:
        raise SkinError("--seeds must be non-negative")
    sensors = args.sensors or list(load_sensors())
    for name in sensors:  # a bad name or file fails before the work starts
        load_sensor(name)
    sizes = (1,) if args.group == 1 else (1, args.group)
    progress = Progress()
    started = time.monotonic()
    runs = []
    for name in sensors:
        for seed in args.seeds:
            label = f"{name} seed {seed}: windows"
            runs.append(measure_response_noise(
                name, seed, args.duration, args.taxels, sizes, args.rate, args.air,
                progress=lambda d, n, label=label: progress.bar(d, n, label, started)))
    progress.done()
    rows, real = summarise(runs), summarise_real(runs)
    out = {"machine": machine(), "sensors": sensors, "seeds": args.seeds,
           "duration": args.duration, "taxels": args.taxels, "air": args.air, "runs": runs,
           "rows": rows, "real": real,
           "wall_time": round(time.monotonic() - started, 2)}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"contact-free windows passing the response check ({len(args.seeds)} seeds x "
          f"{args.duration:g} s x {args.taxels} taxels, air currents "
          f"{'on' if args.air else 'off'}; pass rate / nominal, 95 % CI; 'one point': each "
          f"grid point alone at the single test's threshold, least / median / largest)")
    print(f"{'sensor':<12} {'taxels':>6} {'sigma':>5} {'windows':>8} {'passed':>7} "
          f"{'nominal':>8} {'ratio':>6}  {'CI95':<9}  one point")
    for r in rows:
        ratio = "-" if r["ratio"] is None else f"{r['ratio']:.2f}"
        print(f"{r['sensor']:<12} {r['taxels']:>6} {r['sigmas']:>5g} {r['windows']:>8} "
              f"{r['passed']:>7} {r['nominal']:>8.4f} {ratio:>6}  "
              + ("-".ljust(9) if r["ratio_ci95"] is None
                 else f"{r['ratio_ci95'][0]:.2f}-{r['ratio_ci95'][1]:.2f}".ljust(9))
              + ("  -" if r["point_ratio"] is None
                 else "  " + " / ".join(f"{v:.2f}" for v in r["point_ratio"]))
              + (f" ({r['untested']} untested)" if r["untested"] else ""))
    print(f"real contacts, each force-dated at its onset on its own taxel, showing a response "
          f"at {RESPONSE_SIGMAS:g} sigma (the cost: those that do not are answered unknown):")
    for r in real:
        print(f"  {r['sensor']:<12} {r['responded']} of {r['contacts']}"
              + ("" if r["rate"] is None else
                 f" ({r['rate']:.3f}, 95 % CI {r['rate_ci95'][0]:.3f}-{r['rate_ci95'][1]:.3f})"))
    for r in runs:
        if r["dof_median"] is not None:
            print(f"  {r['sensor']} seed {r['seed']}: noise dof median {r['dof_median']}")
    return 0

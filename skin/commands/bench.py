"""``skin bench``: error (or accuracy) against run time, printed as figures.

``skin bench thermal`` runs every forward model and discretisation on a 2.5 s contact (RMS
error against the closed form or a converged reference, and run time per trial), then the
inverse estimators on simulated trials (effusivity error against contact duration, and run
time per trial). ``--plot DIR`` draws the work-precision diagram and the estimator errors.

``skin bench fusion`` touches cold, warm and room-temperature objects with one or several
taxels (at one initial temperature, or staggered) and reports the accuracy and cost per
contact of the joint model that shares the object's temperature between them
(`skin.models.joint`).

``skin bench pipeline`` pushes a simulated skin of each size (boards of 256 taxels), generated
in chunks of 1 s so that memory stays bounded, through
decode, assemble, calibrate, onset, track, refine and classify one sample at a time and
reports taxel-samples per second of the chain and of each stage, the real-time factor at
200 Hz, the per-sample latency, how long results wait for their share of the budget, and the
memory growth (`skin.bench.pipeline`).

``skin bench soak --hours H --taxels N`` runs the whole chain (simulated boards on
pseudo-terminals, serial drivers, pipeline, JSON-lines sink, MCAP recording) as fast as it goes
for H simulated hours and reports memory and open file descriptors over time, contacts per
simulated hour (or minute), lost frames and the growth of memory (`skin.bench.soak`).

``skin bench bus`` prints what protocol v1 costs on each bus at a sample rate: bytes (and CAN
frames) per sample, bytes per second, the share of the bus, and the most taxels one board can
stream (`skin.drivers.bus_load`), beside what one AVR's ADC can convert.

``skin bench drivers`` measures decode throughput (frames/s, taxel-samples/s, us per frame) of
each driver backend at 64 and 1000 taxels, beside the physical frame rate of the links, so the
margins are plain (`skin.bench.drivers`). ``skin bench fuzz`` feeds every decoder
damaged streams and reports crashes, corrupt frames accepted against the CRC's theoretical
rate, and resynchronisation (`skin.bench.fuzz`). ``skin bench clock`` maps device time to
host time under three transports (USB serial, a loaded host with stalls, CAN over UDP) with
each method (the arrival time, a running minimum offset, `skin.drivers.clock.ClockMap` with
blocks of 0.5-2 s) and prints the error against the true sampling time beside the cost per
frame (`skin.bench.clock`).

``skin bench view`` times one update of the arm view (every taxel's colour computed and
written into the mesh's colour array) beside one render, for skins of 72-1000 taxels on
meshes of 14k and 100k vertices, with a baseline of the same run (`skin.bench.view`).

``skin bench publish`` measures what publishing costs: the pipeline's throughput with a
Zenoh or Foxglove publisher attached against without, and the latency from a sample to a
subscriber in another process at the skin's real rate (`skin.bench.publish`).

``skin bench calibration`` runs simulated calibrations (each taxel's constants drawn within
+-10 % of the paper's, a few contacts with a reference material) and reports how well
`skin.models.sensor_fit.fit_sensor_constants` recovers them, against the nominal constants,
with the fit time per taxel. ``skin bench commission --sensor PRESET`` does the same for
`skin commission --touches` on a unit of any sensor preset: reference touches of water and
neoprene through each one's air gap (``--references``, ``--contact perfect`` for none), the
preset's ADC and smoothing, detected (or ``--labelled``) and fitted, with the response
time's and the effusivity's error against the unit's truth, nominal and fitted, beside the
fit's CPU time (`skin.bench.commission`); ``--classify`` measures
issue 16's target: issue 4's benchmark recorded by the same taxels, classified with their
true and their commissioned constants (`skin.bench.commission.classify`).

``skin bench map`` runs the shared map service with several robots publishing contacts and
reports lost contacts, the time from a contact's decision to its query visibility, and a
1 m^3 box query over a 1 M-voxel map (`skin.bench.map`).

``skin bench tracking`` plays touches of several taxels and pairs of touches on neighbouring
taxels through the pipeline and counts the touches made one whole contact, split into
pieces, merged with another, or missed, beside the tracker's cost (`skin.bench.tracking`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from skin.commands import (
    bench_delay_bound,
    bench_drivers,
    bench_envelope_rate,
    bench_forward,
    bench_gap,
    bench_map,
    bench_onset_shape,
    bench_refine_bound,
    bench_response_noise,
    bench_scene,
    bench_tracking,
    bench_view,
)
from skin.progress import Progress


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin bench``."""
    bench = sub.add_parser("bench", help="error against run time (work-precision)",
                           description=__doc__)
    kinds = bench.add_subparsers(dest="kind", required=True)
    thermal = kinds.add_parser("thermal", help="forward models and inverse estimators")
    thermal.add_argument("--full", action="store_true",
                         help="also the finest grid (96 sensor cells; slower)")
    thermal.add_argument("--quick", action="store_true",
                         help="one coarse grid, two time steps, few trials (a smoke run)")
    thermal.add_argument("--trials", type=int, default=60,
                         help="simulated trials per material for the estimators (default 60)")
    thermal.add_argument("--plot", metavar="DIR", help="write the figures (PNG) into DIR")
    thermal.add_argument("--json", action="store_true", help="print one JSON document")
    thermal.set_defaults(func=main_thermal)
    fusion = kinds.add_parser("fusion", help="several taxels on one cold or warm object")
    fusion.add_argument("--materials", default="aluminium,brick,cardboard,glass,neoprene,pine",
                        help="comma-separated objects (default: one of each group the table "
                             "can tell apart)")
    fusion.add_argument("--trials", type=int, default=40,
                        help="contacts per material and case (default 40)")
    fusion.add_argument("--durations", default="0.5,1,2.5", help="contact durations, s")
    fusion.add_argument("--offset", type=float, default=8.0,
                        help="objects also drawn within +-OFFSET K of ambient (default 8)")
    fusion.add_argument("--seed", type=int, default=0, help="seed of the scene")
    fusion.add_argument("--json", action="store_true", help="print one JSON document")
    fusion.set_defaults(func=main_fusion)
    pipe = kinds.add_parser("pipeline", help="throughput of the streaming chain")
    pipe.add_argument("--taxels", default="64,1000,10000",
                      help="skin sizes (default 64,1000,10000; boards of 256 taxels)")
    pipe.add_argument("--seconds", type=float, default=30.0,
                      help="simulated seconds (30; contacts start in all but the last 10)")
    pipe.add_argument("--contacts-per-minute", type=float, default=6.0,
                      help="contacts per taxel and minute (6)")
    pipe.add_argument("--budget", type=float, default=1.0,
                      help="ms per sample for refining and classifying; 0: one step a sample, "
                           "-1: no budget, every contact finished at once (1)")
    pipe.add_argument("--workers", default="1",
                      help="board worker processes to compare, e.g. 1,2 (default 1: one "
                           "process; skin.stream.board_workers; the first is the baseline)")
    pipe.add_argument("--block", type=int, default=1,
                      help="samples the pipeline takes per call (1: each as it comes; "
                           "skin run takes up to 20)")
    pipe.add_argument("--compare-envelope", action="store_true",
                      help="also run each size (one process) with the onset detector's two "
                           "gust-envelope margins, the noise table's (envelope_noise) and the "
                           "flat one, and give the first's throughput over the second's "
                           "(same run, in the order noise, flat, flat, noise: each margin's "
                           "run with the faster onset stage)")
    pipe.add_argument("--compare-force", action="store_true",
                      help="also run each size (one process) with a force channel on every "
                           "taxel (a FORCE packet after each SAMPLE, 2 N while touched; the "
                           "pipeline dates contacts by it) and without, and give with's "
                           "throughput over without's (order with, without, without, with)")
    pipe.add_argument("--compare-common-mode", action="store_true",
                      help="also run each size (one process) with the onset detector's board "
                           "common mode on and off (its default: on where the heater is not "
                           "PID-held), and give on's throughput "
                           "over off's (same run, in the order on, off, off, on: each one's "
                           "run with the faster onset stage)")
    pipe.add_argument("--json", action="store_true", help="print one JSON document")
    pipe.set_defaults(func=main_pipeline)
    soak = kinds.add_parser("soak", help="the whole chain for hours of simulated time")
    soak.add_argument("--hours", type=float, default=1.0, help="simulated hours (1)")
    soak.add_argument("--taxels", type=int, default=1000,
                      help="skin size (1000; boards of 256 taxels, one simulated board each)")
    soak.add_argument("--every", type=float, default=None,
                      help="simulated seconds between memory samples (default: 60 samples)")
    soak.add_argument("--seed", type=int, default=0, help="seed of the simulated boards (0)")
    soak.add_argument("--no-record", dest="record", action="store_false",
                      help="leave out the MCAP recording")
    soak.add_argument("--out", default=None,
                      help="keep the events and the recording in this folder (default: a "
                           "temporary folder, removed after)")
    soak.add_argument("--wall-hours", type=float, default=None,
                      help="stop after this many wall-clock hours and report the simulated "
                           "time reached (default: run to the end)")
    soak.add_argument("--json", action="store_true", help="print one JSON document")
    soak.set_defaults(func=main_soak)
    bus = kinds.add_parser("bus", help="protocol cost and taxel limits per bus")
    bus.add_argument("--taxels", default="16,64", help="board sizes (default 16,64)")
    bus.add_argument("--rate", type=float, default=200.0, help="sample rate, Hz (default 200)")
    bus.add_argument("--force", action="store_true",
                     help="boards that also send their force channel (FORCE)")
    bus.add_argument("--json", action="store_true", help="print one JSON document")
    bus.set_defaults(func=main_bus)
    cal = kinds.add_parser("calibration", help="recovering each taxel's thermal constants")
    cal.add_argument("--reference", default="water", help="reference material (water)")
    cal.add_argument("--taxels", type=int, default=20, help="simulated taxels (20)")
    cal.add_argument("--contacts", type=int, default=4, help="reference contacts per taxel (4)")
    cal.add_argument("--duration", type=float, default=2.0, help="seconds per contact (2)")
    cal.add_argument("--seed", type=int, default=0, help="seed")
    cal.add_argument("--json", action="store_true", help="print one JSON document")
    cal.set_defaults(func=main_calibration)
    pub = kinds.add_parser("publish", help="what publishing (Zenoh, Foxglove) costs, latency")
    pub.add_argument("--taxels", type=int, default=1000, help="skin size (1000)")
    pub.add_argument("--seconds", type=float, default=10.0, help="simulated seconds (10)")
    pub.add_argument("--chunk", type=int, default=1,
                     help="samples the pipeline takes at once (1: each as it comes)")
    pub.add_argument("--publishers", default="zenoh,foxglove", help="zenoh,foxglove")
    pub.add_argument("--json", action="store_true", help="print one JSON document")
    pub.set_defaults(func=main_publish)
    spread = kinds.add_parser("spread", help="per-taxel spread of the simulated skin against "
                                             "a calibration file of its true constants")
    spread.add_argument("--touches", type=int, default=120, help="touches in the scene (120)")
    spread.add_argument("--spread", type=float, default=0.10,
                        help="relative spread of each taxel's constants (0.10)")
    spread.add_argument("--sensor", default="", help="sensor preset (default: the paper's)")
    spread.add_argument("--seed", type=int, default=0, help="seed")
    spread.add_argument("--calibration", metavar="FILE", default=None,
                        help="a fourth run classified with this file's constants (e.g. from "
                             "`skin commission --touches` on the same unit: same seed), and a "
                             "fifth with the median of its constants (the design: what carries "
                             "over from another unit)")
    spread.add_argument("--durations", default=None, metavar="S1,S2,...",
                        help="hold every touch this long, one set of runs each (e.g. "
                             "0.5,1,2.5; default: touches of 1.5-3 s)")
    spread.add_argument("--model", metavar="FILE", default=None,
                        help="classify with this model file (skin train) in place of the "
                             "joint classifier; one trained with --calibration warps each "
                             "run's taxels with its constants and sits out the spread run, "
                             "which has none")
    spread.add_argument("--contact", choices=("perfect", "finite"), default="perfect",
                        help="simulated contact: perfect (default) or finite, with each "
                             "material's contact conductance (as skin simulate trials)")
    spread.add_argument("--json", action="store_true", help="print one JSON document")
    spread.set_defaults(func=main_spread)
    com = kinds.add_parser("commission", help="commissioning a simulated unit from reference "
                                              "touches against its true constants")
    com.add_argument("--sensor", default="paper", help="sensor preset (paper)")
    com.add_argument("--seed", type=int, default=7, help="the unit: seed of its taxels (7)")
    com.add_argument("--taxels", type=int, default=8, help="taxels touched (8)")
    com.add_argument("--touches", type=int, default=6,
                     help="reference touches, the --references alternately (6)")
    com.add_argument("--hold", type=float, default=None,
                     help="hold each touch, s (default: what skin commission asks for)")
    com.add_argument("--rest", type=float, default=None,
                     help="rest between touches, s (default: what skin commission asks for)")
    com.add_argument("--spread", type=float, default=0.10,
                     help="relative spread of each taxel's constants (0.10)")
    com.add_argument("--labelled", action="store_true",
                     help="fit from the scripted touch times (as --labels), not detected ones")
    com.add_argument("--contact", choices=("perfect", "finite"), default="finite",
                     help="the reference touches' contact: finite (default), a conductance "
                          "from each material's range (as skin simulate trials and real "
                          "hardware), or perfect (eq. 5, no air gap)")
    com.add_argument("--references", default="water,neoprene", metavar="A,B",
                     help="reference materials touched in turn (water,neoprene: both conform, "
                          "so their contact is near perfect); aluminium,pine were the default "
                          "before, and through their air gaps leave the response time 8.5-25 "
                          "%% off")
    com.add_argument("--force", choices=("", "force", "contact"), default="",
                     help="the taxels' force channel: none (default), a force sensor (2 N "
                          "touches, 5 mN noise) or a contact switch; it then dates the touches")
    com.add_argument("--classify", action="store_true",
                     help="issue 16's target instead: issue 4's benchmark recorded by this "
                          "unit's taxels, classified by the joint classifier told the true, "
                          "the commissioned, another unit's (--other-seed) and the nominal "
                          "constants, with each gap's paired standard error and verdict "
                          "(met, not met or unresolved by its 95 %% interval against 3 points)")
    com.add_argument("--trials", type=int, default=40,
                     help="with --classify: trials per material (40; 11 materials)")
    com.add_argument("--durations", default="0.5,1,2.5",
                     help="with --classify: windows, s (0.5,1,2.5)")
    com.add_argument("--other-seed", type=int, default=None,
                     help="with --classify: the other unit commissioned (default seed + 1)")
    com.add_argument("--noise", choices=("described", "measured", "model"),
                     default="described",
                     help="with --classify: the classifier's reading noise, a grid to 0.1 K "
                          "from the sensor description's white noise (described, default) or "
                          "from the noise of the commissioning recording's quiet stretch (the "
                          "2.5 s before its first touch; white-equivalent by the sensor's "
                          "smoothing: measured), or the joint classifier's own 0.1 K whatever "
                          "the sensor (model, the default before)")
    com.add_argument("--noiseless", action="store_true",
                     help="with --classify: the benchmark recorded without the sensor's reading "
                          "noise (the commissioning keeps it): what the noise costs")
    com.add_argument("--object-std", type=float, default=10.0,
                     help="with --classify: the classifier's prior std of the object's "
                          "temperature about ambient, K (10)")
    com.add_argument("--json", action="store_true", help="print one JSON document")
    com.set_defaults(func=main_commission)
    nui = kinds.add_parser("nuisance", help="what each nuisance of the synthetic benchmark "
                                            "costs the classifiers (one fixed at a time)")
    nui.add_argument("--variants", default=None,
                     help="comma-separated (default all): " + ", ".join(
                         ["protocol", "sensor_start", "object_temperature", "taxel_constants",
                          "conductance", "onset", "adc_noise"]))
    nui.add_argument("--methods", default="default,svm-pca,ceiling",
                     help="methods of skin evaluate, and 'ceiling' (default,svm-pca,ceiling)")
    nui.add_argument("--durations", default="0.5,1.5", help="contact durations, s (0.5,1.5)")
    nui.add_argument("--trials", type=int, default=100, help="trials per material (100)")
    nui.add_argument("--seed", type=int, default=7, help="seed of the datasets (7)")
    nui.add_argument("--sensor", default=None, help="sensor preset (default: the paper's)")
    nui.add_argument("--json", action="store_true", help="print one JSON document")
    nui.set_defaults(func=main_nuisance)
    op = kinds.add_parser("object-prior", help="one-taxel contacts with the fixed and the "
                                                "learned prior on the object's temperature")
    op.add_argument("--touches", type=int, default=100, help="touches per scene (100)")
    op.add_argument("--single", type=float, default=0.4,
                    help="share of touches by one taxel only (0.4)")
    op.add_argument("--off", default="0,0.3",
                    help="shares of cold or warm objects, one scene each (0,0.3)")
    op.add_argument("--offset", type=float, default=8.0,
                    help="how far cold and warm objects sit from ambient, K (8)")
    op.add_argument("--seed", type=int, default=0, help="seed of the scenes (0)")
    op.add_argument("--json", action="store_true", help="print one JSON document")
    op.set_defaults(func=main_object_prior)
    bench_drivers.add_parsers(kinds)
    bench_view.add_parsers(kinds)
    bench_map.add_parsers(kinds)
    bench_onset_shape.add_parsers(kinds)
    bench_delay_bound.add_parsers(kinds)
    bench_refine_bound.add_parsers(kinds)
    bench_envelope_rate.add_parsers(kinds)
    bench_tracking.add_parsers(kinds)
    bench_scene.add_parsers(kinds)
    bench_forward.add_parsers(kinds)
    bench_gap.add_parsers(kinds)
    bench_response_noise.add_parsers(kinds)


def main_object_prior(args: argparse.Namespace) -> int:
    """``skin bench object-prior``: the joint classifier's fixed and learned object prior."""
    from skin import bench
    from skin.bench.object_prior import run
    from skin.errors import SkinError

    offs = tuple(float(v) for v in args.off.split(",") if v.strip())
    if args.touches < 1 or not 0 <= args.single <= 1 or any(not 0 <= v <= 1 for v in offs):
        raise SkinError("--touches must be at least 1, --single and --off shares within 0-1")
    progress = Progress()
    started = time.monotonic()
    rows = run(args.touches, args.single, offs, args.offset, args.seed,
               progress=lambda d, n: progress.bar(d, n, "runs", started))
    progress.done()
    if args.json:
        print(json.dumps({"machine": bench.machine(), "seed": args.seed, "rows": rows}))
        return 0
    print(f"{args.touches} touches of 0.4-2.5 s on the arm, {args.single:.0%} by one taxel, "
          f"seed {args.seed}; sure = answers at p >= 0.9")
    print(f"{'off-ambient':>11} {'prior':<8} {'contacts':<15} {'n':>3} {'material':>8} "
          f"{'family':>6} {'unknown':>7} {'sure':>4} {'right':>5} {'ECE':>5} {'std K':>6}")
    for r in rows:
        for key in ("one taxel", "several taxels"):
            c = r[key]
            if not c["contacts"]:
                continue
            right = "-" if c["sure_right"] is None else f"{c['sure_right']:.2f}"
            print(f"{r['off_ambient_share']:>11.0%} {r['object_prior']:<8} {key:<15} "
                  f"{c['contacts']:>3} {c['material']:>8.3f} {c['family']:>6.3f} "
                  f"{c['unknown']:>7.3f} {c['sure']:>4} {right:>5} "
                  f"{c['calibration_error']:>5.3f} {r['learned_prior_std']:>6.2f}")
    return 0


def main_nuisance(args: argparse.Namespace) -> int:
    """``skin bench nuisance``: the synthetic benchmark with one nuisance fixed at a time."""
    from skin import bench
    from skin.bench.nuisance import VARIANTS, nuisance_table
    from skin.errors import SkinError

    variants = list(VARIANTS) if args.variants is None else \
        [v.strip() for v in args.variants.split(",") if v.strip()]
    bad = [v for v in variants if v not in VARIANTS]
    if bad or args.trials < 3:
        raise SkinError(f"unknown variant(s) {', '.join(bad)}; known: {', '.join(VARIANTS)}"
                        if bad else "--trials must be at least 3 (3-fold cross-validation)")
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    durations = [float(d) for d in args.durations.split(",") if d.strip()]
    progress = Progress()
    rows = nuisance_table(variants, methods, durations, args.trials, args.seed, args.sensor,
                          progress=progress.message)
    progress.done()
    if args.json:
        print(json.dumps({"machine": bench.machine(), "seed": args.seed,
                          "sensor": args.sensor or "paper", "variants": VARIANTS,
                          "rows": rows}))
        return 0
    print(f"accuracy, 3-fold, {args.trials} trials per material, seed {args.seed}, sensor "
          f"{args.sensor or 'paper'}; each row fixes one nuisance:")
    methods = [m for m in methods if any(r["method"] == m for r in rows)]
    cols = [(m, d) for d in durations for m in methods]
    print(f"{'fixed':<20}" + "".join(f"{m[:9]:>10} {d:<4g}" for m, d in cols))
    for v in variants:
        acc = {(r["method"], r["duration"]): r["accuracy"] for r in rows if r["variant"] == v}
        print(f"{v:<20}" + "".join(f"{acc[c]:>15.3f}" for c in cols))
    return 0


def main_thermal(args: argparse.Namespace) -> int:
    """Run the thermal benchmark."""
    from skin import bench
    from skin.bench import thermal as thermal_bench

    progress = Progress()
    started = time.monotonic()
    cells = (12, 24, 48, 96) if args.full else (12,) if args.quick else (12, 24, 48)
    dts = (0.1, 0.02) if args.quick else (0.1, 0.02, 0.005, 0.001)
    forward = thermal_bench.forward(
        cells=cells, dts=dts, progress=lambda d, n: progress.bar(d, n, "forward", started))
    progress.done()
    started_inv = time.monotonic()
    inverse, per_material = thermal_bench.inverse(
        durations=(0.25, 2.5) if args.quick else (0.25, 0.5, 1.0, 2.5),
        trials=3 if args.quick else args.trials,
        progress=lambda d, n: progress.bar(d, n, "inverse", started_inv))
    progress.done()
    doc = {"machine": bench.machine(), "wall_time": round(time.monotonic() - started, 2),
           "forward": forward, "inverse": inverse, "inverse_per_material": per_material}
    if args.plot:
        from skin.viz.plots import plot_estimator_errors, plot_work_precision

        out = Path(args.plot)
        doc["figures"] = [str(plot_work_precision(forward, out / "work_precision.png")),
                          str(plot_estimator_errors(inverse, out / "estimators.png"))]
    if args.json:
        print(json.dumps(doc))
        return 0
    base = {r["case"]: r["time_per_trial_ms"] for r in forward
            if r["model"] == "semi-infinite"}
    print(f"forward models, 2.5 s contact, each row on the same {forward[0]['trials']} "
          f"distinct trials; time relative to the semi-infinite closed form of the same case "
          f"({doc['machine']['cpus']} cores)")
    print(f"{'case':<10} {'model':<43} {'scheme':<15} {'cells':>5} {'dt s':>7} "
          f"{'rms err K':>10} {'ms/trial':>9} {'x closed':>9}")
    for r in forward:
        cells_s = "-" if r["cells"] is None else str(r["cells"])
        dt_s = "-" if r["dt"] is None else f"{r['dt']:g}"
        model = r["model"] + ("" if not r.get("conductance") else " h~3000")
        print(f"{r['case']:<10} {model:<43} {r['scheme']:<15} {cells_s:>5} {dt_s:>7} "
              f"{r['rms_error']:>10.2e} {r['time_per_trial_ms']:>9.3f} "
              f"{r['time_per_trial_ms'] / base[r['case']]:>9.0f}")
    print("\ninverse estimators on simulated trials (paper's protocol, 11 materials)")
    print(f"{'estimator':<28} {'dur s':>6} {'valid':>6} {'median |dlog10 e|':>18} "
          f"{'p90':>6} {'converged':>9} {'in 2 std':>8} {'ms/trial':>9}")
    for r in inverse:
        med = "-" if r["median_abs_log10_error"] is None else f"{r['median_abs_log10_error']:.3f}"
        p90 = "-" if r["p90_abs_log10_error"] is None else f"{r['p90_abs_log10_error']:.3f}"
        conv = f"{r['converged']:.2f}" if "converged" in r else "-"
        cover = f"{r['within_2_std']:.2f}" if "within_2_std" in r else "-"
        print(f"{r['estimator']:<28} {r['duration']:>6g} {r['valid']:>6.2f} {med:>18} "
              f"{p90:>6} {conv:>9} {cover:>8} {r['time_per_trial_ms']:>9.3f}")
    last = per_material[0]["duration"] if per_material else None
    print("(least squares (profile): the median of the profile posterior; in 2 std: the "
          "share of true values inside its interval, median width " + ", ".join(
              f"{r['median_interval_width']:.2f}" for r in inverse
              if "median_interval_width" in r) + " decades)")
    print(f"\nbias per material at {last:g} s: median signed dlog10 e (valid trials); "
          f"fits: share within 2 reported std (profile interval: inside it)")
    ests = list(dict.fromkeys(r["estimator"] for r in per_material))
    print(f"{'material':<12} {'e':>8} " + " ".join(f"{e[:22]:>22}" for e in ests))
    for m in dict.fromkeys(r["material"] for r in per_material):
        cells = []
        for e in ests:
            r = next(x for x in per_material if x["material"] == m and x["estimator"] == e)
            bias = "out of range" if r["median_log10_error"] is None \
                else f"{r['median_log10_error']:+.2f}"
            if r["valid"] < 1:
                bias += f" ({r['valid']:.0%} valid)"
            if "within_2_std" in r:
                bias += f" [{r['within_2_std']:.2f}]"
            cells.append(f"{bias:>22}")
        e_true = next(x["true_effusivity"] for x in per_material if x["material"] == m)
        print(f"{m:<12} {e_true:>8.0f} " + " ".join(cells))
    if "figures" in doc:
        print("figures: " + ", ".join(doc["figures"]))
    return 0


def main_fusion(args: argparse.Namespace) -> int:
    """Run the fusion benchmark."""
    from skin import bench
    from skin.bench import fusion as fusion_bench
    from skin.errors import SkinError
    from skin.models import load_materials

    table = load_materials()
    names = [n.strip() for n in args.materials.split(",") if n.strip()]
    unknown = [n for n in names if n not in table]
    if unknown or len(names) < 2:
        raise SkinError(f"--materials wants at least two known materials; unknown: "
                        f"{', '.join(unknown) or 'none'}")
    try:
        durations = [float(d) for d in args.durations.split(",") if d.strip()]
    except ValueError:
        raise SkinError(f"--durations must be numbers, got {args.durations!r}") from None
    if args.trials < 1 or not durations or min(durations) <= 0:
        raise SkinError("--trials must be at least 1 and --durations positive")
    progress = Progress()
    started = time.monotonic()
    rows = fusion_bench.run([table[n] for n in names], trials=args.trials, durations=durations,
                            offsets=((0.0, 0.0), (-args.offset, args.offset)), seed=args.seed,
                            progress=lambda d, n: progress.bar(d, n, "contacts", started))
    progress.done()
    doc = {"machine": bench.machine(), "materials": names, "trials": args.trials,
           "wall_time": round(time.monotonic() - started, 2), "results": rows}
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"joint model, {len(names)} materials x {args.trials} contacts per case "
          f"({doc['machine']['cpus']} cores); chance {1 / len(names):.2f}")
    print("accuracy with the paper's nominal constants, each taxel's fitted from water "
          "contacts, and its true ones")
    print(f"{'object vs ambient':<18} {'taxels':<26} {'dur s':>6} {'nominal':>8} "
          f"{'fitted':>7} {'true':>6} {'ms/contact':>11}")
    for r in rows:
        lo, hi = r["object_offset"]
        where = "at ambient" if lo == hi == 0 else f"{lo:+g} to {hi:+g} K"
        print(f"{where:<18} {r['arrangement']:<26} {r['duration']:>6g} {r['accuracy']:>8.3f} "
              f"{r['accuracy_fitted']:>7.3f} {r['accuracy_calibrated']:>6.3f} "
              f"{r['ms_per_contact']:>11.2f}")
    return 0


def main_calibration(args: argparse.Namespace) -> int:
    """Run the calibration recovery benchmark."""
    from skin import bench
    from skin.errors import SkinError
    from skin.models import load_materials
    from skin.models.sensor_fit import recovery

    if args.reference not in load_materials():
        raise SkinError(f"unknown reference material {args.reference!r}")
    if args.taxels < 1 or args.contacts < 1 or args.duration <= 0:
        raise SkinError("--taxels and --contacts must be at least 1, --duration positive")
    from skin.stream.calibration import thermistor_recovery

    started = time.monotonic()
    doc = {"machine": bench.machine(), **recovery(args.taxels, args.contacts, args.duration,
                                            reference=args.reference, seed=args.seed),
           "thermistors": thermistor_recovery(args.taxels, seed=args.seed),
           "wall_time": round(time.monotonic() - started, 2)}
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"{args.taxels} simulated taxels (constants within +-10 %), {args.contacts} contacts "
          f"of {args.duration:g} s with {args.reference} ({doc['machine']['cpus']} cores)")
    print(f"{'relative error':<16} {'nominal median':>15} {'p95':>7} {'fitted median':>14} "
          f"{'p95':>7}")
    for key in ("diffusivity", "conductivity", "effusivity"):
        b, a = doc["nominal_error"][key], doc["fitted_error"][key]
        print(f"{key:<16} {b['median']:>15.4f} {b['p95']:>7.4f} {a['median']:>14.4f} "
              f"{a['p95']:>7.4f}")
    print(f"fit time {doc['ms_per_taxel']} ms per taxel")
    th = doc["thermistors"]
    print(f"thermistors (R25 +-3 %, B +-1 %; {th['readings']} readings at "
          f"{', '.join(f'{r:g}' for r in th['references'])} C, two-term fit): largest error "
          f"over 25-45 C, median {th['nominal_max_error_k']['median']} K nominal -> "
          f"{th['fitted_max_error_k']['median']} K fitted (p95 "
          f"{th['nominal_max_error_k']['p95']} -> {th['fitted_max_error_k']['p95']} K)")
    return 0


def main_commission(args: argparse.Namespace) -> int:
    """``skin bench commission``: commissioning error against a simulated unit's truth."""
    from skin import bench
    from skin.bench.commission import run
    from skin.errors import SkinError

    if args.taxels < 1 or args.touches < 2 or not 0 <= args.spread < 1:
        raise SkinError("--taxels must be at least 1, --touches at least 2 and --spread "
                        "within [0, 1)")
    for name in ("hold", "rest"):
        if getattr(args, name) is not None and getattr(args, name) <= 0:
            raise SkinError(f"--{name} must be positive")
    from skin.commands.commission import _reference_names
    from skin.models import load_materials

    args.reference_list = tuple(_reference_names(args.references, load_materials(),
                                                 option="--references"))
    if args.classify:
        return _commission_classify(args)
    print("simulating and commissioning...", file=sys.stderr, flush=True)
    doc = {"machine": bench.machine(),
           **run(args.sensor, args.seed, args.taxels, args.touches, args.hold, args.rest,
                 args.spread, args.labelled, args.contact, args.reference_list,
                 args.force)}
    if args.json:
        print(json.dumps(doc))
        return 0
    c = doc["counts"]
    print(f"{doc['sensor']}, unit (seed) {doc['seed']}: {doc['touches']} touches held "
          f"{doc['hold']:g} s, {doc['rest']:g} s apart, on {doc['taxels_touched']} taxels "
          f"({'labelled' if doc['labelled'] else 'force-dated' if doc['force'] else 'detected'}"
          f"); {c['detected']} taxel-touches, "
          f"{c['left_out']} left out, {c['ambiguous']} ambiguous; {c['taxels_fitted']} taxels "
          f"fitted in {doc['fit_cpu_seconds']:g} CPU s ({doc['recording_seconds']:g} s "
          f"recorded; {doc['machine']['cpus']} cores)")
    if "assignment" in doc:
        a = doc["assignment"]
        print("touches named over the response-time sweep: {ambiguous} ambiguous, {wrong} "
              "wrong, {cpu_seconds:g} CPU s".format(**a["swept"])
              + "; at the nominal response time alone: {ambiguous} ambiguous, {wrong} wrong, "
              "{cpu_seconds:g} CPU s".format(**a["nominal"]))
        if "onset_error_ms" in a:
            print("touch onsets ({}) against the scene's: error median {median:g} ms, p90 "
                  "{p90:g} ms, signed median {signed_median:g} ms".format(
                      f"dated by the {doc['force']} channel" if doc["force"] else "detected",
                      **a["onset_error_ms"]))
    if doc.get("force") and not doc["labelled"]:
        print(f"{c.get('force_dated', 0)} touches dated by the force channel of "
              f"{c.get('force_taxels', 0)} taxels")
    if "response_time" not in doc:
        print("no taxel fitted")
        return 0
    print(f"{'relative error':<16} {'nominal':>22} {'fitted':>22}")
    for key in ("response_time", "effusivity"):
        cells = [f"{e['median']:.3f} (p90 {e['p90']:.3f})" for e in
                 (doc[key]["nominal"], doc[key]["fitted"])]
        print(f"{key.replace('_', ' '):<16} {cells[0]:>22} {cells[1]:>22}")
    return 0


def _commission_classify(args: argparse.Namespace) -> int:
    """``skin bench commission --classify``: `skin.bench.commission.classify`, printed."""
    from skin import bench
    from skin.bench.commission import classify
    from skin.errors import SkinError

    try:
        durations = tuple(float(s) for s in args.durations.split(",") if s.strip())
    except ValueError:
        raise SkinError("--durations must be seconds separated by commas") from None
    if args.trials < 1 or not durations or any(not 0.05 <= d <= 30 for d in durations) \
            or not args.object_std > 0:
        raise SkinError("--trials must be at least 1, --durations within 0.05-30 s and "
                        "--object-std positive")
    progress = Progress()
    started = time.monotonic()
    doc = {"machine": bench.machine(),
           **classify(args.sensor, args.seed, args.other_seed, args.trials, durations,
                      args.taxels, args.touches, args.spread, args.labelled,
                      args.object_std, args.noise, args.contact, args.reference_list,
                      args.hold, args.rest, noiseless=args.noiseless,
                      progress=progress.message, force=args.force)}
    doc["wall_time"] = round(time.monotonic() - started, 1)
    progress.done()
    if args.json:
        print(json.dumps(doc))
        return 0
    com = doc["commissioning"]
    print(f"{doc['sensor']}: unit {doc['seed']} commissioned from {doc['touches']} "
          f"{'labelled' if doc['labelled'] else 'detected'} {doc['contact']}-contact touches "
          f"({com['own']['taxels_fitted']} of {doc['taxels']} taxels fitted), unit "
          f"{doc['other_seed']} likewise "
          f"({com['other']['taxels_fitted']}); response-time error median "
          + ", ".join(f"{k} {v['response_time']['median']:.3f}" for k, v in com.items()
                      if "response_time" in v))
    if not doc["rows"]:
        print("no taxel fitted: nothing classified")
        return 0
    print(f"joint classifier, {doc['rows'][0]['contacts']} contacts, accuracy (std); gap "
          f"true - arm (paired std) ({doc['machine']['cpus']} cores, {doc['wall_time']:g} s)")
    print(f"{'window s':>8} {'true':>14} {'commissioned':>14} {'other unit':>14} "
          f"{'nominal':>14} {'gap comm.':>28} {'gap other':>28} {'ms':>6}")
    for r in doc["rows"]:
        cells = [f"{r[k]['accuracy']:.3f} ({r[k]['std']:.3f})"
                 for k in ("true", "commissioned", "other_unit", "nominal")]
        gaps = [f"{r[k]['gap']:+.3f} ({r[k]['std']:.3f}) {r[k]['verdict']}"
                for k in ("commissioned_gap", "other_unit_gap")]
        print(f"{r['duration']:>8g} {cells[0]:>14} {cells[1]:>14} {cells[2]:>14} "
              f"{cells[3]:>14} {gaps[0]:>28} {gaps[1]:>28} {r['ms_per_contact']:>6.2f}")
    print("verdict: within 3 points either way met when gap +- 1.96 std lies within, not met "
          "when wholly outside, else unresolved")
    return 0


def main_spread(args: argparse.Namespace) -> int:
    """``skin bench spread``: what calibration wins back on a skin whose taxels differ."""
    from skin import bench
    from skin.bench.spread import run
    from skin.errors import SkinError

    if args.touches < 1 or not 0 <= args.spread < 1:
        raise SkinError("--touches must be at least 1 and --spread within [0, 1)")
    durations = None
    if args.durations:
        try:
            durations = [float(v) for v in args.durations.split(",") if v.strip()]
        except ValueError:
            raise SkinError(f"--durations {args.durations!r}: seconds separated by commas, "
                            f"e.g. 0.5,1,2.5") from None
        if not durations or any(not 0.1 <= d <= 30 for d in durations):
            raise SkinError("--durations: each between 0.1 and 30 s")
    commissioned = None
    if args.calibration:
        from skin.formats.calibration_file import load_calibration

        commissioned = load_calibration(args.calibration)
        if not any("diffusivity" in v for v in commissioned.taxels.values()):
            raise SkinError(f"{args.calibration}: no taxel's thermal constants (commission "
                            f"them with `skin commission --touches`)")
    progress = Progress()
    started = time.monotonic()
    doc = {"machine": bench.machine(),
           **run(args.touches, args.spread, args.seed, args.sensor,
                 progress=lambda d, n: progress.bar(d, n, "runs", started),
                 commissioned=commissioned, durations=durations, model=args.model,
                 contact=args.contact)}
    progress.done()
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"{args.touches} touches on the arm, taxel constants spread +-{args.spread:.0%} "
          f"(seed {args.seed}, sensor {doc['sensor']}, {args.contact} contact, "
          f"{doc['machine']['cpus']} cores)")
    if "model" in doc:
        print(f"classifier: model {args.model} ({doc['model']['method']}, traces on the "
              f"{doc['model']['time_scale']} time scale); objects of "
              f"{len(doc['materials'])} materials: {', '.join(doc['materials'])}")
    sets = doc["by_duration"].items() if durations else [("1.5-3", doc)]
    for held, figures in sets:
        print(f"touches held {held} s")
        print(f"{'run':<12} {'accuracy':>8} {'detected':>8} {'unknown':>7} {'false':>6} "
              f"{'wall s':>7}")
        for key in ("nominal", "spread", "calibrated", "commissioned", "design"):
            if key not in figures:
                continue
            r = figures[key]
            print(f"{key:<12} {r['accuracy']:>8.3f} {r['detected']:>8} {r['unknown']:>7} "
                  f"{r['false_contacts']:>6} {r['wall_time']:>7}")
        if "calibration_gain" in figures:
            print(f"calibration gain {figures['calibration_gain']:+.3f}, spread loss "
                  f"{figures['spread_loss']:+.3f} (accuracy)")
        for key in ("commissioned", "design"):
            if f"{key}_gap" in figures:
                print(f"{key} {figures[f'{key}_gap']:+.3f} below the true constants")
    return 0


def _alternated(run: object, n: int, args: argparse.Namespace, budget: float | None,
                knob: str, label: object, progress: Progress
                ) -> tuple[dict[bool, dict], dict[str, float]]:
    """Run ``n`` taxels with a pipeline option on and off, alternated (on, off, off, on).

    Neither side always runs first (a warm cache, a load that comes or goes); each side's
    run with the faster onset stage is kept. Returns those runs ({True: on, False: off})
    and the on / off throughput ratios of the chain and the onset stage.
    """
    runs: dict[bool, list[dict]] = {True: [], False: []}
    for on in (True, False, False, True):
        progress.message(f"{n} taxels x {args.seconds:g} s, {label(on)}")
        runs[on].append(run(n, args.seconds, contacts_per_minute=args.contacts_per_minute,
                            budget=budget, workers=1, block=args.block, **{knob: on}))
    best = {k: max(v, key=lambda r: r["stages"]["onset"]) for k, v in runs.items()}
    a, b = best[True], best[False]
    return best, {"chain": round(a["taxel_samples_per_s"] / b["taxel_samples_per_s"], 3),
                  "onset": round(a["stages"]["onset"] / b["stages"]["onset"], 3),
                  "onset_cpu": round(a["stages_cpu"]["onset"] / b["stages_cpu"]["onset"], 3)}


def main_pipeline(args: argparse.Namespace) -> int:
    """Run the pipeline throughput benchmark."""
    from skin import bench
    from skin.bench.pipeline import run
    from skin.errors import SkinError

    try:
        sizes = [int(v) for v in args.taxels.split(",") if v.strip()]
    except ValueError:
        raise SkinError(f"--taxels wants integers, got {args.taxels!r}") from None
    if not sizes or min(sizes) < 1:
        raise SkinError("--taxels must be positive")
    if args.seconds <= 0 or args.contacts_per_minute < 0:
        raise SkinError("--seconds must be positive and --contacts-per-minute >= 0")
    try:
        workers = [int(v) for v in args.workers.split(",") if v.strip()]
    except ValueError:
        raise SkinError(f"--workers wants integers, got {args.workers!r}") from None
    if not workers or min(workers) < 1 or args.block < 1:
        raise SkinError("--workers and --block must be at least 1")
    budget = None if args.budget < 0 else args.budget / 1e3
    progress = Progress()
    rows = []
    for n in sizes:
        for w in workers:
            progress.message(f"{n} taxels x {args.seconds:g} s, {w} worker"
                             f"{'s' if w > 1 else ''}")
            rows.append(run(n, args.seconds, contacts_per_minute=args.contacts_per_minute,
                            budget=budget, workers=w, block=args.block))
    flat = []
    if args.compare_envelope:
        for n in sizes:
            best, ratio = _alternated(run, n, args, budget, "envelope_noise",
                                      lambda on: f"{'noise' if on else 'flat'} envelope margin",
                                      progress)
            flat.append({"taxels": n, "noise": best[True], "flat": best[False],
                         "runs_each": 2, "noise_over_flat": ratio})
    switched: dict[str, list[dict]] = {}  # on / off of one knob, each size: its JSON key
    for flag, knob, name, key in (("compare_common_mode", "common_mode", "common mode",
                                   "common_mode_compare"),
                                  ("compare_force", "force", "force channel", "force_compare")):
        if not getattr(args, flag, False):
            continue
        for n in sizes:
            best, ratio = _alternated(run, n, args, budget, knob,
                                      lambda on, name=name: f"{name} {'on' if on else 'off'}",
                                      progress)
            switched.setdefault(key, []).append(
                {"taxels": n, "on": best[True], "off": best[False], "runs_each": 2,
                 "on_over_off": ratio})
    progress.done()
    doc = {"machine": bench.machine(), "block": args.block, "results": rows,
           "speedup": _speedups(rows, workers)}
    if flat:
        doc["envelope_compare"] = flat
    doc.update(switched)
    if args.json:
        print(json.dumps(doc))
        return 0
    taken = ("one sample at a time" if args.block == 1
             else f"samples taken in blocks of {args.block}")
    print(f"streaming chain, {taken} ({doc['machine']['cpus']} cores; "
          f"{args.contacts_per_minute:g} contacts per taxel-minute; budget "
          f"{'none' if budget is None else f'{args.budget:g} ms'})")
    print("taxel-samples per second, of the chain and of each stage alone (with workers, "
          "decode, assemble, calibrate and onset are the workers' seconds, summed):")
    names = list(rows[0]["stages"])
    print(f"{'taxels':>7} {'workers':>7} {'chain':>10} " + " ".join(f"{k:>10}" for k in names))
    for r in rows:
        print(f"{r['taxels']:>7} {r['workers']:>7} {r['taxel_samples_per_s']:>10} "
              + " ".join(f"{r['stages'][k] or '-':>10}" for k in names))
    print("the same per CPU second of the process that ran each stage (on a loaded machine "
          "the wall time also counts what others ran meanwhile):")
    for r in rows:
        print(f"{r['taxels']:>7} {r['workers']:>7} {r['taxel_samples_per_s']:>10} "
              + " ".join(f"{r['stages_cpu'][k] or '-':>10}" for k in names))
    print(f"\n{'taxels':>7} {'x real time':>11} {'p50 ms':>7} {'p99 ms':>7} {'contacts':>8} "
          f"{'wait p50 ms':>11} {'wait p99 ms':>11} {'memory MB':>9} {'peak MB':>8} {'wall s':>7} "
          f"{'CPU s':>7}")
    for r in rows:
        w = r["result_wait_ms"]
        print(f"{r['taxels']:>7} {r['realtime_factor']:>11} {r['latency_ms']['p50']:>7} "
              f"{r['latency_ms']['p99']:>7} {r['contacts']:>8} {w['p50']!s:>11} "
              f"{w['p99']!s:>11} {r['peak_memory_mb_growth']:>9} {r['peak_memory_mb']:>8} "
              f"{r['wall_s']:>7} {r['cpu_s']:>7}")
    for f in flat:
        print(f"\n{f['taxels']} taxels, one process, each margin's faster onset stage of two "
              f"runs (noise, flat, flat, noise), taxel-samples/s: the noise table's "
              f"envelope margin {f['noise']['taxel_samples_per_s']} (onset stage "
              f"{f['noise']['stages']['onset']}), the flat one's "
              f"{f['flat']['taxel_samples_per_s']} ({f['flat']['stages']['onset']}): "
              f"x{f['noise_over_flat']['chain']} chain, x{f['noise_over_flat']['onset']} onset "
              f"(x{f['noise_over_flat']['onset_cpu']} per CPU second)")
    for key, name in (("common_mode_compare", "board common mode"),
                      ("force_compare", "force channel")):
        for f in switched.get(key, []):
            _print_switched(f, name)
    for sp in doc["speedup"]:
        print(f"\n{sp['taxels']} taxels, samples in blocks of {args.block}: speed-up over "
              f"{workers[0]} worker{'s' if workers[0] > 1 else ''} (same run): "
              + ", ".join(f"{k} workers x{v}" for k, v in sp["measured"].items()))
        if "on_paper" in sp:
            paper = sp["on_paper"]
            print(f"  CPU seconds of the 2-worker run over one process's: parent "
                  f"{paper['parent_share']:.0%}, workers {paper['workers_share']:.0%}; on "
                  f"paper, {paper['workers']} workers and the parent with a core each: "
                  f"x{paper['pipelined']}; 2 workers on 2 cores of their own: "
                  f"x{paper['two_cores']}")
    return 0


def _print_switched(f: dict, name: str) -> None:
    """Print one size's on / off comparison of a knob (`skin bench pipeline --compare-...`)."""
    print(f"\n{f['taxels']} taxels, one process, each one's faster onset stage of two runs "
          f"(on, off, off, on), taxel-samples/s: {name} on "
          f"{f['on']['taxel_samples_per_s']} (onset stage {f['on']['stages']['onset']}), "
          f"off {f['off']['taxel_samples_per_s']} ({f['off']['stages']['onset']}): "
          f"x{f['on_over_off']['chain']} chain, x{f['on_over_off']['onset']} onset "
          f"(x{f['on_over_off']['onset_cpu']} per CPU second)")


def _speedups(rows: list[dict], workers: list[int]) -> list[dict]:
    """Per skin size: each worker count's throughput over the first's; 8 on paper from 1 and 2."""
    from skin.bench.pipeline import workers_on_paper

    out = []
    for n in dict.fromkeys(r["taxels"] for r in rows):
        by = {r["workers"]: r for r in rows if r["taxels"] == n}
        base = by[workers[0]]["taxel_samples_per_s"]
        entry: dict = {"taxels": n, "measured": {
            w: round(r["taxel_samples_per_s"] / base, 2) for w, r in by.items()}}
        if 1 in by and 2 in by:
            entry["on_paper"] = workers_on_paper(by[1], by[2], 8)
        out.append(entry)
    return out


def main_publish(args: argparse.Namespace) -> int:
    """Run the publishing benchmark (`skin.bench.publish`)."""
    from skin import bench
    from skin.bench.publish import run
    from skin.errors import SkinError

    kinds = tuple(k.strip() for k in args.publishers.split(",") if k.strip())
    if not kinds or set(kinds) - {"zenoh", "foxglove"}:
        raise SkinError(f"--publishers: zenoh and/or foxglove, got {args.publishers!r}")
    if args.taxels < 1 or args.seconds <= 0 or args.chunk < 1:
        raise SkinError("--taxels, --seconds and --chunk must be positive")
    progress = Progress()
    doc = run(args.taxels, args.seconds, chunk=args.chunk, publishers=kinds,
              progress=progress.message)
    progress.done()
    doc["machine"] = bench.machine()
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"publishing {doc['taxels']} taxels x {doc['rate_hz']:g} Hz, {doc['samples']} samples "
          f"in blocks of {doc['chunk']} ({doc['machine']['cpus']} cores); without publishing "
          f"the pipeline takes {doc['baseline_samples_per_s']:g} samples/s")
    print("throughput ratio: CPU seconds of the skin's process per sample without publishing / "
          "with (publisher threads included); wall: the same by the wall time of the "
          "pipeline's calls (on a loaded machine the scheduler's favours blur it)")
    print(f"{'publisher':<10} {'throughput (CPU)':>16} {'wall':>6} {'p50 ms':>7} "
          f"{'p99 ms':>7} {'received (paced)':>16} {'received (flat out)':>19}")
    for kind in kinds:
        rows = {r["mode"]: r for r in doc["rows"] if r["publisher"] == kind}
        t, lat = rows["throughput"], rows["latency"]
        print(f"{kind:<10} {t['cpu_ratio']:>16} {t['throughput_ratio']:>6} "
              f"{lat['p50_latency_ms']!s:>7} "
              f"{lat['p99_latency_ms']!s:>7} {lat['received_share']:>16.2%} "
              f"{t['received_share']:>19.2%}")
    return 0


def main_soak(args: argparse.Namespace) -> int:
    """``skin bench soak``."""
    from skin import bench
    from skin.bench.soak import run
    from skin.errors import SkinError

    if args.hours <= 0 or args.taxels < 1 or (args.every is not None and args.every <= 0):
        raise SkinError("--hours, --taxels and --every must be positive")
    progress = Progress()
    r = run(args.hours, args.taxels, seed=args.seed, every=args.every, record=args.record,
            folder=args.out, progress=progress.status,
            wall_limit=None if args.wall_hours is None else args.wall_hours * 3600.0)
    progress.done()
    if args.json:
        print(json.dumps({"machine": bench.machine(), **r}))
        return 0
    print(f"soak: {r['taxels']} taxels on {r['boards']} simulated boards, "
          f"{r['seconds_simulated'] / 3600:.3f} simulated h in {r['wall_s']:.0f} s "
          f"({r['speed']} x real time, {r['taxel_samples_per_s']} taxel-samples/s)"
          + (", recorded" if r["recorded"] else "")
          + (f"; stopped at the wall-clock limit, {args.hours:g} h asked"
             if r["stopped_early"] else ""))
    print(f"{'sim h':>7} {'wall s':>7} {'RSS MB':>7} {'fds':>4} {'frames':>9} {'contacts':>8}")
    for s in r["samples"]:
        print(f"{s['simulated_s'] / 3600:7.3f} {s['wall_s']:7.0f} {s['rss_mb']:7.1f} "
              f"{s['open_fds']:4d} {s['frames']:9d} {s['contacts']:8d}")
    m = r["rss_mb"]
    print(f"RSS {m['start']} MB at start, {m['baseline']} MB at "
          f"{r['rss_growth_baseline_at_s'] / 3600:.3g} h, {m['end']} MB at the end of the run "
          f"(at most {m['max']} MB): growth {100 * r['rss_growth']:+.1f} % (at most "
          f"{100 * r['rss_growth_max']:+.1f} %); open fds {r['open_fds']['start']} -> "
          f"{r['open_fds']['end']}")
    print(f"frames sent {r['frames_sent']}, received {r['frames_received']}, lost "
          f"{r['lost_frames']} (gaps {r['gaps']}, late {r['late']}), CRC errors {r['crc_errors']}"
          + (f", {r['in_flight']} on their way when stopped" if r["stopped_early"] else ""))
    print(f"contacts {r['contacts']} from {r['touches']} touches, results {r['results']}; "
          f"contacts per {r['per']}: {r['contacts_per_bin']}"
          + ("" if r["contacts_per_bin"] == r["touches_per_bin"]
             else f" (touches: {r['touches_per_bin']})"))
    print("the same labels every " + r["per"] + ": "
          + ("yes" if r["same_labels_every_bin"] else "no: " + "; ".join(
              ", ".join(f"{k} {v}" for k, v in b.items()) for b in r["labels_per_bin"])))
    print(f"written {r['written_mb']} MB")
    return 0


def main_bus(args: argparse.Namespace) -> int:
    """``skin bench bus``."""
    from skin.drivers.bus_load import adc_max_taxels, bus_table

    sizes = tuple(int(v) for v in args.taxels.split(","))
    rows = bus_table(sizes, args.rate, args.force)
    adc = {os_: adc_max_taxels(args.rate, os_, args.force) for os_ in (1, 2, 4)}
    if args.json:
        print(json.dumps({"rate_hz": args.rate, "force": args.force,
                          "buses": [r.as_dict() for r in rows],
                          "adc_max_taxels_by_oversampling": adc}))
        return 0
    print(f"protocol v1 at {args.rate:g} Hz (serial 8N1; CAN classic, 11-bit ids, worst-case "
          "stuffing; best case in brackets)"
          + ("; with the force channel (FORCE)" if args.force else ""))
    print(f"{'bus':>6} {'bit/s':>9} {'taxels':>6} {'bytes':>6} {'frames':>6} {'bytes/s':>8} "
          f"{'load':>14} {'max taxels':>10}")
    for r in rows:
        load = f"{100 * r.load:.1f} %" + (f" ({100 * r.load_best:.1f})" if r.bus == "can" else "")
        print(f"{r.bus:>6} {r.bit_rate:>9} {r.taxels:>6} {r.frame_bytes:>6} {r.frames:>6} "
              f"{r.bytes_per_s:>8.0f} {load:>14} {r.max_taxels:>10}")
    print("AVR board at 16 MHz (ADC 16 MHz / 64; scan and main loop in cycles as the firmware's "
          "max-rate formula, 95 % of the period)"
          + (", a force input (1 MHz conversion) on every taxel" if args.force else "")
          + ": at most " + ", ".join(f"{n} taxels with {k}x oversampling" for k, n in adc.items()))
    return 0

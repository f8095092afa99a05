"""``skin bench``: error (or accuracy) against run time, printed as figures.

``skin bench thermal`` runs every forward model and discretisation on a 2.5 s contact (RMS
error against the closed form or a converged reference, and run time per trial), then the
inverse estimators on simulated trials (effusivity error against contact duration, and run
time per trial). ``--plot DIR`` draws the work-precision diagram and the estimator errors.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

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


def machine() -> dict:
    """Describe the machine the figures come from."""
    import os

    import numpy as np

    return {"platform": platform.platform(), "python": platform.python_version(),
            "numpy": np.__version__, "cpus": os.cpu_count()}


def main_thermal(args: argparse.Namespace) -> int:
    """Run the thermal benchmark."""
    from skin.models import thermal_bench

    progress = Progress()
    started = time.monotonic()
    cells = (12, 24, 48, 96) if args.full else (12,) if args.quick else (12, 24, 48)
    dts = (0.1, 0.02) if args.quick else (0.1, 0.02, 0.005, 0.001)
    forward = thermal_bench.forward(
        cells=cells, dts=dts, progress=lambda d, n: progress.bar(d, n, "forward", started))
    progress.done()
    started_inv = time.monotonic()
    inverse = thermal_bench.inverse(
        durations=(0.25, 2.5) if args.quick else (0.25, 0.5, 1.0, 2.5),
        trials=3 if args.quick else args.trials,
        progress=lambda d, n: progress.bar(d, n, "inverse", started_inv))
    progress.done()
    doc = {"machine": machine(), "wall_time": round(time.monotonic() - started, 2),
           "forward": forward, "inverse": inverse}
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
    print(f"forward models, 2.5 s contact; time relative to the semi-infinite closed form "
          f"of the same case ({doc['machine']['cpus']} cores)")
    print(f"{'case':<10} {'model':<36} {'scheme':<15} {'cells':>5} {'dt s':>7} "
          f"{'rms err K':>10} {'ms/trial':>9} {'x closed':>9}")
    for r in forward:
        cells_s = "-" if r["cells"] is None else str(r["cells"])
        dt_s = "-" if r["dt"] is None else f"{r['dt']:g}"
        model = r["model"] + ("" if not r.get("conductance") else f" h={r['conductance']:g}")
        print(f"{r['case']:<10} {model:<36} {r['scheme']:<15} {cells_s:>5} {dt_s:>7} "
              f"{r['rms_error']:>10.2e} {r['time_per_trial_ms']:>9.3f} "
              f"{r['time_per_trial_ms'] / base[r['case']]:>9.0f}")
    print("\ninverse estimators on simulated trials (paper's protocol, 11 materials)")
    print(f"{'estimator':<28} {'dur s':>6} {'valid':>6} {'median |dlog10 e|':>18} "
          f"{'p90':>6} {'ms/trial':>9}")
    for r in inverse:
        med = "-" if r["median_abs_log10_error"] is None else f"{r['median_abs_log10_error']:.3f}"
        p90 = "-" if r["p90_abs_log10_error"] is None else f"{r['p90_abs_log10_error']:.3f}"
        print(f"{r['estimator']:<28} {r['duration']:>6g} {r['valid']:>6.2f} {med:>18} "
              f"{p90:>6} {r['time_per_trial_ms']:>9.3f}")
    if "figures" in doc:
        print("figures: " + ", ".join(doc["figures"]))
    return 0

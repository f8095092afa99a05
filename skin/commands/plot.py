"""``skin plot KIND``: draw a figure into a file (PNG, SVG or PDF, from the suffix of --out).

Kinds:

materials
    the effusivity range of each material of the table on a log axis, with its nominal value
    and the sensor's own effusivity (the paper's Fig. 10); --all adds the extremes kept for
    tests (copper, diamond, polyurethane foam, silica aerogel, water), hatched.
traces
    a taxel's temperature and its slope below, sharing the time axis, with the onsets and
    releases the onset detector finds and the truth where known (the paper's Figs. 1 and 6):
    trials of a dataset (--from trials.npz [--trial K ...]), taxels of a recording
    (--from run.mcap [--taxel ID ...]) or simulated contacts with materials from one initial
    temperature (--material NAME ..., overlaid).
accuracy
    accuracy against contact duration, one line per method, from the JSON of
    ``skin evaluate --json`` (--from evaluate.json).
confusion
    the confusion matrices of ``skin evaluate --json`` (--from evaluate.json), one row per
    method (--method picks some), one panel per duration.
work-precision
    the forward models' RMS error against run time from ``skin bench thermal --json``
    (--from bench.json).
estimators
    the inverse estimators' effusivity error against contact duration from
    ``skin bench thermal --json`` (--from bench.json).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from skin.errors import SkinError

# what each JSON kind is written by, and the keys its rows need
_EVALUATE = "skin evaluate --json"
_BENCH = "skin bench thermal --json"
_ACCURACY_KEYS = ("method", "duration", "accuracy", "accuracy_std")
_CONFUSION_KEYS = ("method", "duration", "accuracy", "confusion", "classes")
_FORWARD_KEYS = ("case", "model", "scheme", "cells", "dt", "rms_error", "time_per_trial_ms")
_INVERSE_KEYS = ("estimator", "duration", "median_abs_log10_error", "p90_abs_log10_error",
                 "time_per_trial_ms")


def _need_from(args: argparse.Namespace, what: str) -> Path:
    if not args.source:
        raise SkinError(f"skin plot {args.kind} needs --from FILE ({what})")
    return Path(args.source)


def load_json(path: str | Path) -> Any:
    """Read a JSON document, with errors that name the file.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    Any
        The document.

    Raises
    ------
    SkinError
        When the file cannot be read or is not JSON.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SkinError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise SkinError(f"{path}: not JSON (not a text file)") from None
    except OSError as exc:
        raise SkinError(f"{path}: cannot read ({exc.strerror or exc})") from None
    try:
        return json.loads(text)
    except ValueError as exc:
        raise SkinError(f"{path}: not JSON ({exc})") from None


def _what_it_is(doc: Any) -> str:
    """Name the command a JSON document looks like the output of, for error messages."""
    if isinstance(doc, dict):
        if "forward" in doc and "inverse" in doc:
            return f"the output of `{_BENCH}` (draw it with `skin plot work-precision`)"
        if isinstance(doc.get("results"), list) and doc["results"] \
                and isinstance(doc["results"][0], dict) and "confusion" in doc["results"][0]:
            return f"the output of `{_EVALUATE}` (draw it with `skin plot accuracy`)"
    return f"a JSON {type(doc).__name__}"


def json_rows(path: str | Path, key: str, needs: tuple[str, ...], writer: str) -> list[dict]:
    """Return the rows under ``key`` of a command's JSON output, checked for ``needs``.

    Parameters
    ----------
    path : str or Path
        The JSON file.
    key : str
        The list of rows (``"results"``, ``"forward"``, ``"inverse"``).
    needs : tuple of str
        Keys every row must have.
    writer : str
        The command that writes such a file, for the error message.

    Returns
    -------
    list of dict
        The rows.

    Raises
    ------
    SkinError
        Naming the file when it is not JSON, is another command's output, or a row misses a
        key.
    """
    doc = load_json(path)
    rows = doc.get(key) if isinstance(doc, dict) else None
    if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
        raise SkinError(f"{path}: not the output of `{writer}` (no '{key}' list of rows); it "
                        f"is {_what_it_is(doc)}")
    for i, row in enumerate(rows):
        missing = [k for k in needs if k not in row]
        if missing:
            raise SkinError(f"{path}: not the output of `{writer}`: row {i} of '{key}' has no "
                            f"{', '.join(repr(k) for k in missing)}; it is {_what_it_is(doc)}")
    return rows


def _materials(args: argparse.Namespace, out: Path) -> tuple[Path, dict]:
    from skin.models import load_materials
    from skin.viz.plots import plot_materials

    return plot_materials(load_materials(), out, include_all=args.all), {}


def _split(values: list[str] | None) -> list[str]:
    return [v.strip() for item in values or [] for v in item.split(",") if v.strip()]


def _traces(args: argparse.Namespace, out: Path) -> tuple[Path, dict]:
    from skin.viz.trace_plots import (
        material_traces,
        plot_traces,
        recording_scene,
        recording_traces,
        trial_traces,
    )

    materials = _split(args.material)
    if args.source and materials:
        raise SkinError("--material simulates contacts; it does not go with --from (pick "
                        "trials with --trial, taxels with --taxel)")
    if not args.source and not materials:
        raise SkinError("skin plot traces needs --from FILE (a trial dataset .npz or a "
                        "recording .mcap) or --material NAME (simulated contacts)")
    source = Path(args.source) if args.source else None
    suffix = source.suffix.lower() if source else ""
    if args.trial and suffix != ".npz":
        raise SkinError("--trial picks trials of a dataset (--from trials.npz)")
    if args.taxel and suffix != ".mcap":
        raise SkinError("--taxel picks taxels of a recording (--from run.mcap)")
    if args.scene and suffix != ".mcap":
        raise SkinError("--scene gives the truth of a recording (--from run.mcap)")
    if source is None:
        traces = material_traces(materials, t_sensor=args.t_sensor, t_object=args.t_object,
                                 ambient=args.ambient, duration=args.duration,
                                 before=args.before, model=args.model,
                                 conductance=args.conductance, noise=args.noise,
                                 seed=args.seed)
        title = (f"contacts from one initial temperature ({args.model}"
                 + ("" if args.model == "semi-infinite" else f", h = {args.conductance:g}")
                 + (f", noise {args.noise:g} °C" if args.noise else "") + ")")
        xlabel = "time since contact, s"
    elif suffix == ".npz":
        from skin.formats.dataset import load_trials

        data = load_trials(source)
        traces = trial_traces(data, args.trial)
        title = f"{source.name}: " + (f"{len(traces)} trials" if len(traces) > 1
                                      else traces[0].name)
        xlabel = "time from the trial's first sample, s"
    elif suffix == ".mcap":
        from skin.drivers.recording import read_recording
        from skin.formats.scene import load_scene

        rec = read_recording(source)
        scene = load_scene(args.scene) if args.scene else recording_scene(rec)
        traces = recording_traces(rec, args.taxel, scene=scene)
        title = f"{source.name}: " + ", ".join(t.name for t in traces[:6]) + \
            (" ..." if len(traces) > 6 else "") + \
            (f" (truth: scene {scene.name})" if scene is not None else "")
        xlabel = "device time, s"
    else:
        raise SkinError(f"{source}: unknown kind of file {source.suffix!r} (want a trial "
                        f"dataset .npz or a recording .mcap)")
    path = plot_traces(traces, out, title=title, xlabel=xlabel, slope=args.slope)
    return path, {"traces": [t.summary() for t in traces]}


def _accuracy(args: argparse.Namespace, out: Path) -> tuple[Path, dict]:
    from skin.viz.plots import plot_accuracy

    src = _need_from(args, f"the output of `{_EVALUATE}`")
    rows = json_rows(src, "results", _ACCURACY_KEYS, _EVALUATE)
    return plot_accuracy(rows, out, title=f"accuracy against contact duration: {src.name}"), {}


def _confusion(args: argparse.Namespace, out: Path) -> tuple[Path, dict]:
    from skin.viz.plots import plot_confusions

    src = _need_from(args, f"the output of `{_EVALUATE}`")
    rows = json_rows(src, "results", _CONFUSION_KEYS, _EVALUATE)
    methods = _split(args.method)
    if methods:
        known = list(dict.fromkeys(r["method"] for r in rows))
        unknown = [m for m in methods if m not in known]
        if unknown:
            raise SkinError(f"{src}: no method {unknown[0]!r}; it holds {', '.join(known)}")
        rows = [r for m in methods for r in rows if r["method"] == m]
    return plot_confusions(rows, out, title=f"confusion matrices: {src.name}"), {}


def _work_precision(args: argparse.Namespace, out: Path) -> tuple[Path, dict]:
    from skin.viz.plots import plot_work_precision

    src = _need_from(args, f"the output of `{_BENCH}`")
    return plot_work_precision(json_rows(src, "forward", _FORWARD_KEYS, _BENCH), out), {}


def _estimators(args: argparse.Namespace, out: Path) -> tuple[Path, dict]:
    from skin.viz.plots import plot_estimator_errors

    src = _need_from(args, f"the output of `{_BENCH}`")
    return plot_estimator_errors(json_rows(src, "inverse", _INVERSE_KEYS, _BENCH), out), {}


# kind -> (function drawing it into the given path: the path written and extra JSON, help)
KINDS: dict[str, tuple[Callable[[argparse.Namespace, Path], tuple[Path, dict]], str]] = {
    "materials": (_materials, "effusivity ranges of the materials (the paper's Fig. 10)"),
    "traces": (_traces, "temperature and slope traces with onset marks (Figs. 1 and 6)"),
    "accuracy": (_accuracy, "accuracy against contact duration (skin evaluate --json)"),
    "confusion": (_confusion, "confusion matrices (skin evaluate --json)"),
    "work-precision": (_work_precision, "forward models' error against run time "
                                        "(skin bench thermal --json)"),
    "estimators": (_estimators, "effusivity estimators' error against duration "
                                "(skin bench thermal --json)"),
}


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin plot``."""
    plot = sub.add_parser("plot", help="draw a figure (materials, traces, accuracy, "
                                       "confusion, work-precision, estimators)",
                          description=__doc__,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    kinds = plot.add_subparsers(dest="kind", required=True, metavar="KIND")
    parsers = {}
    for kind, (_, text) in KINDS.items():
        p = kinds.add_parser(kind, help=text, description=text)
        p.add_argument("--out", metavar="PATH",
                       help="output file; its suffix picks the format: .png, .svg or .pdf "
                            f"(default: out/{kind}.png)")
        p.add_argument("--json", action="store_true",
                       help="print one JSON document (the path written, and for traces the "
                            "marks of each trace)")
        if kind != "materials":
            p.add_argument("--from", dest="source", metavar="FILE",
                           required=kind != "traces",
                           help="trial dataset (.npz) or recording (.mcap)" if kind == "traces"
                           else "JSON file written by " + (_EVALUATE if kind in (
                               "accuracy", "confusion") else _BENCH))
        p.set_defaults(func=main)
        parsers[kind] = p
    parsers["materials"].add_argument(
        "--all", action="store_true", help="also draw the extremes that are not classified")
    parsers["confusion"].add_argument(
        "--method", action="append", metavar="NAME",
        help="only these methods (repeat it, or comma-separated; default: every one)")
    tr = parsers["traces"]
    tr.add_argument("--trial", type=int, nargs="+", action="extend", metavar="K",
                    help="trials of the dataset (default: the first of each class)")
    tr.add_argument("--taxel", type=int, nargs="+", action="extend", metavar="ID",
                    help="taxel ids of the recording (default: those of its first contact)")
    tr.add_argument("--scene", metavar="NAME|FILE",
                    help="the scene a recording was simulated from, for the truth (default: "
                         "the one its recorded command line names)")
    tr.add_argument("--material", nargs="+", action="extend", metavar="NAME",
                    help="simulate contacts with these materials (names or comma-separated), "
                         "overlaid, from one initial temperature")
    tr.add_argument("--slope", choices=("detector", "paper"), default="detector",
                    help="lower panel: the onset detector's slope (default) or the paper's "
                         "first difference through a 2 Hz low-pass")
    sim = tr.add_argument_group("simulated contacts (--material)")
    sim.add_argument("--model", choices=("semi-infinite", "contact", "multilayer"),
                     default="semi-infinite", help="contact physics (default semi-infinite)")
    sim.add_argument("--conductance", type=float, default=3000.0,
                     help="contact conductance, W/(m^2 K), of contact and multilayer (3000)")
    sim.add_argument("--t-sensor", type=float, default=None,
                     help="sensor temperature at contact, C (default: eq. 2's heated value)")
    sim.add_argument("--t-object", type=float, default=None,
                     help="object temperature, C (default: each material's resting one)")
    sim.add_argument("--ambient", type=float, default=25.0, help="ambient, C (25)")
    sim.add_argument("--duration", type=float, default=2.5, help="contact, s (2.5)")
    sim.add_argument("--before", type=float, default=1.0,
                     help="free sensor before contact, s (1; at least 0.6)")
    sim.add_argument("--noise", type=float, default=0.0,
                     help="standard deviation of the reading's noise, C (0)")
    sim.add_argument("--seed", type=int, default=0, help="seed of the noise (0)")


def main(args: argparse.Namespace) -> int:
    """Draw the figure named by ``args.kind`` and print the path written (or JSON)."""
    from skin.viz.plots import output_path

    out = output_path(args.out if args.out else Path("out") / f"{args.kind}.png")
    draw, _ = KINDS[args.kind]
    path, extra = draw(args, out)
    if args.json:
        print(json.dumps({"kind": args.kind, "figure": str(path), **extra}))
    else:
        print(path)
    return 0

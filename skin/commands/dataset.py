"""``skin dataset``: check a trial dataset, or import trials recorded elsewhere.

``skin dataset check FILE.npz`` validates a dataset (version 1 or 2) and prints what it
holds: trials, channels (heated and passive), classes, onsets to detect. ``skin dataset
import FILE.csv -o FILE.npz`` reads the CSV layout of `skin.formats.trial_csv` (one row per
sample of one channel) and writes a version 2 dataset; trials that break a rule are left out
and listed with their index, line and reason. ``skin dataset import run.mcap --labels
touches.csv -o FILE.npz`` cuts the labelled contacts out of a recording
(`skin.formats.recorded_contacts`; label files: `skin.formats.touch_labels`); contacts and
labels that do not pair up are listed.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin dataset check`` and ``skin dataset import``."""
    ds = sub.add_parser("dataset", help="check a trial dataset or import trials from CSV",
                        description=__doc__)
    kinds = ds.add_subparsers(dest="kind", required=True)
    check = kinds.add_parser("check", help="validate a dataset and summarise it")
    check.add_argument("path", help="trial dataset (.npz, version 1 or 2)")
    check.add_argument("--json", action="store_true", help="print one JSON document")
    check.set_defaults(func=main_check)
    imp = kinds.add_parser("import", help="CSV (one row per sample), or a recording and its "
                                          "labels -> version 2 .npz")
    imp.add_argument("path", help="CSV file (see the README's layout) or MCAP recording "
                                  "(skin run --record)")
    imp.add_argument("-o", "--out", required=True, help="dataset to write (.npz)")
    imp.add_argument("--labels", metavar="FILE.csv",
                     help="a recording's touches: time,material[,taxels][,group] (needed for "
                          "a recording; `skin simulate labels` writes a scene's)")
    imp.add_argument("--pre", type=float, default=0.5,
                     help="recording: seconds kept before each onset (default 0.5)")
    imp.add_argument("--duration", type=float, default=3.0,
                     help="recording: seconds kept after each onset (default 3)")
    imp.add_argument("--tolerance", type=float, default=0.5,
                     help="recording: largest gap between a contact's onset and its label, s "
                          "(default 0.5)")
    imp.add_argument("--channels", type=int, default=None,
                     help="recording: taxels kept per contact (default: the most any has)")
    imp.add_argument("--json", action="store_true", help="print one JSON document")
    imp.set_defaults(func=main_import)


def summarise(data) -> dict:
    """Summarise what a dataset holds, as a JSON-ready dict."""
    present = np.isfinite(data.temperature[:, :, 0])
    labels, counts = np.unique(data.label, return_counts=True)
    return {"source": data.source, "trials": len(data), "channels": data.n_channels,
            "samples": data.temperature.shape[-1], "fs": data.fs,
            "heated_channels": int((present & data.heated).sum()),
            "passive_channels": int((present & ~data.heated).sum()),
            "per_class": {str(k): int(v) for k, v in zip(labels, counts, strict=True)},
            "onsets_to_detect": int(np.sum(data.onset < 0)),
            "optional": [k for k in ("ambient", "group", "taxel", "setpoint", "force",
                                     "object_temperature") if getattr(data, k) is not None]}


def _print(doc: dict) -> None:
    print(f"{doc['source']}: {doc['trials']} trials, {doc['channels']} channel(s) of "
          f"{doc['samples']} samples at {doc['fs']:g} Hz ({doc['heated_channels']} heated, "
          f"{doc['passive_channels']} passive channel readings); {len(doc['per_class'])} "
          f"classes: " + ", ".join(f"{k} {v}" for k, v in doc["per_class"].items()))
    if doc["onsets_to_detect"]:
        print(f"{doc['onsets_to_detect']} onsets to detect (-1)")


def main_check(args: argparse.Namespace) -> int:
    """Validate and summarise."""
    from skin.formats.dataset import load_trials

    doc = summarise(load_trials(args.path))
    print(json.dumps(doc)) if args.json else _print(doc)
    return 0


def main_import(args: argparse.Namespace) -> int:
    """Import a CSV file, or the labelled contacts of a recording."""
    from pathlib import Path

    from skin.errors import SkinError

    if Path(args.path).suffix.lower() == ".mcap":
        from skin.formats.recorded_contacts import contacts_from_recording
        from skin.formats.touch_labels import read_touch_labels

        if args.labels is None:
            raise SkinError(f"{args.path}: a recording needs --labels FILE.csv (the touches: "
                            f"time,material[,taxels][,group])")
        labels = read_touch_labels(args.labels)
        if not Path(args.path).is_file():
            raise SkinError(f"{args.path}: no such file")
        data, skipped = contacts_from_recording(
            args.path, labels, pre=args.pre, duration=args.duration,
            tolerance=args.tolerance, channels=args.channels)
        rejected = [{"kind": s.kind, "what": s.ident, "reason": s.reason} for s in skipped]
        messages = [f"skipped {s}" for s in skipped]
    else:
        from skin.formats.trial_csv import read_trials_csv

        if args.labels is not None:
            raise SkinError("--labels is for a recording (.mcap); a CSV carries its labels")
        data, bad = read_trials_csv(args.path)
        rejected = [{"index": r.index, "trial": r.trial, "line": r.line, "reason": r.reason}
                    for r in bad]
        messages = [f"rejected {r}" for r in bad]
    path = data.save(args.out)
    doc = summarise(data) | {"out": str(path), "rejected": rejected}
    if args.json:
        print(json.dumps(doc))
        return 0
    for line in messages:
        print(line, file=sys.stderr)
    _print(doc)
    print(f"wrote {path}" + (f" ({len(rejected)} left out)" if rejected else ""))
    return 0

"""``skin dataset``: check a trial dataset, or import trials recorded elsewhere.

``skin dataset check FILE.npz`` validates a dataset (version 1 or 2) and prints what it
holds: trials, channels (heated and passive), classes, onsets to detect. ``skin dataset
import FILE.csv -o FILE.npz`` reads the CSV layout of `skin.formats.trial_csv` (one row per
sample of one channel) and writes a version 2 dataset; trials that break a rule are left out
and listed with their index, line and reason.
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
    imp = kinds.add_parser("import", help="CSV (one row per sample) -> version 2 .npz")
    imp.add_argument("path", help="CSV file (see the README's layout)")
    imp.add_argument("-o", "--out", required=True, help="dataset to write (.npz)")
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
    """Import a CSV file."""
    from skin.formats.trial_csv import read_trials_csv

    data, rejected = read_trials_csv(args.path)
    path = data.save(args.out)
    doc = summarise(data) | {"out": str(path), "rejected": [
        {"index": r.index, "trial": r.trial, "line": r.line, "reason": r.reason}
        for r in rejected]}
    if args.json:
        print(json.dumps(doc))
        return 0
    for r in rejected:
        print(f"rejected {r}", file=sys.stderr)
    _print(doc)
    print(f"wrote {path}" + (f" ({len(rejected)} trial(s) rejected)" if rejected else ""))
    return 0

"""``skin train``: fit a classifier on a trial dataset and save it as a safe model file.

The model file (skops.io, loaded with an allow-list; see `skin.models.modelfile`) carries the
method, the window duration and sampling rate, the class names, a summary of the training
data and the library version.
"""

from __future__ import annotations

import argparse
import json
import time


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin train``."""
    tr = sub.add_parser("train", help="fit a classifier and save a model file",
                        description=__doc__)
    tr.add_argument("--data", required=True, help="trial dataset (.npz)")
    tr.add_argument("--method", default="default",
                    help="default, svm-pca, knn-pca, hmm or model, the paper's methods "
                         "optionally with :raw, :slope or :both (default: default)")
    tr.add_argument("--duration", type=float, default=1.0,
                    help="contact window the model reads, s (default 1)")
    tr.add_argument("-o", "--out", required=True, help="model file to write (.skops)")
    tr.add_argument("--json", action="store_true", help="print one JSON summary")
    tr.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Fit and save."""
    from skin.dataset import load_trials, with_detected_onsets
    from skin.models.classifiers import make_method, parse_method
    from skin.models.features import trial_matrix
    from skin.models.modelfile import save_model, training_summary

    parse_method(args.method)
    data = with_detected_onsets(load_trials(args.data))  # onset -1: find it first
    x = trial_matrix(data, args.duration)
    started = time.perf_counter()
    estimator = make_method(args.method, fs=data.fs).fit(x, data.label)
    fit_time = time.perf_counter() - started
    path = save_model(args.out, estimator, args.method, args.duration, data.fs,
                      training_summary(data, args.duration))
    summary = {"out": str(path), "method": args.method, "duration": args.duration,
               "classes": [str(c) for c in estimator.classes_], "trials": len(data),
               "fit_seconds": round(fit_time, 3)}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {path}: {args.method} on {len(data)} trials, "
              f"{len(summary['classes'])} classes, {args.duration:g} s window "
              f"(fit in {fit_time:.1f} s)")
    return 0

"""``skin train``: fit a classifier on a trial dataset and save it as a safe model file.

The model file (skops.io, loaded with an allow-list; see `skin.models.modelfile`) carries the
method, the window duration and sampling rate, the class names, a summary of the training
data and the library version. ``--anytime`` trains one model per duration
(`skin.models.classifiers.AnytimeClassifier`), so a brief touch is still named from the
window it gave. ``--calibration FILE`` trains on each taxel's traces warped to the design's
time scale with its commissioned constants (`skin.models.timescale`, as ``skin evaluate
--calibration`` does for METHOD+commissioned); the model file says so, and ``skin run`` then
needs a calibration file to warp each contact's taxels alike.
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
    tr.add_argument("--anytime", default=None, metavar="D1,D2,...",
                    help="train one model per contact duration (s), e.g. 0.25,0.5,1,2.5: the "
                         "pipeline then answers from the longest window each taxel has")
    tr.add_argument("--sensor", default=None, metavar="PRESET|FILE",
                    help="the sensor the training data was recorded (or simulated) with "
                         "(its unknown onsets are found by its detector at the trials' rate; "
                         "without it, by the paper's), recorded in the model file by name: "
                         "`skin run` warns when its layout's boards use another (default: "
                         "not recorded)")
    tr.add_argument("--calibration", default=None, metavar="FILE",
                    help="train on every taxel's traces warped to the design's time scale with "
                         "its thermal constants from this calibration file (skin calibrate "
                         "thermal; the dataset's taxel column says whose trace is whose): the "
                         "model then needs a calibration file in skin run (default: traces as "
                         "recorded)")
    tr.add_argument("-o", "--out", required=True, help="model file to write (.skops)")
    tr.add_argument("--json", action="store_true", help="print one JSON summary")
    tr.set_defaults(func=main)


#: Training trials each class needs per method (PCA keeps 10 components; the HMMs fit states).
MIN_PER_CLASS = {"svm-pca": 2, "knn-pca": 3, "hmm": 2, "model": 1, "default": 2,
                 "fit-trees": 10}  # its early stopping holds out 10 % with every class
MIN_TRIALS = {"svm-pca": 10, "knn-pca": 10}


def check_enough(data, method: str) -> None:
    """Raise a `SkinError` naming the class and the count when a dataset is too small."""
    import numpy as np

    from skin.errors import SkinError
    from skin.models.classifiers import parse_method

    base = parse_method(method)[0]
    labels, counts = np.unique(data.label, return_counts=True)
    need = MIN_PER_CLASS.get(base, 2)
    if counts.min() < need:
        raise SkinError(f"{data.source}: class {str(labels[np.argmin(counts)])!r} has "
                        f"{counts.min()} trial(s); {method} needs at least {need} per class")
    if len(data) < MIN_TRIALS.get(base, 0):
        raise SkinError(f"{data.source}: {len(data)} trials; {method} needs at least "
                        f"{MIN_TRIALS[base]} (PCA keeps 10 components)")


def main(args: argparse.Namespace) -> int:
    """Fit and save."""
    from skin.commands.evaluate import independent_groups
    from skin.errors import SkinError
    from skin.formats.dataset import load_trials, require_classes, with_detected_onsets
    from skin.models.classifiers import (
        AnytimeClassifier,
        fit_grouped,
        make_method,
        method_matrix,
        parse_method,
        reads_channels,
    )
    from skin.models.modelfile import save_model, training_summary

    parse_method(args.method)
    data = require_classes(load_trials(args.data))
    recorded_with = None
    if args.sensor is not None:  # a bad name or file fails before the work starts
        from skin.models.sensors import load_sensor

        recorded_with = load_sensor(args.sensor)
    sensors = None
    if args.calibration:  # before the work starts
        from skin.commands.evaluate import calibrated_sensors

        sensors = calibrated_sensors(args.calibration, data)
    data = with_detected_onsets(data, sensor=recorded_with)  # onset -1: find it
    check_enough(data, args.method)
    if sensors is not None:
        from skin.models.timescale import warp_to_nominal

        data = warp_to_nominal(data, sensors)
    channels = data.n_channels if reads_channels(args.method) else 1
    duration = args.duration
    if args.anytime:
        try:
            durations = tuple(sorted(float(d) for d in args.anytime.split(",") if d.strip()))
        except ValueError:
            raise SkinError(f"--anytime wants durations in s, got {args.anytime!r}") from None
        if not durations or durations[0] <= 0:
            raise SkinError(f"--anytime wants positive durations, got {args.anytime!r}")
        if not hasattr(make_method(args.method, fs=data.fs), "predict_proba"):
            raise SkinError(f"--anytime needs a method with probabilities (default, knn-pca, "
                            f"hmm); {args.method} has none")
        duration = durations[-1]
        estimator = AnytimeClassifier(args.method, durations, fs=data.fs, channels=channels)
        method = f"anytime:{args.method}"
    else:
        estimator = make_method(args.method, fs=data.fs, channels=channels)
        method = args.method
    x = method_matrix(data, args.method, duration)
    # trials that share a taxel or unit share a group: the default's calibration folds keep
    # each on one side, so its probabilities hold on taxels it has not seen
    groups = independent_groups(data)[0]
    started = time.perf_counter()
    try:
        fit_grouped(estimator, x, data.label, groups)
    except ValueError as exc:  # what the estimator found wrong with the data, said plainly
        raise SkinError(f"{data.source}: cannot train {method} on {len(data)} trials: "
                        f"{exc}") from None
    fit_time = time.perf_counter() - started
    training = training_summary(data, duration, sensor=args.sensor)
    if args.calibration:
        training["calibration"] = str(args.calibration)
    time_scale = "nominal" if args.calibration else "taxel"
    path = save_model(args.out, estimator, method, duration, data.fs, training,
                      channels=channels, time_scale=time_scale)
    summary = {"out": str(path), "method": method, "duration": duration,
               "classes": [str(c) for c in estimator.classes_], "trials": len(data),
               "fit_seconds": round(fit_time, 3),
               "time_scale": time_scale}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {path}: {method} on {len(data)} trials, "
              f"{len(summary['classes'])} classes, {duration:g} s window"
              + (f", traces warped to the design's time scale ({args.calibration})"
                 if args.calibration else "") + f" (fit in {fit_time:.1f} s)")
    return 0

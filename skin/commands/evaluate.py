"""``skin evaluate``: cross-validated accuracy of classifiers against contact duration.

Methods (`skin.models.classifiers`): the paper's ``svm-pca``, ``knn-pca``, ``hmm``, ``model``,
each with ``:raw``, ``:slope`` or ``:both`` features (``svm-pca:both``), and ``default``, the
library's recommendation. ``--train A --test B`` trains on one dataset and tests on another.
Trials whose onset is -1 are dated by their force channel where it shows the contact, else run
through the onset detector of ``--sensor`` (default the model's recorded sensor, else the
paper's) at the trials' rate. K-fold cross-validation
grouped so that no taxel is on both sides of a fold (the dataset's ``group`` and ``taxel``
columns; a model is tested on taxels it never saw, as on a new skin); ``--split stratified``
ignores them (optimistic wherever a taxel's constants mark its class). The output says which
split it used. For each
method and duration: accuracy (mean and std over the folds), per-class recall, the confusion
matrix, and fit and predict time per trial; for methods with probabilities, the expected
calibration error and the coverage and accuracy when unsure answers become "unknown".
``--ceiling`` adds, on simulated data, the accuracy of a classifier told every nuisance
(`skin.bench.ceiling`): what no method can be expected to beat.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from skin.errors import SkinError
from skin.progress import Progress


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin evaluate``."""
    ev = sub.add_parser("evaluate", help="cross-validated accuracy against contact duration",
                        description=__doc__)
    src = ev.add_mutually_exclusive_group(required=True)
    src.add_argument("--data", help="trial dataset (.npz) for cross-validation")
    src.add_argument("--train", help="dataset to train on (with --test: no cross-validation)")
    ev.add_argument("--test", help="dataset to test on (with --train); classes absent from "
                                   "training are reported with what they were called")
    ev.add_argument("--model", metavar="FILE",
                    help="evaluate a saved model file (skin train) on --data instead of "
                         "training methods: at its own window, or at each of --durations an "
                         "anytime model reads")
    ev.add_argument("--methods", default="svm-pca",
                    help="comma-separated methods: svm-pca, knn-pca, hmm, model (each with "
                         "optional :raw, :slope or :both features) and default "
                         "(default: svm-pca)")
    ev.add_argument("--durations", default="0.5,1.5,2.5",
                    help="comma-separated contact durations, s (default 0.5,1.5,2.5)")
    ev.add_argument("--cv", type=int, default=3, help="number of folds (default 3)")
    ev.add_argument("--split", choices=("grouped", "stratified"), default="grouped",
                    help="grouped (default): no taxel and no 'group' on both sides of a fold; "
                         "stratified: by class only, folds may share taxels (optimistic)")
    ev.add_argument("--seed", type=int, default=0, help="seed of the fold split")
    ev.add_argument("--merge", default=None, metavar="A+B,C+D",
                    help="also report the accuracy with these classes merged (from the "
                         "confusion matrix), e.g. aluminium+steel,glass+porcelain")
    ev.add_argument("--sensor", default=None, metavar="PRESET|FILE",
                    help="the sensor the trials were recorded with: its detector finds their "
                         "unknown onsets (default: the one --model was trained with, if "
                         "recorded, else the paper's)")
    ev.add_argument("--calibration", default=None, metavar="FILE",
                    help="also report the joint physics fit of all channels with each "
                         "taxel's constants from this calibration file (skin calibrate "
                         "thermal; the taxel column says whose contact is whose), and each "
                         "method as METHOD+commissioned: every taxel's traces resampled onto "
                         "the design's time scale (skin.models.timescale)")
    ev.add_argument("--ceiling", action="store_true",
                    help="also report the known-nuisance ceiling (simulated data only; "
                         "skin.bench.ceiling): the accuracy no method can be expected to beat")
    ev.add_argument("--ceiling-unknown", default="", metavar="A,B+C",
                    help="with --ceiling, also the ceiling told less: each comma-separated "
                         "entry names nuisances kept from it, joined by + (object_temperature, "
                         "taxel_constants), e.g. taxel_constants,taxel_constants+"
                         "object_temperature")
    ev.add_argument("--plot", metavar="DIR",
                    help="draw accuracy against duration and the confusion matrices into DIR")
    ev.add_argument("--object-temperature-range", type=float, default=0.0, metavar="K",
                    help="objects may be up to K colder or warmer than the training data's: "
                         "with --train/--test, also report each method with its confidence "
                         "bounded by the physics over that range (skin.models.nuisance; "
                         "default 0: not reported)")
    ev.add_argument("--json", action="store_true", help="print one JSON document")
    ev.set_defaults(func=main)


def calibrated_sensors(path: str, data) -> dict:
    """Return taxel id -> `SensorConstants` from a calibration file's thermal constants.

    Raises `SkinError` if the file gives none of the dataset's taxels (another unit's file,
    or other ids: nothing would be warped); warns, on stderr, naming the taxels it leaves
    out (their traces stay as recorded).
    """
    import sys

    from skin.formats.calibration_file import load_calibration
    from skin.models.timescale import taxel_constants

    if data.taxel is None:
        raise SkinError(f"{data.source}: --calibration needs the dataset's 'taxel' column")
    sensors = taxel_constants(load_calibration(path), path)
    ids = sorted({int(k) for k in np.asarray(data.taxel).ravel() if k >= 0})
    missing = [k for k in ids if k not in sensors]
    if ids and len(missing) == len(ids):
        raise SkinError(f"{path} gives thermal constants for none of the taxels of "
                        f"{data.source} ({_some(ids)}): a calibration of another unit?")
    if missing:
        print(f"warning: {path} gives no thermal constants for taxel"
              f"{'s' * (len(missing) > 1)} {_some(missing)} of {data.source}: their traces "
              "stay as recorded", file=sys.stderr)
    return sensors


def _some(ids: list[int], most: int = 10) -> str:
    """Name up to ``most`` ids, and how many more."""
    shown = ", ".join(map(str, ids[:most]))
    return shown + (f" and {len(ids) - most} more" if len(ids) > most else "")


def _time_left(spent: list[tuple[float, float]], left: list[float], methods_left: int) -> str:
    """Say how long the rest takes, as far as it is known.

    Methods differ tenfold in cost, and a method's cost grows with the window anywhere from
    not at all (svm-pca) to in proportion (hmm): only a method's own steps predict its next
    ones. The next steps are extrapolated from its first and last as a power of the window
    (exponent 0.5 after one step); methods not started yet are named, not guessed.
    """
    if not spent:
        guess = "time left unknown until a step of it has run"
    else:
        (d0, t0), (d1, t1) = spent[0], spent[-1]
        power = 0.5
        if d1 > d0 and t0 > 0 and t1 > 0:
            power = float(np.clip(np.log(t1 / t0) / np.log(d1 / d0), 0.0, 1.5))
        guess = f"about {sum(t1 * (d / d1) ** power for d in left):.0f} s left of this method"
    if methods_left:
        guess += f", then {methods_left} more method{'s' * (methods_left > 1)} not timed yet"
    return guess


def independent_groups(data) -> tuple[np.ndarray | None, str]:
    """Label the trials so that trials sharing a ``group`` or any taxel share a label.

    Folds that keep each label on one side test every trial on taxels (and recording units)
    the model never saw: the connected components of trials linked by a common ``group`` id
    or a common known taxel id (``taxel`` >= 0, any channel).

    Returns
    -------
    (numpy.ndarray or None, str)
        The component of each trial (None when the dataset names neither groups nor taxels)
        and what the labels were made from.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(data.label)
    rows, cols, used = [], [], []
    offset = n
    if data.group is not None:
        _, g = np.unique(np.asarray(data.group), return_inverse=True)
        rows.append(np.arange(n))
        cols.append(offset + g)
        offset += int(g.max()) + 1
        used.append("group")
    if data.taxel is not None and np.any(np.asarray(data.taxel) >= 0):
        tax = np.asarray(data.taxel).reshape(n, -1)
        trial, ch = np.nonzero(tax >= 0)
        _, t = np.unique(tax[trial, ch], return_inverse=True)
        rows.append(trial)
        cols.append(offset + t)
        offset += int(t.max()) + 1
        used.append("taxel")
    if not used:
        return None, "none"
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(r.size), (r, c)), shape=(offset, offset))
    _, label = connected_components(graph, directed=False)
    return label[:n], " and ".join(used)


def split_folds(data, folds: int, split: str = "grouped", seed: int = 0
                ) -> tuple[list[tuple[np.ndarray, np.ndarray]], str]:
    """Return the cross-validation folds (train, test index pairs) and a line saying how.

    ``"grouped"``: `independent_groups` kept on one side each (stratified by class as far as
    the groups allow); a dataset that names no group or taxel falls back to stratified, and
    the line says so. ``"stratified"``: by class only.

    Raises
    ------
    SkinError
        Too few trials or groups for the folds, or a training fold without some class.
    """
    from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold

    y = data.label
    idx = np.zeros((len(y), 1))
    if split not in ("grouped", "stratified"):
        raise SkinError(f"unknown split {split!r}; grouped or stratified")
    groups, made_of = (None, "") if split == "stratified" else independent_groups(data)
    smallest = min(int(np.sum(y == c)) for c in data.classes)
    if smallest < folds:
        raise SkinError(f"{data.source}: a class has only {smallest} trials, fewer than "
                        f"the {folds} folds")
    if groups is None:
        how = ("stratified by class (folds may share taxels: optimistic where a taxel marks "
               "its class)" if split == "stratified" else
               "stratified by class: the dataset names no group or taxel, so folds may share "
               "taxels")
        return list(StratifiedKFold(folds, shuffle=True, random_state=seed).split(idx, y)), how
    n_groups = int(groups.max()) + 1
    if n_groups < folds:
        raise SkinError(f"{data.source}: {n_groups} independent groups (trials linked by "
                        f"{made_of}) cannot make {folds} folds; --split stratified ignores "
                        f"them (optimistic)")
    out = list(StratifiedGroupKFold(folds, shuffle=True, random_state=seed)
               .split(idx, y, groups))
    for train, _ in out:
        missing = sorted(set(data.classes) - set(y[train].tolist()))
        if missing:
            raise SkinError(f"{data.source}: grouped by {made_of}, a training fold has no "
                            f"trial of {', '.join(missing)}: record each class on more "
                            f"taxels, use fewer --cv folds, or --split stratified (optimistic)")
    return out, (f"grouped: {n_groups} independent groups of trials linked by {made_of}; no "
                 f"taxel on both sides of a fold")


def evaluate(data, method: str, duration: float, folds: int, split: str = "grouped",
             seed: int = 0, per_trial: bool = False) -> dict:
    """Cross-validate ``method`` on the first ``duration`` s after onset; return the figures.

    ``split``: `split_folds`'s; the result's ``split`` says how the folds were made.
    ``per_trial``: also return ``correct``, whether each trial was named right when it was
    in the test fold (bool per trial, for paired errors).
    """
    from sklearn.metrics import confusion_matrix

    from skin.bench.reliability import EVALUATE_BINS, expected_calibration_error
    from skin.models.classifiers import fit_grouped, make_method, method_matrix

    x = method_matrix(data, method, duration)
    y = data.label
    classes = data.classes
    splits, how = split_folds(data, folds, split, seed)
    groups = independent_groups(data)[0] if split == "grouped" else None
    n_train = len(y) - int(np.ceil(len(y) / folds))
    if "pca" in method and min(n_train, x.shape[1] - 2) < 10:
        raise SkinError(f"{data.source}: PCA with 10 components needs at least 10 training "
                        f"trials and 10 samples per window; a {duration} s window with "
                        f"{folds} folds has {n_train} trials of {x.shape[1] - 2} samples")
    acc, fit_t, pred_t = [], [], []
    unknown = 0
    conf = np.zeros((len(classes), len(classes)), dtype=int)
    top, right = [], []  # most probable class's probability, and whether it was right
    correct = np.zeros(len(y), dtype=bool)
    for train, test in splits:
        model = make_method(method, fs=data.fs, channels=data.n_channels)
        t0 = time.perf_counter()
        # a model's own calibration folds then keep the taxels apart too
        fit_grouped(model, x[train], y[train], None if groups is None else groups[train])
        t1 = time.perf_counter()
        if hasattr(model, "predict_proba"):
            proba = model.predict_proba(x[test])
            pred = np.asarray(model.classes_)[np.argmax(proba, axis=1)]
            top.append(proba.max(axis=1))
            right.append(pred == y[test])
        else:
            pred = model.predict(x[test])
        t2 = time.perf_counter()
        acc.append(float(np.mean(pred == y[test])))
        correct[test] = pred == y[test]
        fit_t.append((t1 - t0) / len(train))
        pred_t.append((t2 - t1) / len(test))
        conf += confusion_matrix(y[test], pred, labels=classes)
        unknown += int(np.sum(pred == "unknown"))
    recall = conf.diagonal() / np.maximum(conf.sum(axis=1), 1)
    out = {"method": method, "duration": duration, "folds": folds, "split": how,
           # over all trials (grouped folds differ in size), the std over the folds
           "accuracy": round(float(np.trace(conf) / len(y)), 4),
           "accuracy_std": round(float(np.std(acc)), 4),
           "recall": {c: round(float(r), 4) for c, r in zip(classes, recall, strict=True)},
           "confusion": conf.tolist(), "classes": classes, "unknown": unknown,
           "fit_ms_per_trial": round(1e3 * float(np.mean(fit_t)), 4),
           "predict_ms_per_trial": round(1e3 * float(np.mean(pred_t)), 4)}
    if top:
        top, right = np.concatenate(top), np.concatenate(right)
        out["selective"] = selective(top, right)
        out["calibration_error"] = round(
            expected_calibration_error(top, right, EVALUATE_BINS), 4)
        out["confident_wrong"] = round(confident_wrong(top, right), 4)
    if per_trial:
        out["correct"] = correct
    return out


def selective(top: np.ndarray, right: np.ndarray,
              thresholds: tuple[float, ...] = (0.5, 0.8, 0.9, 0.95)) -> list[dict]:
    """Coverage and accuracy when a method says "unknown" below a probability threshold.

    Parameters
    ----------
    top : numpy.ndarray
        Probability of each trial's most probable class.
    right : numpy.ndarray
        Whether that class was the true one.
    thresholds : tuple of float
        Probabilities below which the answer would be "unknown".

    Returns
    -------
    list of dict
        Per threshold: the fraction of trials named (coverage) and the accuracy among them.
    """
    rows = []
    for t in thresholds:
        named = top >= t
        rows.append({"threshold": t, "coverage": round(float(named.mean()), 4),
                     "accuracy": round(float(right[named].mean()), 4) if named.any()
                     else None})
    return rows


def confident_wrong(top: np.ndarray, right: np.ndarray, level: float = 0.95) -> float:
    """Return the share of all answers given at probability >= ``level`` and wrong."""
    return float(np.mean((np.asarray(top) >= level) & ~np.asarray(right, dtype=bool)))


def bounded_figures(proba: np.ndarray, x: np.ndarray, truth: np.ndarray, classes: list[str],
                    object_range: float, channels: int, fs: float, voted: bool = False
                    ) -> dict:
    """Return the figures of ``proba`` bounded over ``object_range`` K (skin.models.nuisance)."""
    from skin.bench.reliability import EVALUATE_BINS, expected_calibration_error
    from skin.models.nuisance import bound

    q = bound(proba, x, classes, object_range, channels, fs, voted=voted)
    pred = np.asarray(classes)[np.argmax(q, axis=1)]
    top, right = q.max(axis=1), pred == truth
    return {"object_temperature_range": object_range,
            "accuracy": round(float(np.mean(right)), 4),
            "calibration_error": round(
                expected_calibration_error(top, right, EVALUATE_BINS), 4),
            "confident_wrong": round(confident_wrong(top, right), 4),
            "selective": selective(top, right)}


def score_test_set(pred: np.ndarray, proba: np.ndarray | None, truth: np.ndarray,
                 classes: list[str]) -> dict:
    """Return the figures of predictions on a test set.

    Accuracy, recall and the confusion matrix over the test trials whose class is among
    ``classes`` (the model's); the others are reported under ``unseen`` with what they were
    called; answers "unknown" counted; with probabilities, the selective accuracy, the
    calibration error and the share of answers wrong at p >= 0.95.
    """
    from sklearn.metrics import confusion_matrix

    from skin.bench.reliability import EVALUATE_BINS, expected_calibration_error

    seen = np.isin(truth, classes)
    conf = confusion_matrix(truth[seen], pred[seen], labels=classes)
    recall = conf.diagonal() / np.maximum(conf.sum(axis=1), 1)
    unseen = {}
    for c in sorted(set(truth[~seen].tolist())):
        called, counts = np.unique(pred[truth == c], return_counts=True)
        unseen[c] = {str(k): int(v) for k, v in zip(called, counts, strict=True)}
    out = {"accuracy": round(float(np.mean(pred[seen] == truth[seen])), 4)
           if seen.any() else None,
           "accuracy_std": 0.0,
           "recall": {c: round(float(r), 4) for c, r in zip(classes, recall, strict=True)},
           "confusion": conf.tolist(), "classes": classes,
           "unknown": int(np.sum(pred == "unknown")), "unseen": unseen}
    if proba is not None and seen.any():
        top, right = proba[seen].max(axis=1), pred[seen] == truth[seen]
        out["selective"] = selective(top, right)
        out["calibration_error"] = round(
            expected_calibration_error(top, right, EVALUATE_BINS), 4)
        out["confident_wrong"] = round(confident_wrong(top, right), 4)
    return out


def train_test(train, test, method: str, duration: float, object_range: float = 0.0) -> dict:
    """Train ``method`` on one dataset and test it on another; return the figures.

    Test classes absent from the training data are left out of the accuracy and reported
    under ``unseen`` with the labels they were given. With ``object_range`` > 0 the figures
    of the confidence bounded over that many K (`skin.models.nuisance`) are added under
    ``bounded`` (a method without probabilities is bounded from its votes).
    """
    from skin.models.classifiers import fit_grouped, make_method, method_matrix, reads_channels

    if train.n_channels != test.n_channels:
        raise SkinError(f"{test.source}: {test.n_channels} channel(s) per trial, the training "
                        f"data {train.n_channels}")
    x_train, x_test = method_matrix(train, method, duration), method_matrix(test, method,
                                                                              duration)
    model = make_method(method, fs=train.fs, channels=train.n_channels)
    t0 = time.perf_counter()
    fit_grouped(model, x_train, train.label, independent_groups(train)[0])
    t1 = time.perf_counter()
    proba = model.predict_proba(x_test) if hasattr(model, "predict_proba") else None
    if proba is not None:
        pred = np.asarray(model.classes_)[np.argmax(proba, axis=1)]
    else:
        pred = model.predict(x_test)
    t2 = time.perf_counter()
    out = {"method": method, "duration": duration,
           **score_test_set(pred, proba, test.label, train.classes),
           "fit_ms_per_trial": round(1e3 * (t1 - t0) / len(train), 4),
           "predict_ms_per_trial": round(1e3 * (t2 - t1) / len(test), 4)}
    seen = np.isin(test.label, train.classes)
    if object_range > 0 and seen.any():
        from skin.models.nuisance import votes

        p = proba if proba is not None else votes(pred, model.classes_)
        out["bounded"] = bounded_figures(
            p[seen], x_test[seen], test.label[seen], [str(c) for c in model.classes_],
            object_range, train.n_channels if reads_channels(method) else 1, train.fs,
            voted=proba is None)
    return out


def saved_model(doc: dict, test, durations: list[float]) -> list[dict]:
    """Test a loaded model file (`skin.models.modelfile.load_model`) on a dataset.

    Test classes the model does not know are reported under ``unseen`` with what they were
    called, as in `train_test`.
    """
    from skin.models.classifiers import method_matrix

    est = doc["estimator"]
    method = str(doc["method"])
    base = method.removeprefix("anytime:")
    channels = int(doc["features"].get("channels", 1))
    if channels > 1 and test.n_channels != channels:
        raise SkinError(f"{test.source}: {test.n_channels} channel(s) per trial; the model "
                        f"reads {channels}")
    if abs(float(doc["features"]["fs"]) - test.fs) > 1e-6:
        raise SkinError(f"{test.source}: sampled at {test.fs:g} Hz, the model at "
                        f"{doc['features']['fs']:g} Hz")
    if not method.startswith("anytime:"):
        durations = [float(doc["features"]["duration"])]
    classes = [str(c) for c in est.classes_]
    out = []
    for duration in durations:
        x = method_matrix(test if channels > 1 else test.channels([0]), base, duration)
        t1 = time.perf_counter()
        proba = est.predict_proba(x) if hasattr(est, "predict_proba") else None
        pred = (np.asarray(est.classes_)[np.argmax(proba, axis=1)] if proba is not None
                else est.predict(x)).astype(str)
        t2 = time.perf_counter()
        out.append({"method": f"model:{method}", "duration": duration,
                    **score_test_set(pred, proba, test.label, classes), "fit_ms_per_trial": 0.0,
                    "predict_ms_per_trial": round(1e3 * (t2 - t1) / len(test), 4)})
    return out


def family_merge(classes: list[str]) -> list[set[str]] | None:
    """Return the table's families as a merge of ``classes`` (None if one is not in it)."""
    from skin.models.materials import load_materials

    table = load_materials()
    if not all(c in table for c in classes):
        return None
    fams: dict[str, set[str]] = {}
    for c in classes:
        fams.setdefault(table[c].family, set()).add(c)
    return list(fams.values())


def merged_accuracy(result: dict, merge: list[set[str]]) -> float:
    """Accuracy when each set of ``merge`` counts as one class (from the confusion matrix)."""
    classes = result["classes"]
    group = {c: next((i for i, g in enumerate(merge) if c in g), len(merge) + k)
             for k, c in enumerate(classes)}
    conf = np.asarray(result["confusion"])
    same = np.array([[group[a] == group[b] for b in classes] for a in classes])
    return float(conf[same].sum() / conf.sum())


def _parse_merge(text: str | None, classes: list[str]) -> list[set[str]]:
    if not text:
        return []
    merge = [set(part.split("+")) for part in text.split(",") if part.strip()]
    unknown = sorted(set().union(*merge) - set(classes))
    if unknown:
        raise SkinError(f"--merge names classes not in the dataset: {', '.join(unknown)}")
    return merge


def _trained_sensor(model_doc: dict, path: str) -> object:
    """Return the preset a model file says it was trained with, or None (the paper's).

    A model file keeps the sensor's name only: one from a sensor file (not a preset) cannot
    be loaded back, and the paper's detector finds the onsets, with a warning.
    """
    from skin.errors import SensorError
    from skin.models.sensors import load_sensor

    name = model_doc.get("training", {}).get("sensor")
    if name is None:
        return None
    try:
        return load_sensor(name)
    except SensorError:
        print(f"warning: {path} was trained with sensor {name!r}, not a preset: unknown "
              f"onsets are found by the paper's detector; give --sensor FILE for that "
              f"sensor's", file=sys.stderr)
        return None


def main(args: argparse.Namespace) -> int:
    """Run the evaluation and print a table (or JSON)."""
    from skin.formats.dataset import (
        force_onsets,
        load_trials,
        require_classes,
        with_detected_onsets,
    )
    from skin.models.classifiers import parse_method

    if args.train and not args.test:
        raise SkinError("--train needs --test")
    if args.test and not args.train:
        raise SkinError("--test goes with --train (use --data for cross-validation)")
    if args.model and not args.data:
        raise SkinError("--model is evaluated on --data")
    model_doc = None
    if args.model:  # before the work starts: the file, and the constants a warped model needs
        from skin.models.modelfile import check_time_scale, load_model

        model_doc = load_model(args.model)
        if not args.calibration:
            check_time_scale(model_doc, args.model, None)
    data = require_classes(load_trials(args.data or args.train))
    test = load_trials(args.test) if args.test else None
    sets = [s for s in (data, test) if s is not None]  # unknown onsets: force, else detector
    from_force = sum(int(np.sum((s.onset < 0) & (force_onsets(s) >= 0))) for s in sets)
    detected = sum(int(np.sum(s.onset < 0)) for s in sets) - from_force
    recorded_with = None
    if args.sensor is not None:  # a bad name or file fails before the work starts
        from skin.models.sensors import load_sensor

        recorded_with = load_sensor(args.sensor)
    elif model_doc is not None and detected:
        recorded_with = _trained_sensor(model_doc, args.model)
    data = with_detected_onsets(data, sensor=recorded_with)
    test = None if test is None else with_detected_onsets(test, sensor=recorded_with)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    for m in methods:
        parse_method(m)
    try:
        durations = [float(d) for d in args.durations.split(",") if d.strip()]
    except ValueError:
        raise SkinError(f"--durations must be numbers, got {args.durations!r}") from None
    if args.cv < 2:
        raise SkinError("--cv must be at least 2")
    if not (np.isfinite(args.object_temperature_range) and args.object_temperature_range >= 0):
        raise SkinError(f"--object-temperature-range must be a finite K >= 0, got "
                        f"{args.object_temperature_range:g}")
    if args.object_temperature_range > 0 and test is None:
        raise SkinError("--object-temperature-range goes with --train/--test (a "
                        "cross-validation's folds share their objects' temperatures)")
    merge = _parse_merge(args.merge, data.classes)
    cv = test is None and not args.model
    split_line = split_folds(data, args.cv, args.split, args.seed)[1] if cv else None
    told_less = [tuple(p.strip() for p in entry.split("+"))
                 for entry in args.ceiling_unknown.split(",") if entry.strip()]
    if told_less and not args.ceiling:
        raise SkinError("--ceiling-unknown goes with --ceiling")
    if args.ceiling:  # before the work starts
        from skin.bench.ceiling import UNKNOWABLE, check_ceiling

        bad = sorted({u for entry in told_less for u in entry} - set(UNKNOWABLE))
        if bad:
            raise SkinError(f"--ceiling-unknown: unknown nuisance(s) {', '.join(bad)}; "
                            f"choose from {', '.join(UNKNOWABLE)}")
        check_ceiling(test if test is not None else data)
    sensors = None
    if args.calibration:  # before the work starts
        sensors = calibrated_sensors(args.calibration, test if test is not None else data)
    progress = Progress()
    if args.object_temperature_range > 0:
        from skin.models.nuisance import object_spread, uncovered

        warning = uncovered(args.object_temperature_range, object_spread(data))
        if warning:
            progress.message(f"warning: {args.train}: {warning}")
    started = time.monotonic()
    results = []
    total = len(methods) * len(durations)
    runs = [(data, test, "")]
    if sensors is not None:  # each method also reads every taxel on the design's time scale
        from skin.models.timescale import warp_to_nominal

        runs.append((warp_to_nominal(data, sensors),
                     None if test is None else warp_to_nominal(test, sensors), "+commissioned"))
    if model_doc is not None:
        from skin.models.modelfile import check_time_scale, reads_nominal_time

        check_time_scale(model_doc, args.model, sensors)
        results = saved_model(model_doc, runs[-1][0] if reads_nominal_time(model_doc) else data,
                              durations)
        methods = []
    for k, m in enumerate(methods):
        spent: list[tuple[float, float]] = []  # (duration, seconds) of this method's steps
        for j, d in enumerate(durations):
            progress.status(f"evaluate {m} {d:g} s ({len(results) + 1}/{total}; "
                            f"{_time_left(spent, durations[j:], len(methods) - k - 1)})")
            t0 = time.monotonic()
            for ds, ts, tag in runs:
                if ts is None:
                    r = evaluate(ds, m, d, args.cv, args.split, args.seed)
                else:
                    r = train_test(ds, ts, m, d, args.object_temperature_range)
                r["method"] += tag
                results.append(r)
                if merge:
                    r["merged_accuracy"] = round(merged_accuracy(r, merge), 4)
            spent.append((d, time.monotonic() - t0))
    if methods:
        progress.status(f"evaluated {total} method-durations in "
                        f"{time.monotonic() - started:.0f} s", force=True)
    if args.ceiling:
        from skin.bench.ceiling import ceilings, known_nuisance_ceiling

        for d in durations:
            progress.message(f"ceiling {d:g} s")
            for r in ceilings(test if test is not None else data, d):
                results.append(r)
                if merge:
                    r["merged_accuracy"] = round(merged_accuracy(r, merge), 4)
        for unknown in told_less:
            for d in durations:
                progress.message(f"ceiling {d:g} s" + "".join(f", {u} unknown"
                                                              for u in unknown))
                results.append(known_nuisance_ceiling(test if test is not None else data, d,
                                                      unknown))
                if merge:
                    results[-1]["merged_accuracy"] = round(merged_accuracy(results[-1], merge),
                                                           4)
    if sensors is not None:
        from skin.bench.ceiling import joint_fit_accuracy

        for d in durations:
            progress.message(f"joint fit, calibrated, {d:g} s")
            results.append(joint_fit_accuracy(test if test is not None else data, d,
                                              "calibrated", sensors, train=data))
    progress.done()
    families = family_merge(data.classes)
    for r in results:
        if families is not None and r["classes"] == data.classes:
            r["family_accuracy"] = round(merged_accuracy(r, families), 4)
    doc = {"data": str(args.data or args.train), "trials": len(data), "classes": data.classes,
           "cv": args.cv if cv else None, "split": split_line,
           "merge": [sorted(g) for g in merge], "onsets_from_force": from_force,
           "onsets_detected": detected,
           "results": results}
    if test is not None:
        doc["test"] = {"data": str(args.test), "trials": len(test), "classes": test.classes}
    if args.plot:
        from pathlib import Path

        from skin.viz.plots import plot_accuracy, plot_confusions

        out = Path(args.plot)
        doc["figures"] = [str(plot_accuracy(results, out / "accuracy.png"))]
        doc["figures"] += [str(plot_confusions([r for r in results if r["method"] == m],
                                               out / f"confusion_{m.replace(':', '_')}.png"))
                           for m in methods]
    if args.json:
        print(json.dumps(doc))
        return 0
    if cv:
        print(f"{len(data)} trials, {len(data.classes)} classes, {args.cv}-fold "
              f"cross-validation, {split_line}")
    elif test is None:
        print(f"{len(data)} trials, {len(data.classes)} classes, model {args.model}")
    else:
        print(f"trained on {args.train} ({len(data)} trials), tested on {args.test} "
              f"({len(test)} trials)")
    print(f"{'method':<14} {'duration s':>10} {'accuracy':>14} {'fit ms/trial':>13} "
          f"{'predict ms/trial':>17}" + (f" {'merged':>7}" if merge else ""))
    for r in results:
        acc = "-" if r["accuracy"] is None else f"{r['accuracy']:.3f}"
        print(f"{r['method']:<14} {r['duration']:>10g} {acc:>8} +- "
              f"{r['accuracy_std']:.3f} {r['fit_ms_per_trial']:>13.3f} "
              f"{r['predict_ms_per_trial']:>17.4f}"
              + (f" {r['merged_accuracy']:>7.3f}" if merge else ""))
        if "confident" in r:
            print(f"{'':<14} {'':>10}   answers at p >= 0.9: {r['confident']:.0%}"
                  + (f", {r['confident_right']:.3f} of them right" if r["confident"] else ""))
        if "family_accuracy" in r:
            print(f"{'':<14} {'':>10}   family accuracy {r['family_accuracy']:.3f}")
        if "calibration_error" in r:
            print(f"{'':<14} {'':>10}   calibration error {r['calibration_error']:.3f}"
                  + (f", wrong at p >= 0.95: {r['confident_wrong']:.1%} of answers"
                     if "confident_wrong" in r else ""))
        if "bounded" in r:
            b = r["bounded"]
            print(f"{'':<14} {'':>10}   bounded over +-{b['object_temperature_range']:g} K: "
                  f"accuracy {b['accuracy']:.3f}, calibration error "
                  f"{b['calibration_error']:.3f}, wrong at p >= 0.95: "
                  f"{b['confident_wrong']:.1%} of answers")
        for sel in r.get("selective", []):
            if sel["threshold"] in (0.8, 0.95) and sel["accuracy"] is not None:
                print(f"{'':<14} {'':>10}   unknown below p = {sel['threshold']:g}: "
                      f"{sel['coverage']:.0%} named, {sel['accuracy']:.3f} of them right")
        for c, called in r.get("unseen", {}).items():
            print(f"{'':<10} unseen class {c} was called "
                  + ", ".join(f"{k} x{v}" for k, v in called.items()))
    if "figures" in doc:
        print("figures: " + ", ".join(doc["figures"]))
    return 0

"""Model files: a trained classifier with its settings, saved with skops.io, loaded safely.

A model file holds a dictionary: ``format`` (this module's `FORMAT`), ``library`` (the
thermoskin version that wrote it), ``method`` (``"svm-pca:both"``), ``features`` (window
duration, sampling rate, channels and, for a model trained on commissioned traces,
``time_scale`` "nominal"), ``classes``, ``training`` (a summary of the training data) and
``estimator``. Loading never executes code: skops.io itself trusts only plain containers,
numpy arrays and scikit-learn's estimators, and lists every other type a file would build; a
file naming any type outside `ALLOWED` (the exact classes this library's methods are made
of) is refused before anything is built. A file of a format outside `READS` is refused with
the versions in the message.

A model trained on traces warped to the design's time scale (``skin train --calibration``,
`skin.models.timescale`) is only right on traces warped alike, so its file is of format
`NOMINAL_FORMAT`: a version that cannot warp refuses it instead of reading unwarped traces
with it; every other file stays of `FORMAT`.
"""

from __future__ import annotations

import datetime
from pathlib import Path
from typing import Any

import numpy as np

from skin._optional import require
from skin.errors import SkinError

FORMAT = 1
#: Format of a model that reads traces on the design's time scale (``time_scale`` "nominal").
NOMINAL_FORMAT = 2
READS = (FORMAT, NOMINAL_FORMAT)
#: Types beyond skops' own defaults that a model file may build; anything else is refused.
ALLOWED = frozenset({
    "skin.models.classifiers.TraceFeatures",
    "skin.models.classifiers.PhysicsFeatures",
    "skin.models.classifiers.HMMClassifier",
    "skin.models.classifiers.ModelBasedClassifier",
    "skin.models.classifiers.AnytimeClassifier",
    "skin.models.contact.ContactClassifier",
    "skin.models.contact.ContactFeatures",
    "sklearn.metrics._dist_metrics.EuclideanDistance64",  # k-NN's tree
    "sklearn.neighbors._kd_tree.KDTree",
    "sklearn.neighbors._ball_tree.BallTree",
    "sklearn.ensemble._hist_gradient_boosting.predictor.TreePredictor",
    "hmmlearn.hmm.GaussianHMM",
    "hmmlearn.base.ConvergenceMonitor",
    "collections.deque",  # the convergence monitor's history
})


class ModelFileError(SkinError):
    """A model file is unreadable, unsafe, or from an incompatible version."""


def save_model(path: str | Path, estimator: Any, method: str, duration: float, fs: float,
               training: dict[str, Any], channels: int = 1,
               time_scale: str = "taxel") -> Path:
    """Write a trained estimator and its settings to ``path`` (``.skops``).

    ``channels``: channel blocks per row the estimator reads (1: one taxel's trace).
    ``time_scale``: "taxel" (traces as each taxel recorded them) or "nominal" (trained on
    traces warped to the design's time scale with each taxel's commissioned constants,
    `skin.models.timescale.warp_to_nominal`: the pipeline warps contacts alike).
    """
    require("skops", "ml")
    import skops.io as sio

    import skin

    if time_scale not in ("taxel", "nominal"):
        raise ValueError(f"time_scale must be 'taxel' or 'nominal', got {time_scale!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    features = {"duration": float(duration), "fs": float(fs), "channels": int(channels)}
    if time_scale == "nominal":
        features["time_scale"] = "nominal"
    doc = {"format": NOMINAL_FORMAT if time_scale == "nominal" else FORMAT,
           "library": skin.__version__, "method": method, "features": features,
           "classes": [str(c) for c in estimator.classes_], "training": training,
           "written": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
           "estimator": estimator}
    sio.dump(doc, path)
    return path


def untrusted_types(path: str | Path) -> list[str]:
    """Types the file would build that the allow-list does not cover."""
    require("skops", "ml")
    import skops.io as sio

    try:
        types = sio.get_untrusted_types(file=path)
    except Exception as exc:  # skops raises several kinds on a damaged archive
        raise ModelFileError(f"{path}: not a readable model file ({exc})") from None
    return [t for t in types if t not in ALLOWED]


def load_model(path: str | Path) -> dict[str, Any]:
    """Load a model file safely (see the module docstring); return its dictionary."""
    require("skops", "ml")
    import skops.io as sio

    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such model file")
    bad = untrusted_types(path)
    if bad:
        raise ModelFileError(f"{path}: refused, it would build types outside the allow-list: "
                             f"{', '.join(sorted(bad))}")
    trusted = sio.get_untrusted_types(file=path)
    try:
        doc = sio.load(path, trusted=trusted)
    except Exception as exc:
        raise ModelFileError(f"{path}: cannot load ({exc})") from None
    if not isinstance(doc, dict) or "format" not in doc or "estimator" not in doc:
        raise ModelFileError(f"{path}: not a thermoskin model file")
    if doc["format"] not in READS:
        raise ModelFileError(f"{path}: model format {doc['format']} (written by thermoskin "
                             f"{doc.get('library', '?')}); this version reads formats "
                             f"{', '.join(map(str, READS))}")
    scale = doc.get("features", {}).get("time_scale", "taxel")
    if scale not in ("taxel", "nominal") or (scale == "nominal") != (doc["format"]
                                                                     == NOMINAL_FORMAT):
        raise ModelFileError(f"{path}: format {doc['format']} with time scale {scale!r}: "
                             f"inconsistent model file")
    return doc


def reads_nominal_time(doc: dict[str, Any]) -> bool:
    """Whether a loaded model reads traces warped to the design's time scale."""
    return doc.get("features", {}).get("time_scale") == "nominal"


def check_time_scale(doc: dict[str, Any], name: str, sensors: dict | None) -> None:
    """Refuse a model trained on warped traces when no taxel's thermal constants are given.

    ``name``: the model file, named in the error; ``sensors``: taxel id -> commissioned
    constants (`skin.models.timescale.taxel_constants`), or None.

    Raises
    ------
    ModelFileError
        Naming the model file, the calibration it was trained with and what to give.
    """
    if sensors is None and reads_nominal_time(doc):
        trained = doc.get("training", {}).get("calibration")
        raise ModelFileError(
            f"{name}: trained on traces warped to the design's time scale"
            + (f" (with {trained})" if trained else "")
            + ", it needs each taxel's commissioned thermal constants and got none: give "
              "--calibration FILE (or 'calibration' in the skin file), a calibration file "
              "with thermal constants (skin calibrate thermal)")


def training_summary(data: Any, duration: float, sensor: str | None = None) -> dict[str, Any]:
    """Summarise a `skin.formats.dataset.TrialSet` for the model file.

    ``sensor``: the sensor (preset or file) the data came from, when the trainer says so;
    with ``object_temperature_spread`` (K the objects varied, from a measured column) it is
    what `skin.models.nuisance` (`uncovered`, `other_sensors`) checks a run's setup against.
    """
    labels, counts = np.unique(data.label, return_counts=True)
    summary: dict[str, Any] = {
        "source": data.source, "trials": len(data), "duration": float(duration),
        "per_class": {str(k): int(v) for k, v in zip(labels, counts, strict=True)}}
    if data.ambient is not None:
        summary["ambient"] = [round(float(data.ambient.min()), 2),
                              round(float(data.ambient.max()), 2)]
    from skin.models.nuisance import object_spread

    spread = object_spread(data)
    if spread is not None:  # K the objects varied about ambient (a measured column)
        summary["object_temperature_spread"] = round(spread, 2)
    if sensor is not None:
        from skin.models.sensors import load_sensor

        summary["sensor"] = load_sensor(sensor).name  # a bad name fails before training
    return summary

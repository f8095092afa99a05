"""Model files: a trained classifier with its settings, saved with skops.io, loaded safely.

A model file holds a dictionary: ``format`` (this module's `FORMAT`), ``library`` (the
thermoskin version that wrote it), ``method`` (``"svm-pca:both"``), ``features`` (window
duration and sampling rate), ``classes``, ``training`` (a summary of the training data) and
``estimator``. Loading never executes code: skops.io itself trusts only plain containers,
numpy arrays and scikit-learn's estimators, and lists every other type a file would build; a
file naming any type outside `ALLOWED` (the exact classes this library's methods are made
of) is refused before anything is built. A file of another `FORMAT` is refused with the
versions in the message.
"""

from __future__ import annotations

import datetime
from pathlib import Path
from typing import Any

import numpy as np

from skin._optional import require
from skin.errors import SkinError

FORMAT = 1
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
               training: dict[str, Any], channels: int = 1) -> Path:
    """Write a trained estimator and its settings to ``path`` (``.skops``).

    ``channels``: channel blocks per row the estimator reads (1: one taxel's trace).
    """
    require("skops", "ml")
    import skops.io as sio

    import skin

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"format": FORMAT, "library": skin.__version__, "method": method,
           "features": {"duration": float(duration), "fs": float(fs),
                                                   "channels": int(channels)},
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
    if doc["format"] != FORMAT:
        raise ModelFileError(f"{path}: model format {doc['format']} (written by thermoskin "
                             f"{doc.get('library', '?')}); this version reads format {FORMAT}")
    return doc


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

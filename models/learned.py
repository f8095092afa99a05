"""A trained model file as the pipeline's classifier, its taxels' evidence fused.

`LearnedClassifier` classifies a `skin.contact.Contact` with a model file written by
``skin train``: each taxel's window (resampled onto the model's sample grid, cut to the
model's duration) becomes a row ``[ambient, T0, window...]``; the taxels' class probabilities
are fused (`skin.models.classifiers.fuse_probabilities`), and the label is the most probable
material, or ``"unknown"`` when no taxel's window is long enough or the fused probability is
below ``threshold``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from skin.contact import UNKNOWN, Contact, MaterialEstimate


class LearnedClassifier:
    """Classify contacts with a trained model file.

    Parameters
    ----------
    model : str, Path or dict
        A model file path, or the dictionary `skin.models.modelfile.load_model` returns.
    threshold : float
        Fused probability needed to name a material.
    """

    def __init__(self, model: str | Path | dict, threshold: float = 0.0) -> None:
        from skin.models.modelfile import load_model

        self.doc = model if isinstance(model, dict) else load_model(model)
        self.estimator = self.doc["estimator"]
        self.fs = float(self.doc["features"]["fs"])
        self.samples = round(float(self.doc["features"]["duration"]) * self.fs)
        self.classes = [str(c) for c in self.estimator.classes_]
        self.threshold = threshold
        self.method = f"learned:{self.doc['method']}"

    def rows(self, contact: Contact) -> np.ndarray:
        """Rows ``[ambient, T0, window...]`` of the taxels whose windows are long enough."""
        grid = np.arange(self.samples) / self.fs
        rows = []
        for w in contact.windows:
            ok = np.isfinite(w.temperature)
            if ok.sum() < 2 or w.time[ok][-1] < grid[-1] - 0.5 / self.fs:
                continue  # released (or cut) before the model's window is full
            y = np.interp(grid, w.time[ok], w.temperature[ok])
            rows.append(np.concatenate([[contact.ambient, w.initial], y]))
        return np.array(rows).reshape(len(rows), 2 + self.samples)

    def classify(self, contact: Contact) -> MaterialEstimate:
        """Label a contact from all its taxels' evidence."""
        from skin.models.classifiers import fuse_probabilities

        x = self.rows(contact)
        if x.shape[0] == 0:
            return MaterialEstimate(UNKNOWN, {}, 0.0, None, self.method)
        if hasattr(self.estimator, "predict_proba"):
            p = self.estimator.predict_proba(x)
        else:  # a method without probabilities: each taxel votes with certainty
            pred = self.estimator.predict(x)
            p = np.array([[0.999 if c == lab else 0.001 / max(len(self.classes) - 1, 1)
                           for c in self.classes] for lab in pred])
        fused = fuse_probabilities(p)
        best = int(np.argmax(fused))
        probs = {c: float(v) for c, v in zip(self.classes, fused, strict=True)}
        confidence = float(fused[best])
        label = self.classes[best] if confidence >= self.threshold else UNKNOWN
        return MaterialEstimate(label, probs, confidence, None, self.method)

"""A trained model file as the pipeline's classifier, its taxels' evidence fused.

`LearnedClassifier` classifies a `skin.contact.Contact` with a model file written by
``skin train``: each taxel's window (resampled onto the model's sample grid, cut to the
model's duration) becomes a row ``[ambient, T0, window...]``; the taxels' class probabilities
are fused (`skin.models.classifiers.fuse_probabilities`), and the label is the most probable
material, or ``"unknown"`` when no taxel's window is long enough or the fused probability is
below ``threshold``. A model trained with ``skin train --anytime`` holds one model per
duration: each taxel then answers from the longest of them its window covers, so a brief
touch is named from what it gave, with the confidence that brevity allows.
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

    @property
    def lengths(self) -> list[int]:
        """Window lengths (samples) the model reads, shortest first."""
        return list(getattr(self.estimator, "samples_", [self.samples]))

    def rows(self, contact: Contact, samples: int | None = None) -> np.ndarray:
        """Rows ``[ambient, T0, window...]`` of the taxels whose windows cover ``samples``.

        ``samples`` defaults to the model's full window.
        """
        n = self.samples if samples is None else samples
        picked = [w for w in contact.windows if self._covers(w, n)]
        return self._rows(contact, picked, n)

    def probabilities(self, contact: Contact) -> np.ndarray:
        """Class probabilities per taxel, (n_taxels that can answer, n_classes).

        Each taxel answers from the longest window the model reads that it covers.
        """
        parts, left = [], list(contact.windows)
        for n in reversed(self.lengths):
            covers = [self._covers(w, n) for w in left]
            picked = [w for w, c in zip(left, covers, strict=True) if c]
            left = [w for w, c in zip(left, covers, strict=True) if not c]
            if picked:
                parts.append(self._predict(self._rows(contact, picked, n)))
        return np.vstack(parts) if parts else np.empty((0, len(self.classes)))

    def _covers(self, window, samples: int) -> bool:
        ok = np.isfinite(window.temperature)
        return bool(ok.sum() >= 2
                    and window.time[ok][-1] >= (samples - 1) / self.fs - 0.5 / self.fs)

    def _rows(self, contact: Contact, windows: list, samples: int) -> np.ndarray:
        grid = np.arange(samples) / self.fs
        rows = []
        for w in windows:
            ok = np.isfinite(w.temperature)
            y = np.interp(grid, w.time[ok], w.temperature[ok])
            rows.append(np.concatenate([[contact.ambient, w.initial], y]))
        return np.array(rows).reshape(len(rows), 2 + samples)

    def _predict(self, x: np.ndarray) -> np.ndarray:
        from skin.threads import limited_threads

        with limited_threads():
            if hasattr(self.estimator, "predict_proba"):
                return self.estimator.predict_proba(x)
            pred = self.estimator.predict(x)  # no probabilities: each taxel votes with certainty
        return np.array([[0.999 if c == lab else 0.001 / max(len(self.classes) - 1, 1)
                          for c in self.classes] for lab in pred])

    def classify(self, contact: Contact) -> MaterialEstimate:
        """Label a contact from all its taxels' evidence."""
        from skin.models.classifiers import fuse_probabilities

        p = self.probabilities(contact)
        if p.shape[0] == 0:
            return MaterialEstimate(UNKNOWN, {}, 0.0, None, self.method)
        fused = fuse_probabilities(p)
        best = int(np.argmax(fused))
        probs = {c: float(v) for c, v in zip(self.classes, fused, strict=True)}
        confidence = float(fused[best])
        label = self.classes[best] if confidence >= self.threshold else UNKNOWN
        return MaterialEstimate(label, probs, confidence, None, self.method)

"""A trained model file as the pipeline's classifier, its taxels' evidence fused.

`LearnedClassifier` classifies a `skin.contact.Contact` with a model file written by
``skin train``: each taxel's window (resampled onto the model's sample grid, cut to the
model's duration) becomes a row ``[ambient, T0, window...]``; the taxels' class probabilities
are fused (`skin.models.classifiers.fuse_probabilities`), and the label is the most probable
material, or ``"unknown"`` when no taxel's window is long enough or the fused probability is
below ``threshold`` (then the material's family is named when its summed probability
reaches it, `skin.models.materials.hierarchical_answer`). A model of several channels (``skin
train`` on a dataset of several channels per contact) reads one row per contact: its taxels,
warmest before contact first (heated before passive), fill the channels, NaN where it has
fewer. The effusivity reported is measured (`skin.models.contact_fit.fitted_effusivity`).
A model trained with ``skin train --anytime`` holds one model per
duration: each taxel then answers from the longest of them its window covers, so a brief
touch is named from what it gave, with the confidence that brevity allows.
A model trained on traces warped to the design's time scale (``skin train --calibration``)
reads each taxel's window warped alike with that taxel's commissioned constants
(`skin.models.timescale.taxel_times`): it is refused without them.
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
    object_range : float
        K objects may be colder or warmer than the training data's: each taxel's
        probabilities are bounded by the physics over that range (`skin.models.nuisance`)
        before they are fused; 0 uses them as they are.
    sensors : dict, optional
        Taxel id -> commissioned `SensorConstants` (`skin.models.timescale.taxel_constants`
        of a calibration file). A model trained on warped traces needs them and warps each
        taxel's window onto the design's time scale (taxels missing from it are read as
        recorded, as in training); other models ignore them.

    Raises
    ------
    ModelFileError
        If the model reads warped traces and ``sensors`` is None, naming the model file.
    """

    def __init__(self, model: str | Path | dict, threshold: float = 0.0,
                 object_range: float = 0.0, sensors: dict | None = None) -> None:
        from skin.models.modelfile import check_time_scale, load_model, reads_nominal_time
        from skin.models.nuisance import uncovered

        self.doc = model if isinstance(model, dict) else load_model(model)
        check_time_scale(self.doc, "the model" if isinstance(model, dict) else str(model),
                         sensors)
        #: taxel id -> constants its windows are warped with (None: read as recorded)
        self.sensors = None
        if reads_nominal_time(self.doc):
            self.sensors = dict(sensors)
        self.estimator = self.doc["estimator"]
        self.fs = float(self.doc["features"]["fs"])
        self.samples = round(float(self.doc["features"]["duration"]) * self.fs)
        self.classes = [str(c) for c in self.estimator.classes_]
        self.channels = int(self.doc["features"].get("channels", 1))
        self.threshold = threshold
        self.method = f"learned:{self.doc['method']}"
        self.object_range = float(object_range)
        spread = self.doc.get("training", {}).get("object_temperature_spread")
        #: why the bound is needed, when the training data did not vary the range (or None)
        self.coverage_warning = uncovered(self.object_range, spread)

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

    def _times(self, taxel: int, nominal: np.ndarray) -> np.ndarray:
        """Return the times since onset ``taxel`` is read at for the model's ``nominal`` times."""
        if self.sensors is None:
            return nominal
        from skin.models.timescale import taxel_times

        return taxel_times(nominal, self.sensors.get(int(taxel)))

    def _covers(self, window, samples: int) -> bool:
        ok = np.isfinite(window.temperature)
        last = self._times(window.taxel, np.array([(samples - 1) / self.fs]))[0]
        return bool(ok.sum() >= 2 and window.time[ok][-1] >= last - 0.5 / self.fs)

    def _rows(self, contact: Contact, windows: list, samples: int) -> np.ndarray:
        grid = np.arange(samples) / self.fs
        blocks = []
        for w in windows:
            ok = np.isfinite(w.temperature)
            y = np.interp(self._times(w.taxel, grid), w.time[ok], w.temperature[ok])
            blocks.append(np.concatenate([[w.initial], y]))
        if self.channels == 1:  # one row per taxel
            return np.array([np.concatenate([[contact.ambient], b]) for b in blocks]).reshape(
                len(blocks), 2 + samples)
        order = np.argsort([-w.initial for w in windows])[: self.channels]
        row = np.full((self.channels, 1 + samples), np.nan)
        for k, i in enumerate(order):
            row[k] = blocks[i]
        return np.concatenate([[contact.ambient], row.ravel()])[None, :]

    def _predict(self, x: np.ndarray) -> np.ndarray:
        from skin.models.nuisance import bound
        from skin.threads import limited_threads

        with limited_threads():
            if hasattr(self.estimator, "predict_proba"):
                p = self.estimator.predict_proba(x)
            else:
                pred = self.estimator.predict(x)  # no probabilities: each taxel votes
                p = np.array([[0.999 if c == lab else 0.001 / max(len(self.classes) - 1, 1)
                               for c in self.classes] for lab in pred])
        return bound(p, x, self.classes, self.object_range, self.channels, self.fs,
                     voted=not hasattr(self.estimator, "predict_proba"))

    def classify(self, contact: Contact) -> MaterialEstimate:
        """Label a contact from all its taxels' evidence (the family when that is all)."""
        from skin.models.classifiers import fuse_probabilities
        from skin.models.contact_fit import fitted_effusivity
        from skin.models.materials import hierarchical_answer

        p = self.probabilities(contact)
        if p.shape[0] == 0:
            return MaterialEstimate(UNKNOWN, {}, 0.0, None, self.method, UNKNOWN, 0.0)
        fused = fuse_probabilities(p)
        probs = {c: float(v) for c, v in zip(self.classes, fused, strict=True)}
        label, confidence, family, family_confidence = hierarchical_answer(probs,
                                                                           self.threshold)
        measured = fitted_effusivity(contact, self.fs)
        return MaterialEstimate(label, probs, confidence,
                                None if measured is None else measured[0], self.method,
                                family, family_confidence)


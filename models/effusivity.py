"""The paper's model-based classifier: a histogram of pointwise effusivity estimates.

For every sample of a contact the inverse model (eqs. 10-11) gives an effusivity estimate; the
10-bin histogram of log10(e) over all samples (pooled over the contact's taxels, which fuses
their evidence) has a most populated bin, and the material whose log-effusivity range is most
similar to that bin's range is the label: the nearest range (zero distance when they overlap),
ties broken by the distance between centres.
"""

from __future__ import annotations

import numpy as np

from skin.contact import UNKNOWN, Contact, MaterialEstimate
from skin.formats.layout import Layout
from skin.models.materials import Material, load_materials
from skin.models.physics import SensorConstants, effusivity_estimates


class HistogramClassifier:
    """Classify contacts by the paper's effusivity histogram method.

    Parameters
    ----------
    layout : Layout
        Gives each taxel's sensor constants.
    materials : dict of Material, optional
        Candidates; the shipped table's ``classify = true`` materials by default.
    bins : int
        Histogram bins (the paper: 10).
    min_estimates : int
        Fewer valid estimates than this give ``"unknown"``.
    max_distance : float
        A mode bin farther than this from every candidate range (decades of e) is ``"unknown"``.
    """

    method = "model-histogram"

    def __init__(
        self,
        layout: Layout,
        materials: dict[str, Material] | None = None,
        bins: int = 10,
        min_estimates: int = 10,
        max_distance: float = 0.25,
    ) -> None:
        table = materials if materials is not None else load_materials()
        self.candidates = [m for m in table.values() if m.classify]
        self.bins = bins
        self.min_estimates = min_estimates
        self.max_distance = max_distance
        self._sensors = {
            int(t.id): SensorConstants.from_board(layout.boards[t.board]) for t in layout.taxels
        }

    def log_effusivity(self, contact: Contact) -> np.ndarray:
        """All valid pointwise log10 effusivity estimates of a contact, pooled over its taxels."""
        pooled = []
        for w in contact.windows:
            _, e = effusivity_estimates(w.time, w.temperature, w.initial, contact.ambient,
                                        self._sensors[w.taxel])
            pooled.append(np.log10(e))
        return np.concatenate(pooled) if pooled else np.array([])

    def classify(self, contact: Contact) -> MaterialEstimate:
        """Label a contact (``"unknown"`` when the estimates do not allow it)."""
        return self.classify_estimates(self.log_effusivity(contact))

    def classify_estimates(self, log_e: np.ndarray) -> MaterialEstimate:
        """Label a set of log10 effusivity estimates."""
        return classify_log_effusivity(log_e, self.candidates, self.bins, self.min_estimates,
                                       self.max_distance)


def classify_log_effusivity(log_e: np.ndarray, candidates: list[Material], bins: int = 10,
                            min_estimates: int = 10, max_distance: float = 0.25
                            ) -> MaterialEstimate:
    """Label log10 effusivity estimates by the paper's histogram method.

    Parameters
    ----------
    log_e : numpy.ndarray
        Valid pointwise log10 effusivity estimates (of one contact, pooled over taxels).
    candidates : list of Material
        The materials to choose among.
    bins : int
        Histogram bins.
    min_estimates : int
        Fewer estimates give ``"unknown"``.
    max_distance : float
        A mode bin farther than this (decades) from every candidate range is ``"unknown"``.

    Returns
    -------
    MaterialEstimate
        Label, per-material share of the estimates inside its range, confidence, and the
        effusivity of the mode bin.
    """
    method = HistogramClassifier.method
    if log_e.size < min_estimates:
        return MaterialEstimate(UNKNOWN, {}, 0.0, None, method)
    ranges = np.array([m.log_effusivity_range for m in candidates])
    hist, edges = np.histogram(log_e, bins=bins)
    mode = int(np.argmax(hist))
    lo, hi = edges[mode], edges[mode + 1]
    in_mode = log_e[(log_e >= lo) & (log_e <= hi)]
    estimate = float(10 ** np.median(in_mode))
    r_lo, r_hi = ranges[:, 0], ranges[:, 1]
    gap = np.maximum(0.0, np.maximum(r_lo - hi, lo - r_hi))
    centre = np.abs((r_lo + r_hi) / 2 - (lo + hi) / 2)
    best = int(np.lexsort((centre, gap))[0])
    inside = ((log_e[:, None] >= r_lo) & (log_e[:, None] <= r_hi)).sum(axis=0)
    total = inside.sum()
    probs = {m.name: float(c / total) for m, c in zip(candidates, inside, strict=True)
             } if total else {}
    if gap[best] > max_distance:
        return MaterialEstimate(UNKNOWN, probs, 0.0, estimate, method)
    confidence = float(inside[best] / log_e.size)
    return MaterialEstimate(candidates[best].name, probs, confidence, estimate, method)

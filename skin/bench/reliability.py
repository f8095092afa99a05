"""How far a classifier's probabilities can be trusted: log-loss, Brier, reliability table.

A probability is calibrated when, of the answers given at p, a share p is right. Over a set
of answers (each a dict of class probabilities) and their truths, `reliability` gives:

- ``log_loss``: mean of ``-ln p(truth)`` (p floored at `FLOOR`; the uniform answer over
  K classes scores ``ln K``);
- ``brier``: mean over answers of ``sum_k (p_k - [k == truth])^2`` (0 perfect, up to 2);
- ``ece``: expected calibration error, ``sum_b n_b / n |accuracy_b - confidence_b|`` over
  bins of the answer's largest probability (`BINS`), with the bins themselves
  (count, mean confidence, accuracy of the most probable class); `calibration_bins` computes
  it, for ``skin evaluate`` and its benches too (`expected_calibration_error`, 10 equal bins);
- ``sure``: the answers whose largest probability is at least `SURE`: their count and the
  share of them whose most probable class is the truth.

`family_probabilities` sums a material answer into families, so that the same figures hold
at family level.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

#: Edges of the bins of the largest probability (the last bin includes 1).
BINS = (0.0, 0.3, 0.5, 0.7, 0.9, 1.0)
#: ``skin evaluate``'s calibration error (and its benches': ceiling, object prior): equal bins.
EVALUATE_BINS = 10
#: Answers at or above this probability are confident ones.
SURE = 0.9
#: Smallest probability a log-loss counts (an answer that rules the truth out costs ln 1e6).
FLOOR = 1e-6


def family_probabilities(probabilities: Mapping[str, float],
                         family: Mapping[str, str]) -> dict[str, float]:
    """Sum material probabilities into families (a class ``family`` lacks is its own)."""
    out: dict[str, float] = {}
    for name, p in probabilities.items():
        f = family.get(name, name)
        out[f] = out.get(f, 0.0) + float(p)
    return out


def calibration_bins(confidence: np.ndarray, right: np.ndarray,
                     bins: int | Sequence[float] = BINS) -> tuple[float, list[dict[str, Any]]]:
    """Return the expected calibration error of answers and the bins it is summed over.

    Each answer falls in the bin of its ``confidence`` (its largest probability): bin b holds
    ``edges[b] <= confidence < edges[b + 1]``, the last one 1 too. The error is
    ``sum_b n_b / n |accuracy_b - confidence_b|`` over the bins with answers: 0 when, in every
    bin, the share right is the mean probability claimed.

    Parameters
    ----------
    confidence : numpy.ndarray
        Each answer's largest probability, 0-1.
    right : numpy.ndarray of bool
        Whether that answer's most probable class was the truth.
    bins : int or sequence of float
        Increasing bin edges from 0 to 1 (default `BINS`), or a number of equal bins
        (edges ``k / bins``).

    Returns
    -------
    ece : float
        The expected calibration error, 0-1 (NaN without answers).
    table : list of dict
        One per bin: ``lo``, ``hi``, ``count``, ``confidence`` (mean) and ``accuracy``
        (share right), unrounded; None where the bin is empty.
    """
    edges = (np.arange(int(bins) + 1) / int(bins) if isinstance(bins, (int, np.integer))
             else np.asarray(bins, dtype=float))
    if edges.ndim != 1 or edges.size < 2 or edges[0] != 0.0 or edges[-1] != 1.0 \
            or np.any(np.diff(edges) <= 0):
        raise ValueError(f"bins must increase from 0 to 1, got {bins!r}")
    conf = np.asarray(confidence, dtype=float)
    right = np.asarray(right, dtype=bool)
    if conf.shape != right.shape:
        raise ValueError(f"{conf.size} confidences for {right.size} answers")
    n = conf.size
    which = np.clip(np.searchsorted(edges, conf, side="right") - 1, 0, edges.size - 2)
    table, ece = [], 0.0
    for b in range(edges.size - 1):
        inside = which == b
        k = int(inside.sum())
        c = float(conf[inside].mean()) if k else None
        acc = float(right[inside].mean()) if k else None
        if k:
            ece += k / n * abs(acc - c)
        table.append({"lo": float(edges[b]), "hi": float(edges[b + 1]), "count": k,
                      "confidence": c, "accuracy": acc})
    return (float(ece) if n else float("nan")), table


def expected_calibration_error(confidence: np.ndarray, right: np.ndarray,
                               bins: int | Sequence[float] = BINS) -> float:
    """Return the expected calibration error alone (`calibration_bins`)."""
    return calibration_bins(confidence, right, bins)[0]


def reliability(answers: Sequence[Mapping[str, float]], truths: Sequence[str],
                classes: Sequence[str], bins: Sequence[float] = BINS) -> dict[str, Any]:
    """Log-loss, Brier score, ECE and reliability table of ``answers`` against ``truths``.

    Parameters
    ----------
    answers : sequence of dict
        Class -> probability, one per answer. An empty dict (no answer could be computed) is
        the uniform answer over ``classes``.
    truths : sequence of str
        The true class of each answer.
    classes : sequence of str
        Every class the answers may name (the Brier score sums over them).
    bins : sequence of float
        Increasing edges of the bins of the largest probability, from 0 to 1.

    Returns
    -------
    dict
        ``n``, ``log_loss``, ``brier``, ``ece`` and ``accuracy`` (most probable class right,
        share), ``bins`` (one dict per bin: ``lo``, ``hi``, ``count``, ``confidence``,
        ``accuracy``; None where empty) and ``sure`` (``count``, ``right``, ``share_right``).
    """
    if len(answers) != len(truths):
        raise ValueError(f"{len(answers)} answers for {len(truths)} truths")
    calibration_bins(np.zeros(0), np.zeros(0, dtype=bool), bins)  # the bins checked first
    names = list(dict.fromkeys([*classes, *(c for a in answers for c in a), *truths]))
    index = {c: i for i, c in enumerate(names)}
    uniform = np.zeros(len(names))
    uniform[[index[c] for c in classes]] = 1.0 / max(len(classes), 1)
    p = np.tile(uniform, (len(answers), 1))
    for i, a in enumerate(answers):
        if a:
            p[i] = 0.0
            for c, v in a.items():
                p[i, index[c]] = float(v)
    n = len(answers)
    if n == 0:
        return {"n": 0, "log_loss": None, "brier": None, "ece": None, "accuracy": None,
                "bins": [], "sure": {"count": 0, "right": 0, "share_right": None}}
    y = np.array([index[t] for t in truths])
    onehot = np.zeros_like(p)
    onehot[np.arange(n), y] = 1.0
    conf = p.max(axis=1)
    right = p.argmax(axis=1) == y
    # an answer tied at the top is right only if the truth is the first of the tie, as argmax
    ece, table = calibration_bins(conf, right, bins)
    for row in table:  # rounded for display only
        for key in ("confidence", "accuracy"):
            row[key] = None if row[key] is None else round(row[key], 4)
    sure = conf >= SURE
    return {"n": n,
            "log_loss": round(float(-np.mean(np.log(np.maximum(p[np.arange(n), y], FLOOR)))),
                              4),
            "brier": round(float(np.mean(np.sum((p - onehot) ** 2, axis=1))), 4),
            "ece": round(float(ece), 4), "accuracy": round(float(right.mean()), 4),
            "bins": table,
            "sure": {"count": int(sure.sum()), "right": int(right[sure].sum()),
                     "share_right": (round(float(right[sure].mean()), 4) if sure.any()
                                     else None)}}


def material_and_family(answers: Sequence[Mapping[str, float]], truths: Sequence[str],
                        classes: Sequence[str], family: Mapping[str, str]) -> dict[str, Any]:
    """`reliability` at material and at family level (``family``: material -> family)."""
    fams = list(dict.fromkeys(family.get(c, c) for c in classes))
    return {"material": reliability(answers, truths, classes),
            "family": reliability([family_probabilities(a, family) if a else {}
                                   for a in answers],
                                  [family.get(t, t) for t in truths], fams)}

"""`skin.bench.reliability`: log-loss, Brier and the reliability table on hand-made answers."""

import math

import numpy as np
import pytest

from skin.bench.reliability import (
    BINS,
    EVALUATE_BINS,
    calibration_bins,
    expected_calibration_error,
    family_probabilities,
    material_and_family,
    reliability,
)

CLASSES = ["a", "b", "c"]


def test_figures_of_a_hand_made_set():
    answers = [{"a": 0.95, "b": 0.05},           # sure and right
               {"a": 0.6, "b": 0.4},             # right, in the 0.5-0.7 bin
               {"b": 0.6, "a": 0.4},             # wrong (truth a), same bin
               {"c": 0.92, "a": 0.08},           # sure and wrong
               {}]                               # no answer: uniform over the classes
    truths = ["a", "a", "a", "a", "c"]
    r = reliability(answers, truths, CLASSES)
    assert r["n"] == 5
    p_true = [0.95, 0.6, 0.4, 0.08, 1 / 3]
    assert r["log_loss"] == pytest.approx(-sum(map(math.log, p_true)) / 5, abs=1e-4)
    brier = [0.05**2 + 0.05**2, 0.4**2 + 0.4**2, 0.6**2 + 0.6**2, 0.92**2 + 0.92**2,
             2 * (1 / 3) ** 2 + (2 / 3) ** 2]
    assert r["brier"] == pytest.approx(sum(brier) / 5, abs=1e-4)
    # the uniform answer's top is the first class listed (a), so it is wrong against c
    assert r["accuracy"] == pytest.approx(2 / 5)
    bins = {(b["lo"], b["hi"]): b for b in r["bins"]}
    assert bins[(0.3, 0.5)] == {"lo": 0.3, "hi": 0.5, "count": 1,
                                "confidence": pytest.approx(1 / 3, abs=1e-4), "accuracy": 0.0}
    assert bins[(0.5, 0.7)]["count"] == 2 and bins[(0.5, 0.7)]["accuracy"] == 0.5
    assert bins[(0.5, 0.7)]["confidence"] == pytest.approx(0.6)
    assert bins[(0.9, 1.0)]["count"] == 2 and bins[(0.9, 1.0)]["accuracy"] == 0.5
    assert bins[(0.0, 0.3)]["count"] == 0 and bins[(0.0, 0.3)]["accuracy"] is None
    ece = (1 * abs(0 - 1 / 3) + 2 * abs(0.5 - 0.6) + 2 * abs(0.5 - 0.935)) / 5
    assert r["ece"] == pytest.approx(ece, abs=1e-4)
    assert r["sure"] == {"count": 2, "right": 1, "share_right": 0.5}


def test_a_perfect_answer_and_a_truth_ruled_out():
    r = reliability([{"a": 1.0}, {"b": 1.0}], ["a", "a"], CLASSES)
    assert r["bins"][-1]["count"] == 2  # p = 1 falls in the last bin
    assert r["log_loss"] == pytest.approx((0.0 + -math.log(1e-6)) / 2, abs=1e-4)
    assert r["ece"] == pytest.approx(0.5)


def test_family_level_sums_the_materials():
    family = {"a": "metal", "b": "metal", "c": "wood"}
    assert family_probabilities({"a": 0.3, "b": 0.3, "c": 0.4}, family) == \
        pytest.approx({"metal": 0.6, "wood": 0.4})
    both = material_and_family([{"a": 0.3, "b": 0.3, "c": 0.4}], ["b"], CLASSES, family)
    assert both["material"]["accuracy"] == 0.0
    assert both["family"]["accuracy"] == 1.0
    assert both["family"]["log_loss"] == pytest.approx(-math.log(0.6), abs=1e-4)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="2 answers for 1 truths"):
        reliability([{}, {}], ["a"], CLASSES)
    with pytest.raises(ValueError, match="bins"):
        reliability([{}], ["a"], CLASSES, bins=(0.0, 0.5))
    assert reliability([], [], CLASSES)["log_loss"] is None


def test_one_calibration_error_for_the_scene_bench_and_skin_evaluate():
    """`reliability`'s ECE and ``skin evaluate``'s (10 equal bins) are `calibration_bins`."""
    rng = np.random.default_rng(4)
    top = np.concatenate([rng.integers(2, 6, 300) / 5, rng.uniform(0.35, 1.0, 300)])
    right = rng.uniform(size=top.size) < top ** 2  # overconfident
    probs = [{"a": p, "b": 1.0 - p} if p >= 0.5 else {"c": p, "a": 0.5 * (1 - p),
                                                       "b": 0.5 * (1 - p)} for p in top]
    best = [max(a, key=a.get) for a in probs]
    truths = [b if r else next(c for c in CLASSES if c != b)
              for b, r in zip(best, right, strict=True)]
    r = reliability(probs, truths, CLASSES)
    ece, table = calibration_bins(top, right, BINS)
    assert r["ece"] == round(ece, 4) and r["ece"] > 0.05
    assert [b["count"] for b in r["bins"]] == [b["count"] for b in table]
    # equal bins: each answer in the bin it begins, a kNN's 3/5 in [0.6, 0.7), 1 in the last
    ten = calibration_bins(np.array([0.6, 0.6, 1.0, 0.05]), np.array([1, 0, 1, 0], bool),
                           EVALUATE_BINS)[1]
    assert [b["count"] for b in ten] == [1, 0, 0, 0, 0, 0, 2, 0, 0, 1]
    manual = sum(np.count_nonzero(w) / top.size * abs(right[w].mean() - top[w].mean())
                 for b in range(10)
                 if (w := (np.minimum(np.floor(top * 10), 9) == b)).any())
    assert expected_calibration_error(top, right, EVALUATE_BINS) == pytest.approx(manual,
                                                                                   abs=1e-12)
    assert expected_calibration_error(np.full(1000, 0.95), np.arange(1000) < 600,
                                      EVALUATE_BINS) == pytest.approx(0.35)
    with pytest.raises(ValueError, match="confidences"):
        expected_calibration_error(top, right[:-1])
    assert math.isnan(expected_calibration_error(np.zeros(0), np.zeros(0, bool)))

"""``skin bench gap`` and the ceiling told less (issue 17's first target)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from skin.bench.ceiling import (
    _log_density,
    _taxel_grid,
    _taxel_weights,
    known_nuisance_ceiling,
    told_less_ceiling,
)
from skin.bench.gap import binomial_se, clustered_se, paired_se, pooled_margins
from skin.models.materials import load_materials
from skin.models.physics import SensorConstants, contact_trace
from skin.models.timescale import warp_to_nominal
from skin.models.trials import PAPER_MATERIALS, Protocol, simulate_trials, spread_sensors

MATS = load_materials()
FOUR = [MATS[m] for m in ("aluminium", "glass", "pine", "cardboard")]


def _data(seed: int = 3):
    return simulate_trials(FOUR, Protocol(trials=16), seed=seed)


def test_told_everything_it_is_the_known_nuisance_ceiling_and_commissioning_is_the_truth():
    ds = _data()
    told = told_less_ceiling(ds, 1.0)
    assert told["accuracy"] >= known_nuisance_ceiling(ds, 1.0)["accuracy"] - 0.02
    assert told["accuracy"] > 0.9
    assert 0 < told["noise"] < 0.5
    # a calibration holding each taxel's true constants is the told-everything ceiling
    x = ds.extra
    truth = {int(ds.taxel[i, 0]): SensorConstants(
        depth=float(x["true_sensor_depth"][i]), diffusivity=float(x["true_sensor_diffusivity"][i]),
        conductivity=float(x["true_sensor_conductivity"][i])) for i in range(len(ds))}
    assert told_less_ceiling(ds, 1.0, sensors=truth)["accuracy"] == told["accuracy"]
    # on the paper's 11 materials, knowing only the ranges of what a classifier cannot see
    # costs accuracy, and far more than the onset alone
    eleven = simulate_trials([MATS[m] for m in PAPER_MATERIALS], Protocol(trials=8), seed=3)
    all_told = told_less_ceiling(eleven, 0.5)["accuracy"]
    onset = told_less_ceiling(eleven, 0.5, ("onset",))["accuracy"]
    blind = told_less_ceiling(eleven, 0.5, ("taxel_constants", "object_temperature",
                                            "conductance", "onset"))["accuracy"]
    assert 1 / 11 < blind < onset - 0.1 and onset <= all_told + 0.05
    with pytest.raises(ValueError, match="room"):
        told_less_ceiling(ds, 1.0, ("room",))


def test_warp_to_nominal_makes_a_slow_taxel_read_like_the_design():
    ds = simulate_trials(FOUR[:2], Protocol(trials=8), seed=1)
    nominal = SensorConstants()
    # a longer response time, the effusivity the design's (what --reference label fits)
    slow = SensorConstants(depth=nominal.depth * 1.1, diffusivity=nominal.diffusivity * 0.9,
                           conductivity=nominal.conductivity * np.sqrt(0.9))
    on, fs = int(ds.onset[0]), ds.fs
    m = ds.temperature.shape[-1]
    t = (np.arange(m) - on) / fs
    temperature = ds.temperature.copy()
    temperature[0, 0] = contact_trace(t, 35.0, 25.0, 400.0, slow)
    ds = type(ds)(**{**ds.__dict__, "temperature": temperature})
    warped = warp_to_nominal(ds, {int(ds.taxel[0, 0]): slow})
    want = contact_trace(t, 35.0, 25.0, 400.0, nominal)
    ratio = (slow.depth ** 2 / slow.diffusivity) / (nominal.depth ** 2 / nominal.diffusivity)
    inside = on + (np.arange(m) - on) * ratio < m - 1
    assert ratio > 1.3
    assert np.max(np.abs(warped.temperature[0, 0, inside] - want[inside])) < 0.01
    other = ds.taxel[:, 0] != ds.taxel[0, 0]  # taxels without constants: left as they are
    assert other.any() and np.array_equal(warped.temperature[other], ds.temperature[other])


def test_bench_gap_prints_the_target_line_and_the_decomposition():
    out = subprocess.run([sys.executable, "-m", "skin", "bench", "gap", "--trials", "8",
                          "--seeds", "7", "--durations", "0.5", "--reference-trials", "4",
                          "--points", "3", "--json"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    (row,) = doc["rows"]
    assert row["seed"] == 7 and row["duration"] == 0.5 and row["commissioned_taxels"] == 8
    assert row["target"] == pytest.approx(row["svm"] + 2 / 3 * (row["ceiling"] - row["svm"]),
                                          abs=1e-4)
    assert row["met"] == (row["default"] >= row["target"])
    assert row["margin"] == pytest.approx(row["reachable"] - row["target"], abs=2e-4)
    assert row["margin_t"] == pytest.approx(2.365, abs=1e-3)  # t, 7 degrees of freedom
    assert row["ruled_out"] == (row["margin"] < -row["margin_t"] * row["margin_se"])
    assert row["margin_se_kind"].startswith("clustered by the folds' groups")
    assert "taxel: 8 clusters" in row["margin_se_kind"]
    assert 0 < row["margin_se"] < 0.5 and 0 < row["se"]["svm"] < 0.2
    assert row["reachable"] == row["told_less"][
        "taxel_constants+object_temperature+conductance+onset"]
    for key in ("svm", "default", "svm_commissioned", "default_commissioned", "ceiling",
                "reachable", "reachable_commissioned"):
        assert 0 <= row[key] <= 1
    bad = subprocess.run([sys.executable, "-m", "skin", "bench", "gap", "--durations", "x"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode != 0 and "--durations" in bad.stderr
    for few in (["--trials", "4"], ["--cv", "2", "--trials", "5"]):
        out = subprocess.run([sys.executable, "-m", "skin", "bench", "gap", *few],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 2 and "each training fold" in out.stderr, out.stderr


def test_the_design_taxel_is_left_as_it_is_and_evaluate_reads_commissioned_traces(tmp_path):
    ds = simulate_trials(FOUR, Protocol(trials=12), seed=2, skin_seed=4)
    same = warp_to_nominal(ds, {int(t): SensorConstants() for t in np.unique(ds.taxel)})
    assert np.allclose(same.temperature, ds.temperature, atol=1e-12, equal_nan=True)
    ds.save(tmp_path / "data.npz")
    simulate_trials(FOUR, Protocol(trials=8), seed=3, skin_seed=4).save(tmp_path / "ref.npz")

    def skin(*args):
        return subprocess.run([sys.executable, "-m", "skin", *map(str, args)],
                              capture_output=True, text=True, timeout=300)

    out = skin("calibrate", "thermal", "--data", tmp_path / "ref.npz", "--reference", "label",
               "-o", tmp_path / "cal.json")
    assert out.returncode == 0, out.stderr
    out = skin("evaluate", "--data", tmp_path / "data.npz", "--methods", "svm-pca",
               "--durations", "1", "--calibration", tmp_path / "cal.json", "--json")
    assert out.returncode == 0, out.stderr
    rows = {r["method"]: r for r in json.loads(out.stdout)["results"]}
    assert {"svm-pca", "svm-pca+commissioned"} <= set(rows)
    assert 0.25 <= rows["svm-pca+commissioned"]["accuracy"] <= 1


def test_the_taxel_prior_is_the_mass_the_simulated_box_gives_each_grid_point():
    points = 7
    w = _taxel_weights(0.10, points).reshape(points, points)
    assert w.sum() == pytest.approx(1.0) and np.all(w >= 0)
    # taxels drawn as the simulation draws them fall on the grid points with that mass
    grid = _taxel_grid(0.10, points)
    roots = np.log([s.depth / np.sqrt(s.diffusivity) for s in grid[::points]])
    effs = np.log([s.effusivity for s in grid[:points]])
    drawn = spread_sensors(20000, 0.10, np.random.default_rng(0))
    i = np.argmin(np.abs(np.log([s.depth / np.sqrt(s.diffusivity) for s in drawn])[:, None]
                         - roots[None]), axis=1)
    j = np.argmin(np.abs(np.log([s.effusivity for s in drawn])[:, None] - effs[None]), axis=1)
    seen = np.bincount(i * points + j, minlength=points * points).reshape(points, points)
    assert np.max(np.abs(seen / seen.sum() - w)) < 0.01
    # the middle is far more likely than a corner, which the uniform weights ignored
    assert w[points // 2, points // 2] > 10 * w[0, 0]


def test_the_start_prior_leaves_each_trial_out_of_its_own_estimate():
    sample = np.array([0.0, 0.0, 1.0, 5.0])
    log_p = _log_density(sample)
    width = 1.06 * np.std(sample) * sample.size ** -0.2

    def kde(v, over):  # the same kernels, over some of the sample
        return np.log(np.mean(np.exp(-((v - over) / width) ** 2 / 2))
                      / (width * np.sqrt(2 * np.pi)))

    got = log_p(sample, np.array([True, True, False, True]))
    assert got[3] == pytest.approx(kde(5.0, sample[:3]))
    assert got[0] == pytest.approx(kde(0.0, sample[1:]))  # its twin stays
    assert got[2] == pytest.approx(kde(1.0, sample))  # not marked: all of them
    with pytest.raises(ValueError, match="not in the sample"):
        log_p(np.array([0.5]), np.array([True]))


def test_errors_are_binomial_and_paired_ones_cancel_what_the_methods_share():
    assert binomial_se(0.3, 1100) == pytest.approx(np.sqrt(0.3 * 0.7 / 1100))
    a = np.random.default_rng(1).random(500) < 0.4
    assert paired_se((1.0, a), (-1.0, a)) == 0.0
    assert paired_se((1.0, a), (-1.0, ~a)) == pytest.approx(2 * np.std(a, ddof=1) / np.sqrt(500))
    ds = _data()
    told = told_less_ceiling(ds, 0.5, ("onset",), per_trial=True)
    assert np.mean(told["correct"]) == pytest.approx(told["accuracy"], abs=1e-4)
    known = known_nuisance_ceiling(ds, 0.5, per_trial=True)
    assert np.mean(known["correct"]) == pytest.approx(known["accuracy"], abs=1e-4)


def test_the_margin_error_is_clustered_by_taxel_with_a_t_threshold():
    rng = np.random.default_rng(2)
    a, b = rng.random(400) < 0.4, rng.random(400) < 0.6
    one_each = np.arange(400)  # every contact its own cluster: the independent error
    se, t = clustered_se(one_each, (1.0, a), (-1.0, b))
    assert se == pytest.approx(paired_se((1.0, a), (-1.0, b)))
    assert t == pytest.approx(1.966, abs=1e-3)
    # answers that agree within a cluster: the clustered error is far above the independent
    taxel = np.repeat(np.arange(8), 50)
    agree = np.repeat(rng.random(8) < 0.5, 50)
    se, t = clustered_se(taxel, (1.0, agree))
    r = agree - agree.mean()
    want = np.sqrt(8 / 7 * np.sum(np.bincount(taxel, weights=r) ** 2)) / 400
    assert se == pytest.approx(want) and se > 5 * paired_se((1.0, agree))
    assert t == pytest.approx(2.365, abs=1e-3)
    with pytest.raises(ValueError, match="at least 2 clusters"):
        clustered_se(np.zeros(400), (1.0, a))
    with pytest.raises(ValueError, match="cluster labels"):
        clustered_se(np.arange(3), (1.0, a))


def test_a_material_with_one_trial_is_refused_by_name():
    ds = _data()
    glass = np.flatnonzero(ds.label == "glass")
    keep = np.ones(len(ds), dtype=bool)
    keep[glass[1:]] = False
    with pytest.raises(ValueError, match=r"at least 2 trials per material, got glass \(1\)"):
        told_less_ceiling(ds.subset(keep), 0.5, ("onset",))
    with pytest.raises(ValueError, match="sample of one"):
        _log_density(np.array([0.3]))(np.array([0.3]), np.array([True]))


def test_the_taxel_grid_is_weighted_by_the_box_and_the_answers_do_not_depend_on_parts():
    ds = _data()
    untold = ("taxel_constants",)
    box, rng_, even, given, parts = (
        told_less_ceiling(ds, 0.5, untold, points=5, per_trial=True, **kw) for kw in (
            {"taxel_prior": "box"}, {"taxel_prior": "range"},
            {"taxel_prior": np.ones(25)},  # equal weights: the range prior
            {"taxel_prior": _taxel_weights(0.10, 5)},  # the box's weights, given
            {"part_cells": 1}))  # one trial per part
    assert np.sum(box["correct"] != rng_["correct"]) >= 3  # the weights change answers
    assert np.array_equal(even["correct"], rng_["correct"])
    assert np.array_equal(given["correct"], box["correct"])
    assert np.array_equal(parts["correct"], box["correct"])
    with pytest.raises(ValueError, match="25 non-negative"):
        told_less_ceiling(ds, 0.5, untold, points=5, taxel_prior=np.ones(9))


def test_bench_gap_reach_only_with_the_range_prior_prints_reach_minus_target():
    # 6 trials: the default's calibration needs 3 per class in each training fold
    cmd = [sys.executable, "-m", "skin", "bench", "gap", "--trials", "6", "--seeds", "7",
           "--durations", "0.5", "--reference-trials", "2", "--points", "3", "--reach-only",
           "--taxel-prior", "range"]
    out = subprocess.run([*cmd, "--json"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    (row,) = doc["rows"]
    assert doc["taxel_prior"] == row["taxel_prior"] == "range" and row["points"] == 3
    assert row["told_less"] == {} and row["svm_commissioned"] is None
    assert row["default_commissioned"] is None and row["met_commissioned"] is None
    assert 0 <= row["reachable"] <= 1 and 0 <= row["reachable_commissioned"] <= 1
    text = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert text.returncode == 0, text.stderr
    lines = text.stdout.splitlines()
    head = next(ln.split() for ln in lines if ln.split()[:2] == ["seed", "dur"])
    assert head[-5:] == ["reach-target", "+-", "reach-c", "out", "out-c"]
    cells = next(ln.split() for ln in lines if ln.split()[:1] == ["7"])
    assert len(cells) == len(head) - 1  # "dur s" is one column
    assert float(cells[head.index("reach-target") - 1]) == pytest.approx(row["margin"], abs=6e-4)
    assert cells[-1] == ("yes" if row["ruled_out_commissioned"] else "no")


def _row(seed: int, duration: float, margin: float, se: float, default: float = 0.3,
         target: float = 0.32) -> dict:
    return {"seed": seed, "duration": duration, "margin": margin, "margin_se": se,
            "margin_commissioned": margin + 0.1, "margin_commissioned_se": se,
            "default": default, "target": target, "met": default >= target}


def test_pooled_margins_are_the_seeds_mean_with_the_larger_of_two_errors():
    from scipy.stats import t

    margins = [-0.03, -0.01, -0.02, -0.04]
    rows = [_row(s, 0.25, m, 0.01) for s, m in enumerate(margins)]
    rows += [_row(9, 0.5, -0.2, 0.01)]  # one seed only: not pooled
    (p,) = pooled_margins(rows)
    assert p["duration"] == 0.25 and p["seeds"] == 4
    assert p["margin"] == pytest.approx(np.mean(margins), abs=1e-4)
    assert p["se_within"] == pytest.approx(np.sqrt(4 * 0.01 ** 2) / 4, abs=1e-4)
    between = np.std(margins, ddof=1) / 2
    assert p["se_between"] == pytest.approx(between, abs=1e-4)
    assert p["t"] == pytest.approx(t.ppf(0.975, 3), abs=1e-3)
    # -0.025 against t(3) = 3.18 x max(0.005, 0.0065): -0.0205 -> ruled out
    assert p["ruled_out"] is True
    assert p["margin_commissioned"] == pytest.approx(0.075, abs=1e-4)
    assert p["ruled_out_commissioned"] is False
    assert p["default_minus_target"] == pytest.approx(-0.02, abs=1e-4) and p["met_seeds"] == 0
    # the same mean with a spread between seeds twice as large is no longer ruled out
    wide = [_row(s, 0.25, -0.025 + 2 * (m + 0.025), 0.01) for s, m in enumerate(margins)]
    (q,) = pooled_margins(wide)
    assert q["margin"] == pytest.approx(-0.025, abs=1e-4)
    assert q["se_between"] == pytest.approx(2 * between, abs=1e-4) and q["ruled_out"] is False

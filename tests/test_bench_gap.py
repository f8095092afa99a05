"""``skin bench gap`` and the ceiling told less (issue 17's first target)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from skin.bench.ceiling import known_nuisance_ceiling, told_less_ceiling
from skin.models.materials import load_materials
from skin.models.physics import SensorConstants, contact_trace
from skin.models.timescale import warp_to_nominal
from skin.models.trials import PAPER_MATERIALS, Protocol, simulate_trials

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
    assert row["ruled_out"] == (row["reachable"] < row["target"])
    assert row["reachable"] == row["told_less"][
        "taxel_constants+object_temperature+conductance+onset"]
    for key in ("svm", "default", "svm_commissioned", "default_commissioned", "ceiling",
                "reachable", "reachable_commissioned"):
        assert 0 <= row[key] <= 1
    bad = subprocess.run([sys.executable, "-m", "skin", "bench", "gap", "--durations", "x"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode != 0 and "--durations" in bad.stderr


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

"""Ceilings of contacts seen by several channels (issue 17: cold and warm objects)."""

import numpy as np
import pytest

from skin.bench.ceiling import ceilings, channel_truth, joint_fit_accuracy, known_nuisance_ceiling
from skin.errors import SkinError
from skin.formats.dataset import TrialSet
from skin.models.materials import load_materials
from skin.models.trials import Protocol, simulate_trials

MATS = load_materials()
FOUR = [MATS[m] for m in ("aluminium", "glass", "pine", "cardboard")]


def _two_channels(spread: float = 0.1, seed: int = 5) -> TrialSet:
    return simulate_trials(FOUR, Protocol(trials=12, run_length=6, taxel_spread=spread,
                                          channels=("heated", "passive"),
                                          object_offset=(8.0, 8.0)), seed=seed)


def test_each_channel_truth_is_stored_and_the_primary_agrees():
    ds = _two_channels()
    truth = channel_truth(ds)
    for key in ("sensor_temperature", "depth", "diffusivity", "conductivity", "conductance"):
        assert truth[key].shape == (len(ds), 2)
    assert np.array_equal(truth["depth"][:, 0], ds.extra["true_sensor_depth"])
    assert np.array_equal(truth["conductance"][:, 0], ds.extra["true_conductance"])
    # another taxel of the pool: its own constants, and a conductance near the primary's
    assert np.any(truth["depth"][:, 1] != truth["depth"][:, 0])
    ratio = np.log10(truth["conductance"][:, 1] / truth["conductance"][:, 0])
    assert 0 < np.std(ratio) < 0.3
    # the passive channel's reading is the closed form of its own constants: a least-squares
    # choice told every nuisance is (nearly) always right on four distinct effusivities
    assert known_nuisance_ceiling(ds, 1.0)["accuracy"] > 0.95
    one = simulate_trials(FOUR, Protocol(trials=12, run_length=6), seed=5)
    assert channel_truth(one)["depth"].shape == (len(one), 1)


def test_a_second_channel_pins_the_object_where_one_cannot():
    ds = _two_channels()
    primary = TrialSet(temperature=ds.temperature[:, :1], fs=ds.fs, label=ds.label,
                       onset=ds.onset, ambient=ds.ambient, extra={
                           k: v for k, v in ds.extra.items() if not k.startswith("true_ch")})
    both = known_nuisance_ceiling(ds, 1.0, ("object_temperature",))["accuracy"]
    alone = known_nuisance_ceiling(primary, 1.0, ("object_temperature",))["accuracy"]
    assert both > alone + 0.2  # objects 8 K warm: one channel takes them for another material


def test_joint_fit_told_the_constants_equals_nominal_without_spread():
    ds = _two_channels(spread=0.0)
    true = joint_fit_accuracy(ds, 1.0, "true")
    nominal = joint_fit_accuracy(ds, 1.0, "nominal")
    assert true["accuracy"] == nominal["accuracy"] > 0.7
    assert true["method"] == "joint fit (true taxel constants)"
    assert 0.0 <= true["confident"] <= 1.0 and true["predict_ms_per_trial"] > 0
    assert [r["method"] for r in ceilings(ds, 0.5)] == [
        "ceiling", "ceiling (object_temperature unknown)", "joint fit (true taxel constants)",
        "joint fit (nominal taxel constants)"]
    with pytest.raises(ValueError, match="constants"):
        joint_fit_accuracy(ds, 1.0, "guessed")


def test_old_multi_channel_datasets_are_refused_before_the_work():
    ds = _two_channels()
    old = TrialSet(temperature=ds.temperature, fs=ds.fs, label=ds.label, onset=ds.onset,
                   ambient=ds.ambient, extra={k: v for k, v in ds.extra.items()
                                              if not k.startswith("true_channel_sensor_d")})
    with pytest.raises(SkinError, match="simulate it again"):
        ceilings(old, 1.0)


def test_skin_seed_keeps_the_taxels_and_changes_nothing_else():
    p = Protocol(trials=6, run_length=3, channels=("heated", "passive"))
    a = simulate_trials(FOUR, p, seed=5)
    same = simulate_trials(FOUR, p, seed=5, skin_seed=5)
    assert np.array_equal(a.temperature, same.temperature)  # the seed's own taxels
    other = simulate_trials(FOUR, p, seed=6, skin_seed=5)
    # another recording by the same skin: each taxel id has the same constants
    for key in ("depth", "diffusivity", "conductivity"):
        ta, to = channel_truth(a)[key], channel_truth(other)[key]
        for k in set(a.taxel.ravel()) & set(other.taxel.ravel()):
            assert np.unique(ta[a.taxel == k]).size == 1
            assert ta[a.taxel == k][0] == to[other.taxel == k][0]
    # only the taxels differ from seed 6's own skin: the schedule and noise stream are kept
    own = simulate_trials(FOUR, p, seed=6)
    assert np.array_equal(own.extra["true_onset_time"], other.extra["true_onset_time"])
    assert not np.array_equal(own.extra["true_sensor_depth"], other.extra["true_sensor_depth"])


def _skin(*args):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "skin", *args], capture_output=True,
                          text=True, timeout=600)


def test_self_calibration_from_labelled_contacts_then_the_calibrated_joint_fit(tmp_path):
    from skin.formats.calibration_file import load_calibration

    # a training set of known materials at ambient, and cold/warm objects met later by the
    # same skin (the same taxels)
    p = Protocol(trials=24, run_length=6, n_taxels=4, channels=("heated", "passive"))
    train = simulate_trials(FOUR, p, seed=5, skin_seed=1)
    test = simulate_trials(FOUR, Protocol(trials=12, run_length=6, n_taxels=4,
                                          channels=("heated", "passive"),
                                          object_offset=8.0), seed=6, skin_seed=1)
    train.save(tmp_path / "train.npz")
    test.save(tmp_path / "test.npz")
    out = _skin("calibrate", "thermal", "--data", str(tmp_path / "train.npz"), "--reference",
                "label", "-o", str(tmp_path / "cal.json"))
    assert out.returncode == 0, out.stderr
    cal = load_calibration(tmp_path / "cal.json").taxels
    truth = channel_truth(train)
    for tid in np.unique(train.taxel[:, 0]):
        i = np.flatnonzero(train.taxel[:, 0] == tid)[0]
        want = truth["depth"][i, 0] ** 2 / truth["diffusivity"][i, 0]
        got = cal[int(tid)]["depth"] ** 2 / cal[int(tid)]["diffusivity"]
        assert got == pytest.approx(want, rel=0.1)  # the time scale, from the shapes
        # the effusivity stays nominal (the amplitude is the warmed objects')
        e = cal[int(tid)]["conductivity"] / np.sqrt(cal[int(tid)]["diffusivity"])
        assert e == pytest.approx(0.0349 / np.sqrt(2.796e-9), rel=1e-6)
    out = _skin("evaluate", "--train", str(tmp_path / "train.npz"), "--test",
                str(tmp_path / "test.npz"), "--methods", "svm-pca", "--durations", "1.0",
                "--calibration", str(tmp_path / "cal.json"), "--json")
    assert out.returncode == 0, out.stderr
    assert "NaN" not in out.stdout  # strict JSON
    rows = {r["method"]: r for r in __import__("json").loads(out.stdout)["results"]}
    joint = rows["joint fit (calibrated taxel constants, confidence scaled on the training set)"]
    assert joint["accuracy"] > rows["svm-pca"]["accuracy"] + 0.2  # svm-pca: near chance
    assert joint["temperature"] > 0 and 0 <= joint["calibration_error"] <= 1
    # a labelled set with a class that is not a material at rest is refused before the work
    import dataclasses

    bad = dataclasses.replace(train, label=np.where(train.label == "pine", "human_skin",
                                                    train.label))
    bad.save(tmp_path / "bad.npz")
    out = _skin("calibrate", "thermal", "--data", str(tmp_path / "bad.npz"), "--reference",
                "label", "-o", str(tmp_path / "bad.json"))
    assert out.returncode != 0 and "human_skin" in out.stderr
    out = _skin("evaluate", "--data", str(tmp_path / "test.npz"), "--methods", "svm-pca",
                "--split", "stratified", "--calibration", str(tmp_path / "missing.json"))
    assert out.returncode != 0 and "missing.json" in out.stderr

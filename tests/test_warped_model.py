"""A model trained on commissioned traces (skin train --calibration) in the pipeline."""

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("sklearn")
pytest.importorskip("skops")

from skin.contact import Contact, TaxelWindow
from skin.formats.calibration_file import CalibrationFile, load_calibration
from skin.models import load_materials
from skin.models.classifiers import make_method, method_matrix
from skin.models.features import PRE, trial_matrix
from skin.models.learned import LearnedClassifier
from skin.models.modelfile import (
    ModelFileError,
    load_model,
    reads_nominal_time,
    save_model,
    training_summary,
)
from skin.models.physics import SensorConstants
from skin.models.timescale import taxel_constants, time_ratio, warp_to_nominal
from skin.models.trials import Protocol, simulate_trials

MATS = load_materials()
CLASSES = ("aluminium", "pine", "glass", "neoprene")


def skin(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "skin", *args], capture_output=True, text=True,
                          timeout=600, cwd=cwd)


@pytest.fixture(scope="module")
def trials():
    """Training and test trials of one skin whose 8 taxels differ by +-10 %."""
    protocol = Protocol(trials=16, run_length=8)
    train = simulate_trials([MATS[m] for m in CLASSES], protocol, seed=31, skin_seed=31)
    test = simulate_trials([MATS[m] for m in CLASSES], Protocol(trials=6, run_length=6),
                           seed=32, skin_seed=31)
    return train, test


def _calibration(path, taxels):
    """A calibration file whose taxels are up to 12 % slower or faster than the design."""
    nominal = SensorConstants()
    rng = np.random.default_rng(3)
    entries = {int(t): {"depth": nominal.depth * float(rng.uniform(0.94, 1.06)),
                        "diffusivity": nominal.diffusivity * float(rng.uniform(0.94, 1.06)),
                        "conductivity": nominal.conductivity} for t in taxels}
    entries[int(taxels[0])]["depth"] = nominal.depth * 1.06  # one clearly slow taxel
    entries[int(taxels[0])]["diffusivity"] = nominal.diffusivity / 1.06
    CalibrationFile(taxels=entries, references={"thermal": "test"}).save(path)
    return path


def _contact(ds, i, duration):
    """Trial ``i`` as a one-taxel contact, as recorded (not warped), longer than needed."""
    on = int(ds.onset[i])
    y = ds.primary[i, on:on + round(1.5 * duration * ds.fs)]
    window = TaxelWindow(int(ds.taxel[i, 0]), 0.0, float(ds.primary[i, on - PRE:on].mean()),
                         np.arange(y.size) / ds.fs, y, True)
    return Contact(i, [window.taxel], 0.0, duration, float(ds.ambient[i]), [window])


def test_the_pipeline_names_each_contact_as_evaluate_commissioned_does(tmp_path, trials):
    train, test = trials
    train.save(tmp_path / "train.npz")
    cal = _calibration(tmp_path / "cal.json", np.unique(train.taxel))
    for method in ("svm-pca", "knn-pca"):
        model = tmp_path / f"{method}.skops"
        out = skin("train", "--data", str(tmp_path / "train.npz"), "--method", method,
                   "--duration", "1", "--calibration", str(cal), "-o", str(model), "--json")
        assert out.returncode == 0, out.stderr
        assert json.loads(out.stdout)["time_scale"] == "nominal"
        sensors = taxel_constants(load_calibration(cal), str(cal))
        clf = LearnedClassifier(model, sensors=sensors)
        # skin evaluate's commissioned path: the same method fitted on the warped training
        # trials (train_test), tested on the warped test trials
        est = make_method(method, fs=train.fs)
        est.fit(method_matrix(warp_to_nominal(train, sensors), method, 1.0), train.label)
        x = method_matrix(warp_to_nominal(test, sensors), method, 1.0)
        contacts = [_contact(test, i, 1.0) for i in range(len(test))]
        got = [clf.classify(c).label for c in contacts]
        assert got == est.predict(x).astype(str).tolist()
        if hasattr(est, "predict_proba"):  # and the same probabilities, row by row
            p = np.vstack([clf.probabilities(c) for c in contacts])
            assert np.allclose(p, est.predict_proba(x), atol=1e-9)
        rows = np.vstack([clf.rows(c) for c in contacts])
        assert np.allclose(rows, x, atol=1e-9)  # the very rows evaluate reads
    slow = int(np.unique(train.taxel)[0])
    assert time_ratio(sensors[slow]) == pytest.approx(1.06 ** 3)
    unwarped = trial_matrix(test, 1.0)[test.taxel[:, 0] == slow]
    assert not np.allclose(unwarped, x[test.taxel[:, 0] == slow], atol=1e-3)


def test_a_slow_taxel_needs_a_longer_window(tmp_path, trials):
    train, test = trials
    est = make_method("knn-pca", fs=train.fs).fit(trial_matrix(train, 1.0), train.label)
    path = save_model(tmp_path / "m.skops", est, "knn-pca", 1.0, train.fs,
                      training_summary(train, 1.0), time_scale="nominal")
    i = 0
    taxel = int(test.taxel[i, 0])
    slow = dataclasses.replace(SensorConstants(), depth=SensorConstants().depth * 1.1)
    contact = _contact(test, i, 1.0)
    w = contact.windows[0]
    cut = dataclasses.replace(w, time=w.time[:round(1.1 * test.fs)],
                              temperature=w.temperature[:round(1.1 * test.fs)])
    short = dataclasses.replace(contact, windows=[cut])  # 1.1 s: covers 1 s, not 1.21 s
    assert LearnedClassifier(path, sensors={}).classify(short).label != "unknown"
    assert LearnedClassifier(path, sensors={taxel: slow}).classify(short).label == "unknown"


def test_model_file_round_trip_keeps_the_time_scale(tmp_path, trials):
    import skops.io as sio

    train, _ = trials
    est = make_method("svm-pca", fs=train.fs).fit(trial_matrix(train, 0.5), train.label)
    warped = save_model(tmp_path / "w.skops", est, "svm-pca", 0.5, train.fs,
                        training_summary(train, 0.5), time_scale="nominal")
    plain = save_model(tmp_path / "p.skops", est, "svm-pca", 0.5, train.fs,
                       training_summary(train, 0.5))
    doc = load_model(warped)
    assert doc["format"] == 2 and doc["features"]["time_scale"] == "nominal"
    assert reads_nominal_time(doc) and not reads_nominal_time(load_model(plain))
    assert load_model(plain)["format"] == 1  # older versions still read plain models
    x = trial_matrix(train, 0.5)
    assert (doc["estimator"].predict(x) == est.predict(x)).all()
    with pytest.raises(ValueError, match="time_scale"):
        save_model(tmp_path / "bad.skops", est, "svm-pca", 0.5, train.fs, {},
                   time_scale="fast")
    # a file claiming the warp under the old format is inconsistent, not silently unwarped
    bad = dict(doc, format=1)
    sio.dump(bad, tmp_path / "bad.skops")
    with pytest.raises(ModelFileError, match="inconsistent"):
        load_model(tmp_path / "bad.skops")


def test_a_warped_model_without_constants_is_refused_naming_the_file(tmp_path, trials):
    train, _ = trials
    est = make_method("svm-pca", fs=train.fs).fit(trial_matrix(train, 0.5), train.label)
    path = save_model(tmp_path / "w.skops", est, "svm-pca", 0.5, train.fs,
                      {**training_summary(train, 0.5), "calibration": "cal13.json"},
                      time_scale="nominal")
    with pytest.raises(ModelFileError, match=r"w\.skops: trained on traces warped.*cal13\.json"
                                             r".*--calibration FILE"):
        LearnedClassifier(path)


SCENE = """name = "warp-test"
layout = "arm"
duration = 9.0
ambient = 25.0
noise = 0.02
seed = 5
taxel_spread = 0.10
initial_temperature = [34.0, 36.0]
[[objects]]
name = "block"
material = "aluminium"
[[objects]]
name = "board"
material = "pine"
[[touches]]
object = "block"
taxels = [41, 42]
start = 1.0
duration = 2.0
[[touches]]
object = "board"
taxels = [12, 13]
start = 5.0
duration = 2.0
"""


def test_skin_run_warps_with_the_skin_file_calibration_and_refuses_without(tmp_path, trials):
    train, _ = trials
    train.save(tmp_path / "train.npz")
    cal = _calibration(tmp_path / "cal.json", np.unique(train.taxel))
    out = skin("train", "--data", str(tmp_path / "train.npz"), "--method", "svm-pca",
               "--duration", "0.5", "--calibration", str(cal), "-o", str(tmp_path / "w.skops"))
    assert out.returncode == 0, out.stderr
    (tmp_path / "scene.toml").write_text(SCENE)
    out = skin("simulate", "calibration", "--scene", str(tmp_path / "scene.toml"), "-o",
               str(tmp_path / "truth.json"))
    assert out.returncode == 0, out.stderr
    # without a calibration: refused before the first frame, naming the model and the fix
    out = skin("run", "--scene", str(tmp_path / "scene.toml"), "--speed", "0", "--model",
               str(tmp_path / "w.skops"), "--out", str(tmp_path / "bare"), "--no-map")
    assert out.returncode != 0
    assert "w.skops: trained on traces warped" in out.stderr and "--calibration" in out.stderr
    assert not (tmp_path / "bare").exists()
    # the skin file declares model and calibration
    (tmp_path / "skin.toml").write_text(
        '[source]\nscene = "scene.toml"\nspeed = 0\n[skin]\ncalibration = "truth.json"\n'
        '[classifier]\nmodel = "w.skops"\n[output]\nout = "run"\nmap = false\n')
    out = skin("run", "--json", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["detected"] == summary["touches"] == 2
    assert {t["label"] for t in summary["per_touch"]} <= {*CLASSES, "unknown"}


def test_bench_spread_classifies_with_a_model_file(tmp_path, trials, capsys):
    from skin.cli import main as skin_main

    train, _ = trials
    cal = load_calibration(_calibration(tmp_path / "cal.json", np.unique(train.taxel)))
    sensors = taxel_constants(cal, "cal.json")
    paths = {}
    for scale, data in (("taxel", train), ("nominal", warp_to_nominal(train, sensors))):
        est = make_method("svm-pca", fs=train.fs).fit(trial_matrix(data, 0.5), train.label)
        paths[scale] = save_model(tmp_path / f"{scale}.skops", est, "svm-pca", 0.5, train.fs,
                                  training_summary(train, 0.5), time_scale=scale)
    for scale, runs in (("taxel", {"nominal", "spread", "calibrated"}),
                        ("nominal", {"nominal", "calibrated"})):  # no constants: no run
        capsys.readouterr()
        contact = "finite" if scale == "nominal" else "perfect"
        assert skin_main(["bench", "spread", "--touches", "3", "--seed", "7", "--durations",
                          "1", "--model", str(paths[scale]), "--contact", contact,
                          "--json"]) == 0
        doc = json.loads(capsys.readouterr().out)
        assert doc["model"]["time_scale"] == scale and doc["contact"] == contact
        assert doc["materials"] == [m for m in doc["materials"] if m in CLASSES] != []
        figures = doc["by_duration"]["1"]
        assert runs <= set(figures) and not ({"spread"} - runs) & set(figures)
        for run in runs:
            assert figures[run]["detected"] == figures[run]["touches"] == 3
            assert 0 <= figures[run]["correct"] <= 3


def test_a_calibration_of_other_taxels_is_refused_and_a_partial_one_named(tmp_path, trials):
    """Nothing would be warped with another unit's file: refused before the work starts."""
    train, _ = trials
    train.save(tmp_path / "train.npz")
    ids = np.unique(train.taxel[train.taxel >= 0])
    other = _calibration(tmp_path / "other.json", ids + 1000)
    out = skin("train", "--data", str(tmp_path / "train.npz"), "--method", "svm-pca",
               "--duration", "1", "--calibration", str(other), "-o", str(tmp_path / "m.skops"))
    assert out.returncode != 0 and not (tmp_path / "m.skops").exists()
    assert "gives thermal constants for none of the taxels" in out.stderr
    assert "another unit" in out.stderr
    part = _calibration(tmp_path / "part.json", ids[1:])
    out = skin("train", "--data", str(tmp_path / "train.npz"), "--method", "svm-pca",
               "--duration", "1", "--calibration", str(part), "-o", str(tmp_path / "m.skops"))
    assert out.returncode == 0, out.stderr
    assert f"gives no thermal constants for taxel {int(ids[0])} of" in out.stderr

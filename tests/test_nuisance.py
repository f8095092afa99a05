"""Confidence bounded over a declared object temperature range (skin.models.nuisance)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("sklearn")

from skin.errors import SkinError
from skin.models.classifiers import make_method
from skin.models.features import contact_matrix
from skin.models.materials import load_materials
from skin.models.nuisance import (
    NuisanceBounded,
    bound,
    class_misfits,
    object_spread,
    uncovered,
)
from skin.models.physics import SensorConstants, contact_trace
from skin.models.trials import Protocol, simulate_trials

MATS = load_materials()
NAMES = ("aluminium", "pine", "glass", "neoprene", "steel", "cardboard")


@pytest.fixture(scope="module")
def ambient_and_cold():
    """One heated channel: trained on objects at ambient, tested on objects 8 K off."""
    mats = [MATS[m] for m in NAMES]
    train = simulate_trials(mats, Protocol(trials=30, run_length=10), seed=1)
    test = simulate_trials(mats, Protocol(trials=30, run_length=10, object_offset=8.0), seed=2)
    return train, test


def _figures(p: np.ndarray, classes, truth) -> tuple[float, float]:
    pred = np.asarray(classes)[p.argmax(axis=1)]
    right = pred == truth
    return float(np.mean(right)), float(np.mean((p.max(axis=1) >= 0.95) & ~right))


@pytest.mark.parametrize("method", ["default", "svm-pca"])
def test_a_model_trained_at_ambient_is_no_longer_confidently_wrong_on_cold_objects(
        ambient_and_cold, method):
    train, test = ambient_and_cold
    x_train, x_test = contact_matrix(train, 1.5), contact_matrix(test, 1.5)
    model = NuisanceBounded(make_method(method, fs=train.fs), object_temperature_range=8.0,
                            fs=train.fs).fit(x_train, train.label)
    inner = model.estimator_
    raw = (inner.predict_proba(x_test) if hasattr(inner, "predict_proba")
           else (inner.predict(x_test)[:, None] == inner.classes_[None, :]).astype(float))
    acc_raw, wrong_raw = _figures(raw, model.classes_, test.label)
    p = model.predict_proba(x_test)
    assert np.allclose(p.sum(axis=1), 1.0) and np.all(p >= 0)
    acc, wrong = _figures(p, model.classes_, test.label)
    assert wrong_raw > 0.1  # the defect: confident answers on a trace it cannot read
    assert wrong <= 0.03
    assert acc >= acc_raw - 0.03  # the answers stay; their confidence goes
    assert np.array_equal(model.predict(x_test), model.classes_[p.argmax(axis=1)])


def test_a_range_of_zero_changes_nothing(ambient_and_cold):
    train, _ = ambient_and_cold
    x = contact_matrix(train, 1.0)
    rng = np.random.default_rng(0)
    p = rng.dirichlet(np.ones(len(NAMES)), size=x.shape[0])
    assert np.array_equal(bound(p, x, list(NAMES), 0.0), p)
    model = NuisanceBounded(make_method("svm-pca", fs=train.fs), 0.0, fs=train.fs)
    model.fit(x, train.label)
    assert np.array_equal(model.predict(x), model.estimator_.predict(x))


def test_a_cold_low_effusivity_object_fits_a_conductive_one_only_within_the_range():
    """The physics the bound rests on: closed-form traces, no noise."""
    sensor = SensorConstants()
    fs, amb, t0 = 200.0, 25.0, 35.0
    t = np.arange(301) / fs
    classes = ["aluminium", "pine", "neoprene"]
    rows = []
    for mat, offset in (("pine", -8.0), ("pine", 0.0)):
        y = contact_trace(t, t0, amb + offset, MATS[mat].effusivity, sensor, 3000.0)
        rows.append(np.concatenate([[amb, t0], y]))
    trained, declared, samples = class_misfits(np.array(rows), classes, fs=fs,
                                               object_range=8.0)
    rms_t, rms_d = np.sqrt(trained / samples[:, None]), np.sqrt(declared / samples[:, None])
    pine = classes.index("pine")
    # cold pine: pine fits only with the object off ambient; at ambient pine fits as trained
    assert rms_d[0, pine] < 0.01 < rms_t[0, pine]
    assert rms_t[1, pine] < 0.01
    assert np.all(declared <= trained + 1e-9)  # a wider range never fits worse
    assert np.all(np.isfinite(declared)) and np.all(declared >= 0)


def test_the_training_data_that_did_not_vary_the_object_is_named(ambient_and_cold):
    train, _ = ambient_and_cold
    assert object_spread(train) is None  # not recorded
    assert uncovered(0.0, None) is None
    assert "did not record" in uncovered(8.0, None)
    assert "varied only 2.0 K" in uncovered(8.0, 2.0)
    assert uncovered(8.0, 9.0) is None
    with pytest.raises(ValueError, match="object_temperature_range"):
        NuisanceBounded(make_method("svm-pca"), -1.0).fit(contact_matrix(train, 0.5),
                                                          train.label)


def test_evaluate_reports_the_bounded_figures_and_refuses_a_bad_range(tmp_path,
                                                                      ambient_and_cold):
    import argparse
    import json

    from skin.commands import evaluate

    train, test = ambient_and_cold
    train.save(tmp_path / "a.npz")
    test.save(tmp_path / "b.npz")
    parser = argparse.ArgumentParser()
    evaluate.add_parser(parser.add_subparsers())
    args = parser.parse_args(["evaluate", "--train", str(tmp_path / "a.npz"), "--test",
                              str(tmp_path / "b.npz"), "--methods", "svm-pca",
                              "--durations", "1.5", "--object-temperature-range", "8",
                              "--json"])
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert evaluate.main(args) == 0
    r = json.loads(out.getvalue())["results"][0]
    assert r["bounded"]["object_temperature_range"] == 8.0
    assert r["bounded"]["confident_wrong"] <= 0.03
    for bad in (["--object-temperature-range", "-2"], ["--object-temperature-range", "nan"]):
        args = parser.parse_args(["evaluate", "--train", str(tmp_path / "a.npz"), "--test",
                                  str(tmp_path / "b.npz"), *bad])
        with pytest.raises(SkinError, match="object-temperature-range"):
            evaluate.main(args)
    args = parser.parse_args(["evaluate", "--data", str(tmp_path / "a.npz"),
                              "--object-temperature-range", "8"])
    with pytest.raises(SkinError, match="--train/--test"):
        evaluate.main(args)


def test_a_model_file_at_run_time_is_bounded_and_warns(ambient_and_cold):
    from skin.models.learned import LearnedClassifier
    from skin.setup import Setup

    train, test = ambient_and_cold
    est = make_method("svm-pca", fs=train.fs).fit(contact_matrix(train, 1.5), train.label)
    doc = {"estimator": est, "method": "svm-pca", "training": {"trials": len(train)},
           "features": {"duration": 1.5, "fs": train.fs, "channels": 1}}
    x = contact_matrix(test, 1.5)
    plain = LearnedClassifier(doc, threshold=0.5)
    assert plain.coverage_warning is None
    bounded = LearnedClassifier(doc, threshold=0.5, object_range=8.0)
    assert "did not record" in bounded.coverage_warning
    p0, p1 = plain._predict(x), bounded._predict(x)
    right = est.classes_[p1.argmax(axis=1)] == test.label
    assert np.mean((p0.max(axis=1) >= 0.95) & (est.classes_[p0.argmax(axis=1)] != test.label)) > 0.5
    assert np.mean((p1.max(axis=1) >= 0.95) & ~right) <= 0.03
    doc["training"]["object_temperature_spread"] = 10.0
    assert LearnedClassifier(doc, object_range=8.0).coverage_warning is None
    assert Setup().updated({"object_temperature_range": 8}, "test").object_temperature_range == 8
    with pytest.raises(SkinError, match="object_temperature_range"):
        Setup().updated({"object_temperature_range": -1}, "test")
    from skin.formats.skin_file import parse_skin_file

    setup = parse_skin_file("[classifier]\nobject_temperature_range = 8\n", "s.toml")
    assert setup.object_temperature_range == 8.0
    with pytest.raises(SkinError, match=r"s\.toml:2: object_temperature_range"):
        parse_skin_file("[classifier]\nobject_temperature_range = -8\n", "s.toml")


def test_a_run_on_another_sensor_than_the_training_one_is_named(ambient_and_cold):
    from skin.models.modelfile import training_summary
    from skin.models.nuisance import other_sensors

    train, _ = ambient_and_cold
    assert "sensor" not in training_summary(train, 1.0)
    assert training_summary(train, 1.0, sensor="low-cost")["sensor"] == "low-cost"
    with pytest.raises(SkinError):
        training_summary(train, 1.0, sensor="no-such-sensor")
    assert other_sensors(None, ["", "paper"]) is None
    assert "does not record" in other_sensors(None, ["low-cost"])
    assert other_sensors("low-cost", ["low-cost"]) is None
    assert "'paper'" in other_sensors("paper", ["", "low-cost"])


def test_a_scene_declares_its_objects_temperature_range():
    from skin.formats.scene import load_scene
    from skin.models.nuisance import scene_object_range

    scene = load_scene("default")
    assert scene_object_range(scene, MATS) == 0.0  # a forearm holds its own temperature
    obj = next(iter(scene.objects.values()))
    cold = {**scene.objects, "cold": type(obj)("cold", "aluminium", scene.ambient - 6.0)}
    assert scene_object_range(type("S", (), {"objects": cold, "ambient": scene.ambient})(),
                              MATS) == 6.0

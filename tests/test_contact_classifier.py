"""The default contact classifier, the joint grid fit, families, and scikit-learn's contract."""

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

pytest.importorskip("sklearn")

from skin.models import load_materials
from skin.models.classifiers import (
    AnytimeClassifier,
    HMMClassifier,
    ModelBasedClassifier,
    PhysicsFeatures,
    TraceFeatures,
    expected_failed_checks,
    truncate_rows,
)
from skin.models.contact import ContactClassifier, ContactFeatures
from skin.models.contact_fit import grid_basis, grid_fit, grid_fits, grid_responses
from skin.models.features import contact_matrix
from skin.models.materials import hierarchical_answer
from skin.models.physics import SensorConstants, contact_trace
from skin.models.trials import Protocol, simulate_trials

MATS = load_materials()


@pytest.mark.parametrize("est", [ContactFeatures(), ContactClassifier(), TraceFeatures(),
                                 PhysicsFeatures(), ModelBasedClassifier(),
                                 AnytimeClassifier(method="knn-pca", durations=(0.01,)),
                                 HMMClassifier(n_iter=2)], ids=lambda e: type(e).__name__)
def test_check_estimator_passes_but_for_the_declared_checks(est):
    from sklearn.utils.estimator_checks import check_estimator

    declared = expected_failed_checks(est)
    assert all(declared.values())  # every exception has its reason
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = check_estimator(est, expected_failed_checks=declared, on_fail=None)
    failed = [r["check_name"] for r in results if r["status"] == "failed"]
    assert failed == []
    assert sum(r["status"] == "passed" for r in results) >= 20


def test_grid_fit_recovers_effusivity_and_object_from_two_channels():
    s = SensorConstants()
    t = np.arange(300) / 200.0
    e_true, t_obj, amb = 331.0, 17.0, 25.0  # cold pine
    t0 = np.array([[36.0, 25.5]])
    w = np.stack([contact_trace(t, t0[0, i], t_obj, e_true, s, 2000.0) for i in range(2)])[None]
    fit = grid_fit(np.array([amb]), t0, w, grid_responses(t.size, 200.0, s))
    assert abs(fit["log_e"][0] - np.log10(e_true)) < 0.1
    assert abs(fit["object"][0] - (t_obj - amb)) < 0.5
    one = grid_fit(np.array([amb]), t0[:, :1], w[:, :1], grid_responses(t.size, 200.0, s))
    assert one["object_std"][0] > 5 * fit["object_std"][0]  # one channel cannot pin it
    flat = grid_fit(np.array([amb]), np.array([[amb]]), np.full((1, 1, 300), amb),
                    grid_responses(300, 200.0, s))  # a sensor at ambient: nothing to see
    assert all(np.all(np.isfinite(v)) for v in flat.values())


def test_grid_fit_on_the_basis_and_under_several_priors_is_the_same_fit():
    """The low-rank product and the shared statistics change the fit by rounding only."""
    s = SensorConstants()
    rng = np.random.default_rng(3)
    t = np.arange(500) / 200.0
    amb, n = 25.0, 12
    obj = amb + rng.uniform(-8, 8, n)
    t0 = np.column_stack([rng.uniform(30, 40, n), amb + rng.uniform(0, 1, n)])
    e = 10.0 ** rng.uniform(2.5, 4.3, n)
    w = np.stack([[contact_trace(t, t0[i, c], obj[i], e[i], s, 3e3) for c in range(2)]
                  for i in range(n)]) + rng.normal(0, 0.05, (n, 2, t.size))
    w[::3, 1], t0[::3, 1] = np.nan, np.nan  # some contacts reach one taxel only: k = 1 and 2
    resp = grid_responses(t.size, 200.0, s)
    coef, basis = grid_basis(resp)
    assert 5 < basis.shape[0] < 40 and np.allclose(coef @ basis, resp, atol=1e-9)
    ambient = np.full(n, amb)
    full = [grid_fit(ambient, t0, w, resp, object_std=std) for std in (10.0, 1.0)]
    fast = grid_fits(ambient, t0, w, resp, object_stds=(10.0, 1.0), basis=(coef, basis))
    for a, b in zip(full, fast, strict=True):
        for key in a:
            assert np.allclose(a[key], b[key], rtol=1e-7, atol=1e-7), key


def test_hierarchy_names_the_family_when_the_material_is_unresolved():
    probs = {"pine": 0.45, "mdf": 0.40, "glass": 0.15}
    label, conf, family, family_conf = hierarchical_answer(probs, 0.5)
    assert (label, family) == ("unknown", "wood_paper")
    assert conf == pytest.approx(0.45) and family_conf == pytest.approx(0.85)
    assert hierarchical_answer({"pine": 0.9, "glass": 0.1}, 0.5)[::2] == ("pine", "wood_paper")
    assert hierarchical_answer({"pine": 0.4, "glass": 0.35, "steel": 0.25}, 0.5)[2] == "unknown"
    assert hierarchical_answer({}, 0.5) == ("unknown", 0.0, "unknown", 0.0)
    assert {m.family for m in MATS.values()} >= {"metal", "glass_ceramic", "polymer_rubber",
                                                 "wood_paper", "skin"}


@pytest.fixture(scope="module")
def two_channel():
    names = ("aluminium", "pine", "glass", "neoprene")
    train = simulate_trials([MATS[m] for m in names],
                            Protocol(trials=30, run_length=10,
                                     channels=("heated", "passive")), seed=1)
    test = simulate_trials([MATS[m] for m in names],
                           Protocol(trials=20, run_length=10, object_offset=8.0,
                                    channels=("heated", "passive")), seed=2)
    return train, test


def test_passive_channel_names_cold_and_warm_objects_one_channel_cannot(two_channel):
    train, test = two_channel
    acc = {}
    for ch in ([0, 1], [0]):
        tr, te = train.channels(ch), test.channels(ch)
        m = ContactClassifier(len(ch)).fit(contact_matrix(tr, 1.5), tr.label)
        p = m.predict_proba(contact_matrix(te, 1.5))
        assert np.allclose(p.sum(axis=1), 1.0)
        acc[len(ch)] = np.mean(m.classes_[p.argmax(axis=1)] == te.label)
    assert acc[2] > acc[1] + 0.2


def test_copies_only_where_a_second_channel_pins_the_object(two_channel):
    """One heated channel cannot tell a cold object from a conductive one: no copies there."""
    train, _ = two_channel
    one = train.channels([0])
    x1, x2 = contact_matrix(one, 0.5), contact_matrix(train, 0.5)
    m1 = ContactClassifier(1).fit(x1, one.label)
    assert not m1.copied_ and m1.C_ == 1.0
    assert m1.raw_ is not None  # ambient data: the raw-window expert joins in
    forced = ContactClassifier(1, unpinned_copies=True).fit(x1, one.label)
    assert forced.copied_ and forced.C_ == 0.1
    assert ContactClassifier(2).augment(x2, train.label)[0].shape[0] > x2.shape[0]
    assert ContactClassifier(2).fit(x2, train.label).raw_ is None  # it would unteach them
    x2[:, 1 + 101:] = np.nan  # no contact reached the passive taxel: nothing pins the object
    m2 = ContactClassifier(2).fit(x2, train.label)
    assert not m2.copied_
    # the ambient-trained one-channel model is the same with or without the unused spread
    same = ContactClassifier(1, object_spread=0.0).fit(x1, one.label)
    assert np.allclose(m1.predict_proba(x1), same.predict_proba(x1))


def test_calibration_folds_follow_the_groups(two_channel):
    """With groups, the held-out rows that fit the weights come from taxels left out."""
    train, _ = two_channel
    one = train.channels([0])
    x = contact_matrix(one, 0.5)
    grouped = ContactClassifier(1).fit(x, one.label, groups=one.group)
    plain = ContactClassifier(1).fit(x, one.label)
    assert np.unique(one.group).size >= 3
    assert grouped.expert_weights_ != plain.expert_weights_  # other held-out rows
    assert np.allclose(grouped.predict_proba(x).sum(axis=1), 1.0)
    copies = ContactClassifier(2).fit(contact_matrix(train, 0.5), train.label,
                                      groups=train.group)  # groups follow the copies
    assert copies.copied_ and copies.temperature_ > 0
    with pytest.raises(ValueError, match="one per row"):
        ContactClassifier(1).fit(x, one.label, groups=one.group[:-1])


def test_anytime_passes_the_groups_to_each_duration(two_channel):
    train, _ = two_channel
    one = train.channels([0])
    x = contact_matrix(one, 0.5)
    anytime = AnytimeClassifier("default", (0.25, 0.5), fs=one.fs, channels=1).fit(
        x, one.label, groups=one.group)
    for k, model in zip(anytime.samples_, anytime.models_, strict=True):
        alone = ContactClassifier(1).fit(truncate_rows(x, 1, k), one.label, groups=one.group)
        assert model.expert_weights_ == alone.expert_weights_
        assert np.allclose(model.predict_proba(truncate_rows(x, 1, k)),
                           alone.predict_proba(truncate_rows(x, 1, k)))


def test_absent_channel_is_read_as_absent(two_channel):
    train, test = two_channel
    m = ContactClassifier(2).fit(contact_matrix(train, 0.5), train.label)
    x = contact_matrix(test, 0.5)
    x[:, 1 + 101:] = np.nan  # the passive channel did not touch
    p = m.predict_proba(x)
    assert np.all(np.isfinite(p)) and np.allclose(p.sum(axis=1), 1.0)


def skin(*args):
    return subprocess.run([sys.executable, "-m", "skin", *args], capture_output=True, text=True,
                          timeout=300)


def test_train_tiny_dataset_says_why_and_evaluate_reads_a_model_file(tmp_path, two_channel):
    train, test = two_channel
    train.save(tmp_path / "train.npz")
    test.save(tmp_path / "test.npz")
    train.subset(np.arange(0, len(train), 30)).save(tmp_path / "tiny.npz")  # 1 per class
    for method in ("default", "svm-pca", "fit-trees"):
        out = skin("train", "--data", str(tmp_path / "tiny.npz"), "--method", method,
                   "-o", str(tmp_path / "m.skops"))
        assert out.returncode == 2 and "Traceback" not in out.stderr
        assert "needs at least" in out.stderr and "per class" in out.stderr
    out = skin("train", "--data", str(tmp_path / "train.npz"), "--duration", "1.5",
               "-o", str(tmp_path / "m.skops"))
    assert out.returncode == 0, out.stderr
    # the model's calibration folds kept the units apart, as `skin evaluate`'s do
    from skin.commands.evaluate import independent_groups
    from skin.formats.dataset import load_trials
    from skin.models.classifiers import make_method, method_matrix
    from skin.models.modelfile import load_model

    saved = load_trials(tmp_path / "train.npz")
    x, groups = method_matrix(saved, "default", 1.5), independent_groups(saved)[0]
    grouped = make_method("default", saved.fs, saved.n_channels).fit(x, saved.label,
                                                                     groups=groups)
    plain = make_method("default", saved.fs, saved.n_channels).fit(x, saved.label)
    trained = load_model(tmp_path / "m.skops")["estimator"]
    # (equal to float rounding: the command ran in another process, its BLAS threads its own)
    assert trained.temperature_ == pytest.approx(grouped.temperature_, rel=1e-6)
    assert trained.temperature_ != pytest.approx(plain.temperature_, rel=1e-3)
    out = skin("evaluate", "--data", str(tmp_path / "test.npz"), "--model",
               str(tmp_path / "m.skops"), "--json")
    assert out.returncode == 0, out.stderr
    (r,) = json.loads(out.stdout)["results"]
    assert r["method"] == "model:default" and r["duration"] == 1.5
    assert 0.0 <= r["accuracy"] <= 1.0 and r["family_accuracy"] >= r["accuracy"]


def test_run_reports_families_and_a_measured_effusivity(tmp_path, two_channel):
    out = skin("run", "--speed", "0", "--duration", "8", "--no-map", "--out",
               str(tmp_path / "run"), "--json")
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["family_correct"] >= summary["correct"]
    records = [json.loads(line) for line in (tmp_path / "run" / "events.jsonl").open()]
    final = [r for r in records if r["final"]]
    assert final and all({"family", "probabilities", "truth_family"} <= set(r) for r in final)
    named = [r for r in final if r["label"] != "unknown" and r["effusivity"]]
    assert named
    for r in named:  # the contact's measured effusivity, not the label's table value
        assert r["family"] == MATS[r["label"]].family
        assert abs(r["effusivity"] - MATS[r["label"]].effusivity) > 1e-6 * r["effusivity"]
    assert summary["median_log10_effusivity_error"] > 0.0


def test_run_with_a_threshold_and_a_model_that_misses_a_class_of_the_scene(tmp_path,
                                                                          two_channel):
    train, _ = two_channel  # no human skin, which the default scene holds
    train.channels([0]).save(tmp_path / "t.npz")
    out = skin("train", "--data", str(tmp_path / "t.npz"), "--duration", "0.5",
               "-o", str(tmp_path / "m.skops"))
    assert out.returncode == 0, out.stderr
    out = skin("run", "--speed", "0", "--duration", "6", "--no-map", "--model",
               str(tmp_path / "m.skops"), "--threshold", "0.9", "--out", str(tmp_path / "r"))
    assert out.returncode == 2 and "no class 'human_skin'" in out.stderr
    out = skin("run", "--speed", "0", "--duration", "6", "--no-map", "--threshold", "1.5",
               "--out", str(tmp_path / "r"))
    assert out.returncode == 2 and "threshold" in out.stderr


def test_scikit_learn_floor_matches_what_the_code_imports():
    import re
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    spec = next(d for d in project["project"]["optional-dependencies"]["ml"]
                if d.startswith("scikit-learn"))
    floor = tuple(int(v) for v in re.search(r">=\s*([\d.]+)", spec).group(1).split(".")[:2])
    assert floor >= (1, 6)  # sklearn.utils.validation.validate_data arrived in 1.6

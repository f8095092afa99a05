import json
import subprocess
import sys

import numpy as np
import pytest

from skin.formats.dataset import DatasetError, TrialSet, load_trials
from skin.models import load_materials
from skin.models.trials import PAPER_MATERIALS, Protocol, simulate_trials

MATS = load_materials()
PAPER = [MATS[m] for m in PAPER_MATERIALS]


def small(model="contact", trials=20, seed=3, **kw):
    return simulate_trials(PAPER, Protocol(trials=trials, **kw), model=model, seed=seed)


def test_protocol_dataset_has_the_designed_shape_and_truth():
    ds = small()
    assert len(ds) == 11 * 20
    assert ds.temperature.shape == (220, 1, 700)  # 0.5 s before onset + 3 s at 200 Hz
    assert ds.fs == 200.0 and np.all(ds.onset == 100)
    assert ds.classes == sorted(PAPER_MATERIALS)
    assert set(ds.extra) >= {"true_effusivity", "true_sensor_temperature",
                             "true_object_temperature", "true_conductance", "true_onset_time"}
    t0 = ds.extra["true_sensor_temperature"]
    assert 25.0 < t0.min() and t0.max() < 41.0  # the paper: 26-40 C in a 25 C room
    # objects are at or above ambient (warmed by earlier touches, never colder)
    assert np.all(ds.extra["true_object_temperature"] >= ds.ambient - 1e-9)
    # before onset the reading sits near the initial temperature; after it, it falls
    pre = ds.primary[:, 90:100].mean(axis=1)
    assert np.median(np.abs(pre - t0)) < 0.1
    assert np.all(ds.primary[:, -1] < pre)


def test_same_seed_same_dataset_other_seed_other_dataset():
    a, b, c = small(seed=5), small(seed=5), small(seed=6)
    assert np.array_equal(a.temperature, b.temperature)
    assert not np.array_equal(a.temperature, c.temperature)


def test_readings_are_quantised_by_the_paper_adc():
    ds = small(trials=10)
    # a 10-bit ADC gives few distinct readings: steps of 0.05-0.1 C near 25-40 C
    steps = np.diff(np.unique(ds.primary[0]))
    assert steps.min() > 0.03


def test_human_skin_holds_its_own_temperature():
    ds = simulate_trials([MATS["pine"], MATS["human_skin"]], Protocol(trials=20), seed=1)
    tobj = ds.extra["true_object_temperature"][ds.label == "human_skin"]
    assert np.all((tobj >= 30.0) & (tobj <= 34.0))


def test_warm_room_shifts_the_initial_temperatures():
    ds = small(ambient=35.0)
    assert ds.extra["true_sensor_temperature"].min() > 35.0


def test_multilayer_path_runs_the_protocol_with_the_heater_on():
    ds = simulate_trials([MATS["aluminium"], MATS["pine"]], Protocol(trials=12), seed=2,
                         model="multilayer")
    assert ds.temperature.shape == (24, 1, 700)
    assert np.all(np.isfinite(ds.temperature))
    t0 = ds.extra["true_sensor_temperature"]
    al = ds.label == "aluminium"
    # aluminium drains the taxel more than pine, so it starts its next contact colder
    assert t0[al][1:10].mean() < t0[~al][1:10].mean()


def test_dataset_round_trip_and_no_pickles(tmp_path):
    ds = small(trials=5)
    path = ds.save(tmp_path / "t.npz")
    back = load_trials(path)
    assert np.array_equal(back.temperature, ds.temperature)
    assert list(back.label) == list(ds.label)
    assert np.array_equal(back.group, ds.group)
    assert set(back.extra) == set(ds.extra)
    np.savez(tmp_path / "obj.npz", temperature=np.zeros((2, 3)), fs=200.0, onset=[0, 0],
             label=np.array([{"a": 1}, {"b": 2}], dtype=object))
    with pytest.raises(DatasetError, match="plain-array"):
        load_trials(tmp_path / "obj.npz")


def make(**kw):
    base = dict(temperature=np.full((3, 10), 30.0), fs=200.0,
                label=np.array(["a", "b", "a"]), onset=np.array([2, 2, -1]))
    base.update(kw)
    return TrialSet(**base)


@pytest.mark.parametrize(("change", "message"), [
    (dict(temperature=np.full((3,), 30.0)), "n_trials, n_samples"),
    (dict(onset=np.array([2, 10, 0])), "trial 1 is 10"),
    (dict(onset=np.array([2.0, 1.0, 0.0])), "integer"),
    (dict(label=np.array(["a", "b"])), "'label' must have one value per trial"),
    (dict(fs=0.0), "'fs'"),
    (dict(ambient=np.array([25.0, np.nan, 25.0])), "'ambient' of trial 1"),
])
def test_bad_datasets_are_rejected_naming_key_and_trial(change, message):
    with pytest.raises(DatasetError, match=message):
        make(**change)


def test_nan_reading_is_rejected_with_its_trial_and_sample():
    temp = np.full((3, 10), 30.0)
    temp[2, 7] = np.nan
    with pytest.raises(DatasetError, match="trial 2 is not finite at sample 7"):
        make(temperature=temp)


def test_missing_key_is_named(tmp_path):
    np.savez(tmp_path / "m.npz", temperature=np.zeros((2, 3)), fs=200.0)
    with pytest.raises(DatasetError, match=r"missing key.*label.*onset"):
        load_trials(tmp_path / "m.npz")


def skin(*args):
    return subprocess.run([sys.executable, "-m", "skin", *args], capture_output=True, text=True,
                          timeout=300)


def test_simulate_trace_reproduces_the_paper_numbers():
    out = skin("simulate", "trace", "--material", "aluminium", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    t, y = np.array(doc["t"]), np.array(doc["temperature"])
    assert doc["t_sensor"] == pytest.approx(38.963, abs=1e-3)
    assert y[np.searchsorted(t, 0.5)] == pytest.approx(37.229, abs=1e-3)
    assert y[np.searchsorted(t, 2.5)] == pytest.approx(32.327, abs=1e-3)
    pine = json.loads(skin("simulate", "trace", "--material", "pine", "--json").stdout)
    assert pine["temperature"][-1] == pytest.approx(36.636, abs=1e-3)


@pytest.mark.parametrize("model", ["contact", "multilayer"])
def test_simulate_trace_other_models_fall_slower_than_perfect_contact(model):
    ideal = json.loads(skin("simulate", "trace", "--material", "glass", "--json").stdout)
    other = json.loads(skin("simulate", "trace", "--material", "glass", "--model", model,
                            "--json").stdout)
    assert len(other["temperature"]) == len(ideal["temperature"]) == 501
    assert other["temperature"][100] > ideal["temperature"][100]


def test_simulate_trace_unknown_material_is_a_clear_error():
    out = skin("simulate", "trace", "--material", "unobtainium")
    assert out.returncode == 2
    assert "unknown material 'unobtainium'" in out.stderr


def test_simulate_trials_and_evaluate_the_paper_svm(tmp_path):
    path = tmp_path / "trials.npz"
    out = skin("simulate", "trials", "-o", str(path), "--trials", "30", "--materials",
               "aluminium,pine,cardboard", "--json")
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["trials"] == 90 and path.exists()
    out = skin("evaluate", "--data", str(path), "--durations", "0.5,2.5", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert [r["duration"] for r in doc["results"]] == [0.5, 2.5]
    for r in doc["results"]:
        conf = np.array(r["confusion"])
        assert conf.sum() == 90 and conf.shape == (3, 3)
        assert r["accuracy"] == pytest.approx(np.trace(conf) / 90, abs=0.02)
    assert doc["results"][-1]["accuracy"] > 0.9  # three well-separated materials
    assert "selective" not in doc["results"][0]  # a linear SVC gives no probabilities
    assert doc["split"].startswith("grouped: 8 independent groups")  # the default
    assert doc["results"][0]["split"] == doc["split"]
    strat = skin("evaluate", "--data", str(path), "--durations", "1", "--split", "stratified",
                 "--json", "--merge", "aluminium+pine+cardboard")
    assert strat.returncode == 0, strat.stderr
    assert json.loads(strat.stdout)["split"].startswith("stratified by class")
    assert json.loads(strat.stdout)["results"][0]["merged_accuracy"] == 1.0
    table = skin("evaluate", "--data", str(path), "--durations", "1")
    assert "3-fold cross-validation, grouped: 8 independent groups" in table.stdout
    bad = skin("evaluate", "--data", str(path), "--merge", "aluminium+unobtainium")
    assert bad.returncode == 2 and "unobtainium" in bad.stderr


def test_evaluate_rejects_a_window_longer_than_the_trials(tmp_path):
    path = tmp_path / "t.npz"
    skin("simulate", "trials", "-o", str(path), "--trials", "3", "--duration", "1")
    out = skin("evaluate", "--data", str(path), "--durations", "2.5")
    assert out.returncode == 2
    assert "trial 0 has 200 samples after onset" in out.stderr


def test_bench_thermal_quick_prints_work_precision_json():
    out = skin("bench", "thermal", "--quick", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["machine"]["cpus"] >= 1
    fw = doc["forward"]
    assert {r["scheme"] for r in fw} >= {"closed form", "tr-bdf2", "crank-nicolson", "euler"}
    assert all(np.isfinite(r["rms_error"]) and r["time_per_trial_ms"] > 0 for r in fw)
    euler = {r["dt"]: r["rms_error"] for r in fw if r["scheme"] == "euler"
             and r["case"] == "pine" and r["model"].endswith("limit)")
             and r.get("conductance") is None}
    assert euler[0.02] < euler[0.1]  # a smaller step is more accurate
    inv = doc["inverse"]
    assert {r["estimator"] for r in inv} == {"paper (eqs. 10-11, median)",
                                            "least squares (MAP)",
                                            "least squares + onset (MAP)",
                                            "least squares (profile)"}
    assert {r["duration"] for r in inv} == {0.25, 2.5}
    profile = [r for r in inv if r["estimator"] == "least squares (profile)"]
    assert all(0 < r["median_interval_width"] <= 5.0 for r in profile)


def test_multilayer_path_labels_the_taxel_and_ambient_it_simulated():
    ds = simulate_trials([MATS["glass"], MATS["pine"]], Protocol(trials=4, run_length=2),
                         seed=4, model="multilayer")
    per_material = ds.taxel.reshape(2, -1)
    assert np.array_equal(per_material[0], per_material[1])  # lockstep: one taxel per run
    amb = ds.ambient.reshape(2, -1)
    assert np.array_equal(amb[0], amb[1])
    # the initial temperature is read at the contact, not 0.5 s before it
    t0 = ds.extra["true_sensor_temperature"]
    at_onset = ds.primary[:, 99:102].mean(axis=1)
    assert np.max(np.abs(t0 - at_onset)) < 0.15


def test_evaluate_explains_too_few_trials(tmp_path):
    path = tmp_path / "few.npz"
    skin("simulate", "trials", "-o", str(path), "--trials", "2", "--materials", "pine,glass")
    out = skin("evaluate", "--data", str(path), "--cv", "3")
    assert out.returncode == 2 and "fewer than the 3 folds" in out.stderr
    out = skin("evaluate", "--data", str(path), "--cv", "2")
    assert out.returncode == 2 and "PCA with 10 components" in out.stderr
    out = skin("evaluate", "--data", str(path), "--cv", "3", "--split", "stratified")
    assert out.returncode == 2 and "fewer than the 3 folds" in out.stderr


def test_simulate_trace_rejects_a_non_positive_conductance():
    out = skin("simulate", "trace", "--material", "pine", "--model", "contact",
               "--conductance", "0")
    assert out.returncode == 2 and "--conductance must be positive" in out.stderr


def test_object_offsets_make_cold_and_warm_objects_per_run():
    mats = load_materials()
    ds = simulate_trials([mats["glass"], mats["human_skin"]],
                         Protocol(trials=20, run_length=5, object_offset=(-8.0, -6.0)), seed=4)
    glass = ds.label == "glass"
    first = np.arange(len(ds)) % 5 == 0  # a run starts with a rested object
    below = ds.ambient - ds.extra["true_object_temperature"]
    assert np.all((below[glass & first] > 5.9) & (below[glass & first] < 8.1))
    skin_t = ds.extra["true_object_temperature"][~glass]
    assert np.all((skin_t >= 30.0) & (skin_t <= 34.0))  # skin keeps its own temperature
    for key in ("true_sensor_depth", "true_sensor_diffusivity", "true_sensor_conductivity"):
        assert ds.extra[key].shape == (len(ds),)
    with pytest.raises(ValueError, match="multilayer"):
        simulate_trials([mats["glass"]], Protocol(trials=2, object_offset=(-1.0, 1.0)),
                        model="multilayer")
    with pytest.raises(ValueError, match="low, high"):
        simulate_trials([mats["glass"]], Protocol(trials=2, object_offset=(1.0, -1.0)))


def test_simulate_trials_object_offset_option(tmp_path):
    out = skin("simulate", "trials", "--materials", "glass,pine", "--trials", "4",
               "--object-offset=-3,3", "-o", str(tmp_path / "t.npz"))
    assert out.returncode == 0, out.stderr
    ds = load_trials(tmp_path / "t.npz")
    assert np.any(ds.extra["true_object_temperature"] != ds.ambient)
    out = skin("simulate", "trials", "--trials", "4", "--object-offset", "3,x",
               "-o", str(tmp_path / "u.npz"))
    assert out.returncode != 0 and "--object-offset" in out.stderr
    out = skin("simulate", "trials", "--trials", "4", "--object-offset=-3",
               "-o", str(tmp_path / "u.npz"))
    assert out.returncode != 0 and "K >= 0" in out.stderr


def test_bench_fusion_reports_every_arrangement(tmp_path):
    out = skin("bench", "fusion", "--materials", "glass,pine", "--trials", "2",
               "--durations", "0.5", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert len(doc["results"]) == 2 * 4  # two object-temperature ranges, four arrangements
    for r in doc["results"]:
        assert 0.0 <= r["accuracy"] <= 1.0 and 0.0 <= r["accuracy_calibrated"] <= 1.0
        assert 0.0 <= r["accuracy_fitted"] <= 1.0
        assert r["ms_per_contact"] > 0
    out = skin("bench", "fusion", "--materials", "glass,unobtainium")
    assert out.returncode != 0 and "unobtainium" in out.stderr


def test_evaluate_ceiling_on_simulated_data(tmp_path):
    ds = simulate_trials([load_materials()[m] for m in ("aluminium", "pine")],
                         Protocol(trials=12, run_length=4), seed=9)
    ds.save(tmp_path / "t.npz")
    out = skin("evaluate", "--data", str(tmp_path / "t.npz"), "--durations", "0.5",
               "--ceiling", "--json")
    assert out.returncode == 0, out.stderr
    rows = {r["method"]: r for r in json.loads(out.stdout)["results"]}
    assert rows["ceiling"]["accuracy"] >= rows["svm-pca"]["accuracy"] - 0.1
    less = skin("evaluate", "--data", str(tmp_path / "t.npz"), "--durations", "0.5",
                "--ceiling", "--ceiling-unknown",
                "taxel_constants,taxel_constants+object_temperature", "--json")
    assert less.returncode == 0, less.stderr
    methods = [r["method"] for r in json.loads(less.stdout)["results"]]
    assert methods[1:] == ["ceiling", "ceiling (taxel_constants unknown)",
                           "ceiling (taxel_constants unknown) (object_temperature unknown)"]
    bad = skin("evaluate", "--data", str(tmp_path / "t.npz"), "--ceiling",
               "--ceiling-unknown", "onset")
    assert bad.returncode == 2 and "unknown nuisance(s) onset" in bad.stderr


def test_one_class_is_a_dataset_but_not_a_classifier_dataset(tmp_path):
    from skin.formats.dataset import require_classes

    one = make(label=np.array(["a", "a", "a"]))  # a calibration's reference contacts
    with pytest.raises(DatasetError, match="1 class"):
        require_classes(one)
    one.save(tmp_path / "one.npz")
    out = skin("train", "--data", str(tmp_path / "one.npz"), "-o", str(tmp_path / "m.skops"))
    assert out.returncode == 2 and "at least 2" in out.stderr


def test_several_channels_see_one_object_heated_passive_and_held():
    ds = simulate_trials([MATS["pine"], MATS["aluminium"]],
                         Protocol(trials=10, run_length=5, object_offset=8.0,
                                  channels=("heated", "passive", "heated@+10")), seed=4)
    assert ds.temperature.shape == (20, 3, 700)
    assert ds.heated[0].tolist() == [True, False, True]
    assert np.allclose(ds.setpoint[:, 2], ds.ambient + 10.0) and np.isnan(ds.setpoint[:, :2]).all()
    offset = ds.extra["true_object_temperature"] - ds.ambient
    assert np.allclose(np.abs(offset[ds.label == "aluminium"]), 8.0, atol=0.5)  # +-K exactly
    passive = ds.temperature[:, 1]
    change = passive[:, -1] - passive[:, 90:100].mean(axis=1)  # 3 s into contact
    assert np.all(np.sign(change[np.abs(offset) > 4]) == np.sign(offset[np.abs(offset) > 4]))
    t0 = ds.extra["true_channel_sensor_temperature"]
    assert np.all((t0[:, 1] >= ds.ambient - 1e-9) & (t0[:, 1] <= ds.ambient + 1.0))
    assert len(set(ds.taxel[0].tolist())) == 3  # three distinct taxels
    with pytest.raises(ValueError, match="primary"):
        simulate_trials([MATS["pine"]], Protocol(trials=2, channels=("passive", "heated")))
    with pytest.raises(ValueError, match="unknown channel"):
        simulate_trials([MATS["pine"]], Protocol(trials=2, channels=("heated", "warm")))


def test_simulate_trials_command_takes_channels_and_an_offset(tmp_path):
    out = skin("simulate", "trials", "-o", str(tmp_path / "c.npz"), "--trials", "4",
               "--materials", "pine,glass", "--channels", "heated,passive",
               "--object-offset", "8", "--json")
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["channels"] == ["heated", "passive"]
    back = load_trials(tmp_path / "c.npz")
    assert back.n_channels == 2 and not back.heated[:, 1].any()
    bad = skin("simulate", "trials", "-o", str(tmp_path / "d.npz"), "--channels", "passive")
    assert bad.returncode == 2 and "must be heated" in bad.stderr


def test_a_group_is_a_unit_of_taxels_that_touches_every_material():
    """Groups are physical: no taxel in two groups, every group touches every material."""
    mats = [MATS["glass"], MATS["pine"], MATS["steel"]]
    ds = simulate_trials(mats, Protocol(trials=16, n_taxels=4), seed=2)
    assert np.array_equal(ds.group, ds.taxel[:, 0])  # one channel: the unit is the taxel
    for g in range(4):
        assert set(ds.label[ds.group == g]) == {"glass", "pine", "steel"}
    two = simulate_trials(mats, Protocol(trials=16, n_taxels=5, channels=("heated", "passive")),
                          seed=2)
    assert set(two.group.tolist()) == {0, 1}  # 5 taxels make two units of two
    for g in (0, 1):
        inside = set(two.taxel[two.group == g].ravel().tolist())
        outside = set(two.taxel[two.group != g].ravel().tolist())
        assert inside == {2 * g, 2 * g + 1} and not inside & outside
    every = simulate_trials(mats, Protocol(trials=20, run_length=5, n_taxels=8), seed=2)
    for m in ("glass", "pine", "steel"):  # explicit runs take consecutive units
        units = every.group[every.label == m].reshape(4, 5)
        assert (units == units[:, :1]).all()
        assert np.array_equal(np.diff(units[:, 0]) % 8, [1, 1, 1])
    with pytest.raises(ValueError, match="2 channels need at least 2 taxels"):
        simulate_trials(mats, Protocol(trials=4, n_taxels=1, channels=("heated", "passive")))


def test_grouped_folds_keep_every_taxel_on_one_side():
    from skin.commands.evaluate import independent_groups, split_folds
    from skin.errors import SkinError

    mats = [MATS["glass"], MATS["pine"], MATS["steel"]]
    ds = simulate_trials(mats, Protocol(trials=16, n_taxels=4), seed=2)
    folds, how = split_folds(ds, 2)
    assert how.startswith("grouped: 4 independent groups of trials linked by group and taxel")
    for train, test in folds:
        assert not set(ds.taxel[train, 0]) & set(ds.taxel[test, 0])
        assert set(ds.label[train]) == set(ds.label)
    # a taxel shared by two groups joins them; a trial without group or taxel stands alone
    base = TrialSet(ds.temperature, ds.fs, ds.label, onset=ds.onset, ambient=ds.ambient,
                    group=np.arange(len(ds)) % 6, taxel=np.where(np.arange(len(ds)) % 6 < 2,
                                                                 7, -1)[:, None])
    g, made_of = independent_groups(base)
    assert made_of == "group and taxel" and np.unique(g).size == 5
    assert g[0] == g[1]
    nothing = TrialSet(ds.temperature, ds.fs, ds.label, onset=ds.onset, ambient=ds.ambient)
    assert independent_groups(nothing) == (None, "none")
    assert split_folds(nothing, 2)[1].startswith("stratified by class: the dataset names no")
    # one material recorded on one taxel only cannot be tested on a taxel the model never saw
    lone = TrialSet(ds.temperature, ds.fs, ds.label, onset=ds.onset, ambient=ds.ambient,
                    group=np.where(ds.label == "steel", 9, ds.group))
    with pytest.raises(SkinError, match="a training fold has no trial of steel"):
        split_folds(lone, 3)

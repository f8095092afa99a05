"""The joint model: one object, several taxels, the object's temperature shared."""

import numpy as np
import pytest

from skin.models import load_materials
from skin.models.joint import JointContactModel
from skin.models.physics import SensorConstants, contact_trace

MATS = load_materials()
T = np.arange(1, 201) / 200.0  # 1 s at 200 Hz


def _reading(material, t0, t_obj, sensor=None, h=None):
    m = MATS[material]
    h = np.sqrt(np.prod(m.conductance_range)) if h is None else h
    return contact_trace(T, t0, t_obj, m.effusivity, sensor or SensorConstants(), h)


def test_evidence_matches_numerical_integration_over_the_object_temperature():
    model = JointContactModel([MATS["glass"], MATS["pine"]], noise=0.05, object_std=4.0,
                              h_points=1)
    t0 = np.array([33.0, 39.0])
    y = np.array([_reading("pine", v, 21.0) for v in t0])
    y += np.random.default_rng(0).normal(0, 0.05, y.shape)
    log_ev = model.log_evidence(T, y, t0, 25.0)
    # brute force: integrate N(y | T_obj) N(T_obj | 25, 4^2) over T_obj on a fine grid
    # 5 mK steps: the posterior spans some 40 of them (measured: the same agreement, 4e-11,
    # as 1 mK steps, which took 14 s of building (40001, 2, 200) arrays on a loaded machine)
    grid = np.linspace(5.0, 45.0, 8001)
    brute = []
    for i, _ in enumerate(model.classes):
        pred = np.stack([t0v + (grid[:, None] - t0v)
                         * (1.0 - contact_trace(T, 1.0, 0.0, model.effusivity[i],
                                                SensorConstants(), model.conductance[i, 0]))
                         for t0v in t0], axis=1)  # (grid, taxels, samples)
        ll = -0.5 * np.sum((y - pred) ** 2, axis=(1, 2)) / 0.05**2
        prior = -0.5 * (grid - 25.0) ** 2 / 16.0 - 0.5 * np.log(2 * np.pi * 16.0)
        f = ll + prior
        brute.append(f.max() + np.log(np.trapezoid(np.exp(f - f.max()), grid)))
    # the closed form drops the same (2 pi sigma^2)^(-N/2) for every class
    assert np.allclose(log_ev - log_ev[0], np.array(brute) - brute[0], atol=1e-6)


def test_one_taxel_cannot_tell_cold_pine_from_glass_two_at_different_temperatures_can():
    model = JointContactModel([MATS[m] for m in ("glass", "pine", "brick", "cardboard")])
    cold = 16.0  # pine from outdoors, in a 25 C room
    one = model.probabilities(T, _reading("pine", 36.0, cold)[None], np.array([36.0]), 25.0)
    assert one.max() < 0.9  # not sure: a colder object and a higher effusivity look alike
    t0 = np.array([31.0, 40.0])
    two = model.probabilities(T, np.array([_reading("pine", v, cold) for v in t0]), t0, 25.0)
    assert model.classes[int(np.argmax(two))] == "pine" and two.max() > 0.99
    assert model.object_temperature(T, np.array([_reading("pine", v, cold) for v in t0]), t0,
                                    25.0, "pine") == pytest.approx(cold, abs=0.5)
    same = np.array([36.0, 36.0])  # two taxels at one temperature add nothing new
    both = model.probabilities(T, np.array([_reading("pine", v, cold) for v in same]), same,
                               25.0)
    assert both.max() < 0.99


def test_each_taxels_own_constants_are_used():
    model = JointContactModel([MATS[m] for m in ("glass", "pine", "brick", "cardboard")])
    deep = SensorConstants(depth=1.2e-4)
    t0 = np.array([31.0, 40.0])
    y = np.array([_reading("glass", v, 20.0, deep) for v in t0])
    p = model.probabilities(T, y, t0, 25.0, [deep, deep])
    assert model.classes[int(np.argmax(p))] == "glass" and p.max() > 0.99
    # the readings fit far better with the constants that made them
    assert model.log_evidence(T, y, t0, 25.0, [deep, deep]).max() \
        > model.log_evidence(T, y, t0, 25.0).max() + 10.0


def test_extreme_and_degenerate_contacts_stay_finite():
    model = JointContactModel([MATS[m] for m in ("copper", "polyurethane_foam", "pine")])
    at_ambient = np.full((1, T.size), 25.0)  # a cold taxel touching a room-temperature thing
    p = model.probabilities(T, at_ambient, np.array([25.0]), 25.0)
    assert np.all(np.isfinite(p)) and p.sum() == pytest.approx(1.0)
    hot = np.array([_reading("copper", 40.0, 25.0, h=1e9)])  # copper, near-perfect contact
    p = model.probabilities(T, hot, np.array([40.0]), 25.0)
    assert np.all(np.isfinite(p)) and model.classes[int(np.argmax(p))] == "copper"
    foam = np.array([_reading("polyurethane_foam", 40.0, 25.0)])
    assert model.classes[int(np.argmax(model.probabilities(T, foam, np.array([40.0]), 25.0)))] \
        == "polyurethane_foam"


def test_bad_shapes_are_named():
    model = JointContactModel([MATS["glass"], MATS["pine"]])
    with pytest.raises(ValueError, match=r"\(2, 200\)"):
        model.log_evidence(T, np.zeros((1, 200)), np.array([30.0, 31.0]), 25.0)
    with pytest.raises(ValueError, match="1 sensors given for 2 taxels"):
        model.log_evidence(T, np.zeros((2, 200)), np.array([30.0, 31.0]), 25.0,
                           [SensorConstants()])
    with pytest.raises(ValueError, match="no finite reading"):
        model.log_evidence(T, np.full((1, 200), np.nan), np.array([30.0]), 25.0)
    with pytest.raises(ValueError, match="at least one"):
        JointContactModel([])


def test_onset_shifts_by_running_sums_match_shifted_single_evaluations_and_the_gather_path():
    shifts = (0.0, 0.01, 0.02, 0.04)
    mats = [MATS["glass"], MATS["pine"], MATS["aluminium"]]
    model = JointContactModel(mats, onset_shifts=shifts)
    sensors = [SensorConstants(), SensorConstants(diffusivity=3.0e-9), SensorConstants()]
    t0 = np.array([33.0, 36.0, 39.0])
    y = np.array([_reading("pine", v, 24.0, s) for v, s in zip(t0, sensors, strict=True)])
    y += np.random.default_rng(1).normal(0, 0.03, y.shape)
    fast = model.log_evidence(T, y, t0, 25.0, sensors)
    # the same as one model per shift, evaluated on the shifted times, then averaged
    single = np.array([JointContactModel(mats, onset_shifts=(0.0,)).log_evidence(
        T + s, y, t0, 25.0, sensors) for s in shifts])
    top = single.max(axis=0)
    assert np.allclose(fast, top + np.log(np.mean(np.exp(single - top), axis=0)), atol=1e-9)
    # samples a hair off the grid: the lags no longer coincide and the gather path runs
    jitter = np.random.default_rng(2).uniform(0, 1e-8, T.size)
    assert np.allclose(model.log_evidence(T + jitter, y, t0, 25.0, sensors), fast, atol=1e-4)


def test_evidence_by_prior_std_matches_one_model_per_std():
    mats = [MATS[m] for m in ("glass", "pine", "human_skin")]
    t0 = np.array([33.0, 39.0])
    y = np.array([_reading("pine", v, 25.0) for v in t0])
    by_std = JointContactModel(mats).log_evidence_by_std(T, y, t0, 25.0, None, [0.3, 10.0])
    for k, std in enumerate((0.3, 10.0)):
        one = JointContactModel(mats, object_std=std).log_evidence(T, y, t0, 25.0)
        assert np.allclose(by_std[k], one)


def test_learned_object_prior_narrows_on_pinned_contacts_at_ambient_not_on_cold_ones():
    from skin.models.joint import OBJECT_STDS, ObjectTemperaturePrior

    model = JointContactModel([MATS[m] for m in ("glass", "pine", "brick", "cardboard")])
    t0 = np.array([31.0, 40.0])  # two taxels at different temperatures pin the object's

    def pinned(material, t_obj):
        y = np.array([_reading(material, v, t_obj) for v in t0])
        return model.log_evidence_by_std(T, y, t0, 25.0, None, OBJECT_STDS)

    room, cold = ObjectTemperaturePrior(), ObjectTemperaturePrior()
    assert room.std() == pytest.approx(10.0)  # nothing seen: the broad prior
    for i, m in enumerate(("glass", "pine", "brick", "cardboard") * 2):
        room.update(pinned(m, 25.0))
        cold.update(pinned(m, 25.0 + (-8.0 if i % 2 else 8.0)))
    assert abs(room.weights().sum() - 1.0) < 1e-12
    assert room.weights()[-1] == pytest.approx(1.0 / 9.0, abs=1e-3)  # a new kind of object
    assert room.std() < 3.5 and cold.std() > 7.0
    # a contact that does not pin the object's temperature teaches nothing
    flat = ObjectTemperaturePrior()
    flat.update(np.zeros((len(OBJECT_STDS), 4)), weight=0.0)
    assert np.allclose(flat.weights(), ObjectTemperaturePrior().weights())
    # one taxel on glass at ambient: named under the learned prior, not under the broad one
    one = _reading("glass", 36.0, 25.0)[None]
    by_std = model.log_evidence_by_std(T, one, np.array([36.0]), 25.0, None, OBJECT_STDS)

    def answer(prior):
        ev = np.logaddexp.reduce(np.log(prior.weights() + 1e-300)[:, None] + by_std, axis=0)
        p = np.exp(ev - ev.max())
        return p / p.sum()

    broad = answer(ObjectTemperaturePrior())
    assert answer(room)[0] > 0.99 and answer(room)[0] > broad[0]
    assert answer(cold)[0] < answer(room)[0]
    with pytest.raises(ValueError, match="positive"):
        ObjectTemperaturePrior([0.0, 1.0])


def test_object_prior_bench_one_taxel_contacts_named_at_ambient():
    from skin.bench.object_prior import play, random_scene

    scene = random_scene(touches=16, single=0.5, seed=1)
    fixed, learned = play(scene, "fixed"), play(scene, "learned")
    assert fixed["learned_prior_std"] == pytest.approx(10.0)
    assert learned["learned_prior_std"] < 5.0
    one_f, one_l = fixed["one taxel"], learned["one taxel"]
    assert one_l["contacts"] == one_f["contacts"] > 0
    assert one_l["family"] > one_f["family"] and one_l["unknown"] < one_f["unknown"]


def test_own_temperature_stds_apply_to_skin_only_when_asked():
    from skin.models.joint import OBJECT_STDS

    model = JointContactModel([MATS[m] for m in ("pine", "cardboard", "human_skin")])
    t0 = np.array([36.2, 36.2])  # two taxels at one temperature: the object is not pinned
    y = np.array([_reading("human_skin", v, 32.0) for v in t0])
    table = model.log_evidence_by_std(T, y, t0, 25.0, None, OBJECT_STDS)
    own = model.log_evidence_by_std(T, y, t0, 25.0, None, OBJECT_STDS, own=True)
    assert np.allclose(table[:, :2], own[:, :2])  # objects at rest: unchanged
    assert np.ptp(table[:, 2]) < 1e-9  # skin keeps its table prior whatever the std
    assert np.ptp(own[:, 2]) > 1.0  # ... unless asked: then the std about its centre counts
    at_own = model.log_evidence_by_std(T, y, t0, 25.0, None, [model.own_std[2]], own=True)
    assert at_own[0, 2] == pytest.approx(table[0, 2])
    assert own[0, 2] > table[0, 2]  # skin at its centre: a narrow prior explains it better


def test_skin_met_twice_is_not_called_cardboard_with_confidence(tmp_path):
    """Scene seed 8: a forearm touched by two taxels 7 mK apart read like cardboard at 0.92.

    The skin's own temperature prior is now learned from the run's pinned skin contacts, as
    the objects' is: cardboard at ambient no longer wins on the narrower prior alone.
    """
    import json
    import subprocess
    import sys
    from pathlib import Path

    import skin

    scene = (Path(skin.__file__).parent / "data" / "scenes" / "default.toml").read_text()
    (tmp_path / "scene.toml").write_text(scene.replace("\nseed = 7\n", "\nseed = 8\n"))
    out = subprocess.run([sys.executable, "-m", "skin", "run", "--speed", "0", "--duration",
                          "20", "--no-map", "--scene", str(tmp_path / "scene.toml"), "--out",
                          str(tmp_path / "run")], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    final = [json.loads(line) for line in (tmp_path / "run" / "events.jsonl").open()]
    final = [e for e in final if e.get("final") and e.get("truth") not in (None, "(none)")]
    wrong = [e for e in final if e["label"] not in (e["truth"], "unknown")]
    assert not [e for e in wrong if e["confidence"] >= 0.9]
    skin_named = [e for e in final if e["truth"] == "human_skin" and e["label"] == "human_skin"]
    assert len(skin_named) >= 2  # of three (the fourth touch is split by the tracker)


def test_a_noise_grid_integrates_the_evidence_over_the_noise():
    """A grid of noises: each material's evidence averaged over them, with the (2 pi s^2)^(-N/2)
    the fixed noise drops; a one-noise grid is the fixed noise."""
    mats = [MATS[m] for m in ("glass", "pine", "brick")]
    t0 = np.array([33.0, 38.0])
    y = np.array([_reading("glass", v, 25.0) for v in t0])
    y += np.random.default_rng(1).normal(0, 0.03, y.shape)
    grid = (0.03, 0.1, 0.3)
    fixed = [JointContactModel(mats, noise=v).log_evidence(T, y, t0, 25.0) for v in grid]
    assert np.array_equal(JointContactModel(mats, noise=[0.1]).log_evidence(T, y, t0, 25.0),
                          fixed[1])
    by_noise = np.array([f - y.size * np.log(v) for f, v in zip(fixed, grid, strict=True)])
    top = by_noise.max(axis=0)
    expected = top + np.log(np.mean(np.exp(by_noise - top), axis=0))
    model = JointContactModel(mats, noise=grid)
    assert model.noise == 0.3
    got = model.log_evidence(T, y, t0, 25.0)
    assert np.allclose(got - got[0], expected - expected[0], atol=1e-9)
    # a reading the model explains to its noise is judged at that noise: sharper than 0.1 K
    margin = np.sort(got)[-1] - np.sort(got)[-2]
    assert np.argmax(got) == 0 and margin > 1.5 * (np.sort(fixed[1])[-1] - np.sort(fixed[1])[-2])
    assert np.isfinite(model.object_temperature(T, y, t0, 25.0, "glass"))
    with pytest.raises(ValueError, match="positive"):
        JointContactModel(mats, noise=(0.1, 0.0))



def test_the_calibration_is_stored_with_how_it_was_fitted_and_round_trips(tmp_path):
    from skin.models.joint import CALIBRATION_FILE, EvidenceTemperature

    stored = EvidenceTemperature.load()
    assert 0.01 <= stored.temperature <= 10.0
    assert "skin bench fit-calibration" in stored.fitted and "log-loss" in stored.fitted
    assert EvidenceTemperature.load(CALIBRATION_FILE) == stored
    path = tmp_path / "calibration.toml"
    path.write_text(EvidenceTemperature(0.25, 'say "it" \\ here').dump())
    assert EvidenceTemperature.load(path) == EvidenceTemperature(0.25, 'say "it" \\ here')


@pytest.mark.parametrize("text, match", [
    ("temperature = 0.0", "from 0.01 to 10"), ("temperature = nan", "from 0.01 to 10"),
    ("temperature = 11.0", "from 0.01 to 10"), ("temperature = true", "from 0.01 to 10"),
    ('temperature = "0.2"', "from 0.01 to 10"), ("fitted = 'x'", "needs 'temperature'"),
    ("temperature = 0.2\nnoise = 0.1", "needs 'temperature'"),
    ("temperature = ", "cannot read")])
def test_a_bad_calibration_is_refused_naming_the_file(tmp_path, text, match):
    from skin.models.joint import EvidenceTemperature

    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=match) as err:
        EvidenceTemperature.load(path)
    assert str(path) in str(err.value)
    with pytest.raises(ValueError, match="cannot read"):
        EvidenceTemperature.load(tmp_path / "missing.toml")
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfetemperature = 0.2")
    with pytest.raises(ValueError, match="cannot read") as err:
        EvidenceTemperature.load(binary)
    assert str(binary) in str(err.value)


def test_tempering_divides_the_log_evidence_and_keeps_the_ranking():
    from skin.models.joint import EvidenceTemperature

    log_ev = np.array([-3.0, 0.0, -1.0, -np.inf])
    p = EvidenceTemperature(0.5).probabilities(log_ev)
    expected = np.exp(2.0 * (log_ev - 0.0))
    assert np.allclose(p, expected / expected.sum()) and p[3] == 0.0
    assert np.array_equal(np.argsort(p), np.argsort(EvidenceTemperature(1.0).probabilities(
        log_ev)))
    plain = np.exp(log_ev) / np.exp(log_ev).sum()
    assert np.allclose(EvidenceTemperature(1.0).probabilities(log_ev), plain)
    assert EvidenceTemperature(0.5).probabilities(log_ev).max() > plain.max()
    # huge evidences stay finite
    assert np.all(np.isfinite(EvidenceTemperature(0.01).probabilities(np.array([1e6, 0.0]))))


def test_joint_classifier_tempers_its_answer_by_the_stored_calibration():
    from skin.contact import Contact, TaxelWindow
    from skin.formats.layout import load_layout
    from skin.models.joint import EvidenceTemperature, JointClassifier

    layout = load_layout("arm")
    assert JointClassifier(layout).calibration == EvidenceTemperature.load()
    # fitted for the model's default settings: other settings are not tempered by it
    assert JointClassifier(layout, noise=0.05).calibration is None
    assert JointClassifier(layout, object_prior="fixed").calibration is None
    from skin.models.materials import load_materials

    table = load_materials()
    assert JointClassifier(layout, table).calibration == EvidenceTemperature.load()
    fewer = {k: m for k, m in table.items() if k != "pine"}
    assert JointClassifier(layout, fewer).calibration is None
    with pytest.raises(ValueError, match="calibration must be"):
        JointClassifier(layout, calibration="fitted")
    y = _reading("pine", 35.0, 25.0)
    contact = Contact(id=1, taxels=[0], onset=1.0, release=None, ambient=25.0,
                      windows=[TaxelWindow(0, 1.0, 35.0, T, y, False)])
    plain = JointClassifier(layout, calibration=None).classify(contact)
    sharp = JointClassifier(layout, calibration=EvidenceTemperature(0.5)).classify(contact)
    names = list(plain.probabilities)
    p = np.array([plain.probabilities[k] for k in names])
    expected = p**2 / np.sum(p**2)
    assert np.allclose([sharp.probabilities[k] for k in names], expected, atol=1e-9)
    assert sharp.confidence >= plain.confidence

"""The joint model reads each sensor preset as the simulator makes it (`contact_basis`)."""

import dataclasses

import numpy as np
import pytest

from skin.models import load_materials
from skin.models.joint import JointClassifier, JointContactModel
from skin.models.physics import SensorConstants
from skin.models.sensors import (
    apply_dynamics,
    contact_basis,
    contact_reading,
    has_dynamics,
    load_sensor,
    load_sensors,
    smooth,
)

MATS = load_materials()
PRESETS = ("paper", "pid-logger", "fast-film", "low-cost")
FOREIGN = PRESETS[1:]
AMB = 25.0


def _simulated(sensor, t0, t_obj, material, h, seconds=2.0, pre=1.0):
    """The simulator's noise-free reading: contact_reading, then dynamics and smoothing.

    A series settled at ``t0`` for ``pre`` s, the contact at a sample; returns the times
    since contact and the readings of the samples after it (and the whole series' times).
    """
    fs = sensor.sample_rate
    k = np.arange(-round(pre * fs), round((seconds + 1.0) * fs))  # a second more: savgol
    since = k / fs
    e = MATS[material].effusivity
    y = np.where(since > 0, contact_reading(np.maximum(since, 0.0), t0, t_obj, e, sensor, h,
                                            AMB), t0)
    y = smooth(apply_dynamics(y, sensor, fs), sensor, fs=fs)
    after = (since > 0) & (since <= seconds + 1e-9)
    return since[after], y[after], since, y


@pytest.mark.parametrize("name", PRESETS)
def test_basis_is_the_simulators_noise_free_reading(name):
    s = load_sensor(name)
    for material, t0, t_obj in (("aluminium", 37.0, 22.0), ("pine", 31.0, 28.0),
                                ("neoprene", 40.0, 25.0)):
        h = float(np.sqrt(np.prod(MATS[material].conductance_range)))
        t, want, since, whole = _simulated(s, t0, t_obj, material, h)
        p, q, a = contact_basis(t, MATS[material].effusivity, h, s)
        got = (t0 + (t_obj - t0) * p + (0.0 if q is None else (AMB - t0) * q)
               + (0.0 if a is None else a))
        assert np.max(np.abs(got - want)) < 1e-9 * max(1.0, np.max(np.abs(want)))
        assert (q is not None) == (s.heater == "off-at-contact")
        assert (a is not None) == (s.heater == "on-during-contact")
        # before contact: a non-causal smoothing has moved already, a causal one has not
        before = (since <= 0) & (since > -0.5)
        p, q, a = contact_basis(since[before], MATS[material].effusivity, h, s)
        got = (t0 + (t_obj - t0) * p + (0.0 if q is None else (AMB - t0) * q)
               + (0.0 if a is None else a))
        assert np.max(np.abs(got - whole[before])) < 1e-9 * np.max(np.abs(whole))
        assert np.any(got != t0) == (s.smoothing == "savgol")


def test_between_samples_the_basis_interpolates_its_grid():
    s = load_sensor("low-cost")  # 20 Hz, read at 200 Hz by the pipeline's grid
    t = np.arange(1, 60) / 200.0
    p, _, a = contact_basis(t, 400.0, 3000.0, s)
    on_grid, _, a_grid = contact_basis(np.arange(0, 11) / 20.0, 400.0, 3000.0, s)
    assert np.allclose(p, np.interp(t, np.arange(0, 11) / 20.0, on_grid), atol=1e-15)
    assert np.allclose(a, np.interp(t, np.arange(0, 11) / 20.0, a_grid), atol=1e-15)


@pytest.mark.parametrize("name", FOREIGN)
def test_noise_free_contacts_give_the_true_material_and_object_temperature(name):
    s = load_sensor(name)
    names = ("aluminium", "glass", "pine", "neoprene", "cardboard", "brick")
    h = 3000.0
    # noise-free readings, so a small noise: the pid-logger's reading moves by 0.1 K in 1 s
    # (its own noise is some mK), which the default 0.1 K would not resolve
    model = JointContactModel([MATS[m] for m in names], noise=1e-3, object_std=1e4,
                              h_points=1, conductance_range=(h, h))
    plain = JointContactModel([MATS[m] for m in names], noise=1e-3, object_std=1e4,
                              h_points=1, conductance_range=(h, h))
    t0 = np.array([33.0, 39.5])
    wrong = 0
    for material in names:
        for t_obj in (22.0, 25.0, 29.0):
            runs = [_simulated(s, v, t_obj, material, h, seconds=1.0) for v in t0]
            t = runs[0][0]
            y = np.array([r[1] for r in runs])
            log_ev = model.log_evidence(t, y, t0, AMB, [s, s])
            assert np.all(np.isfinite(log_ev))
            assert model.classes[int(np.argmax(log_ev))] == material
            # the closed form's posterior mean is the object's temperature (exact model)
            assert model.object_temperature(t, y, t0, AMB, material, [s, s]) \
                == pytest.approx(t_obj, abs=1e-6)
            # the paper's reading model on the same contacts
            wrong += plain.classes[int(np.argmax(plain.log_evidence(
                t, y, t0, AMB, [s.constants()] * 2)))] != material
    assert wrong > 0  # the reading model matters on this preset


@pytest.mark.parametrize("name", FOREIGN)
def test_evidence_has_the_closed_form_of_the_filtered_regression(name):
    """The offset algebra against a direct Bayesian regression over the readings."""
    s = load_sensor(name)
    model = JointContactModel([MATS["glass"], MATS["pine"]], noise=0.05, object_std=4.0,
                              h_points=2, onset_shifts=(0.0, 0.02))
    t0 = np.array([33.0, 39.0])
    runs = [_simulated(s, v, 21.0, "pine", 900.0, seconds=0.8) for v in t0]
    t = runs[0][0]
    y = np.array([r[1] for r in runs]) + np.random.default_rng(1).normal(0, 0.05, (2, t.size))
    log_ev, mean = model._posterior(t, y, t0, AMB, [s, s])
    for c in range(2):
        for j, h in enumerate(model.conductance[c]):
            for k, shift in enumerate(model.onset_shifts):
                p, q, a = contact_basis(t + shift, model.effusivity[c], h, s)
                # y = T0 + (T_obj - T0) p + (amb - T0) q + a = T_obj p + base
                base = np.array([v - v * p + (0.0 if q is None else (AMB - v) * q)
                                 + (0.0 if a is None else a) for v in t0])
                x, z = np.tile(p, 2), (y - base).ravel()
                precision = x @ x / 0.05**2 + 1.0 / 16.0
                rhs = x @ z / 0.05**2 + AMB / 16.0
                # the model's log evidence drops terms shared by every class and conductance
                want = -0.5 * (z @ z / 0.05**2 + AMB**2 / 16.0 - rhs**2 / precision) \
                    - 0.5 * np.log(16.0 * precision)
                col = j * model.onset_shifts.size + k
                assert mean[c, col] == pytest.approx(rhs / precision, abs=1e-8)
                # from ambient: the same quadratic form, shifted by a term shared by all
                assert log_ev[c, col] - log_ev[0, 0] == pytest.approx(
                    want - _ref(model, s, t, y, t0), abs=1e-6)


def _ref(model, s, t, y, t0):
    """The direct regression's log evidence of class 0, conductance 0, shift 0."""
    p, q, a = contact_basis(t, model.effusivity[0], model.conductance[0, 0], s)
    base = np.array([v - v * p + (0.0 if q is None else (AMB - v) * q)
                     + (0.0 if a is None else a) for v in t0])
    x, z = np.tile(p, 2), (y - base).ravel()
    precision = x @ x / 0.05**2 + 1.0 / 16.0
    rhs = x @ z / 0.05**2 + AMB / 16.0
    return -0.5 * (z @ z / 0.05**2 + AMB**2 / 16.0 - rhs**2 / precision) \
        - 0.5 * np.log(16.0 * precision)


@pytest.mark.parametrize("name", FOREIGN)
def test_extreme_contacts_stay_finite(name):
    s = load_sensor(name)
    model = JointContactModel([MATS[m] for m in ("copper", "polyurethane_foam", "pine")],
                              onset_shifts=(0.0, 0.01, 0.05))
    t = np.arange(1, 41) / 200.0
    at_ambient = np.full((2, t.size), AMB)  # taxels at ambient touching a thing at ambient
    p = model.probabilities(t, at_ambient, np.array([AMB, AMB]), AMB, [s, s])
    assert np.all(np.isfinite(p)) and p.sum() == pytest.approx(1.0)
    tiny = np.array([1e-9, 2e-9])  # t -> 0
    p = model.probabilities(tiny, np.full((1, 2), 38.0), np.array([38.0]), AMB, [s])
    assert np.all(np.isfinite(p))
    for material in ("copper", "polyurethane_foam"):
        h = 1e9 if material == "copper" else 500.0
        runs = [_simulated(s, v, AMB, material, h, seconds=1.0) for v in (34.0, 40.0)]
        y = np.array([r[1] for r in runs])
        p = model.probabilities(runs[0][0], y, np.array([34.0, 40.0]), AMB, [s, s])
        assert np.all(np.isfinite(p)) and model.classes[int(np.argmax(p))] == material
    big = contact_basis(np.array([1e-9, 0.5, 1e4]), np.array([[37137.0], [43.0]]),
                        np.array([[1e12], [1e-3]]), s)
    assert all(x is None or np.all(np.isfinite(x)) for x in big)


def test_the_papers_sensor_keeps_the_plain_path_bit_for_bit():
    paper = load_sensor("paper")
    assert not has_dynamics(paper) and not has_dynamics(SensorConstants())
    assert all(has_dynamics(load_sensor(n)) for n in FOREIGN)
    model = JointContactModel([MATS[m] for m in ("glass", "pine", "aluminium")],
                              onset_shifts=(0.0, 0.01, 0.02))
    t = np.arange(1, 201) / 200.0
    t0 = np.array([33.0, 39.0])
    y = np.array([_simulated(paper, v, 22.0, "pine", 900.0, seconds=1.0)[1] for v in t0])
    a = model.log_evidence_by_std(t, y, t0, AMB, [SensorConstants()] * 2, [0.5, 10.0])
    b = model.log_evidence_by_std(t, y, t0, AMB, [paper] * 2, [0.5, 10.0])
    assert np.array_equal(a, b)


def test_classifier_reads_each_taxel_with_its_boards_description():
    from skin.formats.layout import Layout, load_layout

    arm = load_layout("arm")
    fast = load_sensors()["fast-film"]
    layout = Layout(arm.taxels, [dataclasses.replace(b, **fast.board_fields(), sensor="fast-film")
                                 for b in arm.boards.values()])
    tid = int(layout.taxels[0].id)
    cal = SensorConstants(depth=2.7e-5, diffusivity=3e-9, conductivity=0.035)
    clf = JointClassifier(layout, sensors={tid: cal})
    got = clf._sensors[tid]
    assert got.heater == fast.heater and got.smoothing == fast.smoothing
    assert (got.depth, got.diffusivity, got.conductivity) == (2.7e-5, 3e-9, 0.035)
    other = clf._sensors[int(layout.taxels[1].id)]
    assert other.name == "fast-film" and other.heater == "off-at-contact"


def test_a_foreign_sensors_basis_is_kept_for_the_next_contact_and_bounded():
    from skin.models import joint

    s = load_sensor("fast-film")
    model = JointContactModel([MATS["glass"], MATS["pine"]], onset_shifts=(0.0, 0.01))
    t = np.arange(1, 101) / 200.0
    y = np.full((1, t.size), 36.0)
    first = model.log_evidence(t, y, np.array([38.0]), AMB, [s])
    assert len(model._basis_cache) == 1
    assert np.array_equal(model.log_evidence(t, y, np.array([38.0]), AMB, [s]), first)
    assert len(model._basis_cache) == 1
    for k in range(joint.BASIS_CACHE + 3):
        model.log_evidence(t, y, np.array([38.0]), AMB, [s.with_body(depth=2e-5 + k * 1e-7)])
    assert len(model._basis_cache) == joint.BASIS_CACHE


def test_bench_forward_prints_both_reading_models_per_preset():
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "skin", "bench", "forward", "--sensors",
                          "paper,low-cost", "--durations", "0.5", "--trials", "1", "--json"],
                         capture_output=True, text=True, check=True, timeout=300)
    rows = json.loads(out.stdout)["rows"]
    assert [r["sensor"] for r in rows] == ["paper", "low-cost"]
    for r in rows:
        assert r["contacts"] == 11 and 0 <= r["forward"] <= 1 and r["forward_ms"] > 0
    assert rows[0]["paper_model"] == rows[0]["forward"]  # the same computation on the paper's


@pytest.mark.parametrize("name", PRESETS)
def test_the_protocols_noise_free_contacts_are_the_classifiers_forward_model(name):
    """`simulate_trials` (the benchmarks' simulator, its protocol and room drift) against
    `contact_basis` told each contact's true nuisances: the reading is the model's within a
    tenth of the sensor's own reading noise, and the true material reads nearest (the
    protocol's reheating slope before contact, which the model leaves out, aside).

    The pid-logger's datasets met each touch at the last touch's setpoint (the room drifts
    0.1 K between touches) and ramped to this one's, 0.1 K/s stopped at contact and then
    high-passed again by the loop: 8 mK median and 0.2 K worst against this model, above its
    3.6 mK noise and its 25-50 mK swing in the first second.
    """
    from skin.models.contact import split_contact_rows
    from skin.models.features import contact_matrix
    from skin.models.joint import with_constants
    from skin.models.trials import PAPER_MATERIALS, Protocol, simulate_trials

    s = load_sensor(name)
    quiet = dataclasses.replace(s, noise=0.0, adc_noise=0.0, adc_bits=24)
    mats = [MATS[m] for m in PAPER_MATERIALS]
    data = simulate_trials(mats, dataclasses.replace(Protocol(), trials=4, duration=1.7,
                                                             n_taxels=2),
                           sensor=quiet, seed=5)
    x = data.extra  # two units: runs of two touches, the second after a reheat
    amb, t0, w = split_contact_rows(contact_matrix(data, 1.5), 1)
    lags = np.arange(w.shape[2]) / data.fs
    floor = s.noise_kelvin(AMB + s.heated_rise)
    worst = 0.0
    for i in range(len(data)):
        taxel = with_constants(s, SensorConstants(
            depth=float(x["true_sensor_depth"][i]),
            diffusivity=float(x["true_sensor_diffusivity"][i]),
            conductivity=float(x["true_sensor_conductivity"][i])))
        since = lags - (x["true_onset_time"][i] - Protocol().pre)  # from the true contact
        t_s, t_o = float(x["true_sensor_temperature"][i]), float(x["true_object_temperature"][i])
        # the classifier's T0 (the readings before onset) is the sensor's at contact, but for
        # a reheating sensor's slope over the samples it averages (the paper's: up to 4 mK)
        assert abs(t0[i, 0] - t_s) < 0.2 * floor, (name, i, t0[i, 0] - t_s, floor)
        misfit = []
        for m in mats:
            p, q, a = contact_basis(since, m.effusivity, float(x["true_conductance"][i]), taxel)
            model = (t_s + (t_o - t_s) * p + (0.0 if q is None else (amb[i] - t_s) * q)
                     + (0.0 if a is None else a))
            misfit.append(float(np.max(np.abs(w[i, 0] - model))))
        own = PAPER_MATERIALS.index(data.label[i])
        worst = max(worst, misfit[own])
        assert misfit[own] < 0.1 * floor, (name, i, data.label[i], misfit[own], floor)
        # nearest, but for the reheating slope the model leaves out (low-cost's steel reads
        # 1.4 mK from aluminium's in 1.5 s, its noise is 0.2 K)
        assert misfit[own] <= min(misfit) + 0.01 * floor, (name, i, data.label[i], misfit)
    assert worst > 0.0  # the readings went through the ADC (24 bits), not copied

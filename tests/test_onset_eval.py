"""Simulated streams with known contacts, and the detector judged on them."""

import json
import subprocess
import sys

import numpy as np
import pytest

from skin.bench.onset_eval import evaluate_onsets
from skin.bench.streams import simulate_stream
from skin.models import load_materials
from skin.models.physics import SensorConstants, contact_trace
from skin.stream.onset_refine import refine_onset

MATS = load_materials()


def test_stream_has_its_contacts_where_the_truth_says():
    s = simulate_stream([MATS["aluminium"], MATS["pine"]], n_taxels=3, duration=120.0,
                        contacts_per_minute=2.0, disturbances=False, seed=2)
    assert s.temperature.shape == (24000, 3) and np.all(np.isfinite(s.temperature))
    assert len(s.contacts) >= 3 and s.taxel_hours == pytest.approx(0.1)
    for c in s.contacts:
        k0 = round(c.onset * s.fs)
        before = s.temperature[k0 - 40:k0, c.taxel].mean()
        assert before == pytest.approx(c.sensor_temperature, abs=0.1)
        if c.duration > 1.0:  # a contact with a cooler object pulls the reading down
            assert s.temperature[k0 + 190:k0 + 200, c.taxel].mean() < before - 0.2
        assert 0.05 < c.visible_after < 1.5 or (c.visible_after == np.inf
                                                 and c.duration < 1.0)
        # the largest change the contact made: at least the one at its last sample
        k1 = round(c.release * s.fs) - 1
        seen = abs(s.temperature[k1 - 4:k1, c.taxel].mean() - c.sensor_temperature)
        assert c.peak_change >= seen - 0.05 and (c.peak_change >= 0.1) == (
            c.visible_after < np.inf)
    quiet = simulate_stream([MATS["glass"]], n_taxels=2, duration=60.0,
                            contacts_per_minute=0.0, disturbances=False, seed=1)
    assert quiet.contacts == [] and np.ptp(quiet.temperature) < 0.3  # a steady heated taxel


def test_same_seed_same_stream_and_disturbances_move_the_free_reading():
    a = simulate_stream([MATS["glass"]], n_taxels=2, duration=200.0, contacts_per_minute=0.0,
                        seed=5)
    b = simulate_stream([MATS["glass"]], n_taxels=2, duration=200.0, contacts_per_minute=0.0,
                        seed=5)
    assert np.array_equal(a.temperature, b.temperature)
    assert np.ptp(a.temperature[:, 0]) > 0.5  # heater switching, drift and gusts
    with pytest.raises(ValueError, match="material"):
        simulate_stream([], duration=10.0)


def test_refinement_with_a_finite_contact_is_not_late():
    s = SensorConstants()
    t = np.arange(0, 2.0, 1 / 200)
    rng = np.random.default_rng(0)
    late_perfect, late_rates = [], []
    for _ in range(20):
        t_on = 1.0 + rng.uniform(0, 0.005)
        y = np.where(t < t_on, 36.0, contact_trace(t - t_on, 36.0, 25.0, 13427.0, s, 3000.0))
        y = y + rng.normal(0, 0.01, t.size)
        on_p, _ = refine_onset(t, y, t_on + 0.2, 36.0, 0.0, s.depth, s.diffusivity,
                               rates=(np.inf,))
        on_r, _ = refine_onset(t, y, t_on + 0.2, 36.0, 0.0, s.depth, s.diffusivity)
        late_perfect.append(on_p - t_on)
        late_rates.append(on_r - t_on)
    assert np.median(late_perfect) > 0.03  # eq. 5 alone dates this slow contact late
    # onset and closing rate trade off along a ridge; the fit lands within about 10 ms
    assert abs(np.median(late_rates)) <= 0.012


def test_evaluation_counts_detections_false_alarms_and_delays():
    s = simulate_stream([MATS["aluminium"], MATS["glass"]], n_taxels=4, duration=180.0,
                        contacts_per_minute=2.0, disturbances=False, seed=3)
    truth = [(c.taxel, c.onset, c.release, c.visible_after) for c in s.contacts]
    r = evaluate_onsets(s.times, s.temperature, truth, s.fs)
    assert r["contacts"] == len(truth) and len(r["detected_flags"]) == len(truth)
    # no false fall; the one false rise is the simulator's reheat after a 0.11 s touch the
    # thermistor never saw (the stream restarts the taxel's fast recovery at each release)
    assert r["detection_rate"] > 0.9 and r["false_alarms_by_direction"] == {"fall": 0, "rise": 1}
    assert r["delay_ms"]["median"] >= r["visible_ms"]["median"] - 20  # not before it shows
    assert r["onset_error_ms"]["median"] < 60
    # chunking does not change what is found
    r2 = evaluate_onsets(s.times, s.temperature, truth, s.fs, chunk=7)
    assert r2["detected_flags"] == r["detected_flags"]
    # a taxel with a contact the truth does not know about: a false alarm (judged on the
    # stream up to 2 s after that contact, which the detector has read the same way)
    n = int(np.searchsorted(s.times, truth[0][2] + 2.0))
    fake = [row for row in truth if row[0] != truth[0][0] and row[2] < s.times[n - 1]]
    r3 = evaluate_onsets(s.times[:n], s.temperature[:n], fake, s.fs)
    assert r3["false_alarms"] >= 1


def test_default_streams_are_unchanged_and_warm_objects_make_rises():
    mats = [MATS["aluminium"], MATS["pine"], MATS["human_skin"]]
    s = simulate_stream(mats, n_taxels=3, duration=120.0, contacts_per_minute=3.0, seed=4)
    # the figures of this stream before warm objects existed: same seed, same stream
    assert [(c.taxel, round(c.onset, 4), c.material) for c in s.contacts[:3]] == [
        (1, 20.8257, "pine"), (2, 35.138, "pine"), (1, 35.3368, "aluminium")]
    assert len(s.contacts) == 12 and s.temperature.sum() == pytest.approx(2660737.751, abs=1.0)
    w = simulate_stream(mats, n_taxels=3, duration=120.0, contacts_per_minute=3.0, seed=4,
                        warm=1.0)
    for c in w.contacts:  # every contact warm, but skin keeps its own temperature
        assert (c.direction == 1) == (c.material != "human_skin")
        k0 = round(c.onset * w.fs)
        if c.direction == 1:
            assert 2.0 <= c.object_temperature - c.sensor_temperature <= 25.0
            if c.duration > 1.0:
                assert w.temperature[k0 + 190:k0 + 200, c.taxel].mean() > c.sensor_temperature + 0.2
    with pytest.raises(ValueError, match="warm"):
        simulate_stream(mats, duration=10.0, warm=1.5)


def test_evaluation_by_direction():
    s = simulate_stream([MATS["aluminium"], MATS["glass"], MATS["pine"]], n_taxels=4,
                        duration=180.0, contacts_per_minute=2.0, disturbances=False, seed=5,
                        warm=0.5)
    truth = [(c.taxel, c.onset, c.release, c.visible_after) for c in s.contacts]
    directions = [c.direction for c in s.contacts]
    assert set(directions) == {-1, 1}
    r = evaluate_onsets(s.times, s.temperature, truth, s.fs, directions=directions)
    cool, warm = r["by_direction"]["cool"], r["by_direction"]["warm"]
    assert cool["contacts"] + warm["contacts"] == r["contacts"] == len(truth)
    assert warm["contacts"] == sum(d == 1 for d in directions) >= 5
    assert warm["detection_rate"] > 0.8 and warm["right_direction"] == 1.0
    assert cool["detection_rate"] > 0.8 and cool["right_direction"] == 1.0
    assert warm["onset_error_ms"]["median"] < 60 and warm["delay_ms"]["median"] < 600
    assert r["false_alarms"] <= 1
    with pytest.raises(ValueError, match="directions"):
        evaluate_onsets(s.times, s.temperature, truth, s.fs, directions=directions[1:])


def skin(*args):
    return subprocess.run([sys.executable, "-m", "skin", *args], capture_output=True,
                          text=True, timeout=300)


def test_evaluate_onset_command_on_a_stream_and_on_trials(tmp_path):
    out = skin("evaluate-onset", "--taxels", "2", "--minutes", "1", "--rate", "2", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["contacts"] > 0 and "by_material" in doc and "detected_flags" not in doc
    assert doc["beyond_gusts"]["threshold_k"] == 0.4
    assert 0 <= doc["beyond_gusts"]["detection_rate"] <= 1
    assert doc["detector_us_per_taxel_sample"] > 0
    out = skin("evaluate-onset", "--taxels", "3", "--minutes", "1", "--rate", "3", "--quiet",
               "--warm", "0.6", "--seed", "1")
    assert out.returncode == 0, out.stderr
    assert "warm contacts: detected" in out.stdout and "cool contacts: detected" in out.stdout
    assert "0.6 warm" in out.stdout
    out = skin("evaluate-onset", "--warm", "2")
    assert out.returncode == 2 and "--warm" in out.stderr
    from skin.models.trials import Protocol, simulate_trials

    simulate_trials([MATS["aluminium"], MATS["pine"]], Protocol(trials=6, run_length=3),
                    seed=1).save(tmp_path / "t.npz")
    out = skin("evaluate-onset", "--data", str(tmp_path / "t.npz"), "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["contacts"] == 12 and doc["detection_rate"] > 0.8
    assert doc["common_mode"] is False and "no common mode" in doc["source"]
    # a recording at 20 Hz is judged at its own rate (the paper's sensor, re-rated)
    from skin.formats.dataset import load_trials

    data = load_trials(tmp_path / "t.npz")
    np.savez(tmp_path / "slow.npz", temperature=data.temperature[..., ::10], fs=data.fs / 10,
             label=data.label, onset=data.onset // 10)
    out = skin("evaluate-onset", "--data", str(tmp_path / "slow.npz"), "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert "sensor paper at the recording's 20 Hz" in doc["source"]
    assert doc["contacts"] == 12 and doc["detection_rate"] > 0.8
    # one onset per contact, none released and found again (19 events, 3 false alarms, before
    # the end test and the in-contact trend stayed clear of one sample's noise)
    assert doc["onsets"] == 12 and doc["releases"] == 0 and doc["false_alarms"] == 0
    # the refined onsets' median error here is 31.5 ms. The bound, 35.5 ms, is what this 20 Hz
    # recording got when it was judged by the detector built for 200 Hz (before recordings
    # were judged at their own rate). The median is fragile on 12 trials: while 3 contacts
    # were released and found again it was 19.0 ms, yet the mean of the 12 errors was 42 ms
    # then as now (a refinement window then ended at the spurious release)
    assert doc["onset_error_ms"]["median"] < 35.5
    out = skin("evaluate-onset", "--materials", "unobtainium")
    assert out.returncode == 2 and "unobtainium" in out.stderr


def test_evaluate_onset_refuses_a_common_mode_on_fewer_than_common_min_taxels(tmp_path):
    """A board of fewer than `COMMON_MIN` taxels has no common mode: --common-mode was a
    silent no-op there (the source line still said "common mode"); now refused before the
    stream is simulated (or the detector run over a dataset)."""
    from skin.models.trials import Protocol, simulate_trials
    from skin.stream.onset import COMMON_MIN

    few = str(COMMON_MIN - 1)
    out = skin("evaluate-onset", "--sensor", "low-cost", "--taxels", few, "--common-mode")
    assert out.returncode == 2 and out.stdout == ""
    assert f"at least {COMMON_MIN} taxels" in out.stderr and f"--taxels is {few}" in out.stderr
    assert "simulating" not in out.stderr  # before the work starts
    simulate_trials([MATS["aluminium"]], Protocol(trials=COMMON_MIN - 1, run_length=3),
                    seed=1).save(tmp_path / "few.npz")
    out = skin("evaluate-onset", "--data", str(tmp_path / "few.npz"), "--sensor", "paper",
               "--common-mode")
    assert out.returncode == 2 and f"few.npz has {few} trials" in out.stderr
    # a board of COMMON_MIN taxels has one
    out = skin("evaluate-onset", "--sensor", "low-cost", "--taxels", str(COMMON_MIN),
               "--minutes", "0.5", "--common-mode", "--json")
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["common_mode"] is True


def test_sensor_constants_are_recovered_from_reference_contacts():
    import dataclasses

    from skin.models.sensor_fit import fit_sensor_constants

    base = SensorConstants()
    true = dataclasses.replace(base, diffusivity=base.diffusivity * 1.08,
                               conductivity=base.conductivity * 0.93)
    water = MATS["water"]
    t = np.arange(1, 401) / 200.0
    ts = np.array([31.0, 35.0, 39.0])
    h = np.array([6e4, 1e5, 2e5])
    y = contact_trace(t[None, :], ts[:, None], 25.0, water.effusivity, true, h[:, None])
    y = y + np.random.default_rng(0).normal(0, 0.01, y.shape)
    fit = fit_sensor_constants(t, y, ts, np.full(3, 25.0), water.effusivity,
                               conductance_range=water.conductance_range)
    assert fit.converged and fit.rms < 0.02
    assert fit.sensor.diffusivity == pytest.approx(true.diffusivity, rel=0.01)
    assert fit.sensor.conductivity == pytest.approx(true.conductivity, rel=0.02)
    with pytest.raises(ValueError, match="no heat"):
        fit_sensor_constants(t, y, np.full(3, 25.0), np.full(3, 25.0), water.effusivity)
    with pytest.raises(ValueError, match="n_contacts"):
        fit_sensor_constants(t, y[:2], ts, np.full(3, 25.0), water.effusivity)


def test_bench_calibration_prints_recovery():
    out = skin("bench", "calibration", "--taxels", "2", "--contacts", "2", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    for key in ("diffusivity", "conductivity", "effusivity"):
        assert doc["fitted_error"][key]["median"] < 0.05
    th = doc["thermistors"]
    assert th["fitted_max_error_k"]["median"] < 0.05 < th["nominal_max_error_k"]["median"]


def test_the_evaluation_counts_the_holes_that_kept_the_flat_envelope_margin():
    # a quiet stream at the detector's nominal 200 Hz: no restarts; every tenth sample
    # dropped: each gap is a hole that restarts the envelope margin's settle clock
    s = simulate_stream([MATS["glass"]], n_taxels=2, duration=20.0, contacts_per_minute=0.0,
                        disturbances=False, seed=3)
    whole = evaluate_onsets(s.times, s.temperature, [], s.fs)
    assert whole["settle_restarts"] == 0
    keep = np.arange(s.times.size) % 10 != 9
    holes = evaluate_onsets(s.times[keep], s.temperature[keep], [], s.fs)
    gaps = int(np.sum(np.diff(s.times[keep]) > 1.5 / s.fs))
    assert holes["settle_restarts"] == 2 * gaps > 0

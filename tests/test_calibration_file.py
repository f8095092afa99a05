"""Per-taxel calibration: Steinhart-Hart fits, thermal constants, the file and its use."""

import json
import subprocess
import sys

import numpy as np
import pytest

from skin.formats.calibration_file import CalibrationFileError, load_calibration
from skin.formats.layout import load_layout
from skin.stream.calibration import Calibration, fit_steinhart_hart

C0, C1, C2 = 9.5594e-4, 2.6181e-4, 1.2e-7


def skin(*args):
    return subprocess.run([sys.executable, "-m", "skin", *args], capture_output=True,
                          text=True, timeout=300)


def test_steinhart_hart_fits_recover_both_forms():
    temps = np.array([15.0, 25.0, 35.0, 45.0])
    t_k = temps + 273.15
    ln_r2 = (1 / t_k - C0) / C1
    assert np.allclose(fit_steinhart_hart(np.exp(ln_r2), temps, 2), [C0, C1, 0.0], rtol=1e-9)
    # the full form: solve 1/T = C0 + C1 x + C2 x^3 for x by Newton
    x = ln_r2.copy()
    for _ in range(30):
        x -= (C0 + C1 * x + C2 * x**3 - 1 / t_k) / (C1 + 3 * C2 * x**2)
    assert np.allclose(fit_steinhart_hart(np.exp(x), temps, 3), [C0, C1, C2], rtol=1e-6)
    with pytest.raises(ValueError, match="3 distinct reference"):
        fit_steinhart_hart(np.exp(x[:2]), temps[:2], 3)
    with pytest.raises(ValueError, match="positive"):
        fit_steinhart_hart(np.array([1.0, -1.0]), temps[:2], 2)


def test_three_term_calibration_round_trips_counts_and_temperature():
    one = np.ones(3)
    cal = Calibration(c0=C0 * one, c1=C1 * one, c2=C2 * one, divider_resistor=668.0 * one,
                      supply_voltage=5.06 * one, adc_reference=1.1 * one, adc_max=1023.0 * one)
    temps = np.array([[20.0, 30.0, 40.0]])
    back, status = cal.temperature(cal.counts(temps))
    assert np.allclose(back, temps, atol=1e-9) and not status.any()


def _reference_csv(path, layout, rng, coef, noise=0.3):
    """What a calibration run at 20, 30 and 40 C reads from each of the first 10 taxels."""
    b = next(iter(layout.boards.values()))
    lines = ["taxel,reference_c,counts"]
    for tid in layout.ids[:10]:
        one = np.ones(1)
        cal = Calibration(c0=coef[tid][0] * one, c1=coef[tid][1] * one,
                          divider_resistor=b.divider_resistor * one,
                          supply_voltage=b.supply_voltage * one,
                          adc_reference=b.adc_reference * one, adc_max=(2**b.adc_bits - 1) * one)
        for ref in (20.0, 30.0, 40.0):
            for _ in range(4):
                counts = float(cal.counts(np.array([ref]))[0] + rng.normal(0, noise))
                lines.append(f"{int(tid)},{ref},{counts:.3f}")
    path.write_text("\n".join(lines) + "\n")


def test_calibrate_thermistors_then_show_then_apply(tmp_path):
    layout = load_layout("arm")
    rng = np.random.default_rng(0)
    coef = {int(t): (C0 * (1 + rng.uniform(-0.01, 0.01)), C1 * (1 + rng.uniform(-0.01, 0.01)))
            for t in layout.ids}
    _reference_csv(tmp_path / "refs.csv", layout, rng, coef)
    out = skin("calibrate", "thermistors", "--data", str(tmp_path / "refs.csv"),
               "-o", str(tmp_path / "cal.json"))
    assert out.returncode == 0, out.stderr
    assert "62 of the layout's 72 taxels without" in out.stdout
    cal_file = load_calibration(tmp_path / "cal.json")
    assert set(cal_file.taxels) == {int(t) for t in layout.ids[:10]}
    assert "20, 30, 40 C" in cal_file.references["thermistor"] and cal_file.created
    cal, sensors = cal_file.apply(layout)
    assert len(sensors) == len(layout)
    # the fitted thermistors read a 35 C skin far closer than the nominal constants do
    b = next(iter(layout.boards.values()))
    errors = {"fitted": [], "nominal": []}
    nominal = Calibration.from_layout(layout)
    for i, tid in enumerate(layout.ids[:10]):
        one = np.ones(1)
        true = Calibration(c0=coef[int(tid)][0] * one, c1=coef[int(tid)][1] * one,
                           divider_resistor=b.divider_resistor * one,
                           supply_voltage=b.supply_voltage * one,
                           adc_reference=b.adc_reference * one,
                           adc_max=(2**b.adc_bits - 1) * one)
        counts = np.full(len(layout), float(true.counts(np.array([35.0]))[0]))
        errors["fitted"].append(abs(cal.temperature(counts)[0][i] - 35.0))
        errors["nominal"].append(abs(nominal.temperature(counts)[0][i] - 35.0))
    assert np.median(errors["fitted"]) < 0.1 < np.median(errors["nominal"])
    out = skin("calibrate", "show", str(tmp_path / "cal.json"), "--json")
    doc = json.loads(out.stdout)
    assert len(doc["missing_thermistor"]) == 62 and len(doc["missing_thermal"]) == 72


def test_bad_reference_rows_are_named(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("taxel,reference_c,counts\n0,20,500\n1,twenty,500\n")
    out = skin("calibrate", "thermistors", "--data", str(bad), "-o", str(tmp_path / "c.json"))
    assert out.returncode == 2 and "bad.csv, line 3" in out.stderr
    one_ref = tmp_path / "one.csv"
    one_ref.write_text("taxel,reference_c,counts\n0,20,500\n0,20,501\n")
    out = skin("calibrate", "thermistors", "--data", str(one_ref), "-o", str(tmp_path / "c.json"))
    assert out.returncode == 2 and "taxel 0" in out.stderr and "distinct" in out.stderr
    stranger = tmp_path / "x.csv"
    stranger.write_text("taxel,reference_c,counts\n999,20,500\n999,30,600\n")
    out = skin("calibrate", "thermistors", "--data", str(stranger), "-o", str(tmp_path / "c.json"))
    assert out.returncode == 2 and "taxel 999" in out.stderr


def test_broken_calibration_files_are_named(tmp_path):
    p = tmp_path / "c.json"
    p.write_text('{"format": 1,\n "taxels": {"3": {"thermistor": [1, -2, 0]}}}')
    with pytest.raises(CalibrationFileError, match="taxel 3: 'thermistor'"):
        load_calibration(p)
    p.write_text('{"format": 1,\n "taxels": {\n')
    with pytest.raises(CalibrationFileError, match="line 3"):
        load_calibration(p)
    p.write_text('{"format": 7}')
    with pytest.raises(CalibrationFileError, match="format 7"):
        load_calibration(p)
    with pytest.raises(CalibrationFileError, match="no such"):
        load_calibration(tmp_path / "none.json")


def test_calibrate_thermal_from_water_contacts_then_run_with_it(tmp_path):
    from skin.models import load_materials
    from skin.models.trials import Protocol, simulate_trials

    water = simulate_trials([load_materials()["water"]],
                            Protocol(trials=16, run_length=2, n_taxels=4), seed=3)
    water.save(tmp_path / "water.npz")
    out = skin("calibrate", "thermal", "--data", str(tmp_path / "water.npz"),
               "-o", str(tmp_path / "cal.json"))
    assert out.returncode == 0, out.stderr
    cal_file = load_calibration(tmp_path / "cal.json")
    fitted = {k: v for k, v in cal_file.taxels.items() if "diffusivity" in v}
    assert set(fitted) == set(np.unique(water.taxel).tolist())
    for tid, entry in fitted.items():
        rows = water.taxel[:, 0] == tid
        want = water.extra["true_sensor_diffusivity"][rows][0]
        depth = water.extra["true_sensor_depth"][rows][0]
        # only depth^2 / alpha is seen: compare the fitted time scale with the true one
        assert entry["depth"] ** 2 / entry["diffusivity"] == pytest.approx(depth**2 / want,
                                                                          rel=0.05)
    out = skin("run", "--speed", "0", "--duration", "3", "--calibration",
               str(tmp_path / "cal.json"), "--no-map", "--out", str(tmp_path / "run"), "--json")
    assert out.returncode == 0, out.stderr
    assert "without a thermistor fit" in out.stderr


def test_ambient_offset_is_fitted_from_the_ambient_sensor_at_the_references(tmp_path):
    layout = load_layout("arm")
    rng = np.random.default_rng(1)
    coef = {int(t): (C0, C1) for t in layout.ids}
    _reference_csv(tmp_path / "refs.csv", layout, rng, coef)
    lines = (tmp_path / "refs.csv").read_text().splitlines()
    # the board's LM35 reads 0.4 K low (a reading to 0.1 K, as the paper's sensor gives)
    with_ambient = [lines[0] + ",ambient_c"] + [
        f"{row},{float(row.split(',')[1]) - 0.4 + rng.choice([-0.05, 0.05]):.2f}"
        for row in lines[1:]]
    (tmp_path / "amb.csv").write_text("\n".join(with_ambient) + "\n")
    out = skin("calibrate", "thermistors", "--data", str(tmp_path / "amb.csv"),
               "-o", str(tmp_path / "cal.json"))
    assert out.returncode == 0, out.stderr
    assert "ambient offset +0.3" in out.stdout or "ambient offset +0.4" in out.stdout
    cal_file = load_calibration(tmp_path / "cal.json")
    assert abs(cal_file.ambient_offset - 0.4) < 0.02 and "ambient" in cal_file.references
    bad = [with_ambient[0], with_ambient[1].rsplit(",", 1)[0] + ",warm"]
    (tmp_path / "bad.csv").write_text("\n".join(bad) + "\n")
    out = skin("calibrate", "thermistors", "--data", str(tmp_path / "bad.csv"),
               "-o", str(tmp_path / "bad.json"))
    assert out.returncode == 2 and "bad.csv, line 2" in out.stderr and "ambient_c" in out.stderr


def test_measured_board_constants_are_kept_and_applied(tmp_path):
    layout = load_layout("arm")
    path = tmp_path / "cal.json"
    out = skin("calibrate", "board", "--board", "0", "--divider-resistor", "660",
               "--heater-resistance", "20.5", "-o", str(path))
    assert out.returncode == 0, out.stderr
    out = skin("calibrate", "board", "--board", "0", "--supply-voltage", "5.0", "-o", str(path))
    assert out.returncode == 0, out.stderr
    cal_file = load_calibration(path)
    assert cal_file.boards == {0: {"divider_resistor": 660.0, "heater_resistance": 20.5,
                                   "supply_voltage": 5.0}}
    cal, sensors = cal_file.apply(layout)
    assert np.all(cal.divider_resistor == 660.0) and np.all(cal.supply_voltage == 5.0)
    assert all(s.heater_resistance == 20.5 for s in sensors)
    # the same counts read through the measured divider: a different temperature
    counts = np.full((1, len(layout)), 600.0)
    nominal = Calibration.from_layout(layout).temperature(counts)[0]
    assert np.all(np.abs(cal.temperature(counts)[0] - nominal) > 0.1)
    show = json.loads(skin("calibrate", "show", str(path), "--json").stdout)
    assert show["boards"] == {"0": cal_file.boards[0]}
    for bad, says in ((["--board", "7", "--supply-voltage", "5"], "board 7"),
                      (["--board", "0"], "at least one"),
                      (["--board", "0", "--supply-voltage", "-5"], "positive")):
        out = skin("calibrate", "board", *bad, "-o", str(tmp_path / "x.json"))
        assert out.returncode == 2 and says in out.stderr
    text = path.read_text().replace('"supply_voltage": 5.0', '"supply_voltage": "five"')
    (tmp_path / "broken.json").write_text(text)
    with pytest.raises(CalibrationFileError, match="board 0: 'supply_voltage' must be"):
        load_calibration(tmp_path / "broken.json")

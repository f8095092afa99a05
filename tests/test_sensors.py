"""Sensor descriptions: presets, files, the reading model, and every consumer honouring them."""

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.special import erfc

from skin.cli import main as skin_main
from skin.drivers.sim import SkinSimulator
from skin.errors import LayoutError, SceneError, SensorError
from skin.formats.layout import Board, parse_layout
from skin.formats.scene import load_scene, parse_scene
from skin.models import load_materials
from skin.models.physics import SensorConstants, contact_trace
from skin.models.sensors import (
    SensorDescription,
    apply_dynamics,
    contact_reading,
    heater_term,
    ierfc,
    load_sensor,
    load_sensors,
    parse_sensors,
    smooth,
)
from skin.models.trials import Protocol, simulate_trials

MATS = load_materials()
FOREIGN = ("pid-logger", "fast-film", "low-cost")


def test_the_paper_preset_is_the_paper_sensor_and_the_default_board():
    paper = load_sensor("paper")
    assert paper == SensorDescription()
    assert paper.constants() == SensorConstants()
    assert SensorDescription.from_board(Board()) == paper
    assert load_sensor(None) == paper
    # eq. 2 as the library always computed it: 38.96 C at 25 C
    assert 25.0 + paper.heated_rise == pytest.approx(38.96, abs=0.01)


def test_foreign_presets_differ_from_the_paper_by_factors_2_to_30():
    presets = load_sensors()
    assert set(FOREIGN) <= set(presets)
    paper = presets["paper"]
    heaters = set()
    for name in FOREIGN:
        s = presets[name]
        speed = max(s.response_time / paper.response_time, paper.response_time / s.response_time)
        ratio = s.noise_kelvin() / paper.noise_kelvin()
        noise = max(ratio, 1 / ratio)
        assert 2 <= speed <= 30, (name, speed)
        assert 2 <= noise <= 30, (name, noise)
        assert s.heater != "constant"
        heaters.add(s.heater)
    assert len(heaters) == 3  # each foreign preset drives its heater another way


def test_the_paper_sensor_leaves_every_reading_untouched():
    s = load_sensor("paper")
    t = np.linspace(-0.5, 3, 200)
    assert np.array_equal(contact_reading(t, 38.0, 25.0, 400.0, s, 3000.0),
                          contact_trace(t, 38.0, 25.0, 400.0, SensorConstants(), 3000.0))
    y = np.random.default_rng(0).normal(size=(3, 50))
    assert apply_dynamics(y, s) is y
    assert smooth(y, s) is y


def test_paper_sensor_datasets_are_bit_identical_to_the_default():
    mats = [MATS["pine"], MATS["aluminium"]]
    p = Protocol(trials=6, run_length=3)
    a = simulate_trials(mats, p, seed=4)
    b = simulate_trials(mats, p, seed=4, sensor="paper")
    assert np.array_equal(a.temperature, b.temperature)
    for key in a.extra:
        assert np.array_equal(a.extra[key], b.extra[key])


def test_a_layout_board_naming_the_paper_sensor_simulates_bit_identically(tmp_path):
    scene = load_scene("default")
    arm = _shipped("layouts/arm.toml").read_text()
    (tmp_path / "arm_paper.toml").write_text(
        arm.replace("[[boards]]", '[[boards]]\nsensor = "paper"', 1))
    scene_src = _shipped("scenes/default.toml").read_text().replace(
        'layout = "arm"', 'layout = "arm_paper.toml"')
    other = parse_scene(scene_src, str(tmp_path / "scene.toml"), base=tmp_path)
    assert other.layout.boards[0].sensor == "paper"
    for contact in ("perfect", "finite"):
        a = np.array([f.counts for f in SkinSimulator(scene, 4.0, contact).frames()])
        b = np.array([f.counts for f in SkinSimulator(other, 4.0, contact).frames()])
        assert np.array_equal(a, b)


def _shipped(rel):
    from importlib import resources

    return resources.files("skin") / "data" / rel


def test_user_file_errors_name_the_file_and_line(tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text('[[sensors]]\nname = "a"\n\n[[sensors]]\nname = "b"\ndepth = -1.0\n')
    with pytest.raises(SensorError, match=r"mine.toml:4: sensor #1 \(b\): field 'depth'"):
        load_sensors(f)
    f.write_text('[[sensors]]\nname = "a"\nheater = "sometimes"\n')
    with pytest.raises(SensorError, match=r"mine.toml:1: .*'heater' must be one of"):
        load_sensor(f)
    f.write_text('[[sensors]]\nname = "a"\nsample_rate = 5000.0\n')
    with pytest.raises(SensorError, match=r"mine.toml:1: .*20-1000 Hz"):
        load_sensor(f)
    f.write_text('[[sensors]]\nname = "a"\nsmoothing = "savgol"\nsmoothing_window = 4\n')
    with pytest.raises(SensorError, match="must be odd"):
        load_sensor(f)
    f.write_text('[[sensors]]\nname = "a"\nwibble = 1\n')
    with pytest.raises(SensorError, match="unknown field 'wibble'"):
        load_sensor(f)
    with pytest.raises(SensorError, match="no preset of that name"):
        load_sensor("nonesuch")
    with pytest.raises(SensorError, match="cannot read"):
        load_sensor(tmp_path / "missing.toml")


def test_user_file_by_name_and_effusivity_instead_of_conductivity(tmp_path):
    f = tmp_path / "two.toml"
    f.write_text('[[sensors]]\nname = "a"\neffusivity = 800.0\n\n'
                 '[[sensors]]\nname = "b"\nlag = 0.3\n')
    with pytest.raises(SensorError, match="name one as"):
        load_sensor(f)
    a = load_sensor(f"{f}#a")
    assert a.effusivity == pytest.approx(800.0)
    assert load_sensor(f"{f}#b").lag == 0.3
    with pytest.raises(SensorError, match="not both"):
        parse_sensors('[[sensors]]\nname = "c"\neffusivity = 1.0\nconductivity = 1.0\n')


def test_heater_terms_against_closed_forms_and_extremes():
    s = dataclasses.replace(load_sensor("low-cost"))
    t = np.array([0.0, 1e-9, 0.5, 3.0, 1e7])
    term = heater_term(t, 35.0, 400.0, s)
    assert np.all(np.isfinite(term)) and term[0] == 0.0 and np.all(np.diff(term) >= 0)
    # at the contact plane: 2 F sqrt(t) / (sqrt(pi) (e_s + e_o))
    surf = dataclasses.replace(s, depth=1e-12)
    f = s.heater_power / s.heater_area
    expect = 2 * f * math.sqrt(2.0) / (math.sqrt(math.pi) * (s.effusivity + 400.0))
    assert float(heater_term(2.0, 35.0, 400.0, surf)) == pytest.approx(expect, rel=1e-6)
    assert float(ierfc(0.0)) == pytest.approx(1 / math.sqrt(math.pi))
    assert float(ierfc(np.inf)) == 0.0
    off = load_sensor("fast-film")
    # the heater off: drains from 35 C towards ambient 25 C, never past it
    drain = heater_term(np.array([0.0, 1.0, 1e6]), 35.0, 400.0, off, ambient=25.0)
    assert drain[0] == 0.0 and drain[1] < 0 and drain[2] == pytest.approx(-10.0)
    # a sensor at ambient with the heater off: nothing drains
    assert float(heater_term(1.0, 25.0, 400.0, off, ambient=25.0)) == 0.0
    # eq. 5 itself stays exact under the term for the constant heater
    x = load_sensor("paper")
    assert heater_term(t, 35.0, 400.0, x) == 0.0
    assert float(contact_reading(1.0, 35.0, 25.0, 1e30, x)) == pytest.approx(
        35.0 - 10.0 * erfc(x.depth / (2 * math.sqrt(x.diffusivity))), rel=1e-9)


def test_pid_loop_cancels_a_step_and_lag_delays_it():
    s = dataclasses.replace(load_sensor("paper"), heater="pid", control_time=1.0)
    step = np.r_[np.zeros(10), -np.ones(1000)]
    y = apply_dynamics(step, s, fs=100.0)
    assert y[10] == pytest.approx(-1.0 * math.exp(-0.01), rel=1e-6)
    assert abs(y[-1]) < 1e-3  # the loop has pulled the reading back to the setpoint
    lagged = apply_dynamics(step, dataclasses.replace(load_sensor("paper"), lag=0.5), fs=100.0)
    k63 = int(np.argmax(lagged <= -(1 - math.exp(-1))))
    assert (k63 - 10) / 100.0 == pytest.approx(0.5, abs=0.02)


@pytest.mark.parametrize("name", FOREIGN)
def test_trial_generator_honours_the_sensor(name):
    s = load_sensor(name)
    ds = simulate_trials([MATS["pine"], MATS["aluminium"]], Protocol(trials=4, run_length=2),
                         seed=2, sensor=name)
    assert ds.fs == s.sample_rate
    assert ds.temperature.shape[-1] == round(3.5 * s.sample_rate)
    assert np.all(np.isfinite(ds.temperature))
    assert name in ds.source


def test_trial_depth_response_follows_the_sensor_speed():
    """Pine's reading at 0.25 s has moved further for the fast film than the paper sensor."""
    mats = [MATS["aluminium"]]
    moved = {}
    for name in ("paper", "fast-film"):
        s = load_sensor(name)
        s = dataclasses.replace(s, noise=0.0, adc_noise=0.0, adc_bits=24, smoothing="none",
                                heater="constant")
        ds = simulate_trials(mats, Protocol(trials=2, run_length=2, taxel_spread=0.0,
                                            onset_jitter=0.0), seed=1, sensor=s)
        k0 = int(ds.onset[0])
        k = k0 + round(0.25 * ds.fs)
        moved[name] = (ds.primary[0, k0 - 1] - ds.primary[0, k]) / (
            ds.primary[0, k0 - 1] - ds.primary[0, -1])
    assert moved["fast-film"] > 2 * moved["paper"]


def test_layout_board_and_scene_take_a_sensor(tmp_path):
    text = ('[[boards]]\nid = 0\nsensor = "fast-film"\n\n[[taxels]]\nid = 0\nboard = 0\n'
            'address = 0\nlink = "l"\nposition = [0, 0, 0]\nnormal = [0, 0, 1]\n')
    layout = parse_layout(text, "x.toml")
    b = layout.boards[0]
    assert (b.sample_rate, b.adc_bits, b.sensor_depth) == (1000.0, 12, 2.5e-5)
    assert SensorDescription.from_board(b) == load_sensor("fast-film")
    over = parse_layout(text.replace('sensor = "fast-film"', 'sensor = "fast-film"\n'
                                     'sample_rate = 500.0'), "x.toml")
    assert over.boards[0].sample_rate == 500.0  # the board's own field wins
    with pytest.raises(LayoutError, match=r"x.toml:1: board #0: field 'sensor'.*nonesuch"):
        parse_layout(text.replace("fast-film", "nonesuch"), "x.toml")
    scene = parse_scene('layout = "arm"\nsensor = "pid-logger"\nduration = 2.0\n', "s.toml")
    assert all(b.sensor == "pid-logger" for b in scene.layout.boards.values())
    assert scene.noise is None
    with pytest.raises(SceneError, match=r"s\.toml: field 'sensor'"):
        parse_scene('sensor = "nonesuch"\n', "s.toml")


def _touch_scene(sensor, tmp_path, noise=""):
    src = (f'layout = "arm"\nsensor = "{sensor}"\nduration = 30.0\nseed = 3\n{noise}'
           'initial_temperature = [60.0, 60.0]\n'  # capped at the heated state: settled
           '[[objects]]\nname = "bar"\nmaterial = "aluminium"\n'
           '[[touches]]\nobject = "bar"\ntaxels = [0]\nstart = 10.0\nduration = 15.0\n')
    return parse_scene(src, str(tmp_path / "s.toml"))


@pytest.mark.parametrize("name", ["paper", *FOREIGN])
def test_simulated_skin_honours_the_sensor(name, tmp_path):
    s = load_sensor(name)
    sim = SkinSimulator(_touch_scene(name, tmp_path))
    assert sim.sample_rate == s.sample_rate
    frames = list(sim.frames())
    assert len(frames) == round(30.0 * s.sample_rate)
    temp, status = sim.calibration.temperature(np.array([f.counts for f in frames]))
    assert not status.any()
    quiet = temp[round(2 * s.sample_rate): round(9 * s.sample_rate), 5]
    sigma = float(np.std(np.diff(quiet)) / math.sqrt(2))  # drift-free white noise estimate
    if s.smoothing == "none":
        assert sigma == pytest.approx(s.noise_kelvin(float(np.mean(quiet))), rel=0.25)
    else:  # smoothing removes noise at high frequency
        assert sigma < s.noise_kelvin(float(np.mean(quiet)))
    clean = sim.temperatures()[:, 0]
    k0 = round(10.0 * s.sample_rate)
    drop = clean[k0 - 1] - clean[k0:round(25.0 * s.sample_rate)]
    assert drop.max() > 0.5  # the aluminium bar cools the taxel
    if s.heater == "pid":  # the loop pulls the reading back towards its setpoint
        assert drop[-1] < 0.3 * drop.max()
    step = clean[k0 - 1] - 25.0  # aluminium pulls the surface to the object at once
    early = drop[round(0.25 * s.sample_rate)] / step
    if name == "fast-film":  # 25 um deep: half the step within 0.25 s (erfc(0.47))
        assert early > 0.4
    if name == "paper":  # 80 um deep: 3 % (erfc(1.51))
        assert 0.01 < early < 0.1


def test_scene_noise_replaces_the_sensor_noise(tmp_path):
    sim = SkinSimulator(_touch_scene("low-cost", tmp_path, noise="noise = 0.0\n"))
    assert sim.noise == 0.0
    sim = SkinSimulator(_touch_scene("low-cost", tmp_path))
    assert sim.noise == load_sensor("low-cost").noise


def test_skin_sensors_lists_the_presets(capsys):
    assert skin_main(["sensors", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    names = [s["name"] for s in doc["sensors"]]
    assert names[0] == "paper" and set(FOREIGN) <= set(names)
    assert all(s["response_time"] > 0 and s["noise_kelvin"] > 0 for s in doc["sensors"])
    assert skin_main(["sensors"]) == 0
    assert "pid-logger" in capsys.readouterr().out


def test_skin_simulate_trials_takes_a_sensor(tmp_path, capsys):
    out = tmp_path / "t.npz"
    assert skin_main(["simulate", "trials", "-o", str(out), "--trials", "2",
                      "--materials", "pine", "--sensor", "fast-film", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["fs"] == 1000.0 and doc["sensor"] == "fast-film"
    bad = tmp_path / "bad.toml"
    bad.write_text('[[sensors]]\nname = "x"\nadc_bits = 40\n')
    assert skin_main(["simulate", "trials", "-o", str(tmp_path / "u.npz"), "--trials", "2",
                      "--sensor", str(bad)]) == 2
    assert "bad.toml:1" in capsys.readouterr().err
    assert not (tmp_path / "u.npz").exists()


# -- issue 20 item 19: each simulated taxel has its own constants --------------------------
def test_scene_taxel_spread_is_checked():
    assert parse_scene('layout = "arm"\n', "s.toml").taxel_spread == 0.0
    assert parse_scene('taxel_spread = 0.1\n', "s.toml").taxel_spread == 0.1
    with pytest.raises(SceneError, match=r"s\.toml: field 'taxel_spread' must be within"):
        parse_scene('taxel_spread = 1.5\n', "s.toml")


def test_simulated_taxels_spread_around_their_board_seeded():
    scene = load_scene("spread")
    sim = SkinSimulator(scene, duration=1.0)
    s, nominal = sim.taxel_sensor, sim.sensor
    for field in ("depth", "diffusivity", "conductivity"):
        ratio = np.asarray(getattr(s, field)) / getattr(nominal, field)
        assert ratio.shape == (len(scene.layout),)
        assert np.all(np.abs(ratio - 1) <= 0.10) and ratio.std() > 0.03  # uniform +-10 %
    again = SkinSimulator(scene, duration=1.0).taxel_sensor
    assert np.array_equal(again.depth, s.depth)  # seeded
    other = SkinSimulator(dataclasses.replace(scene, seed=8), duration=1.0).taxel_sensor
    assert not np.array_equal(other.depth, s.depth)
    flat = SkinSimulator(load_scene("default"), duration=1.0)
    assert flat.taxel_sensor is flat.sensor  # no spread: the board's sensor, as before
    # the truth as a calibration file: what `skin run --calibration` applies
    _, sensors = sim.true_calibration().apply(scene.layout)
    assert [x.depth for x in sensors] == pytest.approx(list(s.depth), rel=1e-12)


def test_spread_taxels_read_the_same_touch_differently():
    src = ('layout = "arm"\nduration = 8.0\nnoise = 0.0\ntaxel_spread = 0.1\nseed = 2\n'
           'initial_temperature = [60.0, 60.0]\n'
           '[[objects]]\nname = "bar"\nmaterial = "aluminium"\n'
           '[[touches]]\nobject = "bar"\ntaxels = [0, 1]\nstart = 2.0\nduration = 5.0\n')
    spread = SkinSimulator(parse_scene(src, "s.toml")).temperatures()
    flat = SkinSimulator(parse_scene(src.replace("0.1", "0.0"), "s.toml")).temperatures()
    assert np.array_equal(flat[:, 0], flat[:, 1])
    assert np.abs(spread[:, 0] - spread[:, 1]).max() > 0.1
    assert np.all(np.isfinite(spread))


def test_calibration_measurably_helps_the_spread_demo():
    """The shipped `spread` scene: the true per-taxel constants win back labels."""
    from skin.bench.spread import play

    scene = load_scene("spread")
    plain, calibrated = play(scene, calibrated=False), play(scene, calibrated=True)
    assert plain["detected"] == calibrated["detected"] == len(scene.touches)
    assert calibrated["correct"] >= plain["correct"] + 2, (plain, calibrated)


def test_skin_simulate_calibration_writes_the_truth(tmp_path, capsys):
    from skin.formats.calibration_file import load_calibration

    out = tmp_path / "truth.json"
    assert skin_main(["simulate", "calibration", "--scene", "spread", "-o", str(out)]) == 0
    cal = load_calibration(out)
    assert len(cal.taxels) == 72 and "simulation truth" in cal.references["thermal"]


def test_a_layout_names_a_sensor_file_beside_it(tmp_path):
    from skin.formats.layout import load_layout

    (tmp_path / "mine.toml").write_text('[[sensors]]\nname = "mine"\ndepth = 1e-4\n'
                                        'sample_rate = 100.0\nlag = 0.2\n')
    (tmp_path / "skin.toml").write_text(
        '[[boards]]\nid = 0\nsensor = "mine.toml"\n\n[[taxels]]\nid = 0\nboard = 0\n'
        'address = 0\nlink = "l"\nposition = [0, 0, 0]\nnormal = [0, 0, 1]\n')
    board = load_layout(tmp_path / "skin.toml").boards[0]
    assert (board.sensor_depth, board.sample_rate) == (1e-4, 100.0)
    s = SensorDescription.from_board(board)
    assert s.name == "mine" and s.lag == 0.2
    (tmp_path / "mine.toml").write_text('[[sensors]]\nname = "mine"\nlag = -1.0\n')
    with pytest.raises(LayoutError, match=r"skin.toml:1: board #0: field 'sensor': .*mine.toml:1"):
        load_layout(tmp_path / "skin.toml")


def test_skin_run_says_before_the_first_frame_when_a_scene_s_adc_does_not_fit_the_link(
        tmp_path, capsys):
    """A 16-bit logger (pid-logger) cannot be served over protocol v1's 12-bit words: said at
    once (the board's thread failed and the run ended with "no frame arrived"); in-process,
    through sim://, the same scene runs."""
    from skin.cli import main

    scene = tmp_path / "pl.toml"
    scene.write_text('layout = "arm"\nsensor = "pid-logger"\nduration = 3.0\n')
    assert main(["run", "--scene", str(scene), "--speed", "0", "--no-map", "--out",
                 str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "board 0's ADC has 16 bits (sensor pid-logger)" in err and "sim://" in err
    assert not (tmp_path / "a" / "events.jsonl").exists()
    assert main(["run", "--port", f"sim://{scene}?speed=0", "--no-map", "--json", "--out",
                 str(tmp_path / "b")]) == 0
    assert json.loads(capsys.readouterr().out)["frames"] == 150  # 3 s at 50 Hz

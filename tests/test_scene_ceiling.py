"""`skin bench scene --ceiling`: what the scene's touches allow, and the run's gap to it."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from skin.bench.ceiling import known_nuisance_ceiling
from skin.bench.scene_ceiling import NOISE_STEPS, STEPS, touch_ceiling, touch_trial, touch_truth
from skin.errors import SkinError
from skin.formats.scene import load_scene, parse_scene
from skin.models.materials import load_materials

CANDIDATES = {m.name: m.effusivity for m in load_materials().values() if m.classify}


def test_a_noise_free_touch_is_named_right_by_the_ceiling():
    """On the simulation's own noise-free readings the closed form is exact: certain."""
    from skin.drivers.sim import SkinSimulator

    scene = load_scene("default")
    truths = touch_truth(scene)
    assert len(truths) == len(scene.touches)
    clean = SkinSimulator(scene).temperatures()
    fs = next(iter(scene.layout.boards.values())).sample_rate
    for t in truths:
        assert np.allclose(clean[t["k0"], t["rows"]], t["t0"])
        assert touch_ceiling(t, clean, fs, scene.ambient, 2.5, CANDIDATES) == t["material"]
    # the same touch read with a gross error in one taxel's start is no longer certain
    t = next(t for t in truths if t["material"] == "pine" and len(t["taxels"]) == 1)
    wrong = dict(t, t0=t["t0"] - 1.5)  # told a start 1.5 K colder than it was
    assert touch_ceiling(wrong, clean, fs, scene.ambient, 2.5, CANDIDATES) != "pine"


def test_a_touch_is_a_one_trial_dataset_of_its_taxels():
    scene = load_scene("default")
    truths = touch_truth(scene)
    fs = next(iter(scene.layout.boards.values())).sample_rate
    readings = np.zeros((round(scene.duration * fs) + 1, len(scene.layout)))
    t = next(t for t in truths if len(t["taxels"]) == 3)
    trial = touch_trial(t, readings, fs, scene.ambient, 0.5)
    assert trial.temperature.shape == (1, 3, round(0.5 * fs))  # capped at the window
    assert trial.taxel.tolist() == [t["taxels"]]
    assert trial.extra["true_channel_sensor_temperature"].tolist() == [t["t0"].tolist()]
    with pytest.raises(SkinError, match="not among the candidates"):
        known_nuisance_ceiling(trial, 0.5, candidates={"steel": 1.0})


def test_a_sensor_that_does_not_read_the_closed_form_has_no_ceiling():
    text = """
name = "pid"
layout = "arm"
sensor = "pid-logger"
duration = 3.0
[[objects]]
name = "bar"
material = "aluminium"
[[touches]]
object = "bar"
taxels = [0]
start = 1.0
duration = 1.0
"""
    with pytest.raises(SkinError, match="no ceiling"):
        touch_truth(parse_scene(text, source="pid.toml"))
    with pytest.raises(SkinError, match="finite contact has no ceiling"):
        touch_truth(parse_scene(text.replace("pid-logger", "paper"), source="finite.toml"),
                    contact="finite")
    # a scene whose touches meet the skin through their gaps: its contact is the default one
    finite = text.replace("pid-logger", "paper").replace(
        "duration = 3.0", 'duration = 3.0\ncontact = "finite"', 1)
    with pytest.raises(SkinError, match="finite contact has no ceiling"):
        touch_truth(parse_scene(finite, source="finite.toml"))
    assert touch_truth(parse_scene(finite, source="finite.toml"), contact="perfect")


def test_bench_scene_ceiling_is_never_below_the_run():
    proc = subprocess.run([sys.executable, "-m", "skin", "bench", "scene", "--seeds", "0,1",
                           "--ceiling", "--json"], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    for r in out["runs"]:
        assert list(r["steps"]) == list(STEPS + NOISE_STEPS)
        # the run replayed through a fresh copy of its classifier names what the run named
        assert r["steps"]["run"]["label"] == r["material"]
        assert r["steps"]["run"]["family"] == r["family"]
        # the ceiling's least over seeds 0-29 is 13 of 15 (its only misses: a 0.3 s glass
        # touch read as porcelain, aluminium as steel, effusivities 4-9 % apart)
        assert r["ceiling_family"] >= r["ceiling"] >= r["touches"] - 2
        assert r["touches"] - r["ceiling"] == len(r["ceiling_misses"])
        # every matched touch's taxel windows are dated; the released ones' ends within
        # a few samples of the truth (`skin.stream.release_refine`), most of them
        ends = [d["end"] for d in r["dating"] if d["end"] is not None]
        assert len(r["dating"]) >= r["touches"] and len(ends) >= r["touches"] // 2
        assert np.median(np.abs(ends)) <= 25.0
    t = out["totals"]
    # not a strict bound (the ADC's steps: module docstring): on seeds 0 and 1 the run's most
    # probable answers are all right, the ceiling's least-squares choice misses one
    assert t["steps"]["run"]["best"] >= t["material"] and t["ceiling"] >= t["material"]
    assert t["ceiling"] >= t["runs"] * (t["touches"] // t["runs"] - 1)
    assert t["ceiling_per_run"]["mean"] == round(t["ceiling"] / t["runs"], 2)
    assert abs(t["dating"]["all"]["end"]["median"]) <= 25.0
    assert t["dating"]["short"]["end"]["n"] <= t["dating"]["all"]["end"]["n"]

"""`skin bench fit-calibration`: the joint classifier's temperature by the least log-loss."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from skin.bench.calibration_fit import collect, collect_scenes, fit, score, temper
from skin.models.joint import CALIBRATION_FILE, EvidenceTemperature


@pytest.fixture(scope="module")
def answers():
    return collect("default", [7])


def test_tempering_a_dict_of_probabilities():
    q = temper({"a": 0.6, "b": 0.3, "c": 0.1, "d": 0.0}, 0.5)
    p = np.array([0.36, 0.09, 0.01, 0.0]) / 0.46
    assert np.allclose([q[k] for k in "abcd"], p)
    assert temper({}, 0.5) == {}
    # the same as tempering the log evidence (`EvidenceTemperature.probabilities`)
    log_ev = np.log([0.6, 0.3, 0.1])
    assert np.allclose(list(temper(dict(zip("abc", [0.6, 0.3, 0.1], strict=True)), 0.3)
                            .values()), EvidenceTemperature(0.3).probabilities(log_ev))


def test_the_fit_is_deterministic_and_picks_the_least_log_loss(answers):
    assert len(answers["runs"]) == 1 and len(answers["runs"][0]) >= 10
    temperatures = (1.0, 0.3, 0.02)
    a, b = fit(answers, temperatures), fit(answers, temperatures)
    assert a == b
    losses = {r["temperature"]: r["material"]["log_loss"] for r in a["table"]}
    assert a["least_log_loss"] in temperatures
    assert losses[a["least_log_loss"]] == min(losses.values())
    sure = [r for r in a["table"] if r["sure_wrong"] == 0]  # 1.0 makes none on seed 7
    assert sure and losses[a["best"]] == min(r["material"]["log_loss"] for r in sure)
    one = score(answers, 1.0)  # untempered: the classifier's own answers
    assert a["table"][0] == one
    assert one["material"]["n"] == sum(t is not None for t, _ in answers["runs"][0])
    # a sharper temperature leaves no more touches "unknown" (the top probability only grows)
    assert score(answers, 0.3)["unknown"] <= one["unknown"]
    with pytest.raises(ValueError, match="at least one"):
        fit(answers, ())


def test_fit_calibration_command_prints_json_and_leaves_the_stored_fit_alone():
    before = CALIBRATION_FILE.read_text()
    proc = subprocess.run([sys.executable, "-m", "skin", "bench", "fit-calibration",
                           "--scene", "default", "--seeds", "7", "--json"],
                          capture_output=True, text=True, timeout=300,
                          env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["written"] is None and CALIBRATION_FILE.read_text() == before
    assert out["scenes"] == ["default"]
    assert out["best"] in [r["temperature"] for r in out["table"]]
    assert out["table"][0]["temperature"] == 1.0


def test_the_fit_keeps_out_of_confident_mistakes_that_the_least_log_loss_would_make():
    """Nine answers right at 0.6 and one wrong at 0.7: sharper pays, until the wrong one is
    sure; the fit stops before it, the least log-loss does not."""
    from skin.models.materials import load_materials

    table = load_materials()
    right = ("glass", {"glass": 0.6, "porcelain": 0.4})
    wrong = ("porcelain", {"glass": 0.7, "porcelain": 0.3})
    answers = {"runs": [[right] * 9 + [wrong]], "classes": ["glass", "porcelain"],
               "family": {m: table[m].family for m in ("glass", "porcelain")},
               "threshold": 0.5, "table": table}
    out = fit(answers, (1.0, 0.5, 0.25))
    rows = {r["temperature"]: r for r in out["table"]}
    assert rows[0.25]["sure_wrong"] == 1 and rows[0.5]["sure_wrong"] == 0
    assert out["least_log_loss"] == 0.25 and out["best"] == 0.5
    assert rows[0.5]["material"]["log_loss"] < rows[1.0]["material"]["log_loss"]


def test_one_confident_mistake_among_many_runs_still_binds_the_fit():
    """The constraint counts mistakes, not a rounded mean per run (1 in 201 runs is 0.005)."""
    from skin.models.materials import load_materials

    table = load_materials()
    right = ("glass", {"glass": 0.6, "porcelain": 0.4})
    wrong = ("porcelain", {"glass": 0.7, "porcelain": 0.3})
    runs = [[right] * 9 for _ in range(200)] + [[right] * 9 + [wrong]]
    answers = {"runs": runs, "classes": ["glass", "porcelain"],
               "family": {m: table[m].family for m in ("glass", "porcelain")},
               "threshold": 0.5, "table": table}
    out = fit(answers, (1.0, 0.5, 0.25))
    rows = {r["temperature"]: r for r in out["table"]}
    assert rows[0.25]["sure_wrong_count"] == 1 and rows[0.25]["sure_wrong"] == 0.0
    assert out["best"] == 0.5


def test_scenes_pool_into_one_fit(answers):
    pooled = collect_scenes(["default", "default"], [7])
    assert pooled["runs"] == answers["runs"] * 2
    assert pooled["classes"] == answers["classes"]
    with pytest.raises(ValueError, match="at least one scene"):
        collect_scenes([], [7])


def test_the_cold_warm_scene_is_the_generated_one():
    """The shipped cold-warm scene is what its header says generates it."""
    from pathlib import Path

    import skin
    from skin.bench.calibration_fit import FIT_SCENES
    from skin.bench.object_prior import random_scene_text

    text = (Path(skin.__file__).parent / "data" / "scenes" / "cold-warm.toml").read_text()
    body = "\n".join(line for line in text.splitlines() if not line.startswith("#")) + "\n"
    want = random_scene_text(touches=40, single=0.4, off=0.3, offset=8.0, seed=100)
    assert body == want.replace('name = "object-prior"', 'name = "cold-warm"')
    assert "cold-warm" in FIT_SCENES and "temperature = 17.0" in body

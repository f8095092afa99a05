"""`skin.Skin` and `skin.Setup`: one setup that the command line and Python share."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from skin import Setup, Skin, SkinError
from skin.setup import _CHECKS, SetupError, setup_fields

SKIN = Path(sys.executable).with_name("skin")


def skin(*args, cwd=None, timeout=300):
    return subprocess.run([str(SKIN), *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


def test_every_setup_field_has_a_check_and_values_are_checked():
    assert set(setup_fields()) == set(_CHECKS)
    s = Setup().updated({"window": 1, "port": "sim://default", "provisional": "0.5,1"}, "here")
    assert s.window == 1.0 and s.port == ["sim://default"] and s.provisional == [0.5, 1.0]
    assert s.where("window") == "here" and s.where("speed") == "default"
    with pytest.raises(SetupError, match="here: window: must be a number"):
        Setup().updated({"window": "long"}, "here")
    with pytest.raises(SetupError, match="unknown setting 'windw'"):
        Setup().updated({"windw": 1.0}, "here")


def test_skin_in_python_gives_the_results_of_skin_run(tmp_path):
    proc = skin("run", "--speed", "0", "--duration", "4", "--no-map", "--out", tmp_path / "cli",
                "--json")
    assert proc.returncode == 0, proc.stderr
    cli = [json.loads(line) for line in (tmp_path / "cli" / "events.jsonl").read_text()
           .splitlines()]
    with Skin(speed=0, duration=4, out=None, sinks=[]) as s:
        labels = [(r.contact.id, r.estimate.label) for r in s.results() if r.contact.final]
    assert labels and labels == [(e["contact"], e["label"]) for e in cli if e["final"]]


def test_an_output_folder_is_not_overwritten_without_force(tmp_path):
    out = tmp_path / "run"
    first = skin("run", "--speed", "0", "--duration", "1", "--no-map", "--out", out, "--json")
    assert first.returncode == 0, first.stderr
    again = skin("run", "--speed", "0", "--duration", "1", "--no-map", "--out", out)
    assert again.returncode == 2 and "--force" in again.stderr and "earlier run" in again.stderr
    forced = skin("run", "--speed", "0", "--duration", "1", "--no-map", "--out", out, "--force",
                  "--json")
    assert forced.returncode == 0, forced.stderr


def test_checks_come_before_any_source_is_opened(tmp_path):
    s = Skin(port=["serial:///dev/does-not-exist"], calibration=tmp_path / "none.json",
             out=None)
    with pytest.raises(SkinError, match=r"none\.json"):
        s.check()
    assert s._driver is None

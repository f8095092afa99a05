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


def test_every_setup_field_has_a_check_and_a_table_of_the_skin_file():
    from skin.setup import GROUPS

    assert set(setup_fields()) == set(_CHECKS), "add the field's check to skin.setup._CHECKS"
    tabled = [name for names in GROUPS.values() for name in names]
    assert sorted(tabled) == sorted(setup_fields()), \
        "put each Setup field in one table of skin.setup.GROUPS ([source], [output]...)"


def test_setup_values_are_checked():
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
    (out / "contact_map.png").write_bytes(b"an earlier map")
    forced = skin("run", "--speed", "0", "--duration", "1", "--no-map", "--out", out, "--force",
                  "--json")
    assert forced.returncode == 0, forced.stderr
    assert not (out / "contact_map.png").exists()  # no stale output of the earlier run


def test_checks_come_before_any_source_is_opened(tmp_path):
    s = Skin(port=["serial:///dev/does-not-exist"], calibration=tmp_path / "none.json",
             out=None)
    with pytest.raises(SkinError, match=r"none\.json"):
        s.check()
    assert s._driver is None


# --- skin files --------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    """A folder with a recording (run.mcap), a calibration (cal.json) and a model (model.skops)."""
    from skin.formats.calibration_file import CalibrationFile
    from skin.models import load_materials
    from skin.models.trials import Protocol, simulate_trials

    folder = tmp_path_factory.mktemp("assets")
    proc = skin("run", "--speed", "0", "--duration", "6", "--no-map", "--json", "--out",
                folder / "recorded", "--record", folder / "run.mcap")
    assert proc.returncode == 0, proc.stderr
    # a thermistor fit for a few taxels, 1 % off the board's constants
    CalibrationFile(taxels={t: {"thermistor": [9.5594e-4 * 1.01, 2.6181e-4, 0.0]}
                            for t in range(8)}).save(folder / "cal.json")
    mats = load_materials()
    simulate_trials([mats[m] for m in ("aluminium", "pine", "glass", "neoprene", "human_skin")],
                    Protocol(trials=30), seed=8).save(folder / "t.npz")
    proc = skin("train", "--data", folder / "t.npz", "--method", "svm-pca", "--duration", "0.3",
                "-o", folder / "model.skops")
    assert proc.returncode == 0, proc.stderr
    return folder


def lines(path):
    return [json.loads(line) for line in Path(path).read_text().splitlines()]


SKIN_TOML = """\
# a replayed recording, a calibration, a model and two sinks (paths relative to this file)
[source]
port = "replay://../run.mcap?speed=0"

[skin]
calibration = "../cal.json"

[classifier]
model = "../model.skops"
expect = ["pine"]

[output]
out = "../from_file"
sinks = ["events", "../contacts.jsonl"]
map = false
"""


def test_a_skin_file_gives_the_events_of_the_same_options(assets):
    proc = skin("run", "--port", "replay://run.mcap?speed=0", "--calibration", "cal.json",
                "--model", "model.skops", "--expect", "pine", "--sink", "events", "--sink",
                "options.jsonl", "--out", "from_options", "--no-map", "--json", cwd=assets)
    assert proc.returncode == 0, proc.stderr
    by_options = lines(assets / "from_options" / "events.jsonl")
    assert len(by_options) >= 4 and {e["method"] for e in by_options} == {"learned:svm-pca"}
    assert lines(assets / "options.jsonl") == by_options
    # the skin file in another folder: its relative paths are relative to it
    (assets / "cfg").mkdir()
    (assets / "cfg" / "skin.toml").write_text(SKIN_TOML)
    proc = skin("run", "--json", cwd=assets / "cfg")  # ./skin.toml, no options
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["frames"] == 1200
    assert lines(assets / "from_file" / "events.jsonl") == by_options
    assert lines(assets / "contacts.jsonl") == by_options
    with Skin.from_file(assets / "cfg" / "skin.toml", out=None, sinks=[]) as s:
        got = [(r.contact.id, r.estimate.label) for r in s.results()]
    assert got == [(e["contact"], e["label"]) for e in by_options]
    # an option overrides the file; config show says where each value came from
    proc = skin("config", "show", "--json", "--window", "2", cwd=assets / "cfg")
    shown = json.loads(proc.stdout)
    assert shown["window"] == {"value": 2.0, "from": "command line"}
    assert shown["model"] == {"value": str(assets / "model.skops"), "from": "skin.toml:9"}
    assert shown["speed"]["from"] == "default"
    assert shown["port"]["value"] == [f"replay://{assets}/run.mcap?speed=0"]
    text = skin("config", "show", cwd=assets / "cfg").stdout
    assert 'sinks = ["events", ' in text and "# skin.toml:14" in text


def test_config_show_prints_a_skin_file_that_reads_back():
    from skin.commands.config import setup_text
    from skin.formats.skin_file import parse_skin_file

    setup = Setup().updated({"port": ["sim://default"], "provisional": [0.5, 1.0],
                             "layout": "arm", "map": False}, "command line")
    text = setup_text(setup)
    again = parse_skin_file(text, "shown.toml")
    assert again.as_dict() == setup.as_dict()
    # an unset value says what it means: the scene's contact, not "none"
    assert "# contact = (the scene's)" in text and "# calibration = (none)" in text
    assert "# contact = (none)" not in text
    assert again.where("map").startswith("shown.toml:")


@pytest.mark.parametrize(("text", "message"), [
    ("[source]\nport = 3\n", "bad.toml:2: port: must be a list of strings"),
    ("[source]\nspeed = 1\n\n[output]\nwindow = 2\n", "bad.toml:5: unknown field 'window' in "
     "[output]: it belongs in [classifier]"),
    ("[sources]\nport = 'sim://default'\n", "bad.toml:1: unknown table [sources]"),
    ("window = 2\n", "bad.toml:1: unknown table [window]"),
    ("[classifier]\nprovisional = [\n  0.5,\n  -1,\n]\nwindow = 'x'\n",
     "bad.toml:2: provisional: must be more than 0"),
    ("[source\n", "bad.toml: not valid TOML"),
    ("[skin]\ncommon_mode = \"yes\"\n", "bad.toml:2: common_mode: must be true, false or "
     "\"auto\", got 'yes'"),
])
def test_skin_file_errors_name_the_file_and_line(tmp_path, text, message):
    from skin.formats.skin_file import load_skin_file

    (tmp_path / "bad.toml").write_text(text)
    with pytest.raises(SetupError) as err:
        load_skin_file(tmp_path / "bad.toml")
    assert message in str(err.value).replace(str(tmp_path) + "/", "")


def test_the_readme_python_example_runs(assets):
    import re

    readme = (Path(__file__).parents[1] / "README.md").read_text()
    example = next(block for block in re.findall(r"```python\n(.*?)```", readme, re.S)
                   if "Skin(" in block)
    assert len(example.strip().splitlines()) <= 10
    proc = subprocess.run([sys.executable, "-c", example], cwd=assets, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    printed = proc.stdout.splitlines()
    events = lines(assets / "out" / "py" / "events.jsonl")
    assert len(printed) == len(events) >= 4
    assert lines(assets / "contacts.jsonl") == events


# --- every input is checked before the first frame ---------------------------------------------

def failed_early(tmp_path, *args, message, timeout=60):
    """Run ``skin run`` on the simulated skin: it must fail with ``message`` before any frame."""
    out = tmp_path / "run"
    proc = skin("run", "--speed", "0", "--duration", "2", "--out", out, *args, timeout=timeout)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr, proc.stderr
    assert "frames" not in proc.stderr  # no status line: no frame was read
    assert not out.exists()  # nothing made, nothing overwritten
    return proc.stderr


def test_a_missing_arm_file_fails_before_the_first_frame(tmp_path):
    failed_early(tmp_path, "--arm", tmp_path / "arm.toml", "--no-map", "--video",
                 tmp_path / "v.gif", message="arm.toml: no such arm file")
    failed_early(tmp_path, "--arm", tmp_path / "arm.toml", message="no such arm file")


def test_a_layout_link_without_a_mesh_fails_before_the_first_frame(tmp_path):
    from skin.formats.datafiles import read_data_file

    text, _, _ = read_data_file("arm", "layouts", "layout", SkinError)
    (tmp_path / "tail.toml").write_text(text.replace('link = "upper_arm"', 'link = "tail"', 1))
    failed_early(tmp_path, "--layout", tmp_path / "tail.toml",
                 message="link 'tail' has no geometry")
    # without a view or a map, no arm is needed
    proc = skin("run", "--speed", "0", "--duration", "1", "--out", tmp_path / "ok", "--no-map",
                "--layout", tmp_path / "tail.toml", "--json")
    assert proc.returncode == 0, proc.stderr


def test_a_model_missing_a_class_fails_before_the_first_frame(assets, tmp_path):
    scene = tmp_path / "steel.toml"
    scene.write_text('layout = "arm"\nduration = 3.0\n[[objects]]\nname = "vice"\n'
                     'material = "steel"\n[[touches]]\nobject = "vice"\ntaxels = [0, 1]\n'
                     'start = 1.0\nduration = 1.0\n')
    err = failed_early(tmp_path, "--scene", scene, "--model", assets / "model.skops",
                       message="has no class 'steel', which the scene needs")
    assert "model.skops" in err and "aluminium" in err
    failed_early(tmp_path, "--model", assets / "model.skops", "--expect", "water",
                 message="has no class 'water', which the setup's 'expect' needs")


def test_a_port_that_sends_nothing_fails_and_says_so(tmp_path):
    # issue 20.14: it ran 20 s and exited 0 with "0 frames"
    proc = skin("run", "--port", "serial+loop://", "--out", tmp_path / "run", "--no-map",
                timeout=60)
    assert proc.returncode == 2
    assert "no frame arrived from serial+loop:// in 5 s" in proc.stderr
    assert not (tmp_path / "run" / "summary.json").exists()
    proc = skin("run", "--port", "serial+loop://", "--out", tmp_path / "run", "--no-map",
                "--first-frame-timeout", "0.5")  # an empty events.jsonl is no earlier run
    assert proc.returncode == 2 and "no frame arrived from serial+loop:// in 0.5 s" in proc.stderr
    proc = skin("run", "--port", "serial:///dev/no-such-port", "--out", tmp_path / "run2",
                "--no-map", "--reconnect", "0")
    assert proc.returncode == 2 and "/dev/no-such-port" in proc.stderr


def test_an_unreadable_calibration_fails_before_the_first_frame(tmp_path):
    cal = tmp_path / "cal.json"
    failed_early(tmp_path, "--calibration", cal, "--no-map", message="no such calibration file")
    cal.write_text('{"format": 1,\n "taxels": {\n')
    failed_early(tmp_path, "--calibration", cal, "--no-map", message="cal.json, line 3")


def test_skin_run_is_a_thin_shell_over_skin():
    import inspect

    from skin.commands import run

    lines, _ = inspect.getsourcelines(run.main)
    assert len(lines) <= 60
    assert "Skin(" in "".join(lines)


def test_the_board_common_mode_reaches_the_detector_from_python_and_a_skin_file(tmp_path):
    """``common_mode`` ("auto" by default: on where the heater is not PID-held) switches the
    detector's board common mode on or off: the default scene's arm is one board of 72
    taxels (>= COMMON_MIN) of a constant-power sensor, so "auto" runs it."""
    from skin.formats.skin_file import load_skin_file
    from skin.stream.onset import common_auto

    (tmp_path / "on.toml").write_text("[skin]\ncommon_mode = true\n")
    (tmp_path / "off.toml").write_text("[skin]\ncommon_mode = false\n")
    (tmp_path / "auto.toml").write_text("[skin]\ncommon_mode = \"auto\"\n")
    assert Setup().common_mode == "auto"
    asked = [(Setup(), True), (Setup(common_mode=True), True), (Setup(common_mode=False), False),
             (load_skin_file(tmp_path / "on.toml"), True),
             (load_skin_file(tmp_path / "off.toml"), False),
             (load_skin_file(tmp_path / "auto.toml"), True)]
    for setup, active in asked:
        with Skin(setup, speed=0.0, duration=1.0, out=None, map=False, sinks=[]) as s:
            assert s.pipeline.detector.n_taxels >= 4
            assert s.pipeline.detector.common_active is active
            if setup.common_mode == "auto":
                assert common_auto(s.pipeline.detector.sensor)  # the arm's heater: not PID


def test_leaving_the_with_block_closes_sources_sinks_and_the_simulation(tmp_path):
    with Skin(out=tmp_path / "run", speed=0, duration=5, map=False) as s:
        first = next(r for r in s.results() if r.contact.final)  # leave mid-run
        driver, device = s._driver, s._device
        assert not driver._closed and device is not None
    assert first.estimate.label
    assert driver._closed and s._device is None and s._closers == []
    # what was given before leaving is in events.jsonl
    assert [e["contact"] for e in lines(tmp_path / "run" / "events.jsonl")
            ][:1] == [first.contact.id]


def test_a_device_run_keeps_recent_results_and_exact_counts(monkeypatch):
    """A run of a device keeps the last KEEP_RECENT results, not one per contact."""
    from skin import runner

    monkeypatch.setattr(runner, "KEEP_RECENT", 3)
    with Skin(port=["sim://default?speed=0&duration=30"], out=None, map=False,
              sinks=[]) as skin:
        given = list(skin.results())
        finals = [r for r in given if r.contact.final]
        summary = skin.finish()
    assert len(finals) >= 8  # more contacts than are kept
    assert summary["contacts"] == len(finals)  # the count runs as results come
    assert list(skin.results_given) == given[-3:]
    assert [rec["contact"] for rec in skin.records] == [r.contact.id for r in given[-3:]]
    assert skin._finals == []  # no scene, no map: no contact kept for the summary


def test_a_scene_run_keeps_every_contact_without_its_samples(monkeypatch):
    from skin import runner

    monkeypatch.setattr(runner, "KEEP_RECENT", 2)
    with Skin(speed=0.0, duration=20.0, out=None, map=False, sinks=[]) as skin:
        given = list(skin.results())
        summary = skin.finish()
    finals = [r for r in given if r.contact.final]
    assert summary["contacts"] == len(finals) > 2 and summary["detected"] >= 3
    assert len(skin.records) == len(given)  # a scene's truth is written into every record
    assert len(skin.results_given) == 2
    assert [r.contact.id for r in skin._finals] == [r.contact.id for r in finals]
    assert all(r.contact.windows == [] for r in skin._finals)

"""The ``skin`` command's conveniences: version, logging, completion, --json everywhere."""

import argparse
import io
import json
import logging
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import skin
from skin.cli import build_parser
from skin.logs import configure_logging
from skin.progress import Progress

SKIN = Path(sys.executable).with_name("skin")


def run(*args, cwd=None):
    return subprocess.run([str(SKIN), *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


def test_version():
    proc = run("--version")
    assert proc.returncode == 0 and proc.stdout.strip() == f"skin (thermoskin) {skin.__version__}"


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_log_record_is_never_glued_onto_the_status_line(monkeypatch):
    screen = Terminal()
    monkeypatch.setattr(sys, "stderr", screen)
    configure_logging(0)
    try:
        progress = Progress(screen)
        progress.status("[ 1.0 s] frames 200")
        logging.getLogger("skin.drivers").warning("serial:///dev/x: unplugged; reconnecting")
        logging.getLogger("skin.drivers").info("not shown without -v")
        progress.status("[ 1.1 s] frames 220")
        progress.done()
    finally:
        configure_logging(0)
    text = screen.getvalue()
    # the status line is cleared, the record takes a whole line, the status comes back
    assert text == ("\r\x1b[2K[ 1.0 s] frames 200\r\x1b[2K"
                    "skin.drivers: WARNING: serial:///dev/x: unplugged; reconnecting\n"
                    "\r\x1b[2K[ 1.1 s] frames 220\n")


def test_verbose_and_log_file_keep_stdout_one_json_document(tmp_path):
    log = tmp_path / "skin.log"
    proc = run("run", "-v", "--log-file", log, "--speed", "0", "--duration", "1", "--no-map",
               "--out", tmp_path / "run", "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["frames"] == 200
    assert "skin.runner: INFO: reading serial://" in proc.stderr
    assert "skin.runner INFO: outputs in" in log.read_text()
    quiet = run("run", "--speed", "0", "--duration", "1", "--no-map", "--out", tmp_path / "q",
                "--json")
    assert "INFO" not in quiet.stderr
    bad = run("--log-file", tmp_path / "no" / "such.log", "config", "show")
    assert bad.returncode == 2 and "--log-file" in bad.stderr


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash")
def test_bash_completion_completes_commands_options_and_choices():
    script = run("completion", "bash").stdout

    def complete(*words):
        line = " ".join(f'"{w}"' for w in words)
        proc = subprocess.run(["bash", "-c", f'source /dev/stdin; COMP_WORDS=(skin {line}); '
                               f'COMP_CWORD={len(words)}; _skin; echo "${{COMPREPLY[*]}}"'],
                              input=script, capture_output=True, text=True, timeout=30)
        assert proc.returncode == 0, proc.stderr
        return proc.stdout.split()

    assert complete("ca") == ["calibrate"]
    assert complete("calibrate", "th") == ["thermistors", "thermal"]
    assert complete("run", "--cl") == ["--classifier"]
    assert complete("run", "--classifier", "") == ["joint", "histogram"]
    assert complete("-v", "bench", "vi") == ["view"]


def _leaves(parser, path="skin"):
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield path, {o for a in parser._actions for o in a.option_strings}
        return
    for name, child in subs[0].choices.items():
        yield from _leaves(child, f"{path} {name}")


def test_every_command_that_reports_figures_takes_json():
    no_figures = {"skin completion"}  # prints a script
    missing = [path for path, options in _leaves(build_parser())
               if path not in no_figures and "--json" not in options]
    assert missing == []


def test_calibrate_prints_its_fits_as_json(tmp_path):
    from skin.formats.layout import load_layout
    from skin.stream.calibration import Calibration

    layout = load_layout("arm")
    nominal = Calibration.from_layout(layout)
    rows = ["taxel,reference_c,counts"]
    for ref in (20.0, 30.0, 40.0):
        counts = nominal.counts(np.full(len(layout), ref))
        rows += [f"{int(t)},{ref},{counts[k]:.3f}" for k, t in enumerate(layout.ids[:3])]
    (tmp_path / "refs.csv").write_text("\n".join(rows) + "\n")
    proc = run("calibrate", "thermistors", "--data", tmp_path / "refs.csv", "-o",
               tmp_path / "cal.json", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["fitted"] == 3 and len(doc["missing"]) == len(layout) - 3
    assert max(doc["thermistor_rms"].values()) < 0.01  # counts to 3 decimals: a fit within mK
    proc = run("calibrate", "board", "--board", "0", "--supply-voltage", "5.01", "-o",
               tmp_path / "cal.json", "--json")
    assert json.loads(proc.stdout) == {"file": str(tmp_path / "cal.json"), "board": 0,
                                       "constants": {"supply_voltage": 5.01}}
    from skin.models import load_materials
    from skin.models.trials import Protocol, simulate_trials

    simulate_trials([load_materials()["water"]], Protocol(trials=8, run_length=2, n_taxels=2),
                    seed=3).save(tmp_path / "water.npz")
    proc = run("calibrate", "thermal", "--data", tmp_path / "water.npz", "-o",
               tmp_path / "cal.json", "--json")
    doc = json.loads(proc.stdout)
    assert doc["contacts"] == 8 and set(doc["taxels"]) == {"0", "1"}
    assert all(t["thermal_converged"] is True and t["diffusivity"] > 0
               for t in doc["taxels"].values())


def test_a_reader_that_leaves_early_gets_no_traceback():
    # the reader closes the pipe before skin writes (its start-up takes far longer)
    proc = subprocess.Popen([str(SKIN), "config", "show"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=60) == 0 and err == ""

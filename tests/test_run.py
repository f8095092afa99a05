import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyvista")
from PIL import Image

from skin.models import load_materials
from skin.viz.arm import hex_rgb

SKIN = Path(sys.executable).with_name("skin")


@pytest.mark.slow
def test_skin_run_end_to_end_on_the_simulated_skin(tmp_path):
    out = tmp_path / "run"
    # the histogram method, whose pointwise effusivity this test checks (the joint model, the
    # default, is checked against the scene in test_pipeline)
    proc = subprocess.run([str(SKIN), "run", "--duration", "6", "--speed", "0", "--out",
                           str(out), "--json", "--classifier", "histogram"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)  # --json: one JSON document and nothing else
    # the scene's touches that start within 6 s: aluminium, pine, glass, forearm, neoprene
    assert summary["touches"] == 5
    assert summary["detected"] == 5 and summary["false_contacts"] == 0
    assert summary["crc_errors"] == 0 and summary["gaps"] == 0 and summary["late"] == 0
    assert summary["frames"] == 1200
    assert summary["median_onset_error"] < 0.03
    by_start = {t["start"]: t for t in summary["per_touch"]}
    # pine (e = 331) and MDF (367) are one group to an effusivity method
    assert by_start[2.0]["label"] in {"pine", "mdf"}

    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    assert len(events) == summary["contacts"] == 5
    for ev in events:
        assert {"taxels", "onset", "label", "effusivity", "truth"} <= set(ev)
    pine = next(ev for ev in events if ev["truth"] == "pine")
    assert abs(np.log10(pine["effusivity"] / load_materials()["pine"].effusivity)) < 0.05

    img = np.asarray(Image.open(out / "contact_map.png").convert("RGB")).astype(int)
    assert img.std() > 10
    colours = {m.name: m.colour for m in load_materials().values()}
    for label in {ev["label"] for ev in events} - {"unknown"}:
        diff = np.abs(img - hex_rgb(colours[label]).astype(int)).max(axis=-1)
        assert (diff <= 6).any(), f"colour of {label} not in the contact map"


def test_skin_run_reports_a_bad_scene_cleanly(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[objects]]\nname = "x"\nmaterial = "unobtainium"\n'
                   '[[touches]]\nobject = "x"\ntaxels = [0]\nstart = 1.0\nduration = 1.0\n')
    proc = subprocess.run([str(SKIN), "run", "--scene", str(bad), "--speed", "0", "--out",
                           str(tmp_path / "o"), "--no-map"], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2
    assert "unobtainium" in proc.stderr and "bad.toml" in proc.stderr


@pytest.mark.slow
def test_skin_run_gives_provisional_answers_when_asked(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run([str(SKIN), "run", "--duration", "6", "--speed", "0", "--out",
                           str(out), "--json", "--no-map", "--provisional", "0.5,1"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    finals = [e for e in events if e["final"]]
    assert len(finals) == summary["contacts"] == summary["detected"] == 5
    early = [e for e in events if not e["final"]]
    assert early and {e["contact"] for e in early} <= {e["contact"] for e in finals}
    assert all(e["truth"] == next(f["truth"] for f in finals if f["contact"] == e["contact"])
               for e in early)
    bad = subprocess.run([str(SKIN), "run", "--duration", "1", "--speed", "0", "--out",
                          str(out), "--provisional", "3"], capture_output=True, text=True,
                         timeout=300)
    assert bad.returncode == 2 and "--provisional" in bad.stderr


def test_several_ports_make_one_skin_but_simulations_come_alone(tmp_path, capsys):
    from skin.cli import main

    assert main(["run", "--port", "sim://default", "--port", "sim://default",
                 "--out", str(tmp_path)]) == 2
    assert "sim:// and replay:// are whole skins" in capsys.readouterr().err

"""Labelled contacts cut out of a recording (`skin dataset import run.mcap --labels ...`)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from skin.drivers.recording import read_recording
from skin.formats.dataset import DatasetError, load_trials
from skin.formats.recorded_contacts import contacts_from_recording
from skin.formats.touch_labels import (
    TouchLabel,
    TouchLabelError,
    read_touch_labels,
    write_touch_labels,
)


def skin(*args, check=True):
    out = subprocess.run([sys.executable, "-m", "skin", *args], capture_output=True, text=True,
                         timeout=120)
    if check:
        assert out.returncode == 0, out.stderr
    return out


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A simulated run of the default scene, recorded, and the scene's label file."""
    d = tmp_path_factory.mktemp("rec")
    skin("run", "--speed", "0", "--duration", "12", "--no-map", "--record", str(d / "run.mcap"),
         "--out", str(d / "out"))
    skin("simulate", "labels", "--duration", "12", "-o", str(d / "touches.csv"))
    return d


def test_scene_labels_round_trip(recorded):
    labels = read_touch_labels(recorded / "touches.csv")
    assert [lab.material for lab in labels[:3]] == ["aluminium", "pine", "glass"]
    assert labels[0].taxels == (0, 1, 10) and labels[0].time == 1.0
    assert all(lab.time < 12 for lab in labels)


def test_import_cuts_every_labelled_contact_from_the_recording(recorded):
    labels = read_touch_labels(recorded / "touches.csv")
    data, skipped = contacts_from_recording(recorded / "run.mcap", labels, pre=0.5,
                                            duration=2.0)
    rec = read_recording(recorded / "run.mcap")
    events = {e["contact"]: e for e in rec.events}
    # every touch became a trial or is listed; nothing vanishes silently
    cut_short = [s for s in skipped if s.kind == "contact" and "no label" not in s.reason]
    assert len(data) + sum(s.kind == "label" for s in skipped) + len(cut_short) == len(labels)
    assert all("run past the recording" in s.reason for s in cut_short)
    assert len(data) >= len(labels) - 2
    assert np.all(data.onset == 100) and data.temperature.shape[2] == 500
    assert data.fs == pytest.approx(200.0)
    for i in range(len(data)):
        ev = events[int(data.extra["contact"][i])]
        assert data.extra["onset_time"][i] == ev["onset"]
        assert set(data.taxel[i][data.taxel[i] >= 0]) == set(ev["taxels"])
        # each channel is the recording's own samples around the contact's onset
        k = int(np.searchsorted(rec.times, ev["onset"]))
        for c, taxel in enumerate(data.taxel[i]):
            if taxel >= 0:
                np.testing.assert_array_equal(
                    data.temperature[i, c], rec.temperature[k - 100:k + 400,
                                                             rec.layout.index(int(taxel))])
        # the primary channel is the taxel that cooled most
        present = data.taxel[i] >= 0
        x = data.temperature[i, present]
        drop = x[:, :100].mean(axis=1) - x[:, 100:].min(axis=1)
        assert np.argmax(drop) == 0
    # labels come from the label file: the touch nearest each contact's onset
    for i in range(len(data)):
        nearest = min(labels, key=lambda lab: abs(lab.time - data.extra["onset_time"][i]))
        assert data.label[i] == nearest.material
    assert data.heated.all()


def test_unlabelled_contacts_and_lost_labels_are_listed(recorded, tmp_path):
    labels = read_touch_labels(recorded / "touches.csv")
    # drop the label of the first touch, add one where nothing touched
    path = write_touch_labels(tmp_path / "l.csv", [*labels[1:], TouchLabel(11.7, "pine")])
    data, skipped = contacts_from_recording(recorded / "run.mcap",
                                            read_touch_labels(path), duration=2.0)
    text = [str(s) for s in skipped]
    assert any(s.startswith("contact 0 ") and "no label within 0.5 s" in s for s in text)
    assert any(s.startswith("label line") and "t=11.7 s, pine" in s for s in text)
    assert 0 not in data.extra["contact"]


def test_cli_imports_and_the_dataset_checks(recorded, tmp_path):
    out = skin("dataset", "import", str(recorded / "run.mcap"), "--labels",
               str(recorded / "touches.csv"), "--duration", "2", "-o", str(tmp_path / "c.npz"),
               "--json")
    doc = json.loads(out.stdout)
    assert doc["trials"] >= 8 and doc["onsets_to_detect"] == 0
    data = load_trials(tmp_path / "c.npz")
    assert len(data) == doc["trials"] and data.n_channels == doc["channels"]
    check = json.loads(skin("dataset", "check", str(tmp_path / "c.npz"), "--json").stdout)
    assert check["per_class"] == doc["per_class"]
    one = json.loads(skin("dataset", "import", str(recorded / "run.mcap"), "--labels",
                          str(recorded / "touches.csv"), "--duration", "2", "--channels", "1",
                          "-o", str(tmp_path / "c1.npz"), "--json").stdout)
    assert one["channels"] == 1 and one["trials"] == doc["trials"]


def test_a_recording_needs_labels_and_bad_labels_name_their_line(recorded, tmp_path):
    out = skin("dataset", "import", str(recorded / "run.mcap"), "-o", str(tmp_path / "x.npz"),
               check=False)
    assert out.returncode != 0 and "needs --labels" in out.stderr
    bad = tmp_path / "bad.csv"
    bad.write_text("time,material,taxels\n1.0,pine,3\n2.0,unobtainium,4\n", encoding="utf-8")
    with pytest.raises(TouchLabelError, match=r"bad.csv: line 3: material 'unobtainium'"):
        read_touch_labels(bad)
    bad.write_text("time,material,taxels\n1.0,pine,3 x\n", encoding="utf-8")
    with pytest.raises(TouchLabelError, match=r"line 2: taxels '3 x'"):
        read_touch_labels(bad)
    bad.write_text("when,material\n1.0,pine\n", encoding="utf-8")
    with pytest.raises(TouchLabelError, match="line 1: missing column"):
        read_touch_labels(bad)
    assert not (tmp_path / "x.npz").exists()


def test_no_labelled_contact_is_an_error_naming_the_first_reason(recorded):
    with pytest.raises(DatasetError, match="no labelled contact"):
        contacts_from_recording(recorded / "run.mcap", [TouchLabel(100.0, "pine")])

"""Trial dataset version 2: several channels per contact, v1 compatibility, CSV import."""

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

from skin.formats.dataset import DatasetError, TrialSet, load_trials
from skin.formats.trial_csv import read_trials_csv


def two_channel(n=4, m=50):
    temp = np.full((n, 2, m), 30.0)
    temp[:, 1] = 25.5
    temp[1, 1] = np.nan  # trial 1 has no passive channel
    heated = np.array([[True, False]] * n)
    return TrialSet(temperature=temp, fs=200.0, label=np.array(["a", "b"] * (n // 2)),
                    onset=np.full(n, 10), ambient=np.full(n, 25.0), group=np.arange(n),
                    taxel=np.array([[3, 4]] * n), heated=heated,
                    setpoint=np.full((n, 2), np.nan), force=np.zeros((n, m)),
                    object_temperature=np.full(n, 20.0))


def test_v2_round_trip_keeps_channels_nan_padding_and_optional_columns(tmp_path):
    ds = two_channel()
    back = load_trials(ds.save(tmp_path / "v2.npz"))
    assert back.temperature.shape == (4, 2, 50) and back.n_channels == 2
    assert np.isnan(back.temperature[1, 1]).all()
    assert back.heated.tolist() == ds.heated.tolist()
    for key in ("taxel", "force", "object_temperature", "group"):
        assert np.array_equal(getattr(back, key), getattr(ds, key))
    assert back.primary.shape == (4, 50)
    one = back.channels([0])
    assert one.n_channels == 1 and one.taxel.shape == (4, 1)


def test_v1_file_loads_as_one_heated_channel(tmp_path):
    np.savez(tmp_path / "v1.npz", temperature=np.full((3, 20), 30.0), fs=200.0,
             label=np.array(["a", "b", "a"]), onset=np.array([5, 5, 5]),
             taxel=np.array([1, 2, 3]), ambient=np.full(3, 25.0))
    ds = load_trials(tmp_path / "v1.npz")
    assert ds.temperature.shape == (3, 1, 20)
    assert ds.heated.all() and ds.taxel[:, 0].tolist() == [1, 2, 3]


@pytest.mark.parametrize(("change", "message"), [
    ("partial", "trial 2 channel 1 is not finite at sample 7"),
    ("primary", "trial 0 has no reading on its primary channel 0"),
    ("heated", r"'heated' must be \(n_trials, n_channels\)"),
    ("force", r"'force' must be \(n_trials, n_samples\)"),
])
def test_bad_v2_trials_are_rejected_with_index_and_reason(change, message):
    ds = two_channel()
    kw = dict(temperature=ds.temperature.copy(), fs=ds.fs, label=ds.label, onset=ds.onset,
              heated=ds.heated)
    if change == "partial":
        kw["temperature"][2, 1, 7] = np.nan
    elif change == "primary":
        kw["temperature"][0, 0] = np.nan
    elif change == "heated":
        kw["heated"] = np.ones((4, 3), dtype=bool)
    else:
        kw["force"] = np.zeros((4, 3))
    with pytest.raises(DatasetError, match=message):
        TrialSet(**kw)


CSV_HEADER = "trial,channel,time,temperature,label,ambient,heated,taxel,onset\n"


def write_csv(path, bad_trial=False):
    lines = [CSV_HEADER]
    for trial, label in (("t1", "pine"), ("t2", "glass"), ("t3", "pine")):
        for ch, heated in ((0, 1), (1, 0)):
            for k in range(40):
                temp = (35.0 if heated else 25.5) - (0.0 if k < 10 else 0.1 * (k - 10))
                ambient = "25" if not (bad_trial and trial == "t2" and k == 5) else "26"
                lines.append(f"{trial},{ch},{k / 200:.3f},{temp:.3f},{label},{ambient},"
                             f"{heated},{7 + ch},0.05\n")
    path.write_text("".join(lines))
    return path


def test_csv_import_builds_a_v2_dataset(tmp_path):
    ds, rejected = read_trials_csv(write_csv(tmp_path / "t.csv"))
    assert rejected == []
    assert ds.temperature.shape == (3, 2, 40) and ds.fs == pytest.approx(200.0)
    assert ds.heated[:, 0].all() and not ds.heated[:, 1].any()
    assert ds.onset.tolist() == [10, 10, 10] and ds.taxel[0].tolist() == [7, 8]
    assert ds.label.tolist() == ["pine", "glass", "pine"]


def test_csv_import_rejects_a_trial_naming_index_line_and_reason(tmp_path):
    ds, rejected = read_trials_csv(write_csv(tmp_path / "t.csv", bad_trial=True))
    assert len(ds) == 2 and [r.index for r in rejected] == [1]
    assert "ambient '26' differs" in rejected[0].reason and "line" in rejected[0].reason
    out = subprocess.run([sys.executable, "-m", "skin", "dataset", "import",
                          str(tmp_path / "t.csv"), "-o", str(tmp_path / "t.npz"), "--json"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["trials"] == 2 and doc["rejected"][0]["trial"] == "t2"
    assert doc["passive_channels"] == 2
    check = subprocess.run([sys.executable, "-m", "skin", "dataset", "check",
                            str(tmp_path / "t.npz")], capture_output=True, text=True, timeout=120)
    assert check.returncode == 0 and "2 channel(s)" in check.stdout


def test_csv_missing_column_is_named(tmp_path):
    (tmp_path / "bad.csv").write_text("trial,channel,time,temperature\n1,0,0,30\n")
    with pytest.raises(DatasetError, match=r"missing column.*label, ambient"):
        read_trials_csv(tmp_path / "bad.csv")


def test_force_dates_unknown_onsets_where_it_shows_the_contact():
    """An unknown onset is taken from the force channel: the first sample 5 % of the way up
    from the pre-contact level; no force, noise alone (Gaussian or quantised), a one-sample
    glitch, a force that falls or a NaN one dates nothing."""
    from skin.formats.dataset import force_onsets, with_detected_onsets

    rng = np.random.default_rng(0)
    k = np.arange(400)
    ramp = 2.0 * np.clip((k - 149) / 10.0, 0.0, 1.0)  # 2 N in 10 samples from sample 150
    glitch = np.where(k == 100, 0.01, 0.0)
    quantised = np.round(rng.normal(0.0, 0.004, k.size) / 0.01) * 0.01  # 0.4 LSB of noise
    force = np.stack([ramp + 0.3, ramp + rng.normal(0.0, 0.01, k.size),
                      rng.normal(0.0, 0.01, k.size), np.where(k == 10, np.nan, ramp),
                      glitch, quantised, 2.0 - ramp])
    n = len(force)
    flat = np.full((n, 1, k.size), 30.0)  # a reading where no detector finds a contact
    onset = np.full(n, -1)
    onset[2] = 77
    data = TrialSet(flat, 200.0, np.array(list("abcdefg")), onset, force=force)
    assert force_onsets(data).tolist() == [150, 150, -1, -1, -1, -1, -1]
    assert force_onsets(dataclasses.replace(data, force=None)).tolist() == [-1] * n
    # noise alone never passes: 200 Gaussian and 200 quantised traces
    noise = np.concatenate([rng.normal(0.0, 0.01, (200, k.size)),
                            np.round(rng.normal(0.0, 0.004, (200, k.size)) / 0.01) * 0.01])
    quiet = TrialSet(np.full((400, 1, k.size), 30.0), 200.0, np.array(["a"] * 400),
                     np.full(400, -1), force=noise)
    assert (force_onsets(quiet) == -1).all()
    # a peak only 12 noise levels up (1 N ramped over 0.2 s, 1/12 N of noise): nearly every
    # trial dated (a noise level read high from the ramp's start leaves a few), none more
    # than a sample before the ramp, none more than 12 samples after its start
    ramp = np.clip((k - 149) / 40.0, 0.0, 1.0)
    weak = TrialSet(np.full((200, 1, k.size), 30.0), 200.0, np.array(["a"] * 200),
                    np.full(200, -1), force=ramp + rng.normal(0.0, 1.0 / 12.0, (200, k.size)))
    dated = force_onsets(weak)
    dated = dated[dated >= 0] - 150
    assert dated.size >= 190 and dated.min() >= -1 and dated.max() <= 12
    # trials dated by force skip the detector; a known onset is kept; the rest still must
    # be found in the reading, and here cannot
    with pytest.raises(DatasetError, match="no contact onset found in trial 3 \\(4 trial"):
        with_detected_onsets(data)
    known = np.array([-1, -1, 77, 5, 6, 7, 8])
    found = with_detected_onsets(dataclasses.replace(data, onset=known))
    assert found.onset.tolist() == [150, 150, 77, 5, 6, 7, 8]

"""The onset detector on slowly sampled recordings (20-50 Hz): a contact is one event."""

import json
import subprocess
import sys

import numpy as np
import pytest

from skin.errors import SkinError
from skin.models import load_materials
from skin.models.sensors import load_sensor
from skin.models.trials import Protocol, simulate_trials
from skin.stream.onset import OnsetDetector

MATS = load_materials()


@pytest.fixture(scope="module")
def trials():
    """The 12 aluminium / pine trials of `test_onset_eval` (seed 1), at 200 Hz."""
    return simulate_trials([MATS["aluminium"], MATS["pine"]], Protocol(trials=6, run_length=3),
                           seed=1)


def _events(data, chunk=None, common_mode=False):
    # the 12 trials are 12 recordings, no board (as evaluate-onset --data takes them): no
    # board common mode unless asked
    sensor = load_sensor("paper").at_rate(data.fs, "the trials")
    temperature = data.primary.T.copy()
    times = np.arange(temperature.shape[0]) / data.fs
    detector = OnsetDetector(temperature.shape[1], sensor=sensor, common_mode=common_mode)
    state, events = detector.initial_state(), []
    step = chunk or len(times)
    for i in range(0, len(times), step):
        got, state = detector.process(times[i:i + step], temperature[i:i + step], state)
        events += got
    return detector, events


@pytest.mark.parametrize("factor", [10, 4])  # 20 Hz, 50 Hz
def test_a_slowly_sampled_contact_is_one_onset_not_a_release_and_a_new_onset(trials, factor):
    data = trials.decimated(factor)
    assert data.fs == 200.0 / factor and data.temperature.shape[-1] == 700 // factor
    _, events = _events(data)
    # every trial holds one contact from its onset to its end: one onset each, no release (the
    # detector released and re-detected 3 of the 12 contacts at 20 Hz, 1 at 50 Hz)
    assert sorted(e.taxel for e in events) == list(range(len(data)))
    assert all(e.kind == "onset" and e.direction == -1 for e in events)
    onsets = data.onset / data.fs
    for e in events:
        assert onsets[e.taxel] - 0.1 <= e.time <= onsets[e.taxel] + 0.6  # dated in the contact
    # chunks of any size give the same events
    _, chunked = _events(data, chunk=3)
    assert [(e.taxel, e.kind, e.time, e.detected_at) for e in chunked] == \
        [(e.taxel, e.kind, e.time, e.detected_at) for e in events]


@pytest.mark.parametrize("factor", [10, 4])  # 20 Hz, 50 Hz
def test_a_whole_board_touched_at_once_is_found_on_every_taxel_with_the_common_mode(trials,
                                                                                     factor):
    """The same 12 contacts taken as one board touched at once (a palm pressed flat: every
    taxel from 0.5 s). With the board common mode (on by default for this constant-power
    sensor) the shared start is taken for the room until the first onsets are raised, so
    the taxels still free then are dated later: the cost of the common mode on a whole-board
    touch (50 Hz: two of 12 by 0.18 and 0.24 s, one dated 1.16 s, 0.66 s into the contact;
    20 Hz: one by 0.10 s). Every contact is still one onset, found."""
    data = trials.decimated(factor)
    _, events = _events(data, common_mode=True)
    assert sorted(e.taxel for e in events) == list(range(len(data)))
    assert all(e.kind == "onset" and e.direction == -1 for e in events)
    onsets = data.onset / data.fs
    for e in events:
        assert onsets[e.taxel] - 0.1 <= e.time <= onsets[e.taxel] + 0.7
    alone = {e.taxel: e.time for e in _events(data)[1]}
    later = max(e.time - alone[e.taxel] for e in events)
    assert 0.0 < later <= 0.3  # the cost is there, and bounded


def test_the_contacts_end_test_stays_clear_of_one_samples_noise():
    # in contact, the CUSUM of the other sign needs END_SIGMAS of the raw reading's noise at
    # the least: at 20 Hz that floor sets it (the disturbance floor, 0.06 K x samples, lay
    # below one sample's noise), its follow gate (a quarter) above one ADC count near the
    # heated temperature; at every preset's own rate the disturbance floors lie above it
    paper20 = load_sensor("paper").at_rate(20.0)
    slow = OnsetDetector(2, sensor=paper20)
    assert np.all(slow.end_rise_threshold > slow.rise_threshold)
    assert np.allclose(slow.end_rise_threshold, 8.0 * slow.sigma)
    count = paper20.kelvin_per_count(25.0 + paper20.heated_rise)  # 0.055 K
    assert np.all(slow.end_rise_threshold / 4 > count)
    for preset in ("paper", "fast-film", "low-cost", "pid-logger"):
        native = OnsetDetector(2, sensor=preset)
        assert np.array_equal(native.end_threshold, np.broadcast_to(native.threshold, (2,)))
        assert np.array_equal(native.end_rise_threshold,
                              np.broadcast_to(native.rise_threshold, (2,)))


def test_a_quantised_slow_fall_is_not_released_on_a_one_count_reversal():
    # held out (never tuned on): 5 materials x 8 trials, seed 7, 8 s each, at 20 Hz. With the
    # end test at 8 smoothed sigmas, a one-ADC-count reversal in the staircase of a steady
    # -1.3 K/s fall (copper, trial 36) released its contact at 2.95 s, found again at 3.8 s
    names = ("steel", "glass", "acrylic", "cardboard", "copper")
    data = simulate_trials([MATS[m] for m in names], Protocol(trials=8, duration=8.0),
                           seed=7).decimated(10)
    _, events = _events(data)
    assert [e.kind for e in events].count("release") == 0
    assert sorted(e.taxel for e in events) == list(range(len(data)))


def test_decimated_trials_keep_every_nth_sample_and_date_onsets_at_or_before(trials):
    slow = trials.decimated(10)
    assert np.array_equal(slow.temperature, trials.temperature[..., ::10])
    assert np.array_equal(slow.onset, trials.onset // 10) and "1 sample in 10" in slow.source
    assert np.all(slow.onset / slow.fs <= trials.onset / trials.fs)  # at or before
    assert np.all(trials.onset / trials.fs - slow.onset / slow.fs <= 9 / trials.fs)
    assert trials.decimated(1) is trials
    for bad in (0, 700, True, 2.0):
        with pytest.raises(SkinError, match="decimation factor"):
            trials.decimated(bad)


def test_simulate_trials_decimate_writes_the_slow_dataset(tmp_path, trials):
    out = subprocess.run([sys.executable, "-m", "skin", "simulate", "trials", "--materials",
                          "aluminium,pine", "--trials", "6", "--run-length", "3", "--seed", "1",
                          "--decimate", "10", "-o", str(tmp_path / "slow.npz"), "--json"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["fs"] == 20.0 and doc["samples"] == 70
    from skin.formats.dataset import load_trials

    slow = load_trials(tmp_path / "slow.npz")
    assert np.array_equal(slow.temperature, trials.temperature[..., ::10])
    assert np.array_equal(slow.onset, trials.onset // 10)


@pytest.mark.parametrize(("args", "says"), [
    (["--decimate", "0"], "--decimate must be at least 1"),
    (["--run-length", "0"], "--run-length must be at least 1"),
    (["--decimate", "800"], "0.25 Hz, 1 of a trial's 700 samples: a sensor description "
                            "takes 20-1000 Hz and a trial at least two samples (at most 10"),
    (["--decimate", "11"], "18.1818 Hz, 64 of a trial's 700 samples"),
    (["--decimate", "2", "--sensor", "fast-film"], "sensor 'fast-film' smooths its reading"),
])
def test_simulate_trials_refuses_a_bad_decimation_before_simulating(tmp_path, args, says):
    out = subprocess.run([sys.executable, "-m", "skin", "simulate", "trials", "--materials",
                          "aluminium", "--trials", "2", *args, "-o", str(tmp_path / "x.npz")],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and says in out.stderr
    assert "trials [" not in out.stderr and not (tmp_path / "x.npz").exists()  # nothing ran

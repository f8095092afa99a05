"""Why the detector missed a contact or raised a false alarm, and the benchmark's fair truth."""

import math

import numpy as np
import pytest

from skin.bench.onset_eval import contact_of
from skin.bench.onset_why import ALARM_CAUSES, MISS_CAUSES, explain_outcomes
from skin.bench.streams import StreamContact, simulate_stream
from skin.models import load_materials
from skin.models.sensors import contact_reading, load_sensor
from skin.stream.onset import OnsetEvent

MATS = load_materials()


def _contact(taxel, onset, release, peak=1.0, five=0.05):
    return StreamContact(taxel, onset, release, "pine", 25.0, 38.0, 0.02, peak, five)


def _onset(taxel, t, at, channel=0, direction=-1):
    return OnsetEvent("onset", taxel, t, at, 38.0, 0.0, direction, channel)


def _release(taxel, t, at):
    return OnsetEvent("release", taxel, t, at, 30.0, 0.0, -1, 3)


def test_an_alarm_raised_in_contact_but_dated_early_belongs_to_it():
    # a gust started the CUSUM 0.3 s before the touch; the alarm came while touching
    spans = [(10.0, 12.0), (40.0, 41.0)]
    assert contact_of(_onset(0, 9.7, 10.4), spans) == 0
    assert contact_of(_onset(0, 10.05, 10.2), spans) == 0
    assert contact_of(_onset(0, 9.7, 9.95), spans) is None  # before the touch: not its alarm
    assert contact_of(_onset(0, 20.0, 20.5), spans) is None


def test_each_miss_and_false_alarm_gets_its_cause():
    contacts = [
        _contact(0, 10.0, 12.0),              # detected
        _contact(0, 30.0, 31.0),              # the detector still in contact from 25 s
        _contact(1, 10.0, 11.0),              # a release 0.2 s before: warming up
        _contact(2, 10.0, 10.5),              # alarm 1 s after release
        _contact(3, 10.0, 12.0),              # a gust under way
        _contact(4, 50.0, 51.0),              # heater switched 5 s before
        _contact(5, 10.0, 10.5, five=0.4),    # 5 sigma only 0.1 s before release
        _contact(6, 10.0, 12.0, peak=0.3),    # gust-sized
        _contact(7, 10.0, 12.0, peak=2.0),    # nothing explains it
    ]
    events = [
        _onset(0, 10.05, 10.1), _release(0, 10.3, 10.4), _onset(0, 10.5, 10.6, 2),  # split
        _onset(0, 25.0, 25.3),                          # free false alarm, never released
        _release(1, 9.7, 9.8),
        _onset(2, 11.4, 11.5),                          # after release (a false alarm too)
        _onset(3, 60.0, 60.2, 1, 1),                    # during a later gust
        _onset(4, 47.0, 47.1), _release(4, 47.5, 47.6),  # 3 s before: after a switch
        _onset(5, 100.0, 100.2),                        # 2 s after a heater switch
        _onset(6, 1.0, 1.2), _release(6, 1.5, 1.6),     # warm-up
        _onset(7, 8.5, 8.7), _release(7, 8.8, 8.9),     # 1.5 s before the contact's onset
    ]
    gusts = [(9.0, 3, 0.2, 1.0, 2.0), (59.0, 3, 0.2, 1.0, 2.0)]
    switches = [(0.0, 4, 1.0), (45.0, 4, 0.7), (98.0, 5, 0.85)]
    out = explain_outcomes(events, contacts, [True] * len(contacts), gusts, switches,
                           warmup=0.5, gust_size=0.4)
    causes = [r["cause"] for r in out["missed_contacts"]]
    assert causes == ["in_contact", "warming_up", "alarm_after_release", "gust",
                      "heater_switch", "late_5sigma", "gust_sized", "unflagged"]
    assert out["missed"] == 8 and set(out["misses"]) == set(MISS_CAUSES)
    fa = out["false_alarms"]
    assert set(fa) == set(ALARM_CAUSES) and out["false_alarm_total"] == 8
    assert fa["split"] == 1 and fa["after_release"] == 1 and fa["gust"] == 1
    assert fa["heater_switch"] == 2 and fa["warm_up"] == 1 and fa["before_onset"] == 1
    assert fa["free"] == 1  # the one at 25 s


def test_the_warm_up_lasts_as_long_as_the_detectors_slow_average_takes_to_settle():
    # low-cost's slow window is 10.3 s: an alarm at 8 s is the warm-up's, not the air's
    events = [_onset(0, 8.0, 8.2), _release(0, 8.5, 8.6)]
    short = explain_outcomes(events, [], [], warmup=0.5)
    long = explain_outcomes(events, [], [], warmup=0.5, settle=10.3)
    assert short["false_alarms"]["free"] == 1 and short["false_alarms"]["warm_up"] == 0
    assert long["false_alarms"]["warm_up"] == 1 and long["false_alarms"]["free"] == 0


def test_a_pid_logger_contact_is_not_made_visible_by_the_air():
    # the floor is the contact's own step through the loop and the lag: with gusts and
    # flutter it is that of a quiet stream (before: 165 ms against 670 ms, the flutter's)
    s = load_sensor("pid-logger")
    floors = []
    for quiet in (False, True):
        st = simulate_stream([MATS["aluminium"], MATS["pine"], MATS["neoprene"]], n_taxels=16,
                             duration=240.0, seed=4, sensor=s, disturbances=not quiet)
        seen = [c.visible_after for c in st.contacts if np.isfinite(c.visible_after)]
        assert len(seen) >= 15
        floors.append(float(np.median(seen)))
        sigma = s.noise_kelvin(25.0 + s.heated_rise) * s.smoothing_noise_factor()
        for c in st.contacts:  # 5 sigma comes after 3 sigma, within the contact, and by size
            assert c.five_sigma_after >= c.visible_after
            assert np.isfinite(c.five_sigma_after) == (c.peak_change >= 5 * sigma)
    assert floors[0] == pytest.approx(floors[1], rel=0.3) and floors[0] > 0.4


def test_the_paper_floor_is_the_contact_trace_itself():
    st = simulate_stream([MATS["aluminium"], MATS["pine"]], n_taxels=4, duration=120.0,
                         seed=3, sensor=load_sensor("paper"))
    assert st.gusts and st.switches
    for c in st.contacts:
        k0 = math.ceil(c.onset * st.fs)
        assert c.sensor_temperature == pytest.approx(
            float(st.temperature[k0 - 40:k0, c.taxel].mean()), abs=0.1)
        assert 0.0 <= c.visible_after <= c.five_sigma_after or not np.isfinite(c.visible_after)


def test_heater_off_never_takes_the_reading_below_body_and_object():
    s = load_sensor("fast-film")
    t = np.array([0.0, 1e-6, 0.1, 1.0, 10.0, 100.0, 1e6])
    for e_obj, h in ((2.4e4, np.inf), (400.0, 3000.0), (30.0, 50.0)):
        y = contact_reading(t, 35.0, 25.0, e_obj, s, h, ambient=25.0)
        assert np.all(np.isfinite(y)) and y[0] == 35.0
        assert np.all(y >= 25.0 - 1e-9) and np.all(np.diff(y) <= 1e-12)
        assert y[-1] == pytest.approx(25.0, abs=1e-6)  # body and object both at ambient
    # an object warmer than the body: the reading lies between the draining body and it
    y = contact_reading(t, 35.0, 45.0, 400.0, s, 3000.0, ambient=25.0)
    body = 25.0 + 10.0 * np.exp(-t / s.reheat_time_constant)
    assert np.all(y >= body - 1e-9) and np.all(y <= 45.0)
    # a sensor at ambient touching an object at ambient: nothing moves
    assert np.all(contact_reading(t, 25.0, 25.0, 400.0, s, 3000.0, ambient=25.0) == 25.0)


def test_a_lagged_sensor_may_alarm_after_release_for_its_own_touch():
    from skin.bench.onset_eval import EARLY, release_window

    assert release_window(None) == EARLY == release_window(load_sensor("paper"))
    lagged = release_window(load_sensor("low-cost"))  # 1 s lag and a 2 Hz low-pass
    assert 3.1 < lagged < 3.4 and 1.5 < release_window(load_sensor("pid-logger")) < 1.7
    spans = [(10.0, 11.4)]
    late = _onset(0, 12.5, 12.55, 2)  # the touch's fall, shown 1.1 s after it ended
    assert contact_of(late, spans) is None and contact_of(late, spans, lagged) == 0
    assert contact_of(_onset(0, 16.0, 16.1), spans, lagged) is None


@pytest.mark.parametrize("name", ["pid-logger", "low-cost"])
def test_a_slow_sensor_detector_warms_up_as_long_as_its_baseline_needs(name):
    # its baseline's slope takes seconds to catch the trend: alarms at power-up were false
    from skin.stream.onset import OnsetDetector

    s = load_sensor(name)
    st = simulate_stream([MATS["glass"]], n_taxels=16, duration=20.0, contacts_per_minute=0.0,
                         seed=1, sensor=s)
    det = OnsetDetector(16, sensor=s)
    assert det.warmup == pytest.approx(0.5 * s.response_time / 2.516, rel=0.01)
    assert OnsetDetector(1).warmup == 0.5  # the paper's, as before
    events, _ = det.process(st.times, st.temperature, det.initial_state())
    assert not [e for e in events if e.kind == "onset"]


def test_evaluate_onset_why_prints_the_causes_in_one_json_document():
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "skin", "evaluate-onset", "--sensor", "low-cost",
                          "--minutes", "3", "--taxels", "4", "--why", "--json"],
                         capture_output=True, text=True, check=True)
    doc = json.loads(out.stdout)
    why = doc["why"]
    assert why["counted"] == "5-sigma contacts" and why["contacts"] >= why["missed"]
    assert why["missed"] == sum(why["misses"].values()) == len(why["missed_contacts"])
    assert why["false_alarm_total"] == doc["false_alarms"]

"""Contact tracking (skin.stream.tracking): which onsets make one contact."""

import numpy as np
import pytest

from skin.drivers.sim import SkinSimulator
from skin.formats.datafiles import read_data_file
from skin.formats.scene import SceneError, load_scene, parse_scene
from skin.models import HistogramClassifier
from skin.models.sensors import SensorDescription, load_sensor
from skin.stream.onset import OnsetEvent
from skin.stream.pipeline import Pipeline
from skin.stream.tracking import JOIN_WINDOW, ContactTracker, join_window_for

DEFAULT = load_scene("default")
FS = 200.0


def _onset(taxel, t, delay=0.07):
    return OnsetEvent("onset", DEFAULT.layout.index(taxel), t, t + delay, 35.0, 0.0)


def _release(taxel, t, delay=0.1):
    return OnsetEvent("release", DEFAULT.layout.index(taxel), t, t + delay, 30.0, 0.0)


def _track(events, chunk=None, duration=4.0, **kw):
    """Feed the events to a tracker on the default layout; return its decided contacts."""
    tracker = ContactTracker(DEFAULT.layout, FS, **kw)
    times = np.arange(0.0, duration, 1.0 / FS)
    temperature = np.full((len(times), len(DEFAULT.layout)), 35.0)
    ambient = np.full(len(times), 25.0)
    chunk = chunk or len(times)
    out = []
    for i in range(0, len(times), chunk):
        t = times[i : i + chunk]
        mine = [ev for ev in events if t[0] <= ev.detected_at <= t[-1]]
        out += tracker.update(t, temperature[i : i + chunk], ambient[i : i + chunk], mine)
    return out + tracker.flush()


def _taxels(decided):
    return [sorted(int(DEFAULT.layout.ids[m.index]) for m in d.members) for d in decided]


def test_an_onset_between_two_open_pieces_joins_them_into_one_contact():
    # 57 and 64 are diagonal (not neighbours); 65 neighbours both: seen in this order, the
    # first two start apart and 65 bridges them (scene seed 8's forearm touch)
    events = [_onset(57, 1.00), _onset(64, 1.01), _onset(65, 1.02), _onset(56, 1.03)]
    events += [_release(k, 2.5) for k in (56, 57, 64, 65)]
    for chunk in (None, 7, 1):
        decided = _track(events, chunk)
        assert _taxels(decided) == [[56, 57, 64, 65]]
        assert decided[0].id == 0 and decided[0].final


def test_neighbours_touched_a_second_apart_are_two_contacts():
    # 44 still touched when its neighbour 45 is touched by something else a second later
    events = [_onset(44, 1.0), _onset(45, 2.0), _release(44, 3.0), _release(45, 3.2)]
    assert _taxels(_track(events)) == [[44], [45]]


def test_a_neighbour_released_before_the_next_onset_is_not_joined():
    # two taps on neighbouring taxels within the join window, the first already over
    events = [_onset(44, 1.0), _release(44, 1.2), _onset(45, 1.35), _release(45, 2.0)]
    assert 1.35 - 1.0 < JOIN_WINDOW
    assert _taxels(_track(events)) == [[44], [45]]
    # overlapping in time, the same two onsets are one contact
    events = [_onset(44, 1.0), _onset(45, 1.35), _release(44, 2.0), _release(45, 2.0)]
    assert _taxels(_track(events)) == [[44, 45]]


def test_a_piece_reported_provisionally_is_not_merged_away():
    """Every provisional answer keeps its final one (a map replaces the one by the other)."""
    # the piece of 57 is reported at 1.2 s; 64 starts apart, 65 joins both before 64's
    # snapshot: 64 joins the reported contact
    events = [_onset(57, 1.0), _onset(64, 1.3), _onset(65, 1.35)]
    events += [_release(k, 2.5) for k in (57, 64, 65)]
    decided = _track(events, provisional=(0.2,))
    finals = [d for d in decided if d.final]
    assert _taxels(finals) == [[57, 64, 65]]
    assert {d.id for d in decided} == {finals[0].id}
    # both pieces reported before 65 arrives: they stay two, each with its final answer
    events = [_onset(57, 1.0), _onset(64, 1.1), _onset(65, 1.45)]
    events += [_release(k, 2.5) for k in (57, 64, 65)]
    decided = _track(events, provisional=(0.2,))
    finals = [d for d in decided if d.final]
    assert sorted(_taxels(finals)) == [[57, 65], [64]]
    assert {d.id for d in decided if not d.final} == {d.id for d in finals}


def test_the_join_window_follows_the_sensor():
    assert join_window_for(None) == join_window_for(SensorDescription()) == JOIN_WINDOW
    assert join_window_for(load_sensor("fast-film")) == JOIN_WINDOW  # never shorter
    slow = load_sensor("low-cost")
    assert join_window_for(slow) == pytest.approx(
        JOIN_WINDOW * slow.response_time / SensorDescription().response_time)


def _scene(seed, sensor=""):
    """The default scene with another seed (and a sensor preset on every board)."""
    text, source, base = read_data_file("default", "scenes", "scene", SceneError)
    text = text.replace("\nseed = 7\n", f"\nseed = {seed}\n"
                        + (f'sensor = "{sensor}"\n' if sensor else ""))
    return parse_scene(text, source, base)


def _run(scene, duration, chunk=20):
    frames = list(SkinSimulator(scene, duration=duration).frames())
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout))
    results = []
    for i in range(0, len(frames), chunk):
        results += pipe.process(frames[i : i + chunk])
    return results + pipe.flush()


def test_a_simulated_touch_seen_in_pieces_is_one_contact():
    """Scene seed 8: the forearm's taxels 57, 64 start apart (diagonal), 65 and 56 join them."""
    scene = _scene(8)
    results = _run(scene, 7.5)
    forearm = [r.contact.taxels for r in results if set(r.contact.taxels) & {56, 57, 64, 65}]
    assert forearm == [[56, 57, 64, 65]]
    assert [r.contact.taxels for r in _run(scene, 7.5, chunk=1000)] == [
        r.contact.taxels for r in results]


def test_a_slow_sensor_joins_the_taxels_of_one_touch():
    """The low-cost preset dates the neoprene pad's two taxels 0.55 s apart (scene seed 8)."""
    scene = _scene(8, "low-cost")
    results = _run(scene, 11.0)
    pad = [r.contact.taxels for r in results if set(r.contact.taxels) & {33, 34}]
    assert pad == [[33, 34]]


def test_two_simulated_taps_on_neighbours_are_two_contacts():
    """A 0.25 s tap on 44, then 45 touched 0.3 s after the first began: two objects."""
    text, source, base = read_data_file("default", "scenes", "scene", SceneError)
    text = text[: text.index("[[touches]]")] + """
[[touches]]
object = "glass jar"
taxels = [44]
start = 1.0
duration = 0.25

[[touches]]
object = "pine board"
taxels = [45]
start = 1.3
duration = 1.5
"""
    results = _run(parse_scene(text, source, base), 3.5)
    assert [r.contact.taxels for r in results] == [[44], [45]]


def test_bench_tracking_counts_whole_split_and_merged_touches(capsys):
    import json

    from skin.bench.tracking import random_scene, score
    from skin.cli import main

    scene = random_scene(pairs=2, seed=3)
    assert len(scene.touches) == 6
    pieces = [{k: t.start + 0.01 for k in t.taxels} for t in scene.touches]
    assert score(scene, pieces)["whole"] == 6
    # the first touch in two pieces, the next two as one contact, a false alarm elsewhere
    first = list(pieces[0].items())
    split = [dict(first[:1]), dict(first[1:]), pieces[1] | pieces[2], *pieces[3:], {71: 0.0}]
    assert score(scene, split) == {"touches": 6, "whole": 3, "split": 1, "merged": 1,
                                   "missed": 0, "other_contacts": 1}
    assert main(["bench", "tracking", "--pairs", "2", "--seeds", "3", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)["rows"][0]
    assert row["touches"] == row["whole"] == 6 and row["track_us_per_sample"] > 0


def test_a_released_taxels_samples_reach_past_its_release_short_of_its_next_contact():
    # 44 released at 1.5 s; the contact waits for 45 (released at 2.5 s); 44 is touched
    # again at 2.0 s: its samples reach past its release (the free response, for the
    # release's refinement), up to its next onset, and the window still ends at its release
    events = [_onset(44, 1.0), _onset(45, 1.05), _release(44, 1.5), _onset(44, 2.0),
              _release(45, 2.5), _release(44, 3.0)]
    first = _track(events)[0]
    m44, m45 = first.members
    assert m44.release == 1.5 and m44.end == 1.5
    assert m44.time[-1] == pytest.approx(2.0) and m45.time[-1] == pytest.approx(2.5 + 0.1)


def test_quiet_since_is_when_the_taxels_earlier_touch_ended():
    # 44 touched 1.0-1.5 s, then again at 2.0 s: the second contact's samples reach back to
    # 1.4 s (search 0.6 s), but the taxel was quiet only from its release at 1.5 s; a taxel
    # touched for the first time is quiet from its first sample
    events = [_onset(44, 1.0), _release(44, 1.5), _onset(44, 2.0), _release(44, 2.4)]
    first, second = _track(events)
    assert first.members[0].quiet_since == pytest.approx(first.members[0].time[0])
    m = second.members[0]
    assert m.time[0] < 1.5 and m.quiet_since == pytest.approx(1.5)


def test_a_release_after_its_contact_was_decided_still_ends_the_taxels_activity():
    # touched 1.0-6.0 s: decided while touching (the window), released after; the next
    # touch at 6.3 s reaches back to 5.7 s, but the taxel was quiet only from 6.0 s
    events = [_onset(44, 1.0), _release(44, 6.0), _onset(44, 6.3), _release(44, 6.8)]
    m = _track(events, duration=8.0)[-1].members[0]
    assert m.time[0] < 6.0 and m.quiet_since == pytest.approx(6.0)

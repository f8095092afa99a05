import numpy as np
import pytest

from skin.drivers.sim import SkinSimulator
from skin.errors import SkinError
from skin.formats.layout import Board, Layout, Taxel
from skin.formats.scene import load_scene, match_touches
from skin.models import HistogramClassifier
from skin.stream.pipeline import Pipeline


@pytest.fixture(scope="module")
def scene_frames():
    scene = load_scene("default")
    return scene, list(SkinSimulator(scene, duration=10.0).frames())


def run(scene, frames, chunk, classifier=None):
    pipe = Pipeline(scene.layout, classifier or HistogramClassifier(scene.layout))
    results = []
    for i in range(0, len(frames), chunk):
        results += pipe.process(frames[i : i + chunk])
    return pipe, results + pipe.flush()


def test_chunking_does_not_change_results(scene_frames):
    scene, frames = scene_frames
    _, a = run(scene, frames, 1000)
    _, b = run(scene, frames, 7)
    key = [(r.contact.taxels, round(r.contact.onset, 6), r.estimate.label) for r in a]
    assert key == [(r.contact.taxels, round(r.contact.onset, 6), r.estimate.label) for r in b]


def test_neighbouring_taxels_form_one_contact(scene_frames):
    scene, frames = scene_frames
    pipe, results = run(scene, frames, 20)
    in_time = [t for t in scene.touches if t.end <= 10.0]
    groups = {tuple(sorted(t.taxels)) for t in in_time}
    found = {tuple(sorted(r.contact.taxels)) for r in results}
    assert groups <= found
    assert pipe.stats.gaps == 0 and pipe.stats.flagged.sum() == 0


def test_effusivity_of_passive_materials_is_recovered(scene_frames):
    from skin.models import load_materials

    scene, frames = scene_frames
    _, results = run(scene, frames, 20)
    mats = load_materials()
    matches, unmatched = match_touches(scene, [r.contact.taxels for r in results],
                                       [r.contact.onset for r in results])
    assert not unmatched
    errs = []
    for m in matches:
        if m.contact_index is None or m.touch.end > 10.0 or m.material == "human_skin":
            continue
        est = results[m.contact_index].estimate.effusivity
        errs.append(abs(np.log10(est / mats[m.material].effusivity)))
    assert len(errs) >= 5
    assert np.median(errs) < 0.05


def test_joint_classifier_is_right_as_often_and_wrong_far_less_than_the_histogram(
        scene_frames):
    from skin.models import JointClassifier

    scene, frames = scene_frames

    def score(classifier):
        _, results = run(scene, frames, 50, classifier)
        matches, _ = match_touches(scene, [r.contact.taxels for r in results],
                                   [r.contact.onset for r in results])
        pairs = [(results[m.contact_index].estimate.label, m.material) for m in matches
                 if m.contact_index is not None]
        right = sum(a == b for a, b in pairs)
        wrong = sum(a not in (b, "unknown") for a, b in pairs)
        return right, wrong

    joint_right, joint_wrong = score(JointClassifier(scene.layout))
    hist_right, hist_wrong = score(HistogramClassifier(scene.layout))
    assert joint_right >= hist_right >= 1
    assert joint_wrong <= 2 < hist_wrong  # unsure contacts are "unknown", not mislabelled


def test_gaps_are_counted(scene_frames):
    scene, frames = scene_frames
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout))
    pipe.process(frames[:10] + frames[15:30])
    assert pipe.stats.gaps == 5


def test_frame_from_unknown_board_is_an_error(scene_frames):
    scene, frames = scene_frames
    from dataclasses import replace

    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout))
    with pytest.raises(SkinError, match="board 9"):
        pipe.process([replace(frames[0], board=9)])


def test_boards_with_different_rates_are_refused_clearly():
    taxels = [Taxel(0, 0, 0, "l", (0, 0, 0), (1, 0, 0)), Taxel(1, 1, 0, "l", (0, 0, 1), (1, 0, 0))]
    layout = Layout(taxels, [Board(id=0), Board(id=1, sample_rate=100.0)])
    with pytest.raises(SkinError, match="share a sample rate"):
        Pipeline(layout, classifier=None)


def test_spreading_the_work_over_frames_gives_the_same_results_later(scene_frames):
    scene, frames = scene_frames
    _, now = run(scene, frames, 1)
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout), budget=0.0)
    later = []
    for f in frames:
        later += pipe.process([f])
        assert pipe.pending <= 2  # one step a frame keeps up with this scene
    later += pipe.flush()
    key = [(r.contact.taxels, round(r.contact.onset, 6), r.estimate.label) for r in now]
    assert key == [(r.contact.taxels, round(r.contact.onset, 6), r.estimate.label)
                   for r in later]
    # a zero budget still does one step a frame: each taxel's refinement, then the label
    steps = [len(r.contact.taxels) + 1 for r in later]
    waits = [round((r.reported_at - r.contact.decided_at) * 200) for r in later]
    assert all(0 <= w for w in waits) and any(w > 0 for w in waits)
    assert max(waits) <= sum(steps)
    assert all(0 <= r.reported_at - r.contact.decided_at < 1 / 200 + 1e-9 for r in now)
    assert pipe.stats.results == pipe.stats.contacts == len(later)
    # a contact that waited max_wait is finished whatever the budget
    hurry = Pipeline(scene.layout, HistogramClassifier(scene.layout), budget=0.0, max_wait=0.0)
    quick = [r for f in frames for r in hurry.process([f])] + hurry.flush()
    assert all(0 <= r.reported_at - r.contact.decided_at < 1 / 200 + 1e-9 for r in quick)
    assert set(pipe.stats.seconds) == {"assemble", "calibrate", "onset", "track", "refine",
                                       "classify", "sinks"}
    assert pipe.stats.seconds["refine"] > 0 and pipe.stats.seconds["onset"] > 0


def test_sinks_get_every_result_in_order(scene_frames, tmp_path):
    import json

    from skin.stream.sinks import JsonLinesSink

    scene, frames = scene_frames

    class Collect:
        def __init__(self):
            self.got = []

        def write(self, result):
            self.got.append(result)

    collect = Collect()
    with JsonLinesSink(tmp_path / "events.jsonl") as lines:
        pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout), sinks=[lines, collect])
        results = []
        for i in range(0, len(frames), 50):
            results += pipe.process(frames[i : i + 50])
        results += pipe.flush()
    assert collect.got == results and len(results) >= 5
    records = [json.loads(line) for line in (tmp_path / "events.jsonl").read_text().splitlines()]
    assert [r["contact"] for r in records] == [r.contact.id for r in results]
    assert [r["label"] for r in records] == [r.estimate.label for r in results]


def test_finite_contact_makes_the_simulated_contact_slower_but_not_different_in_the_end():
    scene = load_scene("default")
    perfect = SkinSimulator(scene, duration=3.0).temperatures()
    finite = SkinSimulator(scene, duration=3.0, contact="finite").temperatures()
    touch = scene.touches[0]
    i = scene.layout.index(touch.taxels[0])
    k = round(touch.start * 200)
    assert np.allclose(perfect[:k, i], finite[:k, i])  # before the touch: identical
    drop_p = perfect[k, i] - perfect[k + 60, i]
    drop_f = finite[k, i] - finite[k + 60, i]
    assert 0 < drop_f < drop_p  # a contact through an air gap draws heat more slowly
    with pytest.raises(ValueError, match="finite"):
        SkinSimulator(scene, contact="sticky")


def test_provisional_answers_come_before_the_final_one_and_change_nothing_final(scene_frames):
    scene, frames = scene_frames
    _, plain = run(scene, frames, 20)
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout), provisional=(0.5, 1.0))
    given = []
    for i in range(0, len(frames), 13):
        given += pipe.process(frames[i : i + 13])
    given += pipe.flush()
    finals = [r for r in given if r.contact.final]
    key = [(r.contact.taxels, round(r.contact.onset, 6), r.estimate.label) for r in plain]
    assert key == [(r.contact.taxels, round(r.contact.onset, 6), r.estimate.label)
                   for r in finals]
    early = [r for r in given if not r.contact.final]
    assert early and pipe.stats.contacts == len(finals)
    position = {id(r): i for i, r in enumerate(given)}
    final_at = {r.contact.id: position[id(r)] for r in finals}
    for r in early:
        # a snapshot of a contact still open, taken 0.5 or 1 s after its first onset
        assert position[id(r)] < final_at[r.contact.id]
        first = min(w.onset for w in r.contact.windows)
        assert r.contact.release is None and r.contact.decided_at > first
        assert all(w.time[-1] <= r.contact.decided_at - w.onset + 1e-9
                   for w in r.contact.windows)
    # long contacts (the 2.5 s pine touch) get both snapshots, short ones fewer
    per_contact = {}
    for r in early:
        per_contact[r.contact.id] = per_contact.get(r.contact.id, 0) + 1
    assert max(per_contact.values()) == 2
    with pytest.raises(ValueError, match="provisional"):
        Pipeline(scene.layout, HistogramClassifier(scene.layout), provisional=(3.0,))


def test_the_frames_heater_duty_reaches_the_detector(scene_frames):
    """The pipeline tells the onset detector each taxel's duty as the frames carry it
    (`OnsetDetector.process`'s ``duty``): one board's heaters stepped down half-way show in
    the detector's state, lagging through the body's slowest mode; the others held."""
    import dataclasses

    scene, frames = scene_frames
    board = frames[0].board
    half = len(frames) // 2
    stepped = [dataclasses.replace(f, duty=np.full_like(f.duty, 100))
               if f.board == board and i >= half else f for i, f in enumerate(frames)]
    pipe, _ = run(scene, stepped, 50)
    state = pipe._state
    own = np.array([t.board == board for t in scene.layout.taxels])
    assert np.all(state.duty[own] == 100) and np.all(state.duty[~own] == 255)
    # the stepped heaters' lag still holds most of the step (seconds of a ~60 s mode)
    assert np.all(state.duty_lag[own] > 200) and np.all(state.duty_lag[~own] > 255)

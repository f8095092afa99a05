import numpy as np
import pytest

from skin.drivers.sim import SkinSimulator
from skin.errors import SkinError
from skin.layout import Board, Layout, Taxel
from skin.models import HistogramClassifier
from skin.pipeline import Pipeline
from skin.scene import load_scene, match_touches


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


def test_two_boards_are_refused_clearly():
    taxels = [Taxel(0, 0, 0, "l", (0, 0, 0), (1, 0, 0)), Taxel(1, 1, 0, "l", (0, 0, 1), (1, 0, 0))]
    with pytest.raises(SkinError, match="one board"):
        Pipeline(Layout(taxels, [Board(id=0), Board(id=1)]), classifier=None)


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

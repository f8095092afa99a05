"""Onset detection sharded across worker processes (skin.stream.shards, skin run --workers)."""

import dataclasses
import os
import signal

import numpy as np
import pytest

from skin.bench.pipeline import cylinder_layout
from skin.drivers.sim import SkinSimulator
from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.formats.scene import load_scene
from skin.models import HistogramClassifier, JointClassifier
from skin.stream.pipeline import Pipeline
from skin.stream.shards import shard_taxels, sub_detector


def _key(results):
    """Everything of a result but the host clock's times."""
    return [(repr(r.contact), repr(r.estimate), r.reported_at) for r in results]


def test_shards_are_whole_boards_when_there_are_enough():
    layout = cylinder_layout(1000)  # boards of 256, 256, 256, 232
    shards = shard_taxels(layout, 2)
    boards = np.array([t.board for t in layout.taxels])
    assert sorted(np.concatenate(shards).tolist()) == list(range(1000))
    owned = [set(boards[s].tolist()) for s in shards]
    assert owned[0].isdisjoint(owned[1]) and len(owned[0]) == len(owned[1]) == 2
    assert abs(shards[0].size - shards[1].size) <= 256  # balanced to within a board
    one_board = load_scene("default").layout
    halves = shard_taxels(one_board, 2)  # fewer boards than workers: even runs of taxels
    assert [h.size for h in halves] == [36, 36]
    assert len(shard_taxels(one_board, 100)) == 72  # never an empty shard


def test_a_sub_detector_is_the_whole_detector_on_its_taxels():
    scene = load_scene("default")
    frames = list(SkinSimulator(scene, duration=4.0).frames())
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout))
    temperature, _ = pipe.calibration.temperature(np.array([f.counts for f in frames]))
    times = np.array([f.device_time for f in frames])
    taxels = np.arange(10, 30)
    whole, state = pipe.detector.process(times, temperature, pipe.detector.initial_state())
    sub = sub_detector(pipe.detector, taxels)
    part, sub_state = sub.process(times, temperature[:, taxels], sub.initial_state())
    assert [(int(taxels[e.taxel]), e.time, e.kind, e.channel) for e in part] == [
        (e.taxel, e.time, e.kind, e.channel) for e in whole if 10 <= e.taxel < 30]
    assert np.array_equal(sub_state.in_contact, state.in_contact[taxels])


def _two_boards(scene, frames):
    """The scene's skin wired to two boards, even taxels on board 0, odd on 1, and its frames.

    Every contact of two taxels or more then spans both boards (and so both shards).
    """
    layout = scene.layout
    board = next(iter(layout.boards.values()))
    taxels = [dataclasses.replace(t, board=k % 2, address=k // 2)
              for k, t in enumerate(layout.taxels)]
    two = Layout(taxels, [dataclasses.replace(board, id=b) for b in (0, 1)], name="two boards",
                 source="<two boards>")
    address = np.array([t.address for t in layout.taxels])
    split = []
    for f in frames:
        for b in (0, 1):
            channels = address[b::2]
            split.append(dataclasses.replace(
                f, board=b, counts=f.counts[channels], duty=f.duty[channels],
                status=None if f.status is None else f.status[channels]))
    return two, split


def _run(layout, frames, workers, chunk=20):
    pipe = Pipeline(layout, JointClassifier(layout), workers=workers)
    try:
        results = []
        for i in range(0, len(frames), chunk):
            results += pipe.process(frames[i : i + chunk])
        return results + pipe.flush()
    finally:
        pipe.close()


def test_workers_give_the_results_of_one_process_when_contacts_cross_boards():
    scene = load_scene("default")
    layout, frames = _two_boards(scene, list(SkinSimulator(scene, duration=14.0).frames()))
    one = _run(layout, frames, 1)
    two = _run(layout, frames, 2)
    boards = [t.board for t in layout.taxels]
    crossing = [r for r in one if len({boards[k] for k in r.contact.taxels}) > 1]
    assert len(crossing) >= 3, "no contact spans the two boards (shards): the test proves nothing"
    assert _key(two) == _key(one)
    assert _key(_run(layout, frames, 3)) == _key(one)  # a board split across two workers


def test_workers_give_the_results_of_one_process_on_a_large_cylinder():
    from skin.bench.pipeline import run

    one = run(400, 20.0, budget=None, workers=1, keep_results=True)["results"]
    two = run(400, 20.0, budget=None, workers=2, keep_results=True)["results"]
    assert len(one) > 20
    assert _key(two) == _key(one)


def test_skin_run_with_workers_gives_the_events_of_one_process(tmp_path):
    from skin.runner import Skin

    got = {}
    for workers in (1, 3):
        with Skin(speed=0.0, duration=12.0, out=None, map=False, sinks=[],
                  workers=workers) as skin:
            got[workers] = list(skin.results())
            shards = skin.pipeline.onset_workers
            procs = [] if shards is None else [p for p in shards._procs if p is not None]
        assert all(not p.is_alive() for p in procs)  # closed with the Skin
        assert len(procs) == (2 if workers == 3 else 0)  # shard 0 is detected in this process
    assert len(got[1]) >= 5
    assert _key(got[3]) == _key(got[1])


def test_a_worker_that_dies_is_named_and_the_blocks_before_were_observed():
    scene = load_scene("default")
    frames = list(SkinSimulator(scene, duration=2.0).frames())
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout), workers=2).start()
    seen = []
    pipe.observers.append(lambda times, temperature, host: seen.append(len(times)))
    try:
        pipe.process(frames[:20])
        pid = pipe.onset_workers._procs[1].pid
        os.kill(pid, signal.SIGKILL)
        with pytest.raises(SkinError, match=rf"onset worker 1 \(pid {pid}, 36 taxels of "
                                            r"board 0\) died \(exit code -9\)"):
            pipe.process(frames[20:40])
        assert seen == [20, 20]  # the block the dead worker missed was calibrated and observed
    finally:
        pipe.close()
    assert not pipe.in_contact().any()
    pipe.close()  # idempotent


def test_workers_must_be_at_least_one():
    from skin.setup import Setup

    scene = load_scene("default")
    with pytest.raises(ValueError, match="workers must be >= 1"):
        Pipeline(scene.layout, HistogramClassifier(scene.layout), workers=0)
    with pytest.raises(SkinError, match="workers: must be a whole number of at least 1"):
        Setup().updated({"workers": 0}, "command line")

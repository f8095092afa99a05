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
    # the board common mode needs its whole board in one shard: never split then
    assert [h.size for h in shard_taxels(one_board, 2, whole_boards=True)] == [72]
    assert len(shard_taxels(layout, 8, whole_boards=True)) == 4


def test_with_the_common_mode_a_board_is_never_split_across_workers():
    scene = load_scene("default")
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout), workers=2, common_mode=True)
    try:
        assert pipe.detector.common_active
        pipe.start()
        # one board of 72: one shard, detected in this process (no worker started)
        assert [sh.size for sh in pipe.onset_workers.shards] == [72]
    finally:
        pipe.close()
    # the default ("auto"): on for the default skin's constant-power heaters, so the same
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout), workers=2)
    try:
        assert pipe.detector.common_active
        pipe.start()
        assert [sh.size for sh in pipe.onset_workers.shards] == [72]
    finally:
        pipe.close()


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
                status=None if f.status is None else f.status[channels],
                force=None if f.force is None else f.force[channels]))
    return two, split


def _run(layout, frames, workers, chunk=20, **options):
    pipe = Pipeline(layout, JointClassifier(layout), workers=workers, **options)
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
    # the default skin is one board: split across workers only without the board common mode
    # (on by default for its constant-power heaters: then one process, see below)
    for workers in (1, 3):
        with Skin(speed=0.0, duration=12.0, out=None, map=False, sinks=[],
                  workers=workers, common_mode=False) as skin:
            got[workers] = list(skin.results())
            shards = skin.pipeline.onset_workers
            procs = [] if shards is None else [p for p in shards._procs if p is not None]
        assert all(not p.is_alive() for p in procs)  # closed with the Skin
        assert len(procs) == (2 if workers == 3 else 0)  # shard 0 is detected in this process
    assert len(got[1]) >= 5
    assert _key(got[3]) == _key(got[1])


def _force_frames(seconds):
    """The default scene with a force sensor on every taxel, wired to two boards."""
    scene = dataclasses.replace(load_scene("default"), force="force")
    layout, frames = _two_boards(scene, list(SkinSimulator(scene, duration=seconds).frames()))
    assert frames[0].force is not None
    return layout, frames


def _dated(results):
    """Each final contact's taxels, onset, release and its windows' dating source."""
    return [(r.contact.taxels, r.contact.onset, r.contact.release,
             [w.dated_by for w in r.contact.windows]) for r in results if r.contact.final]


def test_onset_workers_carry_the_force_channel():
    """skin run --workers N on a simulated scene shards onset detection alone; the force is
    merged in this process: the same contacts, dated by the force, as one process."""
    layout, frames = _force_frames(10.0)
    one = _run(layout, frames, 1)
    assert any("force" in k[3] for k in _dated(one))
    for workers in (2, 3):
        assert _key(_run(layout, frames, workers, common_mode=False)) == _key(one), workers
    assert _dated(_run(layout, frames, 2, common_mode=False)) == _dated(one)


def test_a_worker_that_dies_is_named_and_the_blocks_before_were_observed():
    scene = load_scene("default")
    frames = list(SkinSimulator(scene, duration=2.0).frames())
    # one board split across two workers: only without the board common mode
    pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout), workers=2,
                    common_mode=False).start()
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


# --- boards in worker processes (skin.stream.board_workers) ----------------------------------
def _board_workers(layout, shards, block=10):
    from skin.stream.board_workers import BoardWorkers

    pipe = Pipeline(layout, JointClassifier(layout))
    results = []
    with BoardWorkers(pipe, shards, block=block) as bw:
        while not bw.done:
            results += bw.feed(bw.blocks())
        results += bw.finish()
    return results, pipe


def test_board_workers_give_the_results_of_one_process_when_contacts_cross_boards():
    from skin.stream.board_workers import FramesSource

    scene = load_scene("default")
    layout, frames = _two_boards(scene, list(SkinSimulator(scene, duration=14.0).frames()))
    one = _run(layout, frames, 1)  # 20 frames of two boards: blocks of 10 samples
    shards = [([b], FramesSource(tuple(f for f in frames if f.board == b), step=7))
              for b in (0, 1)]
    two, pipe = _board_workers(layout, shards, block=10)
    boards = [t.board for t in layout.taxels]
    assert len([r for r in one if len({boards[k] for k in r.contact.taxels}) > 1]) >= 3
    assert _key(two) == _key(one)
    assert pipe.stats.frames == len(frames) and pipe.stats.samples == len(frames) // 2


def test_board_workers_carry_the_force_channel():
    """Boards read in workers passed no force: their taxels were dated thermally. Now the
    parent merges each block's force as one process does: the same contacts, onsets, dating
    sources and labels; and with force_onsets off, every window thermal again."""
    from skin.stream.board_workers import BoardWorkers, FramesSource

    layout, frames = _force_frames(14.0)
    one = _run(layout, frames, 1)  # 20 frames of two boards: blocks of 10 samples
    dated = _dated(one)
    assert sum(k[3].count("force") for k in dated) >= 10
    shards = [([b], FramesSource(tuple(f for f in frames if f.board == b), step=7))
              for b in (0, 1)]
    two, pipe = _board_workers(layout, shards, block=10)
    assert _dated(two) == dated
    assert _key(two) == _key(one)
    assert pipe.force is not None and pipe.force.onsets > 0
    # without force on one board's first frames: None there, NaN-filled blocks after
    late = [dataclasses.replace(f, force=None) if f.board == 1 and f.seq < 333 else f
            for f in frames]
    ref = _run(layout, late, 1)
    shards = [([b], FramesSource(tuple(f for f in late if f.board == b), step=7))
              for b in (0, 1)]
    assert _key(_board_workers(layout, shards, block=10)[0]) == _key(ref)
    pipe = Pipeline(layout, JointClassifier(layout), force_onsets=False)
    off = []
    with BoardWorkers(pipe, [([b], FramesSource(tuple(f for f in frames if f.board == b)))
                             for b in (0, 1)], block=10) as bw:
        while not bw.done:
            off += bw.feed(bw.blocks())
        off += bw.finish()
    assert off and all(set(k[3]) == {"thermal"} for k in _dated(off))


def test_board_workers_join_a_sample_one_shard_lost_as_one_process_does():
    from skin.stream.board_workers import FramesSource

    scene = load_scene("default")
    layout, frames = _two_boards(scene, list(SkinSimulator(scene, duration=10.0).frames()))
    lost = {(1, 300), (1, 301), (1, 1200)}  # board 1 loses three frames
    frames = [f for f in frames if (f.board, f.seq) not in lost]
    ref = Pipeline(layout, JointClassifier(layout))
    one = ref.process(frames) + ref.flush()
    shards = [([b], FramesSource(tuple(f for f in frames if f.board == b), step=13))
              for b in (0, 1)]
    two, pipe = _board_workers(layout, shards, block=25)
    # blocks of other sizes: the same contacts and labels (a result's report time may move)
    assert len(one) >= 3
    assert [(repr(r.contact), repr(r.estimate)) for r in two] == [
        (repr(r.contact), repr(r.estimate)) for r in one]
    assert pipe.stats.gaps == ref.stats.gaps == 3  # frames missing by sequence numbers
    assert pipe.stats.samples == ref.stats.samples == 2000
    assert np.array_equal(pipe.stats.flagged, ref.stats.flagged)
    assert pipe.stats.flagged.sum() == 3 * 36


def test_board_workers_open_their_own_serial_ports():
    """Two simulated boards on pseudo-terminals, each opened and read by its own worker."""
    from skin.bench.soak import soak_scenes
    from skin.drivers import open as open_driver
    from skin.drivers.sim import PtySerialDevice
    from skin.stream.board_workers import UrlSource

    layout, scenes = soak_scenes(512, 40.0, seed=3)

    def devices():
        return [PtySerialDevice(SkinSimulator(s), speed=0) for s in scenes]

    # one process: the boards read in turn, 10 samples a block
    devs = devices()
    drivers = [open_driver(f"serial://{d.port}?board={d.simulator.board.id}") for d in devs]
    for d in devs:
        d.start()
    ref = Pipeline(layout, JointClassifier(layout))
    one, batch = [], []
    try:
        while True:
            for drv in drivers:
                f = drv.recv(timeout=2.0)
                if f is not None:
                    batch.append(f)
            if len(batch) == 20 or (batch and all(d.done.is_set() for d in devs)):
                one += ref.process(batch)
                batch = []
            if all(d.done.is_set() for d in devs) and ref.stats.frames >= sum(
                    d.frames_sent for d in devs):
                break
        one += ref.flush()
    finally:
        for c in drivers + devs:
            c.close()
    devs = devices()
    try:
        from skin.stream.board_workers import BoardWorkers

        pipe = Pipeline(layout, JointClassifier(layout))
        two = []
        shards = [([d.simulator.board.id],
                   UrlSource((f"serial://{d.port}?board={d.simulator.board.id}",)))
                  for d in devs]
        with BoardWorkers(pipe, shards, block=10) as bw:  # the ports open before any frame
            for d in devs:
                d.start()
            while not (all(d.done.is_set() for d in devs)
                       and bw.frames >= sum(d.frames_sent for d in devs)):
                two += bw.feed(bw.blocks())
            two += bw.finish()
    finally:
        for d in devs:
            d.close()
    assert len(one) >= 6 and ref.stats.frames == 2 * 8000
    assert _key(two) == _key(one)
    assert pipe.stats.frames == ref.stats.frames and pipe.stats.gaps == 0


def test_a_board_worker_that_dies_is_named_with_its_exit_code():
    from skin.stream.board_workers import BoardWorkers, FramesSource

    scene = load_scene("default")
    layout, frames = _two_boards(scene, list(SkinSimulator(scene, duration=30.0).frames()))
    pipe = Pipeline(layout, HistogramClassifier(layout))
    shards = [([b], FramesSource(tuple(f for f in frames if f.board == b), step=1))
              for b in (0, 1)]
    with BoardWorkers(pipe, shards, block=10) as bw:
        pipe_blocks = bw.blocks(1.0)
        bw.feed(pipe_blocks)
        pid = bw._procs[1].pid
        os.kill(pid, signal.SIGKILL)
        with pytest.raises(SkinError, match=rf"board worker 1 \(pid {pid}, 36 taxels of board "
                                            r"1\) died \(exit code -9\)"):
            while True:
                bw.feed(bw.blocks(1.0))
    assert all(not p.is_alive() for p in bw._procs) if bw._procs else True


def test_board_workers_check_their_boards_and_ports_before_the_first_frame():
    from skin.stream.board_workers import BoardWorkers, UrlSource

    layout = cylinder_layout(600)  # boards 0, 1, 2
    pipe = Pipeline(layout, HistogramClassifier(layout))
    with pytest.raises(SkinError, match=r"board \[2\] of .* given to no worker"):
        BoardWorkers(pipe, [([0], UrlSource(())), ([1], UrlSource(()))])
    with pytest.raises(SkinError, match="board 1 is given to workers 0 and 1"):
        BoardWorkers(pipe, [([0, 1], UrlSource(())), ([1, 2], UrlSource(()))])
    with pytest.raises(SkinError, match=r"board worker 1 \(.*\) could not open its boards: "
                                        r".*/dev/no-such-port"):
        BoardWorkers(pipe, [([0, 1], UrlSource(())),
                            ([2], UrlSource(("serial:///dev/no-such-port?board=2",)))])


def _two_serial_boards(tmp_path, seconds: float, duration: float, force: str = ""):
    """skin run --port A --port B --workers 2 on two simulated serial boards (ptys).

    Returns the layout, the boards' scenes, the final results and the run's summary."""
    from skin.bench.soak import soak_scenes
    from skin.drivers.sim import PtySerialDevice
    from skin.formats.layout import layout_toml
    from skin.runner import Skin

    layout, scenes = soak_scenes(512, seconds, seed=5)  # touches at 2, 11.3, 20.7 s per board
    if force:
        scenes = [dataclasses.replace(s, force=force) for s in scenes]
    path = tmp_path / "two_boards.toml"
    path.write_text(layout_toml(layout))
    devs = [PtySerialDevice(SkinSimulator(s), speed=4.0) for s in scenes]
    try:
        ports = [f"serial://{d.port}?board={d.simulator.board.id}" for d in devs]
        with Skin(port=ports, layout=str(path), workers=2, duration=duration, out=None,
                  map=False, sinks=[]) as skin:
            skin.open()
            assert len(skin._workers.shards) == 2
            for d in devs:
                d.start()
            got = [r for r in skin.results() if r.contact.final]
            summary = skin.finish()
    finally:
        for d in devs:
            d.close()
    return layout, scenes, got, summary


def test_skin_with_workers_reads_each_serial_board_in_its_own_worker(tmp_path):
    """skin run --port A --port B --workers 2: each worker opens its port; every touch found."""
    layout, scenes, got, summary = _two_serial_boards(tmp_path, 25.0, 24.0)
    touches = sorted((sorted(layout.index(i) for i in t.taxels), t.start)
                     for s in scenes for t in s.touches if t.start < 22.0)
    found = sorted((sorted(r.contact.taxels), r.contact.onset) for r in got)
    assert len(found) == len(touches) == 6
    for (taxels, onset), (want, start) in zip(found, touches, strict=True):
        assert taxels == want and abs(onset - start) < 0.3
    assert summary["contacts"] == 6 and summary["gaps"] == 0 and summary["crc_errors"] == 0


def test_skin_with_workers_on_serial_boards_dates_by_their_force(tmp_path):
    """skin run --port A --port B --workers 2 (board workers) on boards sending FORCE: the
    contacts are dated by it (they were thermal: the workers dropped the force)."""
    _, scenes, got, summary = _two_serial_boards(tmp_path, 14.0, 13.0, force="force")
    starts = [t.start for s in scenes for t in s.touches if t.start < 12.0]
    assert len(got) == len(starts) >= 2
    assert all(w.dated_by == "force" for r in got for w in r.contact.windows)
    for r in got:
        assert min(abs(r.contact.onset - s) for s in starts) < 0.006
    assert summary["force"]["dated_taxels"]


@pytest.mark.parametrize("sensor", ["paper", "fast-film", "low-cost", "pid-logger"])
def test_a_sub_detector_keeps_the_whole_noise_table(sensor):
    from skin.stream.onset import OnsetDetector

    table = OnsetDetector(5, sensor=sensor)._drop_sd
    # as many taxels as the table has entries: only the per-taxel arrays are sliced
    whole = OnsetDetector(table.size, sensor=sensor)
    half = np.arange(table.size // 2, table.size)
    sub = sub_detector(whole, half)
    assert sub.n_taxels == half.size
    assert np.array_equal(sub._drop_sd, table)
    assert np.array_equal(sub.sigma, whole.sigma[half])
    # every per-taxel array of a detector is in PER_TAXEL (else a shard would get the whole)
    small = OnsetDetector(7, sensor=sensor)
    per_taxel = {k for k, v in vars(small).items()
                 if isinstance(v, np.ndarray) and v.shape == (7,)}
    assert per_taxel <= set(OnsetDetector.PER_TAXEL)


@pytest.mark.parametrize("workers", [2, 3])
def test_workers_give_the_events_of_one_process_with_the_common_mode_on_several_boards(workers):
    """``skin run --workers N`` (`OnsetShards`) with the board common mode on a layout of
    three boards (16, 16, 8 taxels), wired interleaved (a board's taxels are no run in layout
    order): the events of one process, every field, through a stream whose room the common
    mode takes off (tests/test_onset_pinned.py's, low-cost: it engages on every board), the
    heater duty told as the pinned duty case's (stepping down, up, and not known)."""
    from test_onset_pinned import BOARDS, heater_duty, stream

    from skin.formats.layout import Board, Taxel
    from skin.stream.onset import OnsetDetector
    from skin.stream.shards import OnsetShards

    t, y = stream("low-cost", 200.0)
    n = sum(BOARDS)
    # board of each layout index: the pinned stream's boards, dealt out interleaved
    own = np.repeat(np.arange(len(BOARDS)), BOARDS)
    order = np.argsort(np.arange(n) % 5, kind="stable")  # layout index -> stream column
    boards = own[order]
    y = y[:, order]
    duty = heater_duty(t)[:, order]
    layout = Layout([Taxel(k, int(boards[k]), k, "forearm", (0.0, 0.0, 0.01 * k), (1.0, 0.0, 0.0))
                     for k in range(n)], [Board(id=b) for b in range(len(BOARDS))],
                    name="three boards, interleaved", source="<three boards>")
    detector = OnsetDetector(n, sensor="low-cost", boards=boards)  # the default: on
    assert detector.common_active and detector._groups().order is not None
    state = detector.initial_state()
    one, engaged = [], set()
    shards = OnsetShards(detector, layout, workers)
    try:
        assert len(shards.shards) == min(workers, len(BOARDS))  # whole boards
        many = []
        for k in range(0, t.size, 10):
            got, state = detector.process(t[k:k + 10], y[k:k + 10], state,
                                          duty=duty[k:k + 10])
            one += got
            engaged |= set(boards[state.common != 0.0].tolist())
            many += shards.process(t[k:k + 10], y[k:k + 10], duty[k:k + 10])
    finally:
        shards.close()
    assert engaged == set(range(len(BOARDS)))  # the room taken off on every board
    assert sum(e.kind == "onset" for e in one) >= 10
    assert [(e, e.channel) for e in many] == [(e, e.channel) for e in one]

import numpy as np
import pytest

from skin.errors import SkinError
from skin.formats.layout import Board, Layout, Taxel
from skin.frame import Frame
from skin.stream.assembly import FrameAssembler
from skin.stream.calibration import TAXEL_MISSING, Calibration


def two_boards():
    # taxel ids 0-3; board 1 wires its taxels to channels 1 and 0 (reversed)
    wiring = [(0, 0), (1, 1), (0, 1), (1, 0)]  # (board, channel) of taxels 0-3
    taxels = [Taxel(i, b, c, "l", (0, 0, 0.01 * i), (1, 0, 0)) for i, (b, c) in enumerate(wiring)]
    return Layout(taxels, [Board(id=0), Board(id=1)])


def frame(board, seq, counts, ambient=25.0):
    return Frame(seq=seq, device_time=seq / 200, host_time=0.0,
                 counts=np.array(counts, dtype=np.uint16), ambient=ambient,
                 duty=np.full(len(counts), 200, dtype=np.uint8), board=board)


def test_frames_of_two_boards_become_one_sample_in_layout_order():
    asm = FrameAssembler(two_boards())
    out = asm.push([frame(0, 0, [10, 20]), frame(1, 0, [30, 40], ambient=27.0)])
    assert np.array_equal(out.counts, [[10, 40, 20, 30]])
    assert out.ambient.tolist() == [26.0] and out.times.tolist() == [0.0]
    # board 1 ahead, board 0 behind, in any order within the skew
    assert len(asm.push([frame(1, 1, [1, 2]), frame(1, 2, [3, 4])])) == 0
    out = asm.push([frame(0, 1, [5, 6]), frame(0, 2, [7, 8])])
    assert np.array_equal(out.counts, [[5, 2, 6, 1], [7, 4, 8, 3]])
    assert asm.stats.frames == 6 and asm.stats.samples == 3


def test_a_board_that_falls_behind_is_missing_and_flagged_and_its_late_frame_dropped():
    layout = two_boards()
    asm = FrameAssembler(layout, max_skew=3)
    out = asm.push([frame(0, s, [100 + s, 0 + s]) for s in range(6)])
    assert len(out) == 2  # samples 0 and 1 are more than 3 behind board 0's sample 5
    assert np.isnan(out.counts[:, [1, 3]]).all() and not np.isnan(out.counts[:, [0, 2]]).any()
    assert asm.stats.missing == {0: 0, 1: 2}
    asm.push([frame(1, 0, [9, 9])])
    assert asm.stats.late == 1
    out = asm.flush()
    assert len(out) == 4 and asm.stats.samples == 6
    _, status = Calibration.from_layout(layout).temperature(out.counts)
    assert (status[:, [1, 3]] == TAXEL_MISSING).all()


def test_gaps_are_counted_per_board_and_sequence_numbers_may_wrap():
    layout = Layout([Taxel(0, 0, 0, "l", (0, 0, 0), (1, 0, 0))], [Board(id=0)])
    asm = FrameAssembler(layout)
    top = (1 << 32) - 2
    out = asm.push([frame(0, top, [1]), frame(0, top + 1, [2]), frame(0, 0, [3]),
                    frame(0, 3, [4])])
    assert np.array_equal(out.counts[:, 0], [1, 2, 3, 4])
    assert asm.stats.gaps == {0: 2} and asm.stats.late == 0


def test_bad_frames_are_errors_that_name_the_board_and_channel():
    asm = FrameAssembler(two_boards())
    with pytest.raises(SkinError, match="board 7"):
        asm.push([frame(7, 0, [1, 2])])
    with pytest.raises(SkinError, match=r"board 1 has 1 channels.*channel 1"):
        asm.push([frame(1, 0, [1])])


def test_a_skin_of_two_boards_runs_through_the_pipeline():
    from skin.drivers.sim import SkinSimulator
    from skin.formats.scene import load_scene
    from skin.models import HistogramClassifier
    from skin.stream.pipeline import Pipeline

    scene = load_scene("default")
    one = scene.layout
    # the same taxels split over two boards: odd taxel ids move to board 1, same channels
    split = Layout([Taxel(t.id, t.id % 2, t.address, t.link, t.position, t.normal)
                    for t in one.taxels],
                   [one.boards[0], Board(**{**one.boards[0].__dict__, "id": 1})])
    frames = list(SkinSimulator(scene, duration=5.0).frames())
    both = [f2 for f in frames for f2 in (f, Frame(**{**f.__dict__, "board": 1}))]
    a = Pipeline(one, HistogramClassifier(one))
    b = Pipeline(split, HistogramClassifier(split))
    ra = a.process(frames) + a.flush()
    rb = b.process(both) + b.flush()
    assert len(ra) >= 3
    assert [(r.contact.taxels, r.estimate.label) for r in ra] == \
        [(r.contact.taxels, r.estimate.label) for r in rb]
    assert b.stats.frames == 2 * len(frames) and b.stats.samples == len(frames)


def test_an_incomplete_sample_waits_for_the_board_behind_on_the_host_clock():
    now = [0.0]
    asm = FrameAssembler(two_boards(), wait=0.5, clock=lambda: now[0])
    # board 1 far ahead (a threaded reader's burst): nothing leaves, nothing is lost
    assert len(asm.push([frame(1, s, [s, s]) for s in range(100)])) == 0
    now[0] = 0.4
    out = asm.push([frame(0, s, [s, s]) for s in range(60)])
    assert len(out) == 60 and not np.isnan(out.counts).any()
    # board 0 dead: after `wait` host seconds its samples leave without it ...
    now[0] = 0.51
    out = asm.push([frame(1, 100, [1, 1])])
    assert len(out) == 40 and np.isnan(out.counts[:, [0, 2]]).all()
    assert asm.stats.missing == {0: 40, 1: 0} and asm.stats.late == 0
    # ... and its frames that still come for them are counted late
    asm.push([frame(0, s, [s, s]) for s in range(60, 70)])
    assert asm.stats.late == 10 and asm.stats.frames == 171


def test_the_memory_bound_lets_a_sample_leave_without_its_board():
    asm = FrameAssembler(two_boards(), max_skew=50, wait=100.0)
    out = asm.push([frame(1, s, [s, s]) for s in range(60)])
    assert len(out) == 9 and asm.stats.missing == {0: 9, 1: 0}


def test_one_board_leaves_every_sample_at_once():
    layout = Layout([Taxel(0, 0, 0, "l", (0, 0, 0), (1, 0, 0))], [Board(id=0)])
    asm = FrameAssembler(layout, wait=100.0)
    assert len(asm.push([frame(0, s, [s]) for s in range(5)])) == 5


def test_two_serial_boards_read_in_threads_lose_no_frame_when_one_lags(tmp_path):
    """Two boards on real pseudo-terminals read by one BackgroundReader (a thread a port),
    board 0 started 0.3 s (1.2 s of samples at 4x real time) after board 1: every frame is
    merged, none is late, every touch is found and there is no false contact."""
    import time

    from skin.bench.soak import soak_scenes
    from skin.drivers.sim import PtySerialDevice, SkinSimulator
    from skin.formats.layout import layout_toml
    from skin.runner import Skin

    layout, scenes = soak_scenes(512, 25.0, seed=5)  # touches at 2, 11.3 and 20.7 s per board
    path = tmp_path / "two_boards.toml"
    path.write_text(layout_toml(layout))
    devs = [PtySerialDevice(SkinSimulator(s), speed=4.0) for s in scenes]
    try:
        ports = [f"serial://{d.port}?board={d.simulator.board.id}" for d in devs]
        with Skin(port=ports, layout=str(path), workers=1, duration=20.0, out=None,
                  map=False, sinks=[]) as skin:
            skin.open()
            devs[1].start()
            time.sleep(0.3)
            devs[0].start()
            got = [r for r in skin.results() if r.contact.final]
            summary = skin.finish()
            asm = skin.pipeline.assembler.stats
    finally:
        for d in devs:
            d.close()
    assert summary["late"] == 0 and asm.late == 0, asm
    touches = sorted((sorted(layout.index(i) for i in t.taxels), t.start)
                     for s in scenes for t in s.touches if t.start < 18.0)
    found = sorted((sorted(r.contact.taxels), r.contact.onset) for r in got)
    assert len(found) == len(touches) == 4, found
    for (taxels, onset), (want, start) in zip(found, touches, strict=True):
        assert taxels == want and abs(onset - start) < 0.3


def test_late_frames_are_counted_in_the_pipeline_and_its_health():
    from skin.models import HistogramClassifier
    from skin.stream.pipeline import Pipeline
    from skin.stream.publish import health_payload

    layout = two_boards()
    pipe = Pipeline(layout, HistogramClassifier(layout), skew_wait=0.0)  # a board behind is lost
    pipe.process([frame(1, s, [30000, 30000]) for s in range(10)])
    pipe.process([frame(0, s, [30000, 30000]) for s in range(4)])
    assert pipe.stats.late == 4 and pipe.assembler.stats.missing == {0: 10, 1: 0}
    assert health_payload(pipe, "arm")["late"] == 4


def test_holes_of_a_lost_board_make_no_false_contact():
    """The default scene on two boards (even taxels on board 0, odd on 1), board 0's frames
    lost half the time in 0.5 s holes: a free taxel read again after a hole longer than the
    warm-up starts again rather than extrapolating its trend across it, so no hole becomes a
    contact."""
    import dataclasses

    from skin.drivers.sim import SkinSimulator
    from skin.formats.scene import load_scene, match_touches
    from skin.models import JointClassifier
    from skin.stream.pipeline import Pipeline

    scene = load_scene("default")
    sim = SkinSimulator(scene, duration=10.0)
    one = scene.layout
    board = next(iter(one.boards.values()))
    layout = Layout([dataclasses.replace(t, board=k % 2, address=k // 2)
                     for k, t in enumerate(one.taxels)],
                    [dataclasses.replace(board, id=b) for b in (0, 1)], source="<two boards>")
    address = np.array([t.address for t in one.taxels])
    frames = [dataclasses.replace(f, board=b, counts=f.counts[address[b::2]],
                                  duty=f.duty[address[b::2]], status=None)
              for f in sim.frames() for b in (0, 1) if not (b == 0 and f.seq % 200 < 100)]
    pipe = Pipeline(layout, JointClassifier(layout), skew_wait=0.0)
    results = []
    for i in range(0, len(frames), 20):
        results += pipe.process(frames[i : i + 20])
    final = [r for r in results + pipe.flush() if r.contact.final]
    assert pipe.assembler.stats.missing[0] == 1000 and pipe.stats.late == 0
    touches = dataclasses.replace(scene, touches=tuple(t for t in scene.touches
                                                      if t.start < 10.0))
    matches, false = match_touches(touches, [[int(layout.ids[k]) for k in r.contact.taxels]
                                             for r in final],
                                   [r.contact.onset for r in final])
    assert false == [], [(final[i].contact.onset, final[i].contact.taxels) for i in false]
    # every touch on a board-1 taxel (read throughout) is found
    odd = [m for m in matches if any(i % 2 for i in m.touch.taxels)]
    assert odd and all(m.contact_index is not None for m in odd)

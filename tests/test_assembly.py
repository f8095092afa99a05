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

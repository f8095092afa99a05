"""A CAN node's heater duties arrive a group of 8 per sample (DUTY frame, seq mod the groups):
the duties not heard yet are not known (`Frame.duty_known`; NaN in the assembled samples),
not duties of 0, which the onset detector would take for a heater switched off (its lag
started at 0: no heater allowance for a body mode, the review's false onsets over CAN)."""

import numpy as np

from skin.drivers.protocol import CanReassembler, can_sample_frames
from skin.formats.layout import Board, Layout, Taxel
from skin.stream.assembly import FrameAssembler

N = 20  # duty groups of 8, 8, 4: a group per sample


def test_duties_not_heard_yet_are_not_known_until_every_group_came():
    duty = (np.arange(N) * 7 + 50).astype(np.uint8)
    wire = []
    for seq in range(5):
        wire += can_sample_frames(1, seq, seq * 5000, np.arange(N) + 100, 24.0, duty)
    frames = CanReassembler(boards={1: 1}).feed(wire)
    assert len(frames) == 5
    heard = [None if f.duty_known is None else f.duty_known.tolist() for f in frames]
    assert heard[0] == [True] * 8 + [False] * 12
    assert heard[1] == [True] * 16 + [False] * 4
    assert heard[2:] == [None, None, None]  # every group heard: every duty known
    assert np.array_equal(frames[0].duty[:8], duty[:8]) and not frames[0].duty[8:].any()
    assert all(np.array_equal(f.duty, duty) for f in frames[2:])
    # assembled in layout order (a reversed wiring): NaN where not known, else the duty
    layout = Layout([Taxel(i, 1, N - 1 - i, "l", (0, 0, 0.01 * i), (1, 0, 0)) for i in range(N)],
                    [Board(id=1)])
    samples = FrameAssembler(layout).push(frames)
    want = np.tile(duty[::-1].astype(float), (5, 1))
    want[0, : N - 8] = np.nan  # channels 8-19 are taxels 11..0
    want[1, : N - 16] = np.nan
    np.testing.assert_array_equal(samples.duty, want)

"""Progress lines of long jobs (issue 20 item 6)."""

import io
import time

from skin.commands.evaluate import _time_left
from skin.progress import Progress


def test_the_last_state_of_a_bar_is_printed_off_a_terminal():
    # `skin simulate trials` stopped its bar at 500/5500 in a log: the later states came
    # within the 2 s pacing of the first and were swallowed
    out = io.StringIO()
    progress = Progress(out)
    started = time.monotonic()
    for k in range(1, 12):
        progress.bar(500 * k, 5500, "trials", started)
    lines = out.getvalue().splitlines()
    assert "500/5500" in lines[0]
    assert "5500/5500" in lines[-1]
    assert len(lines) == 2  # the pacing still holds in between


def test_the_time_left_of_an_evaluation_comes_from_the_method_itself():
    # the count-based estimate was 19 s with 262 s left (hmm after svm-pca: 10x the cost,
    # growing with the window); now each method extrapolates its own steps and the methods
    # not started yet are named, not guessed
    hmm = [(0.25, 21.3), (0.5, 28.6), (1.0, 56.6), (2.5, 155.1)]  # measured, seconds
    durations = [0.25, 0.5, 1.0, 2.5]
    assert "unknown" in _time_left([], durations, 1)
    assert "1 more method not timed yet" in _time_left(hmm[:1], durations[1:], 1)
    for j in (1, 2, 3):
        said = float(_time_left(hmm[:j], durations[j:], 0).split()[1])
        actual = sum(t for _, t in hmm[j:])
        assert actual / 2.5 < said < actual * 2.5  # measured 0.58, 0.45, 0.70 of it
    flat = [(0.25, 4.6), (0.5, 5.8), (1.0, 4.7), (2.5, 3.9)]  # svm-pca
    said = float(_time_left(flat[:2], durations[2:], 0).split()[1])
    assert 8.6 / 2 < said < 8.6 * 2

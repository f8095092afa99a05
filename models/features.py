"""Features of a contact: the window of samples after onset (the paper's section III-D)."""

from __future__ import annotations

import numpy as np

from skin.dataset import TrialSet
from skin.errors import SkinError


def window(data: TrialSet, duration: float) -> np.ndarray:
    """Return the first ``duration`` seconds after each trial's onset, (n_trials, n).

    Raises `skin.errors.SkinError` naming the trial when a trial is too short or its onset
    is unknown (-1; onset detection on datasets comes with the classifiers' evaluation).
    """
    n = round(duration * data.fs)
    if n < 1:
        raise SkinError(f"a {duration} s window holds no sample at {data.fs} Hz")
    unknown = np.flatnonzero(data.onset < 0)
    if unknown.size:
        raise SkinError(f"{data.source}: trial {int(unknown[0])} has onset -1 (unknown); "
                        f"{unknown.size} trial(s) need the onset detector first")
    short = np.flatnonzero(data.onset + n > data.temperature.shape[1])
    if short.size:
        i = int(short[0])
        raise SkinError(f"{data.source}: trial {i} has {data.temperature.shape[1] - data.onset[i]}"
                        f" samples after onset, fewer than the {n} of a {duration} s window")
    idx = data.onset[:, None] + np.arange(n)[None, :]
    return np.take_along_axis(data.temperature, idx, axis=1)

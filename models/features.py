"""Features of a contact: the window of samples after onset and its slope (paper III-D).

Classifiers take one row per trial laid out by `trial_matrix`::

    [ambient, T0, T(onset), T(onset + 1), ..., T(onset + n - 1)]

``T0`` is the sensor temperature just before contact (the mean of up to ``PRE`` samples
before onset). Keeping ambient and T0 in the row lets every method, physical or learned,
be a plain scikit-learn estimator on a 2-D array.

The slope is the first difference through a causal 8th-order Butterworth low-pass (2 Hz at
200 Hz) in second-order sections. The transfer-function form of this filter holds its poles
(all near z = 1) in one 8th-degree polynomial, whose rounding moves them: at 2 Hz by 6e-6
(a 1e-5 error in the DC gain), at 0.5 Hz out of the unit circle, where it diverges. The
sections keep every pole exact (a test shows both).
"""

from __future__ import annotations

import numpy as np

from skin.errors import SkinError
from skin.formats.dataset import TrialSet

PRE = 10  # samples before onset averaged into T0
KINDS = ("raw", "slope", "both")


def window(data: TrialSet, duration: float, channel: int | slice = 0) -> np.ndarray:
    """Return the first ``duration`` seconds after each trial's onset, (n_trials, n).

    ``channel`` picks the channel (default the primary); ``slice(None)`` returns every channel,
    (n_trials, n_channels, n).

    Raises `skin.errors.SkinError` naming the trial when a trial is too short or its onset
    is unknown (-1: run `skin.models.features.detect_onsets` first).
    """
    n = round(duration * data.fs)
    if n < 1:
        raise SkinError(f"a {duration} s window holds no sample at {data.fs} Hz")
    unknown = np.flatnonzero(data.onset < 0)
    if unknown.size:
        raise SkinError(f"{data.source}: trial {int(unknown[0])} has onset -1 (unknown); "
                        f"{unknown.size} trial(s) need the onset detector first")
    m = data.temperature.shape[-1]
    short = np.flatnonzero(data.onset + n > m)
    if short.size:
        i = int(short[0])
        raise SkinError(f"{data.source}: trial {i} has {m - data.onset[i]}"
                        f" samples after onset, fewer than the {n} of a {duration} s window")
    idx = data.onset[:, None, None] + np.arange(n)[None, None, :]
    out = np.take_along_axis(data.temperature, np.broadcast_to(
        idx, (*data.temperature.shape[:2], n)), axis=2)
    return out[:, 0] if channel == 0 else out[:, channel]


def trial_matrix(data: TrialSet, duration: float) -> np.ndarray:
    """Rows ``[ambient, T0, window...]`` for every trial (see the module docstring)."""
    w = window(data, duration)
    first = np.maximum(data.onset - PRE, 0)
    t0 = np.array([data.primary[i, first[i]:max(data.onset[i], first[i] + 1)].mean()
                   for i in range(len(data))])
    amb = data.ambient if data.ambient is not None else np.full(len(data), np.nan)
    if np.isnan(amb).any():
        raise SkinError(f"{data.source}: the classifiers need the 'ambient' column")
    return np.column_stack([amb, t0, w])


def contact_matrix(data: TrialSet, duration: float) -> np.ndarray:
    """Rows ``[ambient, T0_0, window_0..., T0_1, window_1..., ...]``, one block per channel.

    NaN where a channel is absent; with one channel this is `trial_matrix`.
    """
    w = window(data, duration, channel=slice(None))  # (n, c, m)
    first = np.maximum(data.onset - PRE, 0)
    t0 = np.array([data.temperature[i, :, first[i]:max(data.onset[i], first[i] + 1)].mean(axis=1)
                   for i in range(len(data))])  # (n, c)
    amb = data.ambient if data.ambient is not None else np.full(len(data), np.nan)
    if np.isnan(amb).any():
        raise SkinError(f"{data.source}: the classifiers need the 'ambient' column")
    blocks = np.concatenate([t0[:, :, None], w], axis=2)
    return np.column_stack([amb, blocks.reshape(len(data), -1)])


def split_rows(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split `trial_matrix` rows into (ambient, T0, window)."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[1] < 4:
        raise ValueError(f"expected rows [ambient, T0, window...] of at least 4 values, got "
                         f"shape {x.shape}")
    return x[:, 0], x[:, 1], x[:, 2:]


def slope_filter(fs: float = 200.0, cutoff: float = 2.0, order: int = 8) -> np.ndarray:
    """Return the paper's causal Butterworth low-pass as second-order sections."""
    from scipy.signal import butter

    return butter(order, cutoff, fs=fs, output="sos")


def slope(window: np.ndarray, t0: np.ndarray, fs: float = 200.0) -> np.ndarray:
    """Return the filtered first difference of each window, K/s, shaped like ``window``.

    The filter starts at rest on the flat pre-contact signal (difference 0 at T0), the state
    a causal filter running on the stream would be in at onset.
    """
    from scipy.signal import sosfilt

    w = np.asarray(window, dtype=float)
    prev = np.column_stack([np.asarray(t0, dtype=float), w[:, :-1]])
    diff = (w - prev) * fs
    return sosfilt(slope_filter(fs), diff, axis=1)


def trace_features(x: np.ndarray, kind: str = "raw", fs: float = 200.0) -> np.ndarray:
    """Return the paper's feature vector: raw window, its slope, or both concatenated."""
    if kind not in KINDS:
        raise ValueError(f"unknown feature kind {kind!r}; choose one of {', '.join(KINDS)}")
    _, t0, w = split_rows(x)
    if kind == "raw":
        return w
    s = slope(w, t0, fs)
    return s if kind == "slope" else np.hstack([w, s])

"""Trial datasets (``.npz``): the interchange format for training and evaluation.

Keys (see ``DESIGN.md``)::

    temperature  float (n_trials, n_samples), deg C
    fs           sampling rate, Hz
    label        str (n_trials,)
    onset        int (n_trials,): sample index of contact onset, -1 = unknown (detect it)
    ambient      float (n_trials,), deg C              optional
    group        int (n_trials,): recording run        optional
    taxel        int (n_trials,): taxel id             optional

Simulated datasets add their truth under ``true_`` keys (``true_onset_time``,
``true_sensor_temperature``, ``true_object_temperature``, ``true_effusivity``,
``true_conductance``), which loaders keep but classifiers never read. Files are loaded with
``allow_pickle=False``: a dataset cannot run code.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from skin.errors import SkinError


class DatasetError(SkinError):
    """A trial dataset is missing a key, has a wrong shape, or holds bad values."""


@dataclass
class TrialSet:
    """A validated trial dataset.

    Attributes
    ----------
    temperature : numpy.ndarray
        (n_trials, n_samples), deg C.
    fs : float
        Hz.
    label : numpy.ndarray
        str (n_trials,).
    onset : numpy.ndarray
        int (n_trials,), -1 = unknown.
    ambient, group, taxel : numpy.ndarray or None
        Optional per-trial columns.
    extra : dict
        Any other arrays in the file (e.g. the ``true_`` keys of simulated data).
    source : str
        Where it came from.
    """

    temperature: np.ndarray
    fs: float
    label: np.ndarray
    onset: np.ndarray
    ambient: np.ndarray | None = None
    group: np.ndarray | None = None
    taxel: np.ndarray | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = "<memory>"

    def __post_init__(self) -> None:
        validate(self)

    def __len__(self) -> int:
        return self.temperature.shape[0]

    @property
    def classes(self) -> list[str]:
        """Sorted class names."""
        return sorted(set(self.label.tolist()))

    def subset(self, index: np.ndarray) -> TrialSet:
        """Return the trials at ``index`` (integer or boolean array)."""
        pick = (lambda a: None if a is None else a[index])  # noqa: E731
        return TrialSet(self.temperature[index], self.fs, self.label[index], self.onset[index],
                        pick(self.ambient), pick(self.group), pick(self.taxel),
                        {k: v[index] for k, v in self.extra.items()}, self.source)

    def save(self, path: str | Path) -> Path:
        """Write the dataset as a compressed ``.npz``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {"temperature": self.temperature, "fs": np.asarray(self.fs),
                  "label": self.label.astype(str), "onset": self.onset}
        for key in ("ambient", "group", "taxel"):
            if getattr(self, key) is not None:
                arrays[key] = getattr(self, key)
        arrays.update(self.extra)
        with path.open("wb") as f:
            np.savez_compressed(f, **arrays)
        return path


def validate(ts: TrialSet) -> None:
    """Check shapes and values; raise `DatasetError` naming the key and the trial."""
    src = ts.source
    temp = np.asarray(ts.temperature)
    if temp.ndim != 2 or temp.shape[0] == 0 or temp.shape[1] < 2:
        raise DatasetError(f"{src}: 'temperature' must be (n_trials, n_samples) with at least one "
                           f"trial and two samples, got shape {temp.shape}")
    if not np.issubdtype(temp.dtype, np.floating):
        raise DatasetError(f"{src}: 'temperature' must be float, got {temp.dtype}")
    bad = ~np.all(np.isfinite(temp), axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        j = int(np.flatnonzero(~np.isfinite(temp[i]))[0])
        raise DatasetError(f"{src}: 'temperature' of trial {i} is not finite at sample {j} "
                           f"({int(bad.sum())} trial(s) affected)")
    n, m = temp.shape
    if not (np.isfinite(ts.fs) and ts.fs > 0):
        raise DatasetError(f"{src}: 'fs' must be a positive sampling rate, got {ts.fs!r}")
    for key in ("label", "onset", "ambient", "group", "taxel"):
        a = getattr(ts, key)
        if a is not None and np.shape(a) != (n,):
            raise DatasetError(f"{src}: '{key}' must have one value per trial ({n},), "
                               f"got shape {np.shape(a)}")
    onset = np.asarray(ts.onset)
    if not np.issubdtype(onset.dtype, np.integer):
        raise DatasetError(f"{src}: 'onset' must be integer sample indices, got {onset.dtype}")
    out = (onset < -1) | (onset >= m)
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise DatasetError(f"{src}: 'onset' of trial {i} is {int(onset[i])}, outside -1..{m - 1}")
    if ts.ambient is not None and not np.all(np.isfinite(ts.ambient)):
        i = int(np.flatnonzero(~np.isfinite(ts.ambient))[0])
        raise DatasetError(f"{src}: 'ambient' of trial {i} is not finite")
    for key, a in ts.extra.items():
        if np.shape(a)[:1] != (n,):
            raise DatasetError(f"{src}: '{key}' must have one row per trial, got {np.shape(a)}")


def require_classes(data: TrialSet, at_least: int = 2) -> TrialSet:
    """Return ``data`` if it has ``at_least`` classes (a classifier's), else raise naming it."""
    found = len(data.classes)
    if found < at_least:
        raise DatasetError(f"{data.source}: 'label' has {found} class(es); training and "
                           f"evaluating a classifier need at least {at_least}")
    return data


def load_trials(path: str | Path) -> TrialSet:
    """Load and validate a trial dataset (no pickles are ever loaded).

    One class is allowed (a calibration's reference contacts); classifiers check for two
    with `require_classes`.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            data = {k: npz[k] for k in npz.files}
    except FileNotFoundError:
        raise DatasetError(f"{path}: no such file") from None
    except ValueError as exc:
        raise DatasetError(f"{path}: not a plain-array .npz dataset ({exc})") from None
    except (OSError, EOFError) as exc:
        raise DatasetError(f"{path}: cannot read ({exc})") from None
    missing = [k for k in ("temperature", "fs", "label", "onset") if k not in data]
    if missing:
        raise DatasetError(f"{path}: missing key(s) {', '.join(missing)}")
    fs = data.pop("fs")
    if fs.size != 1:
        raise DatasetError(f"{path}: 'fs' must be one number, got shape {fs.shape}")
    optional = {k: data.pop(k, None) for k in ("ambient", "group", "taxel")}
    temp = data.pop("temperature")
    if np.issubdtype(temp.dtype, np.integer):
        temp = temp.astype(float)
    return TrialSet(temperature=temp, fs=float(fs), label=data.pop("label").astype(str),
                    onset=data.pop("onset"), extra=data, source=str(path), **optional)


def with_detected_onsets(data: TrialSet, depth: float = 8e-5,
                         diffusivity: float = 2.796e-9) -> TrialSet:
    """Fill unknown onsets (-1) with the library's streaming detector, refined by the fit.

    The trials are run through `skin.stream.onset.OnsetDetector` as if each were a taxel (so the
    detector needs its 0.5 s warm-up before contact), and each first onset is dated by
    `skin.stream.onset_refine.refine_onset` with the sensor's depth and diffusivity.

    Raises
    ------
    DatasetError
        Naming the first trial in which no onset was found.
    """
    from skin.stream.onset import OnsetDetector
    from skin.stream.onset_refine import refine_onset

    todo = np.flatnonzero(data.onset < 0)
    if todo.size == 0:
        return data
    y = data.temperature[todo]
    times = np.arange(y.shape[1]) / data.fs
    detector = OnsetDetector(todo.size)
    events, _ = detector.process(times, y.T, detector.initial_state())
    first: dict[int, object] = {}
    for ev in events:
        if ev.kind == "onset" and ev.taxel not in first:
            first[ev.taxel] = ev
    missing = [int(todo[k]) for k in range(todo.size) if k not in first]
    if missing:
        raise DatasetError(f"{data.source}: no contact onset found in trial {missing[0]} "
                           f"({len(missing)} trial(s)); give its onset or a longer recording "
                           f"(the detector needs 0.5 s before contact)")
    onset = data.onset.copy()
    for k, ev in first.items():
        t_on, _ = refine_onset(times, y[k], ev.time, ev.baseline, ev.slope, depth, diffusivity)
        onset[todo[k]] = int(np.clip(np.ceil(t_on * data.fs - 1e-9), 0, y.shape[1] - 1))
    return TrialSet(data.temperature, data.fs, data.label, onset, data.ambient, data.group,
                    data.taxel, data.extra, data.source)

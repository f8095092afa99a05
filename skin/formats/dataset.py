"""Trial datasets (``.npz``): the interchange format for training and evaluation.

Version 2 (see ``DESIGN.md`` and the README): one trial is one contact seen by one or more
channels (taxels)::

    temperature  float (n_trials, n_channels, n_samples), deg C; NaN where a channel is absent
    heated       bool (n_trials, n_channels): False for a passive, unheated thermistor
    taxel        int (n_trials, n_channels): taxel id (-1 where absent)
    fs           sampling rate, Hz
    label        str (n_trials,)
    onset        int (n_trials,): sample index of contact onset, -1 = unknown (detect it)
    ambient      float (n_trials,), deg C
    group        int (n_trials,): what recorded the trial (taxel unit, session), for grouped CV
    setpoint     float (n_trials, n_channels): a held heater's setpoint, deg C (NaN: none) opt.
    force        float (n_trials, n_samples), N; dates an unknown onset            opt.
    object_temperature  float (n_trials,), deg C, where it was measured               opt.
    version      2

Version 1 (``temperature`` of shape (n_trials, n_samples), one heated channel, ``taxel`` and
``ambient`` optional per trial) still loads, as a dataset of one channel. In memory a
`TrialSet` always holds the v2 shapes. Channel 0 is the *primary* channel (a heated one where
the trial has one); methods that read one trace per trial read it.

A channel is either present (every sample finite) or absent (every sample NaN); a trial needs
its primary channel. A trial that breaks a rule is rejected with its index and the reason.
Simulated datasets add their truth under ``true_`` keys (``true_onset_time``,
``true_sensor_temperature``, ``true_object_temperature``, ...), which loaders keep but
classifiers never read. Files are loaded with ``allow_pickle=False``: a dataset cannot run
code.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from skin.errors import SkinError


class DatasetError(SkinError):
    """A trial dataset is missing a key, has a wrong shape, or holds bad values."""


VERSION = 2
#: Per-trial columns (n_trials,) and per-channel columns (n_trials, n_channels).
PER_TRIAL = ("label", "onset", "ambient", "group", "object_temperature")
PER_CHANNEL = ("heated", "taxel", "setpoint")


@dataclass
class TrialSet:
    """A validated trial dataset (version 2 shapes; see the module docstring).

    Attributes
    ----------
    temperature : numpy.ndarray
        (n_trials, n_channels, n_samples), deg C, NaN where a channel is absent. A 2-D array
        (n_trials, n_samples) is taken as one heated channel (version 1).
    fs : float
        Hz.
    label : numpy.ndarray
        str (n_trials,).
    onset : numpy.ndarray
        int (n_trials,), -1 = unknown.
    ambient, group : numpy.ndarray or None
        Optional per-trial columns.
    taxel : numpy.ndarray or None
        int (n_trials, n_channels) (or (n_trials,) for one channel).
    extra : dict
        Any other arrays in the file (e.g. the ``true_`` keys of simulated data).
    source : str
        Where it came from.
    heated : numpy.ndarray or None
        bool (n_trials, n_channels); None: every channel heated.
    setpoint : numpy.ndarray or None
        (n_trials, n_channels), deg C, NaN for a heater not held at a setpoint.
    force : numpy.ndarray or None
        (n_trials, n_samples), N.
    object_temperature : numpy.ndarray or None
        (n_trials,), deg C.
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
    heated: np.ndarray | None = None
    setpoint: np.ndarray | None = None
    force: np.ndarray | None = None
    object_temperature: np.ndarray | None = None

    def __post_init__(self) -> None:
        temp = np.asarray(self.temperature)
        if temp.ndim == 2:  # version 1: one heated channel
            temp = temp[:, None, :]
            if self.taxel is not None and np.ndim(self.taxel) == 1:
                self.taxel = np.asarray(self.taxel)[:, None]
        self.temperature = temp
        if self.heated is None and temp.ndim == 3:
            self.heated = np.ones(temp.shape[:2], dtype=bool)
        validate(self)

    def __len__(self) -> int:
        return self.temperature.shape[0]

    @property
    def n_channels(self) -> int:
        """Channels per trial."""
        return self.temperature.shape[1]

    @property
    def primary(self) -> np.ndarray:
        """The primary channel's readings, (n_trials, n_samples): what one-trace methods read."""
        return self.temperature[:, 0, :]

    @property
    def classes(self) -> list[str]:
        """Sorted class names."""
        return sorted(set(self.label.tolist()))

    def subset(self, index: np.ndarray) -> TrialSet:
        """Return the trials at ``index`` (integer or boolean array)."""
        pick = (lambda a: None if a is None else a[index])  # noqa: E731
        return TrialSet(self.temperature[index], self.fs, self.label[index], self.onset[index],
                        pick(self.ambient), pick(self.group), pick(self.taxel),
                        {k: v[index] for k, v in self.extra.items()}, self.source,
                        pick(self.heated), pick(self.setpoint), pick(self.force),
                        pick(self.object_temperature))

    def channels(self, index: list[int] | np.ndarray) -> TrialSet:
        """Return the dataset with only the channels at ``index`` (the first is primary)."""
        index = np.asarray(index, dtype=int)
        pick = (lambda a: None if a is None else a[:, index])  # noqa: E731
        return TrialSet(self.temperature[:, index], self.fs, self.label, self.onset,
                        self.ambient, self.group, pick(self.taxel), dict(self.extra),
                        self.source, pick(self.heated), pick(self.setpoint), self.force,
                        self.object_temperature)

    def decimated(self, factor: int) -> TrialSet:
        """Return 1 sample in ``factor``, as a sample-and-hold logger at ``fs / factor`` reads.

        The kept samples are point samples of the readings (samples 0, ``factor``,
        2 ``factor``, ...): no anti-alias average, so each keeps its own noise, as a slower
        logger's would.

        Parameters
        ----------
        factor : int
            Keep 1 sample in ``factor``: from 1 (the dataset itself, returned as is) to one
            less than the samples per trial (at least two samples kept). A bool is refused.

        Returns
        -------
        TrialSet
            At ``fs / factor``. Each trial's onset becomes the kept sample at or before it
            (``onset // factor``: up to ``(factor - 1) / fs`` s early; -1 stays unknown). The
            force trace and every extra array of two axes or more whose last axis is as long
            as the readings' (``n_samples``) are decimated alike; other extras (per trial)
            are kept whole.

        Raises
        ------
        DatasetError
            ``factor`` not an integer from 1 to ``n_samples - 1``.
        """
        n = self.temperature.shape[-1]
        if not (isinstance(factor, int | np.integer) and not isinstance(factor, bool)
                and 1 <= factor <= n - 1):
            raise DatasetError(f"{self.source}: decimation factor must be an integer from 1 to "
                               f"{n - 1} (the trials hold {n} samples), got {factor!r}")
        if factor == 1:
            return self
        cut = (lambda a: None if a is None else a[..., ::factor])  # noqa: E731
        extra = {k: (v[..., ::factor] if np.ndim(v) >= 2 and np.shape(v)[-1] == n else v)
                 for k, v in self.extra.items()}
        onset = np.where(self.onset < 0, -1, self.onset // factor)
        return TrialSet(self.temperature[..., ::factor], self.fs / factor, self.label, onset,
                        self.ambient, self.group, self.taxel, extra,
                        f"{self.source}, 1 sample in {factor}", self.heated, self.setpoint,
                        cut(self.force), self.object_temperature)

    def save(self, path: str | Path) -> Path:
        """Write the dataset (version 2) as a compressed ``.npz``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {"version": np.asarray(VERSION), "temperature": self.temperature,
                  "fs": np.asarray(self.fs), "label": self.label.astype(str),
                  "onset": self.onset, "heated": self.heated}
        for key in ("ambient", "group", "taxel", "setpoint", "force", "object_temperature"):
            if getattr(self, key) is not None:
                arrays[key] = getattr(self, key)
        arrays.update(self.extra)
        with path.open("wb") as f:
            np.savez_compressed(f, **arrays)
        return path


def _first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def validate(ts: TrialSet) -> None:
    """Check shapes and values; raise `DatasetError` naming the key, the trial and the reason."""
    src = ts.source
    temp = np.asarray(ts.temperature)
    if temp.ndim != 3 or temp.shape[0] == 0 or temp.shape[1] == 0 or temp.shape[2] < 2:
        raise DatasetError(f"{src}: 'temperature' must be (n_trials, n_samples) or (n_trials, "
                           f"n_channels, n_samples) with at least one trial, one channel and "
                           f"two samples, got shape {np.shape(ts.temperature)}")
    if not np.issubdtype(temp.dtype, np.floating):
        raise DatasetError(f"{src}: 'temperature' must be float, got {temp.dtype}")
    n, c, m = temp.shape
    finite = np.isfinite(temp)
    present = finite.any(axis=2)
    partly = present & ~finite.all(axis=2)
    if partly.any():  # a present channel must be whole
        i, k = (int(v) for v in np.argwhere(partly)[0])
        j = _first(~finite[i, k])
        where = "" if c == 1 else f" channel {k}"
        raise DatasetError(f"{src}: 'temperature' of trial {i}{where} is not finite at sample "
                           f"{j} ({int(partly.any(axis=1).sum())} trial(s) affected)")
    if not present[:, 0].all():
        raise DatasetError(f"{src}: trial {_first(~present[:, 0])} has no reading on its "
                           f"primary channel 0 (all NaN)")
    if not (np.isfinite(ts.fs) and ts.fs > 0):
        raise DatasetError(f"{src}: 'fs' must be a positive sampling rate, got {ts.fs!r}")
    for key in PER_TRIAL:
        a = getattr(ts, key)
        if a is not None and np.shape(a) != (n,):
            raise DatasetError(f"{src}: '{key}' must have one value per trial ({n},), "
                               f"got shape {np.shape(a)}")
    for key in PER_CHANNEL:
        a = getattr(ts, key)
        if a is not None and np.shape(a) != (n, c):
            raise DatasetError(f"{src}: '{key}' must be (n_trials, n_channels) = ({n}, {c}), "
                               f"got shape {np.shape(a)}")
    if ts.heated is not None and np.asarray(ts.heated).dtype != bool:
        raise DatasetError(f"{src}: 'heated' must be bool, got {np.asarray(ts.heated).dtype}")
    if ts.force is not None and np.shape(ts.force) != (n, m):
        raise DatasetError(f"{src}: 'force' must be (n_trials, n_samples) = ({n}, {m}), got "
                           f"shape {np.shape(ts.force)}")
    onset = np.asarray(ts.onset)
    if not np.issubdtype(onset.dtype, np.integer):
        raise DatasetError(f"{src}: 'onset' must be integer sample indices, got {onset.dtype}")
    out = (onset < -1) | (onset >= m)
    if out.any():
        i = _first(out)
        raise DatasetError(f"{src}: 'onset' of trial {i} is {int(onset[i])}, outside -1..{m - 1}")
    for key in ("ambient", "object_temperature"):
        a = getattr(ts, key)
        if a is not None and not np.all(np.isfinite(a)):
            raise DatasetError(f"{src}: '{key}' of trial {_first(~np.isfinite(a))} is not finite")
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
    """Load and validate a trial dataset, version 1 or 2 (no pickles are ever loaded).

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
    version = int(data.pop("version", 1 if data["temperature"].ndim == 2 else 2))
    if version not in (1, 2):
        raise DatasetError(f"{path}: dataset version {version}; this library reads 1 and 2")
    fs = data.pop("fs")
    if fs.size != 1:
        raise DatasetError(f"{path}: 'fs' must be one number, got shape {fs.shape}")
    optional = {k: data.pop(k, None) for k in ("ambient", "group", "taxel", "heated",
                                                 "setpoint", "force", "object_temperature")}
    if optional["heated"] is not None and optional["heated"].dtype != bool:
        if not np.isin(optional["heated"], (0, 1)).all():
            raise DatasetError(f"{path}: 'heated' must be bool (or 0/1)")
        optional["heated"] = optional["heated"].astype(bool)
    temp = data.pop("temperature")
    if np.issubdtype(temp.dtype, np.integer):
        temp = temp.astype(float)
    if version == 1 and temp.ndim != 2:
        raise DatasetError(f"{path}: a version 1 'temperature' is (n_trials, n_samples), got "
                           f"shape {temp.shape}")
    return TrialSet(temperature=temp, fs=float(fs), label=data.pop("label").astype(str),
                    onset=data.pop("onset"), extra=data, source=str(path), **optional)


#: A force trace dates its contact where it first rises this share of the way from its
#: pre-contact level to its peak (`force_onsets`).
FORCE_ONSET_SHARE = 0.05
#: ...provided the peak stands this many times the pre-contact noise above that level,
FORCE_MIN_SNR = 10.0
#: ...the pre-contact stretch is at least this long (s, and 10 samples),
FORCE_MIN_BEFORE = 0.1
#: ...and the force stays over the onset's threshold this long from the onset (s, 3 samples).
FORCE_MIN_HELD = 0.05


def force_onsets(data: TrialSet) -> np.ndarray:
    """Date each trial's contact from its force channel (``force``, compression positive).

    The pre-contact stretch is the samples before the force first reaches halfway from its
    first sample to its peak; its level is their median, its noise their scaled median
    absolute deviation, but at least their resolution (the smallest step between two of
    them; a quantised force has a MAD of 0). The onset is the first sample where the force
    exceeds the level by `FORCE_ONSET_SHARE` of the peak's rise and stays over it
    `FORCE_MIN_HELD` (a noise sample over it before the contact is passed by). A ramp of r
    seconds is dated about 0.05 r late, later where the noise is near the threshold.

    Returns
    -------
    numpy.ndarray
        int (n_trials,): the onset sample of each trial with a finite force trace whose
        pre-contact stretch lasts `FORCE_MIN_BEFORE`, whose peak stands `FORCE_MIN_SNR` noise
        levels above its level and whose force stays over the threshold `FORCE_MIN_HELD`
        from some sample on (the first such is the onset); -1 elsewhere (no force channel,
        NaN samples, no contact in it, a contact from the first samples, a force that falls
        at contact), left to the reading.
    """
    out = np.full(len(data), -1, dtype=int)
    if data.force is None:
        return out
    n_before = max(10, math.ceil(FORCE_MIN_BEFORE * data.fs))
    n_held = max(3, math.ceil(FORCE_MIN_HELD * data.fs))
    for i, f in enumerate(np.asarray(data.force, dtype=float)):
        if not np.all(np.isfinite(f)):
            continue
        half = int(np.argmax(f >= 0.5 * (f.max() + f[0])))
        if half < n_before:
            continue
        before = f[:half]
        level = float(np.median(before))
        steps = np.abs(np.diff(np.unique(before)))
        noise = max(1.4826 * float(np.median(np.abs(before - level))),
                    float(steps.min()) if steps.size else 0.0)
        rise = float(f.max()) - level
        if not rise > FORCE_MIN_SNR * noise or not rise > 0:
            continue
        over = (f > level + FORCE_ONSET_SHARE * rise).astype(int)
        held = np.flatnonzero(np.convolve(over, np.ones(n_held, dtype=int), "valid") == n_held)
        if held.size:  # the first crossing held (a noise sample over it before is passed by)
            out[i] = int(held[0])
    return out


def with_detected_onsets(data: TrialSet, sensor: object | None = None) -> TrialSet:
    """Fill unknown onsets (-1) from the force channel, else by the streaming detector.

    A trial whose ``force`` dates its contact (`force_onsets`) takes that onset. The others
    are run through `skin.stream.onset.OnsetDetector` as if each were a taxel (so the
    detector needs its 0.5 s warm-up before contact), and each first onset is dated by
    `skin.stream.onset_refine.refine_onset`, the fit of the sensor's response.

    Parameters
    ----------
    data : TrialSet
        The trials; those with onset -1 are searched.
    sensor : SensorDescription or str, optional
        The sensor that recorded them (a description, preset name or file; default the
        paper's). The detector runs at the trials' own rate ``data.fs``: its smoothing, CUSUM
        thresholds and hole test are per sample (`SensorDescription.at_rate`: a sensor
        without smoothing is re-rated; a smoothed one must be described at that rate).

    Raises
    ------
    DatasetError
        Naming the first trial in which no onset was found, or a rate the sensor cannot be
        re-rated to.
    """
    from skin.models.sensors import SensorError, load_sensor
    from skin.stream.onset import OnsetDetector
    from skin.stream.onset_refine import refine_onset

    onset = data.onset.copy()
    unknown = onset < 0
    by_force = force_onsets(data)
    onset[unknown] = by_force[unknown]
    todo = np.flatnonzero(onset < 0)
    if todo.size == 0:
        return dataclasses.replace(data, onset=onset)
    y = data.primary[todo]
    times = np.arange(y.shape[1]) / data.fs
    described = load_sensor(sensor)
    try:
        described = described.at_rate(data.fs, "the trials")
    except SensorError as exc:
        raise DatasetError(f"{data.source}: {exc}: give their onsets (or a force channel), "
                           f"or resample") from None
    # each trial its own recording: no room shared across them (no board common mode)
    detector = OnsetDetector(todo.size, sensor=described, common_mode=False)
    events, _ = detector.process(times, y.T, detector.initial_state())
    first: dict[int, object] = {}
    for ev in events:
        if ev.kind == "onset" and ev.taxel not in first:
            first[ev.taxel] = ev
    missing = [int(todo[k]) for k in range(todo.size) if k not in first]
    if missing:
        raise DatasetError(f"{data.source}: no contact onset found in trial {missing[0]} "
                           f"({len(missing)} trial(s)) by sensor {described.name!r}'s "
                           f"detector; give its onset, a force channel, or a longer "
                           f"recording (the detector needs {detector.warmup:g} s before "
                           f"contact, and a contact that moves the reading beyond its noise)")
    for k, ev in first.items():
        t_on, _ = refine_onset(times, y[k], ev.time, ev.baseline, ev.slope, described.depth,
                               described.diffusivity, sensor=described)
        onset[todo[k]] = int(np.clip(np.ceil(t_on * data.fs - 1e-9), 0, y.shape[1] - 1))
    return dataclasses.replace(data, onset=onset)

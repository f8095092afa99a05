"""Trials recorded elsewhere, as a CSV file: one row per sample of one channel.

The layout (also in the README)::

    trial,channel,time,temperature,label,ambient[,heated][,taxel][,group][,onset]
          [,setpoint][,object_temperature]

- ``trial``: any integer or name; the rows of one trial share it (trials keep the order in
  which they first appear);
- ``channel``: 0, 1, ... within the trial; channel 0 is the primary (give a heated one);
- ``time``: s, the same uniform grid for every channel of a trial (the first trial sets the
  sampling rate; every trial must share it); trials of different lengths are all cut to
  the shortest;
- ``temperature``: deg C; ``label``: the material; ``ambient``: deg C;
- optional ``heated`` (1/0, default 1), ``taxel`` (int), ``group`` (int, default: one group
  per trial), ``onset`` (s on the trial's time axis: contact onset; absent or empty: detect
  it), ``setpoint`` (deg C), ``object_temperature`` (deg C).

Per-trial values (label, ambient, group, onset, object_temperature) and per-channel values
(heated, taxel, setpoint) must agree on every row that repeats them. A trial that breaks a
rule is rejected with its index, its ``trial`` value, the CSV line and the reason, and the
others are kept (`read_trials_csv` returns both).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skin.formats.dataset import DatasetError, TrialSet

REQUIRED = ("trial", "channel", "time", "temperature", "label", "ambient")
OPTIONAL = ("heated", "taxel", "group", "onset", "setpoint", "object_temperature")


@dataclass(frozen=True)
class Rejected:
    """A trial left out of an import, and why."""

    index: int
    trial: str
    line: int
    reason: str

    def __str__(self) -> str:
        return f"trial {self.index} ({self.trial!r}, line {self.line}): {self.reason}"


class _TrialRows:
    def __init__(self, name: str, line: int) -> None:
        self.name = name
        self.line = line
        self.meta: dict[str, str] = {}
        self.channels: dict[int, dict] = {}


def _number(text: str, what: str, line: int) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"line {line}: {what} {text!r} is not a number") from None


def read_trials_csv(path: str | Path) -> tuple[TrialSet, list[Rejected]]:
    """Read the CSV layout of the module docstring into a version 2 `TrialSet`.

    Returns
    -------
    (TrialSet, list of Rejected)
        The usable trials, and those rejected with their reason.

    Raises
    ------
    DatasetError
        For a missing file or column, or when no trial is usable.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read ({exc.strerror})") from None
    reader = csv.DictReader(text.splitlines())
    fields = [f.strip() for f in (reader.fieldnames or [])]
    missing = [c for c in REQUIRED if c not in fields]
    if missing:
        raise DatasetError(f"{path}: line 1: missing column(s) {', '.join(missing)}; the "
                           f"layout is {','.join(REQUIRED)} plus optional {','.join(OPTIONAL)}")
    trials: dict[str, _TrialRows] = {}
    broken: dict[str, str] = {}
    for line, raw in enumerate(reader, start=2):
        row = {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}
        name = row["trial"]
        tr = trials.setdefault(name, _TrialRows(name, line))
        if name in broken:
            continue
        try:
            ch = int(row["channel"]) if row["channel"].isdigit() else None
            if ch is None:
                raise ValueError(f"line {line}: channel {row['channel']!r} is not 0, 1, ...")
            for key in ("label", "ambient", "group", "onset", "object_temperature"):
                if key in row and row[key] != "":
                    old = tr.meta.setdefault(key, row[key])
                    if old != row[key]:
                        raise ValueError(f"line {line}: {key} {row[key]!r} differs from the "
                                         f"trial's {old!r}")
            c = tr.channels.setdefault(ch, {"t": [], "y": [], "meta": {}})
            for key in ("heated", "taxel", "setpoint"):
                if key in row and row[key] != "":
                    old = c["meta"].setdefault(key, row[key])
                    if old != row[key]:
                        raise ValueError(f"line {line}: {key} {row[key]!r} differs from "
                                         f"channel {ch}'s {old!r}")
            c["t"].append(_number(row["time"], "time", line))
            c["y"].append(_number(row["temperature"], "temperature", line))
        except ValueError as exc:
            broken[name] = str(exc)
    if not trials:
        raise DatasetError(f"{path}: no rows after the header")
    rejected: list[Rejected] = []
    kept: list[tuple[_TrialRows, dict]] = []
    fs = None
    for index, tr in enumerate(trials.values()):
        if tr.name in broken:
            rejected.append(Rejected(index, tr.name, tr.line, broken[tr.name]))
            continue
        try:
            parsed = _parse_trial(tr, fs)
        except ValueError as exc:
            rejected.append(Rejected(index, tr.name, tr.line, str(exc)))
            continue
        fs = parsed["fs"] if fs is None else fs
        kept.append((tr, parsed))
    if not kept:
        raise DatasetError(f"{path}: no usable trial; first: {rejected[0]}")
    return _assemble(kept, fs, str(path)), rejected


def _parse_trial(tr: _TrialRows, fs: float | None) -> dict:
    if "label" not in tr.meta or "ambient" not in tr.meta:
        raise ValueError("no label or no ambient")
    if 0 not in tr.channels:
        raise ValueError("no channel 0 (the primary channel)")
    ref = np.asarray(tr.channels[0]["t"])
    if ref.size < 2 or np.any(np.diff(ref) <= 0):
        raise ValueError("channel 0's times must increase, with at least two samples")
    step = np.diff(ref)
    if np.ptp(step) > 1e-3 * step.mean():
        raise ValueError(f"channel 0's times are not uniform (steps {step.min():g}-"
                         f"{step.max():g} s)")
    rate = 1.0 / step.mean()
    if fs is not None and abs(rate - fs) > 1e-3 * fs:
        raise ValueError(f"sampled at {rate:g} Hz, the file's first trial at {fs:g} Hz")
    chans = {}
    for ch, c in sorted(tr.channels.items()):
        t = np.asarray(c["t"])
        if t.shape != ref.shape or np.max(np.abs(t - ref)) > 0.25 * step.mean():
            raise ValueError(f"channel {ch}'s times differ from channel 0's")
        y = np.asarray(c["y"])
        if not np.all(np.isfinite(y)):
            raise ValueError(f"channel {ch} has a non-finite temperature")
        heated = c["meta"].get("heated", "1")
        if heated not in ("0", "1", "true", "false", "True", "False"):
            raise ValueError(f"channel {ch}: heated {heated!r} is not 1 or 0")
        chans[ch] = {"y": y, "heated": heated in ("1", "true", "True"),
                     "taxel": int(float(c["meta"].get("taxel", -1))),
                     "setpoint": float(c["meta"].get("setpoint", "nan"))}
    meta = tr.meta
    onset = -1
    if meta.get("onset", "") != "":
        onset = round((float(meta["onset"]) - ref[0]) * rate)
        if not 0 <= onset < ref.size:
            raise ValueError(f"onset {meta['onset']} s lies outside the trial's times")
    return {"fs": float(fs if fs is not None else rate), "channels": chans, "onset": onset,
            "label": meta["label"], "ambient": float(meta["ambient"]),
            "group": int(float(meta["group"])) if "group" in meta else None,
            "object_temperature": float(meta.get("object_temperature", "nan"))}


def _assemble(kept: list[tuple[_TrialRows, dict]], fs: float, source: str) -> TrialSet:
    n = len(kept)
    n_ch = max(max(p["channels"]) + 1 for _, p in kept)
    m = min(p["channels"][0]["y"].size for _, p in kept)  # cut to the shortest trial
    temp = np.full((n, n_ch, m), np.nan)
    heated = np.zeros((n, n_ch), dtype=bool)
    taxel = np.full((n, n_ch), -1, dtype=np.int64)
    setpoint = np.full((n, n_ch), np.nan)
    for i, (_, p) in enumerate(kept):
        for ch, c in p["channels"].items():
            temp[i, ch] = c["y"][:m]
            heated[i, ch], taxel[i, ch], setpoint[i, ch] = c["heated"], c["taxel"], c["setpoint"]
    onset = np.array([p["onset"] if p["onset"] < m else -1 for _, p in kept], dtype=np.int64)
    group = np.array([p["group"] if p["group"] is not None else i
                      for i, (_, p) in enumerate(kept)], dtype=np.int64)
    obj = np.array([p["object_temperature"] for _, p in kept])
    return TrialSet(temperature=temp, fs=fs, label=np.array([p["label"] for _, p in kept]),
                    onset=onset, ambient=np.array([p["ambient"] for _, p in kept]),
                    group=group, taxel=taxel, source=source, heated=heated,
                    setpoint=None if np.isnan(setpoint).all() else setpoint,
                    object_temperature=None if np.isnan(obj).any() else obj)

"""Taxels' temperature and slope traces with their onset marks (the paper's Figs. 1 and 6).

A figure has two panels sharing the time axis: the temperature (deg C) above and its slope
(K/s) below; by default the slope is the onset detector's own smoothed derivative
(`skin.stream.onset.DetectorTrace.slope`, what the detector compares the reading with), or, with
``slope="paper"``, the paper's feature: the first difference through its causal 2 Hz
Butterworth low-pass (`skin.models.features.slope_filter`, the paper's Fig. 6).

Vertical lines in both panels mark what the detector found in each trace, in the trace's
colour: each onset (solid), dated by the contact-response fit as the pipeline dates it
(`skin.stream.onset_refine.refine_onset`), and each release (dash-dot); a triangle on the
temperature marks the sample at which the onset was recognised. Black lines mark the truth
where it is known: onsets dashed, releases dotted. Contacts a recording holds (the pipeline's
results) are shaded in their label's colour.

Traces come from three sources, each a list of `TaxelTrace`:

- `trial_traces`: trials of a trial dataset (`skin.formats.dataset`), the truth from its
  ``true_onset_time`` column (simulated data) or its ``onset`` column;
- `recording_traces`: taxels of an MCAP recording (`skin.drivers.recording`), with its
  recorded contacts, the truth from the scene of a simulated run (`recording_scene`);
- `material_traces`: simulated contacts with several materials from one initial
  temperature (`skin.models.physics.material_trace`), overlaid like the paper's Fig. 6.

Building traces needs numpy (and scipy for simulated ones); drawing imports matplotlib.
"""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from skin.errors import SkinError
from skin.stream.onset import OnsetDetector

if TYPE_CHECKING:
    from skin.drivers.recording import Recording
    from skin.formats.dataset import TrialSet
    from skin.formats.scene import Scene
    from skin.models.materials import Material

#: The paper's thermistor depth (m) and sensor diffusivity (m^2/s), a layout's defaults.
DEPTH = 8e-5
DIFFUSIVITY = 2.796e-9
#: Slope panels: the detector's slope, or the paper's filtered first difference.
SLOPES = ("detector", "paper")
#: Colours of taxels in a recording (Okabe and Ito's colour-blind-safe set).
PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000",
           "#F0E442")
_TRUTH = "#222222"
_MAX_NAMED = 8  # more traces than this: one legend entry per group (material)
_SEARCH = 0.6  # s before the coarse onset searched by the fit (as the pipeline)
_WINDOW = 2.5  # s after it fitted at most (the pipeline's default decision time)


@dataclass(frozen=True)
class RecordedContact:
    """A contact result held in a recording, drawn as a shaded span.

    Attributes
    ----------
    id : int
        The contact's running number.
    onset : float
        Its onset, s (device time).
    end : float
        Its release, or the time it was decided if still open then, s.
    label : str
        The material named.
    confidence : float
        The classifier's confidence.
    colour : str
        The label's colour.
    """

    id: int
    onset: float
    end: float
    label: str
    confidence: float
    colour: str = "#999999"


@dataclass
class TaxelTrace:
    """One taxel's (or trial's) temperature, the detector's view of it and its marks.

    Attributes
    ----------
    name : str
        Legend entry (``"taxel 10"``, ``"aluminium (trial 3)"``).
    times : numpy.ndarray
        Sample times, s.
    temperature : numpy.ndarray
        Readings, deg C (NaN: no reading).
    slope : numpy.ndarray
        The detector's slope after each sample, K/s (`skin.stream.onset.DetectorTrace.slope`).
    onsets : tuple of float
        Detected onsets, s, dated by the contact-response fit.
    detected_at : tuple of float
        When each onset was recognised, s.
    releases : tuple of float
        Detected releases, s.
    true_onsets, true_releases : tuple of float
        The truth, where known, s.
    colour : str
        Colour of the trace and of its marks.
    group : str or None
        Legend entry when a figure holds many traces (the material of a trial).
    contacts : tuple of RecordedContact
        Recorded contacts this taxel took part in.
    """

    name: str
    times: np.ndarray
    temperature: np.ndarray
    slope: np.ndarray
    onsets: tuple[float, ...] = ()
    detected_at: tuple[float, ...] = ()
    releases: tuple[float, ...] = ()
    true_onsets: tuple[float, ...] = ()
    true_releases: tuple[float, ...] = ()
    colour: str = PALETTE[0]
    group: str | None = None
    contacts: tuple[RecordedContact, ...] = field(default=())

    def summary(self) -> dict[str, Any]:
        """Return the marks of the trace as a JSON-ready dict (``skin plot traces --json``)."""
        def r(values: tuple[float, ...]) -> list[float]:
            return [round(float(v), 4) + 0.0 for v in values]  # no -0.0

        return {"name": self.name, "samples": int(self.times.size),
                "onsets": r(self.onsets), "detected_at": r(self.detected_at),
                "releases": r(self.releases), "true_onsets": r(self.true_onsets),
                "true_releases": r(self.true_releases),
                "contacts": [{"id": c.id, "onset": round(c.onset, 4), "label": c.label}
                             for c in self.contacts]}


def detect_traces(
    times: np.ndarray,
    temperature: np.ndarray,
    names: Sequence[str],
    *,
    depth: np.ndarray | float = DEPTH,
    diffusivity: np.ndarray | float = DIFFUSIVITY,
    detector: OnsetDetector | None = None,
) -> list[TaxelTrace]:
    """Run the onset detector over columns of temperatures and keep what it saw.

    Each column is one taxel (the detector treats them independently). Onsets are dated by
    `skin.stream.onset_refine.refine_onset` over the samples from 0.6 s before the detector's coarse
    onset to the release (at most 2.5 s after it), as the pipeline dates them.

    Parameters
    ----------
    times : numpy.ndarray, shape (n_samples,)
        Sample times, s, increasing.
    temperature : numpy.ndarray, shape (n_samples, n_traces)
        Readings, deg C (NaN: no reading).
    names : sequence of str
        Legend entry of each column.
    depth, diffusivity : float or numpy.ndarray
        Thermistor depth (m) and sensor diffusivity (m^2/s), one value or one per column.
    detector : OnsetDetector, optional
        The detector (default: `OnsetDetector` with its defaults, as the pipeline's).

    Returns
    -------
    list of TaxelTrace
        One per column, in the palette's colours (set ``colour`` and the truth after).
    """
    from skin.stream.onset_refine import refine_onset

    times = np.asarray(times, dtype=float)
    temperature = np.asarray(temperature, dtype=float).reshape(times.size, len(names))
    n = temperature.shape[1]
    det = OnsetDetector(n) if detector is None else detector
    if det.n_taxels != n:
        raise ValueError(f"the detector has {det.n_taxels} taxels, the data {n} columns")
    seen = det.trace(times, temperature)
    depth = np.broadcast_to(np.asarray(depth, dtype=float), (n,))
    diffusivity = np.broadcast_to(np.asarray(diffusivity, dtype=float), (n,))
    marks: list[dict[str, list[float]]] = [
        {"onsets": [], "detected_at": [], "releases": []} for _ in range(n)]
    open_onset: dict[int, Any] = {}
    pending: list[tuple[int, Any, float | None]] = []  # (column, onset event, release time)
    for ev in seen.events:
        if ev.kind == "onset":
            open_onset[ev.taxel] = ev
        else:
            marks[ev.taxel]["releases"].append(ev.time)
            if ev.taxel in open_onset:
                pending.append((ev.taxel, open_onset.pop(ev.taxel), ev.time))
    pending += [(k, ev, None) for k, ev in open_onset.items()]
    for k, ev, release in sorted(pending, key=lambda p: p[1].time):
        end = ev.time + _WINDOW if release is None else min(release, ev.time + _WINDOW)
        pick = (times >= ev.time - _SEARCH) & (times <= end)
        t_on, _ = refine_onset(times[pick], temperature[pick, k], ev.time, ev.baseline,
                               ev.slope, float(depth[k]), float(diffusivity[k]),
                               search=_SEARCH)
        marks[k]["onsets"].append(float(t_on))
        marks[k]["detected_at"].append(ev.detected_at)
    return [TaxelTrace(name=names[k], times=times, temperature=temperature[:, k],
                       slope=seen.slope[:, k], onsets=tuple(marks[k]["onsets"]),
                       detected_at=tuple(marks[k]["detected_at"]),
                       releases=tuple(marks[k]["releases"]),
                       colour=PALETTE[k % len(PALETTE)])
            for k in range(n)]


def _material_colours(materials: dict[str, Material] | None) -> dict[str, str]:
    if materials is None:
        from skin.models import load_materials

        materials = load_materials()
    return {name: m.colour for name, m in materials.items()}


def _display(name: str) -> str:
    from skin.viz.plots import display_name

    return display_name(name)


def trial_traces(
    data: TrialSet,
    trials: Sequence[int] | None = None,
    *,
    materials: dict[str, Material] | None = None,
) -> list[TaxelTrace]:
    """Return traces of trials of a dataset, each run through the onset detector.

    Parameters
    ----------
    data : TrialSet
        The dataset (`skin.formats.dataset.load_trials`).
    trials : sequence of int, optional
        Trial indices (default: the first trial of each class, in class order).
    materials : dict of str to Material, optional
        Colours of the labels (default: the shipped materials table); other labels take the
        palette's.

    Returns
    -------
    list of TaxelTrace
        One per trial, time from the trial's first sample; the truth is the trial's
        ``true_onset_time`` (simulated data), else its ``onset`` when known.

    Raises
    ------
    SkinError
        Naming the dataset when a trial index is out of range.
    """
    n = len(data)
    if trials is None:
        trials = [int(np.flatnonzero(data.label == c)[0]) for c in data.classes]
    trials = [int(k) for k in trials]
    bad = [k for k in trials if not 0 <= k < n]
    if bad or not trials:
        raise SkinError(f"{data.source}: no trial {bad[0] if bad else '(none given)'}; the "
                        f"dataset has {n} trials, 0 to {n - 1}")
    times = np.arange(data.temperature.shape[-1]) / data.fs
    labels = [str(data.label[k]) for k in trials]
    traces = detect_traces(times, data.primary[trials].T,
                           [f"{_display(lab)} (trial {k})" for k, lab in
                            zip(trials, labels, strict=True)])
    colours = _material_colours(materials)
    others = iter(PALETTE * (1 + len(trials) // len(PALETTE)))
    by_label: dict[str, str] = {}
    true_time = data.extra.get("true_onset_time")
    for trace, k, lab in zip(traces, trials, labels, strict=True):
        if lab not in by_label:
            by_label[lab] = colours.get(lab) or next(others)
        trace.colour = by_label[lab]
        trace.group = _display(lab)
        if true_time is not None and np.isfinite(true_time[k]):
            trace.true_onsets = (float(true_time[k]),)
        elif data.onset[k] >= 0:
            trace.true_onsets = (float(data.onset[k]) / data.fs,)
    return traces


def recording_scene(recording: Recording) -> Scene | None:
    """Return the scene a recording was simulated from, read off its recorded command line.

    ``skin run --record`` keeps its command line in the recording's metadata; a run without
    ``--port`` played a scene (``--scene``, default ``default``), whose touches are the truth.

    Parameters
    ----------
    recording : Recording
        The recording (`skin.drivers.recording.read_recording`).

    Returns
    -------
    Scene or None
        The scene, or None when the recording came from a device or a replay, or the scene
        cannot be loaded any more.
    """
    from skin.formats.scene import load_scene

    command = recording.metadata.get("thermoskin", {}).get("command", "")
    try:
        words = shlex.split(command)
    except ValueError:
        return None
    if words[:2] != ["skin", "run"] or any(w == "--port" or w.startswith("--port=")
                                           for w in words):
        return None
    name = "default"
    for i, w in enumerate(words):
        if w == "--scene" and i + 1 < len(words):
            name = words[i + 1]
        elif w.startswith("--scene="):
            name = w.split("=", 1)[1]
    try:
        return load_scene(name)
    except (SkinError, OSError):
        return None


def recording_traces(
    recording: Recording,
    taxels: Sequence[int] | None = None,
    *,
    scene: Scene | None = None,
    materials: dict[str, Material] | None = None,
) -> list[TaxelTrace]:
    """Return traces of taxels of a recording: its temperatures through the onset detector.

    Parameters
    ----------
    recording : Recording
        The recording (`skin.drivers.recording.read_recording`).
    taxels : sequence of int, optional
        Taxel ids (default: the taxels of the first contact the recording holds).
    scene : Scene, optional
        The scene the run was simulated from: its touches of each taxel are the truth.
    materials : dict of str to Material, optional
        Colours of the recorded contacts' labels (default: the shipped table).

    Returns
    -------
    list of TaxelTrace
        One per taxel, on the recording's device time, with the recorded contacts it took
        part in.

    Raises
    ------
    SkinError
        Naming the recording when it holds no temperatures, a taxel is not in its layout, or
        no taxel is given and it holds no contact.
    """
    path = recording.path
    if recording.times.size == 0:
        raise SkinError(f"{path}: the recording holds no temperatures (/temperature)")
    n = recording.temperature.shape[1]
    layout = recording.layout
    ids = [int(i) for i in layout.ids] if layout is not None else list(range(n))
    finals = [e for e in recording.events if e.get("final", True)]
    if taxels is None:
        if not finals:
            raise SkinError(f"{path}: the recording holds no contact; name taxels with --taxel")
        taxels = [int(t) for t in finals[0]["taxels"]]
    taxels = list(dict.fromkeys(int(t) for t in taxels))
    missing = [t for t in taxels if t not in ids]
    if missing or not taxels:
        raise SkinError(f"{path}: no taxel {missing[0] if missing else '(none given)'} in the "
                        f"recording's layout (ids {min(ids)} to {max(ids)})")
    columns = [ids.index(t) for t in taxels]
    depth, diffusivity = _sensor_constants(recording, columns)
    traces = detect_traces(recording.times, recording.temperature[:, columns].astype(float),
                           [f"taxel {t}" for t in taxels], depth=depth,
                           diffusivity=diffusivity)
    colours = _material_colours(materials)
    end = float(recording.times[-1])
    for trace, t in zip(traces, taxels, strict=True):
        trace.contacts = tuple(
            RecordedContact(int(e["contact"]), float(e["onset"]),
                            float(e["release"] if e.get("release") is not None
                                  else e.get("decided_at", e["onset"])),
                            str(e["label"]), float(e.get("confidence", 0.0)),
                            colours.get(str(e["label"]), "#999999"))
            for e in finals if t in e["taxels"])
        if scene is not None:
            touches = [h for h in scene.touches if t in h.taxels and h.start <= end]
            trace.true_onsets = tuple(h.start for h in touches)
            trace.true_releases = tuple(h.end for h in touches if h.end <= end)
    return traces


def _sensor_constants(recording: Recording, columns: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Depth and diffusivity of the chosen taxels: the recorded calibration's, else the board's."""
    layout = recording.layout
    if layout is None:
        return np.full(len(columns), DEPTH), np.full(len(columns), DIFFUSIVITY)
    depth = layout.board_array("sensor_depth")[columns]
    diffusivity = layout.board_array("sensor_diffusivity")[columns]
    cal = recording.calibration
    if cal is not None and hasattr(cal, "apply"):
        _, sensors = cal.apply(layout)
        if sensors is not None:
            depth = np.array([sensors[k].depth for k in columns])
            diffusivity = np.array([sensors[k].diffusivity for k in columns])
    return depth, diffusivity


def material_traces(
    names: Sequence[str],
    *,
    t_sensor: float | None = None,
    t_object: float | None = None,
    ambient: float = 25.0,
    duration: float = 2.5,
    before: float = 1.0,
    model: str = "semi-infinite",
    conductance: float = 3000.0,
    fs: float = 200.0,
    noise: float = 0.0,
    seed: int = 0,
    materials: dict[str, Material] | None = None,
) -> list[TaxelTrace]:
    """Simulate contacts with materials, all from one initial sensor temperature.

    Each trace is ``before`` s of the free sensor at ``t_sensor`` followed by ``duration`` s of
    contact (`skin.models.physics.material_trace`), with Gaussian noise if asked, and is run
    through the onset detector like a taxel's reading.

    Parameters
    ----------
    names : sequence of str
        Materials of the table.
    t_sensor : float, optional
        Sensor temperature at contact, deg C (default: the heated sensor's, eq. 2).
    t_object : float, optional
        Object temperature, deg C (default: each material's resting temperature at ambient).
    ambient : float, optional
        Ambient temperature, deg C.
    duration : float, optional
        Contact, s.
    before : float, optional
        Free sensor before the contact, s (at least 0.6: the detector's 0.5 s warm-up).
    model : str, optional
        ``"semi-infinite"``, ``"contact"`` or ``"multilayer"``.
    conductance : float, optional
        Contact conductance, W/(m^2 K), of ``"contact"`` and ``"multilayer"``.
    fs : float, optional
        Sampling rate, Hz.
    noise : float, optional
        Standard deviation of the reading's noise, deg C.
    seed : int, optional
        Seed of the noise.
    materials : dict of str to Material, optional
        The materials table (default: the shipped one).

    Returns
    -------
    list of TaxelTrace
        One per material, time since contact (the truth: onset at 0), in its colour.

    Raises
    ------
    SkinError
        When a material is unknown or a parameter is out of range.
    """
    from skin.models import load_materials
    from skin.models.physics import TRACE_MODELS, SensorConstants, heated_temperature
    from skin.models.physics import material_trace as simulate

    table = load_materials() if materials is None else materials
    names = list(dict.fromkeys(names))
    unknown = [m for m in names if m not in table]
    if unknown or not names:
        raise SkinError(f"unknown material {unknown[0] if unknown else '(none given)'!r}; "
                        f"known: {', '.join(table)}")
    if model not in TRACE_MODELS:
        raise SkinError(f"unknown contact model {model!r}; choose one of "
                        f"{', '.join(TRACE_MODELS)}")
    if not (duration > 0 and fs > 0 and conductance > 0 and noise >= 0):
        raise SkinError("the duration, sampling rate and conductance must be positive and the "
                        "noise at least 0")
    if before < 0.6:
        raise SkinError(f"{before:g} s before contact is too short: the onset detector needs "
                        f"0.5 s of warm-up (give at least 0.6 s)")
    sensor = SensorConstants()
    t0 = float(heated_temperature(ambient, sensor)) if t_sensor is None else float(t_sensor)
    n_pre = round(before * fs)
    columns = []
    for name in names:
        mat = table[name]
        t_obj = mat.resting_temperature(ambient) if t_object is None else float(t_object)
        t, y = simulate(mat, t0, t_obj, duration=duration, fs=fs, model=model,
                        conductance=conductance, ambient=ambient, sensor=sensor)
        columns.append(np.concatenate([np.full(n_pre, t0), y]))
    times = np.concatenate([np.arange(-n_pre, 0) / fs, t])
    temperature = np.column_stack(columns)
    if noise > 0:
        temperature = temperature + np.random.default_rng(seed).normal(0, noise,
                                                                       temperature.shape)
    traces = detect_traces(times, temperature, [_display(m) for m in names],
                           depth=sensor.depth, diffusivity=sensor.diffusivity)
    for trace, name in zip(traces, names, strict=True):
        trace.colour = table[name].colour
        trace.group = trace.name
        trace.true_onsets = (0.0,)
    return traces


def paper_slope(times: np.ndarray, temperature: np.ndarray) -> np.ndarray:
    """Return the paper's slope feature of a whole trace, K/s (section III-D, Fig. 6).

    The first difference times the sampling rate through the causal 8th-order Butterworth
    low-pass at 2 Hz (`skin.models.features.slope_filter`), started at rest on the first
    sample; a missing sample repeats the one before it.

    Parameters
    ----------
    times : numpy.ndarray
        Sample times, s, evenly spaced.
    temperature : numpy.ndarray
        Readings, deg C.

    Returns
    -------
    numpy.ndarray
        The filtered slope at each sample.
    """
    from scipy.signal import sosfilt

    from skin.models.features import slope_filter

    y = np.asarray(temperature, dtype=float).copy()
    finite = np.isfinite(y)
    if not finite.any():
        return np.full(y.shape, np.nan)
    # carry the last reading over the gaps (and the first one back to the start)
    idx = np.where(finite, np.arange(y.size), 0)
    np.maximum.accumulate(idx, out=idx)
    y = y[idx]
    y[: int(np.argmax(finite))] = y[int(np.argmax(finite))]
    fs = 1.0 / float(np.median(np.diff(times))) if len(times) > 1 else 200.0
    if fs <= 4.0:
        raise SkinError(f"the paper's 2 Hz slope filter needs more than 4 samples per second, "
                        f"got {fs:g}")
    diff = np.diff(y, prepend=y[0]) * fs
    return sosfilt(slope_filter(fs), diff)


def traces_figure(
    traces: Sequence[TaxelTrace],
    *,
    title: str | None = None,
    xlabel: str = "time, s",
    slope: str = "detector",
) -> Any:
    """Build the figure of traces: temperature above, slope below, with the onset marks.

    Parameters
    ----------
    traces : sequence of TaxelTrace
        What to draw (`trial_traces`, `recording_traces`, `material_traces`).
    title : str, optional
        Title above the two panels.
    xlabel : str, optional
        Label of the shared time axis.
    slope : str, optional
        ``"detector"``: the onset detector's slope; ``"paper"``: the paper's filtered first
        difference (`paper_slope`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure, on an Agg canvas (no window, no pyplot state). Artists carry gids:
        ``temperature:i`` and ``slope:i`` (the curves of trace i), ``onset:i``,
        ``release:i``, ``detected:i``, ``true_onset``, ``true_release`` and ``contact:ID``.

    Raises
    ------
    SkinError
        When there is no trace or ``slope`` is unknown.
    """
    from skin._optional import require
    from skin.viz.plots import _figure_class

    if not traces:
        raise SkinError("no trace to draw")
    if slope not in SLOPES:
        raise SkinError(f"unknown slope {slope!r}; choose one of {', '.join(SLOPES)}")
    figure_cls, canvas_cls = _figure_class()
    mlines = require("matplotlib.lines", "plotting")
    fig = figure_cls(figsize=(8.0, 6.4), layout="constrained")
    canvas_cls(fig)
    ax_t, ax_s = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    many = len(traces) > _MAX_NAMED
    legend: dict[str, Any] = {}
    for i, tr in enumerate(traces):
        label = (tr.group or tr.name) if many else tr.name
        line, = ax_t.plot(tr.times, tr.temperature, color=tr.colour, lw=1.2,
                          gid=f"temperature:{i}")
        legend.setdefault(label, line)
        values = tr.slope if slope == "detector" else paper_slope(tr.times, tr.temperature)
        ax_s.plot(tr.times, values, color=tr.colour, lw=1.1, gid=f"slope:{i}")
        for ax in (ax_t, ax_s):
            for t in tr.onsets:
                ax.axvline(t, color=tr.colour, ls="-", lw=1.0, alpha=0.85, gid=f"onset:{i}")
            for t in tr.releases:
                ax.axvline(t, color=tr.colour, ls="-.", lw=1.0, alpha=0.85,
                           gid=f"release:{i}")
        for t in tr.detected_at:
            k = int(np.argmin(np.abs(tr.times - t)))
            ax_t.plot([t], [tr.temperature[k]], marker="v", color=tr.colour, ms=6,
                      mec=_TRUTH, mew=0.6, ls="none", gid=f"detected:{i}")
    # the truth, once per instant (the taxels of one touch share it)
    true_on = sorted({round(t, 9) for tr in traces for t in tr.true_onsets})
    true_off = sorted({round(t, 9) for tr in traces for t in tr.true_releases})
    for ax in (ax_t, ax_s):
        for t in true_on:
            ax.axvline(t, color=_TRUTH, ls="--", lw=1.0, gid="true_onset")
        for t in true_off:
            ax.axvline(t, color=_TRUTH, ls=":", lw=1.2, gid="true_release")
    contacts = {c.id: c for tr in traces for c in tr.contacts}
    for c in contacts.values():
        ax_t.axvspan(c.onset, max(c.end, c.onset), color=c.colour, alpha=0.15, lw=0,
                     gid=f"contact:{c.id}")
        ax_t.annotate(f"{_display(c.label)} ({c.confidence:.2f})", (c.onset, 1.0),
                      xycoords=("data", "axes fraction"), xytext=(2, -2),
                      textcoords="offset points", va="top", fontsize="x-small")
    ax_s.axhline(0.0, color="#BBBBBB", lw=0.6, zorder=0)
    ax_t.set_ylabel("temperature, °C")
    ax_s.set_ylabel("slope, K/s (onset detector)" if slope == "detector"
                    else "slope, K/s (2 Hz low-pass)")
    ax_s.set_xlabel(xlabel)
    for ax in (ax_t, ax_s):
        ax.grid(True, alpha=0.3)
    ax_t.legend(list(legend.values()), list(legend), fontsize="x-small", loc="best",
                ncol=1 if len(legend) <= 6 else 2)
    marks = []
    if any(tr.onsets for tr in traces):
        marks.append(mlines.Line2D([], [], color="#666666", ls="-", label="onset (detected)"))
    if any(tr.detected_at for tr in traces):
        marks.append(mlines.Line2D([], [], color="#666666", marker="v", ls="none",
                                   label="recognised"))
    if any(tr.releases for tr in traces):
        marks.append(mlines.Line2D([], [], color="#666666", ls="-.", label="release"))
    if true_on:
        marks.append(mlines.Line2D([], [], color=_TRUTH, ls="--", label="true onset"))
    if true_off:
        marks.append(mlines.Line2D([], [], color=_TRUTH, ls=":", label="true release"))
    if marks:  # below the panels, clear of the curves
        fig.legend(handles=marks, fontsize="x-small", loc="outside lower center",
                   ncol=len(marks), frameon=False)
    if title:
        fig.suptitle(title)
    return fig


def plot_traces(
    traces: Sequence[TaxelTrace],
    path: str | Path,
    *,
    title: str | None = None,
    xlabel: str = "time, s",
    slope: str = "detector",
) -> Path:
    """Draw traces with their onset marks into a file (see `traces_figure`).

    Parameters
    ----------
    traces : sequence of TaxelTrace
        What to draw.
    path : str or Path
        Output file; its suffix picks the format (``.png``, also without a suffix, ``.svg``
        or ``.pdf``). Missing parent folders are created.
    title : str, optional
        Title of the figure.
    xlabel : str, optional
        Label of the time axis.
    slope : str, optional
        ``"detector"`` or ``"paper"`` (see `traces_figure`).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    SkinError
        When the format is not supported or there is no trace.
    MissingDependencyError
        When matplotlib is not installed (``pip install 'thermoskin[viz]'``).
    """
    from skin.viz.plots import _save, output_path

    out = output_path(path)  # check the format before drawing
    return _save(traces_figure(traces, title=title, xlabel=xlabel, slope=slope), out)

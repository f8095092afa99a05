"""Plots drawn with matplotlib, imported only when a plot is drawn.

`plot_materials` draws the effusivity range of each material, like Fig. 10 of the paper
(Bhattacharjee, Wade, Kemp 2015): one horizontal bar per material on a log10 effusivity axis.
`plot_work_precision` and `plot_estimator_errors` draw the figures of ``skin bench thermal``,
`plot_accuracy` and `plot_confusions` those of ``skin evaluate``. Taxels' temperature and
slope traces are in `skin.viz.trace_plots`. Every figure is reachable as ``skin plot KIND``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from skin._optional import require
from skin.errors import SkinError

if TYPE_CHECKING:
    from skin.models.materials import Material
    from skin.models.physics import SensorConstants

#: Output formats, chosen by the suffix of the output path.
FORMATS = (".png", ".svg", ".pdf")

_EFFUSIVITY_UNIT = r"W s$^{1/2}$ m$^{-2}$ K$^{-1}$"
_DISPLAY_NAMES = {"mdf": "MDF"}
_EDGE = "#222222"
_EXTREME_HATCH = "////"


def display_name(name: str) -> str:
    """Name of a material as printed on a figure (``"human_skin"`` -> ``"human skin"``)."""
    return _DISPLAY_NAMES.get(name, name.replace("_", " "))


def output_path(path: str | Path) -> Path:
    """Check the output path of a figure; a path without suffix gets ``.png``.

    Parameters
    ----------
    path : str or Path
        Where the figure goes; its suffix (``.png``, ``.svg`` or ``.pdf``) picks the format.

    Returns
    -------
    Path
        The path, with ``.png`` appended when it had no suffix.

    Raises
    ------
    SkinError
        When the suffix names a format that is not supported.
    """
    out = Path(path)
    if not out.suffix:
        out = out.with_suffix(".png")
    if out.suffix.lower() not in FORMATS:
        raise SkinError(f"{out}: unsupported figure format {out.suffix!r} "
                        f"(use {', '.join(FORMATS)})")
    return out


def _figure_class() -> Any:
    """Import matplotlib with the non-interactive Agg canvas; return `Figure` and the canvas."""
    require("matplotlib", "plotting")
    figure = require("matplotlib.figure", "plotting")
    agg = require("matplotlib.backends.backend_agg", "plotting")
    return figure.Figure, agg.FigureCanvasAgg


def _select(materials: Mapping[str, Material] | Iterable[Material],
            include_all: bool) -> list[Material]:
    values = materials.values() if isinstance(materials, Mapping) else materials
    chosen = [m for m in values if include_all or m.classify]
    return sorted(chosen, key=lambda m: (m.effusivity, m.name))


def materials_figure(
    materials: Mapping[str, Material] | Iterable[Material],
    include_all: bool = False,
    *,
    sensor: SensorConstants | None = None,
) -> Any:
    """Build the figure of the materials' effusivity ranges (the paper's Fig. 10).

    One horizontal bar per material spans its effusivity range ``sqrt(k rho c)`` from the
    (min, max) of its table entry on a log10 axis, in the material's colour, with a marker at
    its nominal effusivity; the materials are sorted by nominal effusivity (lowest at the
    bottom). A dashed vertical line marks the sensor's own effusivity. Materials that are not
    classification candidates (``classify = false``, the extremes kept for tests) are hatched.

    Parameters
    ----------
    materials : mapping of str to Material, or iterable of Material
        The materials table, as returned by `skin.models.load_materials`.
    include_all : bool, optional
        Draw every material; by default only those with ``classify = true``.
    sensor : SensorConstants, optional
        Sensor whose effusivity is drawn (default: the paper's sensor).

    Returns
    -------
    matplotlib.figure.Figure
        The figure, attached to an Agg canvas (no window, no pyplot state).

    Raises
    ------
    SkinError
        When no material is selected.
    """
    from skin.models.physics import SensorConstants

    chosen = _select(materials, include_all)
    if not chosen:
        raise SkinError("no material to plot (the table has no classified material; "
                        "use include_all to draw every one)")
    sensor = SensorConstants() if sensor is None else sensor
    figure_cls, canvas_cls = _figure_class()
    mpatches = require("matplotlib.patches", "plotting")
    mlines = require("matplotlib.lines", "plotting")

    fig = figure_cls(figsize=(7.5, 1.4 + 0.36 * len(chosen)), layout="constrained")
    canvas_cls(fig)
    ax = fig.add_subplot()
    ax.set_xscale("log")
    ys = range(len(chosen))
    for y, m in zip(ys, chosen, strict=True):
        lo, hi = m.effusivity_range
        extreme = not m.classify
        ax.barh(y, hi - lo, left=lo, height=0.6, color=m.colour, edgecolor=_EDGE,
                linewidth=0.8, hatch=_EXTREME_HATCH if extreme else None,
                label=m.name, gid=f"range:{m.name}")
        ax.plot([m.effusivity], [y], marker="D", markersize=5, markerfacecolor="white",
                markeredgecolor=_EDGE, markeredgewidth=1.2, linestyle="none",
                gid=f"nominal:{m.name}")
    e_sensor = float(sensor.effusivity)
    ax.axvline(e_sensor, color=_EDGE, linestyle="--", linewidth=1.2, gid="sensor")

    lows, highs = zip(*(m.effusivity_range for m in chosen), strict=True)
    ax.set_xlim(min(*lows, e_sensor) / 1.5, max(*highs, e_sensor) * 1.5)
    ax.set_yticks(list(ys), [display_name(m.name) for m in chosen])
    ax.set_ylim(-0.7, len(chosen) - 0.3)
    ax.set_xlabel(rf"thermal effusivity $e = \sqrt{{k \rho c}}$ ({_EFFUSIVITY_UNIT}), log scale")
    ax.grid(axis="x", which="major", color="#CCCCCC", linewidth=0.6)
    ax.grid(axis="x", which="minor", color="#EEEEEE", linewidth=0.4)
    ax.set_axisbelow(True)
    ax.set_title("Effusivity ranges of the materials (min to max of k, rho, c)")

    handles = [
        mpatches.Patch(facecolor="#BBBBBB", edgecolor=_EDGE, label="range (min to max)"),
        mlines.Line2D([], [], marker="D", markersize=5, markerfacecolor="white",
                      markeredgecolor=_EDGE, linestyle="none", label="nominal"),
        mlines.Line2D([], [], color=_EDGE, linestyle="--",
                      label=f"sensor e = {e_sensor:.0f}"),
    ]
    if any(not m.classify for m in chosen):
        handles.append(mpatches.Patch(facecolor="white", edgecolor=_EDGE,
                                      hatch=_EXTREME_HATCH, label="extreme (not classified)"))
    ax.legend(handles=handles, loc="lower right", fontsize="small", framealpha=0.9)
    return fig


def plot_materials(
    materials: Mapping[str, Material] | Iterable[Material],
    path: str | Path,
    include_all: bool = False,
    *,
    sensor: SensorConstants | None = None,
) -> Path:
    """Draw the materials' effusivity ranges (the paper's Fig. 10) into a file.

    See `materials_figure` for what the figure shows.

    Parameters
    ----------
    materials : mapping of str to Material, or iterable of Material
        The materials table, as returned by `skin.models.load_materials`.
    path : str or Path
        Output file; its suffix picks the format: ``.png`` (also when there is no suffix),
        ``.svg`` or ``.pdf``. Missing parent folders are created.
    include_all : bool, optional
        Draw every material, the extremes (``classify = false``) hatched; by default only the
        classification candidates.
    sensor : SensorConstants, optional
        Sensor whose effusivity is drawn as a dashed line (default: the paper's sensor).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    SkinError
        When the format is not supported or no material is selected.
    MissingDependencyError
        When matplotlib is not installed (``pip install 'thermoskin[viz]'``).
    """
    out = output_path(path)  # check the format before drawing
    return _save(materials_figure(materials, include_all, sensor=sensor), out)


def _metadata(path: Path) -> dict[str, Any] | None:
    # drop the creation date so that the same table gives the same SVG and PDF bytes
    suffix = path.suffix.lower()
    if suffix == ".svg":
        return {"Date": None}
    if suffix == ".pdf":
        return {"CreationDate": None}
    return None


def _save(fig: Any, path: str | Path) -> Path:
    out = output_path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=150, metadata=_metadata(out))
    return out


_SCHEME_STYLE = {"tr-bdf2": ("#0072B2", "o"), "crank-nicolson": ("#E69F00", "s"),
                 "euler": ("#CC79A7", "^")}


def plot_work_precision(rows: list[dict], path: str | Path) -> Path:
    """Draw the forward models' work-precision diagram (``skin bench thermal``) into a file.

    One panel per test case: RMS error against run time per trial (log-log) for each scheme
    and grid, lines joining the time steps of one grid; the closed forms as reference lines.

    Parameters
    ----------
    rows : list of dict
        The ``forward`` rows of `skin.bench.thermal.forward`.
    path : str or Path
        Output file (``.png``, ``.svg`` or ``.pdf``).

    Returns
    -------
    Path
        The path written.
    """
    figure_cls, canvas_cls = _figure_class()
    cases = sorted({r["case"] for r in rows})
    fig = figure_cls(figsize=(5.5 * len(cases), 4.8), layout="constrained")
    canvas_cls(fig)
    axes = fig.subplots(1, len(cases), squeeze=False)[0]
    for ax, case in zip(axes, cases, strict=True):
        mine = [r for r in rows if r["case"] == case and r["scheme"] != "closed form"
                and r["model"].endswith("limit)") and r.get("conductance") is None]
        for scheme, (colour, marker) in _SCHEME_STYLE.items():
            for cells in sorted({r["cells"] for r in mine}):
                pts = sorted((-r["dt"], r["time_per_trial_ms"], r["rms_error"]) for r in mine
                             if r["scheme"] == scheme and r["cells"] == cells)
                if not pts:
                    continue
                _, x, y = zip(*pts, strict=True)  # joined from the largest step to the smallest
                ax.plot(x, y, color=colour, marker=marker, alpha=0.35 + 0.65 * cells / max(
                    r["cells"] for r in mine), label=f"{scheme}, {cells} cells")
        closed = [r for r in rows if r["case"] == case and r["model"] == "semi-infinite"]
        for r in closed:
            ax.axvline(r["time_per_trial_ms"], color=_EDGE, ls=":", lw=1)
            ax.annotate("closed form", (r["time_per_trial_ms"], 1.0), rotation=90,
                        xycoords=("data", "axes fraction"), va="top", ha="right",
                        fontsize="x-small")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("run time per 2.5 s trial, ms (one trial, this machine)")
        ax.set_ylabel("RMS error against eq. 5, K")
        ax.set_title(f"{case}: multilayer model in the semi-infinite limit")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small", ncol=1)
    return _save(fig, path)


def plot_estimator_errors(rows: list[dict], path: str | Path) -> Path:
    """Draw the inverse estimators' effusivity error against contact duration into a file.

    Parameters
    ----------
    rows : list of dict
        The ``inverse`` rows of `skin.bench.thermal.inverse`.
    path : str or Path
        Output file (``.png``, ``.svg`` or ``.pdf``).

    Returns
    -------
    Path
        The path written.
    """
    figure_cls, canvas_cls = _figure_class()
    fig = figure_cls(figsize=(6.5, 4.5), layout="constrained")
    canvas_cls(fig)
    ax = fig.subplots()
    colours = ("#0072B2", "#D55E00", "#009E73")
    for colour, name in zip(colours, sorted({r["estimator"] for r in rows}), strict=False):
        mine = sorted((r for r in rows if r["estimator"] == name), key=lambda r: r["duration"])
        d = [r["duration"] for r in mine]
        med = [r["median_abs_log10_error"] for r in mine]
        p90 = [r["p90_abs_log10_error"] for r in mine]
        cost = np.mean([r["time_per_trial_ms"] for r in mine])
        ax.plot(d, med, color=colour, marker="o", label=f"{name}: median ({cost:.2g} ms/trial)")
        ax.plot(d, p90, color=colour, marker="o", ls="--", alpha=0.6, label=f"{name}: 90th pct")
    ax.set_xlabel("contact duration, s")
    ax.set_ylabel("|log10 estimated / true effusivity|, decades")
    ax.set_title("effusivity estimators on simulated protocol trials")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    return _save(fig, path)


def plot_accuracy(results: list[dict], path: str | Path, *, title: str | None = None) -> Path:
    """Draw accuracy against contact duration, one line per method (``skin evaluate``).

    Parameters
    ----------
    results : list of dict
        The ``results`` of ``skin evaluate --json`` (``method``, ``duration``, ``accuracy``,
        ``accuracy_std``); a band shows the spread over the folds.
    path : str or Path
        Output file (``.png``, ``.svg`` or ``.pdf``).
    title : str, optional
        Title of the figure (default: "accuracy against contact duration").

    Returns
    -------
    Path
        The path written.
    """
    figure_cls, canvas_cls = _figure_class()
    fig = figure_cls(figsize=(6.5, 4.5), layout="constrained")
    canvas_cls(fig)
    ax = fig.subplots()
    methods = list(dict.fromkeys(r["method"] for r in results))
    for method in methods:
        mine = sorted((r for r in results if r["method"] == method and r["accuracy"] is not None),
                      key=lambda r: r["duration"])
        d = [r["duration"] for r in mine]
        acc = np.array([r["accuracy"] for r in mine])
        sd = np.array([r["accuracy_std"] for r in mine])
        line, = ax.plot(d, 100 * acc, marker="o", label=method, gid=f"accuracy:{method}")
        ax.fill_between(d, 100 * (acc - sd), 100 * (acc + sd), color=line.get_color(),
                        alpha=0.15)
    ax.set_xlabel("contact duration, s")
    ax.set_ylabel("accuracy, % (mean +- std over folds)")
    ax.set_ylim(0, 100)
    ax.set_title(title or "accuracy against contact duration")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return _save(fig, path)


def plot_confusions(results: list[dict], path: str | Path, *, title: str | None = None) -> Path:
    """Draw confusion matrices as row fractions: one row per method, one panel per duration.

    Parameters
    ----------
    results : list of dict
        ``skin evaluate`` results (``method``, ``duration``, ``accuracy``, ``confusion``,
        ``classes``) of one method or several, in the order their rows are drawn.
    path : str or Path
        Output file (``.png``, ``.svg`` or ``.pdf``).
    title : str, optional
        Title of the figure (default: "confusion matrices: METHOD" for one method).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    SkinError
        When ``results`` is empty.
    """
    if not results:
        raise SkinError("no result to draw confusion matrices of")
    figure_cls, canvas_cls = _figure_class()
    methods = list(dict.fromkeys(r["method"] for r in results))
    durations = sorted({r["duration"] for r in results})
    cell = {(r["method"], r["duration"]): r for r in results}
    n, rows = len(durations), len(methods)
    k = max(len(r["classes"]) for r in results)
    fig = figure_cls(figsize=(0.45 * k * n + 2.0, rows * (0.45 * k + 1.4) + 0.4),
                     layout="constrained")
    canvas_cls(fig)
    grid = fig.subplots(rows, n, squeeze=False)
    image = None
    for i, method in enumerate(methods):
        for j, duration in enumerate(durations):
            ax = grid[i, j]
            r = cell.get((method, duration))
            if r is None:
                ax.set_axis_off()
                continue
            names = [display_name(c) for c in r["classes"]]
            conf = np.asarray(r["confusion"], dtype=float)
            frac = conf / np.maximum(conf.sum(axis=1, keepdims=True), 1)
            image = ax.imshow(frac, vmin=0, vmax=1, cmap="viridis",
                              gid=f"confusion:{method}:{duration:g}")
            ax.set_xticks(range(len(names)), names, rotation=90, fontsize="x-small")
            ax.set_yticks(range(len(names)), names if j == 0 else [], fontsize="x-small")
            acc = "-" if r["accuracy"] is None else f"{100 * r['accuracy']:.0f} %"
            head = f"{duration:g} s: {acc}" if rows == 1 else f"{method}, {duration:g} s: {acc}"
            ax.set_title(head, fontsize="small")
            ax.set_xlabel("predicted", fontsize="x-small")
            if j == 0:
                ax.set_ylabel("true", fontsize="x-small")
    fig.colorbar(image, ax=list(grid.ravel()), shrink=0.8, label="fraction of the true class")
    fig.suptitle(title or (f"confusion matrices: {methods[0]}" if rows == 1
                           else "confusion matrices"))
    return _save(fig, path)

"""Plots drawn with matplotlib, imported only when a plot is drawn.

`plot_materials` draws the effusivity range of each material, like Fig. 10 of the paper
(Bhattacharjee, Wade, Kemp 2015): one horizontal bar per material on a log10 effusivity axis.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

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
    out = output_path(path)
    fig = materials_figure(materials, include_all, sensor=sensor)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=150, metadata=_metadata(out))
    return out


def _metadata(path: Path) -> dict[str, Any] | None:
    # drop the creation date so that the same table gives the same SVG and PDF bytes
    suffix = path.suffix.lower()
    if suffix == ".svg":
        return {"Date": None}
    if suffix == ".pdf":
        return {"CreationDate": None}
    return None

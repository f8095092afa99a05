"""The arm view: material labels painted onto a mesh of the arm (pyvista, off screen or live).

The arm is a mesh per link (`skin.viz.arm_mesh`: the procedural arm of the default layout, or
your own STL/OBJ/PLY files); each taxel owns the patch of surface around it, computed once.
Painting writes colours into the mesh's one RGBA point array in place (`skin.viz.arm_paint`):
no mesh is rebuilt and no actor added per update, so an update costs the library well under a
millisecond and a frame costs what the renderer takes.

Use::

    view = ArmView(layout, {m.name: m.colour for m in load_materials().values()})
    view.paint([0, 1], "aluminium", confidence=0.9, at=2.0)    # taxel ids
    view.update(now=3.0, in_contact=pipeline.in_contact(), temperature=t, results=new)
    view.mode = "temperature"
    view.screenshot("map.png", title="contact map")
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from skin._optional import require
from skin.errors import MissingDependencyError, ViewError
from skin.formats.layout import Layout
from skin.viz.arm_mesh import (
    SNAP_TOLERANCE,
    ArmLink,
    ArmSurface,
    LinkGeometry,
    arm_from_meshes,
    default_arm,
    resolve_arm,
)
from skin.viz.arm_paint import BARE, MODES, UNKNOWN_COLOUR, TaxelPainter, hex_rgb

__all__ = [
    "BARE",
    "UNKNOWN_COLOUR",
    "ArmLink",
    "ArmView",
    "LinkGeometry",
    "default_arm",
    "hex_rgb",
    "window_problem",
]


_SQUARE = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])


def window_problem() -> str | None:
    """Return why no window can open here, or None if one can.

    On Linux and BSD a window needs DISPLAY or WAYLAND_DISPLAY.
    """
    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")) and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "there is no display (neither DISPLAY nor WAYLAND_DISPLAY is set)"
    return None


class ArmView:
    """Paint taxel patches of an arm mesh and render them, in a window or off screen.

    Parameters
    ----------
    layout : Layout
        The taxels; each must lie within ``tolerance`` of its link's surface.
    colours : dict
        Material name -> ``"#RRGGBB"`` (the materials table's ``colour``).
    arm : dict, str or Path, optional
        Link name -> `ArmLink` (or `LinkGeometry`), or an arm file (`skin.viz.arm_mesh.load_arm`);
        by default the procedural arm of the default layout (`default_arm`).
    off_screen : bool
        Render without a window; with False a window opens on the first `render` (a
        `ViewError` when there is no display).
    window_size : tuple of int
        Image size, pixels.
    patch_radius : float, optional
        Largest distance from a taxel to a vertex of its patch, m; by default half the median
        distance between neighbouring taxels.
    tolerance : float
        Largest distance from a taxel to its link's surface, m.
    sides : sequence of str
        One view per entry: ``"front"`` (from -y) and/or ``"back"`` (from +y).
    memory : float or None
        Time constant of the contact map's fading, s (None: painted contacts never fade).
    vertices : int
        About how many vertices the procedural arm has (ignored for a given arm).
    highlight : str or None
        Rim colour of taxels in contact; None: black or white, whichever stands out.
    cmap : str
        Colormap of the temperature mode.
    clim : tuple of float, optional
        Temperature range of the colormap, deg C; by default fixed by the first temperatures.
    zoom : float
        Camera zoom of each view, after fitting the arm.

    Attributes
    ----------
    arm : dict
        Link name -> `ArmLink`, its ``pose`` the current one (`set_poses` changes it).
    mesh : pyvista.PolyData
        The whole arm in the world frame; its ``"rgba"`` point array holds the colours.
    patch : numpy.ndarray
        Per vertex, the layout index of the taxel owning it, -1 for bare skin.
    taxel_world : numpy.ndarray
        (N, 3) taxels snapped onto the surface, world frame.
    plotter : pyvista.Plotter
        The plotter (one subplot per side).
    surface : ArmSurface
        The geometry: snapped taxels, patches and rims (`skin.viz.arm_mesh`).
    painter : TaxelPainter
        Each taxel's label, confidence, time, contact and temperature, and the colours they
        give (`skin.viz.arm_paint`).
    """

    def __init__(
        self,
        layout: Layout,
        colours: Mapping[str, str],
        arm: Mapping[str, ArmLink | LinkGeometry] | str | Path | None = None,
        *,
        off_screen: bool = True,
        window_size: tuple[int, int] = (1600, 700),
        patch_radius: float | None = None,
        tolerance: float = SNAP_TOLERANCE,
        sides: Sequence[str] = ("front", "back"),
        memory: float | None = 60.0,
        vertices: int = 14_000,
        highlight: str | None = None,
        cmap: str = "inferno",
        clim: tuple[float, float] | None = None,
        zoom: float = 1.0,
    ) -> None:
        pv = require("pyvista", "the arm view")
        self._pv = pv
        _quiet_vtk()
        why = None if off_screen else window_problem()
        if why is not None:
            raise ViewError(f"cannot open a window: {why}; render off screen instead "
                            "(skin run --video out/run.gif), or run under a virtual display "
                            "(xvfb-run)")
        bad = [s for s in sides if s not in ("front", "back")]
        if bad or not sides:
            raise ViewError(f"sides must be 'front' and/or 'back', got {list(sides)}")
        self.layout = layout
        self.colours = dict(colours)
        self.surface = ArmSurface(layout, resolve_arm(arm, vertices), patch_radius, tolerance)
        self.arm = dict(self.surface.arm)
        self.patch = self.surface.owner
        self.taxel_world = self.surface.taxel_world
        self.painter = TaxelPainter(len(layout), self.colours, self.surface.owner,
                                    self.surface.rim, memory=memory, highlight=highlight,
                                    cmap=cmap, clim=clim)
        self.mesh = self._make_mesh()
        self.off_screen = off_screen
        self._shown = False
        self._legend_key: tuple = ()
        self._bar_range: tuple[float, float] | None = None
        self.plotter = pv.Plotter(off_screen=off_screen, window_size=list(window_size),
                                  shape=(1, len(sides)), border=False)
        self.plotter.set_background("white")
        for col, side in enumerate(sides):
            self.plotter.subplot(0, col)
            self.plotter.add_mesh(self.mesh, scalars="rgba", rgb=True, smooth_shading=False,
                                  ambient=0.35, diffuse=0.7, specular=0.1, name=f"arm_{side}")
            self.plotter.add_text(side, position="lower_left", font_size=10, color="black",
                                  name=f"side_{side}")
            self.plotter.view_vector((0.0, -1.0 if side == "front" else 1.0, 0.35),
                                     viewup=(0, 0, 1))
            self.plotter.reset_camera()
            self.plotter.camera.zoom(zoom * self._fit_zoom(self.plotter.renderer))
        self.plotter.subplot(0, 0)
        self._title = self.plotter.add_text(" ", position="upper_left", font_size=12,
                                            color="black", name="title")
        self.plotter.subplot(0, len(sides) - 1)
        self._front_last = sides[-1] == "front"
        self._legend = self._make_legend()
        self._bar, self._lut = self._make_scalar_bar()
        self._refresh()

    @classmethod
    def from_meshes(cls, layout: Layout, colours: Mapping[str, str],
                    meshes: Mapping[str, tuple[str | Path, Any]], *, scale: float = 1.0,
                    **kwargs: Any) -> ArmView:
        """Make a view of an arm of one mesh file per link: ``{link: (path, pose 4x4)}``.

        See `skin.viz.arm_mesh.arm_from_meshes`; other arguments as `ArmView`.
        """
        return cls(layout, colours, arm_from_meshes(meshes, scale), **kwargs)

    # --- scene -----------------------------------------------------------------------------

    def _make_mesh(self) -> Any:
        from vtkmodules.util.numpy_support import vtk_to_numpy

        s = self.surface
        faces = np.column_stack([np.full(len(s.faces), 3), s.faces]).ravel()
        mesh = self._pv.PolyData(s.points.copy(), faces)
        mesh.point_data["Normals"] = s.normals
        mesh.point_data.active_normals_name = "Normals"
        mesh.point_data["rgba"] = np.zeros((mesh.n_points, 4), dtype=np.uint8)
        data = mesh.GetPointData()
        self._vtk_rgba = data.GetArray("rgba")
        self._rgba32 = vtk_to_numpy(self._vtk_rgba).view(np.uint32).reshape(-1)
        # world points and normals live in VTK's memory: poses are rewritten in place
        self._points = vtk_to_numpy(mesh.GetPoints().GetData())
        self._normals = vtk_to_numpy(data.GetArray("Normals"))
        s.pose_points(self._points, self._normals)
        return mesh

    def _fit_zoom(self, renderer: Any, margin: float = 0.92) -> float:
        """Zoom that makes the arm fill the view (the arm is long and thin, not a sphere)."""
        w, h = renderer.GetSize()
        m = renderer.GetActiveCamera().GetCompositeProjectionTransformMatrix(
            w / max(h, 1), -1, 1)
        proj = np.array([[m.GetElement(i, j) for j in range(4)] for i in range(4)])
        pts = self.surface.points[:: max(1, len(self.surface.points) // 4000)]
        ndc = np.c_[pts, np.ones(len(pts))] @ proj.T
        extent = np.abs(ndc[:, :2] / ndc[:, 3:4]).max()
        return margin / extent if extent > 0 else 1.0

    def _make_legend(self) -> Any:
        from vtkmodules.vtkRenderingAnnotation import vtkLegendBoxActor

        legend = vtkLegendBoxActor()
        legend.SetUseBackground(True)
        legend.SetBackgroundColor(1.0, 1.0, 1.0)
        legend.SetBorder(False)
        legend.GetEntryTextProperty().SetColor(0.0, 0.0, 0.0)
        legend.ScalarVisibilityOn()  # each swatch carries its colour; the text stays black
        self.plotter.add_actor(legend, reset_camera=False, name="legend", pickable=False)
        return legend

    def _make_scalar_bar(self) -> tuple[Any, Any]:
        from vtkmodules.vtkCommonCore import vtkLookupTable
        from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

        lut = vtkLookupTable()
        bar = vtkScalarBarActor()
        bar.SetLookupTable(lut)
        bar.SetTitle("deg C")
        bar.SetNumberOfLabels(5)
        if self._front_last:  # along the top, clear of the hand (see _update_legend)
            bar.SetOrientationToHorizontal()
            bar.SetPosition(0.45, 0.82)
            bar.SetPosition2(0.52, 0.16)
        else:
            bar.SetPosition(0.86, 0.08)
            bar.SetPosition2(0.12, 0.84)
        for prop in (bar.GetTitleTextProperty(), bar.GetLabelTextProperty()):
            prop.SetColor(0.0, 0.0, 0.0)
            prop.ShadowOff()
        bar.SetVisibility(False)
        self.plotter.add_actor(bar, reset_camera=False, name="scalar_bar", pickable=False)
        return bar, lut

    def _update_legend(self) -> None:
        entries = [*self.legend_entries(), ("not touched", BARE)]
        key = tuple(entries)
        if key == self._legend_key:
            return
        self._legend_key = key
        legend = self._legend
        legend.SetNumberOfEntries(len(entries))
        for i, (name, colour) in enumerate(entries):
            swatch = self._pv.PolyData(_SQUARE, faces=[4, 0, 1, 2, 3])
            swatch.cell_data["rgb"] = hex_rgb(colour)[None]
            legend.SetEntry(i, swatch, name, (0.0, 0.0, 0.0))
        height = min(0.9, 0.06 * len(entries))
        # the front view's forearm and hand reach down to the right, the back view's left
        legend.SetPosition(0.74, 0.97 - height if self._front_last else 0.03)
        legend.SetPosition2(0.24, height)

    def _update_scalar_bar(self) -> None:
        from vtkmodules.util.numpy_support import numpy_to_vtk

        if self._bar_range is None:
            table = self.painter.cmap_table()
            rgba = np.column_stack([table, np.full(len(table), 255, np.uint8)])
            self._lut.SetTable(numpy_to_vtk(rgba, deep=True))
        rng = self.painter.temperature_range()
        if rng != self._bar_range:
            self._lut.SetRange(*rng)
            self._bar_range = rng
        if not self._bar.GetVisibility():
            self._bar.SetVisibility(True)

    def _refresh(self) -> None:
        """Recompute the colours into the mesh's array (in place) and the legend."""
        self.painter.fill(self._rgba32)
        self._vtk_rgba.Modified()
        if self.painter.mode == "material":
            self._update_legend()
        else:
            self._update_scalar_bar()

    # --- painting --------------------------------------------------------------------------

    @property
    def mode(self) -> str:
        """What the patches show: ``"material"`` (labels) or ``"temperature"``."""
        return self.painter.mode

    @mode.setter
    def mode(self, value: str) -> None:
        if value not in MODES:
            raise ViewError(f"mode must be one of {', '.join(MODES)}, got {value!r}")
        self.painter.mode = value
        self._legend.SetVisibility(value == "material")
        self._bar.SetVisibility(False)
        self._refresh()

    @property
    def memory(self) -> float | None:
        """Time constant of the contact map's fading, s; None: contacts never fade."""
        return self.painter.memory

    @memory.setter
    def memory(self, value: float | None) -> None:
        if value is not None and not value > 0:
            raise ViewError(f"memory must be a positive time constant or None, got {value!r}")
        self.painter.memory = value
        self._refresh()

    @property
    def title(self) -> str:
        """Text at the upper left of the first view."""
        return str(self._title.GetText(2)).strip()

    @title.setter
    def title(self, text: str | None) -> None:
        self._title.SetText(2, text or " ")

    def paint(self, taxel_ids: Iterable[int], label: str, confidence: float = 1.0,
              at: float | None = None) -> None:
        """Paint these taxels' patches with a label.

        Parameters
        ----------
        taxel_ids : iterable of int
            Taxel ids (not layout indices).
        label : str
            A material name or ``"unknown"``.
        confidence : float
            0-1: the colour is greyer the lower it is.
        at : float, optional
            Device time of the contact, s: it fades from then on (see `memory`); None: it
            never fades.
        """
        idx = [self.layout.index(t) for t in taxel_ids]
        self.painter.paint(idx, label, confidence, at)
        self._refresh()

    def paint_result(self, result: Any) -> None:
        """Paint a `skin.stream.pipeline.ContactResult`: its taxels, label, confidence and time."""
        self._paint_result(result)
        self._refresh()

    def _paint_result(self, result: Any) -> None:
        contact, estimate = result.contact, result.estimate
        at = contact.release if contact.release is not None else contact.decided_at
        self.painter.paint([self.layout.index(t) for t in contact.taxels], estimate.label,
                           estimate.confidence, at)

    def update(self, now: float | None = None, *, in_contact: np.ndarray | None = None,
               temperature: np.ndarray | None = None, results: Iterable[Any] = ()) -> None:
        """Bring the view to a moment of the run: one call per frame, colours in place.

        Parameters
        ----------
        now : float, optional
            Device time, s: painted contacts fade by their age at this time.
        in_contact : numpy.ndarray, optional
            (N,) bool, layout order: taxels touching now (their rims are highlighted).
        temperature : numpy.ndarray, optional
            (N,) deg C, layout order (NaN: no reading): shown in temperature mode.
        results : iterable of ContactResult
            New results to paint first.
        """
        for result in results:
            self._paint_result(result)
        if now is not None:
            self.painter.now = float(now)
        if in_contact is not None:
            self.painter.in_contact[:] = in_contact
        if temperature is not None:
            t = np.asarray(temperature, dtype=float)
            if t.shape != (len(self.layout),):
                raise ViewError(f"temperature must have one value per taxel "
                                f"({len(self.layout)}), got shape {t.shape}")
            self.painter.temperature = t
        self._refresh()

    def clear(self) -> None:
        """Forget every painted contact: bare skin everywhere."""
        self.painter.clear()
        self._refresh()

    def legend_entries(self) -> list[tuple[str, str]]:
        """(label, colour) of every label on the skin now, sorted by name (unknown last)."""
        return [(name.replace("_", " "), colour) for name, colour in self.painter.legend()]

    def taxel_colour(self, taxel_id: int, rim: bool = False) -> np.ndarray:
        """Return the RGB a taxel's patch shows now (inside, or on its rim), uint8."""
        k = self.layout.index(taxel_id)
        row = k + (len(self.layout) + 1 if rim else 0)
        return self.painter.table[row, :3].copy()

    # --- poses -----------------------------------------------------------------------------

    def set_poses(self, poses: Mapping[str, Any]) -> None:
        """Move links: link name -> 4x4 pose (link frame -> world), in place.

        Links not given keep their offset from their ``parent`` (the hand follows the
        forearm) or stay where they are. `arm` and `taxel_world` follow.
        """
        new = self.surface.set_poses(poses)
        self.surface.pose_points(self._points, self._normals)
        self.arm = {name: replace(link, pose=new[name]) for name, link in self.arm.items()}
        self.mesh.GetPoints().Modified()
        self.mesh.GetPointData().GetArray("Normals").Modified()
        self.mesh.Modified()

    # --- output ----------------------------------------------------------------------------

    def render(self) -> None:
        """Draw the current colours (the first call opens the window, when not off screen)."""
        if not self._shown:  # the first render: a window opens (and stays) unless off screen
            self.plotter.show(interactive_update=not self.off_screen, auto_close=False)
            self._shown = True
        elif not self.off_screen:
            self.plotter.update(stime=1, force_redraw=True)  # also handles the window's events
        else:
            self.plotter.render()

    def image(self) -> np.ndarray:
        """Render and return the picture as an (height, width, 3) uint8 array."""
        self.render()
        return np.asarray(self.plotter.screenshot(None, return_img=True))[..., :3]

    def screenshot(self, path: str | Path, title: str | None = None) -> Path:
        """Render to a PNG (with the legend, or the scalar bar in temperature mode)."""
        if title is not None:
            self.title = title
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        self.render()
        self.plotter.screenshot(str(path))
        return path

    def open_movie(self, path: str | Path, fps: float = 10.0) -> Path:
        """Start writing a GIF or MP4 of what is rendered; add frames with `write_frame`.

        A GIF needs imageio, an MP4 imageio-ffmpeg too.
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in (".gif", ".mp4"):
            raise ViewError(f"{path}: a movie must be .gif or .mp4")
        require("imageio", "a movie of the arm view")
        if suffix == ".mp4":
            try:
                import imageio_ffmpeg  # noqa: F401
            except ImportError:
                raise MissingDependencyError(
                    f"{path}: an MP4 needs the package 'imageio-ffmpeg', which is not "
                    "installed: pip install imageio-ffmpeg (or write a .gif)") from None
        path.parent.mkdir(parents=True, exist_ok=True)
        if suffix == ".gif":
            self.plotter.open_gif(str(path), fps=max(1, round(fps)))
        else:
            self.plotter.open_movie(str(path), framerate=max(1, round(fps)))
        return path

    def write_frame(self, repeat: int = 1) -> None:
        """Render once and append the picture ``repeat`` times to the movie (`open_movie`)."""
        writer = getattr(self.plotter, "mwriter", None)
        if writer is None:
            raise ViewError("no movie is open: call open_movie first")
        self.render()
        image = self.plotter.image
        for _ in range(max(1, int(repeat))):
            writer.append_data(image)

    def close(self) -> None:
        """Finish a movie and release the render window (idempotent)."""
        writer = getattr(self.plotter, "mwriter", None)
        if writer is not None:
            writer.close()
            self.plotter.mwriter = None
        self.plotter.close()


def _quiet_vtk() -> None:
    """Keep VTK's warnings about a missing X display (off-screen fallback) off stderr."""
    try:
        from vtkmodules.vtkCommonCore import vtkLogger

        vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    except ImportError:
        pass

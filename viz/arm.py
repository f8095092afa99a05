"""The arm view: material labels painted onto a mesh of the arm (pyvista, off screen or live).

The default arm is procedural: a cylinder per link (upper arm, forearm), an elbow, a wrist and
a hand, in a fixed pose.  Each taxel owns the patch of link surface nearest to it (computed
once); painting changes the colours of those patches in place, without rebuilding the mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skin._optional import require
from skin.contact import UNKNOWN
from skin.errors import LayoutError
from skin.layout import Layout

BARE = "#C8C8C8"  # skin never touched
UNKNOWN_COLOUR = "#3A3A3A"


@dataclass(frozen=True)
class LinkGeometry:
    """A cylindrical link: radius, length, and its pose (4x4, link frame -> world)."""

    radius: float
    length: float
    pose: np.ndarray


def _pose(angle_deg: float, origin: tuple[float, float, float]) -> np.ndarray:
    """Rotation about world y by ``angle_deg`` (link z -> (sin, 0, cos)), then translation."""
    a = np.radians(angle_deg)
    m = np.eye(4)
    m[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    m[:3, 3] = origin
    return m


def default_arm() -> dict[str, LinkGeometry]:
    """Return the procedural two-link arm that matches ``skin/data/layouts/arm.toml``."""
    upper = LinkGeometry(0.055, 0.30, _pose(90.0, (0.0, 0.0, 0.0)))
    elbow = upper.pose[:3, 3] + upper.pose[:3, 2] * (upper.length + 0.055)
    fore = LinkGeometry(0.045, 0.26, _pose(120.0, tuple(elbow)))
    return {"upper_arm": upper, "forearm": fore}


def hex_rgb(colour: str) -> np.ndarray:
    """``"#RRGGBB"`` -> uint8 RGB array."""
    h = colour.lstrip("#")
    return np.array([int(h[i : i + 2], 16) for i in (0, 2, 4)], dtype=np.uint8)


class ArmView:
    """Paint taxel patches of an arm mesh and render them.

    Parameters
    ----------
    layout : Layout
        The taxels; each must lie on its link's surface.
    colours : dict
        Material name -> ``"#RRGGBB"``.
    arm : dict of LinkGeometry, optional
        Link geometry; `default_arm` by default.
    off_screen : bool
        Render without a window.
    window_size : tuple of int
        Image size, pixels.
    patch_radius : float, optional
        Largest distance from a taxel to a vertex of its patch, m; by default 0.5 times the
        median distance between neighbouring taxels.
    """

    def __init__(
        self,
        layout: Layout,
        colours: dict[str, str],
        arm: dict[str, LinkGeometry] | None = None,
        *,
        off_screen: bool = True,
        window_size: tuple[int, int] = (1600, 700),
        patch_radius: float | None = None,
    ) -> None:
        pv = require("pyvista", "the arm view")
        self._pv = pv
        _quiet_vtk()
        self.layout = layout
        self.colours = dict(colours)
        self.arm = arm or default_arm()
        missing = sorted(set(layout.links) - set(self.arm))
        if missing:
            raise LayoutError(f"{layout.source}: link {missing[0]!r} has no geometry in the view")
        if patch_radius is None:
            near = layout.neighbours()
            d = np.linalg.norm(layout.positions[:, None] - layout.positions[None], axis=-1)
            patch_radius = 0.5 * float(np.median(d[near])) if near.any() else 0.02
        self.mesh, self.taxel_world = self._build(patch_radius)
        self.patch = self.mesh.point_data["taxel"]
        self._rgb = self.mesh.point_data["rgb"]
        self._labels: dict[int, str] = {}
        # two views of the one mesh, front and back: a colour change shows in both
        self.plotter = pv.Plotter(off_screen=off_screen, window_size=list(window_size),
                                  shape=(1, 2), border=False)
        self.plotter.set_background("white")
        decorations = self._decorations()
        for col, side in enumerate((-1.0, 1.0)):
            self.plotter.subplot(0, col)
            self.plotter.add_mesh(self.mesh, scalars="rgb", rgb=True, smooth_shading=True,
                                  ambient=0.35, diffuse=0.7, specular=0.1)
            for piece in decorations:
                self.plotter.add_mesh(piece, color=BARE, smooth_shading=True, ambient=0.35)
            self.plotter.add_text("front" if side < 0 else "back", position="lower_left",
                                  font_size=10, color="black")
            self.plotter.view_vector((0.0, side, 0.35), viewup=(0, 0, 1))
            self.plotter.reset_camera()
            self.plotter.camera.zoom(1.15)

    def _build(self, patch_radius: float):
        pv = self._pv
        pieces = []
        world = np.zeros_like(self.layout.positions)
        for name, geo in self.arm.items():
            surf = _tube(pv, geo.radius, geo.length)
            sel = np.flatnonzero(np.array(self.layout.links) == name)
            taxel = np.full(surf.n_points, -1, dtype=np.int64)
            if sel.size:
                pos = self.layout.positions[sel]
                _, closest = surf.find_closest_cell(pos, return_closest_point=True)
                off = np.linalg.norm(np.asarray(closest) - pos, axis=1)
                bad = np.flatnonzero(off > 0.004)
                if bad.size:
                    k = sel[bad[0]]
                    raise LayoutError(
                        f"{self.layout.source}: taxel {self.layout.ids[k]} lies "
                        f"{off[bad[0]] * 1000:.1f} mm from the surface of link {name!r}")
                d = np.linalg.norm(np.asarray(surf.points)[:, None] - pos[None], axis=-1)
                nearest = d.argmin(axis=1)
                taxel = np.where(d.min(axis=1) <= patch_radius, sel[nearest], -1)
                world[sel] = pos @ geo.pose[:3, :3].T + geo.pose[:3, 3]
            surf.point_data["taxel"] = taxel
            pieces.append(surf.transform(geo.pose, inplace=False))
        mesh = pieces[0].append_polydata(*pieces[1:]) if len(pieces) > 1 else pieces[0]
        mesh.point_data["rgb"] = np.tile(hex_rgb(BARE), (mesh.n_points, 1))
        return mesh, world

    def _decorations(self) -> list:
        pv = self._pv
        up, fore = self.arm.get("upper_arm"), self.arm.get("forearm")
        out = []
        if up is not None:
            out.append(pv.Sphere(radius=up.radius * 1.05, center=up.pose[:3, 3]))
        if up is not None and fore is not None:
            out.append(pv.Sphere(radius=up.radius, center=fore.pose[:3, 3]
                                 - fore.pose[:3, 2] * 0.5 * up.radius))
        if fore is not None:
            wrist = fore.pose[:3, 3] + fore.pose[:3, 2] * fore.length
            axis = fore.pose[:3, 2]
            out.append(pv.Sphere(radius=fore.radius * 0.85, center=wrist))
            out.append(pv.Box(bounds=(-0.035, 0.035, -0.045, 0.045, 0.0, 0.12))
                       .transform(_pose(120.0, tuple(wrist + axis * 0.02)), inplace=False))
        return out

    def paint(self, taxel_ids: list[int], label: str) -> None:
        """Colour the patches of these taxels with a material's colour (or the unknown look)."""
        colour = UNKNOWN_COLOUR if label == UNKNOWN else self.colours.get(label, UNKNOWN_COLOUR)
        rgb = hex_rgb(colour)
        idx = [self.layout.index(t) for t in taxel_ids]
        mask = np.isin(self.patch, idx)
        self._rgb[mask] = rgb
        for t in taxel_ids:
            self._labels[int(t)] = label
        self.mesh.Modified()

    def legend_entries(self) -> list[tuple[str, str]]:
        """(label, colour) of every label painted so far, sorted by name."""
        out = []
        for label in sorted(set(self._labels.values())):
            colour = UNKNOWN_COLOUR if label == UNKNOWN else self.colours.get(label, UNKNOWN_COLOUR)
            out.append((label.replace("_", " "), colour))
        return out

    def screenshot(self, path: str | Path, title: str | None = None) -> Path:
        """Render to a PNG with a legend of the painted materials."""
        entries = [*self.legend_entries(), ("not touched", BARE)]
        self.plotter.subplot(0, 1)
        self.plotter.add_legend(labels=[[name, colour] for name, colour in entries],
                                bcolor="white", face="rectangle", size=(0.22, 0.05 * len(entries)),
                                loc="lower right", name="legend")
        if title:
            self.plotter.subplot(0, 0)
            self.plotter.add_text(title, position="upper_left", font_size=12, color="black",
                                  name="title")
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        self.plotter.screenshot(str(path))
        return path

    def close(self) -> None:
        """Release the render window."""
        self.plotter.close()


def _tube(pv, radius: float, length: float, around: int = 96, along: int = 120):
    """Make an open cylinder along z from 0 to ``length``, as triangles."""
    theta = np.linspace(0, 2 * np.pi, around, endpoint=False)
    z = np.linspace(0, length, along)
    tt, zz = np.meshgrid(theta, z)
    points = np.column_stack([radius * np.cos(tt).ravel(), radius * np.sin(tt).ravel(), zz.ravel()])
    i, j = np.meshgrid(np.arange(along - 1), np.arange(around), indexing="ij")
    a = (i * around + j).ravel()
    b = (i * around + (j + 1) % around).ravel()
    c, d = a + around, b + around
    tris = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    faces = np.column_stack([np.full(len(tris), 3), tris]).ravel()
    return pv.PolyData(points, faces)


def _quiet_vtk() -> None:
    """Keep VTK's warnings about a missing X display (off-screen fallback) off stderr."""
    try:
        from vtkmodules.vtkCommonCore import vtkLogger

        vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    except ImportError:
        pass

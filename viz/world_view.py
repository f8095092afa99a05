"""The world material map drawn around the arm (pyvista): a coloured glyph per contact point.

`add_world_map` adds a `skin.world.map.WorldMap` to an `ArmView`, in both of its subplots: one
sphere per point in its material's colour (the materials table's ``colour``), set on the skin
along the point's normal so it is not buried in the mesh; "unknown" points are dark cubes, and
a label that has no colour is grey. A legend names every label with its number of points.
`render_world_map` builds the view (the arm posed as given), draws the map and writes a PNG
(off screen) or opens a window.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from skin._optional import require
from skin.contact import UNKNOWN
from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.viz.arm import UNKNOWN_COLOUR, ArmView, default_arm, window_problem
from skin.world.map import WorldMap

#: Colour of a label that the colour table does not know (not "unknown": a foreign material).
NO_COLOUR = "#777777"


def label_colour(label: str, colours: Mapping[str, str]) -> str:
    """Return the colour a label is drawn in: its material's, the unknown look, or grey."""
    if label == UNKNOWN:
        return UNKNOWN_COLOUR
    return colours.get(label, NO_COLOUR)


def posed_arm_view(layout: Layout, colours: Mapping[str, str],
                   poses: Mapping[str, np.ndarray] | None = None, **kwargs: Any) -> ArmView:
    """Return an `ArmView` whose links stand at ``poses`` (link -> 4x4, link -> world).

    Links without a pose keep the default arm's; with no poses it is the default arm.

    Parameters
    ----------
    layout : Layout
        The taxels.
    colours : dict
        Material name -> ``"#RRGGBB"``.
    poses : dict, optional
        Link poses, e.g. ``chain.poses(q)``.
    **kwargs
        Passed on to `ArmView` (``off_screen``, ``window_size``).
    """
    if poses is None:
        return ArmView(layout, dict(colours), **kwargs)
    arm = {name: dataclasses.replace(geo, pose=np.asarray(poses[name], dtype=float))
           if name in poses else geo for name, geo in default_arm().items()}
    return ArmView(layout, dict(colours), arm=arm, **kwargs)


def add_world_map(view: ArmView, world_map: WorldMap, colours: Mapping[str, str], *,
                  radius: float = 0.010, legend: bool = True) -> dict[str, list[Any]]:
    """Draw a world map's points in both subplots of an arm view.

    Parameters
    ----------
    view : ArmView
        The view (its ``plotter`` has two subplots, front and back).
    world_map : WorldMap
        The points.
    colours : dict
        Material name -> ``"#RRGGBB"``.
    radius : float
        Glyph radius, m; each glyph's centre sits this far out along its point's normal.
    legend : bool
        Add a legend of the labels (with their numbers of points) to the first subplot.

    Returns
    -------
    dict of str to list
        Label -> its actors (one per subplot).
    """
    pv = require("pyvista", "the world map view")
    centres = world_map.points + world_map.normals * radius
    labels = np.asarray(world_map.label)
    counts = world_map.counts()
    order = sorted(counts, key=lambda name: (name == UNKNOWN, name))
    actors: dict[str, list[Any]] = {}
    sphere = pv.Sphere(radius=radius, theta_resolution=20, phi_resolution=20)
    cube = pv.Cube(x_length=1.5 * radius, y_length=1.5 * radius, z_length=1.5 * radius)
    for label in order:
        cloud = pv.PolyData(centres[labels == label])
        glyphs = cloud.glyph(geom=cube if label == UNKNOWN else sphere, scale=False,
                             orient=False)
        colour = label_colour(label, colours)
        actors[label] = []
        for col in (0, 1):
            view.plotter.subplot(0, col)
            actors[label].append(view.plotter.add_mesh(
                glyphs, color=colour, smooth_shading=label != UNKNOWN, ambient=0.45,
                diffuse=0.6, specular=0.15, name=f"world-map {label} {col}"))
    if legend and order:
        view.plotter.subplot(0, 0)
        width, height = 0.3, min(0.05 * len(order), 0.5)
        box = view.plotter.add_legend(
            labels=[[f"{name.replace('_', ' ')} ({counts[name]})", label_colour(name, colours),
                     "rectangle" if name == UNKNOWN else "circle"] for name in order],
            bcolor="white", face="circle", size=(width, height), name="world-map legend")
        # lower right of the subplot; pyvista's loc= places the box by its height, not width
        box.SetPosition(1.0 - width - 0.02, 0.03)
        box.SetPosition2(width, height)
    return actors


def render_world_map(world_map: WorldMap, layout: Layout, colours: Mapping[str, str], *,
                     poses: Mapping[str, np.ndarray] | None = None,
                     path: str | Path | None = None, title: str | None = None,
                     window_size: tuple[int, int] = (1600, 700)) -> Path | None:
    """Draw a world map around the arm: into a PNG (``path``) or a window (no ``path``).

    Parameters
    ----------
    world_map : WorldMap
        The points.
    layout : Layout
        The arm's taxels.
    colours : dict
        Material name -> ``"#RRGGBB"``.
    poses : dict, optional
        Where the arm's links stand (link -> 4x4); the default arm if None.
    path : str or Path, optional
        The PNG to write, off screen; None opens a window and returns when it is closed.
    title : str, optional
        A title in the first subplot.
    window_size : tuple of int
        Image size, pixels.

    Returns
    -------
    Path or None
        The PNG written, or None after a window.

    Raises
    ------
    SkinError
        Without ``path``, if no window can open here (naming why).
    """
    if path is None:
        why = window_problem()
        if why is not None:
            raise SkinError(f"cannot open a window: {why}; give --out map.png to write a PNG "
                            "instead")
    view = posed_arm_view(layout, colours, poses, off_screen=path is not None,
                          window_size=window_size)
    try:
        add_world_map(view, world_map, colours)
        if path is not None:
            return view.screenshot(path, title=title)
        if title:
            view.plotter.subplot(0, 0)
            view.plotter.add_text(title, position="upper_left", font_size=12, color="black")
        view.plotter.show()
        return None
    finally:
        view.close()

"""Arms described in URDF (read with yourdfpy): the chain, joint limits and link meshes.

`load_urdf` turns a URDF file into a `skin.world.kinematics.Chain` (fixed, revolute and
continuous joints; each joint's origin, axis and limits) and, per link, its visual meshes (file,
origin in the link frame, scale). Layouts place taxels on the URDF's links by name, in each
link's frame; `skin.viz.arm_mesh.load_arm` reads ``--arm robot.urdf`` through it, and poses
come from joint states (`skin.world.joint_states`) or CSV/NPZ (`skin.world.kinematics`).

Mesh file names ``package://PKG/rest`` are looked up in the folders above the URDF (a folder
named PKG, or one holding PKG) and in example-robot-data's share folder; plain names are
relative to the URDF's folder.

The shipped example (`XARM7`): UFACTORY's xArm 7 (BSD-3-Clause), from the example-robot-data
package (``pip install 'thermoskin[robots]'``), with the layout ``xarm7`` of the skin's taxels
on its links 3 and 5.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from skin._optional import require
from skin.world.kinematics import Chain, KinematicsError, Link

#: The shipped example arm: (package, path in its share folder).
XARM7 = ("example-robot-data", "robots/xarm_description/urdf/xarm7.urdf")


@dataclass(frozen=True)
class LinkVisual:
    """One visual mesh of a link: its file, pose in the link frame, and scale per axis."""

    path: Path
    origin: np.ndarray
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class UrdfArm:
    """A URDF arm: its chain and each link's visual meshes.

    Attributes
    ----------
    chain : Chain
        Links and joints (limits in rad; default angles 0, or the nearest limit).
    visuals : dict of str to list of LinkVisual
        Per link, its meshes (links without a mesh are absent).
    source : str
        The URDF file.
    """

    chain: Chain
    visuals: dict[str, list[LinkVisual]] = field(repr=False)
    source: str


def share_folder(package: str = "example-robot-data") -> Path | None:
    """Return the share folder of a cmeel-packaged robot description, or None if absent."""
    from importlib.metadata import PackageNotFoundError, distribution

    try:
        folder = Path(str(distribution(package).locate_file(f"cmeel.prefix/share/{package}")))
    except PackageNotFoundError:
        return None
    return folder if folder.is_dir() else None


def example_urdf() -> Path:
    """Return the shipped example arm's URDF (`XARM7`).

    Raises
    ------
    MissingDependencyError
        With the install hint, when example-robot-data is not installed.
    """
    from skin.errors import MissingDependencyError

    folder = share_folder(XARM7[0])
    if folder is None:
        raise MissingDependencyError("the example arm (xArm 7) needs the package "
                                     "'example-robot-data', which is not installed: "
                                     "pip install 'thermoskin[robots]'")
    return folder / XARM7[1]


def _resolve(name: str, urdf: Path) -> Path:
    """Find a mesh file named in a URDF (see the module docstring)."""
    if name.startswith("file://"):
        return Path(name[len("file://"):])
    if not name.startswith("package://"):
        path = Path(name)
        return path if path.is_absolute() else urdf.parent / path
    package, _, rest = name[len("package://"):].partition("/")
    roots = [p for p in urdf.resolve().parents]
    shared = share_folder()
    candidates = [root / rest for root in roots if root.name == package]
    candidates += [root / package / rest for root in roots]
    if shared is not None:
        candidates += [shared.parent / package / rest, shared / rest]
    for path in candidates:
        if path.is_file():
            return path
    return candidates[0] if candidates else Path(rest)


def load_urdf(path: str | Path) -> UrdfArm:
    """Read a URDF file into a chain and link meshes (see the module docstring).

    Raises
    ------
    KinematicsError
        If the file cannot be read, has a joint type the chain cannot move (prismatic,
        planar, floating), or names a mesh file that is not there (file, link and mesh).
    """
    yourdfpy = require("yourdfpy", "reading URDF arms")
    path = Path(path)
    src = str(path)
    if not path.is_file():
        raise KinematicsError(f"{src}: no such URDF file")
    try:
        robot = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False,
                                   filename_handler=lambda f: f).robot
    except Exception as exc:  # yourdfpy raises lxml and its own errors
        raise KinematicsError(f"{src}: cannot read the URDF ({type(exc).__name__}: {exc})"
                              ) from None
    children = {j.child for j in robot.joints}
    links = [Link(lk.name, None, np.eye(4)) for lk in robot.links if lk.name not in children]
    for j in robot.joints:
        origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
        if j.type == "fixed":
            links.append(Link(j.child, j.parent, origin, "fixed"))
            continue
        if j.type not in ("revolute", "continuous"):
            raise KinematicsError(f"{src}: joint {j.name!r} is {j.type}; the chain moves "
                                  "fixed, revolute and continuous joints only")
        axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=float)
        norm = float(np.linalg.norm(axis))
        if norm == 0:
            raise KinematicsError(f"{src}: joint {j.name!r} has a zero axis")
        limits = None
        if j.type == "revolute" and j.limit is not None and j.limit.lower is not None:
            limits = (float(j.limit.lower), float(j.limit.upper))
        default = 0.0 if limits is None else float(np.clip(0.0, *limits))
        links.append(Link(j.child, j.parent, origin, "revolute", j.name,
                          tuple(float(v) for v in axis / norm), limits, default))
    chain = Chain(links, name=robot.name, source=src)
    visuals: dict[str, list[LinkVisual]] = {}
    for lk in robot.links:
        for v in lk.visuals:
            mesh = None if v.geometry is None else v.geometry.mesh
            if mesh is None:
                continue  # boxes, cylinders, spheres: not drawn
            file = _resolve(mesh.filename, path)
            if not file.is_file():
                raise KinematicsError(f"{src}: link {lk.name!r}: mesh {mesh.filename!r} not "
                                      f"found (looked for {file})")
            scale = mesh.scale
            scale = (1.0, 1.0, 1.0) if scale is None else tuple(
                float(s) for s in np.broadcast_to(np.asarray(scale, dtype=float), 3))
            origin = np.eye(4) if v.origin is None else np.asarray(v.origin, dtype=float)
            visuals.setdefault(lk.name, []).append(LinkVisual(file, origin, scale))
    return UrdfArm(chain, visuals, src)

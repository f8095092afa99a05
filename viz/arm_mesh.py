"""The arm's geometry for the arm view: link meshes and poses, taxels snapped on, their patches.

An arm is a dict of link name -> `ArmLink`: a triangle mesh in the link's own frame (the frame
the layout gives taxel positions in) and its pose (4x4, link frame -> world). `default_arm`
makes the procedural arm of the default layout (``skin/data/layouts/arm.toml``); `load_arm`
reads an arm file (TOML, one ``[[links]]`` table per link, each naming an STL, OBJ or PLY file)
and `arm_from_meshes` takes ``{link: (path, pose)}``.

`ArmSurface` joins the links into one mesh, snaps every taxel onto its link's surface and
gives each taxel the vertices nearest to it within a radius (its patch), once, with k-d trees:
a 1000-taxel skin on a 100k-vertex arm builds in well under a second.  Only reading mesh files
and the closest-point search use pyvista (VTK); the rest is numpy and scipy.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from skin._optional import require
from skin.errors import LayoutError, ViewError
from skin.formats.datafiles import header_lines, is_number
from skin.formats.layout import Layout

#: Mesh files an arm can be made of (read by pyvista / VTK).
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".vtk", ".vtp")

#: Largest distance from a taxel's layout position to its link's surface, m.
SNAP_TOLERANCE = 0.005


@dataclass(frozen=True, eq=False)
class ArmLink:
    """One link of the arm: a triangle mesh in the link's frame, and the link's pose.

    Attributes
    ----------
    points : numpy.ndarray
        (n, 3) vertices in the link frame, m.
    faces : numpy.ndarray
        (m, 3) vertex indices of the triangles.
    pose : numpy.ndarray
        (4, 4) rigid transform, link frame -> world.
    parent : str or None
        A link this one moves with: when poses are set without this link's, it keeps its
        offset from the parent (the hand follows the forearm).
    normals : numpy.ndarray or None
        (n, 3) outward unit vertex normals in the link frame; computed from the triangles
        when None.
    source : str
        Where the mesh came from (a file, or ``"procedural"``), for messages.
    """

    points: np.ndarray
    faces: np.ndarray
    pose: np.ndarray
    parent: str | None = None
    normals: np.ndarray | None = None
    source: str = "procedural"


@dataclass(frozen=True)
class LinkGeometry:
    """A cylindrical link: radius, length along its z axis, and its pose (link -> world).

    Accepted wherever an `ArmLink` is (`as_link` makes the tube).
    """

    radius: float
    length: float
    pose: np.ndarray


def rotation_pose(angle_deg: float, origin: tuple[float, float, float]) -> np.ndarray:
    """Rotation about world y by ``angle_deg`` (link z -> (sin, 0, cos)), then translation."""
    return euler_pose(origin, (0.0, angle_deg, 0.0))


def euler_pose(origin: Any, rotation_deg: Any) -> np.ndarray:
    """Rotations about the fixed x, y and z axes (degrees, in that order), then translation."""
    from skin.world.kinematics import transform

    return transform(np.asarray(origin, dtype=float),
                     np.radians(np.asarray(rotation_deg, dtype=float)))


def _translate(pose: np.ndarray, offset: tuple[float, float, float]) -> np.ndarray:
    """``pose`` followed by a translation along the link's own axes."""
    t = np.eye(4)
    t[:3, 3] = offset
    return pose @ t


# the default arm: the layout's radii and ring heights (skin/data/layouts/arm.toml)
UPPER_RADIUS, UPPER_LENGTH = 0.055, 0.30
FORE_RADIUS, FORE_LENGTH = 0.045, 0.26
_ELBOW_GAP = 0.055  # from the upper arm's taxel-bearing length to the elbow joint


def _tube(radius: float, length: float, h: float) -> tuple[np.ndarray, ...]:
    """Make an open cylinder along z from 0 to ``length``, vertices about ``h`` apart."""
    around = max(12, round(2 * np.pi * radius / h))
    along = max(2, round(length / h) + 1)
    theta = np.linspace(0, 2 * np.pi, around, endpoint=False)
    tt, zz = np.meshgrid(theta, np.linspace(0, length, along))
    normals = np.column_stack([np.cos(tt).ravel(), np.sin(tt).ravel(), np.zeros(tt.size)])
    points = normals * radius
    points[:, 2] = zz.ravel()
    i, j = np.meshgrid(np.arange(along - 1), np.arange(around), indexing="ij")
    a = (i * around + j).ravel()
    b = (i * around + (j + 1) % around).ravel()
    c, d = a + around, b + around
    faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return points, faces, normals


def _ellipsoid(axes: tuple[float, float, float], h: float,
               centre: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[np.ndarray, ...]:
    """Make a closed ellipsoid with semi-axes ``axes``, vertices about ``h`` apart."""
    r = max(axes)
    around = max(12, round(2 * np.pi * r / h))
    rings = max(6, round(np.pi * r / h))
    phi = np.linspace(0, np.pi, rings + 1)[1:-1]
    theta = np.linspace(0, 2 * np.pi, around, endpoint=False)
    pp, tt = np.meshgrid(phi, theta, indexing="ij")
    unit = np.column_stack([(np.sin(pp) * np.cos(tt)).ravel(), (np.sin(pp) * np.sin(tt)).ravel(),
                            np.cos(pp).ravel()])
    unit = np.vstack([[0, 0, 1], unit, [0, 0, -1]])
    ring = np.arange(around)
    north, south = 0, len(unit) - 1
    faces = [np.column_stack([np.full(around, north), 1 + ring, 1 + (ring + 1) % around])]
    for k in range(rings - 2):
        a = 1 + k * around + ring
        b = 1 + k * around + (ring + 1) % around
        faces += [np.column_stack([a, a + around, b + around]),
                  np.column_stack([a, b + around, b])]
    last = 1 + (rings - 2) * around
    faces.append(np.column_stack([last + ring, np.full(around, south),
                                  last + (ring + 1) % around]))
    ax = np.asarray(axes, dtype=float)
    normals = unit / ax
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return unit * ax + np.asarray(centre), np.concatenate(faces), normals


def default_arm(vertices: int = 14_000) -> dict[str, ArmLink]:
    """Make the procedural arm of the default layout (``skin/data/layouts/arm.toml``).

    Links: ``upper_arm`` (a cylinder of radius 0.055 m along its z axis; taxels on its first
    0.30 m), ``forearm`` (radius 0.045 m, 0.26 m, bent 30 degrees down at the elbow), and
    the bare ``shoulder``, ``elbow``, ``wrist`` and ``hand``, which follow their parent links.

    Parameters
    ----------
    vertices : int
        About how many vertices the whole arm has (the mesh is refined evenly).

    Returns
    -------
    dict
        Link name -> `ArmLink`.
    """
    upper_pose = rotation_pose(90.0, (0.0, 0.0, 0.0))
    joint = UPPER_LENGTH + _ELBOW_GAP
    elbow_pose = _translate(upper_pose, (0.0, 0.0, joint))
    fore_pose = rotation_pose(120.0, tuple(elbow_pose[:3, 3]))
    wrist_pose = _translate(fore_pose, (0.0, 0.0, FORE_LENGTH))
    r_joint = UPPER_RADIUS * 1.06
    hand_axes = (0.045, 0.024, 0.075)  # flat, its palm toward -y
    # surface areas, to spread the vertices evenly (Knud Thomsen's ellipsoid formula)
    p = 1.6075
    a, b, c = hand_axes
    hand_area = 4 * np.pi * (((a * b) ** p + (a * c) ** p + (b * c) ** p) / 3) ** (1 / p)
    area = (2 * np.pi * (UPPER_RADIUS * joint + FORE_RADIUS * FORE_LENGTH)
            + 4 * np.pi * (2 * r_joint ** 2 + (FORE_RADIUS * 0.9) ** 2) + hand_area)
    h = float(np.sqrt(area / max(vertices, 500)))
    for _ in range(2):  # the grids round: correct the spacing by the count they gave
        parts = _default_parts(h, upper_pose, elbow_pose, fore_pose, wrist_pose, r_joint,
                               hand_axes, joint)
        count = sum(len(pts) for (pts, _, _), _, _ in parts.values())
        h *= float(np.sqrt(count / max(vertices, 500)))
    return {name: ArmLink(pts, faces, pose, parent=parent, normals=normals)
            for name, ((pts, faces, normals), pose, parent) in parts.items()}


def _default_parts(h: float, upper_pose: np.ndarray, elbow_pose: np.ndarray,
                   fore_pose: np.ndarray, wrist_pose: np.ndarray, r_joint: float,
                   hand_axes: tuple[float, float, float], joint: float) -> dict:
    return {
        "upper_arm": (_tube(UPPER_RADIUS, joint, h), upper_pose, None),
        "forearm": (_tube(FORE_RADIUS, FORE_LENGTH, h), fore_pose, None),
        "shoulder": (_ellipsoid((r_joint,) * 3, h), upper_pose, "upper_arm"),
        "elbow": (_ellipsoid((r_joint,) * 3, h), elbow_pose, "upper_arm"),
        "wrist": (_ellipsoid((FORE_RADIUS * 0.9,) * 3, h), wrist_pose, "forearm"),
        "hand": (_ellipsoid(hand_axes, h, (0.0, 0.0, 0.02 + hand_axes[2])), wrist_pose, "wrist"),
    }


def as_link(link: ArmLink | LinkGeometry, vertices_per_m2: float = 50_000.0) -> ArmLink:
    """Return an `ArmLink`; a `LinkGeometry` becomes its open tube."""
    if isinstance(link, ArmLink):
        return link
    area = 2 * np.pi * link.radius * link.length
    h = float(np.sqrt(area / max(500.0, area * vertices_per_m2)))
    pts, faces, normals = _tube(link.radius, link.length, h)
    return ArmLink(pts, faces, np.asarray(link.pose, dtype=float), normals=normals)


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals of a triangle mesh (the triangles' winding)."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    fn = np.cross(b - a, c - a)
    out = np.zeros_like(points)
    for axis in range(3):
        w = np.repeat(fn[:, axis], 3)
        out[:, axis] = np.bincount(faces.ravel(), weights=w, minlength=len(points))
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, norm, out=np.zeros_like(out), where=norm > 0)


def _check_pose(pose: Any, where: str) -> np.ndarray:
    m = np.asarray(pose, dtype=float) if pose is not None else np.eye(4)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ViewError(f"{where}: the pose must be a 4x4 matrix of finite numbers")
    r = m[:3, :3]
    if not (np.allclose(r @ r.T, np.eye(3), atol=1e-6) and np.linalg.det(r) > 0
            and np.allclose(m[3], [0, 0, 0, 1])):
        raise ViewError(f"{where}: the pose must be a rigid transform (a rotation and a "
                        "translation, last row 0 0 0 1)")
    return m


def read_mesh(path: str | Path, link: str, scale: float = 1.0, where: str = "") -> ArmLink:
    """Read one link's mesh file (STL, OBJ, PLY, VTK, VTP) as an `ArmLink` at the identity pose.

    Parameters
    ----------
    path : str or Path
        The mesh file; its coordinates are the link frame's (times ``scale``).
    link : str
        The link's name, for messages.
    scale : float
        File units -> m (0.001 for a file in millimetres).
    where : str
        Prefix of messages (an arm file and line).

    Raises
    ------
    ViewError
        Naming the file and the link when the file is missing, of an unknown kind, unreadable
        or holds no triangles.
    """
    pv = require("pyvista", "reading arm meshes")
    p = Path(path)
    head = f"{where}: " if where else ""
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise ViewError(f"{head}link {link!r}: mesh file {str(p)!r} is not one of "
                        f"{', '.join(MESH_SUFFIXES)}")
    if not p.is_file():
        raise ViewError(f"{head}link {link!r}: mesh file {str(p)!r} does not exist")
    try:
        mesh = pv.read(str(p))
        if not isinstance(mesh, pv.PolyData):
            mesh = mesh.extract_surface()
        mesh = mesh.triangulate().clean()  # STL repeats each triangle's vertices: join them
    except Exception as exc:  # VTK readers raise anything
        raise ViewError(f"{head}link {link!r}: cannot read mesh file {str(p)!r}: {exc}") from None
    if mesh.n_cells == 0 or mesh.n_points < 3:
        raise ViewError(f"{head}link {link!r}: mesh file {str(p)!r} holds no triangles")
    faces = np.asarray(mesh.faces).reshape(-1, 4)[:, 1:].astype(np.int64)
    points = np.asarray(mesh.points, dtype=float) * scale
    return ArmLink(points, faces, np.eye(4), source=str(p))


def arm_from_meshes(meshes: Mapping[str, tuple[str | Path, Any]],
                    scale: float = 1.0) -> dict[str, ArmLink]:
    """Make an arm of one mesh file per link.

    Parameters
    ----------
    meshes : mapping
        Link name -> (mesh file, pose): the file's coordinates are the link frame's, the pose
        (4x4, or None for the identity) takes the link frame to the world.
    scale : float
        File units -> m, for every file.

    Returns
    -------
    dict
        Link name -> `ArmLink`.
    """
    out = {}
    for link, (path, pose) in meshes.items():
        mesh = read_mesh(path, link, scale)
        out[link] = replace(mesh, pose=_check_pose(pose, f"link {link!r}"))
    return out


_LINK_FIELDS = {"name", "mesh", "scale", "pose", "origin", "rotation", "parent"}


def load_urdf_arm(path: str | Path, q: Any = None) -> dict[str, ArmLink]:
    """Load the arm of a URDF file (`skin.world.urdf.load_urdf`): each link's visual meshes.

    A link's meshes are joined, in its frame; its pose is the chain's at joint angles ``q``
    (`skin.world.kinematics.Chain.poses`; the defaults by default), and it moves with the
    nearest ancestor that has a mesh.

    Raises
    ------
    ViewError
        Naming the file and the link of a mesh that cannot be read.
    """
    from skin.world.kinematics import KinematicsError
    from skin.world.urdf import load_urdf

    try:
        urdf = load_urdf(path)
    except KinematicsError as exc:
        raise ViewError(str(exc)) from None
    poses = urdf.chain.poses(q)
    out: dict[str, ArmLink] = {}
    for name in urdf.chain.links:  # parents before children
        parts = urdf.visuals.get(name)
        if not parts:
            continue
        points, faces = [], []
        for v in parts:
            mesh = read_mesh(v.path, name, where=urdf.source)
            local = mesh.points * np.asarray(v.scale)
            points.append(local @ v.origin[:3, :3].T + v.origin[:3, 3])
            faces.append(mesh.faces + sum(len(x) for x in points[:-1]))
        parent = urdf.chain.links[name].parent
        while parent is not None and parent not in out:
            parent = urdf.chain.links[parent].parent
        out[name] = ArmLink(np.vstack(points), np.vstack(faces), poses[name], parent,
                            source=str(parts[0].path))
    if not out:
        raise ViewError(f"{urdf.source}: no link has a mesh to draw")
    return out


def load_arm(path: str | Path) -> dict[str, ArmLink]:
    """Load an arm file: one ``[[links]]`` table per link, each with its own mesh file.

    A URDF file (``.urdf``) is read by `load_urdf_arm`; the name ``xarm7`` is the shipped
    example arm (`skin.world.urdf.example_urdf`).

    Fields of a link: ``name`` (the layout's link name), ``mesh`` (STL, OBJ, PLY; relative
    to the arm file), optional ``scale`` (file units -> m, e.g. 0.001 for millimetres), the
    pose as ``pose`` (a 4x4 matrix, link frame -> world) or ``origin`` (m) and ``rotation``
    (degrees about the fixed x, y, z axes, in that order), and optional ``parent`` (a link
    this one moves with).

    Raises
    ------
    ViewError
        Naming the file, the line and the link of the first problem.
    """
    p = Path(path)
    if str(path) == "xarm7" and not p.exists():
        from skin.world.urdf import example_urdf

        p = example_urdf()
    if p.suffix.lower() == ".urdf":
        return load_urdf_arm(p)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ViewError(f"{p}: cannot read arm file: {exc.strerror}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ViewError(f"{p}: not valid TOML: {exc}") from None
    raw_links = data.get("links")
    if not isinstance(raw_links, list) or not raw_links:
        raise ViewError(f"{p}: no links: add one [[links]] table per link")
    lines = header_lines(text, "links")
    out: dict[str, ArmLink] = {}
    for k, raw in enumerate(raw_links):
        name = raw.get("name", "?") if isinstance(raw, dict) else "?"
        where = f"{p}:{lines[k] if k < len(lines) else 0}: link {name!r}"
        if not isinstance(raw, dict):
            raise ViewError(f"{where}: a link must be a table")
        unknown = sorted(set(raw) - _LINK_FIELDS)
        if unknown:
            raise ViewError(f"{where}: unknown field {unknown[0]!r}")
        for key in ("name", "mesh"):
            if not isinstance(raw.get(key), str) or not raw[key]:
                raise ViewError(f"{where}: field {key!r} must be a non-empty string")
        if name in out:
            raise ViewError(f"{where}: a second link of that name")
        scale = raw.get("scale", 1.0)
        if not is_number(scale) or scale <= 0:
            raise ViewError(f"{where}: field 'scale' must be a positive number")
        if "pose" in raw and ("origin" in raw or "rotation" in raw):
            raise ViewError(f"{where}: give 'pose' or 'origin' and 'rotation', not both")
        if "pose" in raw:
            pose = raw["pose"]
            if not (isinstance(pose, list) and len(pose) == 4 and all(
                    isinstance(r, list) and len(r) == 4 and all(map(is_number, r))
                    for r in pose)):
                raise ViewError(f"{where}: field 'pose' must be 4 rows of 4 numbers")
        else:
            vec = {}
            for key in ("origin", "rotation"):
                v = raw.get(key, [0.0, 0.0, 0.0])
                if not (isinstance(v, list) and len(v) == 3 and all(map(is_number, v))):
                    raise ViewError(f"{where}: field {key!r} must be a list of 3 numbers")
                vec[key] = v
            pose = euler_pose(vec["origin"], vec["rotation"])
        parent = raw.get("parent")
        if parent is not None and not isinstance(parent, str):
            raise ViewError(f"{where}: field 'parent' must be a link name")
        mesh_path = Path(raw["mesh"])
        if not mesh_path.is_absolute():
            mesh_path = p.parent / mesh_path
        mesh = read_mesh(mesh_path, name, float(scale), where=str(p))
        out[name] = replace(mesh, pose=_check_pose(pose, where), parent=parent)
    for name, link in out.items():
        if link.parent is not None and link.parent not in out:
            raise ViewError(f"{p}: link {name!r}: parent {link.parent!r} is not a link of the "
                            "file")
    return out


def resolve_arm(arm: Mapping[str, ArmLink | LinkGeometry] | str | Path | None,
                vertices: int = 14_000) -> dict[str, ArmLink]:
    """Turn what `ArmView` accepts as ``arm`` into a dict of `ArmLink` (see `ArmView`)."""
    if arm is None:
        return default_arm(vertices)
    if isinstance(arm, str | Path):
        return load_arm(arm)
    out = {name: as_link(link) for name, link in arm.items()}
    for name, link in out.items():
        if link.parent is not None and link.parent not in out:
            raise ViewError(f"link {name!r}: parent {link.parent!r} is not a link of the arm")
    return out


def pose_order(arm: Mapping[str, ArmLink]) -> list[str]:
    """Link names, every parent before its children (cycles are an error)."""
    order: list[str] = []
    state: dict[str, int] = {}

    def visit(name: str, chain: tuple[str, ...]) -> None:
        if state.get(name) == 2:
            return
        if name in chain:
            raise ViewError(f"links {' -> '.join((*chain, name))}: a cycle of parents")
        parent = arm[name].parent
        if parent is not None:
            visit(parent, (*chain, name))
        state[name] = 2
        order.append(name)

    for name in arm:
        visit(name, ())
    return order


class ArmSurface:
    """The arm's links as one triangle mesh in the world, with every taxel's patch.

    Parameters
    ----------
    layout : Layout
        The taxels; each must lie within ``tolerance`` of its link's surface.
    arm : dict of ArmLink
        The links (`resolve_arm`).
    patch_radius : float, optional
        Largest distance from a taxel to a vertex of its patch, m; by default half the median
        distance between neighbouring taxels.
    tolerance : float
        Largest distance from a taxel's layout position to its link's surface, m.

    Attributes
    ----------
    links : list of str
        Link names, in the order of their vertices in ``points``.
    slices : dict
        Link name -> slice of its vertices.
    faces : numpy.ndarray
        (m, 3) triangles of the joined mesh.
    points, normals : numpy.ndarray
        (n, 3) vertices and unit normals in the world frame (`pose_points` rewrites them).
    taxel_local : numpy.ndarray
        (N, 3) taxels snapped onto their link's surface, link frame (layout order).
    taxel_world : numpy.ndarray
        (N, 3) the same in the world frame.
    snap_distance : numpy.ndarray
        (N,) distance from each layout position to the surface, m.
    owner : numpy.ndarray
        (n,) the layout index of the taxel owning each vertex, -1 for bare skin.
    rim : numpy.ndarray
        (n,) True for a patch's outer vertices (a neighbour belongs to another patch or
        to bare skin): where the contact highlight is drawn.
    patch_radius : float
        The radius used, m.

    Raises
    ------
    LayoutError
        For a taxel on a link the arm does not have, or farther than ``tolerance`` from its
        link's surface (naming the taxel id, the link and the distance).
    """

    def __init__(self, layout: Layout, arm: Mapping[str, ArmLink],
                 patch_radius: float | None = None, tolerance: float = SNAP_TOLERANCE) -> None:
        from scipy.spatial import cKDTree

        self.layout = layout
        self.arm = dict(arm)
        missing = sorted(set(layout.links) - set(self.arm))
        if missing:
            raise LayoutError(f"{layout.source}: link {missing[0]!r} has no geometry in the "
                              f"view (the arm has {', '.join(sorted(self.arm))})")
        self.links = list(self.arm)
        sizes = [len(self.arm[n].points) for n in self.links]
        starts = np.concatenate([[0], np.cumsum(sizes)])
        self.slices = {n: slice(int(a), int(b))
                       for n, a, b in zip(self.links, starts[:-1], starts[1:], strict=True)}
        self.local_points = np.vstack([np.asarray(self.arm[n].points, dtype=float)
                                       for n in self.links])
        self.local_normals = np.vstack([
            vertex_normals(np.asarray(link.points, float), np.asarray(link.faces))
            if link.normals is None else np.asarray(link.normals, dtype=float)
            for link in (self.arm[n] for n in self.links)])
        self.faces = np.vstack([np.asarray(self.arm[n].faces, dtype=np.int64) + starts[i]
                                for i, n in enumerate(self.links)])
        self.points = np.empty_like(self.local_points)
        self.normals = np.empty_like(self.local_normals)
        n = len(layout)
        self.taxel_local = layout.positions.copy()
        self.snap_distance = np.zeros(n)
        links = np.array(layout.links)
        self._members = {name: np.flatnonzero(links == name) for name in self.links}
        for name, sel in self._members.items():
            if sel.size:
                self._snap(name, sel, tolerance)
        self.patch_radius = (self._default_radius() if patch_radius is None
                             else float(patch_radius))
        self.owner = np.full(len(self.local_points), -1, dtype=np.int64)
        for name, sel in self._members.items():
            if not sel.size:
                continue
            s = self.slices[name]
            verts = self.local_points[s]
            dist, near = cKDTree(self.taxel_local[sel]).query(
                verts, distance_upper_bound=self.patch_radius)
            owner = np.where(np.isfinite(dist), sel[np.minimum(near, sel.size - 1)], -1)
            # a taxel finer than the mesh keeps at least the vertex nearest to it
            nearest = cKDTree(verts).query(self.taxel_local[sel])[1]
            owned = np.bincount(owner[owner >= 0], minlength=n)[sel]
            orphans = owned == 0
            owner[nearest[orphans]] = sel[orphans]
            self.owner[s] = owner
        self.rim = self._rim()
        self.taxel_world = np.empty_like(self.taxel_local)
        self.poses = {name: np.asarray(self.arm[name].pose, dtype=float) for name in self.links}
        self.pose_points(self.points, self.normals)

    def _snap(self, name: str, sel: np.ndarray, tolerance: float) -> None:
        pv = require("pyvista", "the arm view")
        link = self.arm[name]
        faces = np.asarray(link.faces, dtype=np.int64)
        surf = pv.PolyData(np.asarray(link.points, dtype=float),
                           np.column_stack([np.full(len(faces), 3), faces]).ravel())
        pos = self.layout.positions[sel]
        _, closest = surf.find_closest_cell(pos, return_closest_point=True)
        closest = np.asarray(closest, dtype=float).reshape(-1, 3)
        off = np.linalg.norm(closest - pos, axis=1)
        self.taxel_local[sel] = closest
        self.snap_distance[sel] = off
        bad = np.flatnonzero(off > tolerance)
        if bad.size:
            worst = bad[np.argmax(off[bad])]
            k = sel[worst]
            more = f" (and {bad.size - 1} more)" if bad.size > 1 else ""
            raise LayoutError(
                f"{self.layout.source}: taxel {self.layout.ids[k]} lies "
                f"{off[worst] * 1000:.1f} mm from the surface of link {name!r} "
                f"({link.source}; tolerance {tolerance * 1000:g} mm){more}")

    def _default_radius(self) -> float:
        near = self.layout.neighbour_lists()
        d = [np.linalg.norm(self.taxel_local[idx] - self.taxel_local[k], axis=1)
             for k, idx in enumerate(near) if len(idx)]
        return 0.5 * float(np.median(np.concatenate(d))) if d else 0.02

    def _rim(self) -> np.ndarray:
        edges = self.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        a, b = self.owner[edges[:, 0]], self.owner[edges[:, 1]]
        differ = a != b
        rim = np.zeros(len(self.owner), dtype=bool)
        for side, own in ((edges[:, 0], a), (edges[:, 1], b)):
            rim[side[differ & (own >= 0)]] = True
        return rim

    def set_poses(self, poses: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """Set some links' poses; links not given keep their offset from their parent.

        Returns
        -------
        dict
            Every link's pose after the change.

        Raises
        ------
        ViewError
            For a link the arm does not have or a pose that is not a rigid 4x4 transform.
        """
        unknown = sorted(set(poses) - set(self.poses))
        if unknown:
            raise ViewError(f"no link {unknown[0]!r} in the arm ({', '.join(self.links)})")
        given = {name: _check_pose(p, f"link {name!r}") for name, p in poses.items()}
        old = self.poses
        new: dict[str, np.ndarray] = {}
        for name in pose_order(self.arm):
            parent = self.arm[name].parent
            if name in given:
                new[name] = given[name]
            elif parent is not None:  # keep the offset from the parent
                new[name] = new[parent] @ np.linalg.solve(old[parent], old[name])
            else:
                new[name] = old[name]
        self.poses = {name: new[name] for name in self.links}
        return self.poses

    def pose_points(self, points: np.ndarray, normals: np.ndarray) -> None:
        """Write the world vertices and normals of the current poses into these arrays."""
        for name, s in self.slices.items():
            m = self.poses[name]
            r = m[:3, :3]
            np.matmul(self.local_points[s], r.T, out=points[s])
            points[s] += m[:3, 3]
            np.matmul(self.local_normals[s], r.T, out=normals[s])
        self.points, self.normals = points, normals
        for name, sel in self._members.items():
            if sel.size:
                m = self.poses[name]
                self.taxel_world[sel] = self.taxel_local[sel] @ m[:3, :3].T + m[:3, 3]

"""Link poses: a simple kinematic chain, and poses given over time.

A `Chain` is a tree of links. Every link but a root has a parent and a joint: a fixed origin
transform from the parent's frame to the joint frame (``xyz`` in m, ``rpy`` roll-pitch-yaw as
in URDF: R = Rz(yaw) Ry(pitch) Rx(roll)), then a rotation about the joint's ``axis`` by the
joint angle (revolute) or nothing (fixed); a root's origin is its pose in the world.
``chain.poses(q)`` gives each link's 4x4 pose, link frame -> world.

`default_chain` is the default arm of ``skin/data/layouts/arm.toml``: shoulder -> upper_arm
(joint ``shoulder``, about the world's vertical) -> elbow -> forearm (joint ``elbow``) -> wrist
(joint ``wrist``) -> hand; at its default angles (all 0) every link is where the procedural arm
of `skin.viz.arm.default_arm` draws it.

A chain file is TOML, validated on load (every error names the file, line and link)::

    name = "my arm"

    [[links]]
    name = "base"                  # a root: xyz / rpy_deg give its pose in the world

    [[links]]
    name = "upper_arm"
    parent = "base"
    xyz = [0.0, 0.0, 0.1]          # m, joint origin in the parent's frame (default 0)
    rpy_deg = [0.0, 90.0, 0.0]     # deg, roll, pitch, yaw of the joint origin (default 0)
    type = "revolute"              # or "fixed" (the default)
    joint = "shoulder"             # joint name (default: the link's name)
    axis = [1.0, 0.0, 0.0]         # rotation axis in the joint frame
    limits_deg = [-170.0, 170.0]   # optional
    default_deg = 0.0              # the joint's default angle (default 0)

Poses over time (`JointTrack`, `LinkPoseTrack`, `load_poses`): joint angles or link poses
sampled at times on the skin's clock (the device time of the events' ``onset``), interpolated
at any time in their span: joint angles linearly, link poses by linear translation and
spherical-linear rotation. Angles in code and in pose files are radians; only chain files
speak degrees (``_deg`` fields).
"""

from __future__ import annotations

import csv
import io
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from skin.errors import SkinError
from skin.formats.datafiles import header_lines, is_number
from skin.formats.toml_text import toml_value

JOINT_TYPES = ("revolute", "fixed")


class KinematicsError(SkinError):
    """A chain or pose file is malformed, or a pose is asked for outside what is known."""


# ---- rotations ----

def rotation_about(axis: Sequence[float], angle: float) -> np.ndarray:
    """Return the 3x3 rotation by ``angle`` (rad) about a unit ``axis``.

    Parameters
    ----------
    axis : sequence of 3 float
        Unit axis.
    angle : float
        Angle, rad (right-handed).

    Returns
    -------
    numpy.ndarray
        (3, 3) rotation matrix.
    """
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(axis, dtype=float) * float(angle)).as_matrix()


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Return the 3x3 rotation Rz(yaw) Ry(pitch) Rx(roll) (URDF's fixed-axis roll-pitch-yaw).

    Parameters
    ----------
    roll, pitch, yaw : float
        Angles about x, y and z, rad.

    Returns
    -------
    numpy.ndarray
        (3, 3) rotation matrix.
    """
    from scipy.spatial.transform import Rotation

    # lower-case axes: extrinsic (fixed) x, then y, then z
    return Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()


def transform(xyz: Sequence[float] = (0.0, 0.0, 0.0),
              rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Return the 4x4 transform of a translation ``xyz`` (m) and a rotation ``rpy`` (rad)."""
    m = np.eye(4)
    m[:3, :3] = rpy_matrix(*rpy)
    m[:3, 3] = xyz
    return m


# ---- the chain ----

@dataclass(frozen=True, eq=False)
class Link:
    """One link of a chain and the joint that carries it.

    Attributes
    ----------
    name : str
        Link name, as layouts name it (``Taxel.link``).
    parent : str or None
        Parent link; None for a root, whose ``origin`` is its pose in the world.
    origin : numpy.ndarray
        4x4 transform, parent link frame -> joint frame.
    type : str
        ``"revolute"`` or ``"fixed"``.
    joint : str or None
        Name of the joint (revolute links), None for a fixed one.
    axis : tuple of float
        Unit rotation axis in the joint frame (revolute links).
    limits : tuple of float or None
        Joint range, rad.
    default : float
        Default joint angle, rad.
    """

    name: str
    parent: str | None
    origin: np.ndarray
    type: str = "fixed"
    joint: str | None = None
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    limits: tuple[float, float] | None = None
    default: float = 0.0


class PoseSource(Protocol):
    """Anything that gives link poses (4x4, link -> world) at a time on the skin's clock."""

    def poses_at(self, t: float) -> dict[str, np.ndarray]:  # noqa: D102
        ...


class Chain:
    """A tree of links with fixed and revolute joints.

    Parameters
    ----------
    links : list of Link
        The links, in any order; parents must be among them.
    name : str
        A human-readable name.
    source : str
        Where the chain came from (file path), for messages.
    lines : dict of str to int, optional
        The line of each link in its file, for messages.

    Attributes
    ----------
    links : dict of str to Link
        The links, parents before children.
    joints : list of str
        Names of the revolute joints, in that order: the order of a joint-angle vector.

    Raises
    ------
    KinematicsError
        On duplicate link or joint names, an unknown parent or a cycle.
    """

    def __init__(self, links: Sequence[Link], name: str = "", source: str = "<memory>",
                 lines: Mapping[str, int] | None = None) -> None:
        self.name = name
        self.source = source
        lines = lines or {}

        def where(link: str) -> str:
            line = f":{lines[link]}" if link in lines else ""
            return f"{source}{line}: link {link!r}"

        by_name: dict[str, Link] = {}
        for link in links:
            if link.name in by_name:
                raise KinematicsError(f"{where(link.name)}: duplicate link name")
            by_name[link.name] = link
        for link in links:
            if link.parent is not None and link.parent not in by_name:
                raise KinematicsError(f"{where(link.name)}: field 'parent' names "
                                      f"{link.parent!r}, which is not a link of the chain")
        ordered: dict[str, Link] = {}
        for link in links:  # parents first; a walk up that meets itself is a cycle
            path: list[Link] = []
            cur: Link | None = link
            while cur is not None and cur.name not in ordered:
                if any(p.name == cur.name for p in path):
                    raise KinematicsError(
                        f"{where(cur.name)}: its parents form a cycle "
                        f"({' -> '.join([p.name for p in path] + [cur.name])})")
                path.append(cur)
                cur = by_name[cur.parent] if cur.parent is not None else None
            for p in reversed(path):
                ordered[p.name] = p
        self.links = ordered
        self.joints: list[str] = []
        for link in ordered.values():
            if link.type == "revolute":
                if link.joint in self.joints:
                    raise KinematicsError(f"{where(link.name)}: duplicate joint name "
                                          f"{link.joint!r}")
                self.joints.append(str(link.joint))
        self._joint_link = {lk.joint: lk for lk in ordered.values() if lk.type == "revolute"}

    def __repr__(self) -> str:
        return f"Chain({self.name!r}, {len(self.links)} links, joints {self.joints})"

    def __contains__(self, link: object) -> bool:
        """Whether a link name is in the chain."""
        return link in self.links

    @property
    def default_q(self) -> np.ndarray:
        """The default joint angles, rad, in the order of `joints`."""
        return np.array([self._joint_link[j].default for j in self.joints], dtype=float)

    def joint_vector(self, q: Sequence[float] | np.ndarray | Mapping[str, float] | None
                     ) -> np.ndarray:
        """Return a full joint-angle vector from angles in joint order or by name.

        Parameters
        ----------
        q : sequence, array, dict or None
            One angle per joint (rad, order of `joints`); or joint name -> angle, the others
            at their defaults; None: the defaults.

        Returns
        -------
        numpy.ndarray
            Angles, rad, in the order of `joints`.

        Raises
        ------
        KinematicsError
            On a wrong length, an unknown joint name, a non-finite angle or one out of limits.
        """
        out = self.default_q
        if isinstance(q, Mapping):
            for name, value in q.items():
                if name not in self._joint_link:
                    raise KinematicsError(f"{self.source}: no joint named {name!r} "
                                          f"(joints: {', '.join(self.joints) or 'none'})")
                out[self.joints.index(name)] = float(value)
        elif q is not None:
            arr = np.asarray(q, dtype=float).ravel()
            if arr.shape != out.shape:
                raise KinematicsError(f"{self.source}: {arr.size} joint angles given, the chain "
                                      f"has {len(self.joints)} joints ({', '.join(self.joints)})")
            out = arr.copy()
        for name, value in zip(self.joints, out, strict=True):
            link = self._joint_link[name]
            if not np.isfinite(value):
                raise KinematicsError(f"{self.source}: joint {name!r}: angle {value}")
            if link.limits is not None and not (
                    link.limits[0] - 1e-9 <= value <= link.limits[1] + 1e-9):
                raise KinematicsError(
                    f"{self.source}: joint {name!r} (link {link.name!r}): angle "
                    f"{math.degrees(value):.4g} deg is outside its limits "
                    f"[{math.degrees(link.limits[0]):.4g}, {math.degrees(link.limits[1]):.4g}] deg")
        return out

    def poses(self, q: Sequence[float] | np.ndarray | Mapping[str, float] | None = None
              ) -> dict[str, np.ndarray]:
        """Return every link's pose (4x4, link frame -> world) at joint angles ``q``.

        Parameters
        ----------
        q : sequence, array, dict or None
            Joint angles, rad (see `joint_vector`); None: the defaults.

        Returns
        -------
        dict of str to numpy.ndarray
            Link name -> 4x4 pose.
        """
        angles = dict(zip(self.joints, self.joint_vector(q), strict=True))
        out: dict[str, np.ndarray] = {}
        for link in self.links.values():
            m = link.origin.copy()
            if link.type == "revolute":
                m[:3, :3] = m[:3, :3] @ rotation_about(link.axis, angles[str(link.joint)])
            out[link.name] = m if link.parent is None else out[link.parent] @ m
        return out

    def poses_at(self, t: float) -> dict[str, np.ndarray]:
        """Return the poses at the default angles, whatever ``t`` (a chain standing still)."""
        return self.poses()


def default_chain() -> Chain:
    """Return the chain of the default arm (``skin/data/layouts/arm.toml``).

    shoulder (at the world's origin, its z along the world's +x) -> upper_arm (revolute
    ``shoulder``, about the world's vertical) -> elbow (0.355 m along the upper arm: its 0.30 m
    of skin and the elbow's radius) -> forearm (revolute ``elbow``, about the world's y at 0,
    bent 30 deg down at 0) -> wrist (revolute ``wrist``, about the forearm's y, at its far end,
    0.26 m) -> hand. At the default angles (all 0) every link stands where the procedural arm of
    `skin.viz.arm.default_arm` draws it.
    """
    deg = math.radians
    links = [
        Link("shoulder", None, transform(rpy=(0.0, deg(90.0), 0.0))),
        # in the shoulder's frame the world's vertical is -x
        Link("upper_arm", "shoulder", np.eye(4), "revolute", "shoulder", (-1.0, 0.0, 0.0),
             (deg(-180.0), deg(180.0))),
        Link("elbow", "upper_arm", transform((0.0, 0.0, 0.355))),
        Link("forearm", "elbow", transform(rpy=(0.0, deg(30.0), 0.0)), "revolute", "elbow",
             (0.0, 1.0, 0.0), (deg(-120.0), deg(150.0))),
        Link("wrist", "forearm", transform((0.0, 0.0, 0.26)), "revolute", "wrist",
             (0.0, 1.0, 0.0), (deg(-90.0), deg(90.0))),
        Link("hand", "wrist", np.eye(4)),
    ]
    return Chain(links, name="default arm", source="default_chain()")


# ---- chain files ----

_LINK_FIELDS = ("name", "parent", "xyz", "rpy_deg", "type", "joint", "axis", "limits_deg",
                "default_deg")


def _numbers(value: Any, n: int, where: str, field: str) -> list[float]:
    if not (isinstance(value, list) and len(value) == n and all(map(is_number, value))):
        raise KinematicsError(f"{where}: field {field!r} must be a list of {n} finite numbers, "
                              f"got {value!r}")
    return [float(v) for v in value]


def _parse_link(raw: Any, where: str) -> Link:
    if not isinstance(raw, dict):
        raise KinematicsError(f"{where}: a link must be a table")
    unknown = set(raw) - set(_LINK_FIELDS)
    if unknown:
        raise KinematicsError(f"{where}: unknown field {sorted(unknown)[0]!r} "
                              f"(fields: {', '.join(_LINK_FIELDS)})")
    name = raw.get("name")
    if not isinstance(name, str) or not name:
        raise KinematicsError(f"{where}: field 'name' must be a non-empty string")
    parent = raw.get("parent")
    if parent is not None and (not isinstance(parent, str) or not parent):
        raise KinematicsError(f"{where}: field 'parent' must be a link name")
    xyz = _numbers(raw.get("xyz", [0.0, 0.0, 0.0]), 3, where, "xyz")
    rpy = [math.radians(v) for v in _numbers(raw.get("rpy_deg", [0.0, 0.0, 0.0]), 3, where,
                                             "rpy_deg")]
    kind = raw.get("type", "fixed")
    if kind not in JOINT_TYPES:
        raise KinematicsError(f"{where}: field 'type' must be one of {', '.join(JOINT_TYPES)}, "
                              f"got {kind!r}")
    origin = transform(xyz, rpy)
    if kind == "fixed":
        extra = [f for f in ("joint", "axis", "limits_deg", "default_deg") if f in raw]
        if extra:
            raise KinematicsError(f"{where}: field {extra[0]!r} is for a revolute joint; "
                                  "this link's type is fixed")
        return Link(name, parent, origin)
    if parent is None:
        raise KinematicsError(f"{where}: a root link (no 'parent') cannot have a revolute joint")
    joint = raw.get("joint", name)
    if not isinstance(joint, str) or not joint:
        raise KinematicsError(f"{where}: field 'joint' must be a non-empty string")
    if "axis" not in raw:
        raise KinematicsError(f"{where}: missing field 'axis' (a revolute joint's axis)")
    axis = np.array(_numbers(raw["axis"], 3, where, "axis"))
    norm = float(np.linalg.norm(axis))
    if norm < 1e-9:
        raise KinematicsError(f"{where}: field 'axis' must not be zero")
    axis /= norm
    limits = None
    if "limits_deg" in raw:
        lo, hi = _numbers(raw["limits_deg"], 2, where, "limits_deg")
        if not lo < hi:
            raise KinematicsError(f"{where}: field 'limits_deg' must be [low, high] with "
                                  f"low < high, got {[lo, hi]}")
        limits = (math.radians(lo), math.radians(hi))
    default = raw.get("default_deg", 0.0)
    if not is_number(default):
        raise KinematicsError(f"{where}: field 'default_deg' must be a finite number, "
                              f"got {default!r}")
    default = math.radians(float(default))
    if limits is not None and not limits[0] <= default <= limits[1]:
        raise KinematicsError(f"{where}: field 'default_deg' is outside 'limits_deg'")
    return Link(name, parent, origin, "revolute", joint,
                (float(axis[0]), float(axis[1]), float(axis[2])), limits, default)


def parse_chain(text: str, source: str = "<string>") -> Chain:
    """Parse and validate chain TOML text (format: the module docstring).

    Parameters
    ----------
    text : str
        TOML text.
    source : str
        File name used in error messages.

    Returns
    -------
    Chain

    Raises
    ------
    KinematicsError
        Naming the file, line and link of the first problem found.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise KinematicsError(f"{source}: not valid TOML: {exc}") from None
    unknown = set(data) - {"name", "links"}
    if unknown:
        raise KinematicsError(f"{source}: unknown top-level key {sorted(unknown)[0]!r} "
                              "(keys: name, links)")
    raw_links = data.get("links")
    if not isinstance(raw_links, list) or not raw_links:
        raise KinematicsError(f"{source}: no links: add one [[links]] table per link")
    lines = header_lines(text, "links")
    links: list[Link] = []
    seen: dict[str, int] = {}
    joints: dict[str, int] = {}
    for k, raw in enumerate(raw_links):
        line = lines[k] if k < len(lines) else 0
        name = raw.get("name", f"#{k}") if isinstance(raw, dict) else f"#{k}"
        where = f"{source}:{line}: link {name!r}" if isinstance(name, str) else \
            f"{source}:{line}: link #{k}"
        link = _parse_link(raw, where)
        if link.name in seen:
            raise KinematicsError(f"{where}: duplicate link name (first on line "
                                  f"{seen[link.name]})")
        if link.joint is not None and link.joint in joints:
            raise KinematicsError(f"{where}: duplicate joint name {link.joint!r} (first on "
                                  f"line {joints[link.joint]})")
        seen[link.name] = line
        if link.joint is not None:
            joints[link.joint] = line
        links.append(link)
    name = data.get("name", "")
    if not isinstance(name, str):
        raise KinematicsError(f"{source}: 'name' must be a string")
    return Chain(links, name=name, source=source, lines=seen)


def load_chain(path: str | Path) -> Chain:
    """Load and validate a chain TOML file (format: the module docstring).

    Raises
    ------
    KinematicsError
        If the file cannot be read or is malformed (naming the file, line and link).
    """
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise KinematicsError(f"{path}: cannot read the chain file: {exc.strerror}") from None
    return parse_chain(text, source=str(path))


def _rpy_of(r: np.ndarray) -> tuple[float, float, float]:
    """Return (roll, pitch, yaw), rad, of a rotation matrix (the inverse of `rpy_matrix`).

    At gimbal lock (pitch +-90 deg) only roll - yaw or roll + yaw is defined; scipy then
    chooses one split (and warns, here silenced): the matrix is the same.
    """
    import warnings

    from scipy.spatial.transform import Rotation

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Gimbal lock", UserWarning)
        roll, pitch, yaw = Rotation.from_matrix(r).as_euler("xyz")
    return float(roll), float(pitch), float(yaw)


def chain_toml(chain: Chain) -> str:
    """Return chain TOML text that `parse_chain` reads back as ``chain`` (to within 1e-12).

    Parameters
    ----------
    chain : Chain
        The chain.

    Returns
    -------
    str
    """
    out = [f"# kinematic chain (skin.world.kinematics): {chain.name or 'unnamed'}",
           f"name = {toml_value(chain.name)}"]
    for link in chain.links.values():
        roll, pitch, yaw = (math.degrees(a) for a in _rpy_of(link.origin[:3, :3]))
        out += ["", "[[links]]", f"name = {toml_value(link.name)}"]
        if link.parent is not None:
            out.append(f"parent = {toml_value(link.parent)}")
        out.append(f"xyz = {_toml_numbers(link.origin[:3, 3])}")
        out.append(f"rpy_deg = {_toml_numbers([roll, pitch, yaw])}")
        out.append(f"type = {toml_value(link.type)}")
        if link.type == "revolute":
            out.append(f"joint = {toml_value(str(link.joint))}")
            out.append(f"axis = {_toml_numbers(link.axis)}")
            if link.limits is not None:
                out.append(f"limits_deg = {_toml_numbers([math.degrees(v) for v in link.limits])}")
            out.append(f"default_deg = {_toml_numbers(math.degrees(link.default))}")
    return "\n".join(out) + "\n"


def _toml_numbers(values: Any) -> str:
    # 12 significant digits: 30.0, not 29.999999999999996
    return toml_value(np.asarray(values, dtype=float).tolist(), digits=12)


# ---- poses over time ----

def _check_times(time: np.ndarray, source: str) -> np.ndarray:
    t = np.asarray(time, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise KinematicsError(f"{source}: 'time' must be a non-empty 1-D array, "
                              f"got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        k = int(np.flatnonzero(~np.isfinite(t))[0])
        raise KinematicsError(f"{source}: time sample {k} is {t[k]}")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise KinematicsError(f"{source}: times must increase: sample {k} ({t[k]:g} s) "
                              f"follows {t[k - 1]:g} s")
    return t


class _Track:
    """What the two tracks share: a time grid and where a time falls on it."""

    time: np.ndarray
    source: str
    tolerance: float

    @property
    def span(self) -> tuple[float, float]:
        """First and last time, s."""
        return float(self.time[0]), float(self.time[-1])

    def _locate(self, t: float) -> tuple[int, float]:
        """Return (k, f): ``t`` lies a fraction f of the way from sample k to sample k + 1."""
        t0, t1 = self.span
        if not (t0 - self.tolerance <= t <= t1 + self.tolerance):
            raise KinematicsError(f"{self.source}: no pose at t = {t:g} s: the poses cover "
                                  f"{t0:g} to {t1:g} s")
        if self.time.size == 1 or t <= t0:
            return 0, 0.0
        if t >= t1:
            return self.time.size - 2, 1.0
        k = int(np.searchsorted(self.time, t, side="right")) - 1
        return k, float((t - self.time[k]) / (self.time[k + 1] - self.time[k]))


class JointTrack(_Track):
    """Joint angles over time, posed through a chain.

    Parameters
    ----------
    chain : Chain
        The chain.
    time : array_like
        Sample times, s, increasing (the skin's clock).
    q : array_like
        (n, joints) angles, rad, columns in the order of ``joints``.
    joints : sequence of str, optional
        Names of the columns; by default the chain's joints in order. Joints of the chain not
        named keep their default angle.
    source : str
        Where the track came from, for messages.
    tolerance : float
        How far outside its span (s) a time is still answered, with the nearest end's pose.

    Raises
    ------
    KinematicsError
        On a shape mismatch, unknown joint, non-finite angle or times that do not increase.
    """

    def __init__(self, chain: Chain, time: Any, q: Any, joints: Sequence[str] | None = None,
                 source: str = "<memory>", tolerance: float = 0.1) -> None:
        self.chain = chain
        self.source = source
        self.tolerance = float(tolerance)
        self.time = _check_times(time, source)
        self.joints = list(chain.joints if joints is None else joints)
        arr = np.asarray(q, dtype=float)
        if arr.ndim == 1 and len(self.joints) == 1:
            arr = arr[:, None]
        if arr.shape != (self.time.size, len(self.joints)):
            raise KinematicsError(f"{source}: joint angles of shape {arr.shape}, expected "
                                  f"({self.time.size} samples, {len(self.joints)} joints)")
        for k, name in enumerate(self.joints):
            if name not in chain.joints:
                raise KinematicsError(f"{source}: column {name!r} is not a joint of the chain "
                                      f"{chain.source} (joints: {', '.join(chain.joints)})")
            bad = np.flatnonzero(~np.isfinite(arr[:, k]))
            if bad.size:
                raise KinematicsError(f"{source}: joint {name!r}: sample {int(bad[0])} is "
                                      f"{arr[bad[0], k]}")
        if len(set(self.joints)) != len(self.joints):
            raise KinematicsError(f"{source}: a joint is named twice: {self.joints}")
        self.q = arr

    def angles_at(self, t: float) -> dict[str, float]:
        """Return the joint angles at time ``t`` (rad; linear between samples)."""
        k, f = self._locate(t)
        k1 = min(k + 1, self.time.size - 1)
        row = (1.0 - f) * self.q[k] + f * self.q[k1]
        return dict(zip(self.joints, (float(v) for v in row), strict=True))

    def poses_at(self, t: float) -> dict[str, np.ndarray]:
        """Return every link's pose at time ``t``."""
        return self.chain.poses(self.angles_at(t))


class LinkPoseTrack(_Track):
    """Link poses over time (4x4, link -> world), as a motion capture or a robot's log gives.

    Parameters
    ----------
    time : array_like
        Sample times, s, increasing (the skin's clock).
    poses : dict of str to array_like
        Link name -> (n, 4, 4) poses.
    source : str
        Where the track came from, for messages.
    tolerance : float
        How far outside its span (s) a time is still answered, with the nearest end's pose.

    Raises
    ------
    KinematicsError
        On a shape mismatch or a matrix that is not a rigid transform (naming link and sample).
    """

    def __init__(self, time: Any, poses: Mapping[str, Any], source: str = "<memory>",
                 tolerance: float = 0.1) -> None:
        self.source = source
        self.tolerance = float(tolerance)
        self.time = _check_times(time, source)
        self.poses: dict[str, np.ndarray] = {}
        for name, value in poses.items():
            arr = np.asarray(value, dtype=float)
            if arr.shape != (self.time.size, 4, 4):
                raise KinematicsError(f"{source}: link {name!r}: poses of shape {arr.shape}, "
                                      f"expected ({self.time.size}, 4, 4)")
            for k in range(arr.shape[0]):
                _check_rigid(arr[k], f"{source}: link {name!r}: sample {k}")
            self.poses[name] = arr
        self._links = list(self.poses)
        self._steps = _rotation_steps(np.array([self.poses[n][:, :3, :3] for n in self._links]))

    def poses_at(self, t: float) -> dict[str, np.ndarray]:
        """Return every link's pose at time ``t`` (translation linear, rotation slerp)."""
        from scipy.spatial.transform import Rotation

        k, f = self._locate(t)
        k1 = min(k + 1, self.time.size - 1)
        # slerp, as scipy's Slerp does it: R_k exp(f log(R_k^-1 R_k+1)), every link at once
        # (one Slerp call per link costs about 5 times more)
        turn = (Rotation.from_rotvec(f * self._steps[:, k]).as_matrix() if k1 > k
                else np.tile(np.eye(3), (len(self._links), 1, 1)))
        out = {}
        for i, name in enumerate(self._links):
            arr = self.poses[name]
            m = np.eye(4)
            m[:3, 3] = (1.0 - f) * arr[k, :3, 3] + f * arr[k1, :3, 3]
            m[:3, :3] = arr[k, :3, :3] @ turn[i]
            out[name] = m
        return out


def _rotation_steps(rotations: np.ndarray) -> np.ndarray:
    """Rotation vectors from each sample to the next, (links, n - 1, 3), of (links, n, 3, 3)."""
    from scipy.spatial.transform import Rotation

    links, n = rotations.shape[:2]
    if n < 2 or links == 0:
        return np.zeros((links, max(n - 1, 0), 3))
    r0 = Rotation.from_matrix(rotations[:, :-1].reshape(-1, 3, 3))
    r1 = Rotation.from_matrix(rotations[:, 1:].reshape(-1, 3, 3))
    return (r0.inv() * r1).as_rotvec().reshape(links, n - 1, 3)


class StaticPoses:
    """Link poses that do not change (a dict of 4x4 link -> world), as a pose source."""

    def __init__(self, poses: Mapping[str, Any], source: str = "<memory>") -> None:
        self.source = source
        self.poses = {}
        for name, m in poses.items():
            arr = np.asarray(m, dtype=float)
            if arr.shape != (4, 4):
                raise KinematicsError(f"{source}: link {name!r}: a pose must be 4x4, "
                                      f"got shape {arr.shape}")
            _check_rigid(arr, f"{source}: link {name!r}")
            self.poses[name] = arr

    def poses_at(self, t: float) -> dict[str, np.ndarray]:
        """Return the poses, whatever ``t``."""
        return {k: v.copy() for k, v in self.poses.items()}


def _check_rigid(m: np.ndarray, where: str) -> None:
    r = m[:3, :3]
    if not (np.all(np.isfinite(m)) and np.allclose(m[3], [0, 0, 0, 1], atol=1e-9)
            and np.allclose(r @ r.T, np.eye(3), atol=1e-6) and np.linalg.det(r) > 0):
        raise KinematicsError(f"{where}: not a rigid transform (a rotation and a translation "
                              "with last row 0 0 0 1)")


def as_pose_source(poses: Any) -> PoseSource:
    """Return a pose source from a `Chain`, a track, a dict of 4x4 poses, or None.

    None gives `default_chain` at its default angles.
    """
    if poses is None:
        return default_chain()
    if hasattr(poses, "poses_at"):
        return poses
    if isinstance(poses, Mapping):
        return StaticPoses(poses)
    raise TypeError(f"not a pose source: {type(poses).__name__}")


def load_poses(path: str | Path, chain: Chain | None = None,
               tolerance: float = 0.1) -> JointTrack | LinkPoseTrack:
    """Load poses over time from an NPZ or CSV file.

    Formats (angles in radians, times in s on the skin's clock, increasing):

    - NPZ with ``time`` (n,), ``joints`` (J,) names and ``q`` (n, J): joint angles;
    - NPZ with ``time`` (n,), ``links`` (L,) names and ``poses`` (n, L, 4, 4): link poses;
    - CSV with a header ``time,<joint>,<joint>,...`` and one row per sample (``#`` comments);
    - a ROS 2 bag (its folder, SQLite or MCAP storage), an ``.mcap`` file of ROS 2 messages or
      a ROS 1 ``.bag`` of ``sensor_msgs/msg/JointState`` (`skin.world.joint_states`; Unix
      times).

    Parameters
    ----------
    path : str or Path
        The file.
    chain : Chain, optional
        The chain joint angles go through; `default_chain` by default.
    tolerance : float
        How far outside the file's span (s) a time is still answered.

    Returns
    -------
    JointTrack or LinkPoseTrack

    Raises
    ------
    KinematicsError
        If the file cannot be read or is malformed (naming the file and the problem).
    """
    path = Path(path)
    src = str(path)
    chain = chain or default_chain()
    if path.is_dir() or path.suffix.lower() in (".bag", ".mcap"):
        from skin.world.joint_states import load_joint_states

        return load_joint_states(path, chain, tolerance=tolerance)
    if path.suffix.lower() == ".npz":
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
        except (OSError, ValueError) as exc:
            raise KinematicsError(f"{src}: cannot read the poses (NPZ without pickled "
                                  f"objects): {exc}") from None
        if "time" not in arrays:
            raise KinematicsError(f"{src}: no 'time' array (it has: "
                                  f"{', '.join(sorted(arrays)) or 'nothing'})")
        if "q" in arrays:
            names = arrays.get("joints")
            if names is None:
                raise KinematicsError(f"{src}: 'q' needs 'joints', the names of its columns")
            return JointTrack(chain, arrays["time"], arrays["q"], [str(n) for n in names],
                              source=src, tolerance=tolerance)
        if "poses" in arrays:
            names = arrays.get("links")
            poses = np.asarray(arrays["poses"], dtype=float)
            if names is None:
                raise KinematicsError(f"{src}: 'poses' needs 'links', the names of its links")
            if poses.ndim != 4 or poses.shape[1] != len(names) or poses.shape[2:] != (4, 4):
                raise KinematicsError(f"{src}: 'poses' of shape {poses.shape}, expected "
                                      f"(samples, {len(names)} links, 4, 4)")
            return LinkPoseTrack(arrays["time"], {str(n): poses[:, k]
                                                  for k, n in enumerate(names)},
                                 source=src, tolerance=tolerance)
        raise KinematicsError(f"{src}: neither joint angles ('joints', 'q') nor link poses "
                              "('links', 'poses')")
    if path.suffix.lower() == ".csv":
        return _load_csv(path, chain, tolerance)
    raise KinematicsError(f"{src}: poses must be a .npz or .csv file, a ROS 2 bag folder or "
                          ".mcap file, or a ROS 1 .bag")


def _load_csv(path: Path, chain: Chain, tolerance: float) -> JointTrack:
    src = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise KinematicsError(f"{src}: cannot read the poses: {exc.strerror}") from None
    rows = [(n, r) for n, r in enumerate(csv.reader(io.StringIO(text)), start=1)
            if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise KinematicsError(f"{src}: empty: expected a header 'time,<joint>,...' and rows")
    _, header = rows[0]
    header = [h.strip() for h in header]
    if header[0] != "time" or len(header) < 2:
        raise KinematicsError(f"{src}: the header must be 'time,<joint>,...', got "
                              f"{','.join(header)!r}")
    values = np.empty((len(rows) - 1, len(header)))
    for k, (line, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise KinematicsError(f"{src}:{line}: {len(row)} fields, the header has "
                                  f"{len(header)}")
        try:
            values[k] = [float(v) for v in row]
        except ValueError:
            raise KinematicsError(f"{src}:{line}: not a number in {','.join(row)!r}") from None
    if values.shape[0] == 0:
        raise KinematicsError(f"{src}: a header and no samples")
    return JointTrack(chain, values[:, 0], values[:, 1:], header[1:], source=src,
                      tolerance=tolerance)

"""Robots' localisation for the shared map: each robot's base pose in the map's frame over time.

A robot that moves publishes its base pose on ``<prefix>/<robot>/pose`` (from its own
localisation: odometry, SLAM, a motion-capture system), one JSON document per update::

    {"schema": "thermoskin.pose", "robot": "r1", "host_time": 1764100000.25,
     "pose": [x, y, z, roll, pitch, yaw]}          # m and rad; or a 4x4 row-major matrix

``host_time`` is Unix time, s (the time base of the contacts' ``host_onset``). `pose_payload`
makes one. The map service (`skin.world.map_service`) keeps each robot's recent poses
(`RobotPoses`) and places a contact with the pose that held at its ``host_onset``: the latest
update at or before it (or the first one, for a contact older than every update kept). A
robot that publishes no pose is placed with the static ``robot_pose`` its contacts carry (the
skin file's ``[output] robot_pose``), else at the map's origin.
"""

from __future__ import annotations

import bisect
import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from skin.world.kinematics import transform
from skin.world.map_store import MapInputError, check_pose

SCHEMA = "thermoskin.pose"


def pose_payload(robot: str, pose: Sequence[float] | np.ndarray, host_time: float) -> bytes:
    """Return the JSON payload of one pose update (module docstring)."""
    p = np.asarray(pose, dtype=float)
    return json.dumps({"schema": SCHEMA, "robot": robot, "host_time": float(host_time),
                       "pose": p.tolist()}).encode()


def parse_pose(msg: Mapping[str, Any]) -> tuple[str, float, np.ndarray]:
    """Return (robot, host time, 4x4 pose) of a pose update.

    Raises
    ------
    MapInputError
        A field missing or malformed, named.
    """
    if msg.get("schema") != SCHEMA:
        raise MapInputError(f"not a {SCHEMA} payload (schema {msg.get('schema')!r})")
    robot = msg.get("robot")
    if not isinstance(robot, str) or not robot:
        raise MapInputError(f"field 'robot' must be a name (got {robot!r})")
    t = msg.get("host_time")
    if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t):
        raise MapInputError(f"field 'host_time' must be a Unix time, s (got {t!r})")
    raw = msg.get("pose")
    try:
        p = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        p = np.zeros(0)
    if p.shape == (6,) and np.all(np.isfinite(p)):
        m = transform(p[:3], p[3:])
    elif p.shape == (4, 4):
        m = check_pose(p, "field 'pose'")
    else:
        raise MapInputError(f"field 'pose' must be [x, y, z, roll, pitch, yaw] or a 4x4 "
                            f"matrix of finite numbers (got {raw!r})")
    return robot, float(t), m


class RobotPoses:
    """Each robot's pose updates, by host time (the last ``keep`` per robot).

    Parameters
    ----------
    keep : int
        Updates kept per robot (at 100 Hz, 100,000 is about 17 minutes); older ones are
        forgotten, so memory stays bounded on a day-long run.
    """

    def __init__(self, keep: int = 100_000) -> None:
        self.keep = keep
        self._times: dict[str, list[float]] = {}
        self._poses: dict[str, list[list[list[float]]]] = {}

    def __contains__(self, robot: object) -> bool:
        return robot in self._times

    def add(self, robot: str, host_time: float, pose: np.ndarray) -> None:
        """Keep one update (updates may arrive out of order)."""
        times = self._times.setdefault(robot, [])
        poses = self._poses.setdefault(robot, [])
        k = bisect.bisect_right(times, host_time)
        times.insert(k, host_time)
        poses.insert(k, np.asarray(pose, dtype=float).tolist())
        if len(times) > self.keep:
            del times[: len(times) - self.keep]
            del poses[: len(poses) - self.keep]

    def at(self, robot: str, host_time: float) -> list[list[float]] | None:
        """Return the pose that held at ``host_time`` (None for a robot without updates)."""
        times = self._times.get(robot)
        if not times:
            return None
        k = bisect.bisect_right(times, host_time) - 1
        return self._poses[robot][max(k, 0)]

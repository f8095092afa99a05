"""Rotations through scipy.spatial.transform, checked against the closed forms they replaced."""

import math

import numpy as np
import pytest

pytest.importorskip("scipy")
from skin.world.kinematics import (
    Chain,
    LinkPoseTrack,
    _rpy_of,
    chain_toml,
    default_chain,
    parse_chain,
    rotation_about,
    rpy_matrix,
    transform,
)
from skin.world.kinematics import Link as ChainLink

RNG = np.random.default_rng(19)


# --- the hand-written forms used before (the reference) -----------------------------------------

def rodrigues(axis, angle):
    x, y, z = axis
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def rz_ry_rx(roll, pitch, yaw):
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    return rz @ ry @ rx


def quaternion(r):
    w = math.sqrt(max(1.0 + np.trace(r), 0.0)) / 2
    if w > 1e-3:
        q = np.array([w, (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w),
                      (r[1, 0] - r[0, 1]) / (4 * w)])
    else:  # near 180 deg: from the largest diagonal entry (the old branch)
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + r[i, i] - r[j, j] - r[k, k], 0.0))
        q = np.empty(4)
        q[0], q[1 + i] = (r[k, j] - r[j, k]) / s, 0.25 * s
        q[1 + j], q[1 + k] = (r[j, i] + r[i, j]) / s, (r[k, i] + r[i, k]) / s
    return q / np.linalg.norm(q)


def matrix(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def old_slerp(q0, q1, f):
    dot = float(q0 @ q1)
    if dot < 0.0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q = q0 + f * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = math.acos(min(dot, 1.0))
    return (math.sin((1 - f) * theta) * q0 + math.sin(f * theta) * q1) / math.sin(theta)


def unit(v):
    return v / np.linalg.norm(v)


# --- the checks ----------------------------------------------------------------------------------

def test_rotation_about_an_axis_is_rodrigues():
    angles = [0.0, 1e-9, 0.3, -2.0, math.pi, -math.pi, 7.0]
    for angle in angles:
        for _ in range(20):
            axis = unit(RNG.normal(size=3))
            np.testing.assert_allclose(rotation_about(axis, angle), rodrigues(axis, angle),
                                       atol=1e-14)


def test_roll_pitch_yaw_is_rz_ry_rx_and_reads_back():
    cases = [RNG.uniform(-math.pi, math.pi, 3) for _ in range(200)]
    cases += [np.array([0.3, s * math.pi / 2, -1.1]) for s in (1, -1)]  # gimbal lock
    cases += [np.zeros(3), np.array([math.pi, 0.0, 0.0])]
    for rpy in cases:
        r = rpy_matrix(*rpy)
        np.testing.assert_allclose(r, rz_ry_rx(*rpy), atol=1e-14)
        # the angles read back give the same matrix, at gimbal lock too
        np.testing.assert_allclose(rpy_matrix(*_rpy_of(r)), r, atol=1e-12)


def test_a_chain_with_a_gimbal_locked_link_round_trips_through_toml():
    chain = Chain([ChainLink("base", None, transform((0.1, 0.2, 0.3), (0.4, math.pi / 2, 0.9))),
                   ChainLink("arm", "base", transform(rpy=(0.0, -math.pi / 2, 2.0)))])
    again = parse_chain(chain_toml(chain))
    for name in ("base", "arm"):
        np.testing.assert_allclose(again.links[name].origin, chain.links[name].origin,
                                   atol=1e-11)
    default = default_chain()
    assert parse_chain(chain_toml(default)).poses().keys() == default.poses().keys()


def test_link_poses_between_samples_follow_the_old_slerp():
    n = 60
    rots = [rpy_matrix(*RNG.uniform(-math.pi, math.pi, 3)) for _ in range(n)]
    # stiff cases: the same rotation twice, nearly the same, 180 deg apart, and beyond
    # (the shortest arc turns the other way)
    rots[10] = rots[11] = rpy_matrix(0.1, 0.2, 0.3)
    rots[21] = rots[20] @ rotation_about((0.0, 0.0, 1.0), 1e-7)
    rots[31] = rots[30] @ rotation_about(unit(np.array([1.0, 2.0, 0.5])), 3.0)
    rots[41] = rots[40] @ rotation_about((1.0, 0.0, 0.0), math.pi - 1e-6)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = rots
    poses[:, :3, 3] = RNG.normal(size=(n, 3))
    time = np.cumsum(RNG.uniform(0.01, 0.2, n))
    track = LinkPoseTrack(time, {"link": poses})
    worst = 0.0
    for k in range(n - 1):
        for f in (0.0, 0.25, 0.5, 0.9, 1.0):
            t = time[k] + f * (time[k + 1] - time[k])
            got = track.poses_at(t)["link"]
            want = matrix(old_slerp(quaternion(rots[k]), quaternion(rots[k + 1]), f))
            worst = max(worst, float(np.abs(got[:3, :3] - want).max()))
            np.testing.assert_allclose(got[:3, 3], (1 - f) * poses[k, :3, 3]
                                       + f * poses[k + 1, :3, 3], atol=1e-12)
    assert worst < 1e-6  # the old form was linear within 0.9995 of parallel (error ~1e-7)
    # one sample: that pose; outside the samples within the tolerance: the nearest end
    one = LinkPoseTrack([1.0], {"link": poses[:1]})
    np.testing.assert_allclose(one.poses_at(1.05)["link"], poses[0], atol=1e-14)
    np.testing.assert_allclose(track.poses_at(time[-1] + 0.05)["link"], poses[-1], atol=1e-12)


def test_arm_mesh_poses_match_the_old_explicit_forms():
    pytest.importorskip("pyvista")
    from skin.viz.arm_mesh import euler_pose, rotation_pose

    for _ in range(50):
        deg = RNG.uniform(-180, 180, 3)
        origin = RNG.normal(size=3)
        want = np.eye(4)
        want[:3, :3] = rz_ry_rx(*np.radians(deg))
        want[:3, 3] = origin
        np.testing.assert_allclose(euler_pose(origin, deg), want, atol=1e-14)
        a = math.radians(deg[0])
        want[:3, :3] = [[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]]
        np.testing.assert_allclose(rotation_pose(deg[0], tuple(origin)), want, atol=1e-14)

"""URDF arms (yourdfpy): chain, limits, meshes; the shipped xArm 7; joint states from bags."""

import numpy as np
import pytest

pytest.importorskip("yourdfpy")

from skin.errors import SkinError
from skin.formats.layout import load_layout
from skin.world.kinematics import KinematicsError, load_poses
from skin.world.urdf import example_urdf, load_urdf

URDF = """<?xml version="1.0"?>
<robot name="two">
  <link name="base"><visual><geometry><mesh filename="base.stl"/></geometry></visual></link>
  <link name="arm">
    <visual><origin xyz="0 0 0.1" rpy="0 0 0"/>
      <geometry><mesh filename="package://two/arm.stl" scale="2 2 2"/></geometry></visual>
  </link>
  <link name="tip"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="arm"/><origin xyz="0 0 0.5" rpy="0 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="1" velocity="1"/>
  </joint>
  <joint name="tip_joint" type="fixed">
    <parent link="arm"/><child link="tip"/><origin xyz="0 0 0.3" rpy="0 0 0"/>
  </joint>
</robot>
"""


@pytest.fixture
def two(tmp_path):
    pv = pytest.importorskip("pyvista")
    folder = tmp_path / "two"
    (folder / "urdf").mkdir(parents=True)
    pv.Cube(x_length=0.1, y_length=0.1, z_length=0.1).triangulate().save(folder / "arm.stl")
    pv.Cube().triangulate().save(folder / "urdf" / "base.stl")
    path = folder / "urdf" / "two.urdf"
    path.write_text(URDF)
    return path


def test_chain_limits_and_meshes_of_a_urdf(two):
    arm = load_urdf(two)
    assert arm.chain.joints == ["shoulder"]
    assert arm.chain.links["arm"].limits == (-1.5, 1.5)
    assert arm.chain.links["arm"].axis == (0.0, 1.0, 0.0)
    poses = arm.chain.poses({"shoulder": 1.0})  # about y: z turns towards x
    assert np.allclose(poses["tip"][:3, 3], [0.3 * np.sin(1), 0.0, 0.5 + 0.3 * np.cos(1)])
    with pytest.raises(KinematicsError, match="outside its limits"):
        arm.chain.poses({"shoulder": 2.0})
    (visual,) = arm.visuals["arm"]
    assert visual.path.name == "arm.stl" and visual.scale == (2.0, 2.0, 2.0)  # package://
    assert np.allclose(visual.origin[:3, 3], [0, 0, 0.1])
    from skin.viz.arm_mesh import load_arm

    links = load_arm(two)
    assert set(links) == {"base", "arm"} and links["arm"].parent == "base"
    assert np.allclose(np.ptp(links["arm"].points, axis=0), 0.2)  # scaled
    assert np.allclose(links["arm"].points[:, 2].mean(), 0.1)  # at its visual origin


def test_urdf_errors_name_the_file_and_the_joint_or_mesh(tmp_path):
    bad = tmp_path / "slide.urdf"
    bad.write_text(URDF.replace('type="revolute"', 'type="prismatic"'))
    with pytest.raises(KinematicsError, match=r"slide.urdf: joint 'shoulder' is prismatic"):
        load_urdf(bad)
    missing = tmp_path / "m.urdf"
    missing.write_text(URDF)
    with pytest.raises(KinematicsError, match=r"m.urdf: link 'base': mesh 'base.stl' not found"):
        load_urdf(missing)
    with pytest.raises(KinematicsError, match="no such URDF"):
        load_urdf(tmp_path / "none.urdf")


def test_the_shipped_xarm7_carries_every_layout_taxel_on_its_meshes():
    pytest.importorskip("pyvista")
    try:
        path = example_urdf()
    except SkinError as exc:
        pytest.skip(str(exc))
    arm = load_urdf(path)
    assert arm.chain.joints == [f"joint{k}" for k in range(1, 8)]
    assert all(arm.chain.links[f"link{k}"].limits is not None for k in range(1, 8))
    from skin.viz.arm_mesh import ArmSurface, load_arm

    layout = load_layout("xarm7")
    links = load_arm("xarm7")
    ArmSurface(layout, links)  # snaps every taxel onto its link's mesh, or raises
    assert {t.link for t in layout.taxels} == {"link3", "link5"} and len(layout) == 48


def test_poses_from_joint_states_in_a_ros2_bag(tmp_path, two):
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    JointState = ts.types["sensor_msgs/msg/JointState"]
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    t0 = 1_790_000_000.0
    chain = load_urdf(two).chain
    for storage in (StoragePlugin.SQLITE3, StoragePlugin.MCAP):
        bag = tmp_path / f"bag_{storage.name}"
        with Writer(bag, version=9, storage_plugin=storage) as writer:
            conn = writer.add_connection("/joint_states", JointState.__msgtype__, typestore=ts)
            for k in range(50):
                t = t0 + k * 0.02
                msg = JointState(
                    header=Header(stamp=Time(sec=int(t), nanosec=round((t % 1) * 1e9)),
                                  frame_id=""),
                    name=["other", "shoulder"], position=np.array([9.0, 0.01 * k]),
                    velocity=np.zeros(2), effort=np.zeros(2))
                writer.write(conn, int(t * 1e9), ts.serialize_cdr(msg, JointState.__msgtype__))
        track = load_poses(bag, chain)
        if storage == StoragePlugin.MCAP:  # the .mcap file alone reads the same
            (file,) = bag.glob("*.mcap")
            alone = load_poses(file, chain)
            assert np.array_equal(alone.time, track.time) and np.array_equal(alone.q, track.q)
        assert track.joints == ["shoulder"]
        assert track.angles_at(t0 + 0.5)["shoulder"] == pytest.approx(0.25, abs=1e-6)
        assert np.allclose(track.poses_at(t0)["tip"], chain.poses({"shoulder": 0.0})["tip"])
    with pytest.raises(KinematicsError, match="cannot read the bag"):
        load_poses(tmp_path, chain)  # a folder that is no bag

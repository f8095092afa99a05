"""Poses from a robot's recorded joint states: ROS 2 bags (SQLite, MCAP), MCAP files, ROS 1 bags.

`load_joint_states` reads every ``sensor_msgs/msg/JointState`` message of a bag with rosbags
(``pip install 'thermoskin[urdf]'``) into a `skin.world.kinematics.JointTrack` over a chain
(a URDF's, `skin.world.urdf`, or the default arm). Times are the messages' header stamps (or,
where a stamp is zero, the time the bag logged them): Unix time on the robot's clock, the time
base of the events' ``host_*`` times (`skin.stream.sinks.event_record`), so a contact's pose
is ``track.poses_at(event["host_onset"])``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from skin._optional import require
from skin.world.kinematics import Chain, JointTrack, KinematicsError

JOINT_STATE = "sensor_msgs/msg/JointState"


def load_joint_states(path: str | Path, chain: Chain, topic: str | None = None,
                      tolerance: float = 0.1) -> JointTrack:
    """Read the joint states of a bag into a track of joint angles.

    Parameters
    ----------
    path : str or Path
        A ROS 2 bag (its folder), an MCAP file of ROS 2 messages, or a ROS 1 ``.bag`` file.
    chain : Chain
        The chain the angles move; joints of the messages it does not have are ignored.
    topic : str, optional
        The topic to read (default: the one ``JointState`` topic of the bag).
    tolerance : float
        How far outside the bag's span (s) a time is still answered.

    Raises
    ------
    KinematicsError
        Naming the bag and the problem: unreadable, no or several joint-state topics, a
        message without a joint of the chain, times that do not increase.
    """
    highlevel = require("rosbags.highlevel", "reading joint states from bags")
    src = str(path)
    try:
        reader = highlevel.AnyReader([Path(path)])
        reader.open()
    except Exception as exc:  # rosbags raises its own errors per format
        raise KinematicsError(f"{src}: cannot read the bag ({type(exc).__name__}: {exc})"
                              ) from None
    try:
        conns = [c for c in reader.connections if c.msgtype == JOINT_STATE
                 and (topic is None or c.topic == topic)]
        topics = sorted({c.topic for c in conns})
        if not topics:
            raise KinematicsError(f"{src}: no {JOINT_STATE} messages"
                                  + (f" on {topic}" if topic else ""))
        if len(topics) > 1:
            raise KinematicsError(f"{src}: joint states on several topics ({', '.join(topics)});"
                                  " choose one")
        wanted = [j for j in chain.joints]
        times, rows = [], []
        for k, (conn, stamp, raw) in enumerate(reader.messages(connections=conns)):
            msg = reader.deserialize(raw, conn.msgtype)
            t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            index = {str(n): i for i, n in enumerate(msg.name)}
            missing = [j for j in wanted if j not in index]
            if missing:
                raise KinematicsError(f"{src}: {topics[0]} message {k}: no position of joint "
                                      f"{missing[0]!r} of {chain.source}")
            times.append(t if t > 0 else stamp * 1e-9)
            rows.append([float(msg.position[index[j]]) for j in wanted])
    finally:
        reader.close()
    return JointTrack(chain, np.array(times), np.array(rows), wanted, source=src,
                      tolerance=tolerance)

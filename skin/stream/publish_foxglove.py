"""A live Foxglove WebSocket server (foxglove-sdk): ``foxglove://HOST:PORT``.

Open ``ws://HOST:PORT`` in Foxglove (any browser) and add panels:

==============  ==================  ========================================================
topic           schema              what
==============  ==================  ========================================================
``/temperature``  protobuf          one message per sample, log time = the sample's host
                ``thermoskin.       time (Unix): ``host_time`` (Unix s), ``device_time`` (s),
                Temperature``       ``temperature`` (deg C per taxel, layout order, NaN
                                    without a reading) and ``taxel`` (their ids): a Plot
                                    panel plots ``/temperature.temperature[12]``
``/contacts``   JSON schema         each contact result (`skin.stream.publish.contact_payload`:
                ``thermoskin.       material, family, probabilities, centroid and normal in
                contact``           its link's frame, device and host times)
``/tf``         foxglove.           the layout as frames: world -> each link (the arm's pose:
                FrameTransforms     a URDF's chain, or the default arm's, at default angles;
                                    else at the origin) -> ``taxel_<ID>`` (z along the
                                    outward normal)
``/arm``        foxglove.           the arm in 3-D: the chain's links as a stick figure, each
                SceneUpdate         taxel a disc coloured by the material of its last contact
``/health``     JSON schema         `skin.stream.publish.health_payload`, once a second
==============  ==================  ========================================================

Frame transforms and the scene are sent again every ``health_period`` seconds, so a client that
connects later has them within that time. Nothing is encoded while no client subscribes to a
topic: the skin pays for what someone watches.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from skin._optional import require
from skin.formats.layout import Layout
from skin.formats.protobuf import (
    TEMPERATURE_SCHEMA,
    encode_temperature,
    packed_ids,
    temperature_descriptor,
)
from skin.stream.pipeline import ContactResult
from skin.stream.publish import Publisher, contact_payload

LINGER = 0.5  # s the server stays up after the last contact sent, for it to reach the clients

CONTACT_SCHEMA = {
    "title": "thermoskin.contact",
    "type": "object",
    "properties": {
        "contact": {"type": "integer"}, "label": {"type": "string"},
        "family": {"type": ["string", "null"]}, "confidence": {"type": "number"},
        "probabilities": {"type": "object", "additionalProperties": {"type": "number"}},
        "taxels": {"type": "array", "items": {"type": "integer"}},
        "link": {"type": "string"},
        "centroid": {"type": "array", "items": {"type": "number"}},
        "normal": {"type": "array", "items": {"type": "number"}},
        "onset": {"type": "number"}, "host_onset": {"type": ["number", "null"]},
    },
}
HEALTH_SCHEMA = {"title": "thermoskin.health", "type": "object"}
GREY = (0.6, 0.6, 0.6)
#: Diameter and thickness of a taxel's disc in the scene, m.
DISC = (0.012, 0.002)


def _z_frames(normals: np.ndarray) -> np.ndarray:
    """Return rotation matrices (n, 3, 3) whose z axes are the unit ``normals`` (n, 3)."""
    z = np.asarray(normals, dtype=float).reshape(-1, 3)
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    helper = np.where((np.abs(z[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=2)


def _quaternions(rotations: np.ndarray) -> np.ndarray:
    """Return the quaternions (n, 4) as (w, x, y, z) of rotation matrices (n, 3, 3)."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(np.asarray(rotations, dtype=float).reshape(-1, 3, 3)).as_quat()
    return q[:, [3, 0, 1, 2]]


class FoxglovePublisher(Publisher):
    """Serve the skin to Foxglove over WebSocket (see the module docstring).

    Parameters
    ----------
    layout : Layout
        The skin.
    host, port : str, int
        Where the server listens (port 0: any free port; ``port`` then tells it).
    robot : str
        The robot's name (server name, payloads).
    colours : dict of str to tuple, optional
        Material -> RGB 0-1 for the scene; the materials table's by default.
    url : str
        The URL it was opened with, for messages.
    chain : skin.world.kinematics.Chain, optional
        The arm (a URDF's, `skin.world.urdf`), posed at its default angles for the frames and
        the stick figure; the default arm's when the layout's links are its.
    """

    def __init__(self, layout: Layout, host: str = "127.0.0.1", port: int = 8765,
                 robot: str = "skin", colours: dict[str, tuple[float, float, float]] | None
                 = None, url: str = "", chain: Any = None) -> None:
        super().__init__(layout, robot)
        fg = require("foxglove", "the Foxglove server")
        self._fg = fg
        self._msg = require("foxglove.messages", "the Foxglove server")
        channels = require("foxglove.channels", "the Foxglove server")
        if colours is None:
            from skin.models import load_materials

            colours = {m.name: m.rgb for m in load_materials().values()}
        self.colours = colours
        self._ctx = fg.Context()
        try:
            self._server = fg.start_server(name=f"thermoskin {robot}", host=host, port=port,
                                           context=self._ctx)
        except Exception as exc:
            from skin.errors import SkinError

            raise SkinError(f"foxglove://{host}:{port}: cannot start the server ({exc})"
                            ) from None
        self.port = self._server.port
        self.url = url or f"foxglove://{host}:{self.port}"
        ctx = self._ctx
        self._temperature = fg.Channel(
            "/temperature", message_encoding="protobuf", context=ctx,
            schema=fg.Schema(name=TEMPERATURE_SCHEMA, encoding="protobuf",
                             data=temperature_descriptor()))
        self._contacts = fg.Channel("/contacts", schema=CONTACT_SCHEMA, context=ctx)
        self._health = fg.Channel("/health", schema=HEALTH_SCHEMA, context=ctx)
        self._tf = channels.FrameTransformsChannel("/tf", context=ctx)
        self._arm = channels.SceneUpdateChannel("/arm", context=ctx)
        self._taxels = packed_ids(layout.ids)
        self._labels: dict[int, str] = {}  # taxel index -> material of its last contact
        self._poses = self._link_poses(chain)
        frames = _z_frames(layout.normals)  # each taxel's frame: z along its outward normal
        quats = _quaternions(frames).tolist()
        self._tf_msg = self._transforms(quats)
        m = self._msg
        self._disc_poses = []
        for k, (w, x, y, z) in enumerate(quats):
            p = layout.positions[k].tolist()
            self._disc_poses.append(m.Pose(position=m.Vector3(x=p[0], y=p[1], z=p[2]),
                                           orientation=m.Quaternion(x=x, y=y, z=z, w=w)))
        self._discs = [self._disc(k) for k in range(len(layout))]
        self._scene_msg: Any = None
        self._next_static = 0.0
        self._last_contact = -np.inf  # monotonic time of the last contact sent to a client
        self._closed = False

    # -- the layout and the arm --

    def _link_poses(self, chain: Any) -> dict[str, np.ndarray]:
        from skin.world.kinematics import default_chain

        chain = chain or default_chain()
        links = set(self.layout.links)
        poses = chain.poses() if links <= set(chain.links) else {}
        order = list(poses) + sorted(links - set(poses))  # parents before children
        return {link: poses.get(link, np.eye(4)) for link in order}

    def _transforms(self, taxel_quats: list[list[float]]) -> Any:
        """Return the layout's frames (built once: taxels do not move on their links)."""
        m = self._msg

        def tf(parent: str, child: str, t: list[float], q: list[float]) -> Any:
            w, x, y, z = q
            return m.FrameTransform(parent_frame_id=parent, child_frame_id=child,
                                    translation=m.Vector3(x=t[0], y=t[1], z=t[2]),
                                    rotation=m.Quaternion(x=x, y=y, z=z, w=w))

        poses = list(self._poses.items())
        link_quats = _quaternions(np.array([p[:3, :3] for _, p in poses])).tolist()
        out = [tf("world", link, p[:3, 3].tolist(), q)
               for (link, p), q in zip(poses, link_quats, strict=True)]
        positions = self.layout.positions.tolist()
        out += [tf(taxel.link, f"taxel_{taxel.id}", positions[k], taxel_quats[k])
                for k, taxel in enumerate(self.layout.taxels)]
        return m.FrameTransforms(transforms=out)

    def _disc(self, k: int) -> Any:
        """Taxel ``k``'s disc, in the colour of its last contact's material."""
        m = self._msg
        label = self._labels.get(k)
        r, g, b = self.colours.get(label, GREY) if label else GREY
        return m.CylinderPrimitive(pose=self._disc_poses[k],
                                   size=m.Vector3(x=DISC[0], y=DISC[0], z=DISC[1]),
                                   bottom_scale=1.0, top_scale=1.0,
                                   color=m.Color(r=r, g=g, b=b, a=1.0))

    def _scene(self) -> Any:
        """Return the arm: a stick figure of the links and every taxel's disc."""
        if self._scene_msg is not None:
            return self._scene_msg
        m = self._msg
        by_link: dict[str, list[Any]] = {}
        for k, taxel in enumerate(self.layout.taxels):
            by_link.setdefault(taxel.link, []).append(self._discs[k])
        entities = [m.SceneEntity(frame_id=link, id=f"skin/{link}", frame_locked=True,
                                  cylinders=discs) for link, discs in by_link.items()]
        points = [m.Point3(x=float(p[0, 3]), y=float(p[1, 3]), z=float(p[2, 3]))
                  for p in self._poses.values()]
        if len(points) > 1:
            entities.append(m.SceneEntity(
                frame_id="world", id="arm/links", lines=[m.LinePrimitive(
                    type=m.LinePrimitiveLineType.LineStrip, thickness=0.03, points=points,
                    color=m.Color(r=0.75, g=0.75, b=0.78, a=1.0))]))
        self._scene_msg = m.SceneUpdate(entities=entities)
        return self._scene_msg

    def _send_static(self, log_time: int) -> None:
        if self._tf.has_sinks():
            self._tf.log(self._tf_msg, log_time=log_time)
        if self._arm.has_sinks():
            self._arm.log(self._scene(), log_time=log_time)

    # -- the publisher's parts --

    def publish_temperature(self, times: np.ndarray, temperature: np.ndarray,
                            host_times: np.ndarray) -> None:
        """Send one message per sample (only while a client subscribes)."""
        from skin.drivers.clock import WALL_OFFSET

        if self._closed:
            return
        now = time.monotonic()
        if now >= self._next_static:
            self._next_static = now + self.health_period
            self._send_static(time.time_ns())
        if not self._temperature.has_sinks():
            return
        stamps = np.asarray(host_times, dtype=float) + WALL_OFFSET
        log = self._temperature.log
        temps = np.asarray(temperature, dtype="<f4")
        for t, stamp, row in zip(times.tolist(), stamps.tolist(), temps, strict=True):
            log(encode_temperature(stamp, t, row, self._taxels), log_time=int(stamp * 1e9))

    def publish_contact(self, result: ContactResult) -> None:
        """Send a contact result and repaint its taxels."""
        if self._closed:
            return
        payload = contact_payload(result, self.layout, self.robot)
        stamp = payload["host_reported_at"] or time.time()
        if self._contacts.has_sinks():
            self._last_contact = time.monotonic()
        self._contacts.log(payload, log_time=int(stamp * 1e9))
        if result.contact.final:
            for t in result.contact.taxels:
                k = self.layout.index(t)
                self._labels[k] = result.estimate.label
                self._discs[k] = self._disc(k)
            self._scene_msg = None
            self._send_static(int(stamp * 1e9))

    def publish_health(self, payload: dict[str, Any]) -> None:
        """Send a health payload."""
        if not self._closed:
            self._health.log(payload, log_time=int(payload["host_time"] * 1e9))

    def close(self) -> None:
        """Stop the server (idempotent), after the last contact had time to reach the clients.

        The server sends from its own thread and stopping it drops what is still queued, so a
        run's last contacts (decided when it ends) would be lost; it lingers up to `LINGER`
        seconds after the last contact sent to a subscriber.
        """
        if not self._closed:
            self._closed = True
            time.sleep(max(0.0, self._last_contact + LINGER - time.monotonic()))
            self._server.stop()

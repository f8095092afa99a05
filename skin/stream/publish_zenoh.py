"""Publishing over Zenoh (eclipse-zenoh): ``zenoh://[PREFIX]`` (`skin.stream.publish`).

Keys: ``<prefix>/<robot>/temperature``, ``<prefix>/<robot>/contacts``, ``<prefix>/<robot>/health``
with the payloads of `skin.stream.publish` (Zenoh encodings ``application/octet-stream;
thermoskin.temperature`` and ``application/json``). Contacts and health are sent reliably and
block when the network's queue is full (none may be lost); temperatures are dropped rather than
stall the skin. With ``listen`` or ``connect`` endpoints, multicast scouting is off: the session
talks to those endpoints alone.

With ``resend`` (seconds), the publisher also listens to a shared map service's
acknowledgements (``<prefix>/map/acks/<robot>``, `skin.world.map_service`), keeps every contact
the map has not acknowledged, and sends it again every ``resend`` seconds (the map counts it
once), so contacts published while the service was down or unreachable reach it once it is
back. Closing waits up to `FLUSH_TIMEOUT` s for the last acknowledgements.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any

import numpy as np

from skin._optional import require
from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.stream.pipeline import ContactResult
from skin.stream.publish import Publisher, contact_payload, temperature_payload

TOPICS = ("temperature", "contacts", "health")
#: Seconds `ZenohPublisher.close` waits for a map's acknowledgements (with ``resend``).
FLUSH_TIMEOUT = 5.0
#: Most unacknowledged contacts kept for re-sending (the oldest are dropped, counted).
MAX_PENDING = 100_000


def zenoh_config(listen: list[str] | None = None, connect: list[str] | None = None,
                 mode: str | None = None) -> Any:
    """Return a ``zenoh.Config`` for the endpoints given (multicast scouting off with them).

    Raises
    ------
    SkinError
        If Zenoh refuses a setting (a malformed endpoint, an unknown mode).
    """
    zenoh = require("zenoh", "publishing over Zenoh")
    conf = zenoh.Config()
    try:
        if mode:
            conf.insert_json5("mode", json.dumps(mode))
        if listen:
            conf.insert_json5("listen/endpoints", json.dumps(listen))
        if connect:
            conf.insert_json5("connect/endpoints", json.dumps(connect))
        if listen or connect:
            conf.insert_json5("scouting/multicast/enabled", "false")
    except Exception as exc:  # zenoh raises its own ZError
        raise SkinError(f"zenoh: bad configuration ({exc})") from None
    return conf


def open_session(listen: list[str] | None = None, connect: list[str] | None = None,
                 mode: str | None = None) -> Any:
    """Open a Zenoh session (`zenoh_config`), naming the endpoints if it fails."""
    zenoh = require("zenoh", "publishing over Zenoh")
    conf = zenoh_config(listen, connect, mode)
    try:
        return zenoh.open(conf)
    except Exception as exc:
        raise SkinError(f"zenoh: cannot open a session (listen {listen or []}, connect "
                        f"{connect or []}): {exc}") from None


class ZenohPublisher(Publisher):
    """Publish the skin over Zenoh (see the module docstring).

    Parameters
    ----------
    layout : Layout
        The skin.
    prefix : str
        Key prefix (``thermoskin``).
    robot : str
        The robot's name: the key segment after the prefix.
    listen, connect : list of str
        Zenoh endpoints (``tcp/127.0.0.1:7447``).
    mode : str, optional
        ``peer`` (Zenoh's default) or ``client``.
    url : str
        The URL it was opened with, for messages.
    robot_pose : array (4, 4), optional
        The robot's base in the shared map's frame: sent as ``robot_pose`` with each contact.
    link_poses : dict of str to array (4, 4), optional
        Each link's pose in the robot's base frame (its chain standing still): the contact's
        link's is sent as ``link_pose`` (`skin.world.map_store`).
    resend : float, optional
        Re-send contacts a map service has not acknowledged after this many seconds.
    """

    def __init__(self, layout: Layout, prefix: str = "thermoskin", robot: str = "skin",
                 listen: list[str] | None = None, connect: list[str] | None = None,
                 mode: str | None = None, url: str = "", robot_pose: Any = None,
                 link_poses: dict[str, Any] | None = None, resend: float | None = None
                 ) -> None:
        super().__init__(layout, robot)
        self.robot_pose = None if robot_pose is None else np.asarray(robot_pose).tolist()
        self.link_poses = {k: np.round(np.asarray(v), 9).tolist()
                           for k, v in (link_poses or {}).items()}
        zenoh = require("zenoh", "publishing over Zenoh")
        self.url = url or f"zenoh://{prefix}"
        self.keys = {t: f"{prefix}/{robot}/{t}" for t in TOPICS}
        self._session = open_session(listen, connect, mode)
        block, drop = zenoh.CongestionControl.BLOCK, zenoh.CongestionControl.DROP
        reliable = zenoh.Reliability.RELIABLE
        self._pub = {
            "temperature": self._session.declare_publisher(
                self.keys["temperature"], congestion_control=drop, reliability=reliable,
                encoding=zenoh.Encoding("application/octet-stream;thermoskin.temperature")),
            "contacts": self._session.declare_publisher(
                self.keys["contacts"], congestion_control=block, reliability=reliable,
                encoding=zenoh.Encoding.APPLICATION_JSON),
            "health": self._session.declare_publisher(
                self.keys["health"], congestion_control=block, reliability=reliable,
                encoding=zenoh.Encoding.APPLICATION_JSON),
        }
        self._taxels_json = json.dumps(layout.ids.tolist(), separators=(",", ":"))
        self._closed = False
        self.resend = resend
        self._pending: dict[tuple[int, float], list[Any]] = {}  # key -> [payload, sent at]
        self._lock = threading.Lock()
        self._next_check = 0.0
        self._acks = None
        if resend is not None:
            self._acks = self._session.declare_subscriber(f"{prefix}/map/acks/{robot}",
                                                          self._acknowledged)

    def _acknowledged(self, sample: Any) -> None:
        """Forget the contacts a map service acknowledged (a Zenoh callback)."""
        try:
            rows = json.loads(sample.payload.to_bytes())["contacts"]
            keys = [(int(c), round(float(o), 6)) for c, o in rows]
        except (ValueError, KeyError, TypeError):
            return  # not an acknowledgement of this library: nothing to forget
        with self._lock:
            for key in keys:
                self._pending.pop(key, None)

    @property
    def unacknowledged(self) -> int:
        """Contacts sent but not acknowledged by a map service yet (with ``resend``)."""
        with self._lock:
            return len(self._pending)

    def _resend_due(self, force: bool = False) -> None:
        """Send again the contacts unacknowledged for ``resend`` s (checked twice a second)."""
        now = time.monotonic()
        if self.resend is None or (now < self._next_check and not force):
            return
        self._next_check = now + 0.5
        with self._lock:
            due = [entry for entry in self._pending.values() if now - entry[1] >= self.resend]
            for entry in due:
                entry[1] = now
        for data, _ in due:
            self._pub["contacts"].put(data)
            self.sent["resent"] += 1

    def flush(self, timeout: float = FLUSH_TIMEOUT) -> int:
        """Re-send until a map acknowledges every contact or ``timeout`` s pass.

        Returns
        -------
        int
            Contacts still unacknowledged (0 without ``resend``).
        """
        if self.resend is None or self._closed:
            return 0
        end = time.monotonic() + timeout
        while self.unacknowledged and time.monotonic() < end:
            self._resend_due()
            time.sleep(0.05)
        return self.unacknowledged

    def publish_temperature(self, times: np.ndarray, temperature: np.ndarray,
                            host_times: np.ndarray) -> None:
        """Send a block of samples."""
        if not self._closed:
            self._resend_due()
            self._pub["temperature"].put(temperature_payload(
                self.layout, self.robot, times, temperature, host_times, self._taxels_json))

    def publish_contact(self, result: ContactResult) -> None:
        """Send a contact result."""
        if not self._closed:
            msg = contact_payload(result, self.layout, self.robot)
            if msg["link"] in self.link_poses:
                msg["link_pose"] = self.link_poses[msg["link"]]
            if self.robot_pose is not None:
                msg["robot_pose"] = self.robot_pose
            data = json.dumps(msg).encode()
            if self.resend is not None:
                onset = msg["host_onset"] if msg["host_onset"] is not None else msg["onset"]
                with self._lock:
                    self._pending[(msg["contact"], round(float(onset), 6))] = [
                        data, time.monotonic()]
                    while len(self._pending) > MAX_PENDING:
                        self._pending.pop(next(iter(self._pending)))
                        self.sent["dropped_unacknowledged"] += 1
            self._pub["contacts"].put(data)
            self._resend_due()

    def publish_health(self, payload: dict[str, Any]) -> None:
        """Send a health payload."""
        if not self._closed:
            self._pub["health"].put(json.dumps(payload).encode())

    def close(self) -> None:
        """Undeclare the publishers and close the session (idempotent)."""
        if self._closed:
            return
        left = self.flush()
        if left:
            self.sent["unacknowledged_at_close"] = left
        self._closed = True
        if self._acks is not None:
            self._acks.undeclare()
        for pub in self._pub.values():
            pub.undeclare()
        self._session.close()

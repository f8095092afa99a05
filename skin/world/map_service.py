"""The shared map service on Zenoh (``skin map serve``): contacts in, voxels and acks out.

It subscribes to ``<prefix>/*/contacts`` (the ``thermoskin.contact`` payloads of every robot's
`skin.stream.publish_zenoh.ZenohPublisher`), fuses them into a `skin.world.map_store.MapStore`
in batches (one transaction per batch, on disk before anything is acknowledged) and answers
queries:

==============================================  ===============================================
selector                                        reply (one JSON document)
==============================================  ===============================================
``<prefix>/map/voxels?box=x0,y0,z0,x1,y1,z1``   ``thermoskin.map_voxels``: ``voxels`` (each
``[;material=M][;family=F][;limit=N]``          with cell, center, label, confidence, family,
                                                posterior, contacts, first/last seen, robots),
                                                ``count``, ``truncated`` (more than
                                                `MAX_VOXELS` in the box: the first in key
                                                order)
``<prefix>/map/acks?robot=R[;since=T]``         ``thermoskin.map_acks``: ``contacts``, rows of
                                                ``[contact, onset, final]`` stored for robot R
                                                (``since``: stored at or after Unix time T)
``<prefix>/map/stats``                          ``thermoskin.map_stats``: voxels, contacts per
                                                robot, malformed payloads, voxel size
==============================================  ===============================================

Robots that move publish their base pose on ``<prefix>/<robot>/pose``
(`skin.world.robot_poses`): a contact is then placed with the pose that held at its
``host_onset`` (the static ``robot_pose`` a contact carries is the fallback for a robot that
publishes none). Pose updates and contacts are handled in the order they arrive, and the two
topics are not ordered between them: a contact is placed with the poses that have arrived
before it (a robot's contacts that come before its first pose use its static pose).

A bad selector gets an error reply naming the problem. Acknowledgements are also pushed: after
each committed batch, ``<prefix>/map/acks/<robot>`` carries ``thermoskin.map_ack`` with
``contacts`` (``[contact, onset]`` rows of that robot just stored or already held) and
``stored_at``. ``onset`` is the contact's ``host_onset`` (its ``onset`` when it has none), the
key that makes a contact re-sent after a reconnect count once. A payload that is not JSON or
not a usable contact is counted (``malformed``), logged with its key and reason, and skipped.
"""

from __future__ import annotations

import json
import logging
import queue
import sqlite3
import threading
import time
from pathlib import Path
from typing import Any

from skin.errors import SkinError
from skin.world.map_store import MapInputError, MapStore, Placed, place
from skin.world.robot_poses import RobotPoses, parse_pose

log = logging.getLogger(__name__)
VERSION = 1
#: Most voxels one reply carries; a larger box's reply says ``"truncated": true``.
MAX_VOXELS = 200_000


def _payload(schema: str, **fields: Any) -> bytes:
    return json.dumps({"schema": schema, "version": VERSION, **fields},
                      separators=(",", ":")).encode()


class MapService:
    """Run the map service (see the module docstring) until `close`.

    Parameters
    ----------
    db : str or Path
        The SQLite file (created if missing).
    prefix : str
        Key prefix of the robots' publishers (``thermoskin``).
    listen, connect : list of str
        Zenoh endpoints (multicast scouting off when any is given).
    mode : str, optional
        ``peer`` or ``client``.
    voxel : float, optional
        Voxel side of a new map, m.
    threshold : float, optional
        Posterior a material, else a family, needs to be named (a new map's; default 0.5).
    synchronous : str
        ``FULL``: a contact is on disk (fsync) before it is acknowledged; ``NORMAL``: it
        survives the service being killed, not a power cut, and spares the fsync's stalls.
    """

    def __init__(self, db: str | Path, prefix: str = "thermoskin",
                 listen: list[str] | None = None, connect: list[str] | None = None,
                 mode: str | None = None, voxel: float | None = None,
                 threshold: float | None = None, synchronous: str = "FULL") -> None:
        from skin.stream.publish_zenoh import open_session

        if str(db) == ":memory:":
            raise SkinError("the map service needs a database file, not :memory:")
        self.prefix = prefix.strip("/") or "thermoskin"
        self.store = MapStore(db, voxel=voxel, threshold=threshold, synchronous=synchronous)
        self.reader = MapStore(db)  # queries read beside the writer (WAL)
        self._read_lock = threading.Lock()
        self.malformed = 0
        self.received = 0
        self.duplicates = 0
        self.store_errors = 0
        self.poses = RobotPoses()
        self.pose_updates = 0
        self._inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._stop = threading.Event()
        self._session = open_session(listen, connect, mode)
        self._ack_pubs: dict[str, Any] = {}
        self._writer = threading.Thread(target=self._write_loop, name="map-writer", daemon=True)
        self._writer.start()
        self._sub = self._session.declare_subscriber(
            f"{self.prefix}/*/contacts",
            lambda s: self._inbox.put((str(s.key_expr), s.payload.to_bytes())))
        self._pose_sub = self._session.declare_subscriber(
            f"{self.prefix}/*/pose",
            lambda s: self._inbox.put((str(s.key_expr), s.payload.to_bytes())))
        self._queryable = self._session.declare_queryable(f"{self.prefix}/map/**", self._answer)

    # ---- contacts in ----

    def _write_loop(self) -> None:
        while not self._stop.is_set() or not self._inbox.empty():
            try:
                first = self._inbox.get(timeout=0.05)
            except queue.Empty:
                continue
            batch = [first]
            while len(batch) < 2000:
                try:
                    batch.append(self._inbox.get_nowait())
                except queue.Empty:
                    break
            try:
                self._store(batch)
            except sqlite3.Error as exc:  # a full disk, a locked file: nothing acknowledged
                self.store_errors += 1
                log.error("could not store %d contact payloads (not acknowledged): %s",
                          len(batch), exc)

    def _store(self, batch: list[tuple[str, bytes]]) -> None:
        placed: list[Placed] = []
        for key, data in batch:
            if key.endswith("/pose"):
                self._pose_update(key, data)
                continue
            self.received += 1
            try:
                msg = json.loads(data)
                robot = key.split("/")[-2]
                onset = msg.get("host_onset") if isinstance(msg, dict) else None
                if robot in self.poses and isinstance(onset, int | float):
                    msg["robot_pose"] = self.poses.at(robot, float(onset))
                p = place(msg, self.store.voxel)
                if key.split("/")[-2] != p.robot:
                    raise MapInputError(f"robot {p.robot!r} published on another robot's key")
            except (ValueError, MapInputError) as exc:
                self.malformed += 1
                log.warning("%s: skipped a malformed contact payload: %s", key, exc)
                continue
            placed.append(p)
        if not placed:
            return
        result = self.store.add_many(placed)  # committed (on disk) when it returns
        self.duplicates += result.duplicates
        stored_at = time.time()
        by_robot: dict[str, list[list[float]]] = {}
        for p in placed:  # duplicates are acknowledged too: the map holds them
            by_robot.setdefault(p.robot, []).append([p.contact, p.onset])
        for robot, rows in by_robot.items():
            pub = self._ack_pubs.get(robot)
            if pub is None:
                pub = self._ack_pubs[robot] = self._session.declare_publisher(
                    f"{self.prefix}/map/acks/{robot}")
            pub.put(_payload("thermoskin.map_ack", robot=robot, contacts=rows,
                             stored_at=round(stored_at, 6)))

    def _pose_update(self, key: str, data: bytes) -> None:
        try:
            robot, host_time, pose = parse_pose(json.loads(data))
            if key.split("/")[-2] != robot:
                raise MapInputError(f"robot {robot!r} published on another robot's key")
        except (ValueError, MapInputError) as exc:
            self.malformed += 1
            log.warning("%s: skipped a malformed pose payload: %s", key, exc)
            return
        self.poses.add(robot, host_time, pose)
        self.pose_updates += 1

    # ---- queries ----

    def _answer(self, query: Any) -> None:
        key = str(query.key_expr)
        params = query.parameters
        what = key[len(self.prefix) + len("/map/"):] if key.startswith(self.prefix) else ""
        try:
            with self._read_lock:
                body = self.answer(what, {k: params.get(k) for k in
                                          ("box", "material", "family", "limit", "robot",
                                           "since") if params.get(k) is not None})
        except SkinError as exc:
            query.reply_err(_payload("thermoskin.map_error", error=str(exc)))
            return
        except Exception as exc:  # a query must never take the service down
            log.exception("%s: query failed", key)
            query.reply_err(_payload("thermoskin.map_error", error=f"internal error: {exc}"))
            return
        query.reply(key, body)

    def answer(self, what: str, params: dict[str, str]) -> bytes:
        """Return the reply to a query of ``<prefix>/map/<what>`` with these parameters.

        Raises
        ------
        SkinError
            An unknown key or a missing or malformed parameter, named.
        """
        if what == "voxels":
            if "box" not in params:
                raise SkinError("map/voxels needs box=x0,y0,z0,x1,y1,z1 (m)")
            limit = params.get("limit")
            if limit is not None and (not limit.isdigit() or int(limit) < 1):
                raise SkinError(f"limit={limit!r}: a positive integer expected")
            cap = min(MAX_VOXELS, int(limit)) if limit is not None else MAX_VOXELS
            ask = {"material": params.get("material"), "family": params.get("family")}
            text = self.reader.query_json(params["box"], limit=cap + 1, **ask)
            count = text.count('{"cell":')  # one per voxel (a key inside a string is escaped)
            truncated = count > cap and limit is None
            if count > cap:
                text = self.reader.query_json(params["box"], limit=cap, **ask)
                count = cap
            head = _payload("thermoskin.map_voxels", voxel=self.reader.voxel, count=count,
                            truncated=truncated)
            return head[:-1] + b',"voxels":' + text.encode() + b"}"
        if what == "acks":
            robot = params.get("robot")
            if not robot:
                raise SkinError("map/acks needs robot=NAME")
            try:
                since = float(params["since"]) if "since" in params else None
            except ValueError:
                raise SkinError(f"since={params['since']!r}: a Unix time expected") from None
            rows = self.reader.acks(robot, since)
            return _payload("thermoskin.map_acks", robot=robot, count=len(rows), contacts=rows)
        if what == "stats":
            return _payload("thermoskin.map_stats", **self.reader.stats(),
                            received=self.received, malformed=self.malformed,
                            pose_updates=self.pose_updates,
                            duplicates=self.duplicates, store_errors=self.store_errors)
        raise SkinError(f"unknown map key {what!r} (keys: voxels, acks, stats)")

    def close(self) -> None:
        """Store what has arrived, then undeclare and close (idempotent)."""
        if self._stop.is_set():
            return
        self._sub.undeclare()
        self._pose_sub.undeclare()
        self._queryable.undeclare()
        self._stop.set()
        self._writer.join()
        for pub in self._ack_pubs.values():
            pub.undeclare()
        self._session.close()
        self.store.close()
        self.reader.close()

    def __enter__(self) -> MapService:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

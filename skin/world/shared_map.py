"""`SharedMap`: the Python API of the shared material map, over Zenoh or on its database file.

>>> m = SharedMap("zenoh://thermoskin?connect=tcp/127.0.0.1:7447")   # doctest: +SKIP
>>> m.query("0,0,0,1,1,1", material="aluminium")                    # doctest: +SKIP

``SharedMap(URL)`` asks the map service (`skin.world.map_service`, ``skin map serve``) over
Zenoh: ``zenoh://[PREFIX][?connect=...&listen=...&mode=...]`` (endpoints comma separated, as
for the publishers); ``SharedMap(PATH)`` reads a map database directly (a ``.sqlite`` file the
service writes; reading while it runs is safe). Both answer with the same dicts.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from skin.errors import SkinError


class SharedMap:
    """A shared map, remote (``zenoh://...``) or a database file (see the module docstring).

    Parameters
    ----------
    where : str or Path
        ``zenoh://[PREFIX][?connect=&listen=&mode=]`` or the path of a map database.
    timeout : float
        Seconds a Zenoh query waits for the service.
    """

    def __init__(self, where: str | Path, timeout: float = 5.0) -> None:
        self.where = str(where)
        self.timeout = float(timeout)
        self._session: Any = None
        self._store: Any = None
        parts = urlsplit(self.where)
        if parts.scheme == "zenoh":
            from skin.stream.publish_zenoh import open_session

            query = {k: v[-1] for k, v in parse_qs(parts.query).items()}
            unknown = set(query) - {"listen", "connect", "mode"}
            if unknown:
                raise SkinError(f"{self.where}: unknown option(s) {sorted(unknown)} (known: "
                                "connect, listen, mode)")
            self.prefix = (parts.netloc + parts.path).strip("/") or "thermoskin"

            def endpoints(key: str) -> list[str]:
                return [e for e in query.get(key, "").split(",") if e]

            self._session = open_session(endpoints("listen"), endpoints("connect"),
                                         query.get("mode"))
        elif "://" in self.where:
            raise SkinError(f"{self.where}: a map is zenoh://PREFIX or a database file")
        else:
            from skin.world.map_store import MapStore

            if not Path(self.where).is_file():
                raise SkinError(f"{self.where}: no such map database")
            self._store = MapStore(self.where)

    def _get(self, what: str, params: dict[str, Any]) -> dict[str, Any]:
        if self._store is not None:
            from skin.world.map_store import parse_box

            if what == "voxels":
                voxels = json.loads(self._store.query_json(
                    parse_box(params["box"]), params.get("material"), params.get("family"),
                    params.get("limit")))
                return {"schema": "thermoskin.map_voxels", "voxel": self._store.voxel,
                        "voxels": voxels}
            if what == "acks":
                rows = self._store.acks(params["robot"], params.get("since"))
                return {"schema": "thermoskin.map_acks", "robot": params["robot"],
                        "count": len(rows), "contacts": rows}
            return {"schema": "thermoskin.map_stats", **self._store.stats()}
        text = ";".join(f"{k}={v}" for k, v in params.items() if v is not None)
        selector = f"{self.prefix}/map/{what}" + (f"?{text}" if text else "")
        replies = list(self._session.get(selector, timeout=self.timeout))
        for reply in replies:
            if reply.ok is not None:
                return json.loads(reply.ok.payload.to_bytes())
            err = reply.err.payload.to_bytes()
            try:
                message = json.loads(err)["error"]
            except (ValueError, KeyError, TypeError):
                message = err.decode(errors="replace")
            raise SkinError(f"{selector}: {message}")
        raise SkinError(f"{selector}: no map service answered in {self.timeout:g} s "
                        f"({self.where}; is `skin map serve` running and reachable?)")

    def query(self, box: str | Any, material: str | None = None, family: str | None = None,
              limit: int | None = None) -> list[dict[str, Any]]:
        """Return the voxels in a box (``x0,y0,z0,x1,y1,z1``, m, map frame), with their labels.

        Each voxel: ``cell``, ``center`` (m), ``label``, ``confidence``, ``family``,
        ``family_confidence``, ``posterior``, ``contacts``, ``first_seen``, ``last_seen``
        (Unix s), ``robots``. ``material``/``family`` keep the voxels named so.

        Raises
        ------
        SkinError
            A malformed box, a service that does not answer, or its error reply.
        """
        from skin.world.map_store import parse_box

        b = parse_box(box)  # checked here, before anything is sent
        reply = self._get("voxels", {"box": ",".join(repr(v) for v in b), "material": material,
                                     "family": family, "limit": limit})
        if reply.get("truncated"):
            raise SkinError(f"box {','.join(f'{v:g}' for v in b)} holds more than "
                            f"{reply['count']} voxels: ask a smaller box or give a limit")
        return reply["voxels"]

    def acks(self, robot: str, since: float | None = None) -> list[list[Any]]:
        """Return ``[contact, onset, final]`` of every contact of ``robot`` the map holds."""
        return self._get("acks", {"robot": robot, "since": since})["contacts"]

    def stats(self) -> dict[str, Any]:
        """Return voxels, contacts per robot and the voxel size (and the service's counters)."""
        return self._get("stats", {})

    def close(self) -> None:
        """Close the session or the database (idempotent)."""
        if self._session is not None:
            self._session.close()
            self._session = None
        if self._store is not None:
            self._store.close()
            self._store = None

    def __enter__(self) -> SharedMap:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

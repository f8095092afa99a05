"""The shared material map's store: a sparse voxel grid of material evidence in SQLite.

Each contact (a ``thermoskin.contact`` payload of `skin.stream.publish`, from any robot) is
placed in the map's frame and fused into the voxel (cube of side ``voxel`` m, 1 cm by default)
that holds its centroid::

    world = robot_pose (robot base in the map frame) @ link_pose (link in the robot base) @ centroid

``robot_pose`` and ``link_pose`` are 4x4 row-major lists the publisher adds to the payload
(`skin.stream.publish.contact_payload`: the skin file's ``robot_pose`` and the link's pose in
its chain standing still); without them the robot stands at the map's origin and the link is
looked up in the default arm (`skin.world.kinematics.default_chain`) at its default angles. A
contact whose link has no pose is refused (`MapInputError`) rather than placed somewhere wrong.

Each voxel keeps, per material, the sum of ``log max(p, FLOOR)`` of its contacts'
``probabilities`` and how many contacts named it (table ``evidence``, JSON material: [sum,
count], apart from the voxel rows queries read); a contact that did not name a material
counts it at `FLOOR`. The posterior is the softmax of those sums (each contact a likelihood
under a uniform prior, contacts treated as independent: repeated touches of one object make it
confident quickly), named with
`skin.models.materials.hierarchical_answer` when the voxel is written: the material if its
posterior reaches ``threshold``, else its family, else ``"unknown"`` (as a voxel no contact
gave probabilities for). Besides, first and last seen (the contacts' host onset, Unix s), the
contact count and the robots that touched it.

A contact is counted once: its key is (robot, contact id, onset: host time if given, else
device time), so a contact re-sent after a reconnect is a duplicate; a final result replaces
the provisional one of the same contact (its evidence is taken back first).

SQLite: WAL journal, ``synchronous=FULL``: `MapStore.add_many` returns once its transaction is
on disk, so a contact acknowledged after it survives a SIGKILL (and a power cut). Voxels are
found by integer keys through an R*Tree (``rtree_i32``) when SQLite has one, else through the
composite unique index on (ix, iy, iz).
"""

from __future__ import annotations

import json
import math
import sqlite3
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from skin.errors import SkinError

#: Version of the database layout (table ``meta``, key ``format``).
FORMAT = "thermoskin.map_store/1"
#: Probabilities below this count as this (payloads round them to 4 decimals).
FLOOR = 1e-4
_LOG_FLOOR = math.log(FLOOR)


class MapStoreError(SkinError):
    """The map database cannot be opened or is not a map of this library."""


class MapInputError(SkinError):
    """A contact payload the map cannot use; the message names the field."""


@dataclass(frozen=True)
class Placed:
    """A contact ready to fuse: its key, voxel, evidence and times."""

    robot: str
    contact: int
    onset: float
    final: bool
    decided_at: float
    cell: tuple[int, int, int]
    position: tuple[float, float, float]
    logp: dict[str, float]
    host_decided_at: float | None = None
    robot_pose: list[list[float]] | None = None


@dataclass
class AddResult:
    """What `MapStore.add_many` did with a batch."""

    stored: list[Placed] = field(default_factory=list)
    replaced: int = 0
    duplicates: int = 0


def _pose(value: Any, where: str) -> np.ndarray:
    try:
        m = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        m = np.zeros(0)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise MapInputError(f"{where}: must be a 4x4 matrix of finite numbers")
    r = m[:3, :3]
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-4) or not np.allclose(m[3], [0, 0, 0, 1]):
        raise MapInputError(f"{where}: not a rigid transform")
    return m


_DEFAULT_LINKS: dict[str, np.ndarray] | None = None


def _default_link_pose(link: str) -> np.ndarray | None:
    global _DEFAULT_LINKS
    if _DEFAULT_LINKS is None:
        from skin.world.kinematics import default_chain

        _DEFAULT_LINKS = default_chain().poses()
    return _DEFAULT_LINKS.get(link)


def _number(msg: Mapping[str, Any], key: str, optional: bool = False) -> float | None:
    value = msg.get(key)
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise MapInputError(f"field {key!r} must be a finite number (got {value!r})")
    return float(value)


def place(msg: Mapping[str, Any], voxel: float) -> Placed:
    """Check a ``thermoskin.contact`` payload and place it in a voxel of side ``voxel`` m.

    Raises
    ------
    MapInputError
        Naming the field that is missing or malformed, or the link that has no pose.
    """
    if not isinstance(msg, Mapping):
        raise MapInputError("a contact payload must be a JSON object")
    if msg.get("schema") != "thermoskin.contact":
        raise MapInputError(f"not a thermoskin.contact payload (schema {msg.get('schema')!r})")
    robot = msg.get("robot")
    if not isinstance(robot, str) or not robot or not all(c.isalnum() or c in "-_"
                                                          for c in robot):
        raise MapInputError(f"field 'robot' must be a name of letters, digits, - and _ "
                            f"(got {robot!r})")
    contact = msg.get("contact")
    if isinstance(contact, bool) or not isinstance(contact, int):
        raise MapInputError(f"field 'contact' must be an integer (got {contact!r})")
    host_onset = _number(msg, "host_onset", optional=True)
    onset = host_onset if host_onset is not None else _number(msg, "onset")
    centroid = msg.get("centroid")
    try:
        c = np.asarray(centroid, dtype=float)
    except (TypeError, ValueError):
        c = np.zeros(0)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise MapInputError(f"field 'centroid' must be 3 finite numbers (got {centroid!r})")
    link = msg.get("link")
    if "link_pose" in msg and msg["link_pose"] is not None:
        link_pose = _pose(msg["link_pose"], "field 'link_pose'")
    else:
        found = _default_link_pose(link) if isinstance(link, str) else None
        if found is None:
            raise MapInputError(f"link {link!r} has no pose: the payload has no 'link_pose' "
                                "and the default arm has no such link")
        link_pose = found
    given = msg.get("robot_pose") is not None
    robot_pose = _pose(msg["robot_pose"], "field 'robot_pose'") if given else np.eye(4)
    world = robot_pose @ link_pose @ np.append(c, 1.0)
    cell = tuple(math.floor(float(v) / voxel) for v in world[:3])
    if any(abs(k) >= 2**31 - 1 for k in cell):
        raise MapInputError(f"position {world[:3].tolist()} is outside the map's range")
    probs = msg.get("probabilities") or {}
    if not isinstance(probs, Mapping):
        raise MapInputError("field 'probabilities' must be an object of material: probability")
    logp: dict[str, float] = {}
    for name, p in probs.items():
        if (isinstance(p, bool) or not isinstance(p, int | float) or not 0.0 <= p <= 1.0
                or not math.isfinite(p)):
            raise MapInputError(f"probability of {name!r} must be a number in [0, 1] (got {p!r})")
        logp[str(name)] = math.log(max(float(p), FLOOR))
    decided = _number(msg, "decided_at", optional=True)
    return Placed(robot=robot, contact=contact, onset=round(float(onset), 6),
                  final=bool(msg.get("final", True)),
                  decided_at=0.0 if decided is None else decided, cell=cell,  # type: ignore[arg-type]
                  position=tuple(float(v) for v in world[:3]),  # type: ignore[arg-type]
                  logp=logp, host_decided_at=_number(msg, "host_decided_at", optional=True),
                  robot_pose=robot_pose.tolist() if given else None)


_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS voxels (
    id INTEGER PRIMARY KEY, ix INTEGER NOT NULL, iy INTEGER NOT NULL, iz INTEGER NOT NULL,
    contacts INTEGER NOT NULL, informed INTEGER NOT NULL,
    first_seen REAL NOT NULL, last_seen REAL NOT NULL, robots TEXT NOT NULL,
    label TEXT NOT NULL, confidence REAL NOT NULL, family TEXT NOT NULL,
    family_confidence REAL NOT NULL, posterior TEXT NOT NULL,
    UNIQUE (ix, iy, iz));
CREATE TABLE IF NOT EXISTS evidence (voxel INTEGER PRIMARY KEY, evidence TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS contacts (
    robot TEXT NOT NULL, contact INTEGER NOT NULL, onset REAL NOT NULL, final INTEGER NOT NULL,
    decided_at REAL NOT NULL, voxel INTEGER NOT NULL, logp TEXT NOT NULL,
    host_decided_at REAL, stored_at REAL NOT NULL,
    PRIMARY KEY (robot, contact, onset)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS robots (
    robot TEXT PRIMARY KEY, pose TEXT, last_seen REAL NOT NULL) WITHOUT ROWID;
"""


@dataclass(frozen=True)
class Voxel:
    """One voxel of a query's answer (see `MapStore.query`)."""

    cell: tuple[int, int, int]
    center: tuple[float, float, float]
    label: str
    confidence: float
    family: str
    family_confidence: float
    posterior: dict[str, float]
    contacts: int
    first_seen: float
    last_seen: float
    robots: list[str]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {"cell": list(self.cell), "center": [round(v, 5) for v in self.center],
                "label": self.label, "confidence": round(self.confidence, 4),
                "family": self.family, "family_confidence": round(self.family_confidence, 4),
                "posterior": self.posterior,
                "contacts": self.contacts, "first_seen": self.first_seen,
                "last_seen": self.last_seen, "robots": self.robots}


def parse_box(text: str | Sequence[float]) -> tuple[float, ...]:
    """Parse ``x0,y0,z0,x1,y1,z1`` (m, map frame) into a box with its corners in order.

    Raises
    ------
    SkinError
        Naming the box and what is wrong with it.
    """
    try:
        values = ([float(v) for v in text.split(",")] if isinstance(text, str)
                  else [float(v) for v in text])
    except ValueError:
        raise SkinError(f"box {text!r}: six numbers x0,y0,z0,x1,y1,z1 (m) expected") from None
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise SkinError(f"box {text!r}: six finite numbers x0,y0,z0,x1,y1,z1 (m) expected")
    lo = [min(values[i], values[i + 3]) for i in range(3)]
    hi = [max(values[i], values[i + 3]) for i in range(3)]
    return (*lo, *hi)


class MapStore:
    """The voxel map in one SQLite file (see the module docstring).

    Parameters
    ----------
    path : str or Path
        The database; created if missing (``":memory:"`` for a throw-away map).
    voxel : float, optional
        Voxel side, m; a new map's default is 0.01. An existing map keeps its own and refuses
        a different one.
    threshold : float, optional
        Posterior a material (else a family) needs to be named; a new map's default is 0.5,
        kept with the map like the voxel size (each voxel is named as it is written).
    synchronous : str
        SQLite's ``synchronous`` (``FULL``: a commit is on disk when it returns; ``NORMAL``:
        it survives the process being killed, not a power cut).
    """

    def __init__(self, path: str | Path, voxel: float | None = None,
                 threshold: float | None = None, synchronous: str = "FULL") -> None:
        if voxel is not None and not (voxel > 0 and math.isfinite(voxel)):
            raise MapStoreError(f"voxel size {voxel!r}: a positive number of metres expected")
        if threshold is not None and not 0.0 < threshold <= 1.0:
            raise MapStoreError(f"threshold {threshold!r}: a probability in (0, 1] expected")
        if str(synchronous).upper() not in ("OFF", "NORMAL", "FULL", "EXTRA"):
            raise MapStoreError(f"synchronous {synchronous!r}: OFF, NORMAL, FULL or EXTRA")
        self.path = str(path)
        self.threshold = 0.5 if threshold is None else float(threshold)
        if self.path != ":memory:" and not Path(self.path).parent.is_dir():
            raise MapStoreError(f"{self.path}: no such folder {Path(self.path).parent}")
        try:
            self.db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.execute(f"PRAGMA synchronous={str(synchronous).upper()}")
            meta = self._meta()
        except sqlite3.DatabaseError as exc:
            raise MapStoreError(f"{self.path}: not a map database ({exc})") from None
        if meta:
            if meta.get("format") != FORMAT:
                raise MapStoreError(f"{self.path}: format {meta.get('format')!r}, this library "
                                    f"reads {FORMAT}")
            self.voxel = float(meta["voxel"])
            if voxel is not None and not math.isclose(voxel, self.voxel):
                raise MapStoreError(f"{self.path}: a map of {self.voxel} m voxels, not {voxel}")
            stored = float(meta.get("threshold", self.threshold))
            if threshold is not None and not math.isclose(threshold, stored):
                raise MapStoreError(f"{self.path}: a map naming materials at posterior "
                                    f"{stored}, not {threshold}")
            self.threshold = stored
        else:
            self.voxel = 0.01 if voxel is None else float(voxel)
        self.rtree = self._create(meta)
        try:  # SQLite's JSON functions (built in since 3.38, an option before)
            self.db.execute("SELECT json_group_array(json('{}'))").fetchone()
            self.json_sql = True
        except sqlite3.OperationalError:
            self.json_sql = False
        from skin.models.materials import load_materials

        self._materials = load_materials()

    def _meta(self) -> dict[str, str]:
        has = self.db.execute("SELECT 1 FROM sqlite_master WHERE name='meta'").fetchone()
        return dict(self.db.execute("SELECT key, value FROM meta")) if has else {}

    def _create(self, meta: dict[str, str]) -> bool:
        self.db.execute("BEGIN IMMEDIATE")
        for stmt in _SCHEMA.split(";"):
            if stmt.strip():
                self.db.execute(stmt)
        if not meta:
            self.db.executemany("INSERT INTO meta VALUES (?, ?)",
                                [("format", FORMAT), ("voxel", repr(self.voxel)),
                                 ("threshold", repr(self.threshold))])
        try:
            self.db.execute("CREATE VIRTUAL TABLE IF NOT EXISTS voxel_box USING "
                            "rtree_i32(id, x0, x1, y0, y1, z0, z1)")
            rtree = True
        except sqlite3.OperationalError:  # an SQLite built without R*Tree
            rtree = False
        self.db.execute("COMMIT")
        return rtree

    def close(self) -> None:
        """Close the database (idempotent)."""
        self.db.close()

    def __enter__(self) -> MapStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- writing ----

    def add(self, msg: Mapping[str, Any]) -> AddResult:
        """Place and fuse one contact payload (`place`; raises `MapInputError`)."""
        return self.add_many([place(msg, self.voxel)])

    def add_many(self, contacts: Iterable[Placed]) -> AddResult:
        """Fuse placed contacts in one transaction; return once it is on disk."""
        out = AddResult()
        now = time.time()
        db = self.db
        db.execute("BEGIN IMMEDIATE")
        try:
            for c in contacts:
                db.execute("INSERT INTO robots VALUES (?, ?, ?) ON CONFLICT(robot) DO UPDATE "
                           "SET pose=coalesce(excluded.pose, pose), last_seen=excluded.last_seen",
                           (c.robot, None if c.robot_pose is None else json.dumps(c.robot_pose),
                            now))
                old = db.execute("SELECT final, decided_at, voxel, logp FROM contacts WHERE "
                                 "robot=? AND contact=? AND onset=?",
                                 (c.robot, c.contact, c.onset)).fetchone()
                if old is not None:
                    final, decided, voxel, logp = old
                    if final or (not c.final and c.decided_at <= decided):
                        out.duplicates += 1
                        continue
                    self._fuse(voxel, json.loads(logp), -1)
                    db.execute("DELETE FROM contacts WHERE robot=? AND contact=? AND onset=?",
                               (c.robot, c.contact, c.onset))
                    out.replaced += 1
                voxel = self._voxel(c, now)
                self._fuse(voxel, c.logp, +1)
                db.execute("INSERT INTO contacts VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                           (c.robot, c.contact, c.onset, int(c.final), c.decided_at, voxel,
                            json.dumps(c.logp), c.host_decided_at, now))
                out.stored.append(c)
            db.execute("COMMIT")
        except BaseException:
            db.execute("ROLLBACK")
            raise
        return out

    def _voxel(self, c: Placed, now: float) -> int:
        ix, iy, iz = c.cell
        row = self.db.execute("SELECT id, robots FROM voxels WHERE ix=? AND iy=? AND iz=?",
                              (ix, iy, iz)).fetchone()
        seen = c.onset if c.onset > 1e8 else now  # device time only: the time it arrived
        if row is None:
            cur = self.db.execute("INSERT INTO voxels (ix, iy, iz, contacts, informed, "
                                  "first_seen, last_seen, robots, label, confidence, family, "
                                  "family_confidence, posterior) VALUES (?, ?, ?, 0, 0, "
                                  "?, ?, ?, 'unknown', 0, 'unknown', 0, '{}')",
                                  (ix, iy, iz, seen, seen, c.robot))
            vid = int(cur.lastrowid)  # type: ignore[arg-type]
            self.db.execute("INSERT INTO evidence VALUES (?, '{}')", (vid,))
            if self.rtree:
                self.db.execute("INSERT INTO voxel_box VALUES (?, ?, ?, ?, ?, ?, ?)",
                                (vid, ix, ix, iy, iy, iz, iz))
            return vid
        vid, robots = row
        names = robots.split(",")
        if c.robot not in names:
            robots = ",".join(sorted([*names, c.robot]))
        self.db.execute("UPDATE voxels SET first_seen=min(first_seen, ?), "
                        "last_seen=max(last_seen, ?), robots=? WHERE id=?",
                        (seen, seen, robots, vid))
        return int(vid)

    def _fuse(self, voxel: int, logp: Mapping[str, float], sign: int) -> None:
        """Add (``sign`` +1) or take back (-1) a contact's evidence; name the voxel anew."""
        from skin.models.materials import hierarchical_answer

        text, informed = self.db.execute(
            "SELECT e.evidence, v.informed FROM voxels AS v JOIN evidence AS e ON e.voxel = v.id "
            "WHERE v.id=?", (voxel,)).fetchone()
        evidence = json.loads(text)
        for name, value in logp.items():
            s, n = evidence.get(name, (0.0, 0))
            evidence[name] = [s + sign * value, n + sign]
        informed += sign * (1 if logp else 0)
        posterior = posterior_of({k: tuple(v) for k, v in evidence.items()}, informed)
        if posterior:
            answer = hierarchical_answer(posterior, self.threshold, self._materials)
        else:
            answer = ("unknown", 0.0, "unknown", 0.0)
        self.db.execute("UPDATE evidence SET evidence=? WHERE voxel=?",
                        (json.dumps(evidence), voxel))
        self.db.execute("UPDATE voxels SET contacts=contacts+?, informed=?, "
                        "label=?, confidence=?, family=?, family_confidence=?, posterior=? "
                        "WHERE id=?",
                        (sign, informed, *answer,
                         json.dumps({k: round(v, 6) for k, v in posterior.items()}), voxel))

    # ---- reading ----

    def stats(self) -> dict[str, Any]:
        """Return voxels, contacts (per robot), robot poses, the voxel size and the index."""
        robots = dict(self.db.execute("SELECT robot, count(*) FROM contacts GROUP BY robot"))
        return {"voxels": self.db.execute("SELECT count(*) FROM voxels").fetchone()[0],
                "contacts": sum(robots.values()), "robots": robots,
                "robot_poses": self.robot_poses(), "voxel": self.voxel,
                "index": "rtree" if self.rtree else "btree"}

    def robot_poses(self) -> dict[str, list[list[float]] | None]:
        """Return each robot's last pose in the map frame (4x4; None if it never sent one)."""
        return {r: None if p is None else json.loads(p)
                for r, p in self.db.execute("SELECT robot, pose FROM robots ORDER BY robot")}

    def acks(self, robot: str, since: float | None = None) -> list[list[float]]:
        """Return the stored contacts of a robot as ``[contact, onset, final]`` rows."""
        rows = self.db.execute("SELECT contact, onset, final FROM contacts WHERE robot=? AND "
                               "stored_at >= ? ORDER BY onset, contact",
                               (robot, -1.0 if since is None else since))
        return [[c, o, bool(f)] for c, o, f in rows]

    def cells(self, box: Sequence[float]) -> tuple[int, ...]:
        """Return the voxel keys bounding a box ``(x0, y0, z0, x1, y1, z1)`` (inclusive)."""
        v = self.voxel
        lo = [math.floor(x / v) for x in box[:3]]
        hi = [math.floor(x / v) for x in box[3:]]
        return (*lo, *hi)

    def query(self, box: str | Sequence[float], material: str | None = None,
              family: str | None = None, limit: int | None = None) -> list[Voxel]:
        """Return the voxels whose cells meet a box, with their posterior labels.

        Parameters
        ----------
        box : str or sequence of float
            ``x0,y0,z0,x1,y1,z1`` in the map frame, m (`parse_box`).
        material, family : str, optional
            Keep only voxels named this material (label) or of this family.
        limit : int, optional
            At most this many voxels (in key order).
        """
        v = self.voxel
        return [Voxel(cell=(ix, iy, iz), center=((ix + 0.5) * v, (iy + 0.5) * v, (iz + 0.5) * v),
                      label=label, confidence=conf, family=fam, family_confidence=fam_conf,
                      posterior=json.loads(posterior), contacts=contacts, first_seen=first,
                      last_seen=last, robots=robots.split(","))
                for (ix, iy, iz, contacts, first, last, robots, label, conf, fam, fam_conf,
                     posterior) in self.rows(box, material, family, limit)]

    def query_json(self, box: str | Sequence[float], material: str | None = None,
                   family: str | None = None, limit: int | None = None) -> str:
        """Return `query`'s voxels as a JSON array of `Voxel.as_dict` objects (text).

        Built by SQLite's JSON functions when it has them (what the service replies with),
        else from `rows` in Python.
        """
        if not self.json_sql:
            return self.rows_json(self.rows(box, material, family, limit))
        inner, args = self._select(box, material, family)
        sql = ("SELECT json_group_array(json_object('cell', json_array(ix, iy, iz), 'center', "
               "json_array(round((ix + 0.5) * ?, 5), round((iy + 0.5) * ?, 5), "
               "round((iz + 0.5) * ?, 5)), 'label', label, 'confidence', round(confidence, 4), "
               "'family', family, 'family_confidence', round(family_confidence, 4), "
               "'posterior', json(posterior), 'contacts', contacts, 'first_seen', first_seen, "
               "'last_seen', last_seen, 'robots', json('[\"' || replace(robots, ',', '\",\"') "
               f"|| '\"]'))) FROM ({inner} ORDER BY v.ix, v.iy, v.iz"
               + ("" if limit is None else f" LIMIT {int(limit)}") + ")")
        (text,) = self.db.execute(sql, [self.voxel] * 3 + args).fetchone()
        return text

    def _select(self, box: str | Sequence[float], material: str | None,
                family: str | None) -> tuple[str, list[Any]]:
        """Return the SELECT of the voxel rows in a box (named so) and its arguments."""
        b = parse_box(box)
        x0, y0, z0, x1, y1, z1 = self.cells(b)
        if self.rtree:
            within = ("SELECT id FROM voxel_box WHERE x1 >= ? AND x0 <= ? AND y1 >= ? "
                      "AND y0 <= ? AND z1 >= ? AND z0 <= ?")
        else:
            within = ("SELECT id FROM voxels WHERE ix BETWEEN ? AND ? AND iy BETWEEN ? AND ? "
                      "AND iz BETWEEN ? AND ?")
        where, args = ["v.contacts > 0"], [x0, x1, y0, y1, z0, z1]  # 0: a provisional moved
        if material is not None:
            where.append("v.label = ?")
            args.append(material)
        if family is not None:
            where.append("v.family = ?")
            args.append(family)
        return ("SELECT v.ix, v.iy, v.iz, v.contacts, v.first_seen, v.last_seen, v.robots, "
                "v.label, v.confidence, v.family, v.family_confidence, v.posterior FROM "
                f"({within}) AS b CROSS JOIN voxels AS v ON v.id = b.id "
                f"WHERE {' AND '.join(where)}", args)

    def rows(self, box: str | Sequence[float], material: str | None = None,
             family: str | None = None, limit: int | None = None) -> list[tuple]:
        """Return `query`'s voxels as rows (the posterior as JSON text), in key order.

        Each row: ix, iy, iz, contacts, first_seen, last_seen, robots (comma separated),
        label, confidence, family, family_confidence, posterior.
        """
        inner, args = self._select(box, material, family)
        rows = sorted(self.db.execute(inner, args).fetchall())
        return rows if limit is None else rows[:limit]

    def rows_json(self, rows: list[tuple]) -> str:
        """Return rows of `rows` as a JSON array of `Voxel.as_dict` objects, built as text."""
        v = self.voxel
        dumps = json.dumps
        parts = [
            f'{{"cell":[{ix},{iy},{iz}],"center":[{round((ix + 0.5) * v, 5)!r},'
            f'{round((iy + 0.5) * v, 5)!r},{round((iz + 0.5) * v, 5)!r}],'
            f'"label":{dumps(label)},"confidence":{round(conf, 4)!r},"family":{dumps(fam)},'
            f'"family_confidence":{round(fam_conf, 4)!r},"posterior":{posterior},'
            f'"contacts":{contacts},"first_seen":{first!r},"last_seen":{last!r},'
            f'"robots":{dumps(robots.split(","))}}}'
            for (ix, iy, iz, contacts, first, last, robots, label, conf, fam, fam_conf,
                 posterior) in rows]
        return "[" + ",".join(parts) + "]"


def posterior_of(evidence: Mapping[str, tuple[float, int]], n_evid: int) -> dict[str, float]:
    """Return the posterior over materials from (summed log p, count) of ``n_evid`` contacts.

    A contact that did not name a material counts it at `FLOOR`. Empty when no contact gave
    probabilities.
    """
    if n_evid <= 0 or not evidence:
        return {}
    names = sorted(m for m in evidence if evidence[m][1] > 0)
    if not names:
        return {}
    logs = np.array([evidence[m][0] + (n_evid - evidence[m][1]) * _LOG_FLOOR for m in names])
    logs -= logs.max()
    p = np.exp(logs)
    p /= p.sum()
    return {m: float(x) for m, x in zip(names, p, strict=True)}

"""The world material map: contacts as labelled points in the world frame.

Each contact (an ``events.jsonl`` record of `skin.stream.sinks.event_record`, or a `ContactResult`)
becomes one point per taxel: the taxel's position and normal in its link's frame (the layout),
carried to the world by the link's pose at the contact's onset time (`skin.world.kinematics`: a
chain standing still, joint angles over time, or link poses over time). Each point keeps the
contact's label, confidence, onset time and id, and its taxel id: the robot's memory of where
it touched metal, wood or a person.

A map is built from a run folder (``events.jsonl`` and the ``layout.toml`` and ``chain.toml``
that `skin run` writes beside it), from an MCAP recording (its events and layout), or live, as a
sink of the pipeline (`WorldMap.write`). It is saved as NPZ (plain arrays, read without
pickle) or JSON lines (one object per point) and loaded back with `WorldMap.load`.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from skin.errors import LayoutError, SkinError
from skin.formats.layout import Layout
from skin.world.kinematics import Chain, KinematicsError, as_pose_source, chain_toml

#: Version of the saved world map (NPZ key ``format`` / JSON field ``format``).
FORMAT = "thermoskin.world_map/1"
LAYOUT_FILE = "layout.toml"
CHAIN_FILE = "chain.toml"
_ARRAYS = ("points", "normals", "contact", "taxel", "link", "label", "confidence", "time")


class WorldMapError(SkinError):
    """A world map, or what it is built from, is malformed; the message names the file."""


class WorldMap:
    """Contacts as labelled points in the world frame, one point per taxel of a contact.

    Parameters
    ----------
    layout : Layout, optional
        The taxels (positions and normals in their link frames); needed to `add` contacts,
        not to hold or draw a loaded map.
    poses : Chain, pose track, dict of 4x4 arrays, or None
        Link poses (`skin.world.kinematics.as_pose_source`); None: the default chain standing still.
    final_only : bool
        Skip provisional results (``final`` false): their final answer follows.

    Attributes
    ----------
    points : numpy.ndarray
        (n, 3) world positions, m.
    normals : numpy.ndarray
        (n, 3) outward unit normals in the world frame.
    contact, taxel : numpy.ndarray
        Contact id and taxel id of each point (int).
    link : numpy.ndarray
        Link name of each point (str).
    label : numpy.ndarray
        Material label of each point's contact (str; ``"unknown"`` included).
    confidence : numpy.ndarray
        The classifier's confidence in that label, 0-1.
    time : numpy.ndarray
        Onset of the contact, s (the skin's clock): the time its poses were taken at.
    skipped : list of str
        Contacts that gave no points, and why (no pose at their onset time).
    notes : list of str
        What a builder (`from_run`, `from_recording`) assumed: which layout, which poses.
    """

    def __init__(self, layout: Layout | None = None, poses: Any = None, *,
                 final_only: bool = True) -> None:
        self.layout = layout
        self.poses = as_pose_source(poses)
        self.final_only = final_only
        self.skipped: list[str] = []
        self.notes: list[str] = []  # what a builder assumed (which layout, which poses)
        self._parts: list[dict[str, np.ndarray]] = []
        self._arrays: dict[str, np.ndarray] | None = _empty()

    # -- the arrays --

    def _data(self) -> dict[str, np.ndarray]:
        if self._arrays is None:
            self._arrays = {k: np.concatenate([p[k] for p in self._parts]) for k in _ARRAYS}
            self._parts = [self._arrays]
        return self._arrays

    @property
    def points(self) -> np.ndarray:
        """(n, 3) world positions, m."""
        return self._data()["points"]

    @property
    def normals(self) -> np.ndarray:
        """(n, 3) outward unit normals in the world frame."""
        return self._data()["normals"]

    @property
    def contact(self) -> np.ndarray:
        """Contact id of each point."""
        return self._data()["contact"]

    @property
    def taxel(self) -> np.ndarray:
        """Taxel id of each point."""
        return self._data()["taxel"]

    @property
    def link(self) -> np.ndarray:
        """Link name of each point."""
        return self._data()["link"]

    @property
    def label(self) -> np.ndarray:
        """Material label of each point (``"unknown"`` included)."""
        return self._data()["label"]

    @property
    def confidence(self) -> np.ndarray:
        """The classifier's confidence in each point's label, 0-1."""
        return self._data()["confidence"]

    @property
    def time(self) -> np.ndarray:
        """Onset of each point's contact, s (the skin's clock)."""
        return self._data()["time"]

    def __len__(self) -> int:
        return int(self._data()["points"].shape[0])

    def __repr__(self) -> str:
        return (f"WorldMap({len(self)} points, {len(np.unique(self.contact))} contacts, "
                f"{dict(self.counts())})")

    def counts(self) -> dict[str, int]:
        """Return the number of points per label, most first (ties by name)."""
        c = Counter(str(v) for v in self.label)
        return dict(sorted(c.items(), key=lambda kv: (-kv[1], kv[0])))

    def contacts(self) -> int:
        """Return the number of distinct contacts in the map."""
        return int(np.unique(self.contact).size)

    # -- building --

    def add(self, event: Mapping[str, Any] | Any, where: str = "") -> int:
        """Add a contact: one point per taxel, posed at the contact's onset.

        Parameters
        ----------
        event : dict or ContactResult
            An `event_record` dict (``contact``, ``taxels``, ``onset``, ``label``,
            ``confidence``, optional ``final``) or a `skin.stream.pipeline.ContactResult`.
        where : str
            Where the event came from (file and line), for messages.

        Returns
        -------
        int
            Points added (0 for a provisional result, or a contact with no pose at its onset,
            which is listed in `skipped`).

        Raises
        ------
        WorldMapError
            If the event is malformed, or the map has no layout.
        LayoutError
            If a taxel id is not in the layout.
        KinematicsError
            If a taxel's link has no pose.
        """
        if self.layout is None:
            raise WorldMapError("this world map has no layout (a loaded map): give one to add "
                                "contacts")
        rec = _event_fields(event, where or "event")
        if self.final_only and not rec["final"]:
            return 0
        try:
            poses = self.poses.poses_at(rec["onset"])
        except KinematicsError as exc:
            self.skipped.append(f"contact {rec['contact']} at {rec['onset']:g} s: {exc}")
            return 0
        try:
            idx = np.array([self.layout.index(t) for t in rec["taxels"]], dtype=np.int64)
        except LayoutError as exc:
            raise LayoutError(f"{where or 'event'}: {exc}") from None
        links = [self.layout.links[k] for k in idx]
        points = np.empty((idx.size, 3))
        normals = np.empty((idx.size, 3))
        for j, (k, link) in enumerate(zip(idx, links, strict=True)):
            pose = poses.get(link)
            if pose is None:
                raise KinematicsError(
                    f"{self.layout.source}: taxel {int(self.layout.ids[k])} is on link "
                    f"{link!r}, which has no pose (links with poses: "
                    f"{', '.join(sorted(poses)) or 'none'})")
            points[j] = pose[:3, :3] @ self.layout.positions[k] + pose[:3, 3]
            normals[j] = pose[:3, :3] @ self.layout.normals[k]
        n = idx.size
        self._parts.append({
            "points": points, "normals": normals,
            "contact": np.full(n, rec["contact"], dtype=np.int64),
            "taxel": self.layout.ids[idx].astype(np.int64),
            "link": np.array(links, dtype=str).reshape(n),
            "label": np.full(n, rec["label"], dtype=np.array([rec["label"]]).dtype),
            "confidence": np.full(n, rec["confidence"], dtype=float),
            "time": np.full(n, rec["onset"], dtype=float),
        })
        self._arrays = None
        return n

    def write(self, result: Any) -> None:
        """Add a pipeline result (the sink interface, `skin.stream.sinks`)."""
        self.add(result)

    @classmethod
    def from_events(cls, events: Iterable[Mapping[str, Any] | Any], layout: Layout,
                    poses: Any = None, *, final_only: bool = True,
                    source: str = "") -> WorldMap:
        """Build a map from event records or results.

        Parameters
        ----------
        events : iterable of dict or ContactResult
            The contacts.
        layout : Layout
            The layout the events' taxel ids belong to.
        poses : Chain, pose track, dict of 4x4 arrays, or None
            Link poses; None: the default chain standing still.
        final_only : bool
            Skip provisional results.
        source : str
            Where the events came from, for messages (each event is named ``source:#k``).

        Returns
        -------
        WorldMap
        """
        out = cls(layout, poses, final_only=final_only)
        for k, ev in enumerate(events):
            out.add(ev, where=f"{source or 'events'}: event #{k}")
        return out

    @classmethod
    def from_run(cls, folder: str | Path, poses: Any = None,
                 layout: Layout | None = None) -> WorldMap:
        """Build a map from a `skin run` output folder.

        It reads ``events.jsonl``; the layout is ``layout`` if given, else the folder's
        ``layout.toml``, else the shipped ``arm`` layout (runs from before the layout was
        saved); the poses are ``poses`` if given, else the folder's ``chain.toml`` standing
        still, else the default chain standing still. `notes` says which were used.

        Raises
        ------
        WorldMapError
            If the folder has no ``events.jsonl`` or a line of it is malformed (file:line).
        """
        from skin.formats.layout import load_layout
        from skin.world.kinematics import load_chain

        folder = Path(folder)
        events_path = folder / "events.jsonl"
        if not events_path.is_file():
            raise WorldMapError(f"{folder}: no events.jsonl: not the output folder of "
                                "`skin run`")
        notes = []
        if layout is None:
            if (folder / LAYOUT_FILE).is_file():
                layout = load_layout(folder / LAYOUT_FILE)
            else:
                layout = load_layout("arm")
                notes.append(f"no {LAYOUT_FILE} in {folder}: the shipped 'arm' layout")
        if poses is None:
            if (folder / CHAIN_FILE).is_file():
                poses = load_chain(folder / CHAIN_FILE)
                notes.append(f"poses: {folder / CHAIN_FILE} at its default angles")
            else:
                notes.append("poses: none saved with the run: the default chain at its "
                             "default angles")
        records = read_events(events_path)
        out = cls(layout, poses)
        for line, rec in records:
            out.add(rec, where=f"{events_path}:{line}")
        out.notes = notes
        return out

    @classmethod
    def from_recording(cls, path: str | Path, poses: Any = None,
                       layout: Layout | None = None) -> WorldMap:
        """Build a map from an MCAP recording: its events, and its layout unless ``layout``.

        Poses are ``poses`` if given, else the default chain standing still (a recording
        holds no poses).

        Raises
        ------
        WorldMapError
            If the recording has no layout and none is given.
        """
        from skin.drivers.recording import read_recording

        rec = read_recording(path)
        notes = []
        if layout is None:
            layout = rec.layout
            if layout is None:
                raise WorldMapError(f"{path}: the recording holds no layout: give one")
        if poses is None:
            notes.append("poses: none in the recording: the default chain at its default "
                         "angles")
        if rec.problem:
            notes.append(rec.problem)
        out = cls(layout, poses)
        for k, ev in enumerate(rec.events):
            out.add(ev, where=f"{path}: event #{k}")
        out.notes = notes
        return out

    # -- saving --

    def save(self, path: str | Path) -> Path:
        """Save to ``.npz`` (plain arrays) or ``.jsonl`` (one JSON object per point).

        Returns
        -------
        Path
            The file written.

        Raises
        ------
        WorldMapError
            For any other suffix.
        """
        path = Path(path)
        data = self._data()
        suffix = path.suffix.lower()
        if suffix == ".npz":
            with path.open("wb") as f:
                np.savez(f, format=np.array(FORMAT), **{
                    k: (v.astype(str) if v.dtype.kind == "U" else v) for k, v in data.items()})
        elif suffix in (".jsonl", ".json"):
            with path.open("w", encoding="utf-8") as f:
                for k in range(len(self)):
                    f.write(json.dumps({
                        "format": FORMAT,
                        "contact": int(data["contact"][k]), "taxel": int(data["taxel"][k]),
                        "link": str(data["link"][k]), "label": str(data["label"][k]),
                        "confidence": float(data["confidence"][k]),
                        "time": float(data["time"][k]),
                        "point": [float(v) for v in data["points"][k]],
                        "normal": [float(v) for v in data["normals"][k]],
                    }) + "\n")
        else:
            raise WorldMapError(f"{path}: a world map is saved as .npz or .jsonl")
        return path

    @classmethod
    def load(cls, path: str | Path) -> WorldMap:
        """Load a map saved by `save` (``.npz`` or ``.jsonl``); it has no layout.

        Raises
        ------
        WorldMapError
            If the file cannot be read or is not a world map (naming the file, line or key).
        """
        path = Path(path)
        if path.suffix.lower() == ".npz":
            arrays = _load_npz(path)
        elif path.suffix.lower() in (".jsonl", ".json"):
            arrays = _load_jsonl(path)
        else:
            raise WorldMapError(f"{path}: a world map is a .npz or .jsonl file")
        out = cls()
        out._parts = [arrays]
        out._arrays = arrays
        return out


def _empty() -> dict[str, np.ndarray]:
    return {"points": np.zeros((0, 3)), "normals": np.zeros((0, 3)),
            "contact": np.zeros(0, dtype=np.int64), "taxel": np.zeros(0, dtype=np.int64),
            "link": np.zeros(0, dtype="<U1"), "label": np.zeros(0, dtype="<U1"),
            "confidence": np.zeros(0), "time": np.zeros(0)}


def _event_fields(event: Mapping[str, Any] | Any, where: str) -> dict[str, Any]:
    """Return contact, taxels, onset, label, confidence and final of an event or result."""
    if not isinstance(event, Mapping):  # a ContactResult
        c, e = event.contact, event.estimate
        return {"contact": int(c.id), "taxels": [int(t) for t in c.taxels],
                "onset": float(c.onset), "label": str(e.label),
                "confidence": float(e.confidence), "final": bool(c.final)}
    for key in ("contact", "taxels", "onset", "label", "confidence"):
        if key not in event:
            raise WorldMapError(f"{where}: missing field {key!r}")
    taxels = event["taxels"]
    if not (isinstance(taxels, list) and taxels
            and all(isinstance(t, int) and not isinstance(t, bool) for t in taxels)):
        raise WorldMapError(f"{where}: field 'taxels' must be a non-empty list of taxel ids, "
                            f"got {taxels!r}")
    for key in ("onset", "confidence"):
        v = event[key]
        if not (isinstance(v, int | float) and not isinstance(v, bool) and np.isfinite(v)):
            raise WorldMapError(f"{where}: field {key!r} must be a finite number, got {v!r}")
    if not isinstance(event["label"], str):
        raise WorldMapError(f"{where}: field 'label' must be a string")
    if not isinstance(event["contact"], int):
        raise WorldMapError(f"{where}: field 'contact' must be an integer")
    return {"contact": event["contact"], "taxels": taxels, "onset": float(event["onset"]),
            "label": event["label"], "confidence": float(event["confidence"]),
            "final": bool(event.get("final", True))}


def read_events(path: str | Path) -> list[tuple[int, dict[str, Any]]]:
    """Read an ``events.jsonl`` file: (line number, record) per non-blank line.

    Raises
    ------
    WorldMapError
        Naming the file and line of a line that is not a JSON object.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise WorldMapError(f"{path}: cannot read: {exc.strerror}") from None
    out = []
    for line, raw in enumerate(text.splitlines(), start=1):
        if not raw.strip():
            continue
        try:
            rec = json.loads(raw)
        except ValueError as exc:
            raise WorldMapError(f"{path}:{line}: not JSON ({exc})") from None
        if not isinstance(rec, dict):
            raise WorldMapError(f"{path}:{line}: not a JSON object")
        out.append((line, rec))
    return out


def _check_arrays(arrays: dict[str, np.ndarray], src: str) -> dict[str, np.ndarray]:
    n = arrays["points"].shape[0] if arrays["points"].ndim == 2 else -1
    for key in ("points", "normals"):
        if arrays[key].shape != (n, 3) or not np.all(np.isfinite(arrays[key])):
            raise WorldMapError(f"{src}: {key!r} must be (n, 3) finite numbers, got shape "
                                f"{arrays[key].shape}")
    for key in ("contact", "taxel", "link", "label", "confidence", "time"):
        if arrays[key].shape != (n,):
            raise WorldMapError(f"{src}: {key!r} must have one value per point ({n}), got "
                                f"shape {arrays[key].shape}")
    return arrays


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as data:
            raw = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise WorldMapError(f"{path}: cannot read a world map (NPZ without pickled objects): "
                            f"{exc}") from None
    if str(raw.get("format", "")) != FORMAT:
        raise WorldMapError(f"{path}: not a world map (its 'format' is "
                            f"{str(raw.get('format', 'missing'))!r}, expected {FORMAT!r})")
    missing = [k for k in _ARRAYS if k not in raw]
    if missing:
        raise WorldMapError(f"{path}: missing array {missing[0]!r}")
    try:
        arrays = {
            "points": raw["points"].astype(float), "normals": raw["normals"].astype(float),
            "contact": raw["contact"].astype(np.int64), "taxel": raw["taxel"].astype(np.int64),
            "link": raw["link"].astype(str), "label": raw["label"].astype(str),
            "confidence": raw["confidence"].astype(float), "time": raw["time"].astype(float)}
    except (TypeError, ValueError) as exc:
        raise WorldMapError(f"{path}: an array of the wrong type: {exc}") from None
    return _check_arrays(arrays, str(path))


def _load_jsonl(path: Path) -> dict[str, np.ndarray]:
    cols: dict[str, list[Any]] = {k: [] for k in _ARRAYS}
    for line, rec in read_events(path):
        where = f"{path}:{line}"
        if rec.get("format") != FORMAT:
            raise WorldMapError(f"{where}: not a world-map point (its 'format' is "
                                f"{rec.get('format')!r}, expected {FORMAT!r})")
        try:
            point = [float(v) for v in rec["point"]]
            normal = [float(v) for v in rec["normal"]]
            if len(point) != 3 or len(normal) != 3:
                raise ValueError("'point' and 'normal' take 3 numbers")
            cols["points"].append(point)
            cols["normals"].append(normal)
            cols["contact"].append(int(rec["contact"]))
            cols["taxel"].append(int(rec["taxel"]))
            cols["link"].append(str(rec["link"]))
            cols["label"].append(str(rec["label"]))
            cols["confidence"].append(float(rec["confidence"]))
            cols["time"].append(float(rec["time"]))
        except KeyError as exc:
            raise WorldMapError(f"{where}: missing field {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise WorldMapError(f"{where}: {exc}") from None
    if not cols["points"]:
        return _empty()
    arrays = {
        "points": np.array(cols["points"], dtype=float).reshape(-1, 3),
        "normals": np.array(cols["normals"], dtype=float).reshape(-1, 3),
        "contact": np.array(cols["contact"], dtype=np.int64),
        "taxel": np.array(cols["taxel"], dtype=np.int64),
        "link": np.array(cols["link"], dtype=str), "label": np.array(cols["label"], dtype=str),
        "confidence": np.array(cols["confidence"], dtype=float),
        "time": np.array(cols["time"], dtype=float)}
    return _check_arrays(arrays, str(path))


def write_run_setup(folder: str | Path, layout: Layout, chain: Chain | None = None
                    ) -> dict[str, str]:
    """Write what a world map of a run needs beside its events: the layout and the chain.

    Parameters
    ----------
    folder : str or Path
        The run's output folder.
    layout : Layout
        The layout the run used (written as ``layout.toml``).
    chain : Chain, optional
        The arm's chain, standing still at its default angles during the run (written as
        ``chain.toml``); None when the run's poses are unknown (a device).

    Returns
    -------
    dict
        Entries for ``summary.json``: ``layout`` and, with a chain, ``chain`` (file names in
        the folder).
    """
    from skin.formats.layout import layout_toml

    folder = Path(folder)
    (folder / LAYOUT_FILE).write_text(layout_toml(layout), encoding="utf-8")
    out = {"layout": LAYOUT_FILE}
    if chain is not None:
        (folder / CHAIN_FILE).write_text(chain_toml(chain), encoding="utf-8")
        out["chain"] = CHAIN_FILE
    elif (folder / CHAIN_FILE).exists():  # a previous run's: not this one's poses
        (folder / CHAIN_FILE).unlink()
    return out

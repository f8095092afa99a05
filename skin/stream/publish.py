"""Live outputs: publishers that put the skin on the robot's network as it runs.

A publisher is a sink of the pipeline (`skin.stream.sinks`: ``write(result)`` for each contact
result) and an observer of its calibrated samples; `Publisher.attach` makes it both. One
function opens any of them by URL (``skin run --publish URL``, repeatable):

=============================  ==============================================================
URL                            publisher
=============================  ==============================================================
``zenoh://[PREFIX][?...]``     `skin.stream.publish_zenoh.ZenohPublisher` (eclipse-zenoh):
                               ``<PREFIX>/<robot>/temperature``, ``/contacts``, ``/health``;
                               query: ``robot=``, ``listen=``/``connect=`` endpoints (comma
                               separated, e.g. ``tcp/127.0.0.1:7447``), ``mode=`` peer|client,
                               ``resend=S``: re-send contacts a shared map service has not
                               acknowledged within S seconds
``foxglove://HOST:PORT``       `skin.stream.publish_foxglove.FoxglovePublisher`: a Foxglove
                               WebSocket server (foxglove-sdk)
=============================  ==============================================================

Payloads (version `PAYLOAD_VERSION`; every one names its ``schema`` and ``version``, so a
subscriber needs nothing but this description):

- ``thermoskin.temperature``: one message per block of samples the pipeline processed: a
  UTF-8 JSON header, a newline, then ``samples x taxels`` little-endian float32 deg C in the
  header's taxel order (NaN: no reading). Header: ``schema``, ``version``, ``robot``,
  ``taxels`` (ids), ``samples``, ``device_time`` (s, per sample), ``host_time`` (Unix time
  s, per sample, from the clock maps), ``dtype`` (``"<f4"``). `decode_payload` reads it.
- ``thermoskin.contact``: JSON, an ``events.jsonl`` record (`skin.stream.sinks.event_record`:
  label, family and probabilities when the classifier gives them, device and host times) plus
  ``link`` and the contact's ``centroid`` (m) and outward ``normal`` in that link's frame;
  over Zenoh also ``link_pose`` (the link in the robot's base frame, its chain standing still,
  when the publisher knows the chain) and ``robot_pose`` (the base in a shared map's frame,
  when the setup gives one), 4x4 row-major lists, for the shared map (`skin.world.map_store`).
- ``thermoskin.health``: JSON, about once a second: frames, samples, gaps, late frames, contacts
  decided, taxels in contact and flagged, and the host time it was sent.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from typing import Any
from urllib.parse import parse_qs, urlsplit

import numpy as np

from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.stream.pipeline import ContactResult, Pipeline
from skin.stream.sinks import event_record

#: Version of the payloads described in the module docstring.
PAYLOAD_VERSION = 1
SCHEMES = ("zenoh", "foxglove")


def contact_geometry(layout: Layout, taxels: list[int]) -> dict[str, Any]:
    """Return the link, centroid (m) and unit outward normal of a contact's taxels.

    The link is the one most of the taxels sit on; only its taxels are averaged (positions and
    normals are given in their link's frame).
    """
    idx = [layout.index(t) for t in taxels]
    link = Counter(layout.links[k] for k in idx).most_common(1)[0][0]
    on = [k for k in idx if layout.links[k] == link]
    normal = layout.normals[on].sum(axis=0)
    norm = float(np.linalg.norm(normal))
    normal = normal / norm if norm > 0 else layout.normals[on[0]]
    return {"link": link,
            "centroid": [round(float(v), 5) for v in layout.positions[on].mean(axis=0)],
            "normal": [round(float(v), 5) for v in normal]}


def contact_payload(result: ContactResult, layout: Layout, robot: str) -> dict[str, Any]:
    """Return the ``thermoskin.contact`` payload of a result (see the module docstring)."""
    rec = event_record(result)
    return {"schema": "thermoskin.contact", "version": PAYLOAD_VERSION, "robot": robot,
            **rec, **contact_geometry(layout, rec["taxels"])}


def temperature_payload(layout: Layout, robot: str, times: np.ndarray,
                        temperature: np.ndarray, host_times: np.ndarray,
                        taxels_json: str | None = None) -> bytes:
    """Return the ``thermoskin.temperature`` payload of a block (see the module docstring).

    ``taxels_json`` is ``json.dumps(layout.ids.tolist())``, if the caller keeps it.
    """
    from skin.drivers.clock import WALL_OFFSET

    head = json.dumps({
        "schema": "thermoskin.temperature", "version": PAYLOAD_VERSION, "robot": robot,
        "samples": len(times), "device_time": np.round(times, 6).tolist(),
        "host_time": np.round(np.asarray(host_times) + WALL_OFFSET, 6).tolist(),
        "dtype": "<f4"}, separators=(",", ":"))
    ids = taxels_json or json.dumps(layout.ids.tolist(), separators=(",", ":"))
    data = np.ascontiguousarray(temperature, dtype="<f4")
    return f'{head[:-1]},"taxels":{ids}}}'.encode() + b"\n" + data.tobytes()


def health_payload(pipeline: Pipeline, robot: str) -> dict[str, Any]:
    """Return the ``thermoskin.health`` payload of a pipeline (see the module docstring)."""
    stats = pipeline.stats
    return {"schema": "thermoskin.health", "version": PAYLOAD_VERSION, "robot": robot,
            "host_time": round(time.time(), 6), "frames": stats.frames,
            "samples": stats.samples, "gaps": stats.gaps, "late": stats.late,
            "contacts": stats.contacts, "results": stats.results,
            "in_contact": int(pipeline.in_contact().sum()),
            "flagged_taxels": int((stats.flagged > 0).sum())}


def decode_payload(data: bytes) -> dict[str, Any]:
    """Decode any payload of the module docstring into a dict.

    A ``thermoskin.temperature`` payload gets ``temperature``, a float array (samples, taxels).

    Raises
    ------
    ValueError
        If ``data`` is not such a payload, or of a newer version than this library reads.
    """
    head, sep, rest = bytes(data).partition(b"\n")
    try:
        msg = json.loads(head)
    except ValueError as exc:
        raise ValueError(f"not a thermoskin payload: its head is not JSON ({exc})") from None
    schema, version = msg.get("schema"), msg.get("version")
    if not str(schema).startswith("thermoskin.") or not isinstance(version, int):
        raise ValueError(f"not a thermoskin payload (schema {schema!r}, version {version!r})")
    if version > PAYLOAD_VERSION:
        raise ValueError(f"{schema} payload version {version}; this library reads up to "
                         f"{PAYLOAD_VERSION}")
    if schema == "thermoskin.temperature":
        n, taxels = msg["samples"], len(msg["taxels"])
        if not sep or len(rest) != 4 * n * taxels:
            raise ValueError(f"a temperature payload of {len(rest)} data bytes for {n} samples "
                             f"of {taxels} taxels")
        msg["temperature"] = np.frombuffer(rest, dtype=msg["dtype"]).reshape(n, taxels)
    return msg


class Publisher:
    """The part every publisher shares: attach to a pipeline, pace the health messages.

    A backend implements ``publish_temperature(payload_args)``, ``publish_contact(result)``,
    ``publish_health(payload)`` and ``close``.

    Parameters
    ----------
    layout : Layout
        The skin.
    robot : str
        The robot's name, in topics and payloads.
    health_period : float
        Seconds between health messages (host time).

    Attributes
    ----------
    sent : collections.Counter
        Messages handed to the transport, by kind (``temperature``, ``contacts``, ``health``).
    """

    url: str = ""

    def __init__(self, layout: Layout, robot: str = "skin", health_period: float = 1.0) -> None:
        self.layout = layout
        self.robot = robot
        self.health_period = float(health_period)
        self.sent: Counter[str] = Counter()
        self._pipeline: Pipeline | None = None
        self._next_health = 0.0

    def attach(self, pipeline: Pipeline) -> Publisher:
        """Publish ``pipeline``'s samples, contacts and health; return self."""
        self._pipeline = pipeline
        pipeline.sinks.append(self)
        pipeline.observers.append(self.temperature)
        return self

    def temperature(self, times: np.ndarray, temperature: np.ndarray,
                    host_times: np.ndarray) -> None:
        """Publish a block of calibrated samples (a pipeline observer)."""
        self.publish_temperature(times, temperature, host_times)
        self.sent["temperature"] += 1
        now = time.monotonic()
        if self._pipeline is not None and now >= self._next_health:
            self._next_health = now + self.health_period
            self.publish_health(health_payload(self._pipeline, self.robot))
            self.sent["health"] += 1

    def write(self, result: ContactResult) -> None:
        """Publish a contact result (a sink)."""
        self.publish_contact(result)
        self.sent["contacts"] += 1

    def publish_temperature(self, times: np.ndarray, temperature: np.ndarray,
                            host_times: np.ndarray) -> None:
        """Send a block of samples (the backend's)."""
        raise NotImplementedError

    def publish_contact(self, result: ContactResult) -> None:
        """Send a contact result (the backend's)."""
        raise NotImplementedError

    def publish_health(self, payload: dict[str, Any]) -> None:
        """Send a health payload (the backend's)."""
        raise NotImplementedError

    def close(self) -> None:
        """Stop publishing (idempotent)."""

    def __enter__(self) -> Publisher:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _query(url: str) -> tuple[Any, dict[str, str]]:
    parts = urlsplit(url)
    query = {}
    for key, values in parse_qs(parts.query, keep_blank_values=True).items():
        query[key] = values[-1]
    return parts, query


_OPTIONS = {"zenoh": {"robot", "listen", "connect", "mode", "resend"}, "foxglove": {"robot"}}
_PACKAGES = {"zenoh": ("zenoh", "publishing over Zenoh"),
             "foxglove": ("foxglove", "the Foxglove server")}


def check_publisher_url(url: str) -> None:
    """Check a publisher URL without opening it: scheme, options, port, installed package.

    Raises
    ------
    SkinError
        Naming the URL and the problem (or the install hint of a missing package).
    """
    from skin._optional import require

    parts, query = _query(url)
    if parts.scheme not in SCHEMES:
        raise SkinError(f"{url}: unknown publisher {parts.scheme!r} (known: "
                        f"{', '.join(s + '://' for s in SCHEMES)})")
    unknown = set(query) - _OPTIONS[parts.scheme]
    if unknown:
        raise SkinError(f"{url}: unknown option(s) {sorted(unknown)} (known: "
                        f"{', '.join(sorted(_OPTIONS[parts.scheme]))})")
    if parts.scheme == "foxglove":
        try:
            parts.port  # noqa: B018 (parsing it is the check)
        except ValueError:
            raise SkinError(f"{url}: the port is not a number from 0 to 65535") from None
    if "resend" in query:
        try:
            ok = float(query["resend"]) > 0
        except ValueError:
            ok = False
        if not ok:
            raise SkinError(f"{url}: resend= wants a positive number of seconds")
    require(*_PACKAGES[parts.scheme])


def open_publisher(url: str, layout: Layout, robot: str | None = None,
                   chain: Any = None, robot_pose: Any = None) -> Publisher:
    """Open the publisher a URL names (see the module docstring).

    Parameters
    ----------
    url : str
        ``zenoh://[PREFIX][?robot=&listen=&connect=&mode=]`` or ``foxglove://HOST:PORT``.
    layout : Layout
        The skin.
    robot : str, optional
        The robot's name (a key segment); the URL's ``robot=`` wins; ``"skin"`` by default.
    chain : skin.world.kinematics.Chain, optional
        The arm's links and joints (a URDF's), for the views that draw it; the default arm's
        when the layout's links are its.
    robot_pose : array (4, 4), optional
        The robot's base in the shared map's frame (Zenoh contacts carry it).

    Raises
    ------
    SkinError
        An unknown scheme or option, a bad port; the optional dependency's install hint.
    """
    check_publisher_url(url)
    parts, query = _query(url)
    name = query.pop("robot", None) or robot or "skin"
    name = "".join(c if c.isalnum() or c in "-_" else "_" for c in name)
    if parts.scheme == "zenoh":
        from skin.stream.publish_zenoh import ZenohPublisher

        prefix = (parts.netloc + parts.path).strip("/") or "thermoskin"

        def endpoints(key: str) -> list[str]:
            return [e for e in query.get(key, "").split(",") if e]

        from skin.world.kinematics import default_chain

        arm = chain if chain is not None else default_chain()
        links = arm.poses() if set(layout.links) <= set(arm.links) else None
        return ZenohPublisher(layout, prefix=prefix, robot=name, listen=endpoints("listen"),
                              connect=endpoints("connect"), mode=query.get("mode"), url=url,
                              robot_pose=robot_pose, link_poses=links,
                              resend=float(query["resend"]) if "resend" in query else None)
    if parts.scheme == "foxglove":
        from skin.stream.publish_foxglove import FoxglovePublisher

        port = parts.port if parts.port is not None else 8765
        return FoxglovePublisher(layout, host=parts.hostname or "127.0.0.1", port=port,
                                 robot=name, url=url, chain=chain)
    raise AssertionError(parts.scheme)  # check_publisher_url knows every scheme

"""Recordings: MCAP files of the raw wire bytes, temperatures, events, layout and calibration.

`Recorder` writes a recording with the ``mcap`` package (``pip install 'thermoskin[record]'``);
`RecordingReader` and `read_recording` read one back, and `skin.drivers.replay.ReplayDriver`
plays its wire bytes through the same decoders again (``replay://run.mcap``).

What a recording holds (MCAP profile ``thermoskin``, format 2; every channel has a schema that
standard MCAP tools and Foxglove recognise: protobuf, `skin.formats.protobuf`, or jsonschema):

=====================  ==========================================================================
record                 content
=====================  ==========================================================================
metadata ``thermoskin``  ``format`` ("2"), ``library`` (thermoskin's version), ``created`` (ISO
                       date, UTC), ``clock_offset`` (s: wall-clock time minus
                       ``time.monotonic()`` at the start; log times are wall-clock ns)
attachment             ``layout.toml`` (``application/toml``): the layout used, as layout TOML
                       (`skin.formats.layout.layout_toml`; `parse_layout` reads it back)
attachment             ``calibration.json`` (``application/json``), if one was used: either a
                       calibration file (`skin.formats.calibration_file`, format 1, verbatim)
                       or, for a bare `skin.stream.calibration.Calibration`,
                       ``{"format": "calibration-arrays", "c0": [...], ...}``: its per-taxel
                       arrays in layout order
channel ``/wire/<k>``  one per source (driver): the bytes as they came off the wire, one message
                       per chunk the driver read, log time = host arrival time; protobuf
                       ``thermoskin.Wire`` holding the serial protocol's byte stream
                       (metadata ``wire`` = ``serial``) or records of
                       `skin.drivers.protocol.can_record` (``wire`` = ``can``). Channel
                       metadata: ``url``, ``wire``, ``board`` (board id of a serial source),
                       ``boards`` (JSON node -> board of a CAN source)
channel                deg C after calibration, one message per sample, log time = the
``/temperature``       sample's host time (Unix ns; its clock map's); protobuf
                       ``thermoskin.Temperature``: host and device time, deg C per taxel in
                       layout order (NaN: no reading) and the taxel ids
channel ``/events``    one JSON object per contact result (`skin.stream.sinks.event_record`),
                       encoding ``json`` with a JSON schema, log time = the host time the
                       result was given
=====================  ==========================================================================

Format 1 recordings (raw wire bytes, blocks of temperatures in ``thermoskin.temperature``)
read and replay as before.

Surviving a kill: by default the file is unchunked and every record is handed to the
operating system as it is written (the file is flushed after each block), so a recording
process killed at any moment (SIGKILL included) leaves a file whose every complete record is
readable: only the record being written and the summary and footer, which `Recorder.close`
adds, are missing. ``compression="zstd"`` (or ``"lz4"``) writes compressed chunks instead:
smaller, and what tools such as ``mcap compress`` and ``mcap recover`` produce; a kill then
loses the chunk being filled. The reader takes both, decompressing chunks with the mcap
library's own chunk reader (``mcap.stream_reader.breakup_chunk``).
(The file is not fsync'ed: a power cut may still lose what the OS had not written to disk.)
`RecordingReader` reads such a file to its last complete record and says where and how it
ends (``problem``); a record that cannot be what it claims (an unknown opcode, a field running
past its record, a bad attachment CRC) stops reading with a `RecordingError` naming the file
and the byte offset, after every complete message before it has been handed over. Nothing is
ever unpickled: records are raw bytes, JSON, TOML and little-endian arrays.
"""

from __future__ import annotations

import datetime
import heapq
import io
import json
import os
import struct
import threading
import time
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from skin._optional import require
from skin.drivers.clock import WALL_OFFSET
from skin.errors import SkinError
from skin.formats import protobuf
from skin.formats.layout import layout_toml

#: Version of the recording layout described in the module docstring.
FORMAT = 2
PROFILE = "thermoskin"
TEMPERATURE_TOPIC = "/temperature"
EVENTS_TOPIC = "/events"
WIRE_PREFIX = "/wire/"
#: Message encodings of the wire channels, by ``Driver.wire``.
WIRE_ENCODINGS = {"serial": "thermoskin.serial", "can": "thermoskin.can"}
TEMPERATURE_ENCODING = "thermoskin.temperature"  # format 1's blocks
#: Chunk compressions the recorder writes (None: unchunked, the kill-safe default).
COMPRESSIONS = (None, "zstd", "lz4")
LAYOUT_ATTACHMENT = "layout.toml"
CALIBRATION_ATTACHMENT = "calibration.json"

_MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEAD = struct.Struct("<BQ")
_TEMP_HEAD = struct.Struct("<II")
# MCAP opcodes (the specification's): what this reader knows; 0x80-0xFF are user records
_OPCODES = {0x01: "HEADER", 0x02: "FOOTER", 0x03: "SCHEMA", 0x04: "CHANNEL", 0x05: "MESSAGE",
            0x06: "CHUNK", 0x07: "MESSAGE_INDEX", 0x08: "CHUNK_INDEX", 0x09: "ATTACHMENT",
            0x0A: "ATTACHMENT_INDEX", 0x0B: "STATISTICS", 0x0C: "METADATA",
            0x0D: "METADATA_INDEX", 0x0E: "SUMMARY_OFFSET", 0x0F: "DATA_END"}

_EVENT_SCHEMA = {
    "title": "thermoskin contact result (skin.stream.sinks.event_record)",
    "type": "object",
    "properties": {
        "contact": {"type": "integer"},
        "taxels": {"type": "array", "items": {"type": "integer"}},
        "onset": {"type": "number"},
        "release": {"type": ["number", "null"]},
        "duration": {"type": ["number", "null"]},
        "decided_at": {"type": "number"},
        "final": {"type": "boolean"},
        "reported_at": {"type": "number"},
        "label": {"type": "string"},
        "confidence": {"type": "number"},
        "effusivity": {"type": ["number", "null"]},
        "method": {"type": "string"},
        "initial_temperature": {"type": "object",
                                "additionalProperties": {"type": "number"}},
        "ambient": {"type": "number"},
        "host_onset": {"type": ["number", "null"]},
        "host_release": {"type": ["number", "null"]},
        "host_decided_at": {"type": ["number", "null"]},
        "host_reported_at": {"type": ["number", "null"]},
        "family": {"type": ["string", "null"]},
        "family_confidence": {"type": "number"},
        "probabilities": {"type": "object", "additionalProperties": {"type": "number"}},
    },
}


class RecordingError(SkinError):
    """A recording cannot be written or read; the message names the file (and byte offset)."""


# ---- calibration as text ----

def _calibration_bytes(calibration: Any) -> bytes | None:
    """Return the ``calibration.json`` attachment of what `Recorder` was given (None: none)."""
    from skin.formats.calibration_file import CalibrationFile
    from skin.stream.calibration import Calibration

    if calibration is None:
        return None
    if isinstance(calibration, str | os.PathLike):
        path = Path(calibration)
        try:
            return path.read_bytes()
        except OSError as exc:
            raise RecordingError(f"{path}: cannot read the calibration file to record "
                                 f"({exc.strerror})") from None
    if isinstance(calibration, CalibrationFile):
        return (json.dumps(calibration.document(), indent=1) + "\n").encode()
    if isinstance(calibration, Calibration):
        doc: dict[str, Any] = {"format": "calibration-arrays", "source": calibration.source}
        for name in ("c0", "c1", "c2", "divider_resistor", "supply_voltage", "adc_reference",
                     "adc_max"):
            doc[name] = np.asarray(getattr(calibration, name), dtype=float).tolist()
        return (json.dumps(doc) + "\n").encode()
    raise TypeError("calibration must be None, a calibration file path, a CalibrationFile or "
                    f"a Calibration, not {type(calibration).__name__}")


def _parse_calibration(data: bytes, source: str) -> Any:
    from skin.formats.calibration_file import parse_calibration
    from skin.stream.calibration import Calibration

    text = data.decode("utf-8")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{source}, line {exc.lineno}: not JSON ({exc.msg})") from None
    if isinstance(doc, dict) and doc.get("format") == "calibration-arrays":
        try:
            arrays = {k: np.asarray(doc[k], dtype=float) for k in
                      ("c0", "c1", "c2", "divider_resistor", "supply_voltage",
                       "adc_reference", "adc_max")}
        except (KeyError, TypeError, ValueError) as exc:
            raise RecordingError(f"{source}: calibration arrays unreadable ({exc})") from None
        return Calibration(source=str(doc.get("source", source)), **arrays)
    return parse_calibration(text, source)


# ---- writing ----

def _wire_metadata(driver: Any) -> dict[str, str]:
    wire = getattr(driver, "wire", "serial")
    meta = {"url": str(getattr(driver, "url", "")), "wire": wire}
    if wire == "can":
        reassembler = getattr(driver, "_reassembler", None)
        boards = getattr(reassembler, "boards", {}) or {}
        meta["boards"] = json.dumps({str(k): int(v) for k, v in boards.items()})
    else:
        decoder = getattr(driver, "_decoder", None)
        board = getattr(decoder, "board", None)
        if board is None:
            sim = getattr(driver, "simulator", None)  # sim://: the simulated board
            board = getattr(getattr(sim, "board", None), "id", 0)
        meta["board"] = str(int(board))
    return meta


class Recorder:
    """Write a recording (see the module docstring): wire bytes, temperatures, events.

    The layout and calibration are written at once, then every message as it comes, each
    flushed to the operating system, so that a killed process leaves a readable file.
    `add_driver` records a driver's wire bytes through its ``tap``; `temperature` is a
    pipeline observer (``pipeline.observers.append(recorder.temperature)``); `write` makes the
    recorder a sink of contact results. Safe to call from several threads.

    Parameters
    ----------
    path : str or Path
        The MCAP file to create (replaced if it exists).
    layout : skin.formats.layout.Layout
        The layout the data belong to.
    calibration : str, Path, CalibrationFile or Calibration, optional
        The calibration used: a calibration file (its path: its text is kept verbatim; or the
        loaded `skin.formats.calibration_file.CalibrationFile`), or a bare
        `skin.stream.calibration.Calibration` (its per-taxel arrays are kept).
    metadata : dict of str to str, optional
        More entries for the ``thermoskin`` metadata record (the command line, say).
    compression : str, optional
        ``"zstd"`` or ``"lz4"``: write compressed chunks; None (default): unchunked, every
        message on disk as it comes (see the module docstring).

    Attributes
    ----------
    messages : int
        Messages written.
    bytes_recorded : int
        Wire bytes recorded, over all sources.

    Raises
    ------
    RecordingError
        If the file cannot be created or written.
    """

    def __init__(self, path: str | Path, layout: Any, calibration: Any = None,
                 metadata: dict[str, str] | None = None, compression: str | None = None
                 ) -> None:
        mcap_writer = require("mcap.writer", "recording (MCAP)")
        if compression not in COMPRESSIONS:
            raise RecordingError(f"{path}: unknown compression {compression!r} (known: "
                                 f"{', '.join(map(str, COMPRESSIONS))})")
        if compression == "zstd":
            require("zstandard", "zstd-compressed recordings")
        elif compression == "lz4":
            require("lz4", "lz4-compressed recordings")
        self.path = Path(path)
        self.layout = layout
        self.messages = 0
        self.bytes_recorded = 0
        self._lock = threading.Lock()
        self._closed = False
        self._sources = 0
        self._sequence: dict[int, int] = {}
        self._clock_offset = WALL_OFFSET
        cal = _calibration_bytes(calibration)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self.path.open("wb")
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot create the recording "
                                 f"({exc.strerror})") from None
        kind = mcap_writer.CompressionType
        self._writer = mcap_writer.Writer(
            self._file, use_chunking=compression is not None, chunk_size=256 * 1024,
            compression={None: kind.NONE, "zstd": kind.ZSTD, "lz4": kind.LZ4}[compression])
        self._ids = protobuf.packed_ids(layout.ids)
        created = datetime.datetime.now(datetime.UTC)
        with self._guard():
            from skin import __version__

            self._writer.start(profile=PROFILE, library=f"thermoskin {__version__}")
            self._writer.add_metadata("thermoskin", {
                "format": str(FORMAT), "library": __version__,
                "created": created.isoformat(timespec="seconds"),
                "clock_offset": repr(self._clock_offset), **(metadata or {})})
            now = time.time_ns()
            self._writer.add_attachment(now, now, LAYOUT_ATTACHMENT, "application/toml",
                                        layout_toml(layout).encode())
            if cal is not None:
                self._writer.add_attachment(now, now, CALIBRATION_ATTACHMENT,
                                            "application/json", cal)
            temp_schema = self._writer.register_schema(
                protobuf.TEMPERATURE_SCHEMA, "protobuf", protobuf.temperature_descriptor())
            self._temperature = self._writer.register_channel(
                TEMPERATURE_TOPIC, "protobuf", temp_schema,
                {"taxels": str(len(layout)), "unit": "degC",
                 "layout": LAYOUT_ATTACHMENT})
            self._wire_schema = self._writer.register_schema(
                protobuf.WIRE_SCHEMA, "protobuf", protobuf.wire_descriptor())
            schema = self._writer.register_schema(
                "thermoskin.event", "jsonschema", json.dumps(_EVENT_SCHEMA).encode())
            self._events = self._writer.register_channel(EVENTS_TOPIC, "json", schema)
            self._file.flush()

    def _guard(self) -> _Guard:
        return _Guard(self)

    def _log_time(self, host_time: float) -> int:
        return max(0, round((host_time + self._clock_offset) * 1e9))

    def _add(self, channel: int, host_time: float, data: bytes, wire: int = 0) -> None:
        self._add_many(channel, [(host_time, data)], wire)

    def _add_many(self, channel: int, items: list[tuple[float, bytes]], wire: int = 0
                  ) -> None:
        """Write messages (host time, payload) on one channel, then flush once.

        ``wire`` is the count of raw wire bytes they carry.
        """
        with self._lock:
            if self._closed:
                return
            seq = self._sequence.get(channel, 0)
            self._sequence[channel] = seq + len(items)
            publish = self._log_time(time.monotonic())
            with self._guard():
                for k, (host_time, data) in enumerate(items):
                    self._writer.add_message(channel, self._log_time(host_time), data,
                                             publish, seq + k)
                self._file.flush()  # to the OS now: a killed process keeps it
            self.messages += len(items)
            self.bytes_recorded += wire

    def add_driver(self, driver: Any, board: int | None = None) -> list[int]:
        """Record a driver's wire bytes: set its ``tap``; return the channel ids added.

        A `skin.drivers.reader.BackgroundReader` gets one channel per driver it reads, a
        `skin.drivers.replay.ReplayDriver` one per source it replays.

        Parameters
        ----------
        driver : skin.drivers.Driver
            The driver (``driver.wire`` says how its bytes are framed).
        board : int, optional
            Board id of a serial source, if the driver's own cannot be found.
        """
        inner = getattr(driver, "drivers", None)
        if inner is not None:  # a BackgroundReader: each of its drivers is a source
            return [c for d in inner for c in self.add_driver(d, board)]
        sources = getattr(driver, "sources", None)
        if sources is not None:  # a replay: keep its sources apart
            ids = [self._register(dict(s.metadata)) for s in sources]
            driver.source_tap = lambda k, t, data: self.wire(ids[k], t, data)
            return ids
        meta = _wire_metadata(driver)
        if board is not None:
            meta["board"] = str(int(board))
        channel = self._register(meta)
        driver.tap = lambda t, data: self.wire(channel, t, data)
        return [channel]

    def _register(self, meta: dict[str, str]) -> int:
        wire = meta.get("wire", "serial")
        if wire not in WIRE_ENCODINGS:
            raise RecordingError(f"{self.path}: cannot record a {wire!r} wire "
                                 f"(known: {', '.join(WIRE_ENCODINGS)})")
        with self._lock, self._guard():
            channel = self._writer.register_channel(f"{WIRE_PREFIX}{self._sources}",
                                                    "protobuf", self._wire_schema, meta)
            self._sources += 1
        return channel

    def wire(self, channel: int, host_time: float, data: bytes) -> None:
        """Record raw bytes that arrived on a wire channel (of `add_driver`) at ``host_time``."""
        self._add(channel, host_time, protobuf.encode_wire(data), wire=len(data))

    def temperature(self, times: np.ndarray, temperature: np.ndarray,
                    host_times: np.ndarray | None = None) -> None:
        """Record a block of calibrated temperatures (a `skin.stream.pipeline.Pipeline` observer).

        Parameters
        ----------
        times : numpy.ndarray
            Device time of each sample, s, (n,).
        temperature : numpy.ndarray
            deg C in layout order, (n, taxels).
        host_times : numpy.ndarray, optional
            Host time of each sample (``time.monotonic`` clock), s: each message's log time;
            the time of writing without them.
        """
        times = np.asarray(times, dtype=float)
        temp = np.asarray(temperature, dtype="<f4")
        if temp.shape != (times.size, len(self.layout)):
            raise ValueError(f"temperature has shape {temp.shape}; expected "
                             f"({times.size}, {len(self.layout)})")
        host = (np.full(times.size, time.monotonic()) if host_times is None
                else np.asarray(host_times, dtype=float))
        self._add_many(self._temperature, [
            (h, protobuf.encode_temperature(h + self._clock_offset, t, row, self._ids))
            for t, h, row in zip(times.tolist(), host.tolist(), temp, strict=True)])

    def write(self, result: Any) -> None:
        """Record a contact result as its JSON event record (a sink: `skin.stream.sinks`)."""
        from skin.stream.sinks import event_record

        host = getattr(result, "host", None)
        self.event(event_record(result), None if host is None else host.reported_at)

    def event(self, record: dict[str, Any], host_time: float | None = None) -> None:
        """Record an event record (JSON-ready dict) on the events channel.

        ``host_time`` (``time.monotonic`` clock, s) is its log time; the time of writing
        by default.
        """
        self._add(self._events, time.monotonic() if host_time is None else host_time,
                  json.dumps(record).encode())

    def size(self) -> int:
        """Bytes written to the file so far."""
        with self._lock:
            return self.path.stat().st_size if self._file.closed else self._file.tell()

    def close(self) -> None:
        """Write the summary and footer and close the file (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._writer.finish()
            finally:
                self._file.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Guard:
    """Turn the OS errors of a write into a `RecordingError` naming the file."""

    def __init__(self, recorder: Recorder) -> None:
        self.recorder = recorder

    def __enter__(self) -> None:
        return None

    def __exit__(self, kind: type | None, exc: BaseException | None, tb: object) -> bool:
        if isinstance(exc, OSError):
            raise RecordingError(f"{self.recorder.path}: cannot write the recording "
                                 f"({exc.strerror or exc})") from exc
        return False


# ---- reading ----

def _strict_stream() -> type:
    """Return a ReadDataStream class that raises EndOfFile on a short read (a field too long)."""
    data_stream = require("mcap.data_stream", "reading recordings (MCAP)")
    exceptions = require("mcap.exceptions", "reading recordings (MCAP)")

    class StrictStream(data_stream.ReadDataStream):
        def read(self, length: int) -> bytes:
            data = super().read(length)
            if len(data) < length:
                raise exceptions.EndOfFile()
            return data

    return StrictStream


@dataclass(frozen=True)
class WireSource:
    """One recorded wire (a ``/wire/<k>`` channel).

    Attributes
    ----------
    index : int
        Order of the source in the file (k of ``/wire/<k>``).
    channel : int
        MCAP channel id.
    topic : str
        The channel's topic.
    url : str
        The URL of the driver recorded.
    wire : str
        ``"serial"`` or ``"can"``.
    board : int
        Board id of a serial source's frames.
    boards : dict of int to int
        Node -> board id of a CAN source.
    metadata : dict of str to str
        The channel metadata as written.
    """

    index: int
    channel: int
    topic: str
    url: str
    wire: str
    board: int
    boards: dict[int, int]
    metadata: dict[str, str] = field(repr=False)


@dataclass(frozen=True)
class RecordedMessage:
    """A message of a recording.

    Attributes
    ----------
    channel : int
        MCAP channel id.
    topic : str
        Its channel's topic.
    log_time : int
        Host time of the message, wall-clock ns.
    sequence : int
        Per-channel counter (0, 1, ...): a jump means messages are missing.
    data : bytes
        The payload.
    offset : int
        Byte offset of the message record in the file.
    """

    channel: int
    topic: str
    log_time: int
    sequence: int
    data: bytes
    offset: int

    @property
    def time(self) -> float:
        """Host time of the message, s (wall clock)."""
        return self.log_time * 1e-9


class RecordingReader:
    """Read a recording record by record, tolerating a truncated end (see the module docstring).

    Opening reads the head of the file: everything before the first message (the metadata,
    layout and calibration attachments and the channels, as `Recorder` writes them).
    `messages` then goes on to the end, once.

    Parameters
    ----------
    path : str or Path
        The MCAP file.

    Attributes
    ----------
    metadata : dict
        Metadata records by name (``"thermoskin"``), each a dict of str.
    attachments : dict of str to bytes
        Attachments by name.
    channels : dict
        MCAP channel id -> ``mcap.records.Channel``.
    complete : bool
        True once the footer has been read (the recording was closed).
    problem : str or None
        Why reading stopped early, once it has: where the file ends and what was read.
    count : int
        Messages read so far.

    Raises
    ------
    RecordingError
        If the file is missing, not MCAP, or corrupt in its head.
    """

    def __init__(self, path: str | Path) -> None:
        self._records = require("mcap.records", "reading recordings (MCAP)")
        self._stream_cls = _strict_stream()
        self.path = Path(path)
        self.metadata: dict[str, dict[str, str]] = {}
        self.attachments: dict[str, bytes] = {}
        self.channels: dict[int, Any] = {}
        self.complete = False
        self.problem: str | None = None
        self.count = 0
        self._started = False
        try:
            self._file = self.path.open("rb")
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot open the recording "
                                 f"({exc.strerror})") from None
        magic = self._file.read(len(_MAGIC))
        if magic != _MAGIC:
            self._file.close()
            raise RecordingError(f"{self.path}: not an MCAP recording (its first bytes are "
                                 f"{magic[:8]!r}, not the MCAP magic)")
        self._offset = len(_MAGIC)
        self._scan = self._scan_records()
        self._head: list[RecordedMessage] = []
        try:
            for msg in self._scan:  # read up to the first message, keep it for `messages`
                self._head.append(msg)
                break
        except RecordingError:
            self.close()
            raise

    # -- what the head says --

    @property
    def sources(self) -> list[WireSource]:
        """The wire channels seen so far, in file order."""
        out = []
        for ch in self.channels.values():
            if not ch.topic.startswith(WIRE_PREFIX):
                continue
            meta = dict(ch.metadata)
            try:
                boards = {int(k): int(v) for k, v in json.loads(meta.get("boards", "{}")).items()}
                board = int(meta.get("board", "0"))
            except (ValueError, AttributeError, TypeError):
                raise RecordingError(f"{self.path}: channel {ch.topic}: unreadable board ids "
                                     f"in its metadata {meta!r}") from None
            wire = meta.get("wire", "serial")
            out.append(WireSource(len(out), ch.id, ch.topic, meta.get("url", ""), wire, board,
                                  boards, meta))
        return out

    def layout(self) -> Any:
        """Return the recorded layout (`skin.formats.layout.Layout`), or None without one."""
        from skin.formats.layout import parse_layout

        data = self.attachments.get(LAYOUT_ATTACHMENT)
        if data is None:
            return None
        return parse_layout(data.decode("utf-8"), source=f"{self.path}:{LAYOUT_ATTACHMENT}")

    def calibration(self) -> Any:
        """Return the recorded calibration: a `CalibrationFile`, a `Calibration`, or None."""
        data = self.attachments.get(CALIBRATION_ATTACHMENT)
        if data is None:
            return None
        return _parse_calibration(data, f"{self.path}:{CALIBRATION_ATTACHMENT}")

    # -- records --

    def _corrupt(self, offset: int, what: str) -> RecordingError:
        return RecordingError(f"{self.path}: corrupt at byte {offset}: {what}; the {self.count} "
                              f"complete messages before it were read")

    def _cut(self, offset: int, what: str) -> None:
        self.problem = (f"{self.path}: {what}; the recording was cut short (its process "
                        f"killed?): the {self.count} complete messages before byte {offset} "
                        f"were read")

    def _scan_records(self) -> Iterator[RecordedMessage]:
        rec = self._records
        f = self._file
        size = os.fstat(f.fileno()).st_size
        while True:
            offset = self._offset
            head = f.read(_RECORD_HEAD.size)
            if not head:
                self._cut(offset, f"no footer: the file ends at byte {offset}, after its last "
                                  "complete record")
                return
            if len(head) < _RECORD_HEAD.size:
                self._cut(offset, f"the file ends at byte {offset + len(head)}, inside the "
                                  f"head of a record starting at byte {offset}")
                return
            opcode, length = _RECORD_HEAD.unpack(head)
            name = _OPCODES.get(opcode)
            if name is None and opcode < 0x80:
                raise self._corrupt(offset, f"a record with the unknown opcode 0x{opcode:02X}")
            left = max(size, os.fstat(f.fileno()).st_size) - offset - _RECORD_HEAD.size
            if length > left:
                self._cut(offset, f"the file ends at byte {offset + _RECORD_HEAD.size + left}, "
                                  f"inside a {name or 'user'} record starting at byte {offset} "
                                  f"(it claims {length} bytes, {left} are there)")
                return
            body = f.read(length)
            if len(body) < length:  # the file shrank under us
                self._cut(offset, f"the file ends inside a record starting at byte {offset}")
                return
            self._offset = offset + _RECORD_HEAD.size + length
            if name is None:
                continue  # a user record: not ours, skipped as MCAP says
            stream = self._stream_cls(io.BytesIO(body))
            try:
                if name == "MESSAGE":
                    if length < 22:  # channel, sequence and two times
                        raise self._corrupt(offset, f"a MESSAGE record of {length} bytes")
                    yield self._message(rec.Message.read(stream, length), offset)
                elif name == "CHANNEL":
                    ch = rec.Channel.read(stream)
                    self.channels[ch.id] = ch
                elif name == "ATTACHMENT":
                    a = rec.Attachment.read(stream)
                    (crc,) = struct.unpack_from("<I", body, len(body) - 4)
                    if crc and crc != zlib.crc32(body[:-4]):
                        raise self._corrupt(offset, f"attachment {a.name!r} fails its CRC")
                    self.attachments[a.name] = a.data
                elif name == "METADATA":
                    meta = rec.Metadata.read(stream)
                    self.metadata[meta.name] = dict(meta.metadata)
                elif name == "CHUNK":
                    yield from self._chunk(rec.Chunk.read(stream), offset)
                elif name == "FOOTER":
                    self.complete = True
                    if f.read(len(_MAGIC)) != _MAGIC:
                        self.problem = (f"{self.path}: the closing magic after the footer at "
                                        f"byte {offset} is missing or damaged")
                    return
                # HEADER, SCHEMA, DATA_END and the summary's indexes: nothing to keep
            except RecordingError:
                raise
            except (SkinError, ValueError, struct.error, UnicodeDecodeError) as exc:
                raise self._corrupt(offset, f"a {name} record that cannot be read "
                                            f"({type(exc).__name__}: {exc})") from None
            except Exception as exc:  # mcap's EndOfFile: a field runs past its record
                if type(exc).__name__ != "EndOfFile":
                    raise
                raise self._corrupt(offset, f"a {name} record whose fields run past its "
                                            f"{length} bytes") from None

    def _message(self, m: Any, offset: int) -> RecordedMessage:
        """Return a MESSAGE record as a `RecordedMessage` (wire bytes unwrapped)."""
        ch = self.channels.get(m.channel_id)
        if ch is None:
            raise self._corrupt(offset, f"a message on channel {m.channel_id}, which no "
                                        "channel record announced")
        data = m.data
        if ch.topic.startswith(WIRE_PREFIX) and ch.message_encoding == "protobuf":
            try:
                data = protobuf.decode_wire(data)
            except ValueError as exc:
                raise self._corrupt(offset, f"a {ch.topic} message: {exc}") from None
        self.count += 1
        return RecordedMessage(m.channel_id, ch.topic, m.log_time, m.sequence, data, offset)

    def _chunk(self, chunk: Any, offset: int) -> Iterator[RecordedMessage]:
        """Yield the messages of a CHUNK record, decompressed by the mcap library."""
        stream_reader = require("mcap.stream_reader", "reading recordings (MCAP)")
        if chunk.compression == "zstd":
            require("zstandard", "reading zstd-compressed recordings")
        elif chunk.compression == "lz4":
            require("lz4", "reading lz4-compressed recordings")
        elif chunk.compression:
            raise self._corrupt(offset, f"a chunk compressed with {chunk.compression!r}, "
                                        "which MCAP does not define")
        try:
            records = stream_reader.breakup_chunk(chunk, validate_crc=True)
        except stream_reader.CRCValidationError:
            raise self._corrupt(offset, "a chunk fails its CRC") from None
        except Exception as exc:  # zstd/lz4 errors, a record running past the chunk
            raise self._corrupt(offset, f"a chunk that cannot be read ({type(exc).__name__}: "
                                        f"{exc})") from None
        for r in records:
            if isinstance(r, self._records.Channel):
                self.channels[r.id] = r
            elif isinstance(r, self._records.Message):
                yield self._message(r, offset)

    def messages(self) -> Iterator[RecordedMessage]:
        """Yield every complete message, in file order; once per reader.

        Raises
        ------
        RecordingError
            At a corrupt record, after every message before it; or if called twice.
        """
        if self._started:
            raise RecordingError(f"{self.path}: messages() was already called on this reader")
        self._started = True
        try:
            yield from self._head
            self._head = []
            yield from self._scan
        finally:
            self.close()

    def close(self) -> None:
        """Close the file (idempotent)."""
        self._file.close()

    def __enter__(self) -> RecordingReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def merge_by_time(messages: Iterator[RecordedMessage],
                  window: float = 0.5) -> Iterator[RecordedMessage]:
    """Yield messages ordered by log time, allowing ``window`` s of disorder in the input.

    The recorder writes messages as they come, so a file is in host-time order up to the
    scheduling of the threads that fed it; a message is released once one ``window`` newer
    has been read (file order breaks ties). If the input raises (a corrupt record), the
    messages read before it are yielded first.
    """
    heap: list[tuple[int, int, RecordedMessage]] = []
    span = round(window * 1e9)
    try:
        for k, msg in enumerate(messages):
            heapq.heappush(heap, (msg.log_time, k, msg))
            while heap and heap[0][0] <= msg.log_time - span:
                yield heapq.heappop(heap)[2]
    except Exception:  # a corrupt record ends the input: hand over what came before, then raise
        while heap:
            yield heapq.heappop(heap)[2]
        raise
    while heap:
        yield heapq.heappop(heap)[2]


def decode_temperature(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Decode a format-1 ``/temperature`` block: (device times (n,), deg C (n, taxels)).

    Raises
    ------
    ValueError
        If the payload's length does not match its header.
    """
    if len(data) < _TEMP_HEAD.size:
        raise ValueError(f"a temperature message of {len(data)} bytes")
    n, taxels = _TEMP_HEAD.unpack_from(data)
    if len(data) != _TEMP_HEAD.size + 8 * n + 4 * n * taxels:
        raise ValueError(f"a temperature message of {len(data)} bytes for {n} samples of "
                         f"{taxels} taxels")
    times = np.frombuffer(data, dtype="<f8", count=n, offset=_TEMP_HEAD.size)
    temp = np.frombuffer(data, dtype="<f4", count=n * taxels, offset=_TEMP_HEAD.size + 8 * n)
    return times.astype(float), temp.reshape(n, taxels).astype(float)


@dataclass
class Recording:
    """A whole recording in memory (`read_recording`).

    Attributes
    ----------
    path : Path
        The file.
    layout : skin.formats.layout.Layout or None
        The recorded layout.
    calibration : CalibrationFile, Calibration or None
        The recorded calibration.
    sources : list of WireSource
        The wire channels.
    wire : dict of int to list of RecordedMessage
        Per source index, its messages in file order.
    times : numpy.ndarray
        Device time of every recorded temperature sample, s.
    temperature : numpy.ndarray
        deg C, (samples, taxels).
    events : list of dict
        The event records, in order.
    metadata : dict
        Metadata records by name.
    complete : bool
        Whether the recording was closed properly.
    problem : str or None
        Where and why reading stopped early (a truncated file).
    blocks : int
        Temperature messages read (one per sample; a block of samples in format 1).
    """

    path: Path
    layout: Any
    calibration: Any
    sources: list[WireSource]
    wire: dict[int, list[RecordedMessage]]
    times: np.ndarray
    temperature: np.ndarray
    events: list[dict[str, Any]]
    metadata: dict[str, dict[str, str]]
    complete: bool
    problem: str | None

    blocks: int = 0

    @property
    def duration(self) -> float:
        """Host time from the first wire message to the last, s (0 without any)."""
        stamps = [m.log_time for msgs in self.wire.values() for m in msgs]
        return (max(stamps) - min(stamps)) * 1e-9 if stamps else 0.0


def read_recording(path: str | Path) -> Recording:
    """Read a whole recording into memory (every complete message of a truncated one).

    Raises
    ------
    RecordingError
        If the file is not a recording, or is corrupt (the message names the byte offset).
    """
    reader = RecordingReader(path)
    by_channel: dict[int, list[RecordedMessage]] = {}
    times, temps, events = [], [], []
    blocks = 0
    for msg in reader.messages():
        if msg.topic == TEMPERATURE_TOPIC:
            try:
                if reader.channels[msg.channel].message_encoding == "protobuf":
                    sample = protobuf.decode_temperature(msg.data)
                    t = np.array([sample["device_time"]])
                    x = sample["temperature"][None, :]
                else:  # format 1: a block of samples
                    t, x = decode_temperature(msg.data)
            except (ValueError, IndexError, struct.error) as exc:
                raise RecordingError(f"{reader.path}: byte {msg.offset}: {exc}") from None
            times.append(t)
            temps.append(x)
            blocks += 1
        elif msg.topic == EVENTS_TOPIC:
            try:
                events.append(json.loads(msg.data))
            except ValueError as exc:
                raise RecordingError(f"{reader.path}: byte {msg.offset}: an event that is not "
                                     f"JSON ({exc})") from None
        else:
            by_channel.setdefault(msg.channel, []).append(msg)
    sources = reader.sources
    layout = reader.layout()
    n = len(layout) if layout is not None else (temps[0].shape[1] if temps else 0)
    return Recording(
        path=reader.path, layout=layout, calibration=reader.calibration(), sources=sources,
        wire={s.index: by_channel.get(s.channel, []) for s in sources},
        times=np.concatenate(times) if times else np.zeros(0),
        temperature=np.concatenate(temps) if temps else np.zeros((0, n)),
        events=events, metadata=reader.metadata, complete=reader.complete,
        problem=reader.problem, blocks=blocks)


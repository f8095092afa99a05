"""Replay of recordings: the recorded wire bytes through the same decoders, as a driver.

``replay://run.mcap?speed=0`` (a path relative to the working directory) or
``replay:///abs/path/run.mcap``: `ReplayDriver` reads the ``/wire/<k>`` channels of a recording
(`skin.drivers.recording`), merges the sources by host time, and decodes each with the decoder
its wire needs: `skin.drivers.protocol.StreamDecoder` for a serial byte stream,
`skin.drivers.protocol.CanReassembler` for CAN records. The frames are those the recorded
drivers decoded, the same sequence numbers, device times and counts, so a pipeline fed by a
replay gives the events of the recorded run.

``speed`` 1 releases each chunk of bytes at its recorded time relative to the first (real
time), 2 twice as fast, 0 as fast as they decode. A frame's ``host_time`` is its recorded
arrival (the recording's wall clock, as this process's ``time.monotonic`` clock:
`skin.drivers.clock.WALL_OFFSET`), so the clock maps, and the events' host times, are those of
the recorded run whatever the speed: they line up with the robot's logs of that run.
"""

from __future__ import annotations

import collections
import dataclasses
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

from skin.drivers.base import Driver
from skin.drivers.clock import WALL_OFFSET
from skin.drivers.protocol import CanReassembler, LinkStats, StreamDecoder, split_can_records
from skin.drivers.recording import (
    WIRE_PREFIX,
    RecordedMessage,
    RecordingError,
    RecordingReader,
    WireSource,
    merge_by_time,
)
from skin.errors import DeviceError, ProtocolError
from skin.frame import Frame

log = logging.getLogger("skin.drivers")


def replay_path(url: str) -> Path:
    """Return the file of a ``replay://`` URL (``replay://run.mcap``, ``replay:///abs.mcap``).

    Raises
    ------
    DeviceError
        If the URL names no file.
    """
    parts = urlsplit(url)
    path = unquote(parts.netloc + parts.path)
    if not path:
        raise DeviceError(f"{url}: no file: write replay://run.mcap or "
                          f"replay:///absolute/path/run.mcap")
    return Path(path)


def recorded_setup(path: str | Path) -> tuple[Any, Any]:
    """Return the (layout, calibration) a recording holds, each None if it has none.

    Reads only the head of the file. The calibration is a
    `skin.formats.calibration_file.CalibrationFile` (a calibration file was used) or a bare
    `skin.stream.calibration.Calibration`.

    Raises
    ------
    DeviceError
        If the file cannot be read as a recording.
    """
    try:
        with RecordingReader(path) as reader:
            return reader.layout(), reader.calibration()
    except RecordingError as exc:
        raise DeviceError(str(exc)) from None


class ReplayDriver(Driver):
    """Frames decoded again from a recording's wire bytes (see the module docstring).

    Parameters
    ----------
    path : str or Path
        The recording (MCAP, `skin.drivers.recording.Recorder`).
    speed : float
        Pace relative to the recorded time line; 0 = as fast as possible.

    Attributes
    ----------
    reader : RecordingReader
        The file being read (``reader.metadata``, ``reader.attachments``).
    sources : list of WireSource
        The recorded wires (known from the file's head).
    source_tap : callable or None
        If set, called as ``source_tap(source_index, host_time, data)`` with each recorded
        chunk as it is replayed (a `Recorder` re-recording a replay keeps the sources apart);
        otherwise ``tap``, if set, gets every source's chunks.
    problem : str or None
        Once the replay is finished: why the recording ended early, if it did (a truncated
        file, say: every complete message before the cut was replayed).

    Raises
    ------
    DeviceError
        If the file is not a readable recording or ``speed`` is negative. A corrupt record met
        while replaying raises `DeviceError` from `recv` (naming the file and the byte
        offset), after every frame before it was delivered.
    """

    def __init__(self, path: str | Path, speed: float = 1.0) -> None:
        super().__init__()
        self.path = Path(path)
        self.url = f"replay://{self.path}"
        if not speed >= 0:
            raise DeviceError(f"{self.url}: speed must be >= 0 (0: as fast as possible), "
                              f"got {speed}")
        self.speed = float(speed)
        try:
            self.reader = RecordingReader(self.path)
        except RecordingError as exc:
            raise DeviceError(str(exc)) from None
        self.sources: list[WireSource] = self.reader.sources
        wires = {s.wire for s in self.sources}
        self.wire = wires.pop() if len(wires) == 1 else "serial"
        self.source_tap: Callable[[int, float, bytes], None] | None = None
        self.problem: str | None = None
        self._layout: Any = None
        self._decoders: dict[int, tuple[WireSource, StreamDecoder | CanReassembler]] = {}
        self._messages = merge_by_time(m for m in self.reader.messages()
                                       if m.topic.startswith(WIRE_PREFIX))
        self._next: RecordedMessage | None = None
        self._frames: collections.deque[Frame] = collections.deque()
        self._first: int | None = None  # log time of the first message, ns
        self._t0 = 0.0  # monotonic time at which the replay started

    # -- what was recorded --

    @property
    def layout(self) -> Any:
        """The recorded layout (`skin.formats.layout.Layout`), or None."""
        if self._layout is None:
            self._layout = self.reader.layout()
        return self._layout

    @property
    def calibration(self) -> Any:
        """The recorded calibration (`CalibrationFile` or `Calibration`), or None."""
        return self.reader.calibration()

    # -- replaying --

    def _decoder(self, channel: int) -> tuple[WireSource, StreamDecoder | CanReassembler]:
        if channel not in self._decoders:
            sources = {s.channel: s for s in self.reader.sources}
            self.sources = list(sources.values())
            source = sources[channel]
            if source.wire == "serial":
                decoder: StreamDecoder | CanReassembler = StreamDecoder(source.board)
            elif source.wire == "can":
                decoder = CanReassembler(source.boards)
            else:
                raise DeviceError(f"{self.path}: channel {source.topic} holds a {source.wire!r} "
                                  f"wire, which this replay cannot decode")
            self._decoders[channel] = (source, decoder)
            if len(self._decoders) == 1:
                self.stats = decoder.stats
        return self._decoders[channel]

    def _host_time(self, msg: RecordedMessage) -> float:
        if self._first is None:
            self._first = msg.log_time
            self._t0 = time.monotonic()
        return self._t0 + (msg.log_time - self._first) * 1e-9 / (self.speed or 1.0)

    def _decode(self, msg: RecordedMessage, host_time: float) -> None:
        source, decoder = self._decoder(msg.channel)
        if self.source_tap is not None:
            self.source_tap(source.index, host_time, msg.data)
        elif self.tap is not None:
            self.tap(host_time, msg.data)
        recorded = msg.log_time * 1e-9 - WALL_OFFSET
        if isinstance(decoder, StreamDecoder):  # a frame held for its FORCE keeps its time
            frames = decoder.feed(msg.data, recorded)
        else:
            frames = []
            try:
                records = split_can_records(msg.data)
            except ProtocolError:  # a damaged message: the recording's fault, never raised
                decoder.stats.malformed += 1
                records = []
            for ident, data, foreign in records:
                decoder.stats.bytes += len(data)
                if foreign:
                    decoder.stats.malformed += 1
                    continue
                frame = decoder.push(ident, data)
                if frame is not None:
                    frames.append(frame)
        self._frames.extend(frames if isinstance(decoder, StreamDecoder) else (
            dataclasses.replace(f, host_time=recorded) for f in frames))
        self._sum_stats()

    def _sum_stats(self) -> None:
        if len(self._decoders) > 1:
            self.stats = LinkStats(**{
                f.name: sum(getattr(d.stats, f.name) for _, d in self._decoders.values())
                for f in dataclasses.fields(LinkStats)})

    def _recv_internal(self, timeout: float | None) -> Frame | None:
        deadline = time.monotonic() + (0.0 if timeout is None else timeout)
        while not self._frames:
            if self._next is None:
                try:
                    self._next = next(self._messages)
                except StopIteration:
                    if self._flush():  # finished only once these are handed on
                        continue
                    self._finish()
                    return None
                except RecordingError as exc:
                    raise DeviceError(str(exc)) from None
            host_time = self._host_time(self._next)
            if self.speed > 0:
                wait = host_time - time.monotonic()
                if wait > 0:
                    if time.monotonic() + wait > deadline:
                        time.sleep(max(0.0, deadline - time.monotonic()))
                        return None
                    time.sleep(wait)
            msg, self._next = self._next, None
            self._decode(msg, host_time)
        return self._frames.popleft()

    def _flush(self) -> bool:
        """Queue the samples serial decoders hold for a FORCE the recording ends before."""
        for _, decoder in self._decoders.values():
            if isinstance(decoder, StreamDecoder):
                self._frames.extend(decoder.flush())
        self._sum_stats()
        return bool(self._frames)

    def _finish(self) -> None:
        if not self.finished:
            self.finished = True
            self.problem = self.reader.problem
            if self.problem:
                log.warning("%s", self.problem)

    def _close_internal(self) -> None:
        self._messages.close()
        self.reader.close()

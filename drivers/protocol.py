"""Wire protocol, version 0: sample frames over a byte stream.

Every frame is COBS-encoded and ends with a 0x00 byte, so a reader finds the next frame
boundary after any corruption.  Decoded, a frame is (little-endian)::

    u8  version (0)        u8  type (1 = sample)
    u32 sequence number    u32 device time, microseconds (wraps after 71.6 min)
    u16 taxel count n
    u16 x n  ADC counts    i16 ambient, 0.01 deg C
    u8  x n  heater duty   u16 status flags
    u16 CRC-16/CCITT-FALSE over everything before it

This thin first version is replaced by the full protocol of ``firmware/PROTOCOL.md``.
"""

from __future__ import annotations

import binascii
import struct
import time
from dataclasses import dataclass

import numpy as np

from skin._optional import require
from skin.frame import Frame

VERSION = 0
TYPE_SAMPLE = 1
_HEADER = struct.Struct("<BBIIH")
_TAIL = struct.Struct("<hH")  # ambient, flags (after counts and duty)
_CRC = struct.Struct("<H")
MAX_TAXELS = 1024
MAX_FRAME = _HEADER.size + 3 * MAX_TAXELS + _TAIL.size + _CRC.size + 16


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), computed in C by binascii."""
    return binascii.crc_hqx(data, 0xFFFF)


def _cobs():
    return require("cobs.cobs", "the serial wire protocol")


def encode_sample(
    seq: int,
    device_time_us: int,
    counts: np.ndarray,
    ambient: float,
    duty: np.ndarray,
    flags: int = 0,
) -> bytes:
    """Encode one sample frame, COBS-framed and 0x00-terminated.

    Parameters
    ----------
    seq : int
        Sequence number (taken modulo 2**32).
    device_time_us : int
        Device time in microseconds (taken modulo 2**32).
    counts : numpy.ndarray
        ADC counts, one per channel.
    ambient : float
        Ambient temperature, deg C.
    duty : numpy.ndarray
        Heater duty per channel, 0-255.
    flags : int
        Status flags.
    """
    counts = np.asarray(counts)
    n = len(counts)
    if n > MAX_TAXELS:
        raise ValueError(f"{n} channels; protocol v0 carries at most {MAX_TAXELS}")
    body = b"".join((
        _HEADER.pack(VERSION, TYPE_SAMPLE, seq % (1 << 32), device_time_us % (1 << 32), n),
        np.asarray(counts, dtype="<u2").tobytes(),
        np.asarray(duty, dtype=np.uint8).tobytes(),
        _TAIL.pack(round(ambient * 100), flags & 0xFFFF),
    ))
    return _cobs().encode(body + _CRC.pack(crc16(body))) + b"\x00"


@dataclass
class LinkStats:
    """What a decoder has seen on a link.

    Attributes
    ----------
    bytes : int
        Bytes received.
    frames : int
        Valid frames decoded.
    crc_errors : int
        Frames whose CRC did not match.
    malformed : int
        Packets that were not valid COBS, or had an impossible length or header.
    resyncs : int
        Times the decoder discarded bytes to find the next frame boundary.
    """

    bytes: int = 0
    frames: int = 0
    crc_errors: int = 0
    malformed: int = 0
    resyncs: int = 0


class StreamDecoder:
    """Turn a byte stream into frames; corrupt bytes are counted and skipped, never raised.

    A reader that starts in the middle of a frame sees one malformed packet, then locks on.

    Parameters
    ----------
    board : int
        Board id given to the decoded frames.
    """

    def __init__(self, board: int = 0) -> None:
        self.board = board
        self.stats = LinkStats()
        self._buffer = bytearray()
        self._cobs = _cobs()

    def feed(self, data: bytes) -> list[Frame]:
        """Add received bytes; return the frames completed by them."""
        self.stats.bytes += len(data)
        self._buffer += data
        frames = []
        while True:
            end = self._buffer.find(0)
            if end < 0:
                if len(self._buffer) > 2 * MAX_FRAME:  # no delimiter for too long: drop
                    self._buffer.clear()
                    self.stats.resyncs += 1
                break
            packet = bytes(self._buffer[:end])
            del self._buffer[: end + 1]
            if packet:
                frame = self._decode(packet)
                if frame is None:
                    self.stats.resyncs += 1  # skipped to the next delimiter
                else:
                    frames.append(frame)
        return frames

    def _decode(self, packet: bytes) -> Frame | None:
        try:
            raw = self._cobs.decode(packet)
        except self._cobs.DecodeError:
            self.stats.malformed += 1
            return None
        if len(raw) < _HEADER.size + _TAIL.size + _CRC.size:
            self.stats.malformed += 1
            return None
        body, (crc,) = raw[:-2], _CRC.unpack(raw[-2:])
        if crc16(body) != crc:
            self.stats.crc_errors += 1
            return None
        version, ftype, seq, t_us, n = _HEADER.unpack_from(body)
        if version != VERSION or ftype != TYPE_SAMPLE or len(body) != _HEADER.size + 3 * n + 4:
            self.stats.malformed += 1
            return None
        off = _HEADER.size
        counts = np.frombuffer(body, dtype="<u2", count=n, offset=off).astype(np.uint16)
        duty = np.frombuffer(body, dtype=np.uint8, count=n, offset=off + 2 * n).copy()
        ambient, flags = _TAIL.unpack_from(body, off + 3 * n)
        self.stats.frames += 1
        return Frame(seq, t_us * 1e-6, time.monotonic(), counts, ambient / 100.0, duty, flags,
                     self.board)

"""Protobuf messages of thermoskin, encoded and decoded by hand (no protobuf dependency).

Schemas (proto3, package ``thermoskin``; their FileDescriptorSets are what MCAP files and the
Foxglove server carry, so any protobuf reader decodes the messages)::

    message Temperature {          // one sample of every taxel
      double host_time = 1;        // Unix time of the sample on the host's clock, s
      double device_time = 2;      // the board's clock, s
      repeated float temperature = 3;  // deg C per taxel, layout order; NaN: no reading
      repeated uint32 taxel = 4;   // the taxels' ids, in the same order
    }
    message Wire {                 // bytes as they came off a bus
      bytes data = 1;
    }
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

TEMPERATURE_SCHEMA = "thermoskin.Temperature"
WIRE_SCHEMA = "thermoskin.Wire"


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        low, n = n & 0x7F, n >> 7
        out.append(low | (0x80 if n else 0))
        if not n:
            return bytes(out)


def _field(number: int, data: bytes | str | int) -> bytes:
    """One protobuf field: a varint for an int, else length-delimited bytes."""
    if isinstance(data, int):
        return _varint(number << 3) + _varint(data)
    raw = data.encode() if isinstance(data, str) else data
    return _varint(number << 3 | 2) + _varint(len(raw)) + raw


def temperature_descriptor() -> bytes:
    """Return the FileDescriptorSet of ``thermoskin.Temperature`` (proto3), made by hand.

    message Temperature { double host_time = 1; double device_time = 2;
                          repeated float temperature = 3; repeated uint32 taxel = 4; }
    """
    double, float32, uint32, optional, repeated = 1, 2, 13, 1, 3
    fields = [("host_time", 1, optional, double), ("device_time", 2, optional, double),
              ("temperature", 3, repeated, float32), ("taxel", 4, repeated, uint32)]
    message = _field(1, "Temperature") + b"".join(
        _field(2, _field(1, name) + _field(3, num) + _field(4, label) + _field(5, kind))
        for name, num, label, kind in fields)
    file = (_field(1, "thermoskin/Temperature.proto") + _field(2, "thermoskin")
            + _field(4, message) + _field(12, "proto3"))
    return _field(1, file)


def encode_temperature(host_time: float, device_time: float, temperature: np.ndarray,
                       taxels: bytes) -> bytes:
    """Encode one sample as a ``thermoskin.Temperature`` protobuf message.

    ``taxels`` is the packed ``taxel`` field (`packed_ids`), made once per layout.
    """
    data = np.ascontiguousarray(temperature, dtype="<f4").tobytes()
    return (b"\x09" + struct.pack("<d", host_time) + b"\x11" + struct.pack("<d", device_time)
            + b"\x1a" + _varint(len(data)) + data + taxels)


def decode_temperature(data: bytes) -> dict[str, Any]:
    """Decode a ``thermoskin.Temperature`` message (as `encode_temperature` writes it)."""
    out: dict[str, Any] = {"host_time": 0.0, "device_time": 0.0,  # proto3 defaults
                           "temperature": np.zeros(0), "taxel": []}
    i = 0
    while i < len(data):
        key = data[i]
        i += 1
        if key in (0x09, 0x11):
            out["host_time" if key == 0x09 else "device_time"] = struct.unpack_from(
                "<d", data, i)[0]
            i += 8
            continue
        n = shift = 0
        while True:
            b = data[i]
            i += 1
            n |= (b & 0x7F) << shift
            shift += 7
            if b < 0x80:
                break
        body = data[i : i + n]
        i += n
        if key == 0x1A:
            out["temperature"] = np.frombuffer(body, dtype="<f4").astype(float)
        elif key == 0x22:
            ids, v, shift = [], 0, 0
            for b in body:
                v |= (b & 0x7F) << shift
                shift += 7
                if b < 0x80:
                    ids.append(v)
                    v = shift = 0
            out["taxel"] = ids
        else:
            raise ValueError(f"thermoskin.Temperature: unknown field key 0x{key:02X}")
    return out


def packed_ids(ids: Any) -> bytes:
    """Return the packed ``taxel`` field (4) of `encode_temperature` for taxel ids."""
    return _field(4, b"".join(_varint(int(i)) for i in ids))


def wire_descriptor() -> bytes:
    """Return the FileDescriptorSet of ``thermoskin.Wire`` (proto3)."""
    message = _field(1, "Wire") + _field(2, _field(1, "data") + _field(3, 1) + _field(4, 1)
                                          + _field(5, 12))
    file = (_field(1, "thermoskin/Wire.proto") + _field(2, "thermoskin") + _field(4, message)
            + _field(12, "proto3"))
    return _field(1, file)


def encode_wire(data: bytes) -> bytes:
    """Wrap raw bus bytes in a ``thermoskin.Wire`` message."""
    return _field(1, bytes(data))


def decode_wire(message: bytes) -> bytes:
    """Return the bytes of a ``thermoskin.Wire`` message.

    Raises
    ------
    ValueError
        If the message is not one (its field, or a length running past its end).
    """
    if not message:
        return b""
    if message[0] != 0x0A:
        raise ValueError(f"thermoskin.Wire: unknown field key 0x{message[0]:02X}")
    n = shift = 0
    i = 1
    while True:
        if i >= len(message):
            raise ValueError("thermoskin.Wire: the length runs past the message")
        b = message[i]
        i += 1
        n |= (b & 0x7F) << shift
        shift += 7
        if b < 0x80:
            break
    if i + n != len(message):
        raise ValueError(f"thermoskin.Wire: {n} bytes announced, {len(message) - i} there")
    return bytes(message[i:])

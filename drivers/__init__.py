"""Drivers: every source of frames behind one interface, opened by URL.

``open(url)`` understands:

- ``serial:///dev/ttyACM0?baud=1000000``: a board on a serial port (pyserial), speaking wire
  protocol v1 (`skin.drivers.protocol`); the driver also sends it commands;
- ``serial+loop://``, ``serial+socket://host:port``: any other pyserial URL;
- ``can://virtual/ch0``, ``can://socketcan/can0?bitrate=1000000``: protocol-v1 nodes on a CAN
  bus through python-can (``can://<interface>/<channel>``, any python-can interface);
- ``sim://default?speed=1&duration=20``: a simulated skin (a shipped scene name or a scene
  file path), frames handed over directly.

Replay of recordings comes with the drivers work.
"""

from __future__ import annotations

from urllib.parse import parse_qs, urlsplit

from skin.drivers.base import Driver
from skin.drivers.protocol import (
    CanReassembler,
    Command,
    LinkStats,
    MsgType,
    StreamDecoder,
    encode_sample,
)
from skin.errors import DeviceError

__all__ = ["CanReassembler", "Command", "Driver", "LinkStats", "MsgType", "StreamDecoder",
           "encode_sample", "open"]


def _query(query: str, url: str) -> dict[str, str]:
    out = {}
    for key, values in parse_qs(query, keep_blank_values=True).items():
        out[key] = values[-1]
    allowed = {"baud", "bitrate", "speed", "duration"}
    unknown = set(out) - allowed
    if unknown:
        raise DeviceError(f"{url}: unknown option {sorted(unknown)[0]!r} "
                          f"(known: {', '.join(sorted(allowed))})")
    return out


def _float(opts: dict[str, str], key: str, default: float | None, url: str) -> float | None:
    if key not in opts:
        return default
    try:
        return float(opts[key])
    except ValueError:
        raise DeviceError(f"{url}: option {key!r} must be a number, got {opts[key]!r}") from None


def open(url: str) -> Driver:
    """Open a frame source by URL (see the module docstring for the schemes).

    Raises
    ------
    DeviceError
        If the URL is malformed or the device cannot be opened.
    """
    if url.startswith("serial+"):
        from skin.drivers.serial_port import SerialDriver

        inner, _, query = url[len("serial+") :].partition("?")
        opts = _query(query, url)
        return SerialDriver(inner, baudrate=int(_float(opts, "baud", 1_000_000, url)))
    parts = urlsplit(url)
    opts = _query(parts.query, url)
    if parts.scheme == "serial":
        from skin.drivers.serial_port import SerialDriver

        if not parts.path:
            raise DeviceError(f"{url}: no port: write serial:///dev/ttyACM0")
        return SerialDriver(parts.path, baudrate=int(_float(opts, "baud", 1_000_000, url)))
    if parts.scheme == "can":
        from skin.drivers.can_bus import CanDriver

        channel = parts.path.lstrip("/")
        if not parts.netloc or not channel:
            raise DeviceError(f"{url}: write can://<interface>/<channel>, e.g. can://virtual/ch0")
        bitrate = _float(opts, "bitrate", None, url)
        return CanDriver(parts.netloc, channel, None if bitrate is None else int(bitrate))
    if parts.scheme == "sim":
        from skin.drivers.sim import SimDriver, SkinSimulator
        from skin.scene import load_scene

        scene = load_scene(parts.netloc + parts.path or "default")
        sim = SkinSimulator(scene, duration=_float(opts, "duration", None, url))
        return SimDriver(sim, speed=_float(opts, "speed", 1.0, url))
    raise DeviceError(f"{url}: unknown scheme {parts.scheme!r}: use serial://, serial+<pyserial "
                      f"URL>, can://, or sim://")

"""Drivers: every source of frames behind one interface, opened by URL.

``open(url)`` understands:

- ``serial:///dev/ttyACM0?baud=1000000``: a board on a serial port (pyserial), speaking wire
  protocol v1 (`skin.drivers.protocol`); the driver also sends it commands;
- ``serial+loop://``, ``serial+socket://host:port``: any other pyserial URL;
- ``can://virtual/ch0``, ``can://socketcan/can0?bitrate=1000000``: protocol-v1 nodes on a CAN
  bus through python-can (``can://<interface>/<channel>``, any python-can interface);
  ``can://udp_multicast/239.74.163.2?port=43113`` (or an IPv6 group, such as python-can's
  default ``ff15:7079:7468:6f6e:6465:6d6f:6d63:6173``) is a bus shared by processes over UDP
  multicast (it needs msgpack); ``port`` goes to the interfaces that take one; ``can://``
  alone (``?context=SECTION``) is the bus of python-can's own configuration (environment
  ``CAN_INTERFACE``/``CAN_CHANNEL``/``CAN_BITRATE``, ``~/.canrc``...: `skin.drivers.can_bus`);
- ``sim://default?speed=1&duration=20``: a simulated skin (a shipped scene name or a scene
  file path), frames handed over directly.
- ``replay://run.mcap?speed=0``: a recording (`skin.drivers.recording`) played through the same
  decoders (`skin.drivers.replay`); ``speed`` 1 (default) is real time, 0 as fast as possible;
  the path is relative (``replay://out/run.mcap``) or absolute (``replay:///data/run.mcap``).

Options every device URL takes: ``reconnect=S`` (seconds to keep reopening the device after
a fault, with back-off; 0, the default, raises at once), ``queue=N`` (read in a background
thread into a queue of N frames, `skin.drivers.reader.BackgroundReader`); serial URLs also take
``board=N`` (the board id given to the frames). ``open([url, url, ...])`` reads several boards
or buses in background threads into one queue: one skin, on one time base.
"""

from __future__ import annotations

from collections.abc import Sequence
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
    allowed = {"baud", "bitrate", "port", "speed", "duration", "board", "reconnect", "queue",
               "context"}
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


def _serial_options(opts: dict[str, str], url: str) -> dict:
    return {"baudrate": int(_float(opts, "baud", 1_000_000, url)),
            "board": int(_float(opts, "board", 0, url)),
            "reconnect": _float(opts, "reconnect", 0.0, url)}


def open(url: str | Sequence[str]) -> Driver:
    """Open a frame source by URL, or several as one (see the module docstring).

    Raises
    ------
    DeviceError
        If a URL is malformed or a device cannot be opened.
    """
    if not isinstance(url, str):
        from skin.drivers.reader import BackgroundReader

        opened: list[Driver] = []
        try:
            for one in url:
                opened.append(open(one))
        except BaseException:
            for driver in opened:
                driver.close()
            raise
        return BackgroundReader(opened)
    opts = _query(url.partition("?")[2], url)
    queue = _float(opts, "queue", None, url)
    driver = _open_one(url)
    if queue is not None:
        from skin.drivers.reader import BackgroundReader

        return BackgroundReader(driver, maxsize=int(queue))
    return driver


def _open_one(url: str) -> Driver:
    if url.startswith("serial+"):
        from skin.drivers.serial_port import SerialDriver

        inner, _, query = url[len("serial+") :].partition("?")
        opts = _query(query, url)
        return SerialDriver(inner, **_serial_options(opts, url))
    parts = urlsplit(url)
    opts = _query(parts.query, url)
    if parts.scheme == "serial":
        from skin.drivers.serial_port import SerialDriver

        if not parts.path:
            raise DeviceError(f"{url}: no port: write serial:///dev/ttyACM0")
        return SerialDriver(parts.path, **_serial_options(opts, url))
    if parts.scheme == "can":
        from skin.drivers.can_bus import CanDriver

        channel = parts.path.lstrip("/")
        configured = not parts.netloc and not channel  # python-can's configuration
        if not configured and (not parts.netloc or not channel):
            raise DeviceError(f"{url}: write can://<interface>/<channel>, e.g. can://virtual/ch0,"
                              " or can:// for python-can's configuration")
        if "context" in opts and not configured:
            raise DeviceError(f"{url}: 'context' picks a section of python-can's configuration;"
                              " it goes with can:// alone")
        bitrate = _float(opts, "bitrate", None, url)
        port = _float(opts, "port", None, url)
        return CanDriver(parts.netloc or None, channel or None,
                         None if bitrate is None else int(bitrate),
                         reconnect=_float(opts, "reconnect", 0.0, url),
                         port=None if port is None else int(port), context=opts.get("context"))
    if parts.scheme == "sim":
        from skin.drivers.sim import SimDriver, SkinSimulator
        from skin.formats.scene import load_scene

        scene = load_scene(parts.netloc + parts.path or "default")
        sim = SkinSimulator(scene, duration=_float(opts, "duration", None, url))
        return SimDriver(sim, speed=_float(opts, "speed", 1.0, url))
    if parts.scheme == "replay":
        from skin.drivers.replay import ReplayDriver, replay_path

        return ReplayDriver(replay_path(url), speed=_float(opts, "speed", 1.0, url))
    raise DeviceError(f"{url}: unknown scheme {parts.scheme!r}: use serial://, serial+<pyserial "
                      f"URL>, can://, sim:// or replay://")

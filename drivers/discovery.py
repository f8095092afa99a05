"""Find the boards that answer IDENTIFY, and check them against a layout (``skin devices``).

`serial_ports` lists the machine's serial ports (pyserial's ``list_ports``); `can_channels`
the CAN channels python-can detects (SocketCAN on Linux). `identify` opens one device URL and
asks who is there: on a serial port the board answers; on a CAN bus IDENTIFY is broadcast and
every node answers. `check` compares each board with the layout: its taxel count (channels
sampled) against the channels the layout wires, and its layout hash
(`skin.drivers.protocol.layout_hash` of the taxel ids in address order, 0 when the firmware was
built without one) against the layout's.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from skin._optional import require
from skin.drivers.protocol import CAN_BROADCAST, Command, Identity, MsgType, layout_hash
from skin.errors import DeviceError, ProtocolError
from skin.formats.layout import Layout

MCU_NAMES = {0: "host", 1: "ATmega328P", 2: "ATmega2560"}


@dataclass(frozen=True)
class Found:
    """A board that answered IDENTIFY.

    Attributes
    ----------
    url : str
        Where it answered (``serial://...``, ``can://...``).
    node : int or None
        Its CAN node number (None on a serial port).
    identity : Identity
        Its answer.
    """

    url: str
    node: int | None
    identity: Identity

    @property
    def firmware(self) -> str:
        """The firmware version, ``major.minor.patch``."""
        i = self.identity
        return f"{i.fw_major}.{i.fw_minor}.{i.fw_patch}"

    def record(self) -> dict:
        """Return a JSON-ready summary."""
        i = self.identity
        return {"url": self.url, "node": self.node, "board": i.board_id,
                "firmware": self.firmware, "mcu": MCU_NAMES.get(i.mcu, str(i.mcu)),
                "transport": "can" if i.transport else "serial", "taxels": i.taxels,
                "adc_bits": i.adc_bits, "oversampling": i.oversampling, "rate_hz": i.rate_hz,
                "max_rate_hz": i.max_rate_hz, "layout_hash": f"{i.layout_hash:08x}"}


def serial_ports() -> list[str]:
    """Return the device paths of the machine's serial ports (empty without pyserial)."""
    try:
        list_ports = require("serial.tools.list_ports", "listing serial ports")
    except ImportError:
        return []
    return sorted(p.device for p in list_ports.comports())


def can_channels(timeout: float = 2.0) -> list[str]:
    """Return ``can://`` URLs of the CAN channels python-can detects or is configured with.

    The configured one comes from the environment and python-can's config files (empty
    without python-can).
    """
    try:
        can = require("can", "listing CAN channels")
    except ImportError:
        return []
    found = can.detect_available_configs(["socketcan"], timeout=timeout)
    urls = sorted(f"can://{c['interface']}/{c['channel']}" for c in found)
    try:  # the bus python-can's configuration names (environment, ~/.canrc ...), if any
        config = can.util.load_config()
    except Exception:  # an unusable configuration: `skin devices --port can://` says why
        config = {}
    if config.get("interface") and config.get("channel") is not None:
        url = f"can://{config['interface']}/{config['channel']}"
        if url not in urls:
            urls.append(url)
    return urls


def identify(url: str, timeout: float = 0.5) -> list[Found]:
    """Ask the device(s) at ``url`` to identify themselves.

    Returns
    -------
    list of Found
        The board on a serial port, or every node of a CAN bus that answered within
        ``timeout`` s; empty if none did.

    Raises
    ------
    DeviceError
        If the URL cannot be opened.
    """
    from skin import drivers
    from skin.drivers.can_bus import CanDriver

    with drivers.open(url) as driver:
        if isinstance(driver, CanDriver):
            sent = driver.send(Command(MsgType.IDENTIFY), CAN_BROADCAST)
            answers: dict[int, Identity] = {}
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                driver.recv(timeout=0.02)  # reads the bus; replies gather in driver.replies
                while driver.replies:
                    node, reply = driver.replies.popleft()
                    if isinstance(reply, Identity) and reply.token == sent.token:
                        answers[node] = reply
            return [Found(driver.url, node, answers[node]) for node in sorted(answers)]
        try:
            reply = driver.request(Command(MsgType.IDENTIFY), timeout=timeout)
        except ProtocolError:
            return []
        except DeviceError:
            return []
        if not isinstance(reply, Identity):
            return []
        return [Found(driver.url, None, reply)]


def check(found: Found, layout: Layout) -> list[str]:
    """Return what disagrees between a board and the layout (empty if nothing does)."""
    i = found.identity
    where = found.url + ("" if found.node is None else f" node {found.node}")
    if i.board_id not in layout.boards:
        return [f"{where}: board {i.board_id} is not in {layout.source} "
                f"(its boards: {sorted(layout.boards)})"]
    idx, addr = layout.channel_map(i.board_id)
    problems = []
    wired = int(addr.max()) + 1 if len(addr) else 0
    if i.taxels < wired:
        beyond = [int(layout.ids[k]) for k, a in zip(idx, addr, strict=True) if a >= i.taxels]
        problems.append(f"{where}: board {i.board_id} samples {i.taxels} taxels but "
                        f"{layout.source} wires {wired} channels to it (taxels "
                        f"{beyond[:8]}{' ...' if len(beyond) > 8 else ''} are beyond)")
    elif i.taxels != len(idx):
        problems.append(f"{where}: board {i.board_id} samples {i.taxels} taxels, "
                        f"{layout.source} wires {len(idx)} of them")
    if i.layout_hash:
        expected = layout_hash(layout.ids[idx[addr.argsort()]].tolist())
        if i.layout_hash != expected:
            problems.append(f"{where}: board {i.board_id} was built for another layout "
                            f"(hash {i.layout_hash:08x}; {layout.source}: {expected:08x})")
    return problems

"""The serial driver: protocol frames from a serial port, through pyserial's ``serial_for_url``.

Any pyserial URL works: a device path (``/dev/ttyACM0``), a pseudo-terminal, ``loop://``,
``socket://host:port``.
"""

from __future__ import annotations

from collections import deque

from skin._optional import require
from skin.drivers.base import Driver
from skin.drivers.protocol import StreamDecoder
from skin.errors import DeviceError
from skin.frame import Frame


class SerialDriver(Driver):
    """Read sample frames from a serial port.

    Parameters
    ----------
    port : str
        A pyserial port name or URL.
    baudrate : int
        Line rate (ignored by pseudo-terminals and URL handlers).
    board : int
        Board id given to the frames.
    """

    def __init__(self, port: str, baudrate: int = 1_000_000, board: int = 0) -> None:
        super().__init__()
        serial = require("serial", "the serial driver")
        self.url = f"serial://{port}"
        self._serial_exception = serial.SerialException
        try:
            self._port = serial.serial_for_url(port, baudrate=baudrate, timeout=0.05)
        except (serial.SerialException, ValueError) as exc:
            raise DeviceError(f"{self.url}: cannot open: {exc}") from None
        self._decoder = StreamDecoder(board)
        self.stats = self._decoder.stats
        self._pending: deque[Frame] = deque()

    def _recv_internal(self, timeout: float | None) -> Frame | None:
        if not self._pending:
            self._port.timeout = timeout
            try:
                data = self._port.read(max(1, self._port.in_waiting))
            except (self._serial_exception, OSError) as exc:
                raise DeviceError(f"{self.url}: device stopped answering ({exc}); "
                                  f"{self.stats.frames} frames were received before") from None
            self._pending.extend(self._decoder.feed(data))
        return self._pending.popleft() if self._pending else None

    def _close_internal(self) -> None:
        self._port.close()

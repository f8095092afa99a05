"""The serial driver: protocol frames from a serial port, through pyserial's ``serial_for_url``.

Any pyserial URL works: a device path (``/dev/ttyACM0``), a pseudo-terminal, ``loop://``,
``socket://host:port``.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from typing import Any

from skin._optional import require
from skin.drivers.base import Driver
from skin.drivers.protocol import Command, ErrorReply, MsgType, Reply, StreamDecoder
from skin.errors import DeviceError, ProtocolError
from skin.frame import Frame

#: A sample held for its FORCE is handed on without it when the link is quiet and it has
#: waited this long, s, since its SAMPLE arrived (a FORCE comes right after its SAMPLE, a
#: USB frame or two later at most: 1-2 ms; a quiet read alone says nothing, recv(timeout=0)
#: polls between the two).
FORCE_WAIT = 0.02

def _type_name(kind: int) -> str:
    try:
        return MsgType(kind).name
    except ValueError:
        return f"type 0x{kind:02X}"


class SerialDriver(Driver):
    """Read sample frames from a serial port, and send the board commands.

    Not thread-safe: receive frames and send commands from one thread.

    Parameters
    ----------
    port : str
        A pyserial port name or URL.
    baudrate : int
        Line rate (ignored by pseudo-terminals and URL handlers).
    board : int
        Board id given to the frames.
    reconnect : float
        Seconds to keep reopening the port after it vanished (a board unplugged), with
        back-off (`skin.drivers.base`); 0 raises at once.

    Attributes
    ----------
    replies : collections.deque
        Replies received that no `request` or `wait_reply` has taken yet.
    """

    def __init__(self, port: str, baudrate: int = 1_000_000, board: int = 0,
                 reconnect: float = 0.0) -> None:
        super().__init__(reconnect)
        self._serial = require("serial", "the serial driver")
        self.url = f"serial://{port}"
        self._serial_exception = self._serial.SerialException
        self._name, self._baudrate = port, baudrate
        self._port = self._open()
        self._decoder = StreamDecoder(board)
        self.stats = self._decoder.stats
        self.replies: deque[Reply] = self._decoder.replies
        self._pending: deque[Frame] = deque()
        self._token = 0

    def _open(self) -> Any:  # a serial.Serial
        try:
            return self._serial.serial_for_url(self._name, baudrate=self._baudrate,
                                               timeout=0.05)
        except (self._serial_exception, ValueError, OSError) as exc:
            raise DeviceError(f"{self.url}: cannot open: {exc}") from None

    def _reopen(self) -> None:
        self._port = self._open()
        self._decoder.reset()  # a packet cut by the fault cannot be completed

    def _read(self, timeout: float | None) -> None:
        """Read what arrives within ``timeout`` s; queue its frames (replies queue themselves)."""
        try:
            self._port.timeout = timeout
            data = self._port.read(max(1, self._port.in_waiting))
        except (self._serial_exception, OSError) as exc:
            raise DeviceError(f"{self.url}: device stopped answering ({exc}); "
                              f"{self.stats.frames} frames were received before") from None
        if data and self.tap is not None:
            self.tap(time.monotonic(), data)
        self._pending.extend(self._decoder.feed(data))
        if not data:  # the link is quiet: a sample held for its FORCE this long gets none
            self._pending.extend(self._decoder.flush(older_than=FORCE_WAIT))

    def _recv_internal(self, timeout: float | None) -> Frame | None:
        if not self._pending:
            self._read(timeout)
        return self._pending.popleft() if self._pending else None

    def send(self, command: Command) -> Command:
        """Write a command packet to the board.

        A command with token 0 gets the driver's next token (1-255), so that 0 stays free for
        the errors of commands the board could not read.

        Returns
        -------
        Command
            The command as sent, with its token.

        Raises
        ------
        DeviceError
            If the port cannot be written.
        """
        if self._closed:
            raise DeviceError(f"{self.url}: the driver is closed")
        if not self.health.connected:
            raise DeviceError(f"{self.url}: disconnected ({self.health.last_fault})")
        if command.token == 0:
            self._token = self._token % 255 + 1
            command = dataclasses.replace(command, token=self._token)
        try:
            self._port.write(command.encode())
        except (self._serial_exception, OSError) as exc:
            raise DeviceError(f"{self.url}: cannot write a command ({exc})") from None
        return command

    def request(self, command: Command, timeout: float = 1.0) -> Reply:
        """Send a command and wait for its reply (ACK, or IDENTITY for IDENTIFY).

        Every sample frame that arrives meanwhile is kept for `recv`, in order.  A SELFTEST is
        answered by an ACK at once; its result follows: ``wait_reply(ack.token, timeout,
        SelftestResult)``.

        Raises
        ------
        ProtocolError
            If the board answers with an ERROR, or not within ``timeout`` seconds.
        """
        sent = self.send(command)
        return self.wait_reply(sent.token, timeout, command=sent.type)

    def wait_reply(self, token: int, timeout: float = 1.0, kind: type | None = None, *,
                   command: int | None = None) -> Reply:
        """Wait for the reply with ``token`` (of class ``kind``, if given), keeping every frame.

        An ERROR with ``token``, or one for a command the board could not read at all (token
        and command 0: most likely the one awaited, damaged on the way), raises.

        Parameters
        ----------
        token : int
            The token of the command sent.
        timeout : float
            Seconds to wait.
        kind : type, optional
            The reply class awaited (`skin.drivers.protocol.SelftestResult` ...); others with
            the same token stay in ``replies``.
        command : int, optional
            The command's type, for messages.

        Raises
        ------
        ProtocolError
            On an ERROR reply or when the time is up.
        """
        what = f"{_type_name(command) if command is not None else 'the command'} (token {token})"
        deadline = time.monotonic() + timeout
        while True:
            for reply in self.replies:
                unreadable = isinstance(reply, ErrorReply) and reply.token == reply.command == 0
                if (reply.token == token and (kind is None or isinstance(reply, kind)
                                              or isinstance(reply, ErrorReply))) or unreadable:
                    self.replies.remove(reply)
                    if isinstance(reply, ErrorReply):
                        raise ProtocolError(f"{self.url}: the board refused {what}: "
                                            f"{reply.name}, detail {reply.detail}")
                    return reply
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ProtocolError(f"{self.url}: no reply to {what} within {timeout:g} s")
            self._read(min(remaining, 0.05))

    def _close_internal(self) -> None:
        self._decoder.discard()  # a sample held for its FORCE: counted as lost
        self._port.close()

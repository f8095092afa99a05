"""Progress on stderr for long jobs: one status line, redrawn in place on a terminal."""

from __future__ import annotations

import sys
import time
from typing import TextIO

import numpy as np

_SHOWN: list[Progress] = []  # the progress whose status line is on screen (at most one)


def clear_status() -> None:
    """Clear the status line on screen, if any, so a message can take the whole line.

    Log records go through this (`skin.logs`): a driver's warning is never glued onto the
    status line; the next status redraws it.
    """
    for progress in _SHOWN:
        progress.clear()


class Progress:
    """One status line on stderr (redrawn in place on a terminal) plus printed messages.

    Off a terminal (a log file, CI) the status line is printed at most every ``every`` seconds,
    so logs stay short.
    """

    def __init__(self, stream: TextIO | None = None, every: float = 2.0) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.tty = self.stream.isatty()
        self.every = every
        self._last = -np.inf
        self._shown = False

    def status(self, text: str, now: float | None = None, force: bool = False) -> None:
        """Show ``text`` as the status line; ``now`` (s) paces it off a terminal.

        ``force`` prints it off a terminal even within ``every`` seconds of the last line (a
        final state must not be swallowed by the pacing).
        """
        now = time.monotonic() if now is None else now
        if self.tty:
            for other in [p for p in _SHOWN if p is not self]:
                other.clear()  # one status line at a time
            self.stream.write("\r\x1b[2K" + text)
            self.stream.flush()
            self._shown = True
            if self not in _SHOWN:
                _SHOWN.append(self)
        elif force or now - self._last >= self.every:
            self.stream.write(text + "\n")
            self.stream.flush()
            self._last = now

    def bar(self, done: int, total: int, label: str, started: float) -> None:
        """Show ``label [####----] done/total`` with the rate and the time left.

        The last state (``done == total``) is always printed, also off a terminal.
        """
        frac = done / total if total else 1.0
        elapsed = max(time.monotonic() - started, 1e-9)
        rate = done / elapsed
        left = (total - done) / rate if rate > 0 else float("inf")
        filled = round(20 * frac)
        eta = "?" if not np.isfinite(left) else f"{left:.0f}"
        self.status(f"{label} [{'#' * filled}{'-' * (20 - filled)}] {done}/{total} "
                    f"({rate:.2g}/s, {eta} s left)", force=done >= total)

    def clear(self) -> None:
        """Clear this status line if it is on screen (the next `status` redraws it)."""
        if self._shown:
            self.stream.write("\r\x1b[2K")
            self.stream.flush()
            self._forget()

    def message(self, text: str) -> None:
        """Print ``text`` on its own line, clearing the status line first."""
        self.clear()
        self.stream.write(text + "\n")
        self.stream.flush()

    def done(self) -> None:
        """End the status line."""
        if self._shown:
            self.stream.write("\n")
            self._forget()

    def _forget(self) -> None:
        self._shown = False
        if self in _SHOWN:
            _SHOWN.remove(self)

"""Progress on stderr for long jobs: one status line, redrawn in place on a terminal."""

from __future__ import annotations

import sys
import time
from typing import TextIO

import numpy as np


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

    def status(self, text: str, now: float | None = None) -> None:
        """Show ``text`` as the status line; ``now`` (s) paces it off a terminal."""
        now = time.monotonic() if now is None else now
        if self.tty:
            self.stream.write("\r\x1b[2K" + text)
            self.stream.flush()
            self._shown = True
        elif now - self._last >= self.every:
            self.stream.write(text + "\n")
            self.stream.flush()
            self._last = now

    def bar(self, done: int, total: int, label: str, started: float) -> None:
        """Show ``label [####----] done/total`` with the rate and the time left."""
        frac = done / total if total else 1.0
        elapsed = max(time.monotonic() - started, 1e-9)
        rate = done / elapsed
        left = (total - done) / rate if rate > 0 else float("inf")
        filled = round(20 * frac)
        self.status(f"{label} [{'#' * filled}{'-' * (20 - filled)}] {done}/{total} "
                    f"({rate:.0f}/s, {left:.0f} s left)")

    def message(self, text: str) -> None:
        """Print ``text`` on its own line, clearing the status line first."""
        if self._shown:
            self.stream.write("\r\x1b[2K")
            self._shown = False
        self.stream.write(text + "\n")
        self.stream.flush()

    def done(self) -> None:
        """End the status line."""
        if self._shown:
            self.stream.write("\n")
            self._shown = False

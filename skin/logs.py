"""Logging of the ``skin`` command: ``-v`` on the terminal, ``--log-file`` in a file.

Every module logs to a logger under ``skin`` (``skin.drivers``, ``skin.runner``...). On the
terminal, records go out on their own line: the status line (`skin.progress`) is cleared first
and redrawn by the next status, so a warning is never glued onto it. Warnings and errors are
shown by default; ``-v`` adds information, ``-vv`` debugging. A log file gets information and
up (debugging with ``-vv``), with times, whatever the terminal shows.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from skin.errors import SkinError
from skin.progress import clear_status

LEVELS = (logging.WARNING, logging.INFO, logging.DEBUG)


class TerminalHandler(logging.StreamHandler):
    """Write each record on its own line of stderr, clearing the status line first."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    def emit(self, record: logging.LogRecord) -> None:
        """Clear the status line, then write the record."""
        self.stream = sys.stderr  # the stderr of now (tests swap it)
        clear_status()
        super().emit(record)


def configure_logging(verbose: int = 0, log_file: str | Path | None = None) -> None:
    """Send the ``skin`` loggers to the terminal (and to ``log_file``); idempotent.

    Parameters
    ----------
    verbose : int
        0: warnings and errors; 1: information too; 2 or more: debugging too.
    log_file : str or Path, optional
        A file that gets information and up (debugging at ``verbose >= 2``), appended to.
    """
    logger = logging.getLogger("skin")
    for handler in list(logger.handlers):
        if getattr(handler, "_skin", False):
            logger.removeHandler(handler)
            handler.close()
    terminal_level = LEVELS[min(max(verbose, 0), len(LEVELS) - 1)]
    terminal = TerminalHandler()
    terminal.setLevel(terminal_level)
    terminal.setFormatter(logging.Formatter("%(name)s: %(levelname)s: %(message)s"))
    handlers: list[logging.Handler] = [terminal]
    level = terminal_level
    if log_file is not None:
        try:
            file = logging.FileHandler(log_file, encoding="utf-8")
        except OSError as exc:
            raise SkinError(f"--log-file {log_file}: cannot open it: {exc.strerror}") from None
        file.setLevel(min(logging.INFO, terminal_level))
        file.setFormatter(logging.Formatter(
            "%(asctime)s %(name)s %(levelname)s: %(message)s"))
        handlers.append(file)
        level = min(level, file.level)
    for handler in handlers:
        handler._skin = True  # type: ignore[attr-defined]
        logger.addHandler(handler)
    logger.setLevel(level)
    logger.propagate = False

"""Where the pipeline's results go: sinks that take each `ContactResult` as it is given.

A sink has one method, ``write(result)``; `skin.stream.pipeline.Pipeline` hands every result to each
of its sinks in order. `JsonLinesSink` appends one JSON object per contact to a file (flushed
at once, so a killed run keeps every contact already decided); `TerminalSink` prints a line
per contact. Recordings (MCAP) and the live arm view are sinks of the same kind.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, TextIO

from skin.progress import Progress
from skin.stream.pipeline import ContactResult


def event_record(result: ContactResult) -> dict[str, Any]:
    """Return the JSON-ready record of one result (one line of ``events.jsonl``).

    Times without a prefix are the board's device time, s; ``host_onset``, ``host_release``,
    ``host_decided_at`` and ``host_reported_at`` are the same instants on the host's wall
    clock (Unix time, s, mapped through each board's clock map: `skin.drivers.clock`), the
    time base of a robot's own logs; None when the source gave no host time.
    """
    from skin.drivers.clock import wall_time

    c, e, h = result.contact, result.estimate, result.host
    rec: dict[str, Any] = {
        "contact": c.id,
        "taxels": c.taxels,
        "onset": round(c.onset, 4),
        "release": None if c.release is None else round(c.release, 4),
        "duration": None if c.duration is None else round(c.duration, 4),
        "decided_at": round(c.decided_at, 4),
        "final": c.final,
        "reported_at": round(result.reported_at, 4),
        "label": e.label,
        "confidence": round(e.confidence, 3),
        "family": e.family,
        "family_confidence": round(e.family_confidence, 3),
        "probabilities": {k: round(v, 4) for k, v in sorted(e.probabilities.items(),
                                                            key=lambda kv: -kv[1])},
        "effusivity": None if e.effusivity is None else round(e.effusivity, 1),
        "method": e.method,
        "note": e.note or None,
        "initial_temperature": {str(w.taxel): round(w.initial, 3) for w in c.windows},
        "dated_by": "+".join(sorted({w.dated_by for w in c.windows})) or None,
        "ambient": round(c.ambient, 3),
        "host_onset": None if h is None else round(wall_time(h.onset), 6),
        "host_release": None if h is None or h.release is None
        else round(wall_time(h.release), 6),
        "host_decided_at": None if h is None else round(wall_time(h.decided_at), 6),
        "host_reported_at": None if h is None else round(wall_time(h.reported_at), 6),
    }
    return rec


def contact_line(rec: dict[str, Any]) -> str:
    """Return a line of text for a record of `event_record` (with its ``truth``, if any)."""
    eff = "-" if rec["effusivity"] is None else f"{rec['effusivity']:.0f}"
    line = (f"contact {rec['contact']:3d}{' ' if rec['final'] else '~'} t={rec['onset']:7.2f} s  "
            f"taxels {','.join(map(str, rec['taxels'])):<16s} {rec['label']:<11s} "
            f"{rec.get('family') or '-':<14s} e={eff:>6s}")
    if "truth" in rec:
        line += f"  truth {rec['truth']:<11s} {'ok' if rec['truth'] == rec['label'] else 'x'}"
    return line


class JsonLinesSink:
    """Append each result to a JSON-lines file, one object per line, flushed at once.

    Parameters
    ----------
    path : str or Path
        The file; created (or emptied) on opening.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file: TextIO = self.path.open("w", encoding="utf-8")

    def write(self, result: ContactResult) -> None:
        """Append ``result``."""
        self._file.write(json.dumps(event_record(result)) + "\n")
        self._file.flush()

    def close(self) -> None:
        """Close the file (idempotent)."""
        self._file.close()

    def __enter__(self) -> JsonLinesSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class TerminalSink:
    """Print a line per result through a `Progress` (above its status line)."""

    def __init__(self, progress: Progress) -> None:
        self.progress = progress

    def write(self, result: ContactResult) -> None:
        """Print ``result``."""
        self.progress.message(contact_line(event_record(result)))

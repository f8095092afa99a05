"""Skin files (``skin.toml``): one declared setup that ``skin run`` and `skin.Skin` share.

A skin file has up to four tables, each holding fields of `skin.setup.Setup` (``GROUPS``)::

    [source]
    port = "replay://run.mcap?speed=0"   # or a list of URLs; none: the simulated skin
    [skin]
    calibration = "cal.json"
    [classifier]
    model = "model.skops"
    window = 2.0
    [output]
    out = "out/run"
    sinks = ["events", "contacts.jsonl"]

Relative paths are relative to the file's folder. Every value is checked on load; an error
names the file, the line and the field. Values given on the command line (or as keywords of
`skin.Skin`) override the file's.
"""

from __future__ import annotations

import os
import re
import tomllib
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from skin.setup import GROUPS, PATHS, Setup, SetupError

SKIN_FILE = "skin.toml"
"""The skin file ``skin run`` reads from the working directory when it is there."""

_HEADER = re.compile(r"^[ \t]*\[[ \t]*([A-Za-z0-9_-]+)[ \t]*\][ \t]*(#.*)?$")
_KEY = re.compile(r"^[ \t]*([A-Za-z0-9_-]+)[ \t]*=")


def find_skin_file(folder: str | Path = ".") -> Path | None:
    """Return ``folder/skin.toml`` if it is a file, else None."""
    path = Path(folder) / SKIN_FILE
    return path if path.is_file() else None


def load_skin_file(path: str | Path, setup: Setup | None = None) -> Setup:
    """Load a skin file onto ``setup`` (default: the defaults).

    Raises
    ------
    SetupError
        Naming the file, the line and the field of the first problem.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise SetupError(f"{p}: cannot read skin file: {exc.strerror}") from None
    return parse_skin_file(text, str(p), p.parent.absolute(), setup)


def parse_skin_file(text: str, source: str = "<string>", base: Path | None = None,
                    setup: Setup | None = None) -> Setup:
    """Parse skin file text; relative paths are taken from ``base`` (see `load_skin_file`)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SetupError(f"{source}: not valid TOML: {exc}") from None
    lines = _key_lines(text)
    group_of = {name: group for group, names in GROUPS.items() for name in names}
    values: dict[str, Any] = {}
    origin: dict[str, str] = {}
    for group, table in data.items():
        line = lines.get((group, ""), lines.get(("", group), 0))
        if group not in GROUPS:
            raise SetupError(f"{source}:{line}: unknown table [{group}] (tables: "
                             f"{', '.join(f'[{g}]' for g in GROUPS)})")
        if not isinstance(table, dict):
            raise SetupError(f"{source}:{line}: {group} must be a table: [{group}]")
        for name, value in table.items():
            at = f"{source}:{lines.get((group, name), line)}"
            if name not in GROUPS[group]:
                home = group_of.get(name)
                hint = (f"it belongs in [{home}]" if home else
                        f"[{group}] holds {', '.join(GROUPS[group])}")
                raise SetupError(f"{at}: unknown field {name!r} in [{group}]: {hint}")
            values[name] = _relative(name, value, base) if base is not None else value
            origin[name] = at
    return (Setup() if setup is None else setup).updated(values, origin)


def _key_lines(text: str) -> dict[tuple[str, str], int]:
    """(table, key) -> 1-based line of each ``key =`` (and (table, "") of each header)."""
    out: dict[tuple[str, str], int] = {}
    table = ""
    depth = 0  # inside a multi-line array, keys are not keys
    for number, line in enumerate(text.splitlines(), start=1):
        code = line.split("#", 1)[0]
        if depth == 0:
            header = _HEADER.match(line)
            if header:
                table = header.group(1)
                out.setdefault((table, ""), number)
                continue
            key = _KEY.match(code)
            if key:
                out.setdefault((table, key.group(1)), number)
        depth = max(depth + code.count("[") - code.count("]"), 0)
    return out


def _relative(name: str, value: Any, base: Path) -> Any:
    """Make the relative paths of field ``name`` relative to ``base`` (see `PATHS`)."""
    kind = PATHS.get(name)
    if kind is None:
        return value
    if isinstance(value, list):
        return [_relative(name, v, base) for v in value]
    if not isinstance(value, str) or not value:
        return value  # the setup's check names the problem
    if kind == "url":
        parts = urlsplit(value)
        if parts.scheme != "replay" or not parts.netloc:  # replay:///abs is absolute already
            return value
        path = os.path.normpath(base.absolute() / (parts.netloc + parts.path))
        return f"replay://{Path(path).as_posix()}" + (f"?{parts.query}" if parts.query else "")
    p = Path(value)
    if p.is_absolute():
        return value
    if kind == "name" and not p.suffix and len(p.parts) == 1 and not (base / p).is_file():
        return value  # a shipped layout or scene
    if kind == "jsonl" and p.suffix != ".jsonl":
        return value
    return os.path.normpath(base / p)

"""Helpers shared by the TOML data files (layouts, scenes, materials): reading, checks, lines."""

from __future__ import annotations

import math
import re
from importlib import resources
from pathlib import Path
from typing import Any

from skin.errors import SkinError


def read_data_file(
    path: str | Path, folder: str, what: str, error: type[SkinError]
) -> tuple[str, str, Path | None]:
    """Read a TOML data file: a path, or the name of a file in ``skin/data/<folder>``.

    Parameters
    ----------
    path : str or Path
        A file path, or a bare name such as ``"arm"`` for ``skin/data/<folder>/arm.toml``.
    folder : str
        Folder of the shipped files (``"layouts"``, ``"scenes"``).
    what : str
        What the file is, for messages (``"layout"``).
    error : type
        The `SkinError` subclass to raise.

    Returns
    -------
    text : str
        The file's text.
    source : str
        The name to use in messages.
    folder : Path or None
        The folder of a user's file (for relative references), None for a shipped one.
    """
    p = Path(path)
    # a bare name (no folder, no suffix) that is not a file names a shipped one: a folder of
    # that name in the working directory does not hide it
    if not p.suffix and len(p.parts) == 1 and not p.is_file():
        res = resources.files("skin") / "data" / folder / f"{p.name}.toml"
        if not res.is_file():
            raise error(f"no {what} file {str(path)!r} and no shipped {what} of that name")
        return res.read_text(encoding="utf-8"), f"{p.name}.toml", None
    try:
        return p.read_text(encoding="utf-8"), str(path), p.parent
    except OSError as exc:
        raise error(f"{path}: cannot read {what}: {exc.strerror}") from None


def is_number(value: Any) -> bool:
    """Return True for a finite int or float (TOML's booleans are not numbers here)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def header_lines(text: str, name: str) -> list[int]:
    """Return the 1-based line of each ``[[name]]`` array-of-tables header (comments skipped)."""
    pattern = re.compile(rf"^[ \t]*\[\[[ \t]*{re.escape(name)}[ \t]*\]\]", re.MULTILINE)
    return [text.count("\n", 0, m.start()) + 1 for m in pattern.finditer(text)]

"""Touch labels: when a recording's touches happened, where, and what was touched.

A label file is a CSV file with a header line::

    time,material[,taxels][,group]

- ``time``: s, the touch's start on the boards' device clock (the time base of ``onset`` in
  ``events.jsonl`` and in a recording's ``/events``);
- ``material``: a name of the materials table (``skin materials``; ``unknown`` is refused:
  leave such touches out);
- optional ``taxels``: the taxel ids touched, separated by spaces or ``;``, or ``all``
  (empty: not said; `skin commission` then fits every taxel, `skin dataset import` pairs the
  label with the nearest contact anywhere);
- optional ``group``: an integer that keeps touches of one object, session or day together
  when a dataset is split for evaluation (default: one group per touch).

Columns may come in any order; lines starting with ``#`` are comments. One format serves
both `skin dataset import run.mcap --labels` and `skin commission --labels`.

`read_touch_labels` checks every row and raises `TouchLabelError` naming the file, the line
and the field; `scene_labels` writes the touches of a scene (what a simulated run touched)
in the same layout, so a simulated recording can be labelled as a real one is.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from skin.errors import SkinError

COLUMNS = ("time", "material", "taxels", "group")


class TouchLabelError(SkinError):
    """A label file that cannot be read; the message names the file, line and field."""


@dataclass(frozen=True)
class TouchLabel:
    """One labelled touch.

    Attributes
    ----------
    time : float
        Start, s (device time).
    material : str
        The material touched.
    taxels : tuple of int
        The taxels touched; empty: not said.
    group : int or None
        Evaluation group; None: the touch's own.
    line : int
        Line in the label file (0: not from a file).
    """

    time: float
    material: str
    taxels: tuple[int, ...] = ()
    group: int | None = None
    line: int = 0


def read_touch_labels(path: str | Path, materials: dict | None = None,
                      layout: Any = None) -> list[TouchLabel]:
    """Read a label file (module docstring), sorted by time.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    materials : dict, optional
        The materials table names are checked against; default the shipped table.
    layout : skin.formats.layout.Layout, optional
        When given, every taxel id must be one of its taxels, and ``all`` names them all
        (without a layout, ``all`` is the same as empty: not said).

    Raises
    ------
    TouchLabelError
        Missing file or column, an unknown material, a bad number or taxel id (with the line),
        or no label at all.
    """
    from skin.models.materials import load_materials

    path = Path(path)
    table = load_materials() if materials is None else materials
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise TouchLabelError(f"{path}: cannot read the label file ({exc.strerror})") from None
    lines = [(no, line) for no, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise TouchLabelError(f"{path}: empty; a label file has a header "
                              f"(time,material[,taxels][,group]) and one line per touch")
    numbers = [no for no, _ in lines]
    reader = csv.DictReader(line for _, line in lines)
    fields = [f.strip() for f in (reader.fieldnames or [])]
    head = numbers[0]
    missing = [c for c in COLUMNS[:2] if c not in fields]
    if missing:
        raise TouchLabelError(f"{path}: line {head}: missing column(s) {', '.join(missing)}; the "
                              f"layout is time,material[,taxels][,group]")
    unknown = [c for c in fields if c not in COLUMNS]
    if unknown:
        raise TouchLabelError(f"{path}: line {head}: unknown column(s) {', '.join(unknown)}; the "
                              f"layout is time,material[,taxels][,group]")
    ids = None if layout is None else [int(t) for t in layout.ids]
    labels = []
    for k, raw in enumerate(reader, start=1):
        line = numbers[k]
        row = {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}
        where = f"{path}: line {line}"
        try:
            time = float(row["time"])
        except ValueError:
            raise TouchLabelError(f"{where}: time {row['time']!r} is not a number") from None
        if not math.isfinite(time):
            raise TouchLabelError(f"{where}: time {row['time']!r} is not finite")
        material = row["material"]
        if material not in table:
            raise TouchLabelError(f"{where}: material {material!r} is not in the materials "
                                  f"table (known: {', '.join(sorted(table))})")
        taxels: tuple[int, ...] = ()
        field = row.get("taxels") or ""
        if field == "all":
            taxels = () if ids is None else tuple(ids)
        elif field:
            try:
                taxels = tuple(int(t) for t in field.replace(";", " ").split())
            except ValueError:
                raise TouchLabelError(f"{where}: taxels {field!r} are not integer ids "
                                      f"separated by spaces or ';', nor 'all'") from None
            unknown = [t for t in taxels if ids is not None and t not in ids]
            if unknown:
                raise TouchLabelError(f"{where}: taxel {unknown[0]} is not in layout "
                                      f"{layout.name}")
        group = None
        if row.get("group"):
            try:
                group = int(row["group"])
            except ValueError:
                raise TouchLabelError(f"{where}: group {row['group']!r} is not an "
                                      f"integer") from None
        labels.append(TouchLabel(time, material, taxels, group, line))
    if not labels:
        raise TouchLabelError(f"{path}: no label after the header (one line per touch)")
    return sorted(labels, key=lambda lab: lab.time)


def write_touch_labels(path: str | Path, labels: list[TouchLabel]) -> Path:
    """Write labels in the layout of the module docstring; return the path."""
    path = Path(path)
    rows = ["time,material,taxels,group"]
    for lab in labels:
        group = "" if lab.group is None else str(lab.group)
        rows.append(f"{lab.time:.4f},{lab.material},{' '.join(map(str, lab.taxels))},{group}")
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def scene_labels(scene, duration: float | None = None) -> list[TouchLabel]:
    """Return the labels of a scene's touches (those starting before ``duration`` s).

    Each touch's group is its object's index in the scene, so a split keeps every touch of
    one object on the same side.
    """
    index = {name: i for i, name in enumerate(scene.objects)}
    return [TouchLabel(t.start, scene.objects[t.object].material, tuple(t.taxels),
                       index[t.object], t.line)
            for t in scene.touches if duration is None or t.start < duration]

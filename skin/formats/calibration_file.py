"""Per-taxel calibration files: what `skin calibrate` fitted, keyed by taxel id.

A calibration file is JSON::

    {"format": 1, "created": "2026-11-22T08:50:00+00:00", "ambient_offset": 0.0,
     "references": {"thermistor": "refs.csv (20.0, 30.0, 40.0 C)", "thermal": "water"},
     "boards": {"0": {"divider_resistor": 667.4, "supply_voltage": 5.04}},
     "taxels": {"0": {"thermistor": [c0, c1, c2], "diffusivity": ..., "conductivity": ...,
                      "depth": ..., "heater_resistance": ...}, ...}}

Every taxel entry may hold the thermistor's Steinhart-Hart coefficients, the sensor's thermal
constants, its heater's resistance, or any of them; a board entry the divider's measured
constants (``divider_resistor``, ``supply_voltage``, ``adc_reference``) and the heaters'
resistance; what an entry lacks falls back to the layout's nominal board constants. `apply` turns a
file into the vectorised `skin.stream.calibration.Calibration` and the per-taxel sensor constants of
a layout, and says which taxels the file does not cover, so that they are flagged, never
silently treated as calibrated.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.stream.calibration import Calibration

FORMAT = 1
THERMAL = ("diffusivity", "conductivity", "depth")
#: What commissioning measures per taxel from a quiet stretch (`skin commission`).
NOISE = ("noise_sigma", "noise_lowfreq")
#: Measured board constants a calibration file may hold (`skin calibrate board`).
BOARD = ("divider_resistor", "supply_voltage", "adc_reference", "heater_resistance")


class CalibrationFileError(SkinError):
    """A calibration file is unreadable or inconsistent (the message names file and taxel)."""


@dataclass
class CalibrationFile:
    """Per-taxel calibration.

    Attributes
    ----------
    taxels : dict
        Taxel id -> dict with any of ``thermistor`` ([c0, c1, c2]), ``diffusivity``,
        ``conductivity``, ``depth`` and fit diagnostics.
    references : dict
        What each part was fitted from.
    boards : dict
        Board id -> dict with any of `BOARD`'s measured constants.
    ambient_offset : float
        Added to the ambient sensor's reading, K.
    created : str
        ISO date and time of the last change.
    """

    taxels: dict[int, dict[str, Any]] = field(default_factory=dict)
    references: dict[str, str] = field(default_factory=dict)
    ambient_offset: float = 0.0
    created: str = ""
    boards: dict[int, dict[str, float]] = field(default_factory=dict)

    def save(self, path: str | Path) -> Path:
        """Write the file (JSON), stamping the date."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        self.created = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
        path.write_text(json.dumps(self.document(), indent=1) + "\n", encoding="utf-8")
        return path

    def document(self) -> dict[str, Any]:
        """Return the file's JSON document (what `save` writes, with the current date)."""
        return {"format": FORMAT, "created": self.created, "ambient_offset": self.ambient_offset,
                "references": self.references,
                "boards": {str(k): v for k, v in sorted(self.boards.items())},
                "taxels": {str(k): v for k, v in sorted(self.taxels.items())}}

    def missing(self, layout: Layout, part: str) -> list[int]:
        """Ids of the layout's taxels without ``part`` (``"thermistor"`` or ``"thermal"``)."""
        keys = ("thermistor",) if part == "thermistor" else THERMAL[:2]
        return [int(t.id) for t in layout.taxels
                if not all(k in self.taxels.get(int(t.id), {}) for k in keys)]

    def board(self, layout: Layout, board: int) -> Any:
        """Return the layout's `skin.formats.layout.Board` with this file's measured constants."""
        return dataclasses.replace(layout.boards[board], **self.boards.get(board, {}))

    def apply(self, layout: Layout) -> tuple[Calibration, list]:
        """Return the layout's `Calibration` and per-taxel `SensorConstants` from this file.

        Taxels the file does not cover keep their board's constants (see `missing`).
        """
        from skin.models.physics import SensorConstants

        boards = {b: self.board(layout, b) for b in layout.boards}
        measured = Layout(layout.taxels, list(boards.values()), name=layout.name,
                          source=layout.source)
        cal = Calibration.from_layout(measured)
        c = np.vstack([cal.c0, cal.c1, np.zeros_like(cal.c0)]).T.copy()
        sensors = []
        for i, t in enumerate(layout.taxels):
            entry = self.taxels.get(int(t.id), {})
            if "thermistor" in entry:
                c[i] = entry["thermistor"]
            s = SensorConstants.from_board(boards[t.board])
            sensors.append(dataclasses.replace(
                s, **{k: float(entry[k]) for k in (*THERMAL, "heater_resistance")
                      if k in entry}))
        cal = dataclasses.replace(cal, c0=c[:, 0], c1=c[:, 1], c2=c[:, 2],
                                  source=f"calibration file ({self.created})")
        return cal, sensors


def noise_sigma(cal: CalibrationFile | None, layout: Layout) -> np.ndarray | None:
    """Each taxel's commissioned noise per sample, K, in layout order; None if none has one.

    Taxels without one get their board's sensor's noise (`skin.models.sensors`).
    """
    if cal is None or not any("noise_sigma" in e for e in cal.taxels.values()):
        return None
    from skin.models.sensors import SensorDescription

    out = []
    for t in layout.taxels:
        entry = cal.taxels.get(int(t.id), {})
        if "noise_sigma" in entry:
            out.append(float(entry["noise_sigma"]))
        else:
            s = SensorDescription.from_board(layout.boards[t.board])
            out.append(s.delivered_noise(25.0 + s.heated_rise))
    return np.array(out)


def load_calibration(path: str | Path) -> CalibrationFile:
    """Read and check a calibration file; errors name the file, the key and the taxel."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CalibrationFileError(f"{path}: no such calibration file") from None
    return parse_calibration(text, str(path))


def parse_calibration(text: str, source: str = "<string>") -> CalibrationFile:
    """Check calibration file text (as `load_calibration`); errors name ``source``."""
    path = source
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibrationFileError(f"{path}, line {exc.lineno}: not JSON ({exc.msg})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise CalibrationFileError(f"{path}: not a calibration file of format {FORMAT} "
                                   f"(format {found})")
    taxels: dict[int, dict[str, Any]] = {}
    for key, entry in (doc.get("taxels") or {}).items():
        tid = _id(path, "taxel", key)
        if not isinstance(entry, dict):
            raise CalibrationFileError(f"{path}: taxel {tid}: entry must be an object")
        if "thermistor" in entry:
            coef = entry["thermistor"]
            if (not isinstance(coef, list) or len(coef) != 3
                    or not all(isinstance(v, int | float) for v in coef) or coef[1] <= 0):
                raise CalibrationFileError(f"{path}: taxel {tid}: 'thermistor' must be three "
                                           f"numbers [c0, c1, c2] with c1 > 0, got {coef!r}")
        if "drift" in entry and not (isinstance(entry["drift"], int | float)
                                     and np.isfinite(entry["drift"])):
            raise CalibrationFileError(f"{path}: taxel {tid}: 'drift' must be a number (K/s), "
                                       f"got {entry['drift']!r}")
        for k in (*THERMAL, "heater_resistance", *NOISE):
            if k in entry and not _positive(entry[k]):
                raise CalibrationFileError(f"{path}: taxel {tid}: {k!r} must be a positive "
                                           f"number, got {entry[k]!r}")
        taxels[tid] = entry
    boards: dict[int, dict[str, float]] = {}
    for key, entry in (doc.get("boards") or {}).items():
        bid = _id(path, "board", key)
        if not isinstance(entry, dict) or set(entry) - set(BOARD):
            raise CalibrationFileError(f"{path}: board {bid}: entry must be an object with "
                                       f"any of {', '.join(BOARD)}, got {entry!r}")
        for k, v in entry.items():
            if not _positive(v):
                raise CalibrationFileError(f"{path}: board {bid}: {k!r} must be a positive "
                                           f"number, got {v!r}")
        boards[bid] = {k: float(v) for k, v in entry.items()}
    offset = doc.get("ambient_offset", 0.0)
    if not isinstance(offset, int | float) or not np.isfinite(offset):
        raise CalibrationFileError(f"{path}: 'ambient_offset' must be a number, got {offset!r}")
    return CalibrationFile(taxels, dict(doc.get("references") or {}), float(offset),
                           str(doc.get("created", "")), boards)


def _id(path: str, what: str, key: str) -> int:
    try:
        return int(key)
    except ValueError:
        raise CalibrationFileError(f"{path}: {what} id {key!r} is not an integer") from None


def _positive(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and 0 < value < np.inf

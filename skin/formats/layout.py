"""Taxel layout: where every taxel sits, how it is wired, and the hardware constants of its board.

A layout is a TOML file with one ``[[boards]]`` table per board and one ``[[taxels]]`` table
per taxel.  It is validated on load; every error names the file, the taxel and the field.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from skin.errors import LayoutError
from skin.formats.datafiles import header_lines, is_number, read_data_file


@dataclass(frozen=True)
class Board:
    """Hardware constants shared by all taxels of one board (defaults: the paper's rig).

    Attributes
    ----------
    id : int
        Board id, as it appears in frames.
    divider_resistor : float
        R_REF of the thermistor voltage divider, ohm.
    adc_bits : int
        ADC resolution in bits.
    adc_reference : float
        ADC reference voltage, V.
    supply_voltage : float
        Divider supply voltage V+, V.
    heater_resistance : float
        Heater resistance, ohm.
    heater_voltage : float
        Heater supply voltage, V.
    thermistor_c0, thermistor_c1 : float
        Two-term Steinhart-Hart coefficients, 1/T = C0 + C1 ln R (T in K).
    sensor_depth : float
        Thermistor depth below the contact surface, m.
    sensor_diffusivity : float
        Thermal diffusivity of the sensor body, m^2/s.
    sensor_conductivity : float
        Thermal conductivity of the sensor body, W/(m K).
    heater_area : float
        Heater area, m^2.
    sensor_thickness : float
        Sensor body thickness, m.
    sample_rate : float
        Sampling rate, Hz.
    sensor : str
        The board's sensor description: a preset name or a sensor file
        (`skin.models.sensors`); its constants fill the fields the board does not set.
        Empty: the paper's sensor, with the board's constants.
    """

    id: int = 0
    divider_resistor: float = 668.0
    adc_bits: int = 10
    adc_reference: float = 1.1
    supply_voltage: float = 5.06
    heater_resistance: float = 19.7
    heater_voltage: float = 2.5
    thermistor_c0: float = 9.5594e-4
    thermistor_c1: float = 2.6181e-4
    sensor_depth: float = 8e-5
    sensor_diffusivity: float = 2.796e-9
    sensor_conductivity: float = 0.0349
    heater_area: float = 1.5625e-4
    sensor_thickness: float = 2.4e-4
    sample_rate: float = 200.0
    sensor: str = ""

    @property
    def adc_max(self) -> int:
        """Largest ADC count."""
        return (1 << self.adc_bits) - 1


@dataclass(frozen=True)
class Taxel:
    """One taxel: identity, wiring and pose on its link.

    Attributes
    ----------
    id : int
        Unique taxel id.
    board : int
        Id of the board it is wired to.
    address : int
        Channel on that board (index into ``Frame.counts``).
    link : str
        Name of the robot link it sits on.
    position : tuple of float
        Position in the link frame, m.
    normal : tuple of float
        Outward unit normal in the link frame.
    """

    id: int
    board: int
    address: int
    link: str
    position: tuple[float, float, float]
    normal: tuple[float, float, float]


_BOARD_FIELDS = {name: typ for name, typ in Board.__annotations__.items()}
_TAXEL_REQUIRED = ("id", "board", "address", "link", "position", "normal")


class Layout:
    """A validated set of taxels and boards.

    Parameters
    ----------
    taxels : list of Taxel
        The taxels, in the order the pipeline uses for its arrays.
    boards : list of Board
        The boards the taxels are wired to.
    name : str
        A human-readable name.
    source : str
        Where the layout came from (file path), for messages.
    """

    def __init__(
        self, taxels: list[Taxel], boards: list[Board], name: str = "", source: str = "<memory>"
    ) -> None:
        self.taxels = list(taxels)
        self.boards = {b.id: b for b in boards}
        self.name = name
        self.source = source
        self.ids = np.array([t.id for t in self.taxels], dtype=np.int64)
        self.positions = np.array([t.position for t in self.taxels], dtype=float).reshape(-1, 3)
        self.normals = np.array([t.normal for t in self.taxels], dtype=float).reshape(-1, 3)
        self.links = [t.link for t in self.taxels]
        self._index = {int(i): k for k, i in enumerate(self.ids)}

    def __len__(self) -> int:
        return len(self.taxels)

    def __contains__(self, taxel_id: object) -> bool:
        """Whether a taxel id is in the layout."""
        return isinstance(taxel_id, int | np.integer) and int(taxel_id) in self._index

    def __repr__(self) -> str:
        return f"Layout({self.name!r}, {len(self)} taxels, {len(self.boards)} boards)"

    def index(self, taxel_id: int) -> int:
        """Return the array index of a taxel id.

        Raises
        ------
        LayoutError
            If the id is not in the layout.
        """
        try:
            return self._index[int(taxel_id)]
        except KeyError:
            raise LayoutError(f"{self.source}: no taxel with id {taxel_id}") from None

    def board_of(self, k: int) -> Board:
        """Return the board of the taxel at array index ``k``."""
        return self.boards[self.taxels[k].board]

    def channel_map(self, board: int) -> tuple[np.ndarray, np.ndarray]:
        """Return (taxel indices, channel addresses) of the taxels wired to ``board``."""
        idx = np.array([k for k, t in enumerate(self.taxels) if t.board == board], dtype=np.int64)
        addr = np.array([self.taxels[k].address for k in idx], dtype=np.int64)
        return idx, addr

    def board_array(self, field: str) -> np.ndarray:
        """Return a per-taxel array of a board constant, such as ``"sensor_depth"``."""
        return np.array([getattr(self.board_of(k), field) for k in range(len(self))], dtype=float)

    def neighbour_lists(self, radius: float | None = None) -> list[np.ndarray]:
        """Return, per taxel, the indices of the taxels on its link within ``radius`` metres.

        With no radius, 1.6 times the median nearest-neighbour distance is used, which joins
        the adjacent taxels of a regular ring layout and nothing further. Memory and time grow
        with the number of pairs found, not with the square of the taxel count.
        """
        from scipy.spatial import cKDTree

        links = np.array(self.links)
        groups = [np.flatnonzero(links == link) for link in dict.fromkeys(self.links)]
        trees = [(idx, cKDTree(self.positions[idx])) for idx in groups]
        if radius is None:
            nearest = np.full(len(self), np.inf)
            for idx, tree in trees:
                if idx.size > 1:
                    nearest[idx] = tree.query(self.positions[idx], k=2)[0][:, 1]
            finite = nearest[np.isfinite(nearest)]
            radius = 1.6 * float(np.median(finite)) if finite.size else 0.0
        out: list[np.ndarray] = [np.zeros(0, dtype=np.int64)] * len(self)
        for idx, tree in trees:
            for k, near in zip(idx, tree.query_ball_point(self.positions[idx], radius),
                               strict=True):
                found = idx[np.sort(np.asarray(near, dtype=np.int64))]
                out[k] = found[found != k]
        return out

    def neighbours(self, radius: float | None = None) -> np.ndarray:
        """Return a boolean (N, N) matrix: taxels on the same link within ``radius`` metres.

        The dense form of `neighbour_lists` (same radius rule), for small layouts.
        """
        near = np.zeros((len(self), len(self)), dtype=bool)
        for k, idx in enumerate(self.neighbour_lists(radius)):
            near[k, idx] = True
        return near


def _vector(value: Any, where: str, field: str) -> tuple[float, float, float]:
    if not (isinstance(value, list) and len(value) == 3 and all(map(is_number, value))):
        raise LayoutError(f"{where}: field {field!r} must be a list of 3 finite numbers, "
                          f"got {value!r}")
    return (float(value[0]), float(value[1]), float(value[2]))


def _parse_board(raw: Any, where: str, base: Path | None = None) -> Board:
    if not isinstance(raw, dict):
        raise LayoutError(f"{where}: a board must be a table")
    unknown = set(raw) - set(_BOARD_FIELDS)
    if unknown:
        raise LayoutError(f"{where}: unknown field {sorted(unknown)[0]!r}")
    values: dict[str, Any] = {}
    if "sensor" in raw:
        values.update(_sensor_fields(raw["sensor"], where, base))
    for name, value in raw.items():
        typ = _BOARD_FIELDS[name]
        if typ == "str":
            continue  # the sensor, resolved above
        if typ == "int":
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise LayoutError(f"{where}: field {name!r} must be a non-negative integer, "
                                  f"got {value!r}")
        else:
            if not is_number(value) or not value > 0:
                raise LayoutError(f"{where}: field {name!r} must be a positive number, "
                                  f"got {value!r}")
            value = float(value)
        values[name] = value
    board = Board(**values)
    if not 1 <= board.adc_bits <= 24:
        raise LayoutError(f"{where}: field 'adc_bits' must be between 1 and 24")
    return board


def _sensor_fields(ref: Any, where: str, base: Path | None) -> dict[str, Any]:
    """Return the board fields a named sensor sets, and its name (a file: from the layout)."""
    from skin.errors import SensorError
    from skin.models.sensors import load_sensor_field

    try:
        sensor, ref = load_sensor_field(ref, base)
    except SensorError as exc:
        raise LayoutError(f"{where}: field 'sensor': {exc}") from None
    return {**sensor.board_fields(), "sensor": ref}


def _parse_taxel(raw: Any, where: str, boards: dict[int, Board]) -> Taxel:
    if not isinstance(raw, dict):
        raise LayoutError(f"{where}: a taxel must be a table")
    for name in _TAXEL_REQUIRED:
        if name not in raw:
            raise LayoutError(f"{where}: missing field {name!r}")
    unknown = set(raw) - set(_TAXEL_REQUIRED)
    if unknown:
        raise LayoutError(f"{where}: unknown field {sorted(unknown)[0]!r}")
    for name in ("id", "board", "address"):
        value = raw[name]
        if not isinstance(value, int) or isinstance(value, bool) or value < 0:
            raise LayoutError(f"{where}: field {name!r} must be a non-negative integer, "
                              f"got {value!r}")
    if raw["board"] not in boards:
        raise LayoutError(f"{where}: field 'board' names board {raw['board']}, "
                          f"which has no [[boards]] table")
    if not isinstance(raw["link"], str) or not raw["link"]:
        raise LayoutError(f"{where}: field 'link' must be a non-empty string")
    position = _vector(raw["position"], where, "position")
    normal = _vector(raw["normal"], where, "normal")
    norm = float(np.linalg.norm(normal))
    if abs(norm - 1.0) > 1e-3:
        raise LayoutError(f"{where}: field 'normal' must be a unit vector, "
                          f"its length is {norm:.4g}")
    return Taxel(raw["id"], raw["board"], raw["address"], raw["link"], position, normal)


def parse_layout(text: str, source: str = "<string>", base: Path | None = None) -> Layout:
    """Parse and validate layout TOML text.

    Parameters
    ----------
    text : str
        TOML text.
    source : str
        File name used in error messages.
    base : Path, optional
        Folder that a board's relative sensor file is resolved against.

    Returns
    -------
    Layout

    Raises
    ------
    LayoutError
        With the file, line, taxel and field of the first problem found.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise LayoutError(f"{source}: not valid TOML: {exc}") from None
    raw_boards = data.get("boards", [{"id": 0}])
    if not isinstance(raw_boards, list) or not raw_boards:
        raise LayoutError(f"{source}: 'boards' must be an array of tables ([[boards]])")
    boards: dict[int, Board] = {}
    board_lines = header_lines(text, "boards")
    for k, raw in enumerate(raw_boards):
        line = board_lines[k] if k < len(board_lines) else 1
        where = f"{source}:{line}: board #{k}"
        board = _parse_board(raw, where, base)
        if board.id in boards:
            raise LayoutError(f"{where}: duplicate board id {board.id}")
        boards[board.id] = board
    raw_taxels = data.get("taxels")
    if not isinstance(raw_taxels, list) or not raw_taxels:
        raise LayoutError(f"{source}: no taxels: add one [[taxels]] table per taxel")
    lines = header_lines(text, "taxels")
    taxels: list[Taxel] = []
    seen_ids: dict[int, int] = {}
    seen_addr: dict[tuple[int, int], int] = {}
    for k, raw in enumerate(raw_taxels):
        line = lines[k] if k < len(lines) else 0
        tid = raw.get("id", "?") if isinstance(raw, dict) else "?"
        where = f"{source}:{line}: taxel {tid}"
        taxel = _parse_taxel(raw, where, boards)
        if taxel.id in seen_ids:
            raise LayoutError(f"{where}: field 'id': duplicate taxel id {taxel.id} "
                              f"(first used on line {seen_ids[taxel.id]})")
        key = (taxel.board, taxel.address)
        if key in seen_addr:
            raise LayoutError(f"{where}: field 'address': board {taxel.board} address "
                              f"{taxel.address} is already used by taxel {seen_addr[key]}")
        seen_ids[taxel.id] = line
        seen_addr[key] = taxel.id
        taxels.append(taxel)
    return Layout(taxels, list(boards.values()), name=str(data.get("name", "")), source=source)


def load_layout(path: str | Path) -> Layout:
    """Load a layout from a TOML file, or a shipped layout by name (``"arm"``).

    Parameters
    ----------
    path : str or Path
        A file path, or the name of a layout in ``skin/data/layouts``.

    Returns
    -------
    Layout
    """
    text, source, folder = read_data_file(path, "layouts", "layout", LayoutError)
    return parse_layout(text, source=source, base=folder)


def layout_toml(layout: Layout) -> str:
    """Return layout TOML text that `parse_layout` reads back as ``layout``.

    Every board constant and every taxel field is written out, floats exactly, so a layout
    built in memory (a cut of a shipped one, say) round-trips too. An empty ``sensor`` (the
    board's own constants) is left out.

    Parameters
    ----------
    layout : Layout
        The layout.

    Returns
    -------
    str
        The TOML text.
    """
    from dataclasses import fields

    from skin.formats.toml_text import toml_value

    lines = [f"# layout {layout.source}, written by thermoskin",
             f"name = {toml_value(layout.name)}", ""]
    for board in layout.boards.values():
        lines.append("[[boards]]")
        lines += [f"{f.name} = {toml_value(getattr(board, f.name))}" for f in fields(board)
                  if not (f.name == "sensor" and not board.sensor)]
        lines.append("")
    for t in layout.taxels:
        lines += ["[[taxels]]", f"id = {int(t.id)}", f"board = {int(t.board)}",
                  f"address = {int(t.address)}", f"link = {toml_value(t.link)}",
                  f"position = {toml_value(list(t.position))}",
                  f"normal = {toml_value(list(t.normal))}", ""]
    return "\n".join(lines)

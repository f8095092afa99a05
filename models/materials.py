"""The materials table: thermal property ranges, effusivity ranges, colours, sources."""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from skin.errors import MaterialsError
from skin.formats.datafiles import is_number
from skin.models.physics import effusivity

_RANGES = ("k", "rho", "c")
AIR_CONDUCTIVITY = 0.026  # W/(m K), air at 25-40 C: what a light contact conducts through


@dataclass(frozen=True)
class Material:
    """One material of the table.

    Attributes
    ----------
    name : str
        Key of the material (``"pine"``).
    k, rho, c : tuple of float
        (min, max) conductivity W/(m K), density kg/m^3, specific heat J/(kg K).
    nominal : dict
        Nominal ``k``, ``rho``, ``c`` inside those ranges.
    colour : str
        Hex colour used by every view.
    classify : bool
        Whether it is a candidate of the default classifiers.
    temperature : tuple of float or None
        Surface temperature range of a heat-generating material, deg C.
    source : str
        Where the numbers come from.
    gap : tuple of float
        (min, max) effective air gap of a light touch, um; sets the contact conductance.
    family : str
        The family it belongs to (``"metal"``, ``"wood_paper"`` ...; ``"other"`` if not given).
    """

    name: str
    k: tuple[float, float]
    rho: tuple[float, float]
    c: tuple[float, float]
    nominal: dict
    colour: str
    classify: bool
    temperature: tuple[float, float] | None
    source: str
    gap: tuple[float, float] = (2.0, 20.0)
    family: str = "other"

    @property
    def effusivity_range(self) -> tuple[float, float]:
        """(min, max) effusivity sqrt(k rho c)."""
        lo = float(effusivity(self.k[0], self.rho[0], self.c[0]))
        hi = float(effusivity(self.k[1], self.rho[1], self.c[1]))
        return lo, hi

    @property
    def effusivity(self) -> float:
        """Nominal effusivity."""
        return float(effusivity(self.nominal["k"], self.nominal["rho"], self.nominal["c"]))

    @property
    def log_effusivity_range(self) -> tuple[float, float]:
        """(min, max) of log10 effusivity."""
        lo, hi = self.effusivity_range
        return float(np.log10(lo)), float(np.log10(hi))

    def resting_temperature(self, ambient: float) -> float:
        """Surface temperature of a resting object: its own (mid-range) if it makes heat."""
        return ambient if self.temperature is None else float(np.mean(self.temperature))

    @property
    def conductance_range(self) -> tuple[float, float]:
        """(min, max) contact conductance of a light touch, k_air / gap, W/(m^2 K)."""
        return AIR_CONDUCTIVITY / (self.gap[1] * 1e-6), AIR_CONDUCTIVITY / (self.gap[0] * 1e-6)

    @property
    def rgb(self) -> tuple[float, float, float]:
        """Colour as RGB in 0-1."""
        return hex_to_rgb(self.colour)


def hex_to_rgb(colour: str) -> tuple[float, float, float]:
    """Convert ``"#RRGGBB"`` to an RGB tuple in 0-1."""
    h = colour.lstrip("#")
    return tuple(int(h[i : i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]


def _pair(value: object, where: str, field: str) -> tuple[float, float]:
    if (
        not isinstance(value, list)
        or len(value) != 2
        or not all(map(is_number, value))
        or not 0 < value[0] <= value[1]
    ):
        raise MaterialsError(f"{where}: field {field!r} must be [min, max] with 0 < min <= max")
    return float(value[0]), float(value[1])


def parse_materials(text: str, source: str = "<string>") -> dict[str, Material]:
    """Parse and validate a materials table (TOML text)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MaterialsError(f"{source}: not valid TOML: {exc}") from None
    table: dict[str, Material] = {}
    for name, raw in data.items():
        where = f"{source}: material {name!r}"
        if not isinstance(raw, dict):
            raise MaterialsError(f"{where}: must be a table")
        ranges = {f: _pair(raw.get(f), where, f) for f in _RANGES}
        nominal = raw.get("nominal")
        if (
            not isinstance(nominal, dict)
            or set(nominal) != set(_RANGES)
            or not all(map(is_number, nominal.values()))
        ):
            raise MaterialsError(f"{where}: field 'nominal' must give numbers k, rho and c")
        for f in _RANGES:
            lo, hi = ranges[f]
            if not lo <= nominal[f] <= hi:
                raise MaterialsError(f"{where}: nominal {f} = {nominal[f]} lies outside "
                                     f"[{lo}, {hi}]")
        temperature = raw.get("temperature")
        colour = raw.get("colour", "#777777")
        if not (isinstance(colour, str) and re.fullmatch(r"#[0-9A-Fa-f]{6}", colour)):
            raise MaterialsError(f"{where}: field 'colour' must be '#RRGGBB'")
        family = raw.get("family", "other")
        if not (isinstance(family, str) and re.fullmatch(r"[a-z][a-z0-9_]*", family)):
            raise MaterialsError(f"{where}: field 'family' must be a lower-case name")
        classify = raw.get("classify", True)
        if not isinstance(classify, bool):
            raise MaterialsError(f"{where}: field 'classify' must be true or false")
        table[name] = Material(
            name=name,
            nominal={f: float(nominal[f]) for f in _RANGES},
            colour=colour,
            classify=classify,
            temperature=None if temperature is None else _pair(temperature, where, "temperature"),
            source=str(raw.get("source", "")),
            gap=_pair(raw["gap"], where, "gap") if "gap" in raw else (2.0, 20.0),
            family=family,
            **ranges,
        )
    return table


def load_materials(path: str | Path | None = None) -> dict[str, Material]:
    """Load the materials table: the shipped one, or a user's TOML file."""
    if path is None:
        res = resources.files("skin.models") / "data" / "materials.toml"
        return parse_materials(res.read_text(encoding="utf-8"), source="materials.toml")
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise MaterialsError(f"{path}: cannot read materials table: {exc.strerror}") from None
    return parse_materials(text, source=str(path))


def family_of(name: str, table: dict[str, Material] | None = None) -> str | None:
    """Return the family of a material name (None if the table does not know it)."""
    table = load_materials() if table is None else table
    return table[name].family if name in table else None


def hierarchical_answer(probabilities: dict[str, float], threshold: float,
                        table: dict[str, Material] | None = None,
                        ) -> tuple[str, float, str, float]:
    """Name the material, else its family, else "unknown", from class probabilities.

    The family's probability is the sum of its materials'. Classes the table does not know
    are their own family.

    Returns
    -------
    (label, confidence, family, family_confidence)
        ``label`` is the most probable material if its probability reaches ``threshold``,
        else ``"unknown"``; ``family`` is the most probable family if its probability
        reaches ``threshold``, else ``"unknown"``; the confidences are the probabilities
        of the most probable material and family.
    """
    if not probabilities:
        return "unknown", 0.0, "unknown", 0.0
    table = load_materials() if table is None else table
    best = max(probabilities, key=probabilities.__getitem__)
    fam: dict[str, float] = {}
    for name, p in probabilities.items():
        f = table[name].family if name in table else name
        fam[f] = fam.get(f, 0.0) + p
    best_f = max(fam, key=fam.__getitem__)
    conf, conf_f = float(probabilities[best]), float(fam[best_f])
    return (best if conf >= threshold else "unknown", conf,
            best_f if conf_f >= threshold else "unknown", conf_f)

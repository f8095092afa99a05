"""The arm view's colours: what each taxel's patch shows, as numpy arrays (no VTK).

`TaxelPainter` keeps one record per taxel - the last label painted on it, the confidence,
when (device time), whether it is in contact now, its temperature - and turns them into
vertex colours in two steps: one RGBA per taxel (and one per patch rim), computed with numpy
over the taxels, then one gather of those over the vertices into the mesh's colour array
(`numpy.take` of packed 32-bit RGBA through a precomputed vertex -> table index).  The cost
per update is O(taxels) arithmetic plus one O(vertices) copy of 4 bytes each.

The look:

- material mode: a patch takes its material's colour (the materials table's colour-blind-safe
  colours); the less sure the classifier, the greyer (blended toward its own luminance, down to
  ``confidence_floor`` of its saturation at confidence 0); ``"unknown"`` is dark grey; a
  contact fades back to bare skin as ``exp(-age / memory)`` (the contact map's memory);
- temperature mode: each patch shows its taxel's temperature through a colormap;
- in both, the rim of every taxel in contact now is drawn in the highlight colour (by default
  black or white, whichever stands out from the patch).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from skin.contact import UNKNOWN

BARE = "#C8C8C8"  # skin never touched (or whose contact has faded)
UNKNOWN_COLOUR = "#3A3A3A"
MODES = ("material", "temperature")
_LUMA = np.array([0.299, 0.587, 0.114])


def hex_rgb(colour: str) -> np.ndarray:
    """``"#RRGGBB"`` -> uint8 RGB array."""
    h = colour.lstrip("#")
    return np.array([int(h[i : i + 2], 16) for i in (0, 2, 4)], dtype=np.uint8)


def colormap_table(name: str, n: int = 256) -> np.ndarray:
    """(n, 3) uint8 colours of a matplotlib colormap, low to high."""
    from skin._optional import require

    require("matplotlib", "the arm view's temperature mode")
    import matplotlib as mpl

    rgba = mpl.colormaps[name](np.linspace(0.0, 1.0, n))
    return np.rint(rgba[:, :3] * 255).astype(np.uint8)


class TaxelPainter:
    """Per-taxel state of the arm view and the vertex colours it gives (see the module).

    Parameters
    ----------
    n_taxels : int
        Number of taxels (layout order).
    colours : mapping
        Material name -> ``"#RRGGBB"``.
    owner : numpy.ndarray
        (n_vertices,) taxel index owning each vertex, -1 for bare skin.
    rim : numpy.ndarray
        (n_vertices,) True for a patch's rim vertices.
    memory : float or None
        Time constant of the contact map's fading, s; None: contacts never fade.
    confidence_floor : float
        Share of a colour's saturation kept at confidence 0 (1 at confidence 1).
    highlight : str or None
        Rim colour of taxels in contact; None: black or white, whichever contrasts more.
    cmap : str
        Matplotlib colormap of the temperature mode.
    clim : tuple of float, optional
        Temperature range of the colormap, deg C; by default the range of the first
        temperatures given, widened to whole degrees.
    """

    def __init__(self, n_taxels: int, colours: Mapping[str, str], owner: np.ndarray,
                 rim: np.ndarray, *, memory: float | None = 60.0, confidence_floor: float = 0.25,
                 highlight: str | None = None, cmap: str = "inferno",
                 clim: tuple[float, float] | None = None) -> None:
        n = int(n_taxels)
        self.n = n
        self.colours = dict(colours)
        self.memory = memory
        self.confidence_floor = float(confidence_floor)
        self.highlight = highlight
        self.cmap = cmap
        self.clim = clim
        self.mode = "material"
        self.now: float = 0.0
        self.names: list[str] = []  # labels painted so far, in order of first use
        self.label = np.full(n, -1, dtype=np.int64)  # index into names, -1: never painted
        self.confidence = np.ones(n)
        self.at = np.full(n, np.nan)  # device time of the contact; NaN: never fades
        self.in_contact = np.zeros(n, dtype=bool)
        self.temperature: np.ndarray | None = None
        self._palette = hex_rgb(BARE)[None].astype(float)  # one row per name, bare last
        self._cmap_table: np.ndarray | None = None
        owner = np.asarray(owner, dtype=np.int64)
        # vertex -> row of the colour table: [inner 0..n-1 | bare n | rim n+1..2n | bare 2n+1]
        self.vertex_row = np.where(owner < 0, n, owner + np.asarray(rim, bool) * (n + 1))
        self.table = np.zeros((2 * n + 2, 4), dtype=np.uint8)
        self.table[:, 3] = 255
        self.table[[n, 2 * n + 1], :3] = hex_rgb(BARE)
        self.table32 = self.table.view(np.uint32).reshape(-1)

    # --- state -----------------------------------------------------------------------------

    def label_index(self, label: str) -> int:
        """Index of a label in `names`, adding it (and its colour) on first use."""
        try:
            return self.names.index(label)
        except ValueError:
            pass
        colour = self.colour_of(label)
        self.names.append(label)
        self._palette = np.vstack([self._palette[:-1], hex_rgb(colour).astype(float),
                                   self._palette[-1:]])
        return len(self.names) - 1

    def colour_of(self, label: str) -> str:
        """Return the colour a label is painted with (unknown or unlisted: the unknown look)."""
        return UNKNOWN_COLOUR if label == UNKNOWN else self.colours.get(label, UNKNOWN_COLOUR)

    def paint(self, index: np.ndarray | Sequence[int], label: str, confidence: float = 1.0,
              at: float | None = None) -> None:
        """Record a label on these taxels (layout indices) with its confidence and time."""
        idx = np.asarray(index, dtype=np.int64)
        self.label[idx] = self.label_index(label)
        self.confidence[idx] = 1.0 if label == UNKNOWN else float(np.clip(confidence, 0, 1))
        self.at[idx] = np.nan if at is None else float(at)

    def clear(self) -> None:
        """Forget every label (bare skin everywhere); contact and temperature stay."""
        self.label[:] = -1
        self.at[:] = np.nan
        self.confidence[:] = 1.0

    def legend(self) -> list[tuple[str, str]]:
        """(label, colour) of every label on the skin now, sorted by name, unknown last."""
        shown = {self.names[k] for k in np.unique(self.label[self.label >= 0])}
        names = sorted(shown - {UNKNOWN}) + ([UNKNOWN] if UNKNOWN in shown else [])
        return [(name, self.colour_of(name)) for name in names]

    # --- colours ---------------------------------------------------------------------------

    def taxel_colours(self) -> tuple[np.ndarray, np.ndarray]:
        """(inner, rim) colours per taxel as (n, 3) floats 0-255, for the current mode."""
        if self.mode == "temperature":
            inner = self._temperature_colours()
        else:
            inner = self._material_colours()
        rim = inner
        if self.in_contact.any():
            rim = inner.copy()
            hot = self.in_contact
            if self.highlight is not None:
                rim[hot] = hex_rgb(self.highlight)
            else:
                light = inner[hot] @ _LUMA > 110.0
                rim[hot] = np.where(light[:, None], 0.0, 255.0)
        return inner, rim

    def _material_colours(self) -> np.ndarray:
        base = self._palette[self.label]  # label -1 picks the last row: bare
        s = self.confidence_floor + (1.0 - self.confidence_floor) * self.confidence
        grey = base @ _LUMA
        col = grey[:, None] + (base - grey[:, None]) * s[:, None]
        if self.memory is not None:
            age = np.maximum(self.now - self.at, 0.0)
            w = np.exp(-age / self.memory)
            w[np.isnan(w)] = 1.0  # never fades
            bare = self._palette[-1]
            col = bare + (col - bare) * w[:, None]
        return col

    def _temperature_colours(self) -> np.ndarray:
        col = np.empty((self.n, 3))
        col[:] = self._palette[-1]
        t = self.temperature
        if t is None:
            return col
        lo, hi = self.temperature_range()
        table = self.cmap_table()
        ok = np.isfinite(t)
        pos = (t[ok] - lo) * ((len(table) - 1) / max(hi - lo, 1e-9))
        col[ok] = table[np.clip(np.rint(pos), 0, len(table) - 1).astype(np.int64)]
        col[~ok] = hex_rgb(UNKNOWN_COLOUR)
        return col

    def cmap_table(self) -> np.ndarray:
        """(256, 3) uint8 colours of the temperature colormap (made once)."""
        if self._cmap_table is None:
            self._cmap_table = colormap_table(self.cmap)
        return self._cmap_table

    def temperature_range(self) -> tuple[float, float]:
        """Return the colormap's range, deg C (fixed on the first temperatures unless given)."""
        if self.clim is None:
            t = self.temperature
            t = t[np.isfinite(t)] if t is not None else np.zeros(0)
            if not t.size:
                return (20.0, 40.0)
            lo, hi = float(np.floor(t.min())), float(np.ceil(t.max()))
            self.clim = (lo - 1.0, hi + 1.0) if hi - lo < 2 else (lo, hi)
        return self.clim

    def fill(self, out32: np.ndarray) -> None:
        """Write every vertex's packed RGBA into ``out32`` ((n_vertices,) uint32, in place)."""
        inner, rim = self.taxel_colours()
        n = self.n
        self.table[:n, :3] = inner + 0.5  # rounds: the colours are >= 0
        self.table[n + 1 : 2 * n + 1, :3] = rim + 0.5
        np.take(self.table32, self.vertex_row, out=out32, mode="clip")

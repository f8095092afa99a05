"""What one update of the arm view costs the library, beside a render (`skin bench view`).

For each mesh size and taxel count, `run` builds an `ArmView` of the procedural arm with that
many vertices and a skin of that many taxels in rings on the upper arm and forearm
(`arm_layout`), paints a third of them, then times `ArmView.update` (new contact mask and
temperatures: every taxel's colour computed and gathered into the mesh's RGBA array, handed to
VTK by marking it modified) and, apart, its two parts: the per-taxel colours and the per-vertex
gather. Beside them: one render after an update (the colours uploaded and drawn), a render of
an unchanged scene, and a baseline measured in the same run, one `numpy.take` of the
vertex colours, so that figures compare as ratios across machines.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from skin.formats.layout import Board, Layout, Taxel
from skin.viz.arm_mesh import FORE_LENGTH, FORE_RADIUS, UPPER_LENGTH, UPPER_RADIUS

if TYPE_CHECKING:
    from skin.viz.arm import ArmView

BOARD_CHANNELS = 256


def arm_layout(n: int) -> Layout:
    """``n`` taxels in staggered rings on the default arm's upper arm and forearm (by area)."""
    links = [("upper_arm", UPPER_RADIUS, UPPER_LENGTH), ("forearm", FORE_RADIUS, FORE_LENGTH)]
    areas = np.array([2 * np.pi * r * length for _, r, length in links])
    counts = np.round(n * areas / areas.sum()).astype(int)
    counts[-1] = n - counts[:-1].sum()
    taxels: list[Taxel] = []
    for (name, r, length), count in zip(links, counts, strict=True):
        if count <= 0:
            continue
        pitch = np.sqrt(2 * np.pi * r * length / count)
        per_ring = max(3, int(np.ceil(2 * np.pi * r / pitch)))
        rings = int(np.ceil(count / per_ring))
        z = np.linspace(0.015, length - 0.015, rings) if rings > 1 else np.array([length / 2])
        for k in range(count):
            ring, j = divmod(k, per_ring)
            a = 2 * np.pi * (j + 0.5 * (ring % 2)) / per_ring
            normal = (float(np.cos(a)), float(np.sin(a)), 0.0)
            i = len(taxels)
            board, address = divmod(i, BOARD_CHANNELS)
            taxels.append(Taxel(i, board, address, name,
                                (r * normal[0], r * normal[1], float(z[ring])), normal))
    boards = [Board(id=b) for b in range(-(-n // BOARD_CHANNELS))]
    return Layout(taxels, boards, name=f"arm of {n}", source=f"<{n} taxels on the arm>")


def _times(func: Callable[[], object], repeat: int) -> np.ndarray:
    out = np.empty(repeat)
    for k in range(repeat):
        t = time.perf_counter()
        func()
        out[k] = time.perf_counter() - t
    return out


def renderer_name(view: object) -> str:
    """Return the OpenGL renderer VTK draws with (Mesa llvmpipe in software, or a GPU)."""
    try:
        report = view.plotter.render_window.ReportCapabilities()  # type: ignore[attr-defined]
    except Exception:  # a render window without a context: not worth failing a benchmark
        return "unknown"
    for line in report.splitlines():
        if "renderer string" in line.lower():
            return line.split(":", 1)[1].strip()
    return "unknown"


def run(taxels: Sequence[int] = (72, 300, 1000), vertices: Sequence[int] = (14_000, 100_000),
        updates: int = 200, renders: int = 5, window_size: tuple[int, int] = (800, 600),
        progress: Callable[[str], None] | None = None) -> dict:
    """Time updates and renders of the arm view; see the module.

    Parameters
    ----------
    taxels : sequence of int
        Skin sizes.
    vertices : sequence of int
        Mesh sizes (about; the procedural arm rounds them).
    updates : int
        Timed updates per case.
    renders : int
        Timed renders per case.
    window_size : tuple of int
        Image size of the one view rendered, pixels.
    progress : callable, optional
        Called with a line of text before each case.

    Returns
    -------
    dict
        ``renderer`` (OpenGL renderer), ``window_size``, ``results``: one dict per case with
        ``vertices``, ``taxels``, ``build_s``, ``update_ms`` (p50, p99: the library's work per
        update), ``taxel_colours_ms`` and ``vertex_gather_ms`` (p50 of its two parts),
        ``baseline_take_ms`` (one ``np.take`` of the vertex colours), ``render_ms`` (p50 of a
        render after an update), ``render_unchanged_ms`` and ``render_per_update``.
    """
    from skin._optional import require
    from skin.models import load_materials
    from skin.viz.arm import ArmView

    require("pyvista", "the arm view")  # imported before the first build is timed
    colours = {m.name: m.colour for m in load_materials().values()}
    rng = np.random.default_rng(0)
    results = []
    renderer = "unknown"
    for n_vertices in vertices:
        for n_taxels in taxels:
            if progress is not None:
                progress(f"{n_vertices} vertices, {n_taxels} taxels")
            layout = arm_layout(n_taxels)
            started = time.perf_counter()
            view = ArmView(layout, colours, vertices=n_vertices, window_size=window_size,
                           sides=("front",))
            build = time.perf_counter() - started
            try:
                row = _case(view, rng, updates, renders)
                renderer = renderer_name(view)
            finally:
                view.close()
            results.append({"vertices": int(view.mesh.n_points), "taxels": n_taxels,
                            "build_s": round(build, 3), **row})
    return {"renderer": renderer, "window_size": list(window_size), "results": results}


def _case(view: ArmView, rng: np.random.Generator, updates: int, renders: int) -> dict:
    """Time one view: updates, their parts, the baseline and renders (see `run`)."""
    n = len(view.layout)
    names = sorted(view.colours)
    for k in range(0, n, 3):  # a third of the skin painted, at various confidences and ages
        view.painter.paint([k], names[k % len(names)], confidence=float(rng.random()),
                           at=float(rng.random() * 10))
    masks = rng.random((updates, n)) < 0.05
    temps = 25.0 + 10.0 * rng.random((updates, n))
    count = iter(range(1 << 62))

    def update() -> None:
        i = next(count) % updates
        view.update(10.0 + 0.05 * i, in_contact=masks[i], temperature=temps[i])

    _times(update, 10)  # warm up
    upd = _times(update, updates)
    painter = view.painter
    colours_t = _times(painter.taxel_colours, updates)
    out = np.empty(len(painter.vertex_row), dtype=np.uint32)
    take = _times(lambda: np.take(painter.table32, painter.vertex_row, out=out, mode="clip"),
                  updates)
    # the baseline: one gather of every vertex's colour (an identity index)
    src, identity = out.copy(), np.arange(len(out))
    baseline = _times(lambda: np.take(src, identity, out=out, mode="clip"), updates)
    view.render()  # the first render makes the context
    unchanged = _times(view.render, renders)

    def update_and_render() -> float:
        update()
        t = time.perf_counter()
        view.render()
        return time.perf_counter() - t

    rendered = np.array([update_and_render() for _ in range(renders)])
    p50 = float(np.median(upd)) * 1e3
    render_ms = float(np.median(rendered)) * 1e3
    return {
        "update_ms": {"p50": round(p50, 4), "p99": round(float(np.percentile(upd, 99)) * 1e3, 4)},
        "taxel_colours_ms": round(float(np.median(colours_t)) * 1e3, 4),
        "vertex_gather_ms": round(float(np.median(take)) * 1e3, 4),
        "baseline_take_ms": round(float(np.median(baseline)) * 1e3, 4),
        "render_ms": round(render_ms, 2),
        "render_unchanged_ms": round(float(np.median(unchanged)) * 1e3, 2),
        "render_per_update": round(render_ms / p50, 1) if p50 > 0 else None,
    }

"""``skin bench view``: the arm view's own work per update beside the render, by size.

Registered by `skin.commands.bench`; the work is done in `skin.bench.view`, imported when
the command runs.
"""

from __future__ import annotations

import argparse
import json
import time

from skin.errors import SkinError
from skin.progress import Progress


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench view``."""
    view = kinds.add_parser("view", help="arm view: the library's work per update vs a render")
    view.add_argument("--taxels", default="72,300,1000",
                      help="skin sizes (default 72,300,1000)")
    view.add_argument("--vertices", default="14000,100000",
                      help="mesh sizes, about (default 14000,100000)")
    view.add_argument("--updates", type=int, default=200, help="timed updates per case (200)")
    view.add_argument("--renders", type=int, default=5, help="timed renders per case (5)")
    view.add_argument("--size", default="800x600", help="image size WxH (default 800x600)")
    view.add_argument("--quick", action="store_true",
                      help="small sizes and few repeats (a smoke run)")
    view.add_argument("--json", action="store_true", help="print one JSON document")
    view.set_defaults(func=main_view)


def _ints(text: str, what: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise SkinError(f"--{what} wants integers, got {text!r}") from None
    if not values or min(values) < 1:
        raise SkinError(f"--{what} must be positive integers")
    return values


def main_view(args: argparse.Namespace) -> int:
    """Run ``skin bench view``."""
    from skin.bench import machine
    from skin.bench import view as view_bench

    taxels = _ints(args.taxels, "taxels")
    vertices = _ints(args.vertices, "vertices")
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise SkinError(f"--size wants WxH, got {args.size!r}") from None
    updates, renders = args.updates, args.renders
    if args.quick:
        taxels, vertices, updates, renders = [72, 300], [14_000], 30, 2
        width, height = 400, 300
    if updates < 1 or renders < 1:
        raise SkinError("--updates and --renders must be at least 1")
    progress = Progress()
    started = time.monotonic()
    doc = view_bench.run(taxels, vertices, updates=updates, renders=renders,
                         window_size=(width, height), progress=progress.message)
    progress.done()
    import pyvista
    import vtk

    doc = {"machine": {**machine(), "pyvista": pyvista.__version__,
                       "vtk": vtk.vtkVersion.GetVTKVersion(), "renderer": doc["renderer"]},
           "wall_time": round(time.monotonic() - started, 2), **doc}
    if args.json:
        print(json.dumps(doc))
        return 0
    m = doc["machine"]
    print(f"arm view: one update (every taxel's colour into the mesh's RGBA array, handed to "
          f"VTK) beside one render of {width}x{height}, one view")
    print(f"machine: {m['cpus']} cores, {m['platform']}; VTK {m['vtk']}, renderer "
          f"{m['renderer']}")
    print(f"{'vertices':>8} {'taxels':>6} {'build s':>7} {'update ms':>9} {'p99':>6} "
          f"{'colours':>7} {'gather':>6} {'np.take':>7} {'render ms':>9} {'unchanged':>9} "
          f"{'render/update':>13}")
    for r in doc["results"]:
        print(f"{r['vertices']:>8} {r['taxels']:>6} {r['build_s']:>7.2f} "
              f"{r['update_ms']['p50']:>9.3f} {r['update_ms']['p99']:>6.3f} "
              f"{r['taxel_colours_ms']:>7.3f} {r['vertex_gather_ms']:>6.3f} "
              f"{r['baseline_take_ms']:>7.3f} {r['render_ms']:>9.1f} "
              f"{r['render_unchanged_ms']:>9.1f} {r['render_per_update']:>13.0f}")
    print("update: the library's own work per update (p50, p99), of it the per-taxel colours "
          "and the per-vertex gather; np.take: baseline, one gather of every vertex's colour; "
          "render: after an update (colours uploaded) and of an unchanged scene")
    return 0

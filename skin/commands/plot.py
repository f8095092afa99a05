"""``skin plot KIND``: draw a figure into a file (PNG, SVG or PDF, from the suffix of --out).

Kinds:

materials
    the effusivity range of each material of the table on a log axis, with its nominal value
    and the sensor's own effusivity (the paper's Fig. 10); --all adds the extremes kept for
    tests (copper, diamond, polyurethane foam, silica aerogel, water), hatched.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path


def _materials(args: argparse.Namespace, out: Path) -> Path:
    from skin.models import load_materials
    from skin.viz.plots import plot_materials

    return plot_materials(load_materials(), out, include_all=args.all)


# kind -> function drawing it into the given path and returning the path written
KINDS: dict[str, Callable[[argparse.Namespace, Path], Path]] = {
    "materials": _materials,
}


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin plot``."""
    plot = sub.add_parser("plot", help="draw a figure (materials: effusivity ranges)",
                          description=__doc__,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    plot.add_argument("kind", choices=list(KINDS), help="what to draw")
    plot.add_argument("--out", metavar="PATH",
                      help="output file; its suffix picks the format: .png, .svg or .pdf "
                           "(default: out/KIND.png)")
    plot.add_argument("--all", action="store_true",
                      help="materials: also draw the extremes that are not classified")
    plot.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Draw the figure named by ``args.kind`` and print the path written."""
    out = Path(args.out) if args.out else Path("out") / f"{args.kind}.png"
    path = KINDS[args.kind](args, out)
    print(path)
    return 0

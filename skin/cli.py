"""The ``skin`` command: parses the arguments and dispatches to `skin.commands`.

Every subcommand lives in its own module under `skin.commands`; each module registers its
parser with ``add_parser`` and runs with ``main``. Heavy imports happen inside ``main``.
"""

from __future__ import annotations

import argparse
import sys

from skin.commands import (
    bench,
    calibrate,
    devices,
    evaluate,
    evaluate_onset,
    plot,
    record,
    run,
    sensors,
    simulate,
    train,
    view,
)
from skin.errors import SkinError

COMMANDS = (run, simulate, calibrate, train, evaluate, evaluate_onset, bench, plot, record, devices,
            view, sensors)


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of the ``skin`` command."""
    parser = argparse.ArgumentParser(
        prog="skin", description="Material recognition from heat transfer across a robot skin.")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``skin`` command."""
    from skin.threads import limited_threads

    args = build_parser().parse_args(argv)
    try:
        with limited_threads():  # BLAS/OpenMP oversubscribe busy cores (SKIN_THREADS)
            return args.func(args)
    except SkinError as exc:
        print(f"skin: error: {exc}", file=sys.stderr)
        return 2

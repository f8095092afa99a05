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
    commission,
    completion,
    config,
    dataset,
    devices,
    evaluate,
    evaluate_onset,
    map,
    plot,
    record,
    run,
    sensors,
    simulate,
    subscribe,
    train,
    view,
)
from skin.errors import SkinError

COMMANDS = (run, simulate, calibrate, train, evaluate, evaluate_onset, bench, plot, record, devices,
            view, sensors, config, completion, commission, dataset, subscribe,
            map)


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of the ``skin`` command."""
    from skin import __version__

    parser = argparse.ArgumentParser(
        prog="skin", description="Material recognition from heat transfer across a robot skin.")
    parser.add_argument("--version", action="version", version=f"skin (thermoskin) {__version__}")
    _add_logging_options(parser, default=0)
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    for child in sub.choices.values():  # `skin run -v` as well as `skin -v run`
        _add_logging_options(child, default=argparse.SUPPRESS)
    return parser


def _add_logging_options(parser: argparse.ArgumentParser, default: object) -> None:
    parser.add_argument("-v", "--verbose", action="count", default=default,
                        help="log more: -v information, -vv debugging (stderr; never on the "
                             "status line)")
    parser.add_argument("--log-file", metavar="FILE",
                        default=None if default == 0 else argparse.SUPPRESS,
                        help="also log information (debugging with -vv) to FILE, appended")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``skin`` command."""
    from skin.logs import configure_logging
    from skin.threads import limited_threads

    args = build_parser().parse_args(argv)
    try:
        configure_logging(args.verbose, args.log_file)
        with limited_threads():  # BLAS/OpenMP oversubscribe busy cores (SKIN_THREADS)
            return args.func(args)
    except SkinError as exc:
        print(f"skin: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `skin ... | head`: the reader has gone; say nothing more
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0

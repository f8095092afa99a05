"""``skin config show``: the setup ``skin run`` would use, and where each value came from.

Values come from the defaults, then the skin file (``--config FILE``, or ``./skin.toml`` when
there is one), then the options given here (the same as ``skin run``'s). The text form is a
skin file: each value with a comment naming its origin (``default``, ``skin.toml:7``,
``command line``).
"""

from __future__ import annotations

import argparse
import json

from skin.commands import run
from skin.setup import GROUPS, Setup


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin config``."""
    config = sub.add_parser("config", help="show the resolved setup (skin.toml and options)",
                            description=__doc__)
    actions = config.add_subparsers(dest="action", required=True)
    show = actions.add_parser("show", help="print the resolved setup and each value's origin",
                              description=__doc__, argument_default=argparse.SUPPRESS)
    run.add_setup_options(show)
    show.add_argument("--json", action="store_true",
                      help="print one JSON document: each field's value and origin")
    show.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Print the resolved setup."""
    from skin.formats.skin_file import find_skin_file

    setup = run.resolve_setup(args)
    path = getattr(args, "config", None) or find_skin_file()
    if getattr(args, "json", False):
        print(json.dumps({name: {"value": value, "from": setup.where(name)}
                          for name, value in setup.as_dict().items()}))
    else:
        print(f"# skin file: {path}" if path else "# no skin file: defaults and options")
        print(setup_text(setup))
    return 0


#: What an unset value means where it is not simply none (`setup_text`).
UNSET = {"contact": "(the scene's)", "seed": "(the scene's)",
         "duration": "(the scene's; 20 s for a device; a recording to its end)",
         "layout": "(the scene's, the recording's, or arm)"}


def setup_text(setup: Setup) -> str:
    """Return ``setup`` as a skin file, each value's origin in a comment (unset ones too)."""
    from skin.formats.toml_text import toml_value

    lines = ["# the resolved setup of `skin run` (skin config show)"]
    for group, names in GROUPS.items():
        lines += ["", f"[{group}]"]
        for name in names:
            value = getattr(setup, name)
            text = (f"# {name} = {UNSET.get(name, '(none)')}" if value is None
                    else f"{name} = {toml_value(value)}")
            lines.append(f"{text:<48} # {setup.where(name)}")
    return "\n".join(lines)

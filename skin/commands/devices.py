"""``skin devices``: the boards that answer IDENTIFY, checked against the layout.

Probes every serial port of the machine and every CAN channel python-can detects (SocketCAN),
plus any device URL given with ``--port`` (a pseudo-terminal, ``can://virtual/...``,
``can://udp_multicast/...``). For each board that answers it prints the board id, firmware
version, MCU, taxel count, sample rate and layout hash, then what disagrees with the layout:
a taxel count that does not match the channels the layout wires to that board, or a layout
hash the firmware was built with that is not the layout's. Exits with status 1 when something
disagrees or a URL given with ``--port`` cannot be opened, 0 otherwise (also when no board
answers).
"""

from __future__ import annotations

import argparse
import json

from skin.progress import Progress


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin devices``."""
    cmd = sub.add_parser("devices", help="list the boards that answer IDENTIFY",
                         description=__doc__)
    cmd.add_argument("--port", action="append", default=[], metavar="URL",
                     help="also probe this device URL (repeatable)")
    cmd.add_argument("--no-scan", action="store_true",
                     help="probe only the --port URLs, not the machine's ports and buses")
    cmd.add_argument("--layout", default="arm", help="layout to check against (default: arm)")
    cmd.add_argument("--timeout", type=float, default=0.5,
                     help="seconds to wait for answers on each port or bus (default 0.5)")
    cmd.add_argument("--json", action="store_true",
                     help="print one JSON document on stdout and nothing else")
    cmd.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """List and check the boards (see the module docstring)."""
    from skin.drivers.discovery import can_channels, check, identify, serial_ports
    from skin.errors import DeviceError
    from skin.formats.layout import load_layout

    layout = load_layout(args.layout)
    progress = Progress()
    urls = list(args.port)
    if not args.no_scan:
        urls += [f"serial://{p}" for p in serial_ports()] + can_channels()
    boards, silent, problems, dead = [], [], [], []
    for k, url in enumerate(urls):
        progress.status(f"probing {url} ({k + 1}/{len(urls)})")
        try:
            found = identify(url, timeout=args.timeout)
        except DeviceError as exc:
            message = str(exc)  # it names the URL already
            message = message[len(url) + 2:] if message.startswith(f"{url}: ") else message
            silent.append({"url": url, "error": message})
            if k < len(args.port):  # the user asked for this one: a dead port is a failure
                dead.append(f"{url}: {message}")
            continue
        if not found:
            silent.append({"url": url, "error": "no answer to IDENTIFY"})
        for board in found:
            issues = check(board, layout)
            boards.append({**board.record(), "problems": issues})
            problems += issues
    progress.done()
    if args.json:
        print(json.dumps({"layout": layout.source, "boards": boards, "silent": silent}))
    else:
        if not boards:
            print(f"no board answered IDENTIFY ({len(urls)} ports and buses probed)")
        for b in boards:
            where = b["url"] + ("" if b["node"] is None else f" node {b['node']}")
            print(f"{where}: board {b['board']}, firmware {b['firmware']} on {b['mcu']} "
                  f"({b['transport']}), {b['taxels']} taxels, {b['rate_hz']} Hz "
                  f"(max {b['max_rate_hz']}), layout hash {b['layout_hash']}")
        for s in silent:
            if f"{s['url']}: {s['error']}" not in dead:  # else printed as an error below
                print(f"{s['url']}: {s['error']}")
        for p in problems:
            print(f"warning: {p}")
        for d in dead:
            print(f"error: {d}")
    return 1 if problems or dead else 0

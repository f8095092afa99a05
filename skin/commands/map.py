"""``skin map serve|query|stats``: the material map many robots share over Zenoh.

``skin map serve --db map.sqlite [--prefix P] [--listen|--connect tcp/HOST:PORT]`` fuses the
contacts every robot publishes (``skin run --publish zenoh://P``) into a voxel map in SQLite
and answers queries on ``P/map/**`` (`skin.world.map_service`). It prints ``ready`` on stderr
once it listens, a status line every ``--status`` seconds, and stops at Ctrl-C, SIGTERM or after
``--duration`` seconds, storing what has arrived.

``skin map query --box x0,y0,z0,x1,y1,z1 [--material M | --family F] [--map URL|FILE]``
prints the voxels in a box (m, the map's frame) with their posterior labels, from the service
(``zenoh://P?connect=tcp/HOST:PORT``) or from the database file; ``--json`` prints one JSON
document. ``skin map stats`` prints the map's size and contacts per robot.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time
from typing import Any

from skin.errors import SkinError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin map``."""
    p = sub.add_parser("map", help="the material map many robots share over Zenoh",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    verbs = p.add_subparsers(dest="verb", required=True)

    s = verbs.add_parser("serve", help="fuse the robots' contacts into a map and answer queries")
    s.add_argument("--db", default="map.sqlite", help="the map database (default map.sqlite)")
    s.add_argument("--prefix", default="thermoskin", help="Zenoh key prefix (default thermoskin)")
    s.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)")
    s.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to connect to (repeatable)")
    s.add_argument("--mode", choices=("peer", "client"), default=None, help="Zenoh session mode")
    s.add_argument("--voxel", type=float, default=None,
                   help="voxel side of a new map, m (default 0.01)")
    s.add_argument("--threshold", type=float, default=None,
                   help="posterior a material (else its family) needs to be named, of a new "
                        "map (default 0.5)")
    s.add_argument("--synchronous", choices=("full", "normal"), default="full",
                   help="full: each acknowledged contact is on disk (fsync); normal: kept "
                        "across a killed service, not a power cut, without fsync stalls")
    s.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    s.add_argument("--status", type=float, default=10.0,
                   help="seconds between status lines (0: none)")
    s.add_argument("--json", action="store_true",
                   help="print one JSON summary on stdout at the end and nothing else")
    s.set_defaults(func=serve)

    for name, helptext in (("query", "print the voxels in a box with their labels"),
                           ("stats", "print the map's size and contacts per robot")):
        q = verbs.add_parser(name, help=helptext)
        q.add_argument("--map", default="zenoh://thermoskin", metavar="URL|FILE",
                       help="zenoh://PREFIX[?connect=tcp/HOST:PORT] (the service) or a map "
                            "database file (default zenoh://thermoskin)")
        q.add_argument("--timeout", type=float, default=5.0,
                       help="seconds to wait for the service")
        q.add_argument("--json", action="store_true", help="print one JSON document")
        if name == "query":
            q.add_argument("--box", required=True, metavar="x0,y0,z0,x1,y1,z1",
                           help="the box, m, in the map's frame")
            group = q.add_mutually_exclusive_group()
            group.add_argument("--material", help="only voxels named this material")
            group.add_argument("--family", help="only voxels of this family")
            q.add_argument("--limit", type=int, default=None, help="at most this many voxels")
            q.set_defaults(func=query)
        else:
            q.set_defaults(func=stats)


def serve(args: argparse.Namespace) -> int:
    """Run the map service (see the module docstring)."""
    from skin.world.map_service import MapService

    stop = {"now": False}

    def on_signal(signum: int, frame: Any) -> None:
        stop["now"] = True

    signal.signal(signal.SIGTERM, on_signal)
    say = (lambda line: None) if args.json else (lambda line: print(line, flush=True))
    with MapService(args.db, prefix=args.prefix, listen=args.listen, connect=args.connect,
                    mode=args.mode, voxel=args.voxel, threshold=args.threshold,
                    synchronous=args.synchronous) as service:
        say(f"map service: {args.db} ({service.store.voxel:g} m voxels, "
            f"{service.store.stats()['voxels']} voxels) on {service.prefix}/*/contacts, "
            f"queries on {service.prefix}/map/**")
        print("ready", file=sys.stderr, flush=True)  # for scripts waiting on the service
        started = next_status = time.monotonic()
        try:
            while not stop["now"]:
                now = time.monotonic()
                if args.duration is not None and now - started >= args.duration:
                    break
                if args.status > 0 and now >= next_status:
                    if now > started:
                        say(f"received {service.received}  malformed {service.malformed}  "
                            f"duplicates {service.duplicates}")
                    next_status = now + args.status
                time.sleep(0.05)
        except KeyboardInterrupt:
            pass
    if args.json:
        from skin.world.map_store import MapStore

        with MapStore(args.db) as store:
            print(json.dumps({"db": args.db, "received": service.received,
                              "malformed": service.malformed,
                              "duplicates": service.duplicates, **store.stats()}))
    else:
        say(f"stopped: received {service.received}, malformed {service.malformed}, "
            f"duplicates {service.duplicates}")
    return 0


def _open(args: argparse.Namespace) -> Any:
    from skin.world.shared_map import SharedMap

    return SharedMap(args.map, timeout=args.timeout)


def query(args: argparse.Namespace) -> int:
    """Print the voxels in a box (see the module docstring)."""
    from skin.world.map_store import parse_box

    box = parse_box(args.box)  # a clear error before any session opens
    if args.limit is not None and args.limit < 1:
        raise SkinError(f"--limit {args.limit}: a positive number expected")
    with _open(args) as shared:
        voxels = shared.query(box, material=args.material, family=args.family, limit=args.limit)
    if args.json:
        print(json.dumps({"map": args.map, "box": list(box), "count": len(voxels),
                          "voxels": voxels}))
        return 0
    for v in voxels:
        c = v["center"]
        print(f"{c[0]:8.3f} {c[1]:8.3f} {c[2]:8.3f}  {v['label']:<11s} {v['confidence']:5.2f}  "
              f"{v['family']:<10s} {v['family_confidence']:5.2f}  contacts {v['contacts']:3d}  "
              f"{','.join(v['robots'])}")
    print(f"{len(voxels)} voxels in {','.join(f'{x:g}' for x in box)}")
    return 0


def stats(args: argparse.Namespace) -> int:
    """Print the map's size (see the module docstring)."""
    with _open(args) as shared:
        info = shared.stats()
    if args.json:
        print(json.dumps(info))
        return 0
    print(f"{info['voxels']} voxels of {info['voxel']:g} m, {info['contacts']} contacts: "
          + ", ".join(f"{r} {n}" for r, n in sorted(info["robots"].items())))
    return 0

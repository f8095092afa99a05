"""``skin bench map``: the shared map under several robots' contacts, and its box query.

Registered by `skin.commands.bench`; the work is done in `skin.bench.map`, imported when the
command runs.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from skin.errors import SkinError


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench map``."""
    m = kinds.add_parser("map", help="shared map: lost contacts, visibility latency, box query")
    m.add_argument("--robots", type=int, default=3, help="publisher processes (3)")
    m.add_argument("--taxels", type=int, default=1000, help="taxels per robot (1000)")
    m.add_argument("--rate", type=float, default=6.0,
                   help="contacts per taxel and minute (6, issue 7's bench)")
    m.add_argument("--minutes", type=float, default=1.0, help="minutes of publishing (1)")
    m.add_argument("--voxels", type=int, default=1_000_000,
                   help="voxels of the synthetic map the box query runs on (1000000)")
    m.add_argument("--repeats", type=int, default=20, help="timed 1 m^3 box queries (20)")
    m.add_argument("--db", default=None,
                   help="keep (or reuse) the synthetic map in this file (default: temporary)")
    m.add_argument("--synchronous", choices=("full", "normal"), default="full",
                   help="the service's SQLite synchronous setting (full)")
    m.add_argument("--skip", choices=("live", "query"), default=None,
                   help="leave out one part")
    m.add_argument("--json", action="store_true", help="print one JSON document")
    m.set_defaults(func=main_map)


def main_map(args: argparse.Namespace) -> int:
    """Run the shared-map benchmark (`skin.bench.map`)."""
    from skin._optional import require
    from skin.bench import map as bench

    if args.robots < 1 or args.taxels < 1 or args.minutes <= 0 or args.rate <= 0:
        raise SkinError("--robots, --taxels, --minutes and --rate must be positive")
    if args.voxels < 1 or args.repeats < 1:
        raise SkinError("--voxels and --repeats must be positive")
    doc: dict = {"targets": {"lost": 0, "p99_visible_ms": 100, "query_ms": 50}}
    if args.skip != "live":
        require("zenoh", "the shared map service")
        doc["live"] = bench.live(args.robots, args.taxels, args.minutes, args.rate,
                                 progress=not args.json, synchronous=args.synchronous)
    if args.skip != "query":
        doc["query"] = bench.query_time(args.voxels, args.repeats,
                                        db=Path(args.db) if args.db else None,
                                        progress=not args.json)
    if args.json:
        print(json.dumps(doc))
        return 0
    if "live" in doc:
        live = doc["live"]
        print(f"{live['robots']} robots x {live['taxels']} taxels x {live['minutes']:g} min at "
              f"{live['rate_per_taxel_minute']:g} contacts per taxel-minute (synchronous "
              f"{live['synchronous']}): published "
              f"{live['published']}, held by the map {live['held']}, lost {live['lost']} "
              "(target 0)")
        print(f"decision -> visible to queries (ack arrival): p50 {live['p50_visible_ms']} ms, "
              f"p99 {live['p99_visible_ms']} ms (target <= 100), max {live['max_visible_ms']} ms "
              f"over {live['acks_timed']} contacts")
    if "query" in doc:
        q = doc["query"]
        print(f"1 m^3 box over {q['voxels']} voxels ({q['index']} index, median "
              f"{q['voxels_per_box_median']} voxels per box): the service's reply built in p50 "
              f"{q['query_p50_ms']} ms, max {q['query_max_ms']} ms over {q['repeats']} boxes "
              f"(target <= 50); as Python objects p50 {q['objects_query_p50_ms']} ms; over Zenoh "
              f"from `skin map serve`: p50 {q['zenoh_query_p50_ms']} ms, max "
              f"{q['zenoh_query_max_ms']} ms; a full scan of "
              f"the table in the same run {q['full_scan_ms']} ms (ratio "
              f"{q['query_p50_over_scan']})")
    return 0

"""``skin view --map``: the world material map, contacts as coloured points around the arm.

``--map`` takes a ``skin run`` output folder (its ``events.jsonl``, with the ``layout.toml``
and ``chain.toml`` written beside it), an MCAP recording (its events and layout), or a world
map saved with ``--save`` (``.npz`` or ``.jsonl``). Each contact's taxels are posed at the
contact's onset: by ``--poses`` (joint angles or link poses over time, NPZ or CSV, on the skin's
clock), else by ``--chain`` (or the run's ``chain.toml``, or the default arm's chain) standing at
its default angles. The arm is drawn where the poses leave it (the end of ``--poses``).
``--out map.png`` writes a PNG off screen; without it a window opens.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from skin.errors import SkinError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin view``."""
    view = sub.add_parser("view", help="show the world material map (contacts as coloured "
                                       "points around the arm)", description=__doc__)
    view.add_argument("--map", required=True, metavar="SOURCE",
                      help="a `skin run` output folder, an MCAP recording (.mcap), a saved "
                           "world map (.npz, .jsonl), or a shared map: zenoh://PREFIX[?connect="
                           "...] (`skin map serve`) or its database (.sqlite)")
    view.add_argument("--box", default=None,
                      help="of a shared map, the voxels drawn: x0,y0,z0,x1,y1,z1, m, in the "
                           "map's frame (default: 1.5 m around the robot drawn)")
    view.add_argument("--robot", default=None,
                      help="of a shared map, the robot whose arm is drawn at its pose (default: "
                           "the one with the most contacts)")
    view.add_argument("--out", metavar="PNG", help="write the view to this PNG (off screen) "
                                                   "instead of opening a window")
    view.add_argument("--poses", metavar="FILE",
                      help="joint angles or link poses over time (.npz or .csv; time in s on "
                           "the skin's clock, angles in rad), interpolated at each onset")
    view.add_argument("--chain", metavar="FILE",
                      help="kinematic chain TOML (default: the run's chain.toml, else the "
                           "default arm's)")
    view.add_argument("--layout", help="layout TOML file or shipped name (default: the run's "
                                       "or recording's, else 'arm')")
    view.add_argument("--save", metavar="MAP", help="also save the world map (.npz or .jsonl)")
    view.add_argument("--json", action="store_true",
                      help="print one JSON summary on stdout and nothing else")
    view.set_defaults(func=main)


def _arm_poses(source: Any) -> Any:
    """Where to draw the arm: the end of a pose track, else the source's (still) poses."""
    span = getattr(source, "span", None)
    return source.poses_at(span[1] if span is not None else 0.0)


def main(args: argparse.Namespace) -> int:
    """Build and show the world map (see the module docstring)."""
    from skin.formats.layout import load_layout
    from skin.world.kinematics import as_pose_source, default_chain, load_chain, load_poses
    from skin.world.map import CHAIN_FILE, WorldMap

    if args.map.startswith("zenoh://") or args.map.lower().endswith((".sqlite", ".db")):
        return _shared(args)
    source = Path(args.map)
    if not source.exists():
        raise SkinError(f"--map {args.map}: no such file or folder")
    layout = load_layout(args.layout) if args.layout else None
    chain = load_chain(args.chain) if args.chain else None
    if chain is None and source.is_dir() and (source / CHAIN_FILE).is_file():
        chain = load_chain(source / CHAIN_FILE)
    poses: Any = chain
    if args.poses:
        poses = load_poses(args.poses, chain or default_chain())

    suffix = source.suffix.lower()
    if source.is_dir():
        world = WorldMap.from_run(source, poses=poses, layout=layout)
    elif suffix == ".mcap":
        world = WorldMap.from_recording(source, poses=poses, layout=layout)
    elif suffix in (".npz", ".jsonl", ".json"):
        world = WorldMap.load(source)
        world.notes = ["a saved map: its points as saved (--poses and --chain only place "
                       "the arm)"]
    else:
        raise SkinError(f"--map {args.map}: expected a `skin run` folder, a .mcap recording or "
                        "a saved world map (.npz, .jsonl)")
    if layout is None:
        layout = world.layout if world.layout is not None else load_layout("arm")
    arm_poses = _arm_poses(as_pose_source(poses if poses is not None else world.poses))

    if args.save:
        world.save(args.save)
    from skin.models import load_materials
    from skin.viz.world_view import render_world_map

    colours = {m.name: m.colour for m in load_materials().values()}
    counts = world.counts()
    title = f"world map: {len(world)} points, {world.contacts()} contacts ({source.name})"
    written = render_world_map(world, layout, colours, poses=arm_poses,
                               path=args.out, title=title)
    summary = {
        "source": str(source), "points": len(world), "contacts": world.contacts(),
        "per_material": counts, "skipped": world.skipped, "notes": world.notes,
        "out": None if written is None else str(written),
        "saved": args.save,
    }
    if args.json:
        print(json.dumps(summary))
        return 0
    for note in [*world.notes, *world.skipped]:
        print(f"note: {note}")
    per = ", ".join(f"{name} {n}" for name, n in counts.items()) or "none"
    print(f"world map: {len(world)} points from {world.contacts()} contacts ({per})"
          + ("" if written is None else f" -> {written}")
          + (f"; saved {args.save}" if args.save else ""))
    return 0


def _shared(args: argparse.Namespace) -> int:
    """Draw the voxels of a shared map (`skin.world.shared_map`) in a box around the arm."""
    import numpy as np

    from skin.formats.layout import load_layout
    from skin.models import load_materials
    from skin.viz.world_view import render_world_map
    from skin.world.kinematics import default_chain, load_chain
    from skin.world.map import WorldMap
    from skin.world.map_store import parse_box
    from skin.world.shared_map import SharedMap

    given = parse_box(args.box) if args.box is not None else None  # checked before any session
    with SharedMap(args.map) as shared:
        info = shared.stats()
        robots = info["robots"]
        robot = args.robot or (max(robots, key=robots.__getitem__) if robots else None)
        if robot is not None and robot not in info.get("robot_poses", {}):
            raise SkinError(f"--robot {robot}: not in the map (robots: "
                            f"{', '.join(sorted(robots)) or 'none'})")
        pose = (info.get("robot_poses", {}).get(robot) if robot else None)
        base = np.eye(4) if pose is None else np.asarray(pose, dtype=float)
        x, y, z = base[:3, 3]
        box = given or (x - 1.5, y - 1.5, z - 0.5, x + 1.5, y + 1.5, z + 2.0)
        voxels = shared.query(box)
    n = len(voxels)
    arrays = {"points": np.array([v["center"] for v in voxels], dtype=float).reshape(n, 3),
              "normals": np.zeros((n, 3)), "contact": np.arange(n, dtype=np.int64),
              "taxel": np.full(n, -1, dtype=np.int64), "link": np.full(n, "", dtype="<U1"),
              "label": np.array([v["label"] for v in voxels], dtype=str).reshape(n),
              "confidence": np.array([v["confidence"] for v in voxels], dtype=float),
              "time": np.array([v["last_seen"] for v in voxels], dtype=float)}
    world = WorldMap()
    world._parts, world._arrays = [arrays], arrays
    layout = load_layout(args.layout or "arm")
    chain = load_chain(args.chain) if args.chain else default_chain()
    colours = {m.name: m.colour for m in load_materials().values()}
    title = f"shared map: {n} voxels, arm of {robot or 'no robot'} ({args.map})"
    arm = {link: base @ m for link, m in chain.poses().items()}
    written = render_world_map(world, layout, colours, poses=arm, path=args.out, title=title)
    counts = world.counts()
    if args.json:
        print(json.dumps({"source": args.map, "box": list(box), "robot": robot, "voxels": n,
                          "contacts": sum(v["contacts"] for v in voxels),
                          "per_material": counts,
                          "out": None if written is None else str(written)}))
        return 0
    per = ", ".join(f"{name} {k}" for name, k in counts.items()) or "none"
    print(f"shared map: {n} voxels in {','.join(f'{v:g}' for v in box)} around {robot} ({per})"
          + ("" if written is None else f" -> {written}"))
    return 0

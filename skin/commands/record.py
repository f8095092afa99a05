"""``skin record``: record a device's raw wire bytes, and the layout, to an MCAP file.

Only the bytes (with their host arrival times) and the layout (and a calibration file, if
given) are kept, not temperatures or events: ``skin run --port replay://OUT.mcap`` runs the
pipeline on them later, as often as wanted (`skin.drivers.recording`, `skin.drivers.replay`).
Frames are decoded as they come, only to show progress and link errors. The file is readable
whenever the command stops, Ctrl-C and a kill included.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from skin.progress import Progress


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin record``."""
    rec = sub.add_parser("record", help="record a device's raw bytes to MCAP (replay them with "
                                        "skin run --port replay://FILE)",
                         description=__doc__)
    rec.add_argument("url", help="device URL (serial:///dev/ttyACM0, can://virtual/ch0, "
                                 "sim://default?speed=0, ...)")
    rec.add_argument("out", metavar="OUT.mcap", help="the recording to write")
    rec.add_argument("--duration", type=float, default=None,
                     help="seconds to record (default: until the source ends, or Ctrl-C)")
    rec.add_argument("--layout",
                     help="layout kept in the recording (default: a simulation's or a replayed "
                          "recording's own, else 'arm')")
    rec.add_argument("--calibration", metavar="FILE",
                     help="calibration file kept in the recording")
    rec.add_argument("--json", action="store_true",
                     help="print one JSON summary on stdout and nothing else")
    rec.set_defaults(func=main)


def _driver_layout(driver: Any) -> Any:
    """Return the layout a source knows (a simulation's, a recording's), or None."""
    for d in getattr(driver, "drivers", [driver]):
        sim = getattr(d, "simulator", None)
        if sim is not None:
            return sim.layout
        if hasattr(d, "reader"):  # a replay
            return d.layout
    return None


def main(args: argparse.Namespace) -> int:
    """Record (see the module docstring)."""
    from skin import drivers
    from skin.drivers.recording import Recorder
    from skin.formats.layout import load_layout

    if args.duration is not None and args.duration <= 0:
        from skin.errors import SkinError

        raise SkinError(f"--duration must be > 0 s, got {args.duration:g}")
    progress = Progress()
    driver = drivers.open(args.url)
    try:
        layout = load_layout(args.layout) if args.layout else _driver_layout(driver)
        if layout is None:
            layout = load_layout("arm")
        recorder = Recorder(args.out, layout, calibration=args.calibration,
                            metadata={"command": " ".join(["skin", *sys.argv[1:]])})
        recorder.add_driver(driver)
        progress.message(f"recording {driver.url} to {args.out} (layout {layout.source}, "
                         f"{len(layout)} taxels)")
        t0 = time.monotonic()
        shown = 0.0
        frames = 0
        interrupted = False
        try:
            while True:
                elapsed = time.monotonic() - t0
                if args.duration is not None and elapsed >= args.duration:
                    break
                wait = 0.2 if args.duration is None else min(0.2, args.duration - elapsed)
                frame = driver.recv(timeout=max(0.0, wait))
                if frame is not None:
                    frames += 1
                elif driver.finished:
                    break
                if elapsed - shown >= 0.25:
                    shown = elapsed
                    total = "" if args.duration is None else f"/{args.duration:g}"
                    progress.status(f"[{elapsed:6.1f}{total} s] {frames} frames, "
                                    f"{recorder.bytes_recorded / 1e3:.0f} kB off the wire, "
                                    f"file {recorder.size() / 1e6:.2f} MB, "
                                    f"crc errors {driver.stats.crc_errors}", elapsed)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            recorder.close()
        seconds = time.monotonic() - t0
    finally:
        driver.close()
        progress.done()
    summary = {
        "url": args.url, "out": str(args.out), "seconds": round(seconds, 3), "frames": frames,
        "wire_bytes": recorder.bytes_recorded, "messages": recorder.messages,
        "file_bytes": recorder.size(), "crc_errors": driver.stats.crc_errors,
        "malformed": driver.stats.malformed, "interrupted": interrupted,
    }
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"{frames} frames in {seconds:.1f} s: {summary['wire_bytes']} bytes off the wire, "
              f"{summary['file_bytes']} in {args.out} ({summary['crc_errors']} CRC errors); "
              f"replay: skin run --port replay://{args.out}")
    return 0

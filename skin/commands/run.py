"""``skin run``: the main job.

Read a skin (a device, or a simulated skin served on a real pseudo-terminal when no device is
given), detect contacts, label their materials, and write ``events.jsonl``, ``summary.json`` and
``contact_map.png`` (and ``layout.toml``, with ``chain.toml`` for a simulation: the arm's pose,
for ``skin view --map``). ``--record run.mcap`` also keeps the wire bytes, temperatures and events
(`skin.drivers.recording`); ``--port replay://run.mcap`` plays such a recording again, with
its layout and calibration unless ``--layout`` / ``--calibration`` say otherwise. The setup is
``./skin.toml`` (or ``--config FILE``) when there is one, each option given here overriding it
(``skin config show`` prints it); everything is checked before the first frame (`skin.Skin`).
An output folder holding an earlier run is kept unless ``--force``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from skin.setup import Setup, setup_fields


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin run``."""
    # no defaults here: an option left out is absent, so the setup's value (default or skin
    # file) stays; an option's dest is its `skin.setup.Setup` field
    run = sub.add_parser("run", help="read a skin, detect contacts, label materials (main job)",
                         description=__doc__, argument_default=argparse.SUPPRESS)
    add_setup_options(run)
    run.add_argument("--json", action="store_true",
                     help="print one JSON summary on stdout and nothing else")
    run.set_defaults(func=main)


def add_setup_options(run: argparse.ArgumentParser) -> None:
    """Add the options of a setup (``skin run``, ``skin config show``); no defaults."""
    run.add_argument("--config", metavar="FILE",
                     help="skin file (TOML) declaring the setup; options given here override "
                          "it (default: ./skin.toml when there is one)")
    run.add_argument("--port", metavar="URL", action="append",
                     help="device URL (serial:///dev/ttyACM0, can://socketcan/can0, "
                          "sim://default, replay://run.mcap ...); repeat it for a skin of "
                          "several boards or buses; default: a simulated skin served on a "
                          "pseudo-terminal")
    run.add_argument("--reconnect", type=float, metavar="SECONDS",
                     help="after a serial or CAN device fails (unplugged, bus-off), keep "
                          "reopening it for this long before giving up (default 10; 0: "
                          "stop at once; a URL's own reconnect= wins)")
    run.add_argument("--firmware-sim", action="store_true",
                     help="play the scene to the compiled firmware (ATmega2560, 72 taxels) "
                          "running in simavr, read over its pseudo-terminal; needs "
                          "`make -C firmware all harness`")
    run.add_argument("--scene",
                     help="simulation scene: a shipped name or a TOML file (default: default)")
    run.add_argument("--seed", type=int,
                     help="the simulation's seed in place of the scene's: the same touches "
                          "with other noise, starting temperatures and taxel units")
    run.add_argument("--layout", help="layout TOML file (default: the scene's, or 'arm')")
    run.add_argument("--duration", type=float,
                     help="seconds to run (default: the scene's duration; 20 for a device)")
    run.add_argument("--speed", type=float,
                     help="simulation pace relative to real time; 0 = as fast as possible")
    run.add_argument("--contact", choices=("perfect", "finite"),
                     help="simulated contact: perfect (eq. 5) or finite, with each "
                          "material's contact conductance (default: the scene's, perfect "
                          "unless it says contact = \"finite\")")
    run.add_argument("--out", help="output folder (default: out/run)")
    run.add_argument("--model", metavar="FILE",
                     help="classify with a model file from `skin train` (taxels' evidence "
                          "fused); default: see --classifier")
    run.add_argument("--threshold", type=float, metavar="P",
                     help="probability needed to name a material (else its family, else "
                          "\"unknown\"), for --model and the joint classifier (default 0.5)")
    run.add_argument("--object-temperature-range", type=float, metavar="K",
                     help="with --model: objects may be K colder or warmer than the model's "
                          "training data; its confidence is bounded by the physics over that "
                          "range (default: a simulated scene's largest object offset from its "
                          "ambient, else 0)")
    run.add_argument("--classifier", choices=("joint", "histogram"),
                     help="without --model: the joint model that weighs a contact's taxels "
                          "with one object (default), or the paper's effusivity histogram")
    run.add_argument("--calibration", metavar="FILE",
                     help="per-taxel calibration file from `skin calibrate` (thermistors and "
                          "thermal constants; taxels it misses keep their board's constants)")
    run.add_argument("--window", type=float,
                     help="decision time: a contact is classified at its release or this many "
                          "seconds after its onset, whichever comes first (default 2.5)")
    run.add_argument("--provisional", metavar="SECONDS",
                     help="also classify contacts still open at these seconds after their "
                          "onset, e.g. 0.5,1 (anytime answers, marked ~ and \"final\": false)")
    run.add_argument("--record", metavar="FILE.mcap",
                     help="record the wire bytes, temperatures, events, layout and calibration "
                          "to an MCAP file (replay it with --port replay://FILE.mcap)")
    run.add_argument("--no-map", dest="map", action="store_false",
                     help="do not render contact_map.png")
    run.add_argument("--view", action="store_true",
                     help="show the arm in a window, painted as contacts come (at most 10 "
                          "redraws a second; key t: material / temperature); needs a display")
    run.add_argument("--video", metavar="FILE",
                     help="write a movie of the arm view (.gif; .mp4 needs imageio-ffmpeg), "
                          "10 frames per second of the run, off screen")
    run.add_argument("--view-mode", choices=("material", "temperature"),
                     help="what --view and --video show first: material labels (default) or "
                          "each taxel's temperature")
    run.add_argument("--arm", metavar="FILE",
                     help="arm file (TOML: a mesh file and pose per link; or a URDF; or xarm7, "
                          "the example arm) for the views and "
                          "contact_map.png; default: the procedural arm of the default layout")
    run.add_argument("--first-frame-timeout", type=float, metavar="SECONDS",
                     help="fail when a device sends no frame within this time (default 5)")
    run.add_argument("--expect", action="append", metavar="MATERIAL",
                     help="a material the classifier must know (repeatable; a scene adds "
                          "its own): checked before the first frame")
    run.add_argument("--sink", dest="sinks", action="append", metavar="NAME|FILE.jsonl",
                     help="where results go: events (events.jsonl in --out), terminal, or a "
                          "JSON-lines file; repeatable (default: events and terminal)")
    run.add_argument("--publish", action="append", metavar="URL",
                     help="publish live: foxglove://HOST:PORT (a Foxglove WebSocket server) or "
                          "zenoh://[PREFIX] (keys PREFIX/ROBOT/temperature, contacts, health); "
                          "repeatable (skin.stream.publish)")
    run.add_argument("--force", action="store_true",
                     help="overwrite the outputs of an earlier run in --out")
    run.add_argument("--workers", type=int, metavar="N",
                     help="worker processes: with N or more serial --port (one board each), "
                          "each worker reads and processes its own boards; otherwise onset "
                          "detection is sharded across them (default 1; the same results); "
                          "with --common-mode each board stays in one process (a board's "
                          "common mode needs all its taxels), so a one-board skin runs in one")
    run.add_argument("--common-mode", action=argparse.BooleanOptionalAction,
                     help="the onset detector's board common mode: the room's change, shared "
                          "alike by nearly every free taxel of a board of 4 or more, taken "
                          "off first (OnsetDetector common_mode; default: on for sensors "
                          "whose heater is not PID-held, off for PID-held ones, skin.toml "
                          "[skin] common_mode = \"auto\"); it keeps each board in one "
                          "process, so --workers shards by whole boards")
    run.add_argument("--force-onsets", action=argparse.BooleanOptionalAction,
                     help="date the contacts of taxels whose frames carry a force or contact "
                          "reading by it (exact onset and release; the onset detector where "
                          "it has none); --no-force-onsets: the onset detector dates every "
                          "taxel (skin.stream.force; default on)")
    run.add_argument("--response-check", action=argparse.BooleanOptionalAction,
                     help="answer \"unknown\" (noted \"no thermal response\") for a contact "
                          "the force alone dated whose temperature shows no contact: a "
                          "likelihood-ratio test at the detector's noise (skin.stream.response; "
                          "default on); --no-response-check: classify it whatever it shows")


def main(args: argparse.Namespace) -> int:
    """Run the main job (see the module docstring) over `skin.Skin`."""
    from skin.runner import Skin

    with Skin(resolve_setup(args)) as skin:
        summary = skin.run()
    if getattr(args, "json", False):
        print(json.dumps(summary))
    else:
        _print_table([r for r in skin.records if r["final"]], summary, skin.setup.out)
    return 0


def resolve_setup(args: argparse.Namespace) -> Setup:
    """Return the setup of ``skin run``: defaults < skin file (--config, ./skin.toml) < options."""
    from skin.formats.skin_file import find_skin_file, load_skin_file

    path = getattr(args, "config", None) or find_skin_file()
    setup = Setup() if path is None else load_skin_file(path)
    given = {k: v for k, v in vars(args).items() if k in setup_fields()}
    return setup.updated(given, "command line")


def _print_table(records: list[dict[str, Any]], summary: dict[str, Any], out: str | None) -> None:
    print(f"\n{'id':>3} {'onset s':>8} {'dur s':>6} {'taxels':<18} {'label':<11} {'conf':>5} "
          f"{'family':<14} {'e fit':>7} {'truth':<11}")
    for rec in records:
        eff = "-" if rec["effusivity"] is None else f"{rec['effusivity']:.0f}"
        truth = rec.get("truth") or ("-" if "truth" not in rec else "(none)")
        dur = "open" if rec["duration"] is None else f"{rec['duration']:.2f}"
        print(f"{rec['contact']:>3} {rec['onset']:>8.2f} {dur:>6} "
              f"{','.join(map(str, rec['taxels'])):<18} {rec['label']:<11} "
              f"{rec['confidence']:>5.2f} {rec.get('family') or '-':<14} {eff:>7} {truth:<11}")
    print(f"\n{summary['frames']} frames in {summary['wall_time']:.1f} s wall time, "
          f"{summary['contacts']} contacts, {summary['crc_errors']} CRC errors, "
          f"{summary['gaps']} frames lost (gaps), {summary['late']} late frames dropped")
    if "touches" in summary:
        print(f"scene truth: {summary['detected']}/{summary['touches']} touches detected, "
              f"{summary['correct']}/{summary['touches']} labelled correctly "
              f"({summary['family_correct']}/{summary['touches']} at family level) "
              f"(accuracy {summary['accuracy']:.0%}), {summary['false_contacts']} false contacts; "
              f"median onset error {summary['median_onset_error']} s"
              + ("" if summary["median_log10_effusivity_error"] is None else
                 f", median error of the measured effusivity "
                 f"{summary['median_log10_effusivity_error']} decades"))
    if "force" in summary:
        dated = summary["force"]["dated_taxels"]
        silent = summary["force"].get("no_thermal_response", [])
        print(f"force channel: {len(dated)} taxels dated by their force"
              + (f"; {len(silent)} of its contacts showed no thermal response (unknown: "
                 f"{', '.join(map(str, silent))})" if silent else "")
              + "".join(f"\n  {note}" for note in summary["force"]["notes"]))
    if out is not None:
        files = [Path(out) / n for n in ("events.jsonl", "summary.json", "contact_map.png")]
        print(f"outputs: {', '.join(str(f) for f in files if f.exists())}")

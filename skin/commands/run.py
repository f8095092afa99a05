"""``skin run``: the main job.

Read a skin (a device, or a simulated skin served on a real pseudo-terminal when no device is
given), detect contacts, label their materials, and write ``events.jsonl``, ``summary.json`` and
``contact_map.png`` (and ``layout.toml``, with ``chain.toml`` for a simulation: the arm's pose,
for ``skin view --map``). ``--record run.mcap`` also keeps the wire bytes, temperatures and events
(`skin.drivers.recording`); ``--port replay://run.mcap`` plays such a recording again, with
its layout and calibration unless ``--layout`` / ``--calibration`` say otherwise.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from skin.errors import DeviceError, SkinError
from skin.progress import Progress
from skin.stream.pipeline import ContactResult, Pipeline
from skin.stream.sinks import JsonLinesSink, TerminalSink, event_record


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin run``."""
    run = sub.add_parser("run", help="read a skin, detect contacts, label materials (main job)",
                         description=__doc__)
    run.add_argument("--port", metavar="URL", action="append",
                     help="device URL (serial:///dev/ttyACM0, can://socketcan/can0, "
                          "sim://default, replay://run.mcap ...); repeat it for a skin of "
                          "several boards or buses; default: a simulated skin served on a "
                          "pseudo-terminal")
    run.add_argument("--reconnect", type=float, default=10.0, metavar="SECONDS",
                     help="after a serial or CAN device fails (unplugged, bus-off), keep "
                          "reopening it for this long before giving up (default 10; 0: "
                          "stop at once; a URL's own reconnect= wins)")
    run.add_argument("--firmware-sim", action="store_true",
                     help="play the scene to the compiled firmware (ATmega2560, 72 taxels) "
                          "running in simavr, read over its pseudo-terminal; needs "
                          "`make -C firmware all harness`")
    run.add_argument("--scene", default="default",
                     help="simulation scene: a shipped name or a TOML file (default: default)")
    run.add_argument("--layout", help="layout TOML file (default: the scene's, or 'arm')")
    run.add_argument("--duration", type=float, default=None,
                     help="seconds to run (default: the scene's duration; 20 for a device)")
    run.add_argument("--speed", type=float, default=1.0,
                     help="simulation pace relative to real time; 0 = as fast as possible")
    run.add_argument("--contact", choices=("perfect", "finite"), default="perfect",
                     help="simulated contact: perfect (eq. 5, default) or finite, with each "
                          "material's contact conductance")
    run.add_argument("--out", default="out/run", help="output folder (default: out/run)")
    run.add_argument("--model", metavar="FILE",
                     help="classify with a model file from `skin train` (taxels' evidence "
                          "fused); default: see --classifier")
    run.add_argument("--threshold", type=float, default=0.5, metavar="P",
                     help="probability needed to name a material (else its family, else "
                          "\"unknown\") for --model and the joint classifier (default 0.5)")
    run.add_argument("--classifier", choices=("joint", "histogram"), default="joint",
                     help="without --model: the joint model that weighs a contact's taxels "
                          "with one object (default), or the paper's effusivity histogram")
    run.add_argument("--calibration", metavar="FILE",
                     help="per-taxel calibration file from `skin calibrate` (thermistors and "
                          "thermal constants; taxels it misses keep their board's constants)")
    run.add_argument("--window", type=float, default=2.5,
                     help="decision time: a contact is classified at its release or this many "
                          "seconds after its onset, whichever comes first (default 2.5)")
    run.add_argument("--provisional", default="", metavar="SECONDS",
                     help="also classify contacts still open at these seconds after their "
                          "onset, e.g. 0.5,1 (anytime answers, marked ~ and \"final\": false)")
    run.add_argument("--record", metavar="FILE.mcap",
                     help="record the wire bytes, temperatures, events, layout and calibration "
                          "to an MCAP file (replay it with --port replay://FILE.mcap)")
    run.add_argument("--no-map", action="store_true", help="do not render contact_map.png")
    run.add_argument("--view", action="store_true",
                     help="show the arm in a window, painted as contacts come (at most 10 "
                          "redraws a second; key t: material / temperature); needs a display")
    run.add_argument("--video", metavar="FILE",
                     help="write a movie of the arm view (.gif; .mp4 needs imageio-ffmpeg), "
                          "10 frames per second of the run, off screen")
    run.add_argument("--view-mode", choices=("material", "temperature"), default="material",
                     help="what --view and --video show first: material labels (default) or "
                          "each taxel's temperature")
    run.add_argument("--arm", metavar="FILE",
                     help="arm file (TOML: a mesh file and pose per link) for the views and "
                          "contact_map.png; default: the procedural arm of the default layout")
    run.add_argument("--json", action="store_true",
                     help="print one JSON summary on stdout and nothing else")
    run.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run the main job (see the module docstring)."""
    ports = args.port or []
    if len(ports) > 1 and any(p.startswith(("replay:", "sim:")) for p in ports):
        raise SkinError("--port: several URLs make one skin of several boards or buses; "
                        "sim:// and replay:// are whole skins and come alone")
    args.port = ports[0] if len(ports) == 1 else ports or None
    replay = isinstance(args.port, str) and args.port.startswith("replay:")
    if args.duration is None and args.port is not None and not replay:
        args.duration = 20.0
    from skin import drivers
    from skin.formats.layout import load_layout
    from skin.formats.scene import load_scene, match_touches
    from skin.models import HistogramClassifier, JointClassifier, load_materials

    if args.view:
        from skin.viz.arm import window_problem

        why = window_problem()
        if why is not None:
            raise SkinError(f"--view: cannot open a window: {why}; use --video out/run.gif to "
                            "record the view off screen")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    progress = Progress()
    device = None
    scene = None
    recorded_cal: Any = None  # a replay's recorded calibration
    if args.port is None and args.firmware_sim:
        from skin.drivers.firmware_board import emulated_board, firmware_scene
        from skin.drivers.sim import SkinSimulator

        scene = firmware_scene(load_scene(args.scene))
        layout = scene.layout
        sim = SkinSimulator(scene, duration=args.duration, contact=args.contact)
        device = emulated_board(sim, folder=out,
                                realtime=args.speed if args.speed > 0 else None)
        url = f"serial://{device.start()}"
        duration = sim.duration
        progress.message(f"scene '{scene.name}' ({len(layout)} taxels, {len(scene.touches)} "
                         f"touches) played to the firmware in simavr on {device.port}")
    elif args.port is None:
        from skin.drivers.sim import PtySerialDevice, SkinSimulator

        scene = load_scene(args.scene)
        layout = scene.layout if args.layout is None else load_layout(args.layout)
        sim = SkinSimulator(scene, duration=args.duration, contact=args.contact)
        device = PtySerialDevice(sim, speed=args.speed)
        url = f"serial://{device.port}"
        duration = sim.duration
        progress.message(f"simulated skin '{scene.name}' ({len(layout)} taxels, "
                         f"{len(scene.touches)} touches) served on {device.port}")
    else:
        url = args.port
        duration = args.duration
        recorded_layout = None
        if replay:  # the recording's layout and calibration, unless the user gives others
            from skin.drivers.replay import recorded_setup, replay_path

            recorded_layout, recorded_cal = recorded_setup(replay_path(url))
            if duration is None:
                duration = math.inf  # to the end of the recording
        if args.layout or recorded_layout is None:
            layout = load_layout(args.layout or "arm")
            recorded_cal = None  # it belongs to the recording's layout
        else:
            layout = recorded_layout
            progress.message(f"replaying {url}: its layout ({len(layout)} taxels)"
                             + ("" if recorded_cal is None or args.calibration
                                else " and calibration"))
    materials = load_materials()
    calibration, sensors = None, None
    cal_file: Any = None
    if not args.calibration and recorded_cal is not None:
        from skin.stream.calibration import Calibration

        if isinstance(recorded_cal, Calibration):
            calibration = recorded_cal
        else:
            cal_file = recorded_cal
            calibration, sensors = cal_file.apply(layout)
    if args.calibration:
        from skin.formats.calibration_file import load_calibration

        cal_file = load_calibration(args.calibration)
        calibration, sensors = cal_file.apply(layout)
        for part in ("thermistor", "thermal"):
            miss = cal_file.missing(layout, part)
            if miss:
                progress.message(f"calibration: {len(miss)} taxels without a {part} fit keep "
                                 f"their board's constants: {miss[:10]}"
                                 f"{' ...' if len(miss) > 10 else ''}")
    if args.model:
        from skin.models.learned import LearnedClassifier

        classifier = LearnedClassifier(args.model, threshold=args.threshold)
        progress.message(f"classifier: {classifier.method} ({len(classifier.classes)} classes, "
                         f"{classifier.samples / classifier.fs:g} s window)")
        if scene is not None:  # a model that cannot name what the scene holds says so
            from skin.models.learned import uncovered_classes

            missing = uncovered_classes(classifier,
                                        [scene.material_of(t) for t in scene.touches])
            if missing:
                progress.message(f"warning: the model was not trained on {', '.join(missing)}, "
                                 f"which the scene holds: those contacts will be called "
                                 f"something else")
    elif args.classifier == "joint":
        classifier = JointClassifier(
            layout, materials, threshold=args.threshold, sensors=None if sensors is None else
            {int(t.id): s for t, s in zip(layout.taxels, sensors, strict=True)})
    else:
        classifier = HistogramClassifier(layout, materials)
    given: list[ContactResult] = []  # every result, provisional ones too
    events_path = out / "events.jsonl"
    t_wall = time.monotonic()
    first_time: float | None = None
    try:
        provisional = [float(v) for v in args.provisional.split(",") if v.strip()]
        pipeline = Pipeline(layout, classifier, calibration=calibration, sensors=sensors,
                            ambient_offset=0.0 if cal_file is None else
                            cal_file.ambient_offset, window=args.window,
                            provisional=provisional)
    except ValueError as exc:
        raise SkinError(f"--window / --provisional: {exc}") from None
    events = JsonLinesSink(events_path)  # a killed run keeps every contact already given
    pipeline.sinks += [events, TerminalSink(progress)]
    recorder = None
    if args.record:
        from skin.drivers.recording import Recorder

        recorder = Recorder(args.record, layout,
                            calibration=args.calibration or cal_file or calibration,
                            metadata={"command": " ".join(["skin", *sys.argv[1:]])})
        pipeline.sinks.append(recorder)
        pipeline.observers.append(recorder.temperature)
    live = None
    try:
        if args.view or args.video:
            live = _live_view(args, layout, materials)
        with drivers.open(url) as driver:
            # a device given by the user reconnects; the simulated ones end by going away
            for one, port_url in zip(getattr(driver, "drivers", [driver]), ports, strict=False):
                if port_url.startswith(("serial", "can:")) and "reconnect=" not in port_url:
                    one.reconnect = args.reconnect
            if recorder is not None:
                recorder.add_driver(driver)
            if args.firmware_sim:
                from skin.drivers.protocol import ALL_TAXELS, Command, MsgType

                # the scene was simulated with every heater on; the firmware boots with them off
                driver.request(Command(MsgType.SET_DUTY, taxel=ALL_TAXELS, duty=255),
                               timeout=5.0)
            elif device is not None:
                device.start()  # after the port is open: opening it empties its buffer
            chunk: list = []
            now = 0.0
            received = 0
            idle_since = time.monotonic()
            while True:
                try:
                    frame = driver.recv(timeout=0.2)
                except DeviceError:
                    if not args.firmware_sim or device.running:
                        raise
                    frame = None  # the emulated board played its whole scene and stopped
                    now = duration
                if frame is not None:
                    if first_time is None:
                        first_time = frame.device_time
                    chunk.append(frame)
                    received += 1
                    now = frame.device_time - first_time
                    idle_since = time.monotonic()
                idle = frame is None
                # a simulated board is done once all it sent is in (or after 2 s of silence)
                end_of_sim = device is not None and not args.firmware_sim and (
                    device.done.is_set() and (received >= device.frames_sent
                                              or time.monotonic() - idle_since > 2.0))
                finished = now >= duration - 1e-9 or end_of_sim or (idle and driver.finished) or (
                    device is None and idle and time.monotonic() - t_wall > duration + 5)
                if chunk and (len(chunk) >= 20 or idle or finished):
                    new = pipeline.process(chunk)
                    given.extend(new)
                    chunk = []
                    if live is not None:
                        live.step(now, new, pipeline.in_contact(), pipeline.last_temperature)
                    progress.status(
                        f"[{now:6.1f}{'' if math.isinf(duration) else f'/{duration:.1f}'} s] "
                        f"frames {pipeline.stats.frames}  "
                        f"in contact {int(pipeline.in_contact().sum()):2d}  "
                        f"contacts {pipeline.stats.contacts}  "
                        f"crc errors {driver.stats.crc_errors}", now)
                if finished:
                    break
            new = pipeline.flush()
            given.extend(new)
            if live is not None:
                live.step(now, new, pipeline.in_contact(), pipeline.last_temperature)
            link, health = driver.stats, driver.health
    except KeyboardInterrupt:
        progress.message("interrupted: writing what was received")
        link = health = None
    finally:
        events.close()
        if live is not None:
            live.close()
            if live.movie is not None:
                progress.message(f"video: {live.movie} ({live.frames} frames)")
        if recorder is not None:
            recorder.close()
        progress.done()
        if device is not None:
            device.close()
    wall = time.monotonic() - t_wall
    if math.isinf(duration):  # a replay to its end: the time it held
        duration = pipeline.stats.samples / next(iter(layout.boards.values())).sample_rate
    results = [r for r in given if r.contact.final]
    records = [event_record(r) for r in given]

    summary: dict[str, Any] = {
        "source": "simulation" if scene is not None else url,
        "scene": None if scene is None else scene.source,
        "duration": duration,
        "wall_time": round(wall, 3),
        "frames": pipeline.stats.frames,
        "gaps": pipeline.stats.gaps,
        "crc_errors": None if link is None else link.crc_errors,
        "malformed": None if link is None else link.malformed,
        "faults": None if health is None else health.faults,
        "reconnects": None if health is None else health.reconnects,
        "flagged_taxels": [int(layout.ids[k]) for k in np.flatnonzero(pipeline.stats.flagged)],
        "contacts": len(results),
    }
    if scene is not None:
        in_time = [t for t in scene.touches if t.start < duration]
        trimmed = scene if len(in_time) == len(scene.touches) else _with_touches(scene, in_time)
        matches, unmatched = match_touches(trimmed, [r.contact.taxels for r in results],
                                           [r.contact.onset for r in results])
        detected = [m for m in matches if m.contact_index is not None]
        correct = [m for m in detected if results[m.contact_index].estimate.label == m.material]
        family_correct = [m for m in detected if results[m.contact_index].estimate.family
                          == materials[m.material].family]
        # the measured effusivity (skin.models.contact_fit) against the scene's material
        errors = [abs(np.log10(results[m.contact_index].estimate.effusivity
                               / materials[m.material].effusivity))
                  for m in detected if results[m.contact_index].estimate.effusivity]
        truth: dict[int, str | None] = {results[i].contact.id: None for i in unmatched}
        truth.update({results[m.contact_index].contact.id: m.material for m in detected})
        for rec in records:
            if rec["contact"] in truth:
                rec["truth"] = truth[rec["contact"]]
                rec["truth_family"] = (None if rec["truth"] is None
                                       else materials[rec["truth"]].family)
        # the truth is known only once all contacts are matched: rewrite the file with it
        with events_path.open("w", encoding="utf-8") as file:
            for rec in records:
                file.write(json.dumps(rec) + "\n")
        summary.update({
            "touches": len(matches),
            "detected": len(detected),
            "correct": len(correct),
            "family_correct": len(family_correct),
            "false_contacts": len(unmatched),
            "accuracy": round(len(correct) / len(matches), 4) if matches else None,
            "median_onset_error": round(float(np.median(
                [abs(results[m.contact_index].contact.onset - m.touch.start) for m in detected]
            )), 4) if detected else None,
            "median_log10_effusivity_error": round(float(np.median(errors)), 4) if errors else None,
            "per_touch": [
                {"start": m.touch.start, "taxels": list(m.touch.taxels), "truth": m.material,
                 "label": None if m.contact_index is None
                 else results[m.contact_index].estimate.label,
                 "family": None if m.contact_index is None
                 else results[m.contact_index].estimate.family}
                for m in matches
            ],
        })
    from skin.world.kinematics import default_chain
    from skin.world.map import write_run_setup

    # what `skin view --map` needs: the layout, and for a simulation the arm's pose (standing
    # at the default chain's default angles); a device's poses are unknown here
    summary.update(write_run_setup(out, layout, default_chain() if scene is not None else None))
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")

    if not args.no_map:
        from skin.viz import ArmView

        # every contact of the run, at its confidence, none faded
        view = ArmView(layout, {m.name: m.colour for m in materials.values()}, arm=args.arm,
                       memory=None)
        view.update(duration, results=results)
        title = f"contact map: {len(results)} contacts in {duration:g} s"
        view.screenshot(out / "contact_map.png", title=title)
        view.close()

    if args.json:
        print(json.dumps(summary))
    else:
        _print_table([r for r in records if r["final"]], summary, out)
    return 0


def _live_view(args: argparse.Namespace, layout: Any, materials: Any) -> Any:
    """Open the window (--view) and/or the movie (--video) of the run."""
    from skin.viz import ArmView
    from skin.viz.arm_live import LiveArm

    view = ArmView(layout, {m.name: m.colour for m in materials.values()}, arm=args.arm,
                   off_screen=not args.view, window_size=(1200, 560) if args.view else (960, 440))
    view.mode = args.view_mode
    try:
        return LiveArm(view, window=args.view, movie=args.video)
    except BaseException:
        view.close()
        raise


def _with_touches(scene: Any, touches: list) -> Any:
    from dataclasses import replace

    return replace(scene, touches=tuple(touches))


def _print_table(records: list[dict[str, Any]], summary: dict[str, Any], out: Path) -> None:
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
          f"{summary['contacts']} contacts, {summary['crc_errors']} CRC errors")
    if "touches" in summary:
        print(f"scene truth: {summary['detected']}/{summary['touches']} touches detected, "
              f"{summary['correct']}/{summary['touches']} labelled correctly "
              f"({summary['family_correct']}/{summary['touches']} at family level) "
              f"(accuracy {summary['accuracy']:.0%}), {summary['false_contacts']} false contacts; "
              f"median onset error {summary['median_onset_error']} s"
              + ("" if summary["median_log10_effusivity_error"] is None else
                 f", median error of the measured effusivity "
                 f"{summary['median_log10_effusivity_error']} decades"))
    print(f"outputs: {out / 'events.jsonl'}, {out / 'summary.json'}"
          + ("" if not (out / "contact_map.png").exists() else f", {out / 'contact_map.png'}"))

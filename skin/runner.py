"""`Skin`: a setup built into a running chain - sources, calibration, classifier, sinks, outputs.

``Skin`` resolves a `skin.setup.Setup` into the objects of the chain and checks every input
before the first frame is read: files exist and parse, the arm has a mesh for every link of the
layout, the model knows every expected material, the ports open, the calibration reads. Then
``results()`` yields each result as it comes, ``run()`` runs to the end and writes the outputs
(``events.jsonl``, ``summary.json``, ``layout.toml``, ``chain.toml``, ``contact_map.png``), and
``close()`` (or the ``with`` block) closes everything::

    from skin import Skin

    with Skin(port=["replay://run.mcap"], calibration="cal.json", out=None) as skin:
        for result in skin.results():
            print(result.contact.onset, result.estimate.label)

A new kind of output is a sink (anything with ``write(result)``, `skin.stream.sinks`): append it
to ``skin.pipeline.sinks`` after ``check()``, or give it a name in `Skin._make_sinks`.
"""

from __future__ import annotations

import json
import logging
import math
import sys
import time
from collections import deque
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from skin.errors import DeviceError, SkinError
from skin.progress import Progress
from skin.setup import SINKS, Setup, SetupError
from skin.stream.pipeline import ContactResult, Pipeline

log = logging.getLogger("skin.runner")

OUTPUTS = ("events.jsonl", "summary.json", "contact_map.png")
"""Files whose presence marks an output folder as holding an earlier run."""

KEEP_RECENT = 1000
"""Results (and their records) `Skin` keeps of a run of a device: the most recent ones."""


class Skin:
    """A setup built into a chain, checked before the first frame (see the module docstring).

    Parameters
    ----------
    setup : Setup, optional
        The setup (default: every default).
    progress : Progress, optional
        Where messages and the status line go (default: stderr).
    **values
        Setup fields that override ``setup`` (``port=[...]``, ``calibration="cal.json"``...).

    Attributes
    ----------
    setup : Setup
        The resolved setup.
    layout, calibration, classifier, pipeline, scene, materials
        The chain's parts, set by `check`.
    records : list of dict
        The results given, as the lines of ``events.jsonl`` (with ``truth`` for a scene):
        every one for a simulated scene (its touches bound them), else the last
        `KEEP_RECENT` (``events.jsonl`` and the sinks have them all).
    results_given : collections.deque of ContactResult
        The last `KEEP_RECENT` results given. The summary's figures do not depend on it: the
        counts run as results come, and only a scene's matching and the contact map keep
        every final contact, without its samples (``contact.windows`` emptied), so a
        day-long run of a device does not grow with its contacts.
    summary : dict or None
        What `run` (or `finish`) reported.
    """

    def __init__(self, setup: Setup | None = None, *, progress: Progress | None = None,
                 **values: Any) -> None:
        setup = Setup() if setup is None else setup
        self.setup = setup.updated(values, "python") if values else setup
        self.progress = Progress() if progress is None else progress
        self.records: list[dict[str, Any]] = []
        self.summary: dict[str, Any] | None = None
        self.results_given: deque[ContactResult] = deque(maxlen=KEEP_RECENT)
        self._records: deque[dict[str, Any]] | list[dict[str, Any]] = deque(maxlen=KEEP_RECENT)
        self._finals: list[ContactResult] = []  # without samples, when needed:
        self._keep_finals: bool | None = None  # a scene's matching or the contact map
        self._final_count = 0
        self._checked = False
        self._opened = False
        self._closed = False
        self._device: Any = None
        self._driver: Any = None
        self._workers: Any = None  # BoardWorkers: serial boards read in worker processes
        self._closers: list[Any] = []
        self._live: Any = None
        self._recorder: Any = None
        self.publishers: list[Any] = []
        self._events_path: Path | None = None
        self._link: Any = None
        self._health: Any = None
        self._now = 0.0
        self._t_wall = 0.0

    @classmethod
    def from_file(cls, path: str | Path = "skin.toml", *, progress: Progress | None = None,
                  **values: Any) -> Skin:
        """Make a `Skin` of a skin file, ``values`` overriding it (`skin.formats.skin_file`)."""
        from skin.formats.skin_file import load_skin_file

        return cls(load_skin_file(path), progress=progress, **values)

    # --- checks, before any frame ---------------------------------------------------------
    def check(self) -> Skin:
        """Resolve and check every input; nothing is read from a source yet (idempotent).

        Raises
        ------
        SkinError
            Naming the option, the file (and line) and the problem of the first bad input.
        """
        if self._checked:
            return self
        s = self.setup
        if len(s.port) > 1 and any(p.startswith(("replay:", "sim:")) for p in s.port):
            raise SkinError("--port: several URLs make one skin of several boards or buses; "
                            "sim:// and replay:// are whole skins and come alone")
        self.url: Any = s.port[0] if len(s.port) == 1 else list(s.port) or None
        self.replay = isinstance(self.url, str) and self.url.startswith("replay:")
        bad = [k for k in s.sinks if k not in SINKS and not k.endswith(".jsonl")]
        if bad:
            raise SetupError(f"sinks: unknown sink {bad[0]!r} (use {', '.join(SINKS)} or a "
                             "file.jsonl)")
        from skin.stream.publish import check_publisher_url

        for url in s.publish:  # the scheme, its options and its package, before any frame
            check_publisher_url(url)
        if s.view:
            from skin.viz.arm import window_problem

            why = window_problem()
            if why is not None:
                raise SkinError(f"--view: cannot open a window: {why}; use --video "
                                "out/run.gif to record the view off screen")
        self._check_source()
        self._check_calibration()
        self._check_classifier()
        self._check_arm()
        from skin.formats.calibration_file import noise_sigma

        try:
            self.pipeline = Pipeline(
                self.layout, self.classifier, calibration=self.calibration, sensors=self.sensors,
                ambient_offset=0.0 if self.cal_file is None else self.cal_file.ambient_offset,
                window=s.window, provisional=s.provisional, workers=s.workers,
                common_mode=None if s.common_mode == "auto" else s.common_mode,
                force_onsets=s.force_onsets, response_check=s.response_check,
                noise=noise_sigma(self.cal_file, self.layout))  # commissioned noise, if any
        except ValueError as exc:
            which = "" if str(exc).startswith("common_mode") else "--window / --provisional: "
            raise SkinError(f"{which}{exc}") from None
        if s.out is not None and not s.force:
            # an empty events.jsonl is a run that received nothing (a dead port): no loss
            used = [name for name in OUTPUTS if (Path(s.out) / name).exists()
                    and (Path(s.out) / name).stat().st_size > 0]
            if used:
                raise SkinError(f"--out {s.out}: holds an earlier run ({used[0]}); use --force "
                                "to overwrite it, or another folder")
        self._checked = True
        return self

    def _check_source(self) -> None:
        from skin.formats.layout import load_layout

        s = self.setup
        self.scene: Any = None
        self.duration = s.duration
        self.recorded_cal: Any = None
        if self.url is None:  # a simulation: the scene's layout unless one is given
            if s.firmware_sim:
                from skin.drivers.firmware_board import firmware_scene

                self.scene = firmware_scene(self._load_scene())
                self.layout = self.scene.layout
            else:
                self.scene = self._load_scene()
                self.layout = self.scene.layout if s.layout is None else load_layout(s.layout)
            from skin.drivers.sim import SkinSimulator

            # checks the scene's materials, naming its file and line
            self._sim = SkinSimulator(self.scene, duration=s.duration, contact=s.contact)
            self.duration = self._sim.duration
            return
        if s.firmware_sim:
            raise SkinError("--firmware-sim plays a scene to the emulated board: give no --port")
        if s.seed is not None:
            raise SkinError(f"--seed {s.seed} sets a simulated scene's seed: give no --port "
                            "(a sim:// port runs its own scene)")
        if self.duration is None and not self.replay:
            self.duration = 20.0
        recorded_layout = None
        if self.replay:  # the recording's layout and calibration, unless the user gives others
            from skin.drivers.replay import recorded_setup, replay_path

            path = replay_path(self.url)
            if not path.is_file():
                raise SkinError(f"--port {self.url}: no recording {str(path)!r}")
            recorded_layout, self.recorded_cal = recorded_setup(path)
            if self.duration is None:
                self.duration = math.inf  # to the end of the recording
        if s.layout or recorded_layout is None:
            self.layout = load_layout(s.layout or "arm")
            self.recorded_cal = None  # it belongs to the recording's layout
        else:
            self.layout = recorded_layout
            self.progress.message(f"replaying {self.url}: its layout ({len(self.layout)} "
                                  "taxels)" + ("" if self.recorded_cal is None or s.calibration
                                              else " and calibration"))

    def _load_scene(self) -> Any:
        """Load the setup's scene, with the setup's seed when it gives one."""
        from skin.formats.scene import load_scene

        scene = load_scene(self.setup.scene)
        return scene if self.setup.seed is None else replace(scene, seed=self.setup.seed)

    def _check_calibration(self) -> None:
        s = self.setup
        self.calibration: Any = None
        self.sensors: Any = None
        self.cal_file: Any = None
        if not s.calibration and self.recorded_cal is not None:
            from skin.stream.calibration import Calibration

            if isinstance(self.recorded_cal, Calibration):
                self.calibration = self.recorded_cal
            else:
                self.cal_file = self.recorded_cal
                self.calibration, self.sensors = self.cal_file.apply(self.layout)
        if s.calibration:
            from skin.formats.calibration_file import load_calibration

            self.cal_file = load_calibration(s.calibration)
            self.calibration, self.sensors = self.cal_file.apply(self.layout)
            for part in ("thermistor", "thermal"):
                miss = self.cal_file.missing(self.layout, part)
                if miss:
                    self.progress.message(
                        f"calibration: {len(miss)} taxels without a {part} fit keep their "
                        f"board's constants: {miss[:10]}{' ...' if len(miss) > 10 else ''}")

    def expected_materials(self) -> list[str]:
        """Materials the classifier must know: ``expect`` and a scene's objects."""
        want = list(self.setup.expect)
        if self.scene is not None:
            want += [self.scene.material_of(t) for t in self.scene.touches]
        return sorted(set(want))

    def _check_classifier(self) -> None:
        from skin.models import HistogramClassifier, JointClassifier, load_materials

        s = self.setup
        self.materials = load_materials()
        want = self.expected_materials()
        if s.model:
            from skin.models.learned import LearnedClassifier
            from skin.models.nuisance import other_sensors, scene_object_range

            object_range = s.object_temperature_range
            if s.where("object_temperature_range") == "default" and self.scene is not None:
                object_range = scene_object_range(self.scene, self.materials)
                if object_range > 0:
                    self.progress.message(f"object temperature range +-{object_range:g} K "
                                          f"(the scene's objects)")
            self.classifier: Any = LearnedClassifier(
                s.model, threshold=s.threshold, object_range=object_range,
                sensors=self._thermal_constants())
            self._check_time_scale()
            known = set(self.classifier.classes)
            for warning in (self.classifier.coverage_warning, other_sensors(
                    self.classifier.doc.get("training", {}).get("sensor"),
                    [b.sensor for b in self.layout.boards.values()])):
                if warning:
                    self.progress.message(f"warning: {s.model}: {warning}")
            self.progress.message(
                f"classifier: {self.classifier.method} ({len(self.classifier.classes)} classes, "
                f"{self.classifier.samples / self.classifier.fs:g} s window)")
        else:
            known = set(self.materials)
            if s.classifier == "joint":
                self.classifier = JointClassifier(
                    self.layout, self.materials, threshold=s.threshold,
                    sensors=None if self.sensors is None else
                    {int(t.id): v for t, v in zip(self.layout.taxels, self.sensors, strict=True)})
            else:
                self.classifier = HistogramClassifier(self.layout, self.materials)
        missing = [m for m in want if m not in known]
        if missing:
            what = f"model {s.model}" if s.model else "the materials table"
            raise SkinError(f"{what} has no class {missing[0]!r}, which the "
                            + ("setup's 'expect'" if missing[0] in s.expect else "scene")
                            + f" needs (it knows {', '.join(sorted(known))})")

    def _thermal_constants(self) -> dict | None:
        """Taxel id -> the calibration's thermal constants (None: it gives none, or no file)."""
        from skin.formats.calibration_file import THERMAL
        from skin.models.timescale import taxel_constants

        if self.cal_file is None or not any(k in e for e in self.cal_file.taxels.values()
                                            for k in THERMAL):
            return None
        return taxel_constants(self.cal_file, self.setup.calibration or "recorded calibration")

    def _check_time_scale(self) -> None:
        """Warn where a model trained on warped traces cannot warp a taxel, or its window."""
        from skin.models.timescale import time_ratio

        clf, s = self.classifier, self.setup
        if clf.sensors is None:
            return
        bare = [int(i) for i in self.layout.ids if int(i) not in clf.sensors]
        if bare:
            self.progress.message(f"warning: {s.model}: {len(bare)} taxels have no thermal "
                                  f"constants in the calibration, read as recorded: "
                                  f"{bare[:10]}{' ...' if len(bare) > 10 else ''}")
        ratios = [time_ratio(clf.sensors[int(i)]) for i in self.layout.ids
                  if int(i) in clf.sensors]  # this skin's taxels only
        need = max(clf.lengths) / clf.fs * max(ratios, default=1.0)
        if need > s.window + 1e-9:
            self.progress.message(f"warning: {s.model}: its slowest taxel needs {need:.2f} s "
                                  f"of contact for the model's window; --window {s.window:g} "
                                  f"cuts it shorter (such taxels answer from a shorter window "
                                  f"or not at all)")

    def _check_arm(self) -> None:
        """Load the arm once and check it covers the layout, if a view or the map needs it."""
        s = self.setup
        self.arm: Any = s.arm
        if s.arm is not None and not Path(s.arm).is_file() and s.arm != "xarm7":
            raise SkinError(f"--arm {s.arm}: no such arm file (or the shipped 'xarm7')")
        if not (s.view or s.video or (s.map and s.out is not None)):
            return
        from skin.viz.arm_mesh import ArmSurface, resolve_arm

        self.arm = resolve_arm(s.arm)
        ArmSurface(self.layout, self.arm)  # every link has a mesh, every taxel sits on it

    # --- running -----------------------------------------------------------------------------
    def open(self) -> Skin:
        """Check, make the output folder and sinks, start a simulation, open the sources."""
        if self._opened:
            return self
        self.check()
        s = self.setup
        self._opened = True
        if s.out is not None:
            out = Path(s.out)
            out.mkdir(parents=True, exist_ok=True)
            from skin.world.map import CHAIN_FILE, LAYOUT_FILE

            for name in (*OUTPUTS, LAYOUT_FILE, CHAIN_FILE):  # none of an earlier run stays
                (out / name).unlink(missing_ok=True)
        self._make_source()
        shards = self._board_shards()
        if shards is not None:  # each worker opens its own ports, before the sinks
            from skin.stream.board_workers import BoardWorkers

            self._workers = BoardWorkers(self.pipeline, shards, block=10)
            self._closers.append(self._workers)
            log.info("reading %s (%d taxels) in %d board workers", self._source_name(),
                     len(self.layout), len(shards))
            self._make_sinks()
            return self
        from skin import drivers

        self._driver = drivers.open(self.source_url)  # before the sinks: a bad port makes none
        self._closers.append(self._driver)
        log.info("reading %s (%d taxels)", self._source_name(), len(self.layout))
        self._make_sinks()
        if s.workers > 1:  # started before the first frame, stopped with the sources
            self._closers.append(self.pipeline.start())
            shards = self.pipeline.onset_workers.shards
            if len(shards) < s.workers:
                # shards never split a board while its common mode runs, nor leave one empty
                why = ("each board in one process (the board common mode)"
                       if self.pipeline.detector.common_active else "fewer taxels than asked")
                log.info("onset detection in %d of the %d processes asked: %s", len(shards),
                         s.workers, why)
            else:
                log.info("onset detection in %d worker processes", len(shards))
        log.info("sinks: %s", ", ".join(type(k).__name__ for k in self.pipeline.sinks))
        if s.view or s.video:
            self._live = self._live_view()
        # a device given by the user reconnects; the simulated ones end by going away
        for one, port_url in zip(getattr(self._driver, "drivers", [self._driver]), s.port,
                                 strict=False):
            if port_url.startswith(("serial", "can:")) and "reconnect=" not in port_url:
                one.reconnect = s.reconnect
        if self._recorder is not None:
            self._recorder.add_driver(self._driver)
        if s.firmware_sim:
            from skin.drivers.protocol import ALL_TAXELS, Command, MsgType

            # the scene was simulated with every heater on; the firmware boots with them off
            self._driver.request(Command(MsgType.SET_DUTY, taxel=ALL_TAXELS, duty=255),
                                 timeout=5.0)
        elif self._device is not None:
            self._device.start()  # after the port is open: opening it empties its buffer
        return self

    def _board_shards(self) -> list | None:
        """Shard serial ports (one board each, ``?board=``) across ``workers`` processes.

        Used when ``workers`` > 1, every port is a serial port and there are at least as many
        as workers, and nothing records the wire bytes (``record``: they are read in the
        workers); otherwise (a simulation, a replay, CAN buses, a recording) onset detection
        alone runs in workers (`skin.stream.shards`). Returns None then.
        """
        s = self.setup
        urls = [self.source_url] if isinstance(self.source_url, str) else self.source_url
        if (s.workers < 2 or s.record or s.firmware_sim or self.scene is not None or not urls
                or len(urls) < s.workers or not all(u.startswith("serial") for u in urls)):
            return None
        from urllib.parse import parse_qs

        from skin.stream.board_workers import UrlSource, shard_boards

        by_board: dict[int, str] = {}
        for url in urls:
            query = parse_qs(url.partition("?")[2])
            board = int(query.get("board", ["0"])[0])
            if board in by_board:
                raise SkinError(f"--port {url}: board {board} is also {by_board[board]}; give "
                                "each serial port its board id (?board=N)")
            if "reconnect" not in query:
                url += f"{'&' if '?' in url else '?'}reconnect={s.reconnect:g}"
            by_board[board] = url
        if sorted(by_board) != sorted(self.layout.boards):
            raise SkinError(f"--port: the ports give boards {sorted(by_board)}, the layout "
                            f"{self.layout.source} has {sorted(self.layout.boards)}")
        return [(boards, UrlSource(tuple(by_board[b] for b in boards)))
                for boards in shard_boards(self.layout, s.workers)]

    def _make_source(self) -> None:
        s = self.setup
        self.source_url = self.url
        if self.scene is None:
            return
        sim = self._sim
        from skin.drivers.protocol import MAX_COUNT

        for board in self.layout.boards.values():
            if board.adc_max > MAX_COUNT:
                raise SkinError(
                    f"scene {self.scene.source}: board {board.id}'s ADC has {board.adc_bits} bits "
                    f"(sensor {board.sensor or 'of the layout'}); the serial protocol v1 the "
                    f"simulated board is served over carries {MAX_COUNT.bit_length()}: read "
                    f"it in-process instead, with --port sim://{self.scene.source}")
        if s.firmware_sim:
            from skin.drivers.firmware_board import emulated_board

            self._device = emulated_board(sim, folder=s.out,
                                          realtime=s.speed if s.speed > 0 else None)
            self.source_url = f"serial://{self._device.start()}"
            self.progress.message(
                f"scene '{self.scene.name}' ({len(self.layout)} taxels, "
                f"{len(self.scene.touches)} touches) played to the firmware in simavr on "
                f"{self._device.port}")
        else:
            from skin.drivers.sim import PtySerialDevice

            self._device = PtySerialDevice(sim, speed=s.speed)
            self.source_url = f"serial://{self._device.port}"
            self.progress.message(
                f"simulated skin '{self.scene.name}' ({len(self.layout)} taxels, "
                f"{len(self.scene.touches)} touches) served on {self._device.port}")

    def _make_sinks(self) -> None:
        """Each named sink, the recorder, in that order, onto the pipeline."""
        from skin.stream.sinks import JsonLinesSink, TerminalSink

        s = self.setup
        for name in s.sinks:
            if name == "terminal":
                self.pipeline.sinks.append(TerminalSink(self.progress))
                continue
            if name == "events":
                if s.out is None:
                    continue
                path = Path(s.out) / "events.jsonl"
                self._events_path = path
            else:
                path = Path(name)
                path.parent.mkdir(parents=True, exist_ok=True)
            sink = JsonLinesSink(path)  # a killed run keeps every contact already given
            self._closers.append(sink)
            self.pipeline.sinks.append(sink)
        if s.record:
            from skin.drivers.recording import Recorder

            self._recorder = Recorder(
                s.record, self.layout, calibration=s.calibration or self.cal_file
                or self.calibration, metadata={"command": " ".join(["skin", *sys.argv[1:]])})
            self._closers.append(self._recorder)
            self.pipeline.sinks.append(self._recorder)
            self.pipeline.observers.append(self._recorder.temperature)
        if s.publish:
            from skin.stream.publish import open_publisher

            chain = self._urdf_chain()
            pose = None
            if s.robot_pose:
                from skin.world.kinematics import transform

                pose = transform(s.robot_pose[:3], s.robot_pose[3:])
            for url in s.publish:
                pub = open_publisher(url, self.layout, robot=s.robot, chain=chain,
                                     robot_pose=pose).attach(self.pipeline)
                self._closers.append(pub)
                self.publishers.append(pub)

    def _urdf_chain(self) -> Any:
        """Return the chain of a URDF arm (``arm`` a ``.urdf`` file or ``xarm7``), else None."""
        arm = self.setup.arm
        if arm is None or not (arm == "xarm7" or arm.lower().endswith(".urdf")):
            return None
        from skin.world.urdf import example_urdf, load_urdf

        return load_urdf(example_urdf() if arm == "xarm7" else arm).chain

    def _live_view(self) -> Any:
        """Open the window (``view``) and/or the movie (``video``) of the run."""
        from skin.viz import ArmView
        from skin.viz.arm_live import LiveArm

        s = self.setup
        view = ArmView(self.layout, {m.name: m.colour for m in self.materials.values()},
                       arm=self.arm, off_screen=not s.view,
                       window_size=(1200, 560) if s.view else (960, 440))
        view.mode = s.view_mode
        try:
            return LiveArm(view, window=s.view, movie=s.video)
        except BaseException:
            view.close()
            raise

    def results(self) -> Iterator[ContactResult]:
        """Read the sources to the end, yielding every result (provisional ones too) as it comes.

        Raises
        ------
        SkinError
            If no frame arrives within ``first_frame_timeout`` seconds, or none at all.
        """
        self.open()
        if self._workers is not None:
            yield from self._worker_results()
            return
        s, driver, device, pipeline = self.setup, self._driver, self._device, self.pipeline
        duration = self.duration
        self._t_wall = time.monotonic()
        first_time: float | None = None
        chunk: list = []
        received = 0
        idle_since = time.monotonic()
        while True:
            try:
                frame = driver.recv(timeout=0.2)
            except DeviceError:
                if not s.firmware_sim or device.running:
                    raise
                frame = None  # the emulated board played its whole scene and stopped
                self._now = duration
            if frame is not None:
                if first_time is None:
                    first_time = frame.device_time
                chunk.append(frame)
                received += 1
                self._now = frame.device_time - first_time
                idle_since = time.monotonic()
            elif received == 0 and device is None and (
                    time.monotonic() - self._t_wall > s.first_frame_timeout):
                raise SkinError(f"no frame arrived from {self._source_name()} in "
                                f"{s.first_frame_timeout:g} s: is the device powered and "
                                "sending, the port and its settings right?")
            idle = frame is None
            # a simulated board is done once all it sent is in (or after 2 s of silence)
            end_of_sim = device is not None and not s.firmware_sim and (
                device.done.is_set() and (received >= device.frames_sent
                                          or time.monotonic() - idle_since > 2.0))
            finished = self._now >= duration - 1e-9 or end_of_sim or (
                idle and driver.finished) or (
                device is None and idle and time.monotonic() - self._t_wall > duration + 5)
            if chunk and (len(chunk) >= 20 or idle or finished):
                new = pipeline.process(chunk)
                chunk = []
                yield from self._given(new)
                self.progress.status(
                    f"[{self._now:6.1f}{'' if math.isinf(duration) else f'/{duration:.1f}'} "
                    f"s] frames {pipeline.stats.frames}  "
                    f"in contact {int(pipeline.in_contact().sum()):2d}  "
                    f"contacts {pipeline.stats.contacts}  "
                    f"crc errors {driver.stats.crc_errors}", self._now)
            if finished:
                break
        if received == 0:
            raise SkinError(f"no frame arrived from {self._source_name()} during the run")
        yield from self._given(pipeline.flush())
        self._link, self._health = driver.stats, driver.health

    def _worker_results(self) -> Iterator[ContactResult]:
        """`results` when the boards are read in worker processes (`_board_shards`)."""
        from skin.drivers.protocol import LinkStats

        s, workers, duration = self.setup, self._workers, self.duration
        self._t_wall = time.monotonic()
        first_time: float | None = None
        while not workers.done:
            blocks = workers.blocks(0.2)
            if blocks:
                first_time = blocks[0].times[0] if first_time is None else first_time
                self._now = float(blocks[-1].times[-1] - first_time)
            yield from self._given(workers.feed(blocks))
            self.progress.status(
                f"[{self._now:6.1f}/{duration:.1f} s] frames {workers.frames}  in contact "
                f"{int(workers.in_contact.sum()):2d}  contacts {self.pipeline.stats.contacts}  "
                f"crc errors {workers.crc_errors}", self._now)
            if workers.frames == 0 and time.monotonic() - self._t_wall > s.first_frame_timeout:
                raise SkinError(f"no frame arrived from {self._source_name()} in "
                                f"{s.first_frame_timeout:g} s: is the device powered and "
                                "sending, the port and its settings right?")
            if self._now >= duration - 1e-9:
                break
        yield from self._given(workers.finish())
        self._link = LinkStats(crc_errors=workers.crc_errors)

    def _source_name(self) -> str:
        return self.source_url if isinstance(self.source_url, str) else ", ".join(self.source_url)

    def _given(self, new: list[ContactResult]) -> Iterator[ContactResult]:
        from skin.stream.sinks import event_record

        if self._keep_finals is None:  # a scene's matching or the contact map needs them all
            s = self.setup
            self._keep_finals = self.scene is not None or (s.map and s.out is not None)
            if self.scene is not None:
                self._records = []
        self.results_given.extend(new)
        for r in new:
            self._records.append(event_record(r))
            if r.contact.final:
                self._final_count += 1
                if self._keep_finals:
                    self._finals.append(replace(r, contact=replace(r.contact, windows=[])))
        if self._live is not None:
            self._live.step(self._now, new, self.pipeline.in_contact()
                            if self._workers is None else self._workers.in_contact,
                            self.pipeline.last_temperature)
        yield from new

    def run(self) -> dict[str, Any]:
        """Run to the end (Ctrl-C stops early, keeping what was received), then `finish`."""
        try:
            for _ in self.results():
                pass
        except KeyboardInterrupt:
            self.progress.message("interrupted: writing what was received")
        finally:
            self.close_sources()
        return self.finish()

    def close_sources(self) -> None:
        """Close the sources, the sinks, the live view and a simulation (idempotent)."""
        for thing in self._closers:  # the sources first, then the sinks
            thing.close()
        self._closers = []
        if self._live is not None:
            self._live.close()
            if self._live.movie is not None:
                self.progress.message(f"video: {self._live.movie} ({self._live.frames} frames)")
            self._live = None
        self.progress.done()
        if self._device is not None:
            self._device.close()
            self._device = None

    def finish(self) -> dict[str, Any]:
        """Summarise the run; with an output folder, write its files. Returns the summary."""
        from skin.formats.scene import match_touches

        s, pipeline, layout = self.setup, self.pipeline, self.layout
        duration = self.duration
        if math.isinf(duration):  # a replay to its end: the time it held
            duration = pipeline.stats.samples / next(iter(layout.boards.values())).sample_rate
        wall = time.monotonic() - self._t_wall
        results = list(self._finals)  # every final contact when needed, else none
        records = list(self._records)
        link, health = self._link, self._health
        summary: dict[str, Any] = {
            "source": "simulation" if self.scene is not None else self.url,
            "scene": None if self.scene is None else self.scene.source,
            "duration": duration,
            "wall_time": round(wall, 3),
            "frames": pipeline.stats.frames,
            "gaps": pipeline.stats.gaps,
            "late": pipeline.stats.late,
            "crc_errors": None if link is None else link.crc_errors,
            "malformed": None if link is None else link.malformed,
            "faults": None if health is None else health.faults,
            "reconnects": None if health is None else health.reconnects,
            "flagged_taxels": [int(layout.ids[k])
                               for k in np.flatnonzero(pipeline.stats.flagged)],
            "contacts": self._final_count,
        }
        force = getattr(pipeline, "force", None)
        if force is not None:  # the frames carried a force channel (skin.stream.force)
            summary["force"] = {
                "dated_taxels": [int(layout.ids[k]) for k in np.flatnonzero(force.trusted)],
                "unseen_onsets": {str(layout.ids[k]): int(force.unseen[k])
                                  for k in np.flatnonzero(force.unseen)},
                "notes": list(force.notes),
                # force-dated contacts whose temperature showed no contact: "unknown"
                "no_thermal_response": list(pipeline.no_response)}
        if self.publishers:
            summary["published"] = {p.url: dict(p.sent) for p in self.publishers}
        if self.scene is not None:
            scene = self.scene
            in_time = [t for t in scene.touches if t.start < duration]
            trimmed = scene if len(in_time) == len(scene.touches) else replace(
                scene, touches=tuple(in_time))
            matches, unmatched = match_touches(trimmed, [r.contact.taxels for r in results],
                                               [r.contact.onset for r in results])
            detected = [m for m in matches if m.contact_index is not None]
            correct = [m for m in detected
                       if results[m.contact_index].estimate.label == m.material]
            family_correct = [m for m in detected if results[m.contact_index].estimate.family
                              == self.materials[m.material].family]
            # the measured effusivity (skin.models.contact_fit) against the scene's material
            errors = [abs(np.log10(results[m.contact_index].estimate.effusivity
                                   / self.materials[m.material].effusivity))
                      for m in detected if results[m.contact_index].estimate.effusivity]
            truth: dict[int, str | None] = {results[i].contact.id: None for i in unmatched}
            truth.update({results[m.contact_index].contact.id: m.material for m in detected})
            for rec in records:
                if rec["contact"] in truth:
                    rec["truth"] = truth[rec["contact"]]
                    rec["truth_family"] = (None if rec["truth"] is None
                                           else self.materials[rec["truth"]].family)
            if self._events_path is not None:
                # the truth is known once all contacts are matched: rewrite the file with it
                with self._events_path.open("w", encoding="utf-8") as file:
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
                    [abs(results[m.contact_index].contact.onset - m.touch.start)
                     for m in detected])), 4) if detected else None,
                "median_log10_effusivity_error":
                    round(float(np.median(errors)), 4) if errors else None,
                "per_touch": [
                    {"start": m.touch.start, "taxels": list(m.touch.taxels), "truth": m.material,
                     "label": None if m.contact_index is None
                     else results[m.contact_index].estimate.label,
                     "family": None if m.contact_index is None
                     else results[m.contact_index].estimate.family}
                    for m in matches
                ],
            })
        self.records = records
        self.summary = summary
        if s.out is not None:
            self._write_outputs(Path(s.out), summary, results, duration)
        return summary

    def _write_outputs(self, out: Path, summary: dict[str, Any], results: list[ContactResult],
                       duration: float) -> None:
        from skin.world.kinematics import default_chain
        from skin.world.map import write_run_setup

        out.mkdir(parents=True, exist_ok=True)
        # what `skin view --map` needs: the layout, and for a simulation the arm's pose
        # (standing at the default chain's default angles); a device's poses are unknown here
        chain = None
        if self.scene is not None:  # a simulation: the arm stands at its default angles
            chain = self._urdf_chain() or default_chain()
            if not set(self.layout.links) <= set(chain.links):
                chain = None  # not this layout's arm
        summary.update(write_run_setup(out, self.layout, chain))
        (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n",
                                          encoding="utf-8")
        log.info("outputs in %s", out)
        if self.setup.map:
            from skin.viz import ArmView

            # every contact of the run, at its confidence, none faded
            view = ArmView(self.layout, {m.name: m.colour for m in self.materials.values()},
                           arm=self.arm, memory=None)
            view.update(duration, results=results)
            view.screenshot(out / "contact_map.png",
                            title=f"contact map: {len(results)} contacts in {duration:g} s")
            view.close()

    def close(self) -> None:
        """Close everything (idempotent)."""
        if not self._closed:
            self._closed = True
            self.close_sources()

    def __enter__(self) -> Skin:
        return self.check()

    def __exit__(self, *exc: object) -> None:
        self.close()

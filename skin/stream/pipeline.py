"""The streaming pipeline: frames -> samples -> deg C -> onsets -> contacts -> materials -> sinks.

The chain is declared once, in `Pipeline`, as stages that each know only the one before it:

==============  ======================================  =========================================
stage           object                                  takes -> gives
==============  ======================================  =========================================
assemble        `skin.stream.assembly.FrameAssembler`          frames of every board -> `Samples`
calibrate       `skin.stream.calibration.Calibration`          counts -> deg C and per-taxel status
onset           `skin.stream.onset.OnsetDetector`              deg C -> onset and release events
track           `skin.stream.tracking.ContactTracker`          deg C and events -> `DecidedContact`
refine          `skin.stream.tracking.refine_member`           samples -> dated onset and release
classify        the classifier (`Classifier`)           `Contact` -> `MaterialEstimate`
sinks           `skin.stream.sinks` (JSON lines, terminal...)  `ContactResult` -> wherever it goes
==============  ======================================  =========================================

The first four stages run on every block of frames. Refining and classifying are the costly
steps and happen only when a contact is decided, often for many contacts at once; they wait in
a queue and, with a ``budget``, each call does only as much of that work as the budget leaves
(one taxel's refinement or one contact's classification at a time: at least one per call, and
another only if its usual cost fits in what is left), so a burst of contacts is spread over
the frames that follow instead of stalling one of them.
A contact that has waited ``max_wait`` seconds (device time) is finished whatever the budget:
under a load the budget cannot carry, results come late by at most that much, and the calls
that catch up take longer. Without a budget every decided contact is finished in the call
that decided it.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, TypeVar

import numpy as np

from skin.contact import UNKNOWN, Contact, MaterialEstimate
from skin.errors import SkinError
from skin.formats.layout import Layout
from skin.frame import Frame
from skin.stream.assembly import FrameAssembler, Samples
from skin.stream.calibration import Calibration
from skin.stream.onset import OnsetDetector, common_auto
from skin.stream.onset_refine import refine_span
from skin.stream.tracking import (
    ContactTracker,
    DecidedContact,
    finish_contact,
    join_window_for,
    refine_member,
)

if TYPE_CHECKING:
    from skin.stream.board_workers import CalibratedBlock
    from skin.stream.force import ForceOnsets
    from skin.stream.shards import OnsetShards

T = TypeVar("T")

STAGES = ("assemble", "calibrate", "onset", "track", "refine", "classify", "sinks")


class Classifier(Protocol):
    """Anything that turns a `Contact` into a `MaterialEstimate`."""

    def classify(self, contact: Contact) -> MaterialEstimate:  # noqa: D102
        ...


@dataclass(frozen=True)
class ContactResult:
    """A decided contact and what the classifier made of it.

    Attributes
    ----------
    contact : Contact
        The contact (``contact.decided_at``: when the tracker decided it).
    estimate : MaterialEstimate
        The classifier's answer.
    reported_at : float
        Device time of the newest sample when the result was given, s: later than
        ``contact.decided_at`` when the work was spread over frames.
    host : HostTimes or None
        The same instants in host time (None when the source gave no host times).
    """

    contact: Contact
    estimate: MaterialEstimate
    reported_at: float
    host: HostTimes | None = None


@dataclass(frozen=True)
class HostTimes:
    """A contact's instants in host time: ``time.monotonic`` seconds, as ``Frame.host_time``.

    Device times are mapped through the host times the samples carried (each board's clock
    map, `skin.drivers.clock`), so contacts line up with anything else the host stamps (a
    robot's joint states, camera frames); ``skin.drivers.clock.wall_time`` turns them into
    Unix time.

    Attributes
    ----------
    onset, decided_at, reported_at : float
        Host time of ``contact.onset``, ``contact.decided_at`` and ``reported_at``, s.
    release : float or None
        Host time of ``contact.release``, s.
    """

    onset: float
    release: float | None
    decided_at: float
    reported_at: float


class HostTimeline:
    """Device time -> host time, from the (device, host) pairs of the last samples seen.

    The host - device offset of the samples is interpolated (held constant beyond the ends),
    so a contact's instants, at most a window old, map through the same clock maps that
    stamped its frames. A device clock running backwards (a board reset) starts it afresh.

    Parameters
    ----------
    capacity : int
        Samples kept.
    """

    def __init__(self, capacity: int = 8192) -> None:
        self._device = np.full(capacity, np.nan)
        self._offset = np.full(capacity, np.nan)
        self._head = 0  # samples written

    def append(self, device: np.ndarray, host: np.ndarray) -> None:
        """Take a block of samples' device and host times, s."""
        cap = len(self._device)
        if self._head and len(device) and device[0] < self._device[(self._head - 1) % cap]:
            self._device[:] = np.nan
            self._offset[:] = np.nan
            self._head = 0
        device, offset = device[-cap:], (host - device)[-cap:]
        idx = (self._head + np.arange(len(device))) % cap
        self._device[idx] = device
        self._offset[idx] = offset
        self._head += len(device)

    def to_host(self, device_time: float) -> float:
        """Return the host time of ``device_time``, s (NaN before any sample with a host time)."""
        cap = len(self._device)
        n = min(self._head, cap)
        order = (self._head - n + np.arange(n)) % cap
        d, off = self._device[order], self._offset[order]
        ok = np.isfinite(off)
        if not ok.any():
            return float("nan")
        return float(device_time + np.interp(device_time, d[ok], off[ok]))


class Sink(Protocol):
    """Anything that takes results as they come (`skin.stream.sinks`)."""

    def write(self, result: ContactResult) -> None:  # noqa: D102
        ...


@dataclass
class PipelineStats:
    """Running counts kept by the pipeline.

    Attributes
    ----------
    frames : int
        Frames taken.
    samples : int
        Skin-wide samples processed.
    gaps : int
        Frames missing according to sequence numbers, over all boards.
    late : int
        Frames that came after their sample had left without them, over all boards (dropped,
        their taxels NaN in that sample; `skin.stream.assembly.FrameAssembler`).
    flagged : numpy.ndarray
        Per taxel: samples without a temperature (open, saturated or missing).
    onsets, releases : int
        Events seen.
    contacts : int
        Contacts decided (final decisions).
    results : int
        Results handed to the sinks (provisional ones too).
    seconds : dict
        Stage name -> wall time spent in it, s (`STAGES`).
    cpu_seconds : dict
        Stage name -> CPU time of this process spent in it, s (`time.process_time`: on a
        loaded machine the wall time also counts what others ran meanwhile; onset workers'
        CPU is not in it).
    """

    frames: int = 0
    samples: int = 0
    gaps: int = 0
    late: int = 0
    flagged: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    onsets: int = 0
    releases: int = 0
    contacts: int = 0
    results: int = 0
    seconds: dict[str, float] = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))
    cpu_seconds: dict[str, float] = field(
        default_factory=lambda: dict.fromkeys(STAGES, 0.0))


@dataclass
class _Deciding:
    """A decided contact on its way through refine and classify."""

    decided: DecidedContact
    refined: list[tuple[float, float]] = field(default_factory=list)


class Pipeline:
    """Run the whole chain on a stream of frames (see the module docstring).

    Parameters
    ----------
    layout : Layout
        The skin's taxels, on one or more boards sampled in step.
    classifier : Classifier
        Labels each decided contact.
    calibration : Calibration, optional
        Counts to deg C; the layout's nominal board constants by default.
    detector : OnsetDetector, optional
        Onset detector; by default one set by the boards' sensor descriptions and ``noise``.
    window : float
        Longest contact window handed to the classifier, s.
    sensors : list of SensorConstants, optional
        Per-taxel thermal constants in layout order (a calibration file's), used to date
        onsets; the boards' by default.
    ambient_offset : float
        Added to the ambient sensor's reading, K (a calibration file's).
    noise : numpy.ndarray, optional
        Each taxel's commissioned noise per sample, K, in layout order
        (`skin.formats.calibration_file.noise_sigma`); the boards' sensors' by default.
    sinks : iterable of Sink
        Each result is written to every sink, in order, as it is given.
    budget : float, optional
        Seconds per `process` call for refining and classifying decided contacts (see the
        module docstring); None finishes every contact in the call that decided it.
    max_wait : float
        Device seconds after its decision by which a contact is finished whatever the budget.
    max_skew, skew_wait : int, float
        Most samples held behind an incomplete one, and host seconds an incomplete sample
        waits for its missing boards, before it leaves without them
        (`skin.stream.assembly.FrameAssembler`'s ``max_skew`` and ``wait``).
    provisional : sequence of float
        Seconds after a contact's first onset at which it is also classified while still
        open (results with ``contact.final`` False; `skin.stream.tracking.ContactTracker`).
    workers : int
        Processes for onset detection: 1 runs it here; more shard the taxels across that
        many processes, this one included (`skin.stream.shards`); the others are started by
        `start` (or at the first block) and stopped by `close`. The results are the same.
        With the board common mode on, a board is never split, so there are at most as many
        processes as boards (`skin.stream.shards.shard_taxels`' ``whole_boards``).
    common_mode : bool, optional
        The default detector's board common mode (`OnsetDetector`'s ``common_mode``: the
        room's change, shared alike by nearly every free taxel of a board of
        `skin.stream.onset.COMMON_MIN` taxels or more, taken off first; None, the default:
        on where the heater is not PID-held, `skin.stream.onset.common_auto`). Ignored when
        ``detector`` is given: that detector's own setting holds.
    force_onsets : bool
        Date the contacts of the taxels whose frames carry a force reading by it
        (`skin.stream.force.ForceOnsets`: exact onsets and releases, the classifier's window
        starting at the force's onset), the onset detector dating the others and those
        stretches where the force has no reading. False: the onset detector dates every
        taxel. A stream without a force channel costs nothing either way. Blocks assembled
        in board worker processes (`process_calibrated`) carry their force: merged here alike.
    response_check : bool
        Test each contact the force alone dated for a thermal response before classifying it
        (`skin.stream.response`: a likelihood-ratio test of its samples, contact against the
        free sensor's trajectory, at the detector's noise); one that shows none is answered
        "unknown" with the note "no thermal response ..." (`MaterialEstimate.note`), never a
        material or family. False: every contact is classified (as before).

    Attributes
    ----------
    timeline : HostTimeline
        Maps device time to host time by the samples seen (`ContactResult.host`).
    observers : list of callable
        Each is called as ``observer(times, temperature, host_times)`` with every block of
        calibrated samples (device times (n,), deg C (n, taxels) in layout order, NaN where
        flagged, host times (n,)), before onset detection; a recording keeps them
        (`skin.drivers.recording.Recorder`). Their time counts as the ``sinks`` stage's.
        Observers must not modify the arrays.
    """

    def __init__(
        self,
        layout: Layout,
        classifier: Classifier,
        *,
        calibration: Calibration | None = None,
        detector: OnsetDetector | None = None,
        window: float = 2.5,
        sensors: list | None = None,
        ambient_offset: float = 0.0,
        sinks: Iterable[Sink] = (),
        budget: float | None = None,
        max_wait: float = 0.5,
        max_skew: int = 2000,
        skew_wait: float = 1.0,
        provisional: Sequence[float] = (),
        noise: np.ndarray | None = None,
        workers: int = 1,
        common_mode: bool | None = None,
        force_onsets: bool = True,
        response_check: bool = True,
    ) -> None:
        rates = {b.sample_rate for b in layout.boards.values()}
        if len(rates) != 1:
            raise SkinError(f"{layout.source}: the boards of one skin must share a sample rate "
                            f"(sampled in step); got {sorted(rates)} Hz")
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        if budget is not None and budget < 0:
            raise ValueError(f"budget must be None or >= 0 s, got {budget}")
        self.layout = layout
        self.classifier = classifier
        self.assembler = FrameAssembler(layout, max_skew=max_skew, wait=skew_wait)
        self.calibration = calibration or Calibration.from_layout(layout)
        self.detector = detector or _detector_for(layout, noise, common_mode=common_mode)
        # the refinement fits the detector's sensor's own response, over its span
        self.refine_sensor = getattr(self.detector, "sensor", None)
        self.tracker = ContactTracker(layout, rates.pop(), window=window,
                                      provisional=provisional,
                                      search=refine_span(self.refine_sensor)[0],
                                      join_window=join_window_for(self.refine_sensor))
        if sensors is not None:
            if len(sensors) != len(layout):
                raise SkinError(f"{len(sensors)} sensor constants for {len(layout)} taxels")
            self.depth = np.array([s.depth for s in sensors])
            self.diffusivity = np.array([s.diffusivity for s in sensors])
        else:
            self.depth = layout.board_array("sensor_depth")
            self.diffusivity = layout.board_array("sensor_diffusivity")
        self.ambient_offset = float(ambient_offset)
        self.sinks = list(sinks)
        self.observers: list[Callable[[np.ndarray, np.ndarray, np.ndarray], None]] = []
        self.timeline = HostTimeline()
        self.budget = budget
        self.max_wait = float(max_wait)
        self._state = self.detector.initial_state()
        self.workers = int(workers)
        self._shards: OnsetShards | None = None  # from `start` or the first block on
        self._queue: deque[_Deciding] = deque()
        self._typical = {"refine": 0.0, "classify": 0.0}  # running mean of a step's cost, s
        self._now = -np.inf
        self.stats = PipelineStats(flagged=np.zeros(len(layout), dtype=np.int64))
        self.last_temperature = np.full(len(layout), np.nan)
        self.force_onsets = bool(force_onsets)
        self.sample_rate = float(next(iter(layout.boards.values())).sample_rate)
        self.force: ForceOnsets | None = None  # made at the first block with a force channel
        self.response_check = bool(response_check)
        self._response_sensors: tuple | None = None  # (sensors, smoothing factors, effusivities)
        #: ids of the final contacts answered "unknown" for showing no thermal response
        self.no_response: list[int] = []

    @property
    def pending(self) -> int:
        """Decided contacts waiting to be refined and classified."""
        return len(self._queue)

    def process(self, frames: Sequence[Frame]) -> list[ContactResult]:
        """Process a block of frames; return the results given in this call, in order."""
        started = time.perf_counter()
        samples = self._timed("assemble", self.assembler.push, frames)
        self._advance(samples)
        return self._drain(started, self.budget)

    def flush(self) -> list[ContactResult]:
        """End of stream: process what waits, decide the open contacts, finish them all."""
        self._advance(self.assembler.flush())
        self._enqueue(self._timed("track", self.tracker.flush))
        return self._drain(time.perf_counter(), None)

    def in_contact(self) -> np.ndarray:
        """Boolean mask of the taxels in contact now (layout order)."""
        if self._shards is not None:
            return self._shards.in_contact.copy()
        return self._state.in_contact.copy()

    @property
    def onset_workers(self) -> OnsetShards | None:
        """The running `skin.stream.shards.OnsetShards`, or None (one process, or closed)."""
        return self._shards

    def start(self) -> Pipeline:
        """Start the onset workers now rather than at the first block (idempotent)."""
        if self.workers > 1 and self._shards is None:
            from skin.stream.shards import OnsetShards

            self._shards = OnsetShards(self.detector, self.layout, self.workers)
        return self

    def close(self) -> None:
        """Stop the onset workers, if any (idempotent)."""
        if self._shards is not None:
            self._shards.close()
            self._shards = None

    def _timed(self, stage: str, func: Callable[..., T], *args: object) -> T:
        t0, c0 = time.perf_counter(), time.process_time()
        out = func(*args)
        self._spent(stage, t0, c0)
        return out

    def _spent(self, stage: str, t0: float, c0: float) -> float:
        """Book the wall and CPU time since ``t0`` / ``c0`` to ``stage``; return the wall time."""
        wall = time.perf_counter() - t0
        self.stats.seconds[stage] += wall
        self.stats.cpu_seconds[stage] += time.process_time() - c0
        return wall

    def _advance(self, samples: Samples) -> None:
        """Calibrate, detect and track one block of samples; queue the contacts it decides."""
        self.stats.frames = self.assembler.stats.frames
        self.stats.gaps = sum(self.assembler.stats.gaps.values())
        self.stats.late = self.assembler.stats.late
        if len(samples) == 0:
            return
        temperature, status = self._timed("calibrate", self.calibration.temperature,
                                          samples.counts)
        self.stats.flagged += (status != 0).sum(axis=0)
        force = samples.force if self.force_onsets else None
        self._track(samples.times, temperature, samples.ambient, samples.host_times, None,
                    force, samples.duty)

    def process_calibrated(self, block: CalibratedBlock) -> list[ContactResult]:
        """Track a block assembled, calibrated and onset-detected elsewhere; return the results.

        The block comes from `skin.stream.board_workers` (boards read in worker processes).

        The block's frames, gaps, late frames and flagged samples are the caller's to count in
        `stats` (``stats.frames``, ``stats.gaps``, ``stats.late``, ``stats.flagged``).
        """
        started = time.perf_counter()
        if len(block.times):
            force = block.force if self.force_onsets else None
            self._track(block.times, block.temperature, block.ambient, block.host_times,
                        block.events, force)
        return self._drain(started, self.budget)

    def _track(self, times: np.ndarray, temperature: np.ndarray, ambient: np.ndarray,
               host_times: np.ndarray, events: list | None,
               force: np.ndarray | None = None, duty: np.ndarray | None = None) -> None:
        """Observe, detect (unless ``events`` are given) and track calibrated samples.

        ``duty`` is the frames' heater duty (`skin.stream.assembly.Samples.duty`), which the
        detector is told (`skin.stream.onset.OnsetDetector.process`).
        """
        self.stats.samples += len(times)
        self.last_temperature = temperature[-1]
        self._now = float(times[-1])
        self.timeline.append(times, host_times)
        if self.observers:
            t0, c0 = time.perf_counter(), time.process_time()
            for observe in self.observers:
                observe(times, temperature, host_times)
            self._spent("sinks", t0, c0)
        if events is None:
            events = self._timed("onset", self._onsets, times, temperature, duty)
        if force is not None:
            if self.force is None:
                from skin.stream.force import ForceOnsets

                self.force = ForceOnsets(len(self.layout), self.sample_rate,
                                         start=self.stats.samples - len(times),
                                         ids=self.layout.ids)
            events = self._timed("onset", self.force.merge, times, force, temperature, events)
        self.stats.onsets += sum(e.kind == "onset" for e in events)
        self.stats.releases += sum(e.kind == "release" for e in events)
        decided = self._timed("track", self.tracker.update, times, temperature,
                              ambient + self.ambient_offset, events)
        self._enqueue(decided)

    def _onsets(self, times: np.ndarray, temperature: np.ndarray,
                duty: np.ndarray | None = None) -> list:
        if self.workers == 1:
            events, self._state = self.detector.process(times, temperature, self._state,
                                                         in_place=True, duty=duty)
            return events
        return self.start()._shards.process(times, temperature, duty)

    def _enqueue(self, decided: list[DecidedContact]) -> None:
        self._queue.extend(_Deciding(d) for d in decided)
        self.stats.contacts += sum(d.final for d in decided)

    def _classify(self, head: _Deciding, contact: Contact) -> MaterialEstimate:
        """Classify a contact, or answer "unknown" where the force dated it and no heat flowed.

        The force-dated taxels of a contact are first tested for a thermal response
        (`skin.stream.response.check_contact`; ``response_check``). A contact every taxel of
        which the force dated and which shows none (a force glitch on a taxel nothing
        touched) is "unknown", material and family, with a note saying so, and is not
        classified (nor taught to the classifier's priors). A force-dated taxel of a contact
        that does show one, but none of its own (a glitch beside a real touch), is left out
        of the classification, noted.
        """
        members = head.decided.members
        forced = [i for i, m in enumerate(members) if m.dated_by == "force"]
        sigma = getattr(self.detector, "sigma", None)
        if not (self.response_check and forced and sigma is not None):
            return self.classifier.classify(contact)
        from skin.stream.response import check_contact

        if self._response_sensors is None:
            self._response_sensors = _response_sensors(self.layout, self.classifier)
        sensors, shrink, effusivities = self._response_sensors
        idx = [members[i].index for i in forced]
        verdict = check_contact([members[i] for i in forced], [head.refined[i] for i in forced],
                                [sensors[k] for k in idx],
                                np.asarray(sigma)[idx] / shrink[idx], contact.ambient,
                                effusivities, self.tracker.window)
        method = getattr(self.classifier, "method", type(self.classifier).__name__)
        if len(forced) == len(members) and not verdict.responded:
            if contact.final:
                self.no_response.append(contact.id)
            return MaterialEstimate(
                UNKNOWN, {}, 0.0, None, method, family=UNKNOWN,
                note=(f"no thermal response: the force dated it, the temperature shows no "
                      f"contact (likelihood gain {verdict.gain:.1f} <= {verdict.threshold:.1f}, "
                      f"{verdict.taxels} taxels)"))
        silent = {forced[i] for i in verdict.silent}
        if not silent or len(silent) == len(members):
            return self.classifier.classify(contact)
        kept = [w for i, w in enumerate(contact.windows) if i not in silent]
        estimate = self.classifier.classify(dataclasses.replace(contact, windows=kept))
        left = sorted(contact.windows[i].taxel for i in silent)
        return dataclasses.replace(estimate, note=(
            f"taxels {', '.join(map(str, left))}: no thermal response of their own (the "
            f"force dated them), left out of the classification"))

    def _host_times(self, contact: Contact) -> HostTimes | None:
        to_host = self.timeline.to_host
        onset = to_host(contact.onset)
        if np.isnan(onset):
            return None
        return HostTimes(onset, None if contact.release is None else to_host(contact.release),
                         to_host(contact.decided_at), to_host(self._now))

    def _drain(self, started: float, budget: float | None) -> list[ContactResult]:
        """Refine and classify waiting contacts, one step at a time, within the budget."""
        results: list[ContactResult] = []
        steps = 0
        while self._queue:
            head = self._queue[0]
            refining = len(head.refined) < len(head.decided.members)
            if refining and head.decided.members[len(head.refined)].dated_by == "force":
                # nothing to fit (the force dated it): no budgeted step (one step per call
                # for each force-dated member made results wait ~90 ms, p99 ~300 ms)
                t0, c0 = time.perf_counter(), time.process_time()
                head.refined.append(refine_member(head.decided.members[len(head.refined)],
                                                  self.depth, self.diffusivity,
                                                  sensor=self.refine_sensor))
                self._spent("refine", t0, c0)
                continue
            kind = "refine" if refining else "classify"
            # after the first step, start one only if its usual cost fits what is left
            if (budget is not None and steps
                    and time.perf_counter() - started + self._typical[kind] > budget
                    and self._now - head.decided.decided_at < self.max_wait):
                break
            steps += 1
            t0, c0 = time.perf_counter(), time.process_time()
            if refining:
                member = head.decided.members[len(head.refined)]
                head.refined.append(refine_member(member, self.depth, self.diffusivity,
                                                  sensor=self.refine_sensor))
            else:
                self._queue.popleft()
                contact = finish_contact(head.decided, self.layout, head.refined,
                                         self.tracker.window)
                result = ContactResult(contact, self._classify(head, contact), self._now,
                                       self._host_times(contact))
            spent = self._spent(kind, t0, c0)
            self._typical[kind] += 0.1 * (spent - self._typical[kind])
            if refining:
                continue
            t1, c1 = time.perf_counter(), time.process_time()
            for sink in self.sinks:
                sink.write(result)
            self._spent("sinks", t1, c1)
            self.stats.results += 1
            results.append(result)
        return results


def _response_sensors(layout: Layout, classifier: object,
                      ) -> tuple[list, np.ndarray, tuple[float, ...]]:
    """Each taxel's sensor description and smoothing factor, and the candidates' effusivities.

    The candidates are the classifier's (``classifier.model.effusivity``), else the shipped
    table's ``classify = true`` materials.
    """
    from skin.models.sensors import SensorDescription

    boards = {b.id: SensorDescription.from_board(b) for b in layout.boards.values()}
    sensors = [boards[t.board] for t in layout.taxels]
    shrink = np.array([s.smoothing_noise_factor() for s in sensors])
    model = getattr(classifier, "model", None)
    eff = getattr(model, "effusivity", None)
    if eff is None:
        from skin.models.materials import load_materials

        eff = [m.effusivity for m in load_materials().values() if m.classify]
    return sensors, shrink, tuple(sorted({float(v) for v in np.ravel(eff)}))


def _detector_for(layout: Layout, noise: np.ndarray | None = None,
                  envelope_noise: bool | None = None,
                  common_mode: bool | str | None = None) -> OnsetDetector:
    """Return an onset detector set by the boards' sensors (each taxel's noise: its board's).

    ``envelope_noise``: the detector's (None: its default); ``common_mode``: the detector's
    board common mode (None or "auto": `skin.stream.onset.common_auto` of the boards' sensors,
    a ValueError when they differ; on boards of `skin.stream.onset.COMMON_MIN` taxels or more).
    """
    from skin.models.sensors import SensorDescription

    sensors = {b.id: SensorDescription.from_board(b) for b in layout.boards.values()}
    first = sensors[layout.taxels[0].board] if layout.taxels else SensorDescription()
    sigma = [sensors[t.board].delivered_noise(25.0 + sensors[t.board].heated_rise)
             for t in layout.taxels]
    knobs = {} if envelope_noise is None else {"envelope_noise": envelope_noise}
    if common_mode is None or common_mode == "auto":
        kinds = {common_auto(sensors[b]) for b in {t.board for t in layout.taxels}}
        if len(kinds) > 1:  # one detector, one sensor: "auto" cannot hold for both kinds
            raise ValueError(
                "common_mode: the layout mixes boards whose heater is PID-held with "
                "constant-power ones: "
                "the board common mode's \"auto\" cannot serve both; set common_mode true or "
                "false (skin file [skin] common_mode, --[no-]common-mode)")
    return OnsetDetector(len(layout), sensor=first, sigma=sigma if noise is None else noise,
                         boards=[t.board for t in layout.taxels], common_mode=common_mode,
                         **knobs)

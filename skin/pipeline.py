"""The streaming pipeline: frames -> calibrated temperatures -> onsets -> contacts -> materials."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from skin.calibration import Calibration
from skin.contact import Contact, MaterialEstimate
from skin.errors import SkinError
from skin.frame import Frame
from skin.layout import Layout
from skin.onset import OnsetDetector
from skin.tracking import ContactTracker


class Classifier(Protocol):
    """Anything that turns a `Contact` into a `MaterialEstimate`."""

    def classify(self, contact: Contact) -> MaterialEstimate:  # noqa: D102
        ...


@dataclass(frozen=True)
class ContactResult:
    """A decided contact and what the classifier made of it."""

    contact: Contact
    estimate: MaterialEstimate


@dataclass
class PipelineStats:
    """Running counts kept by the pipeline.

    Attributes
    ----------
    frames : int
        Frames processed.
    gaps : int
        Frames missing according to sequence numbers.
    flagged : numpy.ndarray
        Per taxel: samples without a temperature (open or saturated thermistor).
    onsets, releases, contacts : int
        Events seen.
    """

    frames: int = 0
    gaps: int = 0
    flagged: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    onsets: int = 0
    releases: int = 0
    contacts: int = 0


class Pipeline:
    """Run the whole chain on a stream of frames.

    Parameters
    ----------
    layout : Layout
        The skin's taxels.  One board for now: several boards need a merged time base.
    classifier : Classifier
        Labels each decided contact.
    calibration : Calibration, optional
        Counts to deg C; the layout's nominal board constants by default.
    detector : OnsetDetector, optional
        Onset detector; the default settings by default.
    window : float
        Longest contact window handed to the classifier, s.
    sensors : list of SensorConstants, optional
        Per-taxel thermal constants in layout order (a calibration file's), used to date
        onsets; the boards' by default.
    ambient_offset : float
        Added to the ambient sensor's reading, K (a calibration file's).
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
    ) -> None:
        if len(layout.boards) != 1:
            raise SkinError(f"{layout.source}: the pipeline handles one board for now; this "
                            f"layout has {len(layout.boards)}")
        self.layout = layout
        self.classifier = classifier
        self.calibration = calibration or Calibration.from_layout(layout)
        self.detector = detector or OnsetDetector(len(layout))
        self.board = next(iter(layout.boards.values()))
        self.tracker = ContactTracker(layout, self.board.sample_rate, window=window)
        if sensors is not None:
            if len(sensors) != len(layout):
                raise SkinError(f"{len(sensors)} sensor constants for {len(layout)} taxels")
            self.tracker.depth = np.array([s.depth for s in sensors])
            self.tracker.diffusivity = np.array([s.diffusivity for s in sensors])
        self.ambient_offset = float(ambient_offset)
        self._state = self.detector.initial_state()
        self._idx, self._addr = layout.channel_map(self.board.id)
        self._last_seq: int | None = None
        self.stats = PipelineStats(flagged=np.zeros(len(layout), dtype=np.int64))
        self.last_temperature = np.full(len(layout), np.nan)

    def process(self, frames: Sequence[Frame]) -> list[ContactResult]:
        """Process a chunk of frames; return the contacts decided within it, classified."""
        if not frames:
            return []
        n = len(self.layout)
        counts = np.empty((len(frames), n))
        for i, f in enumerate(frames):
            if f.board != self.board.id:
                raise SkinError(f"frame seq {f.seq} comes from board {f.board}, which is not in "
                                f"the layout {self.layout.source}")
            if len(f.counts) <= self._addr.max():
                raise SkinError(f"frame seq {f.seq} has {len(f.counts)} channels; the layout "
                                f"addresses channel {int(self._addr.max())}")
            counts[i, self._idx] = f.counts[self._addr]
            if self._last_seq is not None:
                step = (f.seq - self._last_seq) % (1 << 32)
                if 1 < step < (1 << 31):  # a forward jump; repeats and restarts are not gaps
                    self.stats.gaps += step - 1
            self._last_seq = f.seq
        times = np.array([f.device_time for f in frames])
        ambient = np.array([f.ambient for f in frames]) + self.ambient_offset
        temperature, status = self.calibration.temperature(counts)
        self.stats.frames += len(frames)
        self.stats.flagged += (status != 0).sum(axis=0)
        self.last_temperature = temperature[-1]
        events, self._state = self.detector.process(times, temperature, self._state)
        self.stats.onsets += sum(e.kind == "onset" for e in events)
        self.stats.releases += sum(e.kind == "release" for e in events)
        return self._classify(self.tracker.update(times, temperature, ambient, events))

    def flush(self) -> list[ContactResult]:
        """Decide and classify the contacts still open (end of stream)."""
        return self._classify(self.tracker.flush())

    def in_contact(self) -> np.ndarray:
        """Boolean mask of the taxels in contact now (layout order)."""
        return self._state.in_contact.copy()

    def _classify(self, contacts: list[Contact]) -> list[ContactResult]:
        self.stats.contacts += len(contacts)
        return [ContactResult(c, self.classifier.classify(c)) for c in contacts]

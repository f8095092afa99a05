"""A run as it happens: an `ArmView` fed from the pipeline, drawn to a window and/or a movie.

`LiveArm.step` is called after every block of frames with the results the block gave, the
taxels in contact and the last temperatures. The view's colours are brought up to date on
every call (a fraction of a millisecond); what costs is drawing, so a window is drawn at most
``rate`` times per second of wall time and never more than half of the time (a renderer in
software takes 50-150 ms a frame), and a movie gets one frame per ``1 / fps`` seconds of device
time, so it plays at the run's own pace however fast the run went (a run at real speed falls
behind while it renders them; the frames wait in the device's buffer, none is lost).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from skin.viz.arm import ArmView


class LiveArm:
    """Drive an `ArmView` from a running pipeline (see the module).

    Parameters
    ----------
    view : ArmView
        The view (``off_screen=False`` for a window).
    window : bool
        Draw into the view's window, at most ``rate`` times per second.
    movie : str or Path, optional
        Also write a GIF or MP4 of the run (`ArmView.open_movie`).
    rate : float
        Largest window redraw rate, Hz of wall time.
    fps : float
        Movie frames per second of device time.
    clock : callable
        Wall clock, s (for tests).

    Attributes
    ----------
    frames : int
        Frames written to the movie.
    draws : int
        Window redraws.
    update_seconds : float
        Wall time spent bringing the view's colours up to date (the library's own work).
    draw_seconds : float
        Wall time spent rendering (window and movie).
    """

    def __init__(self, view: ArmView, *, window: bool = False, movie: str | Path | None = None,
                 rate: float = 10.0, fps: float = 10.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.view = view
        self.window = window
        self.rate = float(rate)
        self.fps = float(fps)
        self.clock = clock
        self.movie = None if movie is None else view.open_movie(movie, fps=self.fps)
        self._next_frame = 0.0
        self._next_draw = -math.inf
        self.contacts = 0
        self.frames = 0
        self.draws = 0
        self.update_seconds = 0.0
        self.draw_seconds = 0.0
        if window and view.plotter.iren is not None:
            view.plotter.add_key_event("t", self.toggle_mode)

    def toggle_mode(self) -> None:
        """Switch the view between material labels and temperatures (key t in the window)."""
        self.view.mode = "temperature" if self.view.mode == "material" else "material"

    def step(self, now: float, results: Iterable[Any] = (),
             in_contact: np.ndarray | None = None, temperature: np.ndarray | None = None) -> None:
        """Bring the view to device time ``now``; draw if the window or the movie is due."""
        started = time.perf_counter()
        results = list(results)
        self.contacts += sum(1 for r in results if r.contact.final)
        self.view.update(now, in_contact=in_contact, temperature=temperature, results=results)
        touching = 0 if in_contact is None else int(np.count_nonzero(in_contact))
        self.view.title = f"{now:6.1f} s   {touching} taxels in contact   {self.contacts} contacts"
        drawn = time.perf_counter()
        self.update_seconds += drawn - started
        if self.movie is not None and now >= self._next_frame:
            due = int((now - self._next_frame) * self.fps) + 1
            self.view.write_frame(repeat=due)
            self.frames += due
            self._next_frame += due / self.fps
        if self.window and self.clock() >= self._next_draw:
            started_draw = self.clock()
            self.view.render()
            self.draws += 1
            took = self.clock() - started_draw
            # at most `rate` draws a second, and drawing at most half of the time: a slow
            # (software) renderer must not starve the reading of frames
            self._next_draw = started_draw + max(1.0 / self.rate, 2.0 * took)
        self.draw_seconds += time.perf_counter() - drawn

    def close(self) -> None:
        """Finish the movie and close the window (idempotent)."""
        self.view.close()

"""Streaming contact onset and release detection from each taxel's temperature alone.

Contact with an object cooler than the heated taxel makes its temperature fall below what its
recent trend predicts.  Per taxel the detector smooths the reading, keeps a level-and-slope baseline
(Holt's linear smoother) and a one-sided CUSUM of the shortfall below that baseline; the CUSUM
crossing its threshold is an onset, the moment it left zero is the coarse onset time.  While in
contact the baseline is frozen; release is the rise of the smoothed temperature above its
minimum, dated at the minimum.  `skin.onset_refine.refine_onset` then dates the onset
precisely by fitting the heated sensor's contact response to the window.

The detector is vectorised over taxels and keeps all its state in `DetectorState`: processing
a stream in chunks of any size gives the same events as processing it whole.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np


@dataclass(frozen=True)
class OnsetEvent:
    """An onset or release of one taxel.

    Attributes
    ----------
    kind : str
        ``"onset"`` or ``"release"``.
    taxel : int
        Array index of the taxel (layout order).
    time : float
        Estimated instant of the event, s (device time): for an onset, when the temperature
        left its baseline; for a release, when it stopped falling.
    detected_at : float
        Time of the sample at which the event was recognised, s.
    baseline : float
        For an onset: the baseline temperature extrapolated to ``time``, deg C.
        For a release: the (smoothed) lowest temperature reached, deg C.
    slope : float
        For an onset: the baseline slope before contact, deg C / s.  For a release: 0.
    """

    kind: str
    taxel: int
    time: float
    detected_at: float
    baseline: float
    slope: float


@dataclass(frozen=True)
class DetectorState:
    """Per-taxel state of `OnsetDetector` (arrays of length n_taxels)."""

    level: np.ndarray
    slope: np.ndarray
    t_level: np.ndarray
    var: np.ndarray
    cusum: np.ndarray
    t_start: np.ndarray
    in_contact: np.ndarray
    smooth: np.ndarray
    minimum: np.ndarray
    t_minimum: np.ndarray
    armed_at: np.ndarray
    t_last: np.ndarray
    slow: np.ndarray
    slow_start: np.ndarray

    def copy(self) -> DetectorState:
        """Return a deep copy."""
        return replace(self, **{f.name: getattr(self, f.name).copy() for f in fields(self)})


class OnsetDetector:
    """Vectorised streaming onset/release detector.

    Parameters
    ----------
    n_taxels : int
        Number of taxels.
    level_tau : float
        Time constant of the baseline level, s.
    slope_tau : float
        Time constant of the baseline slope, s.
    drift : float
        Least CUSUM allowance, deg C: shortfalls smaller than this (or than 4 noise standard
        deviations, if larger) do not accumulate.
    threshold : float
        CUSUM alarm threshold, deg C x samples.
    noise_floor : float
        Lowest standard deviation assumed for the smoothed reading, deg C.
    noise_tau : float
        Time constant of the noise variance estimate, s.
    warmup : float
        Time after the first sample (and after a release) before onsets are reported, s.
    release_rise : float
        Rise of the smoothed temperature above its in-contact minimum that marks a release, deg C.
    smooth_tau : float
        Time constant of the smoothing applied to the readings before detection, s.
    stale : float
        A CUSUM that stays above zero this long without an alarm is reset (slow drift), s.
    slow_tau : float
        Time constant of the slow channel's average, s. Contacts with poor conductors through
        an air gap fall too slowly for the CUSUM, whose baseline follows them; the slow channel
        compares the smoothed reading with a slow average of it instead.
    slow_threshold : float
        Fall below the slow average that is a contact, deg C (above what air currents and
        heater switching give within ``slow_tau``).
    slow_begin : float
        Fall below the slow average that dates a slow contact's coarse onset, deg C.
    """

    def __init__(
        self,
        n_taxels: int,
        *,
        level_tau: float = 0.1,
        slope_tau: float = 0.5,
        drift: float = 0.03,
        threshold: float = 0.6,
        noise_floor: float = 0.003,
        noise_tau: float = 5.0,
        warmup: float = 0.5,
        release_rise: float = 0.12,
        smooth_tau: float = 0.03,
        stale: float = 1.0,
        slow_tau: float = 3.0,
        slow_threshold: float = 0.6,
        slow_begin: float = 0.1,
    ) -> None:
        self.n_taxels = n_taxels
        self.level_tau = level_tau
        self.slope_tau = slope_tau
        self.drift = drift
        self.threshold = threshold
        self.noise_floor = noise_floor
        self.noise_tau = noise_tau
        self.warmup = warmup
        self.release_rise = release_rise
        self.smooth_tau = smooth_tau
        self.stale = stale
        self.slow_tau = slow_tau
        self.slow_threshold = slow_threshold
        self.slow_begin = slow_begin

    def initial_state(self) -> DetectorState:
        """Return the state before the first sample."""
        n = self.n_taxels
        nan = np.full(n, np.nan)
        return DetectorState(
            level=nan.copy(),
            slope=np.zeros(n),
            t_level=nan.copy(),
            var=np.full(n, self.noise_floor**2),
            cusum=np.zeros(n),
            t_start=nan.copy(),
            in_contact=np.zeros(n, dtype=bool),
            smooth=nan.copy(),
            minimum=nan.copy(),
            t_minimum=nan.copy(),
            armed_at=np.full(n, np.inf),
            t_last=nan.copy(),
            slow=nan.copy(),
            slow_start=nan.copy(),
        )

    def process(
        self, times: np.ndarray, temperature: np.ndarray, state: DetectorState
    ) -> tuple[list[OnsetEvent], DetectorState]:
        """Run the detector over a chunk of samples.

        Parameters
        ----------
        times : numpy.ndarray, shape (n_samples,)
            Sample times, s, increasing.
        temperature : numpy.ndarray, shape (n_samples, n_taxels)
            Temperatures, deg C; NaN marks a missing or flagged sample, which is skipped.
        state : DetectorState
            State after the previous chunk (`initial_state` for the first); not modified.

        Returns
        -------
        events : list of OnsetEvent
            In time order.
        state : DetectorState
            State after this chunk.
        """
        s = state.copy()
        events: list[OnsetEvent] = []
        temperature = np.asarray(temperature, dtype=float).reshape(len(times), self.n_taxels)
        for t, y in zip(np.asarray(times, dtype=float), temperature, strict=True):
            self._step(float(t), y, s, events)
        return events, s

    def _step(self, t: float, y: np.ndarray, s: DetectorState, events: list[OnsetEvent]) -> None:
        valid = np.isfinite(y)
        new = valid & np.isnan(s.level)
        if new.any():
            s.level[new] = y[new]
            s.smooth[new] = y[new]
            s.slow[new] = y[new]
            s.t_level[new] = t
            s.t_last[new] = t
            s.armed_at[new] = t + self.warmup
        live = valid & ~new
        if not live.any():
            return
        dt = np.maximum(np.where(live, t - s.t_last, 1.0), 1e-9)
        # the smoothed reading averages noise and dithered ADC steps; everything runs on it
        s.smooth[live] += (y[live] - s.smooth[live]) * (1 - np.exp(-dt[live] / self.smooth_tau))
        pred = s.level + s.slope * (t - s.t_level)
        resid = np.where(live, s.smooth - pred, 0.0)
        sigma = np.sqrt(np.maximum(s.var, self.noise_floor**2))
        allowance = np.maximum(self.drift, 4.0 * sigma)
        idle = live & ~s.in_contact

        # CUSUM of the shortfall below the baseline, in deg C x samples
        g_old = s.cusum
        g = np.where(idle, np.maximum(0.0, g_old - resid - allowance), g_old)
        starting = idle & (g_old == 0) & (g > 0)
        s.t_start[starting] = s.t_last[starting]
        stale = idle & (g > 0) & (t - s.t_start > self.stale)
        alarm = idle & (g > self.threshold) & (t >= s.armed_at) & ~stale
        for k in np.flatnonzero(alarm):
            t0 = float(s.t_start[k])
            events.append(OnsetEvent("onset", int(k), t0, t,
                                     float(s.level[k] + s.slope[k] * (t0 - s.t_level[k])),
                                     float(s.slope[k])))
        # the slow channel: a fall below the slow average of the smoothed reading
        fall = np.where(idle, s.slow - s.smooth, 0.0)
        begins = idle & (fall > self.slow_begin) & np.isnan(s.slow_start)
        s.slow_start[begins] = s.t_last[begins]
        s.slow_start[idle & (fall <= self.slow_begin)] = np.nan
        slow_alarm = (idle & ~alarm & (fall > self.slow_threshold) & (t >= s.armed_at)
                      & np.isfinite(s.slow_start))
        for k in np.flatnonzero(slow_alarm):
            events.append(OnsetEvent("onset", int(k), float(s.slow_start[k]), t,
                                     float(s.slow[k]), 0.0))
        alarm = alarm | slow_alarm
        s.slow_start[alarm] = np.nan
        c = 1 - np.exp(-dt / self.slow_tau)
        calm = idle & ~alarm
        s.slow[calm] += c[calm] * (s.smooth[calm] - s.slow[calm])

        s.in_contact[alarm] = True
        s.minimum[alarm] = s.smooth[alarm]
        s.t_minimum[alarm] = t
        g[alarm | stale] = 0.0
        s.cusum[:] = g

        # the baseline follows the signal until there is real evidence of contact
        follow = idle & ~alarm & (g <= self.threshold / 4)
        a = 1 - np.exp(-dt / self.level_tau)
        b = 1 - np.exp(-dt / self.slope_tau)
        err = a * resid
        s.level[follow] = pred[follow] + err[follow]
        s.slope[follow] += (b * err / dt)[follow]
        s.t_level[follow] = t
        quiet = follow & (g == 0)
        v = 1 - np.exp(-dt / self.noise_tau)
        s.var[quiet] += v[quiet] * (resid[quiet] ** 2 - s.var[quiet])

        # release: the smoothed temperature rises clearly above its minimum
        touching = live & s.in_contact & ~alarm
        lower = touching & (s.smooth < s.minimum)
        s.minimum[lower] = s.smooth[lower]
        s.t_minimum[lower] = t
        rise = np.maximum(self.release_rise, 4 * sigma)
        released = touching & (s.smooth - s.minimum > rise)
        for k in np.flatnonzero(released):
            events.append(OnsetEvent("release", int(k), float(s.t_minimum[k]), t,
                                     float(s.minimum[k]), 0.0))
        if released.any():
            r = released
            s.in_contact[r] = False
            s.slope[r] = (s.smooth[r] - s.minimum[r]) / np.maximum(t - s.t_minimum[r], 1e-3)
            s.level[r] = s.smooth[r]
            s.t_level[r] = t
            s.cusum[r] = 0.0
            s.armed_at[r] = t + self.warmup
            s.slow[r] = s.smooth[r]
            s.slow_start[r] = np.nan
        s.t_last[live] = t

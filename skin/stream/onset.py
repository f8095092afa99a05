"""Streaming contact onset and release detection from each taxel's temperature alone.

Contact with an object cooler than the heated taxel makes its temperature fall below what its
recent trend predicts; contact with an object warmer than the taxel (a hot mug, a warm machine
part) makes heat flow into the sensor and its temperature rise above it.  Per taxel the
detector smooths the reading, keeps a level-and-slope baseline (Holt's linear smoother) and two
one-sided CUSUMs, of the shortfall below that baseline and of the excess above it; a CUSUM
crossing its threshold is an onset (a fall, ``direction`` -1, or a rise, +1), the moment it
left zero is the coarse onset time.  A slow channel compares the reading (averaged over a
tenth of its window) with a slow average of it, for falls too slow for the CUSUM (poor
conductors through an air gap).  The baseline
follows a smooth fall as a trend (a poor conductor's, or any contact's through a deep or
lagged thermistor), so the CUSUM sees only its curvature; the gust-envelope test looks at the
fall itself: from where the baseline put the reading when it left the noise, a fall deeper
than any gust of the air's family (``gust_depth``, by default `GUST_DEPTH` of the heated rise,
approached with a time constant of at least ``gust_rise``, by default `GUST_RISE`: the
simulator's family) plus the steepest heater step could make in the time since (told the
heater duty, as the pipeline tells it: the heater's own fall, from the duty's lag through the
body's slowest mode, `OnsetDetector.process`), with
``envelope_sigmas`` (8) noise sigmas to spare, is a contact. A PID-held heater's loop cancels
what moves its sensor slowly: there the gusts, the heater steps and the room's drift are taken
as the reading shows them through the loop (`loop_envelope`), and such an onset is dated when
raised (its reference can date from long before the contact; `refine_onset` searches before
it). A board's common mode (opt-in, ``common_mode``; on boards of `COMMON_MIN` taxels or
more) takes the room off first: gated on a change (nearly) every free taxel shows
by (nearly) the same amount, or, on a PID-held board, the median of its free taxels'
departures on every sample (`OnsetDetector._loop_common`).

What rises without a contact is told apart so: the heater's duty stepping up and ambient drift
move the reading slowly (through the taxel's ~63 s mode), and the baseline follows them; the
taxel's recovery after a release decelerates, so it leaves the baseline on the side away from
a new contact, and nothing accumulates during ``warmup``; a rise that begins right after the
reading fell (a gust's recovery, the reheat after a touch too brief to be reported) is not a
warm object (``rebound``).

In contact the baseline follows the in-contact trend.  Release is the return of the smoothed
temperature from its in-contact extreme (a rise above the minimum after a fall, a fall below
the maximum after a rise), dated at the extreme, or the trend stopping short (the CUSUM of the
other sign), dated where that CUSUM left zero: a taxel still reheating from an earlier contact
keeps rising after a warm touch ends. Both stay clear of one sample's noise at any rate: the
return by ``release_rise``, the stopping short by `END_SIGMAS` of the raw reading's noise per
sample (at 20 Hz a sample's noise is no longer averaged, nor is a slow fall's quantisation
staircase at any rate); and where the smoothing spans under two samples (the paper's below
~67 Hz) the in-contact trend at the onset is the change over the last ``onset_span`` s (0.13-0.15
s), the baseline's prediction standing in for the reading before the CUSUM left zero, not the
one or two noisy samples the CUSUM alarmed in (above, ``onset_span`` is 1e-3 s, a guard only: a
step in the rule at that rate).  `skin.stream.onset_refine.refine_onset` then dates the onset
precisely by fitting the heated sensor's contact response to the window.

A free taxel read again after a hole longer than ``warmup`` (its board's samples lost, or its
readings flagged) starts again as a new one (``warmup`` included): its trend extrapolated
across the hole is no baseline (a taxel recovering from a touch decelerates meanwhile, and
the extrapolation would make that a fall), and a change that happened unseen cannot be dated.

The detector is vectorised over taxels and keeps all its state in `DetectorState`: processing
a stream in chunks of any size gives the same events as processing it whole.

**Set by the sensor and its measured noise.** No threshold is an absolute temperature: each
follows from the taxel's noise and the sensor description (`skin.models.sensors`), unless given.

- ``sigma`` is each taxel's reading noise per sample, K, as the library receives it
  (commissioning measures it from a quiet stretch; default: the sensor description's
  ``noise_kelvin`` times its smoothing's noise factor). The detector's smoothed reading has
  sigma sqrt(g / (2 - g)) for its smoothing gain g; the CUSUM's least allowance (``drift``)
  is 3.3 of those and its noise floor 0.33 (the paper sensor's former 0.03 and 0.003 K).
  Summed over samples, the residual keeps the unsmoothed noise's low-frequency power (sigma
  over the smoothing factor), so the
  CUSUM's threshold against noise is ``arl_threshold`` (Siegmund's approximation of the
  average run length of a one-sided CUSUM) for one false alarm per ``1 / false_alarm_rate``
  taxel-hours, in units of that noise, computed for an allowance of 4 smoothed sigmas where
  the CUSUM subtracts 3.3: not a guaranteed bound (measured far fewer false alarms: the
  allowance is in units of the smoothed, not the summed, noise). Computed at the CUSUM's own
  3.3 it would rise 23 % where it binds (low-cost; the paper sensor at 20-50 Hz) and date a
  20 Hz paper set's onsets 10 ms later (median 31.5 -> 41.5 ms), with no false alarm
  fewer on low-cost seeds 0 and 2 (0.75 and 0 per taxel-hour either way, measured before the
  slow average followed the medium one until armed).
- Levels (the slow channel's; the gust-envelope test's flat margin, which caps its noise
  table's and stands alone before the filters settle) stay 8 sigmas of the averaged
  reading they look at clear of noise, that sigma computed through the sensor's own
  smoothing and then the detector's average (`average_noise`): a reading the sensor already
  smoothed has correlated noise, which a further average removes less of than white noise.
- Disturbances (air currents, heater duty steps, the room drifting) move a heated taxel in
  proportion to how far its heater holds it above ambient (the sensor's ``heated_rise``):
  the thresholds are at least fixed fractions of that rise (`DISTURBANCE`), per second of
  CUSUM (so they scale with the sample rate).
- Time constants of the baseline and the slow channel, and the warm-up, stretch with the
  sensor's response time when it is slower than the paper's (a slow sensor's contact
  departs slowly, and its baseline takes as much longer to catch the reading's trend).
- A sensor at least twice as fast as the paper's (fast-film) has the gust-envelope test read
  the fall on a second, faster reading as well: smoothed over the detector's smoothing
  shortened with the response time (at least one sample, ``envelope_tau``), against that
  reading's own noise, each reading's ``z`` for half the false-alarm target (a fast contact
  stands out of it sooner; the smoothed reading's test still catches the slow ones). The
  union's crossings on noise are counted, not bounded (`skin bench envelope-rate`).
- A sensor body whose slowest thermal mode (62.5 s for the paper's, scaled by l^2 / alpha) is
  faster than the paper's brings heater steps and drift to the thermistor faster: the CUSUM
  thresholds grow with the mode's speed, the slow channel's with what the mode moves within
  its window (never below the paper's fractions; not for a PID-held heater).
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

#: Thresholds as fractions of the sensor's heated rise above ambient (per 200 Hz sample for the
#: CUSUM thresholds): what air currents, heater steps and drift move a heated taxel by. With
#: the paper's sensor (13.96 K) they are the detector's former constants (0.4, 0.6 K x samples;
#: 0.12, 0.6, 0.1 K).
_PAPER_RISE = 2.5**2 / 19.7 * 2.4e-4 / (1.5625e-4 * 0.0349)  # K, eq. 2 with the paper's constants
DISTURBANCE = {"threshold": 0.4 / _PAPER_RISE, "rise_threshold": 0.6 / _PAPER_RISE,
               "release_rise": 0.12 / _PAPER_RISE, "slow_threshold": 0.6 / _PAPER_RISE,
               "slow_begin": 0.1 / _PAPER_RISE}
#: The disturbance family the gust-envelope test is set against (`skin.bench.streams` draws
#: from it): the deepest gust as a fraction of the heated rise (0.4 K of the paper's 13.96 K),
#: the fastest gust's time constant, s, and the largest heater duty step, a fraction of the
#: heated rise reached through the sensor body's slowest mode.
GUST_DEPTH = 0.4 / _PAPER_RISE
GUST_RISE = 1.0
HEATER_STEP = 0.45
# With the heater's duty given (`OnsetDetector.process`'s ``duty``), a fall is allowed the
# heater's own fall where the taxel's duty lies below what its body still holds: the duty
# through the body's slowest mode (``DetectorState.duty_lag``). A taxel's first duty is taken
# as the steepest step down just then, a `HEATER_STEP` share of the duty before it (what its
# heater did before is not known).
#: The fall tests `OnsetDetector.trace` gives margins of (statistic over threshold): the
#: CUSUM (not stale), the CUSUM gone stale (gathering longer than ``stale``: reset, no
#: alarm), the slow channel (its fall below the slow average, counted once it began) and the
#: gust-envelope test (its fall from the reference over the envelope allowed).
MARGIN_TESTS = ("cusum", "cusum_stale", "slow", "envelope")
#: The room's random walk assumed when none is commissioned, K^2/s (about 1 K per 10 minutes):
#: a loop-held sensor passes its fast part (`loop_envelope`). The one default: the simulated
#: room of `skin.bench.streams` drifts at this rate, the rate the detector assumes. (The
#: commissioned ``drift`` of `skin.models.commission` is a taxel's trend, K/s, not this.)
AMBIENT_DRIFT = 1.0 / 600.0
#: The gust-envelope test's flat noise margin, sigmas of the reading it looks at: with the
#: noise table (``envelope_noise``) its cap, and its margin before the filters settle; alone
#: with ``envelope_noise=False``. Not scaled by ``envelope_sigmas`` when the table runs.
FLAT_SIGMAS = 8.0
#: With ``envelope_noise``, the fall's noise table (`drop_noise`) applies to a reference taken
#: this many ``slope_tau`` after the baseline was seated or its filters' run broken (first
#: sample, a hole of any length, a release: ``DetectorState.t_seated``); before, the flat
#: margin. The level/trend filter, seated with no trend, has caught all but
#: 2.6 % (paper, fast-film) to 4.7 % (low-cost, pid-logger) of the reading's own trend after 3
#: ``slope_tau`` (39 % when the warm-up ends, 1 ``slope_tau`` on fast-film: the table applied
#: from there took that transient for a fall, fast-film's evaluate-onset seed 4 two false
#: alarms 4-20 ms after the warm-up).
SETTLE_TAUS = 3.0
#: In contact, the CUSUM of the other sign (the departure stopping short: a release) needs at
#: least this many noise sigmas of the raw reading (``sigma``, quantisation included), per
#: sample, as the release by return (``release_rise``) stays this many clear of noise
#: (`FLAT_SIGMAS`' 8).
END_SIGMAS = 8.0
#: The common mode (`OnsetDetector`'s ``common_mode``) is a change shared by all but this
#: share of a board's free taxels, rounded up (`_shared`), and needs at least `COMMON_MIN` of
#: them.
COMMON_SHARE = 0.1
COMMON_MIN = 4
#: ... and departs from each taxel's level by more than this many noise sigmas of the reading
#: it looks at (the slow channel's; that much of it is left on the readings).
COMMON_MARGIN = 2.0
#: ... and is forgotten (each taxel's level follows the room) within this many ``slow_tau``.
COMMON_FORGET = 10.0
#: ... and moves those taxels by the same amount: the room moves every heated taxel of a board
#: alike, a skin warming up after power-on (or reheating after touches) moves each by its own
#: distance from its steady state. At least `_shared` of the free taxels' departures lie
#: within this many noise sigmas (the departure's, `COMMON_MARGIN`'s sigma) of each other:
#: the range of 16 Gaussian departures exceeds it with probability below 2 x 16 x Q(4) = 1e-3.
COMMON_AGREE = 8.0
#: ... and, held after it ended abruptly, is 0 once below this share of the noise margin.
COMMON_SNAP = 0.01
#: A taxel whose readings' rms step from their smoothed value (the gated form's ``common_var``)
#: is below this share of its noise margin has no noise (stuck, constant): no free taxel the
#: room could have left flat.
_STILL = 1e-6


def _shared(count: np.ndarray) -> np.ndarray:
    """Return how many of a board's ``count`` free taxels a common mode needs.

    All but `COMMON_SHARE`, rounded up: 4 of 4, 8 of 8, 15 of 16, 18 of 20.
    """
    return np.ceil((1.0 - COMMON_SHARE) * np.asarray(count, dtype=float) - 1e-9)


class _Boards(NamedTuple):
    """A layout's boards as the common mode uses them (`OnsetDetector._groups`).

    ``table``: each board's taxel indices, a row each, padded with ``n``; ``row``: each taxel's
    board (its row); ``order`` (None when the boards are runs of taxels in layout order
    already) and ``starts``: the taxels in board order and where each board's begin, for
    counting by board (`OnsetDetector._per_board`); ``need``: `_shared` of 0 .. the widest
    board's taxels; ``sigma``: each board's largest departure sigma (`COMMON_AGREE`'s);
    ``low``: minus each taxel's noise margin; ``still``: `_STILL` of the margin, squared;
    ``ahead``: each table position's index in a table twice as wide (`OnsetDetector._agree`).
    """

    table: np.ndarray
    row: np.ndarray
    order: np.ndarray | None
    starts: np.ndarray
    need: np.ndarray
    sigma: np.ndarray
    low: np.ndarray
    still: np.ndarray
    ahead: np.ndarray


class _Scratch:
    """A step's float temporaries (`OnsetDetector._step`), reused rather than allocated.

    One set per taxel count and thread (`_scratch`): a step overwrites them, none outlives it.
    """

    ROWS = ("dt", "tmp", "part", "pred", "resid", "sigma", "allowance", "slack", "g", "u",
            "fall", "since", "drop", "margin", "flat", "gusty", "err", "heater", "drop_fast",
            "margin_fast")

    def __init__(self, n: int) -> None:
        for name, row in zip(self.ROWS, np.empty((len(self.ROWS), n)), strict=True):
            setattr(self, name, row)
        #: a padded board table's source (`OnsetDetector._padded`): the last slot stays NaN
        self.ext = np.full(n + 1, np.nan)
        #: the common mode's counts' masks (`OnsetDetector._common`)
        self.flags = np.empty((3, n), dtype=bool)


_SCRATCH = threading.local()


def _scratch(n: int) -> _Scratch:
    """Return this thread's `_Scratch` for ``n`` taxels (made at its first use)."""
    mine = getattr(_SCRATCH, "by_size", None)
    if mine is None:
        mine = _SCRATCH.by_size = {}
    work = mine.get(n)
    if work is None:
        work = mine[n] = _Scratch(n)
    return work


def _toward(x: np.ndarray, target: np.ndarray, gain: np.ndarray, where: np.ndarray,
            tmp: np.ndarray) -> None:
    """Move ``x`` one exponential-average step toward ``target`` where ``where``, in place.

    ``x + (target - x) * gain``, the same arithmetic, without temporaries (``tmp`` is
    overwritten).
    """
    np.subtract(target, x, out=tmp)
    tmp *= gain
    np.add(x, tmp, out=x, where=where)


_PAPER_RESPONSE = 2.516  # s, the paper sensor's half-response time (SensorDescription)
_PAPER_MODE = 2.4e-4**2 / 2.796e-9  # s, the paper sensor's l^2 / alpha


@functools.cache
def _paper_smoothed() -> float:
    """Return the paper sensor's noise after the detector's smoothing, K (about 0.0092)."""
    from skin.models.sensors import SensorDescription

    s = SensorDescription()
    g = 1.0 - math.exp(-1.0 / (s.sample_rate * 0.03))
    return s.noise_kelvin(25.0 + s.heated_rise) * math.sqrt(g / (2.0 - g))


def average_noise(sensor: object, tau: float) -> float:
    """Return the noise of an exponential average (time constant ``tau``) of the readings.

    In units of the readings' own noise per sample, as delivered: sqrt(g / (2 - g)) for white
    noise (gain g per sample); more for a reading the sensor already smoothed, whose noise is
    correlated over the smoothing's span (the impulse response of both filters in turn).
    """
    fs = sensor.sample_rate
    g = 1.0 - math.exp(-1.0 / (fs * tau))
    if sensor.smoothing == "none":
        return math.sqrt(g / (2.0 - g))
    from scipy.signal import lfilter

    from skin.models.sensors import smooth

    n = 8 * max(sensor.smoothing_window, int(fs / sensor.smoothing_cutoff)) + 1
    impulse = np.zeros(n + int(40.0 / g))
    impulse[n // 2] = 1.0  # in the middle: a non-causal filter spreads both ways
    h = smooth(impulse, sensor)
    both = lfilter([g], [1.0, g - 1.0], h)
    return float(np.sqrt(np.sum(both**2) / np.sum(h**2)))


def _gust_family(t: np.ndarray, depth: float, rise: float) -> list[np.ndarray]:
    """Return the air's gust family on times ``t``, K.

    Falls of ``depth`` approached with time constants ``rise``, 2 and 4 times it, held 1, 2, 4
    and 8 s, then recovering alike (`loop_envelope` and `_gust_allowance` share it).
    """
    return [-depth * np.where(t < hold, -np.expm1(-t / r),
                              -np.expm1(-hold / r) * np.exp(-(t - hold) / r))
            for r in (rise, 2.0 * rise, 4.0 * rise) for hold in (1.0, 2.0, 4.0, 8.0)]


@functools.cache
def drop_noise(sensor: object, smooth_tau: float, level_tau: float, slope_tau: float,
               horizon: float, fast_tau: float | None = None
               ) -> tuple[float, np.ndarray, float]:
    """Return the noise of the gust-envelope test's fall as a function of the time since.

    The test's fall ``ref_level + ref_slope * since - smooth`` is a linear filter of the
    readout noise: the baseline's prediction and trend where the reference was taken (the
    level/trend filter, gains from ``level_tau`` and ``slope_tau``, run on the reading
    smoothed with ``smooth_tau``), less the smoothed reading ``since`` later (smoothed with
    ``fast_tau`` where given: the test's faster reading, `OnsetDetector`'s ``envelope_tau``).
    Its variance follows from the impulse responses of the sensor's own smoothing, the
    detector's smoothings and the baseline filter, taken in turn, over every reference time.
    (The test extrapolates only a falling trend: ``min(ref_slope, 0)``, whose fall is
    never larger than the linear one's, so the figure errs on the safe side.)

    Parameters
    ----------
    sensor : SensorDescription
        The sensor: its sample rate and smoothing; white readout noise.
    smooth_tau, level_tau, slope_tau : float
        The detector's smoothing and baseline time constants, s.
    horizon : float
        The longest time since the reference, s (the slow channel's window).
    fast_tau : float, optional
        The smoothing of the reading the fall is measured on, s (default ``smooth_tau``).

    Returns
    -------
    step : float
        The table's step, s (one sample).
    sd : numpy.ndarray
        The fall's standard deviation ``k`` steps after the reference, in units of the
        residual's (``sd[0] == 1``: the smoothed reading less the baseline's prediction).
    resid : float
        The residual's standard deviation in units of the delivered reading's noise (the
        reading smoothed with ``fast_tau`` less the baseline's prediction, where given).
    """
    from scipy.signal import correlate, lfilter

    fs = sensor.sample_rate
    dt = 1.0 / fs
    g_s, g_l, g_b = (-math.expm1(-dt / tau) for tau in (smooth_tau, level_tau, slope_tau))
    k_max = math.ceil(horizon * fs) + 1
    h = sensor.smoothing_impulse()
    h = h / np.sqrt(np.sum(h**2))  # the delivered reading's noise: 1
    # long enough for the smoothing and the baseline filter to have forgotten the impulse
    memory = int(40.0 / g_s + 40.0 * max(level_tau, slope_tau) * fs)
    x = np.zeros(h.size + memory + k_max)
    x[: h.size] = h
    a = lfilter([g_s], [1.0, g_s - 1.0], x)  # the smoothed reading
    # the reading the fall is measured on (the same one, or the faster one)
    g_f = g_s if fast_tau is None else -math.expm1(-dt / fast_tau)
    b = a if fast_tau is None else lfilter([g_f], [1.0, g_f - 1.0], x)
    pred = np.empty_like(a)  # the baseline's prediction at each sample
    trend = np.empty_like(a)  # ... and the trend it extrapolates (before the sample's update)
    level = slope = 0.0
    for i, ai in enumerate(a.tolist()):
        p = level + slope * dt
        pred[i], trend[i] = p, slope
        err = g_l * (ai - p)
        level = p + err
        slope += g_b * err / dt
    # sum over reference times r of (pred_r + k dt trend_r - b_{r+k})^2, every k at once
    lags = np.arange(k_max)
    cross_p = correlate(b, pred, mode="full", method="fft")[a.size - 1:][:k_max]
    cross_t = correlate(b, trend, mode="full", method="fft")[a.size - 1:][:k_max]
    var = (np.sum(pred**2) + 2.0 * lags * dt * np.sum(pred * trend)
           + (lags * dt) ** 2 * np.sum(trend**2) - 2.0 * cross_p - 2.0 * lags * dt * cross_t
           + np.sum(b**2))
    sd = np.sqrt(np.maximum(var, 0.0))
    return dt, sd / sd[0], float(sd[0])


@functools.cache
def loop_envelope(sensor: object, horizon: float, gust_depth: float, mode: float,
                  false_alarm_rate: float, gust_rise: float = GUST_RISE
                  ) -> tuple[float, np.ndarray, np.ndarray]:
    """Return what the air, the heater and the room can move a loop-held reading by in a time.

    The gust-envelope test's allowance for a PID-held heater (``sensor.heater == "pid"``),
    whose loop cancels what moves the sensor slowly: each disturbance of the family
    `skin.bench.streams` draws, as the reading shows it through the loop, the thermistor lag
    and the smoothing (`skin.models.sensors.apply_dynamics`, `smooth`):

    - gusts of ``gust_depth`` K at most, rising with a time constant of ``gust_rise`` (default
      `GUST_RISE`) to 4 times that and held 1 to 8 s: the loop cuts a gust's fall to about
      40 % (pid-logger: 0.12 K of 0.29 K), and its recovery overshoots and falls back
      (counted);
    - a heater duty step of `HEATER_STEP` of the heated rise through the body's slowest mode
      (``mode``, s), either way: at the thermistor it stays below about ``HEATER_STEP`` x the
      rise x ``control_time / mode`` (pid-logger: 0.10 K), where a constant-power heater keeps
      falling by ``HEATER_STEP`` x the rise / ``mode`` per second (0.07 K/s);
    - the room's random walk (`AMBIENT_DRIFT` K^2/s): the loop passes its fast part, a
      band-limited noise (pid-logger: 0.032 K sd, 23 times the readout's), whose fall over a
      time has the sd ``sqrt(AMBIENT_DRIFT x sum((g(t) - g(t - s))^2) dt)`` (g: the reading's
      response to a unit step of the room); the test allows z of those sd, with z set so that
      the room's fall over *any* span up to ``horizon``, tested on every sample, passes it
      ``false_alarm_rate`` times per taxel-hour (`_room_quantile`; pid-logger: z = 4.84, where
      one span's quantile, 3.93, let it pass 4.4 times per taxel-hour).

    The gusts are taken one at a time: a gust that begins while the reading still recovers
    from the previous one (about 18 % of the simulator's begin within 12 s of the previous)
    can fall further than the table allows.

    Returns
    -------
    step : float
        The grid step, s: whole samples, at least 0.02 s and a thousandth of ``horizon``
        (the tables' cost grows with their length). Entry j of each table holds for every
        span up to j steps (look up ``ceil(span / step)``: conservative between grid times).
    fall : numpy.ndarray
        The largest fall of a gust and of a heater step, each over any stretch of j steps or
        fewer, summed (both may come together), K; from 0 to past ``horizon``.
    drift : numpy.ndarray
        The quantile of the room's fall over j steps, K.
    """
    from skin.models.sensors import apply_dynamics, smooth

    fs = float(sensor.sample_rate)
    every = max(1, math.ceil(max(0.02, horizon / 1000.0) * fs - 1e-9))  # samples a step
    dt = every / fs
    lags = every * np.arange(math.ceil(horizon / dt) + 2)
    pad = int(2.0 * fs)  # settled before the disturbance
    t = np.arange(round((horizon + 4.0 * gust_rise + 8.0 + 10.0) * fs)) / fs
    gusts = _gust_family(t, gust_depth, gust_rise)
    heater = HEATER_STEP * sensor.heated_rise * -np.expm1(-t / mode)
    room = np.ones_like(t)
    x = np.column_stack([*gusts, -heater, heater, room])
    x = np.concatenate([np.zeros((pad, x.shape[1])), x])
    y = smooth(apply_dynamics(x, sensor, fs, axis=0), sensor, axis=0, fs=fs)
    g = y[:, -1]
    n_gust = len(gusts)
    worst = np.zeros((lags.size, 3))
    # the room's fall over n samples, per unit of its K^2/s: sum((g(t) - g(t - n))^2) / fs,
    # for every n at once from g's autocorrelation (g is 0 before the step)
    g2 = np.concatenate(([0.0], np.cumsum(g**2)))
    auto = np.correlate(g, g, mode="full")[g.size - 1:]
    for i, n in enumerate(lags[lags > 0], start=int(np.sum(lags <= 0))):
        falls = np.max(y[:-n, :-1] - y[n:, :-1], axis=0)
        worst[i] = (falls[:n_gust].max(), falls[n_gust:].max(),
                    (g2[-1] + g2[g.size - n] - 2.0 * auto[n]) / fs)
    worst = np.maximum.accumulate(np.maximum(worst, 0.0), axis=0)
    sd = np.sqrt(AMBIENT_DRIFT * worst[:, 2])
    z = _room_quantile(sensor, lags, sd, false_alarm_rate)
    fall, drift = worst[:, 0] + worst[:, 1], z * sd
    fall.setflags(write=False)  # cached: shared by every detector of the sensor
    drift.setflags(write=False)
    return dt, fall, drift


@functools.cache
def _room_variance(sensor: object, medium_tau: float, slow_tau: float) -> float:
    """Return the variance of the room's random walk in a loop-held taxel's departure, K^2.

    The departure is what `OnsetDetector._loop_common` measures: the reading averaged with
    ``medium_tau`` less its own level, followed with ``slow_tau``. `AMBIENT_DRIFT` times the
    integral of the square of g, the departure's response to a unit step of the room (through
    the loop, the lag, the smoothing and these two filters; g returns to 0): pid-logger
    0.028 K sd, 0.86 of the variance of the reading itself (0.030 K sd). The reference that
    ``common_var``, measured through the same filters, is set against.
    """
    from skin.models.sensors import apply_dynamics, smooth

    fs = float(sensor.sample_rate)
    pad = int(2.0 * fs)
    step = np.concatenate([np.zeros(pad), np.ones(round(600.0 * fs))])
    g = smooth(apply_dynamics(step, sensor, fs), sensor, fs=fs)
    a_m, a_s = (-math.expm1(-1.0 / (fs * tau)) for tau in (medium_tau, slow_tau))
    m = _ema(g, a_m)
    g = m - _ema(m, a_s)
    return float(AMBIENT_DRIFT * np.sum(g**2) / fs)


def _envelope_margin(drop: np.ndarray, gusty: np.ndarray, drop_fast: np.ndarray | None,
                    gusty_fast: np.ndarray | None) -> np.ndarray:
    """Return the gust-envelope test's statistic over its threshold (>= 1: it fires).

    The fall over what it must clear, on the smoothed reading and, where the detector has one
    (``drop_fast``), on its faster reading: the larger of the two; 0 where there is no fall
    (no reference).
    """
    out = np.where(np.isfinite(drop), drop, 0.0) / gusty
    if drop_fast is not None:
        np.fmax(out, np.where(np.isfinite(drop_fast), drop_fast, 0.0) / gusty_fast, out=out)
    return out


def _ema(x: np.ndarray, a: float) -> np.ndarray:
    """Return the exponential average y[i] = y[i-1] + a (x[i] - y[i-1]), y[-1] = 0, of ``x``."""
    from scipy.signal import lfilter

    return lfilter([a], [1.0, a - 1.0], x)


@functools.cache
def _gust_allowance(sensor: object, gust_depth: float, smooth_tau: float, level_tau: float,
                    slope_tau: float, threshold: float, rise_threshold: float,
                    gust_rise: float = GUST_RISE) -> float:
    """Return the least CUSUM allowance, K, at which no gust of the family raises the CUSUM.

    The gusts of `loop_envelope` (``gust_depth`` K, rising with 1 to 4 ``gust_rise``, held 1
    to 8 s), noise-free, through the sensor's loop, lag and smoothing, then the detector's
    smoothing, baseline (level and slope, following while the CUSUM is below a quarter of
    ``threshold``) and falling CUSUM; 15 allowances at once (a column each), three rounds,
    each on the 16th of the last one's bracket (to 1/4096 of ``gust_depth``). If none of them
    holds, ``gust_depth`` itself is tried and returned if it holds; if not, a
    `skin.errors.SkinError` names the sensor, the family and the peak (met only when called
    with a ``threshold`` of 0, which `OnsetDetector` refuses: pid-logger with any positive
    one, and 27 combinations of the smoothing, level and slope time constants tried, held the
    family below its depth).

    By default (`OnsetDetector`'s ``gust_depth`` and ``gust_rise``) the family is the
    simulator's (`skin.bench.streams`: `GUST_DEPTH` of the heated rise, rising in 1 to 4 s,
    held 1 to 8 s), not a commissioned figure: the false-alarm figures measured on its
    streams are measured on the very family this allowance was made for, and are optimistic
    for real air. A gust that rises faster than ``gust_rise`` (a fan switched on: under a
    second) is not covered; real hardware sets both from its air.

    This is a copy of `OnsetDetector._step`'s baseline and CUSUM, not the detector itself:
    no stale reset, warm-up, rebound window or rise alarm (the rise CUSUM is only reset past
    ``rise_threshold``, as a rebound would be). Running the detector instead needs each gust
    on a board of its own with `COMMON_MIN` flat taxels (or the median takes it off), 60
    taxels for 12 gusts, and a run per allowance or a taxel per allowance (900 taxels for 15),
    through its per-sample path: several times this one's cost, paid by every detector built
    on a new sensor. ``tests/test_onset_common.py`` runs the detector itself over the family,
    noise-free, at the allowance this returns, falls and rises.
    """
    from skin.models.sensors import apply_dynamics, smooth

    fs = float(sensor.sample_rate)
    t = np.arange(round((4.0 * gust_rise + 8.0 + 20.0) * fs)) / fs
    gusts = _gust_family(t, gust_depth, gust_rise)
    x = np.concatenate([np.zeros((int(2.0 * fs), len(gusts))), np.column_stack(gusts)])
    y = smooth(apply_dynamics(x, sensor, fs, axis=0), sensor, axis=0, fs=fs)
    a_s, a_l, a_b = (-math.expm1(-1.0 / (fs * tau)) for tau in (smooth_tau, level_tau, slope_tau))
    n = y.shape[1]

    def peaks(ks: np.ndarray) -> np.ndarray:
        """Return the CUSUM's highest point over every gust, for each allowance of ``ks``."""
        k = np.repeat(ks, n)
        sm = level = slope = g = u = top = np.zeros(k.size)
        for row in np.tile(y, (1, ks.size)):
            sm = sm + (row - sm) * a_s
            pred = level + slope / fs
            resid = sm - pred
            g = np.maximum(0.0, g - resid - k)
            u = np.maximum(0.0, u + resid - k)
            top = np.maximum(top, g)
            u = np.where(u > rise_threshold, 0.0, u)  # the recovery: a rebound, reset
            follow = (g <= threshold / 4.0) & (u <= rise_threshold / 4.0)
            err = a_l * resid
            level = np.where(follow, pred + err, level + slope / fs)
            slope = np.where(follow, slope + a_b * err * fs, slope)
        return top.reshape(ks.size, n).max(axis=1)

    lo, hi = 0.0, float(gust_depth)
    found = False
    for _ in range(3):
        ks = lo + (hi - lo) * np.arange(1, 16) / 16.0
        held = np.flatnonzero(peaks(ks) < threshold)  # the peak falls as the allowance grows
        found = found or bool(held.size)
        lo, hi = (float(ks[held[0] - 1]) if held.size and held[0] > 0 else
                  lo if held.size else float(ks[-1]),
                  float(ks[held[0]]) if held.size else hi)
    if not found:
        # no allowance below the gust's own depth held: the depth itself, if it holds (an
        # allowance of the whole depth per sample; checked, never assumed)
        peak = float(peaks(np.array([hi]))[0])
        if not peak < threshold:
            from skin.errors import SkinError

            raise SkinError(
                f"sensor {getattr(sensor, 'name', sensor)!r}: no CUSUM allowance up to the gust "
                f"depth ({gust_depth:.4g} K) keeps the gust family (rising with {gust_rise:g} to "
                f"{4.0 * gust_rise:g} s, held 1 to 8 s) through the sensor's loop below the "
                f"falling threshold {threshold:.4g} K (its peak {peak:.4g} K at an allowance of "
                f"the whole depth): the loop-held board's common mode cannot hold these gusts. "
                f"Give the detector gust_depth / gust_rise measured from the air, or run "
                f"without common_mode")
    return hi


def _room_quantile(sensor: object, lags: np.ndarray, sd: np.ndarray, false_alarm_rate: float,
                   hours: float = 1.0, level: float = 3.0) -> float:
    """Return z: the room's fall through the loop passes z sd over some span this rarely.

    The gust-envelope test compares the fall over every span up to its horizon, on every
    sample, so the quantile of one span's fall (``ndtri(1 - rate x window)``) under-counts
    (pid-logger: z = 3.93 for 0.1 false alarms per taxel-hour let 4.4 through). A fixed-seed
    simulation of the room's random walk (`AMBIENT_DRIFT`) through the sensor's loop, lag
    and smoothing counts the up-crossings of ``level`` by the largest fall over the spans
    ``lags`` (samples), each in units of its sd ``sd``; the tail of a Gaussian field over
    time and span, rate(z) = A z exp(-z^2 / 2) (its Euler characteristic; A measured at
    ``level``), carries that rate to ``false_alarm_rate`` per taxel-hour.
    """
    from skin.models.sensors import apply_dynamics, smooth

    fs = float(sensor.sample_rate)
    every = int(lags[1])  # the table's grid, in samples
    settle = round(60.0 * fs)
    n = round(hours * 3600.0 * fs) + settle
    steps = np.random.default_rng(0).normal(0.0, math.sqrt(AMBIENT_DRIFT / fs), n)
    reading = smooth(apply_dynamics(np.cumsum(steps), sensor, fs), sensor, fs=fs)
    r = reading[settle::every]
    best = np.full(r.size, -np.inf)
    for j in range(1, min(sd.size, r.size)):
        if sd[j] > 0.0:
            np.maximum(best[j:], (r[:-j] - r[j:]) / sd[j], out=best[j:])
    above = best > level
    rate = max(int(np.count_nonzero(above[1:] & ~above[:-1])), 1) / hours
    a = rate * math.exp(0.5 * level**2) / level
    target = max(false_alarm_rate, 1e-12)
    z = level
    for _ in range(50):  # z = sqrt(2 ln(a z / target)): a contraction for z > 1
        z = math.sqrt(2.0 * max(math.log(a * z / target), 0.5 * level**2))
    return z


def arl_threshold(arl: float | np.ndarray, k: float | np.ndarray) -> np.ndarray:
    """Threshold h (in sigma) of a one-sided CUSUM with allowance k (in sigma) for a given ARL.

    Siegmund's approximation of the in-control average run length of a CUSUM of N(0, 1)
    increments, ARL = (exp(2 k b) - 2 k b - 1) / (2 k^2) with b = h + 1.166, solved for h by
    bisection (monotone in b). ``arl`` is in samples.
    """
    arl = np.asarray(arl, dtype=float)
    k = np.maximum(np.asarray(k, dtype=float), 1e-6)
    lo = np.zeros(np.broadcast(arl, k).shape)
    hi = np.full_like(lo, 1e3)
    for _ in range(80):
        b = 0.5 * (lo + hi)
        x = np.minimum(2 * k * b, 700.0)
        run = (np.exp(x) - x - 1) / (2 * k**2)
        lo = np.where(run < arl, b, lo)
        hi = np.where(run < arl, hi, b)
    return np.maximum(0.5 * (lo + hi) - 1.166, 0.0)


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
        left its baseline; for a release, when it stopped moving away from it. Except a
        loop-held sensor's onset raised by the gust-envelope test alone (channel 2, the CUSUM
        not begun): dated when raised (``time == detected_at``), after the contact began;
        `skin.stream.onset_refine.refine_onset` dates it (it searches before the coarse
        onset).
    detected_at : float
        Time of the sample at which the event was recognised, s.
    baseline : float
        For an onset: the baseline temperature extrapolated to ``time``, deg C.
        For a release: the (smoothed) in-contact extreme, deg C: the lowest temperature
        reached for a fall (``direction`` -1), the highest for a rise (+1).
    slope : float
        For an onset: the baseline slope before contact, deg C / s.  For a release: 0.
    direction : int
        -1: the reading fell (an object cooler than the taxel); +1: it rose (an object
        warmer than the taxel, heat flowing into the sensor).  A release has its onset's.
    channel : int
        Which test raised it (0 fall, 1 rise, 2 slow fall, 3 release): the detector gives the
        events of one sample in (channel, taxel) order, so events of shards of taxels
        (`skin.stream.shards`) merge back into the same order. Not compared.
    dated_by : str
        What dated it: ``"thermal"`` (this detector) or ``"force"`` (the taxel's force
        channel, `skin.stream.force.ForceOnsets`: exact, not refined). Not compared.
    """

    kind: str
    taxel: int
    time: float
    detected_at: float
    baseline: float
    slope: float
    direction: int = -1
    channel: int = field(default=0, compare=False, repr=False)
    dated_by: str = field(default="thermal", compare=False, repr=False)


@dataclass(frozen=True)
class DetectorState:
    """Per-taxel state of `OnsetDetector` (arrays of length n_taxels).

    ``direction`` is 0 while free, -1 or +1 in contact (the onset's direction; ``in_contact``
    is ``direction != 0``); ``extreme`` and ``t_extreme`` hold the in-contact minimum (after a
    fall) or maximum (after a rise) and its time.  ``recover_until`` and ``recover_dir`` mark
    the taxel's recovery after a release, during which the slow channel's average follows the
    reading in the recovery's direction (``recover_dir`` = minus the contact's direction).
    ``t_first`` is the time of each taxel's first reading (a loop-held sensor's noise
    estimate is a running mean of the residual's square up to ``noise_tau`` after it).
    ``t_seated`` is when its baseline was last seated or its filters' run broken: the first
    reading, a release, a hole of any length (a missing sample); the envelope margin's noise
    table applies only to a reference taken `SETTLE_TAUS` ``slope_tau`` after it.
    ``settle_restarts`` counts, per taxel, the holes shorter than the warm-up that restarted it
    (a gap over 1.5 of the sensor's nominal sample periods): a stream whose timestamps
    jitter past that shows it here, and keeps the flat margin.
    ``common_smooth`` and ``common_level`` are each taxel's averaged raw reading and its level
    with the board's common mode taken off (`OnsetDetector`'s ``common_mode``); ``common`` the
    common mode taken off its last reading (its board's), K; ``common_var`` (a loop-held
    board's) the variance of what the common mode leaves of a free taxel's departure, K^2;
    on a gated board, the mean square of each reading's step from its smoothed one, K^2.
    ``duty`` is each taxel's last heater duty given (`OnsetDetector.process`'s ``duty``; NaN:
    none yet), ``duty_lag`` that duty through the sensor body's slowest mode (what the
    heater's excess is settling from; NaN: no duty given) and ``duty_top`` the largest duty
    given (the heated rise's duty: the scale of the lag's kelvins). ``heater_fall`` is how far
    the heater's own change has taken the reading down since the contact's onset (its rate
    from ``duty_lag - duty`` as the fall allowance's, signed; 0 while free or with no duty
    known), K, and ``extreme_fall`` its value at the extreme: a contact's extreme and its end
    are judged on the reading with the heater's change put back (`OnsetDetector._release`).
    ``fast`` is the reading smoothed with ``envelope_tau``, the gust-envelope test's faster
    one (NaN where the detector has none).
    """

    level: np.ndarray
    slope: np.ndarray
    t_level: np.ndarray
    var: np.ndarray
    cusum: np.ndarray
    t_start: np.ndarray
    rise_cusum: np.ndarray
    rise_start: np.ndarray
    in_contact: np.ndarray
    direction: np.ndarray
    smooth: np.ndarray
    extreme: np.ndarray
    t_extreme: np.ndarray
    armed_at: np.ndarray
    t_last: np.ndarray
    slow: np.ndarray
    slow_start: np.ndarray
    recover_until: np.ndarray
    recover_dir: np.ndarray
    t_fell: np.ndarray
    ref_level: np.ndarray
    ref_t: np.ndarray
    ref_slope: np.ndarray
    medium: np.ndarray
    t_first: np.ndarray
    t_seated: np.ndarray
    settle_restarts: np.ndarray
    common_smooth: np.ndarray
    common_level: np.ndarray
    common: np.ndarray
    common_var: np.ndarray
    duty: np.ndarray
    duty_lag: np.ndarray
    duty_top: np.ndarray
    heater_fall: np.ndarray
    extreme_fall: np.ndarray
    fast: np.ndarray

    def copy(self) -> DetectorState:
        """Return a deep copy."""
        new = object.__new__(DetectorState)  # frozen: its fields set as `replace` would
        new.__dict__.update({name: value.copy() for name, value in self.__dict__.items()})
        return new


@dataclass(frozen=True)
class DetectorTrace:
    """What `OnsetDetector` saw at every sample of a chunk (`OnsetDetector.trace`).

    Attributes
    ----------
    times : numpy.ndarray, shape (n_samples,)
        Sample times, s.
    smooth : numpy.ndarray, shape (n_samples, n_taxels)
        The smoothed reading after each sample, deg C (NaN before a taxel's first reading).
    slope : numpy.ndarray, shape (n_samples, n_taxels)
        The baseline slope after each sample, K/s: the detector's smoothed derivative of the
        reading (free: time constant ``slope_tau``; in contact: ``contact_slope_tau``; held
        while a CUSUM gathers evidence of a contact or of its end, re-based at an onset and a
        release).
    events : list of OnsetEvent
        The events of the chunk, in time order (as `OnsetDetector.process` gives them).
    state : DetectorState
        State after the chunk.
    margins : numpy.ndarray or None
        With ``trace(..., margins=True)``, shape (n_samples, len(`MARGIN_TESTS`), n_taxels):
        each fall test's statistic over its threshold after each sample, on free, armed
        taxels (NaN elsewhere and before a taxel's first reading): an onset needs 1.
    """

    times: np.ndarray
    smooth: np.ndarray
    slope: np.ndarray
    events: list[OnsetEvent]
    state: DetectorState
    margins: np.ndarray | None = None


def _heater_step(duty: np.ndarray, s: DetectorState, gain: float) -> None:
    """Take one sample's heater duties into ``s``: the duty, its lag and the largest one.

    ``gain`` is the lag's per-sample gain (one sample period over the body's slowest mode).
    A taxel's first duty starts its lag as though the duty had just stepped down by the
    steepest step (`HEATER_STEP` of the duty before, ``duty / (1 - HEATER_STEP)``); the largest
    duty starts at the first. NaN (not known: a lost duty message) leaves all three as they
    were.
    """
    known = np.isfinite(duty)
    first = known & np.isnan(s.duty_lag)
    if np.count_nonzero(first):
        np.copyto(s.duty_lag, duty / (1.0 - HEATER_STEP), where=first)
        np.copyto(s.duty_top, duty, where=first)
    with np.errstate(invalid="ignore"):
        step = (duty - s.duty_lag) * gain
    np.add(s.duty_lag, step, out=s.duty_lag, where=known)
    np.copyto(s.duty, duty, where=known)
    np.fmax(s.duty_top, s.duty, out=s.duty_top)


def common_auto(sensor: object) -> bool:
    """Return whether the board common mode is on by default (``common_mode=None``) for ``sensor``.

    On where the heater is not PID-held (``sensor.heater != "pid"``: constant power, the
    gated form, robust to a board-wide gust or touch), off where it is (the loop form's
    median follows a touch of most of a board: opt-in). A board of fewer than `COMMON_MIN`
    taxels has none either way (`OnsetDetector.common_active`).

    Parameters
    ----------
    sensor : object
        A sensor description (`skin.models.sensors.load_sensor`'s) with a ``heater``.

    Returns
    -------
    bool
    """
    return getattr(sensor, "heater", None) != "pid"


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
        Least CUSUM allowance, deg C: departures from the baseline smaller than this (or than
        4 noise standard deviations, if larger) do not accumulate.
    threshold : float
        Alarm threshold of the falling CUSUM, deg C x samples.
    rise_threshold : float
        Alarm threshold of the rising CUSUM (warm objects), deg C x samples; ``inf`` turns
        rises off.
    noise_floor : float
        Lowest standard deviation assumed for the smoothed reading, deg C.
    noise_tau : float
        Time constant of the noise variance estimate, s.
    warmup : float, optional
        Time after the first sample (and after a release) before onsets are reported, s; a
        free taxel's CUSUMs do not accumulate before it. Default 0.5 s, stretched with the
        sensor's response time as the baseline's time constants are (its slope needs that
        long to catch the reading's trend).
    release_rise : float
        Return of the smoothed temperature from its in-contact extreme that marks a release
        (a rise above the minimum after a fall, a fall below the maximum after a rise), deg C.
    smooth_tau : float
        Time constant of the smoothing applied to the readings before detection, s.
    stale : float
        A CUSUM that stays above zero this long without an alarm is reset (slow drift), s.
    slow_tau : float
        Time constant of the slow channel's average, s. Contacts with poor conductors through
        an air gap fall too slowly for the CUSUM, whose baseline follows them; the slow channel
        compares the smoothed reading with a slow average of it instead. Until a taxel is
        armed (``warmup`` after its first reading, a hole, a release) the slow average is the
        reading averaged over ``slow_tau / 10`` itself: no fall is counted from a seed.
    slow_threshold : float
        Fall of the reading (averaged over ``slow_tau / 10``) below the slow average that is a
        contact, deg C (above what air currents and heater switching give within
        ``slow_tau``, and 8 noise sigmas of that average).
    slow_begin : float
        Fall below the slow average that dates a slow contact's coarse onset, deg C.
    recovery : float
        After a release, the slow average follows the recovering reading (up after a fall, down
        after a rise) for this long, s, so that the taxel's return to its free reading (a
        fall of kelvins after a warm object) is not taken for a slow contact.
    release_slack : float
        In contact, the baseline follows the reading's trend and the CUSUM of the other sign
        watches for the trend stopping short (the contact's end when the reading does not come
        back past its extreme: a warm touch on a taxel still reheating keeps rising after it);
        departures smaller than this times the trend's slope (s) do not accumulate, which
        covers the baseline's lag behind the decelerating in-contact trend. Not with a
        heater switched off at contact (``sensor.heater == "off-at-contact"``): its reading
        settles at the contact's temperature within the sensor's response, so a trend that
        stops is the contact going on; its end shows as the reheat (the return past
        ``release_rise``).
    contact_slope_tau : float
        Time constant of the baseline slope in contact, s.
    rebound : float
        A rise that begins within this long after the reading fell (the falling CUSUM above a
        tenth of its threshold) is the taxel reheating, after a gust or a touch too brief to be
        reported, and raises no onset, s.
    sensor : skin.models.sensors.SensorDescription, optional
        The taxels' sensor (default: the paper's): sets every threshold left as None and the
        noise (see the module docstring).
    sigma : float or array_like, optional
        Each taxel's reading noise per sample, K, as delivered (after any smoothing of the
        sensor's; commissioned from a quiet stretch); default: the sensor's.
    false_alarm_rate : float
        Target of noise-driven false alarms per taxel-hour (sets the CUSUM thresholds' floor).
    gust_envelope : bool
        Whether the gust-envelope test runs (see the module docstring): a fall, from where the
        baseline put the reading when it began, deeper than the deepest and fastest gust of
        ``gust_depth`` and ``gust_rise`` plus the steepest heater step (`HEATER_STEP` through
        the body's slowest mode; told the duty, the heater's own fall: `process`) can make in
        the time since, and ``envelope_sigmas`` noise
        sigmas more, is a contact (channel 2, with the slow channel). A PID-held heater's
        (``sensor.heater == "pid"``): those disturbances and the room's drift through its
        loop (`loop_envelope`), and the onset dated when raised.
    envelope_sigmas : float, optional
        The gust-envelope test's noise margin, in sigmas. With ``envelope_noise`` (the
        default): the ``z`` the noise table is scaled by (default the Gaussian quantile of
        ``false_alarm_rate`` per sample, 4.7-5.4; with a faster reading, ``envelope_tau``, of
        half of it: fast-film 5.55); the cap and the margin before the filters
        settle stay `FLAT_SIGMAS` (8) flat sigmas: where ``z`` x the table exceeds them the
        flat margin applies, so a larger ``z`` brings the margin closer to the flat one.
        Without it (default 8): sigmas of the reading it looks at (its running noise
        estimate or its smoothed readout noise, the larger). The drop it tests is measured
        from an extrapolated baseline, whose own noise this margin covers too: a flat margin
        at the Gaussian quantile (5.1-5.4) instead of 8 raised low-cost's noise-driven false
        alarms ten-fold (seed 0: 0.75 -> 7.75 per taxel-hour) while fast-film's delay /
        floor fell 1.99 -> 1.72 (`skin evaluate-onset --sensor P --seed 0 --flat-envelope
        --envelope-sigmas Z --json`).
    envelope_noise : bool
        Default True: the margin from the drop's own noise at the time since its reference
        (`drop_noise`: the readout noise through the smoothing and the baseline's
        extrapolation, in quadrature with what the running noise estimate finds beyond the
        readout's): smaller than 8 sigmas tens of ms after the reference, larger seconds
        after it; the smaller of the two is the margin, so it is never above the flat one.
        The table models settled filters: a reference taken within `SETTLE_TAUS`
        ``slope_tau`` of the baseline's seating or a break in its filters' run (the first
        sample, a hole of any length, a release: ``DetectorState.t_seated``) gets the flat
        margin (paper, 128 taxels of noise with a 0.1 s hole every 2 s, 60 s: the table applied
        right after each hole raised 2 envelope onsets more than the flat margin; with the
        wait, none).
        ``z`` counts one test a sample; the
        restarted test's crossings on the table's noise process are no more, within counting
        error (`skin bench envelope-rate --sensor P`; with the flat margin too, their union:
        no more on noise). False: the flat 8 sigmas alone (`skin evaluate-onset
        --flat-envelope`). Against it, on seeds 0, 2 (tuned on) and
        4, 6 (held out) of `skin evaluate-onset --sensor P` it lowers fast-film's delay /
        floor 1.97-1.99 -> 1.76-1.77 and paper's 1.34-1.36 -> 1.23-1.25, with no lower
        detection and no more false alarms on any preset; low-cost's and pid-logger's
        figures are unchanged but for pid-logger seed 6, where two more contacts are
        detected and the median delay / floor over the detected ones rises 2.201 -> 2.225.
    envelope_tau : float, optional
        The time constant of the gust-envelope test's second, faster reading, s: the same
        fall (from the same reference) read on the reading smoothed over ``envelope_tau``,
        against its own noise table (`drop_noise`'s ``fast_tau``) and flat margin (8 of its
        sigmas) at the same ``envelope_sigmas``; either reading's crossing is an onset. Only
        with ``envelope_noise`` and not on a loop-held sensor. Default: ``smooth_tau`` times
        the sensor's response time over the paper's, at least one sample, where that is at
        most half ``smooth_tau`` (fast-film: 2.9 ms against 30 ms); else none (``0``: none).
        The two readings share the false-alarm target: each one's ``z`` (unless
        ``envelope_sigmas`` is given) is the quantile of half of it per sample. On fast-film's
        held-out streams it lowers the median delay / floor 1.70-1.72 -> 1.53-1.54 with no
        lower detection (CHANGELOG); the union's crossings on noise are counted by `skin bench
        envelope-rate --sensor fast-film`.
    gust_depth : float, optional
        The air's deepest gust, K (default: `GUST_DEPTH` of the sensor's heated rise, the
        simulator's family, `skin.bench.streams`: not a measured figure of any real air).
    gust_rise : float
        The time constant the air's fastest gust approaches its depth with, s (default
        `GUST_RISE`, the simulator's fastest; a fan switched on can be faster). A loop-held
        board's common mode fits its CUSUM's allowance to these gusts (`_gust_allowance`).
    boards : array_like of int, optional
        Each taxel's board (default: all on one). The common mode is a board's.
    common_mode : bool, optional
        Whether a change shared by (nearly) every free taxel of a board is taken off their
        readings before anything else (active on boards of `COMMON_MIN` taxels or more only,
        `common_active`). None or "auto" (the default, `common_auto`): on for a sensor whose
        heater is not PID-held (the gated form below), off for a PID-held one (its loop
        form is opt-in: a touch of 12 of a board's 16 taxels gives the other 4 a false
        rise, one of all 16 is taken for the room). A PID-held heater's board
        (``sensor.heater == "pid"``, with the gust-envelope test) has its own
        (`_loop_common`): the loop high-passes the room into a band-limited noise that never
        moves (nearly) every taxel beyond its noise at once, so the gated form below
        switched on and off with it, a step in every reading of the board (pid-logger seed
        0: 1.25 false alarms per taxel-hour, three at one instant); there the median of the
        free taxels' departures is taken off on every sample, the envelope's room allowance
        scaled by what it leaves, and the CUSUM's allowance made to hold the family's gusts
        through the loop (`_gust_allowance`); it needs a board of `COMMON_MIN` taxels or
        more (with none, neither it nor the gust allowance is used). The room warming or
        cooling moves every heated taxel alike; a touch moves the taxels it covers; a skin
        warming up after power-on moves each taxel by its own distance from its steady
        state. Per board, each free taxel's departure (its reading averaged as the slow
        channel's) from its own level (followed with ``slow_tau``, the common mode taken
        off, and the room's change with `COMMON_FORGET` times ``slow_tau``), plus
        `COMMON_MARGIN` of that average's noise sigmas: when at least k of the board's n
        free taxels fell beyond their noise, k = ceil((1 - `COMMON_SHARE`) n) (`_shared`: 4
        of 4, 15 of 16), the k-th largest fall is the common mode (for a rise: the k-th
        largest rise less the margin), provided k of them (consecutive in size) lie within
        `COMMON_AGREE` noise sigmas of each other (one change, alike: a warm-up's rises are
        not, and are left on the readings); else 0, so that noise and a touch covering fewer
        than k of a board's free taxels leave the readings alone. Whenever the gate goes
        off the common mode is held, fading as the levels absorb it (`COMMON_FORGET`), and
        is 0 once within `COMMON_SNAP` of the margin: one that went off as the departures
        fell into their noise is near 0 already; one that ends abruptly (a second touch while
        the room moves) makes no step. Nor does one begin or change with a step: a new value
        more than the margin from the board's last one (a board-wide gust whose phases came
        to agree deep, taxels rejoining together after a touch) is no room, and the board
        holds; nor is a change that left a free taxel within its noise (a touch of k of n;
        a taxel whose reading never varies, stuck, counts for nothing). A taxel read again
        after a hole rejoins at its board's common mode. A touch of every taxel at once is
        still taken for the room until its onsets are raised (paper, 16 of 16: raised 50 ms
        later than without the common mode). In the loop form a free taxel more than
        `COMMON_AGREE` sigmas of ``common_var`` from the last common mode is no part of the
        median; the median has no cap (a real room steps through the loop as far as a
        touch): a touch of 12 of 16 still gives the other 4 a false rise, one of 16 of 16 is
        taken for the room. A board with fewer than `COMMON_MIN` free
        taxels takes no new common mode: one that had one (its taxels touched) holds it,
        fading, in either form; a board of fewer than `COMMON_MIN` taxels never has one.

    Every kelvin threshold left as None follows from ``sigma`` and the sensor; the figures in
    the descriptions above are the paper sensor's.
    """

    #: The attributes holding one value per taxel (those present): `skin.stream.shards`
    #: slices these, and only these, for a shard. Other arrays (the noise table
    #: ``_drop_sd``, indexed by time since the reference) are shared, whatever their length.
    PER_TAXEL = ("sigma", "drift", "noise_floor", "noise_threshold", "smoothed_sigma",
                 "_resid_sigma", "_resid_fast", "threshold", "rise_threshold", "end_threshold",
                 "end_rise_threshold", "release_rise",
                 "slow_threshold", "slow_begin", "_common_margin", "board")

    def __init__(
        self,
        n_taxels: int,
        *,
        level_tau: float = 0.1,
        slope_tau: float | None = None,
        drift: float | np.ndarray | None = None,
        threshold: float | np.ndarray | None = None,
        rise_threshold: float | np.ndarray | None = None,
        noise_floor: float | np.ndarray | None = None,
        noise_tau: float = 5.0,
        warmup: float | None = None,
        release_rise: float | np.ndarray | None = None,
        smooth_tau: float | None = None,
        stale: float | None = None,
        slow_tau: float | None = None,
        slow_threshold: float | np.ndarray | None = None,
        slow_begin: float | np.ndarray | None = None,
        recovery: float = 10.0,
        release_slack: float = 0.05,
        contact_slope_tau: float | None = None,
        rebound: float | None = None,
        sensor: object | None = None,
        sigma: float | np.ndarray | None = None,
        false_alarm_rate: float = 0.1,
        gust_envelope: bool = True,
        envelope_sigmas: float | None = None,
        envelope_noise: bool = True,
        envelope_tau: float | None = None,
        gust_depth: float | None = None,
        gust_rise: float = GUST_RISE,
        boards: np.ndarray | None = None,
        common_mode: bool | str | None = None,
    ) -> None:
        from skin.models.sensors import load_sensor

        self.n_taxels = n_taxels
        self.sensor = sensor = load_sensor(sensor)
        self.false_alarm_rate = false_alarm_rate
        fs = sensor.sample_rate
        rise = sensor.heated_rise
        shrink = sensor.smoothing_noise_factor()  # what the sensor's own smoothing removed
        if sigma is None:
            sigma = sensor.noise_kelvin(25.0 + rise) * shrink
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (n_taxels,)).copy()
        if not np.all(np.isfinite(self.sigma) & (self.sigma > 0)):
            raise ValueError("sigma must be positive and finite for every taxel")
        stretch = max(1.0, sensor.response_time / _PAPER_RESPONSE)  # a slower sensor
        if smooth_tau is not None and not smooth_tau > 0.0:
            raise ValueError(f"smooth_tau must be > 0 s, got {smooth_tau}")
        if envelope_tau is not None and not envelope_tau >= 0.0:
            raise ValueError(f"envelope_tau must be >= 0 s (0: no faster reading), "
                             f"got {envelope_tau}")
        if envelope_sigmas is not None and not envelope_sigmas > 0.0:
            raise ValueError(f"envelope_sigmas must be > 0, got {envelope_sigmas}")
        if not 0.0 < false_alarm_rate < fs * 3600.0:
            raise ValueError(f"false_alarm_rate must be > 0 and below one a sample "
                             f"({fs * 3600.0:g}) per taxel-hour, got {false_alarm_rate}")
        for name, value in (("threshold", threshold), ("rise_threshold", rise_threshold),
                            ("slow_threshold", slow_threshold)):
            given = None if value is None else np.asarray(value, dtype=float)
            if given is not None and not np.all(given > 0.0):  # NaN fails; inf switches off
                raise ValueError(f"{name} must be positive for every taxel (a CUSUM threshold "
                                 f"of 0 alarms on every sample; inf switches the test off), "
                                 f"got {value}")
        self.smooth_tau = max(0.03, 1.0 / fs) if smooth_tau is None else smooth_tau
        g = 1.0 - math.exp(-1.0 / (fs * self.smooth_tau))
        smoothed = self.sigma * math.sqrt(g / (2.0 - g))  # the smoothed reading's noise
        white = self.sigma / shrink  # the noise of sums over many samples
        per_sample = fs / 200.0  # CUSUM thresholds add up per sample
        self.level_tau = level_tau
        self.slope_tau = 0.5 * stretch if slope_tau is None else slope_tau
        # in units of the smoothed noise: the paper sensor's former 0.03 and 0.003 K
        ratio = smoothed / _paper_smoothed()
        self.drift = 0.03 * ratio if drift is None else drift
        self.noise_floor = 0.003 * ratio if noise_floor is None else noise_floor
        # against noise: the ARL threshold for the target rate, with the allowance at 4 sigma of
        # the smoothed reading (the CUSUM subtracts 3.3: see the module docstring), in units
        # of the raw sigma
        arl = fs * 3600.0 / max(false_alarm_rate, 1e-12)
        self.noise_threshold = white * arl_threshold(arl, 4.0 * smoothed / white)

        # a sensor body faster than the paper's carries heater steps and drift to the thermistor
        # faster: they bend the baseline's trend more within the CUSUM's and the slow channel's
        # windows (a PID loop holds its setpoint: no heater steps)
        mode = 62.5 * sensor.reheat_time_constant / _PAPER_MODE  # the slowest mode, s
        quick = 1.0 if sensor.heater == "pid" else max(1.0, 62.5 / mode)
        slow_tau_now = 3.0 * stretch if slow_tau is None else slow_tau
        slow_quick = 1.0 if quick == 1.0 else max(
            1.0, -math.expm1(-slow_tau_now / mode) / -math.expm1(-slow_tau_now / 62.5))

        def scaled(value: object, key: str, cusum: bool) -> np.ndarray | float:
            if value is not None:
                return value
            fast = quick if cusum else (slow_quick if key == "slow_threshold" else 1.0)
            floor = DISTURBANCE[key] * rise * fast * (per_sample if cusum else 1.0)
            # levels compared within the smoothed reading stay 8 of its sigmas clear of noise
            # (the slow channel's within its own average of the reading)
            level = slow_sigma if key.startswith("slow") else smoothed
            return np.maximum(floor, self.noise_threshold if cusum else 8.0 * level)

        # what the readout noise is after the detector's averages, from the sensor's own
        # smoothing on (a smoothed reading's noise is correlated: averaging it removes less)
        self.smoothed_sigma = self.sigma * average_noise(sensor, self.smooth_tau)
        # the slow channel averages its reading over a tenth of its window where the noise,
        # not the disturbances, would set its threshold (a noisy, already smoothed reading);
        # elsewhere it looks at the smoothed reading, as the CUSUM does
        self.medium_tau = 0.1 * slow_tau_now
        slow_floor = DISTURBANCE["slow_threshold"] * rise * slow_quick
        if 8.0 * float(np.max(self.smoothed_sigma)) <= slow_floor:
            self.medium_tau = self.smooth_tau
        slow_sigma = self.sigma * average_noise(sensor, self.medium_tau)
        # the gust-envelope test: the deepest, fastest gust and the steepest heater step
        if gust_rise <= 0.0 or (gust_depth is not None and not gust_depth > 0.0):
            raise ValueError(f"gust_depth ({gust_depth}) and gust_rise ({gust_rise}) must be > 0")
        self.gust_rise = float(gust_rise)
        self.gust_depth = ((GUST_DEPTH * rise if gust_depth is None else float(gust_depth))
                           if gust_envelope else np.inf)
        # the margin: flat, 8 sigmas of the reading; or (``envelope_noise``) z sigmas of the
        # fall's own noise at the time since the reference (`drop_noise`), z the Gaussian
        # quantile of the false-alarm target per sample unless given
        self.envelope_noise = bool(envelope_noise)
        z_given = envelope_sigmas is not None
        if envelope_sigmas is None:
            from statistics import NormalDist

            rate = false_alarm_rate / (fs * 3600.0)  # per sample
            envelope_sigmas = (NormalDist().inv_cdf(1.0 - rate) if envelope_noise
                               else FLAT_SIGMAS)
        if not envelope_sigmas > 0.0:
            raise ValueError(f"envelope_sigmas ({envelope_sigmas}) must be > 0")
        self.envelope_sigmas = float(envelope_sigmas)
        if self.envelope_noise:
            step, sd, resid = drop_noise(sensor, self.smooth_tau, self.level_tau,
                                         self.slope_tau, slow_tau_now)
            self._drop_step, self._drop_sd = step, sd
            self._resid_sigma = self.sigma * resid  # the residual's noise, nominal
            # the table models settled filters: a reference taken sooner than SETTLE_TAUS
            # slope_tau after the baseline was seated (a taxel's first sample, a hole, a
            # release) carries the start-up transient (the trend the baseline is still
            # catching, not noise): such a drop gets the flat margin only
            self._settle = SETTLE_TAUS * self.slope_tau
        # a sample missing (a gap over 1.5 sample periods of the sensor's nominal rate, not
        # the stream's measured one) is a hole for the settle clock: a stream whose timestamps
        # jitter past that restarts the clock at each such gap and keeps the flat margin
        # (counted per taxel in ``DetectorState.settle_restarts``)
        self._hole = 1.5 / fs
        self.heater_rate = HEATER_STEP * rise / mode
        # with the duty given: the heater's excess settles through the body's slowest mode,
        # falling at ``rise / mode`` times the duty's lag over the duty, in units of the
        # largest duty (`_heater_step`)
        self.heater_mode = mode
        self._duty_gain = -math.expm1(-1.0 / (fs * mode))
        self._heater_fall_rate = rise / mode  # K/s per unit of the lag's excess (of duty_top)
        # a loop-held sensor's: the disturbances as its reading shows them, through the loop
        # (`loop_envelope`). The closed form above over-allowed a heater step there (0.86 K
        # over the slow window for at most 0.10 K) and a gust (0.29 K for 0.12 K), and under-
        # allowed the room's drift the loop passes: on pid-logger's streams, seeds 0/2/4/6,
        # detected_5sigma .22/.19/.20/.23 -> .28/.24/.23/.29, false alarms unchanged (without
        # the room's term: .41 on seed 0, but 3 false alarms, each a 2.4-3.2 sd fall of it)
        self.envelope = (loop_envelope(sensor, slow_tau_now, float(self.gust_depth), mode,
                                       false_alarm_rate, self.gust_rise)
                         if gust_envelope and sensor.heater == "pid" else None)
        # the faster reading's test (``envelope_tau``): a sensor faster than the paper's
        # has the smoothing shortened with its response time, at least one sample; one
        # not under half the smoothing's adds a test and no speed, and is left out. It reads
        # the noise table's envelope test: none without it, nor on a loop-held sensor
        self.envelope_tau = None
        table_test = gust_envelope and self.envelope_noise and self.envelope is None
        if envelope_tau is None:
            envelope_tau = max(1.0 / fs, self.smooth_tau * min(
                1.0, sensor.response_time / _PAPER_RESPONSE))
            if not (envelope_tau <= 0.5 * self.smooth_tau and table_test):
                envelope_tau = 0.0
        elif envelope_tau > 0.0 and not table_test:
            raise ValueError(f"envelope_tau ({envelope_tau} s) needs the gust-envelope test with "
                             f"its noise table (gust_envelope and envelope_noise) on a sensor "
                             f"whose heater is not PID-held ({sensor.name}: {sensor.heater})")
        if envelope_tau > 0.0:
            self.envelope_tau = float(envelope_tau)
            _, self._fast_sd, fast = drop_noise(sensor, self.smooth_tau, self.level_tau,
                                                self.slope_tau, slow_tau_now,
                                                self.envelope_tau)
            self._resid_fast = self.sigma * fast
            if not z_given:
                # two tests a sample share the target: each reading's z is the quantile of
                # half of it per sample (fast-film: 5.55 for 5.43; without the split, on its
                # held-out 16 taxel-hours, 2 false alarms where there had been none)
                from statistics import NormalDist

                self.envelope_sigmas = NormalDist().inv_cdf(
                    1.0 - false_alarm_rate / (2.0 * fs * 3600.0))
            # its flat margin: 8 of the faster reading's sigmas, not the smoothed one's
            self._fast_flat = average_noise(sensor, self.envelope_tau) / average_noise(
                sensor, self.smooth_tau)
        self.threshold = scaled(threshold, "threshold", True)
        self.rise_threshold = scaled(rise_threshold, "rise_threshold", True)
        self.release_rise = scaled(release_rise, "release_rise", False)
        self.slow_threshold = scaled(slow_threshold, "slow_threshold", False)
        self.slow_begin = scaled(slow_begin, "slow_begin", False)
        # in contact the CUSUM of the other sign watches for the contact's end (a departure
        # stopping short): no easier for noise to trip than the release by return
        # (``release_rise``), `END_SIGMAS` of the raw reading's noise per sample at the least.
        # At the presets' own rates the disturbance floors lie above it (paper 200 Hz: 0.4 /
        # 0.6 K x samples against 0.25; low-cost 20 Hz: 0.92 against 0.73); at 20 Hz the
        # one-sample smoothing averages nothing and the paper's floor (0.06) lay below one
        # sample's noise, so one noisy sample stopped the baseline and its extrapolated,
        # decelerating trend made a release within the contact. The raw sigma, not the
        # smoothed one: a slow fall read through the ADC is a staircase whose rounding error
        # is correlated from sample to sample (not the white noise the smoothing's average
        # assumes), and a one-count reversal (0.055-0.065 K) passed 8 smoothed sigmas' follow gate
        # (0.043) - a copper contact released at 2.95 s during a steady -1.3 K/s fall
        end_floor = END_SIGMAS * self.sigma
        self.end_threshold = np.maximum(self.threshold, end_floor)
        self.end_rise_threshold = np.maximum(self.rise_threshold, end_floor)
        # the in-contact trend at an onset: where the smoothing spans under two samples (below
        # about 67 Hz for the paper's 0.03 s) the reading's change over the last level_tau +
        # smooth_tau (0.13 s at 50 Hz, 0.15 at 20), the baseline's prediction standing in for
        # the reading before the CUSUM left zero - the trend of the one or two samples the
        # CUSUM gathered over carries the noise of the sample that raised the alarm. Above,
        # the trend over the span the CUSUM gathered over (at 200 Hz, 35 ms median; 1e-3 s
        # only guards a zero span): a longer span there delayed the releases of paper seed 2
        # by 5 ms to 10 s. The rule steps at the switch (a sample-count criterion)
        self.onset_span = (self.level_tau + self.smooth_tau if self.smooth_tau * fs < 2.0
                           else 1e-3)  # > 1e-3 only where the span is taken (see `process`)
        self.noise_tau = noise_tau
        self.warmup = 0.5 * stretch if warmup is None else warmup
        self.stale = 1.0 * stretch if stale is None else stale
        self.slow_tau = 3.0 * stretch if slow_tau is None else slow_tau
        self.recovery = recovery
        self.release_slack = release_slack
        # a heater switched off at contact: the reading settles in contact, ends show as reheat
        self.ends_when_stopped = sensor.heater != "off-at-contact"
        self.contact_slope_tau = 0.2 * stretch if contact_slope_tau is None else contact_slope_tau
        self.rebound = 1.0 * stretch if rebound is None else rebound
        # a loop-held sensor has no trend of its own: its noise estimate starts as a running
        # mean (see `_step`)
        self.running_start = sensor.heater == "pid"
        # the common mode looks at the slow channel's reading (averaged over a tenth of its
        # window): the same 0.6 K room fall, a tighter margin (low-cost seed 0: 3 false alarms
        # -> 1 against 3 -> 3 on the smoothed reading with its own margin)
        self._common_margin = COMMON_MARGIN * np.broadcast_to(slow_sigma, (n_taxels,))
        self.board = (np.zeros(n_taxels, dtype=np.int64) if boards is None
                      else np.asarray(boards, dtype=np.int64).reshape(n_taxels).copy())
        # read-only: `_groups` caches the board table for this array (an in-place edit would
        # leave it stale); another wiring is another array (``detector.board = ...``)
        self.board.flags.writeable = False
        # None ("auto"): on where the heater is not PID-held (the gated form, `common_auto`)
        if not (common_mode is None or common_mode == "auto" or isinstance(common_mode, bool)):
            raise TypeError(f"common_mode: True, False, None or \"auto\", got {common_mode!r}")
        self.common_mode = (common_auto(sensor) if common_mode is None or common_mode == "auto"
                            else common_mode)
        # `_groups`' cache: the board array and margins it was built for and its tables
        # (None: not built)
        self._groups_of: tuple[np.ndarray, np.ndarray, _Boards | None] | None = None
        # a loop-held board's common mode (`_loop_common`): the median of its free taxels'
        # departures, always taken off; the envelope's room allowance then scaled by what it
        # leaves (``common_var``) against the room's own variance through the loop
        # (none when no board has `COMMON_MIN` taxels: then neither is the gust allowance)
        self.loop_common = bool(self.common_mode and self.envelope is not None
                                and self._groups() is not None)
        self._room_var = (_room_variance(sensor, self.medium_tau, self.slow_tau)
                          if self.envelope is not None else 0.0)
        self._gust_k = (_gust_allowance(sensor, float(self.gust_depth), self.smooth_tau,
                                        self.level_tau, self.slope_tau,
                                        float(np.min(self.threshold)),
                                        float(np.min(self.rise_threshold)), self.gust_rise)
                        if self.loop_common else 0.0)

    def initial_state(self) -> DetectorState:
        """Return the state before the first sample."""
        n = self.n_taxels
        nan = np.full(n, np.nan)
        return DetectorState(
            level=nan.copy(),
            slope=np.zeros(n),
            t_level=nan.copy(),
            var=np.broadcast_to(np.asarray(self.noise_floor, dtype=float) ** 2, (n,)).copy(),
            cusum=np.zeros(n),
            t_start=nan.copy(),
            rise_cusum=np.zeros(n),
            rise_start=nan.copy(),
            in_contact=np.zeros(n, dtype=bool),
            direction=np.zeros(n),
            smooth=nan.copy(),
            extreme=nan.copy(),
            t_extreme=nan.copy(),
            armed_at=np.full(n, np.inf),
            t_last=nan.copy(),
            slow=nan.copy(),
            slow_start=nan.copy(),
            recover_until=np.full(n, -np.inf),
            recover_dir=np.zeros(n),
            t_fell=np.full(n, -np.inf),
            ref_level=nan.copy(),
            ref_t=nan.copy(),
            ref_slope=np.zeros(n),
            medium=nan.copy(),
            t_first=nan.copy(),
            t_seated=nan.copy(),
            settle_restarts=np.zeros(n, dtype=np.int64),
            common_smooth=nan.copy(),
            common_level=nan.copy(),
            common=np.zeros(n),
            common_var=np.full(n, self._room_var),
            duty=nan.copy(),
            duty_lag=nan.copy(),
            duty_top=nan.copy(),
            heater_fall=np.zeros(n),
            extreme_fall=np.zeros(n),
            fast=nan.copy(),
        )

    def process(
        self, times: np.ndarray, temperature: np.ndarray, state: DetectorState,
        in_place: bool = False, duty: np.ndarray | None = None,
    ) -> tuple[list[OnsetEvent], DetectorState]:
        """Run the detector over a chunk of samples.

        Parameters
        ----------
        times : numpy.ndarray, shape (n_samples,)
            Sample times, s, increasing.
        temperature : numpy.ndarray, shape (n_samples, n_taxels)
            Temperatures, deg C; NaN marks a missing or flagged sample, which is skipped.
        state : DetectorState
            State after the previous chunk (`initial_state` for the first); not modified,
            unless ``in_place``.
        in_place : bool
            Update ``state`` itself and return it (no copy): for a caller that hands its state
            over, as a live pipeline does on every sample (the copy of its 31 arrays was a
            tenth of the detector's time there).
        duty : numpy.ndarray, shape (n_samples, n_taxels), optional
            Each taxel's heater duty at each sample (any unit; NaN: not known), as the frames
            carry it. Given, a fall is allowed the heater's own fall only where the taxel's
            duty lies below its lag through the body's slowest mode (``duty_lag``): at
            ``heated_rise / heater_mode`` times the lag's excess over the duty in units of
            the largest duty given (``duty_top``, taken as the heated rise's), so a taxel
            whose heater held its duty has no heater fall to fear, one that stepped down a
            minute ago a fading one, one switched off long ago none; a taxel's first duty
            is taken as the steepest step down just then. The lag steps once a sample, at
            the sensor's nominal rate (a hole in the samples does not advance it). A NaN
            duty after a known one keeps the last (a lost duty message); none known yet (or
            ``duty`` not given): every fall is allowed the steepest step's
            (``heater_rate``). In contact, the same rate, signed, is the heater's own change
            (``DetectorState.heater_fall``), put back before the contact's extreme and its
            return are judged: a brief touch after a step down is released when the object
            leaves, not held while the heater goes on cooling the reading. A loop-held heater
            (``sensor.heater == "pid"``) has no such allowance (its loop envelope holds its
            steps): there it is not used. The pipeline passes the frames' duty;
            ``skin evaluate-onset`` a simulated stream's (``--no-duty``: none). On those
            streams it finds 1-3 points more of the 5-sigma contacts on paper and fast-film,
            with no more false alarms (the CHANGELOG gives the figures).

        Returns
        -------
        events : list of OnsetEvent
            In time order.
        state : DetectorState
            State after this chunk.
        """
        s = state if in_place else state.copy()
        events: list[OnsetEvent] = []
        temperature = np.asarray(temperature, dtype=float).reshape(len(times), self.n_taxels)
        groups = self._groups()
        taus = self._taus(groups)
        work = _scratch(self.n_taxels)
        limits = self._limits()
        if duty is None or self.envelope is not None:  # a loop-held heater's: not used
            for t, y in zip(np.asarray(times, dtype=float).tolist(), temperature, strict=True):
                self._step(t, y, s, events, taus, groups, work=work, limits=limits)
            return events, s
        duty = np.asarray(duty, dtype=float).reshape(len(times), self.n_taxels)
        for t, y, d in zip(np.asarray(times, dtype=float).tolist(), temperature, duty,
                           strict=True):
            _heater_step(d, s, self._duty_gain)
            self._step(t, y, s, events, taus, groups, work=work, limits=limits, duty=True)
        return events, s

    def trace(
        self, times: np.ndarray, temperature: np.ndarray, state: DetectorState | None = None,
        margins: bool = False, duty: np.ndarray | None = None,
    ) -> DetectorTrace:
        """Run the detector over a chunk and keep its smoothed reading and slope per sample.

        The events and the final state are those of `process`; this costs a copy of two
        arrays per sample more, for plots and diagnosis (with ``margins``, each fall test's
        statistic over its threshold too: `DetectorTrace.margins`).

        Parameters
        ----------
        times : numpy.ndarray, shape (n_samples,)
            Sample times, s, increasing.
        temperature : numpy.ndarray, shape (n_samples, n_taxels)
            Temperatures, deg C; NaN marks a missing sample.
        state : DetectorState, optional
            State after the previous chunk (default: `initial_state`); not modified.
        margins : bool
            Keep each fall test's statistic over its threshold per sample.
        duty : numpy.ndarray, shape (n_samples, n_taxels), optional
            Each taxel's heater duty at each sample (`process`'s ``duty``).

        Returns
        -------
        DetectorTrace
            Per-sample smoothed reading and slope, the events and the state after the chunk.
        """
        s = (self.initial_state() if state is None else state).copy()
        times = np.asarray(times, dtype=float)
        temperature = np.asarray(temperature, dtype=float).reshape(len(times), self.n_taxels)
        smooth = np.empty_like(temperature)
        slope = np.empty_like(temperature)
        events: list[OnsetEvent] = []
        groups = self._groups()
        taus = self._taus(groups)
        kept = (np.full((len(times), len(MARGIN_TESTS), self.n_taxels), np.nan) if margins
                else None)
        row: list | None = [] if margins else None
        work = _scratch(self.n_taxels)
        limits = self._limits()
        if self.envelope is not None:  # a loop-held heater's: not used (as in `process`)
            duty = None
        if duty is not None:
            duty = np.asarray(duty, dtype=float).reshape(len(times), self.n_taxels)
        for i, (t, y) in enumerate(zip(times.tolist(), temperature, strict=True)):
            if duty is not None:
                _heater_step(duty[i], s, self._duty_gain)
            self._step(t, y, s, events, taus, groups, row, work, limits, duty is not None)
            smooth[i] = s.smooth
            slope[i] = s.slope
            if row:
                kept[i] = row.pop()
        return DetectorTrace(times, smooth, slope, events, s, kept)

    def _taus(self, groups: _Boards | None) -> np.ndarray:
        """Return the smoothing time constants of `_step`'s gains, a row each.

        Smooth, slow, level, slope (free, in contact), noise, medium, with a common mode
        (``groups``) how fast the room's change is forgotten, and last the envelope test's
        faster reading's (``envelope_tau``, where it has one). Kept while they stay the same
        (`process` asks at every call).
        """
        taus = (self.smooth_tau, self.slow_tau, self.level_tau, self.slope_tau,
                self.contact_slope_tau, self.noise_tau, self.medium_tau)
        if groups is not None:
            taus += (COMMON_FORGET * self.slow_tau,)
        if self.envelope_tau is not None:
            taus += (self.envelope_tau,)
        cached = getattr(self, "_taus_of", None)
        if cached is None or cached[0] != taus:
            cached = self._taus_of = (taus, np.array(taus)[:, None])
        return cached[1]

    def _limits(self) -> tuple[np.ndarray | float, ...]:
        """Return the CUSUM's derived limits, kept while their sources stay the same objects.

        ``threshold / 10`` (a fall begun: no rebound), ``threshold / 4``, ``rise_threshold /
        4``, ``end_threshold / 4`` and ``end_rise_threshold / 4`` (the baseline still
        follows), ``noise_floor**2`` and ``_resid_sigma**2`` (the envelope's readout noise).
        """
        sources = (self.threshold, self.rise_threshold, self.end_threshold,
                   self.end_rise_threshold, self.noise_floor,
                   getattr(self, "_resid_sigma", None))
        ids = tuple(map(id, sources))
        cached = getattr(self, "_limits_of", None)
        if cached is None or cached[0] != ids:
            th, rise, end, end_rise, floor, resid = sources
            # (the sources kept with their ids: no id is reused while they are cached)
            cached = self._limits_of = (ids, (
                th / 10, th / 4, rise / 4, end / 4, end_rise / 4, floor**2,
                None if resid is None else resid**2), sources)
        return cached[1]

    @property
    def common_active(self) -> bool:
        """Whether a board common mode runs: ``common_mode`` and a board of `COMMON_MIN`."""
        return self._groups() is not None

    def _groups(self) -> _Boards | None:
        """Return the boards' tables (`_Boards`: ``table`` and ``row`` first).

        None when the common mode is off or no board has `COMMON_MIN` taxels.
        """
        if not self.common_mode:
            return None
        # built once per board array (`process` asks at every call: a live skin's call is a
        # sample or a few); a shard's detector (`skin.stream.shards.sub_detector`) has its own
        cached = self._groups_of
        if (cached is not None and cached[0] is self.board
                and cached[1] is self._common_margin):
            return cached[2]
        ids, row, counts = np.unique(self.board, return_inverse=True, return_counts=True)
        groups = None
        if counts.max(initial=0) >= COMMON_MIN:
            order = np.argsort(row, kind="stable")
            table = np.full((ids.size, int(counts.max())), self.n_taxels, dtype=np.int64)
            start = np.concatenate([[0], np.cumsum(counts)[:-1]])
            col = np.arange(self.n_taxels) - np.repeat(start, counts)
            table[row[order], col] = order
            margin = self._common_margin
            groups = _Boards(
                table, row,
                None if np.array_equal(order, np.arange(self.n_taxels)) else order,
                start.astype(np.intp), _shared(np.arange(table.shape[1] + 1)),
                np.append(margin / COMMON_MARGIN, 0.0)[table].max(axis=1), -margin,
                (_STILL * margin)**2,
                np.arange(table.size).reshape(table.shape) + np.arange(ids.size)[:, None]
                * table.shape[1])
        self._groups_of = (self.board, self._common_margin, groups)
        return groups

    @staticmethod
    def _per_board(mask: np.ndarray, groups: _Boards) -> np.ndarray:
        """Return how many taxels of each board ``mask`` holds (integers; the last axis)."""
        if groups.order is not None:
            mask = mask[..., groups.order]
        return np.add.reduceat(mask, groups.starts, axis=-1)

    @staticmethod
    def _padded(values: np.ndarray, keep: np.ndarray, table: np.ndarray,
                work: _Scratch) -> np.ndarray:
        """Return each board's ``values`` of its ``keep`` taxels, sorted, a row each, NaN last.

        (``np.append(np.where(keep, values, np.nan), np.nan)[table]``, sorted: the same
        values, through ``work.ext``, whose last slot, the padding's, stays NaN.)
        """
        ext = work.ext[:-1]
        np.copyto(ext, values)
        np.copyto(ext, np.nan, where=~keep)
        out = work.ext.take(table)
        out.sort(axis=1)
        return out

    def _common(self, t: float, y: np.ndarray, s: DetectorState, live: np.ndarray,
                gain: np.ndarray, groups: _Boards, work: _Scratch) -> np.ndarray:
        """Return the readings with their board's common mode taken off (``common_mode``)."""
        table, row = groups.table, groups.row
        # a taxel read again after a hole: its ``common`` is what its board held before the
        # hole; it rejoins at the board's value now, its level re-seated to it (else its stale
        # 0 against a board holding the room's -0.18 K kept the board's no-step test failing:
        # the board held for ever, low-cost, a 5 s hole on one taxel, 16 false onsets)
        self._rejoin(t, y, s, live, groups, work)
        if self.loop_common:
            return self._loop_common(t, y, s, live, gain, table, row)
        # (the gated form's ``common_var``: the mean square of each reading's step from its
        # smoothed one, over the level's time constant; 0 for a taxel that never varies)
        # (``var + ((y - smooth)**2 - var) * gain[1]``, then ``smooth + (y - smooth) *
        # gain[6]``: one step ``y - smooth`` for both)
        step = np.subtract(y, s.common_smooth, out=work.tmp)
        square = np.square(step, out=work.part)
        square -= s.common_var
        square *= gain[1]
        np.add(s.common_var, square, out=s.common_var, where=live)
        step *= gain[6]
        np.add(s.common_smooth, step, out=s.common_smooth, where=live)
        part = np.subtract(s.common_smooth, s.common_level, out=work.part)
        # beyond the noise: a board's noise alone (all its taxels a little low at once) is
        # taken for nothing, and the common mode stays continuous as it leaves 0. A departure
        # beyond the margin, ``part + margin < 0`` (``part - margin > 0``), is counted as
        # ``part < -margin`` (``part > margin``): the same test (a sum of two doubles has the
        # sign of the exact sum), without the shifted arrays a quiet skin never needs
        margin = self._common_margin
        # a taxel in contact, or recovering from one, is no free taxel: one that rejoined at
        # its release, far from its level, switched a room's rise off at once (paper seed 4:
        # 12 taxels' rise alarms)
        use = live & ~s.in_contact & (t >= s.recover_until)
        # the quantiles can leave 0 only when nearly every free taxel moved the same way:
        # counted first (a free board's departures are noise, half each way), sorted only
        # then; a quiet skin stops at the count (`skin bench pipeline --compare-common-mode`)
        if table.shape[0] == 1:
            free = np.count_nonzero(use)
            count = np.array([free])
            moved = np.zeros(1, dtype=bool)
            if free >= COMMON_MIN:
                need = int(groups.need[free])
                moved[0] = (np.count_nonzero(use & (part < groups.low)) >= need
                            or np.count_nonzero(use & (part > margin)) >= need)
        else:
            # each board's free taxels, and those below (above) 0: a common fall (rise) needs
            # at least `_shared` of them
            flags = work.flags
            np.copyto(flags[0], use)
            np.less(part, groups.low, out=flags[1])
            np.greater(part, margin, out=flags[2])
            flags[1:] &= use
            count, down, up = self._per_board(flags, groups)
            need = groups.need[count]
            moved = (count >= COMMON_MIN) & ((down >= need) | (up >= need))
        if np.count_nonzero(moved):
            # ... and moved every free taxel: the room moves each heated taxel of a board, so
            # a change that left a free taxel within its noise of its level is a touch of the
            # others (15 of 16 taxels under one block: taken for the room until they were
            # raised, the common mode held 0.18 K deep gave the free one a false rise, paper)
            # (a taxel whose reading does not vary at all, stuck or constant, is no heated
            # taxel the room could move: never counted, else it vetoed the board's common mode
            # for ever; low-cost, a 0.6 K fall with one taxel constant: 15 false onsets)
            flat = use & (np.abs(part, out=work.tmp) <= margin) & (s.common_var > groups.still)
            if np.count_nonzero(flat):
                if table.shape[0] == 1:
                    moved[0] = False
                else:
                    moved &= self._per_board(flat, groups) == 0
        if np.count_nonzero(moved):
            # ... by the same amount (`COMMON_AGREE`): a warm-up's rises, each taxel's own, are
            # no room (the default scene with it on: 373 -> 232 of 450 touches named right
            # without this, seeds 0-29)
            moved &= self._agree(part, use, groups, count, work)
        if not np.count_nonzero(moved) and not np.count_nonzero(s.common):
            # a quiet skin: no board's common mode, before nor now (no held mode, no terms of
            # the room's change)
            self._follow_level(s, live, gain, 0.0, work.tmp, part)
            return y
        # a board whose gate is off, whatever the reason, holds its last common mode, fading
        # as each taxel's level absorbs it (`COMMON_FORGET` ``slow_tau``), 0 once within
        # `COMMON_SNAP` of the margin. One that faded into its noise is near 0 already; one
        # that ended abruptly (a second touch while the room moves: too few free taxels left
        # moving alike) would otherwise drop to 0: a step of the room's change in every
        # reading, which hid a slow touch under way (low-cost seed 8, taxel 6 at 648 s: a
        # 0.16 K room rise dropped)
        held = s.common * (1.0 - gain[7])
        held[np.abs(held) < COMMON_SNAP * margin] = 0.0
        if np.count_nonzero(moved):
            common = self._board_common(part + margin, part - margin, use, groups, count, work)
            # ... and never steps: the room moves a board's readings by far less than their
            # noise from one sample to the next, so a common mode more than its margin from
            # the board's last one is no room (the gate passing with the departures already
            # deep: a board-wide gust whose phases came to agree 0.14 K down, paper; taxels
            # rejoining the free set together, reheating alike after a touch of the whole
            # board). Such a board holds, as when its gate is off, until its departures come
            # back within a margin of what it holds (its levels absorb them within
            # ``slow_tau``); a common mode that follows the room stays continuous
            # (one value per board: each taxel's own may have faded by its own gap)
            last = self._board_value(s.common, live, groups, work)
            far = live & (np.abs(common - last) > margin)
            if np.count_nonzero(far):
                if table.shape[0] == 1:
                    moved[0] = False
                else:
                    moved &= self._per_board(far, groups) == 0
        if np.count_nonzero(moved):
            common = np.where(moved[row], common, held)
        elif np.count_nonzero(held):
            common = held
        else:
            common = 0.0
        np.copyto(s.common, common, where=live)
        self._follow_level(s, live, gain, common, work.tmp)
        return y - common if np.any(common) else y

    @classmethod
    def _board_value(cls, values: np.ndarray, keep: np.ndarray, groups: _Boards,
                     work: _Scratch) -> np.ndarray:
        """Return each taxel's board's median of ``values`` over its ``keep`` taxels.

        NaN where a board has none. One value per board (each taxel's ``common`` may have
        faded by its own gap since its last sample).
        """
        vals = cls._padded(values, keep, groups.table, work)  # NaN last
        row = groups.row
        count = np.count_nonzero(np.isfinite(vals), axis=1)
        lo = np.clip((count - 1) // 2, 0, vals.shape[1] - 1)[:, None]
        hi = np.clip(count // 2, 0, vals.shape[1] - 1)[:, None]
        mid = 0.5 * (np.take_along_axis(vals, lo, 1) + np.take_along_axis(vals, hi, 1))[:, 0]
        return np.where(count > 0, mid, np.nan)[row]

    def _rejoin(self, t: float, y: np.ndarray, s: DetectorState, live: np.ndarray,
                groups: _Boards, work: _Scratch) -> None:
        """Re-seat a taxel read again after a hole at its board's common mode.

        Its ``common`` is its board's (`_board_value` of the taxels read on), its smoothed
        reading the reading, its level the reading less the board's common mode (as
        `_loop_common` re-seats a taxel back from a contact).
        """
        ret = live & (s.t_seated == t)  # `process`: a hole (or a warm-up's worth) just ended
        if not np.count_nonzero(ret):
            return
        board = self._board_value(s.common, live & ~ret, groups, work)
        board = np.where(np.isnan(board), s.common, board)
        np.copyto(s.common, board, where=ret)
        np.copyto(s.common_smooth, y, where=ret)
        np.copyto(s.common_level, y - board, where=ret)

    @staticmethod
    def _follow_level(s: DetectorState, live: np.ndarray, gain: np.ndarray,
                      common: np.ndarray | float, tmp: np.ndarray,
                      part: np.ndarray | None = None) -> None:
        """Move each live taxel's ``common_level`` (`_common`) one step.

        The level follows the reading with the common mode taken off, and slowly the room
        too: a room that settled elsewhere is each taxel's new level (the common mode, and its
        noise, gone again); slower changes reach the baseline as a trend. (``level +
        (smooth - common - level) * gain[1] + common * gain[7]``, in place: ``tmp`` is
        overwritten; ``part``, given with a ``common`` of 0, is ``smooth - level``: the same
        numbers, x - 0 being x.)
        """
        if part is None:
            np.subtract(s.common_smooth, common, out=tmp)
            tmp -= s.common_level
            tmp *= gain[1]
        else:
            np.multiply(part, gain[1], out=tmp)
        np.add(s.common_level, tmp, out=tmp)
        tmp += common * gain[7]
        np.copyto(s.common_level, tmp, where=live)

    def _loop_common(self, t: float, y: np.ndarray, s: DetectorState, live: np.ndarray,
                     gain: np.ndarray, table: np.ndarray, row: np.ndarray) -> np.ndarray:
        """Return the readings with a loop-held board's common mode taken off.

        A PID loop high-passes the room: what reaches every taxel of a board is a band-limited
        noise (pid-logger: 0.032 K sd), the same in each (one room, one loop design), never a
        step that (nearly) every taxel shows beyond its noise, so the gated common mode of
        `_common` switched on and off with it. Here the common mode is the median of the free
        taxels' departures (each taxel's averaged reading from its own level), taken off
        every reading of the board on every sample: a touch moves the median of n taxels by a
        step of the others' spread, not by the touch. ``common_var`` follows the square of
        what it leaves of each free taxel's departure (`COMMON_FORGET` ``slow_tau``).
        """
        np.copyto(s.common_smooth, s.common_smooth + (y - s.common_smooth) * gain[6],
                  where=live)
        use = live & ~s.in_contact & (t >= s.recover_until)
        # a taxel back from a contact (its recovery over) rejoins at the board's common mode:
        # its level, stale from before the touch, re-seated (else a board that had too few
        # free taxels resumed its median with the touched ones' old levels: a step)
        back = use & (s.t_last < s.recover_until)
        np.copyto(s.common_level, s.common_smooth - s.common, where=back)
        part = s.common_smooth - s.common_level
        # a free taxel that left the board's last common mode by more than `COMMON_AGREE`
        # sigmas of what the common mode leaves of it (``common_var``) moves on its own, not
        # with the room (a touch not yet raised, its own gust): no part of the median. The
        # room moves them all alike, by a step within their noise from one sample to the
        # next; a touch of half the board, taken in, made the median half the touch
        # (pid-logger, 8 of 16 taxels under a block: false falls on the other 8)
        use &= np.abs(part - s.common) <= COMMON_AGREE * np.sqrt(s.common_var)
        values = np.append(np.where(use, part, np.nan), np.nan)[table]
        values.sort(axis=1)  # NaN last
        count = np.count_nonzero(np.isfinite(values), axis=1)
        lo = np.clip((count - 1) // 2, 0, values.shape[1] - 1)[:, None]
        hi = np.clip(count // 2, 0, values.shape[1] - 1)[:, None]
        median = 0.5 * (np.take_along_axis(values, lo, 1) + np.take_along_axis(values, hi, 1))
        median = np.nan_to_num(median[:, 0])[row]
        # (no cap on its reach: a real room moves further than AMBIENT_DRIFT's walk, a -0.3 K
        # step over 1 s through the loop gave 16 false onsets when a median beyond 0.147 K
        # held; a touch of the whole board is taken for the room, see the tests' xfail)
        few = (count < COMMON_MIN)[row]
        # a board with fewer than `COMMON_MIN` free taxels (a touch covering most of it) has
        # no median to trust: it holds its last common mode, which fades as each taxel's level
        # absorbs it (`COMMON_FORGET` ``slow_tau``, below), rather than dropping to 0 (a step of
        # the room's tens of mK in every reading left: false onsets); the room's change since
        # is back in the readings, and so in full in the allowance
        common = np.where(few, s.common * (1.0 - gain[7]), median)
        np.copyto(s.common, common, where=live)
        np.copyto(s.common_var, self._room_var, where=live & few)
        left = part - common
        # a running mean first, an exponential one after `COMMON_FORGET` ``slow_tau`` (from
        # the room's own variance, the allowance on main, it took minutes to come down)
        dt = np.maximum(t - s.t_last, 1e-9)
        v = np.maximum(gain[7], dt / np.maximum(t - s.t_first + dt, dt))
        np.copyto(s.common_var, s.common_var + (left**2 - s.common_var) * v, where=use)
        np.copyto(s.common_level, s.common_level + left * gain[1] + common * gain[7],
                  where=live)
        return y - common

    def _agree(self, part: np.ndarray, use: np.ndarray, groups: _Boards,
               count: np.ndarray, work: _Scratch) -> np.ndarray:
        """Return whether `_shared` of each board's free taxels' departures agree in size.

        True where some `_shared` (k) of them, consecutive in order, span no more than
        `COMMON_AGREE` noise sigmas of the departure (the board's largest): one change moving
        them all alike, not each taxel's own (a warm-up, a reheat).
        """
        if groups.table.shape[0] == 1:
            # one board (a skin warming up passes the count on most samples): the same
            # spreads and sigma without the padded table; ``count[0]`` is ``values.size``
            # (`_common` counted the same ``use``)
            values = np.sort(part[use])
            k = max(int(groups.need[count[0]]), 1)
            spread = values[k - 1:] - values[: values.size - k + 1]
            sigma = np.max(self._common_margin, initial=0.0) / COMMON_MARGIN
            return np.array([np.min(spread, initial=np.inf) <= COMMON_AGREE * sigma])
        values = self._padded(part, use, groups.table, work)  # NaN last
        k = np.maximum(groups.need[count], 1).astype(np.intp)
        # the spread of each k consecutive departures: the (k-1)-th after each, through a
        # table twice as wide (NaN beyond a board's free taxels: such spreads passed over)
        rows, width = values.shape
        wide = np.full((rows, 2 * width), np.nan)
        wide[:, :width] = values
        spread = wide.take(groups.ahead + (k - 1)[:, None])
        spread -= values
        return np.fmin.reduce(spread, axis=1, initial=np.inf) <= COMMON_AGREE * groups.sigma

    @classmethod
    def _board_common(cls, fall_part: np.ndarray, rise_part: np.ndarray, use: np.ndarray,
                      groups: _Boards, count: np.ndarray, work: _Scratch) -> np.ndarray:
        """Return each taxel's board's common mode from its free taxels' departures.

        ``fall_part`` and ``rise_part``: the departures with the noise margin added, taken off.
        """
        k = np.maximum(groups.need[count], 1).astype(np.int64)
        last = np.maximum(count - 1, 0).astype(np.int64)
        row = groups.row

        def order(part: np.ndarray, at: np.ndarray) -> np.ndarray:
            """Return the ``at``-th smallest (from 0) of each board's free taxels' ``part``."""
            values = cls._padded(part, use, groups.table, work)  # NaN: not counted, last
            return np.take_along_axis(values, np.clip(at, 0, last)[:, None], 1)[:, 0]

        with np.errstate(invalid="ignore"):
            # below 0 only when k or more fell beyond their noise; above 0 only when k rose
            fall = order(fall_part, k - 1)
            rise = order(rise_part, count.astype(np.int64) - k)
            board = np.where(fall < 0, fall, np.where(rise > 0, rise, 0.0))
        board = np.where(count >= COMMON_MIN, np.nan_to_num(board), 0.0)
        return board[row]

    def _step(self, t: float, y: np.ndarray, s: DetectorState, events: list[OnsetEvent],
              taus: np.ndarray, groups: _Boards | None = None,
              margins: list | None = None, work: _Scratch | None = None,
              limits: tuple | None = None, duty: bool = False) -> None:
        # Whole-array updates selected with `np.copyto(..., where=)` or a ufunc's ``where``
        # (the same arithmetic, element by element, as masked updates, at a fraction of the
        # calls), the float temporaries written into ``work`` (`_Scratch`: each expression's
        # operations in its order, so the same numbers to the bit), and the rare branches
        # (new taxels, holes, onsets, contacts) skipped when no taxel takes them: a
        # per-sample step is numpy's call overhead, whatever the taxels.
        w = _scratch(self.n_taxels) if work is None else work
        tmp = w.tmp
        tenth, fall_quarter, rise_quarter, end_quarter, end_rise_quarter, floor2, resid2 = (
            self._limits() if limits is None else limits)
        valid = np.isfinite(y)
        new = valid & np.isnan(s.level)
        if np.count_nonzero(new):
            s.common_smooth[new] = s.common_level[new] = y[new]
            s.level[new] = y[new]
            s.smooth[new] = y[new]
            s.slow[new] = y[new]
            s.medium[new] = y[new]
            if self.envelope_tau is not None:
                s.fast[new] = y[new]
            s.t_first[new] = s.t_seated[new] = t
            s.t_level[new] = t
            s.t_last[new] = t
            s.armed_at[new] = t + self.warmup
            live = valid & ~new
        else:
            live = valid
        n_live = np.count_nonzero(live)
        if not n_live:
            return
        quiet = ~live if n_live < live.size else None  # (None: every taxel read)
        free = ~s.in_contact
        # a free taxel read again after a hole longer than the warm-up (its
        # board's samples lost, or flagged) starts again as a new one: its trend extrapolated
        # across the hole is no baseline, and what changed unseen cannot be dated
        dt = np.subtract(t, s.t_last, out=w.dt)
        back = live & free & (dt > self.warmup)
        if np.count_nonzero(back):
            s.level[back] = s.smooth[back] = s.slow[back] = s.medium[back] = y[back]
            if self.envelope_tau is not None:
                s.fast[back] = y[back]
            s.slope[back] = 0.0
            s.t_level[back] = s.t_last[back] = s.t_seated[back] = t
            s.cusum[back] = s.rise_cusum[back] = 0.0
            s.slow_start[back] = np.nan
            s.ref_level[back] = np.nan
            s.armed_at[back] = t + self.warmup
            s.common_smooth[back] = y[back]
            s.common_level[back] = y[back] - s.common[back]
            np.subtract(t, s.t_last, out=dt)
        # (``max(where(live, t - t_last, 1), 1e-9)``)
        if quiet is not None:
            np.copyto(dt, 1.0, where=quiet)
        np.maximum(dt, 1e-9, out=dt)
        # a hole shorter than the warm-up keeps the baseline, but the smoothing's and the
        # baseline's noise after it is not the settled filters' the noise table models: the
        # settle clock starts again (`SETTLE_TAUS`)
        hole = live & (dt > self._hole)
        if np.count_nonzero(hole):
            np.copyto(s.t_seated, t, where=hole)
            np.add(s.settle_restarts, hole, out=s.settle_restarts)
        # every smoothing gain at once: smooth, slow, level, slope (free, in contact), noise;
        # one column when every taxel's step is the same (a skin's boards sample in step)
        first = dt[:1]
        if np.count_nonzero(dt != first):
            gain = 1 - np.exp(-dt / taus)
        else:
            gain = 1 - np.exp(-first / taus)
        if groups is not None:
            # the room's change, shared by every free taxel of a board, taken off first
            y = self._common(t, y, s, live, gain, groups, w)
        # the smoothed reading averages noise and dithered ADC steps; everything runs on it
        _toward(s.smooth, y, gain[0], live, tmp)
        # the slow channel's reading: averaged over a tenth of its window
        _toward(s.medium, y, gain[6], live, tmp)
        if self.envelope_tau is not None:
            # the gust-envelope test's faster reading
            _toward(s.fast, y, gain[-1], live, tmp)
        # the baseline's prediction, ``level + slope * (t - t_level)``, and the residual
        pred = np.subtract(t, s.t_level, out=w.pred)
        pred *= s.slope
        np.add(s.level, pred, out=pred)
        resid = np.subtract(s.smooth, pred, out=w.resid)
        if quiet is not None:
            np.copyto(resid, 0.0, where=quiet)
        sigma = np.maximum(s.var, floor2, out=w.sigma)
        np.sqrt(sigma, out=sigma)
        if duty:
            # the heater's own change of the reading where its duty is known, K/s (a fall
            # positive): ``rise / mode`` times what the body still holds over the duty
            # (``duty_lag - duty``) in units of the largest duty (``duty_top``: the heated
            # rise's); 0 where never heated, or no duty known yet (``duty_top`` NaN). The fall
            # allowance takes its falls, a contact's end both signs
            heater_slope = np.subtract(s.duty_lag, s.duty, out=w.heater)
            np.divide(heater_slope, s.duty_top, out=heater_slope, where=s.duty_top > 0.0)
            np.copyto(heater_slope, 0.0, where=~(s.duty_top > 0.0))
            heater_slope *= self._heater_fall_rate
        allowance = w.allowance
        if self.loop_common:
            # the room's leftover in the noise estimate had covered the fastest gusts, which
            # the CUSUM of the room-free reading took for contacts (pid-logger seed 2: 14 of
            # 15 false alarms, each within 0.5 s of a gust's start): the allowance adds what
            # the family's gusts need through the loop (`_gust_allowance`), in quadrature
            np.multiply(4.0, sigma, out=allowance)
            np.hypot(allowance, self._gust_k, out=allowance)
        else:
            np.multiply(4.0, sigma, out=allowance)
        np.maximum(self.drift, allowance, out=allowance)
        idle = live & free
        armed = t >= s.armed_at
        # in contact the baseline follows the reading's in-contact trend, and the CUSUM of the
        # other sign watches for the contact's end: a fall stopping short, or a rise
        contact = live & s.in_contact
        any_contact = bool(np.count_nonzero(contact))
        if any_contact:
            cool = live & (s.direction < 0)
            warm = live & (s.direction > 0)
            watch_fall, watch_rise = idle | warm, idle | cool
            # the trend in contact decelerates and the baseline lags it by a fraction of its
            # slope: only a departure beyond that counts
            slack = np.abs(s.slope, out=w.slack)
            np.multiply(self.release_slack, slack, out=slack)
            np.maximum(allowance, slack, out=slack)
            np.copyto(slack, allowance, where=~(cool | warm))
        else:
            watch_fall = watch_rise = idle
            slack = allowance

        # CUSUMs of the shortfall below and the excess above the baseline, deg C x samples;
        # a free taxel's accumulate only once it is armed (the baseline is still catching the
        # reading's trend at start and during the fast recovery after a release)
        g_old, u_old = s.cusum, s.rise_cusum
        unarmed = idle & ~armed
        g = np.subtract(g_old, resid, out=w.g)  # ``max(0, g_old - resid - slack)``
        g -= slack
        np.maximum(0.0, g, out=g)
        np.copyto(g, g_old, where=~watch_fall)
        u = np.add(u_old, resid, out=w.u)  # ``max(0, u_old + resid - slack)``
        u -= slack
        np.maximum(0.0, u, out=u)
        np.copyto(u, u_old, where=~watch_rise)
        np.copyto(g, 0.0, where=unarmed)
        np.copyto(u, 0.0, where=unarmed)
        np.copyto(s.t_start, s.t_last, where=watch_fall & (g_old == 0) & (g > 0))
        np.copyto(s.rise_start, s.t_last, where=watch_rise & (u_old == 0) & (u > 0))
        stale = watch_fall & (g > 0) & (np.subtract(t, s.t_start, out=tmp) > self.stale)
        rise_stale = watch_rise & (u > 0) & (np.subtract(t, s.rise_start, out=tmp) > self.stale)
        fell = (g > self.threshold) & ~stale
        rose = (u > self.rise_threshold) & ~rise_stale
        alarm = idle & fell & armed
        # a rise that begins right after the reading fell is the taxel reheating (after a touch
        # too brief to be reported, or a gust), not a warm object
        rebound = idle & rose & (np.subtract(s.rise_start, s.t_fell, out=tmp) <= self.rebound)
        rise_alarm = idle & rose & armed & ~alarm & ~rebound
        any_alarm = np.count_nonzero(alarm)
        if any_alarm:
            for k in np.flatnonzero(alarm):
                t0 = float(s.t_start[k])
                events.append(OnsetEvent("onset", int(k), t0, t,
                                         float(s.level[k] + s.slope[k] * (t0 - s.t_level[k])),
                                         float(s.slope[k]), -1))
        any_rise = np.count_nonzero(rise_alarm)
        if any_rise:
            for k in np.flatnonzero(rise_alarm):
                t0 = float(s.rise_start[k])
                events.append(OnsetEvent("onset", int(k), t0, t,
                                         float(s.level[k] + s.slope[k] * (t0 - s.t_level[k])),
                                         float(s.slope[k]), 1, 1))
        # the slow channel: a fall below the slow average of the smoothed reading
        fall = np.subtract(s.slow, s.medium, out=w.fall)
        np.copyto(fall, 0.0, where=~idle)
        np.copyto(s.slow_start, s.t_last,
                  where=idle & (fall > self.slow_begin) & np.isnan(s.slow_start))
        np.copyto(s.slow_start, np.nan, where=idle & (fall <= self.slow_begin))
        slow_alarm = (idle & ~alarm & ~rise_alarm & (fall > self.slow_threshold) & armed
                      & np.isfinite(s.slow_start))
        # the gust-envelope test: a fall from where the baseline put the reading when it began
        # to fall, deeper than the deepest, fastest gust and the steepest heater step could
        # make in the time since, and clear of the noise (the baseline, which follows a
        # smooth fall as a trend, lets such a fall pass the CUSUM)
        since = np.subtract(t, s.ref_t, out=w.since)
        # ``ref_level + min(ref_slope, 0) * since - smooth``
        drop = np.minimum(s.ref_slope, 0.0, out=w.drop)
        drop *= since
        np.add(s.ref_level, drop, out=drop)
        drop -= s.smooth
        margin = w.margin
        fast = self.envelope_tau is not None  # (only with the noise table and no loop)
        if self.envelope_noise:
            # the fall's own noise at the time since: the readout noise's through the
            # baseline's extrapolation (`drop_noise`, growing with the time since), and what
            # the running estimate finds beyond the readout's (disturbances: not extrapolated)
            j = np.divide(since, self._drop_step, out=tmp)
            np.ceil(j, out=j)
            np.copyto(j, self._drop_sd.size - 1, where=~(j < self._drop_sd.size))  # or none
            j = j.astype(np.intp)
            readout = np.take(self._drop_sd, j, out=margin)  # ``drop_sd[j] * resid_sigma``
            readout *= self._resid_sigma
            beyond = np.square(sigma, out=w.flat)  # ``max(sigma**2 - resid_sigma**2, 0)``
            beyond -= resid2
            np.maximum(beyond, 0.0, out=beyond)
            if fast:
                # the faster reading's fall has its own readout noise, the same beyond it
                margin_fast = np.take(self._fast_sd, j, out=w.margin_fast)
                margin_fast *= self._resid_fast
                np.square(margin_fast, out=margin_fast)
                margin_fast += beyond
                np.sqrt(margin_fast, out=margin_fast)
                margin_fast *= self.envelope_sigmas
            # ``envelope_sigmas * sqrt(readout**2 + beyond)``
            np.square(readout, out=margin)
            margin += beyond
            np.sqrt(margin, out=margin)
            np.multiply(self.envelope_sigmas, margin, out=margin)
            # a reference taken before the filters settled after their seat (``t_seated``):
            # the flat margin's 8 sigmas (the table does not model the start-up transient);
            # after, the smaller of the two: tens of ms after the reference the table's,
            # seconds after it the flat one (the table counts the trend's noise extrapolated,
            # which grows past the flat margin there, and the flat margin has held the room's
            # random walk, which neither models, on every preset). Never above the flat
            # margin. NaN reference: no drop.
            flat = np.maximum(sigma, self.smoothed_sigma, out=w.flat)
            np.multiply(FLAT_SIGMAS, flat, out=flat)
            young = ~(np.subtract(s.ref_t, s.t_seated, out=tmp) >= self._settle)
            np.minimum(margin, flat, out=margin)
            np.copyto(margin, flat, where=young)
            if fast:
                flat *= self._fast_flat  # 8 of the faster reading's sigmas
                np.minimum(margin_fast, flat, out=margin_fast)
                np.copyto(margin_fast, flat, where=young)
        else:
            np.maximum(sigma, self.smoothed_sigma, out=margin)
            np.multiply(self.envelope_sigmas, margin, out=margin)
        if self.envelope is None:
            # ``gust_depth * -expm1(-since / gust_rise) + heater_rate * since + margin``
            gusty = np.negative(since, out=w.gusty)
            gusty /= self.gust_rise
            np.expm1(gusty, out=gusty)
            np.negative(gusty, out=gusty)
            np.multiply(self.gust_depth, gusty, out=gusty)
            heater = np.multiply(self.heater_rate, since, out=tmp)
            if duty:
                # the heater's own fall where its duty is known (0 where it held or rose);
                # none known yet: the steepest step's, as without the duty
                lost = np.maximum(heater_slope, 0.0, out=w.flat)
                lost *= since
                np.copyto(heater, lost, where=np.isfinite(s.duty_lag))
            gusty += heater
            if fast:
                # the same allowance with the faster reading's margin
                np.add(margin_fast, gusty, out=margin_fast)
                gusty_fast = margin_fast
            gusty += margin
        else:
            # a loop-held sensor: the room's drift and the noise added in quadrature (taken as
            # independent). ``sigma`` is the CUSUM's running noise estimate, which on a
            # loop-held sensor is mostly the room's leftover, not the readout's: the room is
            # counted twice there (the safe side: fewer onsets, never more false alarms)
            step, loop_fall, drift = self.envelope
            j = np.ceil(since / step)
            np.copyto(j, loop_fall.size - 1, where=~(j < loop_fall.size))  # no reference: unused
            j = j.astype(np.intp)
            room = drift[j]
            if self.loop_common:
                # what the board's common mode leaves of the room (and of the other taxels'
                # own disturbances, through the median), measured, against the room alone
                room = room * np.sqrt(np.minimum(s.common_var / self._room_var, 1.0))
            gusty = loop_fall[j] + np.sqrt(margin**2 + room**2)
        beyond_gust = drop > gusty
        if fast:
            # the fall on the faster reading: ``ref_level + min(ref_slope, 0) * since - fast``
            drop_fast = np.add(drop, s.smooth, out=w.drop_fast)
            drop_fast -= s.fast
            beyond_gust |= drop_fast > gusty_fast
        deep = idle & armed & ~alarm & ~rise_alarm & ~slow_alarm & beyond_gust
        if margins is not None:
            # each fall test's statistic over its threshold (>= 1: it fires), on the free,
            # armed taxels (`MARGIN_TESTS`; NaN elsewhere)
            ready = idle & armed
            margins.append(np.where(ready, np.stack([
                np.where(stale, 0.0, g) / self.threshold,
                np.where(stale, g, 0.0) / self.threshold,
                np.where(np.isfinite(s.slow_start), fall, 0.0) / self.slow_threshold,
                _envelope_margin(drop, gusty, drop_fast if fast else None,
                                gusty_fast if fast else None)]), np.nan))
        slow_alarm = slow_alarm | deep
        any_slow = np.count_nonzero(slow_alarm)
        if any_slow:
            # a fall the CUSUM has begun to gather is dated where the CUSUM left zero, as its
            # own onset would be; otherwise where the reading left the noise
            cusum_began = deep & (g > 0) & np.isfinite(s.t_start)
            for k in np.flatnonzero(slow_alarm):
                if cusum_began[k]:
                    t0k = float(s.t_start[k])
                    events.append(OnsetEvent(
                        "onset", int(k), t0k, t,
                        float(s.level[k] + s.slope[k] * (t0k - s.t_level[k])),
                        float(s.slope[k]), -1, 2))
                elif deep[k] and self.envelope is not None:
                    # a loop-held sensor's reference may date from long before the contact
                    # (the room's drift, a gust take the reading out of its noise first):
                    # dated when raised, so that `refine_onset`, which searches before the
                    # coarse onset, searches the span before the alarm (pid-logger seed 0: the
                    # envelope's onsets' refined error median 1.1 s -> 58 ms), the baseline
                    # carried there along the reference's trend as ``drop`` does (a falling
                    # one, a rising not)
                    trend = min(float(s.ref_slope[k]), 0.0)
                    events.append(OnsetEvent("onset", int(k), t, t,
                                             float(s.ref_level[k] + trend * since[k]), trend,
                                             -1, 2))
                elif deep[k]:
                    events.append(OnsetEvent("onset", int(k), float(s.ref_t[k]), t,
                                             float(s.ref_level[k]), float(s.ref_slope[k]),
                                             -1, 2))
                else:
                    events.append(OnsetEvent("onset", int(k), float(s.slow_start[k]), t,
                                             float(s.slow[k]), 0.0, -1, 2))
        any_onset = bool(any_alarm or any_rise or any_slow)
        if any_onset:
            t0 = np.where(alarm, s.t_start, s.rise_start)
            # an envelope onset re-bases the baseline from where the fall began, as a CUSUM's
            # does (the baseline re-based from where the reading left the noise: the CUSUM
            # may have left zero a sample ago); taken before the reference slides below,
            # which on the sample the slow channel's window runs out would move it to now
            t0 = np.where(deep, s.ref_t, t0)
        # the reference slides with the baseline while the reading stays within noise of it
        # (a falling trend extrapolated, a rising one not: it decelerates), and starts again
        # after the slow channel's window (a slower fall is the slow channel's)
        slide = ~(drop > np.multiply(2.0, sigma, out=tmp)) | (since > self.slow_tau)
        np.copyto(s.ref_level, pred, where=slide)
        np.copyto(s.ref_slope, s.slope, where=slide)
        np.copyto(s.ref_t, t, where=slide)
        np.copyto(s.ref_level, np.nan, where=~(idle & armed) | slow_alarm)
        if any_onset:
            alarm = alarm | slow_alarm
            onset = alarm | rise_alarm
            calm = idle & ~onset
        else:
            calm = idle
        _toward(s.slow, s.medium, gain[1], calm, tmp)
        # while the taxel recovers from a release, the slow average keeps up with it
        recovering = calm & (t < s.recover_until)
        if np.count_nonzero(recovering):
            away = np.subtract(s.medium, s.slow, out=tmp)
            np.multiply(s.recover_dir, away, out=away)
            np.copyto(s.slow, s.medium, where=recovering & (away > 0))
        # and until the taxel is armed it is the slow channel's reading itself: seeded with
        # one raw reading, whose noise is the readout's before any averaging (low-cost: 0.17-
        # 0.22 K sd against the reading's first seconds), it would stay there for ``slow_tau``
        # while the medium average settles, and the difference is a fall of one sample's
        # noise (low-cost seeds 0, 14, 20, 24: 6 of 17 false alarms, raised 1.75-12 s into a
        # stream by the slow channel, the first reading 0.30-0.54 K above the next seconds')
        if np.count_nonzero(unarmed):
            np.copyto(s.slow, s.medium, where=unarmed)
        if any_onset:
            s.slow_start[onset] = np.nan
            s.in_contact[onset] = True
            s.direction[alarm] = -1.0
            s.direction[rise_alarm] = 1.0
            s.extreme[onset] = s.smooth[onset]
            s.heater_fall[onset] = s.extreme_fall[onset] = 0.0
            s.t_extreme[onset] = t
            # from the onset on (or a reheat's rebound), the baseline follows the trend from
            # where the reading is now: the change since the CUSUM left zero (t0), over at
            # least `onset_span`, the baseline's own trend filling the span before t0 (the
            # slope over [t - onset_span, t] of the baseline's prediction until t0, the
            # reading after). A CUSUM that alarms within a sample or two gives the difference
            # of two noisy readings, the later one noisy enough to raise the alarm (at 20 Hz,
            # one sample: 0.6 K/s of noise; a paper trial's aluminium contact re-based at
            # -2.6 K/s, its trend -1.5), and the baseline, extrapolating too steep a fall,
            # took the next noisy sample for the fall stopping short (a release, then the
            # contact again). Where `onset_span` is the 1e-3 s guard, as before: the change
            # over max(t - t0, 1e-3)
            o = onset & np.isfinite(t0)
            since_o = t - t0[o]
            start = s.level[o] + s.slope[o] * (t0[o] - s.t_level[o])
            span = self.onset_span
            if span > 1e-3:
                s.slope[o] = (s.smooth[o] - start
                              + s.slope[o] * np.maximum(span - since_o, 0.0)) / np.maximum(
                                  since_o, span)
            else:
                s.slope[o] = (s.smooth[o] - start) / np.maximum(since_o, span)
            s.slope[onset & ~o] = 0.0
            s.level[onset] = s.smooth[onset]
            s.t_level[onset] = t
            np.copyto(s.t_fell, t, where=idle & (g > tenth))
            np.copyto(g, 0.0, where=onset | stale)
            np.copyto(u, 0.0, where=onset | rebound | rise_stale)
        else:
            np.copyto(s.t_fell, t, where=idle & (g > tenth))
            np.copyto(g, 0.0, where=stale)
            np.copyto(u, 0.0, where=rebound | rise_stale)
        np.copyto(s.cusum, g)
        np.copyto(s.rise_cusum, u)

        # the baseline follows the signal until there is real evidence of contact (or, in
        # contact, of its end)
        follow = calm & (g <= fall_quarter) & (u <= rise_quarter)
        if any_contact:
            # in contact, against the end's thresholds (`END_SIGMAS`)
            end_fall_ok = g <= end_quarter
            end_rise_ok = u <= end_rise_quarter
            stopped = ((warm & (g > self.end_threshold) & ~stale)
                       | (cool & (u > self.end_rise_threshold) & ~rise_stale)
                       ) if self.ends_when_stopped else np.zeros_like(live)
            follow |= (warm & ~stopped & end_fall_ok) | (cool & ~stopped & end_rise_ok)
            b = np.where(idle, gain[3], gain[4])
        else:
            b = gain[3]
        err = np.multiply(gain[2], resid, out=w.err)
        np.add(pred, err, out=s.level, where=follow)  # ``pred + err``
        step = np.multiply(b, err, out=tmp)  # ``slope + b * err / dt``
        step /= dt
        np.add(s.slope, step, out=s.slope, where=follow)
        np.copyto(s.t_level, t, where=follow)
        v = gain[5]
        if self.running_start:
            # a loop-held sensor's noise estimate starts as a running mean, an exponential one
            # after ``noise_tau``: started at the floor (pid-logger: 0.26 mK against the
            # 3.7 mK its residual settles at, the room's drift through the loop) the CUSUM's
            # allowance stayed too small past the warm-up, and raised onsets 2-8 s into a
            # stream. Not for a free heated taxel: its baseline still catches the reading's
            # own trend at start, which a running mean would take for noise (the default
            # scene's pipeline then missed its early touches)
            v = np.maximum(v, dt / np.maximum(t - s.t_first, dt))
        # ``var + v * (resid**2 - var)``
        np.square(resid, out=tmp)
        tmp -= s.var
        np.multiply(v, tmp, out=tmp)
        np.add(s.var, tmp, out=s.var, where=follow & idle & (g == 0) & (u == 0))

        # release: the smoothed temperature returns clearly from its in-contact extreme, or
        # its departure stops short of the in-contact trend
        if any_contact:
            if duty:
                # the heater's own change while in contact, put back before the extreme and
                # the end are judged: after a step down a mode ago the reading goes on
                # falling once the object has left, and a brief touch was held for 10-40 s
                # (paper seed 5: 3 of its 4 contacts missed as still in contact)
                heater_slope *= dt
                np.add(s.heater_fall, heater_slope, out=s.heater_fall, where=contact)
            self._release(t, s, events, contact, sigma, warm, stopped, tmp)
        np.copyto(s.t_last, t, where=live)

    def _release(self, t: float, s: DetectorState, events: list[OnsetEvent],
                 touching: np.ndarray, sigma: np.ndarray, warm: np.ndarray,
                 stopped: np.ndarray, tmp: np.ndarray) -> None:
        """End the contacts whose reading came back, or whose departure stopped short.

        ``touching``: the taxels in contact before this sample (not those whose onset it is);
        ``tmp`` is overwritten. The extreme and the return are those of the reading with the
        heater's own change since the onset put back (``heater_fall``: 0 with no duty told).
        """
        d = s.direction
        # ``d * ((smooth + heater_fall) - (extreme + extreme_fall))``: where the reading moved
        # further, the new extreme; elsewhere minus the return from it (a taxel that moved
        # further has returned by less than nothing, never past ``back``)
        away = np.add(s.smooth, s.heater_fall, out=tmp)
        away -= s.extreme
        away -= s.extreme_fall
        away *= d
        further = touching & (away > 0)
        returned = np.negative(away)
        np.copyto(s.extreme, s.smooth, where=further)
        np.copyto(s.extreme_fall, s.heater_fall, where=further)
        np.copyto(s.t_extreme, t, where=further)
        back = np.multiply(4, sigma, out=tmp)
        np.maximum(self.release_rise, back, out=back)
        returned = touching & (returned > back)
        stopped = stopped & touching & ~returned
        released = returned | stopped
        if not np.count_nonzero(released):
            return
        # a contact that stopped short ended where its CUSUM left zero, if not at its extreme
        turn = np.where(warm, s.t_start, s.rise_start)
        s.t_extreme[stopped] = np.minimum(s.t_extreme[stopped], turn[stopped])
        for k in np.flatnonzero(released):
            events.append(OnsetEvent("release", int(k), float(s.t_extreme[k]), t,
                                     float(s.extreme[k]), 0.0, int(d[k]), 3))
        r = released
        s.in_contact[r] = False
        s.recover_dir[r] = -d[r]
        s.recover_until[r] = t + self.recovery
        s.direction[r] = 0.0
        s.slope[returned] = ((s.smooth - s.extreme) / np.maximum(t - s.t_extreme, 1e-3)
                             )[returned]
        s.slope[stopped] = 0.0
        s.level[r] = s.smooth[r]
        s.t_level[r] = t
        s.cusum[r] = 0.0
        s.rise_cusum[r] = 0.0
        s.armed_at[r] = t + self.warmup
        s.t_seated[r] = t
        s.slow[r] = s.medium[r] = s.smooth[r]
        s.slow_start[r] = np.nan
        s.ref_level[r] = np.nan
        s.heater_fall[r] = 0.0
        s.extreme_fall[r] = 0.0

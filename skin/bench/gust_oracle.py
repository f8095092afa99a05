"""A disturbance-aware oracle: whether a stream's own disturbances hide 5-sigma contacts.

`skin.bench.delay_bound`'s oracle is told each contact's exact noise-free change and meets
readout noise only: it detects every 5-sigma contact on every preset. The streams
`skin evaluate-onset` scores on also carry the disturbances `skin.bench.streams` draws: room
drift (a random walk of `skin.stream.onset.AMBIENT_DRIFT` K^2/s), the air's flutter (0.01 K,
0.5 s, scaled by the sensor's heated rise over the paper's), gusts (depth `GUST_DEPTH` scaled,
rise 1-4 s, hold 1-8 s) and heater duty switches (steps of up to 0.45 of the heated rise
through the slowest thermal mode), all through the sensor's loop and lag. This module asks
whether an oracle that knows the contact's template exactly and knows the disturbance family
exactly can still tell the contact from the best-fitting disturbance at 0.1 false alarms per
taxel-hour.

The test (a composite-null generalised likelihood ratio), on one window of raw (unsmoothed)
samples averaged in blocks of `block_size` (about 50 Hz; the information a block average
loses is reported), ``pre`` s (up to 1 s more) before the onset to the end of
the window in which evaluate-onset still credits an alarm to the contact:

- the Gaussian part of the disturbances is the noise: readout (``Stream.raw_noise``), the
  flutter (an Ornstein-Uhlenbeck process) and the room's random walk, each through the
  sensor's loop and lag (`skin.models.sensors.apply_dynamics`); its covariance ``Sigma`` is
  exact for that model at the block rate;
- under both hypotheses the reading carries an unknown offset and an unknown amount of the
  heater's slow mode (a duty switch before the window: ``exp(-t / tau)`` through the loop),
  projected out (profiled);
- the contact hypothesis: the contact's exact template (its size too);
- the null: nothing, or one gust (depth free in [0, 0.4] K before scaling, rise, hold and
  start on a grid: starts from ``hold + 3 rise`` before the window to its end), or one heater
  duty switch inside the window (a change of duty in [-0.45, 0.45], start on a grid).

Statistic ``T = LLR(contact) - max(0, max over the null family of LLR(member))`` (each LLR
against "nothing", amplitudes profiled within their ranges in closed form). Its threshold
for 0.1 alarms per taxel-hour is counted, not extrapolated: on ``null_hours`` taxel-hours of
disturbance-only streams drawn by the streams' own generator (`skin.bench.streams.
stream_chunks` without contacts: the same rates, ranges and scaling; gusts may overlap each
other and a heater switch, which the family does not cover) plus raw noise, scanned window
by window (an alarm restarts the test after the window's end), it is the lowest level at
which the test raises at most 0.1 x ``null_hours`` alarms (`null_threshold`: a 0.5-nat grid
search, then refined among the exact statistic values of the windows above the grid level).
A count of 4 alarms is itself Poisson: the threshold for the true rate is uncertain by
about 0.5-1 nat.
The delay-bound oracle's tail fit (``exp(a - h) h^b``, `skin.bench.delay_bound.fit_tails`)
does not serve here: the statistic's thresholds come out near or below 0 nats (the family
explains away what the drift and flutter make look like a contact), where that form has no
meaning, and the ln ARL bound it falls back to is 14 nats too high for the weak contacts,
which would make the oracle look worse than it is. The oracle's detection of a contact is
the share of fresh draws of the Gaussian noise, the contact's template added at its true
onset, in which ``T`` at that window reaches the threshold (``found_repeats``, 200, draws
for a contact whose threshold was found; standard error at most 0.035); a contact every
draw of which stays above a level at which the null streams raise fewer alarms than that is
detected in every draw, without the search going further down (``threshold_status`` ``"below"``).

It is a disturbance-aware reference test, not a bound. A GLR that maximises over a
composite null is not the Neyman-Pearson test (a likelihood ratio against the family's
mixture, the gusts weighted by their prior, can do better), and the grid's coarseness has
no sign on detection (a coarser grid makes ``T`` larger on the contacts and on the null
streams alike). So its reaching 99 % shows that the disturbances do not rule the target
out; its falling short rules nothing out. What it is told: the exact template (shape, size
and onset) and the generator's Gaussian model of the drift and flutter; ``--grid-factor 2``
halves the grid's steps (a check that the figures do not move) and ``--pre`` sets the past
before the onset (more of it tells the oracle more: the drift's and a gust's state at the
onset). The stream generator freezes the drift, flutter, gusts and heater switches from a
contact's onset to its release (`skin.bench.streams`'s ``_write_contact``: the touching
trace replaces the free reading; after release the free reading plus the gap times the
recovery): the contact-side draws follow it (`frozen_draws`; ``freeze=False``, CLI
``--free-contacts``, draws them free through the contact, noisier than the data), but
the test's contact hypothesis keeps the free covariance, so the test is not the best one
for frozen data (its threshold, set on the null streams, stays right). What it does not
do: scan the candidate onsets near the true one on the contact (a scanner might alarm at a
neighbouring window too; those fit the template worse).

``noise_free_statistic`` (T of the template without noise, half the squared
noise-normalised distance from the template to the family's nearest member, offset and slow
mode profiled) below the threshold marks a contact the family can mimic: with noise it is
detected less than half the time.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from skin.bench.delay_bound import TARGET_FALSE_ALARMS

#: Duty changes a heater switch can make (levels 1, 0.85, 0.7, 0.55: `skin.bench.streams`).
DUTY_STEP = 0.45
#: Gust rise and hold ranges, s (`skin.bench.streams.stream_chunks`).
GUST_RISE = (1.0, 4.0)
GUST_HOLD = (1.0, 8.0)
#: The flutter's size (before scaling), K, and time constant, s.
FLUTTER = (0.01, 0.5)


def block_size(sensor: object, rate: float = 50.0) -> int:
    """Raw samples per block: the sample rate over ``rate`` (at least 1)."""
    return max(1, round(sensor.sample_rate / rate))


def _scales(sensor: object) -> tuple[float, float]:
    """Return the disturbances' scale (heated rise over the paper's) and the heater's mode."""
    from skin.models.sensors import load_sensor

    paper = load_sensor("paper")
    return (sensor.heated_rise / paper.heated_rise,
            62.5 * sensor.reheat_time_constant / paper.reheat_time_constant)


def _dyn(y: np.ndarray, sensor: object, fb: float) -> np.ndarray:
    """Apply the sensor's loop and lag at the block rate, from rest (0 prepended, dropped)."""
    from skin.models.sensors import apply_dynamics

    y = np.asarray(y, dtype=float)
    pad = np.concatenate([np.zeros((1, *y.shape[1:])), y], axis=0)
    return apply_dynamics(pad, sensor, fb, axis=0)[1:]


def covariance(sensor: object, n: int, block: int, raw_noise: float,
               history: float = 40.0) -> np.ndarray:
    """Return the covariance of the Gaussian part of the disturbances and noise, (n, n).

    Block averages of the raw readout noise (``raw_noise**2 / block``), the flutter (an
    Ornstein-Uhlenbeck process, stationary) and the room's random walk (from ``history`` s
    before the window; an offset the test profiles anyway), the latter two through the loop
    and lag at the block rate.

    Parameters
    ----------
    sensor : skin.models.sensors.SensorDescription
        The sensor (rate, loop and lag, the disturbances' scale).
    n : int
        The window's length, blocks.
    block : int
        Raw samples a block average.
    raw_noise : float
        The readout noise's standard deviation per raw sample, K.
    history : float
        Seconds of the random walk before the window.

    Returns
    -------
    numpy.ndarray
        (n, n), K^2.
    """
    from skin.stream.onset import AMBIENT_DRIFT

    fb = sensor.sample_rate / block
    scale, _ = _scales(sensor)
    h = round(history * fb)
    size = h + n
    # flutter: AR(1) at the block rate with the stationary sd of the stream's
    a = math.exp(-1.0 / (FLUTTER[1] * fb))
    sd = FLUTTER[0] * scale
    lags = np.arange(size)
    impulse = (1.0 - a) * a ** lags
    g = _dyn(impulse, sensor, fb) * sd * math.sqrt((1.0 + a) / (1.0 - a))
    # its output's autocovariance from a long impulse response (Toeplitz)
    full = np.correlate(g, g, mode="full")[size - 1:]
    idx = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    cov = full[idx]
    # random walk from `history` before the window: y = dyn(cumsum(w)), var(w) = q / fb
    step = _dyn(np.ones(size), sensor, fb)
    cols = np.arange(size)
    rows = h + np.arange(n)
    d = rows[:, None] - cols[None, :]
    gmat = np.where(d >= 0, step[np.clip(d, 0, size - 1)], 0.0)
    cov = cov + (AMBIENT_DRIFT / fb) * (gmat @ gmat.T)
    return cov + np.eye(n) * raw_noise**2 / block


class Family:
    """The null family's shapes on one window, whitened and profiled.

    Attributes
    ----------
    shapes : numpy.ndarray
        (members, n): each member's change of the reading at unit amplitude, K.
    filters : numpy.ndarray
        (members, n): ``v`` with ``v @ x`` the member's ``<s, x>`` in the whitened,
        profiled metric.
    energy : numpy.ndarray
        (members,): ``<s, s>`` in that metric.
    lo, hi : numpy.ndarray
        (members,): the amplitude's range.
    kind : list of str
        ``"gust"`` or ``"heater"`` per member.

    The amplitudes of gusts and heater switches are profiled within their ranges. Gusts
    that started more than ``hold + 3 rise`` before the window are not members: the
    tails they leave (under 5 % of their depth, decaying) are left to the offset, the slow
    mode and the noise.
    """

    def __init__(self, sensor: object, n: int, block: int, raw_noise: float,
                 grid_factor: float = 1.0) -> None:
        """Build the family on windows of ``n`` blocks.

        Parameters
        ----------
        sensor : skin.models.sensors.SensorDescription
            The sensor (rate, loop and lag, the disturbances' scale, the heater's mode).
        n : int
            The window's length, blocks.
        block : int
            Raw samples a block average.
        raw_noise : float
            The readout noise's standard deviation per raw sample, K.
        grid_factor : float
            The grid's density: ``7 x`` gust rises and ``8 x`` holds, starts every
            ``0.1 / grid_factor`` s. Members whose profiled energy is under 1e-9 of the
            largest are dropped.
        """
        from scipy.linalg import cholesky, solve_triangular

        fb = sensor.sample_rate / block
        self.fb, self.n = fb, n
        scale, tau = _scales(sensor)
        sigma = covariance(sensor, n, block, raw_noise)
        self.chol = cholesky(sigma, lower=True)
        t = (np.arange(n) + 0.5) / fb
        # nuisance: offset, and the heater's slow mode (a duty switch well before the window)
        far = 30.0
        span = np.arange(-int(far * fb), n) / fb + 0.5 / fb
        slow = _dyn(np.where(span > -far + 1e-9, 1.0 - np.exp(-(span + far) / tau), 0.0),
                    sensor, fb)[-n:]
        nuis = np.column_stack([np.ones(n), slow])
        wn = solve_triangular(self.chol, nuis, lower=True)
        self.q_basis, _ = np.linalg.qr(wn)
        shapes, lo, hi, kind = [], [], [], []
        n_rise = max(2, round(7 * grid_factor))
        n_hold = max(2, round(8 * grid_factor))
        stride = max(1, round(0.1 * fb / grid_factor))
        for rise in np.linspace(*GUST_RISE, n_rise):
            for hold in np.linspace(*GUST_HOLD, n_hold):
                back = math.ceil((hold + 3.0 * rise) * fb)
                s = (np.arange(back + n) + 0.5) / fb  # since the gust's start
                shape = np.where(s < hold, 1.0 - np.exp(-s / rise),
                                 (1.0 - np.exp(-hold / rise)) * np.exp(-(s - hold) / rise))
                resp = _dyn(-scale * shape, sensor, fb)  # from rest at its start
                for start in range(-back, n, stride):
                    # the gust starting at block `start` (before the window if < 0)
                    out = np.zeros(n)
                    first = max(start, 0)
                    out[first:] = resp[first - start:n - start]
                    shapes.append(out)
                    lo.append(0.0)
                    hi.append(0.4)
                    kind.append("gust")
        step = _dyn(1.0 - np.exp(-t / tau), sensor, fb) * sensor.heated_rise
        for start in range(0, n, stride):
            out = np.zeros(n)
            out[start:] = step[:n - start]
            shapes.append(out)
            lo.append(-DUTY_STEP)
            hi.append(DUTY_STEP)
            kind.append("heater")
        shapes = np.array(shapes)
        filters, energy = self.whiten(shapes.T)
        # members the offset and slow mode explain (almost) entirely carry no information
        # and only make their amplitudes ill-defined: dropped
        keep = energy >= 1e-9 * float(np.max(energy))
        self.shapes, self.filters, self.energy = shapes[keep], filters[keep], energy[keep]
        self.lo, self.hi = np.array(lo)[keep], np.array(hi)[keep]
        self.kind = [k for k, good in zip(kind, keep, strict=True) if good]

    def subset(self, every: int) -> Family:
        """Return the family of every ``every``-th member (the same window and noise)."""
        out = Family.__new__(Family)
        out.__dict__.update(self.__dict__)
        pick = slice(None, None, every)
        out.shapes, out.filters, out.energy = (self.shapes[pick], self.filters[pick],
                                               self.energy[pick])
        out.lo, out.hi, out.kind = self.lo[pick], self.hi[pick], self.kind[pick]
        return out

    def whiten(self, shapes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the filters (k, n) and energies (k,) of ``shapes`` (n, k)."""
        from scipy.linalg import solve_triangular

        w = solve_triangular(self.chol, shapes, lower=True)
        w = w - self.q_basis @ (self.q_basis.T @ w)
        filt = solve_triangular(self.chol.T, w, lower=False)
        return filt.T, np.sum(w * w, axis=0)

    def best(self, x: np.ndarray) -> np.ndarray:
        """Return the null's best log-likelihood gain over "nothing" for windows x (n, k)."""
        c = self.filters @ x
        e = self.energy[:, None]
        a = np.clip(c / e, self.lo[:, None], self.hi[:, None])
        return np.maximum(np.max(a * c - 0.5 * a * a * e, axis=0), 0.0)

    def draw(self, rng: np.random.Generator, k: int) -> np.ndarray:
        """Return ``k`` draws of the Gaussian noise on the window, (n, k)."""
        return self.chol @ rng.standard_normal((self.n, k))


def frozen_draws(sensor: object, n: int, block: int, raw_noise: float, onset: int,
                 release: int, rng: np.random.Generator, k: int,
                 history: float = 40.0) -> np.ndarray:
    """Return ``k`` draws of the noise on a contact's window as the stream generator makes it.

    The generator (`skin.bench.streams`, ``_write_contact``) replaces the free reading by the
    contact's trace from its onset to its release, so the drift and flutter stop at their
    value just before the onset; after the release the reading is the free one plus the
    gap to where the contact left it times `skin.bench.streams.recovery_shape`. Here: the
    flutter (AR(1) at the block rate, stationary) and the room's random walk from
    ``history`` s before the window, frozen so, through the sensor's loop and lag, plus the
    block-averaged readout noise (the contact's own change is the template's).

    Parameters
    ----------
    sensor : skin.models.sensors.SensorDescription
        The sensor.
    n : int
        The window's length, blocks.
    block : int
        Raw samples a block average.
    raw_noise : float
        The readout noise's standard deviation per raw sample, K.
    onset, release : int
        The blocks of the window at which the contact starts and ends (``release`` may be
        past the window).
    rng : numpy.random.Generator
        The draws' generator.
    k : int
        Draws.
    history : float
        Seconds of the flutter and walk before the window.

    Returns
    -------
    numpy.ndarray
        (n, k), K.
    """
    from scipy.signal import lfilter

    from skin.bench.streams import recovery_shape
    from skin.stream.onset import AMBIENT_DRIFT

    fb = sensor.sample_rate / block
    scale, tau = _scales(sensor)
    h = round(history * fb)
    size = h + n
    a = math.exp(-1.0 / (FLUTTER[1] * fb))
    sd = FLUTTER[0] * scale
    e = rng.standard_normal((size, k)) * sd * math.sqrt(1.0 - a * a)
    e[0] = rng.standard_normal(k) * sd  # stationary from the start
    u = lfilter([1.0], [1.0, -a], e, axis=0)
    u += np.cumsum(rng.normal(0.0, math.sqrt(AMBIENT_DRIFT / fb), (size, k)), axis=0)
    first, last = h + max(onset, 1), h + release
    if first < size:
        frozen = u[first - 1].copy()
        u[first:min(last, size)] = frozen
        if last < size:
            rec = recovery_shape(np.arange(size - last) / fb, tau)
            u[last:] += (frozen - u[last])[None, :] * rec[:, None]
    return _dyn(u, sensor, fb)[-n:] + rng.normal(0.0, raw_noise / math.sqrt(block), (n, k))


def _noise(fam: Family, sensor: object, block: int, raw: float,
           span: tuple[int, int] | None, rng: np.random.Generator, k: int) -> np.ndarray:
    """Return ``k`` noise draws on ``fam``'s window: frozen over ``span`` or free (None)."""
    if span is None:
        return fam.draw(rng, k)
    return frozen_draws(sensor, fam.n, block, raw, span[0], span[1], rng, k)


def block_template(template: np.ndarray, block: int, pre_blocks: int,
                   quantum: int = 1) -> np.ndarray:
    """Return a contact's raw template block-averaged, at least ``pre_blocks`` zeros before it.

    More zeros, up to a window length that is a multiple of ``quantum`` blocks (so that
    contacts share null families; more of the past only tells the oracle more).
    """
    m = np.asarray(template, dtype=float)
    m = m[:m.size // block * block].reshape(-1, block).mean(axis=1)
    n = -(-(pre_blocks + m.size) // quantum) * quantum
    return np.concatenate([np.zeros(n - m.size), m])


def null_streams(sensor: object, seed: int, minutes: float, taxels: int, block: int,
                 raw_noise: float, skip: float = 10.0) -> np.ndarray:
    """Return disturbance-only raw readings, block-averaged, (blocks, taxels).

    The streams' own generator without contacts (`skin.bench.streams.stream_chunks`,
    heater switching, drift, gusts and flutter), through the sensor's loop and lag, plus
    the raw readout noise; the first ``skip`` s dropped. The ``taxels`` of one call share
    one room random walk (as a stream's taxels do), so they are not independent in it.

    Parameters
    ----------
    sensor : skin.models.sensors.SensorDescription
        The sensor (rate, loop and lag, scaling of the disturbances).
    seed : int
        The generator's seed; the readout noise is drawn from ``SeedSequence([seed, 1])``.
    minutes : float
        The stream's length.
    taxels : int
        Taxels drawn.
    block : int
        Raw samples a block average.
    raw_noise : float
        The readout noise's standard deviation per raw sample, K.
    skip : float
        Seconds dropped at the start.

    Returns
    -------
    numpy.ndarray
        (blocks, taxels), K.
    """
    from skin.bench.streams import stream_chunks
    from skin.commands.evaluate_onset import MATERIALS
    from skin.models import load_materials
    from skin.models.sensors import apply_dynamics

    table = load_materials()
    fs = sensor.sample_rate
    n = round(60.0 * minutes * fs)
    (part,) = list(stream_chunks([table[m] for m in MATERIALS.split(",")], taxels,
                                 60.0 * minutes, 0.0, fs=fs, seed=seed, chunk=n,
                                 sensor=sensor, _rng=np.random.default_rng(seed)))
    reading = apply_dynamics(part.temperature, sensor, fs, axis=0)
    # the readout noise's own seed, apart from every piece's (`default_rng(seed + 1)` would
    # be the next piece's generator)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    reading = reading + rng.normal(0.0, raw_noise, reading.shape)
    reading = reading[int(skip * fs):]
    usable = reading.shape[0] // block * block
    return reading[:usable].reshape(-1, block, taxels).mean(axis=1)


def _count(stat: np.ndarray, h: float, n: int) -> int:
    """Alarms of the restarted test at ``h`` on one taxel's window statistics ``stat``."""
    count, last = 0, -1
    for s in np.flatnonzero(stat >= h):
        if s > last:
            count += 1
            last = s + n - 1
    return count


def _refine(stat: Sequence[np.ndarray], level: float, step: float, needed: int,
            n: int) -> float:
    """Return the lowest level in ``[level, level + step]`` raising at most ``needed`` alarms.

    Parameters
    ----------
    stat : sequence of numpy.ndarray
        Per taxel, the windows' statistics; every window at or above ``level`` exact.
    level : float
        A level at which ``needed`` alarms or more are counted.
    step : float
        The grid's step: fewer than ``needed`` alarms are counted at ``level + step``.
    needed : int
        The alarms allowed.
    n : int
        The window's length, blocks (an alarm restarts the test after it).

    Returns
    -------
    float
        The lowest of the exact statistic values in ``[level, level + step)`` (and
        ``level + step``) at which the restarted test raises at most ``needed`` alarms: the
        count only changes at those values, and every window there was computed exactly.
    """
    values = np.concatenate([st[(st >= level) & (st < level + step)] for st in stat])
    for h in np.append(np.unique(values), level + step):
        if sum(_count(st, float(h), n) for st in stat) <= needed:
            return float(h)
    return float(level + step)


def residual_bounds(template: np.ndarray, family: Family,
                    members: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Return linear upper bounds on the statistic ``T``, for the null streams' pruning.

    For any member ``g`` of the family and any amplitude ``a`` in its range, the null's
    profiled gain is at least ``a <g, w> - a^2 <g, g> / 2`` (``w`` the whitened, profiled
    window), so ``T = <u, w> - <u, u> / 2 - best <= <u - a g, w> - <u, u> / 2 +
    a^2 <g, g> / 2``: a linear function of the window, exact whatever the window holds.
    The members that fit the noise-free template best (its amplitude there, within range)
    make the tightest ones: under the null their random part has the variance of the
    template's residual after that member, far smaller than the template's own for a
    contact the family nearly mimics.

    Parameters
    ----------
    template : numpy.ndarray
        (n,) the contact's block-averaged template.
    family : Family
        The null family on windows of ``n`` blocks.
    members : int
        Bounds (the best-fitting members), at most.

    Returns
    -------
    filters : numpy.ndarray
        (k, n): ``filters @ x + offsets`` is at or above ``T`` for every window ``x``.
    offsets : numpy.ndarray
        (k,), nats.
    """
    filt, energy = family.whiten(template[:, None])
    v, q = filt[0], float(energy[0])
    c = family.filters @ template
    a = np.clip(c / family.energy, family.lo, family.hi)
    gain = a * c - 0.5 * a * a * family.energy
    order = np.argsort(-gain, kind="stable")[:members]
    order = order[gain[order] > 0.0]
    filters = v[None, :] - a[order, None] * family.filters[order]
    offsets = -0.5 * q + 0.5 * a[order] ** 2 * family.energy[order]
    return filters, offsets


def null_threshold(x: np.ndarray, template: np.ndarray, family: Family, needed: int,
                   start: float, stop: float, step: float = 0.5, budget: int = 60_000,
                   chunk: int = 256, cache: dict | None = None,
                   spread_at: int = 20_000) -> tuple[float, int, str]:
    """Search the lowest threshold at which the test raises at most ``needed`` alarms on ``x``.

    ``x`` (blocks, taxels) is disturbance-only; every window start is weighed; per taxel, an
    alarm restarts the test after the window's end. T is never above the contact's own LLR
    nor above the linear bounds of `residual_bounds`, nor above T against every 5th member,
    so only the windows all of these leave at or above a level are weighed against the
    whole family there (the grid's levels are walked down one by one; a window's exact T
    is the same whichever way). The level goes down from ``start`` (by ``step``, the step
    doubling) until
    ``needed`` alarms are counted at it, or it falls below ``stop`` (the caller's smallest
    statistic on the contact: any threshold below it detects every draw), or ``budget``
    windows were weighed; a level found is then refined (`_refine`).

    Parameters
    ----------
    x : numpy.ndarray
        (blocks, taxels) disturbance-only block averages (`null_streams`).
    template : numpy.ndarray
        (n,) the contact's block-averaged template (`block_template`).
    family : Family
        The null family on windows of ``n`` blocks.
    needed : int
        The alarms allowed on ``x`` (the target rate x its hours).
    start, stop : float
        The first level tried, nats; the level under which the search stops (``"below"``).
    step : float
        The search grid's first step, nats.
    budget : int
        Windows weighed against the whole family, at most (those the bounds leave: the
        search is exact, the old one's result, as long as the budget does not bind; where
        it binds it stops later than a search that weighed every window reaching a level).
    chunk : int
        Windows weighed at once.
    cache : dict, optional
        The null family's best gain on the windows of ``x`` already weighed, kept between
        calls on the same ``x`` and ``family`` (it does not depend on the contact); filled
        here. Each window's statistic is the same with it or without.
    spread_at : int
        Windows reaching a level, unbounded yet, past which the best-fitting member's
        linear bound is applied to every window by one convolution (a speed choice only).

    Returns
    -------
    level : float
        Nats. ``"found"``: the lowest level at which the restarted test raises at most
        ``needed`` alarms, among the exact statistic values between the highest grid level
        with ``needed`` alarms or more and the next grid level up (`_refine`): at it the
        rate on ``x`` is at most ``needed`` / its hours. Otherwise fewer than ``needed``
        alarms are counted at ``level``, so the threshold is below it.
    windows : int
        Windows weighed against the family.
    status : str
        ``"found"``, ``"below"`` (``level`` < ``stop``) or ``"budget"``.
    """
    from scipy.signal import fftconvolve

    n = family.n
    taxels = x.shape[1]
    filt, energy = family.whiten(template[:, None])
    v, q = filt[0], float(energy[0])
    # (taxels, windows), flat index = taxel x windows + window
    llr = np.ascontiguousarray((fftconvolve(x, v[::-1, None], mode="valid", axes=0)
                                - 0.5 * q).T)
    size = llr.shape[1]
    stat = np.full(llr.shape, -np.inf)
    # upper bounds on T, each exact: a window under the level by one is under the level
    # (its exact T is computed once the level comes down to it). First the linear bounds
    # of `residual_bounds` (on the windows whose LLR reaches the level), then T against
    # every 5th member only, then the whole family. Margin: the bounds' rounding differs from T's.
    margin = 1e-6
    rf, ro = residual_bounds(template, family)
    upper = llr.copy()
    # the best-fitting member's bound on every window at once (one convolution), once as
    # many windows reach a level as make that cheaper than gathering them (a speed choice:
    # every bound is applied to a window before the family weighs it, either way)
    spread = rf.shape[0] == 0
    stage = np.zeros(llr.shape, dtype=np.int8)  # bounds applied: 1 linear, 2 coarse, 3 exact
    if cache is None:
        cache = {}
    if "best" not in cache:
        cache["best"] = np.full(llr.shape, np.nan)
        cache["coarse"] = np.full(llr.shape, np.nan)
    sub = family.subset(5)
    lags = np.arange(n)[None, :]
    highest = [-np.inf]  # the largest exact T so far

    def windows(sel: np.ndarray) -> np.ndarray:
        """Return the windows of flat indices ``sel``, (len(sel), n)."""
        return x[sel[:, None] % size + lags, (sel // size)[:, None]]

    def gain(fam: Family, store: np.ndarray, sel: np.ndarray) -> np.ndarray:
        """Return the family's best gain on the windows ``sel``, from the cache or new."""
        flat = store.reshape(-1)
        new = sel[np.isnan(flat[sel])]
        for a in range(0, new.size, chunk):
            part = new[a:a + chunk]
            flat[part] = fam.best(windows(part).T)
        return flat[sel]

    def weigh(pool: np.ndarray, h: float) -> int:
        """Make T exact on the windows of ``pool`` whose bounds reach ``h``; return how many."""
        up, st, lr = upper.reshape(-1), stage.reshape(-1), llr.reshape(-1)
        sel = pool[(up[pool] >= h - margin) & (st[pool] == 0)]
        for a in range(0, sel.size, chunk):
            part = sel[a:a + chunk]
            bound = np.min(windows(part) @ rf.T + ro, axis=1, initial=np.inf)
            up[part] = np.minimum(up[part], bound)
        st[sel] = 1
        sel = pool[(up[pool] >= h - margin) & (st[pool] == 1)]
        up[sel] = np.minimum(up[sel], lr[sel] - gain(sub, cache["coarse"], sel))
        st[sel] = 2
        sel = pool[(up[pool] >= h - margin) & (st[pool] == 2)]
        if sel.size:
            exact = lr[sel] - gain(family, cache["best"], sel)
            stat.reshape(-1)[sel] = exact
            highest[0] = max(highest[0], float(np.max(exact)))
        st[sel] = 3
        return int(sel.size)

    def count(h: float) -> int:
        """Alarms of the restarted test at ``h`` over every taxel."""
        return sum(_count(stat[j], h, n) for j in range(taxels))

    level, drop, weighed, above = start, step, 0, np.inf
    while True:
        # the windows this pass may weigh: those whose first bounds reach its level
        pool = np.flatnonzero(upper.reshape(-1) >= level - margin)
        if not spread and np.count_nonzero(stage.reshape(-1)[pool] == 0) > spread_at:
            first = fftconvolve(x, rf[0, ::-1, None], mode="valid", axes=0) + ro[0]
            np.minimum(upper, first.T, out=upper)
            spread = True
            pool = np.flatnonzero(upper.reshape(-1) >= level - margin)
        pool = pool[stage.reshape(-1)[pool] < 3]
        if not np.isfinite(above):
            weighed += weigh(pool, level)
        # the grid's levels (level + k step) under the last pass's level, from the top down:
        # the count of alarms only grows as the level falls (the restarted test's alarms
        # are the most windows n apart among those at or above it), so the first level
        # with ``needed`` is the highest, as if every window at or above ``level`` were
        # weighed first (the levels above the last pass's were counted short there). The
        # first pass weighs every window its bounds leave at or above ``start``.
        top = highest[0]
        if np.isfinite(above):
            top = max(top, above)  # windows under the last level are not all weighed yet
        hs = np.arange(level, max(top, level) + step, step)
        for h in hs[::-1]:
            if h >= above:
                continue
            weighed += weigh(pool, float(h))
            if highest[0] >= h and count(float(h)) >= needed:
                return _refine(list(stat), float(h), step, needed, n), weighed, "found"
        above = level  # the walk ended at ``level`` (hs[0]): every window there is weighed
        if level < stop:
            return float(level), weighed, "below"
        if weighed >= budget:
            return float(level), weighed, "budget"
        level -= drop
        drop *= 2.0


def measure_gust_oracle(stream: object, sensor: object, which: Sequence[int], seed: int,
                        false_alarms: float = TARGET_FALSE_ALARMS, repeats: int = 20,
                        null_hours: float = 40.0, null_minutes: float = 15.0,
                        null_taxels: int = 16, pre: float = 2.0, grid_factor: float = 1.0,
                        budget: int = 60_000, found_repeats: int = 200, freeze: bool = True,
                        progress: object | None = None) -> dict:
    """Return the disturbance-aware oracle's detection of the contacts ``which``.

    Parameters
    ----------
    stream : skin.bench.streams.Stream
        A described sensor's stream (its ``templates`` and ``raw_noise``).
    sensor : skin.models.sensors.SensorDescription
        Its sensor.
    which : sequence of int
        Indices of ``stream.contacts`` (evaluate-onset's 5-sigma contacts).
    seed : int
        Seeds the null streams (``seed + 31337``, ``+ 1``, ...: streams of their own) and
        the noise draws.
    false_alarms : float
        The target, per taxel-hour.
    repeats : int
        Noise draws per contact for the threshold search's stop (the smallest draw's T).
    found_repeats : int
        Draws per contact whose threshold was found (its detection is then their share at
        or above it; the first ``repeats`` draws among them): a share's standard error is
        at most ``0.5 / sqrt(found_repeats)``.
    null_hours : float
        Taxel-hours of disturbance-only streams on which each contact's threshold is set
        (``false_alarms * null_hours`` alarms counted, at least 1), drawn as pieces of
        ``null_taxels`` taxels for ``null_minutes``.
    null_minutes, null_taxels
        The pieces' size.
    pre : float
        Seconds before the onset in each window, at least (up to 1 s more: the windows'
        lengths are whole seconds, so that contacts share null families).
    grid_factor : float
        The null grid's density (2: twice the rises and holds, half the start step).
    budget : int
        Null windows weighed against the family per contact, at most (`null_threshold`).
    freeze : bool
        Draw the contact side's noise as the generator makes it (`frozen_draws`: the drift
        and flutter stopped from onset to release); otherwise free (as the test's contact
        hypothesis assumes: noisier than the data).
    progress : callable, optional
        Called as ``progress(done, total)``.

    Returns
    -------
    dict
        Per contact (lists in the order of ``which``): ``detection`` (share of draws with
        ``T`` at or above the threshold), ``draws`` (their number), ``threshold`` and
        ``threshold_status``
        (`null_threshold`), ``noise_free`` (T of the noise-free template), ``information``
        (the template's energy / 2 in the disturbance metric, nats; the old oracle's is in
        readout noise alone), ``block_kept`` (the share of the template's white-noise
        information block averages keep); and ``windows`` weighed, ``null_taxel_hours``,
        ``alarms_needed``, ``block``, ``family_members`` (per window length), ``ln_arl``.
    """
    block = block_size(sensor)
    fb = sensor.sample_rate / block
    pre_blocks = round(pre * fb)
    raw = float(stream.raw_noise)
    pieces = max(1, math.ceil(null_hours * 60.0 / (null_minutes * null_taxels)))
    null = np.concatenate([null_streams(sensor, seed + 31337 + p, null_minutes, null_taxels,
                                        block, raw) for p in range(pieces)], axis=1)
    hours = null.shape[0] * null.shape[1] / fb / 3600.0
    needed = max(1, round(false_alarms * hours))
    log_arl = math.log(fb * 3600.0 / false_alarms)
    rng = np.random.default_rng(seed + 271828)
    families: dict[int, Family] = {}
    # the null family's gains on the null windows, shared by the contacts of one window length
    # (two float arrays the size of the null windows each: freed after a length's last contact)
    caches: dict[int, dict] = {}
    lengths = [block_template(stream.templates[k], block, pre_blocks, round(fb)).size
               for k in which]
    last = {n: i for i, n in enumerate(lengths)}
    out: dict[str, list] = {key: [] for key in ("detection", "threshold", "threshold_status",
                                                "noise_free", "information", "block_kept", "draws")}
    windows = 0
    for i, k in enumerate(which):
        m = block_template(stream.templates[k], block, pre_blocks, round(fb))
        n = m.size
        if n not in families:
            families[n] = Family(sensor, n, block, raw, grid_factor)
        fam = families[n]
        filt, energy = fam.whiten(m[:, None])
        v, q = filt[0], float(energy[0])
        span = None
        if freeze:
            c = stream.contacts[k]
            onset = n - np.asarray(stream.templates[k]).size // block
            span = (onset, onset + round((c.release - c.onset) * fb))
        x = m[:, None] + _noise(fam, sensor, block, raw, span, rng, repeats)
        stat = v @ x - 0.5 * q - fam.best(x)
        start = max(log_arl, float(np.max(stat))) + 0.5
        h, weighed, status = null_threshold(null, m, fam, needed, start, float(np.min(stat)),
                                            budget=budget, cache=caches.setdefault(n, {}))
        if last[n] == i:
            del caches[n]
        windows += weighed
        if status != "below" and found_repeats > repeats:
            more = m[:, None] + _noise(fam, sensor, block, raw, span, rng,
                                       found_repeats - repeats)
            stat = np.concatenate([stat, v @ more - 0.5 * q - fam.best(more)])
        out["detection"].append(1.0 if status == "below" else float(np.mean(stat >= h)))
        out["draws"].append(stat.size)
        out["threshold"].append(h)
        out["threshold_status"].append(status)
        out["noise_free"].append(float(v @ m - 0.5 * q - fam.best(m[:, None])[0]))
        out["information"].append(0.5 * q)
        raw_m = np.asarray(stream.templates[k], dtype=float)
        full = float(np.sum(raw_m[:raw_m.size // block * block] ** 2))
        out["block_kept"].append(float(np.sum(m**2) * block / full) if full > 0 else 1.0)
        if progress is not None:
            progress(i + 1, len(which))
    return {**out, "windows": windows, "null_taxel_hours": hours, "alarms_needed": needed,
            "block": block, "family_members": {n: len(f.kind) for n, f in families.items()},
            "ln_arl": log_arl}

"""Long taxel streams with known contacts and the disturbances a skin lives with.

`simulate_stream` writes what each taxel of a skin reads, at 200 Hz, over minutes to hours of
mostly contact-free time, with every contact's true onset and release recorded. Onset
detectors are judged on it (`skin evaluate-onset`). Per taxel, the free reading is

- **the heater**: the excess over ambient that the heater sustains, following the heater duty
  through the taxel's slowest thermal mode (a first-order lag of `tau`, about 63 s); the duty
  switches at random between levels every 20-120 s (a controller changing its setpoint), so
  the reading drifts by several kelvin over a minute, but slowly;
- **ambient drift**: the room wanders (a random walk of about 1 K per 10 minutes,
  `skin.stream.onset.AMBIENT_DRIFT`: the rate the onset detector assumes by default);
- **air currents**: gusts that cool the face by 0.05-0.4 K over 1-4 s and let it recover,
  and a small turbulent flutter (band-limited noise of 0.01 K);
- **the readout**: 0.5 LSB of ADC noise and 10-bit quantisation through the paper's divider.

Contacts of 0.1-5 s (log-uniform) arrive as a Poisson process per taxel, with long
contact-free stretches between them. Each touches a material of the list at its resting
temperature (or a cold or warm object, within ``object_offset``), through a contact
conductance from the material's range; the thermistor follows the closed-form contact
response from the temperature it had. After release, the reading returns to the free reading
with the taxel's recovery (a fast 2 s part and the slow mode), so a taxel reheats after each
contact. A PID-held sensor's contact swings from the setpoint its loop holds (the loop acts
over the whole stream, see below, whatever the un-looped drift). Setpoint convention: the
setpoint is absolute, the nominal ``ambient`` plus the sensor's heated rise (the loop's
high-pass is anchored at the first sample, so the room's drift is high-passed away); the
trials (`skin.models.trials`) follow each touch's room instead, and a scene's room is constant.

Most objects are cooler than the heated taxel, so a contact makes its reading fall. With
``warm`` > 0, that fraction of the contacts with materials that hold no temperature of their own
(all but skin) touch an object hotter than the taxel (a hot mug, a warm machine part): its
temperature is the taxel's at contact plus a margin drawn uniformly from ``warm_margin``, heat
flows into the sensor and the reading rises, then falls back after release. With ``warm`` = 0
(the default) no draw is made for it: the same seed gives the same stream as before warm
objects existed.

With a ``sensor`` description (`skin.models.sensors`) the stream is that sensor's: its sample
rate; disturbances scaled by its heated rise over the paper's (a gust and a heater step move
a taxel in proportion to how far its heater holds it above ambient) and its slowest mode by
its l^2 / alpha; its heater mode in contact; its PID loop and lag over the whole stream; its
noise, ADC and smoothing. ``visible_after``, ``peak_change`` and ``five_sigma_after`` are then
measured on the contact's own part of the noise-free reading after the loop and the lag (its
step alone through them: the flutter before it is not the contact's), with "visible" at 3 of
the sensor's per-sample noise. Such a stream comes whole (`simulate_stream`: the loop, the lag
and a non-causal smoothing span any chunk). Without one (None), the stream is exactly the
paper's as before.

With a sensor, each contact also says whether any detector held to `BOUND_FALSE_ALARMS` could
see it at all (``detectable_after``, ``information``): Lorden's bound on the contact's own
change over the contact and the window after its release in which
`skin evaluate-onset` still credits an alarm to it (`skin.bench.onset_eval.release_window`),
the change going on after release as the reading recovers (`detectability`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from skin.models.materials import Material
from skin.models.physics import SensorConstants, contact_trace, heated_temperature
from skin.models.trials import adc_readings
from skin.stream.onset import AMBIENT_DRIFT

#: A change of the reading that stands out of its noise (about 3 x 0.5 LSB at 39 C), K.
VISIBLE = 0.1
#: The false-alarm rate at which `StreamContact.bound_after` is set, per taxel-hour (issue 16's
#: target).
BOUND_FALSE_ALARMS = 0.1
#: How much a gust cools a taxel's face, K (drawn uniformly per gust).
GUST_DEPTH = (0.05, 0.4)
#: The air's flutter: white noise of this sd, K (scaled as the gusts), through a first-order lag
#: of `FLUTTER_TAU` s and scaled back to this sd (band-limited noise).
FLUTTER = 0.01
FLUTTER_TAU = 0.5


@dataclass(frozen=True)
class StreamContact:
    """The truth of one simulated contact.

    Attributes
    ----------
    taxel : int
        Column of the stream.
    onset, release : float
        True instants of contact and release, s.
    material : str
        What was touched.
    object_temperature : float
        Its surface temperature, deg C.
    sensor_temperature : float
        The taxel's temperature at contact, deg C.
    visible_after : float
        When the noise-free reading first differs from the sensor's temperature by
        `VISIBLE` K (about three times the reading's noise), s after onset; ``inf`` if never
        during the contact. No detector can be expected to react before it.
    peak_change : float
        The largest change of the noise-free reading from the sensor's temperature during
        the contact, K: a contact that changes it less than a gust does (`GUST_DEPTH`) cannot
        be told from one by its size.
    five_sigma_after : float
        With a sensor description: when the contact's own change first reaches 5 of the
        sensor's noise sigmas, s after onset (``inf`` if never during the contact).
    bound_after : float
        With a sensor description: the earliest any detector can react to the contact at
        `BOUND_FALSE_ALARMS` false alarms per taxel-hour, s after onset (``inf`` if not during
        the contact). It is when the contact's own change has given ``ln ARL`` of
        Kullback-Leibler information (ARL: samples per false alarm), the sum of its squares
        over twice the variance of the sensor's raw, unsmoothed noise: Lorden's lower bound
        on the delay of change detection. A detector told the onset instant and the exact
        shape, in white noise without gusts, nears it; none beats it.
    detectable_after : float
        With a sensor description: the same bound over the contact and the window after its
        release in which an alarm still counts as the contact's
        (`skin.bench.onset_eval.release_window`), the contact's own change going on as the
        reading recovers (``inf`` if not by the window's end): a contact with ``inf`` is out
        of reach of every detector held to `BOUND_FALSE_ALARMS` (on average: its expected
        log-likelihood ratio never reaches ``ln ARL``).
    information : float
        With a sensor description: the Kullback-Leibler information the contact's own change
        gives by the end of that window, nats (``detectable_after`` is finite when it reaches
        ``ln ARL``).
    onset_sd_bound : float
        With a sensor description: the Cramer-Rao lower bound on the standard deviation of
        any unbiased estimate of the onset instant from the contact's samples, s
        (`onset_bound`: the contact's own change known in shape, its size unknown, the
        baseline known, the sensor's raw noise white); ``inf`` if the contact gives no
        information on it.

    With a sensor description (`simulate_stream`'s ``sensor``), ``visible_after``,
    ``peak_change`` and ``five_sigma_after`` are measured on the contact's own part of the
    noise-free reading: its step from the sensor's temperature at contact through the
    sensor's loop and lag, from rest. The air's flutter and gusts before the contact, which
    the loop and the lag carry on into it, neither make a contact visible nor count towards
    its size.
    """

    taxel: int
    onset: float
    release: float
    material: str
    object_temperature: float
    sensor_temperature: float = float("nan")
    visible_after: float = float("inf")
    peak_change: float = 0.0
    five_sigma_after: float = float("inf")
    bound_after: float = float("inf")
    detectable_after: float = float("inf")
    information: float = 0.0
    onset_sd_bound: float = float("inf")

    @property
    def duration(self) -> float:
        """Length of the contact, s."""
        return self.release - self.onset

    @property
    def direction(self) -> int:
        """-1 if the object was cooler than the taxel (its reading falls), +1 if warmer."""
        return 1 if self.object_temperature > self.sensor_temperature else -1


@dataclass
class Stream:
    """A simulated multi-taxel stream and its truth.

    Attributes
    ----------
    times : numpy.ndarray
        Sample times, s, (n_samples,).
    temperature : numpy.ndarray
        Readings after the ADC, deg C, (n_samples, n_taxels).
    ambient : numpy.ndarray
        Room temperature, deg C, (n_samples,).
    contacts : list of StreamContact
        Every contact, in time order.
    fs : float
        Sampling rate, Hz.
    gusts : list of (start, taxel, depth, rise, hold)
        Every air gust (s, column, K before the sensor's scaling, s, s), in time order.
    switches : list of (time, taxel, duty)
        Every heater duty switch (s, column, duty), in time order (the first of each taxel
        at 0 s).
    templates : list of numpy.ndarray
        With a sensor description: for each contact of ``contacts``, its own noise-free change
        of the reading through the sensor's loop and lag, before smoothing, K (signed), at
        every sample from the first one at or after the onset to the end of the window in
        which an alarm still counts as the contact's (as ``detectable_after`` sees it);
        empty without one.
    raw_noise : float
        With a sensor description: the white noise of a raw sample before the smoothing, K
        (``noise_kelvin`` at the heated taxel's temperature over the stream's ambient, as the
        stream draws it); NaN without one.
    """

    times: np.ndarray
    temperature: np.ndarray
    ambient: np.ndarray
    contacts: list[StreamContact]
    fs: float
    gusts: list[tuple[float, int, float, float, float]] = field(default_factory=list)
    switches: list[tuple[float, int, float]] = field(default_factory=list)
    templates: list[np.ndarray] = field(default_factory=list)
    raw_noise: float = float("nan")

    @property
    def taxel_hours(self) -> float:
        """Observed taxel-hours."""
        return self.temperature.shape[1] * self.times.size / self.fs / 3600.0

    def duty(self) -> np.ndarray:
        """Each taxel's heater duty at each sample, (n_samples, n_taxels), as frames carry it.

        From ``switches`` (NaN before a taxel's first; none on a quiet stream: all NaN).
        """
        out = np.full(self.temperature.shape, np.nan)
        for t, taxel, value in self.switches:
            out[np.searchsorted(self.times, t):, taxel] = value
        return out


def _lag(x: np.ndarray, tau: float, fs: float, start: np.ndarray) -> np.ndarray:
    """First-order lag of ``x`` (n_samples, n) with time constant ``tau``, from ``start``."""
    from scipy.signal import lfilter

    a = np.exp(-1.0 / (tau * fs))
    zi = (a * start)[None, :]
    out, _ = lfilter([1.0 - a], [1.0, -a], x, axis=0, zi=zi)
    return out


def simulate_stream(materials: Sequence[Material], n_taxels: int = 16, duration: float = 600.0,
                    contacts_per_minute: float = 1.0, object_offset: tuple[float, float] = (0, 0),
                    ambient: float = 25.0, fs: float = 200.0, seed: int = 0,
                    disturbances: bool = True, tau: float = 62.5, warm: float = 0.0,
                    warm_margin: tuple[float, float] = (2.0, 25.0),
                    sensor: object | None = None, air: bool = True) -> Stream:
    """Simulate ``n_taxels`` taxels for ``duration`` s; see the module docstring.

    The whole run at once: `stream_chunks` joined (the same arrays, bit for bit).

    Parameters
    ----------
    materials : sequence of Material
        What the contacts touch (drawn uniformly).
    n_taxels : int
        Number of taxels (columns).
    duration : float
        Length of the stream, s.
    contacts_per_minute : float
        Mean rate of contacts per taxel.
    object_offset : tuple of float
        Range of a touched object's temperature above its resting temperature, K.
    ambient : float
        Mean room temperature, deg C.
    fs : float
        Sampling rate, Hz.
    seed : int
        Seed: the same seed gives the same stream.
    disturbances : bool
        Heater switching, ambient drift and air currents (False: a quiet heated taxel).
    tau : float
        The taxel's slowest thermal time constant, s.
    warm : float
        Fraction of the contacts (with materials without a temperature of their own) that touch
        an object hotter than the taxel, in [0, 1].
    warm_margin : tuple of float
        Range of a warm object's temperature above the taxel's at contact, K.
    sensor : skin.models.sensors.SensorDescription or str, optional
        The sensor (see the module docstring); its sample rate replaces ``fs``.
    air : bool
        With ``disturbances``: the air currents (gusts and flutter) too. False keeps the
        heater's switching and the room's drift, and every other draw as it is.

    Returns
    -------
    Stream
    """
    if sensor is not None:
        return _sensor_stream(materials, n_taxels, duration, contacts_per_minute,
                              object_offset, ambient, seed, disturbances, tau, warm,
                              warm_margin, sensor, air)
    parts = list(stream_chunks(materials, n_taxels, duration, contacts_per_minute,
                               object_offset, ambient, fs, seed, disturbances, tau, warm,
                               warm_margin, chunk=max(1, round(duration * fs)), air=air))
    if not parts:  # shorter than one sample
        return Stream(np.zeros(0), np.zeros((0, n_taxels)), np.zeros(0), [], fs)
    truth = [c for p in parts for c in p.contacts]
    truth.sort(key=lambda c: (c.onset, c.taxel))
    return Stream(np.concatenate([p.times for p in parts]),
                  np.concatenate([p.temperature for p in parts]),
                  np.concatenate([p.ambient for p in parts]), truth, fs, parts[0].gusts,
                  parts[0].switches)


def _sensor_stream(materials: Sequence[Material], n_taxels: int, duration: float,
                   contacts_per_minute: float, object_offset: tuple[float, float],
                   ambient: float, seed: int, disturbances: bool, tau: float, warm: float,
                   warm_margin: tuple[float, float], sensor: object, air: bool = True,
                   ) -> Stream:
    """Return the whole stream of a described sensor (see the module docstring)."""
    from dataclasses import replace

    from skin.bench.onset_eval import release_window
    from skin.models.sensors import apply_dynamics, load_sensor, smooth

    sensor = load_sensor(sensor)
    fs = sensor.sample_rate
    rng = np.random.default_rng(seed)
    parts = list(stream_chunks(materials, n_taxels, duration, contacts_per_minute,
                               object_offset, ambient, fs, seed, disturbances, tau, warm,
                               warm_margin, chunk=max(1, round(duration * fs)),
                               sensor=sensor, _rng=rng, air=air))
    if not parts:
        return Stream(np.zeros(0), np.zeros((0, n_taxels)), np.zeros(0), [], fs,
                      raw_noise=sensor.noise_kelvin(ambient + sensor.heated_rise))
    (part,) = parts
    reading = apply_dynamics(part.temperature, sensor, fs, axis=0)  # noise-free still
    raw = sensor.noise_kelvin(ambient + sensor.heated_rise)
    sigma = raw * sensor.smoothing_noise_factor()
    window = release_window(sensor)
    recovery = tau * sensor.reheat_time_constant / load_sensor("paper").reheat_time_constant
    starts: dict[int, list[float]] = {}
    for c in part.contacts:
        starts.setdefault(c.taxel, []).append(c.onset)
    truth = []
    for c in part.contacts:
        k0, k1 = int(np.ceil(c.onset * fs)), min(int(np.ceil(c.release * fs)), len(reading))
        t0 = float(reading[k0 - 1, c.taxel])
        # the contact's own part: its step from the sensor's temperature alone through the
        # loop and the lag, from rest (they are linear: what the air and the heater did
        # before the contact goes on in the reading, and is not the contact's)
        step = part.temperature[k0 - 1:k1, c.taxel] - part.temperature[k0 - 1, c.taxel]
        change = apply_dynamics(step, sensor, fs)
        moved = np.abs(change[1:])
        when = part.times[k0:k1] - c.onset
        # and after the release, within the window an alarm still counts as the contact's
        # (up to the taxel's next contact): the change recovering as the stream makes it
        end = min([c.release + window] + [s for s in starts[c.taxel] if s > c.onset])
        k2 = max(k1, min(int(np.ceil(end * fs)), len(reading)))
        since = part.times[k1:k2] - c.release
        own = np.concatenate([step, (step[-1] if step.size > 1 else 0.0)
                              * recovery_shape(since, recovery)])
        detectable, information = detectability(own, part.times[k0:k2] - c.onset, sensor,
                                                raw, fs)
        template = apply_dynamics(own, sensor, fs)[1:]
        truth.append((replace(c, sensor_temperature=t0,
                             visible_after=_first_at(moved, when, 3.0 * sigma),
                             peak_change=float(moved.max()) if moved.size else 0.0,
                             five_sigma_after=_first_at(moved, when, 5.0 * sigma),
                             bound_after=delay_bound(moved, when, raw, fs),
                             detectable_after=detectable, information=information,
                             onset_sd_bound=onset_bound(change, part.times[k0 - 1:k1] - c.onset,
                                                        raw)), template))
    if sensor.noise > 0:
        reading = reading + rng.normal(0.0, sensor.noise, reading.shape)
    temperature = smooth(adc_readings(reading, rng, sensor.adc_noise, sensor.adc_bits),
                         sensor, axis=0, fs=fs)
    truth.sort(key=lambda ct: (ct[0].onset, ct[0].taxel))
    return Stream(part.times, temperature, part.ambient, [c for c, _ in truth], fs, part.gusts,
                  part.switches, [m for _, m in truth], raw)


def recovery_shape(after: np.ndarray, tau: float) -> np.ndarray:
    """Return the share of a released contact's change left ``after`` s after the release.

    A fast 2 s part and the taxel's slowest mode ``tau`` (s), half each: 1 at the release.
    """
    after = np.asarray(after, dtype=float)
    return 0.5 * np.exp(-after / 2.0) + 0.5 * np.exp(-after / tau)


def detectability(change: np.ndarray, when: np.ndarray, sensor: object, sigma: float,
                  fs: float, false_alarms: float = BOUND_FALSE_ALARMS) -> tuple[float, float]:
    """Return Lorden's bound on a contact's own change and the information it gives, nats.

    Parameters
    ----------
    change : numpy.ndarray
        The contact's own change of the reading before the sensor's loop and lag, K: the
        sample before the onset (0) and then every sample since, as far as the detection may
        come (past the release: the change as it recovers).
    when : numpy.ndarray
        The times of ``change[1:]`` since the onset, s.
    sensor : skin.models.sensors.SensorDescription
        Its loop and lag (`skin.models.sensors.apply_dynamics`) act on ``change``.
    sigma, fs, false_alarms
        As for `delay_bound` (``sigma``: the raw, unsmoothed noise).

    Returns
    -------
    bound : float
        `delay_bound` of the change through the loop and the lag, s since the onset
        (``inf``: not within ``when``).
    information : float
        Its Kullback-Leibler information over all of ``when``, nats (the bound is finite
        when this reaches ``ln(fs 3600 / false_alarms)``).
    """
    from skin.models.sensors import apply_dynamics

    moved = np.abs(apply_dynamics(np.asarray(change, dtype=float), sensor, fs)[1:])
    information = float(np.sum(moved**2) / (2.0 * sigma**2)) if moved.size else 0.0
    return delay_bound(moved, when, sigma, fs, false_alarms), information


def delay_bound(moved: np.ndarray, when: np.ndarray, sigma: float, fs: float,
                false_alarms: float = BOUND_FALSE_ALARMS) -> float:
    """Return Lorden's lower bound on the delay of detecting a change, s after it began.

    A detector that raises ``false_alarms`` per hour on white Gaussian noise of ``sigma`` (K)
    sampled at ``fs`` (Hz) waits on average ``ARL = fs 3600 / false_alarms`` samples between
    false alarms, and cannot react to a change of the mean before the change has given
    ``ln ARL`` nats of Kullback-Leibler information: ``sum(moved**2) / (2 sigma**2)`` over the
    samples since it began (Lorden 1971; Lai 1998 for changes that are not constant). Known
    onset and shape make it reachable at best; ``inf`` if ``moved`` never gives enough.

    Parameters
    ----------
    moved : numpy.ndarray
        The change of the noise-free reading at each sample since the change began, K.
    when : numpy.ndarray
        Those samples' times since it began, s.
    sigma : float
        The raw (unsmoothed) noise of a sample, K.
    fs : float
        Sampling rate, Hz.
    false_alarms : float
        False alarms per hour allowed.
    """
    if not (sigma > 0 and fs > 0 and false_alarms > 0):
        raise ValueError("sigma, fs and false_alarms must be positive")
    information = np.cumsum(np.asarray(moved, dtype=float) ** 2) / (2.0 * sigma**2)
    return _first_at(information, when, float(np.log(fs * 3600.0 / false_alarms)))


def onset_bound(change: np.ndarray, when: np.ndarray, sigma: float) -> float:
    """Return the Cramer-Rao lower bound on the standard deviation of an onset estimate, s.

    The samples read ``A m(t - t0)`` above a known baseline, in white Gaussian noise of
    ``sigma``: ``m`` the contact's own change (its shape known), ``A`` its size (unknown,
    1 in truth), ``t0`` the onset. The Fisher information on ``(t0, A)`` is
    ``[[S(m'm'), -S(m m')], [-S(m m'), S(m m)]] / sigma**2`` (``S`` a sum over the samples,
    ``m'`` the change's time derivative), and the variance of any unbiased estimate of ``t0``
    is at least the first element of its inverse, ``sigma**2 / (S(m'm') - S(m m')**2 /
    S(m m))``. With the baseline and the shape to be found as well, no estimate does better;
    a median absolute error of an efficient estimate is 0.6745 times the bound.

    Parameters
    ----------
    change : numpy.ndarray
        The noise-free change of the reading at each sample, K (signed), from the last
        sample before the onset (0) on.
    when : numpy.ndarray
        Those samples' times since the onset, s, increasing.
    sigma : float
        The raw (unsmoothed) noise of a sample, K.

    Returns
    -------
    float
        The bound, s; ``inf`` if the samples carry no information on the onset (fewer than
        two, or a change that does not move).
    """
    if not sigma > 0:
        raise ValueError("sigma must be positive")
    m = np.asarray(change, dtype=float)
    t = np.asarray(when, dtype=float)
    if m.size < 2 or not np.any(m):
        return float("inf")
    slope = np.gradient(m, t)
    slope[t < 0] = 0.0  # before the onset nothing moves (a one-sided difference would say so)
    mm, md, dd = float(m @ m), float(m @ slope), float(slope @ slope)
    information = dd - md * md / mm
    return float(sigma / np.sqrt(information)) if information > 0 else float("inf")


def _first_at(moved: np.ndarray, when: np.ndarray, level: float) -> float:
    """Return the first ``when`` at which ``moved`` reaches ``level`` (``inf`` if never)."""
    hit = moved >= level
    return float(when[np.argmax(hit)]) if hit.any() else float("inf")


@dataclass
class StreamChunk:
    """Consecutive samples of a simulated stream (`stream_chunks`).

    Attributes
    ----------
    start : int
        Index of the chunk's first sample in the whole stream.
    times, temperature, ambient : numpy.ndarray
        As in `Stream`, for the chunk's samples.
    contacts : list of StreamContact
        The contacts whose first touching sample lies in the chunk, in time order.
    gusts, switches : list
        In the first chunk only: the stream's schedules of gusts and heater switches
        (as `Stream`'s).
    """

    start: int
    times: np.ndarray
    temperature: np.ndarray
    ambient: np.ndarray
    contacts: list[StreamContact]
    gusts: list = field(default_factory=list)
    switches: list = field(default_factory=list)


def _skip_normals(rng: np.random.Generator, count: int, block: int = 1 << 20) -> None:
    """Advance ``rng`` past ``count`` normal draws without holding them."""
    while count > 0:
        rng.standard_normal(min(count, block))
        count -= block


def _fork(rng: np.random.Generator) -> np.random.Generator:
    """Return a generator that goes on from ``rng``'s current state, independently of it."""
    out = np.random.Generator(type(rng.bit_generator)())
    out.bit_generator.state = rng.bit_generator.state
    return out


def stream_chunks(materials: Sequence[Material], n_taxels: int = 16, duration: float = 600.0,
                  contacts_per_minute: float = 1.0,
                  object_offset: tuple[float, float] = (0, 0), ambient: float = 25.0,
                  fs: float = 200.0, seed: int = 0, disturbances: bool = True,
                  tau: float = 62.5, warm: float = 0.0,
                  warm_margin: tuple[float, float] = (2.0, 25.0),
                  chunk: int = 2000, sensor: object | None = None,
                  _rng: np.random.Generator | None = None, air: bool = True,
                  ) -> Iterator[StreamChunk]:
    """Yield the stream of `simulate_stream` in chunks of ``chunk`` samples.

    Memory is bounded by the chunk (times the taxels) and the schedule of events (heater
    switches, gusts, contacts), not by the duration. The chunks joined are the arrays of
    `simulate_stream` bit for bit, whatever ``chunk``: the random draws are made in the order
    of the whole-run form, each kind of draw from its own copy of the generator moved past
    the draws before it (the schedules are drawn up front; the noise row by row).

    Parameters
    ----------
    materials, n_taxels, duration, contacts_per_minute, object_offset, ambient, fs, seed, \
disturbances, tau, warm, warm_margin
        As for `simulate_stream`.
    chunk : int
        Samples per chunk (the last one may be shorter).
    sensor : skin.models.sensors.SensorDescription, optional
        Used by `simulate_stream` only: the chunk's readings are then noise-free and
        before the sensor's loop and lag (it finishes them).

    Yields
    ------
    StreamChunk
    """
    from scipy.signal import lfilter

    if n_taxels < 1 or duration <= 0 or fs <= 0 or contacts_per_minute < 0:
        raise ValueError("n_taxels, duration and fs must be positive, the contact rate >= 0")
    if not materials:
        raise ValueError("simulate_stream needs at least one material")
    if not 0.0 <= warm <= 1.0 or warm_margin[0] < 0 or warm_margin[1] < warm_margin[0]:
        raise ValueError("warm must lie in [0, 1] and warm_margin be a range of margins >= 0")
    if chunk < 1:
        raise ValueError(f"chunk must be at least 1 sample, got {chunk}")
    rng = np.random.default_rng(seed) if _rng is None else _rng
    described = sensor is not None
    scale = 1.0
    trace_of = contact_trace
    if described:
        from skin.models.sensors import contact_reading, load_sensor

        scale = sensor.heated_rise / load_sensor("paper").heated_rise
        tau = tau * sensor.reheat_time_constant / load_sensor("paper").reheat_time_constant
        full_excess = sensor.heated_rise
        held = sensor.heater == "pid"

        def trace_of(since, t0, t_obj, e, s, h):  # the sensor's heater mode in contact too
            return contact_reading(since, t0, t_obj, e, s, h, ambient)
    else:
        sensor = SensorConstants()
        held = False
    n = round(duration * fs)
    if described and chunk < n:
        raise ValueError("a described sensor's stream comes whole (simulate_stream): its loop, "
                         "lag and smoothing span chunks")
    if not described:
        full_excess = float(heated_temperature(ambient, sensor)) - ambient
    switches: list[tuple[int, int, float]] = []  # (sample, taxel, duty), in time order
    gusts: list[tuple[float, int, float, float, float]] = []  # (start, taxel, depth, rise, hold)
    amb_rng = flutter_rng = None
    if disturbances:
        amb_rng = _fork(rng)
        _skip_normals(rng, n)
        for j in range(n_taxels):
            k = 0
            while k < n:
                k_next = k + round(rng.uniform(20.0, 120.0) * fs)
                switches.append((k, j, float(rng.choice([1.0, 0.85, 0.7, 0.55]))))
                k = k_next
            for start in np.cumsum(rng.exponential(60.0, int(duration / 30.0) + 2)):
                if start >= duration:
                    break
                depth, rise, hold = rng.uniform(*GUST_DEPTH), rng.uniform(1.0, 4.0), \
                    rng.uniform(1.0, 8.0)
                gusts.append((float(start), j, depth, rise, hold))
        switches.sort(key=lambda e: e[0])  # stable: a taxel's switches stay in order
        gusts.sort(key=lambda g: g[0])
        flutter_rng = _fork(rng)
        _skip_normals(rng, n * n_taxels)
    # the contacts: what the whole-run form draws, taxel by taxel; the readings come later
    schedule: list[tuple] = []
    for j in range(n_taxels):
        t = 5.0 + rng.exponential(60.0 / max(contacts_per_minute, 1e-9))
        while t < duration - 10.0:
            length = float(np.exp(rng.uniform(np.log(0.1), np.log(5.0))))
            mat = materials[rng.integers(len(materials))]
            offset = rng.uniform(*object_offset) if mat.temperature is None else 0.0
            h = 10.0 ** rng.uniform(*np.log10(mat.conductance_range))
            margin = None
            if warm > 0 and mat.temperature is None and rng.random() < warm:
                margin = rng.uniform(*warm_margin)
            schedule.append((int(np.ceil(t * fs)), j, t, length, mat, offset, h, margin))
            t += length + 10.0 + rng.exponential(60.0 / max(contacts_per_minute, 1e-9))
    schedule.sort(key=lambda c: c[0])
    adc_rng = rng  # the readout noise comes last
    a_lag = np.exp(-1.0 / (tau * fs))
    excess_z = (a_lag * np.full(n_taxels, full_excess))[None, :]
    a_flutter = np.exp(-1.0 / (FLUTTER_TAU * fs))
    flutter_z = (a_flutter * np.zeros(n_taxels))[None, :]
    duty_now = np.ones(n_taxels)
    amb_sum = 0.0
    amb_last = reading_last = None  # the sample before the chunk
    live_gusts: list[tuple[float, int, float, float, float]] = []
    # per taxel, its latest contact: [k0, k1, trace, release time, end reading, gap]
    latest: dict[int, list] = {}
    i_switch = i_gust = i_contact = 0
    for a in range(0, n, chunk):
        b = min(a + chunk, n)
        m = b - a
        times = np.arange(a, b) / fs
        if disturbances:
            # the room drifts at the rate the onset detector assumes by default (written so
            # that it gives 1 / sqrt(600 fs) to the bit at every preset's rate)
            steps = amb_rng.normal(0.0, 1.0 / np.sqrt(fs / AMBIENT_DRIFT), m)
            cum = np.cumsum(np.concatenate(([amb_sum], steps)))[1:]
            amb_sum = cum[-1]
            amb = ambient + cum
        else:
            amb = np.full(m, ambient)
        duty = np.tile(duty_now, (m, 1))
        while i_switch < len(switches) and switches[i_switch][0] < b:
            k, j, value = switches[i_switch]
            duty[k - a:, j] = value
            duty_now[j] = value
            i_switch += 1
        gust = np.zeros((m, n_taxels))
        if disturbances:
            while i_gust < len(gusts) and gusts[i_gust][0] < times[-1]:
                live_gusts.append(gusts[i_gust])
                i_gust += 1
            # a gust long gone adds exactly 0 (its exp underflows): drop it
            live_gusts = [g for g in live_gusts if times[0] - g[0] - g[4] < 750.0 * g[3]]
            for start, j, depth, rise, hold in sorted(live_gusts, key=lambda g: g[1]):
                s = np.maximum(times - start, 0.0)
                shape = np.where(s < hold, 1.0 - np.exp(-s / rise),
                                 (1.0 - np.exp(-hold / rise)) * np.exp(-(s - hold) / rise))
                gust[:, j] -= depth * scale * shape
            flutter = flutter_rng.normal(0.0, FLUTTER * scale, (m, n_taxels))
            flutter, flutter_z = lfilter([1.0 - a_flutter], [1.0, -a_flutter], flutter, axis=0,
                                         zi=flutter_z)
            gust += flutter * np.sqrt(2 * FLUTTER_TAU * fs)
            if not air:  # drawn all the same: every other draw stays as it is
                gust[:] = 0.0
        excess, excess_z = lfilter([1.0 - a_lag], [1.0, -a_lag], full_excess * duty, axis=0,
                                   zi=excess_z)
        free = amb[:, None] + excess + gust
        reading = free.copy()
        for j, c in latest.items():  # the contacts before the chunk: their trace, recovery
            _write_contact(reading, free, times, a, j, c, tau)
        found = []
        while i_contact < len(schedule) and schedule[i_contact][0] < b:
            k0, j, t, length, mat, offset, h, margin = schedule[i_contact]
            i_contact += 1
            amb_at = amb[round(t * fs) - a] if round(t * fs) >= a else amb_last
            t_obj = mat.resting_temperature(float(amb_at)) + offset
            t0 = float(reading[k0 - 1 - a, j] if k0 > a else reading_last[j])
            # a PID loop holds its setpoint (the loop's high-pass keeps the reading there,
            # whatever the un-looped drift): the contact's swing starts from it, added to
            # the un-looped value
            base = ambient + full_excess if held else t0
            if margin is not None:
                t_obj = base + margin
            k1 = int(np.ceil((t + length) * fs))
            since = np.arange(k0, min(k1, n)) / fs - t
            trace = trace_of(since, base, t_obj, mat.effusivity, sensor, h)
            end = float(trace_of(length, base, t_obj, mat.effusivity, sensor, h))
            if held:
                trace, end = trace + (t0 - base), end + (t0 - base)
            change = np.abs(trace - t0) >= VISIBLE
            seen = float(since[np.argmax(change)]) if change.any() else float("inf")
            peak = float(np.max(np.abs(trace - t0))) if k1 > k0 else 0.0
            found.append(StreamContact(j, float(t), float(t + length), mat.name, float(t_obj),
                                       t0, seen, peak))
            latest[j] = [k0, k1, trace, t + length, end, None]
            _write_contact(reading, free, times, a, j, latest[j], tau)
        amb_last, reading_last = amb[-1], reading[-1].copy()
        # a described sensor's readout follows in `simulate_stream`, over the whole stream
        temperature = reading if described else adc_readings(reading, adc_rng, 0.5)
        found.sort(key=lambda c: (c.onset, c.taxel))
        first = a == 0
        yield StreamChunk(a, times, temperature, amb, found,
                          list(gusts) if first else [],
                          [(k / fs, j, d) for k, j, d in switches] if first else [])


def _write_contact(reading: np.ndarray, free: np.ndarray, times: np.ndarray, a: int, j: int,
                   c: list, tau: float) -> None:
    """Write a contact's trace and the recovery after it into the chunk starting at ``a``."""
    k0, k1, trace, release, end, gap = c
    b = a + len(times)
    if k0 < b and k1 > a:
        lo, hi = max(k0, a), min(k1, b)
        reading[lo - a:hi - a, j] = trace[lo - k0:hi - k0]
    if k1 < b:
        lo = max(k1, a)
        if gap is None:  # the first free sample after release sets the gap
            gap = c[5] = end - free[k1 - a, j]
        reading[lo - a:, j] = free[lo - a:, j] + gap * recovery_shape(times[lo - a:] - release,
                                                                      tau)

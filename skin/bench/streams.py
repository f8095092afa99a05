"""Long taxel streams with known contacts and the disturbances a skin lives with.

`simulate_stream` writes what each taxel of a skin reads, at 200 Hz, over minutes to hours of
mostly contact-free time, with every contact's true onset and release recorded. Onset
detectors are judged on it (`skin evaluate-onset`). Per taxel, the free reading is

- **the heater**: the excess over ambient that the heater sustains, following the heater duty
  through the taxel's slowest thermal mode (a first-order lag of `tau`, about 63 s); the duty
  switches at random between levels every 20-120 s (a controller changing its setpoint), so
  the reading drifts by several kelvin over a minute, but slowly;
- **ambient drift**: the room wanders (a random walk of about 1 K per 10 minutes);
- **air currents**: gusts that cool the face by 0.05-0.4 K over 1-4 s and let it recover,
  and a small turbulent flutter (band-limited noise of 0.01 K);
- **the readout**: 0.5 LSB of ADC noise and 10-bit quantisation through the paper's divider.

Contacts of 0.1-5 s (log-uniform) arrive as a Poisson process per taxel, with long
contact-free stretches between them. Each touches a material of the list at its resting
temperature (or a cold or warm object, within ``object_offset``), through a contact
conductance from the material's range; the thermistor follows the closed-form contact
response from the temperature it had. After release, the reading returns to the free reading
with the taxel's recovery (a fast 2 s part and the slow mode), so a taxel reheats after each
contact.

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
noise, ADC and smoothing. ``visible_after`` and ``peak_change`` are then measured on the
noise-free reading after the loop and the lag, with "visible" at 3 of the sensor's per-sample
noise. Without one (None), the stream is exactly the paper's as before.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from skin.models.materials import Material
from skin.models.physics import SensorConstants, contact_trace, heated_temperature
from skin.models.trials import adc_readings

#: A change of the reading that stands out of its noise (about 3 x 0.5 LSB at 39 C), K.
VISIBLE = 0.1
#: How much a gust cools a taxel's face, K (drawn uniformly per gust).
GUST_DEPTH = (0.05, 0.4)


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
    """

    taxel: int
    onset: float
    release: float
    material: str
    object_temperature: float
    sensor_temperature: float = float("nan")
    visible_after: float = float("inf")
    peak_change: float = 0.0

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
    """

    times: np.ndarray
    temperature: np.ndarray
    ambient: np.ndarray
    contacts: list[StreamContact]
    fs: float

    @property
    def taxel_hours(self) -> float:
        """Observed taxel-hours."""
        return self.temperature.shape[1] * self.times.size / self.fs / 3600.0


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
                    sensor: object | None = None) -> Stream:
    """Simulate ``n_taxels`` taxels for ``duration`` s; see the module docstring.

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

    Returns
    -------
    Stream
    """
    if n_taxels < 1 or duration <= 0 or fs <= 0 or contacts_per_minute < 0:
        raise ValueError("n_taxels, duration and fs must be positive, the contact rate >= 0")
    if not materials:
        raise ValueError("simulate_stream needs at least one material")
    if not 0.0 <= warm <= 1.0 or warm_margin[0] < 0 or warm_margin[1] < warm_margin[0]:
        raise ValueError("warm must lie in [0, 1] and warm_margin be a range of margins >= 0")
    rng = np.random.default_rng(seed)
    described = sensor is not None
    scale, visible = 1.0, VISIBLE
    if described:
        from skin.models.sensors import load_sensor

        sensor = load_sensor(sensor)
        paper = load_sensor("paper")
        fs = sensor.sample_rate
        scale = sensor.heated_rise / paper.heated_rise
        tau = tau * sensor.reheat_time_constant / paper.reheat_time_constant
        visible = 3.0 * sensor.noise_kelvin(ambient + sensor.heated_rise) \
            * sensor.smoothing_noise_factor()
    else:
        sensor = SensorConstants()
    n = round(duration * fs)
    times = np.arange(n) / fs
    full_excess = (sensor.heated_rise if described else
                   float(heated_temperature(ambient, sensor)) - ambient)
    amb = np.full(n, ambient)
    duty = np.ones((n, n_taxels))
    gust = np.zeros((n, n_taxels))
    if disturbances:
        amb = ambient + np.cumsum(rng.normal(0.0, 1.0 / np.sqrt(600.0 * fs), n))
        for j in range(n_taxels):
            k = 0
            while k < n:
                k_next = k + round(rng.uniform(20.0, 120.0) * fs)
                duty[k:k_next, j] = rng.choice([1.0, 0.85, 0.7, 0.55])
                k = k_next
            for start in np.cumsum(rng.exponential(60.0, int(duration / 30.0) + 2)):
                if start >= duration:
                    break
                depth, rise, hold = rng.uniform(*GUST_DEPTH), rng.uniform(1.0, 4.0), \
                    rng.uniform(1.0, 8.0)
                s = np.maximum(times - start, 0.0)
                shape = np.where(s < hold, 1.0 - np.exp(-s / rise),
                                 (1.0 - np.exp(-hold / rise)) * np.exp(-(s - hold) / rise))
                gust[:, j] -= depth * scale * shape
        flutter = rng.normal(0.0, 0.01 * scale, (n, n_taxels))
        flutter = _lag(flutter, 0.5, fs, np.zeros(n_taxels)) * np.sqrt(2 * 0.5 * fs)
        gust += flutter
    excess = _lag(full_excess * duty, tau, fs, np.full(n_taxels, full_excess))
    free = amb[:, None] + excess + gust
    reading = free.copy()
    truth: list[StreamContact] = []
    spans: list[tuple[int, int]] = []  # sample range of each contact, for a described sensor
    trace = contact_trace
    if described:
        from skin.models.sensors import contact_reading

        def trace(since, t0, t_obj, e, s, h):  # the sensor's heater mode in contact too
            return contact_reading(since, t0, t_obj, e, s, h, ambient)
    for j in range(n_taxels):
        t = 5.0 + rng.exponential(60.0 / max(contacts_per_minute, 1e-9))
        while t < duration - 10.0:
            length = float(np.exp(rng.uniform(np.log(0.1), np.log(5.0))))
            mat = materials[rng.integers(len(materials))]
            t_obj = mat.resting_temperature(float(amb[round(t * fs)])) + (
                rng.uniform(*object_offset) if mat.temperature is None else 0.0)
            h = 10.0 ** rng.uniform(*np.log10(mat.conductance_range))
            k0 = int(np.ceil(t * fs))
            k1 = int(np.ceil((t + length) * fs))
            t0 = float(reading[k0 - 1, j])
            if warm > 0 and mat.temperature is None and rng.random() < warm:
                t_obj = t0 + rng.uniform(*warm_margin)
            since = times[k0:k1] - t
            reading[k0:k1, j] = trace(since, t0, t_obj, mat.effusivity, sensor, h)
            # after release: back to the free reading, fast at first, then slowly
            end = float(trace(length, t0, t_obj, mat.effusivity, sensor, h))
            after = times[k1:] - (t + length)
            gap = end - free[k1:, j][0] if k1 < n else 0.0
            recovery = gap * (0.5 * np.exp(-after / 2.0) + 0.5 * np.exp(-after / tau))
            reading[k1:, j] = free[k1:, j] + recovery
            change = np.abs(reading[k0:k1, j] - t0) >= VISIBLE
            seen = float(since[np.argmax(change)]) if change.any() else float("inf")
            peak = float(np.max(np.abs(reading[k0:k1, j] - t0))) if k1 > k0 else 0.0
            truth.append(StreamContact(j, float(t), float(t + length), mat.name, float(t_obj),
                                       t0, seen, peak))
            spans.append((k0, k1))
            t += length + 10.0 + rng.exponential(60.0 / max(contacts_per_minute, 1e-9))
    if described:
        from dataclasses import replace

        from skin.models.sensors import apply_dynamics, smooth

        reading = apply_dynamics(reading, sensor, fs, axis=0)
        for i, ((k0, k1), c) in enumerate(zip(spans, truth, strict=True)):
            t0 = float(reading[k0 - 1, c.taxel])
            # measured after the loop and the lag: what the taxel's reading can show
            moved = np.abs(reading[k0:k1, c.taxel] - t0)
            change = moved >= visible
            seen = float(times[k0:k1][np.argmax(change)] - c.onset) if change.any() else np.inf
            truth[i] = replace(c, sensor_temperature=t0, visible_after=seen,
                               peak_change=float(moved.max()) if moved.size else 0.0)
        if sensor.noise > 0:
            reading = reading + rng.normal(0.0, sensor.noise, reading.shape)
        temperature = smooth(adc_readings(reading, rng, sensor.adc_noise, sensor.adc_bits),
                             sensor, axis=0, fs=fs)
    else:
        temperature = adc_readings(reading, rng, 0.5)
    truth.sort(key=lambda c: (c.onset, c.taxel))
    return Stream(times, temperature, amb, truth, fs)

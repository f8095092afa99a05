"""Sensor descriptions: what a heated taxel is, how its heater is driven, and how it is read.

A `SensorDescription` holds everything the physics, the simulators and the onset stages need
to know about one kind of taxel:

- **thermal body**: depth of the thermistor below the contact surface, diffusivity and
  conductivity (or effusivity) of the body, heater area, layer thickness, heater voltage and
  resistance (eqs. 1-2 of the paper), and an optional first-order response ``lag`` of the
  thermistor itself (a bead in epoxy, a sensor behind a cover);
- **heater control** (``heater``):

  ``"constant"``
      constant power, heater behind the thermistor: during a contact window its flux does
      not reach the contact plane (l^2 / alpha is many windows long), so the reading is the
      paper's eq. 5. The paper's sensor.
  ``"pid"``
      a PID loop holds the sensor at a setpoint: the free sensor sits at the setpoint, and the
      loop cancels a contact's deviation with the closed-loop time constant ``control_time``
      (the reading is the eq. 5 deviation, first-order high-passed).
  ``"off-at-contact"``
      the heater is switched off at contact: besides eq. 5, the body's heated excess drains
      towards ambient with the lumped time constant l^2 / alpha.
  ``"on-during-contact"``
      a heater at the contact plane stays on: besides eq. 5, its flux q / A flows into both
      solids, adding 2 q/A sqrt(alpha_s t) e_s / (k_s (e_s + e_o)) ierfc(x / (2 sqrt(alpha_s t)))
      at the thermistor (constant flux at the interface of two semi-infinite solids).

- **readout**: sample rate (20-1000 Hz), ADC bits, ADC noise (counts, before rounding) and a
  white temperature noise (K) before the ADC;
- **smoothing** applied before the library sees the data: ``"none"``, ``"moving-average"``
  (causal, ``smoothing_window`` samples), ``"low-pass"`` (causal second-order Butterworth at
  ``smoothing_cutoff`` Hz) or ``"savgol"`` (non-causal Savitzky-Golay over
  ``smoothing_window`` samples, order ``savgol_order``, as offline logs often are).

Presets ship in ``models/data/sensors.toml`` (``skin sensors`` lists them); ``"paper"`` is the
founding paper's sensor and the default everywhere, and reproduces the library's behaviour
before sensor descriptions existed bit for bit. A user's file has the same form: one
``[[sensors]]`` table per sensor; errors name the file and line.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from skin.errors import SensorError
from skin.formats.datafiles import header_lines, is_number
from skin.models.physics import SensorConstants

HEATER_MODES = ("constant", "pid", "off-at-contact", "on-during-contact")
SMOOTHING_KINDS = ("none", "moving-average", "low-pass", "savgol")
SAMPLE_RATE_RANGE = (20.0, 1000.0)
DEFAULT_SENSOR = "paper"
_ERFC_INV_HALF = 0.4769362762044699  # erfc(z) = 0.5


@dataclass(frozen=True)
class SensorDescription(SensorConstants):
    """One kind of heated taxel (defaults: the paper's sensor).

    The thermal and electrical constants, and the figures derived from them (`effusivity`,
    `reheat_time_constant`), are those of `skin.models.physics.SensorConstants`; a description
    adds the reading's dynamics, the heater's control, the sampling and the smoothing.

    Attributes
    ----------
    name : str
        Preset or user name.
    summary : str
        One line saying what it is.
    depth : float
        Thermistor depth below the contact surface, m.
    diffusivity : float
        Thermal diffusivity of the sensor body, m^2/s.
    conductivity : float
        Thermal conductivity of the sensor body, W/(m K).
    heater_area : float
        Heater area, m^2.
    thickness : float
        Sensor layer thickness l, m.
    heater_voltage, heater_resistance : float
        Heater supply, V, and resistance, ohm (power q = V^2 / R).
    lag : float
        First-order response lag of the thermistor reading, s (0: none).
    heater : str
        One of `HEATER_MODES`.
    control_time : float
        Closed-loop time constant of the ``"pid"`` heater, s.
    setpoint : float or None
        Setpoint of the ``"pid"`` heater above ambient, K; None: the heated steady state.
    sample_rate : float
        Samples per second (20-1000).
    adc_bits : int
        ADC resolution (with the paper's divider).
    adc_noise : float
        ADC noise before rounding, counts (std).
    noise : float
        White temperature noise at the thermistor before the ADC, K (std).
    smoothing : str
        One of `SMOOTHING_KINDS`.
    smoothing_window : int
        Samples of the moving average or the Savitzky-Golay window (odd).
    smoothing_cutoff : float
        Cut-off of the low-pass, Hz.
    savgol_order : int
        Polynomial order of the Savitzky-Golay filter.
    """

    name: str = DEFAULT_SENSOR
    summary: str = field(default="the founding paper's sensor", compare=False)
    lag: float = 0.0
    heater: str = "constant"
    control_time: float = 2.0
    setpoint: float | None = None
    sample_rate: float = 200.0
    adc_bits: int = 10
    adc_noise: float = 0.5
    noise: float = 0.0
    smoothing: str = "none"
    smoothing_window: int = 1
    smoothing_cutoff: float = 10.0
    savgol_order: int = 2

    # -- derived figures -------------------------------------------------------------------
    @property
    def heater_power(self) -> float:
        """Heater power V^2 / R, W (eq. 1)."""
        return self.heater_voltage**2 / self.heater_resistance

    @property
    def heated_rise(self) -> float:
        """Heated steady state above ambient, K (eq. 2), or the PID setpoint."""
        if self.heater == "pid" and self.setpoint is not None:
            return float(self.setpoint)
        return self.heater_power * self.thickness / (self.heater_area * self.conductivity)

    @property
    def depth_time(self) -> float:
        """Time for the thermistor to see half a surface step, x^2 / (4 alpha z^2), s."""
        return self.depth**2 / (4.0 * self.diffusivity * _ERFC_INV_HALF**2)

    @property
    def response_time(self) -> float:
        """Rough half-response time of the reading to a surface step: depth plus lag, s."""
        return self.depth_time + math.log(2.0) * self.lag

    def kelvin_per_count(self, temperature: float = 35.0) -> float:
        """Size of one ADC count at ``temperature`` deg C with the paper's divider, K."""
        from skin.formats.layout import Board
        from skin.stream.calibration import Calibration

        b = Board(adc_bits=self.adc_bits)
        one = np.ones(1)
        cal = Calibration(c0=b.thermistor_c0 * one, c1=b.thermistor_c1 * one,
                          divider_resistor=b.divider_resistor * one,
                          supply_voltage=b.supply_voltage * one,
                          adc_reference=b.adc_reference * one, adc_max=b.adc_max * one)
        c = float(cal.counts(np.array([temperature]))[0])
        hi, _ = cal.temperature(np.array([c + 0.5]))
        lo, _ = cal.temperature(np.array([c - 0.5]))
        return abs(float(hi[0]) - float(lo[0]))

    def noise_kelvin(self, temperature: float = 35.0) -> float:
        """Return the reading noise at ``temperature``, K: noise, ADC noise and rounding."""
        lsb = self.kelvin_per_count(temperature)
        return math.sqrt(self.noise**2 + (self.adc_noise**2 + 1.0 / 12.0) * lsb**2)

    def smoothing_impulse(self) -> np.ndarray:
        """Return the sensor's smoothing filter's impulse response (``[1.0]`` for none).

        The impulse sits in the middle of its window: a non-causal filter spreads both ways.
        """
        if self.smoothing == "none":
            return np.ones(1)
        n = 8 * max(self.smoothing_window, int(self.sample_rate / self.smoothing_cutoff)) + 1
        impulse = np.zeros(n)
        impulse[n // 2] = 1.0
        return smooth(impulse, self)

    def smoothing_noise_factor(self) -> float:
        """Return how much the sensor's smoothing shrinks white noise per sample (rms ratio).

        The root of the sum of squares of the smoothing filter's impulse response (1 for no
        smoothing). Sums over many samples keep the white noise's low-frequency power.
        """
        return float(np.sqrt(np.sum(self.smoothing_impulse() ** 2)))

    def delivered_noise(self, temperature: float = 35.0) -> float:
        """Return the reading noise per sample as delivered, K.

        `noise_kelvin` at ``temperature`` after the sensor's own smoothing
        (`smoothing_noise_factor`).
        """
        return self.noise_kelvin(temperature) * self.smoothing_noise_factor()

    # -- conversions ------------------------------------------------------------------------
    def constants(self) -> SensorConstants:
        """Return the thermal body alone, as plain `skin.models.physics.SensorConstants`."""
        return SensorConstants(depth=self.depth, diffusivity=self.diffusivity,
                               conductivity=self.conductivity, heater_area=self.heater_area,
                               thickness=self.thickness, heater_voltage=self.heater_voltage,
                               heater_resistance=self.heater_resistance)

    def with_body(self, **changes: float) -> SensorDescription:
        """Return a copy with some constants changed (``depth=...``), checked."""
        return check_sensor(replace(self, **changes))

    def at_rate(self, fs: float, where: str = "the recording") -> SensorDescription:
        """Return the sensor sampled at ``fs`` instead (itself when it already is).

        Only a sensor without smoothing can be re-rated: a moving average or a
        Savitzky-Golay window is counted in samples and a low-pass cutoff must stay below
        half the rate, so a smoothed recording at another rate needs its own description.

        Raises
        ------
        SensorError
            Naming ``where`` and its rate: outside `SAMPLE_RATE_RANGE`, or a smoothed sensor.
        """
        if fs == self.sample_rate:
            return self
        lo, hi = SAMPLE_RATE_RANGE
        if not (is_number(fs) and lo <= fs <= hi):
            raise SensorError(f"{where} is sampled at {fs:g} Hz, outside the {lo:g}-{hi:g} Hz "
                              f"a sensor description takes")
        if self.smoothing != "none":
            raise SensorError(f"{where} is sampled at {fs:g} Hz and sensor {self.name!r} is "
                              f"described at {self.sample_rate:g} Hz with {self.smoothing} "
                              f"smoothing: describe the sensor at {fs:g} Hz (a sensor file, "
                              f"sample_rate = {fs:g}, its smoothing as the recording has it)")
        return check_sensor(replace(self, sample_rate=float(fs)))

    def board_fields(self) -> dict[str, float | int]:
        """Return the layout `Board` fields this sensor sets."""
        return {"sensor_depth": self.depth, "sensor_diffusivity": self.diffusivity,
                "sensor_conductivity": self.conductivity, "heater_area": self.heater_area,
                "sensor_thickness": self.thickness, "heater_voltage": self.heater_voltage,
                "heater_resistance": self.heater_resistance, "adc_bits": self.adc_bits,
                "sample_rate": self.sample_rate}

    @classmethod
    def from_board(cls, board: Any) -> SensorDescription:
        """Return the sensor of a `skin.formats.layout.Board`: its named preset, its constants.

        A board with no ``sensor`` is the paper's sensor with the board's constants.
        """
        name = getattr(board, "sensor", "") or DEFAULT_SENSOR
        base = load_sensor(name)
        return replace(base, depth=board.sensor_depth, diffusivity=board.sensor_diffusivity,
                       conductivity=board.sensor_conductivity, heater_area=board.heater_area,
                       thickness=board.sensor_thickness, heater_voltage=board.heater_voltage,
                       heater_resistance=board.heater_resistance, adc_bits=board.adc_bits,
                       sample_rate=board.sample_rate)

    def to_dict(self) -> dict[str, Any]:
        """All fields and the derived figures, for ``--json``."""
        out = asdict(self)
        out.update(effusivity=self.effusivity, response_time=self.response_time,
                   heated_rise=self.heated_rise, noise_kelvin=self.noise_kelvin())
        return out


# -- the reading model ---------------------------------------------------------------------
def ierfc(z: np.ndarray) -> np.ndarray:
    """Integrated complementary error function exp(-z^2)/sqrt(pi) - z erfc(z) (z >= 0)."""
    from scipy.special import erfc

    z = np.asarray(z, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        out = np.exp(-(z**2)) / np.sqrt(np.pi) - z * erfc(z)
    return np.where(np.isinf(z), 0.0, np.maximum(out, 0.0))


def heater_term(t: np.ndarray | float, t_sensor: np.ndarray | float,
                e_object: np.ndarray | float, sensor: SensorDescription,
                ambient: np.ndarray | float | None = None,
                response: np.ndarray | float = 0.0) -> np.ndarray | float:
    """Return what the heater adds to eq. 5 at the thermistor t s after contact, K.

    0 for a ``"constant"`` or ``"pid"`` heater (the loop acts in `apply_dynamics`).
    ``"off-at-contact"``: the heated excess drains towards ``ambient`` (default: the heated
    steady state below ``t_sensor``) with l^2 / alpha; ``"on-during-contact"``: the flux q / A
    at the contact plane, shared by the two solids by effusivity (see the module docstring).

    ``response`` is the contact's own normalised response R at t (eq. 5's fraction of the step
    from the sensor to the object reached at the thermistor, 0..1; `contact_reading` gives it):
    a drained body pulls the thermistor only by the (1 - R) it still owes the body, as eq. 5
    with the body's draining temperature in place of ``t_sensor`` (quasi-static: l^2 / alpha
    is many times the contact's own response). So the reading stays between the body's
    temperature and the object's, never below both. 0 (default): the free body's drain.
    """
    if sensor.heater in ("constant", "pid"):
        return 0.0
    t = np.asarray(t, dtype=float)
    pos = t > 0
    safe = np.where(pos, t, 1.0)
    if sensor.heater == "off-at-contact":
        t0 = np.asarray(t_sensor, dtype=float)
        amb = t0 - sensor.heated_rise if ambient is None else np.asarray(ambient, dtype=float)
        drain = (amb - t0) * -np.expm1(-safe / sensor.reheat_time_constant)
        return np.where(pos, drain * (1.0 - np.asarray(response, dtype=float)), 0.0)
    e_s = sensor.effusivity
    share = e_s / (e_s + np.asarray(e_object, dtype=float))
    root = np.sqrt(sensor.diffusivity * safe)
    rise = (2.0 * sensor.heater_power / sensor.heater_area * share / sensor.conductivity * root
            * ierfc(sensor.depth / (2.0 * root)))
    return np.where(pos, rise, 0.0)


def contact_reading(t: np.ndarray | float, t_sensor: np.ndarray | float,
                    t_object: np.ndarray | float, e_object: np.ndarray | float,
                    sensor: SensorDescription, conductance: np.ndarray | float = np.inf,
                    ambient: np.ndarray | float | None = None) -> np.ndarray:
    """Temperature at the thermistor t s after contact, with the sensor's heater mode.

    Before `apply_dynamics` (the lag and the PID loop act on whole series). For a
    ``"constant"`` or ``"pid"`` heater this is `skin.models.physics.contact_trace` exactly.

    Parameters
    ----------
    t : array_like
        Time since contact, s (the reading is ``t_sensor`` for t <= 0).
    t_sensor, t_object : array_like
        Sensor and object temperatures at contact, deg C.
    e_object : array_like
        Object effusivity.
    sensor : SensorDescription
        The sensor.
    conductance : array_like
        Contact conductance h, W/(m^2 K).
    ambient : array_like, optional
        Ambient temperature, deg C (see `heater_term`).
    """
    from skin.models.physics import contact_trace

    y = contact_trace(t, t_sensor, t_object, e_object, sensor, conductance)
    if sensor.heater in ("constant", "pid"):
        return y
    # eq. 5 is linear in the step: its unit response is the share the object holds
    share = (contact_trace(t, 0.0, 1.0, e_object, sensor, conductance)
             if sensor.heater == "off-at-contact" else 0.0)
    return y + heater_term(t, t_sensor, e_object, sensor, ambient, response=share)


def _first_order(y: np.ndarray, a: float, axis: int) -> np.ndarray:
    """Low-pass y[k] = a y[k-1] + (1 - a) x[k], starting settled at the first sample."""
    from scipy.signal import lfilter

    y = np.asarray(y, dtype=float)
    first = np.take(y, [0], axis=axis)
    out = lfilter([1.0 - a], [1.0, -a], y - first, axis=axis)
    return out + first


def apply_dynamics(y: np.ndarray, sensor: SensorDescription, fs: float | None = None,
                   axis: int = -1) -> np.ndarray:
    """Apply the PID loop (``"pid"`` heater) and the thermistor lag to readings over time.

    The series starts settled at its first sample. Returns ``y`` itself when the sensor has
    neither (the paper's sensor).
    """
    fs = sensor.sample_rate if fs is None else fs
    out = np.asarray(y, dtype=float)
    if sensor.heater == "pid":
        a = math.exp(-1.0 / (fs * sensor.control_time))
        first = np.take(out, [0], axis=axis)
        out = out - (_first_order(out, a, axis) - first)  # the loop cancels the slow part
    if sensor.lag > 0:
        out = _first_order(out, math.exp(-1.0 / (fs * sensor.lag)), axis)
    return out


def _moving_average(x: np.ndarray, n: int, start: int) -> np.ndarray:
    """Causal mean of ``n`` samples along axis 0 for rows ``start:`` of ``x``.

    The rows before ``start`` are the samples before (as many as there are, up to n - 1);
    the series starts at row 0 with zeros before it. Each output sums its terms in the same
    order wherever the series is cut, so chunks give the whole series' output bit for bit.
    """
    w = 1.0 / n
    out = w * x[start:]
    for j in range(1, n):
        lo = max(start, j)  # rows whose sample j back exists
        if lo < x.shape[0]:
            out[lo - start:] += w * x[lo - j:x.shape[0] - j]
    return out


def smooth(y: np.ndarray, sensor: SensorDescription, axis: int = -1,
           fs: float | None = None) -> np.ndarray:
    """Apply the sensor's smoothing to readings over time (``y`` itself for ``"none"``)."""
    from scipy import signal

    fs = sensor.sample_rate if fs is None else fs
    kind = sensor.smoothing
    if kind == "none":
        return y
    y = np.asarray(y, dtype=float)
    first = np.take(y, [0], axis=axis)
    if kind == "moving-average":
        x = np.moveaxis(y - first, axis, 0)
        return np.moveaxis(_moving_average(x, sensor.smoothing_window, 0), 0, axis) + first
    if kind == "low-pass":
        sos = signal.butter(2, sensor.smoothing_cutoff, fs=fs, output="sos")
        return signal.sosfilt(sos, y - first, axis=axis) + first
    return signal.savgol_filter(y, sensor.smoothing_window, sensor.savgol_order, axis=axis,
                                mode="interp")


def has_dynamics(sensor: SensorConstants) -> bool:
    """Whether a sensor reads other than eq. 5 of its constants (`contact_basis` needed).

    False for plain `skin.models.physics.SensorConstants` and for a constant-power heater
    without lag or smoothing (the paper's sensor).
    """
    return isinstance(sensor, SensorDescription) and (
        sensor.heater != "constant" or sensor.lag > 0 or sensor.smoothing != "none")


def contact_basis(lags: np.ndarray, e_object: np.ndarray | float,
                  conductance: np.ndarray | float, sensor: SensorDescription,
                  ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Return the parts of a contact reading that the temperatures scale, after filtering.

    What the library sees of a contact (`contact_reading`, then `apply_dynamics` and `smooth`
    over a series settled before the contact) is affine in the sensor's, the object's and the
    room's temperatures, because every filter is linear and time-invariant and keeps a
    constant::

        y = T0 + (T_obj - T0) P + (T_amb - T0) Q + A

    ``P`` is the filtered unit response (the object's share times eq. 5's response R), ``Q``
    the filtered drain of an ``"off-at-contact"`` heater (`heater_term` with unit excess:
    (1 - exp(-t / tau)) (1 - P) before filtering) and ``A`` the filtered flux of an
    ``"on-during-contact"`` heater (it depends on the object's effusivity alone). They are
    computed on the sensor's own sample grid from the contact instant (a sample there, as the
    simulators place it), filtered, and read at ``lags`` by linear interpolation; a
    non-causal smoothing moves the reading before contact too (negative lags).

    Parameters
    ----------
    lags : numpy.ndarray
        Time since contact, s, (n_lags,).
    e_object, conductance : array_like
        Object effusivity and contact conductance, broadcast together (for example
        (n_classes, 1) and (n_classes, n_h)).
    sensor : SensorDescription
        The sensor (its sample rate sets the grid the filters run on).

    Returns
    -------
    P : numpy.ndarray
        (broadcast shape of e_object and conductance, n_lags).
    Q : numpy.ndarray or None
        Same shape; None unless the heater is ``"off-at-contact"``.
    A : numpy.ndarray or None
        (shape of e_object, n_lags) in K; None unless the heater is ``"on-during-contact"``.
    """
    from skin.models.physics import contact_trace

    lags = np.asarray(lags, dtype=float)
    fs = float(sensor.sample_rate)
    savgol = sensor.smoothing == "savgol"
    # settled samples before the contact: a Savitzky-Golay window's edge fit must see none
    # of it; as many after the last lag, so that no lag is read from the series' end
    pre = sensor.smoothing_window + 1 if savgol else 1
    post = sensor.smoothing_window + 1 if savgol else 1
    top = max(int(np.ceil(max(float(lags.max(initial=0.0)), 0.0) * fs)), 1) + post
    # time on the first axis: the filters then run over contiguous rows
    tk = (np.arange(-pre, top + 1) / fs).reshape(-1, *(1,) * len(np.broadcast_shapes(
        np.shape(e_object), np.shape(conductance))))
    e = np.asarray(e_object, dtype=float)
    p = contact_trace(tk, 0.0, 1.0, e, sensor, np.asarray(conductance, dtype=float))
    parts: list[np.ndarray | None] = [p, None, None]
    if sensor.heater == "off-at-contact":
        parts[1] = np.asarray(heater_term(tk, 0.0, e, sensor, ambient=1.0, response=p))
    elif sensor.heater == "on-during-contact":
        parts[2] = np.asarray(heater_term(tk, 0.0, e, sensor))
    pos = lags * fs + pre
    i0 = np.clip(np.floor(pos).astype(int), 0, tk.size - 2)
    w = np.clip(pos - i0, 0.0, 1.0)
    out = []
    for x in parts:
        if x is not None:
            x = smooth(apply_dynamics(x, sensor, fs, axis=0), sensor, axis=0, fs=fs)
            x = np.ascontiguousarray(np.moveaxis(
                x[i0] * (1.0 - w).reshape(-1, *(1,) * (x.ndim - 1))
                + x[i0 + 1] * w.reshape(-1, *(1,) * (x.ndim - 1)), 0, -1))
        out.append(x)
    return out[0], out[1], out[2]


class StreamingDynamics:
    """`apply_dynamics` over a series given in consecutive chunks along axis 0.

    Each chunk's output is that of `apply_dynamics` on the whole series, bit for bit: the
    filters keep their state between chunks and the series' first sample.
    """

    def __init__(self, sensor: SensorDescription, fs: float | None = None) -> None:
        fs = sensor.sample_rate if fs is None else fs
        self._pid = (math.exp(-1.0 / (fs * sensor.control_time)) if sensor.heater == "pid"
                     else None)
        self._lag = math.exp(-1.0 / (fs * sensor.lag)) if sensor.lag > 0 else None
        self._state: list[Any] = [None, None]  # per filter: (first sample, lfilter state)

    def _first_order(self, i: int, y: np.ndarray, a: float) -> np.ndarray:
        from scipy.signal import lfilter

        if self._state[i] is None:
            self._state[i] = (y[:1].copy(), np.zeros((1, *y.shape[1:])))
        first, zi = self._state[i]
        out, zf = lfilter([1.0 - a], [1.0, -a], y - first, axis=0, zi=zi)
        self._state[i] = (first, zf)
        return out + first

    def push(self, y: np.ndarray) -> np.ndarray:
        """Return the dynamics' output for the next chunk ``y`` (n_samples, ...)."""
        out = np.asarray(y, dtype=float)
        if out.shape[0] == 0:
            return out
        if self._pid is not None:
            fo = self._first_order(0, out, self._pid)
            out = out - (fo - self._state[0][0])
        if self._lag is not None:
            out = self._first_order(1, out, self._lag)
        return out


class StreamingSmoother:
    """`smooth` over a series given in consecutive chunks along axis 0.

    `push` returns the rows that are final, `finish` the rest: the rows joined are `smooth`
    of the whole series bit for bit. Causal smoothing returns each chunk at once; the
    non-causal Savitzky-Golay holds back half a window (and the first window).
    """

    def __init__(self, sensor: SensorDescription, fs: float | None = None) -> None:
        from scipy import signal

        self.sensor = sensor
        self.kind = sensor.smoothing
        fs = sensor.sample_rate if fs is None else fs
        self._first: np.ndarray | None = None
        self._zi: np.ndarray | None = None
        if self.kind == "low-pass":
            self._sos = signal.butter(2, sensor.smoothing_cutoff, fs=fs, output="sos")
        self._buf: np.ndarray | None = None  # savgol: rows kept, from ``_buf_start``
        self._buf_start = 0
        self._done = 0  # savgol: rows returned so far

    def push(self, y: np.ndarray) -> np.ndarray:
        """Smooth the next chunk ``y`` (n_samples, ...); return the rows now final."""
        from scipy import signal

        if self.kind == "none":
            return y
        y = np.asarray(y, dtype=float)
        if self.kind == "savgol":
            self._buf = y if self._buf is None else np.concatenate([self._buf, y])
            return self._savgol(final=False)
        if y.shape[0] == 0:
            return y
        if self._first is None:
            self._first = y[:1].copy()
        if self.kind == "moving-average":
            x = y - self._first
            hist = x[:0] if self._zi is None else self._zi
            ext = np.concatenate([hist, x])
            out = _moving_average(ext, self.sensor.smoothing_window, hist.shape[0])
            self._zi = ext[max(0, ext.shape[0] - (self.sensor.smoothing_window - 1)):]
        else:
            if self._zi is None:
                self._zi = np.zeros((self._sos.shape[0], 2, *y.shape[1:]))
            out, self._zi = signal.sosfilt(self._sos, y - self._first, axis=0, zi=self._zi)
        return out + self._first

    def finish(self) -> np.ndarray | None:
        """Return the rows held back (None if none are)."""
        if self.kind != "savgol" or self._buf is None:
            return None
        return self._savgol(final=True)

    def _savgol(self, final: bool) -> np.ndarray:
        """Return the rows whose window lies in the buffer (all of them at the end)."""
        from scipy import signal

        w = self.sensor.smoothing_window
        buf = self._buf
        stop = buf.shape[0] if final else buf.shape[0] - w // 2
        first = self._done - self._buf_start
        if buf.shape[0] < w or stop <= first:
            if final and buf.shape[0] - first > 0:  # shorter than a window: as `smooth` fails
                signal.savgol_filter(buf, w, self.sensor.savgol_order, axis=0, mode="interp")
            return buf[:0]
        # interior rows depend on their window alone; edge rows are fitted to the first or
        # last window of the series, which the buffer holds when they are returned
        out = signal.savgol_filter(buf, w, self.sensor.savgol_order, axis=0,
                                   mode="interp")[first:stop]
        self._done += stop - first
        keep = max(0, self._done - (w - 1) - self._buf_start)
        self._buf = buf[keep:]
        self._buf_start += keep
        return out


# -- files -----------------------------------------------------------------------------------
_FIELDS = {f.name: f.type for f in fields(SensorDescription)}
_POSITIVE = ("depth", "diffusivity", "conductivity", "heater_area", "thickness",
             "heater_voltage", "heater_resistance", "control_time", "smoothing_cutoff")
_NON_NEGATIVE = ("lag", "adc_noise", "noise")


def check_sensor(s: SensorDescription, where: str = "") -> SensorDescription:
    """Validate a description; raise `SensorError` naming ``where`` and the field."""
    pre = f"{where}: " if where else ""
    for name in _POSITIVE:
        v = getattr(s, name)
        if not (is_number(v) and v > 0):
            raise SensorError(f"{pre}field {name!r} must be a positive number, got {v!r}")
    for name in _NON_NEGATIVE:
        v = getattr(s, name)
        if not (is_number(v) and v >= 0):
            raise SensorError(f"{pre}field {name!r} must be a number >= 0, got {v!r}")
    lo, hi = SAMPLE_RATE_RANGE
    if not (is_number(s.sample_rate) and lo <= s.sample_rate <= hi):
        raise SensorError(f"{pre}field 'sample_rate' must be within {lo:g}-{hi:g} Hz, "
                          f"got {s.sample_rate!r}")
    if not (isinstance(s.adc_bits, int) and 8 <= s.adc_bits <= 24):
        raise SensorError(f"{pre}field 'adc_bits' must be an integer within 8-24, "
                          f"got {s.adc_bits!r}")
    if s.heater not in HEATER_MODES:
        raise SensorError(f"{pre}field 'heater' must be one of {', '.join(HEATER_MODES)}, "
                          f"got {s.heater!r}")
    if s.setpoint is not None and not (is_number(s.setpoint) and s.setpoint > 0):
        raise SensorError(f"{pre}field 'setpoint' must be a positive rise above ambient, K, "
                          f"got {s.setpoint!r}")
    if s.smoothing not in SMOOTHING_KINDS:
        raise SensorError(f"{pre}field 'smoothing' must be one of {', '.join(SMOOTHING_KINDS)},"
                          f" got {s.smoothing!r}")
    w, order = s.smoothing_window, s.savgol_order
    if not (isinstance(w, int) and w >= 1):
        raise SensorError(f"{pre}field 'smoothing_window' must be a positive integer, got {w!r}")
    if s.smoothing == "savgol" and not (isinstance(order, int) and 0 <= order < w and w % 2):
        raise SensorError(f"{pre}a Savitzky-Golay window must be odd and longer than its "
                          f"order (smoothing_window {w}, savgol_order {order})")
    if s.smoothing == "low-pass" and not s.smoothing_cutoff < s.sample_rate / 2:
        raise SensorError(f"{pre}field 'smoothing_cutoff' ({s.smoothing_cutoff:g} Hz) must be "
                          f"below half the sample rate ({s.sample_rate / 2:g} Hz)")
    return s


def _parse_one(raw: Any, where: str) -> SensorDescription:
    if not isinstance(raw, dict):
        raise SensorError(f"{where}: a sensor must be a table")
    raw = dict(raw)
    unknown = set(raw) - set(_FIELDS) - {"effusivity"}
    if unknown:
        raise SensorError(f"{where}: unknown field {sorted(unknown)[0]!r} (known: "
                          f"{', '.join(sorted(set(_FIELDS) | {'effusivity'}))})")
    name = raw.get("name")
    if not isinstance(name, str) or not name:
        raise SensorError(f"{where}: missing field 'name'")
    where = f"{where} ({name})"
    if "effusivity" in raw:
        if "conductivity" in raw:
            raise SensorError(f"{where}: give 'effusivity' or 'conductivity', not both")
        e = raw.pop("effusivity")
        alpha = raw.get("diffusivity", SensorDescription.diffusivity)
        if not (is_number(e) and e > 0 and is_number(alpha) and alpha > 0):
            raise SensorError(f"{where}: field 'effusivity' must be a positive number, "
                              f"got {e!r}")
        raw["conductivity"] = float(e) * math.sqrt(float(alpha))
    for key, value in raw.items():
        typ = _FIELDS[key]
        if typ == "str" and not isinstance(value, str):
            raise SensorError(f"{where}: field {key!r} must be a string, got {value!r}")
        if typ == "int" and (not isinstance(value, int) or isinstance(value, bool)):
            raise SensorError(f"{where}: field {key!r} must be an integer, got {value!r}")
        if "float" in typ:
            if not is_number(value):
                raise SensorError(f"{where}: field {key!r} must be a finite number, "
                                  f"got {value!r}")
            raw[key] = float(value)
    return check_sensor(SensorDescription(**raw), where)


def parse_sensors(text: str, source: str = "<string>") -> dict[str, SensorDescription]:
    """Parse sensor TOML (one ``[[sensors]]`` table each); errors name the file and line."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SensorError(f"{source}: not valid TOML: {exc}") from None
    tables = data.get("sensors")
    if not isinstance(tables, list) or not tables:
        raise SensorError(f"{source}: no sensors: add one [[sensors]] table per sensor")
    lines = header_lines(text, "sensors")
    out: dict[str, SensorDescription] = {}
    for k, raw in enumerate(tables):
        where = f"{source}:{lines[k] if k < len(lines) else 0}: sensor #{k}"
        s = _parse_one(raw, where)
        if s.name in out:
            raise SensorError(f"{where}: duplicate sensor name {s.name!r}")
        out[s.name] = s
    return out


def load_sensors(path: str | Path | None = None) -> dict[str, SensorDescription]:
    """Load the shipped presets (no path) or a user's sensor file, by name."""
    if path is None:
        res = resources.files("skin.models") / "data" / "sensors.toml"
        return parse_sensors(res.read_text(encoding="utf-8"), "sensors.toml")
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise SensorError(f"{path}: cannot read sensor file: {exc.strerror}") from None
    return parse_sensors(text, str(path))


def load_sensor_field(ref: object, base: Path | None) -> tuple[SensorDescription, str]:
    """Resolve a file's ``sensor`` field: a preset name or a sensor file relative to ``base``.

    Returns
    -------
    (SensorDescription, str)
        The sensor and the reference as resolved (a relative file joined to ``base``).

    Raises
    ------
    SensorError
        When the field is not a non-empty string or names no sensor.
    """
    if not isinstance(ref, str) or not ref:
        raise SensorError("must be a preset name or a sensor file")
    path = Path(ref.partition("#")[0])
    if base is not None and path.suffix and not path.is_absolute():
        ref = str(base / ref)
    return load_sensor(ref), ref


def load_sensor(ref: str | Path | SensorDescription | None = None) -> SensorDescription:
    """Resolve a sensor: a description, a preset name, a file (one sensor) or ``FILE#NAME``.

    None gives the paper's sensor.
    """
    if isinstance(ref, SensorDescription):
        return ref
    if ref is None:
        ref = DEFAULT_SENSOR
    text = str(ref)
    path, _, name = text.partition("#")
    p = Path(path)
    if not p.suffix and len(p.parts) == 1 and not p.is_file():
        presets = load_sensors()
        if text not in presets:
            raise SensorError(f"no sensor file {text!r} and no preset of that name (presets: "
                              f"{', '.join(presets)})")
        return presets[text]
    found = load_sensors(p)
    if name:
        if name not in found:
            raise SensorError(f"{path}: no sensor {name!r} (has: {', '.join(found)})")
        return found[name]
    if len(found) > 1:
        raise SensorError(f"{path}: holds {len(found)} sensors ({', '.join(found)}); "
                          f"name one as {path}#NAME")
    return next(iter(found.values()))

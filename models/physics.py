"""The paper's heat-transfer model: sensor and object as two semi-infinite solids (eqs. 1-11).

Forward::

    q = V^2 / R                                            (1)
    T_sens(0) = T_amb + q l / (A k_s)                      (2)
    T_surf = (e_s T_sens(0) + e_o T_obj) / (e_s + e_o)     (3), e = k / sqrt(alpha)
    T(x, t) = T_sens(0) + (T_surf - T_sens(0)) erfc(x / (2 sqrt(alpha_s t)))   (5)

With a finite contact conductance h (W/(m^2 K)) between the two surfaces (Carslaw and Jaeger's
composite solid with contact resistance, solved by Laplace transform), the thermistor reads::

    T(x, t) = T_sens(0) + (T_surf - T_sens(0)) R(x, t),
    R = exp(-xi^2) (erfcx(xi) - erfcx(xi + H sqrt(t))),   xi = x / (2 sqrt(alpha_s t)),
    H = h (e_s + e_o) / (e_s e_o),

which is eq. 5 as h -> infinity (erfcx -> 0) and no heat flow at h = 0. The scaled
complementary error function erfcx(z) = exp(z^2) erfc(z) keeps it finite where exp(h x + h^2 t)
would overflow. Both surfaces approach T_surf as 1 - erfcx(H sqrt(t)).

Inverse (pointwise, eqs. 10-11): from one reading T(x, t) recover T_surf, then the object's
effusivity ``e_o = e_s (T_sens(0) - T_surf) / (T_surf - T_obj)``.  It is undefined at t -> 0
(erfc -> 0 amplifies noise without bound), when the surface sits at the object's temperature,
and when the sensor starts at the object's temperature; such samples are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.special import erfc, erfcx

if TYPE_CHECKING:
    from skin.models.materials import Material

#: Forward models of one contact's trace (`material_trace`).
TRACE_MODELS = ("semi-infinite", "contact", "multilayer")


@dataclass(frozen=True)
class SensorConstants:
    """Thermal and electrical constants of one heated taxel (defaults: the paper's sensor)."""

    depth: float = 8e-5
    diffusivity: float = 2.796e-9
    conductivity: float = 0.0349
    heater_area: float = 1.5625e-4
    thickness: float = 2.4e-4
    heater_voltage: float = 2.5
    heater_resistance: float = 19.7

    @property
    def effusivity(self) -> float:
        """Sensor effusivity k / sqrt(alpha), W s^0.5 / (m^2 K)."""
        return self.conductivity / np.sqrt(self.diffusivity)

    @property
    def reheat_time_constant(self) -> float:
        """Lumped time constant l^2 / alpha of the sensor layer, s (the simple simulator)."""
        return self.thickness**2 / self.diffusivity

    @classmethod
    def from_board(cls, board: object) -> SensorConstants:
        """Take the constants from a `skin.formats.layout.Board`."""
        return cls(
            depth=board.sensor_depth,
            diffusivity=board.sensor_diffusivity,
            conductivity=board.sensor_conductivity,
            heater_area=board.heater_area,
            thickness=board.sensor_thickness,
            heater_voltage=board.heater_voltage,
            heater_resistance=board.heater_resistance,
        )


def effusivity(k: np.ndarray | float, rho: np.ndarray | float, c: np.ndarray | float) -> np.ndarray:
    """Thermal effusivity sqrt(k rho c), W s^0.5 / (m^2 K)."""
    return np.sqrt(np.asarray(k, dtype=float) * rho * c)


def heated_temperature(ambient: np.ndarray | float, sensor: SensorConstants) -> np.ndarray:
    """Steady sensor temperature with the heater on, deg C (eqs. 1-2)."""
    q = sensor.heater_voltage**2 / sensor.heater_resistance
    return np.asarray(ambient, dtype=float) + q * sensor.thickness / (
        sensor.heater_area * sensor.conductivity
    )


def contact_temperature(
    t_sensor: np.ndarray | float,
    t_object: np.ndarray | float,
    e_sensor: np.ndarray | float,
    e_object: np.ndarray | float,
) -> np.ndarray:
    """Interface temperature of two semi-infinite solids brought into contact (eq. 3).

    Written as ``T_obj + (T_sens - T_obj) e_s / (e_s + e_o)``, which keeps the limits: an
    object of infinite effusivity holds the surface at its own temperature (no inf / inf).
    """
    e_s = np.asarray(e_sensor, dtype=float)
    e_o = np.asarray(e_object, dtype=float)
    t_o = np.asarray(t_object, dtype=float)
    return t_o + (np.asarray(t_sensor, dtype=float) - t_o) * (e_s / (e_s + e_o))


def depth_response(t: np.ndarray | float, sensor: SensorConstants) -> np.ndarray:
    """Fraction of the surface step seen at the thermistor, erfc(x / (2 sqrt(alpha t))).

    Zero for t <= 0 (before contact), rising towards 1.
    """
    t = np.asarray(t, dtype=float)
    safe = np.where(t > 0, t, 1.0)
    return np.where(t > 0, erfc(sensor.depth / (2.0 * np.sqrt(sensor.diffusivity * safe))), 0.0)


def thermistor_temperature(
    t: np.ndarray | float,
    t_sensor: np.ndarray | float,
    t_surface: np.ndarray | float,
    sensor: SensorConstants,
) -> np.ndarray:
    """Return the thermistor reading at depth x, t seconds after contact (eq. 5)."""
    return t_sensor + (np.asarray(t_surface) - t_sensor) * depth_response(t, sensor)


def effusivity_estimates(
    t: np.ndarray,
    temperature: np.ndarray,
    t_sensor: float,
    t_object: float,
    sensor: SensorConstants,
    min_response: float = 0.02,
    min_difference: float = 0.05,
) -> tuple[np.ndarray, np.ndarray]:
    """Pointwise effusivity estimates of the object (eqs. 10-11), with undefined samples dropped.

    Parameters
    ----------
    t : numpy.ndarray
        Time since contact onset of each sample, s.
    temperature : numpy.ndarray
        Thermistor readings, deg C.
    t_sensor : float
        Sensor temperature just before contact, deg C.
    t_object : float
        Object temperature, deg C (the paper: ambient).
    sensor : SensorConstants
        Sensor constants.
    min_response : float
        Samples whose depth response erfc(...) is below this are dropped: there the estimate
        divides noise by a vanishing number (t -> 0).
    min_difference : float
        Samples with |T_surf - T_obj| or |T_sens(0) - T_surf| below this (deg C) are dropped.

    Returns
    -------
    t_valid : numpy.ndarray
        Times of the samples kept.
    e : numpy.ndarray
        Positive, finite effusivity estimates at those times.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(temperature, dtype=float)
    resp = depth_response(t, sensor)
    keep = (resp >= min_response) & np.isfinite(y)
    if abs(t_sensor - t_object) < min_difference:
        keep[:] = False  # sensor at the object's temperature: no heat flows, nothing to learn
    surf = t_sensor + (y - t_sensor) / np.where(keep, resp, 1.0)  # eq. 11
    num = t_sensor - surf
    den = surf - t_object
    keep &= (np.abs(den) >= min_difference) & (np.abs(num) >= min_difference)
    keep &= np.sign(num) == np.sign(den)  # surface between sensor and object, else unphysical
    e = sensor.effusivity * np.divide(num, den, out=np.ones_like(num), where=keep)
    return t[keep], e[keep]


def _xi(t: np.ndarray, sensor: SensorConstants) -> tuple[np.ndarray, np.ndarray]:
    """Similarity variable x / (2 sqrt(alpha_s t)), +inf where t <= 0, and the mask t > 0."""
    t = np.asarray(t, dtype=float)
    pos = t > 0
    safe = np.where(pos, t, 1.0)
    return np.where(pos, sensor.depth / (2.0 * np.sqrt(sensor.diffusivity * safe)), np.inf), pos


def conductance_rate(
    conductance: np.ndarray | float, e_sensor: np.ndarray | float, e_object: np.ndarray | float
) -> np.ndarray:
    """H = h (e_s + e_o) / (e_s e_o), s^-0.5: how fast a finite contact conductance closes.

    Infinite for perfect contact (h = inf). After t seconds the interface has closed the
    fraction 1 - erfcx(H sqrt(t)) of the step to the contact temperature.
    """
    h = np.asarray(conductance, dtype=float)
    e_s = np.asarray(e_sensor, dtype=float)
    e_o = np.asarray(e_object, dtype=float)
    return h * (1.0 / e_s + 1.0 / e_o)


def contact_response(
    t: np.ndarray | float,
    rate: np.ndarray | float,
    sensor: SensorConstants,
) -> np.ndarray:
    """Fraction of the step T_surf - T_sens(0) seen at the thermistor with contact conductance.

    Parameters
    ----------
    t : array_like
        Time since contact, s (0 before contact).
    rate : array_like
        ``conductance_rate(h, e_s, e_o)``, s^-0.5; ``inf`` gives `depth_response` (eq. 5).
    sensor : SensorConstants
        Sensor constants (depth and diffusivity of the thermistor).

    Returns
    -------
    numpy.ndarray
        ``exp(-xi^2) (erfcx(xi) - erfcx(xi + H sqrt(t)))``, in [0, 1), broadcast over the inputs.
    """
    xi, pos = _xi(t, sensor)
    rate = np.asarray(rate, dtype=float)
    with np.errstate(invalid="ignore", over="ignore"):
        u = np.where(pos, rate * np.sqrt(np.where(pos, t, 1.0)), 0.0)
        # exp(-xi^2) erfcx(xi) is erfc(xi): writing it so avoids 0 * inf when xi is large
        r = erfc(xi) - np.exp(-(xi**2)) * erfcx(np.where(np.isinf(u), np.inf, xi + u))
    return np.where(pos & (rate > 0), np.clip(r, 0.0, 1.0), 0.0)


def contact_trace(
    t: np.ndarray | float,
    t_sensor: np.ndarray | float,
    t_object: np.ndarray | float,
    e_object: np.ndarray | float,
    sensor: SensorConstants,
    conductance: np.ndarray | float = np.inf,
) -> np.ndarray:
    """Thermistor temperature after contact with an object (eqs. 3 and 5, with conductance h).

    Parameters
    ----------
    t : array_like
        Time since contact, s; before contact (t <= 0) the reading is ``t_sensor``.
    t_sensor, t_object : array_like
        Uniform initial temperatures of the sensor and the object, deg C.
    e_object : array_like
        Object effusivity, W s^0.5 / (m^2 K).
    sensor : SensorConstants
        Sensor constants.
    conductance : array_like
        Contact conductance h, W/(m^2 K); ``inf`` (default) is the paper's perfect contact.

    Returns
    -------
    numpy.ndarray
        Readings, broadcast over all inputs (e.g. ``t`` of shape (n,) against parameters of
        shape (m, 1) gives (m, n)).
    """
    e_s = sensor.effusivity
    surface = contact_temperature(t_sensor, t_object, e_s, e_object)
    rate = conductance_rate(conductance, e_s, e_object)
    return t_sensor + (surface - t_sensor) * contact_response(t, rate, sensor)


def material_trace(material: Material, t_sensor: float, t_object: float, *,
                   duration: float, fs: float = 200.0, model: str = "semi-infinite",
                   conductance: float = 3000.0, ambient: float = 25.0,
                   sensor: SensorConstants | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Simulate one contact's thermistor trace from its onset (``skin simulate trace``).

    Parameters
    ----------
    material : skin.models.materials.Material
        The object's material (its nominal properties).
    t_sensor, t_object : float
        Sensor and object temperatures at contact, deg C.
    duration : float
        Length of the contact, s.
    fs : float, optional
        Sampling rate, Hz.
    model : str, optional
        ``"semi-infinite"`` (the paper's eq. 5), ``"contact"`` (a finite contact conductance)
        or ``"multilayer"`` (finite volumes, heater on).
    conductance : float, optional
        Contact conductance h, W/(m^2 K), of ``"contact"`` and ``"multilayer"``.
    ambient : float, optional
        Ambient temperature, deg C (the multilayer column's losses).
    sensor : skin.models.physics.SensorConstants, optional
        Sensor constants (default: the paper's).

    Returns
    -------
    t : numpy.ndarray
        Time since onset of each sample, s (``round(duration * fs) + 1`` samples from 0).
    temperature : numpy.ndarray
        The thermistor's temperature, deg C.
    """
    s = SensorConstants() if sensor is None else sensor
    t = np.arange(round(duration * fs) + 1) / fs
    if model == "multilayer":
        from skin.models.multilayer import MultilayerModel, ObjectBody, Phase, SensorStack

        body = ObjectBody.of(material.nominal["k"], material.nominal["rho"],
                             material.nominal["c"])
        column = MultilayerModel(SensorStack.paper(s), body, ambient=ambient, dt=1.0 / fs)
        state = column.state(t_sensor, t_object)
        res = column.run(state, [Phase(duration, True, heater=1.0, conductance=conductance)],
                         fs=fs)
        return t, np.asarray(res.thermistor[0][: t.size], dtype=float)
    if model not in TRACE_MODELS:
        raise ValueError(f"unknown contact model {model!r}; choose one of "
                         f"{', '.join(TRACE_MODELS)}")
    h = np.inf if model == "semi-infinite" else conductance
    return t, np.asarray(contact_trace(t, t_sensor, t_object, material.effusivity, s, h),
                         dtype=float)

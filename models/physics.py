"""The paper's heat-transfer model: sensor and object as two semi-infinite solids (eqs. 1-11).

Forward::

    q = V^2 / R                                            (1)
    T_sens(0) = T_amb + q l / (A k_s)                      (2)
    T_surf = (e_s T_sens(0) + e_o T_obj) / (e_s + e_o)     (3), e = k / sqrt(alpha)
    T(x, t) = T_sens(0) + (T_surf - T_sens(0)) erfc(x / (2 sqrt(alpha_s t)))   (5)

Inverse (pointwise, eqs. 10-11): from one reading T(x, t) recover T_surf, then the object's
effusivity ``e_o = e_s (T_sens(0) - T_surf) / (T_surf - T_obj)``.  It is undefined at t -> 0
(erfc -> 0 amplifies noise without bound), when the surface sits at the object's temperature,
and when the sensor starts at the object's temperature; such samples are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import erfc


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
        """Take the constants from a `skin.layout.Board`."""
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
    """Interface temperature of two semi-infinite solids brought into contact (eq. 3)."""
    e_s = np.asarray(e_sensor, dtype=float)
    e_o = np.asarray(e_object, dtype=float)
    return (e_s * t_sensor + e_o * t_object) / (e_s + e_o)


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

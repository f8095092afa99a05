"""A commissioned taxel's contacts on the design's time scale.

Taxels of one design differ in thermistor depth and in diffusivity (+-10 % each in the
simulated skins), so the same contact reads faster on one taxel than on another; a model
trained on some taxels then meets others as a shift of every material. Commissioning
(``skin calibrate thermal --reference label``) measures each taxel's time scale
x^2 / alpha; `warp_to_nominal` resamples its contacts onto the nominal taxel's, so that any
classifier (and the physics inside the default) reads every taxel as the design.
"""

from __future__ import annotations

import dataclasses

import numpy as np


def time_ratio(sensor) -> float:
    """Return a taxel's time scale over the nominal taxel's, ``(x^2 / alpha) / (x0^2 / alpha0)``.

    ``sensor``: its `SensorConstants` (None: the nominal taxel, ratio 1). A taxel of ratio r
    reads at time ``t r`` what the nominal taxel reads at ``t`` (perfect contact).
    """
    from skin.models.physics import SensorConstants

    if sensor is None:
        return 1.0
    nominal = SensorConstants()
    return float((sensor.depth ** 2 / sensor.diffusivity)
                 / (nominal.depth ** 2 / nominal.diffusivity))


def taxel_times(nominal_times: np.ndarray, sensor) -> np.ndarray:
    """Return the times since onset at which a taxel reads the nominal taxel's ``nominal_times``.

    Interpolating a taxel's trace at these times puts it on the design's time scale: what
    `warp_to_nominal` does to a dataset and `skin.models.learned.LearnedClassifier` to a
    contact's windows for a model trained on warped traces (``skin train --calibration``).
    """
    return np.asarray(nominal_times, dtype=float) * time_ratio(sensor)


def taxel_constants(cal, source: str) -> dict:
    """Return taxel id -> `SensorConstants` of the taxels with thermal constants in a file.

    ``cal``: a `skin.formats.calibration_file.CalibrationFile`, read from ``source`` (named
    in the error). Constants the file leaves out
    keep the nominal taxel's; taxels without any thermal constant are left out (their traces
    stay as recorded). `skin evaluate --calibration`, ``skin train --calibration`` and ``skin
    run`` with a model trained so all read a file through this.

    Raises
    ------
    SkinError
        If no taxel has thermal constants (``skin calibrate thermal`` writes them).
    """
    from skin.errors import SkinError
    from skin.formats.calibration_file import THERMAL
    from skin.models.physics import SensorConstants

    out = {int(k): dataclasses.replace(SensorConstants(), **{
        key: float(v[key]) for key in THERMAL if key in v}) for k, v in cal.taxels.items()
        if any(key in v for key in THERMAL)}
    if not out:
        raise SkinError(f"{source}: no taxel has thermal constants (skin calibrate "
                        f"thermal)")
    return out


def warp_to_nominal(data, sensors: dict):
    """Return ``data`` with each channel's trace on the nominal taxel's time scale.

    A taxel at depth x with diffusivity alpha reads, under perfect contact, the nominal
    taxel's trace at time ``t tau0 / tau`` (tau = x^2 / alpha): each channel's samples from
    the onset on are resampled at ``onset + k tau / tau0`` (linear interpolation; held at the
    recording's end). A finite contact conductance does not scale so, which leaves a small
    error. Channels whose taxel ``sensors`` (taxel id -> `SensorConstants`) lacks are left
    as they are.

    Raises
    ------
    SkinError
        If the dataset has no ``taxel`` column or an onset is unknown (-1).
    """
    from skin.errors import SkinError

    if data.taxel is None:
        raise SkinError(f"{data.source}: commissioned constants need the 'taxel' column")
    if np.any(data.onset < 0):
        raise SkinError(f"{data.source}: trial {int(np.argmax(data.onset < 0))} has no onset "
                        f"(-1): detect the onsets first")
    temperature = data.temperature.copy()
    m = temperature.shape[-1]
    idx = np.arange(m, dtype=float)
    taxel = np.asarray(data.taxel).reshape(len(data), -1)
    for i, c in zip(*np.nonzero(taxel >= 0), strict=True):
        s = sensors.get(int(taxel[i, c]))
        if s is None or c >= temperature.shape[1]:
            continue
        on = int(data.onset[i])
        at = on + taxel_times(idx[on:] - on, s)
        temperature[i, c, on:] = np.interp(at, idx, data.temperature[i, c])
    return dataclasses.replace(data, temperature=temperature)

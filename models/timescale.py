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
    from skin.models.physics import SensorConstants

    if data.taxel is None:
        raise SkinError(f"{data.source}: commissioned constants need the 'taxel' column")
    if np.any(data.onset < 0):
        raise SkinError(f"{data.source}: trial {int(np.argmax(data.onset < 0))} has no onset "
                        f"(-1): detect the onsets first")
    nominal = SensorConstants()
    tau0 = nominal.depth ** 2 / nominal.diffusivity
    temperature = data.temperature.copy()
    m = temperature.shape[-1]
    idx = np.arange(m, dtype=float)
    taxel = np.asarray(data.taxel).reshape(len(data), -1)
    for i, c in zip(*np.nonzero(taxel >= 0), strict=True):
        s = sensors.get(int(taxel[i, c]))
        if s is None or c >= temperature.shape[1]:
            continue
        ratio = (s.depth ** 2 / s.diffusivity) / tau0
        on = int(data.onset[i])
        at = on + (idx[on:] - on) * ratio
        temperature[i, c, on:] = np.interp(at, idx, data.temperature[i, c])
    return dataclasses.replace(data, temperature=temperature)

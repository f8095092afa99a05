"""Each taxel's thermal constants, fitted from contacts with a reference of known properties.

The paper fitted its sensor's diffusivity and conductivity on one pine trial. A skin needs it
per taxel: a +-10 % spread of those constants, left to the nominal values, costs the joint
classifier more accuracy than ADC noise and onset error together (`skin bench fusion`).

`fit_sensor_constants` fits one taxel's diffusivity alpha_s and conductivity k_s (the
thermistor depth stays nominal: with a semi-infinite body only depth / sqrt(alpha_s) and the
effusivity k_s / sqrt(alpha_s) are seen, so fixing the depth loses nothing) together with each
contact's conductance h, by least squares on a few contacts with a reference material at a
known temperature. Water is a good reference: it conforms, so its contact is close to
perfect, and its properties are known to a percent.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from skin.models.materials import Material
from skin.models.physics import SensorConstants, contact_trace
from skin.summary import median_p95


@dataclass(frozen=True)
class SensorFit:
    """A taxel's fitted thermal constants.

    Attributes
    ----------
    sensor : SensorConstants
        The nominal constants with ``diffusivity`` and ``conductivity`` replaced (and
        ``depth``, when the heater mode pins it: `_depth_matters`).
    conductance : numpy.ndarray
        Each reference contact's fitted conductance, W/(m^2 K).
    rms : float
        Root-mean-square residual, K.
    converged : bool
        Whether the optimiser reported success.
    onset_shift : numpy.ndarray
        Each contact's fitted onset minus the given one, s (zeros unless ``onset_search``).
    """

    sensor: SensorConstants
    conductance: np.ndarray
    rms: float
    converged: bool
    onset_shift: np.ndarray | None = None


#: Where each contact's conductance starts, as a fraction of its log range: near the top (a
#: firm touch). Started mid-range, pine touches of a near-perfect contact settled in a local
#: minimum of a soft contact (response-time error p90 0.16 against 0.04 started here).
_H_START = 0.9


def _reading(t: np.ndarray, t_sensor: np.ndarray, t_object: np.ndarray, e_ref: np.ndarray,
             sensor: SensorConstants, h: np.ndarray, ambient: np.ndarray) -> np.ndarray:
    """Eq. 5 with conductance h, and with a `SensorDescription` its heater mode."""
    from skin.models.sensors import SensorDescription, contact_reading

    if not isinstance(sensor, SensorDescription):
        return contact_trace(t, t_sensor, t_object, e_ref, sensor, h)
    return contact_reading(t, t_sensor, t_object, e_ref, sensor, h, ambient)


def reference_reading(t: np.ndarray, t_sensor: np.ndarray, t_object: np.ndarray,
                      e_ref: np.ndarray, sensor: SensorConstants, h: np.ndarray) -> np.ndarray:
    """Return what a taxel reads in contacts with a reference at room temperature.

    Eq. 5 with conductance h over each contact's samples (the last axis) and, with a
    `skin.models.sensors.SensorDescription`, its heater mode, lag and smoothing.
    """
    return _as_read(_reading(t, t_sensor, t_object, e_ref, sensor, h, t_object), sensor)


def _as_read(y: np.ndarray, sensor: SensorConstants) -> np.ndarray:
    """With a `SensorDescription`: its lag, PID loop and smoothing along each contact's samples."""
    from skin.models.sensors import SensorDescription, apply_dynamics, smooth

    if not isinstance(sensor, SensorDescription):
        return y
    return smooth(apply_dynamics(y, sensor, axis=-1), sensor, axis=-1)


def fit_sensor_constants(t: np.ndarray, temperature: np.ndarray, t_sensor: Sequence[float],
                         t_object: Sequence[float], e_reference: float | Sequence[float],
                         nominal: SensorConstants | None = None,
                         conductance_range: tuple = (1e2, 1e7),
                         onset_search: float = 0.0,
                         conductance_groups: Sequence[int] | None = None,
                         fit_depth: bool | None = None) -> SensorFit:
    """Fit a taxel's diffusivity and conductivity from reference contacts.

    Parameters
    ----------
    t : numpy.ndarray
        Time since contact of each sample, s, (n_samples,), or per contact
        (n_contacts, n_samples) when the contacts' onsets fall between samples.
    temperature : numpy.ndarray
        The taxel's readings in each contact, (n_contacts, n_samples), deg C.
    t_sensor, t_object : sequence of float
        Sensor temperature before, and the reference's temperature in, each contact, deg C.
    e_reference : float or sequence of float
        The reference's effusivity, W s^0.5 / (m^2 K), or each contact's (several reference
        materials: different effusivities pin depth, diffusivity and conductivity better).
    nominal : SensorConstants, optional
        Starting point and the constants that are not fitted (default: the paper's). A
        `skin.models.sensors.SensorDescription` brings its heater mode, lag and smoothing
        into the model (`skin.models.sensors.contact_reading`).
    conductance_range : tuple
        Bounds of each contact's conductance, W/(m^2 K), two floats or two per-contact
        sequences (the reference's range, from
        `skin.models.materials.Material.conductance_range`, keeps a slow contact from
        passing for a slow sensor).
    onset_search : float, optional
        With > 0, each contact's onset is fitted too, within +-``onset_search`` s of the given
        one, together with its baseline (``t_sensor`` is then its start: the reading at the
        onset, and a slope before it). ``t`` must then include samples before the onset (at
        least ``onset_search`` s): they pin the baseline, and the first samples after the
        onset date it. An onset dated some tens of ms late, left fixed, passes for a faster
        sensor with a softer contact (see `skin.models.commission`).
    conductance_groups : sequence of int, optional
        Contacts with the same group number share one conductance (for example one per
        reference material, when the touches were equally firm); default: one per contact.
        Its bounds are the widest of its contacts'.
    fit_depth : bool, optional
        Fit the thermistor depth too; default: when the heater mode pins it
        (`_depth_matters`). False for contacts pooled from taxels that differ.

    Returns
    -------
    SensorFit

    Raises
    ------
    ValueError
        If the shapes disagree, a reading is not finite, or no contact has heat flowing
        (the sensor at the reference's temperature carries no information).
    """
    from scipy.optimize import least_squares

    s0 = SensorConstants() if nominal is None else nominal
    y = np.atleast_2d(np.asarray(temperature, dtype=float))
    ts = np.asarray(t_sensor, dtype=float)
    to = np.asarray(t_object, dtype=float)
    t = np.atleast_2d(np.asarray(t, dtype=float))
    e_ref = np.broadcast_to(np.asarray(e_reference, dtype=float), ts.shape)[:, None]
    if (y.shape != (ts.size, t.shape[-1]) or to.shape != ts.shape
            or t.shape[0] not in (1, ts.size)):
        raise ValueError(f"temperature must be (n_contacts, n_samples) = ({ts.size}, "
                         f"{t.shape[-1]}) with one sensor and one object temperature per "
                         f"contact; got {y.shape}, {ts.size} and {to.size}")
    if not np.all(np.isfinite(y)):
        raise ValueError("readings must be finite")
    if np.all(np.abs(ts - to) < 0.5):
        raise ValueError("every contact has the sensor within 0.5 K of the reference: no heat "
                         "flows, so nothing can be fitted; heat the taxel first")
    search = float(onset_search)
    if search < 0 or (search > 0 and np.any(t[:, 0] > -search)):
        raise ValueError(f"onset_search {search:g} s needs samples from at least that long "
                         f"before each onset; the first is at {t[:, 0].max():.3g} s")

    m = ts.size
    n_free = 3 * m if search > 0 else 0  # onset shift, baseline at the onset, slope before it
    free_depth = _depth_matters(s0) if fit_depth is None else fit_depth
    b = 3 if free_depth else 2  # the body: diffusivity, conductivity (and depth)
    group = np.arange(m) if conductance_groups is None else np.unique(
        np.asarray(conductance_groups), return_inverse=True)[1].ravel()
    if group.shape != (m,):
        raise ValueError(f"conductance_groups needs one group per contact ({m})")
    g = int(group.max()) + 1

    def body(p: np.ndarray) -> SensorConstants:
        depth = {"depth": float(np.exp(p[2]))} if b == 3 else {}
        return dataclasses.replace(s0, diffusivity=float(np.exp(p[0])),
                                   conductivity=float(np.exp(p[1])), **depth)

    def model(p: np.ndarray) -> np.ndarray:
        s = body(p)
        h = np.exp(p[b:b + g])[group, None]
        if not n_free:
            return _as_read(_reading(t, ts[:, None], to[:, None], e_ref, s, h, to[:, None]), s)
        shift, base, slope = (p[b + g + i * m:b + g + (i + 1) * m, None] for i in range(3))
        u = t - shift
        after = _reading(u, base, to[:, None], e_ref, s, h, to[:, None])
        return _as_read(np.where(u > 0, after, base + slope * u), s)

    lo_c = np.broadcast_to(np.log(np.asarray(conductance_range[0], dtype=float)), ts.shape)
    hi_c = np.broadcast_to(np.log(np.asarray(conductance_range[1], dtype=float)), ts.shape)
    lo_h = np.array([lo_c[group == j].min() for j in range(g)])
    hi_h = np.array([hi_c[group == j].max() for j in range(g)])
    start = np.concatenate([[np.log(s0.diffusivity), np.log(s0.conductivity),
                             np.log(s0.depth)][:b], lo_h + _H_START * (hi_h - lo_h)])
    lower = np.concatenate([start[:b] - np.log(3.0), lo_h])
    upper = np.concatenate([start[:b] + np.log(3.0), hi_h])
    if n_free:
        start = np.concatenate([start, np.zeros(m), ts, np.zeros(m)])
        lower = np.concatenate([lower, np.full(m, -search), ts - 3.0, np.full(m, -2.0)])
        upper = np.concatenate([upper, np.full(m, search), ts + 3.0, np.full(m, 2.0)])
    # each contact's residuals depend on the two constants, its conductance and its own
    # onset parameters alone: finite differences then need a few evaluations, not one each
    rows = np.repeat(np.arange(m), y.shape[1])
    sparsity = np.zeros((y.size, start.size), dtype=bool)
    sparsity[:, :b] = True
    sparsity[np.arange(y.size), b + group[rows]] = True
    for i in range(3 if n_free else 0):
        sparsity[np.arange(y.size), b + g + i * m + rows] = True
    res = least_squares(lambda p: (model(p) - y).ravel(), start, bounds=(lower, upper),
                        x_scale=1.0, max_nfev=300, jac_sparsity=sparsity)
    sensor = body(res.x)
    rms = float(np.sqrt(np.mean(res.fun**2)))
    shift = res.x[b + g:b + g + m] if n_free else np.zeros(m)
    return SensorFit(sensor, np.exp(res.x[b:b + g])[group], rms, bool(res.success), shift)


def _depth_matters(sensor: SensorConstants) -> bool:
    """Whether the reading pins the thermistor depth apart from depth^2 / diffusivity.

    With a constant or PID-held heater the contact response depends on depth and
    diffusivity only through depth^2 / diffusivity (and effusivity), so the depth stays
    nominal. A heater switched off at contact drains with thickness^2 / diffusivity, and one
    left on adds a flux term of its own: there a nominal depth forces a wrong diffusivity
    (fast-film, seed 7, noise-free: response time +7.6 % biased with the depth held).
    """
    from skin.models.sensors import SensorDescription

    return isinstance(sensor, SensorDescription) and sensor.heater in (
        "off-at-contact", "on-during-contact")


def reference_contacts(sensor: SensorConstants, reference: Material, rng: np.random.Generator,
                       contacts: int = 4, duration: float = 2.0, fs: float = 200.0,
                       ambient: float = 25.0,
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Simulate a calibration run: ``contacts`` touches of ``reference`` at ambient.

    The taxel starts each touch at 30-40 C; the contact conductance is drawn from the
    reference's range; readings go through the paper's divider and 10-bit ADC (0.5 LSB).

    Returns
    -------
    tuple
        Sample times after contact (n,), readings (contacts, n), the sensor's and the
        reference's temperatures (contacts,): the arguments of `fit_sensor_constants`.
    """
    from skin.models.trials import adc_readings

    t = np.arange(1, round(duration * fs) + 1) / fs
    ts = rng.uniform(30.0, 40.0, contacts)
    to = np.full(contacts, ambient)
    h = 10.0 ** rng.uniform(*np.log10(reference.conductance_range), contacts)
    clean = contact_trace(t[None, :], ts[:, None], to[:, None], reference.effusivity, sensor,
                          h[:, None])
    return t, adc_readings(clean, rng, 0.5), ts, to


def recovery(n_taxels: int = 20, contacts: int = 4, duration: float = 2.0,
             spread: float = 0.10, reference: str = "water", seed: int = 0) -> dict:
    """Run simulated calibrations: how well `fit_sensor_constants` recovers known constants.

    Each taxel's diffusivity and conductivity are drawn within +-``spread`` of the paper's;
    it touches the reference ``contacts`` times from 30-40 C, through a conductance from the
    reference's range, read through the paper's divider and 10-bit ADC with 0.5 LSB of noise.

    Returns
    -------
    dict
        Median and p95 relative error of diffusivity, conductivity and the sensor's effusivity,
        before (nominal constants) and after the fit, and the fit time per taxel.
    """
    import time

    from skin.models.materials import load_materials

    ref = load_materials()[reference]
    rng = np.random.default_rng(seed)
    base = SensorConstants()
    err: dict[str, list[float]] = {"diffusivity": [], "conductivity": [], "effusivity": []}
    before = {k: [] for k in err}
    spent = 0.0
    for _ in range(n_taxels):
        f = 1.0 + rng.uniform(-spread, spread, 2)
        true = dataclasses.replace(base, diffusivity=base.diffusivity * f[0],
                                   conductivity=base.conductivity * f[1])
        t, y, ts, to = reference_contacts(true, ref, rng, contacts, duration)
        started = time.perf_counter()
        fit = fit_sensor_constants(t, y, ts, to, ref.effusivity,
                                   conductance_range=ref.conductance_range)
        spent += time.perf_counter() - started
        for key, got, nom in (("diffusivity", fit.sensor.diffusivity, base.diffusivity),
                              ("conductivity", fit.sensor.conductivity, base.conductivity),
                              ("effusivity", fit.sensor.effusivity, base.effusivity)):
            want = getattr(true, key)
            err[key].append(abs(got / want - 1.0))
            before[key].append(abs(nom / want - 1.0))

    return {"reference": reference, "taxels": n_taxels, "contacts": contacts,
            "duration": duration, "spread": spread,
            "nominal_error": {k: median_p95(v) for k, v in before.items()},
            "fitted_error": {k: median_p95(v) for k, v in err.items()},
            "ms_per_taxel": round(1e3 * spent / n_taxels, 1)}

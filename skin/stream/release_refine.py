"""Date a contact's release precisely, after the fact, by a change-point fit.

The streaming detector (`skin.stream.onset`) dates a release at the smoothed reading's
in-contact extreme: where the reading stops moving away from its baseline. After a release
the sensor body relaxes slowly back towards its heated state (the free response), so the
reading holds nearly flat for a while and the extreme lies tens of milliseconds after the
true release; the window handed to the classifier then ends on a plateau that no contact
with the material produces. `refine_release` finds where the in-contact response stops: it
fits, for every candidate release, the contact response from the onset up to it and the free
response after it, and keeps the candidate with the least squared error.
"""

from __future__ import annotations

import math

import numpy as np

#: Contact closing rates H tried for the in-contact part, s^-0.5 (inf: perfect contact).
RATES = (np.inf, 300.0, 100.0, 30.0, 10.0, 3.0, 1.0)

#: Least samples on each side of a candidate release.
MIN_SAMPLES = 4


def refine_release(
    times: np.ndarray,
    temperature: np.ndarray,
    onset: float,
    coarse: float,
    depth: float,
    diffusivity: float,
    sensor: object | None = None,
    search: float = 0.25,
    after: float = 0.5,
    rates: tuple[float, ...] = RATES,
) -> float:
    """Date a contact's release by fitting the contact response before it, the free after.

    Up to a candidate release ``tr`` the reading is ``a + D R(t - onset; H)``, the
    thermistor's contact response (`skin.models.physics.contact_response`, through the
    sensor's PID loop, lag and smoothing when it has them: `skin.stream.onset_refine.
    sensor_response`) with ``a`` and ``D`` fitted by least squares and H the best of
    ``rates``; from ``tr`` on it is the free response, the body relaxing towards its heated
    (or held) state with the sensor's own time constant tau (l^2 / alpha, the PID loop's
    ``control_time`` for a held heater): ``b + c tau (1 - exp(-(t - coarse) / tau))``, ``b``
    and ``c`` fitted (a straight line while tau is long against ``after``). Candidates are the
    sample instants from ``coarse - search`` to ``coarse + search / 2`` (each the first sample
    read free); both fits for every candidate come from cumulative sums (a few vector
    operations per rate). The sensor's smoothing and thermistor lag delay the kink by their
    group delay (`filter_delay`), which is taken off. ``search`` and ``after`` stretch with
    the sensor's response time when it is slower than the paper's.

    The detector's date is kept (returned as given) when the fit cannot tell: fewer than
    `MIN_SAMPLES` samples on either side of every candidate, non-finite inputs, or a best
    candidate that does not explain the samples better than the detector's own date by more
    than the noise could (its squared error lower by less than ``9 + 2 ln m`` residual
    variances, m the number of candidates: a 3-sigma test with a Bonferroni-like allowance
    for choosing among them). No threshold is in kelvin: the residual variance is the fit's.

    Parameters
    ----------
    times, temperature : numpy.ndarray
        The taxel's samples from (at least) the onset to past the coarse release (NaN samples
        are ignored).
    onset : float
        The contact's (refined) onset, s.
    coarse : float
        The detector's release, s.
    depth, diffusivity : float
        Thermistor depth (m) and sensor diffusivity (m^2/s).
    sensor : skin.models.sensors.SensorDescription, optional
        The taxel's sensor (default: the paper's).
    search : float
        How far before the coarse release candidates reach, s (the paper's sensor).
    after : float
        Samples later than ``coarse + after`` are not used, s (the paper's sensor).
    rates : tuple of float
        Contact closing rates tried, s^-0.5.

    Returns
    -------
    float
        The refined release, s (``coarse`` when the fit cannot tell).
    """
    from skin.models.physics import SensorConstants, contact_response
    from skin.models.sensors import SensorDescription, has_dynamics

    if not (math.isfinite(onset) and math.isfinite(coarse)) or coarse <= onset:
        return coarse
    desc = SensorDescription() if sensor is None else sensor
    stretch = max(1.0, desc.response_time / SensorDescription().response_time)
    search, after = search * stretch, after * stretch
    t = np.asarray(times, dtype=float)
    y = np.asarray(temperature, dtype=float)
    ok = np.isfinite(t) & np.isfinite(y) & (t >= onset) & (t <= coarse + after)
    t, y = t[ok], y[ok]
    n = t.size
    if n < 2 * MIN_SAMPLES + 1:
        return coarse
    lo = max(MIN_SAMPLES, int(np.searchsorted(t, coarse - search)))
    hi = min(n - MIN_SAMPLES, int(np.searchsorted(t, coarse + search / 2, side="right")))
    if hi <= lo:
        return coarse
    y = y - float(np.mean(y))  # centred: the sums below keep their precision

    # the in-contact part: prefix sums of the basis [1, R] for each rate
    body = SensorConstants(depth=depth, diffusivity=diffusivity)
    rate_grid = np.asarray(rates, dtype=float)
    lag = t - onset
    if sensor is not None and has_dynamics(sensor):
        from skin.stream.onset_refine import sensor_response

        basis = sensor_response(lag, rate_grid, body, sensor)  # (rates, n)
    else:
        basis = contact_response(lag[None, :], rate_grid[:, None], body)
    basis = np.nan_to_num(basis)
    pre = _prefix_sse(basis, y)  # (rates, n + 1): sse of the first j samples
    before = pre.min(axis=0)

    # the free part: suffix sums of [1, tau (1 - exp(-(t - coarse) / tau))]
    tau = desc.control_time if desc.heater == "pid" else desc.reheat_time_constant
    tau = max(float(tau), 1e-6)
    free = -tau * np.expm1(-(t - coarse) / tau)
    post = _prefix_sse(free[::-1][None, :], y[::-1])[0, ::-1]  # sse of samples j..n-1

    j = np.arange(lo, hi)
    total = before[j] + post[j]
    if not np.all(np.isfinite(total)):
        return coarse
    best = int(j[np.argmin(total)])
    at_coarse = int(np.clip(np.searchsorted(t, coarse), lo, hi - 1))
    # the residual variance (a floor at float precision for noise-free readings)
    variance = max(float(total.min()) / max(n - 5, 1), 1e-24 * float(np.mean(y * y)), 1e-300)
    # against the detector's date, and against no release at all (the contact's response
    # over every sample)
    gain = min(float(before[at_coarse] + post[at_coarse]), float(before[n])) - float(total.min())
    if not variance > 0 or gain < (9.0 + 2.0 * math.log(j.size)) * variance:
        return coarse
    release = float(t[best]) - filter_delay(desc)
    return max(release, float(t[lo - 1]))


def _prefix_sse(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Squared error of the least-squares fit ``a + b x`` to every prefix of the samples.

    ``x`` is (k, n) (k candidate columns), ``y`` (n,); returns (k, n + 1), entry j the error
    over the first j samples (0 where fewer than 3; a constant column: the mean's error).
    """
    k, n = x.shape

    def cum(v: np.ndarray) -> np.ndarray:
        v = np.broadcast_to(v, (k, n))
        return np.concatenate([np.zeros((k, 1)), np.cumsum(v, axis=-1)], axis=-1)

    m = np.arange(n + 1, dtype=float)[None, :]
    s_x, s_y, s_xx = cum(x), cum(y[None, :]), cum(x * x)
    s_xy, s_yy = cum(x * y[None, :]), cum((y * y)[None, :])
    safe = np.maximum(m, 1.0)
    var_x = s_xx - s_x**2 / safe
    cov = s_xy - s_x * s_y / safe
    var_y = s_yy - s_y**2 / safe
    scale = np.maximum(s_xx, 1e-300)
    fit = np.divide(cov**2, var_x, out=np.zeros_like(var_x), where=var_x > 1e-12 * scale)
    sse = np.maximum(var_y - fit, 0.0)
    return np.where(m >= 3, sse, 0.0)


def filter_delay(sensor: object) -> float:
    """Return how late the sensor's lag and smoothing show a change of slope, s.

    The group delay of a ramp through them: the thermistor lag's time constant, plus (n - 1)
    / (2 fs) for an n-sample moving average, sqrt(2) / (2 pi f_c) for the second-order
    Butterworth low-pass, 0 for the (centred) Savitzky-Golay filter. A PID loop's delay is
    not counted (it bends the free response, which the fit's tau takes).
    """
    delay = float(getattr(sensor, "lag", 0.0) or 0.0)
    kind = getattr(sensor, "smoothing", "none")
    if kind == "moving-average":
        delay += (sensor.smoothing_window - 1) / (2.0 * sensor.sample_rate)
    elif kind == "low-pass":
        delay += math.sqrt(2.0) / (2.0 * math.pi * sensor.smoothing_cutoff)
    return delay

"""Date a contact's release precisely, after the fact, by a change-point fit.

The streaming detector (`skin.stream.onset`) dates a release at the smoothed reading's
in-contact extreme: where the reading stops moving away from its baseline. After a release
the sensor body relaxes slowly back towards its heated state (the free response), so the
reading holds nearly flat for a while and the extreme lies tens of milliseconds after the
true release (the default scene: 90 ms median on touches of 0.6 s or less); the window
handed to the classifier then ends on a plateau that no contact with the material produces.
`refine_release` finds where the in-contact response stops: it fits, for every candidate
release, the contact response from the onset up to it and the free response after it, and
keeps the candidate with the least squared error.
"""

from __future__ import annotations

import math

import numpy as np

#: Contact closing rates H tried for the in-contact part, s^-0.5 (inf: perfect contact).
RATES = (np.inf, 300.0, 100.0, 30.0, 10.0, 3.0, 1.0)

#: Heater modes whose own drain is fitted beside the contact response (`onset_refine`'s).
HEATER_TERMS = ("off-at-contact",)

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

    Up to a candidate release (its first sample read free, ``t_j``) the reading is
    ``a + D R(t - onset; H)``, the thermistor's contact response
    (`skin.models.physics.contact_response`, through the sensor's PID loop, lag and smoothing
    when it has them: `skin.stream.onset_refine.sensor_response`) with H the best of
    ``rates`` (a heater switched off at contact: its drain's column beside it, each weight
    fitted, as `refine_onset` does); from there on it continues from the last sample in
    contact as the free response, the body relaxing towards its heated (or held) state with
    the sensor's own time constant tau (l^2 / alpha; a PID loop's ``control_time``):
    ``a + D R(t_{j-1}) + c tau (1 - exp(-(t - t_{j-1}) / tau))`` (a straight line while tau is
    long against ``after``). The weights are fitted by least squares for every candidate and
    rate at once (normal equations from prefix and suffix sums); the candidate with the
    least squared error wins. Candidates are the sample instants from ``coarse - search`` to
    ``coarse + search / 2``. The reading being continuous at the release is what makes the
    fit precise: without it (two free fits) noise alone moved it by 10-40 ms on one-taxel
    synthetic touches of the paper's sensor. The sensor's smoothing and thermistor lag
    delay the kink by their group delay (`filter_delay`), which is taken off (an
    approximation: with a lag the kink is bent, not shifted; through a PID loop and a
    0.5 s lag, pid-logger's synthetic releases are dated 0.2 s early, against the
    detector's 0.8 s late; in `skin bench tracking`'s scene 0.64 s late, against 1.6 s).
    ``search`` and ``after`` stretch with the sensor's response time when it is slower
    than the paper's.

    The detector's date is kept (returned as given) when the fit cannot tell: fewer than
    `MIN_SAMPLES` samples on either side of every candidate, non-finite inputs, or a best
    candidate that does not explain the samples better than the detector's own date, and
    than the contact's response alone (no release), by more than the noise could (its
    squared error lower by less than ``9 + 2 ln m`` residual variances, m the number of
    candidates: a 3-sigma test with a Bonferroni-like allowance for choosing among them).
    No threshold is in kelvin: the residual variance is the fit's own.

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
    if sensor is not None and sensor.heater in HEATER_TERMS:
        # a heater switched off at contact drains the body from its first instant: its own
        # column beside the response (as `refine_onset` fits it)
        from skin.stream.onset_refine import heater_basis

        basis = np.moveaxis(heater_basis(lag, rate_grid, body, sensor), 0, 1)  # (rates, 2, n)
    elif sensor is not None and has_dynamics(sensor):
        from skin.stream.onset_refine import sensor_response

        basis = sensor_response(lag, rate_grid, body, sensor)[:, None, :]  # (rates, 1, n)
    else:
        basis = contact_response(lag[None, :], rate_grid[:, None], body)[:, None, :]
    basis = np.nan_to_num(basis)
    before = _prefix_sse(basis[:, 0], y).min(axis=0)  # (n + 1,): the response alone

    # the free part, continuing the reading from the last sample in contact
    tau = desc.control_time if desc.heater == "pid" else desc.reheat_time_constant
    tau = max(float(tau), (t[-1] - t[lo - 1]) / 300.0, 1e-9)  # exp(-span / tau) stays finite
    j = np.arange(lo, hi)
    total = _hinge_sse(basis, np.exp(-(t - t[lo - 1]) / tau), tau, y, j).min(axis=0)
    if not np.all(np.isfinite(total)):
        return coarse
    best = int(j[np.argmin(total)])
    at_coarse = int(np.clip(np.searchsorted(t, coarse), lo, hi - 1))
    # the residual variance (a floor at float precision for noise-free readings)
    variance = max(float(total.min()) / max(n - 5, 1), 1e-24 * float(np.mean(y * y)), 1e-300)
    # against the detector's date, and against no release at all (the contact's response
    # over every sample)
    gain = min(float(total[at_coarse - lo]), float(before[n])) - float(total.min())
    if not variance > 0 or gain < (9.0 + 2.0 * math.log(j.size)) * variance:
        return coarse
    release = float(t[best]) - filter_delay(desc)
    return max(release, float(t[lo - 1]))


def _hinge_sse(basis: np.ndarray, u: np.ndarray, tau: float, y: np.ndarray,
               j: np.ndarray) -> np.ndarray:
    """Squared error of the contact-then-free fit for each rate and first free sample ``j``.

    The model (linear in its weights for a given j): ``a + sum_c D_c B_c,i`` for i < j, and
    from j on ``a + sum_c D_c B_c,j-1 + f tau (1 - u_i / u_{j-1})`` (the reading continuous
    at the release, ``u = exp(-t / tau)`` up to a factor). ``basis`` is B (k rates, p
    columns, n); returns (k, len(j)). The normal equations come from prefix and suffix sums.
    """
    k, p, n = basis.shape

    def prefix(v: np.ndarray) -> np.ndarray:  # sum over i < j, along the last axis
        c = np.cumsum(v, axis=-1)
        return np.concatenate([np.zeros((*v.shape[:-1], 1)), c], axis=-1)[..., j]

    def suffix(v: np.ndarray) -> np.ndarray:  # sum over i >= j
        c = np.cumsum(v[..., ::-1], axis=-1)[..., ::-1]
        return np.concatenate([c, np.zeros((*v.shape[:-1], 1))], axis=-1)[..., j]

    last = basis[:, :, j - 1]  # (k, p, m)
    u_last = u[j - 1]
    rest = (n - j).astype(float)  # (m,)
    s_u, s_uu, s_y, s_uy = suffix(u), suffix(u * u), suffix(y), suffix(u * y)
    f1 = tau * (rest - s_u / u_last)  # sum of the free column
    f2 = tau**2 * (rest - 2.0 * s_u / u_last + s_uu / u_last**2)
    g = np.empty((k, j.size, p + 2, p + 2))
    g[..., 0, 0] = n
    g[..., 0, 1:p + 1] = g[..., 1:p + 1, 0] = np.moveaxis(prefix(basis) + rest * last, 1, 2)
    cross = prefix(basis[:, :, None, :] * basis[:, None, :, :])  # (k, p, p, m)
    g[..., 1:p + 1, 1:p + 1] = np.moveaxis(cross + rest * last[:, :, None] * last[:, None],
                                           3, 1)
    g[..., 0, p + 1] = g[..., p + 1, 0] = f1
    g[..., 1:p + 1, p + 1] = g[..., p + 1, 1:p + 1] = np.moveaxis(last * f1, 1, 2)
    g[..., p + 1, p + 1] = np.maximum(f2, 0.0)
    b = np.concatenate([np.broadcast_to(y.sum(), (k, j.size, 1)),
                        np.moveaxis(prefix(basis * y) + last * s_y, 1, 2),
                        np.broadcast_to((tau * (s_y - s_uy / u_last))[:, None],
                                        (k, j.size, 1))], axis=-1)
    ridge = 1e-12 * np.trace(g, axis1=-2, axis2=-1)[..., None, None] * np.eye(p + 2)
    coef = np.linalg.solve(g + ridge, b[..., None])[..., 0]
    return np.maximum(float(y @ y) - np.einsum("kmi,kmi->km", coef, b), 0.0)


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

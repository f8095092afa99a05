"""Date a contact onset precisely by fitting the heated sensor's contact response.

The streaming detector (`skin.stream.onset`) recognises a contact some hundred milliseconds after it
began and dates it coarsely; the classifiers align each taxel's window on its onset, so
`refine_onset` fits the thermistor's response (the paper's eq. 5, or a contact that closes at
a finite rate) to the samples around the coarse onset.
"""

from __future__ import annotations

import functools

import numpy as np

#: Heater modes whose own term `refine_onset` fits beside the response (`heater_basis`). An
#: ``"on-during-contact"`` heater's flux has its known shape (the sensor's heater power,
#: `skin.models.sensors.heater_term`) and a weight bounded to [0, 1], the sensor's share
#: e_s / (e_s + e_o) of it: as an unbounded free column it traded with the onset and dated the
#: low-cost preset's synthetic contacts worse (median |error| 1.4 s against 0.3 s without it).
HEATER_TERMS = ("off-at-contact", "on-during-contact")

#: The drain of an ``"off-at-contact"`` heater goes towards the room: `refine_onset` bounds its
#: fitted size T0 - T_amb to [0, DRAIN_BOUND x the sensor's heated rise] (a margin over the
#: settled heater for a description that is off; after a release the reheat would otherwise
#: be fitted as a drain of the wrong sign).
DRAIN_BOUND = 1.5

#: How much further than its response time `refine_span` stretches a slow sensor's span.
SPAN_MORE = 2.0

#: Largest AR(1) coefficient `refine_onset` whitens a slow sensor's residual by: a choice,
#: not an estimate. On pid-logger's streams the residual's estimate sits at this clip in most
#: contacts, so the refit is in effect on first differences, and its result depends on the
#: clip (a review's scratch check, onset error median on 10 gusty contacts: 0.9 122 ms,
#: 0.95 87 ms, 0.99 17 ms, 0.999 12.5 ms); the whitened level stays a constant (1 - rho),
#: removed by centring, whatever rho. Every sensor with dynamics takes this path, a heater
#: term or not.
AR1_MAX = 0.99

#: Contact closing rates H = h (1/e_s + 1/e_o) tried by `refine_onset`, s^-0.5 (inf: perfect).
RATES = (np.inf, 300.0, 100.0, 30.0, 10.0, 3.0, 1.0, 0.3)


def refine_onset(
    times: np.ndarray,
    temperature: np.ndarray,
    coarse: float,
    baseline: float,
    slope: float,
    depth: float,
    diffusivity: float,
    search: float = 0.6,
    step: float = 0.005,
    rates: tuple[float, ...] = RATES,
    horizon: float = 0.6,
    sensor: object | None = None,
) -> tuple[float, float]:
    """Date a contact onset by fitting the heated sensor's contact response.

    Before the onset the reading follows the baseline ``baseline + slope (t - coarse)``; after
    it, ``T0 + D R(t - t0; H)`` with T0 the baseline at t0, ``R`` the thermistor's response to
    a contact whose conductance closes at rate H (`skin.models.physics.contact_response`; eq.
    5's ``erfc`` for perfect contact) and D fitted by least squares. Candidate onsets lie on a
    grid from ``coarse - search`` to ``coarse``, candidate rates in ``rates`` (refined about
    the best; with dynamics within the least and the largest finite rate given); the pair
    with the smallest squared error over the samples up to ``coarse + horizon`` wins, except
    on a sensor with dynamics and a heater term (below: a finite rate must pass Schwarz's
    criterion). Fitting the rate matters: a contact through an air gap starts slowly, and
    perfect-contact fits date it tens of milliseconds late.

    Parameters
    ----------
    times, temperature : numpy.ndarray
        The taxel's samples around the contact (NaN samples are ignored).
    coarse : float
        Coarse onset from the detector, s.
    baseline, slope : float
        Baseline temperature at ``coarse`` and its slope before contact.
    depth, diffusivity : float
        Thermistor depth (m) and sensor diffusivity (m^2/s).
    search, step : float
        Search span before ``coarse`` and grid step, s.
    rates : tuple of float
        Contact closing rates tried, s^-0.5 (``inf`` is perfect contact).
    horizon : float
        Samples later than ``coarse + horizon`` are not used, s.
    sensor : skin.models.sensors.SensorDescription, optional
        The taxel's sensor: the response fitted is then the reading's own, through the
        sensor's PID loop, thermistor lag and smoothing (`sensor_response`), and ``search``
        and ``horizon`` stretch with its response time when it is slower than the paper's
        (a slow sensor's departure is seen late). A heater switched off at contact
        (``"off-at-contact"``) drains the body from the contact's first instant, linearly in
        t while eq. 5 starts flat: its drain is fitted as a second column (`heater_basis`),
        else the fit dates such contacts early. A heater left on (``"on-during-contact"``)
        warms the thermistor by its flux, of known shape, scaled by the sensor's share
        e_s / (e_s + e_o) of it: fitted as a second column whose weight is bounded to [0, 1].
        With dynamics beside such a heater term a finite closing rate must earn its place by
        Schwarz's criterion (the residual sum of squares lower than perfect contact's by
        sigma^2 ln n, on the whitened samples; perfect contact must be among ``rates``), else
        the fit is perfect contact's: there the free rate traded with the onset and dated
        contacts early. The first, unwhitened fit is perfect contact's (or the free rate's,
        without it among ``rates``): it only gives the residual whose autocorrelation whitens
        the second.
        A PID-held sensor (``"pid"``) has no slope of its own (the loop holds it): ``slope``
        is ignored. A sensor with dynamics is fitted twice, the
        second time on samples whitened by the first fit's residual (AR(1), `_residual_ar1`):
        a gust's slow cooling then no longer passes for the contact's slow departure. None,
        or a sensor without dynamics, smoothing or such a heater: eq. 5 as is.

    Returns
    -------
    onset : float
        Refined onset time, s.
    initial : float
        Sensor temperature at the onset (the baseline there), deg C.
    """
    from skin.models.physics import SensorConstants, contact_response

    dynamic = sensor is not None and _has_dynamics(sensor, step)
    heated = sensor is not None and sensor.heater in HEATER_TERMS
    if sensor is not None and sensor.heater == "pid":
        # the loop holds the sensor at its setpoint: its reading has no slope of its own
        # (a drift is high-passed away), and a detector's slope is the contact's own early
        # departure, which dated pid-logger's synthetic contacts ~120 ms late
        slope = 0.0
    search, horizon = refine_span(sensor, search, horizon)
    t = np.asarray(times, dtype=float)
    y = np.asarray(temperature, dtype=float)
    ok = np.isfinite(y) & (t <= coarse + horizon)
    t, y = t[ok], y[ok]
    grid = coarse - np.arange(0.0, search + step / 2, step)[::-1]
    if t.size < 3:
        return coarse, baseline
    # pairs of samples a sample apart (the whitening below pairs no sample across a hole)
    gaps = np.diff(t)
    adjacent = gaps < 1.5 * np.median(gaps)
    body = SensorConstants(depth=depth, diffusivity=diffusivity)
    pre_model = baseline + slope * (t - coarse)
    # the response is tabulated once per rate on a lag grid a fifth of a step fine and read by
    # linear interpolation: exact at the grid's lags, and far fewer erfcx calls than lags
    dl = step / 5
    # a non-causal smoothing (Savitzky-Golay) starts the reading's departure before the onset
    lead = (sensor.smoothing_window // 2) / sensor.sample_rate \
        if (dynamic or heated) and sensor.smoothing == "savgol" else 0.0
    lags = np.arange(int(np.ceil((t[-1] - grid[0] + lead) / dl)) + 2) * dl - lead

    def best_fit(onsets: np.ndarray, rate_grid: np.ndarray,
                 table: np.ndarray) -> tuple[float, float]:
        base_at = baseline + slope * (onsets - coarse)  # (m,)
        lag = t[None, :] - onsets[:, None]  # (m, n)
        after = lag > -lead
        x = np.maximum(lag + lead, 0.0) / dl
        i = np.minimum(x.astype(np.int64), len(lags) - 2)
        f = x - i
        basis = table[:, i] * (1 - f) + table[:, i + 1] * f  # (rates, m, n); R(0) = 0
        target = np.where(after, y[None, :] - base_at[:, None], 0.0)  # (m, n)
        before = np.where(after, 0.0, y - pre_model)
        # least squares in D for each (rate, onset): sse = |target|^2 - (basis.target)^2/|basis|^2
        den = np.einsum("rmn,rmn->rm", basis, basis)
        num = np.einsum("rmn,mn->rm", basis, target)
        explained = np.divide(num**2, den, out=np.zeros_like(den), where=den > 0)
        sse = ((target**2).sum(-1) + (before**2).sum(-1))[None, :] - explained  # (rates, m)
        r, m = np.unravel_index(int(np.argmin(sse)), sse.shape)
        return float(onsets[m]), float(rate_grid[r])

    def best_fit_level(onsets: np.ndarray, rate_grid: np.ndarray,
                       table: np.ndarray) -> tuple[float, float]:
        # a sensor with dynamics: the baseline's level is fitted with D (least squares in
        # both; the slope stays the detector's), as the loop, the lag and the air's flutter
        # move the detector's smoothed level; over the whole window, the response continuing
        # the baseline's slope
        lag = t[None, :] - onsets[:, None]  # (m, n)
        x = np.maximum(lag + lead, 0.0) / dl
        i = np.minimum(x.astype(np.int64), len(lags) - 2)
        f = x - i
        basis = np.where(lag > -lead, table[:, i] * (1 - f) + table[:, i + 1] * f, 0.0)
        z = y - slope * (t - coarse)  # (n,)
        if rho[0] > 0:  # whitened: the level's column is a constant still, 1 - rho
            z = (z[1:] - rho[0] * z[:-1])[adjacent]
            basis = (basis[..., 1:] - rho[0] * basis[..., :-1])[..., adjacent]
            zc = z - z.mean()
            bc = basis - basis.mean(-1, keepdims=True)
            num = np.einsum("rmn,n->rm", bc, zc)
            den = np.einsum("rmn,rmn->rm", bc, bc)
            explained = np.divide(num**2, den, out=np.zeros_like(den), where=den > 1e-300)
            r, m = np.unravel_index(int(np.argmax(explained)), explained.shape)
            return float(onsets[m]), float(rate_grid[r])
        n = float(t.size)
        s_b = basis.sum(-1)  # (rates, m)
        s_bb = np.einsum("rmn,rmn->rm", basis, basis)
        s_bz = np.einsum("rmn,n->rm", basis, z)
        s_z = float(z.sum())
        det = n * s_bb - s_b**2
        ok = det > 1e-12 * np.maximum(n * s_bb, 1e-300)
        # explained energy of [1, basis] minus that of [1] alone
        explained = np.divide((n * s_bz - s_b * s_z) ** 2, n * det, out=np.zeros_like(det),
                              where=ok)
        r, m = np.unravel_index(int(np.argmax(explained)), explained.shape)
        return float(onsets[m]), float(rate_grid[r])

    def best_fit_heater(onsets: np.ndarray, rate_grid: np.ndarray,
                        table: np.ndarray) -> tuple[float, float]:
        # the drained heater's column beside the response (`heater_basis`: 2 columns per
        # rate), both scaled by least squares; with dynamics the baseline's level too (as in
        # `best_fit_level`), else the detector's baseline as in `best_fit`
        lag = t[None, :] - onsets[:, None]  # (m, n)
        after = lag > -lead
        x = np.maximum(lag + lead, 0.0) / dl
        i = np.minimum(x.astype(np.int64), len(lags) - 2)
        f = x - i
        basis = np.where(after, table[:, :, i] * (1 - f) + table[:, :, i + 1] * f, 0.0)
        if dynamic:  # the level fitted too: centre the columns and the data
            z = y - slope * (t - coarse)
            if rho[0] > 0:  # whitened (AR(1)): the level's column is a constant still
                z = (z[1:] - rho[0] * z[:-1])[adjacent]
                basis = (basis[..., 1:] - rho[0] * basis[..., :-1])[..., adjacent]
            basis = basis - basis.mean(-1, keepdims=True)  # (2, rates, m, n)
            target = np.broadcast_to(z - z.mean(), basis.shape[2:])
            rest = np.zeros(lag.shape[0])
        else:
            base_at = baseline + slope * (onsets - coarse)
            target = np.where(after, y[None, :] - base_at[:, None], 0.0)  # (m, n)
            before = np.where(after, 0.0, y - pre_model)
            rest = (target**2).sum(-1) + (before**2).sum(-1)  # (m,)
        # least squares in both weights: the explained energy of the 2x2 normal equations
        r0, r1 = basis[0], basis[1]  # (rates, m, n)
        g00 = np.einsum("rmn,rmn->rm", r0, r0)
        g01 = np.einsum("rmn,rmn->rm", r0, r1)
        g11 = np.einsum("rmn,rmn->rm", r1, r1)
        u = np.einsum("rmn,mn->rm", r0, target)
        v = np.einsum("rmn,mn->rm", r1, target)
        det = g00 * g11 - g01**2
        ok = (det > 1e-12 * np.maximum(g00 * g11, 1e-300)) & (g00 > 0)
        # the drain's weight is T_amb - T0: the body drains towards the room, by at most
        # DRAIN_BOUND times its heated rise; the least-squares weight is clamped there (the
        # sum of squares is convex in it once D is fitted) and D refitted
        e_fit = np.divide(g00 * v - g01 * u, det, out=np.zeros_like(det), where=ok)
        e_amb = np.clip(e_fit, *bounds)
        g00s = np.where(g00 > 0, g00, 1.0)
        explained = np.where(g00 > 0, 2 * e_amb * v - e_amb**2 * g11
                             + (u - e_amb * g01) ** 2 / g00s, 0.0)
        sse = rest[None, :] - explained  # (rates, m)
        r, m = np.unravel_index(int(np.argmin(sse)), sse.shape)
        # the residual's sum of squares and its samples, for `choose` (dynamic: the target's
        # rows are all the centred data)
        last[0] = float(sse[r, m]) + (float(target[0] @ target[0]) if dynamic else 0.0)
        last[1] = float(target.shape[-1])
        return float(onsets[m]), float(rate_grid[r])

    if heated:
        best_fit = best_fit_heater
        bounds = ((-DRAIN_BOUND * sensor.heated_rise, 0.0) if sensor.heater == "off-at-contact"
                  else (0.0, 1.0))
    elif dynamic:
        best_fit = best_fit_level

    def tabulate(rate_grid: np.ndarray) -> np.ndarray:
        if heated:
            return heater_basis(lags, rate_grid, body, sensor)  # (2, rates, lags)
        if dynamic:
            return sensor_response(lags, rate_grid, body, sensor)
        return contact_response(lags[None, :], rate_grid[:, None], body)  # (rates, lags)

    rho = [0.0]  # the residual's AR(1) coefficient, once estimated (`_residual_ar1`)

    last = [0.0, 1.0]  # the latest heater fit's residual sum of squares and its samples

    def search_all(rates: tuple[float, ...] = rates) -> tuple[float, float]:
        # coarse to fine: every rate on a 4-step grid over the whole span, then every rate on
        # the step grid around the best, then finer rates and fifths of a step around that
        rate_grid = np.asarray(rates, dtype=float)
        table = tabulate(rate_grid)
        onset, rate = best_fit(grid[::-4][::-1], rate_grid, table)
        near = grid[np.abs(grid - onset) <= 4 * step + 1e-9]
        onset, rate = best_fit(near, rate_grid, table)

        def around(rate: float) -> np.ndarray:
            # finer rates about the best; with dynamics kept within the caller's finite
            # rates: halved at each of its four stages a rate left the grid (16x below its
            # least) and a fit on such a bound dated a brick contact a second early (without
            # dynamics a single stage, at most 2x beyond: left free, paper's onsets as they
            # were; clipped there too, paper seed 0's median went 20.4 -> 20.7 ms)
            if np.isinf(rate):
                return np.array([rate])
            finer = rate * 2.0 ** np.arange(-1.0, 1.01, 0.25)
            return np.unique(np.clip(finer, *span)) if dynamic else finer

        if dynamic:
            # through a loop, a lag and a smoothing a slower rate looks much like an earlier
            # onset: refine both together, over a wider span, a few times (a drained heater's
            # column alone does not need it: on fast-film's synthetic contacts it left the
            # median error at 3-4 ms and cost 1.7-3x)
            for _ in range(3):
                near = grid[np.abs(grid - onset) <= 8 * step + 1e-9]
                both = np.unique(np.concatenate([rate_grid, around(rate)]))
                onset, rate = best_fit(near, both, tabulate(both))
        fine_rates = around(rate)
        fine = np.clip(onset + np.arange(-step, step + 1e-9, step / 5), grid[0], grid[-1])
        return best_fit(fine, fine_rates, tabulate(fine_rates))

    finite = [r for r in rates if np.isfinite(r)]
    span = (min(finite), max(finite)) if finite else (np.inf, np.inf)

    def choose(penalise: bool) -> tuple[float, float]:
        # through a loop, a lag and a smoothing with a heater term beside them, a slower
        # closing rate looks much like an earlier onset, and the free rate dated low-cost's
        # contacts early (signed median -116..-366 ms, seeds 0/2/4/6): a finite rate is kept
        # only when it lowers the residual sum of squares by more than Schwarz's criterion
        # for one parameter, sigma^2 ln n, sigma^2 the perfect contact's residual per sample
        # (only on whitened samples, ``penalise``: on the raw ones the residual's lag-1
        # autocorrelation is 0.95-0.98 and sigma^2 ln n under-penalises 40-100 fold); only
        # when the caller's rates hold perfect contact; the first, unwhitened pass fits
        # perfect contact alone, its residual only giving the AR(1) coefficient (the
        # unpenalised free rate instead: low-cost seeds 0/2/4/6 within 1 ms, the same)
        if not penalise and dynamic and heated and np.inf in rates:
            return search_all((np.inf,))
        onset, rate = search_all()
        if not (penalise and dynamic and heated) or np.isinf(rate) or np.inf not in rates:
            return onset, rate
        sse_free = last[0]
        perfect, inf_rate = search_all((np.inf,))
        sse_perfect, n = last
        if sse_perfect - sse_free <= sse_perfect / n * np.log(n):
            return perfect, inf_rate
        return onset, rate

    onset, rate = choose(False)
    if dynamic:
        # the residual of a slow sensor's fit is far from white (the air's flutter through
        # the loop and the lag, a smoothing): estimate its lag-1 autocorrelation and refit on
        # samples whitened by it (feasible generalised least squares, AR(1)); on pid-logger's
        # synthetic streams the onset error median fell from 79-109 ms to 16-77 ms
        table = tabulate(np.array([rate]))  # (rates=1, lags), or (2, 1, lags) heated
        rho[0] = _residual_ar1(t, y - slope * (t - coarse), onset, lead, dl,
                               table.reshape(-1, table.shape[-1]), adjacent)
        if rho[0] > 0 or heated:  # heated: Schwarz's test on the (whitened) samples
            onset, rate = choose(True)
    return onset, float(baseline + slope * (onset - coarse))


def refine_span(sensor: object | None, search: float = 0.6,
                horizon: float = 0.6) -> tuple[float, float]:
    """Return `refine_onset`'s search span and horizon for a sensor, s.

    Both stretch with the sensor's response time when it is slower than the paper's (None:
    the paper's); a caller cuts the taxel's samples from ``coarse - search`` to
    ``coarse + horizon``.
    """
    if sensor is None:
        return search, horizon
    from skin.models.sensors import SensorDescription

    stretch = max(1.0, sensor.response_time / SensorDescription().response_time)
    # a slow sensor whose noise is large against its heated rise is detected late, well into
    # the contact (low-cost: coarse onsets 1.7-4.3 s after it): the span before the coarse
    # onset stretches once more, by that noise over the paper's (up to SPAN_MORE, and no more
    # than the response time), and the horizon after it as much less, so that fewer samples
    # after the release enter the fit
    more = min(stretch, SPAN_MORE, max(1.0, _relative_noise(sensor)
                                      / _relative_noise(SensorDescription())))
    return search * stretch * more, horizon * stretch / more


@functools.lru_cache(maxsize=64)
def _relative_noise(sensor: object) -> float:
    """Return a sensor's smoothed reading noise over its heated rise (both K)."""
    return sensor.delivered_noise() / sensor.heated_rise


def _residual_ar1(t: np.ndarray, z: np.ndarray, onset: float, lead: float, dl: float,
                  table: np.ndarray, adjacent: np.ndarray) -> float:
    """Return the lag-1 autocorrelation of a fit's residual, clipped to [0, `AR1_MAX`].

    ``z`` is the reading less the baseline's slope, ``table`` the response's columns at the
    fitted rate on `refine_onset`'s lag grid (step ``dl``, from ``-lead``), shape (k, lags):
    the response alone, or the response and a heater's term (`heater_basis`); the level and
    the columns' weights are fitted by least squares (unbounded) at ``onset``. The fit that
    chose ``onset`` bounds a heater weight (to [0, 1], or the drain's bound): where that bound
    binds, the unbounded weight here leaves a smaller, less correlated residual than the
    fit's, so rho is if anything under-estimated and the second fit whitened less (how often
    the bound binds and what it costs is not measured); ``adjacent``
    marks the pairs of samples (``z[1:]``, ``z[:-1]``) a sample apart, the only ones it is
    estimated from.
    """
    table = np.atleast_2d(table)
    x = np.maximum(t - onset + lead, 0.0) / dl
    i = np.minimum(x.astype(np.int64), table.shape[-1] - 2)
    f = x - i
    cols = np.where(t - onset > -lead, table[:, i] * (1 - f) + table[:, i + 1] * f, 0.0)
    a = np.column_stack([np.ones_like(z), *cols])
    res = z - a @ np.linalg.lstsq(a, z, rcond=None)[0]
    now, prev = res[1:][adjacent], res[:-1][adjacent]
    energy = float(prev @ prev)
    if not energy > 0:
        return 0.0
    return float(np.clip(float(now @ prev) / energy, 0.0, AR1_MAX))


def _has_dynamics(sensor: object, step: float = 0.005) -> bool:
    """Whether the sensor's reading differs from eq. 5 by a loop, a lag or a smoothing.

    A smoothing that spans less than two grid steps of the refinement (``step``, s) is left
    out: it moves the fitted onset by less than the grid resolves (measured on the fast-film
    preset, 1 kHz with an 8-sample moving average: refined onset error median 8.8 ms with
    it fitted, 6.2 ms without).
    """
    if sensor.heater == "pid" or sensor.lag > 0:
        return True
    fs = sensor.sample_rate
    span = {"none": 0.0, "moving-average": sensor.smoothing_window / fs,
            "savgol": sensor.smoothing_window / fs,
            "low-pass": 1.0 / (2.0 * np.pi * sensor.smoothing_cutoff)}[sensor.smoothing]
    return span > 2 * step


def sensor_response(lags: np.ndarray, rates: np.ndarray, body: object,
                    sensor: object) -> np.ndarray:
    """Return the reading's response to a unit contact step through the sensor's own dynamics.

    `skin.models.physics.contact_response` at the thermistor, then the PID loop and the
    thermistor lag (`skin.models.sensors.apply_dynamics`) and the sensor's smoothing, computed
    at the sensor's sample rate from before the step (a non-causal smoothing starts the
    departure early: negative lags within its half window are not 0) and read at ``lags`` by
    linear interpolation.

    Parameters
    ----------
    lags : numpy.ndarray, shape (n,)
        Times since contact, s (negative: before it).
    rates : numpy.ndarray, shape (r,)
        Contact closing rates, s^-0.5 (``inf``: perfect contact).
    body : skin.models.physics.SensorConstants
        Depth and diffusivity of the thermistor.
    sensor : skin.models.sensors.SensorDescription
        Sample rate, heater mode, lag and smoothing.

    Returns
    -------
    numpy.ndarray, shape (r, n)
    """
    from skin.models.physics import contact_response
    from skin.models.sensors import apply_dynamics, smooth

    fs, grid = _sample_grid(lags, sensor)
    step = contact_response(np.maximum(grid, 0.0)[:, None], np.asarray(rates)[None, :], body)
    step = np.where(grid[:, None] > 0, step, 0.0)
    out = smooth(apply_dynamics(step, sensor, fs, axis=0), sensor, axis=0, fs=fs)
    return np.stack([np.interp(lags, grid, out[:, k]) for k in range(out.shape[1])])


def _sample_grid(lags: np.ndarray, sensor: object) -> tuple[float, np.ndarray]:
    """Return the sensor's sample rate and its sample times spanning ``lags`` (s), padded.

    The padding holds a smoothing window's samples before the step and after the last lag.
    """
    fs = float(sensor.sample_rate)
    pad = max(int(sensor.smoothing_window), 1) + 2  # samples before the step and after the end
    pad = max(pad, int(np.ceil(-float(np.min(lags, initial=0.0)) * fs)) + 2)
    n = int(np.ceil(float(np.max(lags, initial=0.0)) * fs)) + 2 + pad
    return fs, np.arange(-pad, n) / fs


def heater_basis(lags: np.ndarray, rates: np.ndarray, body: object,
                 sensor: object) -> np.ndarray:
    """Return the two columns of a reading whose heater acts in contact, filtered.

    A heater left on during contact (``"on-during-contact"``): the columns are R and the
    heater's flux at the thermistor in K with all of it going into the sensor
    (`skin.models.sensors.heater_term` for an object of effusivity 0); a contact scales the
    flux by the sensor's share e_s / (e_s + e_o), which `refine_onset` bounds to [0, 1]. A
    heater switched off at contact (``"off-at-contact"``):

    A sensor's reading after contact is ``T0 + (T_obj - T0) P + (T_amb - T0) Q``
    (`skin.models.sensors.contact_basis`), with ``P = s R`` (s the object's share, R eq. 5's
    response at closing rate H) and ``Q = d (1 - s R)``, ``d = 1 - exp(-t / tau)`` the body's
    drain (tau = l^2 / alpha, `reheat_time_constant`): the reading moves from the contact's
    first instant, linearly in t, while R starts flat. The temperatures and the share are
    unknown to the refinement, so the columns are R and d, each with its own least-squares
    weight (the small ``d R`` term is left to them: as a third free column it traded with
    the onset and dated fast-film's synthetic contacts worse, median |error| 9 ms against
    3.5 ms). Each column goes through the sensor's loop, lag and smoothing
    (`skin.models.sensors.apply_dynamics`, `smooth`) on its own sample grid, as
    `sensor_response` does (R and d are fractions, 0 to 1, before the filters).

    Parameters
    ----------
    lags : numpy.ndarray, shape (n,)
        Times since contact, s (negative: before it).
    rates : numpy.ndarray, shape (r,)
        Contact closing rates, s^-0.5 (``inf``: perfect contact).
    body : skin.models.physics.SensorConstants
        Depth and diffusivity of the thermistor.
    sensor : skin.models.sensors.SensorDescription
        An ``"off-at-contact"`` or ``"on-during-contact"`` sensor: its reheat time constant or
        heater power, sample rate, lag and smoothing.

    Returns
    -------
    numpy.ndarray, shape (2, r, n)
        R and d (or the flux, K), filtered, at ``lags``.
    """
    from skin.models.physics import contact_response
    from skin.models.sensors import apply_dynamics, smooth

    if sensor.heater not in HEATER_TERMS:
        raise ValueError(f"heater_basis needs a heater mode in {HEATER_TERMS}, "
                         f"got {sensor.heater!r}")
    rates = np.asarray(rates, dtype=float)
    fs, grid = _sample_grid(lags, sensor)
    since = np.maximum(grid, 0.0)
    after = grid > 0
    r = np.where(after[:, None], contact_response(since[:, None], rates[None, :], body), 0.0)
    if sensor.heater == "off-at-contact":
        d = np.where(after, -np.expm1(-since / sensor.reheat_time_constant), 0.0)[:, None]
    else:  # the flux of a heater left on, all of it into the sensor (the object's share 0)
        from skin.models.sensors import heater_term

        d = np.asarray(heater_term(since, 0.0, 0.0, sensor))[:, None]
    stacked = np.stack([r, np.broadcast_to(d, r.shape)])  # (2, grid, r)
    out = smooth(apply_dynamics(stacked, sensor, fs, axis=1), sensor, axis=1, fs=fs)
    return np.stack([[np.interp(lags, grid, out[c, :, k]) for k in range(out.shape[2])]
                     for c in range(out.shape[0])])

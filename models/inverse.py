"""Inverse estimators: the object's effusivity (and more) from a thermistor trace after contact.

Two estimators, taking many trials at once (the fit is vectorised over them):

- `paper_effusivity`: the paper's pointwise estimate (eqs. 9-11) at every sample, summarised
  by the median; "unknown" (NaN with ``valid`` False) when fewer than ``min_samples`` remain,
  "out of range" (0 or inf with ``valid`` False) when the median lies within the resolution
  of the sensor's or the object's temperature. It assumes perfect contact and an object at
  ambient.
- `fit_contact`: non-linear least squares of log10 effusivity, object temperature and
  log10 contact conductance (optionally the sensor's initial temperature) over the whole window,
  with the finite-conductance closed form (`skin.models.physics.contact_trace`). A batched
  Levenberg-Marquardt with Gaussian priors (maximum a posteriori): the semi-infinite model
  sees only an amplitude and a time scale, so effusivity, object temperature and conductance
  are not all identifiable from one trace; the priors (object near ambient, conductance of a
  light touch) resolve what the data cannot, and the reported uncertainty says how much did.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skin.models.physics import SensorConstants, contact_response, depth_response

_LOG_E_BOUNDS = (0.5, 5.5)  # 3 .. 3e5 W s^0.5/(m^2 K): aerogel to diamond
_LOG_H_BOUNDS = (1.0, 7.0)
_T_BOUNDS = (-40.0, 150.0)
_CONVERGED_CHI2 = 0.01  # chi^2 a Gauss-Newton step may still promise at a converged fit
_PROFILE_CHI2 = 4.0  # the profile interval: within this of the optimum's cost (2 std)


@dataclass(frozen=True)
class Priors:
    """Gaussian priors of `fit_contact` (means and standard deviations).

    Attributes
    ----------
    log10_effusivity : tuple of float
        Mean and std of log10 e; weak by default (3.0 +- 1.5 decades: foam to metal).
    object_offset : tuple of float
        Mean and std of the object's temperature minus ambient, K (0 +- 3: objects sit near
        ambient; a hand at 33 C in a 25 C room is 2.7 std away, still reachable).
    log10_conductance : tuple of float
        Mean and std of log10 h, W/(m^2 K) (3.5 +- 0.75: a light touch of a foil sensor).
    sensor_temperature_std : float
        Std of the sensor's initial temperature around the pre-contact reading, K.
    onset_std : float
        Std of the true contact instant around the given onset, s (two samples at 200 Hz).
    centre_on_paper_estimate : bool
        Centre the log10 e prior on each trial's paper estimate (`paper_effusivity`; the
        bound it is beyond when out of range) where that is above ``log10_effusivity[0]``,
        keeping its std (imperfect contact only lowers the paper's estimate). Where the trace
        cannot separate e from the object's temperature (metals), the fit then stays near the
        estimate that assumes the object at ambient instead of being pulled towards 1e3.
    """

    log10_effusivity: tuple[float, float] = (3.0, 1.5)
    object_offset: tuple[float, float] = (0.0, 3.0)
    log10_conductance: tuple[float, float] = (3.5, 0.75)
    sensor_temperature_std: float = 0.05
    onset_std: float = 0.01
    centre_on_paper_estimate: bool = True


@dataclass
class ContactFit:
    """Result of `fit_contact`, one value per trial.

    Attributes
    ----------
    effusivity : numpy.ndarray
        Object effusivity, W s^0.5 / (m^2 K).
    log10_effusivity_std : numpy.ndarray
        Posterior standard deviation of log10 effusivity, decades.
    object_temperature, object_temperature_std : numpy.ndarray
        deg C, K.
    conductance, log10_conductance_std : numpy.ndarray
        Contact conductance h, W/(m^2 K), and the std of its log10.
    sensor_temperature : numpy.ndarray
        Sensor temperature at contact, deg C (fitted or as given).
    rms : numpy.ndarray
        RMS residual of the readings, K.
    iterations : int
        Levenberg-Marquardt iterations taken.
    log10_effusivity_interval : numpy.ndarray or None
        (n_trials, 2): the profile interval of log10 e (``interval=True``): where the
        posterior cost, minimised over every other parameter, is within 4 chi^2 of the
        optimum (two standard deviations were it Gaussian). None when not asked for.
    log10_effusivity_median : numpy.ndarray or None
        The median of log10 e under ``exp(-profile cost / 2)`` (``interval=True``): where the
        valley is flat (metals) the optimum sits where the priors balance, and the median
        weighs the whole valley (trial generator, 2.5 s, seeds 0 and 7: aluminium -0.47 ->
        +0.07 / -0.04 decades, steel -0.57 / -0.45 -> +0.07 / 0.00, copper -0.71 / -0.70 ->
        -0.30 / -0.35; brick reads 0.4-0.5 decades higher than the optimum).
    """

    effusivity: np.ndarray
    log10_effusivity_std: np.ndarray
    object_temperature: np.ndarray
    object_temperature_std: np.ndarray
    conductance: np.ndarray
    log10_conductance_std: np.ndarray
    sensor_temperature: np.ndarray
    onset_shift: np.ndarray
    rms: np.ndarray
    converged: np.ndarray
    iterations: int
    log10_effusivity_interval: np.ndarray | None = None
    log10_effusivity_median: np.ndarray | None = None


def paper_effusivity(
    t: np.ndarray,
    temperature: np.ndarray,
    t_sensor: np.ndarray | float,
    t_object: np.ndarray | float,
    sensor: SensorConstants | None = None,
    min_samples: int = 5,
    min_response: float = 0.02,
    min_difference: float = 0.05,
) -> tuple[np.ndarray, np.ndarray]:
    """Paper's pointwise effusivity estimate (eqs. 10-11), median over a trial's samples.

    Each sample (whose depth response erfc(...) is at least ``min_response``) gives the share
    ``f = (T_sens(0) - T_surf) / (T_sens(0) - T_obj)`` of the step its surface took, and
    ``e = e_s f / (1 - f)`` grows monotonically with it, so the median of ``e`` is ``e`` of
    the median of ``f``. The median is taken over every such sample: one whose surface lies
    within ``min_difference`` of the sensor's or the object's temperature is not dropped (which
    biased the median towards the cut: any e below about 10 read log e ~ 1, anything above
    about 1e5 saturated) but counts as below or above the resolvable range. When the median
    itself falls there, the trial is out of range.

    Parameters
    ----------
    t : numpy.ndarray
        Time since contact of each sample, s, shape (n_samples,).
    temperature : numpy.ndarray
        Readings, shape (n_trials, n_samples) or (n_samples,).
    t_sensor, t_object : array_like
        Sensor temperature at contact and object temperature (the paper: ambient), per trial.
    sensor : SensorConstants, optional
        Sensor constants (default: the paper's).
    min_samples : int
        Fewest usable samples for an estimate.
    min_response : float
        Samples whose depth response is below this are not used (t -> 0).
    min_difference : float
        The resolution, K: a surface temperature closer than this to the sensor's (the object
        is too insulating to tell from nothing) or to the object's (too conductive to tell from
        a perfect conductor) is out of range; so is a sensor within it of the object.

    Returns
    -------
    effusivity : numpy.ndarray
        Median estimate per trial; 0 where it is below the resolvable range
        (``e_s d / (|T_sens(0) - T_obj| - d)``, d = ``min_difference``: about 2.4 for the
        paper's sensor 14 K above the object), ``inf`` where it is above it (about 1.8e5), NaN
        where unknown (too few samples, or the sensor at the object's temperature).
    valid : numpy.ndarray
        Whether the trial has an estimate inside the range.
    """
    s = SensorConstants() if sensor is None else sensor
    t = np.asarray(t, dtype=float)
    y = np.atleast_2d(np.asarray(temperature, dtype=float))
    n = y.shape[0]
    t0 = np.broadcast_to(np.asarray(t_sensor, dtype=float), (n,))
    tobj = np.broadcast_to(np.asarray(t_object, dtype=float), (n,))
    out = np.full(n, np.nan)
    resp = depth_response(t, s)
    usable = resp >= min_response
    step = t0 - tobj
    for i in range(n):  # each trial keeps its own samples
        keep = usable & np.isfinite(y[i])
        if keep.sum() < min_samples or abs(step[i]) < 2 * min_difference:
            continue  # no signal: unknown
        surf = t0[i] + (y[i, keep] - t0[i]) / resp[keep]  # eq. 11
        share = float(np.median((t0[i] - surf) / step[i]))
        cut = min_difference / abs(step[i])
        if share <= cut:
            out[i] = 0.0
        elif share >= 1.0 - cut:
            out[i] = np.inf
        else:
            out[i] = s.effusivity * share / (1.0 - share)  # eq. 10
    return out, np.isfinite(out) & (out > 0)


def fit_contact(
    t: np.ndarray,
    temperature: np.ndarray,
    t_sensor: np.ndarray | float,
    ambient: np.ndarray | float,
    sensor: SensorConstants | None = None,
    priors: Priors | None = None,
    fit_sensor_temperature: bool = False,
    fit_onset: bool = False,
    noise: float | None = None,
    max_iter: int = 60,
    interval: bool = False,
) -> ContactFit:
    """Fit effusivity, object temperature and contact conductance to traces after contact.

    Parameters
    ----------
    t : numpy.ndarray
        Time since contact of each sample, s, shape (n_samples,); samples at t <= 0 are used
        as they are (they pin the sensor's temperature).
    temperature : numpy.ndarray
        Readings, deg C, shape (n_trials, n_samples) or (n_samples,).
    t_sensor : array_like
        Sensor temperature just before contact, deg C, per trial.
    ambient : array_like
        Ambient temperature, deg C, per trial (the centre of the object-temperature prior).
    sensor : SensorConstants, optional
        Sensor constants (default: the paper's).
    priors : Priors, optional
        Gaussian priors (default `Priors()`).
    fit_sensor_temperature : bool
        Also fit the sensor's initial temperature (prior: ``t_sensor`` +- its std).
    fit_onset : bool
        Also fit a shift of the contact instant against ``t = 0`` (prior: 0 +- ``onset_std``),
        for onsets known only to a few samples.
    noise : float, optional
        Reading noise std, K; default: each trial's own, from the residuals of a first fit
        (at least 0.01 K), then fitted again with it.
    max_iter : int
        Levenberg-Marquardt iterations at most (per pass).
    interval : bool
        Also find the profile interval of log10 e (`ContactFit.log10_effusivity_interval`).
        The standard deviations come from the curvature at the optimum; where the posterior
        is a curved ridge (a low contact conductance traded against a low effusivity, as on
        brick in 0.25-0.5 s) they are far too narrow, and the profile follows the ridge.
        Costs about 10-20 more fits.

    Returns
    -------
    ContactFit
        Estimates and posterior standard deviations per trial.
    """
    s = SensorConstants() if sensor is None else sensor
    pr = Priors() if priors is None else priors
    t = np.asarray(t, dtype=float)
    y = np.atleast_2d(np.asarray(temperature, dtype=float))
    n_trials, n_samples = y.shape
    if t.shape != (n_samples,):
        raise ValueError(f"t has shape {t.shape}, the readings have {n_samples} samples")
    if not np.all(np.isfinite(y)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(y), axis=1))[0])
        raise ValueError(f"trial {bad}: readings contain NaN or inf")
    t0 = np.broadcast_to(np.asarray(t_sensor, dtype=float), (n_trials,)).copy()
    amb = np.broadcast_to(np.asarray(ambient, dtype=float), (n_trials,)).copy()

    names = ["log10_e", "t_object", "log10_h"]
    names += ["t_sensor"] * fit_sensor_temperature + ["onset"] * fit_onset
    n_par = len(names)
    prior = {"log10_e": (pr.log10_effusivity[0], pr.log10_effusivity[1], _LOG_E_BOUNDS),
             "t_object": (amb + pr.object_offset[0], pr.object_offset[1], _T_BOUNDS),
             "log10_h": (pr.log10_conductance[0], pr.log10_conductance[1], _LOG_H_BOUNDS),
             "t_sensor": (t0, pr.sensor_temperature_std, _T_BOUNDS),
             "onset": (0.0, pr.onset_std, (-5 * pr.onset_std, 5 * pr.onset_std))}
    mean = np.stack([np.broadcast_to(prior[k][0], (n_trials,)) for k in names], axis=1)
    std = np.array([prior[k][1] for k in names])
    lo = np.array([prior[k][2][0] for k in names])
    hi = np.array([prior[k][2][1] for k in names])
    step_size = np.array([{"t_object": 1e-3, "t_sensor": 1e-3, "onset": 1e-4}.get(k, 1e-4)
                          for k in names])
    # The solver works in the coordinates the trace sees: the contact temperature T_surf
    # (eq. 3) and the rate H = h (1/e_s + 1/e) in place of the object's temperature and log h.
    # The trace depends on (T_surf, H) alone, so the valley the data leave flat (metals: any
    # e >> e_s with T_obj just below T_surf) is a straight line along log e there, which
    # Levenberg-Marquardt follows in a few steps; in (log e, T_obj, log h) it was a curved
    # valley it crawled along (28-49 % of trials stopped at max_iter, flagged not converged).
    # The priors and the result stay in the natural coordinates: same objective, same MAP.
    e_s = s.effusivity
    lo[1:3] = _T_BOUNDS[0], _LOG_H_BOUNDS[0] + np.log10(1 / e_s + 10.0 ** -_LOG_E_BOUNDS[1])
    hi[1:3] = _T_BOUNDS[1], _LOG_H_BOUNDS[1] + np.log10(1 / e_s + 10.0 ** -_LOG_E_BOUNDS[0])

    def sensor_start(q: np.ndarray) -> np.ndarray:
        return q[:, 3] if fit_sensor_temperature else t0

    def natural(q: np.ndarray) -> np.ndarray:
        """(log e, T_surf, log H, ...) -> (log e, T_obj, log h, ...)."""
        p = q.copy()
        inv_e = 10.0 ** -q[:, 0]
        p[:, 1] = q[:, 1] + (q[:, 1] - sensor_start(q)) * e_s * inv_e
        p[:, 2] = q[:, 2] - np.log10(1 / e_s + inv_e)
        return p

    def fitting(p: np.ndarray) -> np.ndarray:
        """(log e, T_obj, log h, ...) -> (log e, T_surf, log H, ...)."""
        q = p.copy()
        e = 10.0 ** p[:, 0]
        q[:, 1] = p[:, 1] + (sensor_start(p) - p[:, 1]) * e_s / (e_s + e)
        q[:, 2] = p[:, 2] + np.log10(1 / e_s + 1 / e)
        return q

    def model(q: np.ndarray) -> np.ndarray:
        ts = sensor_start(q)[:, None]
        shift = q[:, -1:] if fit_onset else 0.0
        return ts + (q[:, 1:2] - ts) * contact_response(t - shift, 10.0 ** q[:, 2:3], s)

    if noise is not None and not (np.isfinite(noise) and noise > 0):
        raise ValueError(f"noise must be a positive standard deviation, got {noise!r}")
    if n_samples < 3 or not np.all(np.isfinite(t)):
        raise ValueError(f"need at least 3 samples at finite times, got {n_samples}")

    def residuals(p: np.ndarray, sig: np.ndarray | float) -> np.ndarray:
        data = (y - model(p)) / np.reshape(sig, (-1, 1))
        return np.concatenate([data, (natural(p) - mean) / std], axis=1)

    def jacobian(p: np.ndarray, r: np.ndarray, sig: np.ndarray | float) -> np.ndarray:
        jac = np.empty((n_trials, r.shape[1], n_par))
        for j in range(n_par):
            step = np.zeros(n_par)
            step[j] = step_size[j]
            # central differences: forward ones left the fit short of the optimum where the
            # noise is small (a noise-free trace stalled at 6e-5 K RMS with noise = 1e-3)
            jac[:, :, j] = (residuals(p + step, sig) - residuals(p - step, sig)) / (2 * step[j])
        return jac

    def solve(p: np.ndarray, sig: np.ndarray, fix_log_e: bool = False
              ) -> tuple[np.ndarray, np.ndarray, int]:
        """Levenberg-Marquardt for every trial independently (a trial stops on its own).

        ``fix_log_e``: hold each trial's log10 e where ``p`` has it (a profile's point).
        """
        free_cols = np.ones(n_par)
        if fix_log_e:
            free_cols[0] = 0.0
        p = p.copy()
        lam = np.full(n_trials, 1e-2)
        r = residuals(p, sig)
        cost = np.sum(r**2, axis=1)
        active = np.ones(n_trials, dtype=bool)
        done = np.zeros(n_trials, dtype=bool)
        it = 0
        for it in range(1, max_iter + 1):  # noqa: B007 - the count is returned
            jac = jacobian(p, r, sig) * free_cols
            jtj = np.einsum("bki,bkj->bij", jac, jac) + np.diag(1.0 - free_cols)
            grad = np.einsum("bki,bk->bi", jac, r)
            done |= active & (left_to_gain(p, jtj, grad) < _CONVERGED_CHI2)
            active &= ~done
            if not active.any():
                break
            damp = lam[:, None, None] * (jtj * np.eye(n_par) + 1e-9 * np.eye(n_par))
            delta = -np.linalg.solve(jtj + damp, grad[:, :, None])[:, :, 0]
            trial = np.clip(p + delta, lo, hi)
            r_new = residuals(trial, sig)
            cost_new = np.sum(r_new**2, axis=1)
            better = (cost_new < cost) & active
            gain = np.where(better, (cost - cost_new) / np.maximum(cost, 1e-300), 0.0)
            p[better], r[better], cost[better] = trial[better], r_new[better], cost_new[better]
            lam = np.where(active, np.where(better, lam / 3.0, lam * 4.0), lam)
            small_step = np.max(np.abs(delta), axis=1) < 1e-6
            done |= active & ((better & (gain < 1e-9)) | small_step)
            active &= ~done & (lam < 1e10)
            if not active.any():
                break
        jac = jacobian(p, r, sig) * free_cols
        grad = np.einsum("bki,bk->bi", jac, r)
        left = left_to_gain(p, np.einsum("bki,bkj->bij", jac, jac) + np.diag(1.0 - free_cols),
                            grad)
        return p, left < _CONVERGED_CHI2, it

    def left_to_gain(p: np.ndarray, jtj: np.ndarray, grad: np.ndarray) -> np.ndarray:
        """Decrease of the cost (chi^2) a full Gauss-Newton step predicts, per trial.

        Parameters held at a bound by the gradient are left out. The residuals are whitened,
        so this is in chi^2 units whatever the noise: a trial is converged when less than
        `_CONVERGED_CHI2` is left, however flat the valley it sits in.
        """
        held = ((p <= lo) & (grad > 0)) | ((p >= hi) & (grad < 0))
        grad = np.where(held, 0.0, grad)
        free = ~held
        jtj = jtj * (free[:, :, None] & free[:, None, :]) + held[:, :, None] * np.eye(n_par)
        step = np.linalg.solve(jtj, grad[:, :, None])[:, :, 0]
        return np.einsum("bi,bi->b", grad, step)

    # the effusivity prior is centred no lower than the paper's pointwise estimate (eqs.
    # 10-11; an object at ambient, perfect contact), which an imperfect contact can only
    # lower: where the data cannot tell effusivity from the object's temperature (metals: the
    # surface sits within a K of the object's temperature for any e >> e_s), a prior centred
    # on 1e3 pulled the MAP down (-0.5 decades for aluminium, -1.1 for diamond); the start
    # is the prior mean
    if pr.centre_on_paper_estimate:
        e_paper, ok = paper_effusivity(t, y, t0, amb, s, min_samples=1)
        centre = np.where(e_paper == 0, _LOG_E_BOUNDS[0], _LOG_E_BOUNDS[1])
        centre = np.where(ok, np.log10(np.where(ok, e_paper, 1.0)), centre)
        known = ok | (e_paper == 0) | np.isinf(e_paper)
        mean[known, 0] = np.clip(np.maximum(centre[known], mean[known, 0]), *_LOG_E_BOUNDS)
    start = fitting(mean)
    if noise is None:
        # fit with a nominal noise, estimate each trial's noise from its residuals, refit
        p, _, it1 = solve(start, np.full(n_trials, 0.05))
        sig = np.maximum(np.sqrt(np.mean((y - model(p)) ** 2, axis=1)), 0.01)
        p, converged, it2 = solve(p, sig)
        iterations = it1 + it2
    else:
        sig = np.full(n_trials, float(noise))
        p, converged, iterations = solve(start, sig)

    rms = np.sqrt(np.mean((y - model(p)) ** 2, axis=1))
    bounds = median = None
    if interval:
        def profile(start: np.ndarray, log_e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            q = start.copy()
            q[:, 0] = log_e
            q, _, _ = solve(q, sig, fix_log_e=True)
            return q, np.sum(residuals(q, sig) ** 2, axis=1) - best

        best = np.sum(residuals(p, sig) ** 2, axis=1)
        bounds = np.empty((n_trials, 2))
        seen_x, seen_c = [p[:, 0].copy()], [np.zeros(n_trials)]  # the profile's points
        for side, edge in ((0, _LOG_E_BOUNDS[0]), (1, _LOG_E_BOUNDS[1])):
            sign = 1.0 if side else -1.0
            inside = p[:, 0].copy()  # last point within 4 chi^2
            start = p.copy()  # its solution: the next point starts there (along the ridge)
            out = np.full(n_trials, edge)  # first point beyond (the bound until found)
            found = np.zeros(n_trials, dtype=bool)
            width = np.full(n_trials, 0.125)
            for _ in range(6):  # step out, doubling, until the cost rises 4 chi^2
                probe = np.where(found, inside, np.clip(p[:, 0] + sign * width, *_LOG_E_BOUNDS))
                q, rise = profile(start, probe)
                seen_x.append(probe)
                seen_c.append(np.where(found, np.inf, rise))
                beyond = ~found & (rise > _PROFILE_CHI2)
                out[beyond] = probe[beyond]
                within = ~found & ~beyond
                inside[within], start[within] = probe[within], q[within]
                found |= beyond | (probe == edge)
                width *= 2.0
                if found.all():
                    break
            for _ in range(4):  # then halve the bracket
                mid = 0.5 * (inside + out)
                q, rise = profile(start, mid)
                seen_x.append(mid)
                seen_c.append(rise)
                beyond = rise > _PROFILE_CHI2
                out = np.where(beyond, mid, out)
                inside = np.where(beyond, inside, mid)
                start[~beyond] = q[~beyond]
            bounds[:, side] = out  # conservative: the bracket's outer end
        # the profile as a posterior over log e (the points the search visited): its median
        xs, cs = np.array(seen_x).T, np.array(seen_c).T
        order = np.argsort(xs, axis=1)
        xs, cs = np.take_along_axis(xs, order, 1), np.take_along_axis(cs, order, 1)
        w = np.exp(-0.5 * np.clip(cs, 0.0, 60.0)) * np.isfinite(cs)
        area = np.concatenate([np.zeros((n_trials, 1)), np.cumsum(
            0.5 * (w[:, 1:] + w[:, :-1]) * np.diff(xs, axis=1), axis=1)], axis=1)
        area /= np.maximum(area[:, -1:], 1e-300)
        median = np.array([np.interp(0.5, a, x) for a, x in zip(area, xs, strict=True)])
    r = residuals(p, sig)
    jac = jacobian(p, r, sig)
    cov = np.linalg.inv(np.einsum("bki,bkj->bij", jac, jac))
    # to the natural coordinates: cov_p = G cov_q G^T, G = d natural / d q
    grad = np.empty((n_trials, n_par, n_par))
    for j in range(n_par):
        step = np.zeros(n_par)
        step[j] = step_size[j]
        grad[:, :, j] = (natural(p + step) - natural(p - step)) / (2 * step[j])
    cov = grad @ cov @ np.swapaxes(grad, 1, 2)
    sd = np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))
    p = natural(p)
    if bounds is not None:
        # a profile solve that stops short of its minimum overstates the cost, so the interval
        # is never narrower than the curvature's two standard deviations
        bounds = np.clip(np.column_stack([np.minimum(bounds[:, 0], p[:, 0] - 2 * sd[:, 0]),
                                          np.maximum(bounds[:, 1], p[:, 0] + 2 * sd[:, 0])]),
                         *_LOG_E_BOUNDS)
    return ContactFit(
        effusivity=10.0 ** p[:, 0],
        log10_effusivity_std=sd[:, 0],
        object_temperature=p[:, 1],
        object_temperature_std=sd[:, 1],
        conductance=10.0 ** p[:, 2],
        log10_conductance_std=sd[:, 2],
        sensor_temperature=p[:, 3] if fit_sensor_temperature else t0,
        onset_shift=p[:, -1] if fit_onset else np.zeros(n_trials),
        rms=rms,
        converged=converged,
        iterations=iterations,
        log10_effusivity_interval=bounds,
        log10_effusivity_median=None if bounds is None else median,
    )

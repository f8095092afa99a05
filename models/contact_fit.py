"""The joint physics fit of a contact's channels on a (log e, log h, onset shift) grid.

After contact each channel reads ``T0_i + (T_obj - T0_i) phi(t)``, with ``phi = r R(t)`` fixed
by the object's effusivity e and the contact conductance h
(`skin.models.physics.contact_response`) and the object's temperature ``T_obj`` *shared* by
the channels. On a grid of (log e, log h, onset shift) the reading is linear in ``T_obj``, so
with a Gaussian prior on ``T_obj`` about ambient its marginal likelihood is closed form (as in
`skin.models.joint`, whose grid is the materials table's; here it is a plain log e grid).
Contacts of one window length share the grid's responses, so a batch costs two matrix
products. With one channel the object's temperature and the effusivity trade off (the
posterior over log e is wide unless the prior is narrow); a second channel at another
starting temperature pins both. numpy only: the pipeline uses it to report the effusivity it
measured.
"""

from __future__ import annotations

import functools

import numpy as np

from skin.models.physics import SensorConstants, conductance_rate, contact_response

#: log10 effusivity grid (aerogel ~1.2 to diamond ~4.8).
LOG_E = np.linspace(1.0, 5.0, 33)
#: log10 contact conductance grid, W/(m^2 K) (air gaps of ~150 um down to ~0.1 um).
LOG_H = np.linspace(2.2, 5.4, 10)
#: Onset shifts, s: how much before the given onset the contact may have begun (+) or after.
SHIFTS = (-0.01, -0.005, 0.0, 0.005, 0.01)


def grid_responses(samples: int, fs: float, sensor: SensorConstants) -> np.ndarray:
    """``phi`` on the grid for samples at k / fs, k = 0 .. samples - 1: (grid points, samples)."""
    e_o = 10.0 ** LOG_E[:, None, None, None]
    h = 10.0 ** LOG_H[None, :, None, None]
    t = np.arange(samples) / fs + np.asarray(SHIFTS)[None, None, :, None]
    r = e_o / (sensor.effusivity + e_o) * contact_response(
        np.maximum(t, 0.0), conductance_rate(h, sensor.effusivity, e_o), sensor)
    return r.reshape(-1, samples)


def grid_basis(responses: np.ndarray, rtol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """Factor the grid's responses as ``coef @ basis`` on their leading singular vectors.

    The 1,650 responses of a window are smooth curves that span few dimensions (18 singular
    values above 1e-12 of the largest at 2.5 s and 200 Hz): a window projected on that basis
    gives every grid point's product with it for ~20x fewer operations than the full product,
    and differs from it by at most ``rtol`` of the largest singular value times the window's
    norm (for a 10 K swing, ~1e-6 in a log-evidence).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``coef`` (grid points, r) and ``basis`` (r, samples).
    """
    u, sv, vt = np.linalg.svd(np.asarray(responses, dtype=float), full_matrices=False)
    r = max(int(np.sum(sv > rtol * sv[0])), 1) if sv.size and sv[0] > 0 else 1
    return u[:, :r] * sv[:r], vt[:r]


def grid_fit(ambient: np.ndarray, t0: np.ndarray, window: np.ndarray, responses: np.ndarray,
             noise: float = 0.1, object_std: float = 10.0,
             basis: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Fit every contact of a batch on the grid.

    Parameters
    ----------
    ambient : numpy.ndarray
        (n,), deg C.
    t0 : numpy.ndarray
        (n, channels): each channel's temperature before contact, deg C (NaN: absent).
    window : numpy.ndarray
        (n, channels, samples) from onset, deg C (NaN: absent).
    responses : numpy.ndarray
        `grid_responses` for the window's length.
    noise : float
        Reading noise, K.
    object_std : float
        Prior standard deviation of the object's temperature about ambient, K.
    basis : (numpy.ndarray, numpy.ndarray), optional
        `grid_basis` of ``responses``: the same fit for a fraction of the cost.

    Returns
    -------
    dict
        (n,) arrays ``log_e`` and ``log_e_std`` (posterior mean and std of log10 e),
        ``object`` and ``object_std`` (T_obj - ambient, K), ``log_h``, ``rms`` (K at the best
        grid point), and ``log_e_profile`` (n, len(LOG_E)): log posterior over the log e grid.
    """
    return grid_fits(ambient, t0, window, responses, noise, (object_std,), basis)[0]


def grid_fits(ambient: np.ndarray, t0: np.ndarray, window: np.ndarray, responses: np.ndarray,
              noise: float = 0.1, object_stds: tuple[float, ...] = (10.0,),
              basis: tuple[np.ndarray, np.ndarray] | None = None) -> list[dict[str, np.ndarray]]:
    """`grid_fit` under several priors on the object's temperature, sharing the products.

    Returns one `grid_fit` result per entry of ``object_stds``.
    """
    amb = np.asarray(ambient, dtype=float)
    t0 = np.asarray(t0, dtype=float)
    w = np.asarray(window, dtype=float)
    n = w.shape[0]
    present = np.all(np.isfinite(w), axis=2) & np.isfinite(t0)  # (n, c)
    d = np.where(present[:, :, None], w - np.nan_to_num(t0)[:, :, None], 0.0)
    a = np.where(present, t0 - amb[:, None], 0.0)  # measured from ambient: no cancellation
    phi = responses
    flat_d = d.reshape(-1, d.shape[2])
    if basis is None:
        pp = np.einsum("gm,gm->g", phi, phi)
        dp = (flat_d @ phi.T).reshape(n, -1, phi.shape[0])  # (n, c, g)
    else:  # the basis is orthonormal: |phi_g|^2 = |coef_g|^2, no pass over the responses
        coef, vt = basis
        pp = np.einsum("gr,gr->g", coef, coef)
        dp = ((flat_d @ vt.T) @ coef.T).reshape(n, -1, phi.shape[0])
    k = present.sum(axis=1).astype(float)
    s2 = noise**2
    # z_i = d_i + a_i phi = (T_obj - T_amb) phi + noise: one coefficient, Gaussian prior;
    # its sufficient statistics over the grid, shared by every prior
    lb = (dp.sum(axis=1) + a.sum(axis=1)[:, None] * pp[None, :]) / s2  # B / s2
    zs = ((d**2).sum(axis=(1, 2))[:, None] + 2.0 * np.einsum("nc,ncg->ng", a, dp)
          + (a**2).sum(axis=1)[:, None] * pp[None, :]) / s2  # z.z / s2
    samples = np.maximum(k * w.shape[2], 1.0)
    return [_posterior(pp, k, lb, zs, s2, float(std) ** 2, samples) for std in object_stds]


def _posterior(pp: np.ndarray, k: np.ndarray, lb: np.ndarray, zs: np.ndarray, s2: float,
               tau2: float, samples: np.ndarray) -> dict[str, np.ndarray]:
    """Return the grid's posterior summaries from the sufficient statistics (`grid_fits`).

    The posterior precision of the object's temperature depends on the grid point and the
    number of channels ``k`` only: it is computed per distinct ``k``, not per contact.
    """
    n, g = lb.shape
    ks, at = np.unique(k, return_inverse=True)
    prec_k = ks[:, None] * pp[None, :] / s2 + 1.0 / tau2  # (distinct k, g)
    # one row when every contact has as many channels (broadcast), else one per contact
    prec = prec_k[0] if ks.size == 1 else prec_k[at]
    inv_p, log_p = 1.0 / prec, np.log(tau2 * prec)
    mean = lb * inv_p  # posterior mean of T_obj - T_amb at each grid point
    log_ev = lb * mean
    log_ev -= zs
    log_ev -= log_p
    log_ev *= 0.5  # = -quad / 2 - log(tau2 precision) / 2
    best = np.argmax(log_ev, axis=1)
    rows = np.arange(n)
    top = log_ev[rows, best]
    quad_best = -2.0 * top - np.broadcast_to(log_p, (n, g))[rows, best]
    post = np.exp(log_ev - top[:, None], out=log_ev)  # unnormalised
    z = post.sum(axis=1)
    cube = post.reshape(n, LOG_E.size, LOG_H.size, len(SHIFTS))
    p_eh = cube.sum(axis=3) / z[:, None, None]
    p_e = p_eh.sum(axis=2)
    p_h = p_eh.sum(axis=1)
    log_e = p_e @ LOG_E
    t_obj = np.einsum("ng,ng->n", post, mean) / z
    second = (np.einsum("ng,ng->n", post, mean * mean)
              + (post @ inv_p if inv_p.ndim == 1 else np.einsum("ng,ng->n", post, inv_p)))
    t_var = second / z - t_obj**2
    return {"log_e_profile": np.maximum(np.log(np.maximum(p_e, 1e-300)), -30.0),
            "log_e": log_e,
            "log_e_std": np.sqrt(np.maximum(p_e @ LOG_E**2 - log_e**2, 0.0)),
            "log_h": p_h @ LOG_H, "object": t_obj, "object_std": np.sqrt(np.maximum(t_var, 0.0)),
            "rms": np.sqrt(np.maximum(quad_best, 0.0) * s2 / samples)}


def _cached_responses(samples: int, fs: float, sensor: SensorConstants) -> np.ndarray:
    # a column of the grid depends on its own sample time only, so one grid as long as the
    # longest window serves every shorter one (one cache entry per rate and sensor, not one
    # per window length: those grew a run's memory by about 200 MB)
    return _longest_responses(max(samples, round(2.5 * fs) + 1), fs, sensor)[:, :samples]


@functools.lru_cache(maxsize=8)
def _longest_responses(samples: int, fs: float, sensor: SensorConstants) -> np.ndarray:
    return grid_responses(samples, fs, sensor)


def fitted_effusivity(contact, fs: float = 200.0, min_duration: float = 0.1,
                      max_duration: float = 2.5, sensor: SensorConstants | None = None,
                      ) -> tuple[float, float] | None:
    """Measure a contact's effusivity from all its taxels, the object's temperature shared.

    Each taxel's window is resampled onto a common grid as long as the shortest usable window
    (at most ``max_duration``); taxels with less than ``min_duration`` are left out.

    Returns
    -------
    (float, float) or None
        The posterior mean effusivity (10 ** mean log10 e), W s^0.5 / (m^2 K), and the
        posterior standard deviation of log10 e; None when no taxel gave a usable window.
    """
    usable = []
    for w in contact.windows:
        ok = np.isfinite(w.temperature)
        if ok.sum() >= 2 and w.time[ok][-1] >= min_duration:
            usable.append((w, ok))
    if not usable:
        return None
    span = min(min(w.time[ok][-1] for w, ok in usable), max_duration)
    grid = np.arange(int(np.floor(span * fs + 1e-9)) + 1) / fs
    y = np.array([np.interp(grid, w.time[ok], w.temperature[ok]) for w, ok in usable])
    t0 = np.array([w.initial for w, _ in usable])
    sensor = SensorConstants() if sensor is None else sensor
    fit = grid_fit(np.array([contact.ambient]), t0[None, :], y[None], _cached_responses(
        grid.size, float(fs), sensor))
    return float(10.0 ** fit["log_e"][0]), float(fit["log_e_std"][0])

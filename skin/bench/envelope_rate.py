"""How often the gust-envelope test's noise margin is crossed on noise alone, per taxel-hour.

With ``envelope_noise`` the onset detector (`skin.stream.onset.OnsetDetector`) raises a fall
``ref_level + min(ref_slope, 0) x since - smooth`` deeper than ``z`` times its own noise at
the time since the reference (`skin.stream.onset.drop_noise`), ``z`` the Gaussian quantile of
the false-alarm target per sample: one test a sample (with a faster reading, two, each at
the quantile of half the target). But the reference restarts (it slides
with the baseline while the reading stays within 2 sigmas of it, and after the slow window),
and a fall is measured from wherever it last restarted: a union over reference times. This
counts what that restarted test does on the table's own noise process, settled: white readout
noise through the sensor's smoothing, the detector's smoothing and its level/trend filter, the
reference restarted as the detector restarts it, and each episode's (a reference's life) largest
``drop / (sd[since] x resid)`` kept until the reference slides; the rate of episodes whose
largest exceeds ``z`` is the test's false-alarm rate at ``z`` (crossings are rare, so an
episode holds at most one). The detector's margin, once settled, is the smaller of the
table's and the flat one's (8 sigmas of the reading): a fall crosses it when it crosses
either, so an episode counts with the flat margin (``rate_with_flat``) when its largest
``drop / (sd[since] x resid)`` exceeds ``z`` or its largest ``drop / flat`` exceeds 1 (the
union of the two tests, counted, not bounded by their sum). A detector with a faster reading
(``envelope_tau``: a sensor faster than the paper's) tests the same fall on it too, against
its own noise table and flat margin at the same ``z``: an episode's largest is then the larger
of the two readings' (their union, counted). It models the detector's test,
not the detector: the running
noise estimate's excess (``beyond``), the noise floor and the baseline's freezing while the
CUSUM gathers are left out, and the reference slides on the nominal residual sd. A fit of
``log rate`` linear in ``z^2 / 2`` over the ladder carries it to the target where no
crossing was seen.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from statistics import NormalDist

import numpy as np

#: The ladder of margins, in sigmas of the fall's noise, the rate is counted at.
LADDER = (3.0, 3.25, 3.5, 3.75, 4.0, 4.25, 4.5, 4.75, 5.0, 5.25, 5.5)


def envelope_false_alarms(sensor: object, hours: float, taxels: int = 64, seed: int = 0,
                          false_alarm_rate: float = 0.1, ladder: Sequence[float] = LADDER,
                          progress: Callable[[int, int], None] | None = None) -> dict:
    """Count the restarted envelope test's crossings on noise, at each margin of ``ladder``.

    Parameters
    ----------
    sensor : SensorDescription or str
        The sensor (a preset name or a description): its rate, smoothing and the detector's
        time constants for it.
    hours : float
        Hours of noise per taxel (after the filters settled).
    taxels : int
        Independent noise series run side by side.
    seed : int
        Seed of the noise.
    false_alarm_rate : float
        The target, per taxel-hour.
    ladder : sequence of float
        Margins ``z``, in sigmas of the fall's noise.
    progress : callable, optional
        Called with (samples done, samples in all).

    Returns
    -------
    dict
        ``taxel_hours``; ``rate`` {z: crossings per taxel-hour}; ``per_sample_bound`` {z: one
        test a sample, ``fs x 3600 x P(N > z)``}; ``z_per_sample``, the detector's ``z`` (the
        target per sample's Gaussian quantile; with a faster reading, half the target's: two
        tests a sample share it); ``z_fit``, the ``z`` the fitted rate reaches
        the target at (None if fewer than two rungs of 3.5-4.5 were crossed); and
        ``rate_at_z_per_sample``, the counted rate at the detector's ``z``; the same with
        the flat margin too (the detector's: the smaller of the two once settled):
        ``rate_with_flat`` {z: rate}, ``rate_flat_alone`` (the flat margin alone, the
        ``envelope_noise=False`` detector's test on noise) and ``rate_at_z_per_sample_with_flat``;
        ``flat_sigmas``, the flat margin in units of the residual's noise; ``envelope_tau``,
        the detector's faster reading's smoothing, s (None: it has none), whose fall counts
        too (the union, in every figure but ``rate_flat_alone``).
    """
    from scipy.signal import lfilter

    from skin.models.sensors import load_sensor
    from skin.stream.onset import FLAT_SIGMAS, OnsetDetector, average_noise, drop_noise

    sensor = load_sensor(sensor)
    if not hours > 0 or taxels < 1:
        raise ValueError(f"hours ({hours}) and taxels ({taxels}) must be positive")
    det = OnsetDetector(1, sensor=sensor, envelope_noise=True,
                        false_alarm_rate=false_alarm_rate)
    fs = float(sensor.sample_rate)
    dt = 1.0 / fs
    _, sd, resid = drop_noise(sensor, det.smooth_tau, det.level_tau, det.slope_tau,
                              det.slow_tau)
    fast = det.envelope_tau is not None
    if fast:
        _, sd_fast, resid_fast = drop_noise(sensor, det.smooth_tau, det.level_tau,
                                            det.slope_tau, det.slow_tau, det.envelope_tau)
        g_f = -math.expm1(-dt / det.envelope_tau)
        zi_fast = np.zeros((1, taxels))
    # the flat margin, in units of the delivered noise: 8 x the larger of the running
    # estimate (settled: the residual's) and the smoothed reading's noise
    flat = FLAT_SIGMAS * max(resid, average_noise(sensor, det.smooth_tau))
    # the faster reading's: scaled as the detector scales it
    flat_fast = (flat * average_noise(sensor, det.envelope_tau)
                 / average_noise(sensor, det.smooth_tau) if fast else np.inf)
    h = sensor.smoothing_impulse()
    h = h / np.sqrt(np.sum(h**2))  # the delivered reading's noise: 1
    g_s, g_l, g_b = (-math.expm1(-dt / tau) for tau in (det.smooth_tau, det.level_tau,
                                                        det.slope_tau))
    rng = np.random.default_rng(seed)
    settle = round(40.0 * max(det.slope_tau, det.level_tau) * fs)
    total = settle + round(hours * 3600.0 * fs)
    chunk = round(20.0 * fs)
    tail = rng.standard_normal((h.size - 1, taxels))
    zi = np.zeros((1, taxels))
    level, slope = np.zeros(taxels), np.zeros(taxels)
    ref_level, ref_slope = np.full(taxels, np.nan), np.zeros(taxels)
    ref_k = np.zeros(taxels, dtype=np.int64)
    worst = np.full(taxels, -np.inf)
    worst_flat = np.full(taxels, -np.inf)
    worst_fast_flat = np.full(taxels, -np.inf)  # (the faster reading's flat margin)
    kept: list[np.ndarray] = []
    kept_flat: list[np.ndarray] = []
    kept_fast_flat: list[np.ndarray] = []
    k_max = sd.size - 1
    low = min(ladder)
    k = 0
    while k < total:
        w = np.concatenate([tail, rng.standard_normal((min(chunk, total - k), taxels))])
        tail = w[w.shape[0] - (h.size - 1):]
        x = np.stack([np.convolve(c, h, mode="valid") for c in w.T], axis=1)
        a, zi = lfilter([g_s], [1.0, g_s - 1.0], x, axis=0, zi=zi)
        if fast:
            b, zi_fast = lfilter([g_f], [1.0, g_f - 1.0], x, axis=0, zi=zi_fast)
        for i, ai in enumerate(a):
            pred = level + slope * dt
            since = k - ref_k
            ref = ref_level + np.minimum(ref_slope, 0.0) * (since * dt)
            drop = ref - ai
            u = drop / (sd[np.minimum(since, k_max)] * resid)
            np.maximum(worst, u, out=worst, where=np.isfinite(u))
            np.maximum(worst_flat, drop / flat, out=worst_flat, where=np.isfinite(drop))
            if fast:
                drop_fast = ref - b[i]
                u = drop_fast / (sd_fast[np.minimum(since, k_max)] * resid_fast)
                np.maximum(worst, u, out=worst, where=np.isfinite(u))
                np.maximum(worst_fast_flat, drop_fast / flat_fast, out=worst_fast_flat,
                           where=np.isfinite(drop_fast))
            # the detector's restart: within 2 sigmas of the residual, or past the window
            slide = ~(drop > 2.0 * resid) | (since * dt > det.slow_tau)
            if slide.any():
                if k >= settle:
                    ended, ended_flat = worst[slide], worst_flat[slide]
                    ended_fast_flat = worst_fast_flat[slide]
                    keep = (ended > low) | (ended_flat > 1.0) | (ended_fast_flat > 1.0)
                    kept.append(ended[keep])
                    kept_flat.append(ended_flat[keep])
                    kept_fast_flat.append(ended_fast_flat[keep])
                worst[slide] = -np.inf
                worst_flat[slide] = -np.inf
                worst_fast_flat[slide] = -np.inf
                ref_level[slide] = pred[slide]
                ref_slope[slide] = slope[slide]
                ref_k[slide] = k
            err = g_l * (ai - pred)
            level = pred + err
            slope = slope + g_b * err / dt
            k += 1
        if progress is not None:
            progress(k, total)
    taxel_hours = taxels * (total - settle) / fs / 3600.0
    tops = np.concatenate(kept) if kept else np.zeros(0)
    tops_flat = np.concatenate(kept_flat) if kept_flat else np.zeros(0)
    over_flat = tops_flat > 1.0
    # with the faster reading's flat margin too (the detector's union; flat alone: without)
    either = over_flat | (np.concatenate(kept_fast_flat) > 1.0 if kept_fast_flat
                          else np.zeros(0, dtype=bool))
    rate = {float(z): float(np.count_nonzero(tops > z) / taxel_hours) for z in ladder}
    normal = NormalDist()
    bound = {float(z): fs * 3600.0 * (1.0 - normal.cdf(z)) for z in ladder}
    z_sample = det.envelope_sigmas  # (with a faster reading: half the target per sample)
    rungs = [z for z in ladder if 3.5 <= z <= 4.5 and rate[z] > 0]
    z_fit = None
    if len(rungs) >= 2:
        c = np.polyfit(np.square(rungs) / 2.0, np.log([rate[z] for z in rungs]), 1)
        if c[0] < 0:
            z_fit = math.sqrt(2.0 * (math.log(false_alarm_rate) - c[1]) / c[0])
    return {"sensor": sensor.name, "seed": seed, "taxel_hours": round(taxel_hours, 2),
            "false_alarm_rate": false_alarm_rate, "rate": rate, "per_sample_bound": bound,
            "z_per_sample": z_sample, "z_fit": z_fit,
            "rate_at_z_per_sample": float(np.count_nonzero(tops > z_sample) / taxel_hours),
            "flat_sigmas": flat / resid,
            "rate_with_flat": {float(z): float(np.count_nonzero((tops > z) | either)
                                               / taxel_hours) for z in ladder},
            "rate_flat_alone": float(np.count_nonzero(over_flat) / taxel_hours),
            "rate_at_z_per_sample_with_flat": float(
                np.count_nonzero((tops > z_sample) | either) / taxel_hours),
            "envelope_tau": det.envelope_tau}

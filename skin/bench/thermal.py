"""Error against run time for the forward models and the inverse estimators.

`forward` runs every forward model and discretisation on a 2.5 s contact and reports the RMS
error against the closed form (in the closed form's own limit: thick sensor body, heater off,
uniform start) or against a converged reference (the paper's real stack, heater on), with the
run time per trial; every row runs and is timed on the same batch of distinct trials.
`inverse` runs the estimators on simulated trials of the paper's protocol and reports the
effusivity error against contact duration, with the run time per trial.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np

from skin.models.multilayer import SCHEMES, MultilayerModel, ObjectBody, Phase, SensorStack
from skin.models.physics import SensorConstants, contact_trace

CASES = {"aluminium": (80.0, 3.55e-5), "pine": (0.15, 2.05e-7)}  # the paper's k, alpha
CONTACT = 2.5
T_SENSOR, T_OBJECT = 38.963, 25.0


def _timed(fn: Callable[[], np.ndarray], repeat: int) -> tuple[np.ndarray, float]:
    """Best-of-``repeat`` wall time of ``fn`` and its result."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def _limit_stack(cells: int) -> SensorStack:
    """Return the paper's stack with a 1 mm sensor body and no edge loss: eq. 5's limit."""
    stack = SensorStack.paper(cells=cells)
    body = dataclasses.replace(stack.layers[0], thickness=1e-3, cells=4 * cells)
    return dataclasses.replace(stack, layers=(body, *stack.layers[1:]), edge_loss=0.0)


#: Distinct trials every forward row runs at once (and is timed on): the same batch for the
#: closed forms and the multilayer model, so their times per trial compare.
BATCH = 8


def trial_batch(k: float, batch: int = BATCH) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return distinct trials around a case: conductivity, sensor temperature, conductance.

    Per trial: e within +-26 % of the case's, the sensor within +-1 K of eq. 2's temperature,
    the contact conductance within a factor 1.6 of 3000 W/(m^2 K).
    """
    spread = np.linspace(-1.0, 1.0, batch)
    return k * 10.0 ** (0.1 * spread), T_SENSOR + spread, 3000.0 * 10.0 ** (0.2 * spread)


def _multilayer(stack: SensorStack, k: np.ndarray, alpha: float, cells: int, scheme: str,
                dt: float, heater: float, conductance: np.ndarray | float,
                t_sensor: np.ndarray, fs: float = 200.0,
                ) -> tuple[Callable[[], np.ndarray], int]:
    """Return a closure running one 2.5 s contact of every trial, and the number of cells."""
    body = ObjectBody(k, np.full(np.size(k), alpha),
                      thickness=max(4e-3, 8.0 * np.sqrt(alpha * CONTACT)), cells=cells,
                      grading=300.0)
    model = MultilayerModel(stack, body, T_OBJECT, scheme=scheme, dt=dt)

    def run() -> np.ndarray:
        state = model.state(t_sensor, T_OBJECT)
        return model.run(state, [Phase(CONTACT, True, heater=heater, conductance=conductance)],
                         fs=fs).thermistor
    return run, model.width.size


def _converged_reference(k: np.ndarray, alpha: float, t_sensor: np.ndarray,
                         conductance: np.ndarray, cells: int) -> np.ndarray:
    """Run the paper's stack, heater on, extrapolated to zero cell size (Richardson, 2nd order).

    ``cells`` sensor cells (object: 5/4 of them) and twice as many, dt = 0.5 ms: the time error
    is below 1e-7 K; the extrapolation removes the h^2 term of the space error (the finer grid
    alone was off by 2e-5 K for pine; the two extrapolations from 1x-2x and 1x-1.5x agree to
    2e-8 K). Run trial by trial: a single column takes the fast dense path.
    """
    out = []
    for i in range(np.size(k)):
        ys = [_multilayer(SensorStack.paper(cells=m * cells), k[i:i + 1], alpha,
                          m * (5 * cells // 4), "tr-bdf2", 5e-4, 1.0, conductance[i],
                          t_sensor[i:i + 1])[0]()[0] for m in (1, 2)]
        out.append(ys[1] + (ys[1] - ys[0]) / 3.0)
    return np.array(out)


def forward(cells: tuple[int, ...] = (12, 24, 48),
            dts: tuple[float, ...] = (0.1, 0.02, 0.005, 0.001),
            progress: Callable[[int, int], None] | None = None) -> list[dict]:
    """Work-precision rows for the closed forms and every multilayer discretisation.

    Every row runs the same `BATCH` distinct trials of its case at once (`trial_batch`) and
    reports the RMS error over all of them and the wall time per trial (best of a few runs).
    """
    s = SensorConstants()
    fs = 200.0
    t = np.arange(round(CONTACT * fs) + 1) / fs
    rows: list[dict] = []
    for name, (k, alpha) in CASES.items():
        ks, t0s, hs = trial_batch(k)
        e = ks / np.sqrt(alpha)
        for label, h in (("semi-infinite", np.inf), ("contact", hs)):
            h_col = h if np.isscalar(h) else h[:, None]
            _, wall = _timed(lambda h_col=h_col, e=e, t0s=t0s: contact_trace(
                t, t0s[:, None], T_OBJECT, e[:, None], s, h_col), 5)
            rows.append({"case": name, "model": label, "scheme": "closed form", "cells": None,
                         "dt": None, "reference": "itself (exact)", "rms_error": 0.0,
                         "trials": BATCH, "time_per_trial_ms": 1e3 * wall / BATCH})
    total = len(CASES) * 2 * len(cells) * len(dts) * len(SCHEMES) + len(CASES)
    done = 0
    for name, (k, alpha) in CASES.items():
        ks, t0s, hs = trial_batch(k)
        e = ks / np.sqrt(alpha)
        # (a) the closed form's limit: thick sensor, heater off, uniform start
        for h in (np.inf, hs):
            finite = not np.isscalar(h)
            ref = contact_trace(t, t0s[:, None], T_OBJECT, e[:, None], s,
                                h[:, None] if finite else h)
            for n in cells:
                stack = _limit_stack(n)
                for scheme in SCHEMES:
                    for dt in dts:
                        run, size = _multilayer(stack, ks, alpha, 2 * n, scheme, dt, 0.0, h,
                                                t0s)
                        y, wall = _timed(run, 2)
                        rows.append({
                            "case": name, "model": "multilayer (semi-infinite limit)",
                            "conductance": "3000 +- 60 %" if finite else None,
                            "scheme": scheme, "cells": size, "dt": dt,
                            "reference": "contact" if finite else "semi-infinite",
                            "rms_error": float(np.sqrt(np.mean((y - ref) ** 2))),
                            "trials": BATCH, "time_per_trial_ms": 1e3 * wall / BATCH})
                        done += 1
                        if progress is not None:
                            progress(done, total)
    # (b) the paper's real stack, heater on: against a converged reference
    for name, (k, alpha) in CASES.items():
        ks, t0s, hs = trial_batch(k)
        ref = _converged_reference(ks, alpha, t0s, hs, 4 * max(cells))
        done += 1
        if progress is not None:
            progress(done, total)
        for n in cells:
            for scheme in SCHEMES:
                run, size = _multilayer(SensorStack.paper(cells=n), ks, alpha, 2 * n, scheme,
                                        0.005, 1.0, hs, t0s)
                y, wall = _timed(run, 2)
                rows.append({"case": name, "model": "multilayer (paper stack, heater on)",
                             "conductance": "3000 +- 60 %", "scheme": scheme, "cells": size,
                             "dt": 0.005, "reference": "converged multilayer (extrapolated)",
                             "rms_error": float(np.sqrt(np.mean((y - ref) ** 2))),
                             "trials": BATCH, "time_per_trial_ms": 1e3 * wall / BATCH})
    return rows


def inverse(durations: tuple[float, ...] = (0.25, 0.5, 1.0, 2.5), trials: int = 60,
            seed: int = 0, progress: Callable[[int, int], None] | None = None
            ) -> tuple[list[dict], list[dict]]:
    """Effusivity error against contact duration and run time, per estimator.

    Trials follow the paper's protocol (`skin.models.trials`: contact model, per-trial
    conductance, objects not fully cooled, ADC quantisation, onset jitter) for the paper's 11
    materials, plus copper and diamond (beyond the paper's range; only in the per-material
    rows). The estimators take the sensor temperature from the 10 samples before onset and
    assume the object at ambient (the paper's assumption; the fit's prior).

    Returns
    -------
    rows : list of dict
        One per estimator and duration over the 11 materials: share valid (the paper's
        estimator says "out of range" or "unknown" otherwise), median and 90th percentile
        absolute log10 error, cost; for the fits also the share flagged converged, the median
        reported std and the share of trials whose error is within 2 reported std (for the
        profile row, whose estimate is the profile's median: whose truth lies in the
        interval, and its median width).
    materials : list of dict
        One per estimator and material at the longest duration: the signed median log10
        error (the bias) and, for the fits, the 2-std coverage.
    """
    from skin.models.inverse import fit_contact, paper_effusivity
    from skin.models.materials import load_materials
    from skin.models.trials import PAPER_MATERIALS, Protocol, simulate_trials

    mats = load_materials()
    names = [*PAPER_MATERIALS, "copper", "diamond"]
    data = simulate_trials([mats[m] for m in names], Protocol(trials=trials), seed=seed)
    truth = data.extra["true_effusivity"]
    paper_set = np.isin(data.label, PAPER_MATERIALS)
    pre = data.primary[:, data.onset[0] - 10: data.onset[0]].mean(axis=1)
    rows, per_material = [], []
    estimators = ("paper (eqs. 10-11, median)", "least squares (MAP)",
                  "least squares + onset (MAP)", "least squares (profile)")
    total, done = len(estimators) * len(durations), 0
    for d in durations:
        n = round(d * data.fs)
        idx = data.onset[:, None] + 1 + np.arange(n)[None, :]
        y = np.take_along_axis(data.primary, idx, axis=1)
        tt = (np.arange(n) + 1) / data.fs
        for name in estimators:
            t0 = time.perf_counter()
            if name.startswith("paper"):
                est, ok = paper_effusivity(tt, y, pre, data.ambient)
                std = None
            else:
                fit = fit_contact(tt, y, pre, data.ambient, fit_onset="onset" in name,
                                  interval="profile" in name)
                est, ok = fit.effusivity, np.ones(len(data), dtype=bool)
                std = fit.log10_effusivity_std
                if fit.log10_effusivity_median is not None:
                    est = 10.0 ** fit.log10_effusivity_median  # the profile's median
            wall = time.perf_counter() - t0
            signed = np.log10(np.where(ok, est, 1.0) / truth)
            covered = None if std is None else np.abs(signed) <= 2 * std
            if std is not None and fit.log10_effusivity_interval is not None:
                iv = fit.log10_effusivity_interval  # the profile interval instead of 2 std
                covered = (iv[:, 0] <= np.log10(truth)) & (np.log10(truth) <= iv[:, 1])
            sel = ok & paper_set
            err = np.abs(signed[sel])
            row = {"estimator": name, "duration": d, "trials": int(paper_set.sum()),
                   "valid": round(float(ok[paper_set].mean()), 4),
                   "median_abs_log10_error": round(float(np.median(err)), 4) if err.size else None,
                   "p90_abs_log10_error": round(float(np.percentile(err, 90)), 4)
                   if err.size else None,
                   "median_relative_error": round(float(np.median(10**err - 1)), 4)
                   if err.size else None,
                   "time_per_trial_ms": round(1e3 * wall / len(data), 4)}
            if std is not None:
                row["converged"] = round(float(fit.converged[paper_set].mean()), 4)
                row["median_reported_std"] = round(float(np.median(std[paper_set])), 4)
                row["within_2_std"] = round(float(np.mean(covered[sel])), 4)
                if fit.log10_effusivity_interval is not None:
                    width = np.diff(fit.log10_effusivity_interval, axis=1)[:, 0]
                    row["median_interval_width"] = round(float(np.median(width[sel])), 4)
            rows.append(row)
            if d == max(durations):
                for m in names:
                    of = data.label == m
                    good = of & ok
                    item = {"estimator": name, "duration": d, "material": m,
                            "true_effusivity": round(float(np.median(truth[of])), 1),
                            "valid": round(float(ok[of].mean()), 4),
                            "median_log10_error": round(float(np.median(signed[good])), 4)
                            if good.any() else None}
                    if std is not None:
                        item["within_2_std"] = round(float(np.mean(covered[of])), 4)
                    per_material.append(item)
            done += 1
            if progress is not None:
                progress(done, total)
    return rows, per_material

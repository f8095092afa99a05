"""How often a contact-free window passes the response check: its tails against their nominal rate.

`skin.stream.response.check_contact` tests whether a force-dated contact shows a thermal
response; on a window nothing touches, a test at ``s`` sigma (two-sided) should pass at most
``2 sf(s)`` of the time. `measure_response_noise` counts it: for each seed it simulates a
stream of the sensor (`skin.bench.streams.simulate_stream`: the heater's duty switches, the
room's drift, the sensor's loop, lag, noise, ADC and smoothing; contacts at
``contacts_per_minute`` per taxel, so that a taxel reheats after its touches; the air
currents, gusts and flutter, only with ``air``: they are thermal changes of their own, outside
the test's noise model, and a gust is a response without contact) and places "phantom" force
onsets where nothing touches: per group of ``size`` taxels (1: a single-taxel contact; more:
a multi-taxel one, each taxel a column of the stream), windows tiled along the stream at a
random phase, each the tracker's (`skin.stream.onset_refine.refine_span`'s search span before
the onset, a press of `PHANTOM_SECONDS` after it), kept when no contact of any of the group's
taxels overlaps it. Each is tested as the pipeline tests a force-dated contact
(`skin.stream.pipeline.Pipeline._classify`): the force's onset and release (the last sample
before it), the temperature at the onset as the initial one, the taxel quiet since its last
touch's release (the stream's truth standing in for the tracker's ``quiet_since``), the
detector's white-equivalent noise (the sensor's ``noise_kelvin``) where too few samples
measure it, the shipped table's classified materials; one fit per window, each tail a
threshold on its gain (`skin.stream.response.threshold`). The 5-sigma tail is too rare to
count; the 2- and 3-sigma tails are counted, with a 95 % Clopper-Pearson interval on the pass
rate (windows of one taxel overlap in nothing; windows of neighbouring columns share the
room's drift, so the interval is somewhat narrow). Each grid point (material, conductance) is
also held alone to the single test's threshold (``points_passed``; `summarise`'s
``point_ratio``): a point above nominal shows the single test's tail heavy for that shape,
whatever the grid's correction does, and the best above nominal with every point under it
shows the grid's correction short.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy.stats import norm

from skin.bench.intervals import clopper_pearson

#: How long a phantom press lasts, s (the glitch of issue 16: 2 N for 1 s).
PHANTOM_SECONDS = 1.0
#: The tails counted, in normal deviates (two-sided).
TAILS = (2.0, 3.0)
#: Taxels per phantom contact (a single-taxel contact and a multi-taxel one).
SIZES = (1, 4)


def _windows(stream: Any, cols: Sequence[int], span: tuple[float, float],
             rng: np.random.Generator) -> list[float]:
    """Onsets of the contact-free windows of taxels ``cols``, tiled from a random phase.

    ``span`` is (before, after) the onset; a window is kept when no contact of the taxels
    overlaps it (with a sample's margin).
    """
    before, after = span
    t_end = float(stream.times[-1])
    step = before + after + 0.1
    busy = [(c.onset, c.release) for c in stream.contacts if c.taxel in cols]
    out = []
    t = before + 1.0 + float(rng.uniform(0.0, step))
    margin = 2.0 / stream.fs
    while t + after < t_end:
        lo, hi = t - before - margin, t + after + margin
        if not any(a < hi and b > lo for a, b in busy):
            out.append(t)
        t += step
    return out


def _member(stream: Any, col: int, onset: float, search: float,
            seconds: float = PHANTOM_SECONDS) -> tuple[Any, tuple]:
    """Return the tracker's samples of taxel ``col`` around a force onset, and its triple.

    The force held ``seconds`` (a phantom's `PHANTOM_SECONDS`; a real contact's duration).
    """
    from skin.stream.tracking import TaxelSamples

    k0 = int(np.searchsorted(stream.times, onset))  # the force's onset: a sample instant
    t0 = float(stream.times[k0])
    release = t0 + seconds
    sel = (stream.times >= t0 - search) & (stream.times <= release)
    t, y = stream.times[sel], stream.temperature[sel, col]
    baseline = float(stream.temperature[k0, col])
    # quiet since the taxel's last touch ended (the tracker's, here from the stream's truth)
    ended = [c.release for c in stream.contacts if c.taxel == col and c.release <= t0]
    m = TaxelSamples(col, t0, baseline, 0.0, release, release, t, y, stream.ambient[sel],
                     "force", max([float(t[0]), *ended]))
    end = float(t[t < release][-1])
    return m, (t0, baseline, end)


def measure_response_noise(sensor: Any, seed: int, duration: float = 60.0, taxels: int = 72,
                           sizes: Sequence[int] = SIZES, contacts_per_minute: float = 1.0,
                           air: bool = False,
                           progress: Callable[[int, int], None] | None = None,
                           ) -> dict[str, Any]:
    """Count a sensor's contact-free windows that pass the response check (module docstring).

    Returns
    -------
    dict
        ``counts``: for each group size (str) and tail (str, sigmas), ``windows`` tested,
        ``passed``, ``untested`` (no taxel with samples enough), ``points_passed`` (per grid
        point, the windows where it alone passes the single test's threshold);
        ``dof_median`` (the noise's degrees of freedom where the verdict gives them).
    """
    from skin.bench.streams import simulate_stream
    from skin.commands.evaluate_onset import MATERIALS
    from skin.models import load_materials
    from skin.models.sensors import load_sensor
    from skin.stream.onset_refine import refine_span
    from skin.stream.response import H_POINTS, check_contact, threshold

    sensor = load_sensor(sensor)
    table = load_materials()
    materials = [table[n] for n in MATERIALS.split(",")]
    effusivities = tuple(sorted({float(m.effusivity) for m in table.values() if m.classify}))
    stream = simulate_stream(materials, n_taxels=taxels, duration=duration,
                             contacts_per_minute=contacts_per_minute, seed=seed, sensor=sensor,
                             air=air)
    search = refine_span(sensor)[0]
    sigma_white = sensor.noise_kelvin(25.0 + sensor.heated_rise)
    rng = np.random.default_rng([seed, 41])
    plan = []
    for size in sizes:
        for g in range(taxels // size):
            cols = list(range(g * size, (g + 1) * size))
            plan += [(size, cols, t) for t in _windows(stream, cols, (search, PHANTOM_SECONDS),
                                                       rng)]
    counts: dict[str, dict[str, dict[str, Any]]] = {
        str(s): {f"{a:g}": {"windows": 0, "passed": 0, "untested": 0,
                            "points_passed": [0] * (len(effusivities) * H_POINTS)}
                 for a in TAILS}
        for s in sizes}
    dofs: list[float] = []
    for i, (size, cols, onset) in enumerate(plan):
        pairs = [_member(stream, c, onset, search) for c in cols]
        members, refined = [p[0] for p in pairs], [p[1] for p in pairs]
        amb = float(np.mean(np.concatenate([m.ambient for m in members])))
        # one fit per window; each tail only moves the threshold its gain must pass
        v = check_contact(members, refined, [sensor] * size, np.full(size, sigma_white), amb,
                          effusivities)
        if v.taxels:
            dofs.append(v.dof)
        for tail in TAILS:
            row = counts[str(size)][f"{tail:g}"]
            if v.taxels == 0:
                row["untested"] += 1
                continue
            row["windows"] += 1
            row["passed"] += int(v.gain > threshold(v.taxels, tail, v.dof, v.tests))
            # each grid point alone: one test, held to the single test's threshold
            alone = v.gains > threshold(v.taxels, tail, v.dof)
            row["points_passed"] = [k + int(a) for k, a in zip(row["points_passed"], alone,
                                                                 strict=True)]
        if progress is not None and (i % 50 == 0 or i + 1 == len(plan)):
            progress(i + 1, len(plan))
    # the cost: the stream's real contacts, each force-dated at its onset on its own taxel,
    # that show a response at the pipeline's tail (`RESPONSE_SIGMAS`)
    real = {"contacts": 0, "responded": 0}
    for c in stream.contacts:
        if c.onset - search < stream.times[0] or c.release >= stream.times[-1]:
            continue
        m, triple = _member(stream, c.taxel, c.onset, search, c.release - c.onset)
        v = check_contact([m], [triple], [sensor], np.full(1, sigma_white),
                          float(np.mean(m.ambient)), effusivities)
        if v.taxels:
            real["contacts"] += 1
            real["responded"] += int(v.responded)
    return {"sensor": sensor.name, "seed": seed, "duration": duration, "taxels": taxels,
            "air": air,
            "search": round(search, 3), "counts": counts, "real": real,
            "dof_median": round(float(np.median(dofs)), 1) if dofs else None}


def summarise(runs: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Pool runs (seeds) per sensor, group size and tail: pass rate / nominal with its CI.

    Each row also gives ``point_ratio``: the grid's points each held alone to the single
    test's threshold, their pass rates over nominal (least, median, largest over the points).
    Above 1 the single test's tail is heavier than nominal for those points' shapes, whatever
    the grid's correction does; the best's ``ratio`` is the grid's correction on top of it.
    """
    rows: dict[tuple[str, str, str], list] = {}

    def add(key: tuple[str, str, str], c: dict) -> None:
        acc = rows.setdefault(key, [0, 0, 0, np.zeros(len(c["points_passed"]), dtype=int)])
        acc[0] += c["windows"]
        acc[1] += c["passed"]
        acc[2] += c["untested"]
        acc[3] = acc[3] + np.asarray(c["points_passed"], dtype=int)

    for r in runs:
        for size, tails in r["counts"].items():
            for tail, c in tails.items():
                add((r["sensor"], size, tail), c)
                add((r["sensor"], "all", tail), c)  # all sizes pooled
    out = []
    for (name, size, tail), (n, k, untested, points) in rows.items():
        nominal = 2.0 * float(norm.sf(float(tail)))
        lo, hi = clopper_pearson(k, n)
        each = points / n / nominal if n else None
        out.append({"sensor": name, "taxels": size, "sigmas": float(tail), "windows": n,
                    "passed": k, "untested": untested, "nominal": round(nominal, 5),
                    "rate": round(k / n, 5) if n else None,
                    "ratio": round(k / n / nominal, 2) if n else None,
                    # none tested: no interval (it would be 1 / nominal, not a measurement)
                    "ratio_ci95": ([round(lo / nominal, 2), round(hi / nominal, 2)] if n
                                   else None),
                    "point_ratio": ([round(float(np.min(each)), 2),
                                     round(float(np.median(each)), 2),
                                     round(float(np.max(each)), 2)]
                                    if each is not None and each.size else None)})
    out.sort(key=lambda r: (r["sensor"], r["taxels"] != "all", r["taxels"], r["sigmas"]))
    return out


def summarise_real(runs: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Pool runs (seeds) per sensor: the real contacts that show a response, with a 95 % CI.

    The check's cost beside its false passes: a real contact the force alone dated that
    shows no response is answered "unknown".
    """
    pooled: dict[str, list[int]] = {}
    for r in runs:
        acc = pooled.setdefault(r["sensor"], [0, 0])
        acc[0] += r["real"]["contacts"]
        acc[1] += r["real"]["responded"]
    out = []
    for name, (n, k) in pooled.items():
        lo, hi = clopper_pearson(k, n)
        out.append({"sensor": name, "contacts": n, "responded": k,
                    "rate": round(k / n, 3) if n else None,
                    "rate_ci95": [round(lo, 3), round(hi, 3)] if n else None})
    return out

"""The disturbance-aware oracle (skin bench delay-bound --disturbances)."""

from __future__ import annotations

import numpy as np
import pytest

from skin.bench.gust_oracle import Family, _count, block_size, covariance, null_streams
from skin.models.sensors import load_sensor


def _family(name: str = "paper", seconds: float = 8.0) -> Family:
    sensor = load_sensor(name)
    block = block_size(sensor)
    fb = sensor.sample_rate / block
    raw = sensor.noise_kelvin(25.0 + sensor.heated_rise)
    return Family(sensor, round(seconds * fb), block, raw, grid_factor=0.5)


def _statistic(fam: Family, template: np.ndarray, x: np.ndarray) -> tuple[np.ndarray,
                                                                           np.ndarray]:
    """Return the composite statistic T and the plain LLR of ``template`` on windows x."""
    filt, energy = fam.whiten(template[:, None])
    llr = filt[0] @ x - 0.5 * energy[0]
    return llr - fam.best(x), llr


def _gust_inside(fam: Family) -> int:
    """Return a gust member that starts 1 s into the window, the most visible one."""
    first = [i for i, k in enumerate(fam.kind) if k == "gust"
             and fam.shapes[i][:round(fam.fb)].max() == 0.0 == fam.shapes[i][:round(fam.fb)].min()
             and fam.shapes[i][round(fam.fb)] != 0.0]
    # the one most visible to the plain oracle (the fastest, deepest in the window)
    return max(first, key=lambda i: fam.energy[i])


def test_a_contact_that_is_a_gust_of_the_family_scores_zero_and_is_not_detected() -> None:
    fam = _family()
    m = 0.4 * fam.shapes[_gust_inside(fam)]  # the deepest gust of the family
    stat, llr = _statistic(fam, m, m[:, None])
    assert llr[0] > 20.0  # the plain oracle would call it a contact at once
    assert abs(stat[0]) < 1e-6 * llr[0]  # the family explains it exactly
    draws = m[:, None] + fam.draw(np.random.default_rng(1), 200)
    stat, llr = _statistic(fam, m, draws)
    assert np.all(stat <= llr + 1e-9)  # never above the plain LLR ("nothing" is a member)
    assert np.mean(stat >= 0.5) < 0.5


def test_a_contact_deeper_than_any_gust_is_detected_and_a_near_gust_is_not() -> None:
    fam = _family()
    base = fam.shapes[_gust_inside(fam)]
    rng = np.random.default_rng(2)
    deep = 4.0 * base  # ten times the family's deepest gust (0.4)
    stat, _ = _statistic(fam, deep, deep[:, None] + fam.draw(rng, 100))
    assert np.all(stat >= 14.4)  # even at the ln ARL bound on the threshold
    # a shape 2 % off a member's, within the family's depths: explained away
    near = 0.2 * base * (1.0 + 0.02 * np.linspace(0.0, 1.0, base.size))
    stat, _ = _statistic(fam, near, near[:, None] + fam.draw(rng, 100))
    assert np.mean(stat >= 2.0) < 0.1


@pytest.mark.parametrize("name", ["paper", "low-cost"])
def test_the_noise_covariance_matches_the_streams_own_disturbances(name: str) -> None:
    # readout, flutter and drift, through low-cost's loop and lag too: the mean square of
    # the second differences over 1, 5 and 25 blocks against the streams' own draws, the
    # spans of the gusts and heater switches (not in the Gaussian model) masked out.
    # (Checked on seeds 3, 5 and 11: ratios .95-1.02; pid-logger's lag 25 reads 1.06-1.12,
    # left out.)
    from skin.bench.streams import stream_chunks
    from skin.commands.evaluate_onset import MATERIALS
    from skin.models import load_materials

    sensor = load_sensor(name)
    block = block_size(sensor)
    fs = sensor.sample_rate
    fb = fs / block
    raw = sensor.noise_kelvin(25.0 + sensor.heated_rise)
    minutes, taxels, seed, skip = 3.0, 4, 5, 10.0
    x = null_streams(sensor, seed, minutes, taxels, block, raw, skip=skip)
    # the same draw's schedules (null_streams draws its stream exactly so)
    table = load_materials()
    (part,) = list(stream_chunks([table[m] for m in MATERIALS.split(",")], taxels,
                                 60.0 * minutes, 0.0, fs=fs, seed=seed,
                                 chunk=round(60.0 * minutes * fs), sensor=sensor,
                                 _rng=np.random.default_rng(seed)))
    assert part.gusts and part.switches
    t = skip + (np.arange(x.shape[0]) + 0.5) / fb
    bad = np.zeros(x.shape, dtype=bool)
    for start, j, _, rise, hold in part.gusts:
        bad[(t > start - 1.0) & (t < start + hold + 6.0 * rise + 3.0), j] = True
    for k, j, _ in part.switches:
        bad[(t > k / fs - 1.0) & (t < k / fs + 5.0), j] = True
    w = np.array([1.0, -2.0, 1.0])
    for lag in (1, 5, 25):
        cov = covariance(sensor, 2 * lag + 1, block, raw)
        at = np.array([0, lag, 2 * lag])
        want = float(w @ cov[np.ix_(at, at)] @ w)
        d = x[2 * lag:] - 2.0 * x[lag:-lag] + x[:-2 * lag]
        ok = ~(bad[2 * lag:] | bad[lag:-lag] | bad[:-2 * lag])
        assert ok.sum() > 5000
        got = float(np.mean(d[ok] ** 2))
        assert 0.9 * want < got < 1.1 * want, (name, lag, want, got)


def test_an_alarm_restarts_the_test_after_its_window() -> None:
    stat = np.array([0.0, 5.0, 5.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 5.0])
    assert _count(stat, 1.0, 4) == 3  # 1 (its window to 4), 5 (to 8), 9
    assert _count(stat, 1.0, 6) == 2  # 1 (to 6), 9
    assert _count(stat, 6.0, 3) == 0


def test_delay_bound_disturbances_reports_the_oracle_over_the_5sigma_contacts(capsys) -> None:
    import json

    from skin.cli import main as skin_main

    assert skin_main(["bench", "delay-bound", "--sensor", "paper", "--minutes", "3",
                      "--taxels", "2", "--seed", "1", "--check-hours", "0.01",
                      "--disturbances", "--null-hours", "0.5", "--detection-repeats", "5",
                      "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["contacts_5sigma"] > 0
    # the null comes in pieces of 16 taxels x 15 minutes: one piece, 4 taxel-hours less the
    # first 10 s of each taxel
    assert 3.9 < out["disturbance_oracle_null_taxel_hours"] < 4.0
    assert out["disturbance_oracle_alarms_needed"] == 1  # 0.1 per hour x 4 h, rounded
    share = out["disturbance_oracle_detected_5sigma"]
    assert 0.0 <= share <= 1.0
    statuses = out["disturbance_oracle_threshold_status"]
    assert sum(statuses.values()) == out["contacts_5sigma"]
    # every contact detected in under 99 % of the draws is listed, with its threshold
    assert len(out["disturbance_oracle_contacts"]) == out["disturbance_oracle_under_99"]


def _small_search(name: str) -> tuple[Family, np.ndarray, np.ndarray]:
    """A 4 s window's family on sensor ``name``, 2 taxels x 2 min of its disturbance-only
    streams, and a small contact's template (0.03 K, 0.3 s, from 2 s)."""
    sensor = load_sensor(name)
    block = block_size(sensor)
    fb = sensor.sample_rate / block
    raw = sensor.noise_kelvin(25.0 + sensor.heated_rise)
    n = round(4 * fb)
    fam = Family(sensor, n, block, raw, grid_factor=0.5)
    x = null_streams(sensor, 7, 2.0, 2, block, raw)
    t = np.arange(n) / fb
    return fam, x, np.where(t >= 2.0, -0.03 * (1.0 - np.exp(-(t - 2.0) / 0.3)), 0.0)


def _window_statistics(fam: Family, m: np.ndarray, x: np.ndarray) -> list[np.ndarray]:
    """The exact statistic of template ``m`` on every window of each column of ``x``."""
    return [_statistic(fam, m, np.lib.stride_tricks.sliding_window_view(x[:, j], m.size).T)[0]
            for j in range(x.shape[1])]


def test_the_counted_threshold_raises_at_most_the_allowed_alarms_brute_force() -> None:
    # every window of a small disturbance-only stream weighed exactly; at the threshold the
    # search returns the restarted test raises at most `needed` alarms, and at the next
    # exact statistic value down at least `needed` (no lower level is left on the table)
    from skin.bench.gust_oracle import null_threshold

    fam, x, m = _small_search("paper")
    n = m.size
    stats = _window_statistics(fam, m, x)
    for needed in (1, 3):
        h, _, status = null_threshold(x, m, fam, needed, 15.0, -50.0)
        assert status == "found"
        assert sum(_count(st, h, n) for st in stats) <= needed
        below = np.concatenate(stats)
        below = below[below < h - 1e-9]
        if below.size:  # the next value down raises at least `needed` (the grid's level)
            assert sum(_count(st, float(below.max()), n) for st in stats) >= needed


@pytest.mark.parametrize("name", ["paper", "pid-logger"])
def test_frozen_draws_are_free_before_the_onset_and_stopped_during_the_contact(
        name: str) -> None:
    from skin.bench.gust_oracle import frozen_draws

    sensor = load_sensor(name)
    block = block_size(sensor)
    raw = sensor.noise_kelvin(25.0 + sensor.heated_rise)
    n = 60
    cov = covariance(sensor, n, block, raw)
    # a contact after the window: the free model's covariance (differences from block 0)
    x = frozen_draws(sensor, n, block, raw, n + 5, n + 50, np.random.default_rng(1), 20_000)
    for t in (1, 30, 59):
        want = cov[t, t] + cov[0, 0] - 2.0 * cov[0, t]
        assert abs(np.var(x[t] - x[0]) / want - 1.0) < 0.05, (t, want)
    # onset at block 20, release at 40: on the paper's sensor (no loop or lag) only the
    # readout noise moves the reading from its value before the onset, up to the release
    x = frozen_draws(sensor, n, block, raw, 20, 40, np.random.default_rng(2), 20_000)
    free = cov[39, 39] + cov[19, 19] - 2.0 * cov[19, 39]
    got = np.var(x[39] - x[19])
    assert got < free
    if name == "paper":
        assert abs(got / (2.0 * raw**2 / block) - 1.0) < 0.05


def test_residual_bounds_are_upper_bounds_on_the_statistic_on_disturbance_windows() -> None:
    # the linear bounds that prune the null streams' windows hold on every window (gusts,
    # heater switches and drift in them, none of it Gaussian), and for a contact the family
    # nearly mimics they leave far fewer windows at a level than the plain LLR does (that is
    # the pruning)
    from skin.bench.gust_oracle import residual_bounds

    sensor = load_sensor("pid-logger")
    block = block_size(sensor)
    raw = sensor.noise_kelvin(25.0 + sensor.heated_rise)
    n = round(4 * sensor.sample_rate / block)
    fam = Family(sensor, n, block, raw, grid_factor=0.5)
    x = null_streams(sensor, 11, 3.0, 2, block, raw)
    t = np.arange(n) * block / sensor.sample_rate
    contact = np.where(t >= 2.0, -0.002 * (1.0 - np.exp(-(t - 2.0) / 0.5)), 0.0)
    m = 0.2 * fam.shapes[_gust_inside(fam)] + contact
    filters, offsets = residual_bounds(m, fam)
    assert filters.shape == (16, n)
    for j in range(x.shape[1]):
        w = np.lib.stride_tricks.sliding_window_view(x[:, j], n).T
        stat, llr = _statistic(fam, m, w)
        bound = np.min(filters @ w + offsets[:, None], axis=0)
        assert np.all(bound >= stat - 1e-9)
        # windows a level of 0 nats leaves to the family: a tenth of the plain LLR's or fewer
        assert np.sum(bound >= 0.0) <= 0.1 * np.sum(llr >= 0.0)
        assert np.sum(llr >= 0.0) > 100


def _unpruned_search(stats: list[np.ndarray], needed: int, start: float, stop: float,
                     n: int, step: float = 0.5) -> tuple[float, str]:
    """The threshold search with every window's T exact from the start (no bounds)."""
    from skin.bench.gust_oracle import _refine

    level, drop = start, step
    while True:
        top = max(float(np.max(st[st >= level], initial=-np.inf)) for st in stats)
        hs = np.arange(level, max(top, level) + step, step)
        ok = [sum(_count(st, float(h), n) for st in stats) >= needed for h in hs]
        if any(ok):
            return _refine(stats, float(hs[np.flatnonzero(ok)[-1]]), step, needed, n), "found"
        if level < stop:
            return float(level), "below"
        level -= drop
        drop *= 2.0


@pytest.mark.parametrize("name", ["paper", "pid-logger"])
def test_the_pruned_search_returns_what_the_unpruned_one_does(name: str) -> None:
    # null_threshold weighs the family only on the windows its exact bounds leave at or
    # above the level it tries, walks the grid down lazily and keeps the family's gains
    # between contacts (cache): the same threshold and status as weighing every window,
    # for contacts the family nearly mimics and ones it does not, cache fresh or shared
    from skin.bench.gust_oracle import null_threshold

    fam, x, contact = _small_search(name)
    n = contact.size
    near = 0.2 * fam.shapes[_gust_inside(fam)] + 0.1 * contact
    cache: dict = {}
    for m in (contact, near, 0.3 * contact):
        stats = _window_statistics(fam, m, x)
        for needed in (1, 3):
            want = _unpruned_search(stats, needed, 15.0, -50.0, n)
            fresh = null_threshold(x, m, fam, needed, 15.0, -50.0)
            shared = null_threshold(x, m, fam, needed, 15.0, -50.0, cache=cache)
            spread = null_threshold(x, m, fam, needed, 15.0, -50.0, spread_at=0)
            assert spread[2] == want[1]
            assert spread[0] == pytest.approx(want[0], abs=1e-9)
            assert fresh[2] == want[1] and shared[2] == want[1]
            assert fresh[0] == pytest.approx(want[0], abs=1e-9)
            assert shared[0] == pytest.approx(want[0], abs=1e-9)

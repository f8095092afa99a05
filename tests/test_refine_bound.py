"""Cramér-Rao bounds on the refined onset (skin bench refine-bound) and issue 16's target."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from skin.bench.onset_eval import onset_error_target
from skin.bench.refine_bound import (
    VARIANTS,
    drift_covariance,
    efficient_sd,
    fisher_matrix,
    median_draws,
    onset_crb,
    smoothing_kernel,
    summarise,
)
from skin.cli import main as skin_main
from skin.models.sensors import load_sensor


def test_a_ramp_in_white_noise_gives_the_closed_form() -> None:
    # m(t) = a t from the onset: every sample of the window after the onset's own has
    # m' = a, so var(t0) >= sigma^2 / sum(m'^2) = sigma^2 / (n a^2) with the rest known
    fs, sigma, a, n = 100.0, 0.1, 0.5, 200
    t = np.arange(n + 5) / fs  # past the window: the slope at its last sample is a too
    got = onset_crb(a * t, fs, sigma, 1, n + 1)
    assert got["known"] == pytest.approx(sigma / math.sqrt(n * a * a), rel=1e-9)
    # the amplitude unknown: the Schur complement of the (t0, A) information
    d, m = np.full(n, -a), a * t[1:n + 1]
    info = np.array([[d @ d, d @ m], [m @ d, m @ m]]) / sigma**2
    assert got["gain"] == pytest.approx(1.0 / math.sqrt(info[0, 0] - info[0, 1] ** 2
                                                        / info[1, 1]), rel=1e-9)
    # a step has no slope anywhere in the window but at the onset's sample: a window after
    # it says nothing of the onset
    assert onset_crb(np.ones(50), fs, sigma, 2, 50)["known"] == math.inf


def test_smoothed_noise_is_weighed_by_its_own_covariance() -> None:
    # the banded solve is the dense D^T (sigma^2 H H^T)^-1 D, H the smoothing's matrix
    rng = np.random.default_rng(0)
    for name in ("low-cost", "fast-film", "pid-logger"):
        kernel, center = smoothing_kernel(load_sensor(name))
        pad = max(center, kernel.size - 1 - center)
        n = 40
        cols = rng.normal(size=(n + 2 * pad, 3))
        h = np.zeros((n, n + 2 * pad))
        for j in range(n + 2 * pad):
            e = np.zeros(n + 2 * pad)
            e[j] = 1.0
            h[:, j] = np.convolve(e, kernel)[center:center + e.size][pad:pad + n]
        dense = (h @ cols).T @ np.linalg.solve(0.04 * h @ h.T, h @ cols)
        assert np.allclose(fisher_matrix(cols, 0.2, kernel, center, pad), dense, rtol=1e-8)
    # no smoothing: the plain sum of squares
    cols = rng.normal(size=(30, 2))
    assert np.allclose(fisher_matrix(cols, 0.5), cols.T @ cols / 0.25)


def test_nuisances_only_raise_the_bound() -> None:
    fs, sigma = 20.0, 0.2
    t = np.arange(120) / fs
    template = -1.5 * (1.0 - np.exp(-t / 1.2)) ** 2  # a lagged, smooth departure
    kernel, center = smoothing_kernel(load_sensor("low-cost"))
    got = onset_crb(template, fs, sigma, -30, 100, kernel, center)
    assert 0 < got["known"] <= got["gain"] <= got["gain_offset"] < math.inf
    # more samples, no less information
    wide = onset_crb(template, fs, sigma, -30, 120, kernel, center)
    assert wide["known"] <= got["known"] * (1 + 1e-12)
    j = np.array([[4.0, 1.0], [1.0, 2.0]])
    assert efficient_sd(j) == pytest.approx(1.0 / math.sqrt(4.0 - 0.5))


def test_the_room_and_the_air_through_no_filter_give_their_closed_forms() -> None:
    """The paper's sensor reads the room and the air as they are (no loop, lag or smoothing):
    the room's walk from the history's start, (min(i, k) + 1) D / fs, plus the flutter's AR(1),
    its stationary sd the simulator's FLUTTER, both from rest."""
    from skin.bench.refine_bound import DRIFT_HISTORY
    from skin.bench.streams import FLUTTER, FLUTTER_TAU
    from skin.stream.onset import AMBIENT_DRIFT

    sensor = load_sensor("paper")
    fs, n = sensor.sample_rate, 60
    got = drift_covariance(sensor, n)
    first = math.ceil(DRIFT_HISTORY * FLUTTER_TAU * fs)  # the window's first sample
    i = first + np.arange(n)
    lo = np.minimum.outer(i, i)
    room = (lo + 1) * AMBIENT_DRIFT / fs
    a = math.exp(-1.0 / (FLUTTER_TAU * fs))
    flutter = (2.0 * FLUTTER_TAU * fs * (1.0 - a) ** 2 * FLUTTER**2
               * a ** np.abs(np.subtract.outer(i, i)) * (1.0 - a ** (2 * (lo + 1)))
               / (1.0 - a * a))
    np.testing.assert_allclose(got, room + flutter, rtol=1e-9)
    assert np.sqrt(flutter[-1, -1]) == pytest.approx(FLUTTER, rel=0.01)  # settled
    # too long for a dense covariance: not computed
    assert drift_covariance(load_sensor("fast-film"), 2000) is None


def test_the_drift_is_noise_the_bound_adds_to_its_own() -> None:
    # a zero covariance added: the banded solve's information, densely
    rng = np.random.default_rng(1)
    kernel, center = smoothing_kernel(load_sensor("low-cost"))
    pad = max(center, kernel.size - 1 - center)
    cols = rng.normal(size=(50 + 2 * pad, 3))
    assert np.allclose(fisher_matrix(cols, 0.2, kernel, center, pad, np.zeros((50, 50))),
                       fisher_matrix(cols, 0.2, kernel, center, pad), rtol=1e-8)
    # the room and the air on a low-cost contact: a bound no lower than without them
    sensor = load_sensor("low-cost")
    fs = sensor.sample_rate
    t = np.arange(120) / fs
    template = -1.5 * (1.0 - np.exp(-t / 1.2)) ** 2
    drift = drift_covariance(sensor, 130)
    got = onset_crb(template, fs, 0.2, -30, 100, kernel, center, drift)
    assert got["gain_offset"] < got["gain_offset_drift"] < math.inf


def test_monte_carlo_medians_of_half_normal_errors() -> None:
    sd = np.full(101, 0.01)  # 101 contacts of sd 10 ms: the median |error| is near 6.745 ms
    med = median_draws(sd, 4000, np.random.default_rng(1))
    out = summarise(med, 6.745)
    assert out["median_ms"] == pytest.approx(6.745, abs=0.1)
    assert 0.4 < out["p_meets_target"] < 0.6
    assert out["p5_p95_ms"][0] < out["median_ms"] < out["p5_p95_ms"][1]
    assert summarise(median_draws(np.full(3, np.inf), 10, np.random.default_rng(0)),
                     15.0)["p_meets_target"] == 0.0


def test_the_target_is_15_ms_or_a_tenth_of_the_median_floor() -> None:
    assert onset_error_target([0.05, 0.1, np.inf]) == 15.0
    assert onset_error_target([1.0, 2.0, 3.0, np.inf]) == 200.0
    assert onset_error_target([]) == 15.0


def test_the_command_and_evaluate_onset_give_the_same_target_and_library_error(capsys) -> None:
    common = ["--minutes", "5", "--taxels", "4"]
    assert skin_main(["evaluate-onset", "--sensor", "low-cost", "--seed", "0", *common,
                      "--json"]) == 0
    onset = json.loads(capsys.readouterr().out)
    assert onset["refined_onset_target_ms"] >= 15.0
    assert skin_main(["bench", "refine-bound", "--sensors", "low-cost", "--seeds", "0",
                      *common, "--draws", "500", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    (run,) = doc["runs"]
    assert run["refined_onset_target_ms"] == onset["refined_onset_target_ms"]
    assert run["library_refined_onset_error_ms_median"] \
        == onset["refined_onset_error_ms_median"]
    assert run["contacts_with_floor"] > 0 and run["draws"] == 500
    for name in VARIANTS:
        b = run["bounds"][name]
        assert {"sd_ms_median", "median_ms", "p5_p95_ms", "p_meets_target",
                "detected"} <= set(b)
        assert 0.0 <= b["p_meets_target"] <= 1.0
    sd = {name: run["bounds"][name]["sd_ms_median"] for name in VARIANTS}
    assert sd["known"] <= sd["gain"] <= sd["gain_offset"] <= sd["gain_offset_drift"]
    assert skin_main(["bench", "refine-bound", "--sensors", "low-cost", "--seeds", "0",
                      *common, "--draws", "200"]) == 0
    text = capsys.readouterr().out
    assert "gain_offset" in text and "target" in text
    assert skin_main(["evaluate-onset", "--sensor", "low-cost", "--seed", "0", *common]) == 0
    assert f"target {onset['refined_onset_target_ms']} ms" in capsys.readouterr().out


@pytest.mark.parametrize("bad", [["--seeds", "-1"], ["--minutes", "0.00001"],
                                 ["--draws", "0"], ["--sensors", "nosuch"]])
def test_refine_bound_refuses_bad_input_before_the_work(bad, capsys) -> None:
    assert skin_main(["bench", "refine-bound", "--sensors", "paper", *bad]) == 2
    named = bad[1] if bad[0] == "--sensors" else bad[0]  # the message names the problem
    assert named in capsys.readouterr().err


def test_each_contacts_bounds_are_its_own_whatever_else_is_asked() -> None:
    """``contact_bounds`` gives a contact the same bounds alone as among others: its windows
    (the refinement's and evaluate-onset's credit window) are its own, not a neighbour's
    (a variable leaked from one loop into the next went unseen by the tests before)."""
    from skin.bench.delay_bound import onset_stream
    from skin.bench.refine_bound import contact_bounds

    sensor = load_sensor("paper")
    stream = onset_stream(sensor, 0, 2.0, 4)
    which = [k for k, c in enumerate(stream.contacts) if np.isfinite(c.visible_after)]
    assert len(which) >= 3
    firsts = {math.ceil(stream.contacts[k].onset * stream.fs) for k in which}
    assert len(firsts) == len(which)  # each contact's template starts at its own sample
    which = which[::-1]  # latest first: a window taken from another contact shows
    together = contact_bounds(stream, sensor, which)
    for i, k in enumerate(which):
        alone = contact_bounds(stream, sensor, [k])
        for name in VARIANTS:
            np.testing.assert_allclose(alone[name], together[name][i:i + 1], rtol=1e-12,
                                       err_msg=f"{name}, contact {k}")
    # and known_credited is evaluate-onset's whole credit window, from EARLY before the onset
    from skin.bench.onset_eval import EARLY

    kernel, center = smoothing_kernel(sensor)
    for i, k in enumerate(which):
        c, m = stream.contacts[k], stream.templates[k]
        first = math.ceil(c.onset * stream.fs)
        early = math.ceil((c.onset - EARLY) * stream.fs) - first
        want = onset_crb(m, stream.fs, float(stream.raw_noise), early, m.size, kernel,
                         center)["known"]
        assert together["known_credited"][i] == pytest.approx(want, rel=1e-12)

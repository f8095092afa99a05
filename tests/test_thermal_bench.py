"""``skin bench thermal``: rows comparable in time, a reference that is converged (item 3)."""

import numpy as np

from skin.bench import thermal


def test_every_forward_row_runs_the_same_batch_of_distinct_trials():
    # issue 20 item 3: the closed forms broadcast one e and h over the batch (~20x cheaper
    # than distinct trials) and the multilayer rows timed a single trial, so "x closed form"
    # was overstated ~14x
    rows = thermal.forward(cells=(4,), dts=(0.1,))
    assert {r["trials"] for r in rows} == {thermal.BATCH}
    assert thermal.BATCH > 1
    ks, t0s, hs = thermal.trial_batch(0.15)
    assert len(set(ks)) == len(set(t0s)) == len(set(hs)) == thermal.BATCH
    assert all(np.isfinite(r["rms_error"]) and r["time_per_trial_ms"] > 0 for r in rows)


def test_the_paper_stack_reference_is_converged_in_space():
    # the reference was the plain fine grid (192 sensor cells): 5.5e-5 K off for pine, ~6 %
    # of the errors it judged; Richardson's extrapolation from two grids removes the h^2 term
    k, alpha = thermal.CASES["pine"]
    one = dict(alpha=alpha, t_sensor=np.array([thermal.T_SENSOR]),
               conductance=np.array([3000.0]))
    coarse = thermal._converged_reference(np.array([k]), cells=32, **one)
    fine = thermal._converged_reference(np.array([k]), cells=48, **one)
    plain = thermal._multilayer(thermal.SensorStack.paper(cells=96), np.array([k]), alpha, 120,
                                "tr-bdf2", 5e-4, 1.0, 3000.0, one["t_sensor"])[0]()
    extrapolated = np.sqrt(np.mean((coarse - fine) ** 2))
    assert extrapolated < 0.1 * np.sqrt(np.mean((plain - fine) ** 2))

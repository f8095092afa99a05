"""Which nuisance costs the classifiers most: the synthetic benchmark with one of them fixed.

A simulated trial's reading depends on its material and on nuisances the classifiers are not
told (`skin.bench.ceiling`): the sensor's temperature before contact (its reheat history),
the object's temperature (warmed by the touches before), each taxel's own constants (+-10 %),
the contact conductance, the onset error and the ADC noise. Each row of this benchmark
simulates the same protocol with *one* of them fixed and cross-validates the methods on it;
the rise over the unchanged protocol is what that nuisance costs each method, and so where
the gap between a method and the known-nuisance ceiling comes from. The folds are grouped
(`skin.commands.evaluate.split_folds`): no taxel on both sides, so with the taxel spread fixed
the methods no longer read a taxel's constants to tell its run (and formerly its material).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

#: Variant name -> what is fixed (the protocol's defaults otherwise).
VARIANTS = {
    "protocol": "nothing fixed (the benchmark as it is)",
    "sensor_start": "sensor fully reheated before every touch (one initial temperature per "
                    "taxel)",
    "object_temperature": "object always at its resting temperature (no warming by the "
                          "touches before)",
    "taxel_constants": "every taxel has the sensor's nominal constants (no +-10 % spread)",
    "conductance": "contact conductance fixed at the geometric middle of each material's range",
    "onset": "recorded onset is the true contact instant",
    "adc_noise": "no ADC noise (quantisation kept)",
}


def variant_data(name: str, trials: int, seed: int, sensor=None):
    """Simulate the paper's 11 materials with the nuisance ``name`` fixed (`VARIANTS`)."""
    from skin.models import load_materials
    from skin.models.trials import PAPER_MATERIALS, Protocol, simulate_trials

    if name not in VARIANTS:
        raise ValueError(f"unknown variant {name!r}; known: {', '.join(VARIANTS)}")
    table = load_materials()
    materials = [table[m] for m in PAPER_MATERIALS]
    p = Protocol(trials=trials)
    if name == "sensor_start":  # long enough reheats and rests: the taxel's free steady state
        p = replace(p, reheat=(1e4, 1e4), rest=1e4)
    elif name == "object_temperature":
        p = replace(p, object_memory=0.0)
    elif name == "taxel_constants":
        p = replace(p, taxel_spread=0.0)
    elif name == "conductance":
        materials = [replace(m, gap=(float(np.sqrt(m.gap[0] * m.gap[1])),) * 2)
                     for m in materials]
    elif name == "onset":
        p = replace(p, onset_jitter=0.0)
    elif name == "adc_noise":
        p = replace(p, adc_noise=0.0)
    return simulate_trials(materials, p, seed=seed, sensor=sensor)


def nuisance_table(variants: Sequence[str], methods: Sequence[str],
                   durations: Sequence[float], trials: int = 100, seed: int = 7,
                   sensor=None, folds: int = 3,
                   progress: Callable[[str], None] | None = None) -> list[dict]:
    """Cross-validated accuracy of each method (and the ceiling) on each variant.

    Returns
    -------
    list of dict
        One row per (variant, method, duration): ``variant``, ``method``, ``duration``,
        ``accuracy``, ``accuracy_std`` and ``predict_ms_per_trial``.
    """
    from skin.bench.ceiling import check_ceiling, known_nuisance_ceiling
    from skin.commands.evaluate import evaluate
    from skin.errors import SkinError

    rows = []
    for v in variants:
        data = variant_data(v, trials, seed, sensor)
        if "ceiling" in methods:
            try:
                check_ceiling(data)
            except SkinError:  # another sensor's reading chain: no ceiling, say so
                methods = [m for m in methods if m != "ceiling"]
                if progress is not None:
                    progress("no ceiling: the sensor does not read the paper's closed form")
        for d in durations:
            for m in methods:
                if progress is not None:
                    progress(f"{v} {m} {d:g} s")
                r = (known_nuisance_ceiling(data, d) if m == "ceiling"
                     else evaluate(data, m, d, folds, "grouped", 0))
                rows.append({"variant": v, "method": m, "duration": d,
                             "accuracy": r["accuracy"], "accuracy_std": r["accuracy_std"],
                             "predict_ms_per_trial": r["predict_ms_per_trial"]})
    return rows

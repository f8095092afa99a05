"""Fit the joint classifier's calibration (`skin.models.joint.EvidenceTemperature`) to scenes.

The pipeline's contacts are played as `skin run --seed N` makes them (`skin.Skin`, nothing
written), once per training seed, and classified in order by the classifier as it stood
before the run, untempered (its learned object prior then grows again, contact by contact,
as in the run; tempering changes the answer, not what it learns). Each answer is kept with
the scene's truth. For every candidate temperature the answers are tempered
(``p ~ p_model ** (1 / temperature)``, the same as dividing the log evidence) and scored by
the log-loss of the true material (`skin.bench.reliability`). The fit is the least log-loss
among the temperatures that name no training touch wrong at p >= 0.9 (the guide's rule: say
"unknown" or the family rather than be confidently wrong; a log-loss alone trades one
confident mistake for many sharper right answers); ties go to the temperature nearer 1. The
unconstrained least log-loss is reported beside it. The same seeds give the same contacts and
so the same fit. Several scenes (other sensor presets, other objects) are pooled into one fit
(`collect_scenes`): one temperature, bound by the confident mistakes of every one of them,
rather than one tuned to a single sensor.
"""

from __future__ import annotations

import copy
import io
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from skin.bench.reliability import SURE, material_and_family

#: The scenes pooled by default: the default scene on the paper's sensor and on `fast-film`, and
#: objects 8 K colder or warmer than the room (`cold-warm`).
FIT_SCENES = ("default", "default-fast-film", "cold-warm")
#: Candidate temperatures: 1 (the model as it is) down to 0.05, log-spaced.
TEMPERATURES = tuple(float(v) for v in np.round(np.geomspace(1.0, 0.05, 14), 4))


def collect_scenes(scenes: Sequence[str], seeds: Sequence[int],
                   progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """`collect` each of ``scenes`` over ``seeds`` and pool their runs (one fit for them all).

    The scenes must share the classifier's classes (the shipped materials table).
    """
    if not scenes:
        raise ValueError("give at least one scene")
    pooled: dict[str, Any] | None = None
    total = len(scenes) * len(seeds)
    for k, scene in enumerate(scenes):
        def step(done: int, _n: int, k: int = k) -> None:
            if progress is not None:
                progress(k * len(seeds) + done, total)
        answers = collect(scene, seeds, step)
        if pooled is None:
            pooled = answers
        elif any(answers[k] != pooled[k] for k in ("classes", "family", "threshold")):
            raise ValueError(f"scene {scene}: its classifier's classes, families or threshold "
                             f"differ from those of scene {scenes[0]}; one calibration cannot "
                             f"cover both")
        else:
            pooled["runs"] += answers["runs"]
    assert pooled is not None
    return pooled


def collect(scene: str, seeds: Sequence[int],
            progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Play ``scene`` once per seed; return its untempered answers with their truths.

    Returns
    -------
    dict
        ``runs``: per seed, a list of (truth, probabilities) of its final contacts in the
        order they were decided (truth None: a false contact); ``classes``, ``family``
        (material -> family), ``threshold`` and ``table`` (the classifier's materials).
    """
    from skin.progress import Progress
    from skin.runner import Skin

    runs, clf = [], None
    for i, seed in enumerate(seeds):
        with Skin(scene=scene, seed=int(seed), speed=0.0, out=None, map=False, sinks=[],
                  progress=Progress(io.StringIO())) as skin:
            clf = copy.deepcopy(skin.classifier)  # before the run teaches it anything
            if not hasattr(clf, "calibration"):
                raise ValueError(f"scene {scene}: its classifier ({clf.method}) is not the "
                                 f"joint classifier the calibration is for")
            clf.calibration = None
            try:
                contacts = [r.contact for r in skin.results() if r.contact.final]
            finally:
                skin.close_sources()
            skin.finish()
            truth = {r["contact"]: r.get("truth") for r in skin.records if r["final"]}
        runs.append([(truth.get(c.id), clf.classify(c).probabilities) for c in contacts])
        if progress is not None:
            progress(i + 1, len(seeds))
    if clf is None:
        raise ValueError("give at least one seed")
    return {"runs": runs, "classes": list(clf.model.classes),
            "family": {m.name: m.family for m in clf.model.materials},
            "threshold": clf.threshold, "table": clf.table}


def temper(probabilities: dict[str, float], temperature: float) -> dict[str, float]:
    """Return ``probabilities`` tempered: each to the power 1 / temperature, renormalised."""
    from skin.models.joint import EvidenceTemperature

    if not probabilities:
        return {}
    with np.errstate(divide="ignore"):  # a probability of 0 stays 0
        log_p = np.log(np.array(list(probabilities.values()), dtype=float))
    q = EvidenceTemperature(temperature).probabilities(log_p)
    return dict(zip(probabilities, q.tolist(), strict=True))


def score(answers: dict[str, Any], temperature: float) -> dict[str, Any]:
    """Figures of the collected answers tempered at ``temperature``.

    The reliability at material and family level (`material_and_family`) and, per run, the
    mean count of touches named right, "unknown", named right at family level, and named
    wrong at p >= `SURE`, as the classifier names them (`hierarchical_answer`).
    """
    from skin.models.materials import hierarchical_answer

    probs, truths = [], []
    named = unknown = family = sure_wrong = 0
    for run in answers["runs"]:
        for truth, p in run:
            if truth is None:
                continue
            q = temper(p, temperature)
            label, conf, fam, _ = hierarchical_answer(q, answers["threshold"], answers["table"])
            probs.append(q)
            truths.append(truth)
            named += label == truth
            unknown += label == "unknown"
            family += fam == answers["family"].get(truth, truth)
            sure_wrong += label not in (truth, "unknown") and conf >= SURE
    n = max(len(answers["runs"]), 1)
    return {"temperature": float(temperature),
            **material_and_family(probs, truths, answers["classes"], answers["family"]),
            "named": round(named / n, 2), "unknown": round(unknown / n, 2),
            "family_named": round(family / n, 2), "sure_wrong": round(sure_wrong / n, 2),
            "sure_wrong_count": int(sure_wrong)}


def fit(answers: dict[str, Any], temperatures: Sequence[float] = TEMPERATURES,
        ) -> dict[str, Any]:
    """Score every temperature (`score`); pick the least log-loss with no confident mistake.

    Returns ``best`` (the temperature of least material log-loss among those that name no
    touch wrong at p >= `SURE`; if every one does, the fewest such mistakes first),
    ``least_log_loss`` (the temperature of least log-loss, unconstrained) and ``table``
    (`score` of each, in the order given).
    """
    if not temperatures:
        raise ValueError("give at least one temperature to try")
    table = [score(answers, float(t)) for t in temperatures]

    def loss(r: dict[str, Any]) -> tuple[float, float]:
        return r["material"]["log_loss"], abs(float(np.log(r["temperature"])))

    best = min(table, key=lambda r: (r["sure_wrong_count"], *loss(r)))
    return {"best": best["temperature"], "least_log_loss": min(table, key=loss)["temperature"],
            "table": table}

"""One scene over many seeds: how `skin run` names its touches when only the noise changes.

`skin run` on the default scene is the library's demo; one seed is one draw of the noise, the
taxels' starting temperatures and their units, so its count of contacts named right is one
sample. `run` plays a scene once per seed through `skin.Skin` (as `skin run --seed N
--speed 0`, nothing written) and reports, per seed and over all of them: touches detected,
named right at material and at family level, "unknown", wrong, wrong at p >= 0.9 and false
contacts; and every miss, grouped by what the touch was and what it was called, with the
effusivity ratio of the two materials (a pair a few per cent apart, such as aluminium and
steel, is one the reading cannot separate) and the touch's taxels and duration; and how far
the answers' probabilities can be trusted over every detected touch (log-loss, Brier,
expected calibration error and a reliability table, `skin.bench.reliability`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from skin.bench.reliability import material_and_family

#: An answer at or above this probability is a confident one.
SURE = 0.9


def play(scene: str, seed: int, duration: float | None = None,
         ceiling: bool = False, common_mode: bool | str = "auto",
         force_onsets: bool = True, response_check: bool = True) -> dict[str, Any]:
    """Run ``scene`` with ``seed`` through `skin.Skin`; return its figures and its misses.

    ``phantoms``: what the scene's phantom presses (force glitches,
    `skin.bench.phantoms.phantom_figures`) became; ``classify_s``: the pipeline's classify
    stage, s (the response test included), over ``contacts`` final contacts.

    With ``ceiling``, also ``ceiling`` (touches the known-nuisance ceiling names right, and
    ``ceiling_family``) and ``steps`` (the gap from the run to it,
    `skin.bench.scene_ceiling.ladder`).
    """
    import io

    from skin.progress import Progress
    from skin.runner import Skin

    started, cpu = time.monotonic(), time.process_time()
    quiet = Progress(io.StringIO())  # the run's own status lines; the bench shows its bar
    with Skin(scene=scene, seed=seed, speed=0.0, duration=duration, out=None, map=False,
              common_mode=common_mode, force_onsets=force_onsets,
              response_check=response_check, sinks=[], progress=quiet) as skin:
        if ceiling:
            import copy

            fresh = copy.deepcopy(skin.classifier)  # before the run teaches it anything
            fs = next(iter(skin.layout.boards.values())).sample_rate
            n = round(skin.duration * fs)
            readings = np.full((n + 1, len(skin.layout)), np.nan)

            def observe(times: np.ndarray, temperature: np.ndarray, _host: np.ndarray) -> None:
                k = np.rint(np.asarray(times) * fs).astype(int)
                ok = (k >= 0) & (k <= n)
                readings[k[ok]] = temperature[ok]

            skin.pipeline.observers.append(observe)
        # as `Skin.run`, keeping each final contact and its estimate: the records
        # (``events.jsonl``'s lines) round the probabilities to 4 decimals and the confidence
        # to 3, for display; every figure here is computed from the estimates themselves
        contacts, estimates = [], {}
        try:
            for r in skin.results():
                if r.contact.final:
                    contacts.append(r.contact)
                    estimates[r.contact.id] = r.estimate
        finally:
            skin.close_sources()
        summary = skin.finish()
        table = skin.materials
    finals = [r for r in skin.records if r["final"]]
    clf = skin.classifier
    classes = list(getattr(clf, "classes", None) or clf.model.classes)
    answers = [[rec["truth"], {k: float(v) for k, v
                               in estimates[rec["contact"]].probabilities.items()}]
               for rec in finals if rec.get("truth") is not None]
    touches = {(tuple(t["taxels"]), t["start"]): t for t in summary["per_touch"]}
    misses, wrong, unknown, sure_wrong = [], 0, 0, 0
    for rec in finals:
        truth = rec.get("truth")
        if truth is None or rec["label"] == truth:
            continue
        est = estimates[rec["contact"]]
        if rec["label"] == "unknown":
            unknown += 1
        else:
            wrong += 1
            sure_wrong += est.confidence >= SURE
        probs = est.probabilities or {}
        best = max(probs, key=probs.get) if probs else None
        misses.append({
            "truth": truth, "label": rec["label"], "best": best,
            "confidence": float(est.confidence), "family": rec.get("family"),
            "family_right": rec.get("family") == table[truth].family,
            "effusivity_ratio": (None if best is None or best == truth else
                                 round(table[best].effusivity / table[truth].effusivity, 3)),
            "taxels": len(rec["taxels"]), "duration": rec["duration"],
            "onset": rec["onset"]})
    from skin.bench.phantoms import phantom_figures

    extra: dict[str, Any] = {"dating": _dating(skin, contacts),
                             "phantoms": phantom_figures(skin.scene.phantoms, finals),
                             "classify_s": skin.pipeline.stats.seconds["classify"],
                             "contacts": len(contacts),
                             "dated_by": {src: sum(w.dated_by == src for c in contacts
                                                   for w in c.windows)
                                          for src in ("thermal", "force")}}
    if ceiling:
        extra = {**extra, **_ceiling_figures(skin, fresh, contacts, readings, fs)}
    return {**extra, "seed": seed, "touches": summary["touches"], "detected": summary["detected"],
            "material": summary["correct"], "family": summary["family_correct"],
            "unknown": unknown, "wrong": wrong, "sure_wrong": sure_wrong,
            "false_contacts": summary["false_contacts"], "misses": misses,
            "answers": answers, "classes": classes,
            "family_of": {m: table[m].family for m in classes if m in table},
            "n_touches": len(touches), "wall_s": round(time.monotonic() - started, 2),
            "cpu_s": round(time.process_time() - cpu, 2)}


def _dating(skin: Any, contacts: list) -> list[dict[str, Any]]:
    """Return `dating_errors` of a played scene's final contacts against its touches.

    The touches' instants are the scene's, on the sample grid (as
    `skin.bench.scene_ceiling.touch_truth` has them, without its simulation: any sensor).
    """
    from skin.formats.scene import match_touches

    fs = next(iter(skin.layout.boards.values())).sample_rate
    n = round(skin.duration * fs)
    truths = [{"touch": t, "k0": round(t.start * fs), "k1": min(round(t.end * fs), n),
               "taxels": [int(k) for k in t.taxels]}
              for t in skin.scene.touches if round(t.start * fs) < n]
    in_time = tuple(t["touch"] for t in truths)
    matches, _ = match_touches(replace(skin.scene, touches=in_time),
                               [c.taxels for c in contacts], [c.onset for c in contacts])
    return dating_errors(matches, contacts, truths, fs)


def _ceiling_figures(skin, fresh, contacts: list, readings: np.ndarray,
                     fs: float) -> dict[str, Any]:
    """Return the ceiling and the gap's steps of one played scene (`play` with ``ceiling``)."""
    from skin.bench.scene_ceiling import ladder, touch_ceiling, touch_truth
    from skin.formats.scene import match_touches

    scene, table = skin.scene, skin.materials
    window = skin.setup.window
    truths = touch_truth(scene, skin.duration, skin.setup.contact)
    candidates = {m.name: m.effusivity for m in fresh.model.materials}
    chosen = [touch_ceiling(t, readings, fs, scene.ambient, window, candidates) for t in truths]
    misses = [{"truth": t["material"], "chosen": c, "taxels": len(t["taxels"]),
               "duration": round((t["k1"] - t["k0"]) / fs, 3)}
              for t, c in zip(truths, chosen, strict=True) if c != t["material"]]
    in_time = tuple(t["touch"] for t in truths)
    matches, _ = match_touches(replace(scene, touches=in_time), [c.taxels for c in contacts],
                               [c.onset for c in contacts])
    steps = ladder(fresh, matches, contacts, truths, readings, fs, scene.ambient, window)
    return {"dating": dating_errors(matches, contacts, truths, fs),
            "ceiling": sum(c == t["material"] for t, c in zip(truths, chosen, strict=True)),
            "ceiling_family": sum(table[c].family == t["family"]
                                  for t, c in zip(truths, chosen, strict=True)),
            "ceiling_misses": misses, "steps": steps}


def dating_errors(matches: list, contacts: list, truths: list[dict[str, Any]],
                  fs: float) -> list[dict[str, Any]]:
    """Return each matched touch's taxel windows' dating errors, ms (estimate - truth).

    One entry per window of a taxel of the touch: ``duration`` (the touch's, s), ``onset``
    and, for a released window ending before the run's cut, ``end`` (the window's last
    sample against the touch's end, the first sample read free), else None.
    """
    out = []
    by_touch = {id(t["touch"]): t for t in truths}
    for m in matches:
        truth = by_touch.get(id(m.touch))
        if m.contact_index is None or truth is None:
            continue
        start, end = truth["k0"] / fs, truth["k1"] / fs
        for w in contacts[m.contact_index].windows:
            if w.taxel not in truth["taxels"]:
                continue
            last = w.onset + (float(w.time[-1]) if w.time.size else 0.0)
            out.append({"duration": round(end - start, 3),
                        "onset": round(1e3 * (w.onset - start), 1),
                        "end": round(1e3 * (last + 1.0 / fs - end), 1) if w.released else None})
    return out


def dating_summary(dating: list[dict[str, Any]], short: float = 0.6) -> dict[str, Any]:
    """Median and 5-95 % of `dating_errors`' onset and end errors, ms, all and short touches.

    ``short``: touches at most this long, s. None where there is nothing to count.
    """
    def spread(values: list[float]) -> dict[str, float] | None:
        if not values:
            return None
        p5, p50, p95 = np.percentile(values, (5, 50, 95))
        return {"median": round(float(p50), 1), "p5": round(float(p5), 1),
                "p95": round(float(p95), 1), "n": len(values)}

    out = {}
    for name, keep in (("all", lambda d: True), ("short", lambda d: d["duration"] <= short)):
        chosen = [d for d in dating if keep(d)]
        out[name] = {"onset": spread([d["onset"] for d in chosen]),
                     "end": spread([d["end"] for d in chosen if d["end"] is not None])}
    return out


def _pair(truth: str, label: str, misses: list[dict]) -> dict[str, Any]:
    """Summarise the misses of one truth called one label (`run`'s ``pairs``).

    ``best`` is the material most often most probable among them, and ``effusivity_ratio``
    that material's effusivity over the truth's (None when the best is the truth).
    """
    bests = [m["best"] for m in misses if m["best"]]
    best = max(sorted(set(bests)), key=bests.count) if bests else ""  # ties: by name
    return {"truth": truth, "label": label, "count": len(misses),
            "median_confidence": round(float(np.median([m["confidence"] for m in misses])), 3),
            "best": best,
            "effusivity_ratio": next((m["effusivity_ratio"] for m in misses
                                      if m["best"] == best), None),
            "family_right": int(sum(m["family_right"] for m in misses)),
            "median_duration": _median([m["duration"] for m in misses]),
            "one_taxel": int(sum(m["taxels"] == 1 for m in misses))}


def _median(values: list) -> float | None:
    """Median of the values that are not None (an open contact has no duration), or None."""
    known = [v for v in values if v is not None]
    return round(float(np.median(known)), 2) if known else None


def run(scene: str = "default", seeds: Sequence[int] = tuple(range(10)),
        duration: float | None = None,
        progress: Callable[[int, int], None] | None = None,
        ceiling: bool = False, common_mode: bool | str = "auto",
        force_onsets: bool = True, response_check: bool = True) -> dict[str, Any]:
    """Play ``scene`` once per seed; return the runs and the figures over all of them.

    ``common_mode``: the onset detector's board common mode (`skin.setup.Setup`'s);
    ``force_onsets``: contacts dated by the scene's force channel where it has one (its).
    ``response_check``: force-dated contacts without a thermal response answered "unknown"
    (`skin.stream.pipeline.Pipeline`'s).

    Returns
    -------
    dict
        ``runs`` (one `play` each), ``totals`` (sums over the runs and the share of runs
        reaching each count of touches named right) and ``pairs`` (the misses grouped by
        truth and answer: count, median confidence, effusivity ratio, median duration and
        taxels of the touches). ``totals["reliability"]``: the probabilities of every
        detected touch against its truth, at material and family level
        (`skin.bench.reliability.material_and_family`). With ``ceiling``, ``totals`` also
        holds ``ceiling``,
        ``ceiling_family`` (sums), ``ceiling_per_run`` (mean, min, max) and ``steps`` (each
        step's counts summed over the runs, `skin.bench.scene_ceiling.ladder`).
    """
    runs = []
    for i, seed in enumerate(seeds):
        runs.append(play(scene, int(seed), duration, ceiling, common_mode,
                         force_onsets, response_check))
        if progress is not None:
            progress(i + 1, len(seeds))
    keys = ("touches", "detected", "material", "family", "unknown", "wrong", "sure_wrong",
            "false_contacts")
    totals: dict[str, Any] = {k: int(sum(r[k] for r in runs)) for k in keys}
    material = np.array([r["material"] for r in runs])
    family = np.array([r["family"] for r in runs])
    totals["runs"] = len(runs)
    totals["material_per_run"] = {"mean": round(float(material.mean()), 2),
                                  "min": int(material.min()), "max": int(material.max())}
    totals["family_per_run"] = {"mean": round(float(family.mean()), 2),
                                "min": int(family.min()), "max": int(family.max())}
    totals["runs_material_at_least"] = {int(k): int((material >= k).sum())
                                        for k in sorted(set(material.tolist()))}
    if ceiling:
        top = np.array([r["ceiling"] for r in runs])
        totals["ceiling"] = int(top.sum())
        totals["ceiling_family"] = int(sum(r["ceiling_family"] for r in runs))
        totals["ceiling_per_run"] = {"mean": round(float(top.mean()), 2), "min": int(top.min()),
                                     "max": int(top.max())}
        totals["steps"] = {step: {k: int(sum(r["steps"][step][k] for r in runs))
                                  for k in runs[0]["steps"][step] if k != "misses"}
                           for step in runs[0]["steps"]}
    totals["dating"] = dating_summary([d for r in runs for d in r["dating"]])
    totals["dated_by"] = {src: int(sum(r["dated_by"][src] for r in runs))
                          for src in ("thermal", "force")}
    totals["phantoms"] = {k: int(sum(r["phantoms"][k] for r in runs))
                          for k in runs[0]["phantoms"]}
    contacts = sum(r["contacts"] for r in runs)
    totals["classify_ms_per_contact"] = (round(1e3 * sum(r["classify_s"] for r in runs)
                                               / contacts, 3) if contacts else None)
    totals["reliability"] = material_and_family(
        [a[1] for r in runs for a in r["answers"]], [a[0] for r in runs for a in r["answers"]],
        runs[0]["classes"], runs[0]["family_of"])
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        for m in r["misses"]:
            groups.setdefault((m["truth"], m["label"]), []).append(m)
    pairs = [_pair(t, lab, ms) for (t, lab), ms in groups.items()]
    pairs.sort(key=lambda p: -p["count"])
    return {"scene": scene, "seeds": [int(s) for s in seeds], "runs": runs, "totals": totals,
            "pairs": pairs}

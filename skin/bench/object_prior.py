"""One-taxel contacts and the prior on the object's temperature (`skin bench object-prior`).

One heated taxel cannot tell a cold object from a more conductive one, so the joint
classifier's answer for a one-taxel contact rests on its prior on the object's temperature.
With a fixed broad prior (10 K) most one-taxel contacts come out "unknown"; the learned prior
(`skin.models.joint.ObjectTemperaturePrior`) narrows it as far as the run's multi-taxel
contacts, which pin their objects' temperatures, justify. `run` plays random scenes of short
touches on the arm - a share of them by one taxel only, human skin among the objects, and
optionally a share of the objects cold or warm - through the pipeline with both priors, and
reports for one-taxel and multi-taxel contacts: material and family accuracy, "unknown",
how many answers came at p >= 0.9 and how many of those were right, and the calibration
error of the answers' probabilities.
"""

from __future__ import annotations

import numpy as np

from skin.formats.scene import Scene, match_touches, parse_scene


def random_scene(touches: int = 60, single: float = 0.4, off: float = 0.0,
                 offset: float = 8.0, seed: int = 0) -> Scene:
    """Build a scene on the arm: ``touches`` touches of 0.4-2.5 s, one every 3 s.

    A share ``single`` touch with one taxel, the others with one or two neighbours too; a
    share ``off`` of the touches is of an object ``offset`` K colder or warmer than the room.
    Human skin (at 32 C, its own warmth) is one of the objects.
    """
    return parse_scene(random_scene_text(touches, single, off, offset, seed),
                       "object-prior-scene.toml")


def random_scene_text(touches: int = 60, single: float = 0.4, off: float = 0.0,
                      offset: float = 8.0, seed: int = 0) -> str:
    """Return `random_scene`'s scene as TOML text."""
    from skin.formats.layout import load_layout
    from skin.models import load_materials

    rng = np.random.default_rng([seed, 5])
    layout = load_layout("arm")
    near = layout.neighbour_lists()
    mats = [m.name for m in load_materials().values() if m.classify and m.temperature is None]
    lines = ['name = "object-prior"', 'layout = "arm"', f"duration = {3.0 * touches + 2.0}",
             "ambient = 25.0", "noise = 0.02", f"seed = {seed}",
             "initial_temperature = [31.0, 38.9]"]
    for m in mats:
        lines += ["[[objects]]", f'name = "{m}"', f'material = "{m}"']
        for sign, word in ((-1, "cold"), (1, "warm")):
            lines += ["[[objects]]", f'name = "{word} {m}"', f'material = "{m}"',
                      f"temperature = {25.0 + sign * offset}"]
    lines += ["[[objects]]", 'name = "human_skin"', 'material = "human_skin"',
              "temperature = 32.0"]
    objects = [*mats, "human_skin"]
    for k in range(touches):
        i = int(rng.integers(len(layout)))
        n_more = 0 if rng.uniform() < single else int(rng.integers(1, 3))
        ids = [int(layout.ids[j]) for j in (i, *rng.permutation(near[i])[:n_more])]
        m = objects[int(rng.integers(len(objects)))]
        if m != "human_skin" and rng.uniform() < off:
            m = f"{'cold' if rng.uniform() < 0.5 else 'warm'} {m}"
        lines += ["[[touches]]", f'object = "{m}"', f"taxels = {ids}",
                  f"start = {1.0 + 3.0 * k}", f"duration = {float(rng.uniform(0.4, 2.5)):.3f}"]
    return "\n".join(lines) + "\n"


def play(scene: Scene, object_prior: str) -> dict:
    """Run the scene through the pipeline; return the figures of the module docstring."""
    from skin.bench.reliability import EVALUATE_BINS, expected_calibration_error
    from skin.drivers.sim import SkinSimulator
    from skin.models import JointClassifier, load_materials
    from skin.stream.pipeline import Pipeline

    table = load_materials()
    sim = SkinSimulator(scene)
    classifier = JointClassifier(scene.layout, table, object_prior=object_prior)
    pipeline = Pipeline(scene.layout, classifier)
    frames = list(sim.frames())
    results = []
    for k in range(0, len(frames), 50):
        results += pipeline.process(frames[k: k + 50])
    results += pipeline.flush()
    results = [r for r in results if r.contact.final]
    matches, _ = match_touches(scene, [r.contact.taxels for r in results],
                               [r.contact.onset for r in results])
    rows = {"one taxel": [], "several taxels": []}
    for m in matches:
        if m.contact_index is None:
            continue
        est = results[m.contact_index].estimate
        n_taxels = len(results[m.contact_index].contact.taxels)
        truth_family = table[m.material].family
        top = max(est.probabilities.values()) if est.probabilities else 0.0
        best = max(est.probabilities, key=est.probabilities.get) if est.probabilities else ""
        rows["one taxel" if n_taxels == 1 else "several taxels"].append(
            (est.label == m.material, est.label == "unknown", est.family == truth_family,
             top, best == m.material))
    out = {}
    for key, r in rows.items():
        if not r:
            out[key] = {"contacts": 0}
            continue
        a = np.array(r, dtype=float)
        sure = a[:, 3] >= 0.9
        out[key] = {"contacts": len(r), "material": round(float(a[:, 0].mean()), 3),
                    "family": round(float(a[:, 2].mean()), 3),
                    "unknown": round(float(a[:, 1].mean()), 3),
                    "sure": int(sure.sum()),
                    "sure_right": round(float(a[sure, 4].mean()), 3) if sure.any() else None,
                    "calibration_error": round(expected_calibration_error(
                        a[:, 3], a[:, 4] > 0, EVALUATE_BINS), 3)}
    out["learned_prior_std"] = round(classifier.prior.std(), 3)
    return out


def run(touches: int = 60, single: float = 0.4, offsets: tuple[float, ...] = (0.0, 0.3),
        offset: float = 8.0, seed: int = 0, progress=None) -> list[dict]:
    """Play each share of cold/warm objects with the fixed and the learned prior."""
    rows = []
    plan = [(off, prior) for off in offsets for prior in ("fixed", "learned")]
    for i, (off, prior) in enumerate(plan):
        scene = random_scene(touches, single, off, offset, seed)
        rows.append({"off_ambient_share": off, "offset": offset, "object_prior": prior,
                     **play(scene, prior)})
        if progress is not None:
            progress(i + 1, len(plan))
    return rows

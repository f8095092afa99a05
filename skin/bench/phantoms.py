"""Force glitches in a scene: presses the force channel reads with nothing thermal behind them.

`place` puts phantom presses (`skin.formats.scene.Phantom`) on taxels and at times no touch
of the scene comes near; `tables` writes them as the scene file's ``[[phantoms]]``;
`phantom_figures` counts what `skin run` made of them: the contacts they started (all of
whose taxels a phantom pressed at the contact's onset), and how many of those were named (a
material or a family) or answered "unknown". `skin bench scene --phantoms N`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from skin.formats.scene import Phantom, Scene

#: How long a phantom press lasts, s, and its force, N (the glitch of issue 16: 2 N for 1 s).
PHANTOM_SECONDS = 1.0
PHANTOM_FORCE = 2.0
#: No touch of the phantom's taxel comes within this of the press, s.
PHANTOM_CLEAR = 1.0


def place(scene: Scene, n: int, seed: int = 0, duration: float | None = None,
          ) -> list[Phantom]:
    """Return ``n`` phantom presses of two neighbouring taxels no touch of ``scene`` comes near.

    Each is on a taxel drawn at random and one of its neighbours (the layout's, at random;
    issue 16's glitch pressed taxels 50 and 51: two taxels pin an object's temperature, and a
    flat reading was named cardboard at p = 1.00), starting at a time drawn at random within
    the scene (from 1 s to its end, or ``duration`` when shorter, less 2 s), such that no touch of
    either taxel lies within `PHANTOM_CLEAR` of it and no other phantom overlaps it; seeded,
    so one file serves every run seed (the noise differs, the glitches do not). A phantom
    may press a taxel beside a touch while it lasts (it then joins that contact).
    """
    rng = np.random.default_rng([seed, 16])
    last = scene.duration if duration is None else min(duration, scene.duration)
    ids = [int(t) for t in scene.layout.ids]
    near = scene.layout.neighbour_lists()
    out: list[Phantom] = []
    for _ in range(1000 * max(n, 1)):
        if len(out) == n:
            break
        k = int(rng.integers(len(ids)))
        if not near[k].size:
            continue
        pair = (ids[k], ids[int(rng.choice(near[k]))])
        start = round(float(rng.uniform(1.0, last - 2.0)), 2)
        end = start + PHANTOM_SECONDS
        touched = [t for t in scene.touches if set(pair) & set(t.taxels)
                   and t.start < end + PHANTOM_CLEAR and t.end > start - PHANTOM_CLEAR]
        overlap = [p for p in out if p.start < end + PHANTOM_CLEAR
                   and p.end > start - PHANTOM_CLEAR]
        if not touched and not overlap:
            out.append(Phantom(pair, start, PHANTOM_SECONDS, PHANTOM_FORCE))
    if len(out) < n:
        raise ValueError(f"{scene.source}: room for only {len(out)} of {n} phantom presses")
    return out


def tables(phantoms: Sequence[Phantom]) -> str:
    """Return the scene file's ``[[phantoms]]`` tables of ``phantoms``."""
    return "".join(f"\n[[phantoms]]\ntaxels = {list(p.taxels)}\nstart = {p.start!r}\n"
                   f"duration = {p.duration!r}\nforce = {p.force!r}\n" for p in phantoms)


def phantom_figures(phantoms: Sequence[Phantom], records: Sequence[dict[str, Any]],
                    ) -> dict[str, int]:
    """Count the final contacts the phantoms started and what they were called.

    A contact is a phantom's when every one of its taxels was pressed by a phantom at its
    onset (within 0.2 s before the press to its end). Returns ``phantoms``, ``contacts``,
    ``unknown`` (material and family unknown), ``named`` (a material or a family) and
    ``no_response`` (the contacts noted "no thermal response").
    """
    counts = {"phantoms": len(phantoms), "contacts": 0, "unknown": 0, "named": 0,
              "no_response": 0}
    for rec in records:
        if not rec.get("final", True):
            continue
        on = [p for p in phantoms if p.start - 0.2 <= rec["onset"] <= p.end]
        pressed = {t for p in on for t in p.taxels}
        if not on or not set(rec["taxels"]) <= pressed:
            continue
        counts["contacts"] += 1
        unknown = rec["label"] == "unknown" and rec.get("family") in (None, "unknown")
        counts["unknown" if unknown else "named"] += 1
        counts["no_response"] += str(rec.get("note") or "").startswith("no thermal response")
    return counts

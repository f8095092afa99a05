"""Streaming force-dated onsets (skin.stream.force) and their place in the pipeline."""

from __future__ import annotations

import numpy as np
import pytest

from skin.stream.force import ForceOnsets
from skin.stream.onset import OnsetEvent

FS = 100.0


def _stream(seed: int = 3, n: int = 1200, taxels: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Force of ``taxels``: 5 mN noise clipped at 0; taxel 0 pressed 2 N from 5.003 s to 7 s
    (20 ms ramp), taxel 1 never, taxel 2 without a reading."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    f = np.clip(rng.normal(0.0, 0.005, (n, taxels)), 0, None)
    ramp = np.clip((t - 5.003) / 0.02, 0, 1) * 2.0 * (t < 7.0)
    f[:, 0] += ramp
    f[:, 2] = np.nan
    return t, np.round(f, 3)


def _run(t: np.ndarray, f: np.ndarray, chunk: int,
         thermal: list[OnsetEvent] = ()) -> list[OnsetEvent]:
    fo = ForceOnsets(f.shape[1], FS)
    y = np.full_like(f, 30.0)
    out = []
    for i in range(0, len(t), chunk):
        sel = slice(i, i + chunk)
        evs = [e for e in thermal if t[sel][0] <= e.detected_at <= t[sel][-1]]
        out += fo.merge(t[sel], f[sel], y[sel], evs)
    return out


def test_force_dates_onset_and_release_exactly_and_chunk_invariant() -> None:
    t, f = _stream()
    events = _run(t, f, 1)
    force = [e for e in events if e.dated_by == "force"]
    assert [e.kind for e in force] == ["onset", "release"]
    assert all(e.taxel == 0 for e in force)
    assert force[0].time == pytest.approx(5.003, abs=0.003)
    assert force[1].time == pytest.approx(7.0, abs=0.011)
    assert force[0].baseline == pytest.approx(30.0)
    for chunk in (7, 100, 333, 5000):
        assert [(e.kind, e.taxel, e.time, e.detected_at) for e in _run(t, f, chunk)] == \
            [(e.kind, e.taxel, e.time, e.detected_at) for e in events]


def test_thermal_events_kept_only_where_the_force_has_no_reading() -> None:
    t, f = _stream()
    thermal = [OnsetEvent("onset", k, 8.0, 8.2, 30.0, 0.0) for k in range(3)]
    thermal.append(OnsetEvent("onset", 1, 0.3, 0.5, 30.0, 0.0))  # before its noise is known
    kept = [e for e in _run(t, f, 50, thermal) if e.dated_by == "thermal"]
    # taxel 0 and 1 have a live force at 8.2 s (it says no contact there): dropped;
    # taxel 2 has none, and taxel 1's early event came before its free level was known
    assert sorted((e.taxel, e.detected_at) for e in kept) == [(1, 0.5), (2, 8.2)]


def test_a_contact_switch_is_dated_between_its_samples() -> None:
    t = np.arange(600) / FS
    f = ((t > 3.004) & (t < 4.5)).astype(float)[:, None]
    events = _run(t, f, 64)
    assert [e.kind for e in events] == ["onset", "release"]
    assert events[0].time == pytest.approx(3.005, abs=0.0051)


def test_pipeline_dates_a_simulated_scene_by_its_force() -> None:
    """A scene with a force channel: skin run's contacts dated by it, within a sample."""
    from skin.bench.scene_seeds import play
    from skin.commands.bench_scene import _with_fields

    scene = _with_fields("default", {"force": "force", "sensor": None})
    on = play(scene, 31, duration=8.0, force_onsets=True)
    off = play(scene, 31, duration=8.0, force_onsets=False)
    assert on["dated_by"]["force"] > 0 and off["dated_by"]["force"] == 0
    err_on = np.abs([d["onset"] for d in on["dating"]])
    err_off = np.abs([d["onset"] for d in off["dating"]])
    assert np.median(err_on) <= 10.0  # ms: one sample at 100 Hz
    assert np.median(err_on) < np.median(err_off)
    assert on["detected"] >= off["detected"]


def test_the_pipeline_on_a_force_scene_is_chunk_invariant_and_force_dated() -> None:
    """A scene with a force channel through Pipeline in chunks of 1000 and 7 frames: the same
    contacts, onsets and sources; the onsets within a sample of the touches'; without
    force_onsets every window is thermal."""
    import dataclasses

    from skin.drivers.sim import SkinSimulator
    from skin.formats.scene import load_scene
    from skin.models import HistogramClassifier
    from skin.stream.pipeline import Pipeline

    scene = dataclasses.replace(load_scene("default"), force="force")
    frames = list(SkinSimulator(scene, duration=8.0).frames())
    assert frames[0].force is not None

    def run(chunk: int, force_onsets: bool = True) -> list:
        pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout),
                        force_onsets=force_onsets)
        out = []
        for i in range(0, len(frames), chunk):
            out += pipe.process(frames[i:i + chunk])
        return [r.contact for r in out + pipe.flush() if r.contact.final]

    def key(contacts: list) -> list:
        return [(c.taxels, c.onset, c.release, [w.dated_by for w in c.windows])
                for c in contacts]

    a = run(1000)
    assert key(a) == key(run(7))
    assert a and all(w.dated_by == "force" for c in a for w in c.windows)
    starts = [t.start for t in scene.touches if t.start < 8.0]
    assert all(min(abs(c.onset - s) for s in starts) < 0.006 for c in a)
    assert all(w.dated_by == "thermal" for c in run(1000, False) for w in c.windows)


def test_a_force_stuck_at_its_free_level_leaves_the_taxel_to_the_detector() -> None:
    """Taxel 0's force stuck at 0 from 4 s (its readings were noisy before): a thermal onset
    there at 7.2 s is kept (it was dropped: the touch lost silently); one at 2 s, and one on a
    contact switch reading 0 throughout (no noise: not stuck), are dropped."""
    t, f = _stream(n=1000)
    f[:, 0] = np.where(t >= 4.0, 0.0, np.clip(f[:, 1], 0.001, None))
    f[:, 2] = 0.0  # a switch, open
    thermal = [OnsetEvent("onset", 0, 7.0, 7.2, 30.0, 0.0),
               OnsetEvent("onset", 0, 1.8, 2.0, 30.0, 0.0),
               OnsetEvent("onset", 2, 7.0, 7.2, 30.0, 0.0)]
    for chunk in (1, 64):
        kept = [e for e in _run(t, f, chunk, thermal) if e.dated_by == "thermal"]
        assert [(e.taxel, e.detected_at) for e in kept] == [(0, 7.2)]

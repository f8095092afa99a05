"""Streaming force-dated onsets (skin.stream.force) and their place in the pipeline."""

from __future__ import annotations

from pathlib import Path

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


#: The detector's onset of taxel 0's touch (it confirms the force's: see `_confirm`).
SEEN = [OnsetEvent("onset", 0, 5.02, 5.2, 30.0, 0.0)]


def test_force_dates_onset_and_release_exactly_and_chunk_invariant() -> None:
    t, f = _stream()
    events = _run(t, f, 1, SEEN)
    force = [e for e in events if e.dated_by == "force"]
    assert [e.kind for e in force] == ["onset", "release"]
    assert all(e.taxel == 0 for e in force)
    assert force[0].time == pytest.approx(5.003, abs=0.003)
    assert force[1].time == pytest.approx(7.0, abs=0.011)
    assert force[0].baseline == pytest.approx(30.0)
    assert not [e for e in events if e.dated_by == "thermal"]  # the detector's: replaced
    for chunk in (7, 100, 333, 5000):
        assert [(e.kind, e.taxel, e.time, e.detected_at) for e in _run(t, f, chunk, SEEN)] == \
            [(e.kind, e.taxel, e.time, e.detected_at) for e in events]


def test_a_dead_force_channel_leaves_its_taxel_to_the_detector() -> None:
    """A dead channel must not overrule the detector: a taxel's force drops the detector's
    events only once it has dated a contact (s7.py S8: a force reading 0.0 throughout lost
    both touches of taxels 0, 1, 10). The detector's events of a touch the force dates
    before it is trusted are that touch's: dropped, the force's reported."""
    t, f = _stream()
    seen = [OnsetEvent("onset", 0, 5.02, 5.2, 30.0, 0.0),
            OnsetEvent("release", 0, 7.05, 7.4, float("nan"), 0.0)]
    dead = f.copy()
    dead[:, 0] = 0.0
    out = _run(t, dead, 50, seen)
    assert [(e.kind, e.dated_by) for e in out] == [("onset", "thermal"), ("release", "thermal")]
    out = sorted(_run(t, f, 50, seen), key=lambda e: e.detected_at)
    assert [(e.kind, e.dated_by) for e in out] == [("onset", "force"), ("release", "force")]


def test_thermal_events_kept_only_where_the_force_has_no_reading() -> None:
    t, f = _stream()
    thermal = [OnsetEvent("onset", k, 8.0, 8.2, 30.0, 0.0) for k in range(3)]
    thermal.append(OnsetEvent("onset", 0, 0.3, 0.5, 30.0, 0.0))  # before its noise is known
    kept = [e for e in _run(t, f, 50, thermal + SEEN) if e.dated_by == "thermal"]
    # taxel 0's force has dated a touch and reads no contact at 8.2 s: dropped; taxel 2 has
    # no reading, taxel 1's force has dated nothing yet (a dead channel?), taxel 0's early
    # event came before its free level was known
    assert sorted((e.taxel, e.detected_at) for e in kept) == [(0, 0.5), (1, 8.2), (2, 8.2)]


def test_a_contact_switch_is_dated_between_its_samples() -> None:
    t = np.arange(600) / FS
    f = ((t > 3.004) & (t < 4.5)).astype(float)[:, None]
    events = _run(t, f, 64, [OnsetEvent("onset", 0, 3.01, 3.1, 30.0, 0.0)])
    assert [e.kind for e in events] == ["onset", "release"]
    assert events[0].time == pytest.approx(3.005, abs=0.0051)


def test_pipeline_dates_a_simulated_scene_by_its_force() -> None:
    """A scene with a force channel: skin run's contacts dated by it, within a sample."""
    from skin.bench.scene_seeds import play
    from skin.commands.bench_scene import _with_fields

    scene = _with_fields("default", {"force": "force", "sensor": None})
    try:
        on = play(scene, 31, duration=8.0, force_onsets=True)
        off = play(scene, 31, duration=8.0, force_onsets=False)
    finally:
        Path(scene).unlink()
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
    f[(t >= 1.5) & (t < 2.0), 0] += 2.0  # a touch, met by the detector: the force is trusted
    f[:, 2] = ((t >= 1.5) & (t < 2.0)).astype(float)  # a switch, the same touch, then open
    thermal = [OnsetEvent("onset", 0, 1.51, 1.6, 30.0, 0.0),
               OnsetEvent("onset", 2, 1.51, 1.6, 30.0, 0.0),
               OnsetEvent("onset", 0, 7.0, 7.2, 30.0, 0.0),
               OnsetEvent("onset", 0, 2.6, 2.8, 30.0, 0.0),
               OnsetEvent("onset", 2, 7.0, 7.2, 30.0, 0.0)]
    for chunk in (1, 64):
        kept = [e for e in _run(t, f, chunk, thermal) if e.dated_by == "thermal"]
        assert [(e.taxel, e.detected_at) for e in kept] == [(0, 7.2)]


def _pressed(start: float, end: float, n: int = 1500, seed: int = 4) -> tuple:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    f = np.round(np.clip(rng.normal(0.0, 0.005, (n, 1)), 0, None), 3)
    f[(t >= start) & (t < end), 0] += 2.0
    return t, f


def test_a_touch_begun_in_the_first_stretch_or_pressed_at_the_start_is_not_lost() -> None:
    """s1.py/s1b.py: a touch from 0.2 s (inside the first noise stretch) or from the stream's
    start made 2 N the free level and its thermal events were dropped: the touch lost, and
    the next one missed. Now the level is learnt only from quiet stretches and re-learnt
    when the force falls far under it; the detector dates that touch, the force the next."""
    for start in (0.0, 0.2):
        t, f = _pressed(start, 1.7)
        f[(t >= 6.0) & (t < 8.0), 0] += 2.0
        thermal = [OnsetEvent("onset", 0, start + 0.01, start + 0.3, 30.0, 0.0),
                   OnsetEvent("release", 0, 1.71, 2.2, float("nan"), 0.0),
                   OnsetEvent("onset", 0, 6.01, 6.2, 30.0, 0.0)]
        for chunk in (1, 50, 2000):
            out = sorted(_run(t, f, chunk, thermal), key=lambda e: e.detected_at)
            assert [(e.kind, e.dated_by) for e in out] == [
                ("onset", "thermal"), ("release", "thermal"), ("onset", "force"),
                ("release", "force")], (start, chunk)
            assert out[2].time == pytest.approx(6.0, abs=0.011)
            assert out[3].time == pytest.approx(8.0, abs=0.011)


def test_a_release_after_a_long_gap_is_dated_at_the_first_reading_after_it() -> None:
    """s10.py: pressed 3-6 s, no reading 6.02-9.0 s: the release was dated 7.55 s (chunks of
    1 or 7) or 9.1 s (100 and more) from a wrapped ring; now 9.0 s whatever the chunking."""
    t, f = _pressed(3.0, 6.0)
    f[(t >= 6.02) & (t < 9.0), 0] = np.nan
    seen = [OnsetEvent("onset", 0, 3.01, 3.2, 30.0, 0.0)]
    for chunk in (1, 7, 100, 400, 2000):
        rel = [e for e in _run(t, f, chunk, seen) if e.kind == "release"]
        assert [(e.dated_by, round(e.time, 6)) for e in rel] == [("force", 9.0)], chunk


def test_force_back_mid_contact_after_a_gap_is_no_onset() -> None:
    """s7.py S7: the force missing 0.6-1.3 s, a touch from 1.0 s: the force's return at 1.3 s
    was taken as the onset. The detector dates that touch; the force the next one."""
    t, f = _pressed(1.0, 2.5)
    f[(t >= 0.6) & (t < 1.3), 0] = np.nan
    f[(t >= 5.0) & (t < 6.0), 0] += 2.0
    thermal = [OnsetEvent("onset", 0, 1.01, 1.2, 30.0, 0.0),
               OnsetEvent("release", 0, 2.51, 2.8, float("nan"), 0.0),
               OnsetEvent("onset", 0, 5.01, 5.2, 30.0, 0.0)]
    out = _run(t, f, 20, thermal)
    assert [(e.kind, e.dated_by) for e in out] == [
        ("onset", "thermal"), ("release", "thermal"), ("onset", "force"), ("release", "force")]
    assert out[2].time == pytest.approx(5.0, abs=0.011)


def test_a_drifting_free_level_does_not_date_onsets_seconds_back() -> None:
    """s13.py: a free level drifting 0.3-1 N/min locked the taxel on and dated onsets up to
    19 s before their detection. A force-dated onset now lies after the last release and
    within the ring; a contact flat near its threshold for long is ended with a note."""
    rng = np.random.default_rng(2)
    n = 12000
    t = np.arange(n) / FS
    for drift in (0.3, 1.0):
        f = (np.round(np.clip(rng.normal(0, 0.005, (n, 1)), 0, None), 3)
             + drift / 60 * np.clip(t[:, None] - 20, 0, None))
        starts = np.arange(5.0, 120, 10)
        for s in starts:
            f[(t >= s) & (t < s + 2), 0] += 2.0
        thermal = [OnsetEvent("onset", 0, s + 0.01, s + 0.1, 30.0, 0.0) for s in starts]
        fo = ForceOnsets(1, FS)
        y = np.full_like(f, 30.0)
        out = []
        for i in range(0, n, 50):
            sl = slice(i, i + 50)
            out += fo.merge(t[sl], f[sl], y[sl],
                            [e for e in thermal if t[sl][0] <= e.detected_at <= t[sl][-1]])
        onsets = [e for e in out if e.kind == "onset" and e.dated_by == "force"]
        assert all(e.detected_at - e.time <= fo.keep / FS for e in onsets)
        found = sum(any(abs(e.time - s) < 0.05 for e in onsets) for s in starts)
        assert found >= 6, (drift, found)  # (before: 3 of 12 at 1 N/min)
        assert fo.notes


def test_bench_scene_leaves_no_temporary_scene(tmp_path, monkeypatch) -> None:
    """`skin bench scene --force-channel` wrote a copy of the scene it never removed."""
    import tempfile

    from skin.cli import main

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert main(["bench", "scene", "--seeds", "20", "--duration", "1",
                 "--force-channel", "force", "--json"]) == 0
    assert not list(tmp_path.glob("bench_scene_*"))


def test_a_force_channel_appearing_mid_stream_is_chunk_invariant() -> None:
    """s2.py: frames without force until 2.3 s: the noise stretches were counted from the first
    block with force (its start depends on the chunking: onsets differed by microseconds);
    now from the stream's first sample."""
    import dataclasses

    from skin.drivers.sim import SkinSimulator
    from skin.formats.scene import load_scene
    from skin.models import HistogramClassifier
    from skin.stream.pipeline import Pipeline

    scene = dataclasses.replace(load_scene("default"), force="force")
    frames = [dataclasses.replace(fr, force=None) if fr.device_time < 2.3 else fr
              for fr in SkinSimulator(scene, duration=8.0).frames()]

    def run(chunk: int) -> list:
        pipe = Pipeline(scene.layout, HistogramClassifier(scene.layout))
        out = []
        for i in range(0, len(frames), chunk):
            out += pipe.process(frames[i:i + chunk])
        return [(tuple(r.contact.taxels), r.contact.onset, r.contact.release,
                 tuple(w.dated_by for w in r.contact.windows))
                for r in out + pipe.flush() if r.contact.final]

    ref = run(1000)
    assert any("force" in k[3] for k in ref)
    for chunk in (1, 97, 333):
        assert run(chunk) == ref, chunk


def test_notes_name_taxels_by_their_layout_ids() -> None:
    """A dead channel's note names the taxel as the layout does (ids 100-102), not its column."""
    t, f = _stream()
    dead = f.copy()
    dead[:, 0] = 0.0
    seen = [OnsetEvent("onset", 0, 5.02, 5.2, 30.0, 0.0),
            OnsetEvent("release", 0, 7.05, 7.4, float("nan"), 0.0),
            OnsetEvent("onset", 0, 9.02, 9.2, 30.0, 0.0)]
    fo = ForceOnsets(3, FS, ids=[100, 101, 102])
    y = np.full_like(dead, 30.0)
    for i in range(0, len(t), 50):
        sel = slice(i, i + 50)
        fo.merge(t[sel], dead[sel], y[sel],
                 [e for e in seen if t[sel][0] <= e.detected_at <= t[sel][-1]])
    assert fo.unseen.tolist() == [2, 0, 0]
    assert len(fo.notes) == 1 and fo.notes[0].startswith("taxel 100: ")
    with pytest.raises(ValueError, match="2 ids for 3 taxels"):
        ForceOnsets(3, FS, ids=[1, 2])


def test_skin_run_reports_the_force_channel_in_its_summary() -> None:
    """`skin run`'s summary says which taxels their force dated (layout ids) and its notes."""
    from skin.commands.bench_scene import _with_fields
    from skin.runner import Skin

    scene = _with_fields("default", {"force": "force", "sensor": None})
    try:
        with Skin(scene=scene, seed=31, speed=0.0, duration=6.0, out=None, map=False,
                  sinks=[]) as skin:
            summary = skin.run()
            ids = set(int(i) for i in skin.layout.ids)
    finally:
        Path(scene).unlink()
    force = summary["force"]
    assert force["dated_taxels"] and set(force["dated_taxels"]) <= ids
    assert isinstance(force["notes"], list) and isinstance(force["unseen_onsets"], dict)


def _presses(inverted: bool, switch: bool = False, seed: int = 5) -> tuple:
    """Taxel 0 pressed 2 N (or a switch closed) 1.5 s from 3, 8, ..., 33 s, read inverted
    (20 N less it; an active-low switch) or not; taxel 1 never pressed; and the onset
    detector's events of each touch (onset 20 ms in, found 0.2 s in; release found late)."""
    rng = np.random.default_rng(seed)
    n = 4000
    t = np.arange(n) / FS
    starts = np.arange(3.0, 34.0, 5.0)
    pressed = np.zeros(n, dtype=bool)
    for s in starts:
        pressed |= (t >= s) & (t < s + 1.5)
    f = np.zeros((n, 2)) if switch else np.clip(rng.normal(0.0, 0.005, (n, 2)), 0, None)
    f[:, 0] += pressed * (1.0 if switch else 2.0)
    if inverted:
        f = (1.0 if switch else 20.0) - f
    thermal = [e for s in starts for e in (
        OnsetEvent("onset", 0, s + 0.02, s + 0.2, 30.0, 0.0),
        OnsetEvent("release", 0, s + 1.55, s + 1.9, float("nan"), 0.0))]
    return t, np.round(f, 3), starts, thermal


def _merged(t, f, thermal, chunk):
    fo = ForceOnsets(f.shape[1], FS, ids=[40, 41])
    y = np.full_like(f, 30.0)
    out = []
    for i in range(0, len(t), chunk):
        sel = slice(i, i + chunk)
        out += fo.merge(t[sel], f[sel], y[sel],
                        [e for e in thermal if t[sel][0] <= e.detected_at <= t[sel][-1]])
    return fo, out


@pytest.mark.parametrize("switch", [False, True])
def test_an_inverted_force_channel_is_turned_and_dates_touches_at_their_presses(switch):
    """An inverted channel (20 N at rest, 18 N pressed; an active-low switch) dated contacts at
    the touches' releases (their onsets 1.5 s late, false contacts between touches). Now its
    falls at the detector's onsets are votes against it: while they outnumber its rises its
    force dates nothing (the detector's events kept), after INVERT_VOTES it is read negated
    (a note names taxel 40) and dates the later touches at their presses."""
    t, f, starts, thermal = _presses(inverted=True, switch=switch)
    ref = None
    for chunk in (1, 7, 64, 1000):
        fo, out = _merged(t, f, thermal, chunk)
        key = sorted((e.detected_at, e.kind, e.taxel, e.time, e.dated_by) for e in out)
        assert ref is None or key == ref, chunk
        ref = key
    onsets = [e for e in out if e.kind == "onset"]
    # every touch has one onset, at its press; none at a release
    assert len(onsets) == len(starts)
    for e, s in zip(sorted(onsets, key=lambda e: e.time), starts, strict=True):
        assert e.time == pytest.approx(s, abs=0.021)
    releases = sorted(e.time for e in out if e.kind == "release")
    assert len(releases) == len(starts)
    assert all(abs(r - (s + 1.5)) <= 0.06 for r, s in zip(releases, starts, strict=True))
    from skin.stream.force import INVERT_VOTES

    by_force = [e.time for e in onsets if e.dated_by == "force"]
    # after the touch it is turned in (its third: turned mid-press, the detector's contact)
    assert len(by_force) == len(starts) - INVERT_VOTES
    assert all(abs(x - s) <= 0.011 for x, s in zip(by_force, starts[INVERT_VOTES:],
                                                     strict=True))
    assert fo.polarity.tolist() == [-1.0, 1.0]
    assert len(fo.notes) == 1 and fo.notes[0].startswith("taxel 40: its force fell at 3")


def test_a_normal_force_channel_is_not_turned():
    """The same touches read as they come: all dated by the force, no vote against it."""
    t, f, starts, thermal = _presses(inverted=False)
    fo, out = _merged(t, f, thermal, 64)
    onsets = [e for e in out if e.kind == "onset"]
    assert [e.dated_by for e in onsets] == ["force"] * len(starts)
    assert all(abs(e.time - s) <= 0.011 for e, s in zip(onsets, starts, strict=True))
    assert fo.polarity.tolist() == [1.0, 1.0] and not fo.notes
    assert fo._tally(0, t[-1]) == (len(starts), 0)


def test_a_channel_falling_at_too_few_touches_is_not_turned_but_not_trusted():
    """Two touches of an inverted channel: too few to turn it; its force dates nothing (it
    dated the second touch at the first's release, a false contact between them), the
    detector both touches."""
    t, f, _, thermal = _presses(inverted=True)
    keep = t < 12.0
    fo, out = _merged(t[keep], f[keep], [e for e in thermal if e.detected_at < 12.0], 50)
    assert [(e.kind, e.dated_by) for e in out] == [("onset", "thermal"), ("release", "thermal")] * 2
    assert fo.polarity.tolist() == [1.0, 1.0] and not fo.notes


def _repeated_scene(path: Path, inverted: bool) -> str:
    """Taxels 0-1 and 44 touched 12 times each, aluminium and pine by turns, with a force
    channel read inverted or not."""
    lines = ['name = "repeated"', 'layout = "arm"', "duration = 32.0", "seed = 3",
             'force = "force"', f"force_inverted = {'true' if inverted else 'false'}",
             '[[objects]]', 'name = "bar"', 'material = "aluminium"',
             '[[objects]]', 'name = "board"', 'material = "pine"']
    for i in range(12):
        for taxels, offset in (("[0, 1]", 1.0), ("[44]", 2.2)):
            lines += ["[[touches]]", f'object = "{("bar", "board")[i % 2]}"',
                      f"taxels = {taxels}", f"start = {offset + 2.5 * i}", "duration = 0.9"]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_skin_run_on_an_inverted_force_channel_gives_no_contact_at_releases(tmp_path) -> None:
    """skin run on a scene whose force channel is wired inverted: contacts were dated at the
    releases (false contacts between touches). Now none is false, every touch is found, the
    later ones dated by the force (at their presses) once it is turned; the notes name the
    taxels; the same scene read as it comes is dated as before."""
    from skin.bench.scene_seeds import play
    from skin.runner import Skin

    inverted = _repeated_scene(tmp_path / "inverted.toml", True)
    on = play(inverted, 3)
    off = play(inverted, 3, force_onsets=False)
    assert on["false_contacts"] == 0 and on["detected"] == on["touches"] == 24
    assert on["detected"] >= off["detected"]
    assert on["dated_by"]["force"] >= 20
    errors = np.abs([d["onset"] for d in on["dating"]])
    assert np.median(errors) <= 10.0  # ms
    normal = play(_repeated_scene(tmp_path / "normal.toml", False), 3)
    assert normal["false_contacts"] == 0 and normal["dated_by"]["thermal"] == 0
    with Skin(scene=inverted, seed=3, speed=0.0, duration=12.0, out=None, map=False,
              sinks=[]) as skin:
        notes = skin.run()["force"]["notes"]
    assert {n.split(":")[0] for n in notes if "inverted" in n} == {"taxel 0", "taxel 1",
                                                                  "taxel 44"}


def test_force_inverted_needs_a_force_channel(tmp_path, capsys) -> None:
    """The scene field and the bench's option say what is wrong."""
    from skin.cli import main
    from skin.formats.scene import SceneError, load_scene

    path = Path(_repeated_scene(tmp_path / "s.toml", True))
    assert load_scene(str(path)).force_inverted
    path.write_text(path.read_text().replace('force = "force"\n', ""))
    with pytest.raises(SceneError, match="'force_inverted' needs a force channel"):
        load_scene(str(path))
    path.write_text(path.read_text().replace("force_inverted = true", "force_inverted = 1"))
    with pytest.raises(SceneError, match="'force_inverted' must be true or false"):
        load_scene(str(path))
    assert main(["bench", "scene", "--seeds", "20", "--force-inverted"]) != 0
    assert "--force-inverted needs --force-channel" in capsys.readouterr().err

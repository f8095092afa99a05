from collections import Counter

import pytest

from skin.errors import SceneError
from skin.formats.scene import Scene, Touch, load_scene, match_touches, parse_scene

HEAD = """duration = 10.0
ambient = 25.0

[[objects]]
name = "bar"
material = "aluminium"

[[objects]]
name = "board"
material = "pine"
"""


def touch(obj: str = "bar", taxels: str = "[0, 1]", start: float = 1.0, duration: float = 1.0):
    return (
        f'\n[[touches]]\nobject = "{obj}"\ntaxels = {taxels}\n'
        f"start = {start}\nduration = {duration}\n"
    )


def touch_line(text: str, n: int) -> int:
    return [i + 1 for i, line in enumerate(text.splitlines()) if line == "[[touches]]"][n]


def scene_error(text: str) -> str:
    with pytest.raises(SceneError) as exc:
        parse_scene(text, source="s.toml")
    return str(exc.value)


@pytest.fixture(scope="module")
def default() -> Scene:
    return load_scene("default")


def test_default_materials(default):
    materials = {obj.material for obj in default.objects.values()}
    assert len(materials) >= 5
    assert {"aluminium", "pine", "glass", "neoprene", "human_skin"} <= materials


def test_default_touch_durations(default):
    assert default.touches
    for t in default.touches:
        assert 0.3 <= t.duration <= 3.0
        assert 0.0 <= t.start and t.end <= default.duration


def test_default_touches_are_sorted_and_in_layout(default):
    starts = [t.start for t in default.touches]
    assert starts == sorted(starts)
    for t in default.touches:
        for tid in t.taxels:
            default.layout.index(tid)
        assert t.object in default.objects


def test_default_has_a_multi_taxel_touch(default):
    assert max(len(t.taxels) for t in default.touches) >= 3


def test_default_touches_a_taxel_twice(default):
    counts = Counter(tid for t in default.touches for tid in t.taxels)
    assert max(counts.values()) >= 2


def test_default_human_skin_is_warm(default):
    (skin,) = [o for o in default.objects.values() if o.material == "human_skin"]
    assert skin.temperature is not None and skin.temperature > default.ambient


def test_parse_good_scene():
    text = HEAD + touch() + touch("board", "[0]", start=3.0, duration=2.0)
    scene = parse_scene(text, source="s.toml")
    assert scene.name == "s"
    assert scene.duration == 10.0
    assert len(scene.layout) == 72
    assert [t.object for t in scene.touches] == ["bar", "board"]
    assert scene.touches[0].line == touch_line(text, 0)
    assert scene.touches[1].end == 5.0
    assert scene.material_of(scene.touches[1]) == "pine"


def test_unknown_object():
    text = HEAD + touch() + touch("cup", start=5.0)
    msg = scene_error(text)
    assert f"s.toml:{touch_line(text, 1)}:" in msg
    assert "'cup'" in msg
    assert "'object'" in msg


def test_taxel_not_in_layout():
    text = HEAD + touch(taxels="[0, 500]")
    msg = scene_error(text)
    assert f"s.toml:{touch_line(text, 0)}:" in msg
    assert "500" in msg
    assert "'taxels'" in msg


def test_touch_exceeds_duration():
    text = HEAD + touch(start=9.5, duration=1.0)
    msg = scene_error(text)
    assert f"s.toml:{touch_line(text, 0)}:" in msg
    assert "10.0 s" in msg


def test_touch_starts_before_zero():
    msg = scene_error(HEAD + touch(start=-0.5))
    assert "s.toml:" in msg


def test_overlapping_touches_on_one_taxel():
    text = (
        HEAD
        + touch(taxels="[3, 4]", start=1.0, duration=2.0)
        + touch("board", "[4, 5]", start=2.5, duration=1.0)
    )
    msg = scene_error(text)
    assert f"s.toml:{touch_line(text, 1)}:" in msg
    assert f"line {touch_line(text, 0)}" in msg
    assert "taxel 4" in msg


def test_overlap_in_time_on_other_taxels_is_fine():
    text = HEAD + touch(taxels="[3]", duration=2.0) + touch("board", "[4]", start=1.5)
    assert len(parse_scene(text, source="s.toml").touches) == 2


def test_back_to_back_touches_are_fine():
    text = HEAD + touch(taxels="[3]", start=1.0, duration=1.0) + touch(taxels="[3]", start=2.0)
    assert len(parse_scene(text, source="s.toml").touches) == 2


def test_invalid_toml():
    assert scene_error("duration = \n").startswith("s.toml:")


def test_load_missing_scene(tmp_path):
    with pytest.raises(SceneError, match=r"none\.toml"):
        load_scene(tmp_path / "none.toml")


def test_match_touches():
    text = (
        HEAD
        + touch("bar", "[0, 1]", start=1.0, duration=1.0)
        + touch("board", "[10]", start=3.0, duration=1.0)
        + touch("bar", "[20]", start=6.0, duration=1.0)
    )
    scene = parse_scene(text, source="s.toml")
    contacts = [[1], [10, 11], [10], [30], [20]]
    onsets = [1.1, 3.05, 3.3, 1.0, 7.0]
    matches, unmatched = match_touches(scene, contacts, onsets, tolerance=0.5)
    assert [m.contact_index for m in matches] == [0, 1, None]
    assert [m.material for m in matches] == ["aluminium", "pine", "aluminium"]
    assert all(isinstance(m.touch, Touch) for m in matches)
    assert unmatched == [2, 3, 4]


def test_match_touches_uses_each_contact_once():
    text = HEAD + touch("bar", "[0]", start=1.0) + touch("board", "[0]", start=2.0)
    scene = parse_scene(text, source="s.toml")
    matches, unmatched = match_touches(scene, [[0]], [1.5], tolerance=0.6)
    assert [m.contact_index for m in matches] == [0, None]
    assert unmatched == []


def test_an_unknown_material_names_the_line_of_its_object(tmp_path):
    # issue 20 item 17: the simulator's check named the file and the object, not the line
    from skin.drivers.sim import SkinSimulator

    text = HEAD.replace('material = "pine"', 'material = "unobtainium"') + touch("board")
    path = tmp_path / "s.toml"
    path.write_text(text)
    line = [i + 1 for i, row in enumerate(text.splitlines()) if row == "[[objects]]"][1]
    scene = load_scene(path)
    assert scene.objects["board"].line == line
    with pytest.raises(SceneError, match=rf"s\.toml:{line}: object 'board': unknown material "
                                         r"'unobtainium'"):
        SkinSimulator(scene)


def test_a_scene_says_how_its_touches_meet_the_skin():
    """``contact``: perfect unless the scene says finite; the simulator follows it unless told."""
    from skin.drivers.sim import SkinSimulator

    assert parse_scene(HEAD + touch(), source="s.toml").contact == "perfect"
    scene = parse_scene('contact = "finite"\n' + HEAD + touch(), source="s.toml")
    assert scene.contact == "finite"
    assert SkinSimulator(scene, duration=0.0).contact == "finite"
    assert SkinSimulator(scene, duration=0.0, contact="perfect").contact == "perfect"
    msg = scene_error('contact = "sticky"\n' + HEAD + touch())
    assert "s.toml: field 'contact'" in msg and "'sticky'" in msg
    shipped = load_scene("reference-touches")
    assert shipped.contact == "finite"
    assert {o.material for o in shipped.objects.values()} == {"water", "neoprene"}
    for material in ("water", "neoprene"):  # >= 3 touches of each, with quiet before the first
        assert sum(shipped.material_of(t) == material for t in shipped.touches) >= 3
    assert shipped.touches[0].start >= 2.5 and shipped.duration <= 60.0

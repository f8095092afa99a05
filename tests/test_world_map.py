import json
import math

import numpy as np
import pytest

from skin.contact import Contact, MaterialEstimate
from skin.errors import LayoutError
from skin.formats.layout import load_layout
from skin.stream.pipeline import ContactResult
from skin.world.kinematics import (
    Chain,
    JointTrack,
    KinematicsError,
    Link,
    LinkPoseTrack,
    chain_toml,
    default_chain,
    load_chain,
    load_poses,
    parse_chain,
    transform,
)
from skin.world.map import WorldMap, WorldMapError

# ---- the chain ----

TWO_LINKS = """
name = "test"

[[links]]
name = "base"
xyz = [1.0, 0.0, 0.0]

[[links]]
name = "arm"
parent = "base"
xyz = [0.0, 0.0, 0.5]
type = "revolute"
joint = "j1"
axis = [0.0, 0.0, 1.0]

[[links]]
name = "tip"
parent = "arm"
xyz = [0.2, 0.0, 0.0]
"""


def test_a_90_degree_joint_against_hand_computed_transforms():
    chain = parse_chain(TWO_LINKS, "two.toml")
    assert chain.joints == ["j1"]
    poses = chain.poses([math.pi / 2])
    # base: translated by (1, 0, 0); arm: 0.5 above it, turned 90 deg about z
    np.testing.assert_allclose(poses["base"], transform((1.0, 0.0, 0.0)), atol=1e-12)
    expected_arm = np.array([[0.0, -1.0, 0.0, 1.0],
                             [1.0, 0.0, 0.0, 0.0],
                             [0.0, 0.0, 1.0, 0.5],
                             [0.0, 0.0, 0.0, 1.0]])
    np.testing.assert_allclose(poses["arm"], expected_arm, atol=1e-12)
    # the tip, 0.2 along the arm's x, now lies along world y
    np.testing.assert_allclose(poses["tip"][:3, 3], [1.0, 0.2, 0.5], atol=1e-12)
    # by name, and the default (0) leaves the tip along world x
    np.testing.assert_allclose(chain.poses({"j1": math.pi / 2})["tip"], poses["tip"])
    np.testing.assert_allclose(chain.poses()["tip"][:3, 3], [1.2, 0.0, 0.5], atol=1e-12)


def test_default_chain_elbow_bends_the_forearm_about_the_elbow():
    chain = default_chain()
    assert chain.joints == ["shoulder", "elbow", "wrist"]
    zero, bent = chain.poses(), chain.poses({"elbow": math.radians(60.0)})
    # the elbow itself does not move; the forearm's axis turns 60 deg about the world's y
    np.testing.assert_allclose(bent["forearm"][:3, 3], zero["forearm"][:3, 3], atol=1e-12)
    cos = float(zero["forearm"][:3, 2] @ bent["forearm"][:3, 2])
    assert cos == pytest.approx(0.5)
    # a quarter turn of the shoulder takes the upper arm from world +x to world +y
    turned = chain.poses({"shoulder": math.pi / 2})
    np.testing.assert_allclose(turned["upper_arm"][:3, 2], [0.0, 1.0, 0.0], atol=1e-12)


def test_default_chain_reproduces_the_default_arm_of_the_view():
    pytest.importorskip("pyvista")
    from skin.viz.arm import default_arm

    poses = default_chain().poses()
    arm = default_arm()
    assert {"upper_arm", "forearm"} <= set(arm)
    for name, geo in arm.items():
        assert name in poses, f"the default chain has no link {name!r}"
        np.testing.assert_allclose(poses[name], geo.pose, atol=1e-12, err_msg=name)


def test_chain_toml_round_trips(tmp_path):
    chain = default_chain()
    path = tmp_path / "chain.toml"
    path.write_text(chain_toml(chain))
    back = load_chain(path)
    q = [0.3, -0.4, 0.2]
    for name, pose in chain.poses(q).items():
        np.testing.assert_allclose(back.poses(q)[name], pose, atol=1e-11)


@pytest.mark.parametrize(("text", "pattern"), [
    ('[[links]]\nname = "a"\n\n[[links]]\nname = "b"\nparent = "c"\n',
     r"bad\.toml:4: link 'b': field 'parent' names 'c'"),
    ('[[links]]\nname = "a"\n\n[[links]]\nname = "b"\nparent = "a"\ntype = "revolute"\n',
     r"bad\.toml:4: link 'b': missing field 'axis'"),
    ('[[links]]\nname = "a"\n\n[[links]]\nname = "b"\nparent = "a"\ntype = "prismatic"\n',
     r"bad\.toml:4: link 'b': field 'type' must be one of revolute, fixed"),
    ('[[links]]\nname = "a"\nxyz = [1, 2]\n', r"bad\.toml:1: link 'a': field 'xyz'"),
    ('[[links]]\nname = "a"\ncolour = "red"\n', r"bad\.toml:1: link 'a': unknown field 'colour'"),
    ('[[links]]\nname = "a"\n\n[[links]]\nname = "a"\n',
     r"bad\.toml:4: link 'a': duplicate link name \(first on line 1\)"),
    ('[[links]]\nname = "a"\nparent = "b"\n\n[[links]]\nname = "b"\nparent = "a"\n',
     r"bad\.toml:\d: link '[ab]': its parents form a cycle"),
    ('[[links]]\nname = "a"\n\n[[links]]\nname = "b"\nparent = "a"\ntype = "revolute"\n'
     'axis = [0, 0, 1]\nlimits_deg = [10, -10]\n', r"bad\.toml:4: link 'b': field 'limits_deg'"),
    ('[[links]]\nname = "a"\n\n[[links]]\nname = "b"\nparent = "a"\ntype = "revolute"\n'
     'axis = [0, 0, 0]\n', r"bad\.toml:4: link 'b': field 'axis' must not be zero"),
    ("links = 3\n", r"bad\.toml: no links"),
])
def test_chain_file_errors_name_the_file_line_and_link(text, pattern):
    with pytest.raises(KinematicsError, match=pattern):
        parse_chain(text, "bad.toml")


def test_joint_limits_and_wrong_angle_counts_are_named():
    chain = default_chain()
    with pytest.raises(KinematicsError, match=r"joint 'wrist' .* outside its limits"):
        chain.poses({"wrist": math.radians(120.0)})
    with pytest.raises(KinematicsError, match="2 joint angles given, the chain has 3"):
        chain.poses([0.0, 0.0])
    with pytest.raises(KinematicsError, match="no joint named 'knee'"):
        chain.poses({"knee": 0.0})


# ---- poses over time ----

def test_joint_angles_are_interpolated_at_a_time(tmp_path):
    chain = default_chain()
    path = tmp_path / "poses.csv"
    path.write_text("# shoulder sweep\ntime,shoulder\n0.0,0.0\n2.0,1.0\n")
    track = load_poses(path, chain)
    assert isinstance(track, JointTrack)
    assert track.angles_at(0.5)["shoulder"] == pytest.approx(0.25)
    np.testing.assert_allclose(track.poses_at(0.5)["forearm"],
                               chain.poses({"shoulder": 0.25})["forearm"], atol=1e-12)
    # just past the end: the last pose; well past it: an error naming the span
    assert track.angles_at(2.05)["shoulder"] == pytest.approx(1.0)
    with pytest.raises(KinematicsError, match=r"no pose at t = 5 s: the poses cover 0 to 2 s"):
        track.poses_at(5.0)
    npz = tmp_path / "poses.npz"
    np.savez(npz, time=[0.0, 2.0], joints=np.array(["elbow"]), q=[[0.0], [0.4]])
    assert load_poses(npz, chain).angles_at(1.0)["elbow"] == pytest.approx(0.2)


def test_link_poses_are_interpolated_with_slerp(tmp_path):
    a = transform((0.0, 0.0, 0.0))
    b = transform((1.0, 0.0, 0.0), (0.0, 0.0, math.pi / 2))
    path = tmp_path / "links.npz"
    np.savez(path, time=[0.0, 1.0], links=np.array(["upper_arm"]),
             poses=np.stack([a, b])[:, None])
    track = load_poses(path)
    assert isinstance(track, LinkPoseTrack)
    mid = track.poses_at(0.5)["upper_arm"]
    np.testing.assert_allclose(mid, transform((0.5, 0.0, 0.0), (0.0, 0.0, math.pi / 4)),
                               atol=1e-12)


@pytest.mark.parametrize(("content", "pattern"), [
    ("time,elbow\n0,0\n0,1\n", r"times must increase: sample 1"),
    ("time,knee\n0,0\n", r"column 'knee' is not a joint"),
    ("time,elbow\n0,0\n1,x\n", r"poses\.csv:3: not a number"),
    ("t,elbow\n0,0\n", r"the header must be 'time,<joint>,...'"),
])
def test_pose_file_errors_name_the_file(tmp_path, content, pattern):
    path = tmp_path / "poses.csv"
    path.write_text(content)
    with pytest.raises(KinematicsError, match=pattern):
        load_poses(path)


# ---- the world map ----

def _event(taxels, onset=1.0, label="aluminium", contact=0, final=True):
    return {"contact": contact, "taxels": taxels, "onset": onset, "label": label,
            "confidence": 0.9, "final": final}


def test_world_points_of_a_taxel_are_its_hand_transformed_position():
    layout = load_layout("arm")
    chain = default_chain()
    # taxel 0: upper arm, (0.055, 0, 0.075) in its frame; taxel 44 is on the forearm
    q = {"shoulder": math.pi / 2, "elbow": 0.0}
    wm = WorldMap.from_events([_event([0]), _event([44], contact=1, label="pine")], layout,
                              StaticPosesOf(chain, q))
    assert len(wm) == 2
    # the upper arm turned to world +y: its x axis is world -z still, its y axis is world -x
    np.testing.assert_allclose(wm.points[0], [0.0, 0.075, -0.055], atol=1e-12)
    np.testing.assert_allclose(wm.normals[0], [0.0, 0.0, -1.0], atol=1e-12)
    k = layout.index(44)
    pose = chain.poses(q)["forearm"]
    np.testing.assert_allclose(wm.points[1], pose[:3, :3] @ layout.positions[k] + pose[:3, 3])
    assert list(wm.taxel) == [0, 44] and list(wm.contact) == [0, 1]
    assert list(wm.label) == ["aluminium", "pine"]
    assert wm.confidence[0] == pytest.approx(0.9) and wm.time[1] == pytest.approx(1.0)
    assert wm.counts() == {"aluminium": 1, "pine": 1}


class StaticPosesOf:
    def __init__(self, chain, q):
        self.chain, self.q = chain, q

    def poses_at(self, t):
        return self.chain.poses(self.q)


def test_world_points_follow_the_poses_at_each_contacts_onset():
    layout = load_layout("arm")
    chain = default_chain()
    track = JointTrack(chain, [0.0, 10.0], [[0.0], [math.pi]], joints=["shoulder"])
    wm = WorldMap.from_events([_event([0], onset=5.0), _event([0], onset=20.0, contact=1)],
                              layout, track)
    expected = chain.poses({"shoulder": math.pi / 2})["upper_arm"]
    np.testing.assert_allclose(wm.points[0], expected[:3, :3] @ layout.positions[0]
                               + expected[:3, 3], atol=1e-12)
    # the second contact has no pose: skipped and said why
    assert len(wm) == 1 and len(wm.skipped) == 1 and "20 s" in wm.skipped[0]


def test_results_provisional_answers_and_unknown_taxels():
    layout = load_layout("arm")
    contact = Contact(id=3, taxels=[10, 11], onset=2.0, release=3.0, ambient=25.0, windows=[])
    estimate = MaterialEstimate("glass", {"glass": 0.8}, 0.8, 1400.0, "joint")
    wm = WorldMap(layout)
    wm.write(ContactResult(contact, estimate, 3.1))
    assert wm.add(_event([5], final=False)) == 0  # a provisional answer: its final one follows
    assert list(wm.taxel) == [10, 11] and set(wm.label) == {"glass"}
    with pytest.raises(LayoutError, match=r"ev\.jsonl:7: .*no taxel with id 999"):
        wm.add(_event([999]), where="ev.jsonl:7")
    with pytest.raises(WorldMapError, match="x: field 'taxels'"):
        wm.add({**_event([1]), "taxels": "1"}, where="x")
    one_link = Chain([Link("upper_arm", None, np.eye(4))])
    with pytest.raises(KinematicsError, match="taxel 44 is on link 'forearm', which has no pose"):
        WorldMap.from_events([_event([44])], layout, one_link)


@pytest.mark.parametrize("suffix", [".npz", ".jsonl"])
def test_save_and_load_round_trip(tmp_path, suffix):
    layout = load_layout("arm")
    wm = WorldMap.from_events([_event([0, 1, 10]), _event([44], 2.5, "unknown", 1),
                               _event([60], 3.0, "human_skin", 2)], layout,
                              default_chain())
    path = wm.save(tmp_path / f"map{suffix}")
    back = WorldMap.load(path)
    assert len(back) == len(wm) == 5
    for key in ("points", "normals", "contact", "taxel", "confidence", "time"):
        np.testing.assert_array_equal(getattr(back, key), getattr(wm, key), err_msg=key)
    assert list(back.label) == list(wm.label) and list(back.link) == list(wm.link)
    assert back.counts() == {"aluminium": 3, "human_skin": 1, "unknown": 1}
    empty = WorldMap().save(tmp_path / f"empty{suffix}")
    assert len(WorldMap.load(empty)) == 0


def test_loading_something_else_is_named(tmp_path):
    bad = tmp_path / "x.npz"
    np.savez(bad, points=np.zeros((1, 3)))
    with pytest.raises(WorldMapError, match=r"x\.npz: not a world map"):
        WorldMap.load(bad)
    lines = tmp_path / "x.jsonl"
    lines.write_text(json.dumps({"format": "thermoskin.world_map/1", "point": [0, 0]}) + "\n")
    with pytest.raises(WorldMapError, match=r"x\.jsonl:1:"):
        WorldMap.load(lines)
    with pytest.raises(WorldMapError, match=r"\.npz or \.jsonl"):
        WorldMap().save(tmp_path / "map.csv")


# ---- skin run -> skin view --map ----

@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    from skin.cli import main

    out = tmp_path_factory.mktemp("wm") / "run"
    assert main(["run", "--speed", "0", "--duration", "5", "--out", str(out), "--no-map",
                 "--record", str(out.parent / "run.mcap"), "--json"]) == 0
    return out


def test_skin_run_saves_what_a_world_map_needs(run_dir):
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["layout"] == "layout.toml" and summary["chain"] == "chain.toml"
    assert len(load_layout(run_dir / "layout.toml")) == 72
    still = load_chain(run_dir / "chain.toml").poses()
    for name, pose in default_chain().poses().items():
        np.testing.assert_allclose(still[name], pose, atol=1e-12)
    wm = WorldMap.from_run(run_dir)
    events = [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()]
    assert len(wm) == sum(len(ev["taxels"]) for ev in events if ev["final"]) > 0
    assert wm.notes == [f"poses: {run_dir / 'chain.toml'} at its default angles"]
    # the recording of the same run gives the same map
    rec = WorldMap.from_recording(run_dir.parent / "run.mcap")
    np.testing.assert_allclose(np.sort(rec.points, axis=0), np.sort(wm.points, axis=0))


def test_skin_view_map_writes_a_png_with_the_materials_colours(run_dir, tmp_path, capsys):
    pytest.importorskip("pyvista")
    from PIL import Image

    from skin.cli import main
    from skin.models import load_materials
    from skin.viz.arm import UNKNOWN_COLOUR, hex_rgb

    png = tmp_path / "map.png"
    assert main(["view", "--map", str(run_dir), "--out", str(png), "--save",
                 str(tmp_path / "map.npz")]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    wm = WorldMap.load(tmp_path / "map.npz")
    assert line.startswith(f"world map: {len(wm)} points from {wm.contacts()} contacts (")
    for name, n in wm.counts().items():
        assert f"{name} {n}" in line
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    colours = {m.name: m.colour for m in load_materials().values()}
    half = img.shape[1] // 2
    for label in wm.counts():
        colour = UNKNOWN_COLOUR if label == "unknown" else colours[label]
        near = np.abs(img - hex_rgb(colour).astype(int)).max(axis=-1) <= 20
        # the back view has no legend: its pixels of the colour are the points' own; the
        # unknown look is dark grey, as the edges of text are (about 50 pixels a view)
        least = 150 if label == "unknown" else 1
        assert near[:, half:].sum() >= least, f"no point of {label} in the back view"
        assert near[:, :half].sum() >= least, f"no point of {label} in the front view"


def test_skin_view_without_a_display_says_so(run_dir, monkeypatch, capsys):
    pytest.importorskip("pyvista")
    from skin.cli import main

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", "--map", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert "cannot open a window" in err and "--out" in err


def test_skin_view_with_poses_over_time(run_dir, tmp_path, capsys):
    pytest.importorskip("pyvista")
    from skin.cli import main

    poses = tmp_path / "poses.csv"
    poses.write_text("time,shoulder\n0,0\n10,1.0\n")
    assert main(["view", "--map", str(run_dir), "--poses", str(poses), "--out",
                 str(tmp_path / "m.png"), "--save", str(tmp_path / "m.jsonl"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    moved, still = WorldMap.load(tmp_path / "m.jsonl"), WorldMap.from_run(run_dir)
    assert summary["points"] == len(moved) == len(still)
    # each point turned about the vertical by its onset's shoulder angle (0.1 rad per s)
    for k in range(len(moved)):
        a = 0.1 * moved.time[k]
        rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        np.testing.assert_allclose(moved.points[k], rz @ still.points[k], atol=1e-9)

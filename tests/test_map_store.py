"""The shared map's store (skin.world.map_store): placing, fusing, persisting, box queries."""

import json
import math
import sqlite3

import numpy as np
import pytest

from skin.errors import SkinError
from skin.world.kinematics import default_chain, transform
from skin.world.map_store import (
    MapInputError,
    MapStore,
    MapStoreError,
    parse_box,
    place,
    posterior_of,
)


def contact(k=1, robot="a", probs=None, centroid=(0.0, 0.0, 0.0), **extra):
    msg = {"schema": "thermoskin.contact", "version": 1, "robot": robot, "contact": k,
           "onset": 1.0 + k, "host_onset": 1.7e9 + k, "final": True, "decided_at": 2.0 + k,
           "probabilities": {"aluminium": 0.9, "pine": 0.1} if probs is None else probs,
           "link": "forearm", "centroid": list(centroid), "host_decided_at": 1.7e9 + k + 1}
    msg.update(extra)
    return msg


def test_position_is_robot_pose_times_link_pose_times_centroid():
    robot = transform((1.0, 2.0, 0.5), (0.0, 0.0, math.pi / 2))
    link = transform((0.1, 0.0, 0.3), (0.2, 0.0, 0.0))
    msg = contact(centroid=(0.05, 0.01, 0.02), robot_pose=robot.tolist(), link_pose=link.tolist())
    p = place(msg, 0.01)
    want = robot @ link @ np.array([0.05, 0.01, 0.02, 1.0])
    assert np.allclose(p.position, want[:3])
    assert p.cell == tuple(math.floor(v / 0.01) for v in want[:3])
    # without poses: the default arm standing still, the robot at the map's origin
    q = place(contact(centroid=(0.05, 0.01, 0.02)), 0.01)
    want = default_chain().poses()["forearm"] @ np.array([0.05, 0.01, 0.02, 1.0])
    assert np.allclose(q.position, want[:3])


@pytest.mark.parametrize("change, words", [
    ({"schema": "thermoskin.health"}, "not a thermoskin.contact"),
    ({"robot": ""}, "'robot'"),
    ({"robot": "a/b"}, "'robot'"),
    ({"link_pose": [["x"] * 4] * 4}, "'link_pose'"),
    ({"contact": "7"}, "'contact'"),
    ({"centroid": [0, 1]}, "'centroid'"),
    ({"centroid": [0, float("nan"), 1]}, "'centroid'"),
    ({"host_onset": None, "onset": None}, "'onset'"),
    ({"link": "tentacle"}, "link 'tentacle' has no pose"),
    ({"link_pose": [[1, 0], [0, 1]]}, "'link_pose'"),
    ({"robot_pose": (2 * np.eye(4)).tolist()}, "not a rigid transform"),
    ({"probabilities": {"aluminium": 1.5}}, "probability of 'aluminium'"),
    ({"probabilities": [0.5]}, "'probabilities'"),
])
def test_malformed_contacts_are_named(change, words):
    with pytest.raises(MapInputError, match=words):
        place(contact(**change), 0.01)


def test_a_contact_counts_once_and_a_final_result_replaces_the_provisional(tmp_path):
    store = MapStore(tmp_path / "m.sqlite")
    assert len(store.add(contact(1)).stored) == 1
    assert store.add(contact(1)).duplicates == 1  # re-sent after a reconnect
    assert store.stats()["contacts"] == 1
    # provisional, then its final answer: counted once, with the final evidence
    store.add(contact(2, probs={"pine": 0.9, "aluminium": 0.1}, final=False, decided_at=3.0))
    r = store.add(contact(2, probs={"aluminium": 0.9, "pine": 0.1}, final=True, decided_at=4.0))
    assert r.replaced == 1
    (v,) = store.query((-1, -1, -1, 2, 2, 2))
    assert v.contacts == 2 and v.label == "aluminium"
    assert v.posterior["aluminium"] == pytest.approx(0.81 / (0.81 + 0.01))
    # a provisional placed elsewhere, then its final answer: the first voxel is empty again
    store.add(contact(9, final=False, decided_at=3.0, centroid=(0.5, 0.5, 0.5),
                      link_pose=np.eye(4).tolist()))
    assert len(store.query((0.4, 0.4, 0.4, 0.6, 0.6, 0.6))) == 1
    store.add(contact(9, final=True, decided_at=4.0, centroid=(0.7, 0.5, 0.5),
                      link_pose=np.eye(4).tolist()))
    assert [v.cell for v in store.query((0.4, 0.4, 0.4, 0.8, 0.6, 0.6))] == [(70, 50, 50)]
    store.db.execute("DELETE FROM contacts WHERE contact=9")  # (back to the case below)
    store.db.execute("DELETE FROM voxel_box WHERE id IN (SELECT id FROM voxels WHERE ix >= 50)")
    store.db.execute("DELETE FROM evidence WHERE voxel IN (SELECT id FROM voxels WHERE ix >= 50)")
    store.db.execute("DELETE FROM voxels WHERE ix >= 50")
    # an older provisional arriving late changes nothing
    assert store.add(contact(2, probs={"pine": 1.0}, final=False, decided_at=3.5)).duplicates == 1
    assert store.stats() == {"voxels": 1, "contacts": 2, "robots": {"a": 2}, "voxel": 0.01,
                             "index": "rtree", "robot_poses": {"a": None}}
    # the same contact id from another robot, or another onset, is another contact
    pose = transform((1.0, 2.0, 0.0), (0.0, 0.0, 0.3))
    store.add(contact(1, robot="b", robot_pose=pose.tolist()))
    store.add(contact(7, robot="b"))  # without a pose: the last one given is kept
    assert np.allclose(store.robot_poses()["b"], pose)
    store.add(contact(1, host_onset=1.8e9))
    assert store.stats()["contacts"] == 5
    assert store.acks("a") == [[1, 1.7e9 + 1, True], [2, 1.7e9 + 2, True], [1, 1.8e9, True]]
    assert store.query((-1, -1, -1, 2, 2, 2))[0].robots == ["a", "b"]  # b's 7: default pose


def test_posterior_names_material_family_or_unknown(tmp_path):
    store = MapStore(tmp_path / "m.sqlite", threshold=0.5)
    at = {"centroid": (0.0, 0.0, 0.0)}
    store.add(contact(1, probs={"aluminium": 0.45, "steel": 0.45, "pine": 0.1}, **at))
    (v,) = store.query((-1, -1, -1, 2, 2, 2))
    assert v.label == "unknown" and v.family == "metal"
    assert v.family_confidence == pytest.approx(0.9, abs=1e-3)
    # no probabilities at all: counted, but unknown
    store.add(contact(2, probs={}, centroid=(0.0, 0.0, 0.5)))
    far = store.query((-1, -1, -1, 2, 2, 2), family="unknown")
    assert [x.contacts for x in far] == [1] and far[0].posterior == {}
    assert posterior_of({}, 0) == {}
    # a material one contact did not name counts at the floor, not as certain absence
    p = posterior_of({"glass": (math.log(0.5), 1), "pine": (math.log(0.5) * 2, 2)}, 2)
    assert p["pine"] > p["glass"] > 0


def test_box_query_matches_a_brute_force_filter(tmp_path):
    store = MapStore(tmp_path / "m.sqlite", voxel=0.05)
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1, 1, (300, 3))
    for k, pt in enumerate(pts):
        store.add(contact(k, link_pose=np.eye(4).tolist(), centroid=pt))
    box = (-0.3, -0.5, -0.2, 0.4, 0.25, 0.6)
    got = {v.cell for v in store.query(box)}
    cells = {tuple(math.floor(x / 0.05) for x in pt) for pt in pts}
    lo = [math.floor(b / 0.05) for b in box[:3]]
    hi = [math.floor(b / 0.05) for b in box[3:]]
    want = {c for c in cells if all(lo[i] <= c[i] <= hi[i] for i in range(3))}
    assert got == want and len(want) > 5
    assert len(store.query(box, limit=3)) == 3
    assert {v.cell for v in store.query(box[3:] + box[:3])} == want  # corners in any order
    assert store.query((5, 5, 5, 6, 6, 6)) == []


def test_the_map_persists_and_keeps_its_voxel_size(tmp_path):
    path = tmp_path / "m.sqlite"
    with MapStore(path, voxel=0.02) as store:
        store.add(contact(1))
    with MapStore(path) as again:
        assert again.voxel == 0.02 and again.stats()["contacts"] == 1
    with pytest.raises(MapStoreError, match=r"0\.02 m voxels, not 0\.01"):
        MapStore(path, voxel=0.01)
    bad = tmp_path / "other.sqlite"
    bad.write_bytes(b"this is not a database" * 100)
    with pytest.raises(MapStoreError, match="not a map database"):
        MapStore(bad)
    other = tmp_path / "foreign.sqlite"
    db = sqlite3.connect(other)
    db.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
    db.execute("INSERT INTO meta VALUES ('format', 'someone.else/3')")
    db.commit()
    db.close()
    with pytest.raises(MapStoreError, match=r"someone\.else/3"):
        MapStore(other)
    with pytest.raises(MapStoreError, match="no such folder"):
        MapStore(tmp_path / "missing" / "m.sqlite")


@pytest.mark.parametrize("text", ["1,2,3", "a,b,c,d,e,f", "0,0,0,1,1,inf", "1,2,3,4,5,6,7"])
def test_bad_boxes_are_named(text):
    with pytest.raises(SkinError, match="x0,y0,z0,x1,y1,z1"):
        parse_box(text)


def test_box_corners_are_ordered():
    assert parse_box("1,0,2,0,1,1") == (0.0, 0.0, 1.0, 1.0, 1.0, 2.0)


def test_each_voxel_is_named_by_the_per_voxel_rule(tmp_path):
    from skin.models.materials import hierarchical_answer

    store = MapStore(tmp_path / "m.sqlite", voxel=0.1)
    rng = np.random.default_rng(5)
    names = ["aluminium", "steel", "glass", "pine", "oak", "foam"]
    for k in range(200):
        p = rng.dirichlet(np.full(len(names), 0.3))
        named = {m: round(float(x), 4) for m, x in zip(names, p, strict=True) if rng.random() < 0.8}
        store.add(contact(k, probs=named, link_pose=np.eye(4).tolist(),
                          centroid=rng.uniform(0, 0.3, 3)))
    voxels = store.query((0, 0, 0, 0.3, 0.3, 0.3))
    assert sum(v.contacts for v in voxels) == 200
    for v in voxels:
        informed, text = store.db.execute(
            "SELECT informed, evidence FROM voxels JOIN evidence ON voxel = id "
            "WHERE ix=? AND iy=? AND iz=?",
            v.cell).fetchone()
        ev = {m: tuple(x) for m, x in json.loads(text).items()}
        want = posterior_of(ev, informed)
        assert v.posterior == pytest.approx(want, abs=1e-6)
        if want:
            label, conf, fam, fam_conf = hierarchical_answer(want, 0.5)
            assert (v.label, v.family) == (label, fam)
            assert (v.confidence, v.family_confidence) == pytest.approx((conf, fam_conf))
        else:
            assert v.label == v.family == "unknown"


def test_rows_as_json_text_equal_the_voxels(tmp_path):
    store = MapStore(tmp_path / "m.sqlite")
    for k in range(20):
        store.add(contact(k, centroid=(0.01 * k, 0.0, 0.0), probs={"glass": 0.7, "oak": 0.3}))
    box = (-1, -1, -1, 1, 1, 1)
    text = store.rows_json(store.rows(box))
    assert json.loads(text) == [json.loads(json.dumps(v.as_dict())) for v in store.query(box)]
    assert [v.label for v in store.query(box, material="glass")] == ["glass"] * len(
        store.query(box))
    assert store.query(box, family="metal") == []


def test_query_json_by_sqlite_equals_the_python_rows(tmp_path):
    store = MapStore(tmp_path / "m.sqlite", voxel=0.02)
    for k in range(40):
        store.add(contact(k, robot="ab"[k % 2], centroid=(0.013 * k, -0.01 * k, 0.0),
                          probs={"glass": 0.6, "oak": 0.3, "steel": 0.1}))
    box = (-1, -1, -1, 1, 1, 1)
    want = [json.loads(json.dumps(v.as_dict())) for v in store.query(box)]
    assert store.json_sql  # SQLite >= 3.38 has its JSON functions built in
    for use_sql in (True, False):
        store.json_sql = use_sql
        got = json.loads(store.query_json(box))
        assert len(got) == len(want) > 10
        for g, w in zip(got, want, strict=True):
            assert g.keys() == w.keys()
            for key in w:
                assert g[key] == pytest.approx(w[key]), (use_sql, key)
        assert len(json.loads(store.query_json(box, limit=4))) == 4
        assert json.loads(store.query_json(box, family="metal")) == []
        assert json.loads(store.query_json((5, 5, 5, 6, 6, 6))) == []

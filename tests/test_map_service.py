"""The shared map service on real Zenoh (localhost, explicit TCP endpoints, no multicast).

Three publisher processes (the real ZenohPublisher, `python -m skin.bench.map`) and one
`skin map serve`; a SIGKILLed service restarted with every acknowledged contact kept and the
publisher reconnecting to it; a publisher process re-sending contacts; malformed payloads.
"""

import contextlib
import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from skin.bench.map import free_port, start_service

pytest.importorskip("zenoh")

SKIN = Path(sys.executable).with_name("skin")


def publisher(port, robot, *extra, prefix="t"):
    return subprocess.Popen(
        [sys.executable, "-m", "skin.bench.map", "--prefix", prefix, "--robot", robot,
         "--connect", f"tcp/127.0.0.1:{port}", "--taxels", "64", "--wait", "0.5", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finished(proc, timeout=30):
    out, err = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, err
    return json.loads(out.strip().splitlines()[-1])


@contextlib.contextmanager
def in_process_service(db, port):
    """The map service in this process (the subprocess tests run `skin map serve` itself)."""
    from skin.world.map_service import MapService

    with MapService(db, prefix="t", listen=[f"tcp/127.0.0.1:{port}"]) as service:
        yield service


def wait_for(predicate, timeout=10.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    return predicate()


def test_three_robots_one_service_and_queries(tmp_path):
    from skin.world.shared_map import SharedMap

    port = free_port()
    url = f"zenoh://t?connect=tcp/127.0.0.1:{port}"
    with in_process_service(tmp_path / "map.sqlite", port):
        procs = [publisher(port, f"r{i}", "--count", "25", "--spacing", "0.01", "--seed", str(i),
                           "--pose", f"{3.0 * i},0,0,0,0,{0.5 * i}") for i in range(3)]
        sent = [finished(p) for p in procs]
        assert [s["published"] for s in sent] == [25, 25, 25]
        with SharedMap(url) as shared:
            held = wait_for(lambda: all(len(shared.acks(f"r{i}")) == 25 for i in range(3)))
            assert held, {f"r{i}": len(shared.acks(f"r{i}")) for i in range(3)}
            # each robot stands 3 m further along x: its voxels are in its own box
            for i in range(3):
                mine = shared.query((3.0 * i - 1, -1, -1, 3.0 * i + 1, 1, 1))
                assert sum(v["contacts"] for v in mine) == 25
                assert {r for v in mine for r in v["robots"]} == {f"r{i}"}
            everything = shared.query("-5,-5,-5,10,5,5")
            assert sum(v["contacts"] for v in everything) == 75
            steel = shared.query("-5,-5,-5,10,5,5", material="steel")
            assert steel and all(v["label"] == "steel" for v in steel)
            metal = shared.query("-5,-5,-5,10,5,5", family="metal")
            assert {v["label"] for v in metal} >= {"steel", "aluminium"}
            assert shared.stats()["contacts"] == 75
            with pytest.raises(Exception, match="needs robot=NAME"):
                shared._get("acks", {})
        # the command line, over Zenoh and on the file; a bad box is named before any session
        out = subprocess.run([str(SKIN), "map", "query", "--map", url, "--box=-5,-5,-5,10,5,5",
                              "--json"], capture_output=True, text=True, timeout=30)
        assert out.returncode == 0, out.stderr
        assert json.loads(out.stdout)["count"] == len(everything)
        out = subprocess.run([str(SKIN), "map", "query", "--map", str(tmp_path / "map.sqlite"),
                              "--box=-5,-5,-5,10,5,5", "--material", "steel"],
                             capture_output=True, text=True, timeout=30)
        assert out.returncode == 0 and f"{len(steel)} voxels in" in out.stdout
        bad = subprocess.run([str(SKIN), "map", "query", "--map", url, "--box", "0,0,1"],
                             capture_output=True, text=True, timeout=30)
        assert bad.returncode == 2 and "box '0,0,1': six" in bad.stderr
        # the shared map drawn around robot r1's arm, at its pose (x = 3 m, yaw 0.5 rad)
        if importlib.util.find_spec("pyvista") is not None:
            png = tmp_path / "view.png"
            out = subprocess.run([str(SKIN), "view", "--map", url, "--robot", "r1", "--out",
                                  str(png), "--json"], capture_output=True, text=True,
                                 timeout=120)
            assert out.returncode == 0, out.stderr
            drawn = json.loads(out.stdout)
            assert drawn["robot"] == "r1" and drawn["box"][0] == pytest.approx(1.5)
            mine = [v for v in everything if v["robots"] == ["r1"]]
            assert drawn["contacts"] == sum(v["contacts"] for v in mine) == 25
            assert drawn["voxels"] == len(mine) and png.stat().st_size > 10_000


def test_malformed_payloads_are_counted_and_skipped(tmp_path):
    from skin.stream.publish_zenoh import open_session
    from skin.world.shared_map import SharedMap

    port = free_port()
    service = start_service(tmp_path / "map.sqlite", port, "t")
    url = f"zenoh://t?connect=tcp/127.0.0.1:{port}"
    session = open_session(connect=[f"tcp/127.0.0.1:{port}"])
    try:
        time.sleep(0.5)
        good = {"schema": "thermoskin.contact", "version": 1, "robot": "x", "contact": 1,
                "onset": 1.0, "host_onset": 1.7e9, "final": True, "decided_at": 1.5,
                "probabilities": {"glass": 0.8, "pine": 0.2}, "link": "forearm",
                "centroid": [0, 0, 0]}
        for payload in (b"\xff\x00 not json", b"[1, 2]", json.dumps(dict(good, centroid="up")),
                        json.dumps(dict(good, robot="y")),  # on robot x's key
                        json.dumps(dict(good, link="tentacle")), json.dumps(good)):
            session.put("t/x/contacts", payload)
        with SharedMap(url) as shared:
            # the service counts a payload received before its batch is stored: wait for both
            stats = wait_for(lambda: (s := shared.stats())["received"] == 6
                             and s["malformed"] + s["contacts"] == 6 and s)
            assert stats["malformed"] == 5 and stats["contacts"] == 1
            assert shared.acks("x") == [[1, 1.7e9, True]]
            with pytest.raises(Exception, match="six finite numbers"):
                shared._get("voxels", {"box": "1,2,3"})
            with pytest.raises(Exception, match="unknown map key 'colour'"):
                shared._get("colour", {})
        assert service.poll() is None  # still serving
    finally:
        session.close()
        service.terminate()
        service.wait(timeout=20)


def test_killed_service_keeps_every_acknowledged_contact_and_publishers_reconnect(tmp_path):
    from skin.stream.publish_zenoh import open_session

    port = free_port()
    db = tmp_path / "map.sqlite"
    service = start_service(db, port, "t")
    acked: set = set()
    listener = open_session(connect=[f"tcp/127.0.0.1:{port}"])

    def on_ack(sample):
        msg = json.loads(sample.payload.to_bytes())
        acked.update((msg["robot"], c, o) for c, o in msg["contacts"])

    sub = listener.declare_subscriber("t/map/acks/*", on_ack)
    # one robot publishing all along (a contact every 20 ms, for 6 s)
    pub = publisher(port, "arm", "--count", "300", "--spacing", "0.02")
    try:
        assert wait_for(lambda: len(acked) >= 50, timeout=10)
        service.send_signal(signal.SIGKILL)
        service.wait(timeout=10)
        before = set(acked)
        service = start_service(db, port, "t")  # the same file, the same endpoint
        # the publisher and the ack listener reconnect; new contacts reach the map again
        assert wait_for(lambda: len(acked) > len(before) + 20, timeout=15), len(acked)
        result = finished(pub)
        assert result["published"] == 300
        import sqlite3

        time.sleep(0.5)
        held = {(r, c, o) for r, c, o in sqlite3.connect(db).execute(
            "SELECT robot, contact, onset FROM contacts")}
        assert before <= held  # every contact acknowledged before the kill is kept
        assert len(held) >= len(acked) >= len(before) + 20
    finally:
        sub.undeclare()
        listener.close()
        if pub.poll() is None:
            pub.kill()
        service.terminate()
        service.wait(timeout=20)


def test_a_publisher_resending_after_a_restart_is_counted_once(tmp_path):
    from skin.world.shared_map import SharedMap

    port = free_port()
    epoch = str(time.time())
    with in_process_service(tmp_path / "map.sqlite", port):
        first = publisher(port, "arm", "--count", "30", "--spacing", "0.005", "--epoch", epoch)
        assert finished(first)["last"] == 29
        # the robot's process restarts and re-sends its last 10 contacts, then goes on
        again = publisher(port, "arm", "--count", "30", "--spacing", "0.005", "--epoch", epoch,
                          "--first", "20")
        assert finished(again)["last"] == 49
        with SharedMap(f"zenoh://t?connect=tcp/127.0.0.1:{port}") as shared:
            rows = wait_for(lambda: len(shared.acks("arm")) == 50 and shared.acks("arm"))
            assert [r[0] for r in rows] == list(range(50))
            stats = wait_for(lambda: (s := shared.stats())["duplicates"] == 10 and s)
            assert stats["contacts"] == 50 and stats["received"] == 60


def test_skin_map_serve_refuses_a_bad_setup(tmp_path):
    bad = subprocess.run([str(SKIN), "map", "serve", "--db", str(tmp_path / "m.sqlite"),
                          "--listen", "nonsense", "--duration", "1"],
                         capture_output=True, text=True, timeout=30,
                         env={**os.environ, "RUST_LOG": "off"})
    assert bad.returncode == 2 and "zenoh" in bad.stderr
    (tmp_path / "x.sqlite").write_bytes(b"garbage" * 200)
    bad = subprocess.run([str(SKIN), "map", "serve", "--db", str(tmp_path / "x.sqlite"),
                          "--duration", "1"], capture_output=True, text=True, timeout=30)
    assert bad.returncode == 2 and "not a map database" in bad.stderr


def test_skin_run_feeds_the_map_under_its_skin_file_name_and_pose(tmp_path):
    from skin.formats.layout import load_layout
    from skin.stream.publish import contact_geometry
    from skin.world.kinematics import default_chain, transform
    from skin.world.shared_map import SharedMap

    port = free_port()
    (tmp_path / "skin.toml").write_text(
        '[output]\nrobot = "west"\nrobot_pose = [2.0, 1.0, 0.0, 0.0, 0.0, 1.5707963]\n'
        f'publish = ["zenoh://t?connect=tcp/127.0.0.1:{port}"]\n')
    with in_process_service(tmp_path / "map.sqlite", port):
        run = subprocess.run([str(SKIN), "run", "--config", str(tmp_path / "skin.toml"),
                              "--duration", "8", "--speed", "0", "--out", str(tmp_path / "run"),
                              "--json", "--no-map"], capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stderr
        events = [json.loads(line) for line in
                  (tmp_path / "run" / "events.jsonl").read_text().splitlines()]
        final = [e for e in events if e["final"]]
        assert final
        with SharedMap(f"zenoh://t?connect=tcp/127.0.0.1:{port}") as shared:
            acks = wait_for(lambda: len(shared.acks("west")) == len(final) and
                            shared.acks("west"))
            assert sorted(a[0] for a in acks) == sorted(e["contact"] for e in final)
            # where each contact lands: robot pose @ link pose @ centroid
            layout = load_layout(tmp_path / "run" / "layout.toml")
            robot = transform((2.0, 1.0, 0.0), (0.0, 0.0, 1.5707963))
            links = default_chain().poses()
            for e in final:
                g = contact_geometry(layout, e["taxels"])
                p = robot @ links[g["link"]] @ np.array([*g["centroid"], 1.0])
                near = shared.query((*(p[:3] - 0.006), *(p[:3] + 0.006)))
                assert any("west" in v["robots"] for v in near), (e["contact"], p)


def test_a_publisher_with_resend_loses_nothing_across_a_service_restart(tmp_path):
    import sqlite3

    port = free_port()
    db = tmp_path / "map.sqlite"
    service = start_service(db, port, "t")
    pub = publisher(port, "arm", "--count", "200", "--spacing", "0.02", "--resend", "0.5")
    try:
        time.sleep(2.0)
        service.send_signal(signal.SIGKILL)  # down for about a second while it publishes
        service.wait(timeout=10)
        time.sleep(1.0)
        service = start_service(db, port, "t")
        result = finished(pub, timeout=60)
        assert result["published"] == 200 and result["resent"] > 0
        assert result["unacknowledged_at_close"] == 0
        held = sqlite3.connect(db).execute(
            "SELECT count(*), count(DISTINCT contact) FROM contacts WHERE robot='arm'").fetchone()
        assert held == (200, 200)  # every contact, each once
    finally:
        if pub.poll() is None:
            pub.kill()
        service.terminate()
        service.wait(timeout=20)


@pytest.mark.parametrize("value", ["0", "-1", "soon"])
def test_a_bad_resend_is_named(value):
    from skin.errors import SkinError
    from skin.stream.publish import check_publisher_url

    with pytest.raises(SkinError, match="resend= wants a positive number"):
        check_publisher_url(f"zenoh://lab?resend={value}")


def test_a_reply_says_when_the_box_holds_more_voxels_than_it_carries(tmp_path, monkeypatch):
    from skin.world import map_service
    from skin.world.map_store import MapStore

    with MapStore(tmp_path / "map.sqlite") as store:
        for k in range(10):
            store.add({"schema": "thermoskin.contact", "robot": "a", "contact": k,
                       "onset": float(k), "probabilities": {"glass": 0.9, "oak": 0.1},
                       "link_pose": np.eye(4).tolist(), "centroid": [0.02 * k, 0.0, 0.0]})
    monkeypatch.setattr(map_service, "MAX_VOXELS", 4)
    port = free_port()
    with map_service.MapService(tmp_path / "map.sqlite", prefix="t",
                                listen=[f"tcp/127.0.0.1:{port}"]) as service:
        full = json.loads(service.answer("voxels", {"box": "-1,-1,-1,1,1,1"}))
        assert (full["count"], full["truncated"], len(full["voxels"])) == (4, True, 4)
        some = json.loads(service.answer("voxels", {"box": "-1,-1,-1,1,1,1", "limit": "3"}))
        assert (some["count"], some["truncated"], len(some["voxels"])) == (3, False, 3)
        small = json.loads(service.answer("voxels", {"box": "-0.01,-1,-1,0.05,1,1"}))
        assert (small["count"], small["truncated"]) == (3, False)


def test_a_moving_robot_is_placed_with_the_pose_that_held_at_each_onset(tmp_path):
    from skin.stream.publish_zenoh import open_session
    from skin.world.robot_poses import pose_payload
    from skin.world.shared_map import SharedMap

    port = free_port()
    url = f"zenoh://t?connect=tcp/127.0.0.1:{port}"
    with in_process_service(tmp_path / "map.sqlite", port) as service:
        session = open_session(connect=[f"tcp/127.0.0.1:{port}"])
        try:
            time.sleep(0.5)
            t0 = 1.7e9
            # the robot drives along x: 0 m until t0 + 10, 5 m after, 9 m after t0 + 20
            for dt, x in ((0.0, 0.0), (10.0, 5.0), (20.0, 9.0)):
                session.put("t/mover/pose", pose_payload("mover", [x, 0, 0, 0, 0, 0], t0 + dt))
            session.put("t/mover/pose", b'{"schema": "thermoskin.pose", "robot": "mover"}')
            session.put("t/mover/pose", pose_payload("other", [0, 0, 0, 0, 0, 0], t0))
            # poses and contacts come on two subscriptions, in no order between them: a
            # contact is placed with the poses that have arrived (README), so wait for them
            assert wait_for(lambda: service.pose_updates == 3 and service.malformed == 2)
            base = {"schema": "thermoskin.contact", "version": 1, "robot": "mover",
                    "final": True, "decided_at": 1.5, "probabilities": {"glass": 0.9},
                    "link": "forearm", "centroid": [0, 0, 0],
                    # a static pose in the contact: the localisation wins
                    "robot_pose": np.eye(4).tolist()}
            for k, dt in enumerate((5.0, 15.0, 25.0, -3.0)):
                session.put("t/mover/contacts", json.dumps(
                    dict(base, contact=k, onset=dt, host_onset=t0 + dt)))
            with SharedMap(url) as shared:
                assert wait_for(lambda: len(shared.acks("mover")) == 4)
                stats = shared.stats()
                assert stats["pose_updates"] == 3 and stats["malformed"] == 2
                # forearm at the default arm's pose, shifted by the robot's x at the onset
                near = {x: sum(v["contacts"] for v in shared.query(
                    (x - 1.5, -1.5, -1.5, x + 1.5, 1.5, 1.5))) for x in (0.0, 5.0, 9.0)}
                assert near == {0.0: 2, 5.0: 1, 9.0: 1}, near
        finally:
            session.close()
    assert service.pose_updates == 3

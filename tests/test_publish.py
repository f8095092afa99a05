"""Live outputs: payloads, URLs, `skin run --publish` to a Foxglove client and Zenoh."""

import asyncio
import json
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from skin.errors import SkinError
from skin.formats.scene import load_scene
from skin.stream.publish import (
    PAYLOAD_VERSION,
    contact_geometry,
    decode_payload,
    open_publisher,
    temperature_payload,
)

SKIN = Path(sys.executable).with_name("skin")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_temperature_payload_round_trips_and_describes_itself():
    layout = load_scene("default").layout
    temp = np.full((3, len(layout)), 30.5)
    temp[1, 4] = np.nan
    data = temperature_payload(layout, "arm", np.array([0.0, 0.005, 0.01]), temp,
                               np.array([10.0, 10.005, 10.01]))
    msg = decode_payload(data)
    assert msg["schema"] == "thermoskin.temperature" and msg["version"] == PAYLOAD_VERSION
    assert msg["taxels"] == layout.ids.tolist() and msg["samples"] == 3
    assert np.isnan(msg["temperature"][1, 4]) and msg["temperature"][2, 0] == 30.5
    assert msg["host_time"][0] > 1.6e9  # Unix time
    with pytest.raises(ValueError, match="data bytes"):
        decode_payload(data[:-4])
    with pytest.raises(ValueError, match="not a thermoskin payload"):
        decode_payload(b'{"schema": "other", "version": 1}')
    newer = json.dumps({"schema": "thermoskin.health", "version": PAYLOAD_VERSION + 1})
    with pytest.raises(ValueError, match="reads up to"):
        decode_payload(newer.encode())


def test_contact_geometry_is_on_the_link_of_most_taxels():
    layout = load_scene("default").layout
    ids = [int(i) for i in layout.ids[:3]]
    geo = contact_geometry(layout, ids)
    assert geo["link"] == layout.links[0]
    assert np.allclose(geo["centroid"], layout.positions[:3].mean(axis=0), atol=1e-5)
    assert np.linalg.norm(geo["normal"]) == pytest.approx(1.0, abs=1e-4)


def test_foxglove_temperature_message_round_trips():
    pytest.importorskip("foxglove")
    from skin.formats.protobuf import (
        _field,
        _varint,
        decode_temperature,
        encode_temperature,
        temperature_descriptor,
    )

    ids = [3, 200, 70000]
    row = np.array([21.5, np.nan, 40.25])
    msg = decode_temperature(encode_temperature(1.7e9 + 0.123, 4.5, row,
                                                _field(4, b"".join(_varint(i) for i in ids))))
    assert msg["host_time"] == 1.7e9 + 0.123 and msg["device_time"] == 4.5
    assert msg["taxel"] == ids and np.isnan(msg["temperature"][1])
    assert msg["temperature"][2] == 40.25
    desc = temperature_descriptor()
    assert b"thermoskin/Temperature.proto" in desc and b"proto3" in desc


def test_open_publisher_names_bad_urls():
    layout = load_scene("default").layout
    with pytest.raises(SkinError, match="unknown publisher 'mqtt'"):
        open_publisher("mqtt://host", layout)
    with pytest.raises(SkinError, match="unknown option"):
        open_publisher("zenoh://x?colour=red", layout)
    with pytest.raises(SkinError, match="port"):
        open_publisher("foxglove://127.0.0.1:99999", layout)


async def _foxglove_client(port: int, deadline: float, exited=lambda: None) -> dict:
    """Connect (retrying until the server is up), subscribe to every channel, collect."""
    import websockets

    from skin.formats.protobuf import decode_temperature

    got: dict = {"temperature": [], "contacts": [], "topics": {}}
    while True:
        try:
            ws = await websockets.connect(f"ws://127.0.0.1:{port}",
                                          subprotocols=["foxglove.sdk.v1",
                                                        "foxglove.websocket.v1"])
            break
        except OSError:
            if time.monotonic() > deadline or exited() is not None:
                return got  # the run's own failure is reported by the caller
            await asyncio.sleep(0.01)
    channels: dict[int, dict] = {}
    try:
        async for data in ws:
            if isinstance(data, str):
                msg = json.loads(data)
                if msg["op"] == "advertise":
                    new = {c["id"]: c for c in msg["channels"]}
                    channels.update(new)
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                        {"id": cid, "channelId": cid} for cid in new]}))
                continue
            op, sub, _log_time = struct.unpack_from("<BIQ", data)
            assert op == 1  # message data
            chan = channels[sub]
            got["topics"][chan["topic"]] = chan.get("schemaName")
            if chan["topic"] == "/temperature":
                got["temperature"].append(decode_temperature(data[13:])["device_time"])
            elif chan["topic"] == "/contacts":
                got["contacts"].append(json.loads(data[13:]))
    except websockets.ConnectionClosed:
        pass
    return got


def test_foxglove_server_delivers_the_last_contact_before_it_stops():
    """A run's last contacts are decided when it ends: closing must not drop them (without the
    linger, the server stopped with the contact still queued behind the temperatures)."""
    pytest.importorskip("foxglove")
    pytest.importorskip("websockets")
    import threading

    from skin.contact import Contact, MaterialEstimate
    from skin.stream.pipeline import ContactResult

    layout = load_scene("default").layout
    for trial in range(8):
        pub = open_publisher("foxglove://127.0.0.1:0", layout)
        got: dict = {}
        port = pub.port

        def listen(got: dict = got, port: int = port) -> None:
            got.update(asyncio.run(_foxglove_client(port, time.monotonic() + 30)))

        client = threading.Thread(target=listen)
        client.start()
        deadline = time.monotonic() + 30
        while not pub._contacts.has_sinks():  # the client subscribed
            assert time.monotonic() < deadline, "the client did not subscribe"
            time.sleep(0.01)
        t = np.arange(400) * 0.005
        pub.publish_temperature(t, np.full((400, len(layout)), 30.0), t + 1.0)
        contact = Contact(trial, [int(layout.ids[0])], onset=1.0, release=2.0, ambient=25.0,
                          windows=[])
        pub.publish_contact(ContactResult(
            contact, MaterialEstimate("pine", {"pine": 1.0}, 1.0, None, "m"), 2.1))
        pub.close()
        client.join(30)
        assert [c["contact"] for c in got["contacts"]] == [trial]


@pytest.mark.slow
def test_skin_run_publishes_every_contact_to_foxglove_and_zenoh(tmp_path):
    pytest.importorskip("foxglove")
    pytest.importorskip("zenoh")
    pytest.importorskip("websockets")
    zport, fport = free_port(), free_port()
    record = tmp_path / "zenoh.jsonl"
    # the Zenoh subscriber: another process, listening on an explicit endpoint (no multicast)
    sub = subprocess.Popen([str(SKIN), "subscribe", f"zenoh://test?listen=tcp/127.0.0.1:{zport}",
                            "--record", str(record), "--idle", "4", "--duration", "120",
                            "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert sub.stderr.readline().strip() == "ready"
        out = tmp_path / "run"
        run = subprocess.Popen(
            [str(SKIN), "run", "--duration", "8", "--speed", "2", "--out", str(out), "--json",
             "--no-map", "--publish", f"foxglove://127.0.0.1:{fport}",
             "--publish", f"zenoh://test?connect=tcp/127.0.0.1:{zport}&robot=arm"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        got = asyncio.run(_foxglove_client(fport, time.monotonic() + 120, run.poll))
        stdout, stderr = run.communicate(timeout=300)
        assert run.returncode == 0, stderr
        sub_out, _ = sub.communicate(timeout=60)
    finally:
        sub.kill()
    summary = json.loads(stdout)
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    assert summary["contacts"] >= 4 and events
    samples = summary["frames"]
    keys = {(e["contact"], e["final"]) for e in events}

    # Foxglove: every contact event, >= 99.9 % of the temperature messages (one per sample)
    assert got["topics"]["/tf"] == "foxglove.FrameTransforms"
    assert got["topics"]["/arm"] == "foxglove.SceneUpdate"
    assert got["topics"]["/temperature"] == "thermoskin.Temperature"
    assert {(c["contact"], c["final"]) for c in got["contacts"]} == keys
    assert all(c["label"] and len(c["centroid"]) == 3 for c in got["contacts"])
    assert len(set(got["temperature"])) >= 0.999 * samples

    # Zenoh, in the other process: the same
    zsummary = json.loads(sub_out)
    recorded = [json.loads(line) for line in record.read_text().splitlines()]
    contacts = [r for r in recorded if r["schema"] == "thermoskin.contact"]
    assert {(c["contact"], c["final"]) for c in contacts} == keys
    assert all(r["key"].startswith("test/arm/") for r in recorded)
    temps = [r for r in recorded if r["schema"] == "thermoskin.temperature"]
    assert sum(r["samples"] for r in temps) >= 0.999 * samples
    assert zsummary["samples"] == sum(r["samples"] for r in temps)
    assert summary["published"][f"zenoh://test?connect=tcp/127.0.0.1:{zport}&robot=arm"][
        "contacts"] == len(events)


def test_protobuf_schemas_are_valid_for_the_protobuf_library():
    pytest.importorskip("google.protobuf")
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    from skin.formats import protobuf as pb

    def message_class(descriptor: bytes, name: str):
        pool = descriptor_pool.DescriptorPool()
        for f in descriptor_pb2.FileDescriptorSet.FromString(descriptor).file:
            pool.Add(f)
        return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))

    Temperature = message_class(pb.temperature_descriptor(), pb.TEMPERATURE_SCHEMA)
    ours = pb.encode_temperature(1.7e9, 2.5, np.array([20.5, np.nan]), pb.packed_ids([5, 300]))
    theirs = Temperature.FromString(ours)
    assert (theirs.host_time, theirs.device_time, list(theirs.taxel)) == (1.7e9, 2.5, [5, 300])
    assert theirs.temperature[0] == 20.5 and np.isnan(theirs.temperature[1])
    back = pb.decode_temperature(Temperature(device_time=0.0, temperature=[1.5],
                                             taxel=[9]).SerializeToString())
    assert back["device_time"] == 0.0 and back["taxel"] == [9]  # proto3 leaves zeros out
    Wire = message_class(pb.wire_descriptor(), pb.WIRE_SCHEMA)
    assert Wire.FromString(pb.encode_wire(b"\x00ab")).data == b"\x00ab"
    assert pb.decode_wire(Wire(data=b"xyz").SerializeToString()) == b"xyz"

"""The simulated CAN node: nodes beyond 128 taxels, commands and refusals, the command line."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from skin import drivers
from skin.bench.pipeline import cylinder_layout
from skin.drivers.protocol import (
    ALL_TAXELS,
    CAN_BROADCAST,
    Ack,
    Command,
    ErrorCode,
    Identity,
    MsgType,
    can_command_frame,
)
from skin.drivers.sim import SkinSimulator
from skin.errors import DeviceError, ProtocolError
from skin.formats.scene import load_scene

can = pytest.importorskip("can")
from skin.drivers.can_sim import CanSimNode  # noqa: E402


@pytest.fixture
def channel(request):
    return f"can-sim-{request.node.name}"


def test_a_board_of_200_channels_takes_two_nodes(channel):
    scene = dataclasses.replace(load_scene("default"), layout=cylinder_layout(200), touches=())
    sim = SkinSimulator(scene, duration=0.2)
    expected = list(sim.frames())
    with drivers.open(f"can://virtual/{channel}") as driver, CanSimNode(
            sim, ("virtual", channel), node=3, speed=0) as node:
        assert node.nodes == [3, 4]
        node.start()
        got = {3: [], 4: []}
        while (frame := driver.recv(timeout=0.3)) is not None:
            got[frame.board].append(frame)
        assert [f.seq for f in got[3]] == [f.seq for f in got[4]] == list(range(40))
        for a, b, want in zip(got[3], got[4], expected, strict=True):
            assert np.array_equal(np.concatenate([a.counts, b.counts]), want.counts)
        first = driver.request(Command(MsgType.IDENTIFY), node=3)
        second = driver.request(Command(MsgType.IDENTIFY), node=4)
        assert isinstance(first, Identity) and (first.taxels, second.taxels) == (128, 72)
        assert first.transport == second.transport == 1
        assert first.layout_hash != second.layout_hash
    with pytest.raises(ValueError, match="nodes are 0-6"):
        CanSimNode(sim, ("virtual", channel), node=6)


def test_commands_duty_refusals_and_broadcast(channel):
    sim = SkinSimulator(load_scene("default"), duration=5.0)
    with drivers.open(f"can://virtual/{channel}") as driver, CanSimNode(
            sim, f"can://virtual/{channel}", node=1, streaming=False) as node:
        node.start()
        assert driver.recv(timeout=0.2) is None  # booted stopped
        assert isinstance(driver.request(Command(MsgType.SET_DUTY, taxel=ALL_TAXELS, duty=9),
                                         node=1), Ack)
        driver.request(Command(MsgType.SET_DUTY, taxel=5, duty=77), node=1)
        driver.request(Command(MsgType.START), node=1)
        frames = [driver.recv(timeout=1.0) for _ in range(12)]  # every DUTY group refreshed
        assert frames[-1].duty[5] == 77 and frames[-1].duty[4] == 9
        with pytest.raises(ProtocolError, match="ERR_ARGUMENT"):
            driver.request(Command(MsgType.SET_RATE, rate_hz=1000), node=1)
        with pytest.raises(ProtocolError, match="no reply"):
            driver.request(Command(MsgType.IDENTIFY), node=5, timeout=0.2)  # not ours
        sent = driver.send(Command(MsgType.IDENTIFY), node=CAN_BROADCAST)
        ident, _ = can_command_frame(1, sent)
        driver._bus.send(can.Message(arbitration_id=ident, data=b"\x01", is_extended_id=False))
        while len(driver.replies) < 2:
            assert driver.recv(timeout=1.0) is not None
        (who, identity), (_, refusal) = driver.replies
        assert who == 1 and identity.token == sent.token and identity.taxels == 72
        assert refusal.code == ErrorCode.ERR_LENGTH and refusal.token == 0
        assert [c.type for c in node.commands][-1] == MsgType.IDENTIFY
        assert node.send_errors == 0


def test_bad_bus_urls():
    sim = SkinSimulator(load_scene("default"), duration=0.1)
    with pytest.raises(DeviceError, match="can://<interface>/<channel>"):
        CanSimNode(sim, "can://virtual")
    with pytest.raises(DeviceError, match="unknown option"):
        CanSimNode(sim, "can://virtual/x?colour=red")
    with pytest.raises(DeviceError, match="cannot open the bus"):
        CanSimNode(sim, ("no-such-interface", "x"))


def test_the_command_line_names_its_errors():
    proc = subprocess.run([sys.executable, "-m", "skin.drivers.can_sim", "--interface",
                           "virtual"], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2 and "--channel is required" in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "skin.drivers.can_sim", "--interface",
                           "virtual", "--channel", "x", "--scene", "no-such-scene"],
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 1 and proc.stderr.startswith("can_sim: ")


@pytest.mark.parametrize("group", ["239.74.163.2", "ff15:7079:7468:6f6e:6465:6d6f:6d63:6173"],
                         ids=["ipv4", "ipv6-default"])
def test_udp_multicast_through_open(group):
    pytest.importorskip("msgpack")
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("", 0))
        port = sock.getsockname()[1]  # a port of our own: other buses on the host stay apart
    url = f"can://udp_multicast/{group}?port={port}"
    sim = SkinSimulator(load_scene("default"), duration=1.0)
    try:
        node = CanSimNode(sim, url, node=4, streaming=False)
    except DeviceError as exc:
        pytest.skip(f"no UDP multicast here: {exc}")
    with node, drivers.open(url) as driver:
        node.start()
        try:
            identity = driver.request(Command(MsgType.IDENTIFY), node=4, timeout=1.0)
        except ProtocolError as exc:
            pytest.skip(f"multicast does not loop back here: {exc} ({node.send_errors} "
                        f"send errors)")
        assert identity.transport == 1 and identity.taxels == 72
        driver.request(Command(MsgType.START), node=4)
        frames = [driver.recv(timeout=1.0) for _ in range(10)]
        assert [f.seq for f in frames] == list(range(10)) and frames[0].board == 4
        assert driver.url == url




def test_no_sample_follows_the_acknowledgement_of_a_stop(channel):
    """A STOP answered while the node waits for a sample's time: that sample stays unsent
    until a START (it went out after the acknowledgement: a host that had stopped the stream
    still got a frame, and the driver contract's quiet check failed on the UDP bus)."""
    import time

    from skin.drivers.protocol import CanType

    def watch(tap, until, linger=0.0):
        """The frame types seen on the bus until ``until(types)`` holds, then ``linger`` s."""
        kinds, deadline, end = [], time.monotonic() + 10.0, None
        while end is None or time.monotonic() < end:
            assert time.monotonic() < deadline, kinds
            if (msg := tap.recv(timeout=0.01)) is not None:
                kinds.append(msg.arbitration_id >> 8)
            if end is None and until(kinds):
                end = time.monotonic() + linger
        return kinds

    sim = SkinSimulator(load_scene("default"), duration=5.0)
    with can.Bus(interface="virtual", channel=channel) as tap, \
            drivers.open(f"can://virtual/{channel}") as driver, \
            CanSimNode(sim, ("virtual", channel), node=1) as node:
        node.start()
        for _ in range(5):
            watch(tap, lambda kinds: CanType.DATA in kinds)  # streaming
            assert isinstance(driver.request(Command(MsgType.STOP), node=1), Ack)
            kinds = watch(tap, lambda kinds: CanType.REPLY in kinds, linger=0.1)
            after = kinds[kinds.index(CanType.REPLY):]  # the STOP's reply, then nothing
            assert CanType.DATA not in after, after
            driver.request(Command(MsgType.START), node=1)
        driver.request(Command(MsgType.STOP), node=1)
        seqs = []
        while (frame := driver.recv(timeout=0.5)) is not None:
            seqs.append(frame.seq)
    # each sample held back went out after the START: nothing lost, nothing twice
    assert seqs == list(range(len(seqs))) and len(seqs) >= 5


def test_a_simulated_node_with_force_sends_force_frames(channel):
    """A scene with a force channel: the simulated CAN node sends FORCE frames and the driver's
    frames carry the simulator's force exactly (1 mN on the wire as in the simulator)."""
    from skin.formats.scene import parse_scene

    text = (Path(__file__).resolve().parents[1] / "skin" / "data" / "scenes"
            / "reference-touches.toml").read_text()
    scene = dataclasses.replace(parse_scene(text, "reference-touches.toml"), force="force")
    sim = SkinSimulator(scene, duration=6.0)
    expected = {f.seq: f for f in sim.frames()}
    with drivers.open(f"can://virtual/{channel}") as driver, CanSimNode(
            sim, ("virtual", channel), node=1, speed=0) as node:
        node.start()
        got = []
        while (frame := driver.recv(timeout=0.3)) is not None:
            got.append(frame)
        stats = driver.stats
    assert len(got) == len(expected) and stats.forces == len(got)
    assert stats.force_missing == stats.force_orphans == 0
    touched = 0
    for f in got:
        want = expected[f.seq].force
        assert np.array_equal(f.force, want, equal_nan=True)
        touched += int(np.nanmax(f.force) > 1.0)
    assert touched > 100  # the first touch pressed

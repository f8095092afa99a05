"""The CAN driver over python-can's virtual bus: a node's frames, commands and replies, garbage."""

import numpy as np
import pytest

from skin import drivers
from skin.drivers.protocol import (
    Ack,
    Command,
    ErrorReply,
    Identity,
    MsgType,
    can_reply_frames,
    can_sample_frames,
)
from skin.errors import DeviceError, ProtocolError

can = pytest.importorskip("can")

from conftest import send_can  # noqa: E402


def sample(node, seq, n=10):
    counts = (np.arange(n) * 37 + seq) % 4096
    return counts, can_sample_frames(node, seq, seq * 5000, counts, 24.5, np.full(n, 200))


def test_a_nodes_samples_come_out_as_frames(node_bus):
    bus, driver = node_bus
    for seq in range(5):
        send_can(bus, sample(3, seq)[1])
    frames = [driver.recv(timeout=1.0) for _ in range(5)]
    assert [f.seq for f in frames] == list(range(5))
    counts, _ = sample(3, 4)
    assert np.array_equal(frames[-1].counts, counts)
    assert frames[-1].board == 3 and frames[-1].ambient == pytest.approx(24.5)
    assert frames[-1].device_time == pytest.approx(0.02)
    assert driver.stats.frames == 5 and driver.stats.missing == 0


def test_a_lost_data_frame_drops_its_sample_and_garbage_is_counted(node_bus):
    bus, driver = node_bus
    send_can(bus, sample(1, 0)[1])
    lossy = sample(1, 1)[1]
    send_can(bus, lossy[:2] + lossy[3:])  # DATA group 1 lost
    bus.send(can.Message(arbitration_id=0x1ABCDEF, data=b"\xff" * 8, is_extended_id=True))
    send_can(bus, [(0x0FF, b"")])  # a SYNC too short to hold anything
    send_can(bus, sample(1, 2)[1])
    frames = []
    while (f := driver.recv(timeout=0.3)) is not None:
        frames.append(f)
    assert [f.seq for f in frames] == [0, 2]
    assert driver.stats.missing >= 1 and driver.stats.malformed >= 1


def test_request_gets_the_nodes_reply_and_keeps_the_frames(node_bus):
    bus, driver = node_bus
    sent = driver.send(Command(MsgType.IDENTIFY), node=2)
    msg = bus.recv(timeout=1.0)  # the node sees the command
    assert msg.arbitration_id == (1 << 8 | 2 << 5) and msg.data[1] == MsgType.IDENTIFY
    send_can(bus, sample(2, 0)[1])
    identity = Identity(token=sent.token + 1, fw_major=1, fw_minor=0, fw_patch=0, board_id=2,
                        mcu=1, transport=1, options=3, taxels=10, adc_bits=12, oversampling=4,
                        rate_hz=200, max_rate_hz=217, layout_hash=0, baud_div=1000)
    send_can(bus, can_reply_frames(2, identity.body()))  # answers the request sent next
    reply = driver.request(Command(MsgType.IDENTIFY), node=2, timeout=2.0)
    assert reply == identity
    assert driver.recv(timeout=0.5).seq == 0  # the sample that came first was kept
    refusal = ErrorReply(token=sent.token + 2, command=MsgType.SET_RATE, code=6, detail=0)
    send_can(bus, can_reply_frames(2, refusal.body()))
    with pytest.raises(ProtocolError, match="ARGUMENT"):
        driver.request(Command(MsgType.SET_RATE, rate_hz=9999), node=2, timeout=2.0)
    send_can(bus, can_reply_frames(2, Ack(token=sent.token + 3, command=MsgType.START).body()))
    assert isinstance(driver.request(Command(MsgType.START), node=2, timeout=2.0), Ack)
    with pytest.raises(ProtocolError, match="no reply"):
        driver.request(Command(MsgType.STOP), node=2, timeout=0.2)


def test_bad_can_urls_are_named():
    with pytest.raises(DeviceError, match="can://<interface>/<channel>"):
        drivers.open("can://virtual")
    with pytest.raises(DeviceError, match="cannot open the bus"):
        drivers.open("can://no-such-interface/ch0")

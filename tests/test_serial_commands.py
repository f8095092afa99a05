"""Commands over a real pseudo-terminal: the serial driver against the simulated board."""

import numpy as np
import pytest

import skin.drivers
from skin.drivers.protocol import (
    Ack,
    Command,
    Identity,
    MsgType,
    SelftestResult,
    layout_hash,
)
from skin.drivers.sim import PtySerialDevice, SkinSimulator
from skin.errors import ProtocolError
from skin.formats.scene import load_scene
from skin.frame import FLAG_STREAMING


@pytest.fixture(scope="module")
def sim() -> SkinSimulator:
    return SkinSimulator(load_scene("default"), duration=3.0)


def read_all(driver, n: int) -> list:
    got = []
    while len(got) < n:
        frame = driver.recv(timeout=2.0)
        assert frame is not None, f"stalled after {len(got)} frames"
        got.append(frame)
    return got


def test_requests_while_streaming_lose_no_frame(sim):
    expected = list(sim.frames())
    with PtySerialDevice(sim, speed=0) as device, skin.drivers.open(
        f"serial://{device.port}"
    ) as driver:
        device.start()
        first = read_all(driver, 50)
        identity = driver.request(Command(MsgType.IDENTIFY))
        assert isinstance(identity, Identity) and identity.token == 1
        assert identity.taxels == len(expected[0].counts)
        assert identity.rate_hz == round(sim.sample_rate)
        order = np.argsort(sim._addr)
        assert identity.layout_hash == layout_hash(sim.layout.ids[sim._idx[order]].tolist())
        ack = driver.request(Command(MsgType.SET_SETPOINT, taxel=0, count=2000))
        assert ack == Ack(2, MsgType.SET_SETPOINT)
        rest = read_all(driver, len(expected) - len(first))
        assert driver.stats.crc_errors == driver.stats.malformed == 0
    got = first + rest
    assert [f.seq for f in got] == [f.seq for f in expected]
    for a, b in zip(got, expected, strict=True):
        assert np.array_equal(a.counts, b.counts) and np.array_equal(a.status, b.status)
        assert a.flags == b.flags | FLAG_STREAMING


def test_refused_commands_raise_and_the_stream_goes_on(sim):
    with PtySerialDevice(sim, speed=0) as device, skin.drivers.open(
        f"serial://{device.port}"
    ) as driver:
        device.start()
        with pytest.raises(ProtocolError, match=r"SET_RATE .*ERR_ARGUMENT, detail 0"):
            driver.request(Command(MsgType.SET_RATE, rate_hz=3))
        taxels = sim._channels
        with pytest.raises(ProtocolError, match="ERR_ARGUMENT"):
            driver.request(Command(MsgType.SET_DUTY, taxel=taxels, duty=1))
        frames = read_all(driver, 20)
        assert [f.seq for f in frames] == list(range(20))


def test_stop_start_and_duty(sim):
    with PtySerialDevice(sim, speed=0) as device, skin.drivers.open(
        f"serial://{device.port}"
    ) as driver:
        device.start()
        read_all(driver, 5)
        driver.request(Command(MsgType.STOP))
        before = []
        while (frame := driver.recv(timeout=0.3)) is not None:
            before.append(frame)
        assert driver.recv(timeout=0.3) is None  # stopped
        driver.request(Command(MsgType.SET_DUTY, taxel=0xFFFF, duty=40))
        driver.request(Command(MsgType.START))
        (after,) = read_all(driver, 1)
        assert after.seq == 5 + len(before)  # the sequence goes on where it stopped
        assert np.all(after.duty == 40)
        ack = driver.request(Command(MsgType.SELFTEST, pulse_ms=100, duty=255))
        result = driver.wait_reply(ack.token, timeout=2.0, kind=SelftestResult)
        assert len(result.response) == sim._channels
    assert [c.type for c in device.commands] == [MsgType.STOP, MsgType.SET_DUTY, MsgType.START,
                                                 MsgType.SELFTEST]


def test_no_answer_is_a_timeout():
    with skin.drivers.open("serial+loop://") as driver:  # echoes the command: not a reply
        with pytest.raises(ProtocolError, match=r"no reply to IDENTIFY .* within 0\.2 s"):
            driver.request(Command(MsgType.IDENTIFY), timeout=0.2)
        assert driver.stats.malformed == 1


def test_tokens_cycle_through_1_to_255():
    with skin.drivers.open("serial+loop://") as driver:
        tokens = [driver.send(Command(MsgType.START)).token for _ in range(256)]
        assert tokens[:2] == [1, 2] and tokens[254:] == [255, 1]
        assert driver.send(Command(MsgType.START, token=0x42)).token == 0x42

"""Faults: a board unplugged mid-frame, a CAN bus-off, a silent node, a flooded queue.

The serial board is a real pseudo-terminal reached through a symbolic link, as a udev rule
names a USB board (/dev/serial/by-id/...): unplugging closes the pty and removes the link,
plugging it back makes a new pty behind the same name.
"""

import os
import threading
import time
import tty

import numpy as np
import pytest

from skin import drivers
from skin.drivers.can_bus import CAN_ERR_BUSOFF
from skin.drivers.protocol import can_sample_frames, encode_sample
from skin.drivers.reader import BackgroundReader
from skin.errors import DeviceError

can = pytest.importorskip("can")


def packet(seq, n=16):
    counts = (np.arange(n) * 53 + seq) % 4096
    return encode_sample(seq, seq * 5000, counts, 24.0, np.full(n, 255))


class UsbBoard:
    """A pty behind a fixed name, that can be unplugged and plugged back."""

    def __init__(self, folder):
        self.link = folder / "ttySKIN0"
        self.fds = None
        self.plug()

    def plug(self):
        master, slave = os.openpty()
        tty.setraw(slave)
        self.fds = (master, slave)
        os.symlink(os.ttyname(slave), self.link)

    def unplug(self):
        for fd in self.fds:
            os.close(fd)
        self.link.unlink()
        self.fds = None

    def write(self, data):
        os.write(self.fds[0], data)

    def close(self):
        if self.fds is not None:
            self.unplug()


@pytest.fixture
def board(tmp_path):
    board = UsbBoard(tmp_path)
    yield board
    board.close()


def wait_for(predicate, timeout=5.0):
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.01)


def test_unplugged_mid_frame_reconnects_and_loses_nothing_received(board):
    driver = drivers.open(f"serial://{board.link}?reconnect=5")

    def play():
        board.write(b"".join(packet(s) for s in range(50)) + packet(50)[:30])  # cut mid-frame
        time.sleep(0.2)
        board.unplug()
        time.sleep(0.4)
        board.plug()
        wait_for(lambda: driver.health.reconnects == 1)
        board.write(b"".join(packet(s) for s in range(51, 100)))

    player = threading.Thread(target=play)
    player.start()
    seqs = []
    deadline = time.monotonic() + 10
    while len(seqs) < 99 and time.monotonic() < deadline:
        frame = driver.recv(timeout=0.2)
        if frame is not None:
            seqs.append(frame.seq)
    player.join()
    health = driver.health
    driver.close()
    assert seqs == list(range(50)) + list(range(51, 100))
    assert health.faults == 1 and health.reconnects == 1 and health.connected
    assert health.attempts >= 2  # the first tries found no device: back-off
    assert "serial://" in health.last_fault


def test_without_reconnect_the_fault_is_raised_after_every_frame_received(board):
    driver = drivers.open(f"serial://{board.link}")
    board.write(b"".join(packet(s) for s in range(20)) + packet(20)[:10])
    time.sleep(0.2)
    seqs = [driver.recv(timeout=1.0).seq]  # the driver has read what was sent...
    board.unplug()  # ... and then the board goes: the 19 frames it holds still come out
    with pytest.raises(DeviceError, match="20 frames were received before"):
        while True:
            frame = driver.recv(timeout=1.0)
            if frame is not None:
                seqs.append(frame.seq)
    assert seqs == list(range(20))
    driver.close()
    driver.close()


def test_a_device_that_stays_away_raises_once_the_reconnect_time_is_up(board):
    driver = drivers.open(f"serial://{board.link}?reconnect=0.5")
    board.write(packet(0))
    assert driver.recv(timeout=1.0).seq == 0
    board.unplug()
    t0 = time.monotonic()
    with pytest.raises(DeviceError, match=r"not back within 0.5 s"):
        while time.monotonic() - t0 < 5:
            assert driver.recv(timeout=0.1) is None  # quiet while it waits
    assert 0.4 < time.monotonic() - t0 < 1.5
    assert driver.health.attempts >= 3
    driver.close()


def send_samples(bus, node, seqs):
    for seq in seqs:
        for ident, data in can_sample_frames(node, seq, seq * 5000, np.arange(8) * 100, 24.0,
                                             np.full(8, 200)):
            bus.send(can.Message(arbitration_id=ident, data=data, is_extended_id=False))


def test_can_bus_off_is_reported_and_the_bus_reopened(request):
    channel = f"faults-{request.node.name}"
    node = can.Bus(interface="virtual", channel=channel)
    driver = drivers.open(f"can://virtual/{channel}?reconnect=5")
    try:
        send_samples(node, 2, range(5))
        node.send(can.Message(arbitration_id=CAN_ERR_BUSOFF, is_error_frame=True, data=b""))

        def later():
            wait_for(lambda: driver.health.reconnects == 1)
            send_samples(node, 2, range(5, 10))

        thread = threading.Thread(target=later)
        thread.start()
        seqs = []
        deadline = time.monotonic() + 5
        while len(seqs) < 10 and time.monotonic() < deadline:
            frame = driver.recv(timeout=0.2)
            if frame is not None:
                seqs.append(frame.seq)
        thread.join()
        assert seqs == list(range(10))
        assert driver.health.faults == 1 and "bus-off" in driver.health.last_fault
    finally:
        driver.close()
        node.shutdown()


def test_a_silent_node_is_reported_until_it_speaks_again(request):
    channel = f"faults-{request.node.name}"
    node = can.Bus(interface="virtual", channel=channel)
    driver = drivers.open(f"can://virtual/{channel}")
    try:
        send_samples(node, 3, range(3))
        assert [driver.recv(timeout=1.0).seq for _ in range(3)] == [0, 1, 2]
        t0 = time.monotonic()
        while time.monotonic() - t0 < 0.8:
            driver.recv(timeout=0.1)
        assert driver.health.silent == {3}
        send_samples(node, 3, [3])
        assert driver.recv(timeout=1.0).seq == 3
        assert driver.health.silent == set()
    finally:
        driver.close()
        node.shutdown()


def test_a_flooded_queue_drops_the_oldest_and_counts_every_frame():
    reader = drivers.open("sim://default?duration=5&speed=0&queue=100")
    assert isinstance(reader, BackgroundReader)
    time.sleep(1.0)  # the caller is busy; the reader is not
    seqs = [frame.seq for frame in reader]
    assert reader.finished
    assert len(seqs) + reader.health.overflows == 1000
    assert reader.health.overflows > 0
    assert seqs == sorted(seqs) and seqs[-1] == 999  # the newest are kept, in order
    reader.close()


def test_a_reader_raises_a_drivers_final_fault_once_after_its_frames(board):
    reader = BackgroundReader(drivers.open(f"serial://{board.link}"), maxsize=1000)
    board.write(b"".join(packet(s) for s in range(10)))
    time.sleep(0.3)
    board.unplug()
    seqs = []
    with pytest.raises(DeviceError, match="device stopped answering"):
        for _ in range(100):
            frame = reader.recv(timeout=1.0)
            if frame is not None:
                seqs.append(frame.seq)
    assert seqs == list(range(10))
    assert reader.recv(timeout=0.1) is None and reader.finished is False
    reader.close()

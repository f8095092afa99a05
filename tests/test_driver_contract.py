"""One contract, every backend (after python-can's test/back2back_test.py).

Each backend is a fixture that opens a driver on a live source and says what the source
should deliver (`Backend`); every check below runs against each of them:

- ``sim``: ``sim://`` (frames handed over directly);
- ``pty-sim``: a serial driver on a real pseudo-terminal fed by `PtySerialDevice`;
- ``pty-firmware``: the same, fed by the compiled firmware in simavr (skipped when the
  toolchain is absent, failing instead with ``SKIN_REQUIRE_FIRMWARE=1``);
- ``can-virtual``: python-can's virtual bus, `CanSimNode` in this process;
- ``can-udp``: python-can's udp_multicast, `CanSimNode` in another process
  (``python -m skin.drivers.can_sim``);
- ``replay``: ``replay://`` of a ``sim://`` run recorded through its tap (`skin.drivers.recording`);
- ``serial-hw``, ``can-hw``: real hardware, opt-in: ``SKIN_TEST_SERIAL=/dev/ttyACM0``,
  ``SKIN_TEST_CAN=socketcan/can0`` (and ``SKIN_TEST_CAN_NODE``, 0 by default).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import itertools
import math
import os
import random
import select
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from skin import drivers
from skin.drivers.base import Driver
from skin.drivers.protocol import (
    CanReassembler,
    Command,
    Identity,
    MsgType,
    StreamDecoder,
    split_can_records,
)
from skin.drivers.sim import PtySerialDevice, SkinSimulator
from skin.errors import DeviceError, ProtocolError
from skin.formats.scene import load_scene
from skin.frame import FLAG_STREAMING, Frame

N = 40  # frames a check reads: 0.2 s at 200 Hz
SIM_SECONDS = 3.0  # the simulated scene every simulated source plays
UDP_SECONDS = 20.0  # the other process's scene: every udp check reads from it in turn
REQUIRE_FIRMWARE = os.environ.get("SKIN_REQUIRE_FIRMWARE") == "1"


@dataclasses.dataclass
class Backend:
    """An opened driver and what its source should deliver.

    ``start`` makes the source stream; until then (or once ``silence`` has drained a finite
    source) nothing comes. ``request`` sends a command and returns the reply (None: the
    source takes no commands). ``expected(seq)`` is the frame the source sent as ``seq``, when
    it is known.
    """

    driver: Driver
    taxels: int
    rate: float
    board: int
    adc_bits: int
    start: Callable[[], None] = lambda: None
    silence: Callable[[], None] = lambda: None
    request: Callable[[Command], object] | None = None
    expected: Callable[[int], Frame] | None = None
    transport: int = 0  # of its IDENTITY: 0 serial, 1 CAN
    lossless: bool = True  # every seq arrives; no sample is missing
    clean: bool = True  # read from its first byte: no malformed packet, no resync
    realtime: bool = False  # paced at the board's rate
    streaming_flag: bool = True  # FLAG_STREAMING set in every frame (the wire's frames)
    finite: bool = False  # ends (``driver.finished``) after its last frame


@functools.cache
def simulator(seconds: float = SIM_SECONDS) -> SkinSimulator:
    return SkinSimulator(load_scene("default"), duration=seconds)


@functools.cache
def expected_frames(seconds: float = SIM_SECONDS) -> list[Frame]:
    return list(simulator(seconds).frames())


def _sim_backend(sim: SkinSimulator, seconds: float, **knowledge) -> dict:
    return dict(taxels=sim._channels, rate=sim.sample_rate, board=sim.board.id,
                adc_bits=sim.board.adc_bits, expected=expected_frames(seconds).__getitem__,
                **knowledge)


def _drain(driver: Driver) -> None:
    while driver.recv(timeout=0.2) is not None:
        pass


# ---- the backends ----

@contextlib.contextmanager
def sim_backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    seconds = 1.0
    driver = drivers.open(f"sim://default?speed=0&duration={seconds:g}")
    with driver:
        yield Backend(driver, silence=lambda: _drain(driver), streaming_flag=False, finite=True,
                      **_sim_backend(simulator(seconds), seconds))


@contextlib.contextmanager
def pty_sim_backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    with PtySerialDevice(simulator(SIM_SECONDS), speed=0) as device:
        driver = drivers.open(f"serial://{device.port}")
        with driver:
            yield Backend(driver, start=device.start,
                          request=lambda c: driver.request(c, timeout=2.0),
                          **_sim_backend(simulator(SIM_SECONDS), SIM_SECONDS))


@contextlib.contextmanager
def firmware_backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    request.getfixturevalue("firmware_built")  # skips (fails in CI) without the toolchain
    from skin.drivers.firmware_board import TAXELS, emulated_board, firmware_scene

    sim = SkinSimulator(firmware_scene(load_scene("default")), duration=2.0)
    folder = request.getfixturevalue("tmp_path")
    with emulated_board(sim, folder=folder) as board:  # powers up on the host's first write
        driver = drivers.open(f"serial://{board.port}")
        with driver:
            yield Backend(driver, taxels=TAXELS, rate=sim.sample_rate, board=0, adc_bits=12,
                          start=lambda: driver.send(Command(MsgType.START)),
                          request=lambda c: driver.request(c, timeout=5.0))


@contextlib.contextmanager
def can_virtual_backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    pytest.importorskip("can")
    from skin.drivers.can_sim import CanSimNode

    channel = f"contract-{request.node.name}"
    node = 2
    with CanSimNode(simulator(SIM_SECONDS), ("virtual", channel), node=node) as sim_node:
        driver = drivers.open(f"can://virtual/{channel}")
        with driver:
            yield Backend(driver, start=sim_node.start, transport=1, realtime=True,
                          request=lambda c: driver.request(c, node=node, timeout=2.0),
                          **{**_sim_backend(simulator(SIM_SECONDS), SIM_SECONDS), "board": node})


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("", 0))
        return sock.getsockname()[1]


@pytest.fixture(scope="module")
def udp_node() -> Iterator[tuple[str, int]]:
    """A simulated node in another process on a UDP multicast bus: (its URL, its node)."""
    pytest.importorskip("can")
    pytest.importorskip("msgpack")
    group = f"239.74.{random.randrange(256)}.{random.randrange(1, 255)}"
    node = 1
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen([sys.executable, "-m", "skin.drivers.can_sim", "--channel", group,
                             "--port", str(_free_udp_port()), "--scene", "default",
                             "--duration", f"{UDP_SECONDS:g}", "--node", str(node),
                             "--stopped"], stdout=subprocess.PIPE, stderr=log)
    try:
        line = b""
        deadline = time.monotonic() + 30.0
        while b"\n" not in line and time.monotonic() < deadline:
            if select.select([proc.stdout], [], [], 0.1)[0]:
                chunk = os.read(proc.stdout.fileno(), 4096)
                if not chunk:
                    break
                line += chunk
        if not line.startswith(b"ready "):
            log.seek(0)
            pytest.fail(f"the CAN node did not start: {line!r} {log.read().decode()[-2000:]}")
        yield line.split()[1].decode(), node
    finally:
        proc.terminate()
        try:
            proc.wait(5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        log.close()


@contextlib.contextmanager
def can_udp_backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    url, node = request.getfixturevalue("udp_node")

    def ask(driver: Driver, command: Command, attempts: int = 3) -> object:
        # UDP loses datagrams (a loaded node's socket overflows with the group's own
        # stream): a command or its reply may be lost, so ask again, as a host on UDP must
        # (every command here is idempotent); a refusal is raised at once
        for _ in range(attempts - 1):
            try:
                return driver.request(command, node=node, timeout=2.0)
            except ProtocolError as exc:
                if "no reply" not in str(exc):
                    raise
        return driver.request(command, node=node, timeout=2.0)

    driver = drivers.open(url)
    try:
        with driver:
            yield Backend(driver, start=lambda: ask(driver, Command(MsgType.START)),
                          request=lambda c: ask(driver, c), transport=1, realtime=True,
                          # datagrams the node sent before the last check's STOP took effect
                          silence=lambda: _drain(driver),
                          lossless=False,  # UDP: a reader that falls behind loses datagrams
                          **{**_sim_backend(simulator(UDP_SECONDS), UDP_SECONDS),
                             "board": node})
    finally:
        # the node stays up for the next check, stopped; the suite runs on several processes,
        # and a node starved by them may miss more STOPs than a check's three tries
        with drivers.open(url) as control:
            ask(control, Command(MsgType.STOP), attempts=8)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A sim:// run recorded through its driver's ``tap`` (`skin.drivers.recording`)."""
    pytest.importorskip("mcap")
    from skin.drivers.recording import Recorder

    path = tmp_path_factory.mktemp("replay") / "run.mcap"
    seconds = 1.0
    with drivers.open(f"sim://default?speed=0&duration={seconds:g}") as driver:
        recorder = Recorder(path, simulator(seconds).layout)
        recorder.add_driver(driver)
        assert sum(1 for _ in driver) == len(expected_frames(seconds))
        recorder.close()
    return path


@contextlib.contextmanager
def replay_backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    # replay:// plays the recording of a sim:// run: the same frames, no commands, finite
    pytest.importorskip("skin.drivers.replay", reason="skin.drivers.replay is not written yet")
    path = request.getfixturevalue("recording")
    driver = drivers.open(f"replay://{path}?speed=0")
    with driver:
        yield Backend(driver, silence=lambda: _drain(driver), streaming_flag=False, finite=True,
                      **_sim_backend(simulator(1.0), 1.0))


def _hardware(driver: Driver, ask: Callable[[Command], object], board: int,
              transport: int) -> Backend:
    ask(Command(MsgType.STOP))
    _drain(driver)
    identity = ask(Command(MsgType.IDENTIFY))
    assert isinstance(identity, Identity), identity
    return Backend(driver, taxels=identity.taxels, rate=identity.rate_hz, board=board,
                   adc_bits=identity.adc_bits, start=lambda: ask(Command(MsgType.START)),
                   request=ask, transport=transport, clean=False, realtime=True)


@contextlib.contextmanager
def serial_hw_backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    port = os.environ.get("SKIN_TEST_SERIAL")
    if not port:
        pytest.skip("hardware: set SKIN_TEST_SERIAL=/dev/ttyACM0 to run on a board")
    url = port if "://" in port else f"serial://{port}"
    with drivers.open(url) as driver:
        yield _hardware(driver, functools.partial(driver.request, timeout=2.0), board=0,
                        transport=0)
    with drivers.open(url) as control:  # a board streams from power-up: leave it so
        control.request(Command(MsgType.START), timeout=2.0)


@contextlib.contextmanager
def can_hw_backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    bus = os.environ.get("SKIN_TEST_CAN")
    if not bus:
        pytest.skip("hardware: set SKIN_TEST_CAN=socketcan/can0 (and SKIN_TEST_CAN_NODE)")
    node = int(os.environ.get("SKIN_TEST_CAN_NODE", "0"))
    url = bus if "://" in bus else f"can://{bus}"
    with drivers.open(url) as driver:
        yield _hardware(driver, functools.partial(driver.request, node=node, timeout=2.0),
                        board=node, transport=1)
    with drivers.open(url) as control:
        control.request(Command(MsgType.START), node=node, timeout=2.0)


#: Every backend the contract runs against. A new backend is a context manager that yields a
#: `Backend`, added here.
BACKENDS: dict[str, Callable[[pytest.FixtureRequest], contextlib.AbstractContextManager]] = {
    "sim": sim_backend,
    "pty-sim": pty_sim_backend,
    "pty-firmware": firmware_backend,
    "can-virtual": can_virtual_backend,
    "can-udp": can_udp_backend,
    "replay": replay_backend,
    "serial-hw": serial_hw_backend,
    "can-hw": can_hw_backend,
}


@pytest.fixture(params=list(BACKENDS))
def backend(request: pytest.FixtureRequest) -> Iterator[Backend]:
    with BACKENDS[request.param](request) as opened:
        yield opened


def read(backend: Backend, n: int, timeout: float = 5.0) -> list[Frame]:
    out = []
    for _ in range(n):
        frame = backend.driver.recv(timeout=timeout)
        assert frame is not None, f"only {len(out)} of {n} frames arrived"
        out.append(frame)
    return out


def same_frame(a: Frame, b: Frame) -> None:
    """``a`` carries ``b``'s sample (as the wire carries it: ambient to 0.01 deg C)."""
    assert a.seq == b.seq
    assert a.device_time == pytest.approx(b.device_time, abs=1e-6)
    assert np.array_equal(a.counts, b.counts)
    assert (a.status is None) == (b.status is None)
    assert a.status is None or np.array_equal(a.status, b.status)
    assert (math.isnan(a.ambient) and math.isnan(b.ambient)) or a.ambient == pytest.approx(
        b.ambient, abs=0.006)


# ---- the contract ----

def test_frames_arrive_in_seq_order_at_the_boards_rate(backend):
    backend.start()
    frames, arrived = [], []
    for _ in range(N):
        frames += read(backend, 1)
        arrived.append(time.monotonic())
    seq = np.array([f.seq for f in frames])
    steps = np.diff(seq)
    assert np.all(steps == 1) if backend.lossless else np.all(steps >= 1), seq
    period = np.diff([f.device_time for f in frames]) / steps
    assert np.all(period > 0)
    assert period == pytest.approx(1.0 / backend.rate, rel=0.02)
    if backend.realtime:  # paced: N frames take about N periods, not a burst
        span = frames[-1].device_time - frames[0].device_time
        assert arrived[-1] - arrived[0] >= 0.5 * span


def test_frames_have_the_boards_shape(backend):
    backend.start()
    for frame in read(backend, 10):
        assert isinstance(frame.seq, int) and isinstance(frame.device_time, float)
        assert frame.counts.shape == (backend.taxels,) and frame.counts.dtype == np.uint16
        assert frame.duty.shape == (backend.taxels,) and frame.duty.dtype == np.uint8
        assert frame.counts.max() < 1 << backend.adc_bits
        if frame.status is not None:
            assert frame.status.shape == (backend.taxels,) and frame.status.dtype == np.uint8
            assert frame.status.max() <= 0xF
        assert frame.board == backend.board
        assert isinstance(frame.ambient, float) and isinstance(frame.flags, int)
        assert bool(frame.flags & FLAG_STREAMING) == backend.streaming_flag
        if backend.expected is not None:
            same_frame(frame, backend.expected(frame.seq))


def test_recv_returns_none_at_its_timeout_when_nothing_comes(backend):
    backend.silence()  # before start, or drained
    timeout = 0.25
    t0 = time.monotonic()
    assert backend.driver.recv(timeout=timeout) is None
    elapsed = time.monotonic() - t0
    assert elapsed < timeout + 0.5
    if not backend.driver.finished:  # a finished source says so at once
        assert elapsed >= 0.9 * timeout


def test_iteration_yields_the_frames(backend):
    backend.start()
    frames = list(itertools.islice(backend.driver, N))
    assert len(frames) == N
    assert all(b.seq > a.seq for a, b in itertools.pairwise(frames))
    if backend.finite:  # iteration ends with the source
        rest = list(backend.driver)
        assert backend.driver.finished and rest and rest[0].seq > frames[-1].seq


def test_close_is_idempotent_and_a_closed_driver_raises(backend):
    backend.start()
    driver = backend.driver
    assert driver.recv(timeout=5.0) is not None
    driver.close()
    driver.close()
    with pytest.raises(DeviceError, match="closed"):
        driver.recv(timeout=0.1)
    assert list(driver) == []
    with pytest.raises(DeviceError):
        driver.send(Command(MsgType.IDENTIFY))


def test_context_manager_closes(backend):
    backend.start()
    with backend.driver as driver:
        assert driver is backend.driver
        assert driver.recv(timeout=5.0) is not None
    with pytest.raises(DeviceError, match="closed"):
        driver.recv(timeout=0.1)


def test_stats_count_the_frames_and_a_clean_link_has_no_errors(backend):
    backend.start()
    read(backend, N)
    stats = backend.driver.stats
    assert stats.frames >= N  # frames decoded and not yet taken count too
    assert stats.crc_errors == 0
    if backend.clean:
        assert stats.malformed == stats.resyncs == 0
    if backend.lossless:  # (CAN: a lost SYNC leaves its DATA frames orphans)
        assert stats.missing == stats.lost_samples == stats.duplicates == stats.orphans == 0


def test_identify_where_the_source_takes_commands(backend):
    if backend.request is None:
        with pytest.raises(DeviceError, match="takes no commands"):
            backend.driver.send(Command(MsgType.IDENTIFY))
        return
    backend.start()
    before = read(backend, 3)
    reply = backend.request(Command(MsgType.IDENTIFY))
    assert isinstance(reply, Identity)
    assert (reply.taxels, reply.rate_hz, reply.adc_bits, reply.transport) == (
        backend.taxels, round(backend.rate), backend.adc_bits, backend.transport)
    after = read(backend, 3)  # the frames that came meanwhile were kept, in order
    if backend.lossless:
        assert after[0].seq == before[-1].seq + 1


def test_the_tap_bytes_decode_to_the_same_frames(backend):
    chunks: list[tuple[float, bytes]] = []
    backend.driver.tap = lambda t, data: chunks.append((t, bytes(data)))
    backend.start()
    frames = read(backend, N)
    assert chunks and all(a[0] <= b[0] for a, b in itertools.pairwise(chunks))
    raw = b"".join(data for _, data in chunks)
    if backend.driver.wire == "serial":
        again = StreamDecoder(backend.board).feed(raw)
    else:
        again = CanReassembler().feed((i, d) for i, d, foreign in split_can_records(raw)
                                      if not foreign)
    # the driver may hold frames decoded and not handed over yet: the tap's begin the same
    assert len(again) >= N
    # CAN refreshes one group of 8 duties per sample: a fresh decoder knows them all after
    # ceil(n / 8) samples (the driver may have known them before the tap was set)
    known = -(-backend.taxels // 8) if backend.driver.wire == "can" else 0
    for k, (a, b) in enumerate(zip(again, frames, strict=False)):
        same_frame(a, b)
        assert a.flags == b.flags and a.board == b.board
        assert k < known or np.array_equal(a.duty, b.duty)

"""The firmware's force inputs (SKIN_FORCE_INPUTS), run in simavr: FORCE after each SAMPLE.

The ``uno_force`` build (``make -C firmware``) reads a force-sensing stage per taxel through a
second multiplexer; the harness feeds it the scene's force (scene version 2) as ADC voltages.
Nothing is mocked: the force comes from the firmware's own conversions, packing and UART.
"""

import numpy as np
import pytest

from skin import drivers
from skin.drivers.avr_sim import EmulatedBoard, firmware_elf, parse_timing, write_scene
from skin.drivers.protocol import OPTION_FORCE, Command, Identity, MsgType, cobs_decode
from skin.errors import DeviceError
from skin.frame import FLAG_SAMPLE_OVERRUN, FLAG_TX_OVERRUN

pytestmark = pytest.mark.slow
RATE, TAXELS, FULL_N = 200.0, 16, 20.0
STEP_N = FULL_N / 1023  # one 10-bit ADC step


def scene(tmp_path, seconds: float, force: np.ndarray | None):
    n = int(seconds * RATE)
    temps = np.full((n, TAXELS), 35.0)
    return write_scene(tmp_path / "scene.bin", temps, np.full(n, 24.0), RATE, 0.0, 30.0, 5.0,
                       force=None if force is None else force[:n])


def test_the_force_build_sends_the_injected_force_after_each_sample(firmware_built, tmp_path):
    seconds = 4.0
    n = int(seconds * RATE)
    force = np.tile(np.linspace(0.0, 18.0, TAXELS), (n, 1))
    force[n // 2:, 3] = 7.5  # taxel 3 pressed harder at 2 s
    force[n // 2:, 11] = 0.0  # taxel 11 released
    board = EmulatedBoard(firmware_elf("uno_force"), scene(tmp_path, seconds, force),
                          taxels=TAXELS, muxes=1, force_inputs=TAXELS, force_full_n=FULL_N,
                          wait_host=True)
    with board:
        driver = drivers.open(f"serial://{board.port}")
        try:
            ident = driver.request(Command(MsgType.IDENTIFY), timeout=10.0)
            assert isinstance(ident, Identity) and ident.options & OPTION_FORCE
            assert ident.rate_hz == 200 and ident.max_rate_hz >= 200
            frames = []
            while len(frames) < 600:
                frame = driver.recv(timeout=10.0)
                assert frame is not None, f"only {len(frames)} frames"
                frames.append(frame)
            stats = driver.stats
        finally:
            driver.close()
    assert np.all(np.diff([f.seq for f in frames]) == 1)
    # the 200 Hz budget holds: every period 5 ms, no sample or link overrun
    assert np.allclose(np.diff([f.device_time for f in frames]), 0.005, rtol=0.01)
    assert not any(f.flags & (FLAG_TX_OVERRUN | FLAG_SAMPLE_OVERRUN) for f in frames)
    assert stats.crc_errors == 0 and stats.malformed == 0 and stats.force_missing == 0
    assert stats.force_orphans <= 1  # the first FORCE, if it came in a read of its own
    with_force = [f for f in frames if f.force is not None]
    assert len(with_force) >= len(frames) - 1
    for f in with_force:
        k = int(f.device_time * RATE)
        # a scan may straddle a scene sample: the nearer of the two, within one ADC step
        err = min(np.max(np.abs(f.force - force[min(j, n - 1)])) for j in (k, k + 1))
        assert err <= STEP_N + 0.002, (f.seq, f.force, force[k])
    late = with_force[-1]
    assert late.device_time > 2.1
    assert late.force[3] == pytest.approx(7.5, abs=STEP_N) and late.force[11] == 0.0
    assert with_force[0].force[3] == pytest.approx(force[0, 3], abs=STEP_N)
    assert np.all(np.abs(late.counts - late.counts[0]) <= 8)  # the thermistors as before


def packet_types(raw: bytes) -> set[int]:
    types = set()
    for packet in raw.split(b"\x00")[1:-1]:  # the first may be cut
        body = cobs_decode(packet)[:-2]
        types.add(body[1])
    return types


def test_a_build_without_force_sends_no_force(firmware_built, tmp_path):
    from skin.bench.firmware import stream_bytes

    raw = stream_bytes(str(firmware_elf("uno")), "uno", 1.0, folder=str(tmp_path))
    assert len(raw) > 150 * 60
    types = packet_types(raw)  # (the first packet, the ACK, is skipped as maybe cut)
    assert MsgType.SAMPLE in types and types <= {MsgType.SAMPLE, MsgType.ACK}
    board = EmulatedBoard(firmware_elf("uno"), scene(tmp_path, 2.0, None), taxels=TAXELS,
                          muxes=1, wait_host=True)
    with board:
        driver = drivers.open(f"serial://{board.port}")
        try:
            ident = driver.request(Command(MsgType.IDENTIFY), timeout=10.0)
            assert not ident.options & OPTION_FORCE
            frames = [driver.recv(timeout=10.0) for _ in range(50)]
        finally:
            driver.close()
    assert all(f is not None and f.force is None for f in frames)
    # the shipped builds carry no timing marks (only `make -C firmware timing`'s do)
    assert parse_timing(board.log)["poll_n"] == 0


def test_the_force_build_streams_force_packets_of_the_right_size(firmware_built, tmp_path):
    from skin.bench.firmware import BUILDS

    assert BUILDS["uno_force"][3] == TAXELS
    n = int(2.0 * RATE)
    board = EmulatedBoard(firmware_elf("uno_force"),
                          scene(tmp_path, 2.0, np.full((n, TAXELS), 1.0)), taxels=TAXELS,
                          muxes=1, force_inputs=TAXELS, force_full_n=FULL_N, wait_host=True,
                          duration=1.0)
    import serial

    with board:
        port = serial.Serial(board.port, timeout=0.5)
        port.write(b"\x00")  # power the board up
        raw = b""
        while len(raw) < 100 * 120:
            chunk = port.read(4096)
            if not chunk:
                break
            raw += chunk
        port.close()
    packets = [cobs_decode(p)[:-2] for p in raw.split(b"\x00")[1:-1]]
    kinds = [p[1] for p in packets]
    # SAMPLE, FORCE, SAMPLE, FORCE ...: each FORCE right after its SAMPLE, the same seq
    start = kinds.index(MsgType.SAMPLE)
    pairs = list(zip(packets[start::2], packets[start + 1::2], strict=False))
    assert len(pairs) > 50
    for sample, force in pairs:
        assert (sample[1], force[1]) == (MsgType.SAMPLE, MsgType.FORCE)
        assert sample[2:6] == force[2:6] and len(force) == 8 + 2 * TAXELS


def test_skin_commission_on_a_recording_of_the_emulated_force_board(firmware_built, tmp_path,
                                                                    capsys):
    """Reference touches played to the uno_force firmware in simavr, recorded (MCAP) from its
    serial stream and commissioned: the touches are dated by the force the firmware read."""
    import json
    from dataclasses import replace

    from skin.cli import main as skin_main
    from skin.drivers.firmware_board import emulated_board, firmware_scene
    from skin.drivers.protocol import ALL_TAXELS
    from skin.drivers.recording import Recorder
    from skin.drivers.sim import SkinSimulator
    from skin.errors import DeviceError
    from skin.formats.calibration_file import load_calibration
    from skin.formats.scene import load_scene

    n = 4
    scene = load_scene("reference-touches")
    scene = replace(scene, force="force", touches=tuple(
        replace(tc, taxels=tuple(range(n))) for tc in scene.touches))
    cut = firmware_scene(scene, taxels=TAXELS)
    sim = SkinSimulator(cut)
    board = emulated_board(sim, folder=tmp_path, build="uno_force")
    path = tmp_path / "touches.mcap"
    with board, Recorder(path, cut.layout) as recorder:
        driver = drivers.open(f"serial://{board.port}")
        recorder.add_driver(driver)
        try:
            # the scene was simulated with every heater on; the firmware boots with them off
            driver.request(Command(MsgType.SET_DUTY, taxel=ALL_TAXELS, duty=255), timeout=5.0)
            try:
                while driver.recv(timeout=2.0) is not None or board.running:
                    pass
            except DeviceError:  # the harness ended with the scene and closed its pty
                pass
            stats = driver.stats
        finally:
            driver.close()
    assert stats.frames >= 52 * 200 and stats.force_missing == 0 and stats.crc_errors == 0
    cal = tmp_path / "cal.json"
    assert skin_main(["commission", "--port", f"replay://{path}?speed=0", "--touches",
                      "water,neoprene", "-o", str(cal), "--json"]) == 0
    out = capsys.readouterr()
    doc = json.loads(out.out)
    assert "force channel" in out.err
    assert doc["force_dated"] == 6 * n and doc["fitted"] == n and doc["ambiguous"] == 0
    _, fitted = load_calibration(cal).apply(cut.layout)
    eff = np.array([s.effusivity for s in fitted[:n]])
    assert np.all(np.abs(eff / sim.taxel_sensor.effusivity[:n] - 1) < 0.03)


def test_bench_firmware_measures_the_cycle_budget_with_and_without_force(firmware_make,
                                                                         firmware_built):
    """`skin bench firmware`'s measurement on the timing builds: the force build keeps the
    200 Hz budget (its scan under 95 % of the period, the main loop's time well inside it),
    its work per sample costs more than the plain build's, and its force is right."""
    from skin.bench.firmware import measure
    from skin.drivers.avr_sim import FIRMWARE_DIR

    elves = [str(firmware_elf(f"timing/{b}")) for b in ("uno", "uno_force")]
    proc = firmware_make(["-C", str(FIRMWARE_DIR), *elves])
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    plain, force = measure("uno", 1.0), measure("uno_force", 1.0)
    for r in (plain, force):
        assert r.frames >= 190 and r.scan_max < 0.95 * r.period_cycles
        assert r.poll_max < 0.5 * r.period_cycles
    assert force.frames_with_force >= force.frames - 1 and plain.frames_with_force == 0
    assert force.max_force_error_n <= FULL_N / 1023 + 0.002
    assert force.work_per_sample > plain.work_per_sample and force.scan_mean > plain.scan_mean
    assert force.bytes_per_sample == pytest.approx(112, abs=1)  # SAMPLE 68 + FORCE 44


def test_an_oversampling_1_force_board_keeps_its_advertised_max_rate(firmware_built,
                                                                     firmware_make, tmp_path):
    """IDENTITY's max_rate_hz holds: an oversampling-1 force build (16 taxels, 16 force inputs;
    the scan is short, so a force conversion's real cost, ~400 cycles not 256, and the main loop
    decide its rate) run at its advertised maximum loses no sample (no SAMPLE_OVERRUN, no
    TX_OVERRUN, no seq gap). Before the cycle formula it advertised 706 Hz and lost 421 of 773."""
    from skin.drivers.avr_sim import FIRMWARE_DIR
    from skin.drivers.bus_load import adc_max_rate

    proc = firmware_make(["-C", str(FIRMWARE_DIR), "build/uno_os1_force/skin_controller.elf"])
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    seconds = 1.2
    n = int(seconds * RATE) + 1
    board = EmulatedBoard(firmware_elf("uno_os1_force"),
                          scene(tmp_path, seconds, np.full((n, TAXELS), 5.0)),
                          taxels=TAXELS, muxes=1, force_inputs=TAXELS, force_full_n=FULL_N,
                          wait_host=True, duration=seconds)
    frames = []
    with board:
        driver = drivers.open(f"serial://{board.port}")
        try:
            ident = driver.request(Command(MsgType.IDENTIFY), timeout=10.0)
            rate = ident.max_rate_hz
            assert rate == adc_max_rate(TAXELS, 1, TAXELS)  # the same formula on the host
            assert rate < 706  # the old formula's, which the board could not keep
            driver.request(Command(MsgType.SET_RATE, rate_hz=rate), timeout=10.0)
            driver.request(Command(MsgType.SET_DUTY, taxel=0xFFFF, duty=128), timeout=10.0)
            while True:
                try:
                    frame = driver.recv(timeout=2.0)
                except DeviceError:  # the harness ends at --duration: its pty closes
                    break
                if frame is None:
                    if not board.running:
                        break
                    continue
                frames.append(frame)
        finally:
            driver.close()
    late = [f for f in frames if f.device_time > 0.3]  # after SET_RATE took effect
    assert len(late) > 0.8 * rate * (seconds - 0.4)
    assert not any(f.flags & FLAG_SAMPLE_OVERRUN for f in late)
    assert not any(f.flags & FLAG_TX_OVERRUN for f in late)
    seqs = np.array([f.seq for f in late])
    assert np.all(np.diff(seqs) == 1)

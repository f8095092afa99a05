"""The compiled skin controller firmware, run in simavr, read by the serial driver over a pty.

The sketches are built with Debian's arduino-mk (``make -C firmware``) and run by the harness
(``firmware/sim/skin_avr``) against scenes of thermistor temperatures; nothing is mocked: the
bytes come from the firmware's own ADC interrupts, controller and UART.
"""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from skin import drivers
from skin.drivers.avr_sim import (
    EmulatedBoard,
    firmware_elf,
    write_scene,
)
from skin.drivers.protocol import (
    ALL_TAXELS,
    Ack,
    Command,
    ErrorReply,
    Identity,
    MsgType,
    SelftestResult,
    cobs_encode,
    crc16,
)
from skin.errors import DeviceError, ProtocolError
from skin.frame import FLAG_SAMPLE_OVERRUN, FLAG_STREAMING, FLAG_TX_OVERRUN

pytestmark = pytest.mark.slow
C0, C1, R_REF, V_PLUS = 9.5594e-4, 2.6181e-4, 668.0, 5.06


def count_of(temp_c: float) -> float:
    """The 12-bit count the paper's divider gives at a thermistor temperature."""
    r = math.exp((1.0 / (temp_c + 273.15) - C0) / C1)
    return V_PLUS * R_REF / (R_REF + r) / 1.1 * 4095.0


class Board:
    """An emulated board with a driver on its port; frames read one at a time."""

    def __init__(self, tmp_path: Path, board: str = "uno", taxels: int = 16, muxes: int = 1,
                 temps: np.ndarray | None = None, seconds: float = 30.0,
                 swap: tuple[int, int] | None = None) -> None:
        rate = 200.0
        if temps is None:
            temps = np.full(taxels, 35.0)
            temps[3] = 30.0
        self.temps = np.asarray(temps, dtype=float)
        scene = tmp_path / f"scene_{board}.bin"
        write_scene(scene, np.tile(self.temps, (int(seconds * rate), 1)),
                    np.full(int(seconds * rate), 24.0), rate_hz=rate, nominal_duty=0.0,
                    heater_rise=30.0, heater_tau=5.0)
        mcu = "atmega2560" if board.startswith("mega") else "atmega328p"
        self.emulator = EmulatedBoard(firmware_elf(board), scene, taxels=taxels, muxes=muxes,
                                      mcu=mcu, swap=swap)

    def __enter__(self) -> "Board":
        port = self.emulator.start()
        self.driver = drivers.open(f"serial://{port}")
        # the board streamed before the port was opened: skip to the first whole frame
        self.first = self.driver.recv(timeout=10.0)
        assert self.first is not None, "no frame from the emulated board"
        self.errors_at_start = self.driver.stats.crc_errors + self.driver.stats.malformed
        return self

    def __exit__(self, *exc: object) -> None:
        self.driver.close()
        self.emulator.close()

    def frames(self, n: int) -> list:
        out = []
        while len(out) < n:
            frame = self.driver.recv(timeout=10.0)
            assert frame is not None, f"only {len(out)} of {n} frames arrived"
            out.append(frame)
        return out

    def errors(self) -> int:
        return self.driver.stats.crc_errors + self.driver.stats.malformed - self.errors_at_start


def test_uno_streams_at_200_hz_every_frame_valid_and_the_counts_right(firmware_built, tmp_path):
    with Board(tmp_path) as board:
        frames = board.frames(400)
        t = np.array([f.device_time for f in frames])
        seq = np.array([f.seq for f in frames])
        assert np.all(np.diff(seq) == 1)
        period = np.diff(t)
        assert np.all(np.abs(period - 0.005) <= 0.005 * 0.01), (period.min(), period.max())
        assert (t[-1] - t[0]) / (len(t) - 1) == pytest.approx(0.005, rel=1e-3)
        assert board.errors() == 0, board.driver.stats
        last = frames[-1]
        expect = np.array([count_of(v) for v in board.temps])
        assert np.all(np.abs(last.counts - expect) <= 8), (last.counts, expect.round())
        assert last.counts[3] < last.counts[2] - 200  # the cooler taxel, at its own address
        assert last.ambient == pytest.approx(24.0, abs=0.15)
        assert last.flags & FLAG_STREAMING and not last.flags & 0x0F
        assert not np.any(last.status) and not np.any(last.duty)


def test_identify_answers_with_the_build(firmware_built, tmp_path):
    with Board(tmp_path) as board:
        reply = board.driver.request(Command(MsgType.IDENTIFY), timeout=5.0)
        assert isinstance(reply, Identity)
        assert (reply.taxels, reply.mcu, reply.transport, reply.adc_bits) == (16, 1, 0, 12)
        assert (reply.oversampling, reply.rate_hz, reply.baud_div) == (4, 200, 10000)
        assert reply.options & 1 and reply.max_rate_hz >= 200


def test_set_duty_drives_the_heater_and_warms_its_own_thermistor(firmware_built, tmp_path):
    with Board(tmp_path) as board:
        before = board.frames(5)[-1].counts.astype(int)
        ack = board.driver.request(Command(MsgType.SET_DUTY, taxel=5, duty=255), timeout=5.0)
        assert isinstance(ack, Ack) and ack.command == MsgType.SET_DUTY
        frames = board.frames(200)  # 1 s
        assert frames[-1].duty[5] == 255 and not np.any(np.delete(frames[-1].duty, 5))
        rise = frames[-1].counts.astype(int) - before
        # 30 K x (1 - exp(-1 s / 5 s)) = 5.4 K: about 170 counts at 35 deg C
        assert rise[5] > 100, rise
        assert np.all(np.abs(np.delete(rise, 5)) <= 8), rise
        board.driver.request(Command(MsgType.SET_SETPOINT, taxel=ALL_TAXELS,
                                     count=int(count_of(40.0))), timeout=5.0)
        duty = board.frames(20)[-1].duty
        assert np.all(duty[[0, 1, 2, 3]] > 0)  # below the setpoint: the PI heats


def test_selftest_answers_and_finds_a_swapped_heater_pair(firmware_built, tmp_path):
    with Board(tmp_path, swap=(2, 4)) as board:
        ack = board.driver.request(Command(MsgType.SELFTEST, pulse_ms=200, duty=255),
                                   timeout=5.0)
        assert isinstance(ack, Ack)
        busy = board.driver.send(Command(MsgType.SELFTEST, pulse_ms=200, duty=255))
        with pytest.raises(ProtocolError, match=r"BUSY"):
            board.driver.wait_reply(busy.token, timeout=5.0)
        result = board.driver.wait_reply(ack.token, timeout=30.0, kind=SelftestResult)
        strongest = list(result.strongest)
        expect = list(range(16))
        expect[2], expect[4] = 4, 2
        assert strongest == expect
        response = np.asarray(result.response)
        assert np.all(np.delete(response, [2, 4]) > 20) and np.all(response[[2, 4]] < 8)


def test_malformed_commands_get_errors_and_streaming_goes_on(firmware_built, tmp_path):
    with Board(tmp_path) as board:
        port = board.driver._port  # write raw bytes, as a faulty host would
        good = Command(MsgType.SET_DUTY, token=9, taxel=1, duty=10).body()
        bad_crc = good + (crc16(good) ^ 0x0101).to_bytes(2, "little")
        port.write(cobs_encode(bad_crc) + b"\x00")
        port.write(b"\x05\x01\x7f\x09\x00")  # not even a whole header
        unknown = bytes([1, 0x42, 7])
        port.write(cobs_encode(unknown + crc16(unknown).to_bytes(2, "little")) + b"\x00")
        frames = board.frames(60)
        errors = [r for r in board.driver.replies if isinstance(r, ErrorReply)]
        board.driver.replies.clear()
        codes = [r.name for r in errors]
        assert len(errors) == 3 and codes[0] == "ERR_CRC" and codes[2] == "ERR_TYPE", codes
        assert codes[1] in ("ERR_FRAMING", "ERR_LENGTH", "ERR_CRC"), codes
        out_of_range = board.driver.send(Command(MsgType.SET_DUTY, taxel=99, duty=1))
        with pytest.raises(ProtocolError, match="ARGUMENT"):
            board.driver.wait_reply(out_of_range.token, timeout=5.0)
        frames += board.frames(60)
        seq = np.array([f.seq for f in frames])
        assert np.all(np.diff(seq) == 1), "streaming stopped or lost frames"
        assert not np.any(frames[-1].duty)  # the damaged SET_DUTY was not carried out


def test_set_rate_changes_the_sample_period(firmware_built, tmp_path):
    with Board(tmp_path) as board:
        board.driver.request(Command(MsgType.SET_RATE, rate_hz=100), timeout=5.0)
        # frames sampled at 200 Hz before the command took effect may still be on their way
        # (a few on a quiet machine, more on a loaded one): the period after them is 10 ms
        period = np.diff([f.device_time for f in board.frames(60)])
        old = np.flatnonzero(~np.isclose(period, 0.010, rtol=0.01))
        start = int(old.max()) + 1 if old.size else 0
        assert start <= 20 and period.size - start >= 39  # then 100 Hz, every frame
        with pytest.raises(ProtocolError, match="ARGUMENT"):
            board.driver.request(Command(MsgType.SET_RATE, rate_hz=5000), timeout=5.0)


def test_mega_streams_72_taxels_through_five_multiplexers_with_every_heater_on(
        firmware_built, tmp_path):
    temps = 30.0 + 0.15 * np.arange(72)  # 0.15 K apart: about 9 counts, 2 ADC steps
    with Board(tmp_path, board="mega", taxels=72, muxes=5, temps=temps) as board:
        frames = board.frames(200)
        expect = np.array([count_of(v) for v in temps])
        assert np.all(np.abs(frames[-1].counts - expect) <= 8), frames[-1].counts - expect
        assert np.all(np.diff(frames[-1].counts.astype(int)) > 0)  # every taxel in its place
        # every heater on: the heaviest sample (all 72 switched, the PI idle) still fits
        board.driver.request(Command(MsgType.SET_DUTY, taxel=ALL_TAXELS, duty=255), timeout=5.0)
        frames += board.frames(400)
        assert np.all(np.diff([f.seq for f in frames]) == 1) and board.errors() == 0
        assert np.allclose(np.diff([f.device_time for f in frames]), 0.005, rtol=0.01)
        assert np.all(frames[-1].duty == 255)
        assert not any(f.flags & (FLAG_TX_OVERRUN | FLAG_SAMPLE_OVERRUN) for f in frames)
        assert frames[-1].counts[0] > frames[199].counts[0] + 100  # and they warm


def test_a_missing_firmware_build_is_named(tmp_path):
    board = EmulatedBoard(tmp_path / "nope.elf", tmp_path / "scene.bin", taxels=1, muxes=0)
    with pytest.raises(DeviceError, match=r"nope\.elf|skin_avr"):
        board.start()


def test_skin_run_with_the_firmware_in_the_loop(firmware_built, tmp_path):
    import json

    proc = subprocess.run(
        [str(Path(sys.executable).with_name("skin")), "run", "--firmware-sim", "--speed", "0",
         "--duration", "6", "--no-map", "--json", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-4000:]
    summary = json.loads(proc.stdout)
    # the board powers up on the host's first command: every sample arrives
    assert summary["frames"] >= 6 * 200 - 2 and summary["gaps"] == 0
    assert summary["crc_errors"] == 0 and summary["malformed"] == 0
    assert summary["touches"] >= 3 and summary["detected"] == summary["touches"]
    assert (tmp_path / "scene.bin").is_file()

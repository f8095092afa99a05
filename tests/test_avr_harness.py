"""The simavr harness (firmware/sim/skin_avr.c) run on its own AVR test program over a real pty.

The test program (firmware/sim/testprog/testprog.c) uses the board wiring of firmware/README.md:
it moves the multiplexer select lines, converts ADC channels with the internal 1.1 V reference,
shifts heater bytes over SPI and pulses the latch PB0, and answers on UART0.
"""

import math
import os
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from skin.drivers.avr_sim import DEFAULT_HARNESS, FIRMWARE_DIR, EmulatedBoard, write_scene
from skin.errors import DeviceError

serial = pytest.importorskip("serial")

C0, C1, R_REF, V_PLUS = 9.5594e-4, 2.6181e-4, 668.0, 5.06
REQUIRE = os.environ.get("SKIN_REQUIRE_FIRMWARE") == "1"


def _missing_tools() -> str | None:
    for tool in ("make", "cc", "avr-gcc"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed"
    if not Path("/usr/include/simavr/sim_avr.h").exists():
        pkg = shutil.which("pkg-config")
        if pkg is None or subprocess.run([pkg, "--exists", "simavr"]).returncode != 0:
            return "simavr's headers (libsimavr-dev) are not installed"
    return None


@dataclass
class Builds:
    harness: Path
    elf: dict[str, Path]


@pytest.fixture(scope="module")
def builds(tmp_path_factory, firmware_make) -> Builds:
    reason = _missing_tools()
    if reason:
        if REQUIRE:
            pytest.fail(f"SKIN_REQUIRE_FIRMWARE=1 but {reason}")
        pytest.skip(f"the simavr harness cannot be built: {reason}")
    out = tmp_path_factory.mktemp("testprog")
    proc = firmware_make(["-C", str(FIRMWARE_DIR), "-f", "sim/sim.mk", "harness", "testprog",
                          f"TESTPROG_DIR={out}"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    mcus = ("atmega328p", "atmega2560")
    return Builds(DEFAULT_HARNESS, {mcu: out / f"testprog_{mcu}.elf" for mcu in mcus})


def count_of_temperature(temp_c: float) -> int:
    """The 10-bit count simavr gives for a thermistor at temp_c (1.1 V reference, whole mV)."""
    r = math.exp((1.0 / (temp_c + 273.15) - C0) / C1)
    mv = round(V_PLUS * R_REF / (R_REF + r) * 1000.0)
    return min(mv * 1023 // 1100, 1023)


def count_of_ambient(temp_c: float) -> int:
    return min(round(temp_c * 10.0) * 1023 // 1100, 1023)


def temperature_of_count(count: int) -> float:
    v = count * 1.1 / 1023
    r = R_REF * (V_PLUS - v) / v
    return 1.0 / (C0 + C1 * math.log(r)) - 273.15


class ProgLink:
    """The host side of testprog.c's commands."""

    def __init__(self, port: str) -> None:
        self.s = serial.Serial(port, timeout=5.0)
        self.s.write(b"P")
        got = b""
        while not got.endswith(b"P"):  # skips READY\n if it is still there
            byte = self.s.read(1)
            assert byte, f"no answer to ping (got {got!r})"
            got += byte

    def _reply(self, n: int) -> bytes:
        data = self.s.read(n)
        assert len(data) == n, f"short reply {data!r}"
        return data

    def adc(self, sel: int, ch: int) -> int:
        self.s.write(bytes([ord("A"), sel, ch]))
        reply = self._reply(3)
        assert reply[:1] == b"A"
        return int.from_bytes(reply[1:], "little")

    def taxel(self, t: int, muxes: int) -> int:
        return self.adc(t % 16, t // 16) if muxes else self.adc(0, t)

    def adc_moving(self, sel: int, ch: int, next_sel: int) -> int:
        self.s.write(bytes([ord("Q"), sel, ch, next_sel]))
        reply = self._reply(3)
        assert reply[:1] == b"Q"
        return int.from_bytes(reply[1:], "little")

    def heaters(self, on: set[int], n_taxels: int) -> None:
        groups = [0] * ((n_taxels + 7) // 8)
        for i in on:
            groups[i // 8] |= 1 << (i % 8)
        shifted = bytes(reversed(groups))  # the byte of heaters 0-7 goes last
        self.s.write(bytes([ord("H"), len(shifted)]) + shifted)
        assert self._reply(1) == b"H"

    def wait_ms(self, ms: int) -> None:
        self.s.write(b"W" + ms.to_bytes(2, "little"))
        assert self._reply(1) == b"W"

    def close(self) -> None:
        self.s.close()


def constant_scene(path: Path, temps: np.ndarray, ambient: float, *, seconds: float = 60.0,
                   rate: float = 10.0, nominal: float = 0.0, rise: float = 0.0,
                   tau: float = 0.02) -> Path:
    n = round(seconds * rate)
    return write_scene(path, np.tile(temps, (n, 1)), np.full(n, ambient), rate, nominal, rise,
                       tau)


def test_adc_reads_each_taxel_through_the_multiplexer(builds, tmp_path):
    temps = 24.0 + 2.5 * np.arange(16)
    scene = constant_scene(tmp_path / "s.sksc", temps, ambient=23.4)
    with EmulatedBoard(builds.elf["atmega328p"], scene, taxels=16, muxes=1) as board:
        prog = ProgLink(board.port)
        got = [prog.taxel(t, muxes=1) for t in range(16)]
        ambient = prog.adc(0, 1)
        # the select lines move on during the conversion: the sample-and-hold keeps taxel 3
        moved = prog.adc_moving(3, 0, 12)
        prog.close()
    expected = [count_of_temperature(t) for t in temps]
    assert np.abs(np.array(got) - expected).max() <= 1, (got, expected)
    assert abs(ambient - count_of_ambient(23.4)) <= 1
    assert abs(moved - expected[3]) <= 1
    assert board.returncode == 0 and "bytes out" in (board.summary or "")


def test_mega_with_five_multiplexers_maps_taxel_t_to_mux_t_div_16(builds, tmp_path):
    temps = 22.0 + 0.5 * np.arange(72)
    scene = constant_scene(tmp_path / "s.sksc", temps, ambient=31.0)
    with EmulatedBoard(builds.elf["atmega2560"], scene, mcu="atmega2560", taxels=72,
                       muxes=5) as board:
        prog = ProgLink(board.port)
        picks = [0, 15, 16, 33, 47, 50, 64, 71]
        got = [prog.taxel(t, muxes=5) for t in picks]
        ambient = prog.adc(0, 5)
        unconnected = prog.adc(8, 4)  # taxel 72 does not exist
        prog.close()
    expected = [count_of_temperature(temps[t]) for t in picks]
    assert np.abs(np.array(got) - expected).max() <= 1, (got, expected)
    assert abs(ambient - count_of_ambient(31.0)) <= 1
    assert unconnected == 0


def test_static_selection_sees_the_scene_move_on(builds, tmp_path):
    rate, seconds = 20.0, 120.0
    n = round(rate * seconds)
    ramp = 25.0 + 5.0 * np.arange(n) / rate / 10.0  # 0.5 K per emulated second
    temps = np.repeat(ramp[:, None], 16, axis=1)
    scene = write_scene(tmp_path / "s.sksc", temps, np.full(n, 22.0), rate, 0.0, 0.0, 0.02)
    with EmulatedBoard(builds.elf["atmega328p"], scene, taxels=16, muxes=1) as board:
        prog = ProgLink(board.port)
        before = temperature_of_count(prog.taxel(7, muxes=1))
        prog.wait_ms(4000)
        after = temperature_of_count(prog.taxel(7, muxes=1))
        prog.close()
    # 4 s at 0.5 K/s, within a scene sample (0.025 K), the commands' time and the ADC's step
    assert after - before == pytest.approx(2.0, abs=0.15)


@pytest.mark.parametrize("swap", [None, (5, 9)])
def test_heater_chain_latches_and_warms_the_right_thermistor(builds, tmp_path, swap):
    base, rise, nominal = 30.0, 8.0, 0.25
    scene = constant_scene(tmp_path / "s.sksc", np.full(16, base), ambient=22.0,
                           nominal=nominal, rise=rise, tau=0.02)
    cold = count_of_temperature(base - rise * nominal)
    hot = count_of_temperature(base + rise * (1.0 - nominal))
    with EmulatedBoard(builds.elf["atmega328p"], scene, taxels=16, muxes=1, swap=swap) as board:
        prog = ProgLink(board.port)
        prog.wait_ms(200)  # ten time constants with every heater off
        before = [prog.taxel(t, muxes=1) for t in range(16)]
        prog.heaters({5, 10}, 16)
        prog.wait_ms(200)
        heated = [prog.taxel(t, muxes=1) for t in range(16)]
        prog.heaters(set(), 16)
        prog.wait_ms(200)
        after = [prog.taxel(t, muxes=1) for t in range(16)]
        prog.close()
    warmed = {9, 10} if swap else {5, 10}
    assert np.abs(np.array(before) - cold).max() <= 1
    assert np.abs(np.array(after) - cold).max() <= 1
    for t in range(16):
        assert abs(heated[t] - (hot if t in warmed else cold)) <= 1, (t, heated)
    assert "2 latches" in (board.summary or "")


def test_back_pressure_holds_the_emulation_and_loses_no_bytes(builds, tmp_path):
    scene = constant_scene(tmp_path / "s.sksc", np.full(16, 30.0), ambient=22.0, seconds=300.0)
    kib = 384
    with EmulatedBoard(builds.elf["atmega328p"], scene, taxels=16, muxes=1) as board:
        prog = ProgLink(board.port)
        prog.s.write(b"B" + kib.to_bytes(2, "little"))
        time.sleep(1.5)  # far more than the pty holds is waiting to be sent
        fd = prog.s.fileno()
        data = bytearray()
        deadline = time.monotonic() + 8.0
        while len(data) < kib * 1024 + 2 and time.monotonic() < deadline:
            data += os.read(fd, 1 << 20)
        prog.close()
    assert len(data) == kib * 1024 + 2
    assert data[:1] == b"B" and data[-1:] == b"E"
    i = np.arange(kib * 1024)
    assert np.array_equal(np.frombuffer(bytes(data[1:-1]), np.uint8), (i + (i >> 8)) & 0xFF)
    waited = float((board.summary or "").split("waited ")[1].split(" s")[0])
    assert waited > 1.0, board.summary


def test_uart_bytes_take_ten_bit_times_at_1_mbaud(builds, tmp_path):
    scene = constant_scene(tmp_path / "s.sksc", np.full(16, 30.0), ambient=22.0)
    n = 2000
    with EmulatedBoard(builds.elf["atmega328p"], scene, taxels=16, muxes=1) as board:
        prog = ProgLink(board.port)
        prog.s.write(b"U" + n.to_bytes(2, "little"))
        data = prog._reply(n + 3)
        prog.close()
    assert data[:n] == b"\x55" * n and data[n : n + 1] == b"U"
    # 8N1: 10 bits of 1 us each (simavr alone counts 11, a parity bit). simavr's UART has no
    # transmit double buffer: a polling sender adds its loop's latency (~0.5 us) to every byte.
    per_byte_us = int.from_bytes(data[n + 1 :], "little") * 4.0 / n
    assert 10.0 <= per_byte_us < 10.8


def test_ends_at_the_end_of_the_scene_with_a_summary(builds, tmp_path):
    scene = constant_scene(tmp_path / "s.sksc", np.full(16, 30.0), ambient=22.0, seconds=0.5)
    board = EmulatedBoard(builds.elf["atmega328p"], scene, taxels=16, muxes=1)
    board.start()
    assert board.wait(timeout=10.0) == 0
    assert "end of scene: emulated 0.500 s, 800000" in (board.summary or "")
    board.close()


def test_duration_and_realtime_pace_the_emulation(builds, tmp_path):
    scene = constant_scene(tmp_path / "s.sksc", np.full(16, 30.0), ambient=22.0, seconds=10.0)
    board = EmulatedBoard(builds.elf["atmega328p"], scene, taxels=16, muxes=1, duration=0.6,
                          realtime=1.0)
    t0 = time.monotonic()
    with board:
        assert board.wait(timeout=10.0) == 0
    assert time.monotonic() - t0 >= 0.55
    assert "end of --duration: emulated 0.600 s" in (board.summary or "")


def test_missing_harness_or_elf_names_the_file_and_the_build(tmp_path):
    scene = constant_scene(tmp_path / "s.sksc", np.full(4, 30.0), ambient=22.0, seconds=1.0)
    missing = tmp_path / "nowhere" / "skin_avr"
    with pytest.raises(DeviceError, match=r"nowhere/skin_avr.*make -C firmware"):
        EmulatedBoard(tmp_path / "x.elf", scene, taxels=4, muxes=0, harness=missing).start()
    fake_harness = tmp_path / "skin_avr"
    fake_harness.write_text("#!/bin/sh\n")
    board = EmulatedBoard(tmp_path / "fw.elf", scene, taxels=4, muxes=0, harness=fake_harness)
    with pytest.raises(DeviceError, match=r"fw\.elf.*make -C firmware"):
        board.start()
    board.close()
    board.close()


def test_write_scene_layout(tmp_path):
    temps = np.arange(6, dtype=float).reshape(3, 2)
    path = write_scene(tmp_path / "s.sksc", temps, [20.0, 21.0, 22.0], 200.0, 0.3, 5.0, 1.5)
    raw = path.read_bytes()
    assert raw[:4] == b"SKSC"
    assert np.frombuffer(raw[4:16], "<u4").tolist() == [1, 2, 3]
    assert np.frombuffer(raw[16:32], "<f4").tolist() == pytest.approx([200.0, 0.3, 5.0, 1.5])
    body = np.frombuffer(raw[32:], "<f4")
    assert body[:6].tolist() == temps.ravel().tolist() and body[6:].tolist() == [20, 21, 22]
    with pytest.raises(ValueError, match="ambient"):
        write_scene(tmp_path / "t.sksc", temps, [20.0], 200.0, 0.3, 5.0, 1.5)

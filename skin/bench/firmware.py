"""``skin bench firmware``: the AVR firmware's cycle budget per sample, measured in simavr.

Each build of ``firmware/Makefile`` runs in the harness (``firmware/sim/skin_avr``) on a scene
(thermistors at 35 deg C; on a build with force inputs a force of 0 - 19 N changing per taxel
and over time) while the serial driver reads its stream. The firmware marks its work in GPIOR0
(two cycles per mark, only in the builds of ``make -C firmware timing``). The harness times,
in CPU cycles of the emulated 16 MHz MCU: the main loop's work on each sample (heater control,
packing, COBS and CRC, queueing the packets; interrupts that fire meanwhile included), the time
it waits in it for the previous packet to leave the UART, and each scan's conversions (timer
interrupt to the last ADC interrupt). Emulated cycles are deterministic: the figures do not
depend on the host's load.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from skin.errors import DeviceError, SkinError

#: Builds measured: name in firmware/Makefile -> (MCU, taxels, multiplexers, force inputs).
BUILDS = {
    "uno": ("atmega328p", 16, 1, 0),
    "uno_force": ("atmega328p", 16, 1, 16),
    "mega": ("atmega2560", 72, 5, 0),
}
F_CPU = 16_000_000
FORCE_FULL_N = 20.0  # SKIN_FORCE_FULL_MN's default


@dataclass
class FirmwareTiming:
    """One build's cycles per sample (see the module docstring)."""

    build: str
    taxels: int
    force_inputs: int
    rate_hz: float
    frames: int
    frames_with_force: int
    max_force_error_n: float
    scan_mean: float
    scan_max: float
    poll_mean: float
    poll_max: float
    wait_per_sample: float
    work_per_sample: float
    period_cycles: float
    bytes_per_sample: float

    def as_dict(self) -> dict:
        """Return the fields as a JSON-ready dict."""
        return asdict(self)


def scene_force(n_samples: int, taxels: int, rate: float) -> np.ndarray:
    """Return the bench scene's force, N.

    Taxel t presses 0.75 t N, every second taxel twice that in the second half (capped at 95 %
    of the full scale).
    """
    force = np.tile(0.75 * np.arange(taxels), (n_samples, 1))
    force[n_samples // 2:, ::2] *= 2.0
    return np.minimum(force, 0.95 * FORCE_FULL_N)


def measure(build: str, seconds: float = 3.0, folder: str | None = None) -> FirmwareTiming:
    """Run one build in the emulator for `seconds` of emulated time and read its timing.

    Parameters
    ----------
    build : str
        A key of `BUILDS`.
    seconds : float
        Emulated seconds.
    folder : str, optional
        Where to write the scene (a temporary folder by default).

    Returns
    -------
    FirmwareTiming
        The build's figures.

    Raises
    ------
    SkinError
        If the build is unknown, or the harness or the build is missing.
    """
    import tempfile
    from pathlib import Path

    from skin import drivers
    from skin.drivers.avr_sim import EmulatedBoard, firmware_elf, parse_timing, write_scene
    from skin.drivers.protocol import Command, MsgType

    if build not in BUILDS:
        raise SkinError(f"unknown firmware build {build!r}; choose from {', '.join(BUILDS)}")
    mcu, taxels, muxes, n_force = BUILDS[build]
    rate = 200.0
    n = int(seconds * rate) + 1
    where = Path(folder or tempfile.mkdtemp(prefix="skin-bench-firmware-"))
    force = scene_force(n, taxels, rate)
    scene = write_scene(where / f"{build}.bin", np.full((n, taxels), 35.0), np.full(n, 24.0),
                        rate, 0.0, 30.0, 5.0, force=force if n_force else None)
    elf = firmware_elf(f"timing/{build}")
    if not elf.is_file():
        raise SkinError(f"{elf} not found: `make -C firmware timing harness` builds the boards "
                        "with the timing marks this bench reads")
    board = EmulatedBoard(elf, scene, taxels=taxels, muxes=muxes, mcu=mcu,
                          force_inputs=n_force, force_full_n=FORCE_FULL_N, wait_host=True,
                          duration=seconds)
    frames = []
    with board:
        driver = drivers.open(f"serial://{board.port}")
        try:
            driver.request(Command(MsgType.SET_DUTY, taxel=0xFFFF, duty=128), timeout=10.0)
            deadline = time.monotonic() + 60.0 + 20.0 * seconds
            while time.monotonic() < deadline:
                try:
                    frame = driver.recv(timeout=1.0)
                except DeviceError:  # the harness ending (end of --duration) closes its pty
                    end = time.monotonic() + 5.0
                    while board.running and time.monotonic() < end:
                        time.sleep(0.05)
                    if board.running:
                        raise
                    break
                if frame is None and not board.running:
                    break
                if frame is not None:
                    frames.append(frame)
            received = driver.stats.bytes
        finally:
            driver.close()
    timing = parse_timing(board.log or "")
    with_force = [f for f in frames if f.force is not None]
    err = 0.0
    for f in with_force:  # a scan may straddle a scene sample: the nearer of the two
        k = int(f.device_time * rate)
        near = min(float(np.max(np.abs(f.force[:n_force] - force[min(j, n - 1), :n_force])))
                   for j in (k, k + 1))
        err = max(err, near)
    samples = max(timing["poll_n"], 1.0)
    wait = timing["wait_mean"] * timing["wait_n"] / samples
    return FirmwareTiming(
        build=build, taxels=taxels, force_inputs=n_force, rate_hz=rate, frames=len(frames),
        frames_with_force=len(with_force), max_force_error_n=round(err, 4),
        scan_mean=timing["scan_mean"], scan_max=timing["scan_max"],
        poll_mean=timing["poll_mean"], poll_max=timing["poll_max"],
        wait_per_sample=round(wait, 1), work_per_sample=round(timing["poll_mean"] - wait, 1),
        period_cycles=F_CPU / rate, bytes_per_sample=round(received / max(len(frames), 1), 1))


def stream_bytes(elf: str, build: str, seconds: float = 2.0, folder: str | None = None) -> bytes:
    """Every byte a firmware ELF sends in `seconds` of emulated time, raw from its pty.

    The board powers up on the host's first write, a SET_DUTY of every heater to 128 (so the
    stream holds heater control too); the scene is `measure`'s (no force); reading stops once
    ``seconds * 200`` packets arrived. Emulation is
    deterministic, so two builds that send the same bytes give the same stream.

    Parameters
    ----------
    elf : str
        The firmware ELF (e.g. main's build of the same board, to check that a change leaves a
        build without force byte for byte as it was).
    build : str
        A key of `BUILDS`: the board the ELF was built for.
    seconds : float
        Emulated seconds.
    folder : str, optional
        Where to write the scene.

    Returns
    -------
    bytes
        The stream (its end may cut a packet: compare whole packets, see `same_packets`).
    """
    import tempfile
    from pathlib import Path

    import serial

    from skin.drivers.avr_sim import EmulatedBoard, write_scene
    from skin.drivers.protocol import Command, MsgType, frame_packet

    mcu, taxels, muxes, _ = BUILDS[build]
    rate = 200.0
    want = int(seconds * rate)  # packets: read until this many, while the board goes on
    n = want + int(2 * rate)
    where = Path(folder or tempfile.mkdtemp(prefix="skin-bench-firmware-"))
    scene = write_scene(where / f"{build}_raw.bin", np.full((n, taxels), 35.0),
                        np.full(n, 24.0), rate, 0.0, 30.0, 5.0)
    board = EmulatedBoard(elf, scene, taxels=taxels, muxes=muxes, mcu=mcu, wait_host=True)
    out = bytearray()
    with board:
        port = serial.Serial(board.port, timeout=0.2)
        try:
            port.write(frame_packet(Command(MsgType.SET_DUTY, token=1, taxel=0xFFFF,
                                            duty=128).body()))
            deadline = time.monotonic() + 30.0 + 10.0 * seconds
            while out.count(0) < want and time.monotonic() < deadline:
                try:
                    out += port.read(65536)
                except (OSError, serial.SerialException):
                    break  # the harness ended (the scene's end) and closed its pty
        finally:
            port.close()
    return bytes(out)


def same_packets(a: bytes, b: bytes, expect: int) -> dict:
    """Compare the first `expect` packets of two streams, packet by packet.

    A fixed count, so that the figure does not depend on how many bytes a pty read returned.

    Parameters
    ----------
    a, b : bytes
        Streams (`stream_bytes`).
    expect : int
        Packets to compare (a stream with fewer whole packets: not ``identical``).

    Returns
    -------
    dict
        ``packets`` compared (at most `expect`), ``identical`` (`expect` packets, all equal),
        ``first_difference`` (packet index, or None).
    """
    pa, pb = a.split(b"\x00")[:-1], b.split(b"\x00")[:-1]
    n = min(len(pa), len(pb), expect)
    first = next((i for i in range(n) if pa[i] != pb[i]), None)
    return {"packets": n, "identical": first is None and n >= expect, "first_difference": first}

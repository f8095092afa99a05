"""The compiled firmware run in simavr: scene files for the harness and a board on a pty.

``firmware/sim/skin_avr`` (built by ``make -C firmware -f sim/sim.mk harness``) runs an AVR ELF
against a scene: thermistor temperatures per taxel per sample, an ambient temperature, and the
heaters' first-order response; UART0 appears on a pseudo-terminal. `EmulatedBoard` starts it and
hands over the pty path, which any serial driver opens like a real board's port.
"""

from __future__ import annotations

import os
import signal
import subprocess
import tempfile
import time
from pathlib import Path
from types import TracebackType
from typing import IO

import numpy as np
from numpy.typing import ArrayLike

from skin.errors import DeviceError

__all__ = ["DEFAULT_HARNESS", "FIRMWARE_DIR", "EmulatedBoard", "firmware_elf", "parse_timing",
           "write_scene"]

FIRMWARE_DIR = Path(__file__).resolve().parents[1] / "firmware"
"""The ``firmware/`` folder of a source checkout (the builds live in its ``build/``)."""

DEFAULT_HARNESS = FIRMWARE_DIR / "build" / "host" / "skin_avr"
"""Where ``make -C firmware -f sim/sim.mk harness`` puts the harness."""

SCENE_MAGIC = b"SKSC"
SCENE_VERSION = 1
SCENE_VERSION_FORCE = 2  # version 1 followed by the force of every taxel at every sample


def firmware_elf(board: str = "uno", sketch: str = "skin_controller") -> Path:
    """Return the path of the skin_controller ELF that ``make -C firmware`` builds for a board.

    Parameters
    ----------
    board : str
        ``"uno"`` (ATmega328P), ``"mega"`` (ATmega2560), ``"uno_force"`` (the Uno with a force
        input per taxel), or another build of ``firmware/Makefile``.
    sketch : str
        ``"skin_controller"`` (serial) or ``"skin_can_node"``.

    Returns
    -------
    Path
        ``firmware/build/<board>/<sketch>.elf`` (which may not exist yet).
    """
    return FIRMWARE_DIR / "build" / board / f"{sketch}.elf"


def write_scene(
    path: str | os.PathLike[str],
    temperatures: ArrayLike,
    ambient: ArrayLike,
    rate_hz: float,
    nominal_duty: float,
    heater_rise: float,
    heater_tau: float,
    force: ArrayLike | None = None,
) -> Path:
    """Write a harness scene file (format version 1, or 2 with `force`; little-endian).

    Parameters
    ----------
    path : str or os.PathLike
        File to write.
    temperatures : array_like, shape (n_samples, n_taxels)
        Thermistor temperature of every taxel at every sample, deg C, with the heaters at their
        nominal duty.
    ambient : array_like, shape (n_samples,)
        Ambient temperature at every sample, deg C (the LM35 channel).
    rate_hz : float
        Sample rate of the scene; emulated time t reads sample ``floor(t * rate_hz)`` and the
        last sample holds after the end.
    nominal_duty : float
        Heater duty (0..1) that `temperatures` already include.
    heater_rise : float
        Rise of a taxel's temperature, K, with its heater always on rather than off.
    heater_tau : float
        Time constant of the heater's effect, s.
    force : array_like, shape (n_samples, n_taxels), optional
        Normal force on every taxel at every sample, N, for the force inputs of a board built
        with ``SKIN_FORCE_INPUTS`` (`EmulatedBoard` ``force_inputs``); written as version 2.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    ValueError
        If the shapes disagree or a parameter is out of range.
    """
    temps = np.asarray(temperatures, dtype="<f4")
    amb = np.asarray(ambient, dtype="<f4")
    if temps.ndim != 2 or temps.shape[0] < 1 or temps.shape[1] < 1:
        raise ValueError(f"temperatures must be (n_samples, n_taxels), got shape {temps.shape}")
    if amb.shape != (temps.shape[0],):
        raise ValueError(f"ambient must have shape ({temps.shape[0]},), got {amb.shape}")
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be positive, got {rate_hz}")
    if not 0.0 <= nominal_duty <= 1.0:
        raise ValueError(f"nominal_duty must be within 0..1, got {nominal_duty}")
    if heater_tau < 0:
        raise ValueError(f"heater_tau must not be negative, got {heater_tau}")
    n_samples, n_taxels = temps.shape
    tail = b""
    version = SCENE_VERSION
    if force is not None:
        forces = np.asarray(force, dtype="<f4")
        if forces.shape != temps.shape:
            raise ValueError(f"force must have the temperatures' shape {temps.shape}, "
                             f"got {forces.shape}")
        tail, version = forces.tobytes(), SCENE_VERSION_FORCE
    header = np.array([version, n_taxels, n_samples], dtype="<u4").tobytes()
    header += np.array([rate_hz, nominal_duty, heater_rise, heater_tau], dtype="<f4").tobytes()
    out = Path(path)
    out.write_bytes(SCENE_MAGIC + header + temps.tobytes() + amb.tobytes() + tail)
    return out


def parse_timing(log: str) -> dict[str, float]:
    """Read the harness's timing line: the firmware's GPIOR0 marks, in CPU cycles.

    Parameters
    ----------
    log : str
        The harness's stderr (`EmulatedBoard.log`).

    Returns
    -------
    dict
        ``poll_n``, ``poll_mean``, ``poll_max`` (the main loop's work on a sample: heater
        control, packing, framing, queueing the packets) and ``scan_n``, ``scan_mean``,
        ``scan_max`` (a scan's conversions, timer interrupt to the last ADC interrupt),
        ``wait_n``, ``wait_mean``, ``wait_max`` (the serial sketch waiting for its previous
        packet to leave: inside the main loop's time, but not work). Counts include replies.

    Raises
    ------
    ValueError
        If the log has no timing line.
    """
    import re

    m = re.search(r"timing: poll (\d+) marks, mean ([\d.]+) max (\d+) cycles; "
                  r"scan (\d+) marks, mean ([\d.]+) max (\d+) cycles; "
                  r"wait (\d+) marks, mean ([\d.]+) max (\d+) cycles", log)
    if m is None:
        raise ValueError("the harness log has no timing line (an older harness?)")
    keys = ("poll_n", "poll_mean", "poll_max", "scan_n", "scan_mean", "scan_max",
            "wait_n", "wait_mean", "wait_max")
    return {k: float(v) for k, v in zip(keys, m.groups(), strict=True)}


class EmulatedBoard:
    """A board whose firmware runs in simavr, its UART0 on a pseudo-terminal.

    Parameters
    ----------
    elf : str or os.PathLike
        The firmware ELF.
    scene : str or os.PathLike
        A scene file (`write_scene`).
    taxels : int
        Taxel count (the scene's).
    muxes : int
        Number of 16-channel multiplexers; 0 = taxels directly on the ADC channels.
    mcu : str
        ``"atmega328p"`` or ``"atmega2560"``.
    freq : int
        Clock frequency, Hz.
    swap : tuple of int, optional
        ``(i, j)``: heaters i and j warm each other's thermistor (a wiring error).
    force_inputs : int
        Taxels 0 .. force_inputs-1 have a force input (the build's ``SKIN_FORCE_INPUTS``), fed
        from the scene's force (version 2).
    force_full_n : float
        Force at the ADC's full scale, N (the build's ``SKIN_FORCE_FULL_MN`` / 1000).
    realtime : float, optional
        Pace emulated time to this multiple of real time (None: as fast as possible).
    duration : float, optional
        Stop after this many emulated seconds rather than at the end of the scene.
    wait_host : bool
        Power the board up when the host first writes to it, rather than at `start`: a host
        that opens the port (which empties its input) then misses none of the board's output.
    harness : str or os.PathLike, optional
        The harness executable (default `DEFAULT_HARNESS`, or ``$SKIN_AVR_HARNESS``).
    start_timeout : float
        Seconds to wait for the harness to announce its pty.

    Attributes
    ----------
    port : str or None
        The pty path once started.
    summary : str or None
        The harness's summary line (emulated seconds, cycles, bytes, real seconds) once closed.
    log : str or None
        Everything the harness wrote to stderr, once closed.
    returncode : int or None
        The harness's exit status once closed.
    """

    def __init__(
        self,
        elf: str | os.PathLike[str],
        scene: str | os.PathLike[str],
        *,
        taxels: int,
        muxes: int,
        mcu: str = "atmega328p",
        freq: int = 16_000_000,
        swap: tuple[int, int] | None = None,
        force_inputs: int = 0,
        force_full_n: float = 20.0,
        realtime: float | None = None,
        duration: float | None = None,
        wait_host: bool = False,
        harness: str | os.PathLike[str] | None = None,
        start_timeout: float = 10.0,
    ) -> None:
        env_harness = os.environ.get("SKIN_AVR_HARNESS")
        self.harness = Path(harness or env_harness or DEFAULT_HARNESS)
        self.elf = Path(elf)
        self.scene = Path(scene)
        self.args = ["--mcu", mcu, "--freq", str(int(freq)), "--elf", str(self.elf),
                     "--scene", str(self.scene), "--taxels", str(int(taxels)),
                     "--muxes", str(int(muxes))]
        if swap is not None:
            self.args += ["--swap", f"{int(swap[0])},{int(swap[1])}"]
        if force_inputs:
            self.args += ["--force-inputs", str(int(force_inputs)),
                          "--force-full-n", repr(float(force_full_n))]
        if realtime:
            self.args += ["--realtime", repr(float(realtime))]
        if duration:
            self.args += ["--duration", repr(float(duration))]
        if wait_host:
            self.args += ["--wait-host", "1"]
        self.start_timeout = start_timeout
        self.port: str | None = None
        self.summary: str | None = None
        self.log: str | None = None
        self.returncode: int | None = None
        self._proc: subprocess.Popen[bytes] | None = None
        self._stderr: IO[bytes] | None = None

    def start(self) -> str:
        """Launch the harness and return the pty path (also in `port`).

        Returns
        -------
        str
            The pseudo-terminal to open as the board's serial port.

        Raises
        ------
        DeviceError
            If the harness, the ELF or the scene is missing, or the harness fails to start.
        """
        if self._proc is not None:
            raise DeviceError("emulated board: already started")
        if not self.harness.is_file():
            raise DeviceError(f"simavr harness not found: {self.harness} (build it with "
                              f"`make -C firmware -f sim/sim.mk harness`; `make -C firmware` "
                              f"builds the firmware)")
        if not self.elf.is_file():
            raise DeviceError(f"firmware ELF not found: {self.elf} (`make -C firmware` builds it)")
        if not self.scene.is_file():
            raise DeviceError(f"scene file not found: {self.scene} (write one with write_scene)")
        self._stderr = tempfile.TemporaryFile()
        self._proc = subprocess.Popen([str(self.harness), *self.args], stdout=subprocess.PIPE,
                                      stderr=self._stderr, stdin=subprocess.DEVNULL)
        assert self._proc.stdout is not None
        line = self._read_line(self._proc.stdout, self.start_timeout)
        if not line.startswith("PTY "):
            self.close()
            raise DeviceError(f"simavr harness did not start: {self.summary or line!r}")
        self.port = line[4:].strip()
        return self.port

    @staticmethod
    def _read_line(stream: IO[bytes], timeout: float) -> str:
        fd = stream.fileno()
        os.set_blocking(fd, False)
        buf = b""
        deadline = time.monotonic() + timeout
        while b"\n" not in buf and time.monotonic() < deadline:
            try:
                chunk = os.read(fd, 256)
            except BlockingIOError:
                time.sleep(0.005)
                continue
            if not chunk:
                break
            buf += chunk
        return buf.decode(errors="replace").split("\n", 1)[0]

    @property
    def running(self) -> bool:
        """Whether the harness process is still running."""
        return self._proc is not None and self._proc.poll() is None

    def wait(self, timeout: float | None = None) -> int:
        """Wait for the harness to end by itself (end of scene) and collect its summary.

        Parameters
        ----------
        timeout : float, optional
            Seconds to wait.

        Returns
        -------
        int
            The exit status.

        Raises
        ------
        subprocess.TimeoutExpired
            If it is still running after `timeout`.
        """
        if self._proc is None:
            raise DeviceError("emulated board: not started")
        self._proc.wait(timeout)
        self.close()
        assert self.returncode is not None
        return self.returncode

    def close(self) -> None:
        """Stop the harness (SIGTERM) and collect its summary; calling it again does nothing."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(5.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()
        self.returncode = proc.returncode
        if self._stderr is not None:
            self._stderr.seek(0)
            text = self._stderr.read().decode(errors="replace").strip()
            self._stderr.close()
            self._stderr = None
            self.log = text
            lines = text.splitlines()
            self.summary = lines[-1] if lines else ""

    def __enter__(self) -> EmulatedBoard:
        if self._proc is None:
            self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __del__(self) -> None:
        proc = getattr(self, "_proc", None)
        if proc is not None and proc.poll() is None:
            proc.kill()

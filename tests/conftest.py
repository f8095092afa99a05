"""Shared test setup: off-screen rendering, and the firmware built once for its tests.

The suite runs on several processes (``make test`` passes ``-n auto`` to pytest-xdist): every
``make`` of the firmware goes through the `firmware_make` fixture, which holds a lock shared by
the workers, so two of them never build the same sketch or harness at once.
"""

import fcntl
import os
import shutil
import subprocess
from pathlib import Path

import pytest

# VTK renders off screen here; keep its fallback warnings quiet in test output
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")
# on several test processes (pytest-xdist's workers) one BLAS / OpenMP thread each, for them
# and the commands they start: more would only oversubscribe the cores
if os.environ.get("PYTEST_XDIST_WORKER"):
    for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

#: With SKIN_REQUIRE_FIRMWARE=1 (CI) a missing toolchain fails the firmware tests, not skips them.
REQUIRE_FIRMWARE = os.environ.get("SKIN_REQUIRE_FIRMWARE") == "1"


def _missing_tools() -> str | None:
    for tool in ("make", "avr-gcc", "g++"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed"
    if not Path("/usr/share/arduino/Arduino.mk").exists():
        return "arduino-mk is not installed"
    if not Path("/usr/include/simavr/sim_avr.h").exists():
        return "simavr's headers (libsimavr-dev) are not installed"
    return None


def _locked_make(args: list[str], lock_dir: Path, timeout: float = 900.0
                 ) -> subprocess.CompletedProcess:
    """Run ``make args`` on the firmware while holding the build lock in ``lock_dir``.

    Parameters
    ----------
    args : list of str
        ``make``'s arguments (``-C firmware ...``).
    lock_dir : Path
        A folder every test process shares (the parent of pytest's base temporary folder).
    timeout : float
        Seconds before the build is given up.

    Returns
    -------
    subprocess.CompletedProcess
        The finished ``make``, its output captured as text.
    """
    with open(lock_dir / "thermoskin-firmware.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            return subprocess.run(["make", *args], capture_output=True, text=True,
                                  timeout=timeout)
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.fixture(scope="session")
def firmware_make(tmp_path_factory):
    """``make`` on the firmware under the lock all test processes of this run share.

    Returns a callable taking ``make``'s arguments (and an optional ``timeout``) and returning
    the finished process, its output captured as text.
    """
    lock_dir = tmp_path_factory.getbasetemp().parent  # shared by xdist's workers
    return lambda args, timeout=900.0: _locked_make(args, lock_dir, timeout)


@pytest.fixture(scope="session")
def firmware_built(firmware_make) -> None:
    """Build the sketches and the simavr harness (``make -C firmware all harness``) once."""
    from skin.drivers.avr_sim import DEFAULT_HARNESS, FIRMWARE_DIR, firmware_elf

    reason = _missing_tools()
    if reason:
        if REQUIRE_FIRMWARE:
            pytest.fail(f"SKIN_REQUIRE_FIRMWARE=1 but {reason}")
        pytest.skip(f"the firmware cannot be built and emulated here: {reason}")
    for target in ("all", "harness"):
        proc = firmware_make(["-C", str(FIRMWARE_DIR), target])
        assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    assert DEFAULT_HARNESS.is_file() and firmware_elf("uno").is_file()


@pytest.fixture
def node_bus(request):
    """A python-can virtual bus and the `can://virtual/...` driver listening on it."""
    can = pytest.importorskip("can")
    from skin import drivers

    channel = f"skin-test-{request.node.name}"
    bus = can.Bus(interface="virtual", channel=channel)
    driver = drivers.open(f"can://virtual/{channel}")
    yield bus, driver
    driver.close()
    bus.shutdown()


def send_can(bus, frames) -> None:
    """Put ``(identifier, data)`` frames on a python-can bus."""
    import can

    for ident, data in frames:
        bus.send(can.Message(arbitration_id=ident, data=data, is_extended_id=False))

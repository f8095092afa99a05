"""Shared test setup: off-screen rendering, and the firmware built once for its tests."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

# VTK renders off screen here; keep its fallback warnings quiet in test output
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

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


@pytest.fixture(scope="session")
def firmware_built() -> None:
    """Build the sketches and the simavr harness (``make -C firmware all harness``) once."""
    from skin.drivers.avr_sim import DEFAULT_HARNESS, FIRMWARE_DIR, firmware_elf

    reason = _missing_tools()
    if reason:
        if REQUIRE_FIRMWARE:
            pytest.fail(f"SKIN_REQUIRE_FIRMWARE=1 but {reason}")
        pytest.skip(f"the firmware cannot be built and emulated here: {reason}")
    for target in ("all", "harness"):
        proc = subprocess.run(["make", "-C", str(FIRMWARE_DIR), target], capture_output=True,
                              text=True)
        assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    assert DEFAULT_HARNESS.is_file() and firmware_elf("uno").is_file()

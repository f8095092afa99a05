"""The firmware's protocol library (C) against the shared test vectors, through its host tests.

Runs ``make -C firmware -f tests/host.mk host-test``, which builds ``firmware/tests/test_proto.cpp``
with g++ (address and undefined-behaviour sanitizers) and checks ``firmware/lib/skinproto``
against ``firmware/test_vectors/serial.txt`` and ``can.txt``. Skipped when g++ or make is missing,
unless ``SKIN_REQUIRE_FIRMWARE=1`` is set: then their absence fails.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "firmware"

# Every kind of firmware/test_vectors/README.md; the summary must report vectors of each.
KINDS = (
    "crc", "cobs", "fnv", "sample", "command", "ack", "error", "identity", "selftest_result",
    "bad_command", "can_sample", "can_command", "can_reply",
)


def _require_tools() -> None:
    missing = [tool for tool in ("g++", "gcc", "make") if shutil.which(tool) is None]
    if not missing:
        return
    reason = f"{', '.join(missing)} not found: cannot build the firmware's host tests"
    if os.environ.get("SKIN_REQUIRE_FIRMWARE") == "1":
        pytest.fail(f"{reason} (SKIN_REQUIRE_FIRMWARE=1)")
    pytest.skip(reason)


@pytest.mark.slow
def test_firmware_protocol_host_tests(firmware_make):
    _require_tools()
    result = firmware_make(["-C", str(FIRMWARE), "-f", "tests/host.mk", "host-test"], timeout=600)
    output = result.stdout + result.stderr
    assert result.returncode == 0, f"host tests failed:\n{output[-8000:]}"
    counts = dict(re.findall(r"^vectors (\w+): (\d+)$", result.stdout, re.MULTILINE))
    empty = [kind for kind in KINDS if int(counts.get(kind, 0)) == 0]
    assert not empty, f"no vectors checked of kind {empty}:\n{output[-4000:]}"
    assert re.search(r"^OK$", result.stdout, re.MULTILINE), output[-4000:]
    control = re.search(r"^control: (\d+) checks, (\d+) failures$", result.stdout, re.MULTILINE)
    assert control and int(control[1]) > 1000 and control[2] == "0", output[-4000:]

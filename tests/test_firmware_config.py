"""Compile-time checks of the firmware's build settings (firmware/lib/skinboard/skin_config.h):
avr-gcc refuses a board whose channels exceed the MCU's analog inputs or whose ADC divider the
ADC does not have, and accepts the shipped boards."""

import shutil
import subprocess
from pathlib import Path

import pytest

CONFIG = Path(__file__).resolve().parents[1] / "firmware" / "lib" / "skinboard"
AVR_GCC = shutil.which("avr-gcc")
pytestmark = pytest.mark.skipif(AVR_GCC is None, reason="avr-gcc is not installed")


def compile_config(tmp_path: Path, mcu: str, *defs: str) -> subprocess.CompletedProcess:
    src = tmp_path / "config.c"
    src.write_text('#include "skin_config.h"\nunsigned long max_rate = SKIN_MAX_RATE_ADC;\n')
    return subprocess.run([AVR_GCC, f"-mmcu={mcu}", "-DF_CPU=16000000UL", f"-I{CONFIG}",
                           *defs, "-fsyntax-only", str(src)], capture_output=True, text=True)


@pytest.mark.parametrize(("mcu", "defs"), [
    ("atmega328p", ["-DSKIN_TAXELS=16", "-DSKIN_MUXES=1", "-DSKIN_OVERSAMPLING=4"]),
    ("atmega328p", ["-DSKIN_TAXELS=16", "-DSKIN_MUXES=1", "-DSKIN_FORCE_INPUTS=16"]),
    ("atmega328p", ["-DSKIN_TAXELS=4", "-DSKIN_MUXES=0", "-DSKIN_FORCE_INPUTS=3"]),  # ADC0-7
    ("atmega2560", ["-DSKIN_TAXELS=72", "-DSKIN_MUXES=5", "-DSKIN_OVERSAMPLING=1"]),
    ("atmega2560", ["-DSKIN_TAXELS=72", "-DSKIN_MUXES=5", "-DSKIN_FORCE_INPUTS=72"]),
])
def test_the_boards_that_fit_compile(tmp_path, mcu, defs):
    proc = compile_config(tmp_path, mcu, *defs)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize(("mcu", "defs", "message"), [
    # the Uno's 4 direct taxels, ambient on ADC4, force on ADC5-8: ADC8 is the temperature sensor
    ("atmega328p", ["-DSKIN_TAXELS=4", "-DSKIN_MUXES=0", "-DSKIN_FORCE_INPUTS=4"],
     "analog inputs"),
    ("atmega328p", ["-DSKIN_TAXELS=64", "-DSKIN_MUXES=4", "-DSKIN_FORCE_INPUTS=64"],
     "analog inputs"),
    ("atmega2560", ["-DSKIN_TAXELS=16", "-DSKIN_MUXES=0"], "analog inputs"),
    ("atmega328p", ["-DSKIN_FORCE_INPUTS=16", "-DSKIN_FORCE_PRESCALER=12"],
     "SKIN_FORCE_PRESCALER"),
    ("atmega328p", ["-DSKIN_ADC_PRESCALER=100"], "SKIN_ADC_PRESCALER"),
])
def test_a_board_the_mcu_cannot_read_is_refused(tmp_path, mcu, defs, message):
    proc = compile_config(tmp_path, mcu, *defs)
    assert proc.returncode != 0 and "#error" in proc.stderr and message in proc.stderr


VARIANTS = Path("/usr/share/arduino/hardware/arduino/avr/variants")  # Debian's arduino-core-avr


@pytest.mark.skipif(not (VARIANTS / "standard").is_dir(), reason="the Arduino AVR core is absent")
@pytest.mark.parametrize(("variant", "force", "fits"), [
    # 4 direct taxels on A0-A3, ambient on A4, force from A5: an Uno brings out A0-A5 only
    ("standard", 1, True), ("standard", 2, False),
    # a Nano (the 328P's TQFP package) also brings out A6 and A7
    ("eightanaloginputs", 3, True), ("eightanaloginputs", 4, False),
])
def test_an_arduino_build_checks_the_inputs_its_board_brings_out(tmp_path, variant, force, fits):
    proc = compile_config(tmp_path, "atmega328p", "-DARDUINO=10807", f"-I{VARIANTS / variant}",
                          "-DSKIN_TAXELS=4", "-DSKIN_MUXES=0", f"-DSKIN_FORCE_INPUTS={force}")
    if fits:
        assert proc.returncode == 0, proc.stderr
    else:
        assert proc.returncode != 0 and "analog inputs" in proc.stderr, proc.stderr

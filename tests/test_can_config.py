"""The CAN driver from python-can's configuration (environment, config file); the DBC file."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

can = pytest.importorskip("can")

from skin import drivers  # noqa: E402
from skin.drivers.protocol import can_sample_frames  # noqa: E402
from skin.errors import DeviceError  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _frame_through(url, channel):
    bus = can.Bus(interface="virtual", channel=channel)
    try:
        with drivers.open(url) as driver:
            for ident, data in can_sample_frames(1, 9, 45000, np.arange(6) + 100, 24.0,
                                                 np.full(6, 255)):
                bus.send(can.Message(arbitration_id=ident, data=data, is_extended_id=False))
            return driver.url, driver.recv(timeout=1.0)
    finally:
        bus.shutdown()


def test_can_url_alone_takes_the_bus_from_the_environment(monkeypatch, request):
    channel = f"skin-env-{request.node.name}"
    monkeypatch.setenv("CAN_INTERFACE", "virtual")
    monkeypatch.setenv("CAN_CHANNEL", channel)
    url, frame = _frame_through("can://", channel)
    assert url == f"can://virtual/{channel}"
    assert frame is not None and frame.seq == 9 and frame.board == 1
    assert frame.counts[:6].tolist() == list(range(100, 106))


def test_can_url_with_a_context_takes_a_section_of_a_config_file(tmp_path, request):
    channel = f"skin-file-{request.node.name}"
    home = tmp_path / "home"
    home.mkdir()
    (home / ".canrc").write_text(f"[default]\ninterface = socketcan\nchannel = can9\n\n"
                                 f"[lab]\ninterface = virtual\nchannel = {channel}\n")
    code = (
        "import numpy as np, can\n"
        "from skin import drivers\n"
        "from skin.drivers.protocol import can_sample_frames\n"
        f"bus = can.Bus(interface='virtual', channel={channel!r})\n"
        "with drivers.open('can://?context=lab') as d:\n"
        "    for i, data in can_sample_frames(0, 3, 15000, np.arange(4), 24.0, [255] * 4):\n"
        "        bus.send(can.Message(arbitration_id=i, data=data, is_extended_id=False))\n"
        "    f = d.recv(timeout=1.0)\n"
        "    print(d.url, f.seq)\n"
        "bus.shutdown()\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}
    env["HOME"] = str(home)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [f"can://virtual/{channel}", "3"]


def test_can_url_without_any_configuration_says_what_to_set(monkeypatch, tmp_path):
    for key in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    if any(Path(p).is_file() for p in ("/etc/can.conf",)):
        pytest.skip("this machine has a python-can configuration")
    with pytest.raises(DeviceError, match="names no interface: set CAN_INTERFACE"):
        drivers.open("can://")
    with pytest.raises(DeviceError, match="goes with can:// alone"):
        drivers.open("can://virtual/x?context=lab")


def test_the_shipped_dbc_decodes_the_frames_of_a_sample():
    cantools = pytest.importorskip("cantools")
    from skin.drivers.dbc import dbc_text

    path = ROOT / "firmware" / "thermoskin.dbc"
    assert path.read_text() == dbc_text()  # the shipped file is the generated one
    db = cantools.database.load_file(path)
    counts = [7, 4095, 0, 300, 2048, 12]
    frames = can_sample_frames(4, 70000, 1_234_567, counts, -3.25, [10, 20, 30, 40, 50, 60],
                               flags=0x201, status=[0, 1, 0, 8, 0, 0])
    decoded = {}
    for ident, data in frames:
        msg = db.get_message_by_frame_id(ident)
        decoded[msg.name] = db.decode_message(ident, data, allow_truncated=True)
    assert decoded["SYNC_N4"] == {"seq": 70000, "time_us": 1_234_567}
    got = {**decoded["DATA_N4_G0"], **decoded["DATA_N4_G1"]}
    assert [got[f"count_{k}"] for k in range(6)] == counts
    assert [got[f"status_{k}"] for k in range(6)] == [0, 1, 0, 8, 0, 0]
    assert [decoded["DUTY_N4_G0"][f"duty_{k}"] for k in range(6)] == [10, 20, 30, 40, 50, 60]
    status = decoded["STATUS_N4"]
    assert status["seq8"] == 70000 & 0xFF and status["flags"] == 0x201
    assert status["ambient"] == pytest.approx(-3.25) and status["groups"] == 2

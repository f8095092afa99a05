"""``skin devices``: boards on a pty and CAN nodes answer IDENTIFY; what the layout disputes."""

import dataclasses
import json
from pathlib import Path

import pytest

import skin
from skin.cli import main
from skin.drivers.discovery import Found, check, identify
from skin.drivers.sim import PtySerialDevice, SkinSimulator
from skin.formats.layout import load_layout
from skin.formats.scene import load_scene


@pytest.fixture
def serial_board():
    device = PtySerialDevice(SkinSimulator(load_scene("default"), duration=30.0), speed=1.0)
    device.start()
    yield device
    device.close()


#: IDENTIFY's wait for the simulated boards, s: they answer from this process's threads, which
#: a loaded machine leaves waiting longer than the command's 0.5 s (failed so at load 5-8)
ANSWER = "5"


def test_a_board_on_a_pty_is_listed_and_agrees_with_its_layout(serial_board, capsys):
    assert main(["devices", "--no-scan", "--port", f"serial://{serial_board.port}",
                 "--timeout", ANSWER, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    [board] = out["boards"]
    assert board["board"] == 0 and board["taxels"] == 72 and board["problems"] == []
    assert board["url"] == f"serial://{serial_board.port}" and board["transport"] == "serial"
    assert out["silent"] == []


def test_disagreements_with_the_layout_are_named():
    layout = load_layout("arm")
    good = identity = SkinSimulator(load_scene("default")).identity()
    assert check(Found("serial://x", None, good), layout) == []
    fewer = dataclasses.replace(identity, taxels=40)
    [problem] = check(Found("serial://x", None, fewer), layout)
    assert "samples 40 taxels" in problem and "wires 72 channels" in problem
    assert "beyond" in problem
    more = dataclasses.replace(identity, taxels=80)
    [problem] = check(Found("serial://x", None, more), layout)
    assert "samples 80 taxels, arm.toml wires 72" in problem
    other = dataclasses.replace(identity, layout_hash=0x12345678)
    [problem] = check(Found("can://virtual/a", 4, other), layout)
    assert "node 4" in problem and "hash 12345678" in problem
    unset = dataclasses.replace(identity, layout_hash=0)  # firmware built without a hash
    assert check(Found("serial://x", None, unset), layout) == []
    stranger = dataclasses.replace(identity, board_id=9)
    [problem] = check(Found("serial://x", None, stranger), layout)
    assert "board 9 is not in" in problem


def test_a_mismatch_makes_the_command_fail_with_a_warning(serial_board, tmp_path, capsys):
    text = (Path(skin.__file__).parent / "data" / "layouts" / "arm.toml").read_text()
    cut = text[: text.index("[[taxels]]\nid = 64\n")]  # the last 8 taxels unwired
    (tmp_path / "short.toml").write_text(cut)
    assert main(["devices", "--no-scan", "--port", f"serial://{serial_board.port}",
                 "--timeout", ANSWER, "--layout", str(tmp_path / "short.toml")]) == 1
    out = capsys.readouterr().out
    assert "board 0, firmware 0.0.0 on host (serial), 72 taxels" in out
    assert "warning:" in out and "samples 72 taxels," in out and "short.toml wires 64" in out
    assert "built for another layout (hash 19ddf41d;" in out


def test_a_port_that_does_not_answer_is_listed_as_silent(capsys):
    assert main(["devices", "--no-scan", "--port", "serial+loop://", "--timeout", "0.1",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["boards"] == []
    assert out["silent"] == [{"url": "serial+loop://", "error": "no answer to IDENTIFY"}]


def test_every_node_on_a_can_bus_answers_a_broadcast_identify(request):
    pytest.importorskip("can")
    from skin.drivers.can_sim import CanSimNode

    channel = f"devices-{request.node.name}"
    sim = SkinSimulator(load_scene("default"), duration=30.0)
    node = CanSimNode(sim, ("virtual", channel), node=5, speed=1.0)
    node.start()
    try:
        found = identify(f"can://virtual/{channel}", timeout=1.5)  # it waits this long
    finally:
        node.close()
    assert [f.node for f in found] == [5]
    assert found[0].identity.taxels == 72 and found[0].identity.transport == 1
    assert check(found[0], load_layout("arm")) == []


def test_a_port_asked_for_that_cannot_be_opened_fails_and_names_its_url_once(capsys):
    # issue 20 item 13: "can://socketcan/can0: can://socketcan/can0: cannot open the bus"
    # and exit 0; an unknown CAN interface fails to open the same way on every machine
    url = "can://nosuchinterface/can0"
    assert main(["devices", "--no-scan", "--port", url, "--timeout", "0.1"]) == 1
    out = capsys.readouterr().out
    assert out.count(url) == 1
    assert f"{url}: {url}" not in out
    assert f"error: {url}:" in out
    assert main(["devices", "--no-scan", "--port", url, "--timeout", "0.1", "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["silent"][0]["url"] == url and not doc["silent"][0]["error"].startswith(url)

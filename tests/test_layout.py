import numpy as np
import pytest

from skin.errors import LayoutError
from skin.formats.layout import Board, Layout, load_layout, parse_layout

BOARDS = "[[boards]]\nid = 0\n"


def taxel(tid: int, **fields: str | None) -> str:
    """TOML of one taxel; a field given as None is left out, others are raw TOML values."""
    values = {
        "id": str(tid),
        "board": "0",
        "address": str(tid),
        "link": '"forearm"',
        "position": f"[0.0, 0.0, {0.01 * tid}]",
        "normal": "[1.0, 0.0, 0.0]",
    }
    values.update(fields)
    body = "".join(f"{k} = {v}\n" for k, v in values.items() if v is not None)
    return f"\n[[taxels]]\n{body}"


def taxel_line(text: str, n: int) -> int:
    """1-based line of the n-th [[taxels]] header."""
    return [i + 1 for i, line in enumerate(text.splitlines()) if line == "[[taxels]]"][n]


def layout_error(text: str) -> str:
    with pytest.raises(LayoutError) as exc:
        parse_layout(text, source="x.toml")
    return str(exc.value)


def assert_names(msg: str, line: int, tid: int, field: str) -> None:
    assert f"x.toml:{line}:" in msg
    assert f"taxel {tid}" in msg
    assert f"'{field}'" in msg


@pytest.fixture(scope="module")
def arm() -> Layout:
    return load_layout("arm")


def test_arm_has_72_unique_taxels(arm):
    assert len(arm) == 72
    assert len(set(arm.ids.tolist())) == 72
    assert arm.positions.shape == (72, 3)


def test_arm_normals_are_unit(arm):
    assert np.allclose(np.linalg.norm(arm.normals, axis=1), 1.0, atol=1e-5)


def test_arm_links(arm):
    assert set(arm.links) == {"upper_arm", "forearm"}
    assert arm.links.count("upper_arm") == 40
    assert arm.links.count("forearm") == 32


def test_arm_board_has_paper_constants(arm):
    assert list(arm.boards) == [0]
    board = arm.boards[0]
    assert board == Board()
    assert board.divider_resistor == 668.0
    assert board.adc_bits == 10 and board.adc_max == 1023
    assert board.adc_reference == 1.1
    assert board.supply_voltage == 5.06
    assert board.heater_resistance == 19.7
    assert board.heater_voltage == 2.5
    assert board.thermistor_c0 == 9.5594e-4
    assert board.thermistor_c1 == 2.6181e-4
    assert board.sensor_depth == 8e-5
    assert board.sensor_diffusivity == 2.796e-9
    assert board.sensor_conductivity == 0.0349
    assert board.heater_area == 1.5625e-4
    assert board.sensor_thickness == 2.4e-4
    assert board.sample_rate == 200.0


def test_arm_index_and_channel_map(arm):
    assert arm.index(71) == 71
    idx, addr = arm.channel_map(0)
    assert len(idx) == 72 and len(set(addr.tolist())) == 72
    with pytest.raises(LayoutError, match="no taxel with id 999"):
        arm.index(999)


def test_neighbours_join_adjacent_ring_taxels(arm):
    n = arm.neighbours()
    assert n.shape == (72, 72)
    assert np.array_equal(n, n.T)
    assert not n.diagonal().any()
    k = arm.index
    assert n[k(0), k(1)] and n[k(0), k(9)]  # next in the ring, both ways round
    assert n[k(0), k(10)]  # same position, next ring
    assert n[k(40), k(41)] and n[k(40), k(47)] and n[k(40), k(48)]


def test_neighbours_skip_far_taxels(arm):
    n = arm.neighbours()
    k = arm.index
    assert not n[k(0), k(5)]  # opposite side of the ring
    assert not n[k(0), k(2)]
    assert not n[k(0), k(20)]  # two rings away
    assert not n[k(0), k(11)]  # diagonal
    assert not n[k(39), k(40)]  # other link
    assert n.sum(axis=1).max() <= 4


def test_neighbours_with_radius(arm):
    assert not arm.neighbours(radius=1e-6).any()
    everything = arm.neighbours(radius=10.0)
    links = np.array(arm.links)
    assert np.array_equal(everything, (links[:, None] == links[None, :]) & ~np.eye(72, dtype=bool))


def test_parse_minimal_layout():
    layout = parse_layout(BOARDS + taxel(0) + taxel(1), source="x.toml")
    assert len(layout) == 2
    assert layout.source == "x.toml"
    assert layout.taxels[1].position == (0.0, 0.0, 0.01)


def test_duplicate_taxel_id():
    text = BOARDS + taxel(3) + taxel(3, address="7")
    msg = layout_error(text)
    assert_names(msg, taxel_line(text, 1), 3, "id")
    assert "duplicate" in msg
    assert f"line {taxel_line(text, 0)}" in msg


def test_duplicate_board_address():
    text = BOARDS + taxel(0) + taxel(1) + taxel(2, address="1")
    msg = layout_error(text)
    assert_names(msg, taxel_line(text, 2), 2, "address")
    assert "already used by taxel 1" in msg


@pytest.mark.parametrize("field", ["board", "address", "link", "position", "normal"])
def test_missing_field(field):
    text = BOARDS + taxel(0) + taxel(1, **{field: None})
    msg = layout_error(text)
    assert_names(msg, taxel_line(text, 1), 1, field)
    assert "missing" in msg


def test_non_unit_normal():
    text = BOARDS + taxel(0) + taxel(1, normal="[1.0, 1.0, 0.0]")
    msg = layout_error(text)
    assert_names(msg, taxel_line(text, 1), 1, "normal")
    assert "unit" in msg


def test_position_with_two_numbers():
    text = BOARDS + taxel(0, position="[0.0, 0.1]")
    msg = layout_error(text)
    assert_names(msg, taxel_line(text, 0), 0, "position")
    assert "list of 3" in msg


def test_unknown_board():
    text = BOARDS + taxel(0) + taxel(1, board="5")
    msg = layout_error(text)
    assert_names(msg, taxel_line(text, 1), 1, "board")
    assert "5" in msg


def test_unknown_field():
    text = BOARDS + taxel(0, colour='"red"')
    msg = layout_error(text)
    assert_names(msg, taxel_line(text, 0), 0, "colour")
    assert "unknown" in msg


def test_unknown_board_field():
    msg = layout_error("[[boards]]\nid = 0\nvoltage = 3.3\n" + taxel(0))
    assert "x.toml:1:" in msg and "'voltage'" in msg


def test_invalid_toml():
    msg = layout_error(BOARDS + "\n[[taxels]]\nid = \n")
    assert msg.startswith("x.toml:")
    assert "TOML" in msg
    assert "line 5" in msg


def test_no_taxels():
    msg = layout_error(BOARDS)
    assert msg.startswith("x.toml:")
    assert "no taxels" in msg


def test_load_layout_from_file(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(BOARDS + taxel(0) + taxel(1), encoding="utf-8")
    layout = load_layout(path)
    assert len(layout) == 2
    assert layout.source == str(path)


def test_load_layout_missing_path(tmp_path):
    missing = tmp_path / "nope.toml"
    with pytest.raises(LayoutError, match=r"nope\.toml"):
        load_layout(missing)


def test_load_layout_unknown_shipped_name():
    with pytest.raises(LayoutError, match="no_such_layout"):
        load_layout("no_such_layout")


def test_a_folder_named_like_a_shipped_layout_does_not_hide_it(tmp_path, monkeypatch):
    (tmp_path / "arm").mkdir()
    monkeypatch.chdir(tmp_path)
    assert len(load_layout("arm")) == 72
    with pytest.raises(LayoutError, match="elsewhere/arm: cannot read layout: No such file"):
        load_layout("elsewhere/arm")

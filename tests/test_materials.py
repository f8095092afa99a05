import pytest

from skin.errors import MaterialsError
from skin.models.materials import hex_to_rgb, load_materials, parse_materials

PAPER = {
    "acrylic", "aluminium", "brick", "cardboard", "glass", "mdf",
    "neoprene", "porcelain", "pine", "rubber", "steel",
}  # fmt: skip
EXTREMES = {"copper", "diamond", "polyurethane_foam", "silica_aerogel", "water"}

GOOD = """
[pine]
k = [0.10, 0.15]
rho = [400, 600]
c = [1250, 2000]
nominal = { k = 0.15, rho = 500, c = 1463.4 }
colour = "#E69F00"
"""


@pytest.fixture(scope="module")
def table():
    return load_materials()


def test_classified_materials(table):
    assert len(PAPER) == 11
    assert {name for name, m in table.items() if m.classify} == PAPER | {"human_skin"}


def test_extremes_are_not_classified(table):
    assert {name for name, m in table.items() if not m.classify} == EXTREMES


def test_every_nominal_lies_in_its_ranges(table):
    for name, m in table.items():
        lo, hi = m.effusivity_range
        assert lo <= m.effusivity <= hi, name
        for field in ("k", "rho", "c"):
            low, high = getattr(m, field)
            assert low <= m.nominal[field] <= high, (name, field)


def test_log_effusivity_range(table):
    pine = table["pine"]
    lo, hi = pine.log_effusivity_range
    assert 10**lo == pytest.approx(pine.effusivity_range[0])
    assert 10**hi == pytest.approx(pine.effusivity_range[1])


def test_paper_nominals(table):
    assert table["aluminium"].effusivity == pytest.approx(80 / 3.55e-5**0.5, rel=1e-3)
    assert table["pine"].effusivity == pytest.approx(0.15 / 2.05e-7**0.5, rel=1e-3)


def test_only_human_skin_has_a_temperature(table):
    assert table["human_skin"].temperature is not None
    lo, hi = table["human_skin"].temperature
    assert 25.0 < lo < hi < 40.0
    assert [n for n, m in table.items() if m.temperature is not None] == ["human_skin"]


def test_classified_colours_are_distinct(table):
    colours = [m.colour.lower() for m in table.values() if m.classify]
    assert len(set(colours)) == len(colours)


def test_colours_are_hex_and_convert(table):
    for m in table.values():
        assert all(0.0 <= v <= 1.0 for v in m.rgb)
    assert hex_to_rgb("#FF0080") == pytest.approx((1.0, 0.0, 128 / 255))


def test_parse_good_table():
    table = parse_materials(GOOD, source="m.toml")
    assert list(table) == ["pine"]
    pine = table["pine"]
    assert pine.classify is True
    assert pine.temperature is None
    assert pine.k == (0.10, 0.15)


@pytest.mark.parametrize("field", ["k", "rho", "c"])
def test_nominal_outside_range(field):
    nominal = {"k": "0.15", "rho": "500", "c": "1463.4"}
    nominal[field] = {"k": "0.5", "rho": "900", "c": "100"}[field]
    text = GOOD.replace(
        "nominal = { k = 0.15, rho = 500, c = 1463.4 }",
        f"nominal = {{ k = {nominal['k']}, rho = {nominal['rho']}, c = {nominal['c']} }}",
    )
    with pytest.raises(MaterialsError) as exc:
        parse_materials(text, source="m.toml")
    msg = str(exc.value)
    assert "m.toml" in msg
    assert "'pine'" in msg
    assert f"nominal {field}" in msg
    assert "outside" in msg


@pytest.mark.parametrize(
    ("field", "bad"),
    [
        ("k", "[0.15, 0.10]"),
        ("rho", "[400]"),
        ("c", '["a", "b"]'),
        ("k", "[0.0, 0.15]"),
        ("rho", "500"),
    ],
)
def test_malformed_range(field, bad):
    good = {"k": "[0.10, 0.15]", "rho": "[400, 600]", "c": "[1250, 2000]"}[field]
    text = GOOD.replace(f"{field} = {good}", f"{field} = {bad}")
    assert text != GOOD
    with pytest.raises(MaterialsError) as exc:
        parse_materials(text, source="m.toml")
    msg = str(exc.value)
    assert "m.toml" in msg
    assert "'pine'" in msg
    assert f"field '{field}'" in msg


def test_malformed_temperature_range():
    with pytest.raises(MaterialsError, match=r"'pine'.*field 'temperature'"):
        parse_materials(GOOD + "temperature = [34.0, 30.0]\n", source="m.toml")


def test_invalid_toml():
    with pytest.raises(MaterialsError, match=r"m\.toml"):
        parse_materials("[pine\n", source="m.toml")


def test_load_missing_file(tmp_path):
    with pytest.raises(MaterialsError, match=r"none\.toml"):
        load_materials(tmp_path / "none.toml")


def test_every_material_has_an_air_gap_and_soft_ones_conduct_best(table):
    assert all(m.gap[0] <= m.gap[1] for m in table.values())
    h_rubber = table["rubber"].conductance_range
    h_glass = table["glass"].conductance_range
    h_brick = table["brick"].conductance_range
    assert h_rubber[0] > h_glass[0] > h_brick[1]  # conforming > smooth > rough
    assert h_glass == pytest.approx((0.026 / 5e-6, 0.026 / 1e-6))


def test_gap_defaults_and_is_validated():
    assert parse_materials(GOOD)["pine"].gap == (2.0, 20.0)
    with pytest.raises(MaterialsError, match="'gap'"):
        parse_materials(GOOD + "gap = [5, 1]\n")

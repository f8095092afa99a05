import numpy as np
import pytest

from skin.errors import LayoutError
from skin.layout import load_layout, parse_layout
from skin.models import load_materials

pytest.importorskip("pyvista")
from PIL import Image

from skin.viz import ArmView
from skin.viz.arm import BARE, UNKNOWN_COLOUR, hex_rgb


@pytest.fixture(scope="module")
def view():
    colours = {m.name: m.colour for m in load_materials().values()}
    v = ArmView(load_layout("arm"), colours, window_size=(800, 400))
    yield v
    v.close()


def test_every_taxel_owns_a_patch(view):
    owned = np.bincount(view.patch[view.patch >= 0], minlength=len(view.layout))
    assert owned.min() > 0


def test_paint_changes_colours_in_place(view):
    mesh_before = view.mesh
    points_before = view.mesh.n_points
    view.paint([0, 1], "aluminium")
    view.paint([44], "unknown")
    assert view.mesh is mesh_before and view.mesh.n_points == points_before
    rgb = view.mesh.point_data["rgb"]
    k0 = view.layout.index(0)
    assert np.all(rgb[view.patch == k0] == hex_rgb(view.colours["aluminium"]))
    assert np.all(rgb[view.patch == view.layout.index(44)] == hex_rgb(UNKNOWN_COLOUR))
    assert np.all(rgb[view.patch == view.layout.index(5)] == hex_rgb(BARE))


def colour_present(img: np.ndarray, colour: str, tol: int = 6) -> bool:
    return bool((np.abs(img.astype(int) - hex_rgb(colour).astype(int)).max(axis=-1) <= tol).any())


def test_screenshot_shows_legend_colours(view, tmp_path):
    view.paint([22], "glass")
    path = view.screenshot(tmp_path / "map.png", title="test")
    img = np.asarray(Image.open(path).convert("RGB"))
    assert img.std() > 10  # not blank
    for label, colour in view.legend_entries():
        assert colour_present(img, colour), f"legend colour of {label} missing"


def test_taxel_off_the_surface_is_named():
    text = """
[[taxels]]
id = 7
board = 0
address = 0
link = "upper_arm"
position = [0.2, 0.0, 0.1]
normal = [1.0, 0.0, 0.0]
"""
    with pytest.raises(LayoutError, match=r"taxel 7 lies .* mm from the surface"):
        ArmView(parse_layout(text, "off.toml"), {})


def test_unknown_link_is_named():
    text = """
[[taxels]]
id = 1
board = 0
address = 0
link = "tail"
position = [0.045, 0.0, 0.1]
normal = [1.0, 0.0, 0.0]
"""
    with pytest.raises(LayoutError, match="link 'tail'"):
        ArmView(parse_layout(text, "tail.toml"), {})

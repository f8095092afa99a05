"""The arm view, off screen: scene structure, colours at known taxels, errors, and pictures.

Pictures are compared with stored references (tests/data/images, 400x300) by the RMS of the
pixel difference. After a deliberate change of the look, regenerate them with
``SKIN_UPDATE_IMAGES=1 .venv/bin/pytest tests/test_viz.py`` and look at them before committing.
"""

import os
import time
from pathlib import Path

import numpy as np
import pytest

from skin.errors import LayoutError, ViewError
from skin.formats.layout import Board, Layout, Taxel, load_layout, parse_layout
from skin.models import load_materials

pytest.importorskip("pyvista")
from PIL import Image

from skin.bench.view import arm_layout
from skin.viz import ArmView, default_arm
from skin.viz.arm import BARE, UNKNOWN_COLOUR, hex_rgb
from skin.viz.arm_live import LiveArm
from skin.viz.arm_mesh import ArmSurface, load_arm
from skin.viz.arm_paint import TaxelPainter, colormap_table

IMAGES = Path(__file__).parent / "data" / "images"
COLOURS = {m.name: m.colour for m in load_materials().values()}


@pytest.fixture(scope="module")
def view():
    v = ArmView(load_layout("arm"), COLOURS, window_size=(800, 400), memory=10.0)
    yield v
    v.close()


@pytest.fixture(autouse=True)
def fresh(request):
    if "view" in request.fixturenames:
        v = request.getfixturevalue("view")
        v.mode = "material"
        v.painter.temperature, v.painter.clim = None, None
        v.clear()
        v.update(0.0, in_contact=np.zeros(len(v.layout), dtype=bool))


def actors(v: ArmView) -> list:
    """Every actor of every view, by name and VTK address."""
    return [(name, a.__this__) for r in v.plotter.renderers for name, a in r.actors.items()]


def inner(v: ArmView, taxel_id: int) -> np.ndarray:
    k = v.layout.index(taxel_id)
    return (v.patch == k) & ~v.surface.rim


def rgb(v: ArmView) -> np.ndarray:
    return v.mesh.point_data["rgba"][:, :3]


# --- structure --------------------------------------------------------------------------------


def test_every_taxel_owns_a_patch_of_its_own_link(view):
    owned = np.bincount(view.patch[view.patch >= 0], minlength=len(view.layout))
    assert owned.min() > 0
    for link, s in view.surface.slices.items():
        owners = view.patch[s][view.patch[s] >= 0]
        assert all(view.layout.links[k] == link for k in np.unique(owners))
    # taxels snapped onto the surface: the layout's positions are on the procedural arm
    assert view.surface.snap_distance.max() < 1e-3
    assert set(view.arm) == {"upper_arm", "forearm", "shoulder", "elbow", "wrist", "hand"}


def test_updates_change_colours_in_place(view):
    mesh, n_points = view.mesh, view.mesh.n_points
    array = view.mesh.GetPointData().GetArray("rgba")
    before = actors(view)
    assert len(before) == 7  # two arms, two side names, title, legend, scalar bar
    mapper = view.plotter.renderers[0].actors["arm_front"].mapper
    assert mapper.dataset is mesh
    for step in range(5):
        view.paint([step], "aluminium", confidence=0.5, at=float(step))
        view.update(float(step), in_contact=np.arange(len(view.layout)) == step,
                    temperature=np.full(len(view.layout), 30.0 + step))
        view.mode = "temperature" if step % 2 else "material"
        view.render()
    assert actors(view) == before  # no actor added, none replaced
    assert view.mesh is mesh and view.mesh.n_points == n_points
    assert view.mesh.GetPointData().GetArray("rgba") is array
    assert mapper.GetInput().GetPointData().GetArray("rgba") is array  # what VTK draws


def test_material_colour_at_known_taxels(view):
    view.paint([0, 1], "aluminium")
    view.paint([44], "unknown")
    colours = rgb(view)
    assert np.all(colours[inner(view, 0)] == hex_rgb(COLOURS["aluminium"]))
    assert np.all(colours[view.patch == view.layout.index(1)] == hex_rgb(COLOURS["aluminium"]))
    assert np.all(colours[view.patch == view.layout.index(44)] == hex_rgb(UNKNOWN_COLOUR))
    assert np.all(colours[view.patch == view.layout.index(5)] == hex_rgb(BARE))
    assert np.all(colours[view.patch < 0] == hex_rgb(BARE))
    assert view.legend_entries() == [("aluminium", COLOURS["aluminium"]),
                                     ("unknown", UNKNOWN_COLOUR)]


def test_confidence_blends_toward_grey(view):
    c = hex_rgb(COLOURS["glass"]).astype(float)
    grey = c @ [0.299, 0.587, 0.114]
    sat = []
    for conf in (1.0, 0.5, 0.0):
        view.paint([22], "glass", confidence=conf)
        got = view.taxel_colour(22).astype(float)
        s = view.painter.confidence_floor + (1 - view.painter.confidence_floor) * conf
        assert np.allclose(got, grey + (c - grey) * s, atol=0.51)
        assert np.all(rgb(view)[inner(view, 22)] == view.taxel_colour(22))
        sat.append(got.max() - got.min())
    assert sat[0] > sat[1] > sat[2] > 0  # greyer as the classifier is less sure
    view.paint([22], "unknown", confidence=0.1)  # the unknown look does not blend
    assert np.all(view.taxel_colour(22) == hex_rgb(UNKNOWN_COLOUR))


def test_past_contacts_fade_with_the_time_constant(view):
    c, bare = hex_rgb(COLOURS["pine"]).astype(float), hex_rgb(BARE).astype(float)
    view.paint([30], "pine", at=2.0)
    view.paint([31], "pine")  # no time: never fades
    for now, w in ((2.0, 1.0), (12.0, np.exp(-1.0)), (32.0, np.exp(-3.0)), (200.0, 0.0)):
        view.update(now)
        assert np.allclose(view.taxel_colour(30), bare + (c - bare) * w, atol=0.51), now
        assert np.all(view.taxel_colour(31) == c)
    view.memory = None
    assert np.all(view.taxel_colour(30) == c)
    view.memory = 10.0
    with pytest.raises(ViewError, match="memory"):
        view.memory = 0.0


def test_taxels_in_contact_are_outlined(view):
    view.paint([3], "aluminium")
    view.paint([40], "cardboard")
    mask = np.isin(view.layout.ids, [3, 40, 50])
    view.update(1.0, in_contact=mask)
    colours = rgb(view)
    for tid, want in ((3, 255), (40, 0), (50, 0)):  # white on dark, black on light patches
        k = view.layout.index(tid)
        rim = (view.patch == k) & view.surface.rim
        assert rim.any() and np.all(colours[rim] == want)
        assert np.all(colours[inner(view, tid)] == view.taxel_colour(tid))
    view.update(2.0, in_contact=np.zeros(len(view.layout), dtype=bool))
    rim = (view.patch == view.layout.index(3)) & view.surface.rim
    assert np.all(colours[rim] == hex_rgb(COLOURS["aluminium"]))


def test_temperature_mode_shows_the_colormap_and_a_scalar_bar(view):
    n = len(view.layout)
    t = np.linspace(20.0, 40.0, n)
    t[5] = np.nan  # a taxel without a reading
    view.update(0.0, temperature=t)
    view.mode = "temperature"  # the range: the first temperatures shown
    assert view.painter.clim == (20.0, 40.0)
    table = colormap_table("inferno")
    for k in (0, n // 2, n - 1):
        want = table[int(np.rint((t[k] - 20.0) / 20.0 * 255))]
        assert np.all(view.taxel_colour(int(view.layout.ids[k])) == want)
    assert np.all(view.taxel_colour(int(view.layout.ids[5])) == hex_rgb(UNKNOWN_COLOUR))
    assert view._bar.GetVisibility() and not view._legend.GetVisibility()
    assert view._lut.GetRange() == (20.0, 40.0)
    view.mode = "material"
    assert not view._bar.GetVisibility() and view._legend.GetVisibility()
    with pytest.raises(ViewError, match="mode"):
        view.mode = "heat"
    with pytest.raises(ViewError, match="one value per taxel"):
        view.update(temperature=np.zeros(3))


def test_paint_result_uses_label_confidence_and_release():
    from skin.contact import Contact, MaterialEstimate
    from skin.stream.pipeline import ContactResult

    painter = TaxelPainter(4, COLOURS, np.array([0, 1, 2, 3, -1]), np.zeros(5, bool),
                           memory=5.0)
    assert painter.vertex_row.tolist() == [0, 1, 2, 3, 4]
    layout = Layout([Taxel(i, 0, i, "forearm", (0.045, 0.0, 0.05 * (i + 1)), (1.0, 0, 0))
                     for i in range(4)], [Board()])
    v = ArmView(layout, COLOURS, window_size=(200, 150), sides=("front",), memory=5.0)
    try:
        contact = Contact(1, [2, 3], onset=1.0, release=3.0, ambient=25.0, windows=[])
        v.paint_result(ContactResult(contact, MaterialEstimate("pine", {}, 0.5, None, "m"), 3.1))
        assert v.painter.at[2] == 3.0 and v.painter.confidence[3] == 0.5
        assert v.legend_entries() == [("pine", COLOURS["pine"])]
    finally:
        v.close()


def test_poses_move_links_in_place_and_children_follow(view):
    mesh, points = view.mesh, view.mesh.points.copy()
    hand = view.surface.slices["hand"]
    upper = view.surface.slices["upper_arm"]
    old = view.arm["forearm"].pose.copy()
    lift = old.copy()
    lift[2, 3] += 0.1
    try:
        view.set_poses({"forearm": lift})
        assert view.mesh is mesh
        assert np.allclose(view.mesh.points[hand], points[hand] + [0, 0, 0.1])  # via the wrist
        assert np.allclose(view.mesh.points[upper], points[upper])
        k = view.layout.index(60)  # a forearm taxel
        assert np.allclose(view.taxel_world[k], view.arm["forearm"].pose[:3, 3]
                           + view.arm["forearm"].pose[:3, :3] @ view.surface.taxel_local[k])
        with pytest.raises(ViewError, match="no link 'tail'"):
            view.set_poses({"tail": np.eye(4)})
        with pytest.raises(ViewError, match="rigid"):
            view.set_poses({"forearm": np.diag([2.0, 1, 1, 1])})
    finally:
        view.set_poses({"forearm": old})
    assert np.allclose(view.mesh.points, points)


# --- pictures ---------------------------------------------------------------------------------


def compare_image(img: np.ndarray, name: str, tolerance: float = 6.0) -> None:
    ref = IMAGES / name
    if os.environ.get("SKIN_UPDATE_IMAGES") == "1" or not ref.exists():
        if os.environ.get("SKIN_UPDATE_IMAGES") != "1":
            pytest.fail(f"no reference image {ref}: run with SKIN_UPDATE_IMAGES=1 to make it")
        ref.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(img).save(ref, optimize=True)
        return
    want = np.asarray(Image.open(ref).convert("RGB")).astype(float)
    assert want.shape == img.shape, f"{name}: size {img.shape} != reference {want.shape}"
    rms = float(np.sqrt(np.mean((img.astype(float) - want) ** 2)))
    if rms > tolerance:
        Image.fromarray(img).save(ref.with_name(ref.stem + "_failed.png"))
    assert rms <= tolerance, f"{name}: RMS difference {rms:.2f} > {tolerance} (see *_failed.png)"


@pytest.fixture(scope="module")
def small():
    v = ArmView(load_layout("arm"), COLOURS, window_size=(400, 300), memory=10.0,
                sides=("front",))
    yield v
    v.close()


def paint_scene(v: ArmView) -> None:
    """Taxels that face the front camera (-y): every look of the material mode."""
    v.paint([7, 8, 17, 18], "aluminium", confidence=1.0, at=9.0)
    v.paint([27, 28, 37, 38], "pine", confidence=0.4, at=9.0)  # greyer: less sure
    v.paint([45, 46, 47], "human_skin", at=0.0)  # 10 s ago: faded by e^-1
    v.paint([53, 54, 55], "unknown", at=9.0)
    v.paint([61, 62, 63], "glass", at=9.0)
    contact = np.isin(v.layout.ids, [54, 61, 62, 63, 70])  # outlined; 70 not labelled yet
    v.update(10.0, in_contact=contact)
    v.title = "contact map"


def test_image_of_the_contact_map(small):
    paint_scene(small)
    compare_image(small.image(), "arm_material.png")


def test_image_of_the_temperature_mode(small):
    paint_scene(small)
    small.painter.clim = (25.0, 40.0)
    small.mode = "temperature"
    small.update(10.0, temperature=np.linspace(25.0, 40.0, len(small.layout)))
    try:
        compare_image(small.image(), "arm_temperature.png")
    finally:
        small.mode = "material"


def test_screenshot_shows_legend_colours(view, tmp_path):
    view.paint([22], "glass")
    view.paint([0], "unknown")
    path = view.screenshot(tmp_path / "map.png", title="test")
    img = np.asarray(Image.open(path).convert("RGB"))
    assert img.std() > 10  # not blank
    for label, colour in [*view.legend_entries(), ("not touched", BARE)]:
        diff = np.abs(img.astype(int) - hex_rgb(colour).astype(int)).max(axis=-1)
        assert (diff <= 6).any(), f"legend colour of {label} missing"


def test_gif_of_a_run(tmp_path):
    pytest.importorskip("imageio")
    v = ArmView(load_layout("arm"), COLOURS, window_size=(200, 100), sides=("front",))
    live = LiveArm(v, movie=tmp_path / "run.gif", fps=10.0)
    n = len(v.layout)
    for step in range(1, 6):  # blocks of 0.1 s, then one of 0.3 s: one frame per 0.1 s
        live.step(0.1 * step, in_contact=np.arange(n) < step, temperature=np.full(n, 30.0))
    live.step(0.8)
    live.close()
    live.close()  # idempotent
    assert live.frames == 9  # 0.0 ... 0.8 s
    with Image.open(tmp_path / "run.gif") as gif:
        assert gif.n_frames >= 6 and gif.size == (200, 100)
    with pytest.raises(ViewError, match=r"\.gif or \.mp4"):
        ArmView(load_layout("arm"), COLOURS, window_size=(100, 100)).open_movie(
            tmp_path / "run.avi")


def test_window_redraws_are_throttled():
    now = [0.0]
    v = ArmView(load_layout("arm"), COLOURS, window_size=(100, 50), sides=("front",))
    live = LiveArm(v, window=True, rate=8.0, clock=lambda: now[0])
    for k in range(16):  # 16 blocks in 1 s of wall time (binary fractions: exact)
        now[0] = k / 16
        live.step(k / 16)
    live.close()
    assert live.draws == 8 and live.frames == 0  # one per 1/8 s


def test_a_window_without_a_display_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    with pytest.raises(ViewError, match="cannot open a window: there is no display"):
        ArmView(load_layout("arm"), COLOURS, off_screen=False)


# --- errors and user meshes ---------------------------------------------------------------------


def one_taxel(link: str, position: str) -> str:
    return (f'[[taxels]]\nid = 7\nboard = 0\naddress = 0\nlink = "{link}"\n'
            f"position = {position}\nnormal = [1.0, 0.0, 0.0]\n")


def test_taxel_off_the_surface_is_named():
    layout = parse_layout(one_taxel("upper_arm", "[0.2, 0.0, 0.1]"), "off.toml")
    with pytest.raises(LayoutError, match=r"off.toml: taxel 7 lies 145\.0 mm from the surface "
                                          r"of link 'upper_arm'"):
        ArmView(layout, {})
    # within the tolerance: snapped onto the surface
    near = parse_layout(one_taxel("upper_arm", "[0.058, 0.0, 0.1]"), "near.toml")
    surface = ArmSurface(near, default_arm(2000))
    assert np.allclose(surface.taxel_local[0], [0.055, 0.0, 0.1], atol=1e-3)
    assert abs(surface.snap_distance[0] - 0.003) < 1e-3


def test_unknown_link_is_named():
    with pytest.raises(LayoutError, match="link 'tail'"):
        ArmView(parse_layout(one_taxel("tail", "[0.045, 0.0, 0.1]"), "tail.toml"), {})


def write_tube_stl(path: Path, radius: float, length: float, scale: float = 1.0) -> Path:
    import pyvista as pv

    from skin.viz.arm_mesh import _tube

    pts, faces, _ = _tube(radius, length, 0.004)
    mesh = pv.PolyData(pts * scale, np.column_stack([np.full(len(faces), 3), faces]).ravel())
    mesh.save(str(path))
    return path


def tube_layout() -> Layout:
    return Layout([Taxel(i, 0, i, "finger", (0.02 * np.cos(a), 0.02 * np.sin(a), 0.05),
                         (np.cos(a), np.sin(a), 0.0))
                   for i, a in enumerate(np.linspace(0, 2 * np.pi, 6, endpoint=False))],
                  [Board()])


def test_user_mesh_from_an_stl(tmp_path):
    stl = write_tube_stl(tmp_path / "finger.stl", 0.02, 0.1)
    pose = np.eye(4)
    pose[:3, 3] = [1.0, 2.0, 3.0]
    v = ArmView.from_meshes(tube_layout(), COLOURS, {"finger": (stl, pose)},
                            window_size=(200, 150), sides=("back",))
    try:
        assert v.arm["finger"].source == str(stl)
        assert np.allclose(v.taxel_world, v.surface.taxel_local + np.array([1.0, 2.0, 3.0]))
        assert np.bincount(v.patch[v.patch >= 0], minlength=6).min() > 0
        v.paint([2], "copper")
        assert np.all(rgb(v)[inner(v, 2)] == hex_rgb(COLOURS["copper"]))
        assert v.image().std() > 5
    finally:
        v.close()


def test_arm_file_with_a_mesh_in_millimetres(tmp_path):
    write_tube_stl(tmp_path / "finger_mm.stl", 0.02, 0.1, scale=1000.0)
    arm = tmp_path / "arm.toml"
    arm.write_text('[[links]]\nname = "finger"\nmesh = "finger_mm.stl"\nscale = 0.001\n'
                   "origin = [0.0, 0.0, 0.5]\nrotation = [0.0, 90.0, 0.0]\n")
    links = load_arm(arm)
    assert np.allclose(links["finger"].pose[:3, :3] @ [0, 0, 1], [1, 0, 0])
    v = ArmView(tube_layout(), COLOURS, arm=arm, window_size=(200, 150), sides=("front",))
    try:
        assert np.allclose(v.taxel_world[:, 0], 0.05, atol=1e-3)  # link z -> world x
        assert np.allclose(v.taxel_world[:, 2] - 0.5, -v.surface.taxel_local[:, 0], atol=1e-9)
    finally:
        v.close()


def test_missing_or_bad_mesh_files_are_named(tmp_path):
    with pytest.raises(ViewError, match=r"link 'finger': mesh file '.*nowhere\.stl' does not "
                                        "exist"):
        ArmView.from_meshes(tube_layout(), COLOURS, {"finger": (tmp_path / "nowhere.stl", None)})
    (tmp_path / "finger.txt").write_text("solid")
    with pytest.raises(ViewError, match=r"link 'finger': mesh file .*finger\.txt' is not one of"):
        ArmView.from_meshes(tube_layout(), COLOURS, {"finger": (tmp_path / "finger.txt", None)})
    arm = tmp_path / "arm.toml"
    arm.write_text('# my arm\n[[links]]\nname = "finger"\nmesh = "gone.stl"\n')
    with pytest.raises(ViewError, match=r"arm\.toml: link 'finger': mesh file .*gone\.stl' "
                                        "does not exist"):
        load_arm(arm)
    arm.write_text('# my arm\n\n[[links]]\nname = "finger"\nmesh = "gone.stl"\nspin = 1\n')
    with pytest.raises(ViewError, match=r"arm\.toml:3: link 'finger': unknown field 'spin'"):
        load_arm(arm)
    write_tube_stl(tmp_path / "f.stl", 0.02, 0.1)
    arm.write_text('[[links]]\nname = "finger"\nmesh = "f.stl"\npose = [[1, 0], [0, 1]]\n')
    with pytest.raises(ViewError, match=r"arm\.toml:1: link 'finger': field 'pose' must be 4 "
                                        "rows of 4 numbers"):
        load_arm(arm)
    arm.write_text('[[links]]\nname = "finger"\nmesh = "f.stl"\nparent = "palm"\n')
    with pytest.raises(ViewError, match="parent 'palm' is not a link"):
        load_arm(arm)


# --- size ------------------------------------------------------------------------------------


def test_a_thousand_taxels_on_a_hundred_thousand_vertices_build_and_update_fast():
    layout = arm_layout(1000)
    started = time.perf_counter()
    surface = ArmSurface(layout, default_arm(100_000))
    build = time.perf_counter() - started
    assert len(surface.points) > 90_000 and build < 10.0
    assert np.bincount(surface.owner[surface.owner >= 0], minlength=1000).min() > 0
    painter = TaxelPainter(1000, COLOURS, surface.owner, surface.rim)
    names = sorted(COLOURS)
    for k in range(0, 1000, 2):
        painter.paint([k], names[k % len(names)], confidence=0.7, at=1.0)
    painter.now = 5.0
    painter.in_contact[::17] = True
    out = np.empty(len(surface.points), dtype=np.uint32)
    times = []
    for _ in range(50):
        t = time.perf_counter()
        painter.fill(out)
        times.append(time.perf_counter() - t)
    assert np.median(times) < 2e-3  # the budget per update (about 0.2 ms here)


# --- skin run --------------------------------------------------------------------------------


SKIN = Path(__import__("sys").executable).with_name("skin")


def test_skin_run_view_without_a_display_fails_clearly(tmp_path):
    import subprocess

    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run([str(SKIN), "run", "--view", "--speed", "0", "--duration", "1",
                           "--out", str(tmp_path)], capture_output=True, text=True, env=env,
                          timeout=60)
    assert proc.returncode == 2
    assert "--view: cannot open a window: there is no display" in proc.stderr
    assert "--video" in proc.stderr


def test_skin_run_writes_a_gif_of_the_run(tmp_path):
    import subprocess

    pytest.importorskip("imageio")
    proc = subprocess.run([str(SKIN), "run", "--speed", "0", "--duration", "2", "--no-map",
                           "--out", str(tmp_path), "--video", str(tmp_path / "run.gif"),
                           "--view-mode", "temperature", "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "video:" in proc.stderr
    with Image.open(tmp_path / "run.gif") as gif:
        assert 19 <= gif.n_frames <= 21 and gif.size == (960, 440)  # one per 0.1 s


def test_skin_bench_view_quick_json():
    import json
    import subprocess

    proc = subprocess.run([str(SKIN), "bench", "view", "--quick", "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)  # one JSON document, nothing else
    assert doc["machine"]["cpus"] >= 1 and doc["machine"]["renderer"]
    assert [r["taxels"] for r in doc["results"]] == [72, 300]
    for r in doc["results"]:
        assert 0 < r["update_ms"]["p50"] < 2.0  # the budget
        assert r["render_ms"] > 0 and r["baseline_take_ms"] > 0
        assert r["render_per_update"] > 1


@pytest.mark.skipif(__import__("shutil").which("xvfb-run") is None,
                    reason="needs xvfb-run (a virtual display) to open a window")
def test_skin_run_view_opens_a_window_on_a_virtual_display(tmp_path):
    import subprocess

    proc = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", str(SKIN), "run",
                           "--view", "--speed", "0", "--duration", "2", "--no-map", "--out",
                           str(tmp_path), "--json"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_cylinder_link_geometry_is_still_accepted():
    from skin.viz import LinkGeometry
    from skin.viz.arm_mesh import rotation_pose

    layout = parse_layout(one_taxel("upper_arm", "[0.05, 0.0, 0.1]"), "one.toml")
    arm = {"upper_arm": LinkGeometry(0.05, 0.2, rotation_pose(90.0, (0.0, 0.0, 0.0)))}
    v = ArmView(layout, COLOURS, arm=arm, window_size=(200, 100))
    try:
        assert np.allclose(v.taxel_world[0], [0.1, 0.0, -0.05])
        assert v.patch.max() == 0
    finally:
        v.close()

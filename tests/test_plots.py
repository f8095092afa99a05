import subprocess
import sys
from pathlib import Path

import pytest

from skin.errors import SkinError
from skin.models import SensorConstants, load_materials

pytest.importorskip("matplotlib")

from skin.viz.plots import materials_figure, plot_materials

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def table():
    return load_materials()


def range_bars(fig):
    (ax,) = fig.axes
    return [bar for container in ax.containers for bar in container]


def test_writes_a_png(table, tmp_path):
    path = plot_materials(table, tmp_path / "m.png")
    assert path == tmp_path / "m.png"
    data = path.read_bytes()
    assert data.startswith(PNG_MAGIC) and len(data) > 1000


def test_writes_an_svg_in_a_new_folder(table, tmp_path):
    path = plot_materials(table, tmp_path / "sub" / "m.svg", include_all=True)
    text = path.read_text(encoding="utf-8")
    assert "<svg" in text and len(text) > 1000


def test_no_suffix_means_png_and_unknown_suffix_fails(table, tmp_path):
    assert plot_materials(table, tmp_path / "m").suffix == ".png"
    with pytest.raises(SkinError, match=r"\.jpg"):
        plot_materials(table, tmp_path / "m.jpg")


def test_one_bar_per_classified_material_sorted_by_nominal(table):
    classified = sorted((m for m in table.values() if m.classify), key=lambda m: m.effusivity)
    fig = materials_figure(table)
    bars = range_bars(fig)
    assert len(bars) == len(classified) == 12
    (ax,) = fig.axes
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert labels[0] == "cardboard" and labels[-1] == "aluminium"
    assert "MDF" in labels and "human skin" in labels
    for bar, m in zip(bars, classified, strict=True):
        lo, hi = m.effusivity_range
        assert bar.get_x() == pytest.approx(lo)
        assert bar.get_x() + bar.get_width() == pytest.approx(hi)
        assert bar.get_facecolor()[:3] == pytest.approx(m.rgb)
        assert not bar.get_hatch()
    assert ax.get_xscale() == "log"


def test_include_all_adds_the_hatched_extremes(table):
    bars = range_bars(materials_figure(table, include_all=True))
    assert len(bars) == len(table) > 12
    hatched = {bar.get_gid().removeprefix("range:") for bar in bars if bar.get_hatch()}
    assert hatched == {name for name, m in table.items() if not m.classify}


def test_sensor_effusivity_line(table):
    (ax,) = materials_figure(table).axes
    (line,) = [ln for ln in ax.lines if ln.get_gid() == "sensor"]
    assert line.get_xdata()[0] == pytest.approx(SensorConstants().effusivity)
    assert line.get_linestyle() == "--"
    nominal = [ln for ln in ax.lines if (ln.get_gid() or "").startswith("nominal:")]
    assert len(nominal) == 12


def test_cli_writes_the_file(tmp_path):
    out = tmp_path / "materials.png"
    proc = subprocess.run([sys.executable, "-m", "skin", "plot", "materials", "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out)
    assert out.read_bytes().startswith(PNG_MAGIC)


def test_cli_default_path_and_all(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "skin", "plot", "materials", "--all"],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(Path("out", "materials.png"))
    assert (tmp_path / "out" / "materials.png").stat().st_size > 1000


def test_cli_rejects_an_unknown_kind_and_format(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "skin", "plot", "nothing"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "invalid choice" in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "skin", "plot", "materials", "--out",
                           str(tmp_path / "m.gif")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "unsupported figure format" in proc.stderr


def test_matplotlib_is_imported_only_when_drawing(tmp_path):
    code = (
        "import sys\n"
        "import skin.viz.plots as plots\n"
        "import skin.commands.plot\n"
        "assert 'matplotlib' not in sys.modules, 'imported at module level'\n"
        "from skin.models import load_materials\n"
        f"plots.plot_materials(load_materials(), {str(tmp_path / 'm.png')!r})\n"
        "assert 'matplotlib' in sys.modules\n"
        "assert 'matplotlib.pyplot' not in sys.modules\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_bench_figures_are_written(tmp_path):
    from skin.models.thermal_bench import forward
    from skin.viz.plots import plot_estimator_errors, plot_work_precision

    rows = forward(cells=(12,), dts=(0.1, 0.02))
    path = plot_work_precision(rows, tmp_path / "wp.png")
    assert path.stat().st_size > 10_000
    inverse_rows = [
        {"estimator": name, "duration": d, "median_abs_log10_error": e,
         "p90_abs_log10_error": 2 * e, "time_per_trial_ms": ms}
        for name, ms in (("paper", 0.1), ("fit", 5.0)) for d, e in ((0.25, 0.4), (2.5, 0.1))]
    path = plot_estimator_errors(inverse_rows, tmp_path / "est.svg")
    assert "<svg" in path.read_text()[:500]

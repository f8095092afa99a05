import re
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
    from skin.bench.thermal import forward
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


# --- every kind from the command line, and the traces of taxels (Figs. 1 and 6) ---------------

import contextlib  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402

import numpy as np  # noqa: E402

from skin import cli  # noqa: E402
from skin.stream.onset import OnsetDetector  # noqa: E402
from skin.viz import trace_plots  # noqa: E402

SVG_START = "<?xml"


def run_cli(*argv):
    """Run ``skin`` in this process; return (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = cli.main([str(a) for a in argv])
        except SystemExit as exc:  # argparse
            code = exc.code
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A small trial dataset, its `skin evaluate --json` and `skin bench thermal --json`."""
    folder = tmp_path_factory.mktemp("plots")
    trials = folder / "trials.npz"
    code, _, err = run_cli("simulate", "trials", "-o", trials, "--trials", "8",
                           "--materials", "aluminium,pine,glass")
    assert code == 0, err
    code, out, err = run_cli("evaluate", "--data", trials, "--methods", "svm-pca,model",
                             "--durations", "0.5,1", "--cv", "2", "--json")
    assert code == 0, err
    (folder / "evaluate.json").write_text(out)
    code, out, err = run_cli("bench", "thermal", "--quick", "--json")
    assert code == 0, err
    (folder / "bench.json").write_text(out)
    return folder


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A 3 s recording of the default scene (an aluminium touch at 1-2.5 s of taxels 0, 1, 10)."""
    pytest.importorskip("mcap")
    folder = tmp_path_factory.mktemp("rec")
    path = folder / "run.mcap"
    proc = subprocess.run([sys.executable, "-m", "skin", "run", "--speed", "0", "--duration",
                           "3", "--no-map", "--json", "--out", str(folder / "run"), "--record",
                           str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return path


@pytest.fixture(scope="module")
def material_set():
    return trace_plots.material_traces(["aluminium", "pine", "glass"], noise=0.02)


def lines_with(ax, gid):
    return [ln for ln in ax.lines if ln.get_gid() == gid]


def test_trace_figure_has_two_panels_sharing_time_and_onset_lines(material_set):
    fig = trace_plots.traces_figure(material_set)
    ax_t, ax_s = fig.axes[:2]
    assert ax_t.get_shared_x_axes().joined(ax_t, ax_s)
    assert ax_t.get_xlim() == ax_s.get_xlim()
    for i, tr in enumerate(material_set):
        assert len(tr.onsets) == 1 and abs(tr.onsets[0]) < 0.03  # contact at 0
        for ax in (ax_t, ax_s):
            (line,) = lines_with(ax, f"onset:{i}")
            assert list(line.get_xdata()) == [tr.onsets[0]] * 2
        (temp,) = lines_with(ax_t, f"temperature:{i}")
        assert np.array_equal(temp.get_ydata(), tr.temperature)
        (mark,) = lines_with(ax_t, f"detected:{i}")
        assert mark.get_xdata()[0] == tr.detected_at[0] > tr.onsets[0]
    # one true onset line per panel for the three traces (they share it)
    for ax in (ax_t, ax_s):
        (truth,) = lines_with(ax, "true_onset")
        assert list(truth.get_xdata()) == [0.0, 0.0]
    assert ax_t.get_ylabel().startswith("temperature") and "K/s" in ax_s.get_ylabel()


def test_slope_panel_is_the_detectors_slope_sample_by_sample(files):
    from skin.formats.dataset import load_trials

    data = load_trials(files / "trials.npz")
    traces = trace_plots.trial_traces(data, [0, 9])
    fig = trace_plots.traces_figure(traces)
    ax_s = fig.axes[1]
    times = np.arange(data.temperature.shape[-1]) / data.fs
    for i, k in enumerate([0, 9]):
        # the detector stepped one sample at a time, its state's slope read after each
        det = OnsetDetector(1)
        state = det.initial_state()
        slope = []
        for t, y in zip(times, data.primary[k], strict=True):
            _, state = det.process([t], [[y]], state)
            slope.append(state.slope[0])
        (line,) = lines_with(ax_s, f"slope:{i}")
        assert np.array_equal(line.get_ydata(), np.array(slope))
        assert np.array_equal(line.get_xdata(), times)


def test_paper_slope_is_the_filtered_first_difference(material_set):
    from scipy.signal import sosfilt

    from skin.models.features import slope_filter

    fig = trace_plots.traces_figure(material_set[:1], slope="paper")
    (line,) = lines_with(fig.axes[1], "slope:0")
    tr = material_set[0]
    expected = sosfilt(slope_filter(200.0), np.diff(tr.temperature, prepend=tr.temperature[0])
                       * 200.0)
    assert np.allclose(line.get_ydata(), expected)
    assert "low-pass" in fig.axes[1].get_ylabel()
    with pytest.raises(SkinError, match="slope"):
        trace_plots.traces_figure(material_set, slope="spline")


def test_trial_traces_take_the_first_of_each_class_and_their_truth(files):
    from skin.formats.dataset import load_trials

    data = load_trials(files / "trials.npz")
    traces = trace_plots.trial_traces(data)
    assert [t.group for t in traces] == ["aluminium", "glass", "pine"]
    table = load_materials()
    for tr in traces:
        k = int(tr.name.rsplit(" ", 1)[1].rstrip(")"))
        assert tr.true_onsets == (data.extra["true_onset_time"][k],)
        assert tr.colour == table[str(data.label[k])].colour
        assert abs(tr.onsets[0] - tr.true_onsets[0]) < 0.06
    with pytest.raises(SkinError, match=r"trials\.npz: no trial 24"):
        trace_plots.trial_traces(data, [0, 24])


def test_recording_traces_hold_the_contact_the_truth_and_the_detectors_marks(recording):
    from skin.drivers.recording import read_recording

    rec = read_recording(recording)
    scene = trace_plots.recording_scene(rec)
    assert scene is not None and scene.name == "default"
    traces = trace_plots.recording_traces(rec, scene=scene)
    assert [t.name for t in traces] == ["taxel 0", "taxel 1", "taxel 10"]
    for tr in traces:
        assert tr.true_onsets == (1.0,) and tr.true_releases == (2.5,)
        assert abs(tr.onsets[0] - 1.0) < 0.03 and abs(tr.releases[0] - 2.5) < 0.15
        (contact,) = tr.contacts
        assert contact.id == 0 and contact.label in load_materials()
    fig = trace_plots.traces_figure(traces)
    assert [p.get_gid() for p in fig.axes[0].patches] == ["contact:0"]
    (release,) = lines_with(fig.axes[1], "release:2")
    assert list(release.get_xdata()) == [traces[2].releases[0]] * 2
    with pytest.raises(SkinError, match=r"run\.mcap: no taxel 999"):
        trace_plots.recording_traces(rec, [0, 999])


KINDS = ("materials", "traces", "accuracy", "confusion", "work-precision", "estimators")


@pytest.mark.parametrize("suffix", [".png", ".svg"])
@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_writes_png_and_svg(kind, suffix, files, tmp_path):
    source = {"traces": ["--material", "aluminium,pine"],
              "accuracy": ["--from", files / "evaluate.json"],
              "confusion": ["--from", files / "evaluate.json"],
              "work-precision": ["--from", files / "bench.json"],
              "estimators": ["--from", files / "bench.json"]}.get(kind, [])
    out = tmp_path / f"figure{suffix}"
    code, stdout, err = run_cli("plot", kind, *source, "--out", out)
    assert code == 0, err
    assert stdout.strip() == str(out)
    if suffix == ".png":
        assert out.read_bytes().startswith(PNG_MAGIC)
    else:
        assert out.read_text(encoding="utf-8").startswith(SVG_START)
    assert out.stat().st_size > 5000


def test_traces_from_a_dataset_and_a_recording_on_the_command_line(files, recording, tmp_path):
    code, stdout, err = run_cli("plot", "traces", "--from", files / "trials.npz", "--trial",
                                "0", "9", "--trial", "17", "--json", "--out", tmp_path / "t.svg")
    assert code == 0, err
    doc = json.loads(stdout)
    assert doc["figure"] == str(tmp_path / "t.svg")
    assert [t["name"] for t in doc["traces"]] == ["aluminium (trial 0)", "pine (trial 9)",
                                                  "glass (trial 17)"]
    code, stdout, err = run_cli("plot", "traces", "--from", recording, "--taxel", "44", "0",
                                "--json", "--out", tmp_path / "r.png")
    assert code == 0, err
    doc = json.loads(stdout)
    assert [t["name"] for t in doc["traces"]] == ["taxel 44", "taxel 0"]
    assert doc["traces"][0]["true_onsets"] == [2.0] and doc["traces"][1]["true_onsets"] == [1.0]
    assert (tmp_path / "r.png").read_bytes().startswith(PNG_MAGIC)


def test_confusion_keeps_the_methods_asked_for_one_row_each(files, tmp_path):
    from skin.viz.plots import plot_confusions

    rows = json.loads((files / "evaluate.json").read_text())["results"]
    assert {r["method"] for r in rows} == {"svm-pca", "model"}
    code, _, err = run_cli("plot", "confusion", "--from", files / "evaluate.json", "--method",
                           "model", "--out", tmp_path / "c.png")
    assert code == 0, err
    path = plot_confusions(rows, tmp_path / "all.png")
    assert path.read_bytes().startswith(PNG_MAGIC)


@pytest.mark.parametrize(("argv", "message"), [
    (["accuracy", "--from", "{bench}"],
     r"bench\.json: not the output of `skin evaluate --json`.*skin plot work-precision"),
    (["confusion", "--from", "{bench}"], r"bench\.json: not the output of `skin evaluate"),
    (["work-precision", "--from", "{evaluate}"],
     r"evaluate\.json: not the output of `skin bench thermal --json`.*skin plot accuracy"),
    (["estimators", "--from", "{trials}"], r"trials\.npz: not JSON"),
    (["accuracy", "--from", "{missing}"], r"missing\.json: no such file"),
    (["confusion", "--from", "{evaluate}", "--method", "hmm"],
     r"evaluate\.json: no method 'hmm'"),
    (["traces", "--from", "{evaluate}"], r"evaluate\.json: unknown kind of file '\.json'"),
    (["traces", "--from", "{trials}", "--trial", "99"], r"trials\.npz: no trial 99"),
    (["traces", "--from", "{trials}", "--material", "pine"], r"does not go with --from"),
    (["traces", "--from", "{trials}", "--taxel", "3"], r"--taxel picks taxels of a recording"),
    (["traces"], r"needs --from FILE .* or --material"),
    (["traces", "--material", "wood"], r"unknown material 'wood'"),
    (["traces", "--material", "pine", "--before", "0.2"], r"0\.5 s of warm-up"),
])
def test_cli_errors_name_the_file(argv, message, files):
    names = {"bench": files / "bench.json", "evaluate": files / "evaluate.json",
             "trials": files / "trials.npz", "missing": files / "missing.json"}
    code, stdout, err = run_cli("plot", *[a.format(**names) for a in argv], "--out",
                                files / "never.png")
    assert code == 2 and stdout == ""
    assert re.search(message, err), err
    assert not (files / "never.png").exists()


def test_a_row_missing_a_key_is_named(tmp_path):
    bad = tmp_path / "fusion.json"
    bad.write_text(json.dumps({"results": [{"duration": 1.0, "accuracy": 0.5}]}))
    code, _, err = run_cli("plot", "accuracy", "--from", bad)
    assert code == 2
    assert "fusion.json: not the output of `skin evaluate --json`: row 0 of 'results' has no " \
           "'method', 'accuracy_std'" in err


def test_traces_are_built_without_matplotlib_and_drawn_with_it(tmp_path):
    code = (
        "import sys\n"
        "import skin.viz.trace_plots as tp\n"
        "traces = tp.material_traces(['pine'])\n"
        "assert traces[0].onsets, 'no onset found'\n"
        "assert 'matplotlib' not in sys.modules, 'imported before drawing'\n"
        f"tp.plot_traces(traces, {str(tmp_path / 't.png')!r})\n"
        "assert 'matplotlib' in sys.modules and 'matplotlib.pyplot' not in sys.modules\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr

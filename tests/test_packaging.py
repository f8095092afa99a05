import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
OPTIONAL = ("scipy", "serial", "can", "sklearn", "hmmlearn", "skops", "pyvista", "vtk",
            "matplotlib", "cobs", "mcap", "zstandard", "foxglove", "zenoh", "yourdfpy",
            "rosbags", "cantools", "websockets")


def run_py(code: str, cwd: Path | None = None, env: dict | None = None) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=cwd, env=env, check=True)
    return out.stdout


def test_import_skin_loads_numpy_alone():
    code = (
        "import sys, json, skin\n"
        f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & set({OPTIONAL!r}))))"
    )
    assert json.loads(run_py(code)) == []


@pytest.mark.parametrize("module", ["skin.drivers", "skin.models", "skin.viz"])
def test_subpackages_do_not_load_optional_dependencies_at_import(module):
    heavy = {"serial", "can", "sklearn", "pyvista", "vtk", "matplotlib", "mcap", "foxglove",
             "zenoh", "yourdfpy", "rosbags", "cantools", "zstandard"}
    code = (
        f"import sys, json, {module}\n"
        "loaded = {m.split('.')[0] for m in sys.modules}\n"
        f"print(json.dumps(sorted(loaded & set({sorted(heavy)!r}))))"
    )
    assert json.loads(run_py(code)) == []


def test_missing_extra_gives_install_hint():
    # block pyserial's import as if it were not installed, then use the serial driver
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'serial' or name.startswith('serial.'):\n"
        "            raise ImportError('blocked')\n"
        "sys.meta_path.insert(0, Block())\n"
        "import skin.drivers\n"
        "from skin.errors import MissingDependencyError\n"
        "try:\n"
        "    skin.drivers.open('serial+loop://')\n"
        "except MissingDependencyError as exc:\n"
        "    print(exc)\n"
    )
    out = run_py(code)
    assert "pyserial" in out and "pip install 'thermoskin[serial]'" in out


def test_python_dash_m_skin_shows_help():
    out = subprocess.run([sys.executable, "-m", "skin", "--help"], capture_output=True,
                         text=True, check=True).stdout
    assert "run" in out


@pytest.mark.slow
def test_wheel_installs_and_imports_subpackages(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w",
                    str(wheels), str(ROOT)], check=True, capture_output=True)
    (wheel,) = wheels.glob("thermoskin-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert not tops & {"drivers", "models", "viz", "tests"}
    assert "skin/drivers/serial_port.py" in names
    assert {"skin/commands/run.py", "skin/stream/pipeline.py", "skin/bench/fuzz.py",
            "skin/formats/layout.py", "skin/world/map.py"} <= set(names)
    assert "skin/data/layouts/arm.toml" in names
    assert "skin/models/data/materials.toml" in names
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--quiet", "--target",
                    str(target), str(wheel)], check=True, capture_output=True)
    code = (
        "import skin, skin.drivers, skin.models, skin.viz\n"
        "from skin.formats.layout import load_layout\n"
        "from skin.models import load_materials\n"
        "print(skin.__file__); print(skin.drivers.__file__); "
        "print(len(load_layout('arm')), len(load_materials()))"
    )
    import os

    env = dict(os.environ, PYTHONPATH=str(target))
    out = run_py(code, cwd=tmp_path, env=env).split()
    assert out[0].startswith(str(target)) and out[1].startswith(str(target))
    assert out[2] == "72" and int(out[3]) >= 12


# commands whose job is to measure: they may import the measuring tools
MEASURING_COMMANDS = {"skin.commands.bench", "skin.commands.bench_drivers",
                      "skin.commands.bench_view", "skin.commands.bench_map",
                      "skin.commands.bench_onset_shape", "skin.commands.bench_tracking",
                      "skin.commands.bench_forward", "skin.commands.bench_scene",
                      "skin.commands.bench_gap", "skin.commands.bench_delay_bound",
                      "skin.commands.bench_envelope_rate",
                      "skin.commands.bench_response_noise", "skin.commands.bench_refine_bound",
                      "skin.commands.evaluate",
                      "skin.commands.evaluate_onset"}


def _module_files():
    """(module name, path) of every module of the package, from its source folders."""
    import tomllib

    dirs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    for package, folder in dirs.items():
        base = ROOT / folder
        for path in base.rglob("*.py"):
            rel = path.relative_to(base).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            if package == "skin" and parts and parts[0] in {"drivers", "models", "viz"}:
                continue  # not there: those live in their own folders
            yield ".".join([package, *parts]), path


def _imports(path: Path) -> set[str]:
    import ast

    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
    return names


def test_no_runtime_module_imports_a_measuring_tool():
    modules = dict(_module_files())
    assert "skin.stream.pipeline" in modules and "skin.bench.fuzz" in modules
    offenders = []
    for name, path in modules.items():
        if name.startswith("skin.bench") or name in MEASURING_COMMANDS:
            continue
        bad = sorted(m for m in _imports(path) if m == "skin.bench" or m.startswith("skin.bench."))
        if bad:
            offenders.append(f"{name} imports {', '.join(bad)}")
    assert offenders == []


def test_the_command_line_loads_no_measuring_tool():
    code = ("import sys, skin.cli\nskin.cli.build_parser()\n"
            "print(sorted(m for m in sys.modules if m.startswith('skin.bench')))")
    assert run_py(code).strip() == "[]"

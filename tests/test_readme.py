"""README's shell examples, in order: each parses, and each file one reads is made by an
earlier example, shipped, or named as the user's own (issue 20 item 18).

Running every example as written is not done here (the paper-sized datasets and benchmarks
take many minutes); the commands that make the files are run in tests of their own.
"""

import re
import shlex
from pathlib import Path

import pytest

from skin.cli import build_parser

README = Path(__file__).resolve().parents[1] / "README.md"

#: Lines that are not skin commands of this machine, with the reason.
NOT_RUN = {
    "make": "the Makefile's own targets",
    "sudo": "installs system packages",
    "pip": "installs packages",
    "source": "shell completion setup",
    "python -m skin run ...": "the same as `skin run`, elided",
}
#: Files an example reads that are the user's own, not made by the README.
USERS_OWN = {
    "my_scene.toml": "the user's scene (copied from the default one)",
    "my_arm.toml": "the user's arm file (their meshes)",
    "trials.csv": "trials recorded elsewhere, imported",
    "refs.csv": "the user's thermistor readings in reference baths",
    "quiet.mcap": "a quiet minute of the user's own skin, recorded",
    "refs.mcap": "the user's reference touches, recorded",
    "ref_touches.csv": "the user's labels of those touches",
    "refs.npz": "the user's reference contacts logged elsewhere (dataset v2)",
}
#: Options whose value is a file the command reads, and those it writes.
READS = {"--data", "--train", "--test", "--from", "--model", "--poses", "--calibration",
         "--scene", "--arm", "--map", "--labels"}
WRITES = {"-o", "--out", "--record", "--video", "--plot", "--log-file"}
SHIPPED = {"default", "arm", "xarm7"}  # shipped scene, layout and arm names


def examples() -> list[tuple[int, str]]:
    """Every command line of the README's sh blocks, in order, with its line number."""
    lines, out, inside, pending = README.read_text().splitlines(), [], False, ""
    for no, line in enumerate(lines, 1):
        if line.startswith("```"):
            inside = line.strip() == "```sh"
            continue
        if not inside:
            continue
        code = re.sub(r"\s+#.*$", "", line) if not line.lstrip().startswith("#") else ""
        if code.rstrip().endswith("\\"):
            pending += code.rstrip()[:-1] + " "
            continue
        code, pending = (pending + code).strip(), ""
        out += [(no, part.strip()) for part in code.split(";") if part.strip()]
    return out


def test_the_readme_has_examples():
    assert len(examples()) > 60


def test_every_example_parses_and_reads_only_files_made_before_it(tmp_path):
    made: set[str] = set()
    problems = []
    for no, cmd in examples():
        if any(cmd.startswith(k) for k in NOT_RUN):
            continue
        if cmd.startswith("printf"):
            made.add(cmd.rsplit(">", 1)[1].strip())
            continue
        argv = shlex.split(cmd.split(" > ")[0])
        if " > " in cmd:
            made.add(cmd.split(" > ")[1].strip())
        assert argv[0] == "skin", f"README.md:{no}: not a skin command: {cmd}"
        try:
            build_parser().parse_args(argv[1:])
        except SystemExit as exc:  # --version and --help exit 0
            if exc.code:
                problems.append(f"README.md:{no}: does not parse: {cmd}")
            continue
        reads = [argv[i + 1] for i, a in enumerate(argv[:-1]) if a in READS]
        reads += [a.split("://", 1)[1].split("?")[0] for a in argv if a.startswith("replay://")]
        if argv[1:3] in (["dataset", "check"], ["calibrate", "show"]):
            reads.append(argv[3])
        for i, a in enumerate(argv[:-1]):
            if a in WRITES:
                made.add(argv[i + 1])
        if argv[1] == "record":
            made.add(argv[3])
        if argv[1] == "run" and "--out" not in argv:
            made.add("out/run")  # its default output folder
        for f in reads:
            if "://" in f:
                continue  # a service's URL (skin map query --map zenoh://...), not a file
            if not (Path(f).suffix or "/" in f) or f in USERS_OWN or f in SHIPPED:
                continue  # a name, not a file (--model multilayer, --scene xarm7)
            if not any(f == m or f.startswith(m.rstrip("/") + "/") for m in made):
                problems.append(f"README.md:{no}: reads {f}, which no earlier example makes")
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("name", sorted(USERS_OWN))
def test_a_users_own_file_is_explained_where_it_is_read(name):
    text = README.read_text()
    assert name in text


#: Lines run in order by `test_the_examples_run_in_order` are shrunk to CI sizes by appending
#: these options (a later option wins in argparse, so the README's own stay visible); the
#: first entry whose words begin the command wins.
CI_SIZES = [
    # the recording cut into a dataset needs contacts released whole, and their windows
    (("skin", "run", "--speed", "0", "--duration", "20", "--no-map", "--record"),
     ["--speed", "0", "--duration", "6", "--force"]),
    (("skin", "run"), ["--speed", "0", "--duration", "3", "--force"]),
    (("skin", "-v", "run"), ["--speed", "0", "--duration", "3", "--force"]),
    (("skin", "simulate", "trials"), ["--trials", "8", "--duration", "2.6"]),
    (("skin", "bench", "thermal"), ["--quick"]),
    (("skin", "bench", "view"), ["--quick"]),
    (("skin", "bench", "fusion"), ["--trials", "2", "--durations", "0.5"]),
    (("skin", "bench", "pipeline"), ["--taxels", "64", "--seconds", "4"]),
    (("skin", "bench", "calibration"), ["--taxels", "2", "--contacts", "2"]),
    (("skin", "evaluate-onset"), ["--taxels", "2", "--minutes", "1"]),
    (("skin", "bench", "spread"), ["--touches", "4"]),
    (("skin", "bench", "soak"), ["--hours", "0.005", "--taxels", "256"]),
    (("skin", "bench", "nuisance"), ["--trials", "6", "--durations", "0.5", "--variants",
                                     "onset", "--methods", "svm-pca"]),
    (("skin", "bench", "object-prior"), ["--touches", "6"]),
    (("skin", "bench", "forward"), ["--sensors", "paper", "--trials", "3", "--durations", "0.5"]),
    (("skin", "bench", "gap"), ["--trials", "8", "--seeds", "7", "--durations", "0.5",
                                "--reference-trials", "4", "--points", "3"]),
    (("skin", "bench", "onset-shape"), ["--minutes", "1", "--taxels", "2"]),
    (("skin", "bench", "delay-bound"), ["--minutes", "1", "--taxels", "2", "--check-hours",
                                        "0.01", "--null-hours", "0.25"]),
    (("skin", "bench", "response-noise"), ["--seeds", "0", "--duration", "20", "--taxels", "8"]),
    (("skin", "bench", "refine-bound"), ["--minutes", "2", "--taxels", "4", "--seeds", "0",
                                         "--draws", "200"]),
    (("skin", "bench", "tracking"), ["--pairs", "2"]),
    (("skin", "bench", "scene"), ["--seeds", "7", "--duration", "6"]),
    (("skin", "bench", "fit-calibration"), ["--scene", "default", "--seeds", "7"]),
]
#: Lines not run, with the reason (hardware, a window, another machine, other extras).
SKIPPED = {
    "serial:///dev/": "a real board",
    "can://socketcan/": "a real CAN bus",
    "--view": "a window",
    "--publish": "publishers (optional extras and a listener)",
    "skin subscribe": "another machine",
    "skin bench publish": "publishers (optional extras)",
    "skin map": "a map service and robots on other machines (tests/test_map_service.py)",
    "skin bench map": "a map service, three robots and a 1 M-voxel map: minutes",
    '--map "zenoh://': "a map service on another machine (tests/test_map_service.py)",
    "--firmware-sim": "the compiled firmware (tests/test_firmware_emulated.py runs it)",
    "skin bench firmware": "the timing builds in simavr (tests/test_firmware_force.py runs it)",
    "xarm7": "the robots extra (URDF meshes)",
    "skin devices": "probes the machine's ports (tests/test_devices.py)",
    "skin evaluate --data trials.npz --methods svm-pca,knn-pca,hmm,model,default":
        "every method with --ceiling: minutes even on 132 trials (each method runs below)",
    "skin run --arm my_arm.toml": "the user's own meshes",
    "skin run --scene my_scene.toml": "the user's own scene",
    "skin calibrate thermistors --data refs.csv": "the user's own reference readings",
    "skin dataset import trials.csv": "the user's own recordings",
    "skin commission --port": "the user's own quiet recording (tests/test_commission.py)",
    "--touches water,neoprene": "1-3 min of fitting (tests/test_commission.py runs it)",
    "--calibration ref.json": "the file of the --touches line (skipped above)",
    "skin commission --data": "the user's own dataset (tests/test_commission.py)",
    "skin bench commission": "a minute of fitting (tests/test_commission.py runs one taxel)",
}


def _shrunk(argv: list[str]) -> list[str]:
    for words, extra in CI_SIZES:
        if tuple(argv[: len(words)]) == words:
            return argv + extra
    return argv


@pytest.mark.slow
def test_the_examples_run_in_order(tmp_path):
    import subprocess
    import sys

    env = {k: v for k, v in __import__("os").environ.items()}
    env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    skin = [sys.executable, "-m", "skin"]
    ran, failed = [], []
    for no, cmd in examples():
        if any(cmd.startswith(k) for k in NOT_RUN) or any(k in cmd for k in SKIPPED):
            continue
        if cmd.startswith("printf"):
            subprocess.run(cmd, shell=True, cwd=tmp_path, check=True)
            continue
        line, _, target = cmd.partition(" > ")
        argv = _shrunk(shlex.split(line))
        if "--version" in argv:
            argv = argv[:2]
        proc = subprocess.run(skin + argv[1:], cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=300)
        if target:
            (tmp_path / target.strip()).write_text(proc.stdout)
        ran.append(no)
        if proc.returncode != 0:
            failed.append(f"README.md:{no}: {' '.join(argv)} -> {proc.returncode}: "
                          f"{proc.stderr.strip().splitlines()[-1:]}")
    assert len(ran) > 40
    assert not failed, "\n".join(failed)

import json
import subprocess
import sys
from pathlib import Path

from skin.bench.pipeline import cylinder_layout, run

SKIN = Path(sys.executable).with_name("skin")


def test_bench_skins_are_wired_to_boards_of_256():
    layout = cylinder_layout(600)
    assert sorted(layout.boards) == [0, 1, 2]
    assert len(layout.channel_map(2)[0]) == 88 and layout.channel_map(1)[1].max() == 255


def test_bench_pipeline_reports_every_stage_and_what_the_budget_delays():
    row = run(1100, duration=16.0, contacts_per_minute=30.0, budget=0.0)
    assert row["boards"] == 5 and row["frames"] == 5 * 3200
    assert set(row["stages"]) == {"decode", "assemble", "calibrate", "onset", "track",
                                  "refine", "classify", "sinks"}
    assert row["contacts"] > 100  # 40 % of the taxels touched in the 6th second
    assert all(v > 0 for v in row["stages"].values())
    # the same stages per CPU second: together they are the run's CPU seconds, less what
    # falls between the stages (the loop, the file reads)
    assert set(row["stages_cpu"]) == set(row["stages"])
    assert all(v > 0 for v in row["stages_cpu"].values())
    samples = row["frames"] // row["boards"] * row["taxels"]
    cpu = sum(samples / v for v in row["stages_cpu"].values())
    assert 0.5 * row["cpu_s"] < cpu <= 1.01 * row["cpu_s"]
    assert 0 < row["latency_ms"]["p50"] <= row["latency_ms"]["p99"]
    # one step a sample: results wait, by whole samples of 5 ms
    assert row["result_wait_ms"]["p99"] >= 5.0


def test_bench_pipeline_command_prints_one_json_document():
    out = subprocess.run([str(SKIN), "bench", "pipeline", "--taxels", "16", "--seconds", "3",
                          "--json"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    (row,) = json.loads(out.stdout)["results"]
    assert row["taxels"] == 16 and row["frames"] == 600 and row["budget_ms"] == 1.0
    assert row["taxel_samples_per_s"] > 0 and row["realtime_factor"] > 0
    out = subprocess.run([str(SKIN), "bench", "pipeline", "--taxels", "0"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and "--taxels" in out.stderr


def test_bench_pipeline_compares_the_two_envelope_margins_in_the_same_run():
    out = subprocess.run([str(SKIN), "bench", "pipeline", "--taxels", "16", "--seconds", "3",
                          "--compare-envelope", "--compare-common-mode", "--json"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    (row,), (both,) = doc["results"], doc["envelope_compare"]
    assert row["envelope"] == "noise"  # the default detector's margin, named
    assert both["runs_each"] == 2
    assert both["noise"]["envelope"] == "noise" and both["flat"]["envelope"] == "flat"
    assert both["noise"]["frames"] == both["flat"]["frames"] == row["frames"] == 600
    ratio = both["noise_over_flat"]
    assert ratio["onset"] == round(both["noise"]["stages"]["onset"]
                                   / both["flat"]["stages"]["onset"], 3)
    assert ratio["chain"] > 0
    assert ratio["onset_cpu"] == round(both["noise"]["stages_cpu"]["onset"]
                                       / both["flat"]["stages_cpu"]["onset"], 3)
    # the board common mode on and off, alternated alike (16 taxels: one board, so it runs)
    (pair,) = doc["common_mode_compare"]
    assert pair["on"]["common_mode"] is True and pair["off"]["common_mode"] is False
    assert row["common_mode"] is True  # on by default: the bench's boards are not PID-held
    assert pair["on_over_off"]["onset"] == round(pair["on"]["stages"]["onset"]
                                                 / pair["off"]["stages"]["onset"], 3)

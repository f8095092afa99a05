"""``skin bench drivers`` and ``skin bench fuzz``: one JSON document each, sane figures."""

import json

import pytest

from skin.bench.drivers import BUSES, wiring
from skin.cli import main
from skin.drivers.bus_load import bus_load
from skin.drivers.protocol import CAN_MAX_TAXELS, MAX_TAXELS

pytest.importorskip("cobs")


def run_json(capsys, argv):
    assert main(argv) == 0
    out = capsys.readouterr().out
    return json.loads(out)  # stdout holds the JSON document and nothing else


@pytest.mark.parametrize(("bus", "bit_rate"), BUSES)
@pytest.mark.parametrize("taxels", [1, 64, 200, 1000, 5000])
def test_skins_are_cut_into_boards_that_fit_at_200_hz(bus, bit_rate, taxels):
    w = wiring(bus, bit_rate, taxels)
    assert sum(w.boards) == taxels and max(w.boards) - min(w.boards) <= 1
    assert sorted(b for link in w.links for b in link) == list(range(len(w.boards)))
    limit = MAX_TAXELS if bus == "serial" else CAN_MAX_TAXELS
    assert max(w.boards) <= limit
    for link in w.links:
        assert len(link) <= (1 if bus == "serial" else 7)
        assert sum(bus_load(bus, bit_rate, w.boards[b]).load for b in link) <= 0.95
    frames, skin_hz = w.physical()
    assert skin_hz >= 200 and frames >= 200 * len(w.boards)
    # one board fewer would not do
    if len(w.boards) > 1:
        assert -(-taxels // (len(w.boards) - 1)) > bus_load(bus, bit_rate, 1).max_taxels


def test_bench_drivers_quick_json(capsys):
    pytest.importorskip("serial")
    pytest.importorskip("can")
    doc = run_json(capsys, ["bench", "drivers", "--quick", "--json"])
    assert doc["machine"]["cpus"] >= 1 and doc["quick"] and doc["rate_hz"] == 200
    base = doc["baseline"]
    for key in ("memcpy_bytes_per_s", "read_loop_bytes_per_s", "frombuffer_us_per_frame",
                "garbage_decode_bytes_per_s"):
        assert base[key] > 0
    rows = doc["results"]
    backends = {r["backend"] for r in rows}
    assert backends == {"serial decode, 64 B reads", "serial decode, 4096 B reads",
                        "SerialDriver over a pty", "CAN reassembly",
                        "CanDriver over virtual CAN"}
    assert {(r["bus"], r["bit_rate"], r["taxels"]) for r in rows} == {
        (bus, rate, n) for bus, rate in BUSES for n in (64, 1000)}
    for r in rows:
        assert r["frames"] > 0 and r["seconds"] > 0
        assert r["frames_per_s"] > 0 and r["taxel_samples_per_s"] > 0 and r["us_per_frame"] > 0
        assert r["taxel_samples_per_s"] == pytest.approx(
            r["frames_per_s"] * r["taxels"] / r["boards"], rel=1e-3, abs=1)
        assert r["physical_frames_per_s"] > 0 and r["physical_skin_hz"] >= 200
        assert r["margin_physical"] > 0 and r["margin_200hz"] > 0 and r["skin_hz"] > 0
        assert sum(r["taxels_per_board"]) == r["taxels"] and r["layout"]
        assert r["x_frombuffer"] > 0
        if r["backend"].startswith("serial decode"):
            assert 0 < r["x_memcpy"] < 1 and r["x_garbage"] > 0
    assert any("7 boards" in r["layout"] for r in rows)  # 1000 taxels at 1 Mbaud


def test_bench_drivers_text(capsys):
    pytest.importorskip("serial")
    pytest.importorskip("can")
    assert main(["bench", "drivers", "--quick", "--taxels", "16"]) == 0
    out = capsys.readouterr().out
    assert "frames/s" in out and "baseline" in out and "x 200Hz" in out


def test_bench_fuzz_json(capsys):
    doc = run_json(capsys, ["bench", "fuzz", "--frames", "12800", "--seed", "3", "--json"])
    assert doc["seed"] == 3 and doc["frames_tried"] >= 12800
    assert doc["crashes"] == 0
    for bus in ("serial", "can"):
        s = doc[bus]["streams"]
        assert s["trials"] > 0 and s["sent"] > 0 and s["out"] > 0
        assert s["crashes"] == s["missed"] == s["unexplained"] == s["inconsistent"] == 0
    assert doc["serial"]["streams"]["corrupt"] == 0
    crc = {r["errors"]: r for r in doc["serial"]["crc"]}
    assert set(crc) == {"1-3 bits", "burst <= 16 bits", "uniform"}
    assert crc["1-3 bits"]["accepted"] == crc["burst <= 16 bits"]["accepted"] == 0
    assert crc["uniform"]["theory"] == 2.0**-16
    for r in doc["serial"]["crc"] + doc["can"]["bus_crc"]:
        lo, hi = r["ci95"]
        assert r["tried"] > 0 and 0 <= lo <= r["rate"] <= hi <= 1 and r["theory_in_ci"]
    bus = {r["errors"]: r for r in doc["can"]["bus_crc"]}
    assert bus["1-5 bits"]["accepted"] == 0 and bus["uniform"]["theory"] == 2.0**-15
    for r in bus.values():
        no, behind = r["reassembler"]["without_bus_crc"], r["reassembler"]["behind_bus_crc"]
        assert no["tried"] > 0 and behind["tried"] == r["tried"]
    assert bus["1-5 bits"]["reassembler"]["without_bus_crc"]["rate"] > 0.1  # no CRC: DATA bits
    assert all(p["tried"] > 0 and p["crashes"] == p["failures"] == 0
               for p in doc["parsers"].values())


def test_bench_fuzz_is_reproducible_and_prints_text(capsys):
    a = run_json(capsys, ["bench", "fuzz", "--frames", "1280", "--json"])
    b = run_json(capsys, ["bench", "fuzz", "--frames", "1280", "--json"])
    for doc in (a, b):
        del doc["wall_time"], doc["machine"]
    assert a == b
    assert main(["bench", "fuzz", "--frames", "1280"]) == 0
    out = capsys.readouterr().out
    assert "0 crashes" in out and "Clopper-Pearson" in out and "what protects" in out


def test_bench_fuzz_refuses_too_few_frames(capsys):
    assert main(["bench", "fuzz", "--frames", "10"]) == 2
    assert "--frames" in capsys.readouterr().err

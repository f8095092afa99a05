"""Recordings (MCAP) and replay: skin run --record, replay://, CAN, SIGKILL, damaged files."""

import dataclasses
import itertools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap")

from skin import drivers
from skin.drivers.protocol import StreamDecoder
from skin.drivers.recording import (
    Recorder,
    RecordingError,
    RecordingReader,
    layout_toml,
    read_recording,
)
from skin.drivers.replay import ReplayDriver, replay_path
from skin.errors import DeviceError
from skin.formats.layout import Layout, load_layout, parse_layout
from skin.stream.calibration import Calibration

SKIN = Path(sys.executable).with_name("skin")
EVENT_KEYS = ("contact", "taxels", "onset", "release", "decided_at", "final", "label",
              "effusivity", "confidence")


def skin(*args, cwd=None, timeout=60):
    proc = subprocess.run([str(SKIN), *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)
    assert proc.returncode == 0, proc.stderr
    return proc


def events(path):
    return [{k: e[k] for k in EVENT_KEYS}
            for e in map(json.loads, Path(path).read_text().splitlines())]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """``skin run`` on the simulated skin (default scene, 10 s), recorded: (folder, summary)."""
    folder = tmp_path_factory.mktemp("recorded")
    proc = skin("run", "--speed", "0", "--duration", "10", "--no-map", "--json", "--out",
                folder / "run", "--record", folder / "run.mcap")
    return folder, json.loads(proc.stdout)


def test_layout_toml_round_trips_a_shipped_and_an_in_memory_layout():
    arm = load_layout("arm")
    cut = Layout(arm.taxels[:5], [dataclasses.replace(arm.boards[0], adc_bits=12,
                                                      sensor_depth=1 / 3)],
                 name='cut "arm"\tfive', source="memory")
    for layout in (arm, cut):
        again = parse_layout(layout_toml(layout), source="again")
        assert again.name == layout.name and again.boards == layout.boards
        assert again.taxels == layout.taxels


def test_replay_of_a_recorded_run_gives_identical_events(recorded):
    folder, summary = recorded
    assert summary["frames"] == 2000 and summary["contacts"] > 3
    # replay://<relative path>, from the recording's folder, with the recorded layout
    proc = skin("run", "--port", "replay://run.mcap?speed=0", "--no-map", "--json", "--out",
                "again", cwd=folder)
    again = json.loads(proc.stdout)
    assert again["frames"] == 2000 and again["duration"] == 10.0
    assert again["crc_errors"] == 0 and again["gaps"] == 0
    assert "its layout (72 taxels)" in proc.stderr
    assert events(folder / "again" / "events.jsonl") == events(folder / "run" / "events.jsonl")


def test_a_recording_holds_wire_bytes_temperatures_events_and_layout(recorded):
    folder, _ = recorded
    rec = read_recording(folder / "run.mcap")
    assert rec.complete and rec.problem is None
    assert rec.metadata["thermoskin"]["format"] == "2"
    assert "--record" in rec.metadata["thermoskin"]["command"]
    assert rec.layout.boards == load_layout("arm").boards and len(rec.layout) == 72
    assert rec.calibration is None  # the nominal one: the layout's board constants
    (source,) = rec.sources
    assert (source.wire, source.board, source.topic) == ("serial", 0, "/wire/0")
    assert source.url.startswith("serial:///dev/pts/")
    # the wire bytes decode to the frames the run saw, in order, and calibrate to the
    # recorded temperatures
    messages = rec.wire[0]
    assert [m.sequence for m in messages] == list(range(len(messages)))
    assert all(a.log_time <= b.log_time for a, b in itertools.pairwise(messages))
    decoder = StreamDecoder(0)
    frames = [f for m in messages for f in decoder.feed(m.data)]
    assert [f.seq for f in frames] == list(range(2000))
    assert decoder.stats.crc_errors == decoder.stats.malformed == 0
    assert rec.temperature.shape == (2000, 72)
    assert np.array_equal(rec.times, [f.device_time for f in frames])
    _, addr = rec.layout.channel_map(0)
    counts = np.array([f.counts[addr] for f in frames], dtype=float)
    expected, _ = Calibration.from_layout(rec.layout).temperature(counts)
    assert np.allclose(rec.temperature, expected, atol=1e-4, equal_nan=True)
    recorded_events = [{k: e[k] for k in EVENT_KEYS} for e in rec.events]
    assert recorded_events == events(folder / "run" / "events.jsonl")


#: How late a paced source may finish on a loaded machine, s (it is never early). Below
#: 0.3 s, so a replay at twice the speed still cannot pass for one at real speed.
LATE = 0.25


def test_replay_paces_at_real_speed_or_as_fast_as_possible(tmp_path):
    from skin.formats.scene import load_scene

    path = tmp_path / "paced.mcap"
    with Recorder(path, load_scene("default").layout) as recorder:
        started = time.monotonic()
        with drivers.open("sim://default?speed=1&duration=0.6") as source:
            opened = time.monotonic()
            recorder.add_driver(source)
            assert len(list(source)) == 120
            ended = time.monotonic()
    assert ended - started >= 0.595 and ended - opened <= 0.6 + LATE  # paced from its open
    # the replay keeps the recorded arrival times (late ones included), divided by the speed
    logged = [m.log_time for m in read_recording(path).wire[0]]
    arrivals = (logged[-1] - logged[0]) * 1e-9
    assert arrivals > 0.5  # paced arrivals were recorded, not one burst
    for speed in (1, 2, 0):
        with drivers.open(f"replay://{path}?speed={speed}") as replay:
            t0 = time.monotonic()
            frames = list(replay)
            took = time.monotonic() - t0
            assert replay.finished and len(frames) == 120
        expected = arrivals / speed if speed else 0.0
        assert expected - 1e-3 <= took <= expected + LATE, speed
        # frames arrive on the replay's time line, in step with the recorded one
        span = frames[-1].device_time - frames[0].device_time
        assert span == pytest.approx(0.595, abs=1e-6)


def test_can_recording_over_the_virtual_bus_replays_the_same_frames(tmp_path, request):
    pytest.importorskip("can")
    from skin.drivers.can_sim import CanSimNode
    from skin.drivers.sim import SkinSimulator
    from skin.formats.scene import load_scene

    channel = f"rec-{request.node.name}"
    path = tmp_path / "can.mcap"
    sim = SkinSimulator(load_scene("default"), duration=0.5)
    with drivers.open(f"can://virtual/{channel}") as driver, \
            CanSimNode(sim, ("virtual", channel), node=2, speed=0) as node, \
            Recorder(path, sim.layout) as recorder:
        assert recorder.add_driver(driver)
        node.start()
        live = []
        while (frame := driver.recv(timeout=0.3)) is not None:
            live.append(frame)
        live_stats = driver.stats
    assert len(live) == 100
    (source,) = read_recording(path).sources
    assert (source.wire, source.url) == ("can", f"can://virtual/{channel}")
    with drivers.open(f"replay://{path}?speed=0") as replay:
        assert replay.wire == "can"
        again = list(replay)
        assert replay.stats.frames == live_stats.frames == 100
        assert replay.stats.bytes == live_stats.bytes
        assert replay.stats.malformed == live_stats.malformed
    assert len(again) == len(live)
    for a, b in zip(again, live, strict=True):
        assert (a.seq, a.device_time, a.board, a.flags) == (b.seq, b.device_time, b.board,
                                                            b.flags)
        assert np.array_equal(a.counts, b.counts) and np.array_equal(a.duty, b.duty)
        assert np.array_equal(a.status, b.status) and a.ambient == b.ambient


def test_a_recording_killed_with_sigkill_reads_to_its_last_complete_message(tmp_path):
    path = tmp_path / "killed.mcap"
    proc = subprocess.Popen([str(SKIN), "run", "--speed", "1", "--duration", "20", "--no-map",
                             "--out", tmp_path / "run", "--record", path],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 30
        while (not path.exists() or path.stat().st_size < 150_000) and proc.poll() is None:
            assert time.monotonic() < deadline, "the recording did not grow"
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    rec = read_recording(path)
    assert not rec.complete and str(path) in rec.problem and "byte" in rec.problem
    assert rec.layout is not None and len(rec.layout) == 72
    # every wire message is there, in sequence, and decodes to consecutive frames
    messages = rec.wire[0]
    assert [m.sequence for m in messages] == list(range(len(messages)))
    decoder = StreamDecoder(0)
    seqs = [f.seq for m in messages for f in decoder.feed(m.data)]
    assert len(seqs) >= 100 and seqs == list(range(len(seqs)))
    assert decoder.stats.crc_errors == decoder.stats.malformed == 0
    # the temperatures recorded are those of frames that came off the wire
    assert 0 < len(rec.times) <= len(seqs)
    assert np.allclose(rec.times, np.arange(len(rec.times)) / 200.0)
    # and the killed recording replays
    with ReplayDriver(path, speed=0) as replay:
        assert [f.seq for f in replay] == seqs
        assert replay.problem == rec.problem


def _messages(path):
    with RecordingReader(path) as reader:
        return list(reader.messages())


def test_a_file_cut_anywhere_keeps_every_complete_message_before_the_cut(recorded, tmp_path):
    folder, _ = recorded
    data = (folder / "run.mcap").read_bytes()
    full = _messages(folder / "run.mcap")
    # record head (opcode, u64 length) and body
    ends = [m.offset + 9 + int.from_bytes(data[m.offset + 1 : m.offset + 9], "little")
            for m in full]
    cut = tmp_path / "cut.mcap"
    rng = np.random.default_rng(0)
    sizes = [0, 5, 9, full[0].offset, ends[0] - 1, ends[0], ends[50] + 1,
             *rng.integers(8, len(data), 30)]
    for size in sizes:
        cut.write_bytes(data[:size])
        if size < 8:
            with pytest.raises(RecordingError, match="not an MCAP recording"):
                RecordingReader(cut)
            continue
        got = _messages(cut)
        expected = [m for m, end in zip(full, ends, strict=True) if end <= size]
        assert [(m.offset, m.data) for m in got] == [(m.offset, m.data) for m in expected]
        rec = read_recording(cut)
        assert not rec.complete and rec.problem.startswith(f"{cut}: ") and "byte" in rec.problem


def test_a_corrupt_record_is_named_with_its_byte_offset_after_the_messages_before_it(
        recorded, tmp_path):
    folder, _ = recorded
    data = bytearray((folder / "run.mcap").read_bytes())
    offsets = [m.offset for m in _messages(folder / "run.mcap")]
    bad = tmp_path / "bad.mcap"
    k = len(offsets) // 2
    at = offsets[k]
    data[at] = 0x42  # an opcode MCAP does not have
    bad.write_bytes(data)
    with pytest.raises(RecordingError, match=rf"{bad}: corrupt at byte {at}: .*0x42"):
        read_recording(bad)
    reader = RecordingReader(bad)
    got = []
    with pytest.raises(RecordingError, match=f"byte {at}"):
        for msg in reader.messages():
            got.append(msg)
    assert [m.offset for m in got] == offsets[:k]
    # a replay hands over every frame before the damage, then says where it is
    frames = []
    with ReplayDriver(bad, speed=0) as replay:
        with pytest.raises(DeviceError, match=rf"{bad}: corrupt at byte {at}"):
            while (frame := replay.recv(timeout=1.0)) is not None:
                frames.append(frame)
    wire_before = [m for m in got if m.topic == "/wire/0"]
    decoder = StreamDecoder(0)
    assert [f.seq for f in frames] == [f.seq for m in wire_before for f in decoder.feed(m.data)]


def test_files_that_are_no_recording_give_clear_errors(tmp_path):
    missing = tmp_path / "missing.mcap"
    with pytest.raises(DeviceError, match=r"missing\.mcap: cannot open"):
        drivers.open(f"replay://{missing}")
    text = tmp_path / "text.mcap"
    text.write_text("hello, world\n")
    with pytest.raises(RecordingError, match=r"text\.mcap: not an MCAP recording"):
        read_recording(text)
    with pytest.raises(DeviceError, match="no file"):
        drivers.open("replay://")
    with pytest.raises(DeviceError, match="speed"):
        drivers.open(f"replay://{text}?speed=-1")


def test_a_damaged_attachment_fails_its_crc(tmp_path):
    path = tmp_path / "a.mcap"
    with Recorder(path, load_layout("arm")):
        pass
    data = bytearray(path.read_bytes())
    at = data.index(b"[[taxels]]")
    data[at + 2] ^= 0x20
    path.write_bytes(data)
    with pytest.raises(RecordingError, match=r"corrupt at byte \d+: attachment 'layout.toml'"):
        read_recording(path)


def test_replay_url_paths():
    assert replay_path("replay://run.mcap?speed=0") == Path("run.mcap")
    assert replay_path("replay://out/run.mcap") == Path("out/run.mcap")
    assert replay_path("replay:///abs/path/run.mcap") == Path("/abs/path/run.mcap")
    assert replay_path("replay://my%20run.mcap") == Path("my run.mcap")


def test_recorded_calibration_is_used_by_the_replay(tmp_path):
    from skin.formats.calibration_file import CalibrationFile, load_calibration

    layout = load_layout("arm")
    cal = CalibrationFile(taxels={0: {"thermistor": [9.6e-4, 2.6e-4, 0.0]}}, ambient_offset=0.5)
    cal_path = cal.save(tmp_path / "cal.json")
    arrays = Calibration.from_layout(layout)
    for given, kind in ((cal_path, "file"), (load_calibration(cal_path), "file"),
                        (arrays, "arrays")):
        path = tmp_path / f"{kind}.mcap"
        with Recorder(path, layout, calibration=given):
            pass
        with ReplayDriver(path) as replay:
            got = replay.calibration
        if kind == "file":
            assert got.taxels == cal.taxels and got.ambient_offset == 0.5
        else:
            for name in ("c0", "c1", "divider_resistor", "adc_max"):
                assert np.array_equal(getattr(got, name), getattr(arrays, name))


def test_skin_record_command_records_the_raw_bytes(tmp_path):
    proc = skin("record", "sim://default?speed=0&duration=2", "rec.mcap", "--json", cwd=tmp_path)
    summary = json.loads(proc.stdout)
    assert summary["frames"] == 400 and summary["crc_errors"] == 0
    assert summary["file_bytes"] == (tmp_path / "rec.mcap").stat().st_size
    rec = read_recording(tmp_path / "rec.mcap")
    assert rec.complete and len(rec.layout) == 72
    assert len(rec.times) == 0 and rec.events == []  # raw bytes only
    assert sum(len(m.data) for m in rec.wire[0]) == summary["wire_bytes"]
    with drivers.open(f"replay://{tmp_path / 'rec.mcap'}?speed=0") as replay:
        assert [f.seq for f in replay] == list(range(400))


def test_without_mcap_recording_fails_with_the_install_hint(tmp_path):
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'mcap' or name.startswith('mcap.'):\n"
        "            raise ImportError('blocked')\n"
        "sys.meta_path.insert(0, Block())\n"
        "from skin.drivers.recording import Recorder\n"
        "from skin.errors import MissingDependencyError\n"
        "from skin.formats.layout import load_layout\n"
        "try:\n"
        f"    Recorder({str(tmp_path / 'x.mcap')!r}, load_layout('arm'))\n"
        "except MissingDependencyError as exc:\n"
        "    print(exc)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "'mcap'" in out and "pip install 'thermoskin[record]'" in out

"""Recordings that standard tools open: the mcap library's own reader, chunked zstd copies."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

mcap = pytest.importorskip("mcap")
pytest.importorskip("zstandard")

from mcap.reader import make_reader  # noqa: E402
from mcap.writer import CompressionType, Writer  # noqa: E402

from skin.drivers.clock import WALL_OFFSET  # noqa: E402
from skin.drivers.recording import Recorder, RecordingError, read_recording  # noqa: E402
from skin.formats import protobuf  # noqa: E402
from skin.formats.scene import load_scene  # noqa: E402

SKIN = Path(sys.executable).with_name("skin")


def skin(*args):
    proc = subprocess.run([str(SKIN), *map(str, args)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rec")
    skin("run", "--speed", "0", "--duration", "8", "--no-map", "--json", "--out",
         folder / "run", "--record", folder / "run.mcap")
    return folder


def copy_with_mcap(src: Path, dst: Path, compression=CompressionType.ZSTD) -> None:
    """Rewrite a recording chunked and compressed with the mcap library alone (as tools do)."""
    with src.open("rb") as f, dst.open("wb") as out:
        reader = make_reader(f)
        header = reader.get_header()
        writer = Writer(out, compression=compression, chunk_size=64 * 1024)
        writer.start(profile=header.profile, library="copy")
        for meta in reader.iter_metadata():
            writer.add_metadata(meta.name, meta.metadata)
        for a in reader.iter_attachments():
            writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        schemas, channels = {}, {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if schema is not None and schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding,
                                                            schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding,
                    schemas.get(channel.schema_id, 0), channel.metadata)
            writer.add_message(channels[channel.id], message.log_time, message.data,
                               message.publish_time, message.sequence)
        writer.finish()


def test_mcap_reader_recognises_every_channel_and_one_message_per_sample(recorded):
    path = recorded / "run.mcap"
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]  # every channel has a schema
            assert schema.encoding in ("protobuf", "jsonschema"), channel.topic
            assert channel.message_encoding == {"protobuf": "protobuf",
                                                "jsonschema": "json"}[schema.encoding]
        names = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert names["/temperature"] == "thermoskin.Temperature"
        assert names["/wire/0"] == "thermoskin.Wire"
        json.loads(summary.schemas[next(c.schema_id for c in summary.channels.values()
                                        if c.topic == "/events")].data)
        temps, events = [], []
        for _, channel, message in reader.iter_messages(log_time_order=False):
            if channel.topic == "/temperature":
                temps.append((message.log_time, protobuf.decode_temperature(message.data)))
            elif channel.topic == "/events":
                events.append((message.log_time, json.loads(message.data)))
    rec = read_recording(path)
    assert len(temps) == len(rec.times) == 1600  # one message per sample
    assert [t["device_time"] for _, t in temps] == rec.times.tolist()
    # log time = the sample's host time
    assert all(abs(log * 1e-9 - t["host_time"]) < 1e-6 for log, t in temps)
    assert temps[0][1]["taxel"] == rec.layout.ids.tolist()
    # events: logged at the host time their result was given
    assert events and all(abs(log * 1e-9 - e["host_reported_at"]) < 1e-5 for log, e in events)


def test_a_chunked_zstd_copy_reads_and_replays_to_the_same_events(recorded, tmp_path):
    path = recorded / "run.mcap"
    copy = tmp_path / "copy.mcap"
    copy_with_mcap(path, copy)
    assert copy.read_bytes().count(b"zstd") > 1  # chunked and compressed
    a, b = read_recording(path), read_recording(copy)
    assert b.complete and b.problem is None
    assert np.array_equal(a.times, b.times)
    assert np.array_equal(a.temperature, b.temperature, equal_nan=True)
    assert a.events == b.events
    assert [m.data for m in a.wire[0]] == [m.data for m in b.wire[0]]
    keys = ("contact", "taxels", "onset", "label", "final")
    replays = []
    for src in (path, copy):
        out = tmp_path / src.stem
        skin("run", "--port", f"replay://{src}?speed=0", "--no-map", "--json", "--out", out)
        replays.append([{k: e[k] for k in keys}
                        for e in map(json.loads, (out / "events.jsonl").read_text()
                                     .splitlines())])
    assert replays[0] == replays[1] and replays[0]


def test_recorder_writes_zstd_chunks_that_read_back(tmp_path):
    layout = load_scene("default").layout
    path = tmp_path / "z.mcap"
    times = np.arange(500) / 200
    temp = 30 + np.sin(times)[:, None] * np.ones(len(layout))
    with Recorder(path, layout, compression="zstd") as rec:
        for k in range(0, 500, 50):
            rec.temperature(times[k : k + 50], temp[k : k + 50], 100.0 + times[k : k + 50])
    back = read_recording(path)
    assert np.array_equal(back.times, times)
    assert np.allclose(back.temperature, temp, atol=1e-5)
    with path.open("rb") as f:
        stamps = [m.log_time for _, _, m in make_reader(f).iter_messages()]
    assert stamps[0] == round((100.0 + WALL_OFFSET) * 1e9)
    with pytest.raises(RecordingError, match="unknown compression"):
        Recorder(tmp_path / "x.mcap", layout, compression="gzip")


def test_a_chunk_with_a_bad_crc_is_named_with_its_byte_offset(recorded, tmp_path):
    copy = tmp_path / "copy.mcap"
    copy_with_mcap(recorded / "run.mcap", copy, CompressionType.NONE)
    data = bytearray(copy.read_bytes())
    chunk = 8  # walk the records to the first CHUNK
    while data[chunk] != 0x06:
        chunk += 9 + int.from_bytes(data[chunk + 1 : chunk + 9], "little")
    data[chunk + 200] ^= 0xFF  # a byte well inside the chunk's records
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=r"corrupt at byte \d+"):
        read_recording(bad)

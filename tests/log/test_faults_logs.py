"""Fault injection, episode logs: damaged files, foreign files and output names, told apart."""

import json

import pytest
from mcap.reader import SeekingReader
from mcap.writer import Writer

from amex.app.log_cli import main
from amex.core.errors import CorruptLogError, LogError
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.log import read_log
from amex.methods.dmp import DMPConfig


@pytest.fixture(scope="module")
def log_file(tmp_path_factory):
    """One logged Task-3 DMP episode of 1.5 s (several 64 KiB chunks)."""
    config = RunConfig(task=3, max_time=1.5)
    config.method = DMPConfig()
    path = tmp_path_factory.mktemp("log") / "episode_000.mcap"
    run_one(config, prepare(config), 0, path)
    return path


def _chunk_content(path, which: float) -> int:
    """An offset inside the compressed content of one chunk (by the file's own index).

    ``which`` in [0, 1) picks the chunk; the offset never depends on the logged values, whose
    last bits (and so the compressed sizes) follow the machine's BLAS kernel.
    """
    with open(path, "rb") as f:
        summary = SeekingReader(f).get_summary()
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    chunk = chunks[min(int(which * len(chunks)), len(chunks) - 1)]
    return chunk.chunk_start_offset + chunk.chunk_length // 2  # well inside its records


def _flipped(src, dst, where: float, count: int = 20):
    data = bytearray(src.read_bytes())
    start = _chunk_content(src, where)
    for i in range(start, start + count):
        data[i] ^= 0xFF
    dst.write_bytes(bytes(data))
    return dst


def _content(data):
    return data.metadata, {
        topic: [(m.log_time, m.data) for m in messages] for topic, messages in data.messages.items()
    }


def _run(argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


def test_flipped_bytes_inside_a_complete_file_are_corrupt_not_truncated(log_file, tmp_path, capsys):
    intact = read_log(log_file)
    damaged = read_log(_flipped(log_file, tmp_path / "flipped.mcap", 0.5))
    assert damaged.corrupt and not damaged.truncated
    assert "1 damaged chunk skipped" in damaged.note
    assert f"of {intact.message_count} messages read" in damaged.note
    assert 0.6 * intact.message_count < damaged.message_count < intact.message_count
    assert damaged.duration == pytest.approx(intact.duration)  # chunks after the damage are read
    code, out, _ = _run(["info", tmp_path / "flipped.mcap"], capsys)
    assert code == 0 and "corrupt file" in out and "truncated" not in out


@pytest.mark.parametrize("where", [i / 40 for i in range(40)])
def test_no_flipped_bytes_pass_as_an_intact_file_with_other_content(log_file, tmp_path, where):
    """20 bytes flipped anywhere: an error, a file said to be damaged, or the same content."""
    data = bytearray(log_file.read_bytes())
    start = int(len(data) * where)
    for i in range(start, min(start + 20, len(data))):
        data[i] ^= 0xFF
    path = tmp_path / "flipped.mcap"
    path.write_bytes(bytes(data))
    try:
        damaged = read_log(path)
    except LogError:
        return
    assert damaged.damage or _content(damaged) == _content(read_log(log_file))


def test_a_cut_file_is_truncated_not_corrupt(log_file, tmp_path, capsys):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(log_file.read_bytes()[: int(log_file.stat().st_size * 0.7)])
    data = read_log(cut)
    assert data.truncated and not data.corrupt
    code, out, _ = _run(["info", cut], capsys)
    assert code == 0 and "truncated file" in out and "corrupt" not in out


def test_a_file_damaged_everywhere_is_one_line_naming_it_corrupt(log_file, tmp_path, capsys):
    data = bytearray(log_file.read_bytes())
    for i in range(200, len(data) - 200, 512):
        data[i] ^= 0xFF
    path = tmp_path / "ruined.mcap"
    path.write_bytes(bytes(data))
    with pytest.raises(CorruptLogError):
        read_log(path)
    code, _, err = _run(["info", path], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "corrupt" in err


def test_recover_writes_the_readable_part_of_a_corrupt_file(log_file, tmp_path, capsys):
    _flipped(log_file, tmp_path / "flipped.mcap", 0.4)
    code, out, _ = _run(["recover", tmp_path / "flipped.mcap", "-o", tmp_path / "fixed"], capsys)
    assert code == 0 and "corrupt file" in out and "fixed.mcap" in out
    fixed = read_log(tmp_path / "fixed.mcap")
    assert not fixed.damage and fixed.metadata["recovery"]["corrupt"] is True


@pytest.fixture
def foreign(tmp_path):
    path = tmp_path / "other_tool.mcap"
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="", library="another tool")
        schema = writer.register_schema("x", "jsonschema", b"{}")
        channel = writer.register_channel("/foo", "json", schema)
        for i in range(10):
            writer.add_message(channel, i * 1000, json.dumps({"a": i}).encode(), i * 1000)
        writer.finish()
    return path


def test_a_valid_mcap_from_another_tool_is_not_called_unfinished(foreign, capsys):
    code, out, _ = _run(["info", foreign], capsys)
    assert code == 0 and "not an amex episode log" in out and "did not finish" not in out
    code, _, err = _run(["plot", foreign], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_plot_reports_the_file_it_really_wrote(log_file, tmp_path, capsys):
    code, out, _ = _run(["plot", log_file, "-o", tmp_path / "figure"], capsys)
    assert code == 0 and out.strip() == f"wrote {tmp_path / 'figure.png'}"
    assert (tmp_path / "figure.png").stat().st_size > 10_000
    code, out, _ = _run(["plot", log_file, "-o", tmp_path], capsys)  # a directory: into it
    assert code == 0 and (tmp_path / "episode_000.png").exists()


@pytest.mark.parametrize(
    ("command", "name"),
    [("plot", "out.txt"), ("plot", "episode.mcap"), ("recover", "out.txt"), ("layout", "x.mcap")],
)
def test_a_bad_output_suffix_is_one_line_and_writes_nothing(
    log_file, tmp_path, capsys, command, name
):
    argv = [command] + ([log_file] if command != "layout" else []) + ["-o", tmp_path / name]
    code, out, err = _run(argv, capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "valid: a name ending in" in err
    assert not (tmp_path / name).exists()


def test_layout_never_overwrites(log_file, tmp_path, capsys):
    target = tmp_path / "episode_000.json"
    target.write_text("precious")
    code, _, err = _run(["layout", "-o", target], capsys)
    assert code == 2 and "already exists" in err and target.read_text() == "precious"
    code, out, _ = _run(["layout", "-o", tmp_path / "panda_layout.json"], capsys)
    assert code == 0 and json.loads((tmp_path / "panda_layout.json").read_text())


def _rewritten(log_file, path, damage):
    """``log_file`` rewritten with ``damage(topic, index, data) -> data`` applied per message."""
    from mcap.writer import CompressionType

    raw = read_log(log_file)._raw
    with open(path, "wb") as f:
        writer = Writer(f, compression=CompressionType.ZSTD)
        writer.start(profile="", library="test")
        schemas = {
            sid: writer.register_schema(s.name, s.encoding, s.data)
            for sid, s in sorted(raw.schemas.items())
        }
        channels = {
            cid: writer.register_channel(c.topic, c.message_encoding, schemas.get(c.schema_id, 0))
            for cid, c in sorted(raw.channels.items())
        }
        for record in raw.metadata:
            writer.add_metadata(record.name, dict(record.metadata))
        seen: dict[str, int] = {}
        for m in raw.messages:
            topic = raw.channels[m.channel_id].topic
            i = seen[topic] = seen.get(topic, -1) + 1
            data = damage(topic, i, m.data)
            writer.add_message(channels[m.channel_id], m.log_time, data, m.publish_time)
        writer.finish()
    return path


def test_one_undecodable_message_leaves_the_rest_of_its_topic_decoded(log_file, tmp_path):
    def damage(topic, i, data):
        return b"\xff\xff\xff" if topic == "/joint_states" and i == 3 else data

    data = read_log(_rewritten(log_file, tmp_path / "one_bad.mcap", damage))
    decoded = data.decoded("/joint_states")
    assert isinstance(decoded[3].data, bytes)
    assert all(isinstance(m.data, dict) for i, m in enumerate(decoded) if i != 3)


def test_export_says_which_messages_it_left_out(log_file, tmp_path, capsys):
    def damage(topic, i, data):
        return b"{not json" if topic == "/tcp" and i in (2, 5) else data

    path = _rewritten(log_file, tmp_path / "bad_json.mcap", damage)
    code, out, err = _run(["export", path, "-o", tmp_path / "tables"], capsys)
    assert code == 0 and "2 of" in err and "/tcp messages could not be decoded" in err

"""The recorder's fast message appender writes what rosbags' own writer writes."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from pdsmc_ros.bag import cdr
from pdsmc_ros.bag.writer import MessageAppender, close_chunk, flush_chunk, open_new_bag
from pdsmc_ros.errors import ConfigError

TOPICS = (("/joint_states", "sensor_msgs/msg/JointState"),
          ("/effort_controller/commands", "std_msgs/msg/Float64MultiArray"))


def _messages(count: int) -> list[tuple[int, int, bytes]]:
    """(topic index, timestamp, data): interleaved topics, a timestamp going backwards,
    and enough bytes to close several 1 MiB chunks."""
    out = []
    for k in range(count):
        js = cdr.encode_joint_state(k // 10, k, ["a", "b"], [0.1 * k, 2.0], [3.0, k], [])
        out.append((0, 1_000_000 + 37 * k, js))
        out.append(
            (1, 1_000_000 + 37 * k + (-500 if k == 7 else 5), cdr.encode_float64_multi_array([1.0] * (k % 40), k))
        )
    return out


def _without_crcs(mcap: bytes) -> bytes:
    """The file with each chunk's CRC-32 checked and then zeroed (rosbags writes 0 there; so does
    its ``Writer.close`` for the last chunk, which the recorder closes itself before)."""
    out = bytearray(mcap)
    off = 8  # magic
    chunks = 0
    while off + 9 <= len(out):
        opcode = out[off]
        (length,) = struct.unpack_from("<Q", out, off + 1)
        body = off + 9
        if opcode == 0x06:
            size, crc = struct.unpack_from("<QI", out, body + 16)
            (kind_len,) = struct.unpack_from("<I", out, body + 28)
            records = body + 32 + kind_len + 8
            if crc:
                assert crc == zlib.crc32(bytes(out[records:records + size])), off
                struct.pack_into("<I", out, body + 24, 0)
                chunks += 1
        off = body + length
    assert chunks > 0
    return bytes(out)


def _write(path: Path, messages: list[tuple[int, int, bytes]], fast: bool, flush_every: int = 0) -> None:
    """Write ``messages`` with rosbags or with ours, closing a chunk every ``flush_every``
    messages as the recorder's flush does (0: only when a chunk is full)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = [writer.add_connection(topic, msgtype, typestore=store) for topic, msgtype in TOPICS]
        appenders = [MessageAppender(writer, conn) for conn in conns]
        for k, (index, stamp, data) in enumerate(messages):
            if fast:
                appenders[index].append(stamp, data)
            else:
                writer.write(conns[index], stamp, data)
            if flush_every and k % flush_every == flush_every - 1:
                close_chunk(writer.storage) if fast else writer.storage.close_chunk()


@pytest.mark.parametrize("flush_every", [0, 997])
def test_appender_writes_the_bytes_rosbags_writes(tmp_path: Path, flush_every: int) -> None:
    messages = _messages(12_000)  # about 3.5 MB: several chunks
    _write(tmp_path / "rosbags" / "bag", messages, fast=False, flush_every=flush_every)
    _write(tmp_path / "fast" / "bag", messages, fast=True, flush_every=flush_every)
    for name in ("bag.mcap", "metadata.yaml"):  # same bag name: the metadata names the file
        ours = (tmp_path / "fast" / "bag" / name).read_bytes()
        theirs = (tmp_path / "rosbags" / "bag" / name).read_bytes()
        assert (_without_crcs(ours) if name.endswith(".mcap") else ours) == theirs, name
    assert len(theirs) > 0 and (tmp_path / "fast" / "bag" / "bag.mcap").stat().st_size > 3 * 2**20


def test_batches_write_the_bytes_rosbags_writes(tmp_path: Path) -> None:
    """append_many (the recorder's batches: runs of one topic at one receive time) against
    rosbags writing the same messages one by one; batches cross chunk boundaries."""
    messages = _messages(12_000)
    batches: list[tuple[int, int, list[bytes]]] = []
    for k, (index, _stamp, data) in enumerate(messages):
        stamp = 2_000_000 + 1_000 * (k // 7)  # a few messages share a receive time
        if batches and batches[-1][0] == index and batches[-1][1] == stamp:
            batches[-1][2].append(data)
        else:
            batches.append((index, stamp, [data]))
    store = get_typestore(Stores.ROS2_JAZZY)
    for fast in (False, True):
        with Writer(tmp_path / ("fast" if fast else "rosbags") / "bag", version=9,
                    storage_plugin=StoragePlugin.MCAP) as writer:
            conns = [writer.add_connection(topic, msgtype, typestore=store) for topic, msgtype in TOPICS]
            appenders = [MessageAppender(writer, conn) for conn in conns]
            for index, stamp, datas in batches:
                if fast:
                    appenders[index].append_many(stamp, datas)
                else:
                    for data in datas:
                        writer.write(conns[index], stamp, data)
    ours = (tmp_path / "fast" / "bag" / "bag.mcap").read_bytes()
    assert _without_crcs(ours) == (tmp_path / "rosbags" / "bag" / "bag.mcap").read_bytes()
    assert (tmp_path / "fast" / "bag" / "metadata.yaml").read_bytes() == \
        (tmp_path / "rosbags" / "bag" / "metadata.yaml").read_bytes()


def test_a_new_bag_is_opened_only_in_a_new_directory(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="the bag directory to write is required"):
        open_new_bag("")
    with pytest.raises(ConfigError, match="already exists; choose a new bag directory"):
        open_new_bag(str(tmp_path))
    (tmp_path / "file").write_text("")
    with pytest.raises(ConfigError, match="cannot create"):
        open_new_bag(str(tmp_path / "file" / "sub" / "bag"))  # a parent that is a file
    writer = open_new_bag(str(tmp_path / "deeper" / "bag"))  # the parent is created
    assert writer.storage is not None and (tmp_path / "deeper" / "bag").is_dir()
    writer.close()


def test_flush_chunk_puts_the_messages_on_disk_before_close(tmp_path: Path) -> None:
    writer = open_new_bag(str(tmp_path / "bag"))
    conn = writer.add_connection(*TOPICS[0], typestore=get_typestore(Stores.ROS2_JAZZY))
    appender = MessageAppender(writer, conn)
    data = cdr.encode_joint_state(0, 0, ["a", "b"], [0.1, 2.0], [3.0, 4.0], [])
    for k in range(100):
        appender.append(1_000 + k, data)
    mcap = next((tmp_path / "bag").glob("*.mcap"))
    before = mcap.stat().st_size
    flush_chunk(writer)
    assert mcap.stat().st_size >= before + 100 * len(data)  # the chunk's records, with the messages
    assert writer.storage.chunk.bio.tell() == 0  # a new chunk is open
    writer.close()
    flush_chunk(None)  # a closed recorder's writer: nothing to do


def test_appender_refuses_a_closed_bag_or_a_foreign_connection(tmp_path: Path) -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    writer = Writer(tmp_path / "a", version=9, storage_plugin=StoragePlugin.MCAP)
    with pytest.raises(ValueError, match="not open"):
        MessageAppender(writer, None)
    other = Writer(tmp_path / "b", version=9, storage_plugin=StoragePlugin.MCAP)
    with writer, other:
        foreign = other.add_connection("/x", "std_msgs/msg/String", typestore=store)
        with pytest.raises(ValueError, match="'/x' is not one of this bag's"):
            MessageAppender(writer, foreign)


def test_run_progress_counts_the_newest_step_of_each_topic_and_ignores_foreign_messages() -> None:
    from pdsmc_ros.bag.cdr import encode_float64_multi_array, encode_joint_state
    from pdsmc_ros.bag.stamps import step_stamp
    from pdsmc_ros.bag.writer import RunProgress

    rate = 100.0

    def state(k: int) -> bytes:
        return encode_joint_state(*step_stamp(k, rate), ["j"], [0.0], [0.0], [0.0])

    progress = RunProgress(("joint_states", "effort"), "effort", last_step=5, rate=rate)
    assert not progress.batch("joint_states", [state(k) for k in range(6)])  # efforts still missing
    assert not progress.batch("effort", [encode_float64_multi_array([0.0], 4), state(99)])  # a foreign one
    assert progress.seen == {"joint_states": 5, "effort": 4}
    assert not progress.batch("effort", [encode_float64_multi_array([0.0], 1000)])  # beyond the run: a rogue's
    assert progress.batch("effort", [encode_float64_multi_array([0.0], 5)])

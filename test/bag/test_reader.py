"""The run reader names a run by the controller's description, or by the recorder's own."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from pdsmc_ros.bag.reader import RECORDER_DESCRIPTION_TOPIC, read_run
from pdsmc_ros.errors import BagError
from pdsmc_ros.runs.builder import make_run

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
String = TYPESTORE.types["std_msgs/msg/String"]


def description(controller: str) -> str:
    data = make_run("serial_3r", "circle", controller).describe()
    data["mode"] = "lockstep"
    return json.dumps(data, sort_keys=True)


def write_bag(path: Path, topics: dict[str, str]) -> Path:
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for i, (topic, text) in enumerate(topics.items()):
            conn = writer.add_connection(topic, "std_msgs/msg/String", typestore=TYPESTORE)
            writer.write(conn, i, TYPESTORE.serialize_cdr(String(data=text), "std_msgs/msg/String"))
    return path


def test_the_controllers_description_names_the_run(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "both", {RECORDER_DESCRIPTION_TOPIC: description("pd"),
                                        "/pdsmc/run_description": description("pdsmc")})
    run = read_run(bag)
    assert run.description["controller"] == "pdsmc" and not run.description_from_recorder


def test_without_it_the_recorders_own_description_names_the_run(tmp_path: Path) -> None:
    run = read_run(write_bag(tmp_path / "own", {RECORDER_DESCRIPTION_TOPIC: description("smc")}))
    assert run.description["controller"] == "smc" and run.description_from_recorder


def test_a_bag_with_neither_is_not_a_run(tmp_path: Path) -> None:
    with pytest.raises(BagError, match="not a pdsmc_ros run"):
        read_run(write_bag(tmp_path / "none", {"/chatter": "hello"}))


def test_a_corrupted_chunk_is_reported_not_read(tmp_path: Path) -> None:
    """Chunks carry their CRC-32 (bag/writer.close_chunk): a flipped byte inside one is an error
    naming the chunk, never silently different numbers."""
    import struct

    from pdsmc_ros.bag import cdr
    from pdsmc_ros.bag.mcapscan import scan
    from pdsmc_ros.bag.writer import MessageAppender, close_chunk

    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState",
                                     typestore=get_typestore(Stores.ROS2_JAZZY))
        MessageAppender(writer, conn).append_many(1, [cdr.encode_joint_state(0, k, ["a"], [0.5 * k], [0.0], [])
                                                      for k in range(100)])
        close_chunk(writer.storage)
    mcap = bag / "bag.mcap"
    assert len(scan(mcap, ["/joint_states"]).messages["/joint_states"]) == 100
    data = bytearray(mcap.read_bytes())
    chunk = data.index(b"\x06", 8)  # the first chunk record after the header
    records = chunk + 9 + 32 + struct.unpack_from("<I", data, chunk + 9 + 28)[0] + 8
    data[records + 200] ^= 0x01  # one bit inside a message
    mcap.write_bytes(bytes(data))
    with pytest.raises(BagError, match=r"the chunk at byte \d+ is corrupted \(CRC-32"):
        scan(mcap, ["/joint_states"])

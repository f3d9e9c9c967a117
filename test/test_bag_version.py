"""Bag metadata versions: 9 (Jazzy's own, the default) and 8 (``bag_version``, for older
``ros2 bag`` readers), written by BagWriter and by id_recorder."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from jetpipe_ros.bag import BagWriter
from jetpipe_ros.nodes.id_recorder import Recorder
from jetpipe_ros.nodes.parameters import StartupError

TOPICS = {"/a/position": "std_msgs/msg/Float64", "/a/chamber1/pressure":
          "sensor_msgs/msg/FluidPressure"}


def _write(path, version):
    store = get_typestore(Stores.ROS2_KILTED)
    bag = BagWriter(path, TOPICS, version)
    for k in range(3):
        msg = store.types["std_msgs/msg/Float64"](data=0.001 * k)
        bag.write("/a/position", 1_000_000 * k, store.serialize_cdr(msg, "std_msgs/msg/Float64"))
    bag.event(3_000_000, event="campaign_done")
    bag.close()
    return yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


@pytest.mark.parametrize("version", [8, 9])
def test_bag_version_is_written_and_read_back(tmp_path, version):
    meta = _write(tmp_path / "bag", version)
    assert meta["version"] == version
    with Reader(tmp_path / "bag") as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts["/a/position"] == 3 and counts["/a/chamber1/pressure"] == 0


def test_version_8_has_what_humble_and_iron_readers_parse(tmp_path):
    """The fields rosbag2's yaml decoder (rosbag2_storage/yaml.hpp) reads up to version 7, each
    with the type it converts to; the QoS profiles a string (version 9 makes them a list, which
    the older decoders reject: ros2/rosbag2#2013). Newer fields are ignored by them. Checked
    against the decoder's source, not against a Humble install."""
    meta = _write(tmp_path / "bag", 8)
    assert isinstance(meta["version"], int) and isinstance(meta["storage_identifier"], str)
    assert isinstance(meta["duration"]["nanoseconds"], int)
    assert isinstance(meta["starting_time"]["nanoseconds_since_epoch"], int)
    assert isinstance(meta["message_count"], int)
    assert all(isinstance(p, str) for p in meta["relative_file_paths"])
    assert isinstance(meta["compression_format"], str)
    assert isinstance(meta["compression_mode"], str)
    for f in meta["files"]:
        assert isinstance(f["path"], str) and isinstance(f["message_count"], int)
        assert isinstance(f["duration"]["nanoseconds"], int)
    for info in meta["topics_with_message_count"]:
        topic = info["topic_metadata"]
        assert all(isinstance(topic[k], str) for k in ("name", "type", "serialization_format",
                                                       "offered_qos_profiles",
                                                       "type_description_hash"))
        assert isinstance(info["message_count"], int)
    nine = _write(tmp_path / "bag9", 9)
    assert not isinstance(nine["topics_with_message_count"][0]["topic_metadata"][
        "offered_qos_profiles"], str)


def test_recorder_takes_bag_version_8_and_refuses_others(ros_context, tmp_path):
    rec = Recorder(context=ros_context, cli_args=[
        "--ros-args", "-p", "mode:=record", "-p", f"bag:={tmp_path / 'bag'}",
        "-p", "bag_version:=8"])
    store = get_typestore(Stores.ROS2_KILTED)
    Time = store.types["builtin_interfaces/msg/Time"]
    header = store.types["std_msgs/msg/Header"](stamp=Time(sec=1, nanosec=0), frame_id="")
    sample = store.types["sensor_msgs/msg/JointState"](
        header=header, name=["piston"], position=np.array([0.01]), velocity=np.array([0.0]),
        effort=np.array([0.0]))
    try:  # one sample as if heard: a recording that received nothing leaves no bag
        rec._stamped(rec._names["joint_states"])(
            bytes(store.serialize_cdr(sample, "sensor_msgs/msg/JointState")))
        rec.close()
    finally:
        rec.destroy_node()
    meta = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())
    assert meta["rosbag2_bagfile_information"]["version"] == 8
    with pytest.raises(StartupError) as info:
        Recorder(context=ros_context, cli_args=[
            "--ros-args", "-p", "mode:=record", "-p", f"bag:={tmp_path / 'bag7'}",
            "-p", "bag_version:=7"])
    assert "bag_version" in "\n".join(info.value.messages)

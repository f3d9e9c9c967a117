"""Write a rosbag2 bag (MCAP storage) from serialized (CDR) messages.

Metadata version 9 by default: Jazzy's own (Kilted reads it too). Humble's rosbag2 writes
version 5 and Iron's 7; their readers take the fields they know from a newer file but expect the
QoS profiles as a string, which version 9 turned into a list ("bad conversion",
ros2/rosbag2#2013). ``version=8`` (the oldest ``rosbags`` writes) keeps the string, for those
older ``ros2 bag`` readers. The messages are the CDR bytes rclpy receives with raw
subscriptions (identical to what rosbags serializes), so nothing is converted on the way.
``close()`` finishes the MCAP file and writes ``metadata.yaml``; a bag closed that way holds
every message written before.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

#: rosbag2 metadata version written by default (Jazzy and later); 8 also possible.
METADATA_VERSION = 9
METADATA_VERSIONS = (8, 9)
#: The recorder's own topic: one std_msgs/String JSON document per campaign event.
EVENTS_TOPIC = "/id_recorder/events"
TYPESTORE = Stores.ROS2_KILTED


class BagWriter:
    """A bag being written: connections by topic name, message counts.

    Args:
        path: bag directory to create (must not exist).
        topics: topic name -> message type (``sensor_msgs/msg/JointState``).
        version: rosbag2 metadata version, one of :data:`METADATA_VERSIONS`.
    """

    def __init__(self, path: str | Path, topics: dict[str, str],
                 version: int = METADATA_VERSION) -> None:
        self.path = Path(path)
        self._store = get_typestore(TYPESTORE)
        self._writer = Writer(self.path, version=version, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        for name, msgtype in {**topics, EVENTS_TOPIC: "std_msgs/msg/String"}.items():
            self._connections[name] = self._writer.add_connection(
                name, msgtype, typestore=self._store)
            self.counts[name] = 0
        self.closed = False

    def write(self, topic: str, stamp_ns: int, data: bytes | memoryview) -> None:
        """Append one serialized message of ``topic`` with log time ``stamp_ns``."""
        self._writer.write(self._connections[topic], stamp_ns, data)
        self.counts[topic] += 1

    def event(self, stamp_ns: int, **fields: Any) -> None:
        """Append a campaign event (JSON in a std_msgs/String) on :data:`EVENTS_TOPIC`."""
        msg = self._store.types["std_msgs/msg/String"](data=json.dumps(fields))
        self.write(EVENTS_TOPIC, stamp_ns,
                   self._store.serialize_cdr(msg, "std_msgs/msg/String"))

    def close(self) -> None:
        """Finish the MCAP file and write metadata.yaml (idempotent)."""
        if not self.closed:
            self.closed = True
            self._writer.close()

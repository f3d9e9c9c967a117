"""Write a rosbag2 bag (MCAP storage) from serialized (CDR) messages.

Metadata version 9 by default: Jazzy's own (Kilted reads it too). Humble's rosbag2 writes
version 5 and Iron's 7; their readers take the fields they know from a newer file but expect the
QoS profiles as a string, which version 9 turned into a list ("bad conversion",
ros2/rosbag2#2013). ``version=8`` (the oldest ``rosbags`` writes) keeps the string, for those
older ``ros2 bag`` readers. The messages are the CDR bytes rclpy receives with raw
subscriptions (identical to what rosbags serializes), so nothing is converted on the way.
``close()`` finishes the MCAP file and writes ``metadata.yaml``; a bag closed that way holds
every message written before.

A writer that is never closed (its process killed with SIGKILL, the machine losing power)
leaves a bag without ``metadata.yaml`` and an MCAP file without summary or footer, which
:mod:`jetpipe_ros.bag.recover` still reads up to the last complete chunk. So that this loses
little, the writer syncs (:meth:`BagWriter.sync`: the pending chunk closed and written to the
file) whenever :data:`SYNC_PERIOD` has passed since the last sync, at the first
:meth:`~BagWriter.write` after it or when its owner calls :meth:`~BagWriter.sync_if_due`: a
process killed at any moment keeps every message written more than :data:`SYNC_PERIOD` before
the kill (plus the time the owner takes to call it while idle). Each sync is also ``fsync``-ed,
by a background thread, so that a lock-step recording never waits on the disk; that covers a
power cut too, once the disk has answered.
"""

from __future__ import annotations

import os
import shutil
import threading
import time
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from jetpipe_ros.fileio import DIR_MODE, FILE_MODE, to_json

#: rosbag2 metadata version written by default (Jazzy and later); 8 also possible.
METADATA_VERSION = 9
METADATA_VERSIONS = (8, 9)
#: The recorder's own topic: one std_msgs/String JSON document per campaign event.
EVENTS_TOPIC = "/id_recorder/events"
TYPESTORE = Stores.ROS2_KILTED
#: Longest time [s, wall clock] a written message waits before it is synced to disk.
SYNC_PERIOD = 1.0


class BagWriter:
    """A bag being written: connections by topic name, message counts.

    Args:
        path: bag directory to create (must not exist; missing parents are made).
        topics: topic name -> message type (``sensor_msgs/msg/JointState``).
        version: rosbag2 metadata version, one of :data:`METADATA_VERSIONS`.

    Raises:
        OSError, rosbags.rosbag2.WriterError: the bag cannot be created (nothing is left).
    """

    def __init__(self, path: str | Path, topics: dict[str, str],
                 version: int = METADATA_VERSION) -> None:
        self.path = Path(path)
        if not str(path).strip():
            raise FileNotFoundError(2, "empty bag path", str(path))
        #: directories this writer creates, deepest first (removed again by discard())
        self._made = [p for p in (self.path, *self.path.parents) if not p.exists()]
        self._store = get_typestore(TYPESTORE)
        self._connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self.closed = True
        self._fsyncer: threading.Thread | None = None
        self._fsync_due = threading.Event()
        try:
            self._writer = Writer(self.path, version=version,
                                  storage_plugin=StoragePlugin.MCAP)
            self._writer.open()
            self.closed = False
            self._storage = self._writer.storage  # the MCAP file (rosbags McapWriter)
            for name, msgtype in {**topics, EVENTS_TOPIC: "std_msgs/msg/String"}.items():
                self._connections[name] = self._writer.add_connection(
                    name, msgtype, typestore=self._store)
                self.counts[name] = 0
            os.chmod(self.path, DIR_MODE)  # whatever the umask, as every file the tools write
            os.chmod(self._storage.path, FILE_MODE)
            _fsync(self.path)
            _fsync(self.path.parent)
            self._fsyncer = threading.Thread(target=self._fsync_loop, name="bag-fsync",
                                             daemon=True)
            self._fsyncer.start()
        except BaseException:
            self.discard()
            raise
        self.synced = time.monotonic()  #: wall time [s, monotonic] of the latest sync
        self.syncs = 0

    def write(self, topic: str, stamp_ns: int, data: bytes | memoryview) -> None:
        """Append one serialized message of ``topic`` with log time ``stamp_ns``."""
        self._writer.write(self._connections[topic], stamp_ns, data)
        self.counts[topic] += 1
        self.sync_if_due()

    def sync_if_due(self) -> None:
        """:meth:`sync` if :data:`SYNC_PERIOD` has passed since the last one."""
        if time.monotonic() - self.synced >= SYNC_PERIOD:
            self.sync()

    def sync(self) -> None:
        """Make every message written so far readable from the file after a crash: close the
        pending MCAP chunk (rosbags otherwise writes one per MiB), flush and fsync the file."""
        self.synced = time.monotonic()
        if self.closed:
            return
        # rosbags' McapWriter keeps the chunk being filled in memory; close_chunk() writes it
        # (schemas and channels go with the first one). An empty chunk is not written.
        if self._storage.chunk.msgs:
            self._storage.close_chunk()
        self._storage.bio.flush()
        self._fsync_due.set()
        self.syncs += 1

    def _fsync_loop(self) -> None:
        """Background thread: fsync the MCAP file after each sync (until closed)."""
        fd = self._storage.bio.fileno()
        while True:
            self._fsync_due.wait()
            self._fsync_due.clear()
            if self.closed:
                return
            try:
                os.fsync(fd)
            except OSError:  # closed under it: close() fsyncs itself
                return

    def event(self, stamp_ns: int, **fields: Any) -> None:
        """Append a campaign event (JSON in a std_msgs/String) on :data:`EVENTS_TOPIC`."""
        msg = self._store.types["std_msgs/msg/String"](data=to_json(fields, indent=None))
        self.write(EVENTS_TOPIC, stamp_ns,
                   self._store.serialize_cdr(msg, "std_msgs/msg/String"))

    def close(self) -> None:
        """Finish the MCAP file and write metadata.yaml (idempotent)."""
        if not self.closed:
            self._stop_fsyncer()
            self._writer.close()
            for item in self.path.iterdir():  # the MCAP file's tail, metadata.yaml
                os.chmod(item, FILE_MODE)
                _fsync(item)
            _fsync(self.path)

    def _stop_fsyncer(self) -> None:
        self.closed = True
        self._fsync_due.set()
        if self._fsyncer is not None:
            self._fsyncer.join()

    def discard(self) -> None:
        """Close and delete the bag, and the parent directories this writer made (if empty):
        for a recording that never started."""
        if not self.closed:
            self._stop_fsyncer()
            try:
                self._writer.close()
            except Exception:  # noqa: BLE001 - it is deleted anyway
                pass
        if self._made:
            shutil.rmtree(self._made[0], ignore_errors=True)
            for parent in self._made[1:]:
                try:
                    parent.rmdir()
                except OSError:
                    break


def _fsync(path: Path) -> None:
    """fsync a file or directory (a directory: so that its new entries survive a power cut)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)

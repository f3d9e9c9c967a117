"""Read the messages of a bag whose recorder died: no ``metadata.yaml``, no MCAP footer.

A recorder killed with SIGKILL (or a power cut) never closes its bag: ``metadata.yaml`` is
missing and the MCAP file ends without its summary and footer, perhaps in the middle of a
record, so ``rosbags`` (and ``ros2 bag``) cannot open it. Its chunks are complete up to the last
one the recorder flushed (:class:`jetpipe_ros.bag.BagWriter` flushes at least every
:data:`~jetpipe_ros.bag.writer.SYNC_PERIOD`). Like ``ros2 bag reindex``, which rebuilds the
metadata from the storage file, :func:`stream_messages` rebuilds what the metadata would say
(topics, types, counts, time span) by reading the file from its start as a stream of records
(``mcap``'s :class:`~mcap.stream_reader.StreamReader`, which never seeks to a summary), and
stops at the first record that is incomplete or corrupt: everything before it is kept.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

#: Largest record the lenient reader accepts [bytes]; a corrupt length beyond it ends the read.
RECORD_LIMIT = 1 << 30


@dataclass
class StreamReport:
    """What :func:`stream_messages` found, complete once the iteration has ended."""

    path: Path
    size: int = 0  #: file size [bytes]
    readable: int = 0  #: bytes up to the end of the last complete record
    messages: int = 0
    counts: dict[str, int] = field(default_factory=dict)  #: messages per topic
    topics: list[str] = field(default_factory=list)  #: every channel's topic, as found
    start_ns: int | None = None  #: earliest log time [ns]
    end_ns: int | None = None  #: latest log time [ns]
    closed: bool = False  #: the file has its data end record / footer (it was closed)
    stop: str = ""  #: why reading stopped early (empty: it reached the end)

    def describe(self) -> str:
        """One line: what was recovered and what was lost."""
        span = ("" if self.start_ns is None else
                f", log times {self.start_ns / 1e9:.3f} to {self.end_ns / 1e9:.3f} s")
        lost = self.size - self.readable
        tail = (f"; the last {lost} bytes (an unfinished record) are unreadable ({self.stop})"
                if lost else "")
        return (f"{self.path}: read {self.messages} messages on {len(self.topics)} topics"
                f"{span} from the MCAP stream{tail}")


def stream_messages(path: str | Path, report: StreamReport | None = None
                    ) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, message type, log time [ns], CDR bytes) of every complete message in MCAP file
    ``path``, in file order, whether or not the file was closed; ``report`` is filled in."""
    path = Path(path)
    report = report if report is not None else StreamReport(path)
    report.path = path
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    with path.open("rb") as handle:
        report.size = path.stat().st_size
        reader = StreamReader(handle, emit_chunks=True, record_size_limit=RECORD_LIMIT)
        records = reader.records
        while True:
            try:
                record = next(records)
                inner = breakup_chunk(record) if isinstance(record, Chunk) else [record]
            except StopIteration:
                break
            except (McapError, EOFError, struct.error, ValueError, KeyError, MemoryError) as exc:
                report.stop = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
                break
            for item in inner:
                if isinstance(item, Schema):
                    schemas[item.id] = item.name
                elif isinstance(item, Channel):
                    channels[item.id] = (item.topic, schemas.get(item.schema_id, ""))
                    if item.topic not in report.topics:
                        report.topics.append(item.topic)
                elif isinstance(item, Message) and item.channel_id in channels:
                    topic, msgtype = channels[item.channel_id]
                    report.messages += 1
                    report.counts[topic] = report.counts.get(topic, 0) + 1
                    t = item.log_time
                    report.start_ns = t if report.start_ns is None else min(report.start_ns, t)
                    report.end_ns = t if report.end_ns is None else max(report.end_ns, t)
                    yield topic, msgtype, t, item.data
                elif isinstance(item, (DataEnd, Footer)):
                    report.closed = True
            report.readable = handle.tell()
    if report.closed:
        report.readable = report.size

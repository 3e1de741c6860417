"""Recording what the bridge publishes as a rosbag2 (MCAP storage, metadata version 9).

``rosbags`` writes the bag: per topic its type, message definition, RIHS01 hash and the QoS the
bridge offered (so ``ros2 bag play`` republishes ``/tf_static`` transient-local). Messages are
stamped with *simulated* time, like ``ros2 bag record --use-sim-time``.

A crash (``kill -9``) loses what was not yet written: the recorder closes an MCAP chunk and
flushes it at least every ``flush_period_s`` of wall time, and ``recover(bag)`` rebuilds a
complete bag (index, ``metadata.yaml``) from every whole chunk of a file left without its footer.
"""

from __future__ import annotations

import io
import shutil
import struct
import time
from pathlib import Path

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.metadata import parse_qos

from .raw_types import typestore

_ZERO = QosTime(0, 0)
_INFINITE = QosTime(0x7FFFFFFF, 0xFFFFFFFF)  # rmw's RMW_DURATION_INFINITE as rosbag2 writes it


def bag_qos(*, reliable: bool, transient_local: bool, depth: int) -> Qos:
    """The QoS a publisher offered, as rosbag2 stores it."""
    return Qos(QosHistory.KEEP_LAST, depth, QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE, _INFINITE,
               _INFINITE, QosLiveliness.AUTOMATIC, _INFINITE, False)


class BagRecorder:
    """``write(topic, type, qos, cdr_bytes, stamp_ns)`` into a new rosbag2 folder ``path``."""

    def __init__(self, path: str | Path, flush_period_s: float = 1.0):
        self.path = Path(path)
        self.flush_period_s = flush_period_s
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._connections: dict[str, object] = {}
        self._last_flush = time.monotonic()
        self.count = 0

    def write(self, topic: str, typename: str, qos: Qos, data: bytes, stamp_ns: int) -> None:
        connection = self._connections.get(topic)
        if connection is None:
            connection = self._writer.add_connection(topic, typename, typestore=typestore(),
                                                     offered_qos_profiles=[qos])
            self._connections[topic] = connection
        self._writer.write(connection, stamp_ns, data)
        self.count += 1
        if time.monotonic() - self._last_flush >= self.flush_period_s:
            self.flush()

    def flush(self) -> None:
        """Close the open MCAP chunk and hand it to the OS: a crash after this keeps it."""
        storage = self._writer.storage
        if storage.chunk.bio.tell():
            storage.close_chunk()
        storage.bio.flush()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        """Write the summary, footer and ``metadata.yaml``."""
        self._writer.close()


def recover(path: str | Path) -> int:
    """Rebuild the bag at ``path`` whose recording was killed (no ``metadata.yaml``) from every whole
    MCAP chunk; returns the number of messages kept, or -1 for a complete bag (left alone). The
    messages are held in memory while the bag is rewritten."""
    from mcap.exceptions import EndOfFile, McapError
    from mcap.records import Channel, Chunk, Message, Schema
    from mcap.stream_reader import StreamReader

    path = Path(path)
    if (path / "metadata.yaml").exists():
        return -1
    files = sorted(path.glob("*.mcap"))
    if not files:
        raise FileNotFoundError(f"no .mcap file in {path}: not a rosbag2 MCAP bag")
    schemas, channels, messages = {}, {}, []
    with open(files[0], "rb") as stream:
        reader = StreamReader(stream, emit_chunks=True)
        try:
            for record in reader.records:
                if not isinstance(record, Chunk):
                    continue
                for inner in _chunk_records(record, StreamReader, EndOfFile):
                    if isinstance(inner, Schema):
                        schemas[inner.id] = inner
                    elif isinstance(inner, Channel):
                        channels[inner.id] = inner
                    elif isinstance(inner, Message):
                        messages.append(inner)
        except (McapError, EOFError, ValueError, struct.error):  # the killed writer's last, partial record: stop there
            pass
    broken = path.with_name(path.name + ".partial")
    shutil.move(str(path), str(broken))
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    connections = {}
    for cid, channel in channels.items():
        qos = parse_qos(channel.metadata.get("offered_qos_profiles", "[]") or "[]")
        connections[cid] = writer.add_connection(channel.topic, schemas[channel.schema_id].name,
                                                 typestore=typestore(), offered_qos_profiles=qos)
    for message in messages:
        writer.write(connections[message.channel_id], message.log_time, message.data)
    writer.close()
    shutil.rmtree(broken)
    return len(messages)


def _chunk_records(chunk, stream_reader, end_of_file) -> list:
    """The records inside a whole chunk (rosbags writes them uncompressed); the reader reports the
    end of the chunk's bytes as ``EndOfFile``."""
    records = []
    try:
        for record in stream_reader(io.BytesIO(chunk.data), skip_magic=True).records:
            records.append(record)
    except end_of_file:
        pass
    return records


__all__ = ["BagRecorder", "bag_qos", "recover"]

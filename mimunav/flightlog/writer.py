"""MCAP flight-log writer: profile ros2, CDR messages with ros2msg schemas, zstd chunks,
indexes and summary (all by the `mcap` package), log_time == publish_time == header.stamp.
Writes to a temporary file beside the target and renames it on success, so a failed or
interrupted write leaves nothing behind and never replaces an existing log unless forced."""
import json
import os

import numpy as np
from mcap.writer import CompressionType, Writer

from ..files import temporary_beside
from . import schemas
from ..errors import InputError

# offered_qos_profiles as rosbag2 writes it (reliable, volatile, keep-last), so ROS 2 tools
# (Foxglove, PlotJuggler, ros2 bag) take the channel as an ordinary topic
QOS = ("- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n"
       "    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n"
       "    nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n"
       "    sec: 9223372036\n    nsec: 854775807\n  avoid_ros_namespace_conventions: false\n")


class LogWriter:
    """with LogWriter(path) as log: log.metadata(...); log.write(topic, schema, ...)."""

    def __init__(self, path, force=False, chunk_size=1 << 20):
        self.path = os.fspath(path)
        if os.path.exists(self.path) and not force:
            raise FileExistsError(f"{self.path} exists; use --force to replace it")
        self._chunk_size = chunk_size
        self._schemas, self._channels = {}, {}

    def __enter__(self):
        fd, self._tmp = temporary_beside(self.path, ".mcap")
        self._fh = os.fdopen(fd, "wb")
        self._mcap = Writer(self._fh, chunk_size=self._chunk_size,
                            compression=CompressionType.ZSTD)
        self._mcap.start(profile="ros2", library="mimunav")
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            if exc_type is None:
                self._mcap.finish()
            self._fh.close()
            if exc_type is None:
                os.replace(self._tmp, self.path)
        finally:
            if os.path.exists(self._tmp):
                os.unlink(self._tmp)
        return False

    def metadata(self, name, values):
        """A Metadata record; structured values are stored as JSON strings."""
        self._mcap.add_metadata(name, {k: v if isinstance(v, str) else json.dumps(v)
                                       for k, v in values.items()})

    def attachment(self, name, data, media_type="application/json"):
        self._mcap.add_attachment(log_time=0, create_time=0, name=name, media_type=media_type,
                                  data=data)

    def write(self, topic, schema_name, frame_id, stamp_ns, **fields):
        """Write a whole channel of fixed-size messages: stamp_ns integer ns since the
        UNIX epoch (N,), increasing; fields as in `schemas.BODIES`."""
        stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
        if np.any(np.diff(stamp_ns) <= 0):
            raise InputError(f"{topic}: stamps must increase")
        msgs = schemas.encode(schema_name, frame_id, stamp_ns, **fields)
        self.write_encoded(topic, schema_name, msgs, stamp_ns)

    def write_encoded(self, topic, schema_name, msgs, stamp_ns):
        channel = self._channel(topic, schema_name)
        size = msgs.dtype.itemsize
        buf = msgs.tobytes()
        add = self._mcap.add_message
        for i, t in enumerate(stamp_ns.tolist()):
            add(channel_id=channel, log_time=t, publish_time=t, sequence=i,
                data=buf[i * size:(i + 1) * size])

    def copy(self, schema, channel, message):
        """Copy a message read from another MCAP (mcap.records objects) unchanged."""
        if channel.topic not in self._channels:
            if schema.name not in self._schemas:
                self._schemas[schema.name] = self._mcap.register_schema(
                    name=schema.name, encoding=schema.encoding, data=schema.data)
            self._channels[channel.topic] = self._mcap.register_channel(
                topic=channel.topic, message_encoding=channel.message_encoding,
                schema_id=self._schemas[schema.name], metadata=channel.metadata)
        self._mcap.add_message(channel_id=self._channels[channel.topic],
                               log_time=message.log_time, publish_time=message.publish_time,
                               sequence=message.sequence, data=message.data)

    def _channel(self, topic, schema_name):
        if schema_name not in self._schemas:
            self._schemas[schema_name] = self._mcap.register_schema(
                name=schema_name, encoding="ros2msg", data=schemas.SCHEMAS[schema_name])
        if topic not in self._channels:
            self._channels[topic] = self._mcap.register_channel(
                topic=topic, message_encoding="cdr", schema_id=self._schemas[schema_name],
                metadata={"offered_qos_profiles": QOS})
        return self._channels[topic]

"""MCAP flight-log writer: profile ros2, CDR messages with ros2msg schemas, zstd chunks,
message and chunk indexes, statistics, metadata index and summary offsets.

A channel of fixed-size messages is written in bulk: its Message records are one numpy
structured array (opcode, length, channel, sequence, log_time, publish_time, CDR payload),
cut into chunks of about `chunk_size` uncompressed bytes, each compressed by zstd with its
CRC-32 and followed by its MessageIndex - no per-message Python work (the `mcap` package's
`Writer.add_message` costs about 11 us a message; a 1 kHz hour of three channels is 10^7).
Each chunk's CRC and compression run on a pool of threads (one per core; zlib and zstd
release the GIL) while the caller encodes the next chunks; finished chunks are written in
their order by the caller's thread, at most `IN_FLIGHT` chunks behind. A record outside
chunks (metadata, attachment, the summary) first writes every chunk before it, so the
file holds the records in the order they were given.
The record layouts are those of the MCAP specification (mcap.dev/spec); the files are read
back by the `mcap` package's reader with CRC validation, by mcap_ros2 and by this project's
reader in the tests. Messages copied from other files (`copy`) go through the same chunks.

Writes to a temporary file beside the target and renames it on success, so a failed or
interrupted write leaves nothing behind and never replaces an existing log unless forced."""
import collections
import json
import os
import struct
import threading
import zlib
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import zstandard

from ..files import temporary_beside
from . import schemas
from ..errors import InputError

MAGIC = b"\x89MCAP0\r\n"
OP = {"header": 0x01, "footer": 0x02, "schema": 0x03, "channel": 0x04, "message": 0x05,
      "chunk": 0x06, "message_index": 0x07, "chunk_index": 0x08, "attachment": 0x09,
      "attachment_index": 0x0A, "statistics": 0x0B, "metadata": 0x0C, "metadata_index": 0x0D,
      "summary_offset": 0x0E, "data_end": 0x0F}
_INDEX_ENTRY = np.dtype([("t", "<u8"), ("o", "<u8")])     # a MessageIndex entry: log time, offset
_MESSAGE_HEAD = 31          # opcode 1 + length 8 + channel 2 + sequence 4 + log 8 + publish 8
IN_FLIGHT = 8               # chunks being compressed or waiting to be written (8 MiB of
                            # messages at the default chunk size)
# zstd's fast strategy with 4-byte matches and a 4096-entry hash table (it stays in the
# L1/L2 cache): on IMU records (8-byte fields of noisy samples, repeating headers) files 1-2 %
# smaller than level 1 (which looks for matches of 7 bytes or more) and compression
# 1.3-1.6x faster, decompression 1.1-1.3x (level -1 is as fast for files 5-7 % larger; the
# whole writer 1.1-1.2x). Measured on the chunks of a 10^6-sample /mimu/raw log and a 600 s
# flight, 2 threads, interleaved: bench/flightlog.py prints zstd's own rate on a log's chunks
# with these parameters, the writer's ceiling.
ZSTD_PARAMETERS = dict(window_log=19, hash_log=12, chain_log=13, search_log=1, min_match=4,
                       target_length=1, strategy=zstandard.STRATEGY_FAST)

# offered_qos_profiles as rosbag2 writes it (reliable, volatile, keep-last), so ROS 2 tools
# (Foxglove, PlotJuggler, ros2 bag) take the channel as an ordinary topic
QOS = ("- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n"
       "    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n"
       "    nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n"
       "    sec: 9223372036\n    nsec: 854775807\n  avoid_ros_namespace_conventions: false\n")


def _string(text):
    raw = text.encode()
    return struct.pack("<I", len(raw)) + raw


def _map(pairs, key=_string, value=_string):
    body = b"".join(key(k) + value(v) for k, v in pairs)
    return struct.pack("<I", len(body)) + body


def _record(op, body):
    return struct.pack("<BQ", op, len(body)) + body


class LogWriter:
    """with LogWriter(path) as log: log.metadata(...); log.write(topic, schema, ...)."""

    def __init__(self, path: str | os.PathLike, force: bool = False, chunk_size: int = 1 << 20
                 ) -> None:
        self.path = os.fspath(path)
        if os.path.exists(self.path) and not force:
            raise FileExistsError(f"{self.path} exists; use --force to replace it")
        self._chunk_size = chunk_size
        self._schemas, self._channels = {}, {}      # name -> id, topic -> (id, schema id)
        self._schema_records, self._channel_records = {}, {}   # id -> record body
        self._announced = set()                     # channel ids whose records are in a chunk
        self._chunk_indexes, self._metadata_indexes, self._attachment_indexes = [], [], []
        self._counts = {}
        self._start = self._end = None
        self._pending, self._pending_bytes = [], 0  # copied messages not yet in a chunk
        self._in_flight = collections.deque()       # chunks handed to the pool, in order
        self._sequence = {}                         # channel id -> next message sequence
        self._last_stamp = {}                       # channel id -> last stamp written (write)

    def __enter__(self):
        fd, self._tmp = temporary_beside(self.path, ".mcap")
        self._fh = os.fdopen(fd, "wb")
        self._fh.write(MAGIC)
        self._fh.write(_record(OP["header"], _string("ros2") + _string("mimunav")))
        self._compressors = threading.local()       # a zstd context per pool thread
        self._pool = ThreadPoolExecutor(os.cpu_count() or 1, thread_name_prefix="mcap-zstd")
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            try:
                if exc_type is None:
                    self._flush_copies()
                    self._wait()
                    self._finish()
            finally:
                self._pool.shutdown(wait=True, cancel_futures=True)
                self._fh.close()
            if exc_type is None:
                os.replace(self._tmp, self.path)
        finally:
            if os.path.exists(self._tmp):
                os.unlink(self._tmp)
        return False

    # ---- records outside chunks -------------------------------------------------------
    def metadata(self, name: str, values: dict) -> None:
        """A Metadata record; structured values are stored as JSON strings."""
        pairs = [(k, v if isinstance(v, str) else json.dumps(v)) for k, v in values.items()]
        rec = _record(OP["metadata"], _string(name) + _map(pairs))
        self._wait()                            # the chunks given before it go first
        self._metadata_indexes.append((self._fh.tell(), len(rec), name))
        self._fh.write(rec)

    def attachment(self, name: str, data: bytes, media_type: str = 'application/json') -> None:
        body = struct.pack("<QQ", 0, 0) + _string(name) + _string(media_type) + \
            struct.pack("<Q", len(data)) + bytes(data)
        rec = _record(OP["attachment"], body + struct.pack("<I", zlib.crc32(body)))
        self._wait()
        self._attachment_indexes.append((self._fh.tell(), len(rec), len(data), name, media_type))
        self._fh.write(rec)

    # ---- messages ---------------------------------------------------------------------
    def write(self, topic: str, schema_name: str, frame_id: str, stamp_ns: np.ndarray,
              **fields: np.ndarray) -> None:
        """Write fixed-size messages of a channel: stamp_ns integer ns since the UNIX epoch
        (N,), increasing; fields as in `schemas.BODIES`. Encoded a chunk at a time (memory and
        cache stay small); a channel may be written in several calls, in time order (a
        log written in blocks)."""
        stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
        channel = self._channel(topic, schema_name)
        self._check_stamps(topic, channel, stamp_ns)
        per = self._per_chunk(schemas.cdr_dtype(schema_name, frame_id).itemsize)
        first = self._sequence.get(channel, 0)      # sequence continues across calls
        self._sequence[channel] = first + len(stamp_ns)
        for a in range(0, len(stamp_ns), per):
            piece = {k: (v[a:a + per] if np.ndim(v) and len(v) == len(stamp_ns) else v)
                     for k, v in fields.items()}
            records = self._records(channel, schemas.cdr_dtype(schema_name, frame_id),
                                    stamp_ns[a:a + per], first + a)
            schemas.encode(schema_name, frame_id, stamp_ns[a:a + per], out=records["data"],
                           **piece)
            self._chunk(channel, records.view(np.uint8), records["log_time"])

    def _check_stamps(self, topic, channel, stamp_ns):
        if np.any(np.diff(stamp_ns) <= 0) or \
                len(stamp_ns) and stamp_ns[0] <= self._last_stamp.get(channel, -2**63):
            raise InputError(f"{topic}: stamps must increase")
        if len(stamp_ns):
            self._last_stamp[channel] = int(stamp_ns[-1])

    def write_encoded(self, topic: str, schema_name: str, msgs: np.ndarray, stamp_ns: np.ndarray,
                      increasing: bool = False) -> None:
        """Messages already encoded (an array of CDR payloads of one size, e.g. `payload`
        rows read by `FlightLog.blocks(topic, fields=PAYLOAD)`) with their log times (ns),
        in bulk, as they are (a recorder's stamps in any order); increasing: refuse stamps
        that do not increase, as `write` does."""
        channel = self._channel(topic, schema_name)
        stamp_ns = np.asarray(stamp_ns, np.int64)
        if increasing:
            self._check_stamps(topic, channel, stamp_ns)
        per = self._per_chunk(msgs.dtype.itemsize)
        first = self._sequence.get(channel, 0)
        self._sequence[channel] = first + len(msgs)
        for a in range(0, len(msgs), per):
            records = self._records(channel, np.dtype(f"V{msgs.dtype.itemsize}"),
                                    stamp_ns[a:a + per], first + a)
            records["data"] = np.ascontiguousarray(msgs[a:a + per]).view(records.dtype["data"])
            self._chunk(channel, records.view(np.uint8), records["log_time"])

    def _per_chunk(self, payload_size):
        return max(1, self._chunk_size // (_MESSAGE_HEAD + payload_size))

    @staticmethod
    def _records(channel, payload, stamp_ns, first_sequence):
        """Zeroed Message records of one chunk as a numpy structured array (opcode, length,
        channel, sequence, log_time, publish_time, then the CDR payload of dtype `payload`,
        filled by the caller); the padding bytes stay zero."""
        n = len(stamp_ns)
        records = np.zeros(n, dtype=np.dtype([
            ("op", "u1"), ("length", "<u8"), ("channel", "<u2"), ("sequence", "<u4"),
            ("log_time", "<u8"), ("publish_time", "<u8"), ("data", payload)]))
        records["op"] = OP["message"]
        records["length"] = _MESSAGE_HEAD - 9 + payload.itemsize
        records["channel"] = channel
        records["sequence"] = np.arange(first_sequence, first_sequence + n, dtype=np.uint32)
        records["log_time"] = records["publish_time"] = stamp_ns
        return records

    def copy(self, schema, channel, message):
        """Copy a message read from another MCAP (mcap.records objects) unchanged."""
        if channel.topic not in self._channels:
            self._schema(schema.name, schema.encoding, schema.data)
            self._channel(channel.topic, schema.name, channel.message_encoding,
                          channel.metadata)
        self._pending.append((self._channels[channel.topic][0], message))
        self._pending_bytes += _MESSAGE_HEAD + len(message.data)
        if self._pending_bytes > self._chunk_size:
            self._flush_copies()

    def _flush_copies(self):
        """The copied messages so far, in chunks of one channel each."""
        by_channel = {}
        for cid, m in self._pending:
            by_channel.setdefault(cid, []).append(m)
        self._pending, self._pending_bytes = [], 0
        for cid, msgs in by_channel.items():
            parts, offsets, pos = [], [], 0
            for m in msgs:
                rec = _record(OP["message"], struct.pack("<HIQQ", cid, m.sequence, m.log_time,
                                                         m.publish_time) + bytes(m.data))
                parts.append(rec)
                offsets.append(pos)
                pos += len(rec)
            self._chunk(cid, np.frombuffer(b"".join(parts), np.uint8),
                        np.array([m.log_time for m in msgs], np.uint64),
                        np.array(offsets, np.uint64))

    # ---- chunks and definitions --------------------------------------------------------
    def _chunk(self, cid, messages, log_times, offsets=None):
        """A chunk of one channel's message records (uint8 array) with their log times and
        offsets from the first message (None: records of one size): its CRC-32 and zstd
        compression handed to the pool (`_pack`), and written with its MessageIndex and
        ChunkIndex entry once the chunks before it are (`_write_chunk`)."""
        if offsets is None:
            offsets = np.arange(len(log_times), dtype=np.uint64) * \
                np.uint64(len(messages) // max(1, len(log_times)))
        head = b""
        if cid not in self._announced:          # definitions travel with the first chunk
            schema_id, channel_body = self._channel_records[cid]
            head = _record(OP["schema"], self._schema_records[schema_id]) + \
                _record(OP["channel"], channel_body)
            messages = np.concatenate([np.frombuffer(head, np.uint8), messages])
            self._announced.add(cid)
        entries = np.empty(len(log_times), dtype=_INDEX_ENTRY)     # the MessageIndex's, made
        entries["t"], entries["o"] = log_times, offsets + np.uint64(len(head))  # while cached
        self._in_flight.append((self._pool.submit(self._pack, messages), cid, len(messages),
                                entries))
        while len(self._in_flight) > IN_FLIGHT:
            self._write_chunk(*self._in_flight.popleft())

    def _pack(self, data):
        """(CRC-32, zstd frame) of a chunk's records, on a pool thread."""
        zstd = getattr(self._compressors, "zstd", None)
        if zstd is None:
            zstd = self._compressors.zstd = zstandard.ZstdCompressor(
                compression_params=zstandard.ZstdCompressionParameters(**ZSTD_PARAMETERS))
        return zlib.crc32(data), zstd.compress(data)

    def _wait(self):
        """Write every chunk handed to the pool (a compression's error is raised here)."""
        while self._in_flight:
            self._write_chunk(*self._in_flight.popleft())

    def _write_chunk(self, packing, cid, size, entries):
        """Write a chunk (once compressed) with its CRC-32, its MessageIndex (`entries`: log
        time and offset per message) and its ChunkIndex entry."""
        crc, comp = packing.result()
        fh = self._fh
        start, end = int(entries["t"].min()), int(entries["t"].max())
        head = struct.pack("<QQQI", start, end, size, crc) + \
            _string("zstd") + struct.pack("<Q", len(comp))
        chunk_start = fh.tell()
        fh.write(struct.pack("<BQ", OP["chunk"], len(head) + len(comp)) + head)
        fh.write(comp)
        chunk_length = fh.tell() - chunk_start
        index_start = fh.tell()
        fh.write(struct.pack("<BQHI", OP["message_index"], 6 + entries.nbytes, cid,
                             entries.nbytes))
        fh.write(entries)
        self._chunk_indexes.append((start, end, chunk_start, chunk_length,
                                    {cid: index_start}, fh.tell() - index_start,
                                    len(comp), size))
        self._counts[cid] = self._counts.get(cid, 0) + len(entries)
        self._start = start if self._start is None else min(self._start, start)
        self._end = end if self._end is None else max(self._end, end)

    def _schema(self, name, encoding="ros2msg", data=None):
        if name not in self._schemas:
            sid = len(self._schemas) + 1
            data = schemas.SCHEMAS[name] if data is None else data
            data = data.encode() if isinstance(data, str) else bytes(data)
            self._schemas[name] = sid
            self._schema_records[sid] = struct.pack("<H", sid) + _string(name) + \
                _string(encoding) + struct.pack("<I", len(data)) + data
        return self._schemas[name]

    def _channel(self, topic, schema_name, encoding="cdr", metadata=None):
        if topic not in self._channels:
            sid = self._schema(schema_name)
            cid = len(self._channels) + 1
            meta = {"offered_qos_profiles": QOS} if metadata is None else dict(metadata)
            body = struct.pack("<HH", cid, sid) + _string(topic) + _string(encoding) + \
                _map(sorted(meta.items()))
            self._channels[topic] = (cid, sid)
            self._channel_records[cid] = (sid, body)
        return self._channels[topic][0]

    # ---- summary -----------------------------------------------------------------------
    def _finish(self):
        """DataEnd, the summary section (schemas, channels, statistics, chunk, attachment
        and metadata indexes), the summary offsets and the footer."""
        fh = self._fh
        fh.write(_record(OP["data_end"], struct.pack("<I", 0)))
        summary_start = fh.tell()
        groups = []

        def group(op, records):
            if records:
                start = fh.tell()
                for body in records:
                    fh.write(_record(op, body))
                groups.append((op, start, fh.tell() - start))

        group(OP["schema"], [self._schema_records[s] for s in sorted(self._schema_records)])
        group(OP["channel"], [self._channel_records[c][1] for c in sorted(self._channel_records)])
        counts = _map(sorted(self._counts.items()), key=lambda k: struct.pack("<H", k),
                      value=lambda v: struct.pack("<Q", v))
        group(OP["statistics"], [struct.pack(
            "<QHIIIIQQ", sum(self._counts.values()), len(self._schemas), len(self._channels),
            len(self._attachment_indexes), len(self._metadata_indexes), len(self._chunk_indexes),
            self._start or 0, self._end or 0) + counts])
        group(OP["chunk_index"], [
            struct.pack("<QQQQ", s, e, off, length) +
            _map(sorted(idx.items()), key=lambda k: struct.pack("<H", k),
                 value=lambda v: struct.pack("<Q", v)) +
            struct.pack("<Q", idx_len) + _string("zstd") + struct.pack("<QQ", comp, raw)
            for s, e, off, length, idx, idx_len, comp, raw in self._chunk_indexes])
        group(OP["attachment_index"], [
            struct.pack("<QQQQQ", off, length, 0, 0, size) + _string(name) + _string(media)
            for off, length, size, name, media in self._attachment_indexes])
        group(OP["metadata_index"], [struct.pack("<QQ", off, length) + _string(name)
                                     for off, length, name in self._metadata_indexes])
        offsets_start = fh.tell()
        for op, start, length in groups:
            fh.write(_record(OP["summary_offset"], struct.pack("<BQQ", op, start, length)))
        fh.write(_record(OP["footer"], struct.pack("<QQI", summary_start if groups else 0,
                                                   offsets_start, 0)))
        fh.write(MAGIC)

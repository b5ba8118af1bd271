"""MCAP flight-log reader.

`FlightLog(path)` reads the summary (schemas, channels, chunk indexes, statistics,
metadata); `read(topic)` returns a channel as a numpy structured array (the CDR layout of
`schemas.cdr_dtype` plus `log_time` ns) by gathering the payloads straight out of the
decompressed chunks at the offsets of the message indexes - no per-message decoding.
Channels whose messages are not of one fixed size (a varying frame_id, another schema) go
through the generic `mcap_ros2` decoder instead.
"""
import json
import os
import struct
import threading
import zlib
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader

from ..errors import InputError, require
from . import schemas
from .writer import MAGIC

_MSG_HEADER = 31        # opcode 1 + length 8 + channel 2 + sequence 4 + log_time 8 + publish 8
_INDEX_ENTRY = np.dtype([("log_time", "<u8"), ("offset", "<u8")])


class LogError(InputError):
    """A log that cannot be read as the contract says, with what and where."""


class LayoutError(LogError):
    """A channel that is not one of the contract's fixed-size layouts (read it generically);
    not damage."""


_DAMAGE = (McapError, ValueError, IndexError, EOFError, struct.error, zstandard.ZstdError)


class TimeOrderError(LogError):
    """A channel whose stamps go back in time, met while streaming it (`FlightLog.blocks`)."""


class FlightLog:
    """A log opened for reading. skip_damaged=False (default): a damaged chunk, an index
    inconsistent with the data or a count that differs from the statistics record is a
    LogError naming the channel and time range; True: the damaged chunk is left out and
    listed in `damaged` {topic: [(start_ns, end_ns, reason)]}."""

    def __init__(self, path: str | os.PathLike, skip_damaged: bool = False) -> None:
        self.path = os.fspath(path)
        self.skip_damaged = skip_damaged
        self.damaged = {}
        if os.path.isdir(self.path):
            from .recover import folder_hint
            raise LogError(f"{self.path}: a folder, not a log file{folder_hint(self.path)}")
        self._fh = open(self.path, "rb")
        head = self._fh.read(len(MAGIC))
        self._fh.seek(0)
        if head != MAGIC:
            from .recover import foreign_hint
            self._fh.close()
            raise LogError(f"{self.path}: not an MCAP file (no MCAP magic at its start"
                           + ("; the file is empty)" if not head else ")") + foreign_hint(head))
        try:
            self.summary = make_reader(self._fh).get_summary()
        except (*_DAMAGE, KeyError, OSError) as exc:
            self.summary = None
            self._summary_error = str(exc)
        if self.summary is None:
            raise LogError(f"{self.path}: no readable summary section ("
                           f"{getattr(self, '_summary_error', 'missing')}); the file may be "
                           "truncated: `mimunav info LOG` reports what is intact, "
                           "`mimunav info LOG --recover OUT.mcap` saves it")
        self.channels = {c.topic: c for c in self.summary.channels.values()}
        for c in self.channels.values():
            if c.schema_id not in self.summary.schemas:
                raise LogError(f"{self.path}: channel {c.topic!r} refers to schema "
                               f"{c.schema_id}, which the log does not define (a damaged "
                               "summary); `mimunav info LOG --recover OUT.mcap` rebuilds it")
        self.time_reversals = {}    # topic -> times a stamp went backwards (file order)

    def close(self) -> None:
        self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---- summary --------------------------------------------------------------------
    def schema_name(self, topic: str) -> str:
        return self.summary.schemas[self._channel(topic).schema_id].name

    def count(self, topic: str) -> int | None:
        stats = self.summary.statistics
        cid = self._channel(topic).id
        return stats.channel_message_counts.get(cid, 0) if stats else None

    def metadata(self) -> dict[str, dict]:
        """{name: {key: value}} with JSON values decoded where they parse."""
        self._fh.seek(0)
        out = {}
        try:
            for record in make_reader(self._fh).iter_metadata():
                out[record.name] = {k: _maybe_json(v) for k, v in record.metadata.items()}
        except _DAMAGE as exc:
            raise LogError(f"{self.path}: damaged metadata ({type(exc).__name__}: {exc}); "
                           "`mimunav info LOG --recover OUT.mcap` keeps what is intact") from None
        return out

    def epoch_ns(self) -> int:
        """The flight's epoch (ns since 1970) from the `flight` metadata record, or None when
        the log has none or its metadata cannot be read; read once."""
        if not hasattr(self, "_epoch_ns"):
            try:
                epoch = int(self.metadata().get("flight", {}).get("epoch_unix_ns"))
            except (LogError, TypeError, ValueError):
                epoch = None
            self._epoch_ns = epoch
        return self._epoch_ns

    def _channel(self, topic):
        if topic not in self.channels:
            raise LogError(f"{self.path}: no channel {topic!r}; the log has "
                           f"{', '.join(sorted(self.channels)) or 'no channels'}")
        return self.channels[topic]

    # ---- messages -------------------------------------------------------------------
    def read(self, topic: str, fields: Sequence[str] | None = None) -> np.ndarray:
        """All messages of a channel as a structured array with a log_time (ns) field,
        in time order (the number of backward steps in file order goes to
        `time_reversals[topic]`); `fields` (names) limits the copy to those fields, or
        `PAYLOAD` gives each message's CDR payload unparsed (field "payload", bytes). Data that
        cannot be decoded (a damaged chunk or index) is a `LogError` naming the channel."""
        try:
            out = self._read(topic, fields)
        except LogError:
            raise
        except _DAMAGE as exc:
            raise LogError(f"{self.path}: {topic}: damaged data ({type(exc).__name__}: {exc});"
                           " `mimunav info LOG --recover OUT.mcap` keeps what is intact") from exc
        self._check_count(topic, len(out))
        return out

    def blocks(self, topic: str, size: int = 1 << 20, fields: Sequence[str] | None = None
               ) -> Iterator[np.ndarray]:
        """The messages of a channel in time order as consecutive structured arrays of
        about `size` messages (whole chunks; the last may be shorter): a log of any length
        in bounded memory. The same checks as `read` - a damaged chunk or index is a LogError
        (or left out and listed in `damaged` with skip_damaged), the total is compared with
        the statistics record at the end - and chunks whose messages go back in time across
        a block boundary are refused (`read` sorts them; a stream cannot)."""
        buf, pos, total, last = None, 0, 0, None     # a new buffer after each yield: the
        try:                                        # block handed out is never written again
            for _, fill in self._pieces(topic, fields):
                if buf is not None and fill.count > len(buf) - pos:
                    total += pos
                    yield buf[:pos]
                    buf, pos = None, 0
                if buf is None or fill.count > len(buf) - pos:
                    buf = np.empty(max(size, fill.count), dtype=fill.dtype)
                n = fill(buf[pos:])
                piece = buf[pos:pos + n]
                if n and np.any(np.diff(piece["log_time"].astype(np.int64)) < 0) or \
                        last is not None and n and int(piece["log_time"][0]) < last:
                    raise TimeOrderError(f"{self.path}: {topic}: stamps go back in time; read "
                                         "the channel whole (FlightLog.read), which sorts them")
                last = int(piece["log_time"][-1]) if n else last
                pos += n
                if pos >= size:
                    total += pos
                    yield buf[:pos]
                    buf, pos = None, 0
        except LogError:
            raise
        except _DAMAGE as exc:
            raise LogError(f"{self.path}: {topic}: damaged data ({type(exc).__name__}: {exc});"
                           " `mimunav info LOG --recover OUT.mcap` keeps what is intact") from exc
        if pos:
            total += pos
            yield buf[:pos]
        self._check_count(topic, total)

    def _damage(self, topic, ci, exc):
        """List a damaged chunk of `topic` once, however often the channel is read."""
        span = (int(ci.message_start_time), int(ci.message_end_time), str(exc))
        spans = self.damaged.setdefault(topic, [])
        if span not in spans:
            spans.append(span)

    def _check_count(self, topic, n):
        expected = self.count(topic)
        if expected is not None and expected != n and topic not in self.damaged:
            raise LogError(f"{self.path}: {topic}: the indexes lead to {n} messages, "
                           f"the statistics record counts {expected}: an index is damaged; "
                           "`mimunav info LOG --recover OUT.mcap` rebuilds the log from its "
                           "intact chunks")

    def _read(self, topic, fields=None):
        out, pos = None, 0
        for n_total, fill in self._pieces(topic, fields):
            if out is None:
                out = np.empty(n_total, dtype=fill.dtype)
            pos += fill(out[pos:])
        if out is None:
            return np.zeros(0, dtype=[("log_time", "<u8")])
        out = out[:pos]
        reversals = int(np.sum(np.diff(out["log_time"].astype(np.int64)) < 0))
        self.time_reversals[topic] = reversals      # in file order, before sorting
        if reversals:
            out = out[np.argsort(out["log_time"], kind="stable")]
        return out

    def _pieces(self, topic, fields=None):
        """Per chunk holding the channel, in the order of the channel's own first message
        per chunk: (messages of the channel in all its chunks, fill) where fill(out) decodes
        the chunk's messages into the start of `out` (a structured array with log_time, of
        dtype `fill.dtype`) and returns how many; a damaged chunk raises or (skip_damaged)
        is listed in `damaged` and fills nothing."""
        channel = self._channel(topic)
        chunks = [ci for ci in self.summary.chunk_indexes
                  if channel.id in ci.message_index_offsets]
        # chunk order by this channel's own first message (a chunk shared with a channel
        # written after it starts earlier than the chunk's other messages of this one); the
        # indexes are read again chunk by chunk below, so that a long log's are not all held
        first, n_total = [], 0
        for ci in chunks:
            index = self._message_index(ci, channel.id)
            first.append(int(index["log_time"].min()) if len(index) else 0)
            n_total += len(index)
        order = sorted(range(len(chunks)), key=lambda i: (first[i], chunks[i].chunk_start_offset))
        layout = []                         # the channel's CDR dtype, from its first chunk
        for ci, index, data in self._decoded_ahead([chunks[i] for i in order], channel.id):
            if len(index) == 0:
                continue
            try:
                data = data.result()
                if not layout:
                    layout.append(self._layout(data, index, topic))
            except LayoutError:
                raise
            except (LogError, *_DAMAGE) as exc:
                if not self.skip_damaged:
                    raise
                self._damage(topic, ci, exc)
                continue

            def fill(out, data=data, index=index, ci=ci):
                try:
                    self._gather(data, index, layout[0], out[:len(index)], topic, ci)
                except (LogError, *_DAMAGE) as exc:
                    if not self.skip_damaged:
                        raise
                    self._damage(topic, ci, exc)
                    return 0
                return len(index)
            fill.dtype = _with_log_time(layout[0], fields)
            fill.count = len(index)
            yield n_total, fill

    def _decoded_ahead(self, chunks, channel_id):
        """(chunk index, the channel's message index in it, future of its decompressed
        records, None when the index is empty) per chunk, in order: the file is read here, one chunk at a time; the
        decompression and CRC (zstd and zlib release the interpreter) run DECODE_THREADS at a
        time, at most DECODE_AHEAD chunks ahead of the consumer; a chunk's damage is raised
        by its future's result()."""
        pending = deque()
        self.epoch_ns()                 # read here: a worker's error message must not seek
        with ThreadPoolExecutor(DECODE_THREADS) as pool:
            for ci in chunks:
                index = self._message_index(ci, channel_id)
                if len(index) == 0:                 # nothing of the channel: not decoded
                    pending.append((ci, index, None))
                else:
                    self._fh.seek(ci.chunk_start_offset)
                    record = self._fh.read(ci.chunk_length)
                    pending.append((ci, index, pool.submit(self._decompressed, ci, record)))
                if len(pending) > DECODE_AHEAD:
                    yield pending.popleft()
            while pending:
                yield pending.popleft()

    def _decompressed(self, ci, record):
        """Decompressed records of a chunk from its record's bytes. Chunk record layout (MCAP
        spec): opcode 1, length 8, start 8, end 8, uncompressed size 8, crc 4, compression
        string (4 + n), records length 8, records."""
        rec = memoryview(record)
        size = int.from_bytes(rec[25:33], "little")
        n = int.from_bytes(rec[37:41], "little")
        compression = bytes(rec[41:41 + n]).decode()
        body = rec[49 + n:]
        if len(body) < int.from_bytes(rec[41 + n:49 + n], "little"):
            raise LogError(f"{self.path}: chunk at byte {ci.chunk_start_offset} is cut short")
        if compression not in ("zstd", "", "lz4"):
            raise LogError(f"{self.path}: unknown chunk compression {compression!r}")
        try:
            if size != ci.uncompressed_size:        # a flipped bit: 2^63 overflowed zstd's
                raise ValueError(f"its uncompressed size, {size} bytes, is not the chunk "
                                 f"index's {ci.uncompressed_size}")      # size argument
            if compression == "zstd":
                data = _decompressor().decompress(body, max_output_size=size)
            elif compression == "lz4":
                import lz4.frame
                data = lz4.frame.decompress(body)
            else:
                data = bytes(body)
        except ValueError as exc:
            data, why = None, str(exc)
        except (zstandard.ZstdError, RuntimeError, OverflowError, MemoryError) as exc:
            data, why = None, f"the decompressor: {exc}"     # lz4's errors are RuntimeErrors
        else:
            crc = int.from_bytes(rec[33:37], "little")
            why = "size mismatch" if len(data) != size else \
                "CRC mismatch" if crc and zlib.crc32(data) != crc else None
        if why:
            raise LogError(f"{self.path}: corrupt chunk at byte {ci.chunk_start_offset} "
                           f"holding messages from {_since_epoch(self, ci.message_start_time)}"
                           f" to {_since_epoch(self, ci.message_end_time)} ({why}); "
                           "`mimunav info LOG --recover OUT.mcap` keeps the rest")
        return np.frombuffer(data, dtype=np.uint8)

    def _message_index(self, ci, channel_id):
        self._fh.seek(ci.message_index_offsets[channel_id])
        head = self._fh.read(15)          # opcode 1, length 8, channel 2, records length 4
        n_bytes = int.from_bytes(head[11:15], "little")
        return np.frombuffer(self._fh.read(n_bytes), dtype=_INDEX_ENTRY)

    def _layout(self, data, index, topic):
        """The CDR dtype of a fixed-size channel, from its first message."""
        schema = self.schema_name(topic)
        start = int(index["offset"][0]) + _MSG_HEADER
        size = int(_u64(data, index["offset"][:1].astype(np.int64) + 1)[0]) - 22
        frame = _frame_id(data, start)
        if schema not in schemas.BODIES or schemas.cdr_dtype(schema, frame).itemsize != size:
            raise LayoutError(f"{self.path}: {topic} ({schema}) is not a fixed-size channel "
                              "of the contract; read it with read_generic()")
        return schemas.cdr_dtype(schema, frame)

    def _gather(self, data, index, dtype, out, topic, ci):
        """Fill out (structured, with log_time) from the messages at the index offsets: read
        through one view of the records (`_records`), copying only the fields asked for."""
        off = index["offset"].astype(np.int64)
        size = dtype.itemsize
        damaged = LogError(f"{self.path}: {topic}: the message index of the chunk at byte "
                           f"{ci.chunk_start_offset} ({_since_epoch(self, ci.message_start_time)}"
                           f" to {_since_epoch(self, ci.message_end_time)}) does not point at "
                           "its messages (damaged index); `mimunav info LOG --recover OUT.mcap` "
                           "rebuilds the log from its intact chunks")
        # each entry at a record's header inside the records, no two at one record (entries
        # repeated had read one message twice and lost another, silently)
        if len(off) and (off.min() < 0 or off.max() > len(data) - _MSG_HEADER or
                         np.any(np.diff(np.sort(off)) < _MSG_HEADER)):
            raise damaged
        channel = _rows(data, off + 9, 2).view("<u2").ravel()
        log_time = _u64(data, off + 15)
        if np.any(log_time != index["log_time"]) or \
                np.any(channel != self._channel(topic).id) or \
                np.any(_rows(data, off, 1).ravel() != 0x05):
            raise damaged
        changed = LogError(f"{self.path}: {topic} changes message size, frame_id or CDR "
                           f"encapsulation within the chunk starting at "
                           f"{ci.message_start_time} ns; read it with read_generic()")
        if np.any(_u64(data, off + 1) != size + _MSG_HEADER - 9) or \
                off.max() > len(data) - _MSG_HEADER - size:
            raise changed
        msgs = _records(data, off, dtype)
        if np.any(msgs["frame_len"] != msgs["frame_len"][0]) or np.any(
                msgs["_encapsulation"] != np.frombuffer(schemas.ENCAPSULATION[:2], np.uint8)):
            raise changed
        if out.dtype.names[0] == "payload":             # fields=PAYLOAD: the CDR bytes
            out["payload"] = _rows(data, off + _MSG_HEADER, size).view(
                out.dtype["payload"]).ravel()
        else:
            for name in out.dtype.names[:-1]:
                out[name] = msgs[name]
        out["log_time"] = log_time

    def read_generic(self, topic: str) -> list[tuple[int, object]]:
        """Messages of any ROS 2 channel, decoded one by one (mcap_ros2): list of
        (log_time ns, message object)."""
        DecoderFactory = require("mcap_ros2.decoder", "import",
                                 "reading a ROS 2 channel").DecoderFactory
        self._fh.seek(0)
        reader = make_reader(self._fh, decoder_factories=[DecoderFactory()])
        return [(m.log_time, d) for _, _, m, d in
                reader.iter_decoded_messages(topics=[self._channel(topic).topic])]


PAYLOAD = ("payload",)      # fields= of read/blocks: each message's CDR payload, unparsed
DECODE_THREADS = min(2, os.cpu_count() or 1)
DECODE_AHEAD = 4            # chunks decompressed ahead of the one being gathered
_local = threading.local()


def _decompressor():
    """This thread's zstd decompressor (one may not serve two threads at once)."""
    if not hasattr(_local, "dctx"):
        _local.dctx = zstandard.ZstdDecompressor()
    return _local.dctx


def _rows(data, starts, size):
    """(n, size) bytes starting at the given offsets: a strided view when the offsets are
    equally spaced (one channel written in order), else a gather."""
    step = int(starts[1] - starts[0]) if len(starts) > 1 else size
    if step > 0 and starts[-1] - starts[0] == step * (len(starts) - 1) and \
            np.all(np.diff(starts) == step):
        return np.lib.stride_tricks.as_strided(data[starts[0]:], (len(starts), size),
                                               (step, 1), writeable=False).copy()
    return data[starts[:, None] + np.arange(size)]


def _records(data, offsets, payload):
    """The Message records starting at the given offsets of a chunk's records (bytes as
    uint8) as one structured array: the first two bytes of each one's CDR encapsulation
    (_encapsulation) and the payload's fields (`payload`, a `cdr_dtype`). A read-only view
    when the offsets are equally spaced (one channel written in order): a field is copied
    only when asked for - else gathered. Offsets of whole records inside the data."""
    names, formats, places = ["_encapsulation"], [("u1", 2)], [_MSG_HEADER]
    for name in payload.names:
        if name != "encap":
            names.append(name)
            formats.append(payload.fields[name][0])
            places.append(_MSG_HEADER + payload.fields[name][1])
    record = np.dtype({"names": names, "formats": formats, "offsets": places,
                       "itemsize": _MSG_HEADER + payload.itemsize})
    step = int(offsets[1] - offsets[0]) if len(offsets) > 1 else record.itemsize
    if len(offsets) and step >= record.itemsize and np.all(np.diff(offsets) == step):
        return np.ndarray((len(offsets),), record, buffer=data, offset=int(offsets[0]),
                          strides=(step,))
    return data[offsets[:, None] + np.arange(record.itemsize)].view(record).ravel()


def _since_epoch(log, ns):
    """A message time for people: s since the flight's epoch (absolute ns if unknown)."""
    epoch = log.epoch_ns()
    return f"t = {(ns - epoch) / 1e9:.3f} s" if epoch is not None else f"{ns} ns"


def _u64(data, offsets):
    return _rows(data, offsets, 8).view("<u8").ravel()


def _frame_id(data, payload_start):
    n = int(data[payload_start + 12:payload_start + 16].view("<u4")[0])
    return bytes(data[payload_start + 16:payload_start + 15 + n]).decode()


def _with_log_time(dtype, fields=None):
    if fields is not None and tuple(fields) == PAYLOAD:
        return np.dtype([("payload", f"V{dtype.itemsize}"), ("log_time", "<u8")])
    names = [n for n in dtype.names if n != "encap" and (fields is None or n in fields)]
    if fields is not None and len(names) != len(fields):
        raise LogError(f"fields {sorted(set(fields) - set(names))} are not in the message")
    return np.dtype([(name, dtype.fields[name][0]) for name in names] + [("log_time", "<u8")])


def _maybe_json(value):
    try:
        return json.loads(value)
    except (json.JSONDecodeError, TypeError):
        return value

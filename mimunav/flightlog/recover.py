"""Damaged logs: walk a file's records, check every chunk, keep every intact one.

A log cut short (a recorder that lost power: no summary, no footer) or hit by a flipped bit
or an overwritten block still holds every chunk that was not touched. `scan` walks the
top-level records by their lengths (MCAP framing: opcode 1 byte, length 8 bytes, body);
where a length leads nowhere it resynchronises on the next chunk header (opcode 0x06 with
its compression string in place). Each chunk is decompressed and its CRC checked; an intact
one contributes its messages, a damaged one is listed with its byte range, its time range
(from its header, when that is readable) and why. Schemas and channels are taken from
wherever they are intact (chunks and the summary section), so the messages of a chunk whose
channel record was in a damaged chunk are still kept. `recover` writes what was kept as a
complete log; the report says exactly what was kept and what dropped.
"""
import os
import struct
import zlib

import zstandard
from mcap.exceptions import EndOfFile, McapError
from mcap.records import Attachment, Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from ..errors import InputError
from .writer import MAGIC

CHUNK, DATA_END, FOOTER = 0x06, 0x0F, 0x02
_COMPRESSIONS = (b"zstd", b"lz4", b"")
_DECODE_ERRORS = (McapError, EOFError, ValueError, KeyError, struct.error, IndexError)


# first bytes of the recordings `mimunav import` reads, and the command for each
FOREIGN_MAGIC = ((b"ULog\x01\x12\x35", "a PX4 ULog: `mimunav import ulog FILE -o LOG.mcap`"),
                 (b"\xa3\x95", "an ArduPilot DataFlash log: `mimunav import dataflash FILE -o "
                               "LOG.mcap`"),
                 (b"#ROSBAG", "a ROS 1 bag: `mimunav import ros1 FILE -o LOG.mcap`"),
                 (b"SQLite f", "an SQLite file, a rosbag2 .db3?: `mimunav import ros2 FOLDER -o "
                               "LOG.mcap` of the folder with its metadata.yaml"))


def folder_hint(path) -> str:
    """'; it looks like ...: import it' for a folder mimunav imports (a rosbag2 folder, an
    RTKLIB drive's), else ''."""
    if os.path.isfile(os.path.join(path, "metadata.yaml")):
        return "; it looks like a rosbag2 folder: `mimunav import ros2 FOLDER -o LOG.mcap`"
    if any(name.endswith(".pos") for name in os.listdir(path)):
        return "; it looks like an RTKLIB drive: `mimunav import rtklib FOLDER -o LOG.mcap`"
    return ""


def foreign_hint(head: bytes) -> str:
    """'; it looks like ...: import it' for the first bytes of a recording mimunav imports,
    else ''."""
    for magic, what in FOREIGN_MAGIC:
        if head.startswith(magic):
            return f"; it looks like {what}"
    return ""


class DamagedLog(InputError):
    """A file that is not an MCAP log at all (no magic, empty)."""


def scan(path: str | os.PathLike, writer=None) -> dict:
    """Report of the intact part of a log: dict(channels={topic: (count, first_ns,
    last_ns)}, metadata=[names], damaged=[{offset, bytes, reason, start_ns, end_ns}],
    expected={topic: count} from the statistics when readable (else {}), size=bytes,
    epoch_ns, complete (nothing damaged)). With a `LogWriter`, the intact records are
    copied into it."""
    data = open(path, "rb").read()
    if not data.startswith(MAGIC):
        raise DamagedLog(f"{path}: not an MCAP file (no MCAP magic at its start"
                         + ("; the file is empty)" if not data else ")") + foreign_hint(data))
    chunks, tops, damaged = _walk(data)
    schemas, channels = {}, {}
    decoded = []
    for offset, length in chunks:
        records, reason, span = _chunk_records(data, offset, length)
        if reason is not None:
            damaged.append({"offset": offset, "bytes": 9 + length, "reason": reason,
                            "start_ns": span[0], "end_ns": span[1]})
            continue
        decoded.append(records)
        for r in records:
            _definition(r, schemas, channels)
    for r in tops:
        _definition(r, schemas, channels)
    counts, names, epoch = {}, [], None
    for r in tops:
        if isinstance(r, Metadata):
            names.append(r.name)
            if r.name == "flight" and "epoch_unix_ns" in r.metadata:
                epoch = _int(r.metadata["epoch_unix_ns"])
            if writer is not None:
                writer.metadata(r.name, r.metadata)
        elif isinstance(r, Attachment) and writer is not None:
            writer.attachment(r.name, r.data, r.media_type)
    orphans = 0
    for records in decoded:
        for r in records:
            if not isinstance(r, Message):
                continue
            channel = channels.get(r.channel_id)
            if channel is None or channel.schema_id not in schemas:
                orphans += 1
                continue
            n, first, last = counts.get(channel.topic, (0, r.log_time, r.log_time))
            counts[channel.topic] = (n + 1, min(first, r.log_time), max(last, r.log_time))
            if writer is not None:
                writer.copy(schemas[channel.schema_id], channel, r)
    if orphans:
        damaged.append({"offset": None, "bytes": 0, "start_ns": None, "end_ns": None,
                        "reason": f"{orphans} intact messages of a channel whose definition "
                                  "was in a damaged record: not kept"})
    expected = _statistics(tops, channels)
    return {"channels": counts, "metadata": names, "damaged": damaged, "expected": expected,
            "size": len(data), "epoch_ns": epoch, "complete": not damaged}


def recover(path: str | os.PathLike, out: str | os.PathLike, force: bool = False) -> dict:
    """Write the intact part of a damaged log to `out` as a complete log; returns `scan`'s
    report."""
    from .writer import LogWriter
    if not open(path, "rb").read(len(MAGIC)) == MAGIC:
        scan(path)                          # raises the error that says why
    with LogWriter(out, force=force) as writer:
        return scan(path, writer)


def _walk(data):
    """(chunks [(offset, body length)], other top-level records decoded, damaged ranges)
    of the data and summary sections; a length that leads out of the file or to an unknown
    opcode sends the walk to the next plausible chunk header."""
    chunks, tops, damaged = [], [], []
    pos, end = len(MAGIC), len(data)
    while pos + 9 <= end:
        op = data[pos]
        length = struct.unpack_from("<Q", data, pos + 1)[0]
        if op == FOOTER or (op == 0 and length == 0):
            break
        if not 0x01 <= op <= 0x0F or pos + 9 + length > end:
            nxt = _next_chunk(data, pos + 1)
            if nxt is None:
                if pos + 9 + length > end and 0x01 <= op <= 0x0F:
                    reason = f"record 0x{op:02x} cut short: the file ends {pos + 9 + length - end} bytes early"
                else:
                    reason = f"unreadable bytes (opcode 0x{op:02x}) to the end of the file"
                damaged.append({"offset": pos, "bytes": end - pos, "reason": reason,
                                "start_ns": None, "end_ns": None})
                break
            damaged.append({"offset": pos, "bytes": nxt - pos, "start_ns": None,
                            "end_ns": None, "reason": "unreadable bytes (a record whose "
                            "length leads nowhere); resumed at the next chunk"})
            pos = nxt
            continue
        if op == CHUNK:
            chunks.append((pos, length))
        elif op != DATA_END:
            record = _decode(data[pos:pos + 9 + length])
            if record is None:
                damaged.append({"offset": pos, "bytes": 9 + length, "start_ns": None,
                                "end_ns": None,
                                "reason": f"record 0x{op:02x} does not decode"})
            else:
                tops.extend(record)
        pos += 9 + length
    return chunks, tops, damaged


def _next_chunk(data, start):
    """Offset of the next plausible chunk header at or after `start`, or None."""
    best = None
    for comp in _COMPRESSIONS[:2]:
        pattern = struct.pack("<I", len(comp)) + comp
        k = data.find(pattern, start + 37)
        while k != -1:
            pos = k - 37
            if pos >= start and data[pos] == CHUNK and \
                    pos + 9 + struct.unpack_from("<Q", data, pos + 1)[0] <= len(data):
                best = pos if best is None else min(best, pos)
                break
            k = data.find(pattern, k + 1)
    return best


def _decode(raw):
    """The records of a byte string of whole records, or None when it does not decode (the
    reader ends with EndOfFile, which counts only where a record ends)."""
    stream = _Bytes(raw)
    out, ends = [], 0
    try:
        for record in StreamReader(stream, skip_magic=True, validate_crcs=True).records:
            out.append(record)
            ends = stream.tell()
    except EndOfFile:
        return out if ends == len(raw) or not raw else None
    except _DECODE_ERRORS:
        return None
    return out


def _chunk_records(data, offset, length):
    """(records, None, (start, end)) of an intact chunk, or (None, reason, (start, end))."""
    rec = data[offset:offset + 9 + length]
    try:
        start, end, size, crc, n = struct.unpack_from("<QQQII", rec, 9)
        compression = rec[41:41 + n]
        body_len = struct.unpack_from("<Q", rec, 41 + n)[0]
        body = rec[49 + n:49 + n + body_len]
        if len(body) != body_len or compression not in _COMPRESSIONS:
            raise ValueError("header inconsistent with its length")
        if compression == b"zstd":
            raw = zstandard.ZstdDecompressor().decompress(body, max_output_size=size)
        elif compression == b"lz4":
            import lz4.frame
            raw = lz4.frame.decompress(body)
        else:
            raw = body
    except (struct.error, ValueError, zstandard.ZstdError, OverflowError, MemoryError,
            RuntimeError) as exc:           # a size beyond 2^63: Overflow; lz4's: RuntimeError
        return None, f"chunk does not decompress ({type(exc).__name__}: {exc})", (None, None)
    if len(raw) != size or (crc and zlib.crc32(raw) != crc):
        return None, "chunk fails its CRC (its bytes changed)", (start, end)
    records = _decode(raw)
    if records is None:
        return None, "chunk's records do not decode", (start, end)
    return records, None, (start, end)


def _definition(record, schemas, channels):
    if isinstance(record, Schema):
        schemas.setdefault(record.id, record)
    elif isinstance(record, Channel):
        channels.setdefault(record.id, record)


def _statistics(tops, channels):
    from mcap.records import Statistics
    for r in tops:
        if isinstance(r, Statistics):
            return {channels[c].topic: n for c, n in r.channel_message_counts.items()
                    if c in channels}
    return {}


def _int(text):
    try:
        return int(text)
    except ValueError:
        return None


class _Bytes:
    """A minimal binary stream over bytes for `StreamReader`."""

    def __init__(self, raw):
        self._raw, self._pos = raw, 0

    def read(self, n=-1):
        if n is None or n < 0:
            n = len(self._raw) - self._pos
        out = self._raw[self._pos:self._pos + n]
        self._pos += len(out)
        return out

    def tell(self):
        return self._pos

    def seek(self, pos, whence=0):
        self._pos = pos if whence == 0 else (self._pos + pos if whence == 1 else
                                             len(self._raw) + pos)
        return self._pos


def _utc(ns):
    """A stamp (ns since 1970) for people when the log's epoch is lost with its metadata:
    UTC to the millisecond (the stamps' own time base, GPS or UTC, is the writer's)."""
    import datetime
    stamp = datetime.datetime.fromtimestamp(ns // 10**9, datetime.timezone.utc)
    return f"{stamp:%Y-%m-%d %H:%M:%S}.{ns % 10**9 // 10**6:03d} UTC"


def describe_scan(report: dict) -> str:
    lines = []
    epoch = report["epoch_ns"]
    when = lambda ns: ("?" if ns is None else f"t = {(ns - epoch) / 1e9:.3f} s"   # noqa: E731
                       if epoch is not None else _utc(ns))
    expected = report["expected"]
    for topic, (n, first, last) in sorted(report["channels"].items()):
        of = f" of {expected[topic]}" if topic in expected else ""
        lines.append(f"  {topic:<14} {n:>9}{of} intact messages, {when(first)} .. {when(last)}")
    for topic in sorted(set(expected) - set(report["channels"])):
        lines.append(f"  {topic:<14}         0 of {expected[topic]} intact messages")
    if not expected and not report["complete"]:
        lines.append("the summary (statistics) is lost: a channel all of whose chunks were "
                     "lost is not listed above, and the counts cannot be compared")
    for d in report["damaged"]:
        where = f"bytes {d['offset']}-{d['offset'] + d['bytes']}" if d["offset"] is not None \
            else "messages"
        span = (f" (messages {when(d['start_ns'])} .. {when(d['end_ns'])})"
                if d.get("start_ns") is not None else "")
        lines.append(f"dropped {where}{span}: {d['reason']}")
    if report["complete"]:
        lines.append("every record is intact")
    return "\n".join(lines)

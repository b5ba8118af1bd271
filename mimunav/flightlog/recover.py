"""Damaged logs: stream a file's records in order (CRCs checked) and keep what is intact.

A log cut short (a recorder that lost power: no summary, no footer) still holds every chunk
written before the cut. `scan` reads records until the first one that is incomplete or
fails its CRC and reports, per channel, how many messages were intact and up to when, and
where and why reading stopped; `recover` also writes the intact part as a complete log.
"""
import os

from mcap.exceptions import McapError
from mcap.records import Channel, Message, Metadata, Attachment, Schema
from mcap.stream_reader import StreamReader


def scan(path, writer=None):
    """Report of the intact part of a log: dict(channels={topic: (count, first_ns,
    last_ns)}, metadata=[names], stopped_at=byte or None, size=bytes, reason=str or None).
    With a `LogWriter`, the intact records are copied into it."""
    size = os.path.getsize(path)
    schemas, channels, counts = {}, {}, {}
    names, reason, good_offset, epoch = [], None, 0, None
    with open(path, "rb") as fh:
        reader = StreamReader(fh, validate_crcs=True)
        try:
            for record in reader.records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    channel = channels[record.channel_id]
                    n, first, _ = counts.get(channel.topic, (0, record.log_time, 0))
                    counts[channel.topic] = (n + 1, first, record.log_time)
                    if writer is not None:
                        writer.copy(schemas[channel.schema_id], channel, record)
                elif isinstance(record, Metadata):
                    names.append(record.name)
                    if record.name == "flight" and "epoch_unix_ns" in record.metadata:
                        epoch = int(record.metadata["epoch_unix_ns"])
                    if writer is not None:
                        writer.metadata(record.name, record.metadata)
                elif isinstance(record, Attachment) and writer is not None:
                    writer.attachment(record.name, record.data, record.media_type)
                good_offset = fh.tell()
        except (McapError, EOFError, ValueError, KeyError, OSError) as exc:
            reason = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    complete = reason is None
    return {"channels": counts, "metadata": names, "size": size, "epoch_ns": epoch,
            "stopped_at": None if complete else good_offset, "reason": reason}


def recover(path, out, force=False):
    """Write the intact part of a damaged log to `out` as a complete log; returns `scan`'s
    report."""
    from .writer import LogWriter
    with LogWriter(out, force=force) as writer:
        return scan(path, writer)


def describe_scan(report):
    lines = []
    epoch = report["epoch_ns"]
    for topic, (n, first, last) in sorted(report["channels"].items()):
        span = (f"t = {(first - epoch) / 1e9:.3f} .. {(last - epoch) / 1e9:.3f} s"
                if epoch is not None else f"{first} .. {last} ns")
        lines.append(f"  {topic:<14} {n:>9} intact messages, {span}")
    if report["stopped_at"] is not None:
        lines.append(f"reading stopped at byte {report['stopped_at']} of {report['size']} "
                     f"({100 * report['stopped_at'] / max(report['size'], 1):.1f} % recovered): "
                     f"{report['reason']}")
    return "\n".join(lines)

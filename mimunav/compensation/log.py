"""A log's raw MIMU compensated block by block into `/mimu/imu` (bounded memory; margins
carried across blocks so the wild-value filter sees the same neighbours as over the whole).
"""
import itertools
import math
import os
from collections.abc import Iterator

import numpy as np

from . import effects
from .model import compensate
from .wild_values import (
    CLIP_RUN,
    CURVE_REACH,
    RecordStats,
    flag_counts,
    wild_value_filter,
)

RAW_FIELDS = ("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency")
BLOCK = 1 << 18             # samples per block of `compensate_log` (~100 MB of work arrays)
HELD_SAMPLES = 1 << 20      # a record up to this long (~140 MB) is read once for the 3 passes


def compensate_log(log_path: str | os.PathLike, cal, out: str | os.PathLike, force: bool = False,
                   skip_damaged: bool = False, block: int = BLOCK) -> dict[str, int]:
    """Apply a calibration to a log's /mimu/raw channel and write OUT: every channel,
    metadata record and attachment of the input copied (the contract's fixed-size channels
    field by field, with CDR padding written as zeros; others byte for byte, their chunks'
    CRCs checked), plus /mimu/imu (sensor_msgs/msg/Imu, sensor axes, interval means, no
    orientation). A damaged chunk or index is a LogError; with skip_damaged its messages are
    left out and listed in the output's `damage` metadata record. Returns the flag counts
    (`flag_counts`).

    Memory is bounded: the record is worked in blocks of `block` samples, in three passes -
    the wild-value filter's noise level from a subsample of the whole record, the clipping
    extremes of the filtered voltages, then the compensation - each block with
    `margin_samples` of its neighbours on both sides, so every sample sees what it
    would see in a whole-record compensation (tests/test_compensation.py checks they agree).
    Where that does not hold: a run of wild or non-finite samples longer than the margin
    across a block edge is repaired from the samples within reach (held, or UNUSABLE when
    the whole extended block has none) instead of interpolated across - flagged either way;
    and the derivative of found terms takes each block's median sample interval (a record
    whose rate changes differs near the change). A record of up to HELD_SAMPLES samples is
    read once and held for the three passes; a longer one is read from the file in each
    (`FlightLog.blocks`), and if its stamps go back in time, read whole and sorted."""
    from ..flightlog.reader import TimeOrderError
    try:
        return _compensate_log(log_path, cal, out, force, skip_damaged, block)
    except TimeOrderError:          # stamps going back in time: read whole, sorted (`read`)
        return _compensate_log(log_path, cal, out, force, skip_damaged, None)


def _channel_blocks(log, topic, block, fields=None):
    """The channel in blocks (`FlightLog.blocks`), or whole and time-sorted (`read`) when
    block is None."""
    if block is None:
        msgs = log.read(topic, fields)
        return [msgs] if len(msgs) else []
    return log.blocks(topic, block, fields)


def compensated_blocks(log, cal, block: int = BLOCK) -> Iterator[tuple]:
    """The /mimu/raw channel of an open FlightLog through `cal`, block by block in bounded
    memory (as `compensate_log` describes): yields (raw messages of the block, f m/s^2,
    w rad/s, flags), sensor axes; `block` None works the channel whole, time-sorted. A
    channel of more than HELD_SAMPLES samples streams from the file, and then raises
    flightlog's TimeOrderError if its stamps go back in time across blocks (read it with
    block=None)."""
    from ..flightlog import LogError
    rng = log.metadata().get("sensor/mimu", {}).get("range", {})
    n = log.count("/mimu/raw") if not log.skip_damaged else None   # checked as it is read
    if n is None:
        n = sum(len(b) for b in _channel_blocks(log, "/mimu/raw", block, ["sample_index"]))
    if n < 2:
        raise LogError(f"{log.path}: /mimu/raw has {n} intact messages")
    # a short record (or one whose stamps go back: block None) is read once, time-sorted,
    # and its blocks are views of it; a long one is read from the file for each pass
    whole = log.read("/mimu/raw") if block is None or n <= HELD_SAMPLES else None

    def with_margins(fields, margin):
        if whole is None:
            return _with_margins(log.blocks("/mimu/raw", max(block, 2 * margin), fields), margin)
        return _margin_views(whole, block or len(whole), margin)
    stats = RecordStats.sigma_of_blocks(
        [whole] if whole is not None else log.blocks("/mimu/raw", block, RAW_FIELDS),
        n, RAW_FIELDS)
    margin = margin_samples(cal, 1e9 / stats.min_step_ns)
    for ext, lo, hi in with_margins(RAW_FIELDS[:2], margin):
        flags = np.zeros(len(ext), np.uint8)
        stats.add_extremes([wild_value_filter(ext[name], flags, sigma=sigma)[lo:hi]
                            for name, sigma in zip(RAW_FIELDS[:2], stats.sigma[:2])])
    stats.finish_extremes()
    t0 = None
    for ext, lo, hi in with_margins(None, margin):
        stamps = ext["log_time"].astype(np.int64)
        t0 = stamps[0] if t0 is None else t0
        f, w, flags = compensate(cal, *(ext[name] for name in RAW_FIELDS),
                                 rng.get("accel_m_s2", np.inf), rng.get("gyro_rad_s", np.inf),
                                 t=(stamps - t0) / 1e9, record=stats)
        yield ext[lo:hi], f[lo:hi], w[lo:hi], flags[lo:hi]


def _compensate_log(log_path, cal, out, force, skip_damaged, block):
    from mcap.reader import make_reader

    from ..flightlog import FlightLog, LayoutError, LogError, LogWriter
    from ..flightlog import schemas as S
    from ..flightlog.reader import PAYLOAD
    with FlightLog(log_path, skip_damaged=skip_damaged) as log:
        if "/mimu/imu" in log.channels:
            raise LogError(f"{log_path} already has /mimu/imu")
    counts = dict.fromkeys(("replaced", "saturated", "unusable"), 0)
    with open(log_path, "rb") as fh, LogWriter(out, force=force) as dst, \
            FlightLog(log_path, skip_damaged=skip_damaged) as log:
        log.metadata()                      # a damaged metadata record is a LogError
        blocks = compensated_blocks(log, cal, block)
        own = next(blocks)                  # the record's checks before anything is written
        reader = make_reader(fh)
        for record in reader.iter_metadata():
            dst.metadata(record.name, record.metadata)
        for att in reader.iter_attachments():
            dst.attachment(att.name, att.data, att.media_type)
        generic = []
        raw_fields = [name for name, _, _ in S.BODIES[S.RAW_MIMU]]
        for topic in log.channels:
            if topic == "/mimu/raw":            # copied below, from the compensation's read
                continue
            try:        # a channel of the contract's layouts: its payloads as they are
                for msgs in _channel_blocks(log, topic, block, PAYLOAD):
                    dst.write_encoded(topic, log.schema_name(topic), msgs["payload"],
                                      msgs["log_time"].astype(np.int64), increasing=True)
            except LayoutError:
                generic.append(topic)
        for raw, f, w, flags in itertools.chain([own], blocks):
            stamps = raw["log_time"].astype(np.int64)
            dst.write("/mimu/raw", S.RAW_MIMU, raw["frame_id"][0].decode(), stamps,
                      **{name: raw[name] for name in raw_fields})
            dst.write("/mimu/imu", S.IMU, "mimu", stamps, **S.imu_fields(w, f))
            for name, count in flag_counts(flags).items():
                counts[name] += count
        fh.seek(0)
        try:
            for schema, channel, message in make_reader(fh, validate_crcs=True).iter_messages(
                    topics=generic):
                dst.copy(schema, channel, message)
        except Exception as exc:            # the mcap reader's own errors on damaged chunks
            raise LogError(f"{log_path}: damaged data in {', '.join(generic)} "
                           f"({type(exc).__name__}: {exc})") from None
        if log.damaged:
            dst.metadata("damage", {topic: [{"start_ns": a, "end_ns": b, "reason": r}
                                            for a, b, r in spans]
                                    for topic, spans in log.damaged.items()})
    return counts


def margin_samples(cal, rate_hz: float) -> int:
    """Samples of context a block needs on each side for `compensate` to act on its
    samples as on the whole record: the cold-start model's dT window, the windows of found
    terms and the derivative window of their conditions (s, at rate_hz), plus the wild-value
    filter's and the clipping test's reach."""
    seconds = [effects.DERIVATIVE_WINDOW_S]
    if cal.cold_start:
        seconds.append(cal.cold_start.get("window_s", 0.0))
    for term in cal.found or []:
        seconds.append(float(term.get("window_s", 0.0)))
        if term["effect"] == "thermal_hysteresis":      # slope over a centred window
            seconds.append(effects.HYSTERESIS_SLOPE_WINDOW_S / 2)
        if term["effect"] == "time_skew":               # the samples shifted by tau
            seconds.append(float(np.max(np.abs(term["coefficient"]))) + effects.DERIVATIVE_WINDOW_S)
        if term["effect"] == "vibration_rectification":  # window + the filter's settling
            seconds.append(effects.VIBRATION_WINDOW_S / 2 + 10.0 / effects.VIBRATION_CUTOFF_HZ)
    return int(math.ceil(max(seconds) * rate_hz)) + 2 * CLIP_RUN + 2 * CURVE_REACH + 8


def _margin_views(whole, block, margin):
    """`_with_margins` of a record held whole: views of blocks of `block` samples with up to
    `margin` samples of their neighbours."""
    for start in range(0, len(whole), block):
        lo, end = max(0, start - margin), min(len(whole), start + block)
        yield whole[lo:min(len(whole), end + margin)], start - lo, end - lo


def _with_margins(blocks, margin):
    """(block with up to `margin` samples of the previous and next blocks around it, start,
    end of the block's own samples in it) for consecutive blocks."""
    before, current = None, None
    for nxt in blocks:
        if current is not None:
            yield _joined(before, current, nxt[:margin])
            before = _tail(before, current, margin)
        current = nxt
    if current is not None:
        yield _joined(before, current, current[:0])


def _joined(before, current, after):
    parts = [p for p in (before, current, after) if p is not None]
    lo = 0 if before is None else len(before)
    return np.concatenate(parts), lo, lo + len(current)


def _tail(before, current, margin):
    if margin == 0:
        return current[:0]
    if before is None or len(current) >= margin:
        return current[-margin:].copy()
    return np.concatenate([before, current])[-margin:]

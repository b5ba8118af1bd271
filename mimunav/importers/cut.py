"""A log cut to a span of time (`mimunav cut LOG --span T0:T1 -o OUT`): every channel's
messages stamped inside [T0, T1] (s since the log's epoch), the metadata and attachments as
they are, and an initial state inside the span - the log's own when it lies there, else the
reference's (/truth/state) at its first epoch in the span with an attitude, else the alignment
of an imported recording redone on the span's IMU and track (`navigation.alignment`). The
span's metadata says where the cut was and where the new initial state came from."""
import json

import numpy as np
from mcap.reader import make_reader

from ..errors import InputError
from ..frames import attitude
from ..frames.mounting import Mounting
from ..motion.carrier import course_keys, recorded_kind
from ..navigation.alignment import initial_alignment
from ..flightlog import FlightLog, LayoutError, LogWriter
from ..flightlog.reader import PAYLOAD
from .recording import heading_source


def cut(log_path, out, t0, t1, force=False):
    """Write the part of the log at `log_path` stamped in [t0, t1] s (since its epoch) to
    `out`; returns (message count, how the initial state was found, (first, last) stamp
    written, s since the epoch)."""
    with FlightLog(log_path) as log:
        meta = log.metadata()
        flight = meta.get("flight")
        if not flight or "epoch_unix_ns" not in flight:
            raise InputError(f"{log_path}: no `flight` metadata with epoch_unix_ns: the span "
                             "has no time base to be cut on")
        epoch = int(flight["epoch_unix_ns"])
        lo, hi = epoch + int(round(t0 * 1e9)), epoch + int(round(t1 * 1e9))
        initial, how, heading, attitude_from = _initial_state(log, flight, meta, t0, t1, epoch)
        count, generic, written = 0, [], [np.inf, -np.inf]
        with LogWriter(out, force=force) as dst, open(log_path, "rb") as fh:
            reader = make_reader(fh)
            for record in reader.iter_metadata():
                values = record.metadata
                if record.name == "flight":    # its description says what it is now
                    values = {**values, "initial_state": initial, "description":
                              f"{values.get('description', '')} - cut to {t0:g}-{t1:g} s"}
                if record.name == "recording" and heading is not None:     # and how the
                    values = _restarted(values, how, heading,   # span's state was found
                                        attitude_from)
                dst.metadata(record.name, values)
            for att in reader.iter_attachments():
                dst.attachment(att.name, att.data, att.media_type)
            dst.metadata("cut", {"span_s": [t0, t1], "from": str(log_path),
                                 "initial_state": how})
            for topic in log.channels:
                try:
                    for msgs in log.blocks(topic, fields=PAYLOAD):
                        stamps = msgs["log_time"].astype(np.int64)
                        keep = (stamps >= lo) & (stamps <= hi)
                        if keep.any():
                            dst.write_encoded(topic, log.schema_name(topic),
                                              msgs["payload"][keep], stamps[keep])
                            count += int(keep.sum())
                            written = [min(written[0], (stamps[keep][0] - epoch) / 1e9),
                                       max(written[1], (stamps[keep][-1] - epoch) / 1e9)]
                except LayoutError:
                    generic.append(topic)
            fh.seek(0)
            for schema, channel, message in make_reader(fh).iter_messages(topics=generic):
                if lo <= message.log_time <= hi:    # (the time arguments' names differ
                    dst.copy(schema, channel, message)  # between mcap releases)
                    count += 1
    return count, how, tuple(written)


def _restarted(values, how, heading, attitude_from):
    """A recording's metadata values with its initial state's account (`assumed`'s
    initial_state, `initial_heading`, `initial_attitude`) the span's: what `diagnose` judges
    the state by; the import's kept as import_initial_state (its biases are the metadata's,
    and `bias_basis` says what they measured)."""
    assumed = values.get("assumed") or "{}"
    assumed = json.loads(assumed) if isinstance(assumed, str) else dict(assumed)
    # the import's own account stays: the biases it measured (kept in the metadata) are its
    assumed.setdefault("import_initial_state", assumed.get("initial_state", ""))
    assumed["initial_state"] = how
    known = json.loads(values.get("reference_heading_known", "true"))    # JSON in the record
    return {**values, "assumed": assumed, "initial_heading": heading_source(heading, known),
            "initial_attitude": attitude_from}


def _initial_state(log, flight, meta, t0, t1, epoch):
    """(initial_state object, how it was found, where its heading came from - None: the
    log's own state, unchanged -, where its attitude came from) inside [t0, t1] (module
    doc)."""
    initial = flight.get("initial_state") or {}
    if t0 <= float(initial.get("t", np.nan)) <= t1:
        return initial, "the log's own (inside the span)", None, None
    if "/truth/state" in log.channels:
        truth = log.read("/truth/state")
        t = (truth["log_time"].astype(np.int64) - epoch) / 1e9
        q = np.asarray(truth["attitude_wxyz"], float)
        ok = np.flatnonzero((t >= t0) & (t <= t1) & np.isfinite(q).all(axis=1))
        if len(ok):
            k = ok[0]
            return ({"t": float(t[k]), "latitude": float(truth["latitude"][k]),
                     "longitude": float(truth["longitude"][k]), "height": float(truth["height"][k]),
                     "velocity_ned": [float(v) for v in truth["velocity_ned"][k]],
                     "attitude_wxyz": [float(v) for v in q[k]]},
                    f"whole state from the reference at t = {t[k]:.3f} s (/truth/state)",
                    "reference", "reference")
        if "/mimu/imu" in log.channels:
            return _realigned(log, truth, t, t0, t1, epoch, meta)
    elif "/mimu/imu" in log.channels and "recording" in meta:   # an IMU alone or beside a
        return _realigned(log, None, None, t0, t1, epoch, meta)  # reference IMU: as imported
    raise InputError(f"the initial state (t = {initial.get('t')}) lies outside the span and the "
                     "log has no reference trajectory to start the span from, nor an imported "
                     "IMU (/mimu/imu) to align on it: cut a span that holds it")


def _realigned(log, truth, t_ref, t0, t1, epoch, meta):
    """The alignment of an imported recording redone on the span's /mimu/imu and track (the
    reference trajectory `truth` at t_ref s; None: the IMU alone, as its import aligned it -
    a Shimmer's pair of accelerometers could be cut only from 0 s)."""
    imu = log.read("/mimu/imu", fields=("angular_velocity", "linear_acceleration"))
    t = (imu["log_time"].astype(np.int64) - epoch) / 1e9
    k = (t >= t0) & (t <= t1)
    inside = np.zeros(0, bool) if truth is None else (t_ref >= t0) & (t_ref <= t1)
    if k.sum() < 10 or (truth is not None and inside.sum() < 2):
        raise InputError(f"the span {t0:g}-{t1:g} s holds {int(k.sum())} IMU samples" + (
            "" if truth is None else f" and {int(inside.sum())} reference epochs")
            + ": too few to start from")
    track = None if truth is None else {"t": t_ref[inside], "lat": truth["latitude"][inside],
             "lon": truth["longitude"][inside], "h": truth["height"][inside],
             "v_ned": np.asarray(truth["velocity_ned"], float)[inside],
             "heading_known": (meta.get("recording") or {}).get("reference_heading_known",
                                                                 True) is not False,
             **course_keys(*recorded_kind(meta.get("recording") or {}))}
    mounting = Mounting.from_dict(meta.get("sensor/mimu", {}).get("mounting", {}))
    # the biases the import measured over the whole recording (its rest) hold for the span:
    # taken out first, where the span alone may hold no rest to measure them
    recording = meta.get("recording") or {}
    gyro_bias, accel_bias = (np.asarray(recording.get(key) or np.zeros(3), float)
                             for key in ("gyro_bias_static_rad_s", "accel_bias_m_s2"))
    align = initial_alignment(t[k], np.asarray(imu["angular_velocity"], float)[k] - gyro_bias,
                              np.asarray(imu["linear_acceleration"], float)[k] - accel_bias,
                              mounting, track)
    method = align.method
    if gyro_bias.any() or accel_bias.any():
        method = ("on the outputs less the biases the import measured over the whole "
                  f"recording, then: {method}")
    q = attitude.as_wxyz(attitude.from_wxyz(np.asarray(align.q_nb, float)))
    return ({"t": float(align.t), "latitude": float(align.lat), "longitude": float(align.lon),
             "height": float(align.h), "velocity_ned": [float(v) for v in align.v_ned],
             "attitude_wxyz": [float(v) for v in q]},
            f"the alignment redone on the span: {method}", align.heading, align.attitude_from)

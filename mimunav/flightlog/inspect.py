"""What `mimunav info` prints of a log: channels, rates, gaps, dropped samples, metadata.
"""
import numpy as np

from . import schemas
from .stamps import mean_rate_hz, missing_samples, rate_segments, scheduled


def channel_report(log, topic, origin_ns=None):
    """dict: schema, count, rate_hz (one rate: the mean over the span, missing samples
    counted; several: the median step's), duration_s, gaps [(t0, t1) s since origin_ns
    (the log's epoch; default the channel's first stamp), where samples are missing given
    the median rate - not sampling jitter; with the number missing in `missing`], dropped
    samples (sample_index jumps, at s since the same origin)."""
    msgs = log.read(topic)
    t = msgs["log_time"].astype(np.int64)
    rep = {"schema": log.schema_name(topic), "count": len(t)}
    if len(t) < 2:
        return rep
    step = np.diff(t)
    gaps = missing_samples(t)
    t0 = int(t[0]) if origin_ns is None else int(origin_ns)
    segments = rate_segments(t)
    if len(segments) > 1:
        rep["rates"] = [((t[a] - t0) / 1e9, 1e9 / period) for a, _, period in segments]
    nominal = np.concatenate([np.full(b - a, period) for a, b, period in segments])
    missing = sum(n for _, n in gaps)
    rep.update(rate_hz=mean_rate_hz(t), duration_s=(t[-1] - t[0]) / 1e9,
               start_ns=int(t[0]), gaps=[((t[k] - t0) / 1e9, (t[k + 1] - t0) / 1e9)
                                          for k, _ in gaps],
               missing=missing, scheduled=scheduled(gaps),
               jitter_ms=float(1.4826 * np.median(np.abs(step - nominal)) / 1e6),
               backwards=log.time_reversals.get(topic, 0), duplicates=int(np.sum(step == 0)))
    if "sample_index" in msgs.dtype.names:
        jumps = np.diff(msgs["sample_index"].astype(np.int64))
        bad = np.nonzero(jumps != 1)[0]
        rep["dropped"] = int(np.sum(jumps[jumps > 1] - 1))
        rep["index_jumps"] = [((t[k] - t0) / 1e9, int(jumps[k])) for k in bad]
    if "header" not in msgs.dtype.names and "sec" in msgs.dtype.names:
        rep["stamp_mismatch"] = int(np.sum(schemas.stamps_ns(msgs) != t))
    return rep


def _lever_text(arm):
    """The turning IMU's place: on the axis, or its lever arm (m, platform axes)."""
    try:
        arm = [float(x) for x in arm]
    except (TypeError, ValueError):
        return "place not stated"
    return ("on the axis" if not any(arm) else
            "at " + ", ".join(f"{x:.3g}" for x in arm) + " m from the axis (platform axes)")


def _mounting_text(doc):
    """A mounting as roll/pitch/yaw (deg, sensor -> vehicle) and lever arm (m)."""
    from ..frames import attitude
    from ..frames.mounting import Mounting
    try:
        m = Mounting.from_dict(doc or {})
    except (ValueError, TypeError):
        return f"{doc} (not readable)"
    yaw, pitch, roll = (float(np.degrees(a)) + 0.0 for a in attitude.as_euler(m.q_vs))
    return (f"roll/pitch/yaw [{roll:.2f}, {pitch:.2f}, {yaw:.2f}] deg, lever arm "
            f"{np.round(m.lever_arm_m, 3).tolist()} m")


HEADING = {"reference": "from the reference's attitude", "course": "from the GNSS course (a "
           "car's heading; of what is not a car, only its course)",
           "assumed": "assumed: nothing measured it"}
ATTITUDE = {"reference": "from the reference", "leveled": "leveled on the IMU's own specific "
            "force", "reference_level": "leveled on the reference's attitude at a rest (the "
            "accelerometers' bias across gravity measured against it)"}


def _recording_lines(meta):
    """An imported recording's initial heading and attitude - where they came from, which
    decides what the diagnosis may find -, the vehicle it declared, and its reference's
    frame, when the metadata says."""
    rec = meta.get("recording") if isinstance(meta.get("recording"), dict) else {}
    assumed = rec.get("assumed") if isinstance(rec.get("assumed"), dict) else {}
    lines = []
    if rec.get("initial_heading"):
        heading = rec["initial_heading"]
        why = str(assumed.get("initial_heading") or "").removeprefix("assumed: ")
        said = f"{heading} ({why})" if why else HEADING.get(heading, heading)
        leveled = ATTITUDE.get(rec.get("initial_attitude"))
        lines.append(f"heading   {said}" + (f"; attitude {leveled}" if leveled else ""))
    if rec:
        lines.append(f"vehicle   {rec['vehicle']} (declared)" if rec.get("vehicle") else
                     "vehicle   not declared (the diagnosis judges it from the track)")
    frame = (meta.get("reference") or {}).get("frame") if isinstance(meta.get("reference"),
                                                                       dict) else None
    if frame:
        lines.append(f"reference {frame}")
    return lines


def describe(log, unreadable=None):
    """The text of `mimunav info`; the topics that cannot be read are appended to the list
    `unreadable` when one is given."""
    lines = [f"log       {log.path}"]
    meta = log.metadata()
    flight = meta.get("flight", {})
    for key in ("format", "name", "description", "source", "epoch_unix_ns"):
        if key in flight:
            lines.append(f"{key:<9} {flight[key]}")
    if "initial_state" in flight:
        s = flight["initial_state"]
        v = np.asarray(s.get("velocity_ned", [np.nan] * 3), float)
        lines.append(f"initial   t = {float(s.get('t', np.nan)):.3f} s, lat "
                     f"{np.degrees(s.get('latitude', 0)):.6f} deg, lon "
                     f"{np.degrees(s.get('longitude', 0)):.6f} deg, h {s.get('height', 0):.1f} m, "
                     f"v_ned [{v[0]:.3f}, {v[1]:.3f}, {v[2]:.3f}] m/s")
    lines += _recording_lines(meta)
    for name in sorted(k for k in meta if k.startswith("sensor/")):
        m = meta[name]
        lines.append(f"{name:<11} {m.get('model', '?')}, {m.get('sample_rate_hz', '?')} Hz, "
                     f"mounting {_mounting_text(m.get('mounting'))}, range "
                     f"{m.get('range') or 'not stated'}")
        p = m.get("platform") if isinstance(m.get("platform"), dict) else None
        if p:
            lines.append(f"{'':<11} on a rotation platform: {p.get('mode', '?')}, "
                         f"{np.degrees(float(p.get('rate_rad_s', np.nan))):.3g} deg/s, IMU "
                         f"inclined {np.degrees(float(p.get('inclination_rad', 0.0))):.3g} deg, "
                         f"{_lever_text(p.get('lever_arm_m'))}; angle on /mimu/platform")
    try:
        origin_ns = int(flight["epoch_unix_ns"])
    except (KeyError, TypeError, ValueError):
        origin_ns = None
    lines.append("channels" + (" (times in s since epoch_unix_ns)" if origin_ns is not None
                               else " (times in s since each channel's first stamp)"))
    for topic in sorted(log.channels):
        try:
            r = channel_report(log, topic, origin_ns)
        except ValueError as exc:
            lines.append(f"  {topic:<14} {log.schema_name(topic)}: {exc}")
            if unreadable is not None:
                unreadable.append(topic)
            continue
        text = f"  {topic:<14} {r['schema']:<28} {r['count']:>9} msgs"
        if "rate_hz" in r:
            text += f"  {r['rate_hz']:9.3f} Hz  {r['duration_s']:9.3f} s"
            problems = []
            if r.get("rates"):
                problems.append("the rate changes: " + ", ".join(
                    f"{hz:.4g} Hz from {t_s:.3f} s" for t_s, hz in r["rates"]))
            if r["gaps"]:
                problems.append(f"{len(r['gaps'])} gaps, {r['missing']} samples missing "
                                f"(first {r['gaps'][0][0]:.3f}-{r['gaps'][0][1]:.3f} s"
                                + (f"; {r['scheduled']}" if r.get("scheduled") else "") + ")")
            if r["jitter_ms"] > 0.05 * 1e3 / r["rate_hz"]:
                problems.append(f"stamp jitter {r['jitter_ms']:.2g} ms (robust sigma)")
            if r.get("dropped"):
                problems.append(f"{r['dropped']} dropped samples (first jump at "
                                f"{r['index_jumps'][0][0]:.3f} s)")
            if r["backwards"]:
                problems.append(f"time goes backwards {r['backwards']} times")
            if r["duplicates"]:
                problems.append(f"{r['duplicates']} duplicate stamps")
            if r.get("stamp_mismatch"):
                problems.append(f"{r['stamp_mismatch']} header stamps differ from log_time")
            text += "  " + ("; ".join(problems) if problems else "no gaps")
        lines.append(text)
    return "\n".join(lines)

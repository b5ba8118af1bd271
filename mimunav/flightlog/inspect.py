"""`mimunav info`: a log's channels, rates, gaps, dropped samples and metadata."""
import math

import numpy as np

from . import schemas
from ..kernels import njit


RATE_RUN = 200          # steps: a different sampling period held this long is a new rate
RATE_CHANGE = 0.05      # relative change of the period that makes a new rate (a logger
                        # switched from 100 to 118 Hz, 15 %, had been read as one rate with
                        # gaps; the block medians scatter ~3 % under +-3 ms of jitter at 100 Hz)


def rate_segments(t):
    """[(first stamp index, last stamp index, period ns)] of a channel whose sampling rate
    may change (a logger switched from 100 to 50 Hz): runs of at least RATE_RUN steps whose
    running-median period differs from the previous run's by more than RATE_CHANGE. One
    segment when the rate holds (jitter and gaps do not make a new rate)."""
    step = np.diff(np.asarray(t, np.int64)).astype(float)
    n = len(step)
    if n < 2 * RATE_RUN:
        return [(0, n, _period(step))]
    size = RATE_RUN // 2                      # medians of blocks of steps: jitter-proof
    blocks = np.median(step[:n // size * size].reshape(-1, size), axis=1)
    bounds, ref = [0], blocks[0]
    for j in range(1, len(blocks)):
        if abs(blocks[j] / ref - 1) > RATE_CHANGE and j * size - bounds[-1] >= RATE_RUN:
            bounds.append(j * size)
            ref = blocks[j]
    bounds.append(n)
    # a block astride a change holds both rates: merge runs of one rate, put each change
    # where the steps fit the two rates best, and merge again (a run astride a change
    # measured a rate between the two)
    merged = _merge_alike(step, bounds)
    log_step = np.log(np.maximum(step, 1.0))
    for i in range(1, len(merged) - 1):
        a, c, b = merged[i - 1], merged[i], merged[i + 1]
        la, lb = math.log(_period(step[a:c])), math.log(_period(step[c:b]))
        lo, hi = max(a + 1, c - RATE_RUN), min(b - 1, c + RATE_RUN)
        cost = [np.abs(log_step[lo:k] - la).sum() + np.abs(log_step[k:hi] - lb).sum()
                for k in range(lo, hi + 1)]
        merged[i] = lo + int(np.argmin(cost))
    merged = _merge_alike(step, merged)
    return [(a, b, _period(step[a:b])) for a, b in zip(merged[:-1], merged[1:])]


def _merge_alike(step, bounds):
    """The run bounds with each pair of neighbouring runs of one rate (periods within
    RATE_CHANGE) merged, and every run shorter than RATE_RUN steps (no rate by the
    definition) merged into the run before it."""
    merged = list(bounds)
    while len(merged) > 2:
        periods = [_period(step[a:b]) for a, b in zip(merged[:-1], merged[1:])]
        alike = [i for i in range(1, len(merged) - 1)
                 if abs(periods[i] / periods[i - 1] - 1) <= RATE_CHANGE
                 or merged[i + 1] - merged[i] < RATE_RUN]
        if not alike:
            break
        del merged[alike[0]]
    return merged


def _period(step):
    """Median step over many samples (jitter averages out), ns."""
    rel = np.concatenate([[0.0], np.cumsum(step)])
    span = max(1, min(100, len(step) // 10))
    return float(np.median((rel[span:] - rel[:-span]) / span))


def missing_samples(t, smoothing=0.02):
    """Gaps of a channel sampled at a nominal period T with jitter: [(index k, samples
    missing between stamps k and k + 1)]. T is the median step over many samples of each
    `rate_segments` run (a change of rate is no gap); each stamp is put in the next free
    slot of the sampling grid, whose phase is tracked as a running mean (weight
    `smoothing`) of the stamps' offsets from it, so a late stamp followed by an early one
    (jitter of 6-9 ms on a 10 ms period) stays in its slot and a clock slightly off is
    followed; slots left empty are the missing samples."""
    t = np.asarray(t, np.int64)
    out = []
    for a, b, period in rate_segments(t):
        if period <= 0:
            continue
        rel = (t[a:b + 1] - int(t[a])).astype(float)
        gaps = _empty_slots(rel, period, smoothing)
        # the period again as the span over its slots, until the slots hold: the median of
        # 100-step means takes lost samples into the period (2 % lost: 10.2 ms for 10, and
        # half of them missed); the span's steps cancel each other's jitter
        for _ in range(5):
            slots = len(rel) - 1 + int(gaps.sum())
            again = _empty_slots(rel, rel[-1] / slots, smoothing)
            if np.array_equal(again, gaps):
                break
            gaps = again
        out += [(int(a + k), int(gaps[k])) for k in np.flatnonzero(gaps)]
    return out


@njit()
def _empty_slots(rel, period, smoothing):
    """Per step k -> k + 1, the empty grid slots between the two stamps."""
    gaps = np.zeros(len(rel) - 1, np.int64)
    slot, phase = 0, 0.0
    for k in range(1, len(rel)):
        step = max(1, int(round((rel[k] - phase) / period)) - slot)
        gaps[k - 1] = step - 1
        slot += step
        phase += smoothing * (rel[k] - period * slot - phase)
    return gaps


def channel_report(log, topic, origin_ns=None):
    """dict: schema, count, rate_hz (median), duration_s, gaps [(t0, t1) s since origin_ns
    (the log's epoch; default the channel's first stamp), where samples are missing given
    the median rate - not sampling jitter; with the number missing in `missing`], dropped
    samples (sample_index jumps, at s since the same origin)."""
    msgs = log.read(topic)
    t = msgs["log_time"].astype(np.int64)
    rep = {"schema": log.schema_name(topic), "count": len(t)}
    if len(t) < 2:
        return rep
    step = np.diff(t)
    med = float(np.median(step))
    gaps = missing_samples(t)
    t0 = int(t[0]) if origin_ns is None else int(origin_ns)
    segments = rate_segments(t)
    if len(segments) > 1:
        rep["rates"] = [((t[a] - t0) / 1e9, 1e9 / period) for a, _, period in segments]
    nominal = np.concatenate([np.full(b - a, period) for a, b, period in segments])
    rep.update(rate_hz=1e9 / med, duration_s=(t[-1] - t[0]) / 1e9,
               start_ns=int(t[0]), gaps=[((t[k] - t0) / 1e9, (t[k + 1] - t0) / 1e9)
                                          for k, _ in gaps],
               missing=sum(n for _, n in gaps),
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
    from .. import attitude
    from ..sensors import Mounting
    try:
        m = Mounting.from_dict(doc or {})
    except (ValueError, TypeError):
        return f"{doc} (not readable)"
    yaw, pitch, roll = (float(np.degrees(a)) + 0.0 for a in attitude.as_euler(m.q_vs))
    return (f"roll/pitch/yaw [{roll:.2f}, {pitch:.2f}, {yaw:.2f}] deg, lever arm "
            f"{np.round(m.lever_arm_m, 3).tolist()} m")


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
                                f"(first {r['gaps'][0][0]:.3f}-{r['gaps'][0][1]:.3f} s)")
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

"""A `Recording` written as a contract log: `/mimu/imu` (calibrated units, not compensated
beyond the recorder's own scaling), `/truth/state` when an external reference exists
(attitude unknown: NaN quaternion, and `reference.attitude = "unknown"` in the metadata),
`/gnss/fix` (latitude and longitude in rad as the contract's conventions say - not ROS's
degrees - and position_covariance ENU m^2), the `flight` metadata with an `initial_state`
from `navigation.alignment.initial_alignment`, `sensor/mimu`, and `recording` (what is
real, what was assumed; the biases the alignment measured, sensor axes, and in words the
diagnosis reads: `initial_heading` reference | course | assumed, `initial_attitude`
reference | leveled | reference_level, `bias_basis` as `alignment.Alignment`'s).
"""
import json

import numpy as np

from ..navigation import alignment
from ..navigation.rest_biases import vertical_note
from ..flightlog import LogWriter
from ..flightlog import schemas as S
from ..sensors.accuracy import Accuracy
from .recording import UNKNOWN_ATTITUDE, heading_source
from ..flightlog.stamps import (longest_gap, mean_rate_hz, missing_samples, rate_segments,
                               scheduled)
from .checks import (differenced, reference_track, check_recording,
                     resting_upright, velocity_lag_s)
from .velocity_check import positions_velocity


WRITE_BLOCK_S = 10.0        # s: channels are written interleaved in blocks of this much time


def _reference_metadata(rec, known):
    """The `reference` metadata of rec's reference (`known`: it carries an attitude): its
    source, what it gives, and its velocity's lag behind its positions (s, positive: late)
    unless that velocity is their differences."""
    meta = {"source": rec.real.get("reference", "external"),
            "attitude": ("given by the reference (" + rec.reference_meta.get("source", "its "
                         "source") + ")" if known else "unknown"),
            "velocity": "given by the reference"}
    meta.update({k: str(v) for k, v in rec.reference_meta.items()})
    v_pos = positions_velocity(rec.reference)           # differenced once, used twice
    if differenced(rec.reference, v_pos):
        meta["velocity"] = "differenced from its positions (central differences)"
    elif (lag := velocity_lag_s(rec.reference, v_pos=v_pos)) is not None:
        meta["velocity_lag_s"] = f"{lag[0]:.4f}"
        meta["velocity_lag_se_s"] = f"{lag[1]:.4f}"
    return meta


def _recording_metadata(rec, align, assumed, heading, track):
    """The log's `recording` metadata record: what the import measured (`real`) and assumed,
    the alignment's biases (sensor axes: gyro rad/s, accelerometer m/s^2) and rest (s from
    the IMU's first stamp), the initial heading's source, and what the checks decided."""
    epoch = int(rec.imu_ns[0])
    return {"real": json.dumps(rec.real), "assumed": json.dumps(assumed),
            "gyro_bias_static_rad_s": list(map(float, align.gyro_bias)),
            "accel_bias_m_s2": list(map(float, align.accel_bias)),
            "static_s": (None if np.isnan(align.static[0]) else
                         [float(align.static[0]), float(align.static[1])]),
            "observed_max": {"gyro_rad_s": float(np.abs(rec.w).max()),
                             "accel_m_s2": float(np.abs(rec.f).max())},
            "initial_heading": heading, "initial_attitude": align.attitude_from,
            "bias_basis": align.bias_basis,
            "reference_heading_known": rec.reference_heading_known,
            "reference_imu_clock_se_s": rec.reference_imu_clock_se_s,
            "vehicle": rec.vehicle, "aliased": rec.aliased,
            "faces_course": None if track is None else track["faces_course"],
            "reference_imu_moved": rec.reference_imu_moved,
            "reference_imu_clock_open": rec.reference_imu_clock_open,
            "reference_clock_open": rec.reference_clock_open,
            "reference_clock_unapplied_s": rec.reference_clock_unapplied_s,
            "imu_point_off": rec.imu_point_off,
            "trajectory_point_off": rec.trajectory_point_off,
            "mounting_off_kept": rec.mounting_off_kept,
            "clip_spans_s": [[(a - epoch) / 1e9, (b - epoch) / 1e9, n]
                             for a, b, n in rec.clip_spans_ns]}


def write_log(rec, path, force=False):
    """Write `rec` as a contract log at `path` (atomically; an existing file only with
    force), after `check_recording`. Returns the initial alignment (`alignment.Alignment`)."""
    check_recording(rec)
    epoch = int(rec.imu_ns[0])
    t = (rec.imu_ns - epoch) / 1e9
    ref = rec.reference
    track = reference_track(rec, epoch)
    align = alignment.initial_alignment(t, rec.w, rec.f, rec.mounting, track)
    resting_upright(rec, align)
    initial = {"t": float(align.t), "latitude": float(align.lat), "longitude": float(align.lon),
               "height": float(align.h), "velocity_ned": list(map(float, align.v_ned)),
               "attitude_wxyz": list(map(float, align.q_nb))}
    assumed = dict(rec.assumed)
    assumed["initial_state"] = align.method
    heading = heading_source(align.heading, rec.reference_heading_known)
    if heading != align.heading:
        source = "attitude" if align.heading == "reference" else align.heading
        assumed["initial_heading"] = ("assumed: the reference lies in a local frame whose "
                                      "azimuth is not known, so the heading from its "
                                      f"{source} is no true heading")
    rate = rec.sample_rate_hz
    with LogWriter(path, force=force) as log:
        log.metadata("flight", {
            "format": "mimunav-log/1", "name": rec.name, "description": rec.description,
            "epoch_unix_ns": str(epoch), "source": "recording", "initial_state": initial})
        log.metadata("sensor/mimu", {
            "model": rec.model, "sample_rate_hz": f"{rate:.6g}",
            "mounting": rec.mounting.as_dict(), **({"range": rec.range} if rec.range else {})})
        log.metadata("recording", _recording_metadata(rec, align, assumed, heading, track))
        channels = [("/mimu/imu", S.IMU, "mimu", rec.imu_ns, S.imu_fields(rec.w, rec.f))]
        if rec.reference_imu is not None:
            ref_imu = rec.reference_imu
            fog = {"model": ref_imu.get("model", "unknown"),
                   "sample_rate_hz": f"{mean_rate_hz(ref_imu['ns']):.6g}",
                   "mounting": ref_imu["mounting"].as_dict()}
            if ref_imu.get("accuracy"):
                fog["accuracy"] = ref_imu["accuracy"]
            log.metadata("sensor/fog", fog)
            channels.append(("/fog/imu", S.IMU, "fog", ref_imu["ns"],
                             S.imu_fields(ref_imu["w"], ref_imu["f"])))
        if ref is not None:
            q = ref.get("q_nb")
            known = q is not None and np.isfinite(q).all(axis=1).any()
            log.metadata("reference", _reference_metadata(rec, known))
            channels.append(("/truth/state", S.NAV_STATE, "vehicle", ref["ns"], dict(
                latitude=ref["lat"], longitude=ref["lon"], height=ref["h"],
                velocity_ned=ref["v_ned"],
                attitude_wxyz=q if known else np.tile(UNKNOWN_ATTITUDE, (len(ref["ns"]), 1)))))
        if rec.fixes is not None:
            fx = rec.fixes
            log.metadata("gnss", {"latitude_longitude": "rad (log contract conventions)",
                                  "position_covariance": "m^2, ENU"})
            channels.append(("/gnss/fix", S.NAV_SAT_FIX, "gnss", fx["ns"], dict(
                status=fx["status"], service=np.ones(len(fx["ns"]), np.uint16),
                latitude=fx["lat"], longitude=fx["lon"], altitude=fx["h"],
                position_covariance=fx["covariance"],
                position_covariance_type=np.full(len(fx["ns"]), 2, np.uint8))))
        _write_interleaved(log, channels)
    return align


def _write_interleaved(log, channels, block_s=WRITE_BLOCK_S):
    """Write each channel (topic, schema, frame, stamps ns, fields) block_s of time at a time,
    all channels per block, so that a log cut short (a full disk, a copy stopped) keeps the
    reference and fixes up to the cut, not only the IMU."""
    lo = min(int(c[3][0]) for c in channels if len(c[3]))
    step = int(block_s * 1e9)
    # only the blocks that hold a sample (channels far apart in time leave long empty spans)
    blocks = np.unique(np.concatenate([(np.asarray(c[3], np.int64) - lo) // step
                                       for c in channels]))
    for start in (lo + blocks * step).tolist():
        for topic, schema, frame, ns, fields in channels:
            a, b = np.searchsorted(ns, [start, start + step])
            if b > a:
                log.write(topic, schema, frame, ns[a:b], **{k: v[a:b] for k, v in fields.items()})


def summary(rec, align, path):
    """What an import wrote and decided, line by line: the samples and their rates, what was
    assumed, the measured mounting yaw, the initial state and the biases the alignment took
    (rad/s shown in deg/s, m/s^2; sensor axes)."""
    runs = rate_segments(rec.imu_ns - rec.imu_ns[0])
    rates = " then ".join(f"{1e9 / p:.1f}" for _, _, p in runs) if len(runs) > 1 else \
        f"{rec.sample_rate_hz:.1f}"
    lines = [f"wrote {path}: {len(rec.imu_ns)} IMU samples at {rates} Hz"
             + (f", {len(rec.reference['ns'])} reference epochs" if rec.reference else "")
             + (f", {len(rec.fixes['ns'])} GNSS fixes" if rec.fixes else "")]
    lines += [f"assumed {key}: {value}" for key, value in rec.assumed.items()]
    gaps = missing_samples(rec.imu_ns)
    if gaps:
        t = (rec.imu_ns - rec.imu_ns[0]) / 1e9
        k = longest_gap(t, gaps)[0]
        lines.append(f"gaps: the IMU misses {sum(m for _, m in gaps)} samples in {len(gaps)} "
                     f"gaps (longest {t[k + 1] - t[k]:.3g} s at t = {t[k]:.3f} s)"
                     + (f"; {regular}" if (regular := scheduled(gaps)) else "")
                     + (f"; {rec.real['imu_time']}" if "misses" in rec.real.get("imu_time", "")
                        else ""))
    if "reference" in rec.real:
        lines.append(f"reference: {rec.real['reference']}")
    if "clipped" in rec.real:
        lines.append(f"clipped: {rec.real['clipped']}")
    if "mounting_yaw_against_course" in rec.real:
        lines.append(f"measured mounting yaw: {rec.real['mounting_yaw_against_course']}")
    if "reference_clock" in rec.real:
        lines.append(f"measured clock offset: {rec.real['reference_clock']}")
    if rec.reference_imu is not None:
        stated = rec.reference_imu.get("accuracy")
        accuracy = Accuracy.from_dict(stated, "stated to the import") if stated else Accuracy()
        lines.append(f"reference IMU accuracy: {accuracy.grade_said()}")
    for key in ("imu_stamps", "reference_imu_stamps", "imu_intervals",
                "reference_imu_intervals", "reference_imu_clock",
                "reference_imu_mounting", "reference_imu_lever_arm", "aliasing",
                "reference_attitude_rates", "mounting_against_attitude",
                "reference_point"):     # said too
        if key in rec.real:
            lines.append(f"measured {key.replace('_', ' ')}: {rec.real[key]}")
    lines += [f"warning: {why}" for why in rec.aliased.values()]
    lines += [f"warning: {why}" for why in (rec.imu_point_off, rec.trajectory_point_off) if why]
    if "reference_heading" in rec.real:
        lines.append(f"measured heading: {rec.real['reference_heading']}")
    if "vehicle" in rec.real:
        lines.append(f"warning: {rec.real['vehicle']}")
    if "course_checks" in rec.real:
        lines.append(f"course checks: {rec.real['course_checks']}")
    if "resting_tilt" in rec.real:
        lines.append(f"warning: {rec.real['resting_tilt']}")
    lines.append(f"initial state at t = {align.t:.3f} s: {align.method}")
    if np.isnan(align.static[0]) and np.any(align.gyro_bias):
        lines.append("biases from the reference's attitude and velocity (sensor axes): gyro "
                     + ", ".join(f"{np.degrees(b):+.4f}" for b in align.gyro_bias) + " deg/s, "
                     "accelerometer " + ", ".join(f"{b:+.4f}" for b in align.accel_bias)
                     + " m/s^2")
    elif np.isnan(align.static[0]):
        lines.append("gyro bias: not observed (no rest of 2 s in the recording)")
    else:
        lines.append(f"gyro bias at rest {align.static[0]:.1f}-{align.static[1]:.1f} s (sensor "
                     "axes) " + ", ".join(f"{np.degrees(b):+.4f}" for b in align.gyro_bias)
                     + " deg/s" + _rest_scatter(rec, align) + _about_the_vertical(rec, align))
    return lines


def _about_the_vertical(rec, align):
    """'' or what the rest says of its rate about the vertical (`rest_biases.vertical_note`:
    a bias the IMU alone cannot tell from a steady turn, or the reference's turn), where the
    initial state's words do not say it already."""
    t = (rec.imu_ns - rec.imu_ns[0]) / 1e9
    ref = rec.reference or {}
    track = {"t": (np.asarray(ref["ns"], np.int64) - rec.imu_ns[0]) / 1e9,
             "q_nb": np.asarray(ref["q_nb"], float)} if "q_nb" in ref else {}
    said = vertical_note(track, t, rec.w, rec.f, *align.static)
    return f"; {said[2:]}" if said and said not in align.method else ""


def _rest_scatter(rec, align):
    """' (95 % within ... deg/s ...)' of the rest's gyro bias: Student t over its 1 s means
    (a hand that sways at a stand moves it: a walker's 2 s rest had read a bias 0.38 deg/s
    off with no word; 1 s means, since a still unit's noise is white over them); '' with
    fewer than two seconds."""
    t = (rec.imu_ns - rec.imu_ns[0]) / 1e9
    edges = np.arange(align.static[0], align.static[1] + 1e-9, 1.0)
    means = [rec.w[k].mean(axis=0) for a in edges[:-1]
             if (k := (t > a) & (t <= a + 1.0)).any()]        # a second in a gap: none
    if len(means) < 2:
        return ""
    from scipy import stats
    half = stats.t.ppf(0.975, len(means) - 1) * np.std(means, axis=0, ddof=1) / np.sqrt(
        len(means))
    return " (95 % within " + ", ".join(f"{np.degrees(x):.2g}" for x in half) + \
        f" deg/s: Student t over its {len(means)} 1 s means)"

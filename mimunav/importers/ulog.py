"""PX4 ULog flight logs (read by pyulog): the IMU from `sensor_combined` and GNSS from
`vehicle_gps_position` (or `sensor_gps` in newer PX4); as reference, when the log has it, the
autopilot's own estimate (`vehicle_global_position` with the velocity of
`vehicle_local_position` and the attitude of `vehicle_attitude`) - labelled "autopilot
estimate, not independent": EKF2 fuses this very IMU, so it cannot show that IMU's errors
beyond what the filter leaves. Every `sensor_accel` / `sensor_gyro` instance is listed in the
metadata with its rate and temperature range; one may be imported as the IMU instead of
sensor_combined, another as the reference IMU.

PX4 conventions: sensor_combined holds gyro_rad (rad/s) and accelerometer_m_s2 (specific
force, m/s^2) in the vehicle body frame FRD (the board rotation applied), each the mean
over its integration interval, stamped in microseconds since boot. GNSS: lat/lon in 1e-7 deg
(or latitude_deg), alt_ellipsoid in mm (or altitude_ellipsoid_m), vel_n/e/d_m_s. The UNIX
time of boot comes from the GNSS's time_utc_usec; without it boot is put at the UNIX epoch
and the metadata says so.
"""
import os

import numpy as np

from ..frames.mounting import Mounting
from ..sensors.accuracy import AUTOPILOT_MEMS, AUTOPILOT_MEMS_SOURCE
from .clip_counts import clip_spans, clips_said, merged
from .recording import Recording, RecordingError, attitude_at, rate_onto
from ..errors import require

GNSS_TOPICS = ("vehicle_gps_position", "sensor_gps")
REFERENCE_TOPICS = ("vehicle_global_position", "vehicle_local_position", "vehicle_attitude")
INSTANCE_TOPICS = ("sensor_accel", "sensor_gyro")
CLIP_TOPICS = {"vehicle_imu_status": 0, "sensor_accel": 1, "sensor_gyro": 1, "sensor_combined": 2}
CLIP_FIELDS = [f"{s}_clipping[{i}]" for s in ("accel", "gyro") for i in range(3)] + [
    f"clip_counter[{i}]" for i in range(3)]


def _topic(ulog, name):
    found = [d for d in ulog.data_list if d.name == name]
    return min(found, key=lambda d: d.multi_id) if found else None


def _field(data, *names, scales=None):
    """The first of `names` the topic has, times its scale (default 1): newer and older PX4
    messages name and scale a quantity differently."""
    for k, name in enumerate(names):
        if name in data.data:
            return np.asarray(data.data[name], dtype=float) * (scales[k] if scales else 1.0)
    raise RecordingError(f"ULog topic {data.name} lacks {' / '.join(names)}")


def _instance(ulog, path, n):
    """(boot us (N,), w rad/s, f m/s^2 (N, 3) FRD, temperature text) of IMU instance n: its
    sensor_accel samples (timestamp_sample when logged), the sensor_gyro of the same instance
    interpolated linearly onto them (PX4 publishes the two on their own clocks). These are
    the board-rotated outputs before PX4's calibration (sensor_combined holds the calibrated
    ones of the instance the estimator uses)."""
    found = {d.name: d for d in ulog.data_list if d.name in INSTANCE_TOPICS and d.multi_id == n}
    if len(found) < 2:
        have = sorted({d.multi_id for d in ulog.data_list if d.name in INSTANCE_TOPICS})
        raise RecordingError(f"{path}: no sensor_accel and sensor_gyro of instance {n} "
                             f"(instances logged: {have})")
    stamp = lambda d: np.asarray(d.data.get("timestamp_sample", d.data["timestamp"]),  # noqa
                                 np.int64)
    acc, gyr = found["sensor_accel"], found["sensor_gyro"]
    t_a, t_g = stamp(acc), stamp(gyr)
    inside = (t_a >= t_g[0]) & (t_a <= t_g[-1])
    if inside.sum() < 2:
        raise RecordingError(f"{path}: sensor_accel and sensor_gyro of instance {n} do not "
                             "overlap in time")
    keep, w, gaps = rate_onto(t_a, t_g, np.column_stack([_field(gyr, c) for c in "xyz"]),
                              f"sensor_gyro:{n}", unit_s=1e-6)
    f = np.column_stack([_field(acc, c) for c in "xyz"])[keep]
    temps = [np.asarray(d.data["temperature"], float) for d in (acc, gyr)
             if "temperature" in d.data]
    temps = np.concatenate(temps) if temps else np.array([])
    temps = temps[np.isfinite(temps)]
    text = (f"temperature {temps.min():.2f} to {temps.max():.2f} degC" if len(temps)
            else "no temperature")
    return t_a[keep], w, f, text + (f"; {gaps}" if gaps else "")


def read(path, mounting=None, instance=None, reference_instance=None):
    """The recording of a PX4 ULog as a `Recording` (IMU in FRD body axes): the IMU from
    sensor_combined, or with `instance` from that sensor_accel / sensor_gyro instance
    (`_instance`); with `reference_instance` another instance is the reference IMU (two
    autopilot IMUs against each other: the sensor level of the diagnosis)."""
    ULog = require("pyulog", "import", "the ulog importer").ULog
    try:
        ulog = ULog(path, message_name_filter_list=["sensor_combined", *GNSS_TOPICS,
                                                    *REFERENCE_TOPICS, *INSTANCE_TOPICS,
                                                    "vehicle_imu_status"])
    except Exception as exc:            # pyulog raises its own and struct errors
        raise RecordingError(f"{path}: not a readable ULog ({exc})") from None
    if instance is None:
        imu = _topic(ulog, "sensor_combined")
        if imu is None:
            raise RecordingError(f"{path}: no sensor_combined topic")
        boot_us = np.asarray(imu.data["timestamp"], dtype=np.int64)
        w = np.column_stack([_field(imu, f"gyro_rad[{i}]") for i in range(3)])
        f = np.column_stack([_field(imu, f"accelerometer_m_s2[{i}]") for i in range(3)])
        source, topic = f"sensor_combined ({len(boot_us)} samples)", "sensor_combined"
    else:
        boot_us, w, f, temp = _instance(ulog, path, instance)
        source = (f"sensor_accel:{instance} with sensor_gyro:{instance} interpolated onto it "
                  f"({len(boot_us)} samples, {temp}; before PX4's calibration)")
        topic = f"sensor_accel/sensor_gyro instance {instance}"
    gps = next((g for g in (_topic(ulog, n) for n in GNSS_TOPICS) if g is not None), None)
    assumed = {}
    offset_us, fixes = _gnss(gps) if gps is not None else (0, None)
    if offset_us == 0:
        assumed["time"] = "no GNSS UTC time: boot placed at the UNIX epoch"
    keep = np.concatenate([[True], np.diff(boot_us) > 0])
    name = os.path.splitext(os.path.basename(path))[0]
    real = {"imu": source, "source": os.path.abspath(path), "imu_instances": instances(ulog)}
    second = None
    if reference_instance is not None:
        if reference_instance == instance:
            raise RecordingError(f"{path}: the reference IMU instance is the IMU's own")
        r_us, r_w, r_f, r_temp = _instance(ulog, path, reference_instance)
        r_keep = np.concatenate([[True], np.diff(r_us) > 0])
        second = dict(ns=(r_us[r_keep] + offset_us) * 1000, w=r_w[r_keep], f=r_f[r_keep],
                      mounting=Mounting(), model=f"PX4 IMU instance {reference_instance}",
                      accuracy=dict(AUTOPILOT_MEMS))
        assumed["reference_imu_accuracy"] = AUTOPILOT_MEMS_SOURCE
        real["reference_imu"] = (f"sensor_accel:{reference_instance} with sensor_gyro:"
                                 f"{reference_instance} ({int(r_keep.sum())} samples, {r_temp})")
    cut = cut_short(path)
    if cut:
        real["file"] = cut
    if fixes is not None:
        real["gnss"] = f"{gps.name} ({len(fixes['ns'])} 3-D fixes)"
    reference = autopilot_estimate(ulog, offset_us)
    if reference is not None:
        real["reference"] = ("PX4 EKF2 output: vehicle_global_position, vehicle_local_position "
                             f"velocity, vehicle_attitude ({len(reference['ns'])} epochs)")
    else:
        assumed["reference"] = unused_reference(ulog)
    assumed.update(mounting="PX4 body frame FRD = vehicle frame" if mounting is None
                   else "given on the command line",
                   calibration="PX4's on-board calibration, as logged" if instance is None
                   else "none: the instance's outputs before PX4's calibration (its CAL_* "
                        "offsets and scales are not applied), used as recorded")
    clips, topics = _clip_counts(ulog, None if instance is None else
                                 [instance, reference_instance])
    clips = [(a + offset_us * 1000, b + offset_us * 1000, n) for a, b, n in clips]
    if clips:
        real["clipped"] = clips_said(clips, f"PX4 ({topics})",
                                     (boot_us[keep][0] + offset_us) * 1000)
    rate = 1e6 / np.median(np.diff(boot_us[keep]))
    span = (boot_us[-1] - boot_us[0]) / 1e6
    return Recording(name, f"PX4 ULog {os.path.basename(path)}: {topic} {rate:.0f} Hz, "
                     f"{span:.1f} s", (boot_us[keep] + offset_us) * 1000,
                     w[keep], f[keep], mounting or Mounting(), model="PX4 autopilot IMU",
                     reference=reference,
                     reference_meta=({"source": "autopilot estimate (PX4 EKF2)",
                                      "independent": "no: the autopilot fuses this IMU"}
                                     if reference is not None else {}),
                     fixes=fixes, real=real, assumed=assumed, reference_imu=second,
                     clip_spans_ns=clips)


def _clip_counts(ulog, instances):
    """([(t0, t1 ns since boot, clips)] where a clip count of one of `instances` rose
    (`clip_counts`; None: of every instance, sensor_combined's being one of them), the
    topics and instances counted, said): of each instance the first of CLIP_TOPICS it logs - the running
    totals of vehicle_imu_status, the counts of each sensor_accel / sensor_gyro sample
    period (clip_counter, PX4's msg/SensorAccel.msg), sensor_combined's clipped axes of each
    sample (a bit an axis) -, so that one clip is counted once."""
    found = {}
    for d in ulog.data_list:
        rank = CLIP_TOPICS.get(d.name)
        wanted = instances is None or (d.multi_id in instances and d.name != "sensor_combined")
        if rank is not None and wanted and (totals := _clip_totals(d)) is not None:
            found.setdefault(d.multi_id, []).append((rank, d.name, d.data["timestamp"], totals))
    spans, topics, which = [], set(), set()
    for instance, each in found.items():
        first = min(rank for rank, *_ in each)
        for rank, name, us, totals in each:
            counted = clip_spans(us, totals) if rank == first else []
            spans += [(a * 1000, b * 1000, n) for a, b, n in counted]
            topics |= {name} if counted else set()
            which |= {instance} if counted else set()
    said = (f"{', '.join(sorted(topics))} of instance {', '.join(map(str, sorted(which)))}"
            + ("; sensor_combined's instance is not logged, so these may be another's"
               if instances is None else ""))
    return merged(spans), said


def _clip_totals(data):
    """(N, k) running clip totals of a topic of CLIP_TOPICS, None where it logs no count."""
    if data.name == "sensor_combined":
        bits = [np.asarray(data.data[k], np.uint8) for k in ("accelerometer_clipping",
                                                             "gyro_clipping") if k in data.data]
        return np.cumsum(sum(np.unpackbits(b[:, None], axis=1).sum(axis=1) for b in bits),
                         dtype=float) if bits else None
    fields = [k for k in CLIP_FIELDS if k in data.data]
    if not fields:
        return None
    counts = np.column_stack([np.asarray(data.data[k], float) for k in fields])
    return counts if data.name == "vehicle_imu_status" else np.cumsum(counts, axis=0)


def _gnss(gps):
    """(boot to UTC offset, us - 0 without UTC time; the 3-D fixes {ns, status, lat, lon rad,
    h m, covariance ENU m^2, v_ned m/s}) of a ULog GNSS topic."""
    offset_us = 0
    t_gps = np.asarray(gps.data["timestamp"], dtype=np.int64)
    utc = np.asarray(gps.data.get("time_utc_usec", np.zeros(len(t_gps))), dtype=np.int64)
    valid = utc > 0
    if valid.any():
        offset_us = int(np.median(utc[valid] - t_gps[valid]))
    lat = np.radians(_field(gps, "latitude_deg", "lat", scales=(1.0, 1e-7)))
    lon = np.radians(_field(gps, "longitude_deg", "lon", scales=(1.0, 1e-7)))
    h = _field(gps, "altitude_ellipsoid_m", "alt_ellipsoid", scales=(1.0, 1e-3))
    fix_type = _field(gps, "fix_type").astype(int)
    eph, epv = _field(gps, "eph"), _field(gps, "epv")
    good = fix_type >= 3
    cov = np.zeros((len(t_gps), 9))
    cov[:, 0] = cov[:, 4] = eph ** 2
    cov[:, 8] = epv ** 2
    ns = (t_gps + offset_us) * 1000
    fixes = dict(ns=ns[good], status=np.zeros(good.sum(), np.int8), lat=lat[good],
                 lon=lon[good], h=h[good], covariance=cov[good])
    fixes["v_ned"] = np.column_stack([_field(gps, f"vel_{c}_m_s") for c in "ned"])[good]
    return offset_us, fixes


def cut_short(path):
    """'' when the ULog's messages fill the file exactly, else what is missing: the file
    ends inside a message (a logger that lost power or a copy cut short). pyulog reads such
    a file silently up to its last whole message. Format (PX4 docs, ULog File Format): a
    16-byte header (magic 'ULog' 0x01 0x12 0x35, version, uint64 timestamp), then messages of
    uint16 size, uint8 type and `size` bytes; a walk over the headers, no payload decoded."""
    with open(path, "rb") as fh:
        data = fh.read()
    k, n = 16, len(data)
    while k + 3 <= n:
        size = data[k] | data[k + 1] << 8
        if k + 3 + size > n:
            break
        k += 3 + size
    if k == n:
        return ""
    return (f"the file ends inside a message at byte {k} of {n} ({n - k} bytes of a "
            "partial message left out): the log was cut short, and ends at its last whole "
            "message")


def instances(ulog):
    """{topic:instance: 'N samples at R Hz, temperature a-b degC'} of every sensor_accel and
    sensor_gyro instance (the IMUs behind sensor_combined)."""
    out = {}
    for d in sorted((d for d in ulog.data_list if d.name in INSTANCE_TOPICS),
                    key=lambda d: (d.name, d.multi_id)):
        t = np.asarray(d.data["timestamp"], float) / 1e6
        rate = (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 and t[-1] > t[0] else 0.0
        text = f"{len(t)} samples at {rate:.3g} Hz"
        if "temperature" in d.data:
            temp = np.asarray(d.data["temperature"], float)
            temp = temp[np.isfinite(temp)]
            if len(temp):
                text += f", temperature {temp.min():.2f} to {temp.max():.2f} degC"
        out[f"{d.name}:{d.multi_id}"] = text
    return out


def unused_reference(ulog):
    """Why the log gives no reference trajectory: which of REFERENCE_TOPICS it has and lacks
    (a logged attitude or local position without a global position is not used)."""
    have = [n for n in REFERENCE_TOPICS if _topic(ulog, n) is not None]
    missing = [n for n in REFERENCE_TOPICS[:2] if n not in have]
    return (f"none: the log has {', '.join(have) or 'none of ' + ', '.join(REFERENCE_TOPICS)}"
            f" but not {' and '.join(missing)}; the reference trajectory needs the autopilot's "
            "global position and local velocity (an attitude alone is not used)")


def autopilot_estimate(ulog, offset_us):
    """The autopilot's trajectory on the epochs of vehicle_global_position: lat, lon (rad),
    h (m, ellipsoidal), v_ned (m/s, vehicle_local_position vx/vy/vz interpolated), q_nb (wxyz,
    vehicle_attitude q, body FRD -> NED, by slerp; NaN outside its span); None when the log
    has no global position or no local velocity."""
    pos, loc = _topic(ulog, "vehicle_global_position"), _topic(ulog, "vehicle_local_position")
    if pos is None or loc is None or len(pos.data["timestamp"]) < 2:
        return None
    t = np.asarray(pos.data["timestamp"], np.int64)
    h = _field(pos, "alt_ellipsoid", "alt")
    t_loc = np.asarray(loc.data["timestamp"], float)
    v = np.column_stack([np.interp(t, t_loc, _field(loc, c)) for c in ("vx", "vy", "vz")])
    q = np.full((len(t), 4), np.nan)
    att = _topic(ulog, "vehicle_attitude")
    if att is not None and len(att.data["timestamp"]) >= 2:
        q = attitude_at(t, np.asarray(att.data["timestamp"], float),
                        np.column_stack([_field(att, f"q[{i}]") for i in range(4)]))
    return dict(ns=(t + offset_us) * 1000, lat=np.radians(_field(pos, "lat")),
                lon=np.radians(_field(pos, "lon")), h=h, v_ned=v, q_nb=q)

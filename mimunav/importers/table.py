"""Any logger's columns - CSV or NumPy arrays - described by a TOML spec, as a `Recording`.

    mimunav import table SPEC.toml -o OUT.mcap

The spec names each quantity's file (and columns), its unit and its time base; nothing is
guessed. Paths are relative to `root` (default: the spec's folder; `mimunav import table
--root DIR` overrides it). A column source is either
a path string or a table:

    { file = "imu.csv", columns = ["gx", "gy", "gz"], unit = "deg/s", scale = 0.01,
      time = <column source> }

`columns` picks CSV columns by header name or 0-based index, or NumPy columns by index
(default: all); `file` may be a glob pattern ("oxts/data/*.txt": a file per epoch, their rows
in the order of their names). `rows = {MessageType = "UncalAccel"}` keeps only the rows
whose text in that CSV column is that (or one of a list; a headerless file's column by its
0-based index, `rows = {1 = "3"}`: NCLT's RTK fixes only): a logger writing several sensors'
rows to one file (Android GnssLogger's) - such a file is refused without it. `scale`
multiplies the column before its unit converts it (a logger's counts: a time in ticks of
10 us is `unit = "us", scale = 10`; a gyro in 0.01 deg/s steps is `unit = "deg/s", scale =
0.01`; one scale per column gives a logger's own signs: a roll rate
positive left wing down is `scale = [-1, 1, 1]` of the triad's FRD columns). `offset` is then
added, in the column's unit (one number, or one per column): KITTI's roll, pitch (positive
nose down) and yaw (from east, counter-clockwise) are attitude_rpy's with `unit = "rad",
scale = [1, -1, -1], offset = [0, 0, 1.5707963267948966]`. A time column's
`age` (a column source in a time unit) is the data's age when its row was written (a packet
that arrived late): it is subtracted. `time` overrides the section's time for that quantity (e.g. a
gyro on its own clock: it is interpolated linearly onto the specific force's stamps, and the
metadata says so). A CSV may start with Excel's `sep=;` line (its separator then: , ; tab |);
a text table of numbers separated by spaces (KITTI's, TUM's) is read as such, its lines
starting with '#' before the data comments - the last of them its header when it names every
column ('# timestamp tx ty tz qx qy qz qw');
rows that repeat the row before them (a logger writing a sample twice) are left out and
counted; a repeated time with other values is refused. Every key is checked: an unknown one is
refused, naming the nearest known one.

    name, description, model     text
    root                         folder of the data files
    nonfinite = "refuse"         or "drop": rows with a NaN/inf cell are left out and counted
                                 (a logger's missed reading), instead of refusing the table
    vehicle                      what carried the IMU (`importers.kinds.VEHICLES`: car, ...)
    [imu]     time               device time of the samples
              angular_rate       rad/s | deg/s                      (N, 3), sensor axes
              specific_force     m/s^2 | g                          (N, 3), sensor axes
              or angle_increment rad | deg, velocity_increment m/s: each sample's increment
                                 over the interval its stamp ends (divided by that interval)
              axes               required (or mounting_rpy_deg): the vehicle directions of
                                 sensor x, y, z, e.g. "FRD" (`Mounting.from_axes`)
              or mounting_rpy_deg = [roll, pitch, yaw]; lever_arm_m = [x, y, z] (vehicle FRD)
              range              the sensor's full scale: {angular_rate = {value = 2000,
                                 unit = "deg/s"}, specific_force = {value = 16, unit = "g"}}
                                 (a bare number: SI): outputs at it are counted as clipped, and
                                 the log's sensor/mimu range says it
              time_offset_s      added to this section's device time (also in [reference],
                                 [reference_imu]): a second clock's offset
              sampling = "interval_mean" (default: each sample the mean over the interval
                                 its stamp ends, as the log contract says) or "instant" (the
                                 value at its stamp, as most loggers sample: the stamps move
                                 half an interval later)
    [time] (required; a logger without UTC states unix_offset_s = 0: its clock's epoch)
              unix_offset_s      UNIX time = device time + offset (s), or
              gps_week_tow       {file, time}: rows of (GPS week, time of week s) stamped in
                                 device time; the offset is their median difference, the GPS -
                                 UTC leap seconds of that date removed
    [reference_imu] (optional)   a better IMU flown with it, the reference IMU (/fog/imu: the
              diagnosis' sensor level): time, angular_rate, specific_force, axes or
              mounting_rpy_deg as [imu]; model text; accuracy = {gyro_scale = 1e-4, ...}
              (1-sigma, keys of `sensors.accuracy.Accuracy`: gyro_scale, accel_scale (1),
              gyro_misalignment_rad, accel_misalignment_rad (rad), gyro_bias (rad/s),
              accel_bias (m/s^2) - its bias stability -, gyro_step (rad/s), accel_step
              (m/s^2) - the step its outputs were logged in (a value written with 2
              decimals: 0.01); checked at import; default: seed S1 Table 4's FOG-IMU, the
              steps measured from the outputs where they sit on one)
    [reference] (optional)
              time               device time of the epochs
              latitude, longitude  deg | rad;  height  m (ellipsoidal)   or  position_ecef m
              or position_local  m | mm | ft: x, y, z in a local level frame (a motion-capture
                                 room's, a map frame), placed on the Earth by
              local_frame = {axes = "enu" | "ned" | "z_up" | "z_down",
                             origin = [lat_deg, lon_deg, h_m] (the frame's origin, ellipsoidal
                             height: it sets gravity and the Earth rate's direction),
                             azimuth_deg = x's azimuth from true north, clockwise (z_up and
                             z_down only: y completes a right-handed frame), or "unknown" -
                             then the reference's heading measures nothing, and no finding
                             stands on it}
              or position_utm    m: easting, northing and ellipsoidal height on a UTM grid
                                 (WGS-84), its source naming it: {file, columns, zone = 1-60,
                                 hemisphere = "N" | "S"} (`frames.utm`)
              velocity_ned  m/s  or  velocity_ecef  m/s  (else central differences of position)
              or velocity_local  m/s in the local frame's axes
              or ground_speed  m/s | km/h | kn  with  course  deg | rad from true north,
                                 clockwise (a receiver's speed and course over ground, NMEA
                                 RMC, a phone's Location): north and east from them, down
                                 from the heights' central differences; where either is
                                 negative (iOS's "invalid", -1) or empty, the positions'
                                 differences for that epoch
              attitude_wxyz      unit quaternions with `rotates` = "body_to_ecef" | "body_to_ned"
                                 (| "body_to_local", the default beside position_local; |
                                 "body_to_utm", the grid's east, north, up, the default beside
                                 position_utm: turned by the grid's convergence); the body is
                                 the vehicle's FRD axes, or an IMU's own (attitude_of)
              or attitude_matrix 1: the rotation matrix's nine elements R11 R12 R13 R21 ... R33,
                                 the first row first (a 3x4 pose [R | t] row by row: columns
                                 [0, 1, 2, 4, 5, 6, 8, 9, 10]), `rotates` as attitude_wxyz's
              body_axes          the vehicle directions of the attitude's body x, y, z
                                 (default "FRD"; a ROS or KAIST body "FLU", a camera "RDF")
              or attitude_rpy    deg | rad: roll, pitch, yaw of body -> NED (yaw, then pitch,
                                 then roll: the aerospace z-y-x sequence); beside
                                 position_local, of body -> a local frame whose z is down
              attitude_of        "vehicle" (default), "reference_imu": the attitude is the
                                 reference IMU's own axes' (an INS's solution), so a turn
                                 measured between the two IMUs is the IMU's mounting; or "imu":
                                 the MIMU's own axes' and point (a motion-capture truth of the
                                 IMU), turned into the vehicle's by [imu]'s mounting
              source, independent ("yes" / "no: why"), position_sigma_m   text for the metadata
                                 (position_sigma_m's leading number, m, 1 sigma horizontal, is
                                 the position error `mimunav windows` allows for)

Units: s, ms, us, ns, iso8601 (a CSV column of date-times with their UTC offset,
'2023-08-04 17:47:58.125-04:00' or '2023-08-04T21:47:58.125Z', or without one and the
source's `zone = "Z"` or "+02:00": UNIX time, so [time] unix_offset_s = 0); rad/s, deg/s;
m/s^2, g (9.80665); deg, rad; m, mm, ft; m/s.
"""
import os

import numpy as np

from ..errors import InputError
from ..frames import attitude
from ..flightlog.stamps import mean_rate_hz
from ..frames.mounting import Mounting
from ..motion.intervals import means_of_instants
from ..sensors.accuracy import Accuracy
from .columns import check_keys
from .recording import Recording, RecordingError, at_range, rate_onto
from .series import increment_intervals
from .table_reference import reference_of
from .table_spec import KINDS, RANGE_KEYS, UNITS, Spec, unix_ns, unix_offset_s, unrepeated

SAMPLING = ("interval_mean", "instant")      # what an IMU section's samples are (`_sampled`)
# what the [reference] attitude is of: the vehicle's axes, the reference IMU's (an INS's
# solution: `pairing` measures the MIMU's mounting against it) or the MIMU's own
ATTITUDE_OF = ("vehicle", "reference_imu", "imu")


def _mounting(spec, section="imu"):
    imu = spec.section(section)
    lever = imu.get("lever_arm_m", (0.0, 0.0, 0.0))
    if "mounting_rpy_deg" in imu:
        return Mounting.from_rpy_deg(imu["mounting_rpy_deg"], lever), \
            f"roll/pitch/yaw {imu['mounting_rpy_deg']} deg (spec)"
    if "axes" in imu:
        return Mounting.from_axes(imu["axes"], lever), f"sensor axes {imu['axes']} (spec)"
    raise RecordingError(f"{spec.path}: [{section}] needs axes (e.g. \"FRD\") or "
                         "mounting_rpy_deg")


def _imu(spec, section):
    """(device time s, w rad/s, f m/s^2) of an IMU section ([imu] or [reference_imu]): rates
    and specific forces, or increments divided by their intervals; the angular rate on its
    own clock interpolated onto the specific force's stamps; rows that repeat the one before
    left out."""
    path = spec.path
    rate_key = _one_of(spec, section, "angular_rate", "angle_increment")
    force_key = _one_of(spec, section, "specific_force", "velocity_increment")
    t_f, f = spec.time_of(section, force_key), spec.column(section, force_key)
    t_w, w = spec.time_of(section, rate_key), spec.column(section, rate_key)
    for name, t, x in ((force_key, t_f, f), (rate_key, t_w, w)):
        if len(t) != len(x):
            raise RecordingError(f"{path}: [{section}] {name} has {len(x)} rows, its time "
                                 f"{len(t)}")
    if len(t_w) == len(t_f) and np.array_equal(t_w, t_f, equal_nan=True):     # one clock
        t_f, f, w = spec.finite_rows(f"[{section}]", t_f, f, w)
        t_f, f, w = unrepeated(spec, f"[{section}]", t_f, f, w)
        t_w = t_f
    else:
        t_f, f = unrepeated(spec, f"[{section}] {force_key}",
                             *spec.finite_rows(f"[{section}] {force_key}", t_f, f))
        t_w, w = unrepeated(spec, f"[{section}] {rate_key}",
                             *spec.finite_rows(f"[{section}] {rate_key}", t_w, w))
    dt_f = None
    if force_key == "velocity_increment":
        dt_f, said = increment_intervals(t_f, f)
        if said:
            spec.notes[f"{section}_intervals"] = said
        f = _per_second(t_f, f, dt_f)
    if rate_key == "angle_increment":       # on the force's clock, the force's intervals
        one_clock = len(t_w) == len(t_f) and np.array_equal(t_w, t_f)
        w = _per_second(t_w, w, dt_f if one_clock else None)
    if len(t_w) != len(t_f) or np.any(t_w != t_f):
        if np.any(np.diff(t_w) <= 0):
            raise RecordingError(f"{path}: [{section}] {rate_key} times do not increase")
        inside = (t_f >= t_w[0]) & (t_f <= t_w[-1])
        if inside.sum() < 2:
            raise RecordingError(f"{path}: the angular rate's times ({t_w[0]:.6g} .. "
                                 f"{t_w[-1]:.6g} s) and the specific force's ({t_f[0]:.6g} .. "
                                 f"{t_f[-1]:.6g} s) of [{section}] do not overlap: are both "
                                 "time units right?")
        keep, w, gaps = rate_onto(t_f, t_w, w, f"[{section}] {rate_key}")
        t_f, f = t_f[keep], f[keep]
        spec.notes[f"{section}_time"] = ("angular rate interpolated linearly onto the specific "
                                         "force's stamps" + (f"; {gaps}" if gaps else ""))
    return _sampled(spec, section, t_f, w, f, (rate_key, force_key))


def _sampled(spec, section, t, w, f, keys):
    """(t s, w rad/s, f m/s^2) of an IMU section as the log contract means them - each sample
    the mean over the interval its stamp ends: a logger's instantaneous samples (`sampling =
    "instant"`) become the means of the intervals centred on them
    (`intervals.means_of_instants`; outputs at the section's range stay as recorded), and
    their stamps move half a median interval later (read as means they lead by it: a 200 Hz
    IMU by 2.5 ms, which the diagnosis then measures as a time skew)."""
    sampling = spec.section(section).get("sampling", "interval_mean")
    if sampling not in SAMPLING:
        raise RecordingError(f"{spec.path}: [{section}] sampling {sampling!r}: "
                             + " or ".join(f'"{k}"' for k in SAMPLING))
    if sampling == "interval_mean":
        return t, w, f
    if any(k.endswith("increment") for k in keys):
        raise RecordingError(f"{spec.path}: [{section}] sampling = \"instant\" belongs to "
                             "rates and specific forces: an increment is over its interval")
    half = 0.5 * float(np.median(np.diff(t)))
    spec.notes[f"{section}_sampling"] = (
        f"instantaneous samples: each made the mean of the interval centred on it (x[k-1] + "
        f"22 x[k] + x[k+1]) / 24 and stamped {half * 1e3:.4g} ms later, at that interval's "
        "end")
    clipped = at_range(w, f, sensor_range(spec, section))
    return (t + half, means_of_instants(t, w, clipped), means_of_instants(t, f, clipped))


def _one_of(spec, section, rate, increment):
    """The key the section gives for a quantity: its rate or its increment (not both)."""
    given = [k for k in (rate, increment) if spec.has(section, k)]
    if len(given) != 1:
        raise RecordingError(f"{spec.path}: [{section}] needs {rate} or {increment}"
                             + (" - not both" if len(given) == 2 else "") + (
                                 GYROS_ALONE if section == "reference_imu" and not given and
                                 rate == "specific_force" else ""))
    return given[0]


GYROS_ALONE = (": the sensor level predicts the IMU's accelerometers from the reference "
               "IMU's too, and a reference of gyros alone (a FOG's angle increments without "
               "accelerometers) is not read yet - leave [reference_imu] out and diagnose "
               "against [reference]'s trajectory (the track level for a car, else the "
               "navigation level)")


def _per_second(t, x, dt=None):
    """Increments x over the intervals their stamps t (s) end, divided by those intervals
    (`dt`, s, when decided otherwise: `increment_intervals`; the first sample's by the median
    interval)."""
    stamped = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
    if np.any(stamped <= 0):
        raise RecordingError(f"increments' times do not increase (at row "
                             f"{int(np.argmax(stamped <= 0))})")
    return x / (stamped if dt is None else dt)[:, None]


def sensor_range(spec, section="imu"):
    """The section's `range` as the log's sensor range {gyro_rad_s, accel_m_s2} (SI), or {}."""
    given = spec.section(section).get("range")
    if given is None:
        return {}
    if not isinstance(given, dict):
        raise RecordingError(f"{spec.path}: [{section}] range must be a table of "
                             f"{', '.join(RANGE_KEYS)}")
    check_keys(spec.path, given, RANGE_KEYS, f"[{section}] range")
    out = {}
    for key, name in (("angular_rate", "gyro_rad_s"), ("specific_force", "accel_m_s2")):
        if key not in given:
            continue
        value = given[key]
        unit = KINDS[key][0]
        if isinstance(value, dict):
            check_keys(spec.path, value, ("value", "unit"), f"[{section}] range.{key}")
            value, unit = value.get("value"), value.get("unit", unit)
        if unit not in KINDS[key] or not isinstance(value, (int, float)) or \
                isinstance(value, bool) or not (np.isfinite(value) and value > 0):
            raise RecordingError(f"{spec.path}: [{section}] range.{key}: a positive number "
                                 f"in {', '.join(KINDS[key])}")
        out[name] = float(value) * UNITS[unit]
    return out


def clipped_note(w, f, rng):
    """What the outputs say of the sensor's range: how many samples sit at it (`at_range`),
    or ''."""
    at = at_range(w, f, rng)
    if not at.any():
        return ""
    beyond = [f"{name} to {peak / rng[key]:.3g} times it" for x, key, name in (
        (w, "gyro_rad_s", "the rates"), (f, "accel_m_s2", "the specific forces"))
        if key in rng and (peak := float(np.abs(x).max())) > RANGE_PAST * rng[key]]
    return (f"{int(at.sum())} samples at the range given or within 0.1 % of it on some axis "
            "(clipped by the sensor's own limit, or about to be: the diagnosis leaves them out "
            "of every test, no finding)" + (
                f"; but {' and '.join(beyond)} reach beyond it: that range is not the one the "
                "outputs were clipped at (another setting of the part, or outputs calibrated "
                "past its rails) - check it" if beyond else ""))


RANGE_PAST = 1.01       # of the range given: outputs beyond it (a Shimmer's calibrated gyro
#                         to 1.46 times a 500 deg/s range) say the range is not the sensor's


def _rate_hz(t):
    """The sample rate (Hz) of stamps t (s) as the log's metadata states it
    (`flightlog.stamps.mean_rate_hz`: a phone's jittered 100 Hz read 100.1 by its median
    step where `info` said 100.000)."""
    return mean_rate_hz(np.round((t - t[0]) * 1e9).astype(np.int64))


def read(path, mounting=None, root=None):
    """The recording a table spec describes, as a `Recording`; root: the folder of its data
    files instead of the spec's `root`."""
    spec = Spec(path, root)
    offset = unix_offset_s(spec)
    t_f, w, f = _imu(spec, "imu")
    notes = spec.notes
    given = mounting is not None
    spec_mounting, how = _mounting(spec)
    if given and not np.any(mounting.lever_arm_m):  # a rotation given (--mounting-rpy-deg):
        mounting = Mounting(mounting.attitude_wxyz, spec_mounting.lever_arm_m)  # the spec's arm
    mounting = mounting or spec_mounting
    reference, frame = reference_of(spec, offset)
    rng = sensor_range(spec)
    meta = {k: v for k, v in spec.section("reference").items()
            if k in ("source", "independent", "position_sigma_m", "attitude_of")}
    if frame is not None:
        meta["frame"] = frame.description
    if "attitude_rpy" in spec.section("reference"):     # what a wrong attitude may be
        meta["attitude_as"] = ("columns' order (attitude_rpy: roll, pitch, yaw of body -> "
                               "NED, turned by yaw, then pitch, then roll) or unit")
    if "attitude_matrix" in spec.section("reference"):
        meta["attitude_as"] = ("matrix layout (attitude_matrix: R11 R12 R13 R21 ... row by "
                               "row; a column-major one is its transpose, the rotation the "
                               "other way), its rotates or body_axes")
    second, ref_how = None, None
    if spec.section("reference_imu"):
        t_r, w_r, f_r = _imu(spec, "reference_imu")
        ref_mounting, ref_how = _mounting(spec, "reference_imu")
        section = spec.section("reference_imu")
        if "accuracy" in section:               # refused now, not at the diagnosis
            Accuracy.from_dict(section["accuracy"], f"{spec.path}: [reference_imu] accuracy")
        second = dict(ns=unix_ns(spec, t_r, offset, "[reference_imu] time"), w=w_r, f=f_r,
                      mounting=ref_mounting, model=section.get("model", "unknown"),
                      accuracy=section.get("accuracy"),
                      mounting_hint="mounting_rpy_deg = [{roll}, {pitch}, {yaw}] in the spec's "
                                    "[reference_imu]")
        notes["reference_imu"] = (f"{len(t_r)} samples at {_rate_hz(t_r):.4g} "
                                  f"Hz ({section.get('model', 'model not stated')})")
    _to_the_vehicles_attitude(spec, meta, reference, mounting, second)
    name = spec.doc.get("name", os.path.splitext(os.path.basename(path))[0])
    real = {"imu": f"{len(t_f)} samples at {_rate_hz(t_f):.4g} Hz from {spec.root}",
            "source": spec.doc.get("source", spec.root), "spec": spec.path, **notes}
    if clipped_note(w, f, rng):
        real["clipped"] = clipped_note(w, f, rng)
    if reference is not None:
        real["reference"] = f"{meta.get('source', 'reference columns')} " \
                            f"({len(reference['ns'])} epochs)"
    assumed = {"mounting": (f"given on the command line, the lever arm "
                            f"{mounting.lever_arm_m.tolist()} m the spec's") if given else how,
               "time": spec.section("time").get("note", "as the spec's [time] says"),
               "calibration": "none: the outputs are used as recorded"}
    if ref_how:
        assumed["reference_imu_mounting"] = ref_how
    return Recording(name, spec.doc.get("description", f"table import of {spec.path}"),
                     unix_ns(spec, t_f, offset, "[imu] time"), w, f, mounting,
                     model=spec.doc.get("model", "unknown"), reference=reference,
                     reference_meta=meta, real=real, assumed=assumed, reference_imu=second,
                     vehicle=spec.doc.get("vehicle"), range=rng,
                     reference_heading_known=frame is None or frame.azimuth_known,
                     reference_imu_offset_given="time_offset_s" in spec.section(
                         "reference_imu"),
                     sampled_at_instants=spec.section("imu").get("sampling") == "instant")


def _to_the_vehicles_attitude(spec, meta, reference, mounting, second):
    """The reference attitude (`reference` q_nb, in place) of the vehicle's axes, where
    [reference] attitude_of says it is of an IMU's own axes: q_nv = q_ns q_vs^-1, q_vs that
    IMU's mounting (sensor -> vehicle). "imu": the MIMU's, whose point the reference then is
    (a lever arm would place it elsewhere: refused); "reference_imu": the reference IMU's
    (`pairing` then turns the MIMU against it, not it)."""
    of = meta.get("attitude_of", "vehicle")
    if of not in ATTITUDE_OF:
        raise RecordingError(f"{spec.path}: [reference] attitude_of {of!r}: "
                             + " or ".join(f'"{k}"' for k in ATTITUDE_OF))
    body = spec.section("reference").get("body_axes")
    if body is not None and of != "vehicle":
        raise RecordingError(f"{spec.path}: [reference] body_axes names the vehicle's axes the "
                             f"attitude is of; attitude_of = {of!r} says they are that IMU's "
                             "own, which its mounting turns: one of them")
    if of == "vehicle":
        if body is not None and reference is not None and "q_nb" in reference:
            try:
                q_vb = Mounting.from_axes(body).q_vs    # the attitude's body -> vehicle FRD
            except InputError as exc:
                raise RecordingError(f"{spec.path}: [reference] body_axes: {exc}") from None
            reference["q_nb"] = attitude.as_wxyz(attitude.from_wxyz(reference["q_nb"])
                                                 * np.conjugate(q_vb))
            meta["attitude_axes"] = f"the vehicle's, given as {body} (body_axes)"
        return
    if of == "reference_imu" and second is None:
        raise RecordingError(f"{spec.path}: [reference] attitude_of = \"reference_imu\" needs "
                             "a [reference_imu] section (the IMU whose axes the attitude is of)")
    imu = mounting if of == "imu" else second["mounting"]
    if of == "imu" and np.any(imu.lever_arm_m != 0):
        raise RecordingError(f"{spec.path}: [reference] attitude_of = \"imu\": the reference "
                             "is the MIMU's own point, so its lever_arm_m must be 0 (it is "
                             f"{[float(x) for x in imu.lever_arm_m]} m)")
    if reference is not None and "q_nb" in reference:
        q_ns = attitude.from_wxyz(reference["q_nb"])
        reference["q_nb"] = attitude.as_wxyz(q_ns * np.conjugate(imu.q_vs))
        meta["attitude_axes"] = (f"the {'MIMU' if of == 'imu' else 'reference IMU'}'s own "
                                 "(attitude_of), turned into the vehicle's by its mounting")

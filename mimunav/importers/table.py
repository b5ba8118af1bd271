"""Any logger's columns - CSV or NumPy arrays - described by a TOML spec, as a `Recording`.

    mimunav import table SPEC.toml -o OUT.mcap

The spec names each quantity's file (and columns), its unit and its time base; nothing is
guessed. Paths are relative to `root` (default: the spec's folder; `mimunav import table
--root DIR` overrides it). A column source is either
a path string or a table:

    { file = "imu.csv", columns = ["gx", "gy", "gz"], unit = "deg/s", scale = 0.01,
      time = <column source> }

`columns` picks CSV columns by header name or 0-based index, or NumPy columns by index
(default: all). `scale` multiplies the column before its unit converts it (a logger's counts:
a time in ticks of 10 us is `unit = "us", scale = 10`; a gyro in 0.01 deg/s steps is
`unit = "deg/s", scale = 0.01`; one scale per column gives a logger's own signs: a roll rate
positive left wing down is `scale = [-1, 1, 1]` of the triad's FRD columns). A time column's
`age` (a column source in a time unit) is the data's age when its row was written (a packet
that arrived late): it is subtracted. `time` overrides the section's time for that quantity (e.g. a
gyro on its own clock: it is interpolated linearly onto the specific force's stamps, and the
metadata says so). A CSV may start with Excel's `sep=;` line (its separator then: , ; tab |);
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
              axes = "FRD"       vehicle direction of sensor x, y, z (`Mounting.from_axes`)
              or mounting_rpy_deg = [roll, pitch, yaw]; lever_arm_m = [x, y, z] (vehicle FRD)
              range              the sensor's full scale: {angular_rate = {value = 2000,
                                 unit = "deg/s"}, specific_force = {value = 16, unit = "g"}}
                                 (a bare number: SI): outputs at it are counted as clipped, and
                                 the log's sensor/mimu range says it
              time_offset_s      added to this section's device time (also in [reference],
                                 [reference_imu]): a second clock's offset
    [time]    unix_offset_s      UNIX time = device time + offset (s), or
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
              velocity_ned  m/s  or  velocity_ecef  m/s  (else central differences of position)
              attitude_wxyz      unit quaternions with `rotates` = "body_to_ecef" | "body_to_ned"
              or attitude_rpy    deg | rad: roll, pitch, yaw of body -> NED (yaw, then pitch,
                                 then roll: the aerospace z-y-x sequence)
              attitude_of        "vehicle" (default) or "reference_imu": the attitude is the
                                 reference IMU's own axes' (an INS's solution), so a turn
                                 measured between the two IMUs is the IMU's mounting
              source, independent ("yes" / "no: why"), position_sigma_m   text for the metadata

Units: s, ms, us, ns, iso8601 (a CSV column of date-times with their UTC offset,
'2023-08-04 17:47:58.125-04:00' or '2023-08-04T21:47:58.125Z': UNIX time, so [time]
unix_offset_s = 0); rad/s, deg/s; m/s^2, g (9.80665); deg, rad; m, mm, ft; m/s.
"""
import os
import tomllib

import numpy as np
import quaternion

from ..frames import earth
from ..frames.mounting import Mounting
from ..sensors.accuracy import Accuracy
from .columns import check_keys, load_date_times, load_spec
from .recording import RecordingError, Recording, gps_to_unix_s, text_file
from ..motion.track import velocity_from_positions
from ..frames import attitude

G_UNIT = 9.80665
UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "rad/s": 1.0,
         "deg/s": np.pi / 180, "m/s^2": 1.0, "g": G_UNIT, "rad": 1.0, "deg": np.pi / 180,
         "m": 1.0, "mm": 1e-3, "ft": 0.3048, "m/s": 1.0, "1": 1.0, "iso8601": 1.0}
KINDS = {"time": ("s", "ms", "us", "ns", "iso8601"), "angular_rate": ("rad/s", "deg/s"),
         "specific_force": ("m/s^2", "g"), "angle_increment": ("rad", "deg"),
         "velocity_increment": ("m/s",), "latitude": ("deg", "rad"), "longitude": ("deg", "rad"),
         "height": ("m", "mm", "ft"), "position_ecef": ("m",), "velocity_ned": ("m/s",),
         "velocity_ecef": ("m/s",), "attitude_wxyz": ("1",), "attitude_rpy": ("deg", "rad")}
WIDTH = {"angular_rate": 3, "specific_force": 3, "angle_increment": 3, "velocity_increment": 3,
         "position_ecef": 3, "velocity_ned": 3, "velocity_ecef": 3, "attitude_wxyz": 4,
         "attitude_rpy": 3}
# every key a spec may hold, by where it stands (an unknown one is refused, the nearest named)
IMU_KEYS = ("time", "angular_rate", "specific_force", "angle_increment", "velocity_increment",
            "axes", "mounting_rpy_deg", "lever_arm_m", "range", "time_offset_s")
SECTION_KEYS = {
    "": ("name", "description", "model", "source", "root", "nonfinite", "vehicle", "imu", "time",
         "reference", "reference_imu"),
    "imu": IMU_KEYS, "reference_imu": IMU_KEYS + ("model", "accuracy"),
    "time": ("unix_offset_s", "gps_week_tow", "note"),
    "reference": ("time", "latitude", "longitude", "height", "position_ecef", "velocity_ned",
                  "velocity_ecef", "attitude_wxyz", "attitude_rpy", "attitude_of", "source",
                  "independent", "position_sigma_m", "time_offset_s")}
SOURCE_KEYS = ("file", "columns", "unit", "scale", "time", "rotates", "age")
RANGE_KEYS = ("angular_rate", "specific_force")
ELSEWHERE = {**{key: "in a column source ({file = ..., " + key + " = ...})" for key in SOURCE_KEYS},
             **{key: "in [" + section + "]" for section, keys in reversed(SECTION_KEYS.items())
                if section for key in keys},
             **{key: "at the spec's top level, beside `name`" for key in SECTION_KEYS[""]}}


class Spec:
    """A parsed table spec: `column(section, key)` loads a quantity in SI units."""

    def __init__(self, path, root=None):
        self.path = os.path.abspath(path)
        try:
            with open(path, "rb") as fh, text_file(path):
                self.doc = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise RecordingError(f"{path}: not a valid TOML spec ({exc})") from None
        if root is None:
            root = os.path.join(os.path.dirname(self.path), self.doc.get("root", "."))
            if not os.path.isdir(root):
                raise RecordingError(f"{path}: its data folder (root = "
                                     f"{self.doc.get('root', '.')!r}, relative to the spec) "
                                     f"is {os.path.normpath(root)}, which does not exist: "
                                     "give the folder with --root")
        elif not os.path.isdir(root):
            raise RecordingError(f"--root {root}: "
                                 + ("a file, not a folder" if os.path.exists(root) else
                                    "no such folder"))
        self.root = os.path.normpath(os.path.abspath(root))
        self.notes = {}             # what reading the files left out, for the metadata
        for section in ("imu", "time"):
            if not isinstance(self.doc.get(section), dict):
                raise RecordingError(f"{path}: no [{section}] section (its keys: "
                                     f"{', '.join(SECTION_KEYS[section])}; every key of a "
                                     "spec: mimunav import --spec-keys)")
        check_keys(self.path, self.doc, SECTION_KEYS[""], "the spec", ELSEWHERE)
        for section, keys in SECTION_KEYS.items():
            if section and isinstance(self.doc.get(section), dict):
                check_keys(self.path, self.doc[section], keys, f"[{section}]", ELSEWHERE)

    def section(self, name):
        return self.doc.get(name) or {}

    def has(self, section, key):
        return key in self.section(section)

    def column(self, section, key):
        """The quantity `key` of `section` in SI units, (N,) or (N, width)."""
        source = self.section(section).get(key)
        if source is None:
            raise RecordingError(f"{self.path}: [{section}] has no {key}")
        return self.load(source, key, f"[{section}] {key}")

    def load(self, source, kind, where):
        """A column source (path string or {file, columns, unit}) of quantity `kind`, SI."""
        if isinstance(source, str):
            source = {"file": source}
        if not isinstance(source, dict) or "file" not in source:
            raise RecordingError(f"{self.path}: {where} needs a file")
        check_keys(self.path, source, SOURCE_KEYS, where, ELSEWHERE)
        unit = source.get("unit", KINDS[kind][0])
        if unit not in KINDS[kind]:
            raise RecordingError(f"{self.path}: {where} unit {unit!r}: one of "
                                 f"{', '.join(KINDS[kind])} (a count of another size: `scale`)")
        width = WIDTH.get(kind, 1)
        scale = _scale(self.path, source.get("scale", 1.0), width, where)
        x = self._date_times(source, where) if unit == "iso8601" else \
            load_spec(os.path.join(self.root, source["file"]), source.get("columns"), self.notes)
        if width == 1 and x.ndim == 2 and x.shape[1] == 1:
            x = x[:, 0]
        if (x.ndim == 1 and width != 1) or (x.ndim == 2 and x.shape[1] != width) or x.ndim > 2:
            raise RecordingError(f"{self.path}: {where} from {source['file']} has shape "
                                 f"{x.shape}, expected {width} column(s)")
        if np.isnan(x).all():
            raise RecordingError(f"{self.path}: {where} from {source['file']} holds no number in "
                                 "any row: a column of text (ISO 8601 date-times such as "
                                 "2023-08-04 17:47:58-04:00 are read with unit = \"iso8601\", "
                                 "UNIX time: [time] unix_offset_s = 0)")
        if not np.isfinite(x).all() and self.doc.get("nonfinite", "refuse") != "drop":
            raise RecordingError(f"{self.path}: {where} from {source['file']} holds values that "
                                 f"are not finite (first at data row "
                                 f"{int(np.argmax(~np.isfinite(x.reshape(len(x), -1)).all(1)))}"
                                 ", counted from 0 after any header line); `nonfinite = "
                                 "\"drop\"` at the spec's top level, beside `name`, leaves such "
                                 "rows out (and counts them)")
        x = x * (UNITS[unit] * scale)
        if "age" in source:             # the data's age when the row was written: its time
            if kind != "time":          # is the row's less the age
                raise RecordingError(f"{self.path}: {where}: `age` belongs to a time column")
            age = self.load(source["age"], "time", f"{where}.age")
            if len(age) != len(x):
                raise RecordingError(f"{self.path}: {where}.age has {len(age)} rows, the time "
                                     f"{len(x)}")
            x = x - age
        return x

    def _date_times(self, source, where):
        """UNIX time (s) of a column of ISO 8601 date-times (`unit = "iso8601"`)."""
        columns = source.get("columns", [0])
        columns = columns if isinstance(columns, list) else [columns]
        if len(columns) != 1 or source.get("scale", 1.0) != 1.0:
            raise RecordingError(f"{self.path}: {where}: date-times are one column, unscaled")
        return load_date_times(os.path.join(self.root, source["file"]), columns[0])

    def finite_rows(self, where, *columns):
        """The columns (equal lengths) with every row that is not finite in any of them left
        out, and counted in `notes` (only `nonfinite = "drop"` lets such values through
        `load`)."""
        ok = np.ones(len(columns[0]), bool)
        for x in columns:
            ok &= np.isfinite(np.reshape(x, (len(x), -1))).all(axis=1)
        if ok.sum() < 2:
            raise RecordingError(f"{self.path}: {where}: {int(ok.sum())} of {len(ok)} rows are "
                                 "finite in every column (nonfinite = \"drop\" left the rest "
                                 "out): nothing to import")
        if not ok.all():
            self.notes[f"nonfinite {where}"] = (f"{int((~ok).sum())} of {len(ok)} rows not "
                                                "finite: left out (nonfinite = \"drop\")")
        return tuple(x[ok] for x in columns)

    def time_of(self, section, key):
        """Device time (s) of quantity `key`: its own `time`, else its section's, plus the
        section's time_offset_s."""
        source = self.section(section).get(key)
        if isinstance(source, dict) and "time" in source:
            t = self.load(source["time"], "time", f"[{section}] {key}.time")
        else:
            t = self.column(section, "time")
        offset = self.section(section).get("time_offset_s", 0.0)
        if not isinstance(offset, (int, float)) or isinstance(offset, bool) or \
                not np.isfinite(offset):
            raise RecordingError(f"{self.path}: [{section}] time_offset_s {offset!r}: a number "
                                 "of seconds")
        return t + offset


def _scale(path, scale, width, where):
    """A source's `scale`: one non-zero number, or one per column (a logger's own signs: a
    roll rate positive left wing down is `scale = [-1, 1, 1]` of an FRD triad)."""
    values = scale if isinstance(scale, list) else [scale]
    if len(values) not in (1, width) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) and v != 0
            for v in values):
        raise RecordingError(f"{path}: {where} scale {scale!r}: a finite non-zero number (the "
                             f"column's step in its unit), or {width} of them, one per column")
    return np.asarray(values, float) if len(values) > 1 else float(values[0])


def unix_offset_s(spec):
    """UNIX time minus device time, s, from the [time] section."""
    section = spec.section("time")
    if "unix_offset_s" in section:
        return float(section["unix_offset_s"])
    if "gps_week_tow" in section:
        src = section["gps_week_tow"]
        rows = load_spec(os.path.join(spec.root, src["file"]), src.get("columns"))
        device = spec.load(src.get("time"), "time", "[time] gps_week_tow.time")
        if rows.ndim != 2 or rows.shape[1] != 2 or len(rows) != len(device):
            raise RecordingError(f"{spec.path}: gps_week_tow needs (N, 2) rows of (week, time of "
                                 f"week) and N device times; got {rows.shape}, {device.shape}")
        gps_s = rows[:, 0] * 604800.0 + rows[:, 1]
        return float(np.median(gps_to_unix_s(gps_s) - device))
    raise RecordingError(f"{spec.path}: [time] needs unix_offset_s or gps_week_tow")


def unix_ns(spec, t, offset, where):
    """UNIX ns of device times t (s) + offset; refused beyond 1970-2100 (a time column in ns
    or us declared as s, or an offset in the wrong unit) instead of overflowing int64."""
    unix = np.asarray(t, float) + offset
    if len(unix) and not (0.0 <= unix.min() and unix.max() < 4.1e9):
        raise RecordingError(f"{spec.path}: {where} + the [time] offset reaches "
                             f"{unix.min():.4g} .. {unix.max():.4g} s since 1970, outside "
                             "1970-2100: is the time column's unit (s, ms, us, ns) right?")
    return np.round(unix * 1e9).astype(np.int64)


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


def reference_of(spec, offset):
    """The [reference] section as a Recording's reference dict, or None."""
    if not spec.section("reference"):
        return None
    keys = ["time"] + [k for k in ("position_ecef", "latitude", "longitude", "height",
                                   "velocity_ned", "velocity_ecef", "attitude_wxyz",
                                   "attitude_rpy") if spec.has("reference", k)]
    if "attitude_wxyz" in keys and "attitude_rpy" in keys:
        raise RecordingError(f"{spec.path}: [reference] gives attitude_wxyz and attitude_rpy: "
                             "one of them")
    if "position_ecef" in keys:
        keys = [k for k in keys if k not in ("latitude", "longitude", "height")]
    else:
        missing = [k for k in ("latitude", "longitude", "height") if k not in keys]
        if missing:
            raise RecordingError(f"{spec.path}: [reference] has no {', '.join(missing)} "
                                 "(give latitude, longitude and height, or position_ecef)")
    own = [k for k in keys[1:] if isinstance(spec.section("reference")[k], dict)
           and "time" in spec.section("reference")[k]]      # quantities on their own clock
    keys = [k for k in keys if k not in own]
    columns = [spec.time_of("reference", "time")] + [spec.column("reference", k)
                                                     for k in keys[1:]]
    n = len(columns[0])
    for key, x in zip(keys, columns):
        if len(x) != n:
            raise RecordingError(f"{spec.path}: [reference] {key} has {len(x)} rows, time {n}")
    col = dict(zip(keys, _unrepeated(spec, "[reference]",
                                     *spec.finite_rows("[reference]", *columns),
                                     names=keys[1:])))
    for key in own:
        col[key] = _onto(spec, key, col["time"])
    if own:                             # epochs beyond what the own clocks cover: left out
        inside = np.isfinite(np.column_stack([col[k] for k in own])).all(axis=1)
        if inside.sum() < 2:
            raise RecordingError(f"{spec.path}: [reference] {', '.join(own)} on their own "
                                 "clocks do not cover the reference's times")
        col = {k: x[inside] for k, x in col.items()}
    t = col["time"]
    if "position_ecef" in col:
        lat, lon, h = earth.ecef_to_geodetic(col["position_ecef"])
    else:
        lat, lon, h = col["latitude"], col["longitude"], col["height"]
    v = None
    if "velocity_ned" in col:
        v = col["velocity_ned"]
    elif "velocity_ecef" in col:
        v = np.einsum("kji,kj->ki", earth.ned_to_ecef_matrix(lat, lon), col["velocity_ecef"])
    ns = unix_ns(spec, t, offset, "[reference] time")
    back = np.flatnonzero(np.diff(ns) <= 0)
    if len(back):
        raise RecordingError(f"{spec.path}: [reference] time does not increase at data row "
                             f"{back[0] + 1} (0-based, after the header; {len(back)} such rows):"
                             " sort the reference by time or drop its repeated rows")
    if v is None:
        v = velocity_from_positions(ns, lat, lon, h)
    ref = dict(ns=ns, lat=lat, lon=lon, h=h, v_ned=v)
    if "attitude_wxyz" in col:
        ref["q_nb"] = _attitude_ned(spec, col["attitude_wxyz"], lat, lon)
    if "attitude_rpy" in col:           # roll, pitch, yaw of body -> NED (z-y-x turns)
        rpy = col["attitude_rpy"]
        ref["q_nb"] = attitude.as_wxyz(attitude.from_euler(rpy[:, 2], rpy[:, 1], rpy[:, 0]))
    ok = np.isfinite(ref["v_ned"]).all(axis=1)      # differenced velocity: none across a gap
    return {k: x[ok] for k, x in ref.items()}


def _onto(spec, key, t):
    """[reference] quantity `key` on its own clock, interpolated linearly onto the times t
    (s) - a box's pressure altitude beside a receiver's packets; NaN where it does not cover
    them."""
    t_k, x = _unrepeated(spec, f"[reference] {key}", *spec.finite_rows(
        f"[reference] {key}", spec.time_of("reference", key), spec.column("reference", key)))
    if len(t_k) < 2 or np.any(np.diff(t_k) <= 0):
        raise RecordingError(f"{spec.path}: [reference] {key}'s own times must increase")
    outside = (t < t_k[0]) | (t > t_k[-1])
    spec.notes[f"reference_{key}_time"] = (
        f"{key} interpolated linearly onto the reference's times"
        + (f"; {int(outside.sum())} epochs beyond its span left out" if outside.any() else ""))
    x2 = np.reshape(x, (len(x), -1))
    out = np.column_stack([np.interp(t, t_k, x2[:, i]) for i in range(x2.shape[1])])
    out[outside] = np.nan
    return out[:, 0] if x.ndim == 1 else out


def _attitude_ned(spec, wxyz, lat, lon):
    """The reference attitude `wxyz` (its spec's `rotates`) as q_nb (body -> NED, wxyz)."""
    q = attitude.from_wxyz(wxyz)
    rotates = spec.section("reference")["attitude_wxyz"].get("rotates", "body_to_ned")
    if rotates == "body_to_ned":
        q_nb = q
    elif rotates == "body_to_ecef":
        q_en = quaternion.from_rotation_matrix(earth.ned_to_ecef_matrix(lat, lon))
        q_nb = np.conjugate(q_en) * q
    else:
        raise RecordingError(f"{spec.path}: attitude rotates {rotates!r}: body_to_ned or "
                             "body_to_ecef")
    return attitude.as_wxyz(q_nb)


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
        t_f, f, w = _unrepeated(spec, f"[{section}]", t_f, f, w)
        t_w = t_f
    else:
        t_f, f = _unrepeated(spec, f"[{section}] {force_key}",
                             *spec.finite_rows(f"[{section}] {force_key}", t_f, f))
        t_w, w = _unrepeated(spec, f"[{section}] {rate_key}",
                             *spec.finite_rows(f"[{section}] {rate_key}", t_w, w))
    f = _per_second(t_f, f) if force_key == "velocity_increment" else f
    w = _per_second(t_w, w) if rate_key == "angle_increment" else w
    if len(t_w) != len(t_f) or np.any(t_w != t_f):
        if np.any(np.diff(t_w) <= 0):
            raise RecordingError(f"{path}: [{section}] {rate_key} times do not increase")
        inside = (t_f >= t_w[0]) & (t_f <= t_w[-1])
        if inside.sum() < 2:
            raise RecordingError(f"{path}: the angular rate's times ({t_w[0]:.6g} .. "
                                 f"{t_w[-1]:.6g} s) and the specific force's ({t_f[0]:.6g} .. "
                                 f"{t_f[-1]:.6g} s) of [{section}] do not overlap: are both "
                                 "time units right?")
        t_f, f = t_f[inside], f[inside]
        w = np.column_stack([np.interp(t_f, t_w, w[:, i]) for i in range(3)])
        spec.notes[f"{section}_time"] = ("angular rate interpolated linearly onto the specific "
                                         "force's stamps")
    return t_f, w, f


def _one_of(spec, section, rate, increment):
    """The key the section gives for a quantity: its rate or its increment (not both)."""
    given = [k for k in (rate, increment) if spec.has(section, k)]
    if len(given) != 1:
        raise RecordingError(f"{spec.path}: [{section}] needs {rate} or {increment}"
                             + (" - not both" if len(given) == 2 else ""))
    return given[0]


def _per_second(t, x):
    """Increments x over the intervals their stamps t (s) end, divided by those intervals (the
    first sample's by the median interval)."""
    dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
    if np.any(dt <= 0):
        raise RecordingError(f"increments' times do not increase (at row "
                             f"{int(np.argmax(dt <= 0))})")
    return x / dt[:, None]


def _unrepeated(spec, where, t, *columns, names=None):
    """The rows with each row that repeats the one before it left out and counted in the
    notes: the same values within half the median step of time (a logger that wrote a sample
    twice; stamped twice in whole ms, or by its data's age, its times may differ by a tick);
    a repeated time with other values is refused (which of the two is the sample?)."""
    if len(t) < 2:
        return (t, *columns)
    step = np.diff(t)
    same = np.concatenate([[False], np.abs(step) < 0.5 * np.median(step)])
    for x in columns:
        flat = np.reshape(x, (len(x), -1))
        same &= np.concatenate([[False], (flat[1:] == flat[:-1]).all(axis=1)])
    clash = np.concatenate([[False], step == 0]) & ~same
    if clash.any():
        k = int(np.argmax(clash))
        differ = [n for n, x in zip(names or [], columns)
                  if not np.array_equal(np.reshape(x[k], -1), np.reshape(x[k - 1], -1))]
        hint = (f" Only {', '.join(differ)} differ{'s' if len(differ) == 1 else ''}: a column "
                "of another clock (its own `time = {...}` in the spec interpolates it onto "
                "these times)" if differ and len(differ) < len(columns) else
                " Drop one of them")
        raise RecordingError(f"{spec.path}: {where} repeats the time {t[k]:.6g} s at data row {k} "
                             "(0-based, after the header) with other values: which is the "
                             f"sample?{hint}")
    if not same.any():
        return (t, *columns)
    spec.notes[f"repeated {where}"] = (f"{int(same.sum())} rows repeating the row before "
                                       "(within half a step): left out")
    keep = ~same
    return (t[keep], *(x[keep] for x in columns))


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
    """What the outputs say of the sensor's range: how many samples sit at it (within 0.1 %)
    on some axis, or ''."""
    at = np.zeros(len(w), bool)
    for x, key in ((w, "gyro_rad_s"), (f, "accel_m_s2")):
        if key in rng:
            at |= (np.abs(x) >= 0.999 * rng[key]).any(axis=1)
    if not at.any():
        return ""
    return (f"{int(at.sum())} samples at the range given (clipped: the diagnosis tests them "
            "as saturation)")


def read(path, mounting=None, root=None):
    """The recording a table spec describes, as a `Recording`; root: the folder of its data
    files instead of the spec's `root`."""
    spec = Spec(path, root)
    offset = unix_offset_s(spec)
    t_f, w, f = _imu(spec, "imu")
    notes = spec.notes
    given = mounting is not None
    spec_mounting, how = _mounting(spec)
    mounting = mounting or spec_mounting
    reference = reference_of(spec, offset)
    rng = sensor_range(spec)
    meta = {k: v for k, v in spec.section("reference").items()
            if k in ("source", "independent", "position_sigma_m", "attitude_of")}
    if meta.get("attitude_of", "vehicle") not in ("vehicle", "reference_imu"):
        raise RecordingError(f"{spec.path}: [reference] attitude_of {meta['attitude_of']!r}: "
                             "\"vehicle\" or \"reference_imu\"")
    name = spec.doc.get("name", os.path.splitext(os.path.basename(path))[0])
    rate = 1.0 / np.median(np.diff(t_f))
    real = {"imu": f"{len(t_f)} samples at {rate:.4g} Hz from {spec.root}",
            "source": spec.doc.get("source", spec.root), "spec": spec.path, **notes}
    if clipped_note(w, f, rng):
        real["clipped"] = clipped_note(w, f, rng)
    if reference is not None:
        real["reference"] = f"{meta.get('source', 'reference columns')} " \
                            f"({len(reference['ns'])} epochs)"
    assumed = {"mounting": "given on the command line" if given else how,
               "time": spec.section("time").get("note", "as the spec's [time] says"),
               "calibration": "none: the outputs are used as recorded"}
    second = None
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
        real["reference_imu"] = (f"{len(t_r)} samples at {1.0 / np.median(np.diff(t_r)):.4g} "
                                 f"Hz ({section.get('model', 'model not stated')})")
        assumed["reference_imu_mounting"] = ref_how
    return Recording(name, spec.doc.get("description", f"table import of {spec.path}"),
                     unix_ns(spec, t_f, offset, "[imu] time"), w, f, mounting,
                     model=spec.doc.get("model", "unknown"), reference=reference,
                     reference_meta=meta, real=real, assumed=assumed, reference_imu=second,
                     vehicle=spec.doc.get("vehicle"), range=rng)

"""A table spec (`importers.table`) parsed: its keys checked, each column source loaded in SI
units on its section's device time, the time bases, and a logger's repeated rows.
"""
import os
import tomllib

import numpy as np

from .columns import check_keys, load_date_times, load_spec
from .recording import RecordingError, gps_to_unix_s, text_file

G_UNIT = 9.80665
UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "rad/s": 1.0,
         "deg/s": np.pi / 180, "m/s^2": 1.0, "g": G_UNIT, "rad": 1.0, "deg": np.pi / 180,
         "m": 1.0, "mm": 1e-3, "ft": 0.3048, "m/s": 1.0, "km/h": 1 / 3.6, "kn": 1852 / 3600,
         "1": 1.0, "iso8601": 1.0}
KINDS = {"time": ("s", "ms", "us", "ns", "iso8601"), "angular_rate": ("rad/s", "deg/s"),
         "specific_force": ("m/s^2", "g"), "angle_increment": ("rad", "deg"),
         "velocity_increment": ("m/s",), "latitude": ("deg", "rad"), "longitude": ("deg", "rad"),
         "height": ("m", "mm", "ft"), "position_ecef": ("m",), "velocity_ned": ("m/s",),
         "velocity_ecef": ("m/s",), "attitude_wxyz": ("1",), "attitude_rpy": ("deg", "rad"),
         "position_local": ("m", "mm", "ft"), "velocity_local": ("m/s",),
         "ground_speed": ("m/s", "km/h", "kn"), "course": ("deg", "rad"),
         "position_utm": ("m",), "attitude_matrix": ("1",)}
WIDTH = {"angular_rate": 3, "specific_force": 3, "angle_increment": 3, "velocity_increment": 3,
         "position_ecef": 3, "velocity_ned": 3, "velocity_ecef": 3, "attitude_wxyz": 4,
         "attitude_rpy": 3, "position_local": 3, "velocity_local": 3, "position_utm": 3,
         "attitude_matrix": 9}
# every key a spec may hold, by where it stands (an unknown one is refused, the nearest named)
IMU_KEYS = ("time", "angular_rate", "specific_force", "angle_increment", "velocity_increment",
            "axes", "mounting_rpy_deg", "lever_arm_m", "range", "time_offset_s", "sampling")
SECTION_KEYS = {
    "": ("name", "description", "model", "source", "root", "nonfinite", "vehicle", "imu", "time",
         "reference", "reference_imu"),
    "imu": IMU_KEYS, "reference_imu": IMU_KEYS + ("model", "accuracy"),
    "time": ("unix_offset_s", "gps_week_tow", "note"),
    "reference": ("time", "latitude", "longitude", "height", "position_ecef", "velocity_ned",
                  "velocity_ecef", "attitude_wxyz", "attitude_rpy", "attitude_of", "source",
                  "independent", "position_sigma_m", "time_offset_s", "position_local",
                  "velocity_local", "local_frame", "ground_speed", "course", "position_utm",
                  "attitude_matrix", "body_axes")}
SOURCE_KEYS = ("file", "columns", "unit", "scale", "offset", "time", "rotates", "age",
               "zone", "rows", "hemisphere")
FRAME_KEYS = ("axes", "origin", "azimuth_deg")          # [reference] local_frame = {...}
RANGE_KEYS = ("angular_rate", "specific_force")
ELSEWHERE = {**{key: "in [reference] local_frame = {" + key + " = ...}" for key in FRAME_KEYS},
             **{key: "in a column source ({file = ..., " + key + " = ...})" for key in SOURCE_KEYS},
             **{key: "in [" + section + "]" for section, keys in reversed(SECTION_KEYS.items())
                if section for key in keys},
             **{key: "at the spec's top level, beside `name`" for key in SECTION_KEYS[""]}}


MAY_BE_EMPTY = ("ground_speed", "course")   # a receiver leaves them empty where it has no
#   fix of them (Android's Location.csv at a standstill: hasBearing false): read as not
#   given - for that epoch, the velocity of the positions' differences (`table_reference`)

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
        offset = _scale(self.path, source.get("offset", 0.0), width, where, "offset")
        if "zone" in source and unit != "iso8601" and kind != "position_utm":
            raise RecordingError(f"{self.path}: {where}: `zone` belongs to date-times "
                                 "(unit = \"iso8601\") and to position_utm")
        x = self._date_times(source, where) if unit == "iso8601" else \
            load_spec(os.path.join(self.root, source["file"]), source.get("columns"), self.notes,
                      source.get("rows"))
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
        empty = ~np.isfinite(x) if kind in MAY_BE_EMPTY else np.zeros(np.shape(x), bool)
        x = np.where(empty, 0.0, x)     # an empty cell: not given, as a negative value is
        if not np.isfinite(x).all() and self.doc.get("nonfinite", "refuse") != "drop":
            raise RecordingError(f"{self.path}: {where} from {source['file']} holds values that "
                                 f"are not finite (first at data row "
                                 f"{int(np.argmax(~np.isfinite(x.reshape(len(x), -1)).all(1)))}"
                                 ", counted from 0 after any header line); `nonfinite = "
                                 "\"drop\"` at the spec's top level, beside `name`, leaves such "
                                 "rows out (and counts them)")
        x = np.where(empty, -1.0, (x * scale + offset) * UNITS[unit])   # (after its scale
        #                                 and offset: a course from east had read 91 deg there)
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
        return load_date_times(os.path.join(self.root, source["file"]), columns[0],
                               source.get("zone"), source.get("rows"))

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


def _scale(path, scale, width, where, key="scale"):
    """A source's `scale`: one non-zero number, or one per column (a logger's own signs: a
    roll rate positive left wing down is `scale = [-1, 1, 1]` of an FRD triad); with key
    "offset", its `offset` (any finite numbers, 0 allowed)."""
    values = scale if isinstance(scale, list) else [scale]
    if len(values) not in (1, width) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
            and (v != 0 or key == "offset") for v in values):
        raise RecordingError(f"{path}: {where} {key} {scale!r}: a finite "
                             + ("non-zero number (the column's step in its unit)"
                                if key == "scale" else "number in the column's unit")
                             + f", or {width} of them, one per column")
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
    raise RecordingError(f"{spec.path}: [time] needs unix_offset_s or gps_week_tow (a logger "
                         "without UTC: unix_offset_s = 0, its own clock as the epoch)")


def unix_ns(spec, t, offset, where):
    """UNIX ns of device times t (s) + offset; refused beyond 1970-2100 (a time column in ns
    or us declared as s, or an offset in the wrong unit) instead of overflowing int64."""
    unix = np.asarray(t, float) + offset
    if len(unix) and not (0.0 <= unix.min() and unix.max() < 4.1e9):
        raise RecordingError(f"{spec.path}: {where} + the [time] offset reaches "
                             f"{unix.min():.4g} .. {unix.max():.4g} s since 1970, outside "
                             "1970-2100: is the time column's unit (s, ms, us, ns) right?")
    return np.round(unix * 1e9).astype(np.int64)


def unrepeated(spec, where, t, *columns, names=None):
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

"""Any logger's columns - CSV or NumPy arrays - described by a TOML spec, as a `Recording`.

    mimunav import table SPEC.toml -o OUT.mcap

The spec names each quantity's file (and columns), its unit and its time base; nothing is
guessed. Paths are relative to `root` (default: the spec's folder; `mimunav import table
--root DIR` overrides it). A column source is either
a path string or a table:

    { file = "imu.csv", columns = ["gx", "gy", "gz"], unit = "deg/s", time = <column source> }

`columns` picks CSV columns by header name or 0-based index, or NumPy columns by index
(default: all). `time` overrides the section's time for that quantity (e.g. a gyro on its own
clock: it is interpolated linearly onto the specific force's stamps, and the metadata says so).

    name, description, model     text
    root                         folder of the data files
    nonfinite = "refuse"         or "drop": rows with a NaN/inf cell are left out and counted
                                 (a logger's missed reading), instead of refusing the table
    [imu]     time               device time of the samples
              angular_rate       rad/s | deg/s                      (N, 3), sensor axes
              specific_force     m/s^2 | g                          (N, 3), sensor axes
              axes = "FRD"       vehicle direction of sensor x, y, z (`Mounting.from_axes`)
              or mounting_rpy_deg = [roll, pitch, yaw]; lever_arm_m = [x, y, z] (vehicle FRD)
    [time]    unix_offset_s      UNIX time = device time + offset (s), or
              gps_week_tow       {file, time}: rows of (GPS week, time of week s) stamped in
                                 device time; the offset is their median difference, the GPS -
                                 UTC leap seconds of that date removed
    [reference_imu] (optional)   a better IMU flown with it, the reference IMU (/fog/imu: the
              diagnosis' sensor level): time, angular_rate, specific_force, axes or
              mounting_rpy_deg as [imu]; model text; accuracy = {gyro_scale = 1e-4, ...}
              (1-sigma, keys of `diagnosis.reference.Accuracy`: gyro_scale, accel_scale,
              gyro_misalignment_rad, accel_misalignment_rad; default: seed Table 4's FOG-IMU)
    [reference] (optional)
              time               device time of the epochs
              latitude, longitude  deg | rad;  height  m (ellipsoidal)   or  position_ecef m
              velocity_ned  m/s  or  velocity_ecef  m/s  (else central differences of position)
              attitude_wxyz      unit quaternions with `rotates` = "body_to_ecef" | "body_to_ned"
              source, independent ("yes" / "no: why"), position_sigma_m   text for the metadata

Units: s, ms, us, ns; rad/s, deg/s; m/s^2, g (9.80665); deg, rad; m, mm; m/s.
"""
import os
import tomllib

import numpy as np
import quaternion

from ..frames import earth
from ..frames.mounting import Mounting
from .recording import RecordingError, Recording, gps_to_unix_s, text_file
from ..motion.track import velocity_from_positions
from ..frames import attitude

G_UNIT = 9.80665
UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "rad/s": 1.0,
         "deg/s": np.pi / 180, "m/s^2": 1.0, "g": G_UNIT, "rad": 1.0, "deg": np.pi / 180,
         "m": 1.0, "mm": 1e-3, "m/s": 1.0, "1": 1.0}
KINDS = {"time": ("s", "ms", "us", "ns"), "angular_rate": ("rad/s", "deg/s"),
         "specific_force": ("m/s^2", "g"), "latitude": ("deg", "rad"), "longitude": ("deg", "rad"),
         "height": ("m", "mm"), "position_ecef": ("m",), "velocity_ned": ("m/s",),
         "velocity_ecef": ("m/s",), "attitude_wxyz": ("1",)}
WIDTH = {"angular_rate": 3, "specific_force": 3, "position_ecef": 3, "velocity_ned": 3,
         "velocity_ecef": 3, "attitude_wxyz": 4}


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
                raise RecordingError(f"{path}: no [{section}] section")

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
        unit = source.get("unit", KINDS[kind][0])
        if unit not in KINDS[kind]:
            raise RecordingError(f"{self.path}: {where} unit {unit!r}: one of "
                                 f"{', '.join(KINDS[kind])}")
        x = load_spec(os.path.join(self.root, source["file"]), source.get("columns"), self.notes)
        width = WIDTH.get(kind, 1)
        if width == 1 and x.ndim == 2 and x.shape[1] == 1:
            x = x[:, 0]
        if (x.ndim == 1 and width != 1) or (x.ndim == 2 and x.shape[1] != width) or x.ndim > 2:
            raise RecordingError(f"{self.path}: {where} from {source['file']} has shape "
                                 f"{x.shape}, expected {width} column(s)")
        if not np.isfinite(x).all() and self.doc.get("nonfinite", "refuse") != "drop":
            raise RecordingError(f"{self.path}: {where} from {source['file']} holds values that "
                                 f"are not finite (first at data row "
                                 f"{int(np.argmax(~np.isfinite(x.reshape(len(x), -1)).all(1)))}"
                                 ", counted from 0 after any header line); `nonfinite = "
                                 "\"drop\"` in the spec leaves such rows out (and counts them)")
        return x * UNITS[unit]

    def finite_rows(self, where, *columns):
        """The columns (equal lengths) with every row that is not finite in any of them left
        out, and counted in `notes` (only `nonfinite = "drop"` lets such values through
        `load`)."""
        ok = np.ones(len(columns[0]), bool)
        for x in columns:
            ok &= np.isfinite(np.reshape(x, (len(x), -1))).all(axis=1)
        if not ok.all():
            self.notes[f"nonfinite {where}"] = (f"{int((~ok).sum())} of {len(ok)} rows not "
                                                "finite: left out (nonfinite = \"drop\")")
        return tuple(x[ok] for x in columns)

    def time_of(self, section, key):
        """Device time (s) of quantity `key`: its own `time`, else its section's."""
        source = self.section(section).get(key)
        if isinstance(source, dict) and "time" in source:
            return self.load(source["time"], "time", f"[{section}] {key}.time")
        return self.column(section, "time")


def load_spec(path, columns, notes=None):
    """A numeric array from a CSV (header row optional) or a NumPy file (.npy, .npz with one
    array, or an extension-less .npy as comma2k19 stores them). A CSV's last line cut short
    (a logger stopped mid-write) is left out and said in `notes`; any other line whose column
    count differs is refused."""
    if not os.path.exists(path):
        raise RecordingError(f"{path}: no such file")
    if path.endswith((".csv", ".txt")):
        with open(path) as fh, text_file(path):
            first = fh.readline()
        header = not all(_number(x) for x in first.strip().split(","))
        data = _read_csv(path, header, notes)
        if header:
            names = list(data.dtype.names)
            data = np.column_stack([data[n] for n in names])
            if columns is not None:
                try:
                    columns = [names.index(c) if isinstance(c, str) else c for c in columns]
                except ValueError:
                    raise RecordingError(f"{path}: columns {columns} not among {names}") from None
    else:
        try:
            data = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise RecordingError(f"{path}: not a NumPy array file ({exc})") from None
        if isinstance(data, np.lib.npyio.NpzFile):
            if len(data.files) != 1:
                raise RecordingError(f"{path}: {len(data.files)} arrays; store one per file")
            data = data[data.files[0]]
    data = np.asarray(data, dtype=float)
    if data.size == 0:
        raise RecordingError(f"{path}: no data rows")
    if columns is not None:
        if any(isinstance(c, str) for c in columns):
            raise RecordingError(f"{path}: columns by name need a CSV header")
        data = data.reshape(len(data), -1)[:, list(columns)]
    return data


def _number(text):
    """Whether a CSV cell reads as a number ('nan', 'inf' and empty do: a first row of data
    with a missing reading is no header)."""
    try:
        float(text or "nan")
        return True
    except ValueError:
        return False


def _read_csv(path, header, notes):
    import re
    read = lambda **kw: np.genfromtxt(path, delimiter=",", names=True if header else None,  # noqa: E731
                                      dtype=float, invalid_raise=True, **kw)
    try:
        return read()
    except ValueError as exc:
        bad = [int(n) for n in re.findall(r"Line #(\d+)", str(exc))]
        if not bad:
            raise RecordingError(f"{path}: not a numeric CSV ({str(exc).strip()[:120]})") from None
        with open(path, "rb") as fh:
            last = sum(1 for line in fh if line.strip())
        if bad != [last]:
            raise RecordingError(f"{path}: line(s) {', '.join(map(str, bad[:5]))} have another "
                                 "column count than the first; a table needs the same columns "
                                 "on every line") from None
    if notes is not None:
        notes[f"{os.path.basename(path)}"] = f"its last line (#{last}) was cut short: left out"
    return read(skip_footer=1)


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
                                   "velocity_ned", "velocity_ecef", "attitude_wxyz")
                       if spec.has("reference", k)]
    if "position_ecef" in keys:
        keys = [k for k in keys if k not in ("latitude", "longitude", "height")]
    else:
        missing = [k for k in ("latitude", "longitude", "height") if k not in keys]
        if missing:
            raise RecordingError(f"{spec.path}: [reference] has no {', '.join(missing)} "
                                 "(give latitude, longitude and height, or position_ecef)")
    columns = [spec.column("reference", k) for k in keys]
    n = len(columns[0])
    for key, x in zip(keys, columns):
        if len(x) != n:
            raise RecordingError(f"{spec.path}: [reference] {key} has {len(x)} rows, time {n}")
    col = dict(zip(keys, spec.finite_rows("[reference]", *columns)))
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
    ok = np.isfinite(ref["v_ned"]).all(axis=1)      # differenced velocity: none across a gap
    return {k: x[ok] for k, x in ref.items()}


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
    """(device time s, w rad/s, f m/s^2) of an IMU section ([imu] or [reference_imu]): the
    angular rate on its own clock interpolated onto the specific force's stamps."""
    path = spec.path
    t_f = spec.time_of(section, "specific_force")
    f = spec.column(section, "specific_force")
    t_w = spec.time_of(section, "angular_rate")
    w = spec.column(section, "angular_rate")
    for name, t, x in (("specific_force", t_f, f), ("angular_rate", t_w, w)):
        if len(t) != len(x):
            raise RecordingError(f"{path}: [{section}] {name} has {len(x)} rows, its time "
                                 f"{len(t)}")
    if len(t_w) == len(t_f) and np.array_equal(t_w, t_f, equal_nan=True):     # one clock
        t_f, f, w = spec.finite_rows(f"[{section}]", t_f, f, w)
        t_w = t_f
    else:
        t_f, f = spec.finite_rows(f"[{section}] specific_force", t_f, f)
        t_w, w = spec.finite_rows(f"[{section}] angular_rate", t_w, w)
    if len(t_w) != len(t_f) or np.any(t_w != t_f):
        if np.any(np.diff(t_w) <= 0):
            raise RecordingError(f"{path}: [{section}] angular_rate times do not increase")
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
    meta = {k: v for k, v in spec.section("reference").items()
            if k in ("source", "independent", "position_sigma_m")}
    name = spec.doc.get("name", os.path.splitext(os.path.basename(path))[0])
    rate = 1.0 / np.median(np.diff(t_f))
    real = {"imu": f"{len(t_f)} samples at {rate:.4g} Hz from {spec.root}",
            "source": spec.doc.get("source", spec.root), "spec": spec.path, **notes}
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
        second = dict(ns=unix_ns(spec, t_r, offset, "[reference_imu] time"), w=w_r, f=f_r,
                      mounting=ref_mounting, model=section.get("model", "unknown"),
                      accuracy=section.get("accuracy"))
        real["reference_imu"] = (f"{len(t_r)} samples at {1.0 / np.median(np.diff(t_r)):.4g} "
                                 f"Hz ({section.get('model', 'model not stated')})")
        assumed["reference_imu_mounting"] = ref_how
    return Recording(name, spec.doc.get("description", f"table import of {spec.path}"),
                     unix_ns(spec, t_f, offset, "[imu] time"), w, f, mounting,
                     model=spec.doc.get("model", "unknown"), reference=reference,
                     reference_meta=meta, real=real, assumed=assumed, reference_imu=second)

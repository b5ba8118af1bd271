"""ArduPilot DataFlash logs (binary `.bin`, or the text `.log` a ground station writes of one:
lines `FMT, ...`, `IMU, ...`; read by pymavlink's DFReader): the IMU from the `IMU`
messages of one instance, GNSS from `GPS` (+ `GPA` accuracies), and as reference either the
GNSS itself (independent, no attitude) or the autopilot's own estimate (`POS` position,
`XKF1` velocity, `ATT` attitude; EKF3 fuses this very IMU: "not independent").

ArduPilot conventions (libraries/AP_Logger/LogStructure.h, AP_InertialSensor, AP_GPS):
Older logs (ArduPilot 3.x, 2013-2016) stamp in ms since boot (TimeMS, read as TimeUS / 1000),
log the second IMU as its own IMU2 type, and their GPS message carries TimeMS = the GPS time of
week in ms, Week and T = ms since boot (read as GMS, GWk, TimeUS); a log with both or neither
time field of a message is refused, naming it.
- IMU: TimeUS (us since boot), I (instance; older logs: IMU, IMU2, IMU3 message types),
  GyrX..Z (rad/s), AccX..Z (m/s^2, specific force), T (degC), body frame FRD (x forward,
  y right, z down) with the board orientation applied. The logged values are the sensor's
  *filtered* outputs at the logging rate (INS_GYRO_FILTER / INS_ACCEL_FILTER low-pass), not
  interval means: fast motion is attenuated, which the metadata says.
- GPS: Status (0 no GPS, 1 no fix, 2 2D, 3 3D, 4 DGPS, 5 RTK float, 6 RTK fixed), GMS
  (ms of GPS week), GWk (GPS week), Lat, Lng (deg), Alt (m above mean sea level), Spd
  (ground speed, m/s), GCrs (course over ground, deg from north), VZ (vertical velocity,
  m/s, positive down: NED). GPA (when logged): HAcc, VAcc (m), SAcc (m/s), 1 sigma.
- POS: Lat, Lng (deg), Alt (m above mean sea level); XKF1 (core C = 0): VN, VE, VD (m/s);
  ATT: Roll, Pitch, Yaw (deg, z-y-x Euler of body FRD -> NED).
Heights stay above mean sea level (no geoid undulation is applied; the metadata says so):
a constant offset of tens of metres changes gravity by < 1e-5 m/s^2.
The UNIX time of boot is the median of (GPS week time - TimeUS) over 3-D fixes, leap seconds
removed (`gps_to_unix_s`); without fixes boot is put at the UNIX epoch and the metadata says
so.
"""
import contextlib
import ctypes
import io
import os
import sys
import tempfile

import numpy as np

from ..frames import attitude
from ..frames.mounting import Mounting
from ..sensors.accuracy import AUTOPILOT_MEMS, AUTOPILOT_MEMS_SOURCE
from .clip_counts import clip_spans, clips_said, merged
from .recording import Recording, RecordingError, attitude_at, gps_to_unix_s
from ..errors import require

GPS_STATUS = {0: "no GPS", 1: "no fix", 2: "2D", 3: "3D", 4: "DGPS", 5: "RTK float",
              6: "RTK fixed"}
# NavSatStatus of /gnss/fix for each ArduPilot status: FIX 0, SBAS_FIX 1, GBAS_FIX 2
NAV_SAT_STATUS = {3: 0, 4: 1, 5: 2, 6: 2}
EKF_VELOCITY = {"XKF1": "EKF3", "NKF1": "EKF2", "EKF1": "EKF1"}   # its velocity, newest first:
#                       ArduPilot up to 4.0 logs EKF2 as NKF1, 3.x EKF1 (an older log's had
#                       been left for the GPS fixes without a word)
TYPES = ("IMU", "IMU2", "IMU3", "GPS", "GPS2", "GPA", "POS", "ATT", "PARM",
         "VIBE") + tuple(EKF_VELOCITY)


BINARY_HEAD = b"\xa3\x95"        # a binary record's first two bytes (AP_Logger)
TEXT_HEAD = b"FMT,"             # a text log's first format line, after any header line


def _reader(path):
    """(pymavlink's reader of the log at `path`, whether it is binary), binary or text as
    its first bytes say; a RecordingError for a file that is neither."""
    DFReader = require("pymavlink.DFReader", "import", "the dataflash importer")
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if head.startswith(BINARY_HEAD):
        kind = DFReader.DFReader_binary
    elif TEXT_HEAD in head:
        kind = DFReader.DFReader_text
    else:
        raise RecordingError(f"{path}: not a DataFlash log: a binary log begins with the bytes "
                             f"0xA3 0x95 and a text log holds 'FMT, ...' lines in its first "
                             f"4 kB; this one begins {head[:16]!r}")
    try:
        return kind(path, zero_time_base=False), kind is DFReader.DFReader_binary
    except Exception as exc:            # DFReader raises its own, struct and index errors
        raise RecordingError(f"{path}: not a readable DataFlash log ({exc})") from None


def _messages(path):
    """({type: {field: array}} of the types this importer reads, '' or a note on what was
    not read: the file ending inside a record, bytes pymavlink skipped as unreadable (its
    reports, printed byte by byte, are held back and counted)); older logs' numbered types
    (IMU2, IMU3, GPS2) and un-numbered ones get the instance field I they lack."""
    with _output_held() as said:
        log, binary = _reader(path)
        rows = _rows(log, path)
    out = {kind: {k: np.array([r.get(k, np.nan) for r in rs]) for k in rs[0]
                  if k != "mavpackettype"} for kind, rs in rows.items()}
    notes = []
    skipped = [line for line in said[0].splitlines()
               if "bad header" in line or "Skipped" in line]
    if skipped:
        notes.append(f"pymavlink skipped unreadable bytes ({len(skipped)} reports, the first: "
                     f"{skipped[0].strip()})")
    left = int(log.data_len - log.offset)       # DFReader stops before a partial record
    if left > 0 and binary:                     # (a text log's reader ends past its end)
        notes.append(f"the file ends inside a record at byte {log.offset} of {log.data_len} "
                     f"({left} bytes left out): the log was cut short, and ends at its last "
                     "whole record")
    return out, "; ".join(notes)


@contextlib.contextmanager
def _output_held():
    """Hold back what is written to the process's stdout and stderr - by Python and by C
    (pymavlink's compiled indexer prints a line per unreadable byte with printf) - into a
    scratch file; yields a list that gets the text once the block ends."""
    said, text = io.StringIO(), []
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with tempfile.TemporaryFile() as scratch:
            os.dup2(scratch.fileno(), 1)
            os.dup2(scratch.fileno(), 2)
            try:
                with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
                    yield text
            finally:
                ctypes.CDLL(None).fflush(None)      # C's buffered printf, before fd 1 returns
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
            scratch.seek(0)
            text.append(scratch.read().decode(errors="replace") + said.getvalue())
    finally:
        for fd in saved:
            os.close(fd)


def _rows(log, path):
    """{type: [message dicts]} of the types this importer reads, each with TimeUS and I."""
    rows = {}
    while True:
        try:
            m = log.recv_match(type=list(TYPES))
        except Exception as exc:
            raise RecordingError(f"{path}: damaged DataFlash message ({exc})") from None
        if m is None:
            return rows
        kind = m.get_type()
        if kind == "PARM":                      # a parameter: no time needed (2014's have none)
            rows.setdefault(kind, []).append(m.to_dict())
            continue
        d = _boot_time_us(m.to_dict(), kind, path)
        if kind in ("IMU2", "IMU3", "GPS2"):
            d["I"] = int(kind[-1]) - 1
            kind = kind[:3]
        elif kind in ("IMU", "GPS", "GPA"):
            d.setdefault("I", 0)                # older logs: instance 0 has no I field
        rows.setdefault(kind, []).append(d)


def _boot_time_us(d, kind, path):
    """A message's fields with its time since boot as TimeUS (module doc: older logs' TimeMS;
    their GPS's TimeMS, Week, T as GMS, GWk, TimeUS)."""
    if "TimeUS" in d:
        return d
    if kind.startswith("GPS") and "Week" in d:          # ArduPilot 3.x: GPS time + boot ms
        if "T" not in d:
            raise RecordingError(f"{path}: a {kind} message without its boot time (T): its "
                                 "fixes cannot be placed on the IMU's clock")
        return {**d, "GMS": d.get("TimeMS"), "GWk": d["Week"], "TimeUS": d["T"] * 1000}
    if "TimeMS" in d:
        return {**d, "TimeUS": d["TimeMS"] * 1000}
    raise RecordingError(f"{path}: a {kind} message with neither TimeUS nor TimeMS: no time "
                         "since boot")


def _instance(table, instance):
    if table is None:
        return None
    if "I" not in table:
        return table if instance == 0 else None
    keep = table["I"] == instance
    return {k: v[keep] for k, v in table.items()} if keep.any() else None


def _imu(msgs, instance, path):
    """(boot us, w rad/s, f m/s^2 - in time order, repeated stamps dropped -, how many were
    dropped, the IMU table) of the IMU messages of `instance`."""
    imu = _instance(msgs.get("IMU"), instance)
    if imu is None or len(imu["TimeUS"]) < 2:
        found = sorted({int(i) for i in msgs.get("IMU", {}).get("I", [])})
        raise RecordingError(f"{path}: no IMU messages of instance {instance}"
                             + (f" (instances logged: {found})" if found else ""))
    boot_us = imu["TimeUS"].astype(np.int64)
    w = np.column_stack([imu[f"Gyr{c}"] for c in "XYZ"]).astype(float)
    f = np.column_stack([imu[f"Acc{c}"] for c in "XYZ"]).astype(float)
    order = np.argsort(boot_us, kind="stable")
    boot_us, w, f = boot_us[order], w[order], f[order]
    keep = np.concatenate([[True], np.diff(boot_us) > 0])
    return boot_us[keep], w[keep], f[keep], int((~keep).sum()), imu


def _temperature(imu):
    """The IMU table's temperature range as text, or None when it logs none."""
    temp = imu["T"][np.isfinite(imu["T"])] if "T" in imu else []
    return f"{temp.min():.2f} to {temp.max():.2f} degC" if len(temp) else None


def read(path, mounting=None, instance=0, reference="auto", reference_status=3,
         reference_instance=None):
    """The recording of an ArduPilot DataFlash log as a `Recording` (IMU in FRD body axes).

    instance: the IMU (and GPS) instance; reference: "ekf" (POS + XKF1 + ATT, autopilot
    estimate, not independent), "gnss" (fixes of status >= reference_status, velocity from
    ground speed, course and VZ; independent, no attitude), "none", or "auto" (ekf when
    logged, else gnss when there are fixes); reference_instance: another IMU instance as
    the reference IMU (two autopilot IMUs against each other, both in the body frame, on
    one clock: the sensor level of the diagnosis)."""
    if reference not in ("auto", "ekf", "gnss", "none"):
        raise RecordingError(f"reference must be auto, ekf, gnss or none, not {reference!r}")
    if reference_instance is not None and reference_instance == instance:
        raise RecordingError(f"{path}: the reference IMU instance is the IMU's own")
    msgs, cut = _messages(path)
    boot_us, w, f, repeated, imu = _imu(msgs, instance, path)
    gps_instance = instance if _instance(msgs.get("GPS"), instance) else 0
    gps = _instance(msgs.get("GPS"), gps_instance)
    gpa = _instance(msgs.get("GPA"), instance) or _instance(msgs.get("GPA"), 0)
    offset_us, assumed, params = 0, {}, _params(msgs.get("PARM"))
    fixes = None
    if gps is not None:
        t_gps = gps["TimeUS"].astype(np.int64)
        status = gps["Status"].astype(int)
        three_d = status >= 3
        if three_d.any():
            gps_s = gps["GWk"][three_d] * 604800.0 + gps["GMS"][three_d] / 1e3
            unix_us = np.round(gps_to_unix_s(gps_s) * 1e6).astype(np.int64)
            offset_us = int(np.median(unix_us - t_gps[three_d]))
            fixes = _fixes(gps, gpa, three_d, offset_us)        # at their epochs' own times
            offset_us, assumed["time"] = _less_gps_lag(offset_us, params, gps_instance)
    if offset_us == 0:
        assumed["time"] = "no 3-D GPS fix: boot placed at the UNIX epoch"
    ref, ref_meta = _reference(msgs, fixes, reference, reference_status, offset_us, path)
    name = os.path.splitext(os.path.basename(path))[0]
    real = _real(path, msgs, instance, len(boot_us), repeated, imu, cut)
    second = None
    if reference_instance is not None:
        r_us, r_w, r_f, r_repeated, r_imu = _imu(msgs, reference_instance, path)
        second = dict(ns=(r_us + offset_us) * 1000, w=r_w, f=r_f,
                      mounting=Mounting(lever_arm_m=_position(params, reference_instance)),
                      model=f"ArduPilot autopilot IMU instance {reference_instance}",
                      accuracy=dict(AUTOPILOT_MEMS))
        assumed["reference_imu_mounting"] = (
            f"ArduPilot body frame FRD = vehicle frame; at INS_POS{reference_instance + 1} "
            f"{_said_m(second['mounting'].lever_arm_m)} (the log's parameters)")
        assumed["reference_imu_accuracy"] = AUTOPILOT_MEMS_SOURCE
        real["reference_imu"] = (f"IMU instance {reference_instance} ({len(r_us)} samples; "
                                 f"{r_repeated} repeated stamps dropped"
                                 + (f"; {_temperature(r_imu)}" if _temperature(r_imu) else "")
                                 + ")")
    if fixes is not None:
        counts = {GPS_STATUS.get(s, str(s)): int((gps["Status"] == s).sum())
                  for s in np.unique(gps["Status"].astype(int))}
        real["gnss"] = f"GPS ({', '.join(f'{k}: {v}' for k, v in counts.items())})"
    if ref is not None:
        real["reference"] = f"{len(ref['ns'])} epochs: {ref_meta['source']}"
    position = _position(params, instance)
    assumed.update(mounting=("ArduPilot body frame FRD = vehicle frame" if mounting is None
                             else "given on the command line")
                   + f"; at INS_POS{instance + 1} {_said_m(position)} (the log's parameters)",
                   calibration="ArduPilot's on-board calibration, as logged",
                   imu_values=_imu_values(params),
                   height="above mean sea level (geoid undulation not applied)")
    clips = _clip_counts(msgs.get("VIBE"), [instance, reference_instance], offset_us * 1000)
    if clips:
        real["clipped"] = clips_said(clips, "the autopilot (VIBE.Clip of IMU "
                                     f"{instance}" + ("" if reference_instance is None else
                                                      f" or {reference_instance}") + ")",
                                     (boot_us[0] + offset_us) * 1000)
    rate = 1e6 / np.median(np.diff(boot_us))
    span = (boot_us[-1] - boot_us[0]) / 1e6
    return Recording(name, f"ArduPilot DataFlash {os.path.basename(path)}: IMU {instance} "
                     f"{rate:.0f} Hz, {span:.1f} s", (boot_us + offset_us) * 1000,
                     w, f, Mounting((mounting or Mounting()).attitude_wxyz, position),
                     model="ArduPilot autopilot IMU",
                     reference=ref, reference_meta=ref_meta, fixes=fixes, real=real,
                     assumed=assumed, reference_imu=second, clip_spans_ns=clips)


def _clip_counts(vibe, instances, offset_ns):
    """[(t0, t1 ns since boot + offset_ns, clips)] where the VIBE clip counter of one of
    `instances` (None: left out) rose (`clip_counts`): `Clip` of the records of that `IMU`
    (ArduPilot 4.0 on), or `Clip0`..`Clip2` of every record (3.3-3.6); none without VIBE."""
    spans = []
    for i in (i for i in instances if i is not None and vibe is not None):
        if "IMU" in vibe and "Clip" in vibe:
            keep = vibe["IMU"] == i
            us, totals = vibe["TimeUS"][keep], vibe["Clip"][keep]
        elif f"Clip{i}" in vibe:
            us, totals = vibe["TimeUS"], vibe[f"Clip{i}"]
        else:
            continue
        spans += [(a * 1000 + offset_ns, b * 1000 + offset_ns, n)
                  for a, b, n in clip_spans(us, totals)]
    return merged(spans)


def _real(path, msgs, instance, samples, repeated, imu, cut):
    """The `real` metadata of `read`'s IMU: its samples, source, temperature, the file's
    damage (`cut`) and the instances the log holds."""
    real = {"imu": f"IMU instance {instance} ({samples} samples; {repeated} repeated stamps "
                   "dropped)", "source": os.path.abspath(path)}
    if cut:
        real["file"] = cut
    if _temperature(imu):
        real["imu_temperature"] = _temperature(imu)
    found = sorted({int(i) for i in msgs["IMU"].get("I", [0])})
    real["imu_instances"] = ", ".join(str(i) for i in found)
    return real


def _less_gps_lag(offset_us, params, gps_instance=0):
    """(the boot clock's offset to UNIX time, us, what was assumed of it): a GPS message is
    logged when the receiver's solution arrives, after its epoch by the lag its delay
    parameter declares (the EKF's delay: GPSn_DELAY_MS from ArduPilot 4.5, GPS_DELAY_MS and
    GPS_DELAY_MS2 before), so the boot time of an epoch is its logging time less that lag;
    not declared (absent or 0: the driver's default), the offset as the messages' logging
    times place it, said."""
    n = gps_instance + 1
    names = (f"GPS{n}_DELAY_MS", "GPS_DELAY_MS" if n == 1 else f"GPS_DELAY_MS{n}")
    name = next((k for k in names if k in (params or {})), names[0])
    lag_ms = float((params or {}).get(name, 0.0))
    if lag_ms > 0:
        return offset_us + int(round(lag_ms * 1000)), (
            f"boot placed in UNIX time by the GPS messages' week time, each logged "
            f"{name} {lag_ms:g} ms after its epoch (the log's parameters)")
    return offset_us, ("boot placed in UNIX time by the GPS messages' week time at their "
                       f"logging (no {name} declared: the receiver's lag, if any, makes the "
                       "IMU's UNIX times early by it)")


def _params(parm):
    """{name: value} of the log's PARM messages (the last of each), or None without any."""
    return None if parm is None else dict(zip(parm["Name"].tolist(), parm["Value"].tolist()))


def _position(params, instance):
    """(3,) m: where the log's parameters put IMU `instance` in the body frame (INS_POSn_X,
    _Y, _Z; n = instance + 1; ArduPilot's FRD from the vehicle's origin), zeros where they
    do not say."""
    n = instance + 1
    return np.array([float((params or {}).get(f"INS_POS{n}_{a}", 0.0)) for a in "XYZ"])


def _said_m(position):
    return "[" + ", ".join(f"{v:g}" for v in position) + "] m"


def _imu_values(value):
    """What the IMU messages' values are, with the low-pass corners the log's parameters
    (`_params`) set (INS_GYRO_FILTER, INS_ACCEL_FILTER, Hz; 0: none) when it holds them."""
    said = "outputs at the logging rate, not interval means"
    if value is None:
        return f"filtered {said} (INS_*_FILTER low-pass; the log holds no parameters)"
    corners = [f"{k} {value[k]:g} Hz" for k in ("INS_GYRO_FILTER", "INS_ACCEL_FILTER")
               if k in value]
    return (f"{said}, low-passed as the log's parameters say: {', '.join(corners)} (0: none)"
            if corners else f"filtered {said} (INS_*_FILTER low-pass: not in its parameters)")


def _fixes(gps, gpa, use, offset_us):
    """GNSS fixes (status >= 3D) for /gnss/fix: covariance from GPA's HAcc, VAcc when
    logged (else HDop x 5 m, a consumer receiver's UERE: assumption, said in the source)."""
    t = gps["TimeUS"].astype(np.int64)
    n = int(use.sum())
    cov = np.zeros((n, 9))
    h_sigma = v_sigma = speed_sigma = None
    if gpa is not None and len(gpa["TimeUS"]) >= 2 and "HAcc" in gpa:
        t_a = gpa["TimeUS"].astype(float)
        h_sigma = np.interp(t[use], t_a, gpa["HAcc"]) / np.sqrt(2)   # per horizontal axis
        v_sigma = np.interp(t[use], t_a, gpa["VAcc"])
        if "SAcc" in gpa:
            speed_sigma = np.interp(t[use], t_a, gpa["SAcc"])
    else:
        h_sigma = 5.0 * gps["HDop"][use] / np.sqrt(2)
        v_sigma = 1.5 * 5.0 * gps["HDop"][use]
    cov[:, 0] = cov[:, 4] = h_sigma ** 2
    cov[:, 8] = v_sigma ** 2
    course = np.radians(gps["GCrs"][use])
    speed = gps["Spd"][use]
    status = gps["Status"][use].astype(int)
    return dict(ns=(t[use] + offset_us) * 1000,
                status=np.array([NAV_SAT_STATUS.get(s, 0) for s in status], np.int8),
                ap_status=status, lat=np.radians(gps["Lat"][use]),
                lon=np.radians(gps["Lng"][use]), h=gps["Alt"][use].astype(float),
                covariance=cov, speed_sigma=speed_sigma,
                v_ned=np.column_stack([speed * np.cos(course), speed * np.sin(course),
                                       gps["VZ"][use]]))


def _reference(msgs, fixes, kind, min_status, offset_us, path):
    """(reference dict or None, its metadata) of the chosen kind (`read`)."""
    name = next((k for k in EKF_VELOCITY if k in msgs), None)
    ekf = "POS" in msgs and name is not None
    fallback = ""
    if kind == "auto":
        kind = "ekf" if ekf else ("gnss" if fixes is not None else "none")
        fallback = "" if ekf else (f" - the log holds no EKF estimate (POS with one of "
                                   f"{', '.join(EKF_VELOCITY)})")
    if kind == "none":
        return None, {}
    if kind == "gnss":
        if fixes is None:
            raise RecordingError(f"{path}: a GNSS reference needs 3-D GPS fixes; the log has none")
        use = fixes["ap_status"] >= min_status
        if use.sum() < 3:
            raise RecordingError(f"{path}: {int(use.sum())} GPS fixes of status >= "
                                 f"{GPS_STATUS.get(min_status, min_status)}; a reference "
                                 "needs at least 3")
        sigma = np.sqrt(fixes["covariance"][use, 0] + fixes["covariance"][use, 4])
        meta = {"source": f"GPS fixes of status >= {GPS_STATUS.get(min_status, min_status)}, "
                          "velocity from ground speed, course and VZ" + fallback,
                "independent": "yes: GNSS only",
                "position_sigma_m": f"{np.median(sigma):.3g}"}
        if fixes["speed_sigma"] is not None:
            meta["velocity_sigma_m_s"] = f"{np.median(fixes['speed_sigma'][use]):.3g}"
        return {k: fixes[k][use] for k in ("ns", "lat", "lon", "h", "v_ned")}, meta
    if not ekf:
        raise RecordingError(f"{path}: an autopilot reference needs POS and one of "
                             f"{', '.join(EKF_VELOCITY)} (the EKF's velocity) messages")
    pos, xkf = msgs["POS"], msgs[name]
    vel = {k: v[xkf["C"] == 0] for k, v in xkf.items()} if "C" in xkf else xkf   # core 0
    t = pos["TimeUS"].astype(np.int64)
    t_v = vel["TimeUS"].astype(float)
    v = np.column_stack([np.interp(t, t_v, vel[c]) for c in ("VN", "VE", "VD")])
    q = np.full((len(t), 4), np.nan)
    att = msgs.get("ATT")
    if att is not None and len(att["TimeUS"]) >= 2:
        q = attitude_at(t, att["TimeUS"].astype(float), attitude.as_wxyz(
            attitude.from_euler(np.radians(att["Yaw"]), np.radians(att["Pitch"]),
                                np.radians(att["Roll"]))))
    meta = {"source": f"autopilot estimate (ArduPilot: POS and ATT of the active EKF, "
                      f"velocity from {EKF_VELOCITY[name]}'s {name} core 0)",
            "independent": "no: the autopilot fuses this IMU"}
    return dict(ns=(t + offset_us) * 1000, lat=np.radians(pos["Lat"]), lon=np.radians(pos["Lng"]),
                h=pos["Alt"].astype(float), v_ned=v, q_nb=q), meta

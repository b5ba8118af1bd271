"""A CSV IMU log time-tagged by RTKLIB's stream server, with an RTKLIB position solution
(the rtklibexplorer/GNSS_IMU drive format, shared/data/rtklib-drive/README.md).

    imu_*.csv       ax, ay, az [g], gx, gy, gz [deg/s], tick [ms since IMU power-up]; no
                    header; lines with another number of fields (a partial first or last
                    line) are dropped and counted
    imu_*.csv.tag   RTKLIB time tags: 60-byte text header, uint32 tick_f, uint32 start
                    (GPST s since 1970), float64 fraction, then (uint32 tick ms, uint32 file
                    position) records: the receiving computer's clock when the stream's
                    bytes up to that position had arrived. Each tag times the last complete
                    line at its position; the IMU ticks go onto the tags by a line fitted
                    over all of them (`clock_fit`: the IMU clock's rate measured, lines
                    logged before the first tag placed too). Where the positions do not
                    meet the lines, the first and last ticks are mapped onto the first and
                    last tags (`imu_stamps_ns`). (The data README maps onto [start, start +
                    last]; that stretches the IMU's 548.59 s by the 0.131 s before the first
                    arrival, 2.4e-4, and the yaw-rate lag then drifts from 0 to 0.13 s along
                    the drive - measured by `diagnosis.track.time_lag` per segment. With
                    arrival times the stamps carry the stream's latency as a constant lag.)
    *.pos           RTKLIB solution: GPST date and time, lat, lon [deg], height [m,
                    ellipsoidal], Q (1 fix, 2 float), ns, sdn, sde, sdu, sdne, sdeu, sdun [m],
                    age, ratio, vn, ve, vu [m/s], then velocity sigmas (RTKLIB's other time
                    and position layouts too: `read_pos`)
Times go from GPST to the UNIX (UTC) scale of the log contract by the leap seconds in force.
"""
import calendar
import glob
import math
import os
import struct

import numpy as np

from ..frames.mounting import Mounting
from .recording import GPS_EPOCH_UNIX_S, RecordingError, Recording, gps_to_unix_s, text_file
from ..motion.track import velocity_from_positions

G_UNIT = 9.80665            # m/s^2 per g: the standard gravity an accelerometer's g means
GPS_UTC_LEAP_S = 18         # GPST - UTC since 2017-01-01 (IERS Bulletin C: none added since)
SOLUTION_NAMES = {1: "fix", 2: "float", 3: "sbas", 4: "dgps", 5: "single", 6: "ppp"}   # RTKLIB Q
TAG_HEADER = 60
# The sensor -> vehicle (FRD) rotation of the rtklibexplorer kit, roll/pitch/yaw in deg (the
# drive's README): sensor z up, x backward - the default; --mounting-rpy-deg overrides it.
NOMINAL_RPY_DEG = (180.0, 0.0, 180.0)


def read_imu_csv(path):
    """(ticks ms (N,) int64, f m/s^2 (N, 3), w rad/s (N, 3), dropped line numbers)."""
    rows, dropped = [], []
    with open(path) as fh, text_file(path):
        for number, line in enumerate(fh, 1):
            parts = line.strip().split(",")
            try:
                if len(parts) != 7:
                    raise ValueError
                rows.append([float(x) for x in parts])
            except ValueError:
                dropped.append(number)
    if len(rows) < 2:
        raise RecordingError(f"{path}: fewer than two complete IMU lines")
    a = np.asarray(rows)
    if not np.isfinite(a).all():
        k = int(np.argmax(~np.isfinite(a).all(axis=1)))
        raise RecordingError(f"{path}: a value that is not finite near line {k + 1}")
    return a[:, 6].astype(np.int64), a[:, :3] * G_UNIT, np.radians(a[:, 3:6]), dropped


def read_time_tags(path):
    """(start GPST s since 1970 as float, tag ticks ms (M,), file positions (M,))."""
    raw = open(path, "rb").read()
    if len(raw) < TAG_HEADER + 16 or not raw.startswith(b"TIMETAG"):
        raise RecordingError(f"{path}: not an RTKLIB time-tag file (no 'TIMETAG' header)")
    _tick_f, start, fraction = struct.unpack("<IId", raw[TAG_HEADER:TAG_HEADER + 16])
    body = raw[TAG_HEADER + 16:]
    records = np.frombuffer(body[:len(body) // 8 * 8], dtype="<u4").reshape(-1, 2)
    if len(records) == 0:
        raise RecordingError(f"{path}: no time-tag records")
    return start + fraction, records[:, 0].astype(np.int64), records[:, 1].astype(np.int64)


CLOCK_PPM = 50e-6     # the IMU's tick clock against the computer's: crystals hold +-20-50 ppm
# (the shared drive's 548.590 s of ticks took 548.600 s of tags: 18 ppm with its ends)
TICK_WRAP = 2 ** 32   # both tick counters are uint32 ms: they wrap after 49.7 days


def _unwrapped(ticks):
    """uint32 ms ticks made monotonic across a wrap of the counter."""
    ticks = np.asarray(ticks, np.int64)
    return ticks + TICK_WRAP * np.concatenate([[0], np.cumsum(np.diff(ticks) < -TICK_WRAP // 2)])


def imu_stamps_ns(ticks, start_gpst, tag_ticks):
    """UNIX ns of each IMU tick: the first and last ticks on the first and last tag ticks
    after `start` (GPST), linear in between, then GPST -> UTC. The two spans must agree to
    the clocks' CLOCK_PPM plus two of the tags' longest interval (a tag is the arrival of
    a piece of the stream: each end may be a piece late); else the CSV and its .tag are
    not of one recording, or one of them is cut (a CSV cut short was stretched over the
    whole .tag's span)."""
    ticks, tag_ticks = _unwrapped(ticks), _unwrapped(tag_ticks)
    if ticks[-1] == ticks[0]:
        raise RecordingError("the IMU ticks do not advance")
    first, last = tag_ticks[0] / 1e3, tag_ticks[-1] / 1e3
    imu_span = (ticks[-1] - ticks[0]) / 1e3
    step = float(np.max(np.diff(tag_ticks))) / 1e3 if len(tag_ticks) > 1 else 0.0
    allowed = CLOCK_PPM * imu_span + 2 * step
    if not abs(last - first - imu_span) <= allowed:
        raise RecordingError(
            f"the IMU's ticks span {imu_span:.3f} s but its time tags {last - first:.3f} s "
            f"(they may differ by {allowed:.3f} s: {CLOCK_PPM * 1e6:.0f} ppm of clock and two "
            f"tag intervals of {step * 1e3:.0f} ms): the CSV and its .tag are not of one "
            "recording, or one of them is cut; cut both at the same place, or neither")
    s = start_gpst - GPS_UTC_LEAP_S + first + (ticks - ticks[0]) / (ticks[-1] - ticks[0]) * \
        (last - first)
    return np.round(s * 1e9).astype(np.int64)


def read_pos(path):
    """RTKLIB solution as arrays: ns (UNIX), lat, lon (rad), h (m), Q, sd (M, 3) n/e/u m,
    v_ned (M, 3) m/s (NaN where the file has no velocity columns).

    RTKLIB's output options (rtkpost / rnx2rtkp, `out-solformat`, `out-timeform`,
    `out-timesys`, `out-degform`), read from the column header line (the last '%' line
    before the data, its first word the time system):
      time:     'yyyy/mm/dd hh:mm:ss.sss' or 'week tow' (GPS week, seconds of week), in GPST
                (the leap seconds of the date removed), UTC or JST (UTC + 9 h);
      position: latitude/longitude in deg or d m s, height m; or ECEF x, y, z m (the
                velocity then ECEF too; the sigmas' diagonal turned into n, e, u);
      an ENU baseline (relative to an unstated base) is refused."""
    system, layout = "GPST", "deg"
    rows = []
    with open(path) as fh, text_file(path):
        for number, line in enumerate(fh, 1):
            if line.startswith("%"):
                head = line[1:].split()
                if head and head[0] in TIME_SYSTEMS:
                    system, layout = head[0], _position_layout(path, line)
                continue
            if not line.strip():
                continue
            rows.append(_solution_row(path, number, line, system, layout))
    if not rows:
        raise RecordingError(f"{path}: no solution lines")
    a = np.asarray(rows)
    if layout == "xyz":
        from ..frames import earth
        lat, lon, h = earth.ecef_to_geodetic(a[:, 1:4])
        c_en = earth.ned_to_ecef_matrix(lat, lon)
        v_ned = np.einsum("kji,kj->ki", c_en, a[:, 14:17])
        sd = np.sqrt(np.einsum("kji,kj->ki", c_en ** 2, a[:, 6:9] ** 2))     # n, e, d
    else:
        lat, lon, h = np.radians(a[:, 1]), np.radians(a[:, 2]), a[:, 3]
        v_ned = np.column_stack([a[:, 14], a[:, 15], -a[:, 16]])
        sd = a[:, 6:9]
    return dict(ns=np.round(a[:, 0] * 1e9).astype(np.int64), lat=lat, lon=lon, h=h,
                quality=a[:, 4].astype(int), sd=sd, v_ned=v_ned)


TIME_SYSTEMS = {"GPST": None, "UTC": 0.0, "JST": -9 * 3600.0}   # s to add for UTC (GPST: leaps)


def _position_layout(path, header):
    """'deg', 'dms' or 'xyz' from a .pos column header line; an ENU baseline is refused."""
    if "x-ecef" in header:
        return "xyz"
    if "e-baseline" in header:
        raise RecordingError(f"{path}: an ENU baseline solution (relative to its base station, "
                             "whose position the file does not give): write the solution as "
                             "latitude/longitude/height (RTKLIB out-solformat=llh) or ECEF xyz")
    return "dms" if "latitude(d'" in header else "deg"


def _solution_row(path, number, line, system, layout):
    """[UNIX time s, lat deg | x, lon deg | y, h | z, Q, ns, 6 sigmas, age, ratio, 3
    velocities (nan when absent)] of one .pos data line."""
    parts = line.split()
    need = 15 + (4 if layout == "dms" else 0)
    if len(parts) < need:
        raise RecordingError(f"{path}:{number}: {len(parts)} columns, an RTKLIB solution line "
                             f"has at least {need} (time (2), position, Q, ns, 6 sigmas, age, "
                             "ratio)")
    try:
        if "/" in parts[0]:                             # yyyy/mm/dd hh:mm:ss.sss
            date, clock = parts[0].split("/"), parts[1].split(":")
            sec = float(clock[2])
            t = calendar.timegm((int(date[0]), int(date[1]), int(date[2]), int(clock[0]),
                                 int(clock[1]), 0)) + sec
            gps_s = t - GPS_EPOCH_UNIX_S
        else:                                           # GPS week, seconds of week
            gps_s = int(parts[0]) * 604800.0 + float(parts[1])
            t = gps_s + GPS_EPOCH_UNIX_S
        vals = [float(x) for x in parts[2:]]
    except (ValueError, IndexError):
        raise RecordingError(f"{path}:{number}: cannot read {line.strip()[:60]!r}: the time "
                             "is neither 'yyyy/mm/dd hh:mm:ss' nor 'week tow'") from None
    t = float(gps_to_unix_s(gps_s)) if system == "GPST" else t + TIME_SYSTEMS[system]
    if layout == "dms":                  # d m s, the sign on the degrees ("-0 30 0.0")
        angle = lambda k: math.copysign(abs(vals[k]) + vals[k + 1] / 60 + vals[k + 2] / 3600,
                                        -1.0 if parts[2 + k].startswith("-") else 1.0)
        vals = [angle(0), angle(3)] + vals[6:]
    vel = vals[13:16] if len(vals) >= 16 else [math.nan] * 3
    return [t] + vals[:13] + vel


def find_files(folder):
    """(csv, tag, pos) of a drive folder: one imu_*.csv, its .tag, one *.pos."""
    if not os.path.isdir(folder):
        what = "a file, not a folder" if os.path.exists(folder) else "no such folder"
        raise RecordingError(f"{folder}: {what} (an RTKLIB drive is a folder holding "
                             "imu_*.csv, its .tag and a .pos: give the folder)")

    def one(pattern):
        found = sorted(glob.glob(os.path.join(folder, pattern)))
        if len(found) != 1:
            raise RecordingError(f"{folder}: expected one {pattern}, found {len(found)}")
        return found[0]
    csv = one("imu_*.csv")
    tag = csv + ".tag"
    if not os.path.exists(tag):
        raise RecordingError(f"{folder}: no time-tag file {os.path.basename(tag)}")
    return csv, tag, one("*.pos")


MAX_DRIFT = 1e-3        # a crystal holds +-20-50 ppm; twenty times that is no clock's rate


def csv_line_ends(path):
    """The byte offset after each line of the file (its line endings as they are)."""
    with open(path, "rb") as fh:
        return np.cumsum([len(line) for line in fh], dtype=np.int64)


def clock_fit(ticks, ends, tag_ticks, tag_positions):
    """(a ms, b, what was measured) of the map tag tick = a + b * IMU tick, fitted by least
    squares over every time tag: a tag says when the stream's bytes up to its file position
    had arrived, so it times the last complete line there. Both tick counters unwrapped. The
    lines' ends must meet the tags' positions (the last tag at the file's end, within a line;
    a file whose CRLF endings were turned into LF is met by one byte a line): else None, and
    the caller maps the ends. Refused (RecordingError) when the fitted rate is beyond
    MAX_DRIFT or the tags leave the line by more than the ends' allowance (`imu_stamps_ns`):
    the ticks and the tags are not one recording's."""
    ticks, tag_ticks = _unwrapped(ticks), _unwrapped(tag_ticks)
    longest = int(np.max(np.diff(np.r_[0, ends]))) if len(ends) else 0
    for extra, how in ((0, "as written"), (1, "one byte a line more: CRLF read as LF")):
        shifted = ends + extra * np.arange(1, len(ends) + 1)
        if len(shifted) and abs(int(tag_positions[-1]) - int(shifted[-1])) <= longest + extra:
            break
    else:
        return None
    line = np.searchsorted(shifted, tag_positions, side="right") - 1
    ok = line >= 0
    if ok.sum() < 10:
        return None
    x, y = ticks[line[ok]].astype(float), tag_ticks[ok].astype(float)
    b, a = np.polyfit(x - x[0], y, 1)
    a -= b * x[0]
    residual = y - (a + b * x)
    span = (x[-1] - x[0]) / 1e3
    step = float(np.max(np.diff(tag_ticks))) / 1e3 if len(tag_ticks) > 1 else 0.0
    allowed = CLOCK_PPM * span + 2 * step
    worst = float(np.max(np.abs(residual))) / 1e3
    if abs(b - 1) > MAX_DRIFT or worst > allowed:
        raise RecordingError(
            f"the IMU's ticks against its time tags (each tag timing the line at its file "
            f"position): rate {(b - 1) * 1e6:+.0f} ppm (at most {MAX_DRIFT * 1e6:.0f}), tags up "
            f"to {worst:.3f} s off the line (at most {allowed:.3f} s): the CSV and its .tag are "
            "not of one recording, or one of them was cut or spliced")
    said = (f"fitted over {int(ok.sum())} time tags by the lines at their file positions "
            f"({how}): the IMU's clock runs {(b - 1) * 1e6:+.1f} ppm against the computer's; "
            f"the tags scatter {np.std(residual):.1f} ms about the line (the stream's latency, "
            "whose mean the stamps keep as a constant lag)")
    return a, b, said


def read_drive(folder, mounting=None, name=None, solutions=(1,)):
    """The drive in `folder` as a `Recording` (IMU in SI sensor axes; as the reference the
    RTK epochs whose Q is in `solutions` (1 fix, 2 float, 5 single) and that carry velocity;
    every epoch also as a GNSS fix with its sigmas)."""
    csv, tag, pos = find_files(folder)
    ticks, f, w, dropped = read_imu_csv(csv)
    start, tag_ticks, tag_positions = read_time_tags(tag)
    ends = np.delete(csv_line_ends(csv), np.asarray(dropped, int) - 1)
    fitted = clock_fit(ticks, ends, tag_ticks, tag_positions)
    if fitted is None:
        ns = imu_stamps_ns(ticks, start, tag_ticks)
        timing = (f"first and last IMU ticks mapped onto the first and last RTKLIB time tags "
                  f"(arrival times) of {os.path.basename(tag)} (its file positions do not meet "
                  "the CSV's lines: an excerpt?)")
    else:
        a, b, said = fitted
        ms = a + b * _unwrapped(ticks).astype(float)
        ns = np.round((start - GPS_UTC_LEAP_S + ms / 1e3) * 1e9).astype(np.int64)
        timing = f"IMU ticks onto the RTKLIB time tags of {os.path.basename(tag)}, {said}"
    # a repeated tick (or one behind a sample already kept): keep the first
    keep = np.concatenate([[True], ns[1:] > np.maximum.accumulate(ns)[:-1]])
    if (~keep).mean() > 0.01:
        k = int(np.argmax(~keep))
        raise RecordingError(f"{csv}: {int((~keep).sum())} of {len(ns)} IMU ticks repeat or go "
                             f"back (first at complete line {k + 1}: {ticks[k - 1]} then "
                             f"{ticks[k]} ms): the tick is not the sampling clock (jittered "
                             "or reordered); the samples cannot be placed in time")
    sol = read_pos(pos)
    chosen = np.isin(sol["quality"], solutions)
    counts = ", ".join(f"{SOLUTION_NAMES.get(q, q)} {int((sol['quality'] == q).sum())}"
                       for q in np.unique(sol["quality"]))
    kinds = "/".join(SOLUTION_NAMES.get(q, str(q)) for q in solutions)
    if chosen.sum() < 3:
        raise RecordingError(f"{pos}: {int(chosen.sum())} {kinds} epochs ({counts}); choose the "
                             "solution kinds that serve as reference with --solutions (e.g. "
                             "--solutions fix float)")
    velocity = "RTKLIB's velocity columns"
    if not np.isfinite(sol["v_ned"][chosen]).all():      # RTKLIB's default output has none
        sol["v_ned"][chosen] = velocity_from_positions(sol["ns"][chosen], sol["lat"][chosen],
                                                 sol["lon"][chosen], sol["h"][chosen])
        velocity = "central differences of the positions (the .pos has no velocity columns)"
    good = chosen & np.isfinite(sol["v_ned"]).all(axis=1)
    reference = {k: sol[k][good] for k in ("ns", "lat", "lon", "h", "v_ned")}
    sd = sol["sd"]
    cov = np.zeros((len(sol["ns"]), 9))
    cov[:, 0], cov[:, 4], cov[:, 8] = sd[:, 1] ** 2, sd[:, 0] ** 2, sd[:, 2] ** 2    # ENU
    fixes = dict(ns=sol["ns"], lat=sol["lat"], lon=sol["lon"], h=sol["h"],
                 status=np.where(sol["quality"] == 1, 2, 0).astype(np.int8), covariance=cov)
    given = mounting is not None
    mounting = mounting or Mounting.from_rpy_deg(NOMINAL_RPY_DEG)
    rate = 1e9 / np.median(np.diff(ns[keep]))
    span = (ns[keep][-1] - ns[keep][0]) / 1e9
    back = int((~keep).sum())
    real = {"imu": f"{os.path.basename(csv)}: {len(ticks)} complete lines "
                   f"({len(dropped)} partial dropped: lines {dropped[:5]}"
                   + (f"; {back} whose tick repeats or goes back dropped, first at line "
                      f"{int(np.argmax(~keep)) + 1} of the complete ones" if back else "")
                   + f"); g -> m/s^2 by {G_UNIT}, deg/s -> rad/s; no temperature channel",
            "imu_time": f"{timing}; GPST - {GPS_UTC_LEAP_S} s = UTC; the stream's latency "
                        "is not removed",
            "reference": f"RTK solution {os.path.basename(pos)}: {int(good.sum())} {kinds} "
                         f"epochs with velocity of {len(good)} ({counts}); velocity from "
                         f"{velocity}",
            "source": os.path.abspath(folder)}
    assumed = {"mounting": ("given on the command line" if given else
                            f"sensor -> vehicle roll/pitch/yaw {list(NOMINAL_RPY_DEG)} deg (the "
                            "rtklibexplorer kit's frame)"),
               "lever_arm": "as the mounting says (0 unless given): IMU and antenna at one point",
               "calibration": "none: the IMU's outputs are used as recorded (bias, scale and "
                              "axis errors remain)"}
    sigma = np.linalg.norm(sd[good], axis=1)
    meta = {"source": f"RTKLIB solution ({kinds})", "independent": "yes: GNSS only",
            "position_sigma_m": f"{np.median(sigma):.3g}" if len(sigma) else "unknown",
            "solutions": kinds}
    name = name or os.path.basename(os.path.normpath(folder))
    return Recording(name, f"MEMS IMU {rate:.0f} Hz, {span:.0f} s, with an RTK solution "
                     f"({counts})", ns[keep], w[keep], f[keep], mounting,
                     model="unknown (RTKLIB-tagged CSV)", reference=reference,
                     reference_meta=meta, fixes=fixes, real=real, assumed=assumed)

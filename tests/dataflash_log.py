"""An ArduPilot DataFlash log written from a simulated flight, for the importer's tests: the
record layout (0xA3 0x95, message id, packed fields; FMT records first) and the message
formats of ArduPilot's libraries/AP_Logger/LogStructure.h (IMU, GPS, GPA, POS, XKF1, ATT,
PARM, VIBE),
read back by pymavlink's DFReader - not by code of this project."""
import struct

import numpy as np

from mimunav.frames import attitude
from mimunav.motion import truth
from mimunav.importers.recording import GPS_EPOCH_UNIX_S
from mimunav.motion.profile import Profile

HEAD = b"\xa3\x95"
STRUCT = {"b": "b", "B": "B", "h": "h", "H": "H", "i": "i", "I": "I", "f": "f", "n": "4s",
          "N": "16s", "Z": "64s", "c": "h", "C": "H", "e": "i", "E": "I", "L": "i", "q": "q",
          "Q": "Q"}
SCALE = {"c": 100.0, "C": 100.0, "e": 100.0, "E": 100.0, "L": 1e7}
FORMATS = {   # name: (id, format, columns) as in LogStructure.h (ArduPilot 4.x)
    "IMU": (10, "QBffffffIIfBBHH", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz"),
    "GPS": (11, "QBBIHBcLLeffffB", "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,VZ,"
                                   "Yaw,U"),
    "GPA": (12, "QBCCCCfBIH", "TimeUS,I,VDop,HAcc,VAcc,SAcc,YAcc,VV,SMS,Delta"),
    "POS": (13, "QLLfff", "TimeUS,Lat,Lng,Alt,RelHomeAlt,RelOriginAlt"),
    "XKF1": (14, "QBccCfffffffccce", "TimeUS,C,Roll,Pitch,Yaw,VN,VE,VD,dPD,PN,PE,PD,GX,GY,GZ,OH"),
    "ATT": (15, "QccccCCCCB", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF"),
    "PARM": (16, "QNff", "TimeUS,Name,Value,Default"),
    "VIBE": (17, "QBfffI", "TimeUS,IMU,VibeX,VibeY,VibeZ,Clip"),
}
LEAP_S = 18                 # GPS - UTC since 2017
PROFILE = {"name": "copter-like", "start": {"latitude_deg": -35.36, "longitude_deg": 149.17,
                                            "height_m": 584.0, "speed_m_s": 0.0,
                                            "heading_deg": 70.0},
           "segment": [{"kind": "hold", "duration_s": 12.0},
                       {"kind": "accelerate", "to_speed_m_s": 15.0, "accel_g": 0.15},
                       {"kind": "turn", "load_factor": 1.15, "heading_change_deg": 120.0},
                       {"kind": "climb", "flight_path_deg": 8.0, "load_factor": 1.05,
                        "duration_s": 10.0},
                       {"kind": "turn", "load_factor": 1.1, "heading_change_deg": -90.0},
                       {"kind": "hold", "duration_s": 10.0}]}


class Writer:
    def __init__(self):
        self.parts = [self._fmt(128, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")]
        self.lines = ["FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns"]
        for name, (mid, fmt, cols) in FORMATS.items():
            self.parts.append(self._fmt(mid, name, fmt, cols))
            self.lines.append(f"FMT, {mid}, {self._size(fmt)}, {name}, {fmt}, {cols}")

    @staticmethod
    def _size(fmt):
        return 3 + struct.calcsize("<" + "".join(STRUCT[c] for c in fmt))

    def _fmt(self, mid, name, fmt, cols):
        length = 89 if name == "FMT" else self._size(fmt)
        return HEAD + bytes([128]) + struct.pack("<BB4s16s64s", mid, length, name.encode(),
                                                 fmt.encode(), cols.encode())

    def add(self, name, **values):
        mid, fmt, cols = FORMATS[name]
        packed = []
        for c, col in zip(fmt, cols.split(",")):
            v = values.get(col, 0)
            packed.append(int(round(v * SCALE[c])) if c in SCALE else v.encode()
                          if c in "nNZ" else (float(v) if c == "f" else int(v)))
        self.parts.append(HEAD + bytes([mid]) + struct.pack(
            "<" + "".join(STRUCT[c] for c in fmt), *packed))
        # the text form a ground station writes: scaled fields in their units, floats as
        # the float32 they are stored in, 7 significant digits (Mission Planner's)
        self.lines.append(", ".join([name] + [
            f"{p / SCALE[c]:.7f}" if c in SCALE else
            f"{float(np.float32(p)):.7g}" if c == "f" else
            p.decode() if isinstance(p, bytes) else str(p)
            for c, p in zip(fmt, packed)]))

    def bytes(self):
        return b"".join(self.parts)

    def text(self):
        """The log as a text DataFlash log (`.log`): a header line, then a line a record."""
        return ("ArduCopter V4.5.0 (test)\n" + "\n".join(self.lines) + "\n").encode()


def flight(rate=400.0, seed=0, unix_start_s=1714550400.0, boot_s=93.25, text=False,
           gps_lag_ms=0, lag_name="GPS_DELAY_MS", clip=None, lost=()):
    """(DataFlash bytes - binary, or with `text` the text form -, truth run, flight times t
    (s), UNIX time of t = 0) of PROFILE (the autopilot booted boot_s before t = 0):
    IMU instance 0 = interval means + white noise + a bias, instance 1 = the same at another
    noise; GPS RTK fixed with GPA, POS, XKF1, ATT at 5 Hz from the truth; gps_lag_ms: the
    GPS messages logged that long after their epochs, declared as lag_name (GPS_DELAY_MS
    before ArduPilot 4.5, GPS1_DELAY_MS from it). clip: (t0, t1 s, m/s^2): instance 0's
    AccZ short by that much in [t0, t1) - its sensor at range inside the logged values -, and
    its VIBE clip count (both instances' logged at 10 Hz) up by 18 at the next record.
    lost: [(instance, t0, t1 s)]: that instance's IMU records in [t0, t1) not written."""
    motion = Profile.from_dict(PROFILE).motion()
    t = np.arange(0.0, motion.t1 - 1e-9, 1.0 / rate)
    run = truth.generate(motion, t)
    rng = np.random.default_rng(seed)
    dt = np.diff(t)
    w = run.dtheta / dt[:, None]
    f = run.dv / dt[:, None]
    out = Writer()
    for name, value in (("INS_GYRO_FILTER", 20.0), ("INS_ACCEL_FILTER", 10.0),
                        ("INS_POS2_X", 0.001),              # instance 1, 1 mm forward
                        (lag_name, float(gps_lag_ms))):
        out.add("PARM", TimeUS=int(boot_s * 1e6) - 1_000_000, Name=name, Value=value,
                Default=value)
    boot_us = np.round((boot_s + t[1:]) * 1e6).astype(np.int64)
    for inst, (sw, sf) in enumerate(((2e-3, 2e-2), (4e-3, 4e-2))):
        wn = w + rng.normal(0, sw, w.shape) + [1e-3, -2e-3, 5e-4]
        fn = f + rng.normal(0, sf, f.shape) + [0.02, -0.01, 0.03]
        if clip is not None and inst == 0:
            fn[(t[1:] >= clip[0]) & (t[1:] < clip[1]), 2] += clip[2]
        written = np.ones(len(boot_us), bool)
        for i, t0, t1 in lost:
            written &= (i != inst) | (t[1:] < t0) | (t[1:] >= t1)
        for k in np.flatnonzero(written):
            out.add("IMU", TimeUS=boot_us[k], I=inst, GyrX=wn[k, 0], GyrY=wn[k, 1],
                    GyrZ=wn[k, 2], AccX=fn[k, 0], AccY=fn[k, 1], AccZ=fn[k, 2],
                    T=41.0 + 0.01 * t[k + 1], GHz=rate, AHz=rate)
    for k in range(0, len(t), int(rate / 10)) if clip is not None else ():
        for inst in (0, 1):
            out.add("VIBE", TimeUS=int(round((boot_s + t[k]) * 1e6)), IMU=inst, VibeX=0.5,
                    VibeY=0.5, VibeZ=0.8, Clip=18 * (inst == 0 and t[k] >= clip[1]))
    tr = run.trajectory
    yaw, pitch, roll = attitude.as_euler(tr.q_nb)
    for k in range(0, len(t), int(rate / 5)):
        unix = unix_start_s + t[k]
        gps_s = unix - GPS_EPOCH_UNIX_S + LEAP_S
        week, tow = divmod(gps_s, 604800.0)
        vn, ve, vd = tr.v_ned[k]
        us = int(round((boot_s + t[k]) * 1e6))
        out.add("GPS", TimeUS=us + 1000 * gps_lag_ms, Status=6, GMS=int(round(tow * 1e3)), GWk=int(week), NSats=18,
                HDop=0.7, Lat=np.degrees(tr.lat[k]), Lng=np.degrees(tr.lon[k]), Alt=tr.h[k],
                Spd=np.hypot(vn, ve), GCrs=np.degrees(np.arctan2(ve, vn)) % 360, VZ=vd)
        out.add("GPA", TimeUS=us, VDop=1.1, HAcc=0.02, VAcc=0.03, SAcc=0.05, SMS=0)
        out.add("POS", TimeUS=us, Lat=np.degrees(tr.lat[k]), Lng=np.degrees(tr.lon[k]),
                Alt=tr.h[k])
        out.add("XKF1", TimeUS=us, C=0, Roll=np.degrees(roll[k]), VN=vn, VE=ve, VD=vd)
        out.add("ATT", TimeUS=us, Roll=np.degrees(roll[k]), Pitch=np.degrees(pitch[k]),
                Yaw=np.degrees(yaw[k]) % 360)
    return out.text() if text else out.bytes(), run, t, unix_start_s


# ArduCopter 3.1-3.2 (2014): ms since boot, the second IMU its own type, the GPS message with
# the GPS time of week (TimeMS), Week and the boot time T (libraries/DataFlash/LogStructure.h
# of that release)
FORMATS_2014 = {
    "IMU": (131, "Iffffff", "TimeMS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ"),
    "IMU2": (132, "Iffffff", "TimeMS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ"),
    "GPS": (130, "BIHBcLLeeEefI", "Status,TimeMS,Week,NSats,HDop,Lat,Lng,RelAlt,Alt,Spd,GCrs,"
                                  "VZ,T"),
    "ATT": (133, "IccccCC", "TimeMS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw"),
}


def flight_2014(rate=100.0, unix_start_s=1404000000.0, boot_s=61.5):
    """(DataFlash bytes of a 2014 ArduCopter log, truth run, t, UNIX time of t = 0): IMU and
    IMU2 (TimeMS), GPS 3-D fixes at 5 Hz with Week/TimeMS/T, ATT; no EKF position."""
    saved = dict(FORMATS)
    FORMATS.clear()
    FORMATS.update(FORMATS_2014)
    try:
        motion = Profile.from_dict(PROFILE).motion()
        t = np.arange(0.0, motion.t1 - 1e-9, 1.0 / rate)
        run = truth.generate(motion, t)
        dt = np.diff(t)
        w, f = run.dtheta / dt[:, None], run.dv / dt[:, None]
        out = Writer()
        boot_ms = np.round((boot_s + t[1:]) * 1e3).astype(np.int64)
        for name, bias in (("IMU", 0.0), ("IMU2", 1e-3)):
            for k in range(len(boot_ms)):
                out.add(name, TimeMS=boot_ms[k], GyrX=w[k, 0] + bias, GyrY=w[k, 1],
                        GyrZ=w[k, 2], AccX=f[k, 0], AccY=f[k, 1], AccZ=f[k, 2])
        tr = run.trajectory
        yaw, pitch, roll = attitude.as_euler(tr.q_nb)
        leap_2014 = 16
        for k in range(0, len(t), int(rate / 5)):
            gps_s = unix_start_s + t[k] - GPS_EPOCH_UNIX_S + leap_2014
            week, tow = divmod(gps_s, 604800.0)
            vn, ve, vd = tr.v_ned[k]
            ms = int(round((boot_s + t[k]) * 1e3))
            out.add("GPS", Status=3, TimeMS=int(round(tow * 1e3)), Week=int(week), NSats=9,
                    HDop=1.2, Lat=np.degrees(tr.lat[k]), Lng=np.degrees(tr.lon[k]),
                    Alt=tr.h[k], Spd=np.hypot(vn, ve), GCrs=np.degrees(np.arctan2(ve, vn)) % 360,
                    VZ=vd, T=ms)
            out.add("ATT", TimeMS=ms, Roll=np.degrees(roll[k]), Pitch=np.degrees(pitch[k]),
                    Yaw=np.degrees(yaw[k]) % 360)
        return out.bytes(), run, t, unix_start_s
    finally:
        FORMATS.clear()
        FORMATS.update(saved)

"""Recordings that nobody here wrote, turned into contract logs (`mimunav-log/1`).

    rtklib   a CSV IMU log with RTKLIB time tags and an RTKLIB position solution
    ros2     any ROS 2 MCAP with sensor_msgs/msg/Imu (+ sensor_msgs/msg/NavSatFix), by topic
    ulog     a PX4 ULog (sensor_combined + vehicle_gps_position / sensor_gps), by pyulog

Each reader returns a `Recording` - the IMU in SI units and its own axes, the GNSS and
reference data it has, and what is measured and what is assumed - and `write_log` writes
it: `/mimu/imu` (calibrated units, not compensated beyond the recorder's own scaling),
`/truth/state` when an external reference exists (attitude unknown: NaN quaternion, and
`reference.attitude = "unknown"` in the metadata), `/gnss/fix` (latitude and longitude in
rad as the contract's conventions say - not ROS's degrees - and position_covariance ENU m^2), the `flight` metadata with
an `initial_state` from `alignment.initial_alignment`, `sensor/mimu`, and `recording` (what is
real, what was assumed).
"""
import json
from dataclasses import dataclass, field

import numpy as np

from .. import alignment, earth
from ..flightlog import LogWriter
from ..flightlog import schemas as S
from ..sensors import Mounting
from ..errors import InputError

UNKNOWN_ATTITUDE = np.full(4, np.nan)
GPS_EPOCH_UNIX_S = 315964800            # 1980-01-06T00:00:00Z, the start of GPS time
# GPS - UTC, s, from the GPS time (s since the GPS epoch) at which each took effect (IERS
# Bulletin C; none added after 2017-01-01)
LEAP_SECONDS = ((0, 0), (46828800, 7), (78364801, 8), (109900802, 9), (173059203, 10),
                (252028804, 11), (315187205, 12), (346723206, 13), (820108813, 14),
                (914803214, 15), (1025136015, 16), (1119744016, 17), (1167264017, 18))


class RecordingError(InputError):
    """A recording that cannot be turned into a contract log, with what and where."""


@dataclass
class Recording:
    """A foreign recording in SI units.

    imu_ns: IMU stamps, integer ns since the UNIX epoch (N,), strictly increasing;
    w: angular rate, rad/s, IMU sensor axes (N, 3); f: specific force, m/s^2 (N, 3);
    reference: optional external trajectory {ns, lat, lon (rad), h (m), v_ned (m/s, (M, 3)),
      optional q_nb (M, 4) wxyz vehicle FRD -> NED (NaN rows: unknown)}, described by
      `reference_meta` {source, independent ("yes"/"no: why"), position_sigma_m, ...};
    fixes: optional GNSS fixes {ns, lat, lon, h, status (int8 as
      in NavSatStatus), covariance (M, 9) m^2 ENU}; real / assumed: what the metadata says
      is measured and what this import assumed."""
    name: str
    description: str
    imu_ns: np.ndarray
    w: np.ndarray
    f: np.ndarray
    mounting: Mounting
    model: str = "unknown"
    reference: dict | None = None
    reference_meta: dict = field(default_factory=dict)
    fixes: dict | None = None
    real: dict = field(default_factory=dict)
    assumed: dict = field(default_factory=dict)

    def __post_init__(self):
        self.imu_ns = np.asarray(self.imu_ns, dtype=np.int64)
        n = len(self.imu_ns)
        for name in ("w", "f"):
            x = np.asarray(getattr(self, name), dtype=float)
            if x.shape != (n, 3):
                raise RecordingError(f"{self.name}: IMU {name} has shape {x.shape}, expected "
                                   f"({n}, 3)")
            setattr(self, name, x)
        if n < 2:
            raise RecordingError(f"{self.name}: fewer than two IMU samples")
        if np.any(np.diff(self.imu_ns) <= 0):
            k = int(np.argmax(np.diff(self.imu_ns) <= 0))
            raise RecordingError(f"{self.name}: IMU stamps do not increase at sample {k + 1}")
        bad = ~np.isfinite(np.hstack([self.w, self.f])).all(axis=1)
        if bad.any():
            raise RecordingError(f"{self.name}: {bad.sum()} IMU samples are not finite (first at "
                               f"sample {int(np.argmax(bad))}); a log must not carry them")

    @property
    def sample_rate_hz(self):
        return float(1e9 / np.median(np.diff(self.imu_ns)))


def gps_to_unix_s(gps_s):
    """UNIX (UTC) seconds of GPS times (s since 1980-01-06), the leap seconds then in force
    removed."""
    gps_s = np.asarray(gps_s, dtype=float)
    starts, leaps = np.array(LEAP_SECONDS).T
    return gps_s + GPS_EPOCH_UNIX_S - leaps[np.searchsorted(starts, gps_s, side="right") - 1]


def write_log(rec, path, force=False):
    """Write `rec` as a contract log at `path` (atomically; an existing file only with
    force). Returns the initial alignment (`alignment.Alignment`)."""
    epoch = int(rec.imu_ns[0])
    t = (rec.imu_ns - epoch) / 1e9
    ref = rec.reference
    align = alignment.initial_alignment(t, rec.w, rec.f, rec.mounting, _track(rec, epoch))
    initial = {"t": float(align.t), "latitude": float(align.lat), "longitude": float(align.lon),
               "height": float(align.h), "velocity_ned": list(map(float, align.v_ned)),
               "attitude_wxyz": list(map(float, align.q_nb))}
    assumed = dict(rec.assumed)
    assumed["initial_state"] = align.method
    rate = rec.sample_rate_hz
    with LogWriter(path, force=force) as log:
        log.metadata("flight", {
            "format": "mimunav-log/1", "name": rec.name, "description": rec.description,
            "epoch_unix_ns": str(epoch), "source": "recording", "initial_state": initial})
        log.metadata("sensor/mimu", {
            "model": rec.model, "sample_rate_hz": f"{rate:.6g}",
            "mounting": rec.mounting.as_dict()})      # range: unknown, not written
        log.metadata("recording", {"real": json.dumps(rec.real), "assumed": json.dumps(assumed),
                                   "gyro_bias_static_rad_s": list(map(float, align.gyro_bias)),
                                   "accel_bias_along_gravity_m_s2":
                                       list(map(float, align.accel_bias)),
                                   "static_s": (None if np.isnan(align.static[0]) else
                                                [float(align.static[0]), float(align.static[1])]),
                                   "observed_max": {"gyro_rad_s": float(np.abs(rec.w).max()),
                                                    "accel_m_s2": float(np.abs(rec.f).max())}})
        log.write("/mimu/imu", S.IMU, "mimu", rec.imu_ns, **S.imu_fields(rec.w, rec.f))
        if ref is not None:
            q = ref.get("q_nb")
            known = q is not None and np.isfinite(q).all(axis=1).any()
            meta = {"source": rec.real.get("reference", "external"),
                    "attitude": "measured" if known else "unknown", "velocity": "measured"}
            meta.update({k: str(v) for k, v in rec.reference_meta.items()})
            log.metadata("reference", meta)
            log.write("/truth/state", S.NAV_STATE, "vehicle", ref["ns"],
                      latitude=ref["lat"], longitude=ref["lon"], height=ref["h"],
                      velocity_ned=ref["v_ned"],
                      attitude_wxyz=q if known else np.tile(UNKNOWN_ATTITUDE, (len(ref["ns"]), 1)))
        if rec.fixes is not None:
            fx = rec.fixes
            log.metadata("gnss", {"latitude_longitude": "rad (log contract conventions)",
                                  "position_covariance": "m^2, ENU"})
            log.write("/gnss/fix", S.NAV_SAT_FIX, "gnss", fx["ns"], status=fx["status"],
                      service=np.ones(len(fx["ns"]), np.uint16), latitude=fx["lat"],
                      longitude=fx["lon"], altitude=fx["h"],
                      position_covariance=fx["covariance"],
                      position_covariance_type=np.full(len(fx["ns"]), 2, np.uint8))
    return align


def _track(rec, epoch):
    """The trajectory the alignment takes heading from (t s since epoch, lat, lon, h,
    v_ned): the reference, else the GNSS fixes (their velocity when recorded, else central
    differences of their positions), else None."""
    src = rec.reference if rec.reference is not None else rec.fixes
    if src is None or len(src["ns"]) < 3:
        return None
    t = (np.asarray(src["ns"], np.int64) - epoch) / 1e9
    v = src.get("v_ned")
    if v is None:
        ned = earth.ned_difference(src["lat"], src["lon"], src["h"], src["lat"][0],
                                   src["lon"][0], src["h"][0])
        v = np.gradient(ned, t, axis=0)
    return dict(t=t, lat=src["lat"], lon=src["lon"], h=src["h"], v_ned=v, q_nb=src.get("q_nb"),
                attitude_source=rec.reference_meta.get("source", "the reference"))

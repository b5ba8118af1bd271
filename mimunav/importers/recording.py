"""A foreign recording in SI units (`Recording`), what every importer returns, and the
time bases importers share (GPS time, leap seconds, counters that wrap).
"""
import contextlib
from dataclasses import dataclass, field

import numpy as np

from ..frames import attitude
from ..frames.mounting import Mounting
from .kinds import VEHICLES
from ..errors import InputError
from ..flightlog.stamps import longest_gap, mean_rate_hz, missing_samples, scheduled


UNKNOWN_ATTITUDE = np.full(4, np.nan)
G0 = 9.80665                # m/s^2, standard gravity: the size a check of units compares with
GPS_EPOCH_UNIX_S = 315964800            # 1980-01-06T00:00:00Z, the start of GPS time
# GPS - UTC, s, from the GPS time (s since the GPS epoch) at which each took effect (IERS
# Bulletin C; none added after 2017-01-01)
LEAP_SECONDS = ((0, 0), (46828800, 7), (78364801, 8), (109900802, 9), (173059203, 10),
                (252028804, 11), (315187205, 12), (346723206, 13), (820108813, 14),
                (914803214, 15), (1025136015, 16), (1119744016, 17), (1167264017, 18))


class RecordingError(InputError):
    """A recording that cannot be turned into a contract log, with what and where."""


QUATERNION_SCALE = 0.01    # |q| held by every row within 1e-3 of one value this near 1 is
#                            a device's scale of its quaternions (an NGIMU writes 0.99831),
#                            which normalising removes; an attitude's rows vary by far less


def unit_quaternions(wxyz, where):
    """Rows of w, x, y, z as unit quaternions (an array of them), each divided by its
    length; refused, naming `where` and the worst row, where a row lies further than 1e-3
    from unit length - or from the one length every row holds within QUATERNION_SCALE of 1
    - (not an attitude: a rotation vector, angles or another column among the four; an
    order of the four leaves |q| alike)."""
    q = attitude.from_wxyz(wxyz)
    norm = np.abs(q)
    held = float(np.median(norm))
    if abs(held - 1) > QUATERNION_SCALE or np.any(np.abs(norm - held) > 1e-3):
        held = held if abs(held - 1) <= QUATERNION_SCALE else 1.0
        k = int(np.argmax(np.abs(norm - held)))
        raise RecordingError(f"{where} is no unit quaternion (|q| {norm[k]:.4g} at row {k}): "
                             "are the four columns an attitude's w, x, y, z - no rotation "
                             "vector, angle or other column among them?")
    return q / norm


def heading_source(heading, reference_heading_known):
    """Where an initial heading came from (`alignment.Alignment.heading`: reference, course or
    assumed) as the log's `initial_heading` says it: a heading taken from a reference, or from
    its course, in a frame of unknown azimuth measures nothing - assumed."""
    return heading if reference_heading_known is not False else "assumed"


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
      is measured and what this import assumed;
    reference_imu: optional second IMU flown with it that serves as the reference IMU
      (/fog/imu: the sensor level of the diagnosis) {ns, w rad/s, f m/s^2 (its sensor axes),
      mounting (`Mounting`), model, optional accuracy (`sensors.accuracy.Accuracy` keys)}."""
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
    reference_imu: dict | None = None
    vehicle: str | None = None      # what carried the IMU, one of VEHICLES, when declared
    reference_shift_s: float = 0.0  # what --reference-time-offset (or a spec) added, s
    reference_imu_offset_given: bool = False    # an offset of the reference IMU's stamps
    #                                   was given (--reference-imu-time-offset, a spec's
    #                                   [reference_imu] time_offset_s): it picks the clock's
    #                                   lobe where the data find rivals (`pairing`)
    reference_imu_clock_se_s: float | None = None   # the standard error (s) of the
    #                                   reference IMU's clock where `pairing` measured it
    range: dict = field(default_factory=dict)   # the IMU's full scale when known: gyro_rad_s,
                                                # accel_m_s2 (outputs at it are clipped)
    sampled_at_instants: bool = False   # the IMU's samples were instantaneous, made interval
    #                                     means at import (`aliasing` asks what they folded)
    aliased: dict = field(default_factory=dict)     # {sensor: why} (`aliasing.aliased`)
    reference_imu_moved: str = ""   # why no one mounting holds the pair (`pairing`), or ''
    reference_imu_clock_open: str = ""  # the clock search's words where it left the stamps
    #                                     as given without finding them its peak (`pairing`)
    imu_point_off: str = ""     # where the IMU's forces place the trajectory's point off the
    #                             reference IMU's (`trajectory_point`), or ''
    mounting_off_kept: str = ""     # a mounting measured off the reference's attitude beyond
    #                                 its standard errors and kept as given (`attitude_check`)
    trajectory_point_off: str = ""  # where the reference trajectory's point is measured off
    #                                 the origin and left there (`trajectory_point`), or ''
    reference_clock_unapplied_s: float | None = None    # the reference trajectory's lag
    #                                   (s, its stamps late) the import measured and left to
    #                                   the diagnosis as the IMU's latency, not applied
    reference_clock_open: str = ""  # the same of the reference trajectory's clock, where the
    #                                 data peak away from its stamps among rivals (`checks`)
    clip_spans_ns: list = field(default_factory=list)   # [(t0, t1 ns, clips)] where an IMU's
    #                                     own clip counter rose (`clip_counts`), on imu_ns's clock
    reference_heading_known: bool = True    # False: the reference lies in a local frame whose
                                            # azimuth is not known (`local_frame`)

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
            raise RecordingError(f"{self.name}: IMU stamps do not increase at sample {k + 1}"
                                 + _wrap_hint(self.imu_ns[k + 1] - self.imu_ns[k]))
        bad = ~np.isfinite(np.hstack([self.w, self.f])).all(axis=1)
        if bad.any():
            raise RecordingError(f"{self.name}: {bad.sum()} IMU samples are not finite (first at "
                               f"sample {int(np.argmax(bad))}); a log must not carry them")
        if self.reference_imu is not None:
            self.reference_imu = _checked_reference_imu(self.name, self.reference_imu)
        if self.vehicle is not None and self.vehicle not in VEHICLES:
            raise RecordingError(f"{self.name}: vehicle {self.vehicle!r}: one of "
                                 f"{', '.join(VEHICLES)}")

    def shift_reference_imu(self, offset_s, why, drift=0.0, at_s=0.0):
        """Add offset_s (s) to the reference IMU's stamps - and drift (s/s) times their time
        from at_s (s, the grid of `pairing`: stamps in s), a clock running at another rate -,
        saying so (`why`) in the assumed metadata."""
        if self.reference_imu is None:
            raise InputError("--reference-imu-time-offset: the recording has no reference IMU "
                             "(--reference-imu-topic, [reference_imu], --reference-imu-instance)")
        ns = self.reference_imu["ns"]
        slope = np.round(drift * (ns / 1e9 - at_s) * 1e9).astype(np.int64) if drift else 0
        self.reference_imu["ns"] = ns + int(round(offset_s * 1e9)) + slope
        if np.any(np.diff(self.reference_imu["ns"]) <= 0):
            raise RecordingError(f"{self.name}: the reference IMU's stamps, shifted by the "
                                 "clock measured, no longer increase")
        self._say_shift("reference_imu_time", offset_s, why)

    def shift_reference(self, offset_s, why):
        """Add offset_s (s) to the reference trajectory's and the GNSS fixes' stamps, saying
        so (`why`) in the assumed metadata."""
        if self.reference is None and self.fixes is None:
            raise InputError("--reference-time-offset: the recording has no reference "
                             "trajectory or GNSS fixes")
        step = int(round(offset_s * 1e9))
        for part in (self.reference, self.fixes):
            if part is not None:
                part["ns"] = np.asarray(part["ns"], dtype=np.int64) + step
        self.reference_shift_s += offset_s
        self._say_shift("reference_time", offset_s, why)

    def _say_shift(self, key, offset_s, why):
        """Say in the assumed metadata (`key`) that stamps were shifted by offset_s (s)."""
        said = f"its stamps shifted by {offset_s:+.4f} s ({why})"
        before = self.assumed.get(key)
        self.assumed[key] = f"{before}; then {said}" if before else said

    @property
    def sample_rate_hz(self):
        """The IMU's sample rate (Hz): `flightlog.stamps.mean_rate_hz`."""
        return mean_rate_hz(self.imu_ns)


@contextlib.contextmanager
def text_file(path):
    """Turn a UnicodeDecodeError while reading `path` as text into a RecordingError naming
    the file (a binary or damaged file where a text one belongs)."""
    try:
        yield
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{path}: not a text file (byte {exc.object[exc.start]:#04x} at "
                             f"offset {exc.start} is not UTF-8): is it the right file, or "
                             "damaged?") from None


def _checked_reference_imu(name, ref):
    """The reference IMU dict with ns int64, w and f (N, 3) float, its stamps increasing and
    its values finite - else a RecordingError naming it."""
    ref = dict(ref)
    ref["ns"] = np.asarray(ref["ns"], dtype=np.int64)
    n = len(ref["ns"])
    for key in ("w", "f"):
        ref[key] = np.asarray(ref[key], dtype=float)
        if ref[key].shape != (n, 3):
            raise RecordingError(f"{name}: reference IMU {key} has shape {ref[key].shape}, "
                                 f"expected ({n}, 3)")
    if n < 2 or np.any(np.diff(ref["ns"]) <= 0):
        raise RecordingError(f"{name}: the reference IMU's stamps do not increase (or fewer "
                             "than two samples)")
    bad = ~np.isfinite(np.hstack([ref["w"], ref["f"]])).all(axis=1)
    if bad.any():
        raise RecordingError(f"{name}: {bad.sum()} reference IMU samples are not finite (first "
                             f"at sample {int(np.argmax(bad))})")
    return ref


# counters that loggers stamp with, and the jump back their wrap makes (ns)
COUNTER_WRAPS = {"a 32-bit microsecond counter": 2**32 * 1000, "a 32-bit millisecond counter":
                 2**32 * 1_000_000, "a 16-bit millisecond counter": 2**16 * 1_000_000}


def _wrap_hint(step_ns):
    """': ... wrapped' when a step back of step_ns (< 0) is a known counter's wrap, else ''."""
    for what, span in COUNTER_WRAPS.items():
        if abs(-int(step_ns) - span) < 0.01 * span:
            return (f" (back by {-int(step_ns) / 1e9:.6g} s: {what} wrapped there; unwrap the "
                    f"time column by adding {span / 1e9:.6g} s after each wrap)")
    return ""


def gps_to_unix_s(gps_s):
    """UNIX (UTC) seconds of GPS times (s since 1980-01-06), the leap seconds then in force
    removed."""
    gps_s = np.asarray(gps_s, dtype=float)
    starts, leaps = np.array(LEAP_SECONDS).T
    return gps_s + GPS_EPOCH_UNIX_S - leaps[np.searchsorted(starts, gps_s, side="right") - 1]


def attitude_at(t, t_att, wxyz):
    """Attitudes (M, 4) wxyz at times t (M,) by slerp between the recorded attitudes wxyz
    (K, 4) at increasing times t_att (K,) (same time unit); NaN outside their span."""
    from scipy.spatial.transform import Slerp
    q = np.full((len(t), 4), np.nan)
    inside = (t >= t_att[0]) & (t <= t_att[-1])
    turns = Slerp(t_att, attitude.as_scipy(attitude.from_wxyz(np.asarray(wxyz))))
    q[inside] = attitude.as_wxyz(attitude.from_scipy(turns(np.asarray(t, float)[inside])))
    return q


def utc_text(ns):
    return np.datetime_as_string(np.datetime64(int(ns), "ns"), unit="s") + "Z"


def rate_onto(t, t_w, w, what, unit_s=1.0):
    """(keep (M,) bool, w at t[keep] (K, 3), said or None): a gyro sampled on its own clock
    (times t_w) interpolated linearly onto the specific force's times t (both in units of
    unit_s seconds; M samples). A specific force stamped inside a gap of the gyro's stamps
    (`flightlog.stamps.missing_samples`) has no angular rate beside it: it is left out, so
    the log shows the gap, not a rate drawn across it (2 s of a turn's gyro rows missing
    had been bridged by a line: 16 deg of the turn's 86). `what` names the gyro in `said`."""
    gaps = missing_samples(np.round((t_w - t_w[0]) * unit_s * 1e9).astype(np.int64))
    keep = (t >= t_w[0]) & (t <= t_w[-1])
    inside = keep.copy()
    for k, _ in gaps:
        keep &= ~((t > t_w[k]) & (t < t_w[k + 1]))
    w_at = np.column_stack([np.interp(t[keep], t_w, w[:, i]) for i in range(w.shape[1])])
    if not gaps:
        return keep, w_at, None
    k = longest_gap(t_w, gaps)[0]
    said = (f"{what} misses {sum(m for _, m in gaps)} samples in {len(gaps)} gaps (longest "
            f"{(t_w[k + 1] - t_w[k]) * unit_s:.4g} s, from {(t_w[k] - t_w[0]) * unit_s:.6g} s "
            f"of its record): the {int(np.sum(inside & ~keep))} specific-force samples inside "
            "them left out" + (f"; {regular}" if (regular := scheduled(gaps)) else ""))
    return keep, w_at, said


def at_range(w, f, rng):
    """(N,) bool: the samples with an output at the sensor's range `rng` (a Recording's
    `range`: gyro_rad_s, accel_m_s2; within 0.1 %) on some axis - clipped, or about to be."""
    at = np.zeros(len(w), bool)
    for x, key in ((w, "gyro_rad_s"), (f, "accel_m_s2")):
        if key in rng:
            at |= (np.abs(x) >= 0.999 * rng[key]).any(axis=1)
    return at

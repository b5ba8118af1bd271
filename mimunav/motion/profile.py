"""Flight profiles: a start state and segments a flight-test engineer writes, turned into
a smooth, analytic true motion (`ProfileMotion`).

A profile is a TOML file (see `flights/*.toml`):

    name = "..."                  description = "..."
    [start]   latitude_deg, longitude_deg, height_m, speed_m_s, heading_deg,
              flight_path_deg (= pitch), roll_deg, optional ramp_s (default 0.5)
    [[segment]] kind = ...         one table per segment, in flight order

Segment kinds (angles in deg, positive right/up; every segment accepts ramp_s):
    hold | coast   duration_s                       keep speed, path, heading, bank
    accelerate     accel_g (signed), duration_s | to_speed_m_s
    turn           load_factor (> 1), heading_change_deg (signed), roll_rate_deg_s (60)
    pull           load_factor (!= 1), flight_path_change_deg (signed, matching n - 1)
    climb | dive   flight_path_deg, duration_s, load_factor (2; pull-in and level-off)
    roll           rate_deg_s, angle_deg (signed)

Kinematic model. Four channels define the motion: speed V, flight-path angle gamma,
track/heading chi and bank phi. The vehicle flies with zero angle of attack and sideslip:
attitude yaw = chi, pitch = gamma, roll = phi, and v_ned = V (cos g cos c, cos g sin c, -sin g).
Each segment changes a channel's *rate* along a smooth trapezoid: the rate rises from 0 to
its peak along a quintic smootherstep s(x) = 6x^5 - 15x^4 + 10x^3 over `ramp_s`, holds, and
falls back the same way, so rates are C2 and channels C3 (continuous angular
acceleration and jerk). Load factors set peak rates at the segment's entry state:
turn rate = g0 tan(phi)/V (coordinated in the steady turn), pull rate = g0 (n - 1)/V.
"""
import math
import tomllib
from dataclasses import dataclass, field

import numpy as np
import quaternion
from scipy.interpolate import PPoly

from .truth import Kinematics, Motion
from ..kernels import njit
from ..errors import InputError

G0 = 9.80665        # standard gravity, m/s^2: the unit of load factors and accel_g
SPEED, PATH, HEADING, BANK = range(4)
_SMOOTHERSTEP = np.array([0, 0, 0, 10, -15, 6], dtype=float)   # ascending powers of x


def dumps(doc):
    """A profile document (the dict `Profile.from_dict` takes) as TOML text."""
    lines = [f'name = "{doc["name"]}"', f'description = "{doc.get("description", "")}"',
             "[start]"]
    lines += [f"{k} = {v}" for k, v in doc["start"].items()]
    for seg in doc["segment"]:
        lines.append("[[segment]]")
        lines += [f'{k} = "{v}"' if isinstance(v, str) else f"{k} = {v}" for k, v in seg.items()]
    return "\n".join(lines) + "\n"


class ProfileError(InputError):
    """A flight profile that cannot be flown as written."""


@dataclass
class Ramp:
    """One rate trapezoid on one channel: rate 0 -> peak -> 0 between t0 and t1, s."""
    channel: int
    t0: float
    t1: float
    peak: float
    ramp: float

    @property
    def change(self):
        """Total change of the channel over the trapezoid (peak * (t1 - t0 - ramp))."""
        return self.peak * (self.t1 - self.t0 - self.ramp)


@dataclass
class Profile:
    """A parsed flight profile. Start values in SI (rad, m, m/s)."""
    name: str
    description: str
    start: dict
    segments: list
    ramps: list = field(default_factory=list)
    duration: float = 0.0

    @classmethod
    def load(cls, path, severity=1.0):
        """A profile from its TOML file; `severity` != 1 scales its dynamics
        (`scale_severity`)."""
        with open(path, "rb") as fh:
            try:
                doc = tomllib.load(fh)
            except tomllib.TOMLDecodeError as exc:
                raise ProfileError(f"{path}: not valid TOML: {exc}") from None
        if severity != 1.0:
            doc = scale_severity(doc, severity)
        return cls.from_dict(doc, source=str(path))

    @classmethod
    def from_dict(cls, doc, source="profile"):
        _known(doc, TOP_KEYS, source)
        start_doc = dict(doc.get("start", {}))
        need = ["latitude_deg", "longitude_deg", "height_m", "speed_m_s", "heading_deg"]
        missing = [k for k in need if k not in start_doc]
        if missing:
            raise ProfileError(f"{source}: [start] lacks {', '.join(missing)}")
        _known(start_doc, START_KEYS, f"{source}: [start]")
        for key, (lo, hi) in START_KEYS.items():
            if key in start_doc:
                _number(start_doc[key], lo, hi, f"{source}: [start] {key}")
        start = dict(lat=math.radians(start_doc["latitude_deg"]),
                     lon=math.radians(start_doc["longitude_deg"]),
                     h=float(start_doc["height_m"]), speed=float(start_doc["speed_m_s"]),
                     path=math.radians(start_doc.get("flight_path_deg", 0.0)),
                     heading=math.radians(start_doc["heading_deg"]),
                     bank=math.radians(start_doc.get("roll_deg", 0.0)),
                     ramp=float(start_doc.get("ramp_s", 0.5)))
        if abs(start["lat"]) > math.radians(89):
            raise ProfileError(f"{source}: start latitude must be within +-89 deg")
        segments = doc.get("segment", [])
        if not segments:
            raise ProfileError(f"{source}: no [[segment]] tables")
        for i, seg in enumerate(segments):
            where = f"{source}: segment {i + 1} ({seg.get('kind', '?')})"
            if seg.get("kind") not in SEGMENT_KEYS:
                raise ProfileError(f"{where}: unknown kind; one of {', '.join(SEGMENT_KEYS)}")
            _known(seg, {"kind": None, "ramp_s": None, **SEGMENT_KEYS[seg["kind"]]}, where)
            for key, value in seg.items():
                if key != "kind":
                    _number(value, *VALUE_RANGES[key], f"{where}: {key}")
        prof = cls(doc.get("name", source), doc.get("description", ""), start, segments)
        prof._plan(source)
        return prof

    def _plan(self, source):
        """Turn segments into rate trapezoids, tracking the channels' values."""
        state = [self.start["speed"], self.start["path"], self.start["heading"],
                 self.start["bank"]]
        t = 0.0
        for i, seg in enumerate(self.segments):
            where = f"{source}: segment {i + 1} ({seg.get('kind', '?')})"
            try:
                ramps, t_end = _segment_ramps(seg, t, state, self.start["ramp"])
            except (KeyError, TypeError) as exc:
                raise ProfileError(f"{where}: missing or bad key {exc}") from None
            except ProfileError as exc:
                raise ProfileError(f"{where}: {exc}") from None
            for r in ramps:
                state[r.channel] += r.change
                if state[SPEED] < -1e-9:
                    raise ProfileError(f"{where}: speed would become negative")
                if abs(state[PATH]) > math.radians(85):
                    raise ProfileError(f"{where}: flight-path angle beyond +-85 deg "
                                       "(Euler pitch singularity)")
            self.ramps += ramps
            t = t_end
        self.duration = t
        if t > MAX_DURATION_S:
            raise ProfileError(f"{source}: the profile lasts {t:.4g} s; at most "
                               f"{MAX_DURATION_S:g} s (24 h) per flight")

    def motion(self):
        return ProfileMotion(self)


def _segment_ramps(seg, t, state, default_ramp):
    """Rate trapezoids of one segment starting at t, and the segment's end time."""
    kind = seg["kind"]
    ramp = float(seg.get("ramp_s", default_ramp))
    if ramp <= 0:
        raise ProfileError("ramp_s must be positive")
    speed = state[SPEED]
    if kind in ("hold", "coast"):
        return [], t + _positive(seg, "duration_s")
    if kind == "accelerate":
        acc = float(seg["accel_g"]) * G0
        if acc == 0:
            raise ProfileError("accel_g must be non-zero")
        if "to_speed_m_s" in seg:
            dv = float(seg["to_speed_m_s"]) - speed
            if dv * acc <= 0:
                raise ProfileError("to_speed_m_s is not reached with this accel_g sign")
            length = dv / acc + ramp
        else:
            length = _positive(seg, "duration_s")
        _fits(length, 2 * ramp)
        return [Ramp(SPEED, t, t + length, acc, ramp)], t + length
    if kind == "roll":
        rate = math.radians(_positive(seg, "rate_deg_s"))
        angle = math.radians(float(seg["angle_deg"]))
        length = abs(angle) / rate + ramp
        return [Ramp(BANK, t, t + length, math.copysign(rate, angle), ramp)], t + length
    if kind in ("turn", "pull", "climb", "dive") and speed < 1.0:
        raise ProfileError(f"a {kind} needs forward speed (have {speed:.3g} m/s)")
    if kind == "turn":
        n = float(seg["load_factor"])
        if n <= 1:
            raise ProfileError("a level turn needs load_factor > 1")
        change = math.radians(float(seg["heading_change_deg"]))
        bank = math.copysign(math.acos(1 / n), change) - state[BANK]
        roll_rate = math.radians(float(seg.get("roll_rate_deg_s", 60.0)))
        roll_len = abs(bank) / roll_rate + ramp
        turn_rate = math.copysign(G0 * math.sqrt(n * n - 1) / speed, change)
        steady = abs(change / turn_rate) - roll_len
        if steady < 0:
            raise ProfileError("heading change too small for this load factor and roll rate")
        t_out = t + roll_len + steady
        return [Ramp(BANK, t, t + roll_len, math.copysign(roll_rate, bank), ramp),
                Ramp(HEADING, t, t_out + roll_len, turn_rate, roll_len),
                Ramp(BANK, t_out, t_out + roll_len, -math.copysign(roll_rate, bank), ramp)
                ], t_out + roll_len
    if kind == "pull":
        return _pull(float(seg["load_factor"]), math.radians(
            float(seg["flight_path_change_deg"])), t, speed, ramp)
    if kind in ("climb", "dive"):
        target = math.radians(float(seg["flight_path_deg"]))
        n = float(seg.get("load_factor", 2.0))
        up = target - state[PATH]
        r_in, t1 = _pull(n if up > 0 else 2 - n, up, t, speed, ramp)
        t2 = t1 + _positive(seg, "duration_s")
        r_out, t3 = _pull(2 - n if up > 0 else n, -up, t2, speed, ramp)
        return r_in + r_out, t3
    raise ProfileError(f"unknown kind {kind!r}")


def _pull(n, change, t, speed, ramp):
    rate = G0 * (n - 1) / speed
    if rate * change <= 0:
        raise ProfileError(f"load factor {n:g} cannot change the flight path by "
                           f"{math.degrees(change):+.3g} deg (pull-up needs n > 1, "
                           "push-over n < 1)")
    length = change / rate + ramp
    _fits(length, 2 * ramp)
    return [Ramp(PATH, t, t + length, rate, ramp)], t + length


TOP_KEYS = {"name": None, "description": None, "start": None, "segment": None}
# [start] keys and their ranges (deg, m, m/s, s): the Euler pitch singularity, the WGS-84
# normal gravity's validity (up to ~20 km above the ellipsoid it is good to 1e-6 g; the
# range allows suborbital profiles), speeds below orbital
START_KEYS = {"latitude_deg": (-89.0, 89.0), "longitude_deg": (-360.0, 360.0),
              "height_m": (-1000.0, 100e3), "speed_m_s": (0.0, 7800.0),
              "heading_deg": (-360.0, 720.0), "flight_path_deg": (-85.0, 85.0),
              "roll_deg": (-180.0, 180.0), "ramp_s": (1e-3, 3600.0)}
SEGMENT_KEYS = {"hold": {"duration_s": None}, "coast": {"duration_s": None},
                "accelerate": {"accel_g": None, "duration_s": None, "to_speed_m_s": None},
                "turn": {"load_factor": None, "heading_change_deg": None,
                         "roll_rate_deg_s": None},
                "pull": {"load_factor": None, "flight_path_change_deg": None},
                "climb": {"flight_path_deg": None, "duration_s": None, "load_factor": None},
                "dive": {"flight_path_deg": None, "duration_s": None, "load_factor": None},
                "roll": {"rate_deg_s": None, "angle_deg": None}}
VALUE_RANGES = {"duration_s": (0.0, 86400.0), "ramp_s": (1e-3, 3600.0),
                "accel_g": (-100.0, 100.0), "to_speed_m_s": (0.0, 7800.0),
                "load_factor": (-20.0, 100.0), "heading_change_deg": (-36000.0, 36000.0),
                "roll_rate_deg_s": (1e-3, 3600.0), "flight_path_change_deg": (-170.0, 170.0),
                "flight_path_deg": (-85.0, 85.0), "rate_deg_s": (1e-3, 3600.0),
                "angle_deg": (-36000.0, 36000.0)}
MAX_DURATION_S = 86400.0


def scale_severity(doc, s):
    """A profile document (TOML dict) with its dynamics scaled by s > 0: accelerations
    accel_g x s, load factors n -> 1 + s (n - 1) (the g exposure above 1 g), roll and turn-in
    rates x s; angles, speeds reached and hold durations kept, so a milder flight flies the
    same manoeuvres more slowly. Named NAME@s."""
    if not (isinstance(s, (int, float)) and 0 < s <= 10):
        raise ProfileError(f"severity must be in (0, 10], got {s!r}")
    out = dict(doc, segment=[dict(seg) for seg in doc.get("segment", [])])
    out["name"] = f"{doc.get('name', 'profile')}@{s:g}"
    for seg in out["segment"]:
        for key in ("accel_g", "rate_deg_s", "roll_rate_deg_s"):
            if key in seg:
                seg[key] = seg[key] * s
        if "load_factor" in seg:
            seg["load_factor"] = 1 + s * (seg["load_factor"] - 1)
    return out


def _known(doc, keys, where):
    unknown = sorted(set(doc) - set(keys))
    if unknown:
        raise ProfileError(f"{where}: unknown key(s) {', '.join(unknown)}; known: "
                           f"{', '.join(keys)}")


def _number(value, lo, hi, where):
    """A finite number within [lo, hi] (bool and text refused)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value):
        raise ProfileError(f"{where} = {value!r}: a finite number is needed")
    if not lo <= value <= hi:
        raise ProfileError(f"{where} = {value!r}: outside [{lo:g}, {hi:g}]")
    return float(value)


def _positive(seg, key):
    value = float(seg[key])
    if not value > 0:
        raise ProfileError(f"{key} must be positive")
    return value


def _fits(length, need):
    if length < need:
        raise ProfileError(f"segment of {length:.3g} s is shorter than its two ramps "
                           f"({need:.3g} s): reduce ramp_s or lengthen it")


def _taylor_shift(c, d):
    """Coefficients (ascending) of p(u + d) given those of p(u)."""
    n = len(c)
    out = np.zeros(n)
    for j in range(n):
        for m in range(j + 1):
            out[m] += c[j] * math.comb(j, m) * d ** (j - m)
    return out


def rate_ppoly(ramps, t_end):
    """One PPoly with the four channels' rates (c shape (6, intervals, 4))."""
    pieces = []          # (channel, a, b, ascending coefficients in (t - a))
    for r in ramps:
        up = r.peak * _SMOOTHERSTEP / r.ramp ** np.arange(6)
        down = r.peak * np.array([1, 0, 0, -10, 15, -6]) / r.ramp ** np.arange(6)
        pieces.append((r.channel, r.t0, r.t0 + r.ramp, up))
        if r.t1 - r.ramp > r.t0 + r.ramp:
            pieces.append((r.channel, r.t0 + r.ramp, r.t1 - r.ramp,
                           np.array([r.peak, 0, 0, 0, 0, 0])))
        pieces.append((r.channel, r.t1 - r.ramp, r.t1, down))
    x = np.unique(np.concatenate([[0.0, t_end], [p[1] for p in pieces],
                                  [p[2] for p in pieces]]))
    c = np.zeros((6, len(x) - 1, 4))
    for ch, a, b, coef in pieces:
        for i in np.nonzero((x[:-1] >= a) & (x[1:] <= b))[0]:
            c[:, i, ch] += _taylor_shift(coef, x[i] - a)[::-1]
    return PPoly(c, x, extrapolate=True)


class ProfileMotion(Motion):
    """The analytic true motion of a `Profile` (see the module doc for the model)."""

    def __init__(self, profile):
        self.profile = profile
        s = profile.start
        self.t0, self.t1 = 0.0, profile.duration
        self.lat0, self.lon0, self.h0 = s["lat"], s["lon"], s["h"]
        rate = rate_ppoly(profile.ramps, profile.duration)
        value = rate.antiderivative()
        value.c[-1] += np.array([s["speed"], s["path"], s["heading"], s["bank"]])
        self.knots = rate.x
        self._c = np.ascontiguousarray(value.c)      # (7, intervals, 4), descending powers

    def channels(self, t):
        """Speed m/s, flight-path angle, heading, bank (rad) at times t, shape (N, 4)."""
        t = np.asarray(t, dtype=float)
        idx = np.clip(np.searchsorted(self.knots, t, side="right") - 1, 0, len(self.knots) - 2)
        u = t - self.knots[idx]
        return sum(self._c[j, idx] * u[:, None] ** (6 - j) for j in range(7))

    def kinematics(self, t):
        t = np.ascontiguousarray(t, dtype=float)
        n = len(t)
        v, a, q = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 4))
        w, dw = np.empty((n, 3)), np.empty((n, 3))
        _euler_kinematics(t, self.knots, self._c, v, a, q, w, dw)
        return Kinematics(v, a, quaternion.as_quat_array(q), w, dw)


@njit(nogil=True, error_model="numpy")
def _euler_kinematics(t, knots, c, v_ned, a_ned, q_nb, w_nb, dw_nb):
    """Channels (V, gamma, chi, phi) and two derivatives by Horner's rule on the piecewise
    polynomial (its interval: the previous time's when it holds t, else found by bisection;
    the first or last beyond the knots), then NED velocity, its rate, q_nb (z-y-x Euler:
    chi, gamma, phi), and the body rate from the Euler-angle rates with its derivative
    (T&W eq. 3.29 inverted):
        p = phi' - chi' sin g,  q = g' cos phi + chi' cos g sin phi,
        r = -g' sin phi + chi' cos g cos phi."""
    deg = c.shape[0] - 1
    last = knots.shape[0] - 2
    y, dy, ddy = np.empty(4), np.empty(4), np.empty(4)
    i = 0
    for k in range(t.shape[0]):
        if not knots[i] <= t[k] < knots[i + 1]:
            i = min(max(np.searchsorted(knots, t[k], side="right") - 1, 0), last)
        u = t[k] - knots[i]
        for ch in range(4):
            p0, p1, p2 = c[0, i, ch], 0.0, 0.0
            for j in range(1, deg + 1):
                p2 = p2 * u + 2.0 * p1
                p1 = p1 * u + p0
                p0 = p0 * u + c[j, i, ch]
            y[ch], dy[ch], ddy[ch] = p0, p1, p2
        V, dV = y[0], dy[0]
        g, dg, ddg = y[1], dy[1], ddy[1]
        x, dx, ddx = y[2], dy[2], ddy[2]
        p, dp, ddp = y[3], dy[3], ddy[3]
        # half angles for q_nb, the full angles' sin and cos from them (6 calls, not 12)
        chy, shy = math.cos(0.5 * x), math.sin(0.5 * x)
        chp, shp = math.cos(0.5 * g), math.sin(0.5 * g)
        chr_, shr = math.cos(0.5 * p), math.sin(0.5 * p)
        sg, cg = 2.0 * shp * chp, (chp - shp) * (chp + shp)
        sx, cx = 2.0 * shy * chy, (chy - shy) * (chy + shy)
        sp, cp = 2.0 * shr * chr_, (chr_ - shr) * (chr_ + shr)
        ux, uy, uz = cg * cx, cg * sx, -sg
        dux = -sg * cx * dg - cg * sx * dx
        duy = -sg * sx * dg + cg * cx * dx
        duz = -cg * dg
        v_ned[k, 0], v_ned[k, 1], v_ned[k, 2] = V * ux, V * uy, V * uz
        a_ned[k, 0] = dV * ux + V * dux
        a_ned[k, 1] = dV * uy + V * duy
        a_ned[k, 2] = dV * uz + V * duz
        q_nb[k, 0] = chy * chp * chr_ + shy * shp * shr
        q_nb[k, 1] = chy * chp * shr - shy * shp * chr_
        q_nb[k, 2] = chy * shp * chr_ + shy * chp * shr
        q_nb[k, 3] = shy * chp * chr_ - chy * shp * shr
        w_nb[k, 0] = dp - dx * sg
        w_nb[k, 1] = dg * cp + dx * cg * sp
        w_nb[k, 2] = -dg * sp + dx * cg * cp
        dw_nb[k, 0] = ddp - ddx * sg - dx * cg * dg
        dw_nb[k, 1] = (ddg * cp - dg * sp * dp + ddx * cg * sp - dx * sg * dg * sp
                       + dx * cg * cp * dp)
        dw_nb[k, 2] = (-ddg * sp - dg * cp * dp + ddx * cg * cp - dx * sg * dg * cp
                       - dx * cg * sp * dp)

"""Quaternion strapdown navigator in the local NED frame on the rotating WGS-84 Earth.

The same navigator serves every IMU (MIMU, FOG-IMU, ideal), so comparisons are fair.
Inputs are body angle increments dtheta (rad) and velocity increments dv (m/s) over the
intervals (t[k-1], t[k]] (t[-1] being the initial state's time), i.e. the integrals of
w_ib^b and of the specific force f^b.

Algorithm (Savage, "Strapdown Analytics", 2nd ed. 2007, ch. 7; Titterton & Weston 2004
sec. 11.2), per interval k of length T:
  attitude   phi_k   = dth_k + (1/12) dth_{k-1} x dth_k           two-sample coning
             q_nb(k) = exp(-zeta_k/2) * q_nb(k-1) * exp(phi_k/2)   zeta_k = (w_ie^n + w_en^n) T
  velocity   dv'_k   = dv_k + (1/2) dth_k x dv_k                   rotation compensation,
                       + (1/6) dth_k x (dth_k x dv_k)                to second order
                       + (1/12)(dth_{k-1} x dv_k + dv_{k-1} x dth_k)   two-sample sculling
             v(k)    = v(k-1) + (I - zeta_k x / 2) C_nb(k-1) dv'_k
                       + (g^n - (2 w_ie^n + w_en^n) x v^n) T
  position   trapezoidal in velocity: h -= T (vD(k-1) + vD(k))/2,
             lat += T (vN(k-1) + vN(k))/2 / (R_N + h), lon likewise with (R_E + h) cos(lat)
Earth rate, transport rate, gravity and Coriolis are evaluated at the interval's mid-epoch
from the previous two states by linear extrapolation (Savage sec. 7.2.2). With
`two_sample=False` the single-sample forms are used (no coning, no sculling term).
The second-order rotation term (Savage sec. 7.2.2.2, the series of (1 - sin a / a) / a^2
a x (a x dv)) matters under fast rolls in g: 400 deg/s at 1 kHz in 1 g leaves 8e-8 m/s
per step without it, 1e-10 with it.

Optional height aiding (`h_aid`, m, one value per sample) damps the unstable vertical
channel with a critically damped second-order loop of time constant `h_aid_tau` s:
  h -= (2/tau) (h - h_aid) T,  vD += (1/tau^2) (h - h_aid) T.
"""
import math

import numpy as np
import quaternion

from ..frames import attitude, earth
from ..kernels import njit
from ..motion.trajectory import State, Trajectory
from ..errors import InputError

MAX_RATE = 50.0          # rad/s (2865 deg/s): above any navigation gyro's range
MAX_SPECIFIC_FORCE = 2000.0   # m/s^2 (~200 g): above any navigation accelerometer's range


class IncrementError(InputError):
    """Navigation inputs that cannot be right (shape, NaN/inf, time order, units)."""


def integrate(t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, initial: State, *,
              h_aid: np.ndarray | None = None, h_aid_tau: float = 10.0, two_sample: bool = True,
              check_units: bool = True) -> Trajectory:
    """Navigate body increments from an initial state.

    t: sample times, s (N,), strictly increasing, all after initial.t;
    dtheta: angle increments over (t[k-1], t[k]], rad, body axes (N, 3);
    dv: velocity increments (integrated specific force), m/s, body axes (N, 3);
    initial: the `motion.trajectory.State` to start from (t s, lat, lon rad, h m, v_ned
      m/s, q_nb body -> NED), e.g. `Trajectory.state(0)`;
    h_aid: optional external height, m (N,), for vertical-channel damping;
    check_units: refuse magnitudes no navigation IMU produces (rate > 50 rad/s: degrees
      or rates given; specific force > 2000 m/s^2 or a median over 20 g: rates
      given; a median near 1 m/s^2: g units). Degrees of motion slower than 50 deg/s
      cannot be told from magnitudes.
    Returns a Trajectory at [initial t, t...] (N + 1 samples). `Navigator` does the same
    block by block.
    """
    nav = Navigator(initial, h_aid_tau=h_aid_tau, two_sample=two_sample,
                    check_units=check_units)
    return nav.step(t, dtheta, dv, h_aid=h_aid, before=nav.state())


# the kernel's memory between samples (`_navigate`): lat, lon, h, v_ned (3), q_nb (4); the
# previous lat, h, v_ned and interval (mid-epoch extrapolation) from _PREV; the previous
# increments dtheta, dv (coning, sculling); 1 once a sample has been navigated
_LAT, _LON, _H, _V, _Q, _PREV, _DT_P, _STARTED, _STATE = 0, 1, 2, 3, 6, 10, 15, 22, 23


class Navigator:
    """The strapdown navigator of `integrate`, resumable: `step` navigates a block of
    increments and keeps the kernel's memory (state, previous interval and increments), so
    blocks fed one after another give exactly (bit for bit) what one `integrate` over their
    concatenation gives - a flight of any length in bounded memory.

    initial: as for `integrate`; h_aid_tau, two_sample, check_units as there; whole_record:
    the first block is the whole record, so the median specific-force units test of
    `integrate` applies to it (False when blocks of a longer record come: a short first
    block may be a launch at 20 g; the per-sample limits still apply to every block)."""

    def __init__(self, initial: State, *, h_aid_tau: float = 10.0, two_sample: bool = True,
                 check_units: bool = True, whole_record: bool = True) -> None:
        t0, lat0, lon0, h0, v0, q0 = _checked_initial(initial)
        self.t = t0                         # s, time of the latest state
        self.two_sample, self.check_units, self.whole_record = two_sample, check_units, \
            whole_record
        self.h_aid_tau = h_aid_tau
        self._state = np.zeros(_STATE)
        self._state[[_LAT, _LON, _H]] = lat0, lon0, h0
        self._state[_V:_V + 3] = v0
        self._state[_Q:_Q + 4] = q0
        self._state[_PREV:_PREV + 5] = lat0, h0, *v0
        self._state[_DT_P] = 1.0

    def state(self) -> Trajectory:
        """The latest state as a one-sample Trajectory (vehicle origin of the increments)."""
        s = self._state
        return Trajectory(np.array([self.t]), s[[_LAT]], s[[_LON]], s[[_H]],
                          s[None, _V:_V + 3].copy(),
                          quaternion.as_quat_array(s[None, _Q:_Q + 4].copy()))

    def step(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray,
             h_aid: np.ndarray | None = None, before: Trajectory | None = None) -> Trajectory:
        """Navigate increments over (t[k-1], t[k]] (t[-1]: the latest state's time); t s
        (N,), dtheta rad and dv m/s (N, 3) body axes, h_aid m (N,) or None. Returns the
        Trajectory at t (N states); before: a one-sample Trajectory to place ahead of them
        (N + 1 samples, the states written after it: no concatenation's copy)."""
        t, dtheta, dv = _checked_inputs(t, dtheta, dv, self.check_units, t_prev=self.t,
                                        median=self.whole_record and not self._state[_STARTED])
        if t[0] <= self.t:
            raise IncrementError(f"first sample time {float(t[0]):.9g} s is not after the "
                                 f"{'latest' if self._state[_STARTED] else 'initial'} "
                                 f"state's time {self.t:.9g} s")
        if h_aid is None:
            h_ref, k1, k2 = np.empty(0), 0.0, 0.0
        else:
            h_ref = np.ascontiguousarray(h_aid, dtype=float)
            if h_ref.shape != t.shape or not np.all(np.isfinite(h_ref)):
                raise IncrementError("h_aid must hold one finite height (m) per sample")
            k1, k2 = 2.0 / self.h_aid_tau, 1.0 / self.h_aid_tau**2
        lead = 0 if before is None else 1
        n = len(t) + lead
        lat, lon, h = np.empty(n), np.empty(n), np.empty(n)
        v, q = np.empty((n, 3)), np.empty((n, 4))
        if lead:
            lat[0], lon[0], h[0], v[0] = before.lat[0], before.lon[0], before.h[0], \
                before.v_ned[0]
            q[0] = attitude.as_wxyz(before.q_nb[0])
        _navigate(t, self.t, dtheta, dv, self._state, self.two_sample, h_ref, k1, k2,
                  lat[lead:], lon[lead:], h[lead:], v[lead:], q[lead:])
        self.t = float(t[-1])
        if lead:
            t = np.concatenate([before.t[:1], t])
        return Trajectory(t, lat, lon, h, v, quaternion.as_quat_array(q))


def _checked_inputs(t, dtheta, dv, check_units, t_prev=None, median=True):
    """The inputs as contiguous float arrays, refused with the sample named when they cannot
    be right; t_prev: the time before t[0] (the first sample's rate is checked over it);
    median: the median specific-force test (once per record: a later block may be ballistic)."""
    t = np.ascontiguousarray(t, dtype=float)
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dv = np.ascontiguousarray(dv, dtype=float)
    if t.ndim != 1 or len(t) == 0:
        raise IncrementError(f"t must be a non-empty 1-D array of times in s, got shape {t.shape}")
    for name, x in (("dtheta", dtheta), ("dv", dv)):
        if x.shape != (len(t), 3):
            raise IncrementError(f"{name} must have shape (N, 3) = ({len(t)}, 3) like t, "
                                 f"got {x.shape}")
    problem, k, value = _scan(t, dtheta, dv, MAX_RATE if check_units else np.inf,
                              MAX_SPECIFIC_FORCE if check_units else np.inf)
    if not problem and check_units and t_prev is not None and t[0] > t_prev:
        step = t[0] - t_prev
        first = (np.linalg.norm(dtheta[0]) / step, np.linalg.norm(dv[0]) / step)
        problem, k, value = ((5, 0, first[0]) if first[0] > MAX_RATE else
                             (6, 0, first[1]) if first[1] > MAX_SPECIFIC_FORCE else (0, 0, 0.0))
    if problem:
        at = f"at sample {k} (t = {float(t[k]):.9g} s)"
        raise IncrementError({
            1: f"t is not finite {at}",
            2: f"dtheta is not finite {at}: {dtheta[k]}",
            3: f"dv is not finite {at}: {dv[k]}",
            4: f"time does not increase {at}: the previous sample is at {float(t[k - 1]):.9g} s",
            5: f"angular rate {value:.4g} rad/s {at} exceeds {MAX_RATE} rad/s: are dtheta "
               "in degrees, or rates rather than increments (rad)?",
            6: f"specific force {value:.4g} m/s^2 {at} exceeds {MAX_SPECIFIC_FORCE} m/s^2: "
               "are dv rates (m/s^2) rather than increments (m/s)?"}[problem])
    if check_units and median:
        check_median_force(t, dv)
    return t, dtheta, dv


def check_median_force(t, dv):
    """An IncrementError when the median specific force of a whole record's increments dv
    (m/s, (N, 3), over the intervals ending at t s) is not a specific force in m/s^2: near
    1 g expressed in g, or over 20 g. Of a whole record only: a piece of one may lie in a
    coast or a free fall (a balloon's burst: 2.6 m/s^2 over a window), which no units
    error is. Fewer than 100 samples: not judged."""
    if len(t) < 100:
        return
    step = max(1, len(t) // 1000)       # over a subsample: near 1 g for anything on Earth
    force = np.median(np.linalg.norm(dv[1::step], axis=1) / (t[1::step] - t[:-1:step]))
    if 0.3 < force < 3.0:
        raise IncrementError(
            f"median specific force is {force:.3g} m/s^2, near 1 g expressed in g: dv "
            "must be in m/s (specific force in m/s^2 times the interval) - or, for a "
            "compensated MIMU, the calibration is another unit's")
    if force > 20 * 9.8:
        raise IncrementError(
            f"median specific force is {force:.3g} m/s^2 (over 20 g for most of the "
            "flight): are dv rates (m/s^2) rather than increments (m/s)?")


@njit(nogil=True)
def _scan(t, dth, dv, max_rate, max_force):
    """First problem in the inputs: (code, sample, value); code 0 = none.
    Codes: 1 t not finite, 2 dtheta not finite, 3 dv not finite, 4 time not increasing,
    5 rate above max_rate, 6 specific force above max_force."""
    for k in range(t.shape[0]):
        if not math.isfinite(t[k]):
            return 1, k, 0.0
        a2 = dth[k, 0] ** 2 + dth[k, 1] ** 2 + dth[k, 2] ** 2
        if not math.isfinite(a2):
            return 2, k, 0.0
        u2 = dv[k, 0] ** 2 + dv[k, 1] ** 2 + dv[k, 2] ** 2
        if not math.isfinite(u2):
            return 3, k, 0.0
        if k > 0:
            T = t[k] - t[k - 1]
            if not T > 0:
                return 4, k, 0.0
            if a2 > (max_rate * T) ** 2:
                return 5, k, math.sqrt(a2) / T
            if u2 > (max_force * T) ** 2:
                return 6, k, math.sqrt(u2) / T
    return 0, 0, 0.0


def _checked_initial(initial):
    try:
        t0 = float(initial.t)
        lat0, lon0, h0 = float(initial.lat), float(initial.lon), float(initial.h)
        v0 = np.asarray(initial.v_ned, dtype=float).reshape(3)
        q0 = np.asarray(attitude.as_wxyz(initial.q_nb), dtype=float).reshape(4)
    except (AttributeError, TypeError, ValueError) as exc:
        raise IncrementError("initial state needs t (s), lat, lon (rad), h (m), v_ned (3, m/s) "
                             f"and q_nb (w, x, y, z): {exc}") from None
    values = np.concatenate([[t0, lat0, lon0, h0], v0, q0])
    if not np.all(np.isfinite(values)):
        raise IncrementError(f"initial state is not finite: {values}")
    if abs(lat0) > math.pi / 2:
        raise IncrementError(f"initial latitude {lat0:.9g} is beyond +-pi/2: it must be in rad")
    if abs(lon0) > 2 * math.pi:
        raise IncrementError(f"initial longitude {lon0:.9g} is beyond +-2 pi: it must be in rad")
    if abs(np.linalg.norm(q0) - 1) > 1e-6:
        raise IncrementError(f"initial q_nb {q0} is not a unit quaternion "
                             f"(norm {np.linalg.norm(q0):.9g})")
    return t0, lat0, lon0, h0, v0, q0 / np.linalg.norm(q0)


# Cells of the latitude grid from which the kernel takes sin and cos by angle addition,
# per rad: |lat - cell| <= 2^-12 rad, where the series below are exact to 1e-24.
_LAT_CELLS = 2048.0


# error_model="numpy": no zero-division test before each division (the inputs are checked);
# fastmath "contract" only: a*b+c in one fused multiply-add (rounded once, not twice) where
# the processor has one - results then differ between processors with and without FMA in
# their last bits (3.7e-14 rad of latitude after 840 s at 100 Hz).
# Divisions by constants are multiplications by their reciprocals, the half-angle and
# latitude sine and cosine series rather than library calls: the divider's and the calls'
# throughput bounded the kernel (alone, on 1e6 samples of bench/strapdown.py's flight at
# 1 kHz: 8.7 -> 13.3 M samples/s; with the Earth model replaced by constants, 18).
@njit(nogil=True, error_model="numpy", fastmath={"contract"})
def _navigate(t, t_prev, dth, dvb, state, two_sample, h_ref, k1, k2, lat, lon, h, v, q):
    """Scalar kernel of `Navigator.step`; fills lat, lon, h, v, q (N rows, the states at the
    samples t, s; t_prev: the time of the state in `state`) from the memory in `state`
    (layout at _LAT ... _STATE), which it leaves as it is after the last sample. A compiled
    kernel kept whole past the 80-line rule: one loop over the samples with every step
    inlined in registers (coning, sculling, Earth and transport rates, gravity); split into
    functions its state would cross calls every sample."""
    la, lo, hh = state[0], state[1], state[2]
    vn, ve, vd = state[3], state[4], state[5]
    qw, qx, qy, qz = state[6], state[7], state[8], state[9]
    la_p, hh_p, vn_p, ve_p, vd_p, dt_p = state[10], state[11], state[12], state[13], \
        state[14], state[15]
    tx_p, ty_p, tz_p, ux_p, uy_p, uz_p = state[16], state[17], state[18], state[19], \
        state[20], state[21]
    started = state[22] > 0.0
    aided = h_ref.shape[0] > 0
    cell, la_c, s_c, c_c = math.nan, 0.0, 0.0, 1.0   # latitude cell: number, rad, sin, cos
    for k in range(t.shape[0]):
        T = t[k] - t_prev
        t_prev = t[k]
        tx, ty, tz = dth[k, 0], dth[k, 1], dth[k, 2]
        ux, uy, uz = dvb[k, 0], dvb[k, 1], dvb[k, 2]
        # body-frame corrections: rotation, coning and sculling
        px, py, pz = tx, ty, tz
        cx_, cy_, cz_ = ty * uz - tz * uy, tz * ux - tx * uz, tx * uy - ty * ux
        wx = ux + 0.5 * cx_ + (ty * cz_ - tz * cy_) * (1.0 / 6.0)
        wy = uy + 0.5 * cy_ + (tz * cx_ - tx * cz_) * (1.0 / 6.0)
        wz = uz + 0.5 * cz_ + (tx * cy_ - ty * cx_) * (1.0 / 6.0)
        if two_sample and started:
            px += (ty_p * tz - tz_p * ty) * (1.0 / 12.0)
            py += (tz_p * tx - tx_p * tz) * (1.0 / 12.0)
            pz += (tx_p * ty - ty_p * tx) * (1.0 / 12.0)
            wx += ((ty_p * uz - tz_p * uy) + (uy_p * tz - uz_p * ty)) * (1.0 / 12.0)
            wy += ((tz_p * ux - tx_p * uz) + (uz_p * tx - ux_p * tz)) * (1.0 / 12.0)
            wz += ((tx_p * uy - ty_p * ux) + (ux_p * ty - uy_p * tx)) * (1.0 / 12.0)
        tx_p, ty_p, tz_p, ux_p, uy_p, uz_p = tx, ty, tz, ux, uy, uz
        # mid-epoch navigation quantities by linear extrapolation
        r = 0.5 * T / dt_p if started else 0.0
        started = True
        la_m = la + r * (la - la_p)
        hh_m = hh + r * (hh - hh_p)
        vn_m, ve_m, vd_m = vn + r * (vn - vn_p), ve + r * (ve - ve_p), vd + r * (vd - vd_p)
        # sin, cos of la_m: those of the nearest cell's latitude, rotated by the rest d
        if np.floor(la_m * _LAT_CELLS + 0.5) != cell:     # a float: NaN never equals it
            cell = np.floor(la_m * _LAT_CELLS + 0.5)
            la_c = cell / _LAT_CELLS
            s_c, c_c = math.sin(la_c), math.cos(la_c)
        d = la_m - la_c
        d2 = d * d
        cos_d = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0))
        sin_d = d * (1.0 - d2 * ((1.0 / 6.0) - d2 * (1.0 / 120.0)))
        ien, ied, enn, ene, end, g, per_n, per_e = earth.nav_rates_at(
            s_c * cos_d + c_c * sin_d, c_c * cos_d - s_c * sin_d, hh_m, vn_m, ve_m)
        zx, zy, zz = (ien + enn) * T, ene * T, (ied + end) * T
        # velocity: rotate dv' to NED at k-1, then the nav-frame rotation over the interval
        dn, de, dd = attitude.rotate_scalar(qw, qx, qy, qz, wx, wy, wz)
        dn, de, dd = (dn - 0.5 * (zy * dd - zz * de), de - 0.5 * (zz * dn - zx * dd),
                      dd - 0.5 * (zx * de - zy * dn))
        cx, cy, cz = 2.0 * ien + enn, ene, 2.0 * ied + end
        vn_new = vn + dn - (cy * vd_m - cz * ve_m) * T
        ve_new = ve + de - (cz * vn_m - cx * vd_m) * T
        vd_new = vd + dd + (g - (cx * ve_m - cy * vn_m)) * T
        # position, trapezoidal
        la_p, hh_p, vn_p, ve_p, vd_p, dt_p = la, hh, vn, ve, vd, T
        hh = hh - 0.5 * (vd + vd_new) * T
        la = la + 0.5 * (vn + vn_new) * T * per_n
        lo = lo + 0.5 * (ve + ve_new) * T * per_e
        vn, ve, vd = vn_new, ve_new, vd_new
        if aided:
            err = hh - h_ref[k]
            hh -= k1 * err * T
            vd += k2 * err * T
        # attitude: q = exp(-zeta/2) * q * exp(phi/2)
        ang2 = px * px + py * py + pz * pz
        if ang2 < 1e-2:       # cos(a/2), sin(a/2)/a: Taylor series, exact to < 1e-19 below
            # |phi| = 0.1 rad (100 rad/s at 1 kHz)
            bw = 1.0 - ang2 * ((1.0 / 8.0) - ang2 * ((1.0 / 384.0) - ang2 * (
                (1.0 / 46080.0) - ang2 * (1.0 / 10321920.0))))
            bs = 0.5 - ang2 * ((1.0 / 48.0) - ang2 * ((1.0 / 3840.0) - ang2 * (
                (1.0 / 645120.0) - ang2 * (1.0 / 185794560.0))))
        else:
            ang = math.sqrt(ang2)
            bw = math.cos(0.5 * ang)
            bs = math.sin(0.5 * ang) / ang
        bx, by, bz = bs * px, bs * py, bs * pz
        q1w = qw * bw - qx * bx - qy * by - qz * bz
        q1x = qw * bx + qx * bw + qy * bz - qz * by
        q1y = qw * by - qx * bz + qy * bw + qz * bx
        q1z = qw * bz + qx * by - qy * bx + qz * bw
        z2 = zx * zx + zy * zy + zz * zz     # |zeta| < 1e-3 rad for any T < 10 s
        nw = 1.0 - z2 * (1.0 / 8.0) + z2 * z2 * (1.0 / 384.0)
        ns = -(0.5 - z2 * (1.0 / 48.0))
        nx, ny, nz = ns * zx, ns * zy, ns * zz
        qw = nw * q1w - nx * q1x - ny * q1y - nz * q1z
        qx = nw * q1x + nx * q1w + ny * q1z - nz * q1y
        qy = nw * q1y - nx * q1z + ny * q1w + nz * q1x
        qz = nw * q1z + nx * q1y - ny * q1x + nz * q1w
        norm = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        qw, qx, qy, qz = qw * norm, qx * norm, qy * norm, qz * norm
        lat[k], lon[k], h[k] = la, lo, hh
        v[k, 0], v[k, 1], v[k, 2] = vn, ve, vd
        q[k, 0], q[k, 1], q[k, 2], q[k, 3] = qw, qx, qy, qz
    state[0], state[1], state[2], state[3], state[4], state[5] = la, lo, hh, vn, ve, vd
    state[6], state[7], state[8], state[9] = qw, qx, qy, qz
    state[10], state[11], state[12], state[13], state[14], state[15] = \
        la_p, hh_p, vn_p, ve_p, vd_p, dt_p
    state[16], state[17], state[18], state[19], state[20], state[21] = \
        tx_p, ty_p, tz_p, ux_p, uy_p, uz_p
    state[22] = 1.0 if started else 0.0

"""The motion of a land vehicle from a GNSS track, as a `truth.Motion`, so that the same exact
increment generator that simulates flights simulates the ideal IMU of a recorded drive.

A GNSS track gives position and velocity but no attitude; a car's attitude follows from
its velocity under two assumptions, stated wherever the result is used:
  - non-holonomic: the car moves along its forward axis (no side slip, no reversing), so
    yaw = atan2(v_E, v_N) and pitch = atan2(-v_D, v_H), v_H the horizontal speed;
  - roll = 0: the body does not bank (road camber and body roll on the springs are
    unknown; a car rolls a few degrees per g of lateral acceleration).
Below HOLD_SPEED the course is noise: yaw holds its last value (the first moving one for a
rest that starts the track), pitch the grade of the road over the last HOLD_DISTANCE_M
driven (the next, for a rest that starts the track; `_road_pitch`), and the rates are
zero. Velocity and its derivative come from a cubic smoothing spline per NED component
(`smoothing_spline`, scipy's `make_smoothing_spline` in compiled code), its smoothing chosen
by generalised cross-validation (`gcv_smoothing`); north and east share one smoothing, the
geometric mean of their two choices, since the course mixes them. The rates follow analytically:
    yaw' = (v_N a_E - v_E a_N) / v_H^2,   pitch' = (v_D v_H' - a_D v_H) / (v_H^2 + v_D^2),
    w_nb^b = (-yaw' sin(pitch), pitch', yaw' cos(pitch))      (roll = 0, T&W eq. 3.19)
and their derivatives from the spline's second derivative (jerk) in the same way.

The smoothing that keeps the track's noise out also blunts what it keeps: a sharp turn's
yaw rate comes out lower and wider than the vehicle's (an independent drive, 2 cm RTK fixes
at 10 Hz: 0.37 deg/s rms, 4.1 deg/s at the sharpest turns, and a yaw gyro's scale read
+0.8 to +2.4 % where it had none). What is compared with it must pass through the same
smoothing (`in_band`): an IMU's output, integrated, sampled at the epochs, smoothed by the
same spline and differentiated, carries the same blunting (0.10 deg/s rms, scale +0.05 %).
"""
import math

import numpy as np
from scipy import optimize
from scipy.interpolate import CubicSpline

from ..frames import attitude
from ..kernels import njit
from .truth import Kinematics, Motion
from ..errors import InputError
from .intervals import RunningIntegral, intervals
from .track import white_noise

HOLD_SPEED = 0.5            # m/s: below it the attitude holds and the rates are zero
TRUSTED_SPEED = 2.0         # m/s: above it (or at rest) the attitude model is taken as valid
REST_SPEED = 0.05           # m/s: at rest
EDGE_EPOCHS = 5             # epoch steps at least in `TrackMotion.edge_s`: 0.27^5 = 1.4e-3


class TrackMotion(Motion):
    """Land-vehicle motion through the GNSS track (t s, lat, lon rad, h m, v_ned m/s);
    differenced: the velocities are central differences of the positions (an importer's
    `velocity_from_positions`, np.gradient's second-order form on uneven epochs), each a
    weighted mean of the mean velocities over the steps behind and ahead (one-sided at the
    ends), not a point sample - `in_band` then takes the IMU's integral through the same
    differences."""

    def __init__(self, t, lat, lon, h, v_ned, differenced=False):
        t = np.asarray(t, float)
        self.differenced = bool(differenced)
        self.t0, self.t1 = float(t[0]), float(t[-1])
        self.lat0, self.lon0, self.h0 = float(lat[0]), float(lon[0]), float(h[0])
        v_ned = np.asarray(v_ned, float)
        lam = [gcv_smoothing(t, v_ned[:, i]) for i in range(3)]
        self.lam_horizontal = math.sqrt(lam[0] * lam[1])       # s^3: the spline's lambda
        self.lam_vertical = lam[2]
        self._v = [smoothing_spline(t, v_ned[:, i], smoothing)
                   for i, smoothing in enumerate([self.lam_horizontal] * 2 + lam[2:])]
        self._a = [s.derivative() for s in self._v]
        self._j = [s.derivative(2) for s in self._v]
        v = self._velocity(t)
        yaw, pitch = _yaw_pitch(v)
        moving = np.hypot(v[:, 0], v[:, 1]) >= HOLD_SPEED
        if not moving.any():
            raise InputError(f"the reference never moves faster than {HOLD_SPEED:g} m/s "
                             f"horizontally in its smoothed velocity (peak "
                             f"{np.hypot(v[:, 0], v[:, 1]).max():.2g} m/s; recorded "
                             f"{np.nanmax(np.hypot(v_ned[:, 0], v_ned[:, 1])):.2g}): the track level "
                             "models a land vehicle whose attitude follows its course, so it "
                             "does not apply here (it does not read a reference's own attitude)")
        first = np.argmax(moving)
        last = np.maximum.accumulate(np.where(moving, np.arange(len(t)), first))
        self._t, self._yaw_hold = t, yaw[last]
        # a stopped vehicle's pitch: the grade of the road behind it (before it first moves,
        # the road ahead), at the epochs a held attitude is taken from - the last moving one
        # before each stop
        distance, h = _distance(t, v), np.asarray(h, float)
        hold, hold_sd = np.array(pitch, float), np.full(len(t), np.nan)
        for i in np.unique(np.append(last[~moving], np.flatnonzero(moving[:-1] & ~moving[1:]))):
            hold[i], hold_sd[i] = _road_pitch(distance, h, i, ahead=i == first,
                                              otherwise=pitch[i])
        self._pitch_hold, self._pitch_hold_sd = hold[last], hold_sd[last]
        self._vertical_sd = _smoothed_noise(t, v_ned[:, 2], self.lam_vertical)

    def _velocity(self, t):
        return np.column_stack([s(t) for s in self._v])

    def speed(self, t):
        """|v| (m/s) of the smoothed track at times t (s)."""
        return np.linalg.norm(self._velocity(np.asarray(t, float)), axis=1)

    def held_pitch_sd(self, t):
        """rad: the error (1 sigma) of the pitch a stopped vehicle holds at times t (s), as
        `_road_pitch` measures it; 0 where it moves, NaN where the grade was not measured."""
        t = np.asarray(t, float)
        moving = np.hypot(*self._velocity(t)[:, :2].T) >= HOLD_SPEED
        k = np.clip(np.searchsorted(self._t, t, side="right") - 1, 0, len(self._t) - 1)
        return np.where(moving, 0.0, self._pitch_hold_sd[k])

    def moving_pitch_sd(self, t):
        """rad: the error (1 sigma) of the pitch a moving vehicle is given at times t (s) -
        the smoothed vertical velocity's (`_smoothed_noise`) over the horizontal speed,
        atan2(-v_D, v_H) to first order; 0 where it stops (`held_pitch_sd`). A train's
        vertical differenced from 1-3 m heights at 1 Hz put its pitch 3.7 deg off at 4 m/s,
        read as an accelerometer's 0.64 m/s^2 excursion."""
        v = self._velocity(np.asarray(t, float))
        speed = np.hypot(v[:, 0], v[:, 1])
        return np.where(speed >= HOLD_SPEED, self._vertical_sd / np.maximum(speed, HOLD_SPEED),
                        0.0)

    def trusted(self, t):
        """True where the attitude model holds: at rest or faster than TRUSTED_SPEED."""
        s = self.speed(t)
        return (s < REST_SPEED) | (s > TRUSTED_SPEED)

    @property
    def error_time_s(self):
        """s: how long the errors of the track's rates and accelerations stay correlated - the
        first zero of the autocorrelation of white velocity noise smoothed by the spline and
        differentiated, 1.84 / w_c, with w_c = (lambda dt)^(-1/4) rad/s the spline's
        half-power frequency (its transfer function 1 / (1 + lambda dt w^4), dt the median
        epoch step); and at least two epoch steps, over which a (nearly) interpolating
        spline's error between its knots is one function of the same few knots (a 1 Hz track
        chose lambda 3.5e-6 - the bounded search's floor: its GCV falls towards
        interpolation - 0.08 s, and a null drive's correlated bins gave an accel.x scale
        [0.028, 0.069]). Velocities differenced from positions decorrelate sooner (1.28 /
        w_c: an independent 10 Hz drive with 2 cm fixes, w_c 2.40 rad/s, crossed zero at
        0.55 s)."""
        dt = float(np.median(np.diff(self._t)))
        return max(1.84 * (self.lam_horizontal * dt) ** 0.25, 2 * dt)

    @property
    def edge_s(self):
        """s: how far from the track's ends its smoothing is one-sided - twice the equivalent
        kernel's width (lambda dt)^(1/4) of the wider of its two smoothers, dt the median
        epoch step (on a level road the vertical's: all noise, its GCV lambda at the search's
        bound N, so 2 (N dt)^(1/4) = 2 T^(1/4) for a track of T s - 9.9 s for 600 s; its
        derivative had drifted 0.006 m/s^2 over the first 8 s of a rest, z 17 against the
        part's noise) - and at least EDGE_EPOCHS epoch steps, over which a (nearly)
        interpolating spline's end condition fades (by 2 - sqrt 3 = 0.27 per knot: a 1 Hz
        track with lambda 3.5e-6 was 4.7 deg/s off over its first 2.5 s)."""
        dt = float(np.median(np.diff(self._t)))
        return max(2 * (max(self.lam_horizontal, self.lam_vertical) * dt) ** 0.25,
                   EDGE_EPOCHS * dt)

    def in_band(self, t, x):
        """x (N, k) - an IMU's outputs, any units and axes, each the mean over its own sample
        interval ending at its stamp t (s) - through the track's own smoothing, in the same
        form. The model's rates and accelerations are the derivative of a smoothing spline
        through point samples of the velocity; the IMU's outputs are put through the same
        operation: their running integral (exact at the stamps), sampled at the track's
        epochs - or, of a `differenced` track, averaged over each epoch's differencing steps
        as its velocity is (a 2 s boxcar at 1 Hz: without it a null drive's sharp turns read
        as excursions of accel.y and gyro.z at z 9-11 and a yaw scale 'set aside' at 1.3 %)
        - smoothed by the horizontal velocity's spline (the same lambda) and
        differentiated - as each output's mean over its own interval. (A mean over each
        epoch of a point-sampled track, a 0.25 s boxcar at 4 Hz, is a filter the model does
        not have: a smooth start's longitudinal acceleration differed by 0.01 m/s^2, z 7
        against the part's noise.) An output that is not finite counts as its neighbours'
        (linear in time) in the integral, NaN in the result; across a gap in the stamps
        the output after it is held over the gap."""
        t, x = np.asarray(t, float), np.asarray(x, float)
        _, span, edges = intervals(t)
        finite = np.isfinite(x).all(axis=1)
        if finite.sum() < 2:
            raise InputError("fewer than 2 finite IMU outputs: nothing to compare with the track")
        filled = np.column_stack([np.interp(t, t[finite], x[finite, c])
                                  for c in range(x.shape[1])])
        integral = RunningIntegral(edges, filled)
        rate = integral.area[-1] / (edges[-1] - edges[0])
        # the velocity the outputs make, sampled as the track's (differenced: `_as_sampled`)
        sampled = self._as_sampled(integral.once, integral.twice)
        sampled -= (self._t - edges[0])[:, None] * rate     # the mean rate, for the fit
        spline = smoothing_spline(self._t, sampled, self.lam_horizontal)
        out = (spline(t) - spline(t - span)) / span[:, None] + rate
        out[~finite] = np.nan
        return out

    def _as_sampled(self, value, integral):
        """(M, k): a quantity at the track's epochs as the track samples its velocity, from
        callables of times (s): value (the quantity) and integral (its running integral).
        At the epochs; of a `differenced` track, interior epochs as np.gradient differences
        them: the means over the steps behind (h_b) and ahead (h_f), weighted h_f and h_b
        over their sum - exact for a quadratic, so a constant output (gravity, a rest's
        bias) keeps its epoch (an even mean over both steps had moved it a quarter of a
        dropped fix's gap: z 131 on a 1 Hz null drive with 3 % of its fixes dropped). The
        two end epochs, differenced one-sidedly, as points: their span's constant would be
        read half a step off, a kink the spline turns into a rate (gyro.z z 17 at a start)."""
        epochs = self._t
        sampled = value(epochs)
        if self.differenced:
            volume = integral(epochs)
            h_b, h_f = np.diff(epochs)[:-1, None], np.diff(epochs)[1:, None]
            behind = (volume[1:-1] - volume[:-2]) / h_b
            ahead = (volume[2:] - volume[1:-1]) / h_f
            sampled[1:-1] = (h_f * behind + h_b * ahead) / (h_b + h_f)
        return sampled

    def course_rate_in_band(self, t, yaw_rate):
        """(N,) rad/s: an IMU's yaw rate about down (rad/s, (N,), each the mean over its
        interval ending at its stamp t s) as the model makes its own yaw rate - the rate of
        the course of the smoothed velocity: a velocity of the model's speed along the IMU's
        heading (its yaw rate integrated from the model's first course; a constant offset
        turns the velocity and leaves its course's rate), sampled as the track's velocity
        (`_as_sampled`), smoothed by the horizontal spline, its course differenced over each
        output's interval. A yaw rate smoothed on its own is not the model's: the course of
        a smoothed velocity is not the smoothed course where the speed changes or the course
        turns fast (under 5 cm fixes, lambda 1.3, 0.3 deg/s at sharp turns). A non-finite
        rate counts as its neighbours'."""
        t, yaw_rate = np.asarray(t, float), np.asarray(yaw_rate, float)
        step, span, edges = intervals(t)
        finite = np.isfinite(yaw_rate)
        rate = np.interp(t, t[finite], yaw_rate[finite])
        v0 = self._velocity(self._t[:1])[0]
        # each interval's mean heading and velocity: at its middle
        heading = math.atan2(v0[1], v0[0]) + np.cumsum(rate * step) - 0.5 * rate * step
        middle = t - 0.5 * step
        speed = self.speed(middle)
        v = np.column_stack([speed * np.cos(heading), speed * np.sin(heading)])
        velocity = RunningIntegral(edges, v)

        def at(times):                  # the velocity at times, between the middles
            return np.column_stack([np.interp(times, middle, v[:, c]) for c in range(2)])
        spline = smoothing_spline(self._t, self._as_sampled(at, velocity.once),
                                  self.lam_horizontal)

        def course(x):
            smoothed = spline(x)
            return np.arctan2(smoothed[:, 1], smoothed[:, 0])
        return np.angle(np.exp(1j * (course(t) - course(t - span)))) / span

    def kinematics(self, t):
        t = np.asarray(t, float)
        v = self._velocity(t)
        a = np.column_stack([s(t) for s in self._a])
        j = np.column_stack([s(t) for s in self._j])
        yaw, pitch = _yaw_pitch(v)
        vh2 = v[:, 0] ** 2 + v[:, 1] ** 2
        vh = np.sqrt(vh2)
        moving = vh >= HOLD_SPEED
        with np.errstate(invalid="ignore", divide="ignore"):
            yaw_dot = (v[:, 0] * a[:, 1] - v[:, 1] * a[:, 0]) / vh2
            yaw_ddot = (v[:, 0] * j[:, 1] - v[:, 1] * j[:, 0]) / vh2 \
                - 2 * yaw_dot * (v[:, 0] * a[:, 0] + v[:, 1] * a[:, 1]) / vh2
            vh_dot = (v[:, 0] * a[:, 0] + v[:, 1] * a[:, 1]) / vh
            vh_ddot = (a[:, 0] ** 2 + a[:, 1] ** 2 + v[:, 0] * j[:, 0] + v[:, 1] * j[:, 1]) / vh \
                - vh_dot ** 2 / vh
            den = vh2 + v[:, 2] ** 2
            pitch_dot = (v[:, 2] * vh_dot - a[:, 2] * vh) / den
            pitch_ddot = (v[:, 2] * vh_ddot - j[:, 2] * vh
                          - 2 * pitch_dot * (vh * vh_dot + v[:, 2] * a[:, 2])) / den
        k = np.clip(np.searchsorted(self._t, t, side="right") - 1, 0, len(self._t) - 1)
        yaw = np.where(moving, yaw, self._yaw_hold[k])
        pitch = np.where(moving, pitch, self._pitch_hold[k])
        yd, pd, ydd, pdd = (np.where(moving, x, 0.0)
                            for x in (yaw_dot, pitch_dot, yaw_ddot, pitch_ddot))
        s_p, c_p = np.sin(pitch), np.cos(pitch)
        w = np.column_stack([-yd * s_p, pd, yd * c_p])
        dw = np.column_stack([-ydd * s_p - yd * pd * c_p, pdd, ydd * c_p - yd * pd * s_p])
        q = attitude.from_euler(yaw, pitch, np.zeros_like(yaw))
        return Kinematics(v, a, q, w, dw)


def _smoothed_noise(t, x, lam):
    """The error (1 sigma) of the smoothing spline of lambda `lam` through x at epochs t: the
    white noise of x (`track.white_noise`; an upper bound for velocities differenced from
    positions, whose noise cancels over a window) through the
    spline's equivalent kernel (Silverman 1984: bandwidth h = (lam dt)^(1/4); the integral
    of its square, as of its transfer function's 1 / (1 + lam dt w^4) squared over 2 pi,
    3 / (8 sqrt 2 h)): sigma sqrt(dt 3 / (8 sqrt 2 h)), dt the median step."""
    sigma = white_noise(x)
    dt = float(np.median(np.diff(t)))
    h = max((lam * dt) ** 0.25, dt)
    return sigma * math.sqrt(min(1.0, dt * 3 / (8 * math.sqrt(2) * h)))


HOLD_DISTANCE_M = 20.0      # m of road whose grade a stopped vehicle's pitch is


def _distance(t, v):
    """(M,) m: the horizontal distance driven at the epochs t (s) of the velocities v (M, 3),
    by the trapezoid rule."""
    speed = np.hypot(v[:, 0], v[:, 1])
    return np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])


def _road_pitch(distance, h, i, ahead=False, otherwise=0.0):
    """(rad, rad): the road's pitch at epoch i - the least-squares slope of the height h (m,
    at the epochs) against the distance driven (m) over the HOLD_DISTANCE_M behind epoch i
    (ahead of it with `ahead`) - and its error: the slope's standard error beside how far
    the grade turns over the stretch (a quadratic fit's slope at epoch i less the line's; a
    grade of 1-3 % curving over 500 m left the line's 0.14 deg off at a stop); or
    (`otherwise`, NaN) when less than half of that was driven. What a stopped vehicle holds:
    the velocity's pitch atan(-v_D / v_H) as v_H falls to HOLD_SPEED divides the heavily
    smoothed vertical velocity by a vanishing speed - on an independent drive over 5 m hills
    1-4 deg off at stops, accel.x excursions of z 10-23 on null drives (the fixes' height
    noise, 2-5 cm over 20 m, is 0.1-0.3 deg). distance: non-decreasing."""
    if ahead:
        k = slice(i, np.searchsorted(distance, distance[i] + HOLD_DISTANCE_M, "right"))
    else:
        k = slice(np.searchsorted(distance, distance[i] - HOLD_DISTANCE_M, "left"), i + 1)
    if np.ptp(distance[k]) < 0.5 * HOLD_DISTANCE_M or len(distance[k]) < 5:
        return float(otherwise), math.nan
    x = distance[k] - distance[k].mean()
    y = h[k] - h[k].mean()
    slope = float(x @ y) / float(x @ x)
    rest = y - slope * x
    se = math.sqrt(float(rest @ rest) / (len(x) - 2) / float(x @ x))
    (curve, line, _), cov = np.polyfit(x, y, 2, cov=True)
    # the grade's turn only where the curve is there (2 of its standard errors): else the
    # quadratic's own noise, 2-3 times the line's, had been counted twice
    significant = abs(curve) > 2 * math.sqrt(max(cov[0, 0], 0.0))
    turn = 2 * curve * (distance[i] - distance[k].mean()) + line - slope if significant else 0.0
    return math.atan(slope), math.hypot(se, turn)


def gcv_smoothing(t, y):
    """lambda (s^3 for a velocity in m/s over t in s) of the cubic smoothing spline through
    (t, y), unit weights, chosen by generalised cross-validation: the minimum of `gcv`
    over (0, N), N = len(t), by the bounded Brent search - the criterion, bounds and search
    of scipy's `make_smoothing_spline(t, y)` (which does not return its lambda), evaluated
    in O(N) compiled code instead of scipy's Python loops (6000 epochs: 3.7 s there, 11 ms
    here). Its curve is flat at the minimum: the two choices agree to 2e-4 with GCV scores
    equal to 1e-8. Refuses (InputError) fewer than 5 epochs, times that do not increase
    and values that are not finite - scipy's checks, which the compiled score lacks (a NaN
    had returned a lambda)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    if t.ndim != 1 or y.shape != t.shape or len(t) < 5:
        raise InputError(f"a smoothing spline needs 5 or more epochs with one value each "
                         f"(t {t.shape}, values {y.shape})")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y)) and np.all(np.diff(t) > 0)):
        raise InputError("a smoothing spline needs finite values at finite, increasing times")
    return float(optimize.minimize_scalar(gcv, bounds=(0, len(t)), method="bounded",
                                          args=(np.diff(t), y)).x)


def smoothing_spline(t, y, lam):
    """The cubic smoothing spline through (t s (N,), y (N,) or (N, k)) with smoothing lam and
    unit weights - the minimiser of sum (y_i - f(t_i))^2 + lam int f''^2, scipy's
    `make_smoothing_spline(t, y, lam=lam)` - as a `CubicSpline`: the natural cubic spline
    through its own values at the knots (`_smoothed`), which it is; evaluated and
    differentiated like scipy's (scipy builds its penalty matrix in a Python loop: 0.15 s
    per call at 6000 epochs, here 2 ms)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    values = _smoothed(lam, np.diff(t), y.reshape(len(t), -1)).reshape(y.shape)
    return CubicSpline(t, values, bc_type="natural", axis=0)


@njit(nogil=True)
def _factor(lam, h):
    """Reinsch's form of the cubic smoothing spline with smoothing lam through knots spaced
    h (N - 1,) (Green and Silverman 1994 sec. 2.3): the second derivatives gamma at the
    interior knots solve M gamma = Q'y, M = R + lam Q'Q (pentadiagonal), and y - f =
    lam Q gamma. Q: column j has 1/h_j, -(1/h_j + 1/h_(j+1)), 1/h_(j+1) at rows j, j+1,
    j+2; R: tridiagonal, (h_j + h_(j+1))/3 on the diagonal, h_(j+1)/6 beside it. Returns
    Q's three bands (qa, qb, qc), Q'Q's (c0, c1, c2) and M = L D L' (d, l1, l2; L unit
    lower with bands l1, l2)."""
    m = h.shape[0] - 1
    qa, qb, qc = 1.0 / h[:m], np.empty(m), 1.0 / h[1:m + 1]
    qb[:] = -(qa + qc)
    c1, c2 = np.zeros(m), np.zeros(m)
    c0 = qa * qa + qb * qb + qc * qc
    c1[:m - 1] = qb[:m - 1] * qa[1:] + qc[:m - 1] * qb[1:]
    c2[:m - 2] = qc[:m - 2] * qa[2:]
    d, l1, l2 = np.empty(m), np.zeros(m), np.zeros(m)
    for i in range(m):
        v = (h[i] + h[i + 1]) / 3.0 + lam * c0[i]
        if i >= 1:
            v -= l1[i - 1] * l1[i - 1] * d[i - 1]
        if i >= 2:
            v -= l2[i - 2] * l2[i - 2] * d[i - 2]
        d[i] = v
        if i + 1 < m:
            w = h[i + 1] / 6.0 + lam * c1[i]
            if i >= 1:
                w -= l1[i - 1] * l2[i - 1] * d[i - 1]
            l1[i] = w / v
        if i + 2 < m:
            l2[i] = lam * c2[i] / v
    return qa, qb, qc, c0, c1, c2, d, l1, l2


@njit(nogil=True)
def _misfit(lam, qa, qb, qc, d, l1, l2, y):
    """y - f (N,) of the smoothing spline of `_factor` through y (N,): lam Q gamma."""
    m = d.shape[0]
    z = qa * y[:m] + qb * y[1:m + 1] + qc * y[2:]       # Q'y, then gamma
    for i in range(m):
        if i >= 1:
            z[i] -= l1[i - 1] * z[i - 1]
        if i >= 2:
            z[i] -= l2[i - 2] * z[i - 2]
    z /= d
    for i in range(m - 1, -1, -1):
        if i + 1 < m:
            z[i] -= l1[i] * z[i + 1]
        if i + 2 < m:
            z[i] -= l2[i] * z[i + 2]
    e = np.zeros(m + 2)
    e[:m] += qa * z
    e[1:m + 1] += qb * z
    e[2:] += qc * z
    return lam * e


@njit(nogil=True)
def _smoothed(lam, h, y):
    """f (N, k): the smoothing spline's values at the knots, per column of y (N, k)."""
    qa, qb, qc, _, _, _, d, l1, l2 = _factor(lam, h)
    out = np.empty_like(y)
    for c in range(y.shape[1]):
        column = np.ascontiguousarray(y[:, c])
        out[:, c] = column - _misfit(lam, qa, qb, qc, d, l1, l2, column)
    return out


@njit(nogil=True)
def gcv(lam, h, y):
    """GCV score N |y - f|^2 / tr(I - A)^2 of the cubic smoothing spline f = A y with
    smoothing lam through knots spaced h (N - 1,) (Wahba 1990 eq. 4.3.1), in Reinsch's form
    (`_factor`), tr(I - A) = lam tr(M^-1 Q'Q) from the central bands of M^-1 (Hutchinson
    and de Hoog 1985)."""
    qa, qb, qc, c0, c1, c2, d, l1, l2 = _factor(lam, h)
    e = _misfit(lam, qa, qb, qc, d, l1, l2, y)
    m = d.shape[0]
    s0, s1, s2 = np.zeros(m + 2), np.zeros(m + 2), np.zeros(m + 2)   # S = M^-1: S_ii,
    trace = 0.0                                                    # S_(i+1)i, S_(i+2)i
    for i in range(m - 1, -1, -1):
        s1[i] = -(l1[i] * s0[i + 1] + l2[i] * s1[i + 1])
        s2[i] = -(l1[i] * s1[i + 1] + l2[i] * s0[i + 2])
        s0[i] = 1.0 / d[i] - l1[i] * s1[i] - l2[i] * s2[i]
        trace += s0[i] * c0[i] + 2.0 * (s1[i] * c1[i] + s2[i] * c2[i])
    trace *= lam
    return y.shape[0] * np.sum(e * e) / (trace * trace) if trace > 0.0 else np.inf


def _yaw_pitch(v):
    return np.arctan2(v[:, 1], v[:, 0]), np.arctan2(-v[:, 2], np.hypot(v[:, 0], v[:, 1]))

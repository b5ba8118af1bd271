#!/usr/bin/env python3
"""Independent generator of a car drive on a level (or, with --hills-m, hilly) road and its
consumer-grade IMU + RTK fixes, written as a ROS 2 MCAP bag (sensor_msgs/msg/Imu,
sensor_msgs/msg/NavSatFix).

Written by a helper session trying mimunav as a new user (2026-11-27), from the physics alone:
numpy/scipy and the mcap_ros2 writer, NOT mimunav's code - an oracle for the import and the
track level (`bench/track_drive.py`). Validated there against its own checks: at rest the
gyro reads the Earth rate and the accelerometers -gamma exactly; two integrations of the
position agree to 1.3e-8 m; a plain strapdown of its noise-free IMU ends 3.4 mm off after
600 s.
Hills added by a later helper (2026-11-27), same rules (nothing from mimunav); checked by its
own script: a plain NED strapdown (coning, rotation compensation, midpoint gravity/Coriolis)
over the noise-free IMU ends 2.9/3.9/0.05 mm (N/E/D) off after 600 s on the level road and
2.8/4.3/6.3 mm (A 5 m, L 300 m), 3.4/3.5/1.9 mm (5, 400), 2.2/4.3/0.6 mm (15, 1000); the
velocity agrees with the position's central differences to 1e-6 m/s, h'' and theta' with
theirs to 4e-7 m/s^2 and 3e-9 rad/s; pitch = atan(-v_D / v_H) to 3e-17 rad; at rest on a
grade f^b = C_bn [0, 0, -gamma] with |f^b| = gamma exactly. --hills-m 0 writes the very
bytes (.mcap and .truth.json) it wrote before the hills.

Physics (NED, WGS-84):
  vehicle body = FRD, roll 0; heading psi(t) and horizontal speed v(t) in closed form
  (raised-cosine edged pulses of yaw rate and acceleration), the distance s(t) = int v dt in
  closed form too (`pulse_distance`). Height above the ellipsoid h = H0 + A sin(2 pi s / L)
  (--hills-m A, default 0: level, h = H0; --hill-length-m L, default 300 m; the grade
  dh/ds = A 2 pi / L cos(.) peaks at A 2 pi / L: keep it under ~0.1, e.g. A 5 m with L 400 m,
  A 15 m with L 1000 m). v_D = -h' = -(dh/ds) v, a_D = -h'' = -((dh/ds) a - A (2 pi/L)^2
  sin(.) v^2). The body pitches with the road: theta = atan(dh/ds) (nose up climbing; the
  body's x axis along the velocity), theta' = -A (2 pi/L)^2 sin(.) v / (1 + (dh/ds)^2); a car
  at rest on a grade stays pitched. C_nb = Rz(psi) Ry(theta).
  lat/lon by integrating v_N/(R_N+h), v_E/((R_E+h) cos lat) (Gauss-Legendre per 10 ms).
  w_ib^b = C_bn (w_ie^n + w_en^n) + w_nb^b,  w_nb^b = [-psi_dot sin theta, theta_dot,
           psi_dot cos theta]   (w_en^n with R + h(t))
  f^n    = dv^n/dt + (2 w_ie^n + w_en^n) x v^n - g^n,   g^n = [0, 0, gamma(lat, h(t))] (Somigliana),
           dv^n/dt = [a cos psi - v psi' sin psi, a sin psi + v psi' cos psi, -h'']
  f^b    = C_bn f^n
  IMU sample k stamped t_k = mean over (t_k - T, t_k] of the true quantity at time (t - skew),
  by 5-point Gauss-Legendre quadrature; then sensor axes: x_s = C_sv x_b, with
  C_vs = Rz(mount_yaw) Ry(mount_pitch) Rx(180 deg) (REP-103 FLU sensor -> FRD vehicle, pitched by
  mount_pitch about the vehicle's right axis and yawed by mount_yaw about its down axis:
  mimunav's --mounting-rpy-deg 180 mount_pitch mount_yaw), scale factor on
  sensor z gyro, constant biases (sensor axes), white noise. GNSS fixes at the true lat, lon,
  h(t) plus white noise.
"""
import argparse
import json
import math
import os

import numpy as np

# ---------------- WGS-84 -----------------
A = 6378137.0
F = 1.0 / 298.257223563
E2 = F * (2 - F)
OMEGA = 7.292115e-5
GM = 3.986004418e14
B = A * (1 - F)
GAMMA_E = 9.7803253359
K_SOM = 0.00193185265241
M_SOM = OMEGA ** 2 * A ** 2 * B / GM


def radii(lat):
    s2 = np.sin(lat) ** 2
    den = np.sqrt(1 - E2 * s2)
    RN = A * (1 - E2) / den ** 3          # meridian
    RE = A / den                          # prime vertical
    return RN, RE


def gamma(lat, h):
    s2 = np.sin(lat) ** 2
    g0 = GAMMA_E * (1 + K_SOM * s2) / np.sqrt(1 - E2 * s2)
    return g0 * (1 - 2 / A * (1 + F + M_SOM - 2 * F * s2) * h + 3 / A ** 2 * h ** 2)


# ---------------- drive schedule -----------------
def pulse(t, t0, amp, te, tp):
    """raised-cosine-edged trapezoid pulse: value and integral from t0."""
    t = np.asarray(t, float)
    t1 = t0 + te + tp
    t2 = t1 + te
    val = np.zeros_like(t)
    integ = np.zeros_like(t)
    r = (t >= t0) & (t < t0 + te)
    x = t[r] - t0
    val[r] = amp * 0.5 * (1 - np.cos(np.pi * x / te))
    integ[r] = amp * 0.5 * (x - te / np.pi * np.sin(np.pi * x / te))
    p = (t >= t0 + te) & (t < t1)
    val[p] = amp
    integ[p] = amp * te / 2 + amp * (t[p] - t0 - te)
    fall = (t >= t1) & (t < t2)
    x = t[fall] - t1
    val[fall] = amp * 0.5 * (1 + np.cos(np.pi * x / te))
    integ[fall] = amp * te / 2 + amp * tp + amp * (x - 0.5 * (x - te / np.pi * np.sin(np.pi * x / te)))
    after = t >= t2
    integ[after] = amp * (te + tp)
    return val, integ


# (kind, t0, total change, |rate|, edge s). kind v: dv m/s, a m/s^2; psi: dpsi deg, r deg/s
# (positive psi = clockwise seen from above = right turn in NED/FRD)
EVENTS = [
    ("v", 30.0, 12.0, 1.5, 1.5),
    ("psi", 44.0, 90.0, 12.0, 2.0),
    ("v", 56.0, 6.0, 1.0, 1.5),
    ("psi", 66.0, -45.0, 6.0, 2.5),
    ("v", 80.0, -18.0, 2.0, 1.5),          # stop at ~90 s
    ("v", 104.0, 10.0, 2.0, 1.5),
    ("psi", 112.0, -90.0, 18.0, 1.5),
    ("v", 122.0, 10.0, 1.2, 2.0),
    ("psi", 136.0, 20.0, 8.0, 1.5),
    ("psi", 141.0, -20.0, 8.0, 1.5),
    ("v", 150.0, -12.0, 1.5, 2.0),
    ("psi", 160.0, 120.0, 15.0, 2.0),
    ("v", 172.0, 8.0, 1.0, 2.0),
    ("psi", 184.0, -60.0, 10.0, 2.0),
    ("v", 196.0, -16.0, 2.0, 1.5),         # stop at ~205 s
    ("v", 220.0, 14.0, 1.8, 1.5),
    ("psi", 230.0, 30.0, 5.0, 3.0),
    ("psi", 245.0, -75.0, 9.0, 2.5),
    ("v", 258.0, 5.0, 0.8, 2.0),
    ("psi", 268.0, 15.0, 5.0, 1.5),
    ("psi", 276.0, -15.0, 5.0, 1.5),
    ("v", 285.0, -9.0, 1.5, 2.0),
    ("psi", 294.0, 90.0, 16.0, 1.5),
    ("v", 302.0, 10.0, 1.5, 1.5),
    ("psi", 314.0, 45.0, 7.0, 2.0),
    ("v", 325.0, -20.0, 2.5, 1.5),         # stop at ~334 s
    ("v", 350.0, 8.0, 2.0, 1.0),
    ("psi", 356.0, -90.0, 20.0, 1.0),
    ("v", 362.0, 12.0, 1.5, 1.5),
    ("psi", 375.0, 10.0, 3.0, 2.0),
    ("psi", 385.0, -10.0, 3.0, 2.0),
    ("v", 395.0, -6.0, 1.0, 2.0),
    ("psi", 404.0, 135.0, 14.0, 2.0),
    ("v", 416.0, 6.0, 1.2, 2.0),
    ("psi", 428.0, -30.0, 8.0, 1.5),
    ("psi", 436.0, 30.0, 8.0, 1.5),
    ("v", 444.0, -20.0, 2.0, 2.0),         # stop at ~455 s
    ("v", 470.0, 9.0, 1.5, 1.5),
    ("psi", 478.0, 90.0, 15.0, 2.0),
    ("v", 488.0, 9.0, 1.0, 2.0),
    ("psi", 502.0, -45.0, 6.0, 3.0),
    ("psi", 520.0, 60.0, 10.0, 2.0),
    ("v", 532.0, -8.0, 1.5, 1.5),
    ("psi", 541.0, -100.0, 15.0, 1.5),
    ("v", 552.0, -10.0, 1.5, 2.0),         # stop at ~560 s, rest to the end
]
T_END = 600.0
LAT0, LON0, H0 = math.radians(48.137), math.radians(11.575), 520.0
PSI0 = math.radians(30.0)


def schedule():
    pulses = {"v": [], "psi": []}
    for kind, t0, d, rate, te in EVENTS:
        if kind == "psi":
            d, rate = math.radians(d), math.radians(rate)
        dur = abs(d) / rate
        tp = dur - te
        assert tp >= -1e-12, (kind, t0)
        pulses[kind].append((t0, math.copysign(rate, d), te, max(tp, 0.0)))
    return pulses


PULSES = schedule()


def pulse_distance(t, t0, amp, te, tp):
    """the second integral from t0 of `pulse` (closed form): the distance its speed covers."""
    t = np.asarray(t, float)
    t1 = t0 + te + tp
    t2 = t1 + te
    q = te ** 2 / np.pi ** 2
    s_rise = amp / 2 * (te ** 2 / 2 - 2 * q)
    s_top = s_rise + amp * te / 2 * tp + amp * tp ** 2 / 2
    s_fall = s_top + (amp * te / 2 + amp * tp) * te + amp / 2 * (te ** 2 / 2 + 2 * q)
    out = np.zeros_like(t)
    r = (t >= t0) & (t < t0 + te)
    x = t[r] - t0
    out[r] = amp / 2 * (x ** 2 / 2 + q * (np.cos(np.pi * x / te) - 1))
    p = (t >= t0 + te) & (t < t1)
    x = t[p] - t0 - te
    out[p] = s_rise + amp * te / 2 * x + amp * x ** 2 / 2
    fall = (t >= t1) & (t < t2)
    x = t[fall] - t1
    out[fall] = s_top + (amp * te / 2 + amp * tp) * x + amp / 2 * (
        x ** 2 / 2 - q * (np.cos(np.pi * x / te) - 1))
    after = t >= t2
    out[after] = s_fall + amp * (te + tp) * (t[after] - t2)
    return out


# hills (--hills-m, --hill-length-m): h(s) = H0 + HILL_A sin(2 pi s / HILL_L) of the horizontal
# distance s travelled; 0 = the level road
HILL_A, HILL_L = 0.0, 300.0


def motion(t):
    """speed v, accel a, heading psi, yaw rate r at times t (closed form)."""
    t = np.asarray(t, float)
    a = np.zeros_like(t); v = np.zeros_like(t)
    r = np.zeros_like(t); psi = np.full_like(t, PSI0)
    for p in PULSES["v"]:
        val, integ = pulse(t, *p)
        a += val; v += integ
    for p in PULSES["psi"]:
        val, integ = pulse(t, *p)
        r += val; psi += integ
    return v, a, psi, r


def road(t):
    """height h above the ellipsoid, climb rate h', its rate h'', pitch theta and pitch rate
    theta' at times t (closed form; v is the horizontal speed, s its integral)."""
    t = np.asarray(t, float)
    if HILL_A == 0.0:
        z = np.zeros_like(t)
        return np.full_like(t, H0), z, z, z, z
    v, a, _, _ = motion(t)
    s = np.zeros_like(t)
    for p in PULSES["v"]:
        s += pulse_distance(t, *p)
    k = 2 * np.pi / HILL_L
    sn, cs = np.sin(k * s), np.cos(k * s)
    grade = HILL_A * k * cs                            # dh/ds
    h = H0 + HILL_A * sn
    hd = grade * v
    hdd = grade * a - HILL_A * k ** 2 * sn * v ** 2
    theta = np.arctan(grade)                           # nose up while climbing
    thetad = -HILL_A * k ** 2 * sn * v / (1 + grade ** 2)
    return h, hd, hdd, theta, thetad


def position_solution(dt=0.01, nodes=6):
    """lat(t), lon(t) (callable, array of shape (2, n)): N/E path integrals by Gauss-Legendre
    quadrature over each dt (machine-exact for the smooth closed-form motion), the radii's
    dependence on lat by fixed-point iteration, cubic-spline interpolation between the grid."""
    from scipy.interpolate import CubicSpline
    grid = np.arange(-2.0, T_END + 1.0 + dt / 2, dt)
    xg, wg = np.polynomial.legendre.leggauss(nodes)
    tn = (grid[:-1, None] + dt / 2 + xg[None, :] * dt / 2)
    v, _, psi, _ = motion(tn.ravel())
    vN = (v * np.cos(psi)).reshape(tn.shape)
    vE = (v * np.sin(psi)).reshape(tn.shape)
    hn = road(tn.ravel())[0].reshape(tn.shape)
    lat_n = np.full(tn.shape, LAT0)
    for _ in range(3):
        RN, RE = radii(lat_n)
        dlat = (vN / (RN + hn)) @ wg * dt / 2
        lat_g = LAT0 + np.concatenate([[0.0], np.cumsum(dlat)])
        spl_lat = CubicSpline(grid, lat_g)
        lat_n = spl_lat(tn)
    RN, RE = radii(lat_n)
    dlon = (vE / ((RE + hn) * np.cos(lat_n))) @ wg * dt / 2
    lon_g = LON0 + np.concatenate([[0.0], np.cumsum(dlon)])
    spl_lon = CubicSpline(grid, lon_g)
    # the path starts at rest at t = -2 .. 30 s, so the integration origin is the start point
    return lambda t: np.stack([spl_lat(t), spl_lon(t)])


def truth_at(t, possol):
    """w_ib^b (rad/s) and f^b (m/s^2) in the vehicle FRD frame, plus lat, lon, v_ned, psi
    (and h, theta when `full`)."""
    v, a, psi, r = motion(t)
    h, hd, hdd, theta, thetad = road(t)
    ll = possol(t)
    lat = ll[0]
    RN, RE = radii(lat)
    c, s = np.cos(psi), np.sin(psi)
    vN, vE = v * c, v * s
    vned = np.stack([vN, vE, -hd], -1)
    w_ie = np.stack([OMEGA * np.cos(lat), np.zeros_like(lat), -OMEGA * np.sin(lat)], -1)
    w_en = np.stack([vE / (RE + h), -vN / (RN + h), -vE * np.tan(lat) / (RE + h)], -1)
    dv = np.stack([a * c - v * r * s, a * s + v * r * c, -hdd], -1)
    g = np.stack([np.zeros_like(v), np.zeros_like(v), gamma(lat, h)], -1)
    f_n = dv + np.cross(2 * w_ie + w_en, vned) - g
    w_in = w_ie + w_en

    def to_b(x):  # C_bn = Ry(theta)^T Rz(psi)^T
        y = np.stack([c * x[:, 0] + s * x[:, 1], -s * x[:, 0] + c * x[:, 1], x[:, 2]], -1)
        if HILL_A == 0.0:
            return y
        ct, st = np.cos(theta), np.sin(theta)
        return np.stack([ct * y[:, 0] - st * y[:, 2], y[:, 1], st * y[:, 0] + ct * y[:, 2]], -1)
    w_ib = to_b(w_in)
    # w_nb^b of yaw psi then pitch theta (roll 0): [-psi' sin theta, theta', psi' cos theta]
    if HILL_A == 0.0:
        w_ib[:, 2] += r
    else:
        w_ib += np.stack([-r * np.sin(theta), thetad, r * np.cos(theta)], -1)
    return w_ib, to_b(f_n), lat, ll[1], vned, psi


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


RX180 = np.diag([1.0, -1.0, -1.0])


def imu_ideal(t_stamp, dt, possol, skew=0.0, nodes=5):
    """interval means over (t_k - dt, t_k] of w_ib^b, f^b (vehicle FRD), true time = stamp - skew."""
    xg, wg = np.polynomial.legendre.leggauss(nodes)
    W = np.zeros((len(t_stamp), 3)); Fb = np.zeros((len(t_stamp), 3))
    for x, w in zip(xg, wg):
        tn = t_stamp - skew - dt / 2 + x * dt / 2
        wi, fi, *_ = truth_at(tn, possol)
        W += 0.5 * w * wi
        Fb += 0.5 * w * fi
    return W, Fb


# ---------------- ROS 2 message definitions -----------------
HEADER_DEFS = """================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
IMU_DEF = """std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
""" + HEADER_DEFS + """================================================================================
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
"""
FIX_DEF = """std_msgs/Header header
NavSatStatus status
float64 latitude
float64 longitude
float64 altitude
float64[9] position_covariance
uint8 COVARIANCE_TYPE_UNKNOWN = 0
uint8 COVARIANCE_TYPE_APPROXIMATED = 1
uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN = 2
uint8 COVARIANCE_TYPE_KNOWN = 3
uint8 position_covariance_type
""" + HEADER_DEFS + """================================================================================
MSG: sensor_msgs/NavSatStatus
int8 STATUS_NO_FIX = -1
int8 STATUS_FIX = 0
int8 STATUS_SBAS_FIX = 1
int8 STATUS_GBAS_FIX = 2
int8 status
uint16 SERVICE_GPS = 1
uint16 SERVICE_GLONASS = 2
uint16 SERVICE_COMPASS = 4
uint16 SERVICE_GALILEO = 8
uint16 service
"""

EPOCH_NS = 1_714_550_400_000_000_000  # 2024-05-01T08:00:00Z


def stamp(ns):
    return {"sec": int(ns // 1_000_000_000), "nanosec": int(ns % 1_000_000_000)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--gnss-rate", type=float, default=10.0)
    ap.add_argument("--skew", type=float, default=0.0, help="IMU stamps late by this (s)")
    ap.add_argument("--mount-yaw-deg", type=float, default=0.0)
    ap.add_argument("--mount-pitch-deg", type=float, default=0.0)
    ap.add_argument("--gyro-sf-z", type=float, default=0.0, help="sensor z gyro scale error")
    ap.add_argument("--gyro-bias-dps", type=float, nargs=3, default=[0.08, -0.15, 0.25])
    ap.add_argument("--accel-bias-mg", type=float, nargs=3, default=[4.0, -3.0, 6.0])
    ap.add_argument("--gyro-arw", type=float, default=0.0038, help="deg/s/sqrt(Hz)")
    ap.add_argument("--accel-vrw", type=float, default=70.0, help="ug/sqrt(Hz)")
    ap.add_argument("--gnss-sigma", type=float, default=0.02)
    ap.add_argument("--hills-m", type=float, default=0.0,
                    help="road height H0 + A sin(2 pi s / L) of the distance s travelled (m)")
    ap.add_argument("--hill-length-m", type=float, default=300.0, help="L of --hills-m (m)")
    ap.add_argument("--npz", help="also save the ideal/true arrays here")
    ap.add_argument("--vib", type=float, default=0.0,
                    help="optional road/engine vibration while moving: white accel noise of "
                         "VIB*(0.3 + v/20) m/s^2 and gyro VIB*(0.3 + v/20)*0.2 deg/s rms per axis")
    args = ap.parse_args()

    global HILL_A, HILL_L
    HILL_A, HILL_L = args.hills_m, args.hill_length_m
    rng = np.random.default_rng(args.seed)
    possol = position_solution()
    dt = 1.0 / args.rate
    n = int(round(T_END * args.rate))
    t_imu = np.arange(1, n + 1) * dt
    W, Fb = imu_ideal(t_imu, dt, possol, skew=args.skew)
    C_vs = rot_z(math.radians(args.mount_yaw_deg)) @ rot_y(math.radians(args.mount_pitch_deg)) \
        @ RX180
    C_sv = C_vs.T
    w_s = W @ C_sv.T
    f_s = Fb @ C_sv.T
    w_s[:, 2] *= 1.0 + args.gyro_sf_z
    w_s += np.radians(args.gyro_bias_dps)
    f_s += np.asarray(args.accel_bias_mg) * 1e-3 * 9.80665
    sg = math.radians(args.gyro_arw) * math.sqrt(args.rate)
    sa = args.accel_vrw * 1e-6 * 9.80665 * math.sqrt(args.rate)
    w_s += rng.normal(0, sg, w_s.shape)
    f_s += rng.normal(0, sa, f_s.shape)
    if args.vib > 0:
        vk = motion(t_imu - args.skew)[0]
        amp = np.where(vk > 0.05, args.vib * (0.3 + vk / 20.0), 0.0)[:, None]
        f_s += amp * rng.normal(0, 1, f_s.shape)
        w_s += np.radians(0.2) * amp * rng.normal(0, 1, w_s.shape)

    gdt = 1.0 / args.gnss_rate
    t_fix = np.arange(0, int(round(T_END * args.gnss_rate)) + 1) * gdt
    ll = possol(t_fix)
    RN, RE = radii(ll[0])
    dn, de, dd = rng.normal(0, args.gnss_sigma, (3, len(t_fix)))
    h_fix = road(t_fix)[0]
    lat_f = ll[0] + dn / (RN + h_fix)
    lon_f = ll[1] + de / ((RE + h_fix) * np.cos(ll[0]))
    h_f = h_fix - dd

    if args.npz:
        v, a, psi, r = motion(t_fix)
        np.savez(args.npz, t_imu=t_imu, W=W, Fb=Fb, w_s=w_s, f_s=f_s, t_fix=t_fix,
                 lat=ll[0], lon=ll[1], v=v, psi=psi, r=r, h=h_fix, theta=road(t_fix)[3])

    from mcap_ros2.writer import Writer
    tmp = args.output + ".tmp"
    with open(tmp, "wb") as fh:
        wr = Writer(fh)
        s_imu = wr.register_msgdef("sensor_msgs/msg/Imu", IMU_DEF)
        s_fix = wr.register_msgdef("sensor_msgs/msg/NavSatFix", FIX_DEF)
        gv, av = sg ** 2, sa ** 2
        events = [(int(round(tk * 1e9)), 0, k) for k, tk in enumerate(t_imu)] + \
                 [(int(round(tk * 1e9)), 1, k) for k, tk in enumerate(t_fix)]
        events.sort()
        for ns, kind, k in events:
            abs_ns = EPOCH_NS + ns
            if kind == 0:
                msg = {"header": {"stamp": stamp(abs_ns), "frame_id": "imu_link"},
                       "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                       "orientation_covariance": [-1.0] + [0.0] * 8,
                       "angular_velocity": dict(zip("xyz", map(float, w_s[k]))),
                       "angular_velocity_covariance": [gv, 0, 0, 0, gv, 0, 0, 0, gv],
                       "linear_acceleration": dict(zip("xyz", map(float, f_s[k]))),
                       "linear_acceleration_covariance": [av, 0, 0, 0, av, 0, 0, 0, av]}
                wr.write_message("/imu/data", s_imu, msg, log_time=abs_ns, publish_time=abs_ns)
            else:
                s2 = args.gnss_sigma ** 2
                msg = {"header": {"stamp": stamp(abs_ns), "frame_id": "gnss"},
                       "status": {"status": 2, "service": 1},
                       "latitude": math.degrees(lat_f[k]), "longitude": math.degrees(lon_f[k]),
                       "altitude": float(h_f[k]),
                       "position_covariance": [s2, 0, 0, 0, s2, 0, 0, 0, s2],
                       "position_covariance_type": 2}
                wr.write_message("/gnss/fix", s_fix, msg, log_time=abs_ns, publish_time=abs_ns)
        wr.finish()
    os.replace(tmp, args.output)
    truth = dict(seed=args.seed, skew_s=args.skew, mount_yaw_deg=args.mount_yaw_deg,
                 mount_pitch_deg=args.mount_pitch_deg,
                 mounting_rpy_deg_true=[180, args.mount_pitch_deg, args.mount_yaw_deg],
                 gyro_sf_z=args.gyro_sf_z,
                 gyro_bias_dps_sensor=args.gyro_bias_dps, accel_bias_mg_sensor=args.accel_bias_mg,
                 gyro_arw=args.gyro_arw, accel_vrw_ug=args.accel_vrw, gnss_sigma=args.gnss_sigma,
                 rate=args.rate, gnss_rate=args.gnss_rate)
    if HILL_A != 0.0:      # (absent on the level road: its truth file as before)
        grade = HILL_A * 2 * math.pi / HILL_L
        truth |= dict(hills_m=HILL_A, hill_length_m=HILL_L, max_grade=grade,
                      max_pitch_deg=math.degrees(math.atan(grade)))
    with open(args.output + ".truth.json", "w") as fh:
        json.dump(truth, fh, indent=1)
    print(f"wrote {args.output}: {n} IMU, {len(t_fix)} fixes")


if __name__ == "__main__":
    main()

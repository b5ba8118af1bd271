"""Continuous-time true motion on the rotating WGS-84 Earth and the exact increments of
an ideal IMU riding on it.

A `Motion` knows the vehicle's NED velocity, its time derivative, the attitude q_nb, the
body rate w_nb^b and its derivative as analytic functions of time. Position is the
integral of velocity; `generate` integrates it along the sample times and computes the
ideal angle and velocity increments of every interval (t[k-1], t[k]] by Gauss-Legendre
quadrature of the continuous body rate and specific force (never by differencing a
navigator):

    w_ib^b = w_nb^b + C_bn (w_ie^n + w_en^n)                  (Titterton & Weston 3.4)
    f^b    = C_bn (dv^n/dt + (2 w_ie^n + w_en^n) x v^n - g^n)  (T&W eq. 3.70 solved for f)
"""
import math
import os
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..frames import attitude, earth
from ..kernels import njit
from .trajectory import Trajectory
from ..errors import InputError

# 3-point Gauss-Legendre rule on [0, 1]: exact for polynomials up to degree 5.
_GL_X = 0.5 + 0.5 * np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GL_W = np.array([5.0, 8.0, 5.0]) / 18.0
_CHUNK = 1 << 16       # intervals per batch of quadrature nodes
THREADS = min(2, os.cpu_count() or 1)   # batches of nodes evaluated side by side


@dataclass
class Kinematics:
    """Position-free kinematics at a set of times.

    v_ned: m/s (N, 3); a_ned: d(v_ned)/dt, m/s^2 (N, 3) (the rate of change of the NED
    components, not an inertial acceleration); q_nb: quaternion array (N,);
    w_nb_b: body rate relative to NED, in body axes, rad/s (N, 3); dw_nb_b: its time
    derivative, rad/s^2 (N, 3).
    """
    v_ned: np.ndarray
    a_ned: np.ndarray
    q_nb: np.ndarray
    w_nb_b: np.ndarray
    dw_nb_b: np.ndarray


class Motion:
    """Base class of true motions. Subclasses set t0, t1 (s), lat0, lon0 (rad), h0 (m)
    and implement `kinematics(t)`; `knots` lists the times where the motion's higher
    derivatives jump (quadrature intervals are split there)."""
    t0 = 0.0
    t1 = np.inf
    lat0 = lon0 = h0 = 0.0
    knots = np.empty(0)

    def kinematics(self, t: np.ndarray) -> Kinematics:
        raise NotImplementedError


def integrate_position(motion: Motion, t: np.ndarray, kin: Kinematics | None = None,
                       start: tuple | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geodetic position (lat, lon rad; h m) of `motion` at sorted times t, t[0] == motion.t0
    (or from `start` = (lat, lon, h) at t[0], for a record made block by block).

    Per step, the NED displacement is the Euler-Maclaurin corrected trapezoid
    d = h/2 (v0 + v1) + h^2/12 (a0 - a1) (exact for cubic velocity), converted to
    latitude/longitude with the radii at the step's mid-point; the latitude dependence of
    the radii is resolved per step by fixed-point iteration from the previous step's
    (converged to round-off).
    """
    kin = motion.kinematics(t) if kin is None else kin
    lat0, lon0, h0 = (motion.lat0, motion.lon0, motion.h0) if start is None else start
    dt = np.diff(t)[:, None]
    v, a = kin.v_ned, kin.a_ned
    d = 0.5 * dt * (v[1:] + v[:-1]) + dt**2 / 12 * (a[:-1] - a[1:])
    h = h0 - np.concatenate([[0.0], np.cumsum(d[:, 2])])
    lat, lon = np.empty(len(t)), np.empty(len(t))
    _geodetic_steps(np.ascontiguousarray(d), h, float(lat0), float(lon0), lat, lon)
    return lat, lon, h


@njit(nogil=True, error_model="numpy")
def _geodetic_steps(d, h, lat0, lon0, lat, lon):
    """lat, lon (rad) at the steps' ends from lat0, lon0 and the NED displacements d (m,
    (N-1, 3)) at heights h (m, N): dlat = d_N / (R_N + h), dlon = d_E / ((R_E + h) cos lat)
    at the step's mid-point, the mid-point latitude iterated to a fixed point (at most 4
    passes; 2 where the step is like the previous one). The steps are summed from zero and
    added to lat0, lon0 (a running sum near lat0 would lose its last bits)."""
    lat[0], lon[0] = lat0, lon0
    step, north, east = 0.0, 0.0, 0.0
    for k in range(d.shape[0]):
        h_mid = 0.5 * (h[k] + h[k + 1])
        for _ in range(4):
            s = math.sin(lat[k] + 0.5 * step)
            new = d[k, 0] / (earth.radii_from_sin2(s * s)[0] + h_mid)
            if new == step:
                break
            step = new
        lat_mid = lat[k] + 0.5 * step
        north += step
        lat[k + 1] = lat0 + north
        s = math.sin(lat_mid)
        east += d[k, 1] / ((earth.radii_from_sin2(s * s)[1] + h_mid) * math.cos(lat_mid))
        lon[k + 1] = lon0 + east


def latitude_rate(lat: ArrayLike, h: ArrayLike, v_ned: ArrayLike) -> np.ndarray:
    """dlat/dt = v_N / (R_N + h), rad/s, at latitudes lat (rad), heights h (m) and NED
    velocities v_ned (m/s, (N, 3))."""
    return v_ned[:, 0] / (earth.meridian_radius(lat) + h)


def body_rate_and_specific_force(lat: np.ndarray, h: np.ndarray, kin: Kinematics
                                 ) -> tuple[np.ndarray, np.ndarray]:
    """Inertial body rate w_ib^b (rad/s) and specific force f^b (m/s^2) from kinematics at
    the given positions (rad, m); shapes (N, 3)."""
    n = len(lat)
    w_ib, f_b = np.empty((n, 3)), np.empty((n, 3))
    _imu_signals(np.ascontiguousarray(lat, dtype=float), np.ascontiguousarray(h, dtype=float),
                 kin.v_ned, kin.a_ned, attitude.as_wxyz(kin.q_nb), kin.w_nb_b,
                 w_ib, f_b)
    return w_ib, f_b


@njit(nogil=True)
def _imu_signals(lat, h, v, a, q, w_nb, w_ib, f_b):
    for k in range(lat.shape[0]):
        ie_n, ie_d, en_n, en_e, en_d, g, _, _ = earth.nav_rates(lat[k], h[k], v[k, 0],
                                                                v[k, 1])
        qw, qx, qy, qz = q[k, 0], -q[k, 1], -q[k, 2], -q[k, 3]      # q_bn
        wx, wy, wz = attitude.rotate_scalar(qw, qx, qy, qz, ie_n + en_n, en_e, ie_d + en_d)
        w_ib[k, 0], w_ib[k, 1], w_ib[k, 2] = w_nb[k, 0] + wx, w_nb[k, 1] + wy, w_nb[k, 2] + wz
        cx, cy, cz = 2.0 * ie_n + en_n, en_e, 2.0 * ie_d + en_d
        vn, ve, vd = v[k, 0], v[k, 1], v[k, 2]
        fx, fy, fz = attitude.rotate_scalar(qw, qx, qy, qz, a[k, 0] + cy * vd - cz * ve,
                                            a[k, 1] + cz * vn - cx * vd,
                                            a[k, 2] + cx * ve - cy * vn - g)
        f_b[k, 0], f_b[k, 1], f_b[k, 2] = fx, fy, fz


@dataclass
class TruthRun:
    """A sampled true flight: the trajectory at t (t[0] is the initial state) and the ideal
    increments of the intervals (t[k-1], t[k]], k >= 1: dtheta rad, dv m/s, (N-1, 3), of an
    IMU at the vehicle frame's origin, in vehicle axes.

    w_ib: inertial body rate at the sample times, rad/s (N, 3); ww: the interval integrals
    of w w^T, rad^2/s (N-1, 3, 3), which give the centripetal term at any lever arm."""
    trajectory: Trajectory
    dtheta: np.ndarray
    dv: np.ndarray
    w_ib: np.ndarray
    ww: np.ndarray

    def dv_at(self, r_b: ArrayLike) -> np.ndarray:
        """Velocity increments (m/s, vehicle axes, (N-1, 3)) felt at lever arm r_b (m, vehicle
        axes) from the origin: dv + integral of (dw/dt x r + w x (w x r)) dt
        = dv + (w_k - w_{k-1}) x r + (M - tr(M) I) r, M = integral of w w^T (exact)."""
        r = np.asarray(r_b, dtype=float)
        centripetal = self.ww @ r - np.trace(self.ww, axis1=1, axis2=2)[:, None] * r
        return self.dv + np.cross(np.diff(self.w_ib, axis=0), r) + centripetal


def generate(motion: Motion, t: np.ndarray, start: tuple | None = None) -> TruthRun:
    """Sample `motion` at sorted times t (s, t[0] == motion.t0) and compute exact increments;
    with `start` = (lat, lon, h) the position at t[0] (t[0] then anywhere in the motion's
    span: one block of a longer record).

    Position at the quadrature nodes inside an interval comes from cubic Hermite
    interpolation of the sampled positions (position error ~ dt^4 * jerk / 384, far
    below anything that changes gravity or Earth rate); velocity, attitude and rates at
    the nodes are evaluated exactly.
    """
    t = np.asarray(t, dtype=float)
    if (t[0] != motion.t0 if start is None else t[0] < motion.t0) or \
            np.any(np.diff(t) <= 0) or t[-1] > motion.t1 + 1e-9:
        raise InputError(f"sample times must increase from the motion's start {motion.t0} s "
                         f"to at most its end {motion.t1} s")
    kin = motion.kinematics(t)
    lat, lon, h = integrate_position(motion, t, kin, start)
    truth = Trajectory(t, lat, lon, h, kin.v_ned, kin.q_nb)
    lat_rate = latitude_rate(lat, h, kin.v_ned)

    # Quadrature nodes: 3 per piece; the pieces are the sample intervals cut at the
    # motion's knots (where its higher derivatives jump), each piece tagged with its interval.
    knots = motion.knots[(motion.knots > t[0]) & (motion.knots < t[-1])]
    knots = knots[~np.isin(knots, t)]
    edges = np.insert(t, np.searchsorted(t, knots), knots)
    a, b = edges[:-1], edges[1:]
    k_of = np.searchsorted(t, a, side="right") - 1
    t_lo = t[:-1]
    dtheta, dv = np.zeros((len(t_lo), 3)), np.zeros((len(t_lo), 3))
    ww = np.zeros((len(t_lo), 3, 3))

    def node_signals(c):
        """Nodes of the pieces c ... c + _CHUNK (node arrays ~ 10 MB: bounded memory): their
        intervals, quadrature weights (s), w_ib (rad/s) and f_b (m/s^2)."""
        width = b[c:c + _CHUNK] - a[c:c + _CHUNK]
        nodes = (a[c:c + _CHUNK, None] + width[:, None] * _GL_X).ravel()
        k_node = np.repeat(k_of[c:c + _CHUNK], 3)
        lat_n, h_n = hermite_position(t, lat, lat_rate, h, kin.v_ned, k_node, nodes)
        w_ib, f_b = body_rate_and_specific_force(lat_n, h_n, motion.kinematics(nodes))
        return k_node, (width[:, None] * _GL_W).ravel(), w_ib, f_b

    # the batches' signals on THREADS threads (numba kernels and numpy release the
    # interpreter), summed here in order: the same sums whatever the number of threads
    with ThreadPoolExecutor(THREADS) as pool:
        at_samples = pool.submit(body_rate_and_specific_force, lat, h, kin)
        pending = deque()
        for c in range(0, len(a), _CHUNK):
            pending.append(pool.submit(node_signals, c))
            if len(pending) > THREADS:
                _accumulate(*pending.popleft().result(), dtheta, dv, ww)
        while pending:
            _accumulate(*pending.popleft().result(), dtheta, dv, ww)
        w_samples, _ = at_samples.result()
    return TruthRun(truth, dtheta, dv, w_samples, ww)


@njit(nogil=True)
def _accumulate(k_node, weights, w_ib, f_b, dtheta, dv, ww):
    """Quadrature sums over the nodes of interval k: dtheta[k] += c w_ib, dv[k] += c f_b,
    ww[k] += c w_ib w_ib^T (c the node's weight)."""
    for j in range(k_node.shape[0]):
        k, c = k_node[j], weights[j]
        for i in range(3):
            dtheta[k, i] += c * w_ib[j, i]
            dv[k, i] += c * f_b[j, i]
            for m in range(3):
                ww[k, i, m] += c * w_ib[j, i] * w_ib[j, m]


@njit(nogil=True)
def hermite_position(t: np.ndarray, lat: np.ndarray, lat_rate: np.ndarray, h: np.ndarray,
                     v_ned: np.ndarray, k_node: np.ndarray, tq: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Latitude and height at times tq inside intervals k_node, by cubic Hermite
    interpolation with the exact rates lat' = v_N / (R_N + h) (lat_rate, rad/s, at t),
    h' = -v_D at the ends."""
    lat_q, h_q = np.empty(tq.shape[0]), np.empty(tq.shape[0])
    for j in range(tq.shape[0]):
        k = k_node[j]
        w = t[k + 1] - t[k]
        s = (tq[j] - t[k]) / w
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        lat_q[j] = (h00 * lat[k] + h10 * w * lat_rate[k] + h01 * lat[k + 1]
                    + h11 * w * lat_rate[k + 1])
        h_q[j] = h00 * h[k] - h10 * w * v_ned[k, 2] + h01 * h[k + 1] - h11 * w * v_ned[k + 1, 2]
    return lat_q, h_q

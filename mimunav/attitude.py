"""Attitude as numpy-quaternion arrays: Hamilton, scalar first, q_ab maps frame a to frame b
(v_b = q_ab * v_a * conj(q_ab)); see the log contract's conventions.

Euler angles are the aerospace z-y-x sequence: yaw (heading) about down, pitch about the
new right axis, roll about the new forward axis, giving q_nb for a body FRD frame in NED.
"""
import math

import numpy as np
import quaternion

from .kernels import njit


def from_euler(yaw, pitch, roll):
    """q_nb from yaw, pitch, roll (rad, z-y-x); array of numpy quaternions."""
    cy, sy = np.cos(0.5 * yaw), np.sin(0.5 * yaw)
    cp, sp = np.cos(0.5 * pitch), np.sin(0.5 * pitch)
    cr, sr = np.cos(0.5 * roll), np.sin(0.5 * roll)
    return quaternion.from_float_array(np.stack([
        cy * cp * cr + sy * sp * sr,
        cy * cp * sr - sy * sp * cr,
        cy * sp * cr + sy * cp * sr,
        sy * cp * cr - cy * sp * sr], axis=-1))


def as_euler(q_nb):
    """(yaw, pitch, roll) in rad of q_nb (z-y-x)."""
    w, x, y, z = np.moveaxis(quaternion.as_float_array(q_nb), -1, 0)
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    pitch = np.arcsin(np.clip(2 * (w * y - x * z), -1.0, 1.0))
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    return yaw, pitch, roll


def rotate(q_ab, v_a):
    """v_b = q_ab * v_a * conj(q_ab) for unit q_ab (normalised here), element by element
    with numpy broadcasting of q_ab (...) against v_a (..., 3); a compiled loop
    (`rotate_scalar`), 50x faster than the quaternion products it equals."""
    q = quaternion.as_float_array(q_ab) if np.asarray(q_ab).dtype == quaternion.quaternion \
        else np.asarray(q_ab, dtype=float)
    v = np.asarray(v_a, dtype=float)
    shape = np.broadcast_shapes(q.shape[:-1], v.shape[:-1])
    q = np.ascontiguousarray(np.broadcast_to(q, shape + (4,)).reshape(-1, 4))
    v = np.ascontiguousarray(np.broadcast_to(v, shape + (3,)).reshape(-1, 3))
    out = np.empty_like(v)
    _rotate(q, v, out)
    return out.reshape(shape + (3,))


@njit(nogil=True)
def _rotate(q, v, out):
    for k in range(v.shape[0]):
        n = 1.0 / math.sqrt(q[k, 0] ** 2 + q[k, 1] ** 2 + q[k, 2] ** 2 + q[k, 3] ** 2)
        out[k, 0], out[k, 1], out[k, 2] = rotate_scalar(
            q[k, 0] * n, q[k, 1] * n, q[k, 2] * n, q[k, 3] * n, v[k, 0], v[k, 1], v[k, 2])


def short_way(q):
    """q (quaternion array) with the sign that makes w >= 0: the same rotations (q and -q
    are one), as the turn of angle <= pi - the form a rotation vector or a slerp needs
    (a reference written with w >= 0 flips sign against a navigator's continuous q)."""
    q = np.array(q, copy=True)
    q[quaternion.as_float_array(q)[..., 0] < 0] *= -1
    return q


def rotation_vector_error(q, q_ref):
    """Small-angle error phi (rad, shape (..., 3), |phi| <= pi) with q = exp(phi/2) * q_ref:
    the rotation that takes the reference attitude to q, expressed in the first frame (NED
    for q_nb); the same for either sign of q or q_ref."""
    return quaternion.as_rotation_vector(short_way(q * np.conjugate(q_ref)))


def turn_rate(t, q):
    """Mean rotation rate (rad/s, (N-1,)) between successive attitudes q (quaternion array)
    at times t (s): the angle (<= pi) of conj(q_k) q_k+1 over the step."""
    return np.linalg.norm(quaternion.as_rotation_vector(short_way(np.conjugate(q[:-1]) * q[1:])),
                          axis=1) / np.diff(t)


@njit(inline="always")
def rotate_scalar(qw, qx, qy, qz, x, y, z):
    """Scalar core of `rotate` for compiled kernels: q * (x, y, z) * conj(q), q unit.
    v' = v + 2 w (u x v) + 2 u x (u x v), u = (qx, qy, qz)."""
    tx, ty, tz = 2.0 * (qy * z - qz * y), 2.0 * (qz * x - qx * z), 2.0 * (qx * y - qy * x)
    return (x + qw * tx + (qy * tz - qz * ty), y + qw * ty + (qz * tx - qx * tz),
            z + qw * tz + (qx * ty - qy * tx))

"""Attitude as numpy-quaternion arrays: Hamilton, scalar first, q_ab maps frame a to frame b
(v_b = q_ab * v_a * conj(q_ab)); see the log contract's conventions.

Euler angles are the aerospace z-y-x sequence: yaw (heading) about down, pitch about the
new right axis, roll about the new forward axis, giving q_nb for a body FRD frame in NED.
"""
import numba
import numpy as np
import quaternion


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
    """v_b = q_ab * v_a * conj(q_ab), element by element; v_a shape (..., 3)."""
    v = quaternion.from_vector_part(np.asarray(v_a, dtype=float))
    return quaternion.as_vector_part(q_ab * v * np.conjugate(q_ab))


def rotation_vector_error(q, q_ref):
    """Small-angle error phi (rad, shape (..., 3)) with q = exp(phi/2) * q_ref: the rotation
    that takes the reference attitude to q, expressed in the first frame (NED for q_nb)."""
    return quaternion.as_rotation_vector(q * np.conjugate(q_ref))


def turn_rate(t, q):
    """Mean rotation rate (rad/s, (N-1,)) between successive attitudes q (quaternion array)
    at times t (s): the angle of conj(q_k) q_k+1 over the step."""
    return np.linalg.norm(quaternion.as_rotation_vector(np.conjugate(q[:-1]) * q[1:]),
                          axis=1) / np.diff(t)


@numba.njit(cache=True, inline="always")
def rotate_scalar(qw, qx, qy, qz, x, y, z):
    """Scalar core of `rotate` for compiled kernels: q * (x, y, z) * conj(q), q unit.
    v' = v + 2 w (u x v) + 2 u x (u x v), u = (qx, qy, qz)."""
    tx, ty, tz = 2.0 * (qy * z - qz * y), 2.0 * (qz * x - qx * z), 2.0 * (qx * y - qy * x)
    return (x + qw * tx + (qy * tz - qz * ty), y + qw * ty + (qz * tx - qx * tz),
            z + qw * tz + (qx * ty - qy * tx))

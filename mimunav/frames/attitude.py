"""Attitude as numpy-quaternion arrays: Hamilton, scalar first, q_ab maps frame a to frame b
(v_b = q_ab * v_a * conj(q_ab)); see the log contract's conventions. This is the one attitude
type passed between modules; `as_wxyz` / `from_wxyz` convert to and from the files' float
arrays (w, x, y, z) and `as_scipy` / `from_scipy` to and from scipy's `Rotation` (which orders
x, y, z, w) for its algorithms.

Euler angles are the aerospace z-y-x sequence: yaw (heading) about down, pitch about the
new right axis, roll about the new forward axis, giving q_nb for a body FRD frame in NED.
"""
import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation


def import_quaternion() -> None:
    """Import numpy-quaternion without the scipy.interpolate import it makes only to pick
    spline rather than finite-difference calculus for its derivative and integral helpers
    (0.6-0.8 s of a command's start, and mimunav uses neither); the spline versions it would
    have picked are put back, and they import scipy.interpolate when called. A version that
    cannot be imported so is left to be imported plainly. Run when this module is first
    imported - the CLI imports it before a command that works with attitudes (the
    sys.modules entry it sets for the import's duration is process-wide: before any thread
    starts; measured 0.8-1.5 s against 3.1-3.7 s for numpy-quaternion's import on a loaded
    2-core machine)."""
    import sys
    if "quaternion" in sys.modules or "scipy.interpolate" in sys.modules:
        return
    sys.modules["scipy.interpolate"] = None         # `from scipy.interpolate import` fails
    try:
        import quaternion
        from quaternion import calculus
    except ImportError:
        for name in [m for m in sys.modules if m == "quaternion" or m.startswith("quaternion.")]:
            del sys.modules[name]
        return
    finally:
        if sys.modules.get("scipy.interpolate", 0) is None:
            del sys.modules["scipy.interpolate"]
    for name, spline in (("spline", "spline_evaluation"), ("derivative", "spline_derivative"),
                         ("antiderivative", "spline_indefinite_integral"),
                         ("indefinite_integral", "spline_indefinite_integral"),
                         ("definite_integral", "spline_definite_integral")):
        if hasattr(calculus, spline):
            for module in (calculus, quaternion):
                setattr(module, name, getattr(calculus, spline))


import_quaternion()
import quaternion                                       # noqa: E402

from ..kernels import njit                              # noqa: E402


def as_wxyz(q: np.ndarray) -> np.ndarray:
    """Float array (..., 4) w, x, y, z of the quaternion array q."""
    return quaternion.as_float_array(q)


def from_wxyz(wxyz: ArrayLike) -> np.ndarray:
    """Quaternion array of the float array (..., 4) w, x, y, z."""
    return quaternion.from_float_array(wxyz)


def as_scipy(q: np.ndarray) -> "Rotation":
    """scipy's `Rotation` of the quaternion array q (the same rotation: scipy orders x, y,
    z, w)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_quat(np.roll(as_wxyz(q), -1, axis=-1))


def from_scipy(rotation: "Rotation") -> np.ndarray:
    """Quaternion array of scipy's `Rotation` (one or many)."""
    return from_wxyz(np.roll(rotation.as_quat(), 1, axis=-1))


def from_euler(yaw: ArrayLike, pitch: ArrayLike, roll: ArrayLike) -> np.ndarray:
    """q_nb from yaw, pitch, roll (rad, z-y-x); array of numpy quaternions."""
    cy, sy = np.cos(0.5 * yaw), np.sin(0.5 * yaw)
    cp, sp = np.cos(0.5 * pitch), np.sin(0.5 * pitch)
    cr, sr = np.cos(0.5 * roll), np.sin(0.5 * roll)
    return quaternion.from_float_array(np.stack([
        cy * cp * cr + sy * sp * sr,
        cy * cp * sr - sy * sp * cr,
        cy * sp * cr + sy * cp * sr,
        sy * cp * cr - cy * sp * sr], axis=-1))


GIMBAL_LOCK = 1e-9     # cos(pitch) below which roll and yaw are one angle: their two
#                        arctan2s read rounding (a mounting of 90 deg turns, pitch 90 to
#                        1e-16, had printed roll 49.4 and yaw -79.7 for 0 and -90)


def as_euler(q_nb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(yaw, pitch, roll) in rad of q_nb (z-y-x; C = q_nb's rotation matrix, body -> nav:
    yaw = atan2(C21, C11), pitch = atan2(-C31, hypot(C32, C33)), roll = atan2(C32, C33)).
    At pitch +-90 deg (cos(pitch) under GIMBAL_LOCK) only yaw -+ roll is defined: roll is
    0 and yaw atan2(-C12, C22), the same rotation."""
    w, x, y, z = np.moveaxis(quaternion.as_float_array(q_nb), -1, 0)
    c32, c33 = 2 * (w * x + y * z), 1 - 2 * (x * x + y * y)
    level = np.hypot(c32, c33)
    pitch = np.arctan2(2 * (w * y - x * z), level)
    locked = level < GIMBAL_LOCK
    yaw = np.where(locked, np.arctan2(2 * (w * z - x * y), 1 - 2 * (x * x + z * z)),
                   np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
    roll = np.where(locked, 0.0, np.arctan2(c32, c33))
    return yaw, pitch, roll


def rotate(q_ab: np.ndarray, v_a: ArrayLike) -> np.ndarray:
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


def short_way(q: np.ndarray) -> np.ndarray:
    """q (quaternion array) with the sign that makes w >= 0: the same rotations (q and -q
    are one), as the turn of angle <= pi - the form a rotation vector or a slerp needs
    (a reference written with w >= 0 flips sign against a navigator's continuous q)."""
    q = np.array(q, copy=True)
    q[quaternion.as_float_array(q)[..., 0] < 0] *= -1
    return q


def rotation_vector_error(q: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """Small-angle error phi (rad, shape (..., 3), |phi| <= pi) with q = exp(phi/2) * q_ref:
    the rotation that takes the reference attitude to q, expressed in the first frame (NED
    for q_nb); the same for either sign of q or q_ref."""
    return quaternion.as_rotation_vector(short_way(q * np.conjugate(q_ref)))


def turn_rate(t: ArrayLike, q: np.ndarray) -> np.ndarray:
    """Mean rotation rate (rad/s, (N-1,)) between successive attitudes q (quaternion array)
    at times t (s): the angle (<= pi) of conj(q_k) q_k+1 over the step."""
    return np.linalg.norm(quaternion.as_rotation_vector(short_way(np.conjugate(q[:-1]) * q[1:])),
                          axis=1) / np.diff(t)


@njit(inline="always")
def rotate_scalar(qw: float, qx: float, qy: float, qz: float, x: float, y: float, z: float
                  ) -> tuple[float, float, float]:
    """Scalar core of `rotate` for compiled kernels: q * (x, y, z) * conj(q), q unit.
    v' = v + 2 w (u x v) + 2 u x (u x v), u = (qx, qy, qz)."""
    tx, ty, tz = 2.0 * (qy * z - qz * y), 2.0 * (qz * x - qx * z), 2.0 * (qx * y - qy * x)
    return (x + qw * tx + (qy * tz - qz * ty), y + qw * ty + (qz * tx - qx * tz),
            z + qw * tz + (qx * ty - qy * tx))

"""Attitude conventions against independent geometry."""
import numpy as np
import pytest
import quaternion

from mimunav.frames import attitude


def test_euler_round_trip_and_axes_in_ned():
    rng = np.random.default_rng(0)
    yaw, pitch, roll = (rng.uniform(-np.pi, np.pi, 1000), rng.uniform(-1.5, 1.5, 1000),
                        rng.uniform(-np.pi, np.pi, 1000))
    q = attitude.from_euler(yaw, pitch, roll)
    for a, b in zip(attitude.as_euler(q), (yaw, pitch, roll)):
        np.testing.assert_allclose(np.angle(np.exp(1j * (a - b))), 0, atol=1e-12)
    # body x (forward) in NED is (cos p cos y, cos p sin y, -sin p) for any roll
    x_n = attitude.rotate(q, np.tile([1.0, 0, 0], (1000, 1)))
    np.testing.assert_allclose(x_n, np.stack([np.cos(pitch) * np.cos(yaw),
                                              np.cos(pitch) * np.sin(yaw), -np.sin(pitch)], -1),
                               atol=1e-12)
    # a 90 deg right bank puts body y (right wing) along NED down
    q = attitude.from_euler(np.zeros(1), np.zeros(1), np.full(1, np.pi / 2))
    np.testing.assert_allclose(attitude.rotate(q, np.array([[0.0, 1, 0]])), [[0, 0, 1]], atol=1e-15)


def test_rotation_vector_error_is_the_small_rotation_in_ned():
    q_ref = attitude.from_euler(np.array([0.3]), np.array([0.1]), np.array([-0.2]))
    q = attitude.from_euler(np.array([0.3 + 1e-6]), np.array([0.1]), np.array([-0.2]))
    # a yaw step is a rotation about NED down
    np.testing.assert_allclose(attitude.rotation_vector_error(q, q_ref), [[0, 0, 1e-6]],
                               atol=1e-12)


def test_turn_rate_of_a_steady_rotation_is_its_rate():
    """q(t) = exp(w t / 2 n) about a fixed axis n: the rate between samples is w exactly
    (the step angle over the step), at uneven steps too."""
    import quaternion
    w, n = 0.7, np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    t = np.cumsum(np.r_[0.0, np.random.default_rng(1).uniform(0.01, 0.2, 50)])
    q = quaternion.from_rotation_vector(w * t[:, None] * n)
    np.testing.assert_allclose(attitude.turn_rate(t, q), w, rtol=1e-12)


def test_pitch_at_minus_90_deg_survives_round_off():
    """q = (sqrt(.5), 0, -sqrt(.5), 0) is pitch -90 deg; 2 (w y - x z) rounds to
    -1.0000000000000002, which arcsin alone turns into NaN: the sine is clipped to [-1, 1]."""
    import quaternion
    h = np.sqrt(0.5)
    for sign in (-1.0, 1.0):
        q = quaternion.from_float_array([[h, 0.0, sign * h, 0.0]])
        _, pitch, _ = attitude.as_euler(q)
        np.testing.assert_allclose(pitch, sign * np.pi / 2, atol=1e-7)


def test_euler_angles_at_pitch_90_deg_give_back_the_rotation():
    """At pitch +-90 deg roll and yaw are one angle (yaw - roll at +90, yaw + roll at -90):
    a mounting made of 90 deg turns (roll 0, pitch 90, yaw -90), composed with rounding, had
    printed [49.4, 90.0, -79.7] - 39 deg of another rotation, which pasted back into a spec
    was measured 39.1 deg off. The angles now give back the rotation (scipy's Rotation, an
    independent library, as the oracle), with roll 0 at the lock."""
    from scipy.spatial.transform import Rotation
    turns = Rotation.from_euler("ZYX", [-90.0, 90.0, 0.0], degrees=True) * \
        Rotation.from_rotvec([1e-17, 0.0, 0.0])
    q = attitude.from_wxyz(np.roll(turns.as_quat(), 1))
    yaw, pitch, roll = attitude.as_euler(q)
    assert np.degrees([roll, pitch, yaw]) == pytest.approx([0.0, 90.0, -90.0], abs=1e-9)
    for angles in ([-90.0, 90.0, 30.0], [20.0, -90.0, 40.0], [170.0, -89.99999, -170.0]):
        r = Rotation.from_euler("ZYX", angles, degrees=True)
        got = attitude.as_euler(attitude.from_wxyz(np.roll(r.as_quat(), 1)))
        back = Rotation.from_euler("ZYX", np.array(got).ravel())
        assert (back.inv() * r).magnitude() < 1e-9


def test_euler_of_a_quaternion_array_of_any_shape():
    """as_euler works elementwise on a (2, 3) array as on its flattened copy."""
    rng = np.random.default_rng(3)
    q = attitude.from_euler(rng.uniform(-3, 3, 6), rng.uniform(-1.5, 1.5, 6),
                            rng.uniform(-3, 3, 6))
    for a, b in zip(attitude.as_euler(q.reshape(2, 3)), attitude.as_euler(q)):
        np.testing.assert_allclose(a.ravel(), b, atol=1e-15)


@pytest.mark.slow
def test_quaternion_is_imported_without_scipy_interpolate_and_keeps_its_spline_calculus():
    """The CLI imports numpy-quaternion without the scipy.interpolate import (0.6-0.8 s) it
    makes only to choose its calculus helpers (`mimunav.frames.attitude.import_quaternion`,
    run at the attitude module's import): a fresh process
    that does so and then loads the evaluation has not imported scipy.interpolate, yet
    quaternion's derivative is still the spline one a plain import picks, and it
    differentiates a uniform rotation about z, q(t) = exp(w t z / 2), to
    dq/dt = q (0, 0, 0, w / 2)."""
    import subprocess
    import sys
    probe = ("import sys, numpy as np; from mimunav.frames import attitude; "
             "import mimunav.evaluation.replay, quaternion; "
             "print('scipy.interpolate' in sys.modules, "
             "quaternion.derivative is quaternion.calculus.spline_derivative, "
             "quaternion.definite_integral is quaternion.calculus.spline_definite_integral); "
             "w, t = 0.7, np.linspace(0.0, 2.0, 401); "
             "q = quaternion.from_rotation_vector(np.outer(w * t, [0.0, 0.0, 1.0])); "
             "dq = quaternion.derivative(quaternion.as_float_array(q), t); "
             "e = quaternion.as_float_array(q * quaternion.quaternion(0, 0, 0, w / 2)); "
             "print(float(np.abs(dq[5:-5] - e[5:-5]).max()))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout.split("\n")
    assert out[0] == "False True True"
    assert float(out[1]) < 1e-8


def _unit(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def test_short_way_takes_w_nonnegative_and_keeps_the_rotation():
    """short_way flips q to -q where w < 0 (the same rotation) and leaves the others: the
    rotation vector of the result is the turn of angle <= pi."""
    rng = np.random.default_rng(3)
    q = quaternion.as_quat_array(_unit(rng.normal(size=(500, 4))))
    s = attitude.short_way(q)
    qa, sa = quaternion.as_float_array(q), quaternion.as_float_array(s)
    assert np.all(sa[:, 0] >= 0) and np.any(qa[:, 0] < 0)
    np.testing.assert_array_equal(sa, np.where(qa[:, :1] < 0, -qa, qa))
    assert np.all(np.linalg.norm(quaternion.as_rotation_vector(s), axis=1) <= np.pi + 1e-12)


def test_rotate_broadcasts_one_attitude_over_many_vectors_and_back():
    """rotate of one quaternion over (4, 5, 3) vectors equals the rotation matrix applied to
    each, and of (4, 5) quaternions over one vector the same per quaternion."""
    rng = np.random.default_rng(4)
    q = quaternion.as_quat_array(_unit(rng.normal(size=4)))
    v = rng.normal(size=(4, 5, 3))
    np.testing.assert_allclose(attitude.rotate(q, v), v @ quaternion.as_rotation_matrix(q).T,
                               atol=1e-12)
    qs = quaternion.as_quat_array(_unit(rng.normal(size=(4, 5, 4))))
    one = rng.normal(size=3)
    np.testing.assert_allclose(attitude.rotate(qs, one),
                               np.einsum("...ij,j->...i", quaternion.as_rotation_matrix(qs), one),
                               atol=1e-12)

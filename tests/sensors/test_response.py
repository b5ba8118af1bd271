"""The MIMU's sensing elements written forward (sensors.response) against closed forms, and
against the compensation (seed S1 eqs. 1-4) only as a cross-check of the series reversion."""
import numpy as np

from mimunav.compensation.calibration_file import Calibration
from mimunav.compensation.model import compensate
from mimunav.sensors.mimu import MimuUnit
from mimunav.sensors import response


def _triad(gain, coupling, a2, a3, p0=(0.1, -0.2, 0.05)):
    p1 = np.diag(gain) + coupling
    return response.TriadResponse.from_model(np.array(p0), p1, np.array(a2), np.array(a3),
                                             np.zeros((3, 3))), p1


def test_an_element_inverts_its_model_to_third_order_with_the_closed_form_remainder():
    """No coupling, exaggerated nonlinearity: f = p0 + p1 u + p2 u^2 + p3 u^3 applied to the
    element's output leaves exactly the reversion's fourth-order remainder
    p1_ii 5 n2 (n2^2 - n3) z^4 + O(z^5), z = (x - p0) / p1_ii."""
    gain = np.array([2.0, 3.0, 0.5])
    tri, p1 = _triad(gain, np.zeros((3, 3)), [1e-2, -2e-2, 5e-3], [3e-3, 1e-3, -2e-3])
    x = np.outer(np.linspace(-0.05, 0.05, 11), [1.0, 1.0, 1.0]) + tri.null
    u = tri.volts(x, np.zeros_like(x))
    back = tri.null + u @ p1.T + u * u * (np.array([1e-2, -2e-2, 5e-3])
                                          + np.array([3e-3, 1e-3, -2e-3]) * u)
    z = (x - tri.null) / gain
    remainder = gain * 5 * tri.n2 * (tri.n2**2 - tri.n3) * z**4
    np.testing.assert_allclose(back - x, remainder, rtol=0.05, atol=1e-15)
    # the linear response is the sensitivity: z = S (x - x0) with S = p1^-1
    np.testing.assert_allclose(tri.sensitivity @ p1, np.eye(3), atol=1e-15)


def test_coupling_carries_an_elements_nonlinearity_to_the_other_outputs():
    """With cross-coupling, an input on axis 0 alone comes back from eqs. 1-4 on axis j as
    p1_j0 n2_0 z_0^2: the cross-axis nonlinearity the 63-coefficient model lacks."""
    gain = np.array([2.0, 3.0, 0.5])
    coupling = np.array([[0, 0.02, -0.01], [0.03, 0, 0.01], [-0.04, 0.02, 0]])
    a2 = np.array([1e-3, 0.0, 0.0])
    tri, p1 = _triad(gain, coupling, a2, np.zeros(3), p0=(0, 0, 0))
    x = np.zeros((5, 3))
    x[:, 0] = np.linspace(-0.5, 0.5, 5)
    u = tri.volts(x, np.zeros_like(x))
    back = u @ p1.T + a2 * u * u
    z0 = (u - u * u * tri.n2)[:, 0]              # the element's linear response, to 2nd order
    expect = np.outer(z0**2, p1[:, 0] * tri.n2[0])
    expect[:, 0] = 0.0
    np.testing.assert_allclose(back[:, 1:] - x[:, 1:], expect[:, 1:], rtol=0.02, atol=1e-12)


def test_thermal_offset_and_g_sensitivity_are_what_the_sensor_adds():
    """At zero input the output is the thermal offset b0 + b1 T + b2 T^2 plus the null; a
    gyro under specific force f senses w - G f."""
    unit = MimuUnit.draw(3)
    c = unit.coefficients
    temp = np.array([[20.0, 30.0, 40.0]])
    freq = np.array([[14e3, 14.1e3, 13.9e3]])
    f = np.array([[0.0, 0.0, -9.8]])
    u_a, u_w = response.raw_output(c, f, np.zeros((1, 3)), temp, freq, f)
    u_a0, u_w0 = response.raw_output(c, np.zeros((1, 3)), np.zeros((1, 3)), temp, freq,
                                     np.zeros((1, 3)))
    gyro = response.TriadResponse.from_model(c.W0, c.W1, c.W2, c.W3, c.cw)
    np.testing.assert_allclose(u_w, gyro.volts(-f @ c.C.T, freq), rtol=1e-14)
    offset = c.ct[:, 0] + temp * (c.ct[:, 1] + temp * c.ct[:, 2])
    accel = response.TriadResponse.from_model(c.A0, c.A1, c.A2, c.A3, np.zeros((3, 3)))
    np.testing.assert_allclose(u_a0 - offset, accel.volts(np.zeros((1, 3)), temp), atol=1e-15)


def test_a_drawn_unit_compensated_by_its_own_coefficients_is_right_to_the_stated_bounds():
    """Cross-check against the compensation: a default unit's outputs over its range,
    compensated with its drawn coefficients, give back the input within the module's stated
    bounds of the cross-axis nonlinearity (0.3 mg at 30 g, 4e-3 deg/s at 400 deg/s), and not
    exactly (the sensor is not the model's inverse)."""
    unit = MimuUnit.draw(11)
    rng = np.random.default_rng(2)
    n = 2000
    f = rng.uniform(-30, 30, (n, 3)) * 9.80665 / np.sqrt(3)
    w = rng.uniform(-400, 400, (n, 3)) * np.pi / 180 / np.sqrt(3)
    temp = rng.uniform(-40, 70, (n, 3))
    freq = unit.thermal.resonance_frequency(temp)
    u_a, u_w = response.raw_output(unit.coefficients, f, w, temp, freq, f)
    f_c, w_c, _ = compensate(Calibration.from_dict(unit.coefficients.as_dict()), u_a, u_w,
                             temp, freq, filter_outliers=False)
    df, dw = np.abs(f_c - f).max(), np.abs(w_c - w).max()
    assert 1e-9 < df < 0.3e-3 * 9.80665, df
    assert 1e-9 < dw < 4e-3 * np.pi / 180, dw

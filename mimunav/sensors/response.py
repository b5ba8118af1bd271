"""The MIMU's sensing elements written forward, as a datasheet describes them: the voltage a
triad outputs for a physical input at a temperature. This is the simulated unit's sensor
behaviour; the compensation (`mimunav.compensation`, seed S1 eqs. 1-4) is the analysis that
inverts it, and shares no code with it.

Each element i of a triad (accelerometer: input = specific force, m/s^2; gyro: input = rate
minus the g-induced rate, rad/s) responds as

    z = S (x - x0)                         linear response, V: sensitivity S (V per input
                                           unit; rows = the elements' sensitive axes, with
                                           their misalignment and cross-coupling), null x0
    v_i = z_i + n2_i z_i^2 + n3_i z_i^3    the element's own nonlinearity (1/V, 1/V^2)
    u_i = v_i + b_i(T_i)                   thermal offset, V, a quadratic in the element's
                                           temperature reading (degC; the gyro's: its
                                           resonance frequency, Hz)

and a gyro senses x = w - G f: its g-sensitivity G ((rad/s)/(m/s^2)) driven by the true
specific force.

The unit's parameters are drawn as the seed's Table 2 gives them, in the compensation
model's terms (`sensors.mimu`: A0..A3, W0..W3, C, ct, cw); `from_model` maps them to the
element form by series reversion (an element's inverse z = y - n2 y^2 + (2 n2^2 - n3) y^3
+ 5 n2 (n2^2 - n3) y^4 + ...):

    S = A1^-1,  x0 = A0,  n2_i = -A2_i / A1_ii,  n3_i = 2 n2_i^2 - A3_i / A1_ii.

So the model of eqs. 1-4 describes this sensor to third order on each element's own axis,
and misses, by construction of a real sensor rather than of the model:
- cross-axis nonlinearity: an element's nonlinearity reaches the other outputs through the
  coupling of A1; eqs. 1-4 with the drawn coefficients err by A1_ji n2_i z_i^2 on output j
  (j != i): coupling (accel 0.1-2 %, gyro
  0.1-0.5 %) times the nonlinearity - up to 0.3 mg at 30 g and 4e-3 deg/s at 400 deg/s for
  the default "table1" nonlinearity;
- the fourth-order remainder A1_ii 5 n2_i (n2_i^2 - n3_i) z_i^4 (below 1e-9 of full scale).
"""
from dataclasses import dataclass

import numpy as np

from ..kernels import njit


@dataclass(frozen=True)
class TriadResponse:
    """Forward response of one triad (module doc). Arrays: null (3,) input units,
    sensitivity (3, 3) V per input unit, n2 (3,) 1/V, n3 (3,) 1/V^2, thermal (3, 3) rows
    [b0, b1, b2] of the offset b0 + b1 T + b2 T^2 in V."""
    null: np.ndarray
    sensitivity: np.ndarray
    n2: np.ndarray
    n3: np.ndarray
    thermal: np.ndarray

    @classmethod
    def from_model(cls, p0, p1, p2, p3, thermal):
        """The element form of a triad given in the compensation model's terms (module doc):
        p0 (3,) input units, p1 (3, 3) input units per V, p2 (3,) per V^2, p3 (3,) per V^3,
        thermal (3, 3) V."""
        p1 = np.asarray(p1, dtype=float)
        gain = np.diag(p1)
        n2 = -np.asarray(p2, dtype=float) / gain
        n3 = 2 * n2**2 - np.asarray(p3, dtype=float) / gain
        return cls(np.asarray(p0, dtype=float), np.linalg.inv(p1), n2, n3,
                   np.asarray(thermal, dtype=float))

    def volts(self, x, temperature):
        """Output voltage u (V, (N, 3)) for input x ((N, 3), input units) at the elements'
        temperature readings ((N, 3))."""
        x = np.ascontiguousarray(x, dtype=float)
        temp = np.ascontiguousarray(temperature, dtype=float)
        if x.ndim != 2 or x.shape[1] != 3 or temp.shape != x.shape:
            raise ValueError(f"inputs {x.shape} and temperatures {temp.shape} must be (N, 3)")
        return _volts(x, temp, self.null, np.ascontiguousarray(self.sensitivity), self.n2,
                      self.n3, np.ascontiguousarray(self.thermal))


def raw_output(coefficients, f, w, accel_temperature, gyro_frequency, f_gyro):
    """Raw MIMU voltages (U_a, U_w), V (N, 3), of a unit whose drawn coefficients are
    `coefficients` (a Calibration, model entire-63) for the specific force f (m/s^2) and rate
    w (rad/s) its elements sense, sensor axes, at the accelerometers' temperature (degC) and
    the gyros' resonance frequency (Hz); f_gyro: the true specific force that drives the
    gyros' g-sensitivity (m/s^2)."""
    c = coefficients
    accel = TriadResponse.from_model(c.A0, c.A1, c.A2, c.A3, c.ct)
    gyro = TriadResponse.from_model(c.W0, c.W1, c.W2, c.W3, c.cw)
    sensed_rate = np.asarray(w, dtype=float) - np.asarray(f_gyro, dtype=float) @ c.C.T
    return accel.volts(f, accel_temperature), gyro.volts(sensed_rate, gyro_frequency)


@njit(nogil=True)
def _volts(x, temp, null, sens, n2, n3, thermal):
    """`TriadResponse.volts` sample by sample (one pass, no temporaries)."""
    u = np.empty_like(x)
    for k in range(x.shape[0]):
        d0, d1, d2 = x[k, 0] - null[0], x[k, 1] - null[1], x[k, 2] - null[2]
        for i in range(3):
            z = sens[i, 0] * d0 + sens[i, 1] * d1 + sens[i, 2] * d2     # linear response
            tk = temp[k, i]
            u[k, i] = z + z * z * (n2[i] + n3[i] * z) + (
                thermal[i, 0] + tk * (thermal[i, 1] + tk * thermal[i, 2]))
    return u

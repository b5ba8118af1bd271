"""Temperatures in time: environment, power-on self-heating, gyro resonance frequency.

Every sensor follows a first-order thermal lag toward the equipment-bay temperature plus
its own self-heating rise (its power dissipation):
    tau_i dT_i/dt = T_bay(t) + dT_self,i - T_i,      T_i(0) = T_bay(0) (powered on cold)
and the bay lags the outside air, which follows the ISA lapse rate with altitude:
    tau_bay dT_bay/dt = T_ground - 0.0065 (h - h_ground) - T_bay
so a cold start (seed S3's warm-up) and in-flight swings happen in every simulated flight.
Lags are integrated exactly for a piecewise-constant input (y += (1 - exp(-dt/tau))(u - y)).

A MEMS gyro's drive-mode resonance frequency falls with temperature through Young's
modulus of silicon: f = f0 (1 + tcf (T - 25 degC)), tcf about -30 ppm/degC (datasheet
class); f is the gyro's only temperature reading (seed S1, eq. 4).
"""
from dataclasses import asdict, dataclass

import math

import numpy as np

from ..kernels import njit

ISA_LAPSE = 0.0065          # K/m, ISA troposphere
BAY_TAU_S = 900.0           # s, equipment-bay lag behind the outside air (datasheet class)
SELF_HEATING_C = (8.0, 20.0)        # degC above the bay, uniform per sensor (datasheet class)
SELF_HEATING_TAU_S = (180.0, 600.0)     # s, its time constants, uniform (datasheet class)


def first_order_lag(t, u, tau, y0):
    """y with tau dy/dt = u - y and y(t[0]) = y0, u held over each step (exact for that):
    y[k] = y[k-1] + (1 - exp(-(t[k] - t[k-1]) / tau)) (u[k] - y[k-1]).
    t (n,) s; u (n,) or (n, k); tau s and y0, scalars or (k,); returns the shape of u."""
    u = np.asarray(u, dtype=float)
    u2 = u.reshape(len(u), -1)
    tau = np.broadcast_to(np.asarray(tau, dtype=float), (u2.shape[1],)).copy()
    y0 = np.broadcast_to(np.asarray(y0, dtype=float), (u2.shape[1],)).copy()
    y = np.empty_like(u2)
    _lag(np.asarray(t, dtype=float), u2, tau, y0, y)
    return y.reshape(u.shape)


@njit(nogil=True)
def _lag(t, u, tau, y0, y):
    m = u.shape[1]
    gain = np.empty(m)
    step = 0.0
    if u.shape[0]:
        y[0] = y0
    for k in range(1, u.shape[0]):
        if k == 1 or t[k] - t[k - 1] != step:   # a uniform record: one exp per axis
            step = t[k] - t[k - 1]
            for j in range(m):
                gain[j] = 1.0 - math.exp(-step / tau[j])
        for j in range(m):                      # the axes' recursions side by side
            y[k, j] = y[k - 1, j] + gain[j] * (u[k, j] - y[k - 1, j])


@dataclass
class ThermalModel:
    """Thermal parameters of one unit. Temperatures degC, times s.

    self_heating / tau: 6 values, accelerometers x y z then gyros x y z."""
    self_heating: list
    tau: list
    f0: list = (10000.0, 10000.0, 10000.0)      # gyro resonance at 25 degC, Hz
    tcf: list = (-30e-6, -30e-6, -30e-6)        # 1/degC
    thermistor_noise: float = 0.005             # degC, per sample
    frequency_noise: float = 0.002              # Hz, per sample

    @classmethod
    def draw(cls, rng):
        """Datasheet-class values: 8-20 degC self-heating reached with 3-10 min time
        constants; resonance 8-12 kHz with -25..-35 ppm/degC."""
        return cls(self_heating=rng.uniform(*SELF_HEATING_C, 6).tolist(),
                   tau=rng.uniform(*SELF_HEATING_TAU_S, 6).tolist(),
                   f0=rng.uniform(8000, 12000, 3).tolist(),
                   tcf=(-rng.uniform(25e-6, 35e-6, 3)).tolist())

    def as_dict(self):
        return {k: (list(v) if isinstance(v, (tuple, list)) else v)
                for k, v in asdict(self).items()}

    def sensor_temperatures(self, t, t_env, warm_up_s=0.0, before=None):
        """True accelerometer and gyro temperatures (degC, (n, 3) each) for a bay
        temperature history t_env (degC, (n,)), the unit powered on cold warm_up_s
        seconds before t[0] (the bay at t_env[0] meanwhile). `before`: (t s, the six
        temperatures degC) of the sample before t[0] when the record goes on from an earlier
        block (then warm_up_s is not used)."""
        t = np.asarray(t, dtype=float)
        t_env = np.asarray(t_env, dtype=float)
        u = t_env[:, None] + np.asarray(self.self_heating)
        if before is not None:
            temps = first_order_lag(np.insert(t, 0, before[0]), np.vstack([u[:1], u]),
                                    np.asarray(self.tau), before[1])[1:]
            return temps[:, :3], temps[:, 3:]
        if warm_up_s > 0:
            t, u = np.insert(t, 0, t[0] - warm_up_s), np.vstack([u[:1], u])
        temps = first_order_lag(t, u, np.asarray(self.tau), float(t_env[0]))
        if warm_up_s > 0:
            temps = temps[1:]
        return temps[:, :3], temps[:, 3:]

    def resonance_frequency(self, t_gyro):
        """Gyro drive-mode resonance frequency, Hz (n, 3), at gyro temperatures degC."""
        return np.asarray(self.f0) * (1 + np.asarray(self.tcf) * (t_gyro - 25.0))

    def temperature_at_frequency(self, freq):
        """Inverse of `resonance_frequency`, degC."""
        return 25.0 + (freq / np.asarray(self.f0) - 1) / np.asarray(self.tcf)


def bay_temperature(t, h, t_ground, h_ground, tau=BAY_TAU_S, before=None):
    """Equipment-bay temperature (degC) lagging the ISA outside air along height h (m),
    starting at t_ground; `before`: (t s, degC) of the sample before t[0] when the record
    goes on from an earlier block."""
    outside = t_ground - ISA_LAPSE * (np.asarray(h) - h_ground)
    if before is None:
        return first_order_lag(t, outside, tau, t_ground)
    return first_order_lag(np.insert(np.asarray(t, float), 0, before[0]),
                           np.insert(outside, 0, outside[0]), tau, before[1])[1:]

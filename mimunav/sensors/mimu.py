"""The MEMS IMU (MIMU) of seed S1: a unit's true coefficients, thermal and noise behaviour,
and its simulation from true motion to raw outputs (volts, thermistor degC, resonance Hz).

Where each value comes from (G0 = 9.80665 m/s^2; "datasheet class" = typical published
values for tactical MEMS parts of the seed's class, ranges >= 30 g / >= 400 deg/s):
  voltage scale       accel 0.1 V/g, gyro 5 mV/(deg/s), +-2 % unit to unit; datasheet class
                      (e.g. ADXRS-class gyros 5-7 mV/(deg/s)); outputs differential about 0 V
  cross-coupling      off-diagonals of A1 (W1) relative to the diagonal, magnitude uniform in
                      0.1-2 % (0.1-0.5 %), random sign                      seed S1 Table 2
  2nd-order scale     k2 uniform 2e-5..1e-4 /g (1.5e-4..2.5e-4 /(deg/s)), random sign:
                      contributes k2 x^2 with x in g (deg/s): A2 = k2 A1^2 / G0,
                      W2 = k2 W1^2 (180/pi)                   seed S1 Table 2 [reading of spec]
  3rd-order scale     k3 uniform 5e-6..2e-5 /g^2 (4e-10..1e-9 /(deg/s)^2): A3 = k3 A1^3 / G0^2,
                      W3 = k3 W1^3 (180/pi)^2                               seed S1 Table 2
  g-sensitivity C     every entry uniform 0.01-0.04 (deg/s)/g, random sign  seed S1 Table 2
  bias A0, W0         accel N(0, 20 mg), gyro N(0, 0.5 deg/s); datasheet-class zero offsets
  temperature         bias slope accel U(0.05, 0.5) mg/degC, gyro U(0.005, 0.05) (deg/s)/degC,
                      curvature accel U(1, 5) ug/degC^2, gyro U(1e-5, 1e-4) (deg/s)/degC^2,
                      random signs, zero at 25 degC; datasheet class. Gyro terms expressed in
                      the resonance frequency f through f(T) (thermal.py) as the file needs
  noise               white: accel 100 ug/sqrt(Hz), gyro 0.02 (deg/s)/sqrt(Hz) (datasheet
                      class); flicker bias instability B: accel 0.5 mg, gyro 15 deg/h, half
                      the Table 1 zero-drift bounds (<= 1 mg, <= 30 deg/h); turn-on bias
                      repeatability (per power-on) accel 0.2 mg, gyro 10 deg/h (1 sigma)
  range               accel 40 g, gyro 450 deg/s (Table 1: >= 30 g, >= 400 deg/s, with margin
                      for the shipped 30 g / 400 deg/s flight); the sensing element saturates
  ADC                 20 bits over +-5 V (9.5 uV LSB), outputs clipped at the rails
The `nonlinearity="datasheet"` option divides the gyro k2 by 100: Table 2 taken literally
gives 6-10 % of full scale at 400 deg/s before compensation (see the spec's reading).
"""
import json
import math
from dataclasses import dataclass, field

import numpy as np

from .. import compensation
from ..compensation import Calibration
from ..files import write_atomic
from . import noise
from .mounting import Mounting
from .thermal import ThermalModel
from ..errors import InputError

G0 = 9.80665
DEG = math.pi / 180
UNIT_FORMAT = "mimunav-unit/1"


@dataclass
class NoiseModel:
    """Noise of one triad in physical units: white density (per sqrt(Hz)), flicker
    instability B, turn-on repeatability (1 sigma). Accel m/s^2..., gyro rad/s..."""
    accel_white: float = 100e-6 * G0
    accel_flicker: float = 0.5e-3 * G0
    accel_turn_on: float = 0.2e-3 * G0
    gyro_white: float = 0.02 * DEG
    gyro_flicker: float = 15 * DEG / 3600
    gyro_turn_on: float = 10 * DEG / 3600


@dataclass
class MimuUnit:
    """One MEMS IMU: true compensation coefficients (the inverse of what it outputs), thermal
    and noise models, range and ADC. `coefficients` is a `Calibration` (model entire-63)."""
    name: str
    coefficients: Calibration
    thermal: ThermalModel
    noise: NoiseModel = field(default_factory=NoiseModel)
    range_accel: float = 40 * G0            # m/s^2
    range_gyro: float = 450 * DEG           # rad/s
    adc_lsb: float = 10.0 / 2**20           # V
    adc_rail: float = 5.0                   # V
    rate_hz: float = 1000.0
    mounting: Mounting = field(default_factory=Mounting)
    seed: int | None = None

    @classmethod
    def draw(cls, seed, nonlinearity="table2", rate_hz=1000.0, name=None):
        """Draw a unit like a real one (see the module doc for every value's source)."""
        if nonlinearity not in ("table2", "datasheet"):
            raise InputError("nonlinearity must be 'table2' or 'datasheet'")
        rng = np.random.default_rng(seed)
        sign = lambda n: rng.choice([-1.0, 1.0], n)                        # noqa: E731
        thermal = ThermalModel.draw(rng)
        a_diag = G0 / (0.1 * (1 + 0.02 * rng.standard_normal(3)))         # (m/s^2)/V
        w_diag = DEG / (5e-3 * (1 + 0.02 * rng.standard_normal(3)))       # (rad/s)/V
        a1 = np.diag(a_diag) + _cross(rng, a_diag, 0.001, 0.02)
        w1 = np.diag(w_diag) + _cross(rng, w_diag, 0.001, 0.005)
        k2a, k3a = sign(3) * rng.uniform(2e-5, 1e-4, 3), sign(3) * rng.uniform(5e-6, 2e-5, 3)
        k2w = sign(3) * rng.uniform(1.5e-4, 2.5e-4, 3) / (100 if nonlinearity == "datasheet" else 1)
        k3w = sign(3) * rng.uniform(4e-10, 1e-9, 3)
        coeff = Calibration(
            model="entire-63", unit=name or f"MIMU-{seed:04d}", procedure="true coefficients",
            A0=rng.normal(0, 20e-3 * G0, 3), A1=a1,
            A2=k2a * a_diag**2 / G0, A3=k3a * a_diag**3 / G0**2,
            W0=rng.normal(0, 0.5 * DEG, 3), W1=w1,
            W2=k2w * w_diag**2 / DEG, W3=k3w * w_diag**3 / DEG**2,
            C=sign((3, 3)) * rng.uniform(0.01, 0.04, (3, 3)) * DEG / G0)
        # temperature: bias(T) = s1 (T - 25) + s2 (T - 25)^2 in volts
        a_s1 = sign(3) * rng.uniform(0.05e-3, 0.5e-3, 3) * G0 / a_diag
        a_s2 = sign(3) * rng.uniform(1e-6, 5e-6, 3) * G0 / a_diag
        w_s1 = sign(3) * rng.uniform(0.005, 0.05, 3) * DEG / w_diag
        w_s2 = sign(3) * rng.uniform(1e-5, 1e-4, 3) * DEG / w_diag
        coeff.ct = _poly_about(a_s1, a_s2, 25.0, 1.0)
        # gyro: T - 25 = (f - f0) / (f0 tcf)
        f0, tcf = np.asarray(thermal.f0), np.asarray(thermal.tcf)
        coeff.cw = _poly_about(w_s1, w_s2, f0, f0 * tcf)
        return cls(name=coeff.unit, coefficients=coeff, thermal=thermal, rate_hz=rate_hz,
                   seed=seed)

    # ---- simulation ---------------------------------------------------------------
    def simulate(self, t, dtheta, dv, t_env, rng, hidden=None, warm_up_s=0.0):
        """Raw outputs for ideal sensor-axis increments over (t[k-1], t[k]] (rad, m/s, (N, 3))
        at sample times t (s, (N,), uniform at rate_hz), the unit powered on cold at
        t[0] - dt - warm_up_s in a bay at t_env (degC, (N,)). Returns a dict of the
        `/mimu/raw` fields plus the true sensor temperatures (for the truth file).

        Order: interval-mean rates -> + noise (white, flicker, turn-on bias) -> saturation
        of the sensing element at the range -> temperatures -> inverse of eqs. 1-4 (the
        gyro's g-sensitivity driven by the true specific force) -> ADC quantization and
        rails. The nonlinearity acts on the interval mean (its intra-interval variance term
        is below 1e-6 of full scale at >= 100 Hz for flight dynamics).
        `hidden` (optional) maps (f, w, temps) -> (f, w): extra physics the 63-coefficient
        model lacks (used by the diagnosis tests), applied before saturation."""
        t = np.asarray(t, dtype=float)
        n = len(t)
        dt = np.diff(t, prepend=t[0] - 1 / self.rate_hz)
        f_true = dv / dt[:, None]
        w_true = dtheta / dt[:, None]
        nz = self.noise
        f = (f_true + noise.white(rng, n, self.rate_hz, [nz.accel_white] * 3)
             + noise.flicker(rng, n, self.rate_hz, [nz.accel_flicker] * 3)
             + rng.normal(0, nz.accel_turn_on, 3))
        w = (w_true + noise.white(rng, n, self.rate_hz, [nz.gyro_white] * 3)
             + noise.flicker(rng, n, self.rate_hz, [nz.gyro_flicker] * 3)
             + rng.normal(0, nz.gyro_turn_on, 3))
        t_acc, t_gyro = self.thermal.sensor_temperatures(t, t_env, warm_up_s)
        freq = self.thermal.resonance_frequency(t_gyro)
        if hidden is not None:
            f, w = hidden(f, w, dict(t=t, accel_temperature=t_acc, gyro_temperature=t_gyro,
                                     gyro_frequency=freq, f_true=f_true, w_true=w_true))
        saturated = ((np.abs(f) > self.range_accel) | (np.abs(w) > self.range_gyro)).any(axis=1)
        f = np.clip(f, -self.range_accel, self.range_accel)
        w = np.clip(w, -self.range_gyro, self.range_gyro)
        u_a, u_w = compensation.raw_from_physics(
            self.coefficients, f, w, t_acc, freq,
            f_gyro=np.clip(f_true, -self.range_accel, self.range_accel))
        rail = self.adc_rail
        u_a = np.clip(noise.quantize(u_a, self.adc_lsb), -rail, rail)
        u_w = np.clip(noise.quantize(u_w, self.adc_lsb), -rail, rail)
        return dict(
            t=t, sample_index=np.arange(n, dtype=np.uint64), accel_volts=u_a, gyro_volts=u_w,
            accel_temperature=t_acc + rng.normal(0, self.thermal.thermistor_noise, (n, 3)),
            gyro_frequency=freq + rng.normal(0, self.thermal.frequency_noise, (n, 3)),
            true_accel_temperature=t_acc, true_gyro_temperature=t_gyro,
            saturated=saturated)

    # ---- truth file -----------------------------------------------------------------
    def as_dict(self):
        return {"format": UNIT_FORMAT, "name": self.name, "seed": self.seed,
                "coefficients": self.coefficients.as_dict(), "thermal": self.thermal.as_dict(),
                "noise": vars(self.noise).copy(),
                "range": {"accel_m_s2": self.range_accel, "gyro_rad_s": self.range_gyro},
                "adc": {"lsb_v": self.adc_lsb, "rail_v": self.adc_rail},
                "sample_rate_hz": self.rate_hz, "mounting": self.mounting.as_dict()}

    @classmethod
    def from_dict(cls, doc, source="unit"):
        if doc.get("format") != UNIT_FORMAT:
            raise InputError(f"{source}: format is {doc.get('format')!r}, expected {UNIT_FORMAT!r}")
        try:
            return cls(name=doc["name"], seed=doc.get("seed"),
                       coefficients=Calibration.from_dict(doc["coefficients"], source),
                       thermal=ThermalModel(**doc["thermal"]), noise=NoiseModel(**doc["noise"]),
                       range_accel=doc["range"]["accel_m_s2"],
                       range_gyro=doc["range"]["gyro_rad_s"],
                       adc_lsb=doc["adc"]["lsb_v"], adc_rail=doc["adc"]["rail_v"],
                       rate_hz=doc["sample_rate_hz"],
                       mounting=Mounting.from_dict(doc.get("mounting", {})))
        except (KeyError, TypeError) as exc:
            raise InputError(f"{source}: unit file lacks or mistypes {exc}") from None

    @classmethod
    def load(cls, path):
        with open(path) as fh:
            try:
                doc = json.load(fh)
            except json.JSONDecodeError as exc:
                raise InputError(f"{path}: not valid JSON ({exc})") from None
        return cls.from_dict(doc, str(path))

    def save(self, path, force=False):
        write_atomic(path, json.dumps(self.as_dict(), indent=1) + "\n", force=force)


def _cross(rng, diag, lo, hi):
    """Off-diagonal coupling: entry (i, j) = eps * diag[i], |eps| uniform in [lo, hi]."""
    eps = rng.uniform(lo, hi, (3, 3)) * rng.choice([-1.0, 1.0], (3, 3))
    np.fill_diagonal(eps, 0.0)
    return eps * diag[:, None]


def _poly_about(s1, s2, x0, scale):
    """Coefficients [c0, c1, c2] per axis of s1 u + s2 u^2 with u = (x - x0)/scale."""
    x0 = np.broadcast_to(np.asarray(x0, dtype=float), (3,))
    scale = np.broadcast_to(np.asarray(scale, dtype=float), (3,))
    c2 = s2 / scale**2
    c1 = s1 / scale - 2 * c2 * x0
    c0 = -s1 * x0 / scale + c2 * x0**2
    return np.stack([c0, c1, c2], axis=1)

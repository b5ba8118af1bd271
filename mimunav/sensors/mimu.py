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
                      Both taken literally only with `nonlinearity="table2"`. The default
                      reading `"table1"` (the spec's corrected reading) scales each triad's
                      Table 2 ranges by one factor, so the largest nonlinearity at full scale
                      (k2 x^2 + k3 x^3 at the ranges' tops: gyro 10 % FS at 400 deg/s, accel
                      2.1 % FS at 30 g) equals Table 1's scale-factor fit residual (gyro
                      0.2 % FS, accel 0.05 % FS): gyro x 1/50, accel x 1/42; Table 2's ranking
                      of the terms is kept
  g-sensitivity C     every entry uniform 0.01-0.04 (deg/s)/g, random sign  seed S1 Table 2
  bias A0, W0         accel N(0, 20 mg), gyro N(0, 0.5 deg/s); datasheet-class zero offsets
  temperature         bias slope accel U(0.05, 0.5) mg/degC, gyro U(0.005, 0.05) (deg/s)/degC,
                      curvature accel U(1, 5) ug/degC^2, gyro U(1e-5, 1e-4) (deg/s)/degC^2,
                      random signs, zero at 25 degC; datasheet class. Gyro terms expressed in
                      the resonance frequency f through f(T) (thermal.py) as the file needs
  noise               by grade (`MIMU_GRADES`, default "table1"): white density, flicker bias
                      instability B and turn-on repeatability (1 sigma) of each triad; every
                      grade's source is given where it is defined
  range               accel 40 g, gyro 450 deg/s (Table 1: >= 30 g, >= 400 deg/s, with margin
                      for the shipped 30 g / 400 deg/s flight); the sensing element saturates
  ADC                 20 bits over +-5 V (9.5 uV LSB), outputs clipped at the rails

Beyond the model (`beyond_model`, drawn by default): physics a real MIMU has and the
63-coefficient model of eqs. 1-4 lacks, so that no calibration of that model is perfect by
construction. Written as sensor behaviour in `sensors.hidden` (terms in the log contract's
effect vocabulary, so a diagnosis can name them and a truth file lists them):
  temperature_rate    seed S3's e*dT (thermal gradient during warm-up), dT = change of the
                      sensor temperature over the preceding 60 s: accel U(0.02, 0.1) mg/degC,
                      gyro U(0.001, 0.005) (deg/s)/degC, random sign. S3 gives no magnitudes:
                      assumption, a tenth to a fifth of the static bias slopes above, so a cold
                      start's first minutes carry 0.05-0.3 mg and 10-50 deg/h
  scale_asymmetry     k |x| on each axis (IEEE Std 528 scale-factor asymmetry), |k| U(50, 200)
                      ppm, random sign; datasheet class (an odd-only cubic cannot absorb it)
  cross-axis          the sensing elements are simulated forward (`sensors.response`: an
  nonlinearity        element's own nonlinearity, then the coupling), so each element's
                      nonlinearity reaches the other outputs through the cross-coupling:
                      up to 0.3 mg at 30 g, 4e-3 deg/s at 400 deg/s (response's module doc)
`beyond_model=False` draws a unit that is exactly the 63-coefficient model (its outputs the
inverse of eqs. 1-4 to round-off): for tests of a fit's recovery of known coefficients and
for the diagnosis proof, whose answer keys must hold only the effect each log hides.
"""
import json
import math
from dataclasses import dataclass, field

import numpy as np

from ..compensation.model import raw_from_physics
from ..compensation.calibration_file import Calibration
from ..files import check_format, read_json, write_atomic
from ..kernels import njit
from . import noise, response
from .hidden import HiddenPhysics, HiddenSet
from ..frames.mounting import Mounting
from .thermal import ThermalModel
from ..errors import InputError

G0 = 9.80665
DEG = math.pi / 180
UNIT_FORMAT = "mimunav-unit/1"


# Random-error grades of the MIMU, in datasheet units: white density (accel ug/sqrt(Hz),
# gyro deg/h/sqrt(Hz) = 60 x ARW in deg/sqrt(h)), flicker bias instability B (mg, deg/h),
# turn-on repeatability per power-on (mg, deg/h, 1 sigma).
MIMU_GRADES = {
    # Seed S1 Table 1 at its bound: gyro zero drift <= 30 deg/h, accel ~1 mg, read as the
    # bias stability of 10 s means (GJB 2426 style): white noise gives 2/3 of it (gyro 72
    # deg/h/sqrt(Hz) = 1.2 deg/sqrt(h), 23 deg/h over 10 s; ADXRS450-class density 0.015-0.02
    # (deg/s)/sqrt(Hz)), flicker B half of it; turn-on 1/3 of it (assumption).
    "table1": {"accel_white": 100.0, "accel_flicker": 0.5, "accel_turn_on": 0.2,
               "gyro_white": 72.0, "gyro_flicker": 15.0, "gyro_turn_on": 10.0},
    # Tactical MEMS IMU, ADIS16488A-class datasheet: gyro ARW 0.26 deg/sqrt(h), in-run bias
    # stability 5.1 deg/h; accel VRW 0.029 m/s/sqrt(h) (49 ug/sqrt(Hz)), in-run 0.1 mg;
    # turn-on taken equal to the in-run stability (assumption).
    "tactical": {"accel_white": 49.0, "accel_flicker": 0.1, "accel_turn_on": 0.1,
                 "gyro_white": 15.6, "gyro_flicker": 5.1, "gyro_turn_on": 5.1},
    # Navigation-class MEMS IMU, STIM300-class datasheet: gyro ARW 0.15 deg/sqrt(h), bias
    # instability 0.5 deg/h; accel VRW 0.07 m/s/sqrt(h) (119 ug/sqrt(Hz)), instability
    # 0.05 mg; turn-on twice the instability (assumption).
    "stim300": {"accel_white": 119.0, "accel_flicker": 0.05, "accel_turn_on": 0.1,
                "gyro_white": 9.0, "gyro_flicker": 0.5, "gyro_turn_on": 1.0},
}
# Temperature and g-sensitivity ranges (module doc): magnitudes uniform, random sign
ACCEL_TEMPERATURE_SLOPE_G = (0.05e-3, 0.5e-3)       # g/degC, datasheet class (assumed)
ACCEL_TEMPERATURE_CURVATURE_G = (1e-6, 5e-6)        # g/degC^2, datasheet class (assumed)
GYRO_TEMPERATURE_SLOPE_DEG_S = (0.005, 0.05)        # (deg/s)/degC, datasheet class (assumed)
GYRO_TEMPERATURE_CURVATURE_DEG_S = (1e-5, 1e-4)     # (deg/s)/degC^2, datasheet class (assumed)
G_SENSITIVITY_DEG_S_G = (0.01, 0.04)                # (deg/s)/g, seed S1 Table 2
# Nonlinearity readings (module doc): one factor per triad (accel, gyro) on Table 2's k2, k3.
# "table1": the largest k2 x^2 + k3 x^3 at full scale (30 g, 400 deg/s) equals Table 1's fit
# residual (0.05 % FS, 0.2 % FS): accel 0.15 g / (0.09 + 0.54) g, gyro 0.8 / (40 + 0.064) deg/s.
MIMU_GRADE_SOURCES = {
    "table1": "seed S1 Table 1 at its bound (gyro zero drift 30 deg/h, accel ~1 mg as 10 s bias "
              "stability; ADXRS-class white noise 1.2 deg/sqrt(h))",
    "tactical": "ADIS16488A-class datasheet (ARW 0.26 deg/sqrt(h), in-run 5.1 deg/h; VRW 0.029 "
                "m/s/sqrt(h), 0.1 mg); turn-on assumed equal to in-run",
    "stim300": "STIM300-class datasheet (ARW 0.15 deg/sqrt(h), instability 0.5 deg/h; VRW 0.07 "
               "m/s/sqrt(h), 0.05 mg); turn-on assumed twice the instability"}
NONLINEARITY_SOURCES = {
    "table1": "Table 2 ranges scaled to Table 1's fit residual (the spec's corrected reading)",
    "table2": "Table 2 taken literally (6-10 % of full scale at 400 deg/s; contradicts Table 1)"}
NONLINEARITY = {"table1": (5e-4 * 30 / (1e-4 * 30**2 + 2e-5 * 30**3),
                           2e-3 * 400 / (2.5e-4 * 400**2 + 1e-9 * 400**3)),
                "table2": (1.0, 1.0)}


@dataclass
class NoiseModel:
    """Noise of one triad in physical units: white density (per sqrt(Hz)), flicker
    instability B, turn-on repeatability (1 sigma). Accel m/s^2..., gyro rad/s...
    Defaults: the "table1" grade (`MIMU_GRADES`)."""
    accel_white: float = 100e-6 * G0
    accel_flicker: float = 0.5e-3 * G0
    accel_turn_on: float = 0.2e-3 * G0
    gyro_white: float = 72 * DEG / 3600
    gyro_flicker: float = 15 * DEG / 3600
    gyro_turn_on: float = 10 * DEG / 3600

    @classmethod
    def grade(cls, name):
        """The noise of a named grade of `MIMU_GRADES` in SI units."""
        if name not in MIMU_GRADES:
            raise InputError(f"MIMU grade {name!r}: one of {', '.join(MIMU_GRADES)}")
        g = MIMU_GRADES[name]
        return cls(**{k: v * (1e-6 * G0 if k == "accel_white" else 1e-3 * G0
                              if k.startswith("accel") else DEG / 3600) for k, v in g.items()})


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
    beyond_model: list = field(default_factory=list)   # terms, log contract section 3

    @classmethod
    def draw(cls, seed, nonlinearity="table1", rate_hz=1000.0, name=None, beyond_model=True,
             grade="table1"):
        """Draw a unit like a real one (see the module doc for every value's source):
        `nonlinearity` "table1" (default) or "table2" (Table 2 literally), random errors of
        `grade` (`MIMU_GRADES`); `beyond_model=False`: exactly the 63-coefficient model."""
        if nonlinearity not in NONLINEARITY:
            raise InputError(f"nonlinearity must be one of {', '.join(NONLINEARITY)}")
        noise_model = NoiseModel.grade(grade)
        k_accel, k_gyro = NONLINEARITY[nonlinearity]
        rng = np.random.default_rng(seed)
        sign = lambda n: rng.choice([-1.0, 1.0], n)                        # noqa: E731
        thermal = ThermalModel.draw(rng)
        a_diag = G0 / (0.1 * (1 + 0.02 * rng.standard_normal(3)))         # (m/s^2)/V
        w_diag = DEG / (5e-3 * (1 + 0.02 * rng.standard_normal(3)))       # (rad/s)/V
        a1 = np.diag(a_diag) + _cross(rng, a_diag, 0.001, 0.02)
        w1 = np.diag(w_diag) + _cross(rng, w_diag, 0.001, 0.005)
        k2a = sign(3) * rng.uniform(2e-5, 1e-4, 3) * k_accel
        k3a = sign(3) * rng.uniform(5e-6, 2e-5, 3) * k_accel
        k2w = sign(3) * rng.uniform(1.5e-4, 2.5e-4, 3) * k_gyro
        k3w = sign(3) * rng.uniform(4e-10, 1e-9, 3) * k_gyro
        coeff = Calibration(
            model="entire-63", unit=name or f"MIMU-{seed:04d}", procedure="true coefficients",
            A0=rng.normal(0, 20e-3 * G0, 3), A1=a1,
            A2=k2a * a_diag**2 / G0, A3=k3a * a_diag**3 / G0**2,
            W0=rng.normal(0, 0.5 * DEG, 3), W1=w1,
            W2=k2w * w_diag**2 / DEG, W3=k3w * w_diag**3 / DEG**2,
            C=sign((3, 3)) * rng.uniform(*G_SENSITIVITY_DEG_S_G, (3, 3)) * DEG / G0)
        # temperature: bias(T) = s1 (T - 25) + s2 (T - 25)^2 in volts
        a_s1 = sign(3) * rng.uniform(*ACCEL_TEMPERATURE_SLOPE_G, 3) * G0 / a_diag
        a_s2 = sign(3) * rng.uniform(*ACCEL_TEMPERATURE_CURVATURE_G, 3) * G0 / a_diag
        w_s1 = sign(3) * rng.uniform(*GYRO_TEMPERATURE_SLOPE_DEG_S, 3) * DEG / w_diag
        w_s2 = sign(3) * rng.uniform(*GYRO_TEMPERATURE_CURVATURE_DEG_S, 3) * DEG / w_diag
        coeff.ct = _poly_about(a_s1, a_s2, 25.0, 1.0)
        # gyro: T - 25 = (f - f0) / (f0 tcf)
        f0, tcf = np.asarray(thermal.f0), np.asarray(thermal.tcf)
        coeff.cw = _poly_about(w_s1, w_s2, f0, f0 * tcf)
        extra = _draw_beyond_model(
            np.random.default_rng(None if seed is None else [seed, 63]), thermal) \
            if beyond_model else []
        return cls(name=coeff.unit, coefficients=coeff, thermal=thermal, rate_hz=rate_hz,
                   seed=seed, beyond_model=extra, noise=noise_model)

    # ---- simulation ---------------------------------------------------------------
    def simulate(self, t, dtheta, dv, t_env, rng, hidden=None, warm_up_s=0.0):
        """Raw outputs for ideal sensor-axis increments over (t[k-1], t[k]] (rad, m/s, (N, 3))
        at sample times t (s, (N,), uniform at rate_hz), the unit powered on cold at
        t[0] - dt - warm_up_s in a bay at t_env (degC, (N,)). Returns a dict of the
        `/mimu/raw` fields plus the true sensor temperatures (for the truth file).

        Order: interval-mean rates -> + noise (white, flicker, turn-on bias) -> saturation
        of the sensing element at the range -> temperatures -> the sensing elements' forward
        response (`sensors.response`; the gyro's g-sensitivity driven by the true specific
        force) -> ADC quantization and rails. A unit without `beyond_model` terms is exactly
        the model of eqs. 1-4 instead: its outputs are their inverse, solved to round-off
        (`compensation.raw_from_physics`), for tests of the fits' algebra. The nonlinearity acts on the interval mean (its intra-interval variance term
        is below 1e-6 of full scale at >= 100 Hz for flight dynamics).
        `hidden` (optional) maps (f, w, temps) -> (f, w): extra physics the 63-coefficient
        model lacks (used by the diagnosis tests), applied before saturation after the
        unit's own `beyond_model` terms."""
        rec = MimuRecorder(self, len(t), rng, hidden, warm_up_s)
        settled, rest = rec.record(t, dtheta, dv, t_env), rec.finish()
        if not len(rest["t"]):
            return dict(settled, t=settled["t"].copy())      # not a view of the caller's t
        return {k: np.concatenate([settled[k], rest[k]]) for k in settled}

    # ---- truth file -----------------------------------------------------------------
    def as_dict(self):
        return {"format": UNIT_FORMAT, "name": self.name, "seed": self.seed,
                "coefficients": self.coefficients.as_dict(), "thermal": self.thermal.as_dict(),
                "noise": vars(self.noise).copy(),
                "range": {"accel_m_s2": self.range_accel, "gyro_rad_s": self.range_gyro},
                "adc": {"lsb_v": self.adc_lsb, "rail_v": self.adc_rail},
                "sample_rate_hz": self.rate_hz, "mounting": self.mounting.as_dict(),
                "beyond_model": [dict(term) for term in self.beyond_model]}

    @classmethod
    def from_dict(cls, doc, source="unit"):
        check_format(doc, UNIT_FORMAT, source)
        try:
            return cls(name=doc["name"], seed=doc.get("seed"),
                       coefficients=Calibration.from_dict(doc["coefficients"], source),
                       thermal=ThermalModel(**doc["thermal"]), noise=NoiseModel(**doc["noise"]),
                       range_accel=doc["range"]["accel_m_s2"],
                       range_gyro=doc["range"]["gyro_rad_s"],
                       adc_lsb=doc["adc"]["lsb_v"], adc_rail=doc["adc"]["rail_v"],
                       rate_hz=doc["sample_rate_hz"],
                       mounting=Mounting.from_dict(doc.get("mounting", {})),
                       beyond_model=[HiddenPhysics(term).term
                                     for term in doc.get("beyond_model", [])])
        except (KeyError, TypeError) as exc:
            raise InputError(f"{source}: unit file lacks or mistypes {exc}") from None

    @classmethod
    def load(cls, path):
        return cls.from_dict(read_json(path, "unit file"), str(path))

    def save(self, path, force=False):
        write_atomic(path, json.dumps(self.as_dict(), indent=1) + "\n", force=force)


def _draw_beyond_model(rng, thermal):
    """The unit's physics beyond eqs. 1-4 (module doc), as effect terms in SI units of the
    contract: gyro temperature terms per Hz of resonance frequency (f = f0 (1 + tcf dT))."""
    sign = lambda: float(rng.choice([-1.0, 1.0]))                         # noqa: E731
    terms = []
    for i, axis in enumerate("xyz"):
        per_hz = 1.0 / (thermal.f0[i] * thermal.tcf[i])                   # degC per Hz
        terms += [
            {"effect": "temperature_rate", "sensor": "accel", "axis": axis, "window_s": 60.0,
             "coefficient": sign() * rng.uniform(0.02e-3, 0.1e-3) * G0},
            {"effect": "temperature_rate", "sensor": "gyro", "axis": axis, "window_s": 60.0,
             "coefficient": sign() * rng.uniform(0.001, 0.005) * DEG * per_hz}]
        terms += [{"effect": "scale_asymmetry", "sensor": s, "axis": axis,
                   "coefficient": sign() * rng.uniform(50e-6, 200e-6)} for s in ("accel", "gyro")]
    return terms


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


class MimuRecorder:
    """`MimuUnit.simulate` block by block, for a record of any length in bounded memory:
    `record` the ideal increments of consecutive blocks (t s, dtheta rad, dv m/s, t_env degC)
    and get the raw outputs of the samples settled so far; `finish` gives the rest. Every
    random error comes from its own generator (white noise per triad, flicker shaped over the
    whole record of n samples once, `sensors.noise.TriadNoise`; turn-on; thermistor and
    frequency noise), the thermal lag carries its state, and a hidden effect sees the samples
    it reaches back and ahead (`HiddenPhysics.reach`; a sample waits for its look-ahead
    until the block that completes the record's n samples settles them all), so the outputs
    do not depend on how the record is cut (to round-off where an effect sums over its
    context: time_skew's interpolation). `folder`: where a long record's
    flicker noise is kept (a file) instead of memory. A hidden effect that needs a statistic
    of the whole record (`reach` whole) is refused unless the record comes in one block."""

    def __init__(self, unit, n, rng, hidden=None, warm_up_s=0.0, folder=None):
        self.unit, self.n, self.warm_up_s = unit, n, warm_up_s
        accel, gyro, turn_on, thermistor, frequency = rng.spawn(5)
        nz = unit.noise
        self.accel_noise = noise.TriadNoise(accel, n, unit.rate_hz, nz.accel_white,
                                            nz.accel_flicker, folder)
        self.gyro_noise = noise.TriadNoise(gyro, n, unit.rate_hz, nz.gyro_white,
                                           nz.gyro_flicker, folder)
        self.turn_on = (turn_on.normal(0, nz.accel_turn_on, 3),
                        turn_on.normal(0, nz.gyro_turn_on, 3))
        self.thermistor_rng, self.frequency_rng = thermistor, frequency
        self.hidden = self._with_own(unit, hidden)
        back, ahead, self.whole = self._reach(self.hidden)
        # samples: the reach, plus the interpolation's and gradient's neighbours
        self.back = int(math.ceil(back * unit.rate_hz)) + 2 if self.hidden is not None else 0
        self.ahead = int(math.ceil(ahead * unit.rate_hz)) + 2 if self.hidden is not None else 0
        self.history = self.pending = None     # context already settled / still waiting
        self.last, self.first, self.done = None, None, 0

    @staticmethod
    def _with_own(unit, hidden):
        """The unit's own physics beyond the model, then `hidden`."""
        if not unit.beyond_model:
            return hidden
        own = HiddenSet([HiddenPhysics(term, unit.thermal) for term in unit.beyond_model])
        return own if hidden is None else HiddenSet([own, hidden])

    @staticmethod
    def _reach(hidden):
        """(s back, s ahead, whole record needed) of hidden physics; a callable that does
        not say (no `reach`) needs the whole record."""
        if hidden is None:
            return 0.0, 0.0, False
        if isinstance(hidden, HiddenSet):
            reaches = [MimuRecorder._reach(e) for e in hidden.effects] or [(0.0, 0.0, False)]
            return (max(r[0] for r in reaches), max(r[1] for r in reaches),
                    any(r[2] for r in reaches))
        return hidden.reach() if hasattr(hidden, "reach") else (0.0, 0.0, True)

    @classmethod
    def needs_whole_record(cls, unit, hidden):
        """Whether the unit's and `hidden`'s physics need the record in one block."""
        return cls._reach(cls._with_own(unit, hidden))[2]

    def record(self, t, dtheta, dv, t_env):
        """Raw outputs (the `/mimu/raw` fields and truth extras) of the samples settled."""
        t = np.asarray(t, dtype=float)
        if self.whole and (self.done or self.pending is not None or len(t) != self.n):
            raise InputError("a hidden effect needs the whole record's statistics "
                             "(temperature_scale): simulate the record in one block")
        unit = self.unit
        prev_t = t[0] - 1 / unit.rate_hz if self.last is None else self.last[0]
        dt = np.diff(t, prepend=prev_t)
        f_true, w_true = dv / dt[:, None], dtheta / dt[:, None]
        f = f_true + self.accel_noise.take(len(t)) + self.turn_on[0]
        w = w_true + self.gyro_noise.take(len(t)) + self.turn_on[1]
        t_acc, t_gyro = unit.thermal.sensor_temperatures(
            t, t_env, self.warm_up_s, None if self.last is None else self.last[:2])
        self.last = (t[-1], np.concatenate([t_acc[-1], t_gyro[-1]]))
        block = dict(t=t, f=f, w=w, f_true=f_true, w_true=w_true, accel_temperature=t_acc,
                     gyro_temperature=t_gyro,
                     gyro_frequency=unit.thermal.resonance_frequency(t_gyro))
        if self.first is None:
            self.first = {k: block[k][:1] for k in ("accel_temperature", "gyro_temperature")}
        waiting = block if self.pending is None else _joined(self.pending, block)
        last = self.done + len(waiting["t"]) >= self.n    # the record's end: none to wait for
        return self._settle(waiting, keep=0 if last else self.ahead)

    def finish(self):
        """The outputs of the samples still waiting for their look-ahead."""
        return self._settle(self.pending, keep=0)

    def _settle(self, waiting, keep):
        if waiting is None:
            return self._outputs(None)
        n_wait = len(waiting["t"])
        ready = max(n_wait - keep, 0)
        if not ready:                   # all still waiting for their look-ahead
            self.pending = waiting
            return self._outputs(None)
        if self.hidden is not None:
            ext = waiting if self.history is None else _joined(self.history, waiting)
            lead = len(ext["t"]) - n_wait
            ctx = dict(ext, first=self.first)
            f, w = self.hidden(ext["f"], ext["w"], ctx)
            settled = {k: v[lead:lead + ready] for k, v in ext.items()}
            settled["f"], settled["w"] = f[lead:lead + ready], w[lead:lead + ready]
            done_ext = {k: v[:lead + ready] for k, v in ext.items()}
            self.history = {k: v[-self.back:] if self.back else v[:0]
                            for k, v in done_ext.items()}
        else:
            settled = {k: v[:ready] for k, v in waiting.items()}
        self.pending = {k: v[ready:] for k, v in waiting.items()} if ready < n_wait else None
        return self._outputs(settled)

    def _outputs(self, b):
        unit = self.unit
        if b is None or not len(b["t"]):
            return {k: np.empty((0, 3)) if k in _TRIADS else np.empty(0, dtype=_DTYPES.get(k, float))
                    for k in _FIELDS}
        k = len(b["t"])
        f, saturated = _saturated(b["f"], unit.range_accel)
        w, saturated_w = _saturated(b["w"], unit.range_gyro)
        saturated |= saturated_w
        f_gyro = _saturated(b["f_true"], unit.range_accel)[0]
        t_acc, freq = b["accel_temperature"], b["gyro_frequency"]
        if unit.beyond_model:           # the sensing elements, forward (sensors.response)
            u_a, u_w = response.raw_output(unit.coefficients, f, w, t_acc, freq, f_gyro)
        else:                           # exactly eqs. 1-4: their inverse, to round-off
            u_a, u_w = raw_from_physics(unit.coefficients, f, w, t_acc, freq,
                                                     f_gyro=f_gyro)
        thermistor = self.thermistor_rng.normal(0, unit.thermal.thermistor_noise, (k, 3))
        thermistor += t_acc
        frequency = self.frequency_rng.normal(0, unit.thermal.frequency_noise, (k, 3))
        frequency += freq
        out = dict(
            t=b["t"], sample_index=np.arange(self.done, self.done + k, dtype=np.uint64),
            accel_volts=_adc(u_a, unit.adc_lsb, unit.adc_rail),
            gyro_volts=_adc(u_w, unit.adc_lsb, unit.adc_rail),
            accel_temperature=thermistor, gyro_frequency=frequency,
            true_accel_temperature=t_acc, true_gyro_temperature=b["gyro_temperature"],
            saturated=saturated)
        self.done += k
        return out


_FIELDS = ("t", "sample_index", "accel_volts", "gyro_volts", "accel_temperature",
           "gyro_frequency", "true_accel_temperature", "true_gyro_temperature", "saturated")
_TRIADS = ("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency",
           "true_accel_temperature", "true_gyro_temperature")
_DTYPES = {"sample_index": np.uint64, "saturated": bool}


@njit(nogil=True)
def _saturated(x, limit):
    """(x clipped to +-limit, whether a sample had an axis beyond it); x (N, 3). NaN stays."""
    out = np.empty_like(x)
    beyond = np.zeros(x.shape[0], dtype=np.bool_)
    for k in range(x.shape[0]):
        for i in range(x.shape[1]):
            v = x[k, i]
            if v > limit:
                out[k, i], beyond[k] = limit, True
            elif v < -limit:
                out[k, i], beyond[k] = -limit, True
            else:
                out[k, i] = v
    return out, beyond


def _adc(u, lsb, rail):
    """The ADC's reading of u (V, a fresh array, changed in place): quantised to the step
    lsb (V), then the rails +-rail (V)."""
    return np.clip(noise.quantize(u, lsb, out=u), -rail, rail, out=u)


def _joined(a, b):
    return {k: np.concatenate([a[k], b[k]]) for k in b}

"""Lab runs as the fits see them: a recorded run's steady windows (`LabRun`, `Window`),
their means and flicker covariance, the known inputs of each position and the setting errors
of the lab, and the unit class of seed S1 Table 1 the fits assume.
"""
import math
from dataclasses import dataclass, field

import numpy as np
import quaternion

from ..flightlog import FlightLog
from ..sensors.noise import FLICKER_SPAN
from ..frames import attitude
from .gls import FitError, flicker_covariance


POSITION_NAMES = ["x up", "x down", "y up", "y down", "z up", "z down"]    # lab.SIX_POSITIONS
T_REF = 25.0
AXES = "xyz"
G0 = 9.80665                # standard gravity, m/s^2
DEG = math.pi / 180
# The unit class's datasheet random errors, the fits' weights unless a measured noise file is
# given (`calibrate --noise`, a `mimunav noise` result): seed S1 Table 1 at its bound (gyro
# zero drift 30 deg/h, accel ~1 mg) read as the stability of 10 s means, of which the flicker
# bias instability B is half and the turn-on repeatability a third (assumption). Stated here
# from the seed, not read from the simulator (`sensors.mimu` states its own).
TURN_ON = {"accel": 0.2e-3 * G0, "gyro": 10 * DEG / 3600}
INSTABILITY = {"accel": 0.5e-3 * G0, "gyro": 15 * DEG / 3600}
# nominal voltage scale of the class (datasheet: accel 0.1 V/g, gyro 5 mV/(deg/s))
NOMINAL_SCALE = {"accel": G0 / 0.1, "gyro": DEG / 5e-3}     # (m/s^2)/V, (rad/s)/V
NOMINAL_SCALE_TOLERANCE = 0.02       # 1 sigma, unit to unit (datasheet class, sensors.mimu)
# Table 1 of seed S1: full scale (the stated minimum range) and scale-factor fit residuals
TABLE1_FULL_SCALE = {"accel": 30 * G0, "gyro": 400 * DEG}
TABLE1_RESIDUAL = {"accel": 0.05e-2, "gyro": 0.2e-2}       # fraction of full scale


def _uniform_rms(lo, hi):
    """RMS of a magnitude uniform in [lo, hi] with a random sign."""
    return math.sqrt((hi**3 - lo**3) / (3.0 * (hi - lo)))


# Seed S1 Table 2's class ranges of the terms a reduced model leaves out, as the 1-sigma of
# random effects (magnitude uniform in the range, random sign): the accelerometers' cross-
# coupling (relative to the diagonal) and the gyros' acceleration effect C, (rad/s)/(m/s^2)
CLASS_CROSS_COUPLING = {"accel": _uniform_rms(0.001, 0.02), "gyro": _uniform_rms(0.001, 0.005)}
CLASS_G_SENSITIVITY = _uniform_rms(0.01, 0.04) * DEG / G0


# ---- reading a run -----------------------------------------------------------------------
@dataclass
class Window:
    point: int
    position: int
    q_ps: np.ndarray           # sensor -> platform (nominal)
    r_p: np.ndarray            # unit origin, platform axes, m
    rate: float                # rad/s about platform z
    theta0: float              # platform heading at t0, rad
    t0: float                  # s, start of the first whole interval inside
    t1: float                  # s, end of the last
    k0: int                    # sample slice [k0, k1)
    k1: int
    chamber_c: float


@dataclass
class LabRun:
    """A lab log as windows and raw samples. Times in s since the log's epoch."""
    path: str
    procedure: str
    site: dict
    equipment: dict
    t: np.ndarray
    raw: dict                   # accel_volts, gyro_volts, accel_temperature, gyro_frequency
    windows: list
    power_cycle: bool = False
    # the unit's random errors the fits weight with: flicker instability B and turn-on
    # repeatability per sensor (SI); by default the unit class's datasheet (`INSTABILITY`,
    # `TURN_ON`), or measured (`calibrate(noise=...)`, a `mimunav noise` file)
    noise: dict = field(default_factory=lambda: {
        "instability": dict(INSTABILITY), "turn_on": dict(TURN_ON),
        "source": "assumed: the datasheet class of seed S1 Table 1 (calibration.INSTABILITY, TURN_ON)"})

    def instability(self, sensor):
        return self.noise["instability"][sensor]

    def turn_on(self, sensor):
        return self.noise["turn_on"][sensor]

    @classmethod
    def load(cls, path):
        with FlightLog(path) as log:
            meta = log.metadata()
            if "lab" not in meta:
                raise FitError(f"{path}: no `lab` metadata: not a lab run (see mimunav.lab)")
            raw = log.read("/mimu/raw")
            state = log.read("/lab/state")
        epoch = int(meta["flight"]["epoch_unix_ns"])
        t = (raw["log_time"].astype(np.int64) - epoch) / 1e9
        if len(t) < 2:
            raise FitError(f"{path}: /mimu/raw has {len(t)} samples")
        fields = ("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency")
        data = {k: np.ascontiguousarray(raw[k], dtype=float) for k in fields}
        bad = [k for k in fields if not np.isfinite(data[k]).all()]
        if bad:
            raise FitError(f"{path}: non-finite raw values in {', '.join(bad)}")
        ts = (state["log_time"].astype(np.int64) - epoch) / 1e9
        return cls.from_arrays(str(path), meta["lab"], t, data, ts, state)

    @classmethod
    def from_arrays(cls, path, lab, t, data, ts, state):
        """A run from its samples (t s, raw fields) and lab-state messages (stamps ts s and
        a structured array or dict of LabState fields); `lab` is the `lab` metadata."""
        windows = []
        for j in np.nonzero(np.asarray(state["steady"]) == 1)[0]:
            end = ts[j + 1] if j + 1 < len(ts) else t[-1]
            k0 = int(np.searchsorted(t, ts[j], side="left")) + 1     # interval (t[k0-1], t[k0]]
            k1 = int(np.searchsorted(t, end + 1e-9, side="right"))
            if k1 - k0 < 2:
                continue
            t0 = t[k0 - 1]
            rate = float(state["table_rate"][j])
            windows.append(Window(int(state["point"][j]), int(state["position"][j]),
                                  np.array(state["fixture_attitude_wxyz"][j]),
                                  np.array(state["position_m"][j]), rate,
                                  float(state["table_angle"][j]) + rate * (t0 - ts[j]),
                                  t0, t[k1 - 1], k0, k1, float(state["chamber_temperature"][j])))
        return cls(path, lab["procedure"], lab["site"], lab["equipment"], t, data,
                   windows, bool(lab.get("power_cycle", False)))

    def means(self, x):
        """Window means of a per-sample array x (N, ...) -> (n_windows, ...)."""
        return slice_means(x, np.array([w.k0 for w in self.windows]),
                           np.array([w.k1 for w in self.windows]))

    def flicker(self):
        """`flicker_covariance` of this run's windows, from 1 / (FLICKER_SPAN x run length)
        - slower wander is a near-constant offset that the fitted bias absorbs - to Nyquist
        (cached)."""
        if getattr(self, "_flicker", None) is None:
            t0 = np.array([w.t0 for w in self.windows])
            t1 = np.array([w.t1 for w in self.windows])
            rate = 1.0 / np.median(np.diff(self.t))
            f_low = 1.0 / (FLICKER_SPAN * (self.t[-1] - self.t[0]))
            self._flicker = flicker_covariance(t0, t1, f_low, rate / 2)
        return self._flicker

    def row_covariance(self, white, instability, rows):
        """Covariance of row means (each row the mean of its windows) for window white
        variances `white` (n_windows,) and a flicker bias of instability B (same units)."""
        p = np.zeros((len(rows), len(self.windows)))
        for j, r in enumerate(rows):
            p[j, list(r)] = 1.0 / len(r)
        return p @ (np.diag(white) + instability**2 * self.flicker()) @ p.T

    def design(self, v, order):
        """`WindowDesign` of the voltages v (N, 3) for polynomial order 1 or 3."""
        return WindowDesign(self, v, order)

    def mean_variances(self, x):
        """White-noise variance of each window mean of x (N, k): var(x) / n, var from the
        second difference of the samples (insensitive to slow drift within the window)."""
        return np.array([np.diff(x[w.k0:w.k1], n=2, axis=0).var(axis=0) / 6.0 / (w.k1 - w.k0)
                         for w in self.windows])


def slice_means(x, k0, k1):
    """Means of x (N, ...) over the disjoint, increasing sample slices [k0, k1)."""
    pad = np.concatenate([x, np.zeros((1,) + x.shape[1:])])
    sums = np.add.reduceat(pad, np.column_stack([k0, k1]).ravel(), axis=0)[::2]
    return sums / (k1 - k0).reshape((-1,) + (1,) * (x.ndim - 1))


class WindowDesign:
    """Window means of the triad regressors [1, Vx, Vy, Vz, V^2 (3), V^3 (3)] and the
    white-noise covariance of those means (from second differences), so the regressors of
    output axis i, [1, V, V_i^2, V_i^3], and the variance b^T S b of any model's window mean
    come without touching the samples again."""

    def __init__(self, run, v, order):
        # the cubic columns always (an order-1 fit states what it leaves out: `omitted`)
        x = np.concatenate([np.ones((len(v), 1)), v, v * v, v * v * v], axis=1)
        self.order = order
        self.mean = run.means(x)
        self.cov = np.array([_second_difference_cov(x[w.k0:w.k1]) for w in run.windows])

    def columns(self, i):
        return [0, 1, 2, 3] + ([4 + i, 7 + i] if self.order == 3 else [])

    def regressors(self, i, rows):
        """(n_rows, p) regressors of output axis i averaged over each row's windows."""
        m = self.mean[:, self.columns(i)]
        return np.array([m[list(r)].mean(axis=0) for r in rows])

    def omitted(self, i, rows, sensor):
        """(n_rows, 2) for an order-1 fit: the nonlinearity shapes it leaves out,
        (x / FS)^2 and (x / FS)^3 with x = N V_i (N the nominal scale), each times its prior
        1-sigma at full scale. Seed S1 Table 1 bounds the scale-factor nonlinearity to
        TABLE1_RESIDUAL of full scale; each shape's full-scale value is taken uniform within
        that bound (1 sigma = bound / sqrt 3). None for an order-3 fit (it models them)."""
        if self.order == 3:
            return None
        fs = TABLE1_FULL_SCALE[sensor]
        x = NOMINAL_SCALE[sensor] / fs
        m = self.mean[:, [4 + i, 7 + i]] * [x**2, x**3]
        sigma = TABLE1_RESIDUAL[sensor] * fs / math.sqrt(3.0)
        return sigma * np.array([m[list(r)].mean(axis=0) for r in rows])

    def variances(self, i, b):
        """White variance of each window's mean model output b . regressors."""
        c = self.columns(i)
        return np.einsum("j,kjl,l->k", b, self.cov[:, c][:, :, c], b)


def _second_difference_cov(x):
    d2 = np.diff(x, n=2, axis=0)
    d2 = d2 - d2.mean(axis=0)
    return d2.T @ d2 / (6.0 * max(len(d2) - 1, 1) * len(x))


# ---- known input ---------------------------------------------------------------------------
def known_inputs(run, tilt=(0.0, 0.0), rate_rel=0.0, fixture=None, radius=None):
    """Mean specific force (m/s^2) and rate (rad/s), sensor axes, over every window (n, 3)
    each, for the nominal lab state perturbed by setting errors: table tilt (rad, 2), rate
    error (relative), fixture rotation per position (rad, (n_pos, 3), platform axes), radius
    error per position (m)."""
    ws = run.windows
    lat, g = run.site["latitude"], run.site["gravity_m_s2"]
    omega = run.site["earth_rate_rad_s"]
    c_tilt = quaternion.as_rotation_matrix(quaternion.from_rotation_vector([*tilt, 0.0]))
    w_ie = c_tilt.T @ np.array([omega * math.cos(lat), 0.0, -omega * math.sin(lat)])
    g_n = c_tilt.T @ np.array([0.0, 0.0, g])
    pos = np.array([w.position for w in ws])
    rate = np.array([w.rate for w in ws]) * (1 + rate_rel)
    th0 = np.array([w.theta0 for w in ws])
    dth = rate * np.array([w.t1 - w.t0 for w in ws])
    moving = np.abs(dth) > 1e-12
    safe = np.where(moving, dth, 1.0)
    c = np.where(moving, (np.sin(th0 + dth) - np.sin(th0)) / safe, np.cos(th0))
    s = np.where(moving, (np.cos(th0) - np.cos(th0 + dth)) / safe, np.sin(th0))

    def mean_to_platform(v):          # mean of Rz(theta)^T v
        return np.column_stack([c * v[0] + s * v[1], -s * v[0] + c * v[1],
                                np.full(len(c), v[2])])
    r = np.array([w.r_p for w in ws], dtype=float)
    if radius is not None:
        r[:, 0] += np.where(r[:, 0] != 0, np.asarray(radius)[pos], 0.0)
    r_h = r * [1.0, 1.0, 0.0]
    w_ie_p = mean_to_platform(w_ie)
    v_p = np.cross(rate[:, None] * [0.0, 0.0, 1.0], r)            # velocity / ... of the point
    f_p = -rate[:, None] ** 2 * r_h + 2 * np.cross(w_ie_p, v_p) - mean_to_platform(g_n)
    w_p = w_ie_p + rate[:, None] * [0.0, 0.0, 1.0]
    q = attitude.from_wxyz(np.array([w.q_ps for w in ws]))
    if fixture is not None:
        q = quaternion.from_rotation_vector(np.asarray(fixture)[pos]) * q
    c_ps = quaternion.as_rotation_matrix(q)
    return np.einsum("kji,kj->ki", c_ps, f_p), np.einsum("kji,kj->ki", c_ps, w_p)


def setting_perturbations(run):
    """The lab's setting errors as (name, kwargs for known_inputs) at +1 sigma each."""
    eq = run.equipment
    n_pos = 1 + max(w.position for w in run.windows)
    out = [(f"tilt{i}", {"tilt": tuple(eq["table_tilt_rad"] * (np.arange(2) == i))})
           for i in range(2)]
    if any(w.rate for w in run.windows):
        out.append(("rate", {"rate_rel": eq["rate_rel"]}))
    for p in range(n_pos):
        for i in range(3):
            fix = np.zeros((n_pos, 3))
            fix[p, i] = eq["fixture_rad"]
            out.append((f"fixture{p}{AXES[i]}", {"fixture": fix}))
        if any(w.r_p[0] and w.position == p for w in run.windows):
            rad = np.zeros(n_pos)
            rad[p] = eq["radius_m"]
            out.append((f"radius{p}", {"radius": rad}))
    return out

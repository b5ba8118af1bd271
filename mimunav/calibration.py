"""Fits that turn lab runs (`lab`, or real lab recordings with the same channels) into
calibration files (`mimunav-calibration/1`) with the covariance of every fitted term.

A run is read as steady *windows* (from `/lab/state`): per window the means of the raw
outputs over the whole sample intervals inside it, and the *known input*, the exact mean
specific force and rate that the sensor axes felt there, computed from the nominal lab state
(platform frame as in `lab`: z down along the table axis, heading theta(t) = theta_a +
W (t - t_a)), never from the simulator:
    w_p = W z + C_pn(theta) w_ie^n
    f_p = -W^2 r_h + 2 (C_pn(theta) w_ie^n) x (W z x r) - C_pn(theta) g^n
(the Earth-rate cross terms of w_ib x (w_ib x r) + dw_ib/dt x r reduce to the Coriolis form),
averaged over the window in closed form (theta is linear in t), then C_sp applied.

Methods (seed S1 section 3.1 unless stated):
  entire           thermal chamber -> ct, cw (eqs. 2, 4); rate table, paired positions
                   (axis up at +W with axis down at -W: gravity and its C term cancel) ->
                   W0..W3 (eqs. 5, 6); centrifuge -> A0..A3 (eq. 7) and C from the residual
                   of eq. 3 regressed on the applied acceleration (eqs. 8-10), with a
                   nuisance bias for that power-on's turn-on offset (not written)
  traditional      multi-position statics -> A0, A1; single-axis rate table -> W0, W1;
                   no temperature, nonlinearity or g-sensitivity (the paper's refs [2-5])
  twelve-position  seed S2: twelve statics -> A0, A1; gyro biases from the mean of all
                   twelve (Earth rate and g cancel) with the datasheet scale (5 mV/(deg/s))
  cold-start       seed S3 (see `fit_cold_start`)
  rotation         seed S4 eqs. 4-5: the gyros' k0..k3 from the unit turning on a rotation
                   mechanism on a level rate table (`rotation_calibration`, model rotation-cubic)
  ellipsoid        seed S4 / S1 ref [3], field calibration: static orientations nobody
                   measured (`lab` procedure hand-held) -> A0 and an upper-triangular A1
                   from |A0 + A1 u| = g alone (`fit_ellipsoid`); gyro biases as S2's

Estimator: generalised least squares per output axis on window means. Their covariance is
the white noise of each mean (from second differences of its samples) plus the bias
instability of the unit class as a flicker process (datasheet B, `INSTABILITY`; the
covariance of window means under a 1/f spectrum, `flicker_covariance`), so slow bias wander
shared by neighbouring set points is not mistaken for independent scatter; the covariance
is scaled by chi2/dof where that exceeds 1. Uncertainty is carried as a linear map
from independent unit-variance sources to every coefficient's error: each stage's own GLS
covariance, the lab's setting errors (`lab.EQUIPMENT`, from the log's metadata), the turn-on
bias repeatability of the power-on a bias was fitted in (datasheet values, `TURN_ON`),
and the upstream coefficients a stage depends on (chamber -> rate table and centrifuge;
rate table -> C), each propagated by finite differences of the refit (the fits are linear
in these perturbations to first order).

Gauge: a constant voltage offset of eq. 2 (4) trades exactly against A0..A3 (W0..W3),
so the temperature polynomials are fixed to vanish at a reference reading: T_ref = 25 degC
for the accelerometers, f_ref = each gyro's resonance frequency at the chamber's 25 degC set
point; both are written to the file under "reference".
"""
import math
from dataclasses import dataclass, field

import numpy as np
import quaternion
import scipy.linalg
import scipy.optimize

from .compensation import Calibration, compensate, poly2
from .effects import temperature_change
from .flightlog import FlightLog
from .sensors.noise import FLICKER_SPAN
from .errors import InputError

POSITION_NAMES = ["x up", "x down", "y up", "y down", "z up", "z down"]    # lab.SIX_POSITIONS
METHODS = ("entire", "traditional", "twelve-position", "cold-start", "ellipsoid", "rotation")
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


class FitError(InputError):
    """Lab data that cannot give the requested coefficients, saying what is missing."""


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
    q = quaternion.from_float_array(np.array([w.q_ps for w in ws]))
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


# ---- estimator -----------------------------------------------------------------------------
def gls(x, y, cov, omitted=None):
    """Generalised least squares y = x b + e, Cov(e) = cov (n, n). Returns (b, Cov(b),
    chi2 / dof, rms residual); Cov(b) is scaled by chi2 / dof when that exceeds 1 (scatter
    beyond the noise model is reported, never hidden).

    `omitted` (n, k): shapes the model leaves out, each column scaled to its 1-sigma prior
    size (a random effect). The estimate is unchanged (weights from `cov` alone); Cov(b)
    adds their projection P P^T, P = (x' cov^-1 x)^-1 x' cov^-1 omitted, and chi2 is taken
    against cov + omitted omitted^T, so scatter they explain does not inflate twice."""
    n, p = x.shape
    if n <= p:
        raise FitError(f"{n} data points for {p} coefficients")
    scale = np.abs(x).max(axis=0)
    scale[scale == 0] = 1.0
    xs = x / scale
    chol = np.linalg.cholesky(cov + np.eye(n) * 1e-12 * np.trace(cov) / n)
    a = scipy.linalg.solve_triangular(chol, xs, lower=True)
    yw = scipy.linalg.solve_triangular(chol, y, lower=True)
    cond = np.linalg.cond(a)
    if cond > 1e10:
        raise FitError(f"the design cannot separate the {p} coefficients (condition number "
                       f"{cond:.2g})")
    b, *_ = np.linalg.lstsq(a, yw, rcond=None)
    inv = np.linalg.inv(a.T @ a)
    if omitted is None:
        ratio = float(np.sum((yw - a @ b) ** 2)) / (n - p)
        cov_b = inv * max(1.0, ratio)
    else:
        r = y - xs @ b
        ratio = float(r @ np.linalg.solve(cov + omitted @ omitted.T, r)) / (n - p)
        proj = inv @ a.T @ scipy.linalg.solve_triangular(chol, omitted, lower=True)
        cov_b = inv * max(1.0, ratio) + proj @ proj.T
    rms = float(np.sqrt(np.mean((y - xs @ b) ** 2)))
    return b / scale, cov_b / np.outer(scale, scale), ratio, rms


def flicker_covariance(t0, t1, f_min, f_max, n_freq=4000):
    """Covariance of the means over windows [t0_k, t1_k] (s) of a flicker process of unit
    instability (one-sided PSD 1 / (pi f), `sensors.noise`) between f_min and f_max (Hz):
    C_jk = int S(f) cos(2 pi f (c_j - c_k)) sinc(f T_j) sinc(f T_k) df, c the window
    centres, T the lengths (numerical, log-spaced frequencies). Read-only; up to
    KEPT_WINDOWS windows kept for the process's later calls with the same windows (every
    unit of a campaign has its lab's)."""
    t0, t1 = np.asarray(t0, dtype=float), np.asarray(t1, dtype=float)
    key = (t0.tobytes(), t1.tobytes(), float(f_min), float(f_max), int(n_freq))
    cov = _FLICKER_COVARIANCES.get(key)
    if cov is None:
        cov = _flicker_covariance(t0, t1, f_min, f_max, n_freq)
        cov.flags.writeable = False
        if len(t0) <= KEPT_WINDOWS:
            if len(_FLICKER_COVARIANCES) >= 32:
                _FLICKER_COVARIANCES.pop(next(iter(_FLICKER_COVARIANCES)))
            _FLICKER_COVARIANCES[key] = cov
    return cov


KEPT_WINDOWS = 512                # a lab run's (the rate table has 252): at most 2 MiB each
_FLICKER_COVARIANCES = {}         # (windows, band, grid) -> covariance, oldest first


def _flicker_covariance(t0, t1, f_min, f_max, n_freq):
    f = np.geomspace(f_min, f_max, n_freq)
    weight = np.gradient(np.log(f)) * f / (math.pi * f)          # S(f) df on a log grid
    c, length = 0.5 * (t0 + t1), t1 - t0
    h = np.sinc(np.outer(length, f))
    phase = 2 * math.pi * np.outer(c, f)
    re, im = h * np.cos(phase), h * np.sin(phase)
    return (re * weight) @ re.T + (im * weight) @ im.T


@dataclass
class Fitted:
    """Coefficients with their error as a linear map from independent unit sources:
    error = E @ z, z ~ N(0, I); sources named so later stages can extend E."""
    values: dict                                    # name -> float
    errors: dict = field(default_factory=dict)      # name -> {source: sensitivity}
    stage: str = ""
    rms: dict = field(default_factory=dict)         # residual rms per output axis

    def covariance(self, names):
        sources = sorted({s for n in names for s in self.errors.get(n, {})})
        e = np.array([[self.errors.get(n, {}).get(s, 0.0) for s in sources] for n in names])
        return e @ e.T if sources else np.zeros((len(names), len(names)))


def _merge(into, name, sens):
    row = into.setdefault(name, {})
    for s, v in sens.items():
        row[s] = row.get(s, 0.0) + v


def _add_cov_sources(fitted, names, cov, tag):
    """Own GLS covariance of `names` as sources tag:0.. (its Cholesky columns)."""
    vals, vecs = np.linalg.eigh(cov)
    cols = vecs * np.sqrt(np.clip(vals, 0, None))
    for i, name in enumerate(names):
        _merge(fitted.errors, name, {f"{tag}:{j}": cols[i, j] for j in range(len(names))})


def _propagate(fitted, names, refit, base, upstream, parents):
    """Add to `names` the effect of the errors of `parents` (names in `upstream`): for every
    source of the parents, refit with the parents moved by that source's sensitivity."""
    sources = sorted({s for n in parents for s in upstream.errors.get(n, {})})
    for s in sources:
        delta = {n: upstream.errors.get(n, {}).get(s, 0.0) for n in parents}
        if not any(delta.values()):
            continue
        new = refit(delta)
        for i, name in enumerate(names):
            _merge(fitted.errors, name, {s: new[i] - base[i]})


# ---- stage 1: temperature (eqs. 2, 4) ----------------------------------------------------
def fit_temperature(run):
    """Chamber: per axis U = c0 + c1 x + c2 x^2 on window means (x = T, or f), gauge fixed
    at the reference reading. Returns (Fitted, reference dict)."""
    temps = sorted({round(w.chamber_c, 3) for w in run.windows})
    if len(temps) < 4 or temps[-1] - temps[0] < 30:
        raise FitError(f"{run.path}: the chamber run has steady set points at {temps} degC; "
                       "eqs. 2/4 need at least 4 set points spanning 30 degC or more")
    room = min(range(len(run.windows)), key=lambda k: abs(run.windows[k].chamber_c - T_REF))
    fitted = Fitted({})
    reference = {"accel_temperature_c": [T_REF] * 3, "gyro_frequency_hz": []}
    for sensor, volts, reading in (("accel", "accel_volts", "accel_temperature"),
                                   ("gyro", "gyro_volts", "gyro_frequency")):
        u, x = run.raw[volts], run.raw[reading]
        u_mean, u_var = run.means(u), run.mean_variances(u)
        for i in range(3):
            x_ref = T_REF if sensor == "accel" else float(run.means(x[:, i])[room])
            span = 10.0 if sensor == "accel" else 1.0      # scaled reading for conditioning
            s = (x[:, i] - x_ref) / span
            design = np.column_stack([np.ones(len(run.windows)), run.means(s), run.means(s * s)])
            instability = run.instability(sensor) / NOMINAL_SCALE[sensor]        # V
            b, cov, _, _ = gls(design, u_mean[:, i], np.diag(u_var[:, i])
                               + instability**2 * run.flicker())
            # gauge: b0 = 0 (the polynomial vanishes at x_ref); back to raw-reading powers
            jac = np.array([[0.0, -x_ref / span, x_ref**2 / span**2],
                            [0.0, 1 / span, -2 * x_ref / span**2],
                            [0.0, 0.0, 1 / span**2]])
            c = jac @ b
            key = "ct" if sensor == "accel" else "cw"
            names = [f"{key}[{i}][{j}]" for j in range(3)]
            for j in range(3):
                fitted.values[names[j]] = float(c[j])
            _add_cov_sources(fitted, names, jac @ cov @ jac.T, f"chamber-{key}{i}")
            if sensor == "gyro":
                reference["gyro_frequency_hz"].append(x_ref)
    return fitted, reference


def _poly_matrix(fitted, key):
    return np.array([[fitted.values.get(f"{key}[{i}][{j}]", 0.0) for j in range(3)]
                     for i in range(3)])


# ---- stage 2/3: triads (eqs. 5-7) ----------------------------------------------------------
def _block_names(sensor, order, i):
    p = "A" if sensor == "accel" else "W"
    names = [f"{p}0[{i}]"] + [f"{p}1[{i}][{j}]" for j in range(3)]
    return names + ([f"{p}2[{i}]", f"{p}3[{i}]"] if order == 3 else [])


def _require_positions(run, n):
    """Refuse a run that lacks any of its procedure's n fixture positions."""
    have = {w.position for w in run.windows}
    missing = [p for p in range(n) if p not in have]
    if missing:
        names = [POSITION_NAMES[p % 6] + (" turned 180 deg" if p >= 6 else "") for p in missing]
        raise FitError(f"{run.path}: the {run.procedure} run has no steady data in fixture "
                       f"position(s) {', '.join(names)}; each sensor axis must be measured "
                       "pointing both ways along the input axis")


def _pairs(run):
    """Window index pairs (axis up at +W, axis down at -W) for the rate table; refuses a run
    whose positions or rates do not pair."""
    _require_positions(run, 6)
    by = {}
    for k, w in enumerate(run.windows):
        by.setdefault(w.position, []).append(k)
    pairs = []
    for p in range(0, 6, 2):
        up, down = by[p], list(by[p + 1])
        for k in up:
            target = -run.windows[k].rate
            match = [m for m in down if abs(run.windows[m].rate - target) < 1e-9]
            if not match:
                raise FitError(f"{run.path}: rate {math.degrees(run.windows[k].rate):.1f} "
                               f"deg/s in position {p} has no reverse-rate partner in "
                               f"position {p + 1}")
            down.remove(match[0])
            pairs.append((k, match[0]))
    return pairs


def _fit_triad_blocks(run, design, y_rows, rows, sensor):
    """GLS of every output axis on the design's regressors; returns (values (3, p), covs,
    rms residuals). Row covariance: white variance of each window's mean model output
    (from a first OLS pass) plus the datasheet bias instability as flicker; an order-1 fit's
    covariance also carries the nonlinearity it leaves out (`WindowDesign.omitted`)."""
    out, covs, rms = [], [], []
    for i in range(3):
        x = design.regressors(i, rows)
        b, *_ = np.linalg.lstsq(x, y_rows[:, i], rcond=None)
        cov = run.row_covariance(design.variances(i, b), run.instability(sensor), rows)
        b, cov, _, r = gls(x, y_rows[:, i], cov, design.omitted(i, rows, sensor))
        out.append(b), covs.append(cov), rms.append(r)
    return np.array(out), covs, rms


def _voltage_design(run, sensor, poly, order):
    """Design of the temperature-compensated voltages (eqs. 2, 4) with polynomial `poly`."""
    if sensor == "accel":
        v = run.raw["accel_volts"] - poly2(poly, run.raw["accel_temperature"])
    else:
        v = run.raw["gyro_volts"] - poly2(poly, run.raw["gyro_frequency"])
    return run.design(v, order)


def _check_levels(values, need, what, path):
    """Refuse inputs with fewer than `need` levels apart by 1 % of the largest input."""
    step = 0.01 * np.abs(values).max()
    levels = np.unique(np.round(values / step)) * step if step > 0 else np.zeros(1)
    if len(levels) < need:
        raise FitError(f"{path}: {what} takes only {len(levels)} distinct input levels "
                       f"({', '.join(f'{x:.4g}' for x in levels)}); the fit needs at least "
                       f"{need} to separate its polynomial terms")


def fit_gyro_triad(run, temp, order=3, propagate=True):
    """Rate table (paired positions) -> W0, W1 (, W2, W3), errors propagated from `temp`
    (the chamber fit, or None for no temperature model) and the lab settings."""
    pairs = _pairs(run)
    cw = _poly_matrix(temp, "cw") if temp else np.zeros((3, 3))
    design = _voltage_design(run, "gyro", cw, order)

    def solve(cw_=None, **perturb):
        d = design if cw_ is None else _voltage_design(run, "gyro", cw_, order)
        _, w_in = known_inputs(run, **perturb)
        y = np.array([w_in[list(r)].mean(axis=0) for r in pairs])
        return _fit_triad_blocks(run, d, y, pairs, "gyro")
    _, w_in = known_inputs(run)
    y = np.array([w_in[list(r)].mean(axis=0) for r in pairs])
    for i in range(3):
        _check_levels(y[:, i], order + 1 if order == 3 else 2,
                      f"gyro {AXES[i]} (paired rate points, rad/s)", run.path)
    coef, covs, rms = solve()
    return _assemble(run, "gyro", order, coef, covs, rms, solve, cw, temp, "cw",
                     tag=run.procedure, propagate=propagate)


def fit_accel_triad(run, temp, order=3, propagate=True):
    """Centrifuge (or static positions) -> A0, A1 (, A2, A3)."""
    ct = _poly_matrix(temp, "ct") if temp else np.zeros((3, 3))
    rows = [(k,) for k in range(len(run.windows))]
    _require_positions(run, 12 if run.procedure == "twelve-position" else 6)
    f_in, _ = known_inputs(run)
    for i in range(3):
        _check_levels(f_in[:, i], order + 1, f"accelerometer {AXES[i]} (m/s^2)", run.path)

    design = _voltage_design(run, "accel", ct, order)

    def solve(ct_=None, **perturb):
        d = design if ct_ is None else _voltage_design(run, "accel", ct_, order)
        f, _ = known_inputs(run, **perturb)
        return _fit_triad_blocks(run, d, f, rows, "accel")
    coef, covs, rms = solve()
    return _assemble(run, "accel", order, coef, covs, rms, solve, ct, temp, "ct",
                     tag=run.procedure, propagate=propagate)


def _assemble(run, sensor, order, coef, covs, rms, solve, poly, temp, key, tag, propagate):
    """Fitted values with their error sources; `propagate=False` keeps only each stage's
    own GLS covariance and the turn-on term (fast, for campaigns that need no covariance)."""
    fitted = Fitted({})
    names = []
    for i in range(3):
        block = _block_names(sensor, order, i)
        names += block
        for n, val in zip(block, coef[i]):
            fitted.values[n] = float(val)
        _add_cov_sources(fitted, block, covs[i], f"{tag}-{sensor}{i}")
    base = np.concatenate(list(coef))
    for label, perturb in setting_perturbations(run) if propagate else []:
        new = np.concatenate(list(solve(**perturb)[0]))
        for n, d in zip(names, new - base):
            _merge(fitted.errors, n, {f"{tag}-setting-{label}": d})
    # the turn-on bias of this power-on sits in the bias terms
    p0 = "A0" if sensor == "accel" else "W0"
    for i in range(3):
        _merge(fitted.errors, f"{p0}[{i}]", {f"{tag}-turn-on-{sensor}{i}": run.turn_on(sensor)})
    if temp and propagate:
        parents = [f"{key}[{i}][{j}]" for i in range(3) for j in range(3)]

        def refit(delta):
            moved = poly + np.array([[delta[f"{key}[{i}][{j}]"] for j in range(3)]
                                     for i in range(3)])
            return np.concatenate(list(solve(moved)[0]))
        _propagate(fitted, names, refit, base, temp, parents)
    fitted.rms = dict(zip(AXES, rms))
    fitted.stage = f"{tag} {sensor}"
    return fitted


# ---- stage 3b: g-sensitivity (eqs. 8-10) ---------------------------------------------------
def fit_g_sensitivity(run, temp, gyro, propagate=True):
    """Centrifuge: R = w_known - w_model(V_w) (eq. 10) regressed on the applied specific force,
    R_i = C_i . f + b_i (b_i the turn-on nuisance). Errors from `temp`, `gyro`, settings."""
    cw = _poly_matrix(temp, "cw")
    f_in, w_in = known_inputs(run)

    design = _voltage_design(run, "gyro", cw, 3)
    rows = [(k,) for k in range(len(run.windows))]

    def solve(cw_, g_vals, **perturb):
        f, w = known_inputs(run, **perturb) if perturb else (f_in, w_in)
        d = design if cw_ is None else _voltage_design(run, "gyro", cw_, 3)
        x = np.column_stack([f, np.ones(len(f))])
        res = []
        for i in range(3):
            b = np.array([g_vals[n] for n in _block_names("gyro", 3, i)])
            w_model = d.regressors(i, rows) @ b
            cov = run.row_covariance(d.variances(i, b), run.instability("gyro"), rows)
            res.append(gls(x, w[:, i] - w_model, cov))
        return np.array([r[0][:3] for r in res]), [r[1][:3, :3] for r in res], \
            [r[3] for r in res]
    c, covs, rms = solve(None, gyro.values)
    fitted = Fitted({})
    names = [f"C[{i}][{j}]" for i in range(3) for j in range(3)]
    for i in range(3):
        block = names[3 * i:3 * i + 3]
        for n, val in zip(block, c[i]):
            fitted.values[n] = float(val)
        _add_cov_sources(fitted, block, covs[i], f"centrifuge-C{i}")
    base = c.ravel()
    if not propagate:
        fitted.rms, fitted.stage = dict(zip(AXES, rms)), "centrifuge C"
        return fitted
    for label, perturb in setting_perturbations(run):
        new = solve(None, gyro.values, **perturb)[0].ravel()
        for n, d in zip(names, new - base):
            _merge(fitted.errors, n, {f"centrifuge-setting-{label}": d})
    # upstream: every source of cw and of W moves C; refit with both moved
    parents = [f"cw[{i}][{j}]" for i in range(3) for j in range(3)]
    w_names = list(gyro.values)
    upstream = Fitted({**temp.values, **gyro.values}, {**temp.errors})
    for n in w_names:
        upstream.errors[n] = gyro.errors.get(n, {})

    def refit(delta):
        dcw = np.array([[delta.get(f"cw[{i}][{j}]", 0.0) for j in range(3)] for i in range(3)])
        g_vals = {n: gyro.values[n] + delta.get(n, 0.0) for n in w_names}
        # a source of W alone leaves the compensated voltages, so their design, as they are
        return solve(cw + dcw if dcw.any() else None, g_vals)[0].ravel()
    _propagate(fitted, names, refit, base, upstream, parents + w_names)
    fitted.rms = dict(zip(AXES, rms))
    fitted.stage = "centrifuge C"
    return fitted


# ---- methods -------------------------------------------------------------------------------
def _runs_by_procedure(runs, need, method):
    by = {r.procedure: r for r in runs}
    missing = [p for p in need if p not in by]
    if missing:
        have = ", ".join(sorted(by)) or "none"
        raise FitError(f"method {method!r} needs lab runs {', '.join(need)}; missing "
                       f"{', '.join(missing)} (given: {have})")
    return by


def calibrate(runs, method, unit="", propagate=True, noise=None):
    """Fit `method` to lab runs (log paths or `LabRun`s); returns a `Calibration` with
    covariance (`propagate=False`: each stage's own only, for speed). `noise`: the unit's
    measured random errors, {"source": str, "instability": {"accel": m/s^2, "gyro": rad/s}}
    (e.g. `reports.noise.load` of a `mimunav noise` file; a sensor left out keeps the unit
    class's), used instead of the unit class's assumed bias instability."""
    if method not in METHODS:
        raise FitError(f"unknown method {method!r}; one of {', '.join(METHODS)}")
    if method == "rotation":            # seed S4 eqs. 4-5: its own model and file
        from .rotation_calibration import fit
        return fit(runs, unit=unit, noise=noise)
    runs = [r if isinstance(r, LabRun) else LabRun.load(r) for r in runs]
    for r in runs if noise else []:
        r.noise = dict(r.noise, instability={**r.noise["instability"], **noise["instability"]},
                       source=noise["source"])
    if method == "entire":
        by = _runs_by_procedure(runs, ("thermal-chamber", "rate-table", "centrifuge"), method)
        temp, reference = fit_temperature(by["thermal-chamber"])
        gyro = fit_gyro_triad(by["rate-table"], temp, propagate=propagate)
        accel = fit_accel_triad(by["centrifuge"], temp, propagate=propagate)
        g_sens = fit_g_sensitivity(by["centrifuge"], temp, gyro, propagate=propagate)
        parts = (temp, gyro, accel, g_sens)
        cal = Calibration(model="entire-63", unit=unit,
                          procedure="thermal-chamber+rate-table+centrifuge")
        cal.extra["reference"] = reference
    elif method == "traditional":
        by = _runs_by_procedure(runs, ("multi-position", "single-axis-rate"), method)
        accel = fit_accel_triad(by["multi-position"], None, order=1, propagate=propagate)
        gyro = fit_gyro_triad(by["single-axis-rate"], None, order=1, propagate=propagate)
        parts = (accel, gyro)
        cal = Calibration(model="linear", unit=unit, procedure="multi-position+single-axis-rate")
    elif method == "ellipsoid":
        by = _runs_by_procedure(runs, ("hand-held",), method)
        accel = fit_ellipsoid(by["hand-held"])
        gyro = fit_gyro_bias_unknown_attitude(by["hand-held"], accel)
        parts = (accel, gyro)
        cal = Calibration(model="linear", unit=unit,
                          procedure="hand-held orientations, ellipsoid fit (seed S4)")
        cal.extra["frame"] = ("the accelerometers' own (z along sensor z, x in the sensor x-z "
                              "plane); the gyro frame may differ by the triad's misalignment "
                              "(up to about 1-2 deg), which magnitudes cannot show")
    elif method == "twelve-position":
        by = _runs_by_procedure(runs, ("twelve-position",), method)
        accel = fit_accel_triad(by["twelve-position"], None, order=1)
        gyro = fit_gyro_bias(by["twelve-position"])
        parts = (accel, gyro)
        cal = Calibration(model="linear", unit=unit, procedure="twelve-position (seed S2)")
    else:
        by = _runs_by_procedure(runs, ("cold-start",), method)
        return fit_cold_start(by["cold-start"], unit=unit)
    merged = Fitted({})
    for part in parts:
        merged.values.update(part.values)
        merged.errors.update(part.errors)
    _fill(cal, merged.values)
    names = list(merged.values)
    cov = merged.covariance(names)
    se = np.sqrt(np.diag(cov))
    cal.covariance = {"names": names, "standard_error": se.tolist(), "matrix": cov.tolist(),
                      "residual_rms": {p.stage: p.rms for p in parts if p.rms},
                      "note": "GLS + setting errors + turn-on repeatability + upstream "
                              "coefficients, first-order propagation (mimunav.calibration)",
                      "noise_model": runs[0].noise}
    return cal


def _fill(cal, values):
    import re
    for name, val in values.items():
        key, *idx = re.findall(r"\w+", name)
        arr = getattr(cal, key)
        arr[tuple(int(i) for i in idx)] = val


def standard_errors(cal):
    """{name: standard error} from a fitted file's covariance block."""
    cov = cal.covariance
    return dict(zip(cov.get("names", []), cov.get("standard_error", [])))


def fit_gyro_bias(run):
    """Seed S2: gyro bias = -W1_nominal @ mean V over all positions (each axis up and
    down, each turned 180 deg: Earth rate and the g term average out)."""
    if len(run.windows) < 12:
        raise FitError(f"{run.path}: the twelve-position run has {len(run.windows)} steady "
                       "positions; gyro biases need all twelve")
    v = run.means(run.raw["gyro_volts"]).mean(axis=0)
    var = run.mean_variances(run.raw["gyro_volts"]).sum(axis=0) / len(run.windows) ** 2
    fitted = Fitted({})
    for i in range(3):
        fitted.values[f"W0[{i}]"] = float(-NOMINAL_SCALE["gyro"] * v[i])
        for j in range(3):
            fitted.values[f"W1[{i}][{j}]"] = NOMINAL_SCALE["gyro"] * (i == j)
        fitted.errors[f"W0[{i}]"] = {
            f"twelve-gyro{i}": NOMINAL_SCALE["gyro"] * math.sqrt(var[i]),
            f"turn-on-gyro{i}": run.turn_on("gyro")}
    _nominal_gyro_scale_errors(fitted, v)
    return fitted


def _nominal_gyro_scale_errors(fitted, v):
    """The datasheet gyro scale N is nominal: the unit's own is N (1 + e), e ~ the class's
    tolerance (1 sigma, sensors.mimu). Per unit e the fitted W1[i][i] is off by -N and a bias
    W0 = ... - N v (v: the mean voltage) by +N v[i]: one source per axis, in both."""
    k = NOMINAL_SCALE_TOLERANCE * NOMINAL_SCALE["gyro"]
    for i in range(3):
        _merge(fitted.errors, f"W0[{i}]", {f"nominal-scale-gyro{i}": k * float(v[i])})
        _merge(fitted.errors, f"W1[{i}][{i}]", {f"nominal-scale-gyro{i}": -k})


def fit_ellipsoid(run, windows=None):
    """Accelerometer triad from static windows at unknown orientations: per window k the
    mean voltage u_k and |A0 + A1 u_k| = g (site gravity). A1 upper triangular (its rotation
    is not observable from magnitudes: the calibrated frame has z along the sensor z axis,
    x in the sensor x-z plane), A0 (3): 9 unknowns, so >= 9 windows, well spread. Whitened
    nonlinear least squares (scipy), each window's magnitude weighted by its mean's white
    noise plus the unit's bias instability; the covariance is scaled by the Birge ratio
    chi^2/dof when above 1 and carries the turn-on repeatability in A0.
    `windows`: indices of the run's windows to use (default all).
    The calibrated frame is the accelerometers' own (z along sensor z, x in the sensor x-z
    plane); it differs from the gyros' frame by the triad's misalignment (0.1-2 % couplings:
    up to about 1-2 deg), which no magnitude can show - the A1 errors hold within this
    gauge. Use a turntable method where the gyro and accelerometer frames must agree."""
    ws = run.windows if windows is None else [run.windows[k] for k in windows]
    if len(ws) < 9:
        raise FitError(f"{run.path}: {len(ws)} static orientations; the ellipsoid fit has 9 "
                       "unknowns and needs at least 9 (more, well spread, for accuracy)")
    k0, k1 = np.array([w.k0 for w in ws]), np.array([w.k1 for w in ws])
    u = slice_means(run.raw["accel_volts"], k0, k1)
    var = np.array([np.diff(run.raw["accel_volts"][a:b], n=2, axis=0).var(axis=0) / 6.0 / (b - a)
                    for a, b in zip(k0, k1)])
    g = run.site["gravity_m_s2"]
    sigma = np.sqrt(NOMINAL_SCALE["accel"] ** 2 * var.mean(axis=1) + run.instability("accel") ** 2)
    upper = np.triu_indices(3)

    def unpack(p):
        a1 = np.zeros((3, 3))
        a1[upper] = p[3:]
        return p[:3], a1

    def resid(p):
        a0, a1 = unpack(p)
        return (np.linalg.norm(a0 + u @ a1.T, axis=1) - g) / sigma
    p0 = np.concatenate([np.zeros(3), np.diag([NOMINAL_SCALE["accel"]] * 3)[upper]])
    sol = scipy.optimize.least_squares(resid, p0, method="lm", x_scale="jac")
    chi2 = float(sol.fun @ sol.fun)
    dof = len(ws) - 9
    birge = max(chi2 / dof, 1.0) if dof > 0 else 1.0
    cov = birge * np.linalg.pinv(sol.jac.T @ sol.jac)
    if dof <= 0 or not np.all(np.isfinite(cov)) or np.linalg.cond(sol.jac) > 1e12:
        raise FitError(f"{run.path}: the orientations do not determine the ellipsoid (too few "
                       "or too alike); hold the unit in more, well-spread attitudes")
    a0, a1 = unpack(sol.x)
    names = [f"A0[{i}]" for i in range(3)] + [f"A1[{i}][{j}]" for i, j in zip(*upper)]
    fitted = Fitted({n: float(v) for n, v in zip(names, sol.x)}, stage="hand-held accel",
                    rms={"magnitude": float(np.sqrt(np.mean((sol.fun * sigma) ** 2))),
                         "birge_ratio": birge})
    for i, j in zip(*np.tril_indices(3, -1)):
        fitted.values[f"A1[{i}][{j}]"] = 0.0
    _add_cov_sources(fitted, names, cov, "ellipsoid")
    for i in range(3):
        _merge(fitted.errors, f"A0[{i}]", {f"ellipsoid-turn-on-accel{i}": run.turn_on("accel")})
    return fitted


def fit_gyro_bias_unknown_attitude(run, accel, windows=None):
    """Gyro biases from static windows at unknown orientations, the datasheet scale (like
    seed S2): per window, the Earth rate's vertical part (Omega sin(lat) along the up
    direction the fitted accelerometers give) minus the nominally scaled output; the horizontal
    part (Omega cos(lat), heading unknown) averages out over varied headings and stays in
    the scatter, whose standard error of the mean is the reported error with the nominal
    scale's tolerance and the turn-on repeatability."""
    ws = run.windows if windows is None else [run.windows[k] for k in windows]
    k0, k1 = np.array([w.k0 for w in ws]), np.array([w.k1 for w in ws])
    a0 = np.array([accel.values[f"A0[{i}]"] for i in range(3)])
    a1 = np.array([[accel.values[f"A1[{i}][{j}]"] for j in range(3)] for i in range(3)])
    f = slice_means(run.raw["accel_volts"], k0, k1) @ a1.T + a0
    up = f / np.linalg.norm(f, axis=1)[:, None]
    omega_up = run.site["earth_rate_rad_s"] * math.sin(run.site["latitude"])
    # w = W0 + N v must read the Earth rate at rest: W0 = Omega_up up - N v, per window
    v = slice_means(run.raw["gyro_volts"], k0, k1)
    w0 = omega_up * up - NOMINAL_SCALE["gyro"] * v
    mean = w0.mean(axis=0)
    sem = w0.std(axis=0, ddof=1) / math.sqrt(len(ws))
    fitted = Fitted({}, stage="hand-held gyro")
    for i in range(3):
        fitted.values[f"W0[{i}]"] = float(mean[i])
        for j in range(3):
            fitted.values[f"W1[{i}][{j}]"] = NOMINAL_SCALE["gyro"] * (i == j)
        fitted.errors[f"W0[{i}]"] = {
            f"hand-held-gyro{i}": float(sem[i]), f"turn-on-gyro{i}": run.turn_on("gyro")}
    _nominal_gyro_scale_errors(fitted, v.mean(axis=0))
    return fitted


COLD_START_WINDOWS_S = (60.0, 120.0, 180.0, 300.0)     # n = 1, 2, 3, 5 min (seed S3)
COLD_START_BIN_S = 60.0


def fit_cold_start(run, unit=""):
    """Seed S3 on a cold-start run (one power-on per axis up): per axis
        E = E(T) / (a + b T) + (c + d T) + e dT_n
    with E(T) the nominally scaled raw output (datasheet 0.1 V/g, 5 mV/(deg/s); A1, W1
    diagonal, no bias), T the accelerometer thermistor (degC) or the gyro resonance (Hz),
    E the known input (gravity and Earth rate of each position). Gyros keep a = 1, b = 0:
    Earth rate is too small to separate their scale from their bias.
    Data: 60 s bin means; GLS with flicker + per-power-on turn-on covariance (white noise
    of a 60 s mean is below 5 % of the flicker there),
    solved by scipy.optimize.least_squares on the whitened residuals. The window n is
    chosen among the basic model (no e) and n = 1, 2, 3, 5 min by BIC; every candidate's
    chi2, BIC and e are written to the file ("selection")."""
    if len(run.windows) < 3:
        raise FitError(f"{run.path}: the cold-start run has {len(run.windows)} power-ons; "
                       "seed S3 needs x, y and z up")
    f_in, w_in = known_inputs(run)
    edges = []                                  # bins: (k0, k1, power-on index)
    for j, w in enumerate(run.windows):
        step = max(2, int(round(COLD_START_BIN_S / np.median(np.diff(run.t)))))
        edges += [(k, min(k + step, w.k1), j) for k in range(w.k0, w.k1 - 1, step)]
    k0 = np.array([e[0] for e in edges])
    k1 = np.array([e[1] for e in edges])
    power_on = np.array([e[2] for e in edges])
    t0, t1 = run.t[k0 - 1], run.t[k1 - 1]
    same = (power_on[:, None] == power_on[None, :]).astype(float)

    def bins(x):
        return slice_means(x, k0, k1)
    flick = flicker_covariance(t0, t1, 1.0 / (FLICKER_SPAN * (run.t[-1] - run.t[0])),
                               0.5 / np.median(np.diff(run.t)))
    cal = Calibration(model="cold-start", unit=unit, procedure="cold-start (seed S3)",
                      A1=np.diag([NOMINAL_SCALE["accel"]] * 3),
                      W1=np.diag([NOMINAL_SCALE["gyro"]] * 3))
    selection, fits = {}, {}
    for sensor, volts, reading, truth_in in (("accel", "accel_volts", "accel_temperature", f_in),
                                             ("gyro", "gyro_volts", "gyro_frequency", w_in)):
        e_t = run.raw[volts] * NOMINAL_SCALE[sensor]
        temp = run.raw[reading]
        cov_base = (run.instability(sensor) ** 2 * flick + run.turn_on(sensor) ** 2 * same)
        covs = [cov_base + _cold_start_omitted(sensor, i, f_in[power_on]) for i in range(3)]
        for n in (None,) + COLD_START_WINDOWS_S:
            d_t = bins(_power_on_temperature_change(run, temp, n or 60.0))
            fit = [_fit_cold_axis(bins(e_t[:, i]), bins(temp[:, i]), d_t[:, i],
                                  truth_in[power_on, i], covs[i], sensor == "accel",
                                  n is not None) for i in range(3)]
            fits[sensor, n] = fit
            label = "basic" if n is None else f"{n:g}"
            selection.setdefault(sensor, {})[label] = {
                "chi2": [f["chi2"] for f in fit], "bic": float(sum(f["bic"] for f in fit)),
                "e": [f["values"][4] for f in fit], "e_se": [f["se"][4] for f in fit]}
    # one window for the file: the best total BIC over both triads
    best = min((None,) + COLD_START_WINDOWS_S, key=lambda n: sum(
        selection[s]["basic" if n is None else f"{n:g}"]["bic"] for s in ("accel", "gyro")))
    for sensor in ("accel", "gyro"):
        fit = fits[sensor, best]
        cal.cold_start[sensor] = {k: np.array([f["values"][j] for f in fit])
                                  for j, k in enumerate("abcde")}
        cal.covariance[sensor] = {k: [f["se"][j] for f in fit] for j, k in enumerate("abcde")}
        cal.covariance[sensor]["matrix"] = [f["cov"] for f in fit]      # per axis, a..e
    cal.cold_start["window_s"] = best or 60.0
    cal.extra["selection"] = {"chosen": "basic" if best is None else f"{best:g} s",
                              "criterion": "BIC (GLS chi2 + k ln N)", "candidates": selection}
    return cal


def _cold_start_omitted(sensor, i, f_bins):
    """Covariance (bins x bins) of what seed S3's per-axis model leaves out of axis i, each
    power-on's gravity f_bins (m/s^2, sensor axes, per bin) through terms of seed S1 Table 2's
    class as random effects: the accelerometer's cross-coupling to the other axes, the gyro's
    acceleration effect C on all three (a per-power-on offset the turn-on term alone
    understated: zero-g offsets came out at z up to 24, zero-rate at 12)."""
    if sensor == "accel":
        shapes = CLASS_CROSS_COUPLING["accel"] * np.delete(f_bins, i, axis=1)
    else:
        shapes = CLASS_G_SENSITIVITY * f_bins
    return shapes @ shapes.T


def _power_on_temperature_change(run, temp, window):
    """dT = T(t) - T(t - window) within each power-on (effects.temperature_change)."""
    out = np.zeros_like(temp)
    for w in run.windows:
        first = w.k0 - 1
        out[first:w.k1] = temperature_change(temp[first:w.k1], window, run.t[first:w.k1])
    return out


def _fit_cold_axis(e_t, temp, d_t, known, cov, scale_free, with_rate):
    """One axis of the S3 model by whitened nonlinear least squares."""
    chol = np.linalg.cholesky(cov + np.eye(len(cov)) * 1e-12 * np.trace(cov) / len(cov))
    t_c = temp - temp.mean()                           # centred for conditioning

    def model(p):
        a, b, c, d, e = p
        return e_t / (a + b * t_c) + c + d * t_c + e * d_t
    free = np.array([scale_free, scale_free, True, True, with_rate])
    p0 = np.array([1.0, 0.0, 0.0, 0.0, 0.0])

    def resid(q):
        p = p0.copy()
        p[free] = q
        return scipy.linalg.solve_triangular(chol, model(p) - known, lower=True)
    sol = scipy.optimize.least_squares(resid, p0[free], method="lm", x_scale="jac")
    p = p0.copy()
    p[free] = sol.x
    jac = sol.jac
    chi2 = float(sol.fun @ sol.fun)
    # a model that misses part of the data (chi^2/dof > 1) has wider errors than its GLS
    # covariance says: scale by the Birge ratio chi^2/dof (never shrink)
    birge = max(chi2 / max(len(known) - int(free.sum()), 1), 1.0)
    cov_q = birge * np.linalg.inv(jac.T @ jac)
    cov_p = np.zeros((5, 5))                        # all five parameters, 0 for fixed ones
    cov_p[np.ix_(free, free)] = cov_q
    # back from centred temperature: a + b (T - Tm) = (a - b Tm) + b T, likewise c + d T
    tm = temp.mean()
    jac_abs = np.eye(5)
    jac_abs[0, 1] = jac_abs[2, 3] = -tm
    values = jac_abs @ p
    cov_abs = jac_abs @ cov_p @ jac_abs.T
    return {"values": values.tolist(), "se": np.sqrt(np.diag(cov_abs)).tolist(),
            "cov": cov_abs.tolist(), "chi2": chi2, "birge": birge,
            "bic": chi2 + int(free.sum()) * math.log(len(known))}


def check(cal, run):
    """Held-out check of a calibration on a lab run it was not fitted on: per steady window,
    compensated mean output minus the known input. Returns a dict of (n_windows, 3) arrays:
    accel_error m/s^2, gyro_error rad/s, accel_input m/s^2, gyro_input rad/s,
    temperature degC (accelerometer thermistors)."""
    r = run.raw
    f, w, _ = compensate(cal, r["accel_volts"], r["gyro_volts"], r["accel_temperature"],
                         r["gyro_frequency"], t=run.t)
    f_in, w_in = known_inputs(run)
    return {"accel_error": run.means(f) - f_in, "gyro_error": run.means(w) - w_in,
            "accel_input": f_in, "gyro_input": w_in,
            "temperature": run.means(r["accel_temperature"])}

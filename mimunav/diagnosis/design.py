"""The sensor level's design: the residual of the recorded MIMU against the reference's
prediction (accel m/s^2, gyro rad/s, MIMU sensor axes), its bin means, the reference's inputs
and every candidate's columns on the same bins, the priors of the reference's and the
calibration's own linear errors (18 parameters: each triad's scale and misalignment), and a
term's contribution to each channel.
"""
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy import linalg

from ..compensation import effects
from ..lab.calibrate import standard_errors
from ..evaluation.replay import compensated_mimu
from ..compensation.effects import AXES, Conditions, derivative, vibration_power
from . import library, wander
from .reference import DERIVATIVE_WINDOW_S, predicted_mimu
from ..errors import InputError


FAST_BIN_S = 0.01
DETREND_KNOT_S = 10.0           # bias removed for display and the scan: piecewise linear
LINEAR_TOLERANCE = 1e-9         # a candidate is 'linear' when the reference inputs span it
CHANNELS = [("accel", a) for a in AXES] + [("gyro", a) for a in AXES]
DEG = math.pi / 180


@dataclass
class Design:
    """Bin means of the residual, the reference's inputs and every candidate's columns."""
    t: np.ndarray               # (nb,) bin centres, s
    residual: np.ndarray        # (nb, 6)
    inputs: np.ndarray          # (nb, 6): predicted f (m/s^2) then w (rad/s), MIMU axes
    columns: list               # per candidate: {channel: (nb, k)}
    k: list                     # per candidate: parameter count
    terms: list                 # the candidates
    kept: np.ndarray            # usable bins of the raw binning
    prior: np.ndarray           # (18, 18) reference error covariance (`Accuracy.prior`)
    along: list                 # per candidate: (18, k) map to gamma if linear, else None
    allowance: list = field(default_factory=list)   # per candidate: (k, k) the stated
                                # covariance of its coefficient that is no physics the model
                                # lacks: the calibration's (`model_allowance`) or the
                                # reference's through the lever-arm transfer (`transfer_allowance`)
    allowance_of: list = field(default_factory=list)    # per candidate: whose ("calibration",
                                # "reference", or None when it has none)
    levels: np.ndarray = field(default_factory=lambda: wander.LAMBDA_GRID)   # wander levels
                                # the fits may choose from
    wander_steps: np.ndarray | None = None  # (6,) each channel's largest wander step
                                # variance per bin, SI^2 (`diagnose`; None: no cap)
    bin_s: float = FAST_BIN_S   # the bins' length, s
    shape: np.ndarray | None = None     # (nb, 6) each bin's white variance over its channel's
                                # (`diagnose`'s noise_shape; None: constant)
    reference: object = None    # the reference's `sensors.accuracy.Accuracy` (`_reference_may_carry`)
    calibrated: bool = False    # the MIMU compensated by a calibration of the unit (not
                                # a recording's outputs taken as they are): `physical_limit`
    q_vs: np.ndarray = field(default_factory=lambda: np.array([1.0, 0, 0, 0]))   # MIMU
                                # sensor -> vehicle (w, x, y, z): a lever arm is reported in
                                # the vehicle frame of the metadata's lever_arm_m

    @property
    def channels(self):
        return 6

    def ref_columns(self, c):
        """(nb, 3) the reference input of channel c's triad."""
        return self.inputs[:, :3] if c < 3 else self.inputs[:, 3:]

    def ref_pinv(self, c):
        """(3, nb) the pseudo-inverse of `ref_columns(c)` (lstsq's cutoff: singular values
        below eps max(shape) of the largest), one per triad."""
        return self._ref_pinvs[int(c >= 3)]

    @cached_property
    def _ref_pinvs(self):
        return tuple(np.linalg.pinv(ref, rcond=np.finfo(float).eps * max(ref.shape))
                     for ref in (self.inputs[:, :3], self.inputs[:, 3:]))

    @cached_property
    def channel_columns(self):
        """Per channel c: ((nb, 4 + sum k) [residual, reference inputs, every candidate's
        columns on c], {candidate: its column indices}) - what every `Fitter` filters. Each
        candidate's `columns` become views of these (the same numbers, held once: a 2-hour
        flight's bins of 70 candidates are about a gigabyte)."""
        out = []
        for c in range(6):
            cols = [self.residual[:, c:c + 1], self.ref_columns(c)]
            slot, start = {}, 4
            for j in range(len(self.terms)):
                if c in self.columns[j]:
                    cols.append(self.columns[j][c])
                    slot[j] = np.arange(start, start + self.k[j])
                    start += self.k[j]
            out.append((np.hstack(cols), slot))
            for j, s in slot.items():
                self.columns[j][c] = out[-1][0][:, s[0]:s[-1] + 1]
        return out

    @cached_property
    def detrend_q(self):
        """(nb, knots) orthonormal basis of the piecewise-linear bias (hat functions with
        knots every DETREND_KNOT_S) that `detrended` removes: one per design, not per call. By
        Cholesky (Q = B L'^-1, B'B = L L'): the hats' Gram is tridiagonal and well
        conditioned, and Householder QR of the 68,000 x 70 basis of a 10-minute flight took
        0.35 s against 0.03 s; the projection Q Q' is the same."""
        knots = np.arange(self.t[0], self.t[-1] + DETREND_KNOT_S, DETREND_KNOT_S)
        basis = np.clip(1 - np.abs((self.t[:, None] - knots[None, :]) / DETREND_KNOT_S), 0,
                        None)
        basis = basis[:, basis.sum(axis=0) > 0.5]
        try:
            lower = np.linalg.cholesky(basis.T @ basis)
        except np.linalg.LinAlgError:       # hats that see the same few bins across a gap
            return np.linalg.qr(basis)[0]
        return linalg.solve_triangular(lower, basis.T, lower=True).T


def residual(flight, cal, vibration=None):
    """(t s, residual (N, 6) accel m/s^2 then gyro rad/s, usable (N,), Conditions).
    vibration: (N, 3) the MIMU's vibration power, (m/s^2)^2, when its outputs in `flight`
    were filtered (`diagnose`); else from them."""
    temperature, frequency = flight.mimu_temperatures()
    w, f, flags = compensated_mimu(flight, cal, per_sample=True)
    f_p, w_p, inside = predicted_mimu(flight)
    t = flight.mimu_t
    # vibration power from the MIMU's own specific force: the reference, often sampled more
    # slowly, averages part of an airframe vibration away (an interval mean attenuates a
    # tone by sinc(pi f dt): 17 % of the power of 117 Hz at 500 Hz)
    cond = Conditions(t, f_p, w_p, derivative(t, f_p, DERIVATIVE_WINDOW_S),
                      derivative(t, w_p, DERIVATIVE_WINDOW_S),
                      temperature, frequency,
                      vibration_power(t, np.nan_to_num(f)) if vibration is None else vibration)
    res = np.hstack([f - f_p, w - w_p])
    usable = inside & (flags == 0) & np.isfinite(res).all(axis=1)
    usable[0] = False                       # the sample at the first stamp has no interval
    return t, res, usable, cond, {"measured": np.hstack([f, w]),
                                  "predicted": np.hstack([f_p, w_p]), "flags": flags,
                                  "inside": inside, "compensated": (w, f)}


def bins(t, t_reference, bin_s=FAST_BIN_S):
    """(m, start): bins of m consecutive MIMU samples from sample `start` on, bin_s long
    or the shortest length above it that is a whole number of reference intervals, and,
    where the reference IMU's stamps are a subset of the MIMU's (its rate an integer
    fraction of the MIMU's), beginning and ending on reference stamps: the
    bin means of both IMUs then cover the same intervals exactly, so motion faster than the
    reference resolves (an airframe's vibration near its Nyquist rate) cancels in the
    residual instead of being interpolated. The phase is the first reference stamp the MIMU
    shares; a lost MIMU sample shifts the bins after it off the reference's stamps (the bins
    count samples)."""
    dt = float(np.median(np.diff(t)))
    m = max(1, round(bin_s / dt))
    if t_reference is None or len(t_reference) < 2:
        return m, 0
    ratio = float(np.median(np.diff(t_reference))) / dt
    p = round(ratio)
    if p < 1 or abs(ratio - p) > 1e-3:
        return m, 0
    m = max(p, math.ceil(bin_s / dt / p - 1e-9) * p)     # never shorter than bin_s
    i = np.clip(np.searchsorted(t, t_reference), 0, len(t) - 1)   # the MIMU stamp at or
    on = np.flatnonzero(np.abs(t[i] - t_reference) < 1e-3 * dt)  # after each reference one
    return (m, int((i[on[0]] + 1) % m)) if len(on) else (m, 0)


class Binning:
    """Means of bins = (m, start): m consecutive samples from sample `start` on; bins with
    any unusable sample (`usable` (N,) bool) are NaN. Which bins those are is found once,
    for every series binned alike."""

    def __init__(self, bins, usable):
        self.m, self.start = bins
        self.n = (len(usable) - self.start) // self.m * self.m
        self.bad = ~usable[self.start:self.start + self.n].reshape(-1, self.m).all(axis=1)

    def __call__(self, x):
        """(nb,) or (nb, k...) bin means of x (N,) or (N, k...)."""
        m, n = self.m, self.n
        x = x[self.start:self.start + n]
        shape = (n // m, m) + x.shape[1:]
        # the mean over axis 1, by einsum where samples have columns (5x faster; a single
        # column's means differ from numpy's by an ulp in about a third of the bins); times
        # keep numpy's pairwise mean
        out = (x.reshape(shape).mean(axis=1) if x.ndim == 1 else
               np.einsum("ij...->i...", x.reshape(shape)) / m)
        out[self.bad] = np.nan
        return out


def calibration_prior(cal):
    """(18, 18) covariance of the calibration's own linear error in the MIMU's axes, in the
    layout of `sensors.accuracy.Accuracy.prior`: from the standard errors of A1 and W1 in the file's
    `covariance` block (relative: E_ij = dA1_ij / A1_jj, the compensated output's error per
    unit input); zero when the file states none (e.g. a unit's true coefficients). A term
    within it is the lab fit's own uncertainty, not physics the model lacks (the terms the
    model carries beyond A1/W1: `model_allowance`)."""
    se = standard_errors(cal)
    var = np.zeros(18)
    for k, (key, matrix) in enumerate((("A1", cal.A1), ("W1", cal.W1))):
        for i in range(3):
            for j in range(3):
                s = se.get(f"{key}[{i}][{j}]")
                if s is not None and np.isfinite(s) and matrix[j, j] != 0:
                    var[9 * k + 3 * i + j] = (s / abs(matrix[j, j])) ** 2
    return np.diag(var)


def model_allowance(cal, term):
    """Variance (SI, of the term's coefficient) that the calibration's own stated covariance
    allows a non-linear term the model carries: g_sensitivity gyro i <- f_j is the error of
    C[i][j]; scale_nonlinearity order 2 / 3 of A2_i / A1_ii^2, A3_i / A1_ii^3 (W for gyros);
    temperature_bias per degC (per Hz for gyros) of A1_ii (ct1_i + 2 ct2_i T0) with the
    log's mean T0 (W1_ii and cw). 0 when the file states no covariance or the term has no
    counterpart in the model."""
    names = cal.covariance.get("names", [])
    if not names or "matrix" not in cal.covariance:
        return 0.0
    index = {n: k for k, n in enumerate(names)}
    cov = np.asarray(cal.covariance["matrix"], float)
    effect, sensor = term["effect"], term["sensor"]
    if sensor not in ("accel", "gyro") or term["axis"] not in AXES:
        return 0.0
    i = AXES.index(term["axis"])
    gain = abs((cal.A1 if sensor == "accel" else cal.W1)[i, i])
    if effect == "g_sensitivity":
        weights = {f"C[{i}][{AXES.index(term['input_axis'])}]": 1.0}
    elif effect == "scale_nonlinearity":
        key = {("accel", 2): "A2", ("accel", 3): "A3", ("gyro", 2): "W2", ("gyro", 3): "W3"}
        weights = {f"{key[sensor, term['order']]}[{i}]": 1.0 / gain ** term["order"]}
    elif effect == "temperature_bias":
        poly = "ct" if sensor == "accel" else "cw"
        weights = {f"{poly}[{i}][1]": gain, f"{poly}[{i}][2]": 2 * term["reference"] * gain}
    else:
        return 0.0
    if not all(n in index for n in weights):
        return 0.0
    k = [index[n] for n in weights]
    w = np.asarray(list(weights.values()))
    return float(w @ cov[np.ix_(k, k)] @ w)


# ---- the design --------------------------------------------------------------------------
def make_design(t, res, usable, cond, cands, m, prior, cal, transfer=None):
    """Bin the residual, the reference inputs and each candidate's regressor; drop candidates
    the flight cannot drive (no variation) and mark those the reference inputs span.
    `transfer`: (d (3,) m, P (9, 9)) the lever arm from the reference to the MIMU in the
    MIMU's axes and the covariance of the reference's gyro error matrix there
    (`transfer_allowance`), or None."""
    if len(t) < m[0] + m[1]:
        raise InputError(f"{len(t)} MIMU samples: fewer than one {FAST_BIN_S:g} s bin")
    mean = Binning(m, usable)
    tb, rb = mean(t), mean(res)
    ok = np.isfinite(rb).all(axis=1)
    inputs = mean(np.hstack([cond.f, cond.w]))[ok]
    design = Design(tb[ok], rb[ok], inputs, [], [], [], ok, prior, [])
    means = {"accel": cond.T[usable].mean(axis=0), "gyro": cond.freq[usable].mean(axis=0)}
    for term in cands:
        term = dict(term)
        if term["effect"] in ("temperature_bias", "temperature_scale"):
            term["reference"] = float(means[term["sensor"]][AXES.index(term["axis"])])
        cols = {}
        for (sensor, i), x in effects.regressor(term, cond).items():
            if "channels" in term and f"{sensor}.{AXES[i]}" not in term["channels"]:
                continue                    # a channel the reference cannot carry (`track`)
            cols[(0 if sensor == "accel" else 3) + i] = mean(x)[ok]
        if not cols:
            continue
        if not all(np.isfinite(x).all() for x in cols.values()):
            continue                        # e.g. temperature terms of a log without them
        if term["effect"] == "vibration_rectification" and \
                not library.vibrating(next(iter(cols.values()))):
            continue                        # a flight without airframe vibration
        scale = max(np.abs(x).max() for x in cols.values())
        spread = max(np.ptp(x, axis=0).max() for x in cols.values())
        if not spread > 1e-9 * max(scale, 1e-300):
            continue
        design.columns.append(cols)
        design.k.append(next(iter(cols.values())).shape[1])
        design.terms.append(term)
        design.along.append(_along(design, cols))
        design.allowance.append(np.atleast_2d(model_allowance(cal, term)))
        design.allowance_of.append("calibration" if design.allowance[-1].any() else None)
    if transfer is not None and np.any(transfer[0]):
        rates = (mean(cond.w)[ok], mean(cond.w_dot)[ok])
        for j, term in enumerate(design.terms):
            if term["effect"] in TRANSFERRED:
                design.allowance[j] = transfer_allowance(design.columns[j], *rates, *transfer)
                design.allowance_of[j] = "reference"
    cond.release_shared()
    design.channel_columns          # made now, channel by channel: the columns held once
    return design


TRANSFERRED = ("lever_arm", "size_effect")


def transfer_allowance(columns, w, w_dot, d, cov):
    """(k, k) the covariance a candidate's coefficient takes from the reference IMU's stated
    gyro error through the lever-arm transfer (`reference.predicted_mimu`): a reference that
    reads (I + G) w moves the specific force it predicts at the MIMU, d away, by
        df = (G w) x (w x d) + w x ((G w) x d) + (G dw/dt) x d
    (the first-order change of w x (w x d) + dw/dt x d) - a lever-arm-like signature that a
    lever arm or a proof-mass offset fits (on effect-free foreign-05 variants, 0.3 m apart
    and reference gyro errors at their stated 2.5e-4 / 1e-4 rad, a size effect's z of
    2-5 fell to 0.5-0.7 with the reference's error taken away). columns: the candidate's
    {channel: (nb, k)} bin means; w, w_dot: (nb, 3) the predicted rates (rad/s, rad/s^2) in
    the MIMU's axes; d (3,) m, MIMU axes; cov (9, 9) the gyro error matrix G's covariance,
    row-major, MIMU axes (`Accuracy.prior`'s gyro block). B = the least-squares fit of the
    candidate to each of G's nine unit signatures on its channels (`transfer_signatures`);
    returns B cov B'."""
    signatures = transfer_signatures(w, w_dot, d)
    chans = sorted(c for c in columns if c < 3)     # TRANSFERRED terms act on accelerometers
    x = np.vstack([columns[c] for c in chans])
    s = np.vstack([signatures[:, c, :] for c in chans])
    b = np.linalg.lstsq(x, s, rcond=None)[0]             # (k, 9)
    return b @ cov @ b.T


def transfer_signatures(w, w_dot, d):
    """(n, 3, 9) d(df)/dG: the change of the transferred specific force w x (w x d) + dw/dt x d
    (m/s^2) per unit entry of the reference's gyro error matrix G (row-major), to first order
    (`transfer_allowance`). w (n, 3) rad/s, w_dot (n, 3) rad/s^2, d (3,) m, one frame."""
    out = np.empty((len(w), 3, 9))
    for e in range(9):
        g = np.zeros(9)
        g[e] = 1.0
        gw, gw_dot = w @ g.reshape(3, 3).T, w_dot @ g.reshape(3, 3).T
        out[:, :, e] = (np.cross(gw, np.cross(w, d)) + np.cross(w, np.cross(gw, d))
                        + np.cross(gw_dot, d))
    return out


def gamma_slots(c):
    """Indices into gamma of channel c's row of its triad's error matrix."""
    return (0 if c < 3 else 9) + 3 * (c % 3) + np.arange(3)


def _along(design, cols):
    """(18, k) V with columns = reference inputs @ V on every channel, when the candidate is
    exactly a combination of the reference's inputs (a linear term); None otherwise."""
    k = next(iter(cols.values())).shape[1]
    v = np.zeros((18, k))
    for c, x in cols.items():
        ref = design.ref_columns(c)
        coef = design.ref_pinv(c) @ x         # least squares, as np.linalg.lstsq
        if np.linalg.norm(x - ref @ coef) > LINEAR_TOLERANCE * max(np.linalg.norm(x), 1e-300):
            return None
        v[gamma_slots(c)] = coef
    return v


def term_contribution(tier, pos, beta):
    """(nb, channels) the term's contribution to each channel, natural units (`tier`: any
    object with `t`, `channels` and per-candidate `columns`)."""
    out = np.zeros((len(tier.t), tier.channels))
    for ch, cols in tier.columns[pos].items():
        out[:, ch] = cols @ beta
    return out


def reference_error(design, fit):
    """(nb, 6) the fitted reference error x_ref' gamma per channel."""
    g = fit.gamma()
    return np.column_stack([design.ref_columns(c) @ g[gamma_slots(c)] for c in range(6)])


def detrended(design, resid):
    """Residual with a piecewise-linear bias (knots every DETREND_KNOT_S) removed per
    channel: for display, the rms figures and the scan."""
    q = design.detrend_q
    return resid - q @ (q.T @ resid)

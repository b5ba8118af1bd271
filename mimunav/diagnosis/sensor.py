"""Sensor-level diagnosis: the recorded MIMU, compensated with the user's calibration, against
what the reference motion says it should have read (`reference.predicted_mimu`).

Model of the residual (6 channels: accel x y z in m/s^2, gyro x y z in rad/s, on 10 ms bin
means - longer where the reference's own error is correlated longer, `diagnose`'s bin_s),
per channel c:
    r_c = sum_j X_cj beta_j  +  x_ref,c' gamma  +  b_c(t)  +  white noise
  - X_cj: the candidate terms of the library (`library`, regressors `effects.regressor`);
  - gamma: the reference IMU's own linear error (scale factor and axis misalignment of each
    triad, seen in the MIMU's axes) with a Gaussian prior of the reference's stated accuracy
    (`reference.Accuracy`: from the log's `sensor/fog` metadata, the command line, or seed
    S1 Table 4) - so the reference's error is neither ignored nor allowed to be anything;
  - b_c: a bias that wanders as a random walk whose level is fitted to the channel's own
    residual by maximum likelihood (`wander`); the bias itself is part of it.
Generalised least squares under that covariance (`wander`: the Kalman filter's innovations),
so a term that acts in one event (one boost) or slowly (temperature) is tested against the
noise and wander that really overlap it.

Procedure:
 1. the flight is cut into SPLIT_BLOCK_S blocks, alternately training and held-out, so every
    manoeuvre of the flight as flown - one boost, one ramp - lands in both halves;
 2. forward selection on the training rows: each candidate is tested (likelihood ratio for a
    term of one channel, Wald for one shared by several) against the
    nuisance and the terms already chosen; the smallest p-value must pass Holm's step-down
    threshold over the library (family-wise error alpha). A candidate whose estimate lies
    outside its physical range (`library.physical_limit`) is a look-alike absorbing another
    term's signature and is not chosen. Candidates that fit as well as the chosen one and
    explain each other away are compared again on the whole flight (the same rule, on the
    held-out rows too): one that encompasses the others there is named (`named_on`), and
    those still explaining each other away are named with it (`indistinguishable_from`);
 3. terms linear in the sensor's own input (scale factor, cross-coupling, mounting
    misalignment: exactly what the reference's own error, or the calibration's own fit
    error, looks like) must pass the same threshold with the stated accuracies of both
    (`reference.Accuracy`, the calibration file's covariance) added to their variance;
    so must the terms the model itself carries (g-sensitivity C, nonlinearity A2/A3/W2/W3,
    temperature ct/cw) against the calibration's stated covariance of them
    (`model_allowance`); those significant against the noise alone are listed as
    `within_reference_accuracy`, never dropped silently;
 4. the chosen terms are refitted on the held-out rows alone: coefficient and 95 % interval
    (for linear terms including those accuracies; for a one-parameter term of one channel,
    tested by the likelihood ratio, the profile-likelihood interval of that test, the wander
    level profiled at each value - `Fitter.profile_interval`; else Wald's at the fitted
    level); confirmed when p < alpha / (number
    chosen) with the training sign. Attribution: `mimu`, or where the stated accuracies
    could still explain it on the held-out rows, `mimu-or-reference` (a linear term) or
    `mimu-or-calibration` (a term the model carries);
    Limits, said plainly: for terms slower than a block (temperature), both halves share one
    bias path, so the held-out check guards against noise but not against a wander the
    random-walk model misdescribes; forward selection with recomputed p-values follows
    Holm's thresholds but is not Holm's procedure, so the family-wise rate is not guaranteed
    - the false-alarm rates measured on null recordings (reports/diagnosis-proof.md) are
    the evidence; where the whole flight chose among look-alikes the training half could not
    tell apart (`named_on` "whole flight"), the held-out rows confirm the group's signal,
    not the name, and the held-out interval is mildly optimistic;
 5. the residual left after the confirmed terms and the fitted reference error is scanned
    for localized excursions (2 s windows, robust z, Bonferroni): an unexplained residual
    with its place.
"""
import math
from dataclasses import dataclass, field
from functools import cache, cached_property

import numpy as np
import quaternion
from scipy import linalg, optimize, stats

from .. import effects
from ..calibration import standard_errors
from ..compensation import REPLACED, UNUSABLE, poly2
from ..evaluation import compensated_mimu
from ..effects import AXES, Conditions, derivative, vibration_power
from ..sensors.mimu import G0, MimuUnit
from . import library, outputs, wander
from .reference import DERIVATIVE_WINDOW_S, accuracy_of, predicted_mimu
from ..errors import InputError

FAST_BIN_S = 0.01
SPLIT_BLOCK_S = 0.5
MAX_TERMS = 6
SCAN_WINDOW_S = 2.0
SCAN_DOF = 10
MAP_SECONDS = 1.0
DETREND_KNOT_S = 10.0           # bias removed for display and the scan: piecewise linear
LINEAR_TOLERANCE = 1e-9         # a candidate is 'linear' when the reference inputs span it
PIN = 1e12                      # prior precision factor that holds the reference error at zero
CHI2_95_1DOF = float(stats.chi2.isf(0.05, 1))   # 3.84: a 95 % profile-likelihood interval
CHANNELS = [("accel", a) for a in AXES] + [("gyro", a) for a in AXES]
# findings that carry an offset of their own, so a channel that has one is not tested for a
# bias shift or wander (`outputs.bias_tests`): a clip or a lattice, and the temperature terms,
# whose reference offset the contract leaves to the bias (T0 the log's mean)
OWN_OFFSET = ("saturation", "quantization", "temperature_bias", "temperature_scale",
              "temperature_rate", "thermal_hysteresis")
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
    allowance: list = field(default_factory=list)   # per candidate: the calibration's
                                # stated variance of that term (`model_allowance`)
    levels: np.ndarray = field(default_factory=lambda: wander.LAMBDA_GRID)   # wander levels
                                # the fits may choose from
    wander_steps: np.ndarray | None = None  # (6,) each channel's largest wander step
                                # variance per bin, SI^2 (`diagnose`; None: no cap)
    bin_s: float = FAST_BIN_S   # the bins' length, s
    shape: np.ndarray | None = None     # (nb, 6) each bin's white variance over its channel's
                                # (`diagnose`'s noise_shape; None: constant)
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
        columns on c], {candidate: its column indices}) - what every `Fitter` filters."""
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
        return out

    @cached_property
    def detrend_q(self):
        """(nb, knots) orthonormal basis of the piecewise-linear bias (hat functions with
        knots every DETREND_KNOT_S) that `_clean` removes: one per design, not per call. By
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


@dataclass
class SensorDiagnosis:
    level = "sensor"
    findings: list              # contract findings (+ extra keys)
    unexplained: list           # [{"t0", "t1", "channel", "z"}]
    rejected: list              # chosen on training data, not confirmed (with why)
    within_reference: list      # significant, but no larger than the reference's accuracy
    design: Design
    train: np.ndarray           # bool over bins
    conditions: dict            # bin condition masks for the map
    residual_map: dict          # "before"/"after": (conditions, 6) rms ratios
    before: np.ndarray          # (nb, 6) residual, fitted reference error and bias removed
    after: np.ndarray           # the same with the confirmed terms removed
    accuracy: dict              # the reference accuracy used
    candidates: int
    candidates_list: list       # [term]
    fitter: object = None       # the all-rows `Fitter` (for `term_z`)
    bias_null: dict = None      # the wander the bias tests take as normal, and its source
    compensated: tuple = None   # (flight, w rad/s, f m/s^2 (N, 3) sensor axes): the MIMU of
                                # the flight diagnosed through the model, every sample (the
                                # report navigates them when it reports on that flight)


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


def diagnose(flight, cal, alpha=0.05, candidates=None, accuracy=None, max_wander=None,
             output_tests=True, noise=None, vibration=None, bin_s=FAST_BIN_S,
             block_s=SPLIT_BLOCK_S, noise_shape=None, wander_steps=None):
    """Sensor-level diagnosis of `flight` (an `evaluation.Flight` with a reference IMU)
    against calibration `cal`. `candidates`: the library to test (default
    `library.candidates()`); `max_wander`: the largest wander level (random-walk step
    variance over the white variance of a bin) the fits may choose - for a reference whose
    own errors are structured and would otherwise pass for wander (`track`); `accuracy`:
    the reference's `reference.Accuracy` (default: the
    log's metadata, else Table 4); `output_tests`: also test the effects that are no
    regressor (`outputs`: saturation, quantization, the bias's wander and level against the
    MEMS class - not for a reference made from a vehicle's track); `noise`: the unit's
    measured random errors for those bias tests (`outputs.bias_tests`); `vibration`: (N, 3)
    the MIMU's vibration power, (m/s^2)^2, when its outputs in `flight` were filtered into
    the reference's band (`track`: a smoothed track's); `bin_s`, `block_s`: the bins' and
    the split blocks' lengths (s) - longer where the reference's own error is correlated
    over more than a bin (`track`: a smoothed track's rates), so that bins are independent
    as the fit assumes and the held-out blocks do not share the training blocks' noise;
    `noise_shape`: (N, 6) each sample's white variance relative to its channel's, where the
    reference's own error varies along the record (`track`: a yaw rate from the course
    errs as 1/speed): the fit weighs and the scan judges each bin by it; `wander_steps`:
    (6,) the largest step variance of each channel's bias wander per bin, SI units squared,
    whatever white variance the fit finds (`track`: a level capped by `max_wander` alone
    grows with the vehicle model's own errors, which swell that white variance). Nothing
    here is random."""
    if flight.mimu_platform is not None:
        raise InputError(f"{flight.path}: the MIMU turns on a platform (/mimu/platform); "
                         "this analysis does not follow the rotation yet - replay and table do")
    acc = accuracy_of(flight.fog_meta, accuracy)
    q_sf = np.conjugate(flight.mimu_mounting.q_vs) * flight.fog_mounting.q_vs
    t, res, usable, cond, samples = residual(flight, cal, vibration)
    m = bins(t, flight.fog_t, bin_s)
    full_scale = {"accel": float(flight.mimu_range.get("accel_m_s2", MimuUnit.range_accel)),
                  "gyro": float(flight.mimu_range.get("gyro_rad_s", MimuUnit.range_gyro))}
    on_outputs = []
    cands = library.candidates() if candidates is None else candidates
    if output_tests:
        on_outputs, clipped, quantized = _output_findings(flight, cal, t, samples, full_scale)
        usable = usable & ~clipped
        # a quantized output's error depends on where its input falls between two steps:
        # terms of that channel alone would fit the lattice, not physics
        cands = [c for c in cands if not _on_channels_only(c, quantized)]
    design = _design(t, res, usable, cond, cands, m,
                     acc.prior(q_sf) + calibration_prior(cal), cal)
    design.q_vs = flight.mimu_mounting.attitude_wxyz
    design.bin_s = bin_s
    if noise_shape is not None:
        design.shape = Binning(m, usable)(np.asarray(noise_shape, float))[design.kept]
    if max_wander is not None:
        design.levels = wander.LAMBDA_GRID[wander.LAMBDA_GRID <= max_wander]
    design.wander_steps = wander_steps
    if len(design.t) < 4 * block_s / bin_s:
        raise InputError(f"{flight.path}: {len(design.t) * bin_s:.1f} s of usable MIMU "
                         f"samples inside the reference IMU's span; the sensor level needs "
                         f"at least {4 * block_s:g} s")
    block = outputs.block_index(design.t, block_s)
    train = block % 2 == 0
    held = ~train

    # the all-rows fit, made when first needed (look-alikes during the selection; its Grams
    # cost about a second on a 10-minute flight)
    whole = cache(lambda: Fitter(design, np.ones(len(design.t), bool)))
    chosen, within = _select(design, train, alpha, full_scale, whole)
    findings, rejected = _judge(design, chosen, train, held, alpha, full_scale, cond)
    everything = whole()
    before = _clean(design, design.residual - _reference_error(design, everything.fit([])))
    found = [_position(design, f) for f in findings]
    fit = everything.fit(found)
    removed = design.residual - _reference_error(design, fit)
    for f, j in zip(findings, found):
        removed = removed - _contribution(design, j, _beta(f))
    conds = _condition_masks(design, cond, m, usable)
    scanned = removed.copy()
    if output_tests:
        scanned[:, sorted(quantized)] = 0.0     # a lattice's own error is no excursion
    # localized excursions (against a local baseline: the constant of a bias_shift removed
    # below does not move them)
    unexplained = _scan(design, scanned, alpha)
    if output_tests:
        # an excursion is no wander of the bias, and no offset: its bins (and a scan window
        # either side) are left out of the bias tests - a 2 s bias pulse outside the
        # vocabulary had been named bias_instability beside the excursion it is
        quiet = conds["quiet"] & ~_near(design.t, unexplained, SCAN_WINDOW_S)
        on_outputs += outputs.bias_tests(design, removed, quiet,
                                         alpha / (len(design.terms) + 12), cal,
                                         skip={(f["sensor"], f["axis"]) for f in
                                               on_outputs + findings
                                               if f["effect"] in OWN_OFFSET}, noise=noise)
    for f in on_outputs:
        if f["effect"] == "bias_shift":
            removed[:, CHANNELS.index((f["sensor"], f["axis"]))] -= f["coefficient"]
    findings = findings + on_outputs
    after = _clean(design, removed)
    diag = SensorDiagnosis(findings, unexplained, rejected, within, design, train, conds,
                           {"before": _map(design, before, conds),
                            "after": _map(design, after, conds)},
                           before, after, acc.as_dict(), len(design.terms), design.terms,
                           everything, outputs.bias_null(noise) if output_tests else None,
                           (flight, *samples["compensated"]))
    diag.inconclusive = [why for why in (_jitter(flight.mimu_t, "the MIMU's"),
                                         _jitter(flight.fog_t, "the reference IMU's")) if why]
    return diag


def _near(t, spans, margin_s):
    """(n,) bool: the times t (s) within margin_s of any span {"t0", "t1"} (s)."""
    out = np.zeros(len(t), bool)
    for span in spans:
        out |= (t >= span["t0"] - margin_s) & (t <= span["t1"] + margin_s)
    return out


STAMP_JITTER = 0.25     # robust sigma of the sampling steps over the period: beyond it a
                        # stamp does not say which interval its sample is the mean of


def _jitter(t, whose):
    """Why the stamps `t` (s) cannot carry a sample-by-sample comparison, or '': their steps
    scatter (robust sigma, MAD / 0.6745) by more than STAMP_JITTER of the median step (a
    recording stamped +-5 ms at 100 Hz gave spurious scale terms on the accelerometers)."""
    if t is None or len(t) < 10:
        return ""
    step = np.diff(t)
    period = float(np.median(step))
    sigma = float(np.median(np.abs(step - period))) / 0.6745
    if period > 0 and sigma > STAMP_JITTER * period:
        return (f"{whose} stamps jitter by {sigma * 1e3:.2g} ms (robust sigma of their steps) on "
                f"a {period * 1e3:.3g} ms period: a stamp does not say which interval its sample "
                "averages, and terms driven by fast motion may be that jitter")
    return ""


def _output_findings(flight, cal, t, samples, full_scale):
    """(saturation and quantization findings, samples clipped (N,) bool, quantized channels
    {channel index}): the tests on the outputs themselves (`outputs`), on every sample the
    compensation did not repair (a sample stuck at an extreme is flagged SATURATED there and
    is tested here). Quantization first: a quantized channel's clip test allows its step."""
    measured, predicted = samples["measured"], samples["predicted"]
    repaired = (samples["flags"] & (REPLACED | UNUSABLE)) != 0
    rows = samples["inside"] & ~repaired & np.isfinite(measured).all(axis=1) \
        & np.isfinite(predicted).all(axis=1)
    rows[0] = False
    live = rows & (samples["flags"] == 0)
    sigma = outputs.noise_sigma(np.where(live[:, None], measured - predicted, np.nan))
    raw = flight.mimu_raw
    volts = None if raw is None else np.hstack([raw["accel_volts"], raw["gyro_volts"]])
    found = outputs.quantization(t, measured, volts, _volt_gains(cal, raw, live), live, sigma)
    steps = np.zeros(6)
    for f in found:
        steps[CHANNELS.index((f["sensor"], f["axis"]))] = f["coefficient"]
    train = outputs.block_index(t, SPLIT_BLOCK_S) % 2 == 0
    clips, clipped = outputs.saturation(t, measured, predicted, rows, train, full_scale, steps,
                                        sigma if np.array_equal(live, rows) else None)
    return clips + found, clipped, set(np.flatnonzero(steps))


def _on_channels_only(term, channels):
    """Whether `term` acts on one channel and it is among `channels` (indices)."""
    if term.get("sensor") not in ("accel", "gyro") or term.get("axis") not in AXES:
        return False
    return CHANNELS.index((term["sensor"], term["axis"])) in channels


def _volt_gains(cal, raw, rows):
    """(6, 3) the slope of each channel's output in SI per V of its own raw volts over the
    samples `rows` (median, smallest, largest magnitude): A1_ii + 2 A2_i V + 3 A3_i V^2 at
    the temperature-compensated V (eqs. 1-4; W for the gyros); ones without raw volts."""
    if raw is None or cal is None or cal.base_model not in ("entire-63", "linear"):
        return np.ones((6, 3))
    out = []
    for (a1, a2, a3), u, temp, poly in (
            ((cal.A1, cal.A2, cal.A3), raw["accel_volts"], raw["accel_temperature"], cal.ct),
            ((cal.W1, cal.W2, cal.W3), raw["gyro_volts"], raw["gyro_frequency"], cal.cw)):
        v = (u - poly2(poly, temp))[rows]
        slope = np.abs(np.diag(a1) + 2 * a2 * v + 3 * a3 * v * v)
        out += [(np.median(slope[:, i]), slope[:, i].min(), slope[:, i].max())
                for i in range(3)]
    return np.asarray(out)


def calibration_prior(cal):
    """(18, 18) covariance of the calibration's own linear error in the MIMU's axes, in the
    layout of `reference.Accuracy.prior`: from the standard errors of A1 and W1 in the file's
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


def verdict(diag):
    """The contract verdict: missing-physics when a term is confirmed, otherwise
    unexplained-residual when a localized excursion remains or the reference cannot explain
    the recording (an inconclusive track level), otherwise no-missing-physics."""
    if diag.findings:
        return "missing-physics"
    if diag.unexplained or getattr(diag, "inconclusive", None):
        return "unexplained-residual"
    return "no-missing-physics"


# ---- the design --------------------------------------------------------------------------
def _design(t, res, usable, cond, cands, m, prior, cal):
    """Bin the residual, the reference inputs and each candidate's regressor; drop candidates
    the flight cannot drive (no variation) and mark those the reference inputs span."""
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
        design.allowance.append(model_allowance(cal, term))
    return design


def _gamma_slots(c):
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
        v[_gamma_slots(c)] = coef
    return v


# ---- fits --------------------------------------------------------------------------------
class Fitter:
    """GLS fits on a set of rows. For each channel and each wander level of `design.levels`,
    the Gram matrix of the Kalman innovations of [residual, reference inputs, every candidate
    column of the channel] is computed once; a fit then takes, per channel, the level of
    maximum profile likelihood under its own model (so a slow term is tested against the
    wander that remains with it in the model, not against one inflated by it)."""

    def __init__(self, design, rows):
        self.design, self.rows = design, rows
        self.gram, self.logdet, self.slot = [], [], []
        self._levels = {}
        for c in range(6):
            x, slot = design.channel_columns[c]
            gram, logdet, self.n = wander.grams(
                x, rows, design.levels, None if design.shape is None else design.shape[:, c])
            self.gram.append(gram)
            self.logdet.append(logdet)
            self.slot.append(slot)
        self.precision = np.linalg.inv(design.prior + 1e-24 * np.eye(18))
        self.row_prior = [design.prior[np.ix_(_gamma_slots(c), _gamma_slots(c))]
                          for c in range(6)]
        self.row_precision = [np.linalg.inv(p + 1e-24 * np.eye(3)) for p in self.row_prior]

    def _profile(self, c, cols, pinned=False, gram=None):
        """(Grams, r, log-likelihood) of channel c at every wander level, with the candidate
        columns `cols` (indices into the channel's columns) in the mean and the reference
        inputs (columns 1-3) under the reference's prior: the
        likelihood of y ~ N(X beta, r (wander) + R P R'), by Woodbury over the 3 prior
        columns, with r profiled (fixed-point on the penalized residual); and the
        coefficients of the reference inputs and `cols` at every level. `gram`: the
        channel's Grams with another residual (`profile_interval`)."""
        g = self.gram[c] if gram is None else gram
        every = [1, 2, 3] + list(cols)
        m = g[:, every][:, :, every]
        h = g[:, every, 0]
        pen = np.zeros((len(every), len(every)))
        pen[:3, :3] = self.row_precision[c] * (PIN if pinned else 1.0)
        r = np.maximum(g[:, 0, 0], 1e-300) / self.n
        for _ in range(4):
            theta = np.linalg.solve(m + r[:, None, None] * pen + 1e-12 * np.eye(len(every)) *
                                    np.maximum(np.einsum("lii->l", m), 1e-300)[:, None, None]
                                    / len(every), h[:, :, None])[:, :, 0]
            q = np.maximum(g[:, 0, 0] - np.einsum("li,li->l", h, theta), 1e-300)
            r = q / self.n
        _, logdet_prior = np.linalg.slogdet(np.eye(3) + self.row_prior[c] @ m[:, :3, :3]
                                            / (r[:, None, None] * (PIN if pinned else 1.0)))
        loglik = -0.5 * (self.logdet[c] + self.n * np.log(r) + logdet_prior + q / r)
        if self.design.wander_steps is not None:    # levels whose step exceeds the cap: out
            over = self.design.levels * r > self.design.wander_steps[c]
            over[0] = False                         # (the lowest level stays)
            loglik = np.where(over, -np.inf, loglik)
        return g, r, loglik, theta

    def _level(self, c, cols, pinned=False):
        """(Gram, r, log-likelihood) of channel c at the wander level of maximum marginal
        likelihood (`_profile`); kept per (channel, columns in their order, pinned): a
        selection step fits every candidate with the same chosen terms on the channels the
        candidate does not touch, and the likelihood ratio refits the fit's own model."""
        key = (c, tuple(cols), pinned)
        if key not in self._levels:
            g, r, loglik, _ = self._profile(c, cols, pinned)
            best = int(np.argmax(loglik))
            self._levels[key] = g[best], float(r[best]), float(loglik[best])
        return self._levels[key]

    def _columns(self, c, terms):
        return [i for j in terms if j in self.slot[c] for i in self.slot[c][j]]

    def likelihood_ratio(self, terms, j):
        """2 (max log-likelihood with candidate j - without it), the other `terms` in both and
        each channel's wander level profiled in each (the reference error under its prior,
        marginalised: `_level`)."""
        return 2 * sum(self._level(c, self._columns(c, terms + [j]))[2]
                       - self._level(c, self._columns(c, terms))[2]
                       for c in self.design.columns[j])

    def profile_interval(self, terms, j, sd, chi2=CHI2_95_1DOF):
        """95 % profile-likelihood interval of the one-parameter candidate j of one channel,
        fitted with `terms` (which hold j; sd: its Wald standard deviation, the search's
        step): the values beta at which 2 (max log-likelihood - log-likelihood with j held
        at beta) = chi2, the wander level, its scale and the other columns of the channel
        profiled at each beta. It is the interval of the likelihood-ratio test that named
        the term (beta = 0 lies outside it exactly when the test's statistic exceeds chi2),
        and wider than the Wald interval at the fitted level where a slow term and the
        wander can stand in for each other (a temperature ramp on a cold start): the Wald
        interval takes the level as known."""
        (c,) = self.design.columns[j]
        cols = self._columns(c, terms)
        (x,) = self._columns(c, [j])
        others = [i for i in cols if i != x]
        g = self.gram[c]
        _, _, loglik, theta = self._profile(c, cols)
        best = int(np.argmax(loglik))
        top, centre = float(loglik[best]), float(theta[best, 3 + cols.index(x)])

        def deficit(beta):                  # 2 (max - profile at beta) - chi2
            held = g.copy()                 # the Grams of the residual y - beta x
            held[:, 0, :] -= beta * g[:, x, :]
            held[:, :, 0] = held[:, 0, :]
            held[:, 0, 0] = g[:, 0, 0] - 2 * beta * g[:, 0, x] + beta ** 2 * g[:, x, x]
            return 2 * (top - float(np.max(self._profile(c, others, gram=held)[2]))) - chi2

        def edge(direction):                # the first crossing, stepping out by sd / 2
            inside, step = 0.0, 0.5 * max(sd, 1e-12 * max(abs(centre), 1e-300))
            for _ in range(200):
                if deficit(centre + direction * step) > 0:
                    return optimize.brentq(lambda d: deficit(centre + direction * d), inside,
                                           step, xtol=1e-6 * step)
                inside, step = step, step * 1.25
            return math.inf
        if not deficit(centre) < 0:         # the profile's top not resolved (its scale's
            return -math.inf, math.inf      # fixed point): unbounded, the caller keeps Wald's
        lo, hi = centre - edge(-1.0), centre + edge(1.0)
        if deficit(0.0) <= 0:               # the test does not reject zero: neither does the
            lo, hi = min(lo, 0.0), max(hi, 0.0)     # interval (a profile of several tops)
        return lo, hi

    def fit(self, terms, pinned=False):
        """`Fit` of the candidates `terms` (indices) with the reference error gamma under its
        prior (`pinned`: gamma held at zero - the candidates against the noise alone);
        parameters [gamma (18), terms...]."""
        k = [self.design.k[j] for j in terms]
        offsets = 18 + np.concatenate([[0], np.cumsum(k)]).astype(int)
        size = offsets[-1]
        a, h = np.zeros((size, size)), np.zeros(size)
        for c in range(6):
            cols, slots = [1, 2, 3], list(_gamma_slots(c))
            for j, o, kj in zip(terms, offsets, k):
                if j in self.slot[c]:
                    cols += list(self.slot[c][j])
                    slots += list(range(o, o + kj))
            g, r, _ = self._level(c, cols[3:], pinned)
            a[np.ix_(slots, slots)] += g[np.ix_(cols, cols)] / r
            h[slots] += g[cols, 0] / r
        a[:18, :18] += self.precision * (PIN if pinned else 1.0)
        cov = _covariance(a)
        beta = cov @ h
        return Fit(beta, cov, [slice(o, o + kj) for o, kj in zip(offsets, k)], list(terms))


def _covariance(a):
    """The inverse of the normal matrix `a`: a near-singular one (terms that the flight
    cannot tell apart, a channel recording twice its input) is inverted over its eigenvalues
    floored at 1e-15 of the largest, so the unresolved directions get a huge variance - a
    wide interval - instead of a negative one from round-off (whose square root was NaN)."""
    try:
        cov = np.linalg.inv(a)
        if np.all(np.diag(cov) > 0):
            return cov
    except np.linalg.LinAlgError:
        pass
    lam, vec = np.linalg.eigh(0.5 * (a + a.T))
    lam = np.maximum(lam, 1e-15 * max(float(lam.max()), 1e-300))
    return (vec / lam) @ vec.T


@dataclass
class Fit:
    beta: np.ndarray
    cov: np.ndarray
    slices: list
    terms: list

    def gamma(self):
        return self.beta[:18]

    def of(self, j):
        """(estimate, covariance) of candidate j."""
        s = self.slices[self.terms.index(j)]
        return self.beta[s], self.cov[s, s]


def _reference_dir(design, j):
    """Covariance of the reference's error expressed as candidate j's parameter (the part of
    j the reference can fake); None for a term the reference's linear error cannot make."""
    v = design.along[j]
    if v is None:
        return None
    vp = np.linalg.pinv(v)
    return vp @ design.prior @ vp.T


def wald(b, cov):
    """(chi-square statistic, log p) of b = 0."""
    try:
        stat = float(b @ np.linalg.solve(cov, b))
    except np.linalg.LinAlgError:
        return 0.0, 0.0
    return stat, float(stats.chi2.logsf(stat, len(b)))


def _test(fitter, terms, j):
    """Test of candidate j within the fit of `terms` (which holds j): dict with the estimate,
    its covariance (with the reference's share), log p of the statistical test and log p
    with the reference's (and the calibration's) stated accuracy. A term the reference's
    linear error cannot make is tested by the likelihood ratio when it acts on one channel
    (wander level profiled with and without it: a slow term must beat the wander it would
    otherwise be), by Wald when it acts on several (one parameter shared by the channels:
    time skew); a linear one by Wald twice: with the reference error under its prior, and
    with it held at zero (the evidence against the noise alone)."""
    design = fitter.design
    b, cov = fitter.fit(terms).of(j)
    ref = _reference_dir(design, j)
    if ref is None and len(design.columns[j]) == 1:
        stat = max(fitter.likelihood_ratio([i for i in terms if i != j], j), 0.0)
        logp = float(stats.chi2.logsf(stat, len(b)))
        logp_ref = logp
        if design.allowance[j] > 0:     # must also beat the calibration's own uncertainty
            logp_ref = max(logp, wald(b, cov + design.allowance[j])[1])
        return {"b": b, "cov": cov, "stat": stat, "logp": logp, "logp_ref": logp_ref,
                "linear": False}
    if ref is None:                 # a term of several channels (time skew): Wald
        stat, logp = wald(b, cov)
        return {"b": b, "cov": cov, "stat": stat, "logp": logp, "logp_ref": logp,
                "linear": False}
    stat, logp = wald(*fitter.fit(terms, pinned=True).of(j))
    _, logp_ref = wald(b, cov)
    return {"b": b, "cov": cov, "stat": stat, "logp": logp, "logp_ref": logp_ref,
            "linear": True}


def _plausible(design, j, b, full_scale):
    limit = library.physical_limit(design.terms[j], full_scale)
    return float(np.linalg.norm(b)) <= limit, limit


# ---- selection on training rows ----------------------------------------------------------
def _select(design, train, alpha, full_scale, whole=None):
    """Forward selection with Holm's step-down thresholds over the library; `whole`: a
    callable giving the all-rows `Fitter` (look-alikes the training rows cannot tell apart
    are compared on it, `_told_apart`). Returns (chosen: [dict], within: linear terms
    significant but inside the reference's accuracy)."""
    m = len(design.terms)
    chosen, excluded, within = [], set(), {}
    fitter = Fitter(design, train)
    for step in range(MAX_TERMS):
        current = [c["j"] for c in chosen]
        tests, implausible, significant = {}, [], {}
        for j in range(m):
            if j in excluded:
                continue
            res = _test(fitter, current + [j], j)
            # a term must beat the stated accuracies (the reference's for a linear term, the
            # calibration's own for one the model carries) at the selection's threshold
            if res["logp_ref"] > math.log(alpha / max(m - step, 1)):
                if res["logp"] < math.log(alpha / m) and j not in within:
                    within[j] = res
                continue
            res = dict(res, logp=res["logp_ref"])
            significant[j] = res
            ok, limit = _plausible(design, j, res["b"], full_scale)
            if not ok:
                implausible.append(j)
                continue
            tests[j] = res
        threshold = alpha / max(m - step, 1)
        passing = [j for j, r in tests.items() if r["logp"] <= math.log(threshold)]
        if not passing:
            break
        best, alternatives = _encompassing(fitter, current, passing, tests, threshold)
        encompassed, named_on = [], "training half"
        if alternatives and whole is not None:
            before = best
            best, alternatives, encompassed = _told_apart(whole(), current, best,
                                                          alternatives, threshold)
            named_on = "whole flight" if best != before else named_on
        best, set_aside = _whole_unit_or_one_axis(fitter, best, tests, significant,
                                                  threshold)
        alternatives = [j for j in alternatives if j != best]
        chosen.append(dict(j=best, alternatives=alternatives, named_on=named_on,
                           p_train=math.exp(tests[best]["logp"]), threshold=threshold,
                           b_train=tests[best]["b"],
                           implausible=[library.label(design.terms[j]) for j in implausible]))
        # a look-alike the whole flight tells apart without either explaining the other
        # away stays a candidate of the next step
        excluded |= {best, *alternatives, *encompassed, *set_aside}
    return chosen, [_within(design, j, r) for j, r in within.items()
                    if j not in {c["j"] for c in chosen}]


def _whole_unit_or_one_axis(fitter, best, tests, significant, level):
    """(chosen, [set aside]): a lever arm moves all three accelerometers by one vector; a
    proof-mass offset moves one. A lever arm is kept only when the size effect of at least
    two accelerometer axes passes this step on its own (`significant`: every candidate of
    the step with its p-value with the stated accuracies, a size effect beyond its physical
    range too - it still shows that its axis moves) - else the strongest plausible one
    (`tests`) replaces it and the lever arm is set aside (with one axis carrying it,
    the lever arm's fit of the other two is their small transfer errors, which a 3-channel
    Wald test turns into significance)."""
    design = fitter.design
    if design.terms[best]["effect"] != "lever_arm":
        return best, []
    alone = [j for j, term in enumerate(design.terms) if term["effect"] == "size_effect"
             and j in significant and significant[j]["logp"] <= math.log(level)]
    if len(alone) != 1 or alone[0] not in tests:
        return best, []
    return alone[0], [best]


def _encompassing(fitter, current, passing, tests, level, contenders=10):
    """The chosen term among the passing candidates, and those it cannot be told from. The
    strongest alone is not enough (a linear term's Wald test and a slow term's likelihood
    ratio differ in kind): a contender replaces it when it stays significant given the
    current choice while the choice adds nothing given it (it encompasses the choice), both
    at the selection's own `level` (Holm's threshold of the step: telling look-alikes apart
    needs the same evidence as finding a term).
    Candidates that explain each other away are indistinguishable on the training half;
    among them the one of lowest order is named (`library.order`: a g-sensitivity before a
    g^2 term that mimics it at constant f_z), the others listed - until the whole flight
    tells them apart (`_told_apart`)."""
    design = fitter.design
    ranked = sorted(passing, key=lambda j: (tests[j]["logp"], -tests[j]["stat"]))[:contenders]
    log_level = math.log(level)

    def adds(j, given):
        return _adds(fitter, current, j, given, log_level)
    best = ranked[0]
    for j in ranked[1:]:
        if adds(j, best) and not adds(best, j):
            best = j
    alike = [j for j in ranked if j != best and not adds(j, best) and not adds(best, j)]
    group = [best] + alike
    named = min(group, key=lambda j: (library.order(design.terms[j]), tests[j]["logp"]))
    return named, [j for j in group if j != named]


def _told_apart(whole, current, named, alike, level):
    """(named, the look-alikes it still cannot be told from, those it encompasses) after the
    group is compared again on the whole flight (`whole`: the all-rows `Fitter`) by
    `_encompassing`'s pass at the same level: a member that adds to the named term while
    the named adds nothing to it replaces it; listed are the members where neither adds
    given the other. Half the flight may hold too little of what tells two terms apart - a
    g^2 term and a cross-coupling to the pitch rate coincide in a pull-up at constant speed
    and part only where the speed differs. The held-out rows take part in this choice, so
    their confirmation (`_judge`) confirms the group's signal, not which member is named:
    such a finding says so (`named_on`)."""
    log_level = math.log(level)

    def adds(j, given):
        return _adds(whole, current, j, given, log_level)
    best = named
    for j in alike:
        if adds(j, best) and not adds(best, j):
            best = j
    others = [j for j in [named, *alike] if j != best]
    still = [j for j in others if not adds(j, best) and not adds(best, j)]
    return best, still, [j for j in others if adds(best, j) and not adds(j, best)]


def _adds(fitter, current, j, given, log_level):
    """Candidate j is significant at log_level (its p with the stated accuracies) given the
    terms `current` and `given`."""
    return _test(fitter, current + [given, j], j)["logp_ref"] <= log_level


def _within(design, j, res):
    """A term set aside (`_test`'s logp_ref above the threshold): the stated 1 sigma along it
    - the reference's linear error (with the calibration's) for a term it can make
    (`reference_1sigma`), else the calibration's own (`calibration_1sigma`, a term the model
    carries) - and the 1 sigma the test used (`total_1sigma`: the estimate's with the
    reference's prior, or the noise's plus the calibration's allowance, as `_test` takes it)."""
    ref = _reference_dir(design, j)
    if ref is not None:
        stated = {"reference_1sigma": np.sqrt(np.diag(ref)).tolist()}
        total = np.sqrt(np.diag(res["cov"]))
    else:
        stated = {"calibration_1sigma": [math.sqrt(design.allowance[j])] * len(res["b"])}
        total = np.sqrt(np.diag(res["cov"]) + design.allowance[j])
    return {"label": library.label(design.terms[j]), **_describe_b(res["b"]), **stated,
            "total_1sigma": total.tolist(),
            "p_train": math.exp(res["logp"]),
            "note": "significant against the noise alone, but not once the reference's and "
                    "the calibration's stated errors may share it: the data cannot tell it "
                    "from them (total_1sigma: the estimate's uncertainty with those priors), "
                    "so it cannot be charged to physics the model lacks"}


def _describe_b(b):
    return {"vector": b.tolist()} if len(b) > 1 else {"coefficient": float(b[0])}


# ---- confirmation on held-out rows -------------------------------------------------------
def _judge(design, chosen, train, held, alpha, full_scale, cond):
    if not chosen:
        return [], []
    idx = [c["j"] for c in chosen]
    held_fitter = Fitter(design, held)
    cleaned = _clean(design, design.residual)
    level = alpha / len(chosen)
    findings, rejected = [], []
    for c in chosen:
        j = c["j"]
        term = design.terms[j]
        res = _test(held_fitter, idx, j)
        b_tr, b_ho = c["b_train"], res["b"]
        interval = None
        if not res["linear"] and len(design.columns[j]) == 1 and design.k[j] == 1:
            interval = held_fitter.profile_interval(idx, j, float(np.sqrt(res["cov"][0, 0])))
            if not (np.all(np.isfinite(interval)) and interval[0] <= b_ho[0] <= interval[1]):
                interval = None     # unbounded, or the joint fit off the channel's: Wald's
        finding = _estimate(design, term, b_ho, res["cov"], interval)
        finding["ci95_method"] = "profile-likelihood" if interval is not None else "wald"
        where = _where_rows(_contribution(design, j, b_ho))
        finding["where"] = _spans(design, where, term, cond)
        finding["fit"] = _rms_fit(design, cleaned, j, b_tr, where, train, held, term)
        for key in ("order", "window_s", "reference"):
            if key in term:
                finding[key] = term[key]
        p_ho, p_ref = math.exp(res["logp"]), math.exp(res["logp_ref"])
        finding.update(
            label=library.label(term), p_train=c["p_train"], holm_threshold=c["threshold"],
            p_heldout=p_ho, train_coefficient=b_tr.tolist() if len(b_tr) > 1 else float(b_tr[0]),
            attribution=_attribution(term, p_ref < level, res["linear"]),
            named_on=c.get("named_on", "training half"),
            indistinguishable_from=[_alternative(design.terms[a]) for a in c["alternatives"]],
            not_chosen_as_implausible=c["implausible"])
        if res["linear"]:
            finding["p_heldout_with_reference_accuracy"] = p_ref
        ok, limit = _plausible(design, j, b_ho, full_scale)
        why = None
        if p_ho >= level:
            why = f"held-out p = {p_ho:.2g}, needs < {level:.2g}"
        elif float(b_tr @ np.linalg.lstsq(res["cov"], b_ho, rcond=None)[0]) <= 0:
            # (a vector in the held-out fit's metric: its well-determined directions count)
            why = "the held-out coefficient has the other sign"
        elif not ok:
            why = (f"held-out magnitude {np.linalg.norm(b_ho):.3g} beyond the physical range "
                   f"{limit:.3g}")
        (findings if why is None else rejected).append(
            finding if why is None else dict(finding, rejected=why))
    return findings, rejected


def _attribution(term, beyond_reference, linear):
    """Whom a finding is charged to: the MIMU's sensors, or for the whole unit's terms its
    installation (mounting, lever arm) or its timing (time_skew); '-or-reference' when the
    reference's stated accuracy could hold it, '-or-calibration' when the calibration's
    stated covariance could."""
    who = {"mounting_misalignment": "installation", "lever_arm": "installation",
           "time_skew": "timing"}.get(term["effect"], "mimu")
    if beyond_reference:
        return who
    return who + ("-or-reference" if linear else "-or-calibration")


def _estimate(design, term, b, cov, interval=None):
    """`estimate` with the 95 % interval of covariance `cov` (or `interval`, (lo, hi) of a
    scalar: `Fitter.profile_interval`); a lever arm (fitted in the sensor axes) turned into
    the vehicle frame of the metadata's lever_arm_m, its sensor-axes vector kept for the
    compensation (`vector_sensor_axes`); a mounting misalignment (a rotation vector of the
    sensor axes, as the contract's `vector`) also as the same turn about the vehicle's
    axes (`vector_vehicle`, FRD, with `vector_vehicle_ci95`): a mounting that turns the
    sensor's z axis up reverses the sign of a yaw read off the sensor axes."""
    if interval is not None:
        return estimate(term, b, np.array([interval[0]]), np.array([interval[1]]))
    if term["effect"] not in ("lever_arm", "mounting_misalignment"):
        half = 1.96 * np.sqrt(np.diag(cov))
        return estimate(term, b, b - half, b + half)
    c_vs = quaternion.as_rotation_matrix(quaternion.from_float_array(design.q_vs))
    b_v, cov_v = c_vs @ b, c_vs @ cov @ c_vs.T
    half_v = 1.96 * np.sqrt(np.diag(cov_v))
    if term["effect"] == "mounting_misalignment":    # the sensor axes' turn phi (q_vs q(phi))
        half = 1.96 * np.sqrt(np.diag(cov))          # is the turn C_vs phi of the vehicle
        return dict(estimate(term, b, b - half, b + half),  # axes (q(C_vs phi) q_vs)
                    vector_vehicle=b_v.tolist(),
                    vector_vehicle_ci95=np.column_stack([b_v - half_v, b_v + half_v]).tolist())
    return dict(estimate(term, b_v, b_v - half_v, b_v + half_v), frame="vehicle",
                vector_sensor_axes=b.tolist())


def estimate(term, beta, lo, hi):
    """The contract's description of a term with its held-out estimate and 95 % interval
    (a vector parameter as `vector`, its largest component as `coefficient`, and the frame
    of its components: the MIMU's sensor axes here)."""
    finding = {k: v for k, v in term.items() if k in ("effect", "sensor", "axis", "input_axis")}
    if len(beta) == 1:
        finding.update(coefficient=float(beta[0]), ci95=[float(lo[0]), float(hi[0])])
    else:
        big = int(np.argmax(np.abs(beta)))
        finding.update(coefficient=float(beta[big]), ci95=[float(lo[big]), float(hi[big])],
                       vector=beta.tolist(), vector_ci95=np.column_stack([lo, hi]).tolist(),
                       frame="sensor")
    finding["units"] = effects.units(term)
    return finding


def _alternative(term):
    out = {k: term[k] for k in ("effect", "sensor", "axis", "input_axis", "order", "window_s")
           if k in term}
    out["label"] = library.label(term)
    return out


def _position(design, finding):
    labels = [library.label(t) for t in design.terms]
    return labels.index(finding["label"])


def _beta(finding):
    return np.asarray(finding.get("vector_sensor_axes",
                                  finding.get("vector", [finding["coefficient"]])), float)


def _contribution(tier, pos, beta):
    """(nb, channels) the term's contribution to each channel, natural units (`tier`: any
    object with `t`, `channels` and per-candidate `columns`)."""
    out = np.zeros((len(tier.t), tier.channels))
    for ch, cols in tier.columns[pos].items():
        out[:, ch] = cols @ beta
    return out


def _reference_error(design, fit):
    """(nb, 6) the fitted reference error x_ref' gamma per channel."""
    g = fit.gamma()
    return np.column_stack([design.ref_columns(c) @ g[_gamma_slots(c)] for c in range(6)])


def _where_rows(contribution):
    """Rows where the term acts: its contribution above a quarter of its peak (99.9th
    percentile of the magnitude over the channels it drives)."""
    mag = np.linalg.norm(contribution / (np.abs(contribution).max(axis=0) + 1e-300), axis=1)
    peak = np.percentile(mag, 99.9)
    return mag >= 0.25 * peak if peak > 0 else np.zeros(len(mag), bool)


def _clean(design, resid):
    """Residual with a piecewise-linear bias (knots every DETREND_KNOT_S) removed per
    channel: for display, the rms figures and the scan."""
    q = design.detrend_q
    return resid - q @ (q.T @ resid)


def _rms_fit(design, before, j, b_tr, where, train, held, term):
    """Residual rms in the term's located rows before (`before`: the residual with its bias
    removed, `_clean`) and after removing the term with the training coefficient, on
    training and on held-out rows."""
    after = _clean(design, design.residual - _contribution(design, j, b_tr))
    chans = sorted(design.columns[j])
    if term["sensor"] == "imu":         # report the sensor whose channels gain most
        gains = {s: [ch for ch in chans if (ch < 3) == (s == "accel")] for s in ("accel", "gyro")}
        ratio = {s: _rms(after, where, chs) / max(_rms(before, where, chs), 1e-300)
                 for s, chs in gains.items() if chs}
        sensor = min(ratio, key=ratio.get)
        chans = gains[sensor]
    else:
        sensor = term["sensor"]
    out = {}
    for part, rows in (("train", train), ("heldout", held)):
        out[f"{part}_rms_before"] = _rms(before, where & rows, chans)
        out[f"{part}_rms_after"] = _rms(after, where & rows, chans)
    out["units"] = "m/s^2" if sensor == "accel" else "rad/s"
    out["channels"] = [f"{CHANNELS[ch][0]}.{CHANNELS[ch][1]}" for ch in chans]
    out["basis"] = (f"bin means ({design.bin_s:.3g} s), piecewise-linear bias removed, rows where "
                    "the term acts; 'after' uses the training coefficient")
    return out


def _rms(x, rows, chans):
    v = x[np.ix_(rows, chans)]
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


def _spans(tier, rows, term, cond, gap_s=2.0, max_spans=20):
    """Contiguous time spans of the rows (gaps below gap_s merged) with the flight
    conditions met there."""
    t = tier.t
    if not rows.any():
        return []
    half = 0.5 * float(np.median(np.diff(t)))
    idx = np.flatnonzero(rows)
    breaks = np.flatnonzero(np.diff(t[idx]) > gap_s)
    starts, ends = np.r_[idx[0], idx[breaks + 1]], np.r_[idx[breaks], idx[-1]]
    order = np.argsort(-(t[ends] - t[starts]))[:max_spans]
    spans = []
    for a, b in sorted(zip(starts[order], ends[order])):
        t0, t1 = float(t[a] - half), float(t[b] + half)
        spans.append({"t0": t0, "t1": t1, "condition": _condition(cond, t0, t1, term)})
    return spans


def _condition(cond, t0, t1, term):
    """What the flight did in [t0, t1]: peak |f| (g), |w| (deg/s), temperature range."""
    a, b = int(np.searchsorted(cond.t, t0, "left")), int(np.searchsorted(cond.t, t1, "right"))
    k = slice(a, b)                     # the samples t0 <= t <= t1 (the times increase)
    if a >= b:
        return library.label(term)
    f = np.linalg.norm(cond.f[k], axis=1).max() / G0
    w = np.linalg.norm(cond.w[k], axis=1).max() / DEG
    temp = cond.T[k].mean(axis=1)
    text = f"{library.label(term)} acting: |f| up to {f:.1f} g, |w| up to {w:.0f} deg/s"
    if np.isfinite(temp).all():
        text += f", T {temp.min():.1f}-{temp.max():.1f} degC"
    return text


def term_z(diag, term):
    """How detectable `term` is on this flight: its Wald z (sqrt of the statistic) fitted
    alone on all rows; NaN when it is not among the candidates."""
    labels = [library.label(t) for t in diag.design.terms]
    if library.label(term) not in labels:
        return float("nan")
    j = labels.index(library.label(term))
    res = _test(diag.fitter, [j], j)
    return math.sqrt(res["stat"])


# ---- after the fit: residual map and localized excursions -------------------------------
def _scan(design, x, alpha):
    """Localized excursions of the residual x: per channel, the mean over SCAN_WINDOW_S
    windows started every second against its local baseline (the windows starting 4 and 5 s
    before and after, so a slow wander cancels and an excursion of a few seconds does not
    hide in its own baseline); robust z across the windows (MAD), Bonferroni over windows x
    channels with Student-t tails of SCAN_DOF degrees of freedom. Where the bins' white
    variance varies (`design.shape`) each window's step is first divided by its own standard
    deviation under that shape, so the MAD compares like with like (a vehicle model's yaw
    rate at 2 m/s errs ten times more than at 20 m/s: departures from stops had stood out at
    z 10-25 on null drives). Returns spans [{"t0", "t1", "channel", "z"}] (overlapping
    windows merged)."""
    t = design.t
    sec = outputs.block_index(t, 1.0)
    n = sec.max() + 1
    counts = np.bincount(sec, minlength=n).astype(float)
    length = int(round(SCAN_WINDOW_S))
    kernel = np.ones(length)
    win_counts = np.convolve(counts, kernel, "valid")
    full = win_counts >= 0.5 * np.median(win_counts)
    nwin = len(win_counts)
    z_limit = stats.t.isf(alpha / (2 * nwin * 6), SCAN_DOF)
    spans = []
    def around(w):                  # (4, nwin): the baseline windows of each window
        pad = np.concatenate([np.full(5, np.nan), w, np.full(5, np.nan)])
        return np.stack([pad[5 + d:5 + d + nwin] for d in (-5, -4, 4, 5)])
    for ch in range(6):
        sums = np.convolve(np.bincount(sec, x[:, ch], minlength=n), kernel, "valid")
        means = np.where(full, sums / np.maximum(win_counts, 1), np.nan)
        base_windows = around(means)
        count = np.isfinite(base_windows).sum(axis=0)
        base = np.nansum(base_windows, axis=0) / np.maximum(count, 1)
        step = np.where(count >= 2, means - base, np.nan)
        if design.shape is not None:            # each step over its own sd (the shape's)
            var = np.convolve(np.bincount(sec, design.shape[:, ch], minlength=n), kernel,
                              "valid") / np.maximum(win_counts, 1) ** 2
            var = np.where(full, var, np.nan)
            # a window without samples: NaN, left out below
            with np.errstate(invalid="ignore", divide="ignore"):
                step = step / np.sqrt(var + np.nansum(around(var), axis=0) /
                                      np.maximum(count, 1) ** 2)
        good = np.isfinite(step)
        if good.sum() < 10:
            continue
        centre = np.median(step[good])
        spread = 1.4826 * np.median(np.abs(step[good] - centre))
        if spread == 0:
            continue
        z = np.where(good, (step - centre) / spread, 0.0)
        # an excursion also shows, halved and reversed, where it sits in a baseline (4-6 s
        # away): keep only windows that are the largest within that reach
        peak = np.abs(z) >= _running_max(np.abs(z), 6)
        for w_id in np.flatnonzero((np.abs(z) > z_limit) & peak):
            t0 = t[0] + w_id
            if spans and spans[-1]["channel"] == ch and spans[-1]["t1"] >= t0 - 1e-9:
                spans[-1]["t1"] = t0 + SCAN_WINDOW_S
                spans[-1]["z"] = max(spans[-1]["z"], float(z[w_id]), key=abs)
            else:
                spans.append({"t0": float(t0), "t1": float(t0 + SCAN_WINDOW_S), "channel": ch,
                              "z": float(z[w_id])})
    for s in spans:
        s["channel"] = f"{CHANNELS[s['channel']][0]}.{CHANNELS[s['channel']][1]}"
    return spans


def _running_max(x, reach):
    """max(x[i - reach .. i + reach]) for every i."""
    pad = np.concatenate([np.zeros(reach), x, np.zeros(reach)])
    return np.max(np.stack([pad[k:k + len(x)] for k in range(2 * reach + 1)]), axis=0)


CONDITIONS = ("quiet", "|f| > 2 g", "|w| > 60 deg/s", "|dw/dt| > 300 deg/s^2",
              "|dT/dt| > 0.5 degC/min")


def _condition_masks(design, cond, m, usable):
    """Bin masks of the flight conditions of the residual map."""
    mean, ok = Binning(m, usable), design.kept
    f = mean(np.linalg.norm(cond.f, axis=1)[:, None])[ok, 0] / G0
    w = mean(np.linalg.norm(cond.w, axis=1)[:, None])[ok, 0] / DEG
    wd = mean(np.linalg.norm(cond.w_dot, axis=1)[:, None])[ok, 0] / DEG
    temperature = mean(cond.T.mean(axis=1)[:, None])[ok]     # slope on the bins
    dT = (np.abs(derivative(design.t, temperature, 30.0)[:, 0] * 60)
          if np.isfinite(temperature).all() else np.zeros(ok.sum()))   # none recorded
    masks = {"|f| > 2 g": f > 2, "|w| > 60 deg/s": w > 60, "|dw/dt| > 300 deg/s^2": wd > 300,
             "|dT/dt| > 0.5 degC/min": dT > 0.5}
    # quiet: no manoeuvre (a warm-up's temperature change alone does not make a bin busy,
    # else a flight that warms throughout would have no quiet reference at all)
    masks["quiet"] = ~np.any([masks[k] for k in CONDITIONS[1:4]], axis=0)
    return {k: masks[k] for k in CONDITIONS}


def _map(design, x, conds, seconds=MAP_SECONDS):
    """(conditions, 6): rms of the cleaned residual x averaged over `seconds` (so systematic
    terms stand out of the white noise) in each condition (a majority of its bins) over the
    same in quiet flight; NaN where a condition has fewer than 10 such averages."""
    t = design.t
    sec = outputs.block_index(t, seconds)
    n = sec.max() + 1
    count = np.maximum(np.bincount(sec, minlength=n), 1)
    means = np.column_stack([np.bincount(sec, x[:, c], minlength=n) / count for c in range(6)])
    full = np.bincount(sec, minlength=n) >= 0.5 * seconds / design.bin_s
    share = {k: np.bincount(sec, m.astype(float), minlength=n) / count for k, m in conds.items()}
    quiet = full & (share["quiet"] > 0.5)
    quiet = quiet if quiet.sum() >= 10 else full
    ref = np.sqrt(np.mean(means[quiet] ** 2, axis=0))
    out = np.full((len(conds), 6), np.nan)
    for r, key in enumerate(conds):
        mask = full & (share[key] > 0.5)
        if mask.sum() >= 10:
            out[r] = np.sqrt(np.mean(means[mask] ** 2, axis=0)) / ref
    return out

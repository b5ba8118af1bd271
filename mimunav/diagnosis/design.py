"""The sensor level's design: the residual of the recorded MIMU against the reference's
prediction (accel m/s^2, gyro rad/s, MIMU sensor axes), its bin means, the reference's inputs
and every candidate's columns on the same bins, the priors of the reference's and the
calibration's own linear errors (18 parameters: each triad's scale and misalignment), and a
term's contribution to each channel.
"""
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy import linalg

from ..lab.calibrate import standard_errors
from ..compensation.effects import AXES
from . import library, wander
from .spill import ScratchMatrix


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
    columns: list               # per candidate: {channel: (nb, k)} (`TermColumns`)
    k: list                     # per candidate: parameter count
    terms: list                 # the candidates
    kept: np.ndarray            # usable bins of the raw binning
    prior: np.ndarray           # (18, 18) reference error covariance (`Accuracy.prior`)
    along: list                 # per candidate: (18, k) map to gamma if linear, else None
    allowance: list = field(default_factory=list)   # per candidate: (k, k) the stated
                                # covariance of its coefficient that is no physics the model
                                # lacks: the calibration's (`model_allowance`), the
                                # reference's through the lever-arm transfer (`transfer_allowance`)
    allowance_of: list = field(default_factory=list)    # per candidate: whose
                                # ("calibration", "reference"; None: it has none)
    nuisance: dict = field(default_factory=dict)    # {candidate: prior variance} fitted
                                # beside every fit's candidates, never one itself: the
                                # reference's clock (`add_clock_nuisance`)
    levels: np.ndarray = field(default_factory=lambda: wander.LAMBDA_GRID)   # wander levels
                                # the fits may choose from
    wander_steps: np.ndarray | None = None  # (6,) each channel's largest wander step
                                # variance per bin, SI^2 (`diagnose`; None: no cap)
    bin_s: float = FAST_BIN_S   # the bins' length, s
    bins_why: str = ""          # why they are longer than FAST_BIN_S (`vibration_bin_s`)
    bins_doubt: str = ""        # why even the longest leave the diagnosis inconclusive
    shape: np.ndarray | None = None     # (nb, 6) each bin's white variance over its channel's
                                # (`diagnose`'s noise_shape; None: constant)
    scan_shape: np.ndarray | None = None    # the same as the excursion scan judges it (None:
                                # `shape`'s)
    reference: object = None    # the reference's `sensors.accuracy.Accuracy` (`_reference_may_carry`)
    arm_given: bool = True      # a lever arm given between the MIMU and the reference IMU
                                # (`library.physical_limit`: else one vehicle's)
    calibrated: bool = False    # the MIMU compensated by a calibration of the unit (not
                                # a recording's outputs taken as they are): `physical_limit`
    channel_columns: list = field(default_factory=list)  # per channel c: ((nb, 4 + k)
                                # [residual, reference inputs, the candidates' columns on c,
                                # a column that repeats another held once], {candidate: its
                                # column indices}) - what every `Fitter` filters, an
                                # array or, for a flight that streams, a
                                # `spill.ScratchMatrix`; each candidate's `columns` read them
    shocks: list = field(default_factory=list)  # spans of the samples left out where the
                                # lever-arm transfer misses a shock (`reference.transfer_shocks`)
    clips_counted: list = field(default_factory=list)  # spans of the samples left out
                                # where the IMU counted clips of its own (`outputs.counted_clips`)
    gaps: list = field(default_factory=list)    # spans of the samples left out beside a gap
                                # of either IMU's stamps (`reference.across_gaps`)
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
    def detrend_basis(self):
        """The piecewise-linear bias `detrended` removes: hat functions with knots every
        DETREND_KNOT_S (those that see less than half a bin's weight dropped), held as each
        bin's two hats (left index (nb,), weights (nb, 2); -1 for a dropped hat), the banded
        Cholesky factor of their Gram B'B, tridiagonal (or where that is singular the Gram
        itself, dense, which `detrend` pseudo-inverts) and whether it is the factor: memory
        linear in the flight's length (a dense basis of a 2-hour flight's 720,000 bins and
        720 knots is 4 GB)."""
        knots = np.arange(self.t[0], self.t[-1] + DETREND_KNOT_S, DETREND_KNOT_S)
        left = np.clip(np.searchsorted(knots, self.t, "right") - 1, 0, len(knots) - 2) \
            if len(knots) > 1 else np.zeros(len(self.t), int)
        u = (self.t - knots[left]) / DETREND_KNOT_S
        weights = np.column_stack([1 - u, u]) if len(knots) > 1 else np.ones((len(self.t), 1))
        index = np.column_stack([left, left + 1])[:, :weights.shape[1]]
        kept = np.bincount(index.ravel(), weights.ravel(), len(knots)) > 0.5
        slot = np.cumsum(kept) - 1                  # a kept hat's column
        index = np.where(kept[index], slot[index], -1)
        weights = np.where(index >= 0, weights, 0.0)
        k = int(kept.sum())
        gram = np.zeros((2, k))                     # upper band: (0, j) B_j-1'B_j, (1, j) B_j'B_j
        for c in range(index.shape[1]):
            on = index[:, c] >= 0
            gram[1] += np.bincount(index[on, c], weights[on, c] ** 2, k)
        if index.shape[1] == 2:
            both = (index >= 0).all(axis=1)
            gram[0] += np.bincount(index[both, 1], weights[both, 0] * weights[both, 1], k)
        try:
            return index, weights, linalg.cholesky_banded(gram), True
        except np.linalg.LinAlgError:   # hats that see the same few bins across a gap
            return index, weights, np.diag(gram[1]) + np.diag(gram[0, 1:], 1) \
                + np.diag(gram[0, 1:], -1), False

    def detrend(self, x):
        """(nb, k) x less its least-squares projection on `detrend_basis` (B (B'B)^+ B' x)."""
        index, weights, factor, banded = self.detrend_basis
        k = factor.shape[1]
        projected = np.column_stack([
            sum(np.bincount(index[on, c], weights[on, c] * x[on, j], k)
                for c in range(index.shape[1]) for on in [index[:, c] >= 0])
            for j in range(x.shape[1])])
        coef = linalg.cho_solve_banded((factor, False), projected) if banded \
            else np.linalg.lstsq(factor, projected, rcond=None)[0]  # the dense Gram
        fitted = np.zeros_like(x)
        for c in range(index.shape[1]):
            on = index[:, c] >= 0
            fitted[on] += weights[on, c, None] * coef[index[on, c]]
        return x - fitted


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
    shared = on_reference_stamps(t, t_reference)
    return (m, (shared[1] + 1) % m) if shared is not None else (m, 0)


# The bins' length where the reference is re-expressed on the MIMU's stamps (another clock):
# that prediction errs at vibration frequencies (a hexacopter's 1 kHz FOG at its MIMU's
# jittered host stamps: 3.5 % of its 52-208 Hz rotor lines' power), and the error sits in the
# regressors and, with the opposite sign, in the residual - errors in variables, which bias
# every linear term by its share of the regressors' variance: in 0.01 s bins the vibration
# held 3.4 times the motion's variance, and the null twin read an accel.z scale of -0.027
# (truth +0.004) and its 400 Hz twin a time skew of -1.6 ms (truth 0.05). The shortest of
# VIBRATION_BIN_S whose bin means keep at most VIBRATION_SHARE of the motion's variance (at
# that error size a bias under 1e-2 x 0.035 = 4e-4) is taken, the longest when none does.
VIBRATION_BIN_S = (FAST_BIN_S, 0.02, 0.05, 0.1, 0.2)
VIBRATION_SHARE = 0.01
WHOLE_PERIODS_S = 0.5   # s: the longest bin of whole periods of a line (`whole_periods`): its
#                         means keep motion at 1 Hz at sinc(0.5) = 0.64 of its size
MOTION_HZ = 5.0     # a vehicle's motion lies below it; above it an engine's, a rotor's, a road's


def on_reference_stamps(t, t_reference):
    """(p, phase): the reference's stamps a subset of the MIMU's stamps t (s), one in p of
    them from MIMU sample `phase` on, or None when they are not (another clock)."""
    dt = float(np.median(np.diff(t)))
    if t_reference is None or len(t_reference) < 2:
        return None
    ratio = float(np.median(np.diff(t_reference))) / dt
    p = round(ratio)
    if p < 1 or abs(ratio - p) > 1e-3:
        return None
    i = np.clip(np.searchsorted(t, t_reference), 0, len(t) - 1)   # the MIMU stamp at or
    on = np.flatnonzero(np.abs(t[i] - t_reference) < 1e-3 * dt)  # after each reference one
    return (p, int(i[on[0]])) if len(on) else None


def vibration_share(t_reference, f_reference, bin_s):
    """The variance of bin_s-long bin means of the reference's specific force (m/s^2, (N, 3))
    above MOTION_HZ - its vibration, each line through the bin mean's sinc - over its
    variance below it (the motion), from its Welch spectrum (10 s segments); 0 without
    motion or samples enough."""
    return _share(reference_spectrum(t_reference, f_reference), bin_s)


def reference_spectrum(t_reference, f_reference):
    """(frequencies Hz, the three axes' summed Welch power, 10 s segments) of a reference's
    specific force f_reference (m/s^2, (N, 3)) at t_reference (s), or None (too short)."""
    from scipy.signal import welch
    rate = 1.0 / float(np.median(np.diff(t_reference)))
    n = min(int(10 * rate), len(t_reference) // 4)
    if n < 16 or rate <= 2 * MOTION_HZ:
        return None
    f, p = welch(f_reference - f_reference.mean(axis=0), fs=rate, nperseg=n, axis=0)
    return f, p.sum(axis=1)


def _share(spectrum, bin_s):
    if spectrum is None:
        return 0.0
    f, p = spectrum
    motion = p[(f > 0) & (f <= MOTION_HZ)].sum()
    above = f > MOTION_HZ
    vibration = (p[above] * np.sinc(f[above] * bin_s) ** 2).sum()
    return float(vibration / motion) if motion > 0 else 0.0


def vibration_bin_s(t, t_reference, f_reference):
    """(bin_s, why or '', doubt or ''): FAST_BIN_S where the reference's stamps are the MIMU's
    (t s) or it does not vibrate, else the shortest of VIBRATION_BIN_S and of the whole
    periods of its strongest line (`whole_periods`) whose bin means keep at most
    VIBRATION_SHARE of the motion's variance in the reference's specific force
    (`vibration_share`, at the length `bins` makes of it; t_reference s, f_reference m/s^2
    (N, 3)); the one that keeps least when none does, and then the doubt that makes the
    diagnosis inconclusive (an 8 s cut of a light aircraft, its engine 0.2 of its motion in
    0.2 s bins, had stood 'no-missing-physics' beside scale factors of 0.2-1.4 the
    selection could not choose). The spectrum once."""
    if on_reference_stamps(t, t_reference) is not None or f_reference is None:
        return FAST_BIN_S, "", ""
    spectrum = reference_spectrum(t_reference, f_reference)
    dt = float(np.median(np.diff(t)))
    candidates = sorted(set(VIBRATION_BIN_S) | set(whole_periods(spectrum)))
    shares = {b: _share(spectrum, bins(t, t_reference, b)[0] * dt) for b in candidates}
    share = shares[FAST_BIN_S]
    if share <= VIBRATION_SHARE:
        return FAST_BIN_S, "", ""
    chosen = next((b for b in candidates if shares[b] <= VIBRATION_SHARE),
                  min(candidates, key=shares.get))
    left = shares[chosen]
    why = (f"bins of {chosen:.3g} s, not {FAST_BIN_S:g} s: the reference, re-expressed on the "
           f"MIMU's stamps (another clock), moves above {MOTION_HZ:g} Hz (a vibration, or "
           f"motion as fast as a foot's strides) with {share:.2g} times its slower motion's "
           f"variance in {FAST_BIN_S:g} s bins, {left:.2g} in these: its re-expression's "
           "error there would bias every linear term")
    doubt = "" if left <= VIBRATION_SHARE else (
        f"the reference's vibration keeps {left:.2g} of its motion's variance even in "
        f"{chosen:.3g} s bins (at most {VIBRATION_SHARE:g}): its re-expression on the MIMU's "
        "stamps (another clock) may bias every linear term - the recording's motion is too "
        "small beside its vibration")
    return chosen, why, doubt


def whole_periods(spectrum):
    """(s) whole numbers of periods, up to WHOLE_PERIODS_S, of the strongest line above
    MOTION_HZ in `spectrum` (`reference_spectrum`; its frequency refined by a parabola through the
    peak and its neighbours): a bin that long holds whole cycles of the line and of its
    harmonics - a rotor's or an engine's lines - and its mean cancels them (a helicopter's
    6.6 Hz once-per-rev kept 0.57 of its motion's variance in 0.2 s bins, 1.3 cycles, and
    every diagnosis of it was inconclusive); [] without such a line."""
    if spectrum is None:
        return []
    f, p = spectrum
    above = np.flatnonzero(f > MOTION_HZ)
    if len(above) < 3:
        return []
    k = int(above[np.argmax(p[above])])
    if k + 1 >= len(f) or k == 0:
        return []
    a, b, c = p[k - 1], p[k], p[k + 1]
    den = a - 2 * b + c
    line = f[k] + (0.5 * (a - c) / den if den < 0 else 0.0) * (f[1] - f[0])
    return [n / line for n in range(1, int(WHOLE_PERIODS_S * line) + 1)]


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
def make_design(binned, terms, prior, cal, transfer=None):
    """The design of the bins `binned` (`samples.Bins`, of `terms`: the candidates, each
    temperature term with its reference): the usable bins kept, candidates the flight cannot
    drive (no variation) dropped and those the reference inputs span marked. `transfer`:
    (d (3,) m, P (9, 9)) the lever arm from the reference to the MIMU in the MIMU's axes and
    the covariance of the reference's gyro error matrix there (`transfer_allowance`), or
    None. The bins' channel matrices become the design's (rows and columns left out in
    place, `_compacted`; `binned.matrices` is emptied as they are taken)."""
    ok = np.isfinite(binned.residual).all(axis=1)
    design = Design(binned.t[ok], binned.residual[ok], binned.inputs[ok], [], [], [], ok,
                    prior, [])
    matrices = [binned.matrices.pop(0) for _ in range(6)]
    kept = []
    for j, term in enumerate(terms):
        cols = {c: matrices[c][:, slot[j][0]:sum(slot[j])][ok]
                for c, slot in enumerate(binned.slots) if j in slot}
        if _drivable(term, cols):
            kept.append(j)
            design.terms.append(term)
            design.k.append(next(iter(cols.values())).shape[1])
            design.along.append(_along(design, cols))
            design.allowance.append(np.atleast_2d(model_allowance(cal, term)))
            design.allowance_of.append("calibration" if design.allowance[-1].any() else None)
    _hand_over(design, matrices, binned, kept, ok)
    if transfer is not None and np.any(transfer[0]):
        rates = (binned.inputs[ok, 3:], binned.w_dot[ok])
        for j, term in enumerate(design.terms):
            if term["effect"] in TRANSFERRED:
                design.allowance[j] = transfer_allowance(design.columns[j], *rates, *transfer)
                design.allowance_of[j] = "reference"
    return design


def _drivable(term, cols):
    """Whether the flight drives the candidate's columns {channel: (nb, k)}: finite (a log
    without temperatures has none for the temperature terms), varying, and for a vibration
    rectification, vibrating."""
    if not cols or not all(x.size and np.isfinite(x).all() for x in cols.values()):
        return False                        # no bins (none usable), or not finite
    if term["effect"] == "vibration_rectification" and \
            not library.vibrating(next(iter(cols.values()))):
        return False                        # a flight without airframe vibration
    scale = max(np.abs(x).max() for x in cols.values())
    spread = max(np.ptp(x, axis=0).max() for x in cols.values())
    return spread > 1e-9 * max(scale, 1e-300)


def _hand_over(design, matrices, binned, kept, ok):
    """The channel matrices into `design`: their usable bins `ok` and the columns of the
    residual, the reference inputs and the candidates `kept` (indices of `binned`'s terms;
    twins share theirs, `samples.Bins`), moved in place (`_compacted`); each kept
    candidate's `columns` read from them (`TermColumns`); matrices in scratch files
    (`spill.ScratchMatrix`) select theirs without moving them."""
    where_of = [{} for _ in kept]
    for c in range(6):
        slot = binned.slots[c]
        used = sorted(set(range(4)).union(*(range(slot[j][0], sum(slot[j]))
                                             for j in kept if j in slot)))
        x = matrices[c].selected(ok, used) if isinstance(matrices[c], ScratchMatrix) \
            else _compacted(matrices[c], ok, used)
        matrices[c] = None
        where = {col: i for i, col in enumerate(used)}
        own = {}
        for new, j in enumerate(kept):
            if j in slot:
                start, k = where[slot[j][0]], slot[j][1]
                own[new] = np.arange(start, start + k)
                where_of[new][c] = (start, k)
        design.channel_columns.append((x, own))
    design.columns = [TermColumns(design.channel_columns, spans) for spans in where_of]


class TermColumns(Mapping):
    """A candidate's columns {channel c: (nb, k)}, read from the design's channel matrices
    when asked for (a view of an array; from scratch files, `spill.ScratchMatrix`, a copy):
    `spans` {c: (its first column in channel c's matrix, k)}."""

    def __init__(self, channel_columns, spans):
        self._matrices, self._spans = channel_columns, spans

    def __getitem__(self, c):
        first, k = self._spans[c]
        return self._matrices[c][0][:, first:first + k]

    def __iter__(self):
        return iter(self._spans)

    def __len__(self):
        return len(self._spans)


COMPACTING_ROWS = 1 << 15       # rows moved at a time by `_compacted`


def _compacted(x, rows, cols):
    """x's rows where `rows` (bool) and columns `cols` (ascending), as a view of x's top-left
    corner: moved there in place, COMPACTING_ROWS at a time, with no copy of x beside it (a
    2-hour flight's channel matrix is ~0.1 GB); x itself when nothing is left out."""
    if rows.all() and cols == list(range(x.shape[1])):
        return x
    done = 0
    for a in range(0, len(x), COMPACTING_ROWS):
        piece = x[a:a + COMPACTING_ROWS][rows[a:a + COMPACTING_ROWS]][:, cols]   # a copy
        x[done:done + len(piece), :len(cols)] = piece       # rows up to a: read before
        done += len(piece)
    return x[:done, :len(cols)]


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


def add_clock_nuisance(design, clock_se):
    """Fit the reference IMU's clock, which the import measured to clock_se (s, 1 sigma),
    beside every candidate: time_skew imu.all (a clock off by d moves every channel's
    residual by d times its predicted output's rate of change) becomes a nuisance of every
    fit under the prior N(0, clock_se^2) and is no candidate. The clock is one for the six
    channels, so the others pin it where one channel's term looks like it: a gyro's
    g-sensitivity on a roll oscillation is such a shift on its own axis (f_y ~ g phi,
    dw_x/dt ~ -Omega^2 phi) - a ship's hidden 1.78e-4 (rad/s)/(m/s^2), against a clock
    measured to 1.8 ms, had been set aside at 3.9e-5 +- 1.1e-4 with the clock's effect on
    that one channel added as an allowance; with the clock fitted it is found, 1.74e-4
    [1.62e-4, 1.86e-4], and its null twin names no g-sensitivity and no time skew."""
    names = [library.label(t) for t in design.terms]
    if "time_skew imu.all" in names:
        design.nuisance = {names.index("time_skew imu.all"): clock_se ** 2}


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


def white_per_bin(resid):
    """(k,) each column's white variance per bin of a residual (nb, k): half the variance of
    its differences, which a slow wander or trend hardly moves; NaN rows left out."""
    return np.nanvar(np.diff(resid, axis=0), axis=0) / 2


def detrended(design, resid):
    """Residual with a piecewise-linear bias (knots every DETREND_KNOT_S) removed per
    channel: for display, the rms figures and the scan."""
    return design.detrend(resid)

"""MIMU compensation: the calibration file (contract `mimunav-calibration/1`) and the seed
paper's equations, raw volts -> physics, and their exact inverse, physics -> raw volts.

Seed S1 (Dai et al. 2011) eqs. 1-4, per axis i, powers element-wise:
    V_a = U_a - (ct[i,0] + ct[i,1] T + ct[i,2] T^2)          eq. 2, T thermistor degC
    V_w = U_w - (cw[i,0] + cw[i,1] f + cw[i,2] f^2)          eq. 4, f resonance freq. Hz
    a   = A0 + A1 @ V_a + A2 * V_a^2 + A3 * V_a^3              eq. 1, m/s^2
    w   = W0 + W1 @ V_w + W2 * V_w^2 + W3 * V_w^3 + C @ a      eq. 3, rad/s
applied in the paper's order (section 3.2): wild-value filtering, temperature, accelerometer
triad, gyro triad with the compensated acceleration.

Models: `entire-63` (all terms), `linear` (A0, A1, W0, W1: the "traditional" compensation;
absent keys are zero), `cold-start` (seed S3, per axis, on top of the linear triads):
    E = E(T) / (a + b T) + (c + d T) + e dT
with E(T) the linear-triad output with its own scale divided out, T the axis's temperature
reading (accelerometer: degC; gyro: resonance frequency, Hz), dT = T(t) - T(t - window_s)
(T(t0) before the window is full). Keys: "accel"/"gyro" {"a","b","c","d","e": [3]},
"window_s".
Any model name + "+found" (e.g. `entire-63+found`, written by `mimunav diagnose`) adds the
key "found": a list of terms of the diagnosis effect vocabulary (`mimunav.effects`, log
contract section 3: effect, sensor, axis, input_axis, coefficient or vector, and order,
window_s, reference where the regressor needs them), each removed from the output after
eqs. 1-4 (time_skew by shifting the samples back).
"""
import functools
import itertools
import json
import math
from dataclasses import dataclass, field

import numpy as np

from . import effects
from .effects import Conditions, temperature_change
from .effects import apply as apply_effects
from .files import check_format, read_json, write_atomic
from .errors import InputError

FORMAT = "mimunav-calibration/1"
MODELS = ("entire-63", "linear", "cold-start")
FOUND_SUFFIX = "+found"     # a model plus the terms a diagnosis found ("found": [terms])
MAX_CONDITION = 100.0   # of A1 and W1: a triad's scale factors alike (one part, one range)
# and its axes within a few degrees of orthogonal make it 1.0-1.1 (the six foreign flights'
# files 1.01-1.05, the lab fits 1.03-1.04); 100 is a scale factor 1 % of the others' or two
# axes 1.1 deg apart - no triad, a typing error (a zeroed diagonal: 3674, compensated
# without a word into a confident 'saturation' and a g-sensitivity 3.5 times the truth)
_TRIAD_KEYS = {"accel": ("A0", "A1", "A2", "A3", "ct"), "gyro": ("W0", "W1", "W2", "W3", "C", "cw")}
_SHAPES = {"A0": (3,), "A1": (3, 3), "A2": (3,), "A3": (3,), "ct": (3, 3),
           "W0": (3,), "W1": (3, 3), "W2": (3,), "W3": (3,), "C": (3, 3), "cw": (3, 3)}
_COLD_KEYS = ("a", "b", "c", "d", "e")

# Sample flags (bit mask) set by `compensate`
REPLACED = 1       # a wild (outlier) or non-finite raw value replaced by its neighbours' median
SATURATED = 2      # compensated output at or beyond the unit's range on some axis, or a raw
                   # output clipped (stuck at its extreme, `clipped`)
CLIP_RUN = 5       # identical consecutive samples at a channel's extreme: clipped
UNUSABLE = 4       # could not be repaired (non-finite across the whole filter window)


class CalibrationError(InputError):
    """A calibration file that does not follow the contract, or cannot be applied."""


@dataclass
class Calibration:
    """Coefficients of one MIMU compensation (SI; see the module doc for the equations).

    A0 m/s^2 (3,); A1 (m/s^2)/V (3, 3); A2, A3 diagonals (m/s^2)/V^2, /V^3 (3,);
    ct V, V/degC, V/degC^2 (3, 3); W0 rad/s; W1 (rad/s)/V; W2, W3 diagonals;
    C (rad/s)/(m/s^2) (3, 3); cw V, V/Hz, V/Hz^2 (3, 3).
    """
    model: str = "entire-63"
    unit: str = ""
    procedure: str = ""
    A0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    A1: np.ndarray = field(default_factory=lambda: np.eye(3))
    A2: np.ndarray = field(default_factory=lambda: np.zeros(3))
    A3: np.ndarray = field(default_factory=lambda: np.zeros(3))
    ct: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    W0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    W1: np.ndarray = field(default_factory=lambda: np.eye(3))
    W2: np.ndarray = field(default_factory=lambda: np.zeros(3))
    W3: np.ndarray = field(default_factory=lambda: np.zeros(3))
    C: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    cw: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    cold_start: dict = field(default_factory=dict)    # {"accel": {a..e}, "gyro": {..}, "window_s"}
    covariance: dict = field(default_factory=dict)
    found: list = field(default_factory=list)         # diagnosis terms (model "<base>+found")
    extra: dict = field(default_factory=dict)         # keys of the file this version ignores

    @property
    def base_model(self):
        return self.model[:-len(FOUND_SUFFIX)] if self.model.endswith(FOUND_SUFFIX) else self.model

    @classmethod
    def identity(cls, procedure="identity: outputs already in SI units (/mimu/imu)"):
        """The linear model that leaves outputs as they are: the base of the found terms of
        a unit recorded already compensated (an imported recording's /mimu/imu)."""
        return cls(model="linear", procedure=procedure)

    @property
    def is_identity(self):
        """True when the base model changes nothing (eqs. 1-4 with A1 = W1 = I, the rest 0)."""
        zero = ("A0", "A2", "A3", "ct", "W0", "W2", "W3", "C", "cw")
        return (self.base_model in ("linear", "entire-63") and not self.cold_start
                and all(not np.any(getattr(self, k)) for k in zero)
                and all(np.array_equal(getattr(self, k), np.eye(3)) for k in ("A1", "W1")))

    # ---- file contract -------------------------------------------------------------
    @classmethod
    def from_dict(cls, doc, source="calibration"):
        """Validate a parsed `mimunav-calibration/1` document and build the object."""
        def fail(msg):
            raise CalibrationError(f"{source}: {msg}")
        check_format(doc, FORMAT, source, CalibrationError)
        model = doc.get("model")
        base = (model[:-len(FOUND_SUFFIX)] if isinstance(model, str)
                and model.endswith(FOUND_SUFFIX) else model)
        if base == "rotation-cubic":
            fail("model 'rotation-cubic' is the gyros' scale factor from a rotation run (seed "
                 "S4, `mimunav.rotation_calibration`): it has no accelerometer terms and "
                 "cannot compensate a log; compare it with `mimunav calibration compare`")
        if base not in MODELS:
            fail(f"model {model!r} is not one of {', '.join(MODELS)} (optionally with "
                 f"{FOUND_SUFFIX!r})")
        cal = cls(model=model, unit=str(doc.get("unit", "")),
                  procedure=str(doc.get("procedure", "")),
                  covariance=doc.get("covariance", {}) or {})
        for triad, keys in _TRIAD_KEYS.items():
            block = doc.get(triad, {})
            if not isinstance(block, dict):
                fail(f'"{triad}" must be an object')
            allowed = set(keys) | (set(_COLD_KEYS) if base == "cold-start" else set())
            unknown = set(block) - allowed
            if unknown:
                fail(f'"{triad}" has keys {sorted(unknown)} that model {base!r} does not use')
            if base == "linear":
                extra_terms = [k for k in block if k not in ("A0", "A1", "W0", "W1")]
                if extra_terms:
                    fail(f'model "linear" takes only A0, A1, W0, W1; {triad} has {extra_terms}')
            for key in keys:
                if key in block:
                    setattr(cal, key, _array(block[key], _SHAPES[key], f"{source}: {triad}.{key}"))
                elif key in ("A1", "W1"):
                    fail(f'{triad}.{key} is required (the linear scale/misalignment matrix)')
            if base == "cold-start":
                missing = [k for k in _COLD_KEYS if k not in block]
                if missing:
                    fail(f'cold-start model lacks {triad}.{missing}')
                cal.cold_start[triad] = {k: _array(block[k], (3,), f"{source}: {triad}.{k}")
                                         for k in _COLD_KEYS}
        if base == "cold-start":
            window = doc.get("window_s")
            if not isinstance(window, (int, float)) or not window > 0:
                fail("cold-start model needs window_s > 0 (s), the dT window")
            cal.cold_start["window_s"] = float(window)
            for triad in ("accel", "gyro"):
                scale = cal.cold_start[triad]["a"]
                if np.any(scale == 0):
                    fail(f"cold-start {triad}.a has a zero (scale factor a + b T must not vanish)")
        for name in ("A1", "W1"):
            m = getattr(cal, name)
            if np.linalg.cond(m) > MAX_CONDITION:
                fail(f"{name} is singular or nearly so (condition number "
                     f"{np.linalg.cond(m):.3g}, above {MAX_CONDITION:g}; a calibrated triad's "
                     "is near 1): a scale factor of zero or near it, or two axes nearly "
                     "parallel - the compensated triad would be blind along an axis and the "
                     "raw outputs could not be inverted")
        if model != base:
            found = doc.get("found")
            if not isinstance(found, list) or not found:
                fail(f'model {model!r} needs a non-empty "found" list of terms')
            for k, term in enumerate(found):
                try:
                    effects.check_term(term)
                except (ValueError, TypeError, KeyError) as exc:
                    fail(f"found[{k}]: {exc}")
            cal.found = [dict(term) for term in found]
        known = {"format", "model", "unit", "procedure", "accel", "gyro", "covariance", "window_s",
                 "found"}
        cal.extra = {k: v for k, v in doc.items() if k not in known}
        return cal

    @classmethod
    def load(cls, path):
        return cls.from_dict(read_json(path, "calibration file", CalibrationError),
                             source=str(path))

    def as_dict(self):
        doc = {"format": FORMAT, "model": self.model, "unit": self.unit,
               "procedure": self.procedure}
        for triad, keys in _TRIAD_KEYS.items():
            keys = [k for k in keys if self.base_model != "linear" or k in ("A0", "A1", "W0", "W1")]
            doc[triad] = {k: getattr(self, k).tolist() for k in keys}
            if self.base_model == "cold-start":
                doc[triad].update({k: v.tolist() for k, v in self.cold_start[triad].items()})
        if self.base_model == "cold-start":
            doc["window_s"] = self.cold_start["window_s"]
        if self.found:
            doc["found"] = self.found
        if self.covariance:
            doc["covariance"] = self.covariance
        doc.update(self.extra)
        return doc

    def with_voltage_offset(self, d_accel, d_gyro):
        """The same compensation written with temperature polynomials lowered by d (V, per
        axis), so V' = V + d: eqs. 1/3 re-expanded about the shifted voltage, exactly
        (A0' = A0 - A1 d + A2 d^2 - A3 d^3, A1' = A1 + diag(3 A3 d^2 - 2 A2 d),
        A2' = A2 - 3 A3 d). A constant offset of eq. 2 (4) is not identifiable apart from
        the triad's terms; this moves a calibration to another gauge."""
        out = Calibration.from_dict(self.as_dict())
        for p0, p1, p2, p3, c, d in (("A0", "A1", "A2", "A3", "ct", d_accel),
                                     ("W0", "W1", "W2", "W3", "cw", d_gyro)):
            d = np.asarray(d, dtype=float)
            a0, a1, a2, a3 = (getattr(self, k) for k in (p0, p1, p2, p3))
            setattr(out, p0, a0 - a1 @ d + a2 * d**2 - a3 * d**3)
            setattr(out, p1, a1 + np.diag(3 * a3 * d**2 - 2 * a2 * d))
            setattr(out, p2, a2 - 3 * a3 * d)
            shifted = getattr(self, c).copy()
            shifted[:, 0] -= d
            setattr(out, c, shifted)
        return out

    def save(self, path, force=False):
        """Write the file atomically (temporary file + rename); refuses to replace an
        existing file unless force=True."""
        write_atomic(path, json.dumps(self.as_dict(), indent=1) + "\n", force=force)


def _array(value, shape, where):
    try:
        arr = np.asarray(value)
        if arr.dtype.kind not in "iuf":         # JSON numbers only: "0.1" is text, not 0.1
            raise TypeError
        arr = arr.astype(float)
    except (TypeError, ValueError):
        raise CalibrationError(f"{where} is not numeric: {value!r}") from None
    if arr.shape != shape:
        raise CalibrationError(f"{where} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{where} has non-finite values: {arr.tolist()}")
    return arr


# ---- equations ---------------------------------------------------------------------------
def poly2(c, x):
    """Per-axis quadratic c[i,0] + c[i,1] x_i + c[i,2] x_i^2 for x (N, 3) -> (N, 3)."""
    return c[:, 0] + x * (c[:, 1] + x * c[:, 2])


def triad(p0, p1, p2, p3, v):
    """p0 + p1 @ v + p2 * v^2 + p3 * v^3 for v (N, 3): eqs. 1 and 3 without C."""
    return p0 + v @ p1.T + v * v * (p2 + p3 * v)


def compensate(cal, accel_volts, gyro_volts, accel_temperature, gyro_frequency,
               range_accel=np.inf, range_gyro=np.inf, filter_outliers=True, t=None,
               record=None):
    """Raw MIMU samples -> specific force f (m/s^2) and rate w (rad/s), sensor axes, and a
    flag per sample (REPLACED | SATURATED | UNUSABLE bits).

    Inputs (N, 3): accel_volts U_a and gyro_volts U_w (V), accel_temperature T (degC),
    gyro_frequency f (Hz). range_*: the unit's range (m/s^2, rad/s); outputs whose magnitude
    on any axis reaches it are flagged SATURATED, and so are raw outputs stuck at their
    extreme (`clipped`: an ADC or amplifier limit below the declared range). t: sample
    times, s (N,), needed by the
    cold-start model's dT window. record: `RecordStats` of the whole record when these
    samples are a block of it (`compensate_log`): the wild-value filter's noise level and
    the clipping extremes are then the record's, as if it were compensated whole.
    """
    if cal is None:
        raise CalibrationError("the MIMU is recorded raw (/mimu/raw: volts and frequencies); "
                               "its calibration is needed to compensate it (--cal CAL.json)")
    chans = [np.ascontiguousarray(x, dtype=float) for x in
             (accel_volts, gyro_volts, accel_temperature, gyro_frequency)]
    n = len(chans[0])
    for name, x in zip(("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency"),
                       chans):
        if x.shape != (n, 3):
            raise InputError(f"{name} must have shape (N, 3) = ({n}, 3), got {x.shape}")
    flags = np.zeros(n, dtype=np.uint8)
    sigmas, extremes = (record.sigma, record.extremes) if record else ([None] * 4, [None] * 2)
    if filter_outliers:
        chans = [wild_value_filter(x, flags, sigma=sigma) for x, sigma in zip(chans, sigmas)]
    else:
        for x in chans:
            flags[~np.isfinite(x).all(axis=1)] |= UNUSABLE
    u_a, u_w, temp, freq = chans
    flags[clipped(u_a, extremes[0]) | clipped(u_w, extremes[1])] |= SATURATED
    if (cal.base_model == "cold-start" or cal.found) and t is None:
        raise CalibrationError(f"model {cal.model!r} needs the sample times t")
    if cal.base_model == "cold-start":
        f, w = _cold_start(cal, u_a, u_w, temp, freq, np.asarray(t, dtype=float))
    else:
        v_a = u_a - poly2(cal.ct, temp)                                   # eq. 2
        v_w = u_w - poly2(cal.cw, freq)                                   # eq. 4
        f = triad(cal.A0, cal.A1, cal.A2, cal.A3, v_a)                    # eq. 1
        w = triad(cal.W0, cal.W1, cal.W2, cal.W3, v_w) + f @ cal.C.T      # eq. 3
    if cal.found:                      # terms found by a diagnosis, removed (effects.apply)
        cond = Conditions.from_outputs(np.asarray(t, float), f, w, temp, freq)
        f, w = apply_effects(cal.found, cond, sign=-1.0)
    flags[(np.abs(f) >= range_accel).any(axis=1) | (np.abs(w) >= range_gyro).any(axis=1)] \
        |= SATURATED
    return f, w, flags


def _cold_start(cal, u_a, u_w, temp, freq, t):
    """Seed S3: E = E(T)/(a + b T) + (c + d T) + e dT per axis on the linear triad output."""
    out = []
    window = cal.cold_start["window_s"]
    for triad_name, u, p1, temperature in (("accel", u_a, cal.A1, temp),
                                           ("gyro", u_w, cal.W1, freq)):
        k = cal.cold_start[triad_name]
        p0 = cal.A0 if triad_name == "accel" else cal.W0
        e_t = p0 + u @ p1.T
        d_t = temperature_change(temperature, window, t)
        out.append(e_t / (k["a"] + k["b"] * temperature) + k["c"] + k["d"] * temperature
                   + k["e"] * d_t)
    return out[0], out[1]


def clipped(x, extremes=None):
    """Samples (N,) bool where some axis of x (N, 3) sits at that axis's extreme value in a
    run of at least CLIP_RUN identical consecutive samples: an output clipped by its ADC or
    amplifier, whatever the declared range says. A live sensor's noise moves a quantized
    output every sample; a channel that never moves (ptp 0) is left alone. extremes: the
    (max, min) (2, 3) of the whole record's finite values when x is a block of it (NaN
    where a column has fewer than CLIP_RUN finite values or never moves)."""
    x = np.asarray(x, dtype=float)
    out = np.zeros(len(x), dtype=bool)
    if extremes is None:
        extremes = column_extremes(x)
    for col, top, bottom in zip(x.T, *extremes):
        if not np.isfinite(top):
            continue
        for extreme in (top, bottom):
            at = np.concatenate([[0], (col == extreme).astype(np.int8), [0]])
            edges = np.flatnonzero(np.diff(at))
            for a, b in zip(edges[::2], edges[1::2]):
                if b - a >= CLIP_RUN:
                    out[a:b] = True
    return out


def column_extremes(x):
    """(max, min) (2, 3) of each column's finite values for `clipped`; NaN where a column
    has fewer than CLIP_RUN finite values or never moves."""
    out = np.full((2, x.shape[1]), np.nan)
    for j, col in enumerate(np.asarray(x, dtype=float).T):
        finite = col[np.isfinite(col)]
        if len(finite) >= CLIP_RUN and np.ptp(finite) > 0:
            out[:, j] = finite.max(), finite.min()
    return out


def noise_sigma(sub):
    """The wild-value filter's noise standard deviation per column from a subsample of the
    record (every step-th sample, step = max(1, N // 20000)): 1.4826 MAD of the second
    difference, divided by sqrt(1.5); at least 1e-12 of the largest value; 0 for a column
    without finite values."""
    # an all-NaN channel (UNUSABLE later) gets sigma 0 without nanmedian's warning: a
    # process-wide warnings filter would also silence the threads navigating meanwhile
    with np.errstate(all="ignore"):
        d2 = np.abs(sub[1:-1] - 0.5 * (sub[:-2] + sub[2:])) if len(sub) >= 3 else np.abs(sub)
        sigma, top = np.full(sub.shape[1], np.nan), np.full(sub.shape[1], np.nan)
        some = np.isfinite(d2).any(axis=0)
        sigma[some] = 1.4826 * np.nanmedian(d2[:, some], axis=0) / math.sqrt(1.5)
        some = np.isfinite(sub).any(axis=0)
        top[some] = np.nanmax(np.abs(sub[:, some]), axis=0)
        floor = np.maximum(1e-12 * top, _step_noise(sub))
    return np.where(np.isfinite(sigma), np.maximum(sigma, floor), 0.0) + 1e-300


def _step_noise(sub):
    """Per column, the rms of the quantization noise q / sqrt(12) of a column whose values
    sit on a few levels (fewer distinct values than half its samples; q the smallest
    spacing of the distinct values), else 0: a quantized output whose noise is below its
    step has second differences that are mostly 0, and a MAD of 0 would call every step of
    it wild."""
    out = np.zeros(sub.shape[1])
    for j in range(sub.shape[1]):
        col = sub[:, j][np.isfinite(sub[:, j])]
        levels = np.unique(col)
        if 3 <= len(levels) < 0.5 * len(col):
            out[j] = float(np.min(np.diff(levels))) / math.sqrt(12.0)
    return out


def subsample_step(n):
    """The stride of the subsample `noise_sigma` reads from a record of n samples."""
    return max(1, n // 20000)


@dataclass
class RecordStats:
    """What `compensate` needs from a whole record when it sees a block of it: the
    wild-value filter's noise sigma of each raw channel (accel volts, gyro volts,
    temperature, frequency; `noise_sigma`), and the (max, min) of the filtered voltages
    (accel, gyro) for `clipped` (`column_extremes`)."""
    sigma: list
    extremes: list = None
    min_step_ns: int = 0        # the shortest sample interval of the record (margins)

    @classmethod
    def sigma_of_blocks(cls, blocks, n, names):
        """The sigmas from blocks (structured arrays holding the fields `names`) of a record
        of n samples, read once: the same numbers as on the whole record."""
        step, seen, min_step, last = subsample_step(n), 0, None, None
        subs = [[] for _ in names]
        for block in blocks:
            first = (-seen) % step
            for k, name in enumerate(names):
                subs[k].append(np.asarray(block[name], dtype=float)[first::step])
            seen += len(block)
            stamps = block["log_time"].astype(np.int64)
            steps = np.diff(stamps if last is None else np.r_[last, stamps])
            steps = steps[steps > 0]
            if len(steps):
                min_step = int(steps.min()) if min_step is None else min(min_step, int(steps.min()))
            last = int(stamps[-1])
        return cls([noise_sigma(np.concatenate(sub)) for sub in subs],
                   min_step_ns=min_step or 10**6)

    def add_extremes(self, filtered):
        """Fold the filtered voltages of one block (accel, gyro, each (N, 3)) into the
        record's extremes; `finish_extremes` turns them into `column_extremes`' form."""
        if not hasattr(self, "_top"):
            self._top, self._bottom = np.full((2, 3), -np.inf), np.full((2, 3), np.inf)
            self._count = np.zeros((2, 3), int)
        for k, x in enumerate(filtered):
            finite = np.isfinite(x)
            self._top[k] = np.maximum(self._top[k], np.where(finite, x, -np.inf).max(axis=0))
            self._bottom[k] = np.minimum(self._bottom[k], np.where(finite, x, np.inf).min(axis=0))
            self._count[k] += finite.sum(axis=0)

    def finish_extremes(self):
        moving = (self._count >= CLIP_RUN) & (self._top > self._bottom)
        self.extremes = [np.where(moving[k], np.stack([self._top[k], self._bottom[k]]), np.nan)
                         for k in range(2)]


CURVE_REACH = 5      # the wild-value filter's curvature: second differences up to 5 samples away


def wild_value_filter(x, flags, n_sigma=6.0, sigma=None):
    """Wild-value (outlier) filter, seed S1 section 3.2 step 1.

    A sample is wild when it is non-finite, or when it disagrees with both linear
    extrapolations from its neighbours, 2 x[k-1] - x[k-2] from the left and 2 x[k+1] - x[k+2]
    from the right (only the available one at the record's ends), by more than
    n_sigma * sqrt(6) noise standard deviations (the extrapolation difference of white noise
    has variance 6 sigma^2), plus twice the local curvature seen without the sample (the
    largest second difference centred 2 to CURVE_REACH samples away on either side), so a
    smooth but fast-changing signal with little noise - a manoeuvre, or an airframe vibration
    sampled a few times a period - is not mistaken for spikes. An isolated spike disagrees with both sides; a
    step or a ramp agrees with one; a spike's neighbours agree with their clean side. Wild samples are
    flagged REPLACED and replaced by linear interpolation between the nearest good samples;
    a channel with no good sample is flagged UNUSABLE.

    The noise standard deviation of each channel is robust and global: 1.4826 MAD of the
    second difference x[k] - (x[k-1] + x[k+1])/2 over the record, divided by sqrt(1.5).
    x (N, 3); returns a filtered copy; flags are updated in place. sigma: the record's
    noise sigma (`noise_sigma`) when x is a block of it."""
    x = np.ascontiguousarray(x, dtype=float)
    out = x.copy()
    if sigma is None:
        sigma = noise_sigma(x[::subsample_step(len(x))])
    wild = _find_wild(x, n_sigma * sigma * math.sqrt(6.0))
    for j in np.nonzero(wild.any(axis=0))[0]:
        good = ~wild[:, j]
        if not good.any():
            flags[:] |= UNUSABLE
            continue
        idx = np.arange(len(x))
        out[~good, j] = np.interp(idx[~good], idx[good], x[good, j])
        flags[~good] |= REPLACED
    return out


def _find_wild(x, limit):
    """The wild samples of x (N, k) as `wild_value_filter` defines them, (N, k) bool, for
    per-column limits (k,): n_sigma * sqrt(6) noise sigmas. Plain numpy, so that `compensate`
    does not pay numba's start-up (about 1 s a process): the rule is evaluated only at the
    candidates - samples whose second difference |x[k] - (x[k-1] + x[k+1]) / 2| exceeds
    limit / 2 (the tolerance is at least the limit), the record's ends, non-finite samples.
    Non-finite second differences of the curvature are left out of its maximum (NaN) or
    make it infinite (inf), and an infinite curvature leaves the tolerance at the limit."""
    n, cols = x.shape
    limit = np.broadcast_to(np.asarray(limit, dtype=float), (cols,))
    wild = ~np.isfinite(x)
    with np.errstate(invalid="ignore", over="ignore"):
        mid = np.full(x.shape, np.inf)                  # the ends are never quiet
        mid[1:-1] = np.abs(x[1:-1] - 0.5 * (x[:-2] + x[2:]))
        k, j = np.nonzero(~(mid <= 0.5 * limit) & ~wild)
        curvature = _curvature_of_all if len(k) > DENSE_CANDIDATES * x.size else _curvature_at
        curve = curvature(x, k, j)
        tol = np.where(np.isfinite(curve), limit[j] + 2.0 * curve, limit[j])

        def at(d):                                      # x[k + d, j], clipped to the record
            return x[np.clip(k + d, 0, n - 1), j]
        v = x[k, j]
        from_left = np.where(k >= 2, 2.0 * at(-1) - at(-2), np.nan)
        from_right = np.where(k <= n - 3, 2.0 * at(1) - at(2), np.nan)
        agree = (np.abs(v - from_left) <= tol) | (np.abs(v - from_right) <= tol)
        some_side = np.isfinite(from_left) | np.isfinite(from_right)
        wild[k, j] = ~(mid[k, j] <= 0.5 * tol) & some_side & ~agree
    return wild


DENSE_CANDIDATES = 1 / 16   # above this share of samples, the curvature of every sample


def _curvature_at(x, k, j):
    """Local curvature seen without x[k, j], at the candidates (k, j): the largest second
    difference centred at k-2 .. k-CURVE_REACH and k+2 .. k+CURVE_REACH - half a period of a
    vibration at a tenth of the sample rate, so a sampled vibration's curvature is seen
    whatever its phase at k - each summed from the sample nearer k outwards; 0 when none
    is finite. From the 2 CURVE_REACH + 3 samples around each candidate."""
    n, cols = x.shape
    r = CURVE_REACH + 1                                 # near[:, r] is the candidate
    near = x.ravel()[np.clip(k[:, None] + np.arange(-r, r + 1), 0, n - 1) * cols + j[:, None]]
    c = np.arange(2, CURVE_REACH + 1)
    left = np.abs(near[:, r + 1 - c] - 2.0 * near[:, r - c] + near[:, r - 1 - c])
    right = np.abs(near[:, r - 1 + c] - 2.0 * near[:, r + c] + near[:, r + 1 + c])
    left[k[:, None] < c + 1] = np.nan                   # centres outside the record
    right[k[:, None] > n - c - 2] = np.nan
    return np.fmax.reduce(np.fmax(left, right), axis=1, initial=0.0)


def _curvature_of_all(x, k, j):
    """`_curvature_at`, from the second differences of the whole record (a record where
    most samples are candidates: a vibrating one), padded with NaN beyond its ends."""
    pad = np.full((CURVE_REACH + 1, x.shape[1]), np.nan)
    inward = np.concatenate([pad, np.abs(x[2:] - 2.0 * x[1:-1] + x[:-2]), pad])
    outward = np.concatenate([pad, np.abs(x[:-2] - 2.0 * x[1:-1] + x[2:]), pad])
    # centre i sits at row i + CURVE_REACH; the window of CURVE_REACH - 1 centres starting
    # at k - CURVE_REACH (left) or k + 2 (right)
    w = CURVE_REACH - 1

    def window_max(d):
        m = d[:len(d) - w + 1]
        for i in range(1, w):
            m = np.fmax(m, d[i:len(d) - w + 1 + i])
        return m
    left = window_max(inward)[k, j]
    right = window_max(outward)[k + CURVE_REACH + 2, j]
    return np.fmax(np.fmax(left, right), 0.0)


def raw_from_physics(cal, f, w, accel_temperature, gyro_frequency, f_gyro=None):
    """Inverse of `compensate` for the triad models (entire-63, linear): the raw voltages
    U_a, U_w (V, (N, 3)) whose compensation gives specific force f (m/s^2) and rate w
    (rad/s) at the given temperature readings. Solved by Newton's method to round-off:
    the cubic terms and the C @ a coupling make the equations implicit. f_gyro: the
    specific force that drives the g-sensitivity C (default f; a simulation passes the
    true one, so the compensation's use of the measured f is a realistic residual)."""
    if cal.model not in ("entire-63", "linear"):
        raise CalibrationError(f"raw_from_physics has no inverse for model {cal.model!r}")
    f = np.ascontiguousarray(f, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    v_a = _invert_triad(cal.A0, cal.A1, cal.A2, cal.A3, f)
    f_gyro = f if f_gyro is None else np.asarray(f_gyro, dtype=float)
    v_w = _invert_triad(cal.W0, cal.W1, cal.W2, cal.W3, w - f_gyro @ cal.C.T)
    return v_a + poly2(cal.ct, accel_temperature), v_w + poly2(cal.cw, gyro_frequency)


def _invert_triad(p0, p1, p2, p3, y):
    v = np.empty_like(y)
    worst = _newton_kernel()(p0, p1, np.linalg.inv(p1), p2, p3, y, v)
    if not worst < 1e-12:
        raise CalibrationError(f"inverse of the triad model did not converge (relative "
                               f"residual {worst:.3g}): input beyond the model's monotonic range")
    return v


@functools.cache
def _newton_kernel():
    """`_newton_triad` compiled by numba on first use: only the simulation and the tests
    invert the compensation, and `compensate` need not import numba."""
    from .kernels import njit
    return njit(nogil=True)(_newton_triad)


def _newton_triad(p0, p1, p1_inv, p2, p3, y, v):
    """Solve p0 + p1 v + p2 v^2 + p3 v^3 = y per row (Newton, 3x3 steps by Cramer's rule);
    returns the worst relative residual."""
    worst = 0.0
    for k in range(y.shape[0]):
        y0, y1, y2 = y[k, 0] - p0[0], y[k, 1] - p0[1], y[k, 2] - p0[2]
        a = p1_inv[0, 0] * y0 + p1_inv[0, 1] * y1 + p1_inv[0, 2] * y2
        b = p1_inv[1, 0] * y0 + p1_inv[1, 1] * y1 + p1_inv[1, 2] * y2
        c = p1_inv[2, 0] * y0 + p1_inv[2, 1] * y1 + p1_inv[2, 2] * y2
        scale = (abs(y[k, 0]) + abs(y[k, 1]) + abs(y[k, 2]) + abs(p0[0]) + abs(p0[1])
                 + abs(p0[2]) + 1e-300)           # relative to the outputs and the offset
        res = 0.0
        for it in range(30):
            r0 = p1[0, 0] * a + p1[0, 1] * b + p1[0, 2] * c + (p2[0] + p3[0] * a) * a * a - y0
            r1 = p1[1, 0] * a + p1[1, 1] * b + p1[1, 2] * c + (p2[1] + p3[1] * b) * b * b - y1
            r2 = p1[2, 0] * a + p1[2, 1] * b + p1[2, 2] * c + (p2[2] + p3[2] * c) * c * c - y2
            res = abs(r0) + abs(r1) + abs(r2)
            if res <= 1e-15 * scale or it == 29:
                break
            j00 = p1[0, 0] + (2.0 * p2[0] + 3.0 * p3[0] * a) * a
            j11 = p1[1, 1] + (2.0 * p2[1] + 3.0 * p3[1] * b) * b
            j22 = p1[2, 2] + (2.0 * p2[2] + 3.0 * p3[2] * c) * c
            j01, j02, j10, j12, j20, j21 = p1[0, 1], p1[0, 2], p1[1, 0], p1[1, 2], p1[2, 0], p1[2, 1]
            c00, c01, c02 = j11 * j22 - j12 * j21, j02 * j21 - j01 * j22, j01 * j12 - j02 * j11
            c10, c11, c12 = j12 * j20 - j10 * j22, j00 * j22 - j02 * j20, j02 * j10 - j00 * j12
            c20, c21, c22 = j10 * j21 - j11 * j20, j01 * j20 - j00 * j21, j00 * j11 - j01 * j10
            det = j00 * c00 + j01 * c10 + j02 * c20
            a -= (c00 * r0 + c01 * r1 + c02 * r2) / det
            b -= (c10 * r0 + c11 * r1 + c12 * r2) / det
            c -= (c20 * r0 + c21 * r1 + c22 * r2) / det
        v[k, 0], v[k, 1], v[k, 2] = a, b, c
        worst = max(worst, res / scale)
    return worst


RAW_FIELDS = ("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency")
BLOCK = 1 << 18             # samples per block of `compensate_log` (~100 MB of work arrays)
HELD_SAMPLES = 1 << 20      # a record up to this long (~140 MB) is read once for the 3 passes


def compensate_log(log_path, cal, out, force=False, skip_damaged=False, block=BLOCK):
    """Apply a calibration to a log's /mimu/raw channel and write OUT: every channel,
    metadata record and attachment of the input copied (the contract's fixed-size channels
    field by field, with CDR padding written as zeros; others byte for byte, their chunks'
    CRCs checked), plus /mimu/imu (sensor_msgs/msg/Imu, sensor axes, interval means, no
    orientation). A damaged chunk or index is a LogError; with skip_damaged its messages are
    left out and listed in the output's `damage` metadata record. Returns the flag counts
    (`flag_counts`).

    Memory is bounded: the record is worked in blocks of `block` samples, in three passes -
    the wild-value filter's noise level from a subsample of the whole record, the clipping
    extremes of the filtered voltages, then the compensation - each block with
    `margin_samples` of its neighbours on both sides, so every sample sees what it
    would see in a whole-record compensation (tests/test_compensation.py checks they agree).
    Where that does not hold: a run of wild or non-finite samples longer than the margin
    across a block edge is repaired from the samples within reach (held, or UNUSABLE when
    the whole extended block has none) instead of interpolated across - flagged either way;
    and the derivative of found terms takes each block's median sample interval (a record
    whose rate changes differs near the change). A record of up to HELD_SAMPLES samples is
    read once and held for the three passes; a longer one is read from the file in each
    (`FlightLog.blocks`), and if its stamps go back in time, read whole and sorted."""
    from .flightlog.reader import TimeOrderError
    try:
        return _compensate_log(log_path, cal, out, force, skip_damaged, block)
    except TimeOrderError:          # stamps going back in time: read whole, sorted (`read`)
        return _compensate_log(log_path, cal, out, force, skip_damaged, None)


def _channel_blocks(log, topic, block, fields=None):
    """The channel in blocks (`FlightLog.blocks`), or whole and time-sorted (`read`) when
    block is None."""
    if block is None:
        msgs = log.read(topic, fields)
        return [msgs] if len(msgs) else []
    return log.blocks(topic, block, fields)


def compensated_blocks(log, cal, block=BLOCK):
    """The /mimu/raw channel of an open FlightLog through `cal`, block by block in bounded
    memory (as `compensate_log` describes): yields (raw messages of the block, f m/s^2,
    w rad/s, flags), sensor axes; `block` None works the channel whole, time-sorted. A
    channel of more than HELD_SAMPLES samples streams from the file, and then raises
    flightlog's TimeOrderError if its stamps go back in time across blocks (read it with
    block=None)."""
    from .flightlog import LogError
    rng = log.metadata().get("sensor/mimu", {}).get("range", {})
    n = log.count("/mimu/raw") if not log.skip_damaged else None   # checked as it is read
    if n is None:
        n = sum(len(b) for b in _channel_blocks(log, "/mimu/raw", block, ["sample_index"]))
    if n < 2:
        raise LogError(f"{log.path}: /mimu/raw has {n} intact messages")
    # a short record (or one whose stamps go back: block None) is read once, time-sorted,
    # and its blocks are views of it; a long one is read from the file for each pass
    whole = log.read("/mimu/raw") if block is None or n <= HELD_SAMPLES else None

    def with_margins(fields, margin):
        if whole is None:
            return _with_margins(log.blocks("/mimu/raw", max(block, 2 * margin), fields), margin)
        return _margin_views(whole, block or len(whole), margin)
    stats = RecordStats.sigma_of_blocks(
        [whole] if whole is not None else log.blocks("/mimu/raw", block, RAW_FIELDS),
        n, RAW_FIELDS)
    margin = margin_samples(cal, 1e9 / stats.min_step_ns)
    for ext, lo, hi in with_margins(RAW_FIELDS[:2], margin):
        flags = np.zeros(len(ext), np.uint8)
        stats.add_extremes([wild_value_filter(ext[name], flags, sigma=sigma)[lo:hi]
                            for name, sigma in zip(RAW_FIELDS[:2], stats.sigma[:2])])
    stats.finish_extremes()
    t0 = None
    for ext, lo, hi in with_margins(None, margin):
        stamps = ext["log_time"].astype(np.int64)
        t0 = stamps[0] if t0 is None else t0
        f, w, flags = compensate(cal, *(ext[name] for name in RAW_FIELDS),
                                 rng.get("accel_m_s2", np.inf), rng.get("gyro_rad_s", np.inf),
                                 t=(stamps - t0) / 1e9, record=stats)
        yield ext[lo:hi], f[lo:hi], w[lo:hi], flags[lo:hi]


def _compensate_log(log_path, cal, out, force, skip_damaged, block):
    from mcap.reader import make_reader

    from .flightlog import FlightLog, LayoutError, LogError, LogWriter
    from .flightlog import schemas as S
    from .flightlog.reader import PAYLOAD
    with FlightLog(log_path, skip_damaged=skip_damaged) as log:
        if "/mimu/imu" in log.channels:
            raise LogError(f"{log_path} already has /mimu/imu")
    counts = dict.fromkeys(("replaced", "saturated", "unusable"), 0)
    with open(log_path, "rb") as fh, LogWriter(out, force=force) as dst, \
            FlightLog(log_path, skip_damaged=skip_damaged) as log:
        log.metadata()                      # a damaged metadata record is a LogError
        blocks = compensated_blocks(log, cal, block)
        own = next(blocks)                  # the record's checks before anything is written
        reader = make_reader(fh)
        for record in reader.iter_metadata():
            dst.metadata(record.name, record.metadata)
        for att in reader.iter_attachments():
            dst.attachment(att.name, att.data, att.media_type)
        generic = []
        raw_fields = [name for name, _, _ in S.BODIES[S.RAW_MIMU]]
        for topic in log.channels:
            if topic == "/mimu/raw":            # copied below, from the compensation's read
                continue
            try:        # a channel of the contract's layouts: its payloads as they are
                for msgs in _channel_blocks(log, topic, block, PAYLOAD):
                    dst.write_encoded(topic, log.schema_name(topic), msgs["payload"],
                                      msgs["log_time"].astype(np.int64), increasing=True)
            except LayoutError:
                generic.append(topic)
        for raw, f, w, flags in itertools.chain([own], blocks):
            stamps = raw["log_time"].astype(np.int64)
            dst.write("/mimu/raw", S.RAW_MIMU, raw["frame_id"][0].decode(), stamps,
                      **{name: raw[name] for name in raw_fields})
            dst.write("/mimu/imu", S.IMU, "mimu", stamps, **S.imu_fields(w, f))
            for name, count in flag_counts(flags).items():
                counts[name] += count
        fh.seek(0)
        try:
            for schema, channel, message in make_reader(fh, validate_crcs=True).iter_messages(
                    topics=generic):
                dst.copy(schema, channel, message)
        except Exception as exc:            # the mcap reader's own errors on damaged chunks
            raise LogError(f"{log_path}: damaged data in {', '.join(generic)} "
                           f"({type(exc).__name__}: {exc})") from None
        if log.damaged:
            dst.metadata("damage", {topic: [{"start_ns": a, "end_ns": b, "reason": r}
                                            for a, b, r in spans]
                                    for topic, spans in log.damaged.items()})
    return counts


def margin_samples(cal, rate_hz):
    """Samples of context a block needs on each side for `compensate` to act on its
    samples as on the whole record: the cold-start model's dT window, the windows of found
    terms and the derivative window of their conditions (s, at rate_hz), plus the wild-value
    filter's and the clipping test's reach."""
    seconds = [effects.DERIVATIVE_WINDOW_S]
    if cal.cold_start:
        seconds.append(cal.cold_start.get("window_s", 0.0))
    for term in cal.found or []:
        seconds.append(float(term.get("window_s", 0.0)))
        if term["effect"] == "thermal_hysteresis":      # slope over a centred window
            seconds.append(effects.HYSTERESIS_SLOPE_WINDOW_S / 2)
        if term["effect"] == "time_skew":               # the samples shifted by tau
            seconds.append(float(np.max(np.abs(term["coefficient"]))) + effects.DERIVATIVE_WINDOW_S)
        if term["effect"] == "vibration_rectification":  # window + the filter's settling
            seconds.append(effects.VIBRATION_WINDOW_S / 2 + 10.0 / effects.VIBRATION_CUTOFF_HZ)
    return int(math.ceil(max(seconds) * rate_hz)) + 2 * CLIP_RUN + 2 * CURVE_REACH + 8


def _margin_views(whole, block, margin):
    """`_with_margins` of a record held whole: views of blocks of `block` samples with up to
    `margin` samples of their neighbours."""
    for start in range(0, len(whole), block):
        lo, end = max(0, start - margin), min(len(whole), start + block)
        yield whole[lo:min(len(whole), end + margin)], start - lo, end - lo


def _with_margins(blocks, margin):
    """(block with up to `margin` samples of the previous and next blocks around it, start,
    end of the block's own samples in it) for consecutive blocks."""
    before, current = None, None
    for nxt in blocks:
        if current is not None:
            yield _joined(before, current, nxt[:margin])
            before = _tail(before, current, margin)
        current = nxt
    if current is not None:
        yield _joined(before, current, current[:0])


def _joined(before, current, after):
    parts = [p for p in (before, current, after) if p is not None]
    lo = 0 if before is None else len(before)
    return np.concatenate(parts), lo, lo + len(current)


def _tail(before, current, margin):
    if margin == 0:
        return current[:0]
    if before is None or len(current) >= margin:
        return current[-margin:].copy()
    return np.concatenate([before, current])[-margin:]


def flag_counts(flags):
    """Samples flagged REPLACED, SATURATED, UNUSABLE by `compensate`: {name: count}."""
    return {name: int(np.sum(flags & bit > 0)) for name, bit in
            (("replaced", REPLACED), ("saturated", SATURATED), ("unusable", UNUSABLE))}

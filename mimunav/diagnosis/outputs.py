"""Effects of the vocabulary that are no regressor, tested on the outputs themselves (sensor
level, log contract section 3):

  saturation        the output stops following its input at a level below the declared
                    range: where the reference says the input went well beyond anything the
                    channel ever output, the channel stays flat (its slope against the input
                    near zero). Coefficient: the clip level (SI, magnitude), `side` + / - /
                    both. The clipped samples are left out of every other test.
  quantization      the output sits on a lattice of step q: in SI (the compensated output) or
                    in raw volts (an ADC), found from the spacing of the distinct values and
                    confirmed by the phase coherence |mean exp(2 pi i y / q)| (1 on a
                    lattice, ~ N^-1/2 for a continuous output). Reported when it matters:
                    the quantization noise q^2/12 at least QUANTIZATION_SHARE of the channel's
                    white noise. Coefficient: q in SI (a volt step times the channel's gain).
  bias_instability  the bias wanders more than the unit class allows, and
  bias_shift        a constant offset beyond the unit's normal bias: the fitted bias's SPAN_S
                    means (longer on a long flight: `bias_span`) over quiet
                    flight against a unit of the class (turn-on spread and
                    in-run zero drift, `calibration.TURN_ON`, `CLASS_DRIFT`, with the
                    calibration's own stated A0 / W0 error and the reference's bias, Table 4:
                    1 deg/h, 100 ug): likelihood ratios of a free constant and of a free
                    Gauss-Markov wander (`bias_tests`), at the library's first Holm threshold.
Each is held to the same family-wise alpha as the library; a clip must show on both halves of
the diagnosis' split (alternate SPLIT_BLOCK_S blocks).
"""
import functools
import math

import numpy as np
from scipy import stats

from ..lab.runs import TURN_ON
from ..lab.calibrate import standard_errors
from ..compensation.effects import AXES
from .bias_models import GM_TAU_S, SPAN_S, bias_models
from .design import white_per_bin
from .library import MIN_VARIANCE_SHARE
from ..sensors.accuracy import Accuracy

G0 = 9.80665
DEG = math.pi / 180
CHANNELS = [("accel", a) for a in AXES] + [("gyro", a) for a in AXES]

SATURATION_MIN_SAMPLES = 10      # samples beyond the clip level needed to call it
SATURATION_MARGIN_SIGMA = 5.0    # "well beyond": the reference above the output's maximum by
                                 # this many per-sample noise sigmas and 1 % of the level
SATURATION_FLAT_SLOPE = 0.5      # slope of output on input above the level: 0 clipped, 1 live
SATURATION_OF_RANGE = 0.98       # a level at the declared range is the model's own limit
QUANTIZATION_SHARE = MIN_VARIANCE_SHARE  # q^2/12 against the white noise variance: the
                                 # share every finding must remove (a 1.8 mg ADC step under
                                 # 0.02 m/s^2 of noise, 7 %, had been held below a 10 % bar)
QUANTIZATION_COHERENCE = 0.9     # |mean exp(2 pi i y/q)| on a lattice (jitter << q)
QUANTIZATION_RESOLUTION = 1e-6   # relative half-width of a step read off the lattice: the
                                 # round-off of raw volts through the calibration and back
# the class's in-run instability: seed S1 Table 1's zero drift of a MEMS unit, the bound (a unit
# anywhere inside its class is no bias_instability; the datasheet's typical 15 deg/h and
# 0.5 mg, `calibration.INSTABILITY`, would call a unit at the class's edge one)
CLASS_DRIFT = {"accel": 1e-3 * G0, "gyro": 30 * DEG / 3600}


def _finding(effect, sensor, axis, coefficient, ci95, where, rms, test, **extra):
    """A finding with the keys of the library's (`confirmation.confirm_chosen`): rms = (before, after) on
    the rows where it acts, test = (p_train, p_heldout, threshold) or None for a test that
    is no p-value (a clip or a lattice is seen, not inferred)."""
    unit = "m/s^2" if sensor == "accel" else "rad/s"
    p_train, p_held, threshold = test or (0.0, 0.0, 0.0)
    return {"effect": effect, "sensor": sensor, "axis": axis, "coefficient": float(coefficient),
            "ci95": [float(ci95[0]), float(ci95[1])], "units": unit, "where": where,
            "fit": {"train_rms_before": rms[0], "train_rms_after": rms[1],
                    "heldout_rms_before": rms[0], "heldout_rms_after": rms[1], "units": unit,
                    "channels": [f"{sensor}.{axis}"]},
            "label": f"{effect} {sensor}.{axis}", "attribution": "mimu",
            "p_train": p_train, "p_heldout": p_held, "holm_threshold": threshold,
            "effect_size": {"heldout_variance_removed": _share(*rms), "basis":
                            "1 - (rms after / rms before)^2 on the rows where it acts"},
            **{"indistinguishable_from": [], **extra}}


def _share(before, after):
    """The share of the variance a finding takes away: 1 - (after / before)^2."""
    return float(1.0 - (after / before) ** 2) if before > 0 else 0.0


def noise_sigma_of(column, width):
    """Per-sample white noise sigma of each of the columns column(c), c < width, of a
    residual: 1.4826 MAD of the first difference over sqrt 2 (robust to a wandering bias
    and to manoeuvres), over the differences finite in every column; the columns read one at
    a time (twice: the rows finite in all, then each one's MAD)."""
    finite = None
    for c in range(width):
        ok = np.isfinite(np.diff(column(c)))
        finite = ok if finite is None else finite & ok
    out = np.empty(width)
    for c in range(width):
        d = np.diff(column(c))[finite]
        out[c] = 1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2)
    return out


# ---- saturation ----------------------------------------------------------------------------
def saturation(t, measured, predicted, rows, train, full_scale, steps=None, sigma=None):
    """(findings, clipped (N,) bool). measured, predicted: (N, 6) per-sample outputs
    (accel m/s^2, gyro rad/s, MIMU axes); rows: samples fit to test (not repaired, inside
    the reference); train: the split's training samples; full_scale {"accel", "gyro"};
    steps (6,): a quantized channel's step (SI), which widens "beyond" by a step (a
    quantized output's maximum sits up to half a step from its input's); sigma (6,): the
    `noise_sigma` of measured - predicted over `rows` when the caller has it. measured and
    predicted are read a column at a time, x[:, c] (`samples.Columns`)."""
    if sigma is None:
        sigma = noise_sigma_of(lambda c: np.where(rows, measured[:, c] - predicted[:, c],
                                                  np.nan), 6)
    sigma = sigma + (0.0 if steps is None else np.asarray(steps) / SATURATION_MARGIN_SIGMA)
    clipped = np.zeros(len(t), bool)
    findings = []
    for c, (sensor, axis) in enumerate(CHANNELS):
        sides, y = {}, measured[:, c]
        x = predicted[:, c] + own_offset(y, predicted[:, c], rows)
        for sign in (1.0, -1.0):
            side = _clip_side(sign * y, sign * x, rows, train, sigma[c], full_scale[sensor])
            if side:
                sides["+" if sign > 0 else "-"] = side
                clipped |= rows & (sign * x > side["level"] - 5 * sigma[c])
        if sides:
            findings.append(_saturation_finding(t, sensor, axis, sides, y, x))
    return findings, clipped


def own_offset(y, x, rows):
    """The channel's offset from its input, SI: the median of y - x over the `rows` whose
    input lies inside the range the output reached (a clip's samples, however many, do not
    move it). The input is judged beyond the output's reach as the output would read it,
    offset included: a rocket's uncorrected 25 mg bias at its tilted rest had put the
    reference beyond anything accel.z output, and flat - a clip 'found' at its rest
    reading, 4.956 m/s^2, over 61,206 samples."""
    if not rows.any():
        return 0.0
    inside = rows & (x >= np.min(y[rows])) & (x <= np.max(y[rows]))
    return float(np.median((y - x)[inside if inside.any() else rows]))


def at_declared_range(measured, predicted, declared):
    """(N,) bool: the samples where a channel's output sits at its declared range
    (SATURATION_OF_RANGE of it) or its input lies beyond it - clipped by the unit's own
    limit, which is no finding but leaves the sample saying nothing of the other terms (a
    rate table's 300 deg/s steps on a 250 deg/s gyro had been fitted: an asymmetric scale
    read as 0.0012 rad/s of bias instability, a null twin's cross-coupling 'found' at p
    1e-23). measured, predicted: (N, 6) as `saturation`'s, read a column at a time;
    declared: {"accel": m/s^2, "gyro": rad/s} of the ranges the log states (a channel not
    stated: none)."""
    out = np.zeros(len(measured[:, 0]), bool)          # a column at a time (`samples.Columns`)
    for c, (sensor, _) in enumerate(CHANNELS):
        if sensor in declared:
            limit = float(declared[sensor])
            out |= (np.abs(measured[:, c]) >= SATURATION_OF_RANGE * limit) | \
                (np.abs(predicted[:, c]) > limit)
    return out


def _clip_side(y, x, rows, train, sigma, full_scale):
    """The clip of one side: {level, half (95 %), beyond (N,) bool, slope} or None."""
    if not rows.any():
        return None
    top = float(np.max(y[rows]))
    beyond = rows & (x > top + SATURATION_MARGIN_SIGMA * sigma + 0.01 * abs(top))
    if beyond.sum() < SATURATION_MIN_SAMPLES or top <= 0:
        return None
    halves = []
    for part in (beyond & train, beyond & ~train):
        if part.sum() < SATURATION_MIN_SAMPLES // 2:
            return None
        halves.append(_flat(y[part], x[part], sigma))
    if any(h is None for h in halves):
        return None
    level = float(np.mean(y[beyond]))
    if np.std(y[beyond]) > SATURATION_MARGIN_SIGMA * sigma:
        return None         # not at a rail: an output that moves beyond is a model error
                            # (an unmodelled lever arm in a roll), not a clip
    if level >= SATURATION_OF_RANGE * full_scale:
        return None
    return {"level": level, "half": 1.96 * sigma / math.sqrt(beyond.sum()), "beyond": beyond,
            "slope": halves[0]}


def _flat(y, x, sigma):
    """Slope of y on x where it is determined and below SATURATION_FLAT_SLOPE with 95 %
    confidence (the output does not follow its input); None otherwise. An input range too
    short to fix a slope counts as flat when the output stays at its level while the input
    is beyond it (the caller's condition)."""
    spread = float(np.std(x))
    if spread * math.sqrt(len(x)) < 10 * sigma:       # slope undetermined: level test only
        return 0.0
    slope, _ = np.polyfit(x, y, 1)
    se = sigma / (spread * math.sqrt(len(x)))
    return float(slope) if slope + 1.96 * se < SATURATION_FLAT_SLOPE else None


def _saturation_finding(t, sensor, axis, sides, y, x):
    levels = [s["level"] for s in sides.values()]
    level = float(np.mean(levels))
    half = float(max(s["half"] for s in sides.values()) + np.ptp(levels) / 2)
    beyond = np.any([s["beyond"] for s in sides.values()], axis=0)
    clip = np.clip(x, -sides["-"]["level"] if "-" in sides else -np.inf,
                   sides["+"]["level"] if "+" in sides else np.inf)
    rms = (float(np.sqrt(np.mean((y - x)[beyond] ** 2))),
           float(np.sqrt(np.mean((y - clip)[beyond] ** 2))))
    return _finding("saturation", sensor, axis, level, (level - half, level + half),
                    spans(t, beyond, f"{sensor}.{axis} beyond {level:.4g}: clipped"), rms, None,
                    ci95_method="the sides' levels and their spread",
                    side="both" if len(sides) == 2 else next(iter(sides)),
                    slope_beyond={k: s["slope"] for k, s in sides.items()},
                    samples_clipped=int(beyond.sum()),
                    note="where the reference is beyond the level the output stays flat "
                         "(slope_beyond: output against input there, both halves of the "
                         "split); 'after': the output clipped at the level")


# ---- quantization --------------------------------------------------------------------------
def quantization(t, measured, raw, gains, rows, sigma):
    """Findings of channels whose output (SI) or raw volts (raw (N, 6) or None) sit on a
    lattice that matters against the white noise sigma (6,). gains (6, 3): per channel the
    output's slope in SI per V over the samples (median, smallest, largest: eqs. 1/3 are
    not linear, so a volt step is not one SI step over the range - the interval spans it)."""
    findings = []
    for c, (sensor, axis) in enumerate(CHANNELS):
        for domain, y, gain in (("output", measured[:, c], (1.0, 1.0, 1.0)),
                                ("raw volts", None if raw is None else raw[:, c], gains[c])):
            if y is None:
                continue
            q = lattice_step(y[rows])
            step = None if q is None else q * gain[0]
            if step is None or step ** 2 / 12 < QUANTIZATION_SHARE * sigma[c] ** 2:
                continue
            unit = "m/s^2" if sensor == "accel" else "rad/s"
            rms = (float(sigma[c]), float(math.sqrt(max(sigma[c] ** 2 - step ** 2 / 12, 0.0))))
            lo = q * gain[1] * (1 - QUANTIZATION_RESOLUTION)
            hi = q * gain[2] * (1 + QUANTIZATION_RESOLUTION)
            findings.append(_finding(
                "quantization", sensor, axis, step, (lo, hi),
                spans(t, rows, f"{sensor}.{axis}: every sample"), rms, None,
                domain=domain, step_in_domain=q, ci95_method="the lattice's resolution",
                note=f"the {domain} take only multiples of {q:.4g}"
                     f"{'' if domain == 'output' else ' V'}: quantization noise "
                     f"{step / math.sqrt(12):.3g} {unit} rms of the white noise "
                     f"{sigma[c]:.3g} ('after': the white noise without it)"))
            break
    return findings


DITHERED_STEPS = 0.5    # white noise (in steps) from which a quantized channel's mean error
#                         is independent of its input: by Widrow's theorem its dependence is
#                         at most q/pi exp(-2 pi^2 sigma^2 / q^2), 0.002 q here (a 16-bit gyro's
#                         0.0076 deg/s step under 0.07 deg/s of noise had kept every gyro.z
#                         term out of a rate table's diagnosis: its scales never tested)


def undithered(steps, *sigmas):
    """{channel index}: the quantized channels (steps (6,) SI, 0 where none) whose own white
    noise before the quantizer is below DITHERED_STEPS of their step - their error then
    depends on where the input falls between two steps, which terms of that channel alone
    would fit. sigmas: (6,) estimates of the white noise after it, each holding more than the
    unit's own (the residual's: the reference's noise too; the outputs' own differences: the
    motion too) - the least of them, less the step's own q^2/12, is the unit's."""
    steps = np.asarray(steps, float)
    after = np.min(np.asarray(sigmas, float), axis=0)
    own = np.sqrt(np.maximum(after ** 2 - steps ** 2 / 12, 0.0))
    return set(np.flatnonzero(steps > own / DITHERED_STEPS).tolist())


def lattice_step(y):
    """The step q of a lattice the values y (n,) sit on, or None: the smallest spacing of the
    distinct values (above round-off) refined as the mean of the spacings within 10 % of it,
    kept when the phase coherence |mean exp(2 pi i y / q)| exceeds QUANTIZATION_COHERENCE."""
    y = y[np.isfinite(y)]
    if len(y) < 100:
        return None
    scale = float(np.max(np.abs(y))) or 1.0
    levels = np.unique(y)
    d = np.diff(levels)
    d = d[d > 1e-9 * scale]
    if len(d) < 2:                      # fewer than three levels: no lattice to speak of
        return None
    q0 = float(np.min(d))
    q = float(np.mean(d[d < 1.1 * q0]))
    # the distinct multiples of q the values round to (round(y / q) is monotonic in y: the
    # distinct values' rounded, in order, need no second sort)
    if q <= 0 or np.count_nonzero(np.diff(np.round(levels / q))) + 1 > 0.5 * len(y):
        return None         # more levels than half the samples: no lattice of this step
    coherence = abs(np.mean(np.exp(2j * math.pi * (y - y[0]) / q)))
    return q if coherence > QUANTIZATION_COHERENCE else None


# ---- the bias: its wander and its level --------------------------------------------------
def bias_null(noise=None):
    """{"instability": {sensor: B (SI)}, "units", "source"}: the in-run wander `bias_tests`
    takes as normal - the unit's measured B where `noise` has it, else the class's zero
    drift."""
    measured = (noise or {}).get("instability", {})
    source = noise["source"] if measured else ""
    return {"instability": {**CLASS_DRIFT, **measured},
            "units": {"accel": "m/s^2", "gyro": "rad/s"},
            "source": "; ".join(filter(None, [
                source and f"measured ({', '.join(sorted(measured))}): {source}",
                len(measured) < 2 and "class: seed S1 Table 1's zero drift bound "
                "(diagnosis.outputs.CLASS_DRIFT)"]))}


BIAS_QUIET_BINS = 100   # bins of quiet flight the bias tests read, at least


def bias_untested(quiet_bins):
    """'' or why the bias's offset and wander went untested (`bias_tests`): fewer than
    BIAS_QUIET_BINS bins of quiet flight (a walker's foot never rests: an offset of 0.5
    deg/s had been neither found nor said untested)."""
    if quiet_bins >= BIAS_QUIET_BINS:
        return ""
    return (f"bias_shift and bias_instability are not tested: {quiet_bins} bins of quiet "
            f"flight, {BIAS_QUIET_BINS} needed (in manoeuvres what the library misses would "
            "pass for an offset) - 'nothing found' does not cover them")


def bias_tests(design, fit, quiet, alpha_level, cal, skip=(), noise=None, carried=None):
    """bias_instability and bias_shift findings per channel, from the bias's `bias_span` means
    over quiet flight. fit: residual without the fitted reference error and confirmed terms
    (nb, 6) on the design's bins (what is left: the bias and the white noise); quiet (nb,)
    bool: the bins of quiet flight, the only ones read - in manoeuvres whatever the model and
    the library miss (a cross-axis nonlinearity, the reference's own dynamic errors) would
    pass for wander or offset; alpha_level: the family-wise threshold of the library's first
    step; skip: channels (sensor, axis) whose outputs are clipped or quantized (that makes
    an offset and a wander of its own); noise: the unit's measured random errors
    ({"source", "instability": {sensor: B}}, `reports.noise.load` of a `mimunav noise`
    file): a sensor's measured B replaces the class's zero drift as the null's wander, so
    the question becomes "more than this unit wanders at rest"; carried: (6,) SI, 1 sigma of
    each channel's quiet mean that the confirmed terms' removal leaves (their estimates'
    error, `removal.removal_sigma`), a part of the offset's null.

    Three models of the means x (m,) at times t, each Gaussian (`bias_models`):
      class   x ~ N(0, B^2 F + s0^2 11' + w I): a unit of the class - an in-run wander of
              the class's zero drift B (`CLASS_DRIFT`) as a flicker (1/f) bias (F: the
              covariance of its window means, `calibration.flicker_covariance`), a
              turn-on offset of spread s0 (`calibration.TURN_ON`, the calibration's stated
              A0 / W0 error, the reference's bias) and the white share w;
      shift   the class's wander about a free constant mu (bias_shift);
      wander  the class plus a Gauss-Markov wander of free sigma (R_ij =
              exp(-|ti - tj| / tau)): bias_instability, sigma its coefficient.
    Every model also carries the channel's temperature reading as a free linear term, so a
    thermal drift too weak for the library to name is not read as wander or offset. The
    tests: the offset's generalised-least-squares mean against the class's spread, z^2 =
    mu^2 / (se^2 + s0^2) ~ chi2(1); the wander's likelihood ratio against the class (nested,
    one parameter on its boundary: chi2(1) is conservative). Each at alpha_level; when both
    pass, the model of the higher likelihood is named, and the other listed as not told
    apart when their likelihoods are within chi2(1)'s 95 %."""
    if quiet.sum() < BIAS_QUIET_BINS:
        return []
    fit, span = np.where(quiet[:, None], fit, np.nan), bias_span(design.t)
    t_means, means = span_means(design.t, fit, span)
    inputs = span_means(design.t, np.where(quiet[:, None], design.inputs, np.nan), span)[1]
    thermal = _temperature_means(design, quiet, span)
    se_cal = standard_errors(cal)
    measured = (noise or {}).get("instability", {})
    drift = {**CLASS_DRIFT, **measured}
    whose = {s: "the unit's measured" if s in measured else "the class's" for s in drift}
    dt = float(np.median(np.diff(design.t)))
    findings = []
    for c, (sensor, axis) in enumerate(CHANNELS):
        keep = np.isfinite(means[:, c])
        if (sensor, axis) in skip or keep.sum() < 3:
            continue
        key = f"{'A0' if sensor == 'accel' else 'W0'}[{AXES.index(axis)}]"
        reference = _reference_bias(design, sensor)
        removal = 0.0 if carried is None else float(carried[c])
        offset = math.sqrt(TURN_ON[sensor] ** 2 + reference ** 2
                           + (se_cal.get(key) or 0.0) ** 2 + removal ** 2)
        white = float(white_per_bin(fit[:, c])) * dt / span
        # the null's wander: the MIMU's (class or measured) and the reference's own
        wander = math.hypot(drift[sensor], reference)
        model = (t_means[keep], means[keep, c], wander, offset, white,
                 None if thermal is None else thermal[keep, c:c + 1], span)
        m = bias_models(*model)
        passing = [k for k in ("shift", "wander") if m[k]["p"] < alpha_level]
        if not passing:
            continue
        named = functools.partial(_bias_finding, m=m, x=means[keep, c], sensor=sensor,
                                  axis=axis, where=spans(design.t, quiet,
                                                         f"{sensor}.{axis}: quiet flight"),
                                  alpha_level=alpha_level, offset=offset, white=white,
                                  whose=whose[sensor], drift=wander, span=span)
        finding = _shift_or_wander(m, passing, named, model, inputs[keep], alpha_level)
        findings.append(_qualified(finding, design, cal, removal))
    return findings


def _shift_or_wander(m, passing, named, model, inputs, alpha_level):
    """The bias finding of one channel whose models `m` (`bias_models`) pass as `passing`
    ("shift", "wander"): the better fit of the two, the other listed as not told apart when
    their likelihoods are within chi2(1)'s 95 %; a wander judged beside the inputs
    (`judged_beside_inputs`, about a free mean when the offset passed), and the offset
    named instead when they explain it about that offset. named(best, p=, alike=): the
    finding (`_bias_finding` with the channel's arguments)."""
    best = max(passing, key=lambda k: m[k]["lr"])
    other = "wander" if best == "shift" else "shift"
    sensor, axis = named.keywords["sensor"], named.keywords["axis"]
    # a Gauss-Markov wander slower than the flight is an offset on it: when the other
    # model passes too and fits about as well, the flight cannot tell them apart - named,
    # as the library's look-alikes are
    label = f"{EFFECT_OF[other]} {sensor}.{axis}"
    alike = ([{"effect": EFFECT_OF[other], "sensor": sensor, "axis": axis, "label": label}]
             if other in passing
             and m[best]["lr"] - m[other]["lr"] < stats.chi2.isf(0.05, 1) else [])
    finding = named(best, p=m[best]["p"], alike=alike)
    if best == "shift":
        return finding
    finding = judged_beside_inputs(finding, model, inputs, alpha_level,
                                   free_offset="shift" in passing)
    if finding.get("rejected") and "shift" in passing:
        finding = named("shift", p=m["shift"]["p"], alike=[])
        finding["note"] += ("; a wander read beside it follows the reference's inputs about "
                            "this offset: not a wander")
    return finding


INPUT_NAMES = ("f_x", "f_y", "f_z", "w_x", "w_y", "w_z")    # `design.Design.inputs`' columns


def judged_beside_inputs(finding, model, inputs, alpha_level, free_offset=False):
    """The wander finding, `rejected` when it is no longer beyond alpha_level once the
    reference's inputs (span means (m, 6), `INPUT_NAMES`) may enter linearly beside it - the
    models `model` (`bias_models`' arguments) fitted again with them as nuisance columns: a
    wander that follows an input is that input's term (a rate table's x <- z coupling, 0.002
    on its rate steps, had read as 0.001 rad/s of bias instability and carried a null twin's
    verdict), and a wander does not (a Gauss-Markov path beside a flight's inputs stays).
    free_offset: an offset beyond the class's is established (its own test passed), so the
    wander is judged about a free mean (`bias_models`' about_mean) - an uncalibrated part's
    whole turn-on bias (a rate table's 0.0045 rad/s) had kept alive a wander that the
    inputs explain about it."""
    t, x, wander, offset, white, nuisance, span = model
    ok = np.isfinite(inputs).all(axis=1)
    cols = inputs[ok] - inputs[ok].mean(axis=0)
    spread = cols.std(axis=0)
    moving = spread > 1e-9 * max(float(np.abs(inputs[ok]).max()) if ok.any() else 0.0, 1e-12)
    if not moving.any() or ok.sum() < moving.sum() + 5:
        return finding
    z = cols[:, moving] / spread[moving]
    extra = z if nuisance is None else np.hstack([nuisance[ok], z])
    again = bias_models(t[ok], x[ok], wander, offset, white, extra, span, free_offset)
    if again["wander"]["p"] < alpha_level:
        return finding
    r = [abs(float(np.corrcoef(x[ok], col)[0, 1])) for col in z.T]
    name = np.array(INPUT_NAMES)[moving][int(np.argmax(r))]
    finding["rejected"] = (
        f"once the reference's inputs may enter linearly beside it, no wander is left (p "
        f"{again['wander']['p']:.2g}; its means follow {name}, correlation {max(r):.2f}): a "
        "term of the input, not a wander - not confirmed")
    return finding


def _qualified(finding, design, cal, removal):
    """A bias finding with what qualifies it: a shift's null offset's share from the
    confirmed terms' removal (`removal`, SI) and, on outputs taken as recorded (`cal` an
    identity), that the part's turn-on bias shows whole; and `mimu-or-reference` where the
    reference may wander so."""
    if finding["effect"] == "bias_shift":
        if removal > 0.0:
            finding["found_terms_1sigma"] = removal     # a part of normal_offset_1sigma
        if cal is not None and cal.is_identity:
            finding["note"] += ("; the outputs are taken as recorded: no calibration removed "
                                "the part's turn-on bias, which shows here whole (the class's "
                                "offset is a calibrated MIMU's)")
    reference = design.reference
    if reference is not None and (reference.mems_grade or abs(
            finding["coefficient"]) <= reference.bias_allowance(finding["sensor"])):
        finding["attribution"] = "mimu-or-reference"
    return finding


def _reference_bias(design, sensor):
    """1 sigma of the reference's own bias on one axis of `sensor` (SI): its stated stability
    and logging step (`sensors.accuracy.Accuracy.bias_sigma`), else seed S1 Table 4's."""
    return (design.reference or Accuracy()).bias_sigma(sensor)


def _bias_finding(best, m, x, sensor, axis, where, p, alpha_level, offset, white, alike,
                  whose, drift, span):
    """The bias_shift (best "shift") or bias_instability ("wander") finding of a channel
    from its models `m` (`bias_models`) over the span (s) means x; whose: whose wander drift
    (SI) is the null's."""
    unit = "m/s^2" if sensor == "accel" else "rad/s"
    if best == "shift":
        mu, half = m["shift"]["mu"], 1.96 * m["shift"]["se"]
        return _finding(
            "bias_shift", sensor, axis, mu, (mu - half, mu + half), where,
            (float(np.sqrt(np.mean(x ** 2))), float(np.sqrt(np.mean((x - mu) ** 2)))),
            (p, p, alpha_level), normal_offset_1sigma=offset, ci95_method="wald",
            likelihood_ratio={k: m[k]["lr"] for k in ("shift", "wander")},
            indistinguishable_from=alike,
            note=f"a constant {mu:.3g} {unit} beyond the offset a unit of the class may "
                 f"show ({offset:.3g}: turn-on spread, calibration, reference, found terms) "
                 f"and {whose} in-run wander ({drift:.3g}): "
                 "better "
                 "explained as an offset than as a larger wander (likelihood ratios); "
                 f"rms of the {span:g} s means before and after")
    sigma, lo, hi = m["wander"]["sigma"], m["wander"]["lower"], m["wander"]["upper"]
    return _finding(
        "bias_instability", sensor, axis, sigma, (lo, hi), where,
        (float(np.std(x)), math.sqrt(white)), (p, p, alpha_level),
        ci95_method="profile-likelihood",
        likelihood_ratio={k: m[k]["lr"] for k in ("shift", "wander")},
        indistinguishable_from=alike,
        note=f"the bias wanders like a Gauss-Markov process of sigma {sigma:.3g} "
             f"{unit} (tau {GM_TAU_S:g} s) against {whose} "
             f"{drift:.3g}; 'after': the white share of a "
             f"{span:g} s mean")




def _temperature_means(design, quiet, span):
    """(m, 6) `span` (s) means over quiet flight of each channel's temperature_bias regressor
    (its temperature reading about the log's mean), or None when the library has none
    (a log without temperatures); a channel without one is 0."""
    cols = np.zeros((len(design.t), 6))
    for j, term in enumerate(design.terms):
        if term["effect"] == "temperature_bias":
            for c, x in design.columns[j].items():
                cols[:, c] = x[:, 0]
    if not cols.any():
        return None
    return span_means(design.t, np.where(quiet[:, None], cols, np.nan), span)[1]


EFFECT_OF = {"shift": "bias_shift", "wander": "bias_instability"}
MAX_SPANS = 900     # at most this many means (`bias_span`): the models' covariances are
                    # dense (m, m) and their eigendecompositions O(m^3) - 6 channels x 7 of
                    # them took a 48-minute flight's 1440 means to a minute and 0.3 GB;
                    # 900 holds 30 minutes of 2 s means, far more than any test flight's


def bias_span(t):
    """The length (s) of the means `bias_tests` reads over the bins at t (s): SPAN_S, or for
    a flight of more than MAX_SPANS of them the least multiple of SPAN_S that keeps their
    number to MAX_SPANS (a 2-hour flight: 10 s), still far below the Gauss-Markov wander's
    GM_TAU_S (a mean over span / tau of it keeps its structure)."""
    return SPAN_S * max(1, math.ceil((float(t[-1] - t[0]) / SPAN_S + 1) / MAX_SPANS))


def block_index(t, length_s):
    """(n,) int: the consecutive length_s blocks of t (s, increasing) from t[0], each stamp
    in the block it opens when it falls on a boundary. The boundaries fall on samples (a
    1 kHz flight's 0.5 s split, bin times that are means of stamps), where a plain floor
    put a stamp on either side by its last bit: a rounding of 1e-14 s had moved bins
    between the training and held-out halves and changed a finding's interval by 1 %."""
    return np.floor((t - t[0]) / length_s + BOUNDARY_TOLERANCE).astype(int)


BOUNDARY_TOLERANCE = 1e-6   # of a block: far above rounding (1e-14 s), below any sample step


def span_means(t, x, span=SPAN_S):
    """(times (m,), means (m, k)) of x (n, k) over consecutive spans of `span` s of t, NaN
    where fewer than half a span's bins are finite."""
    sec = block_index(t, span)
    n = sec.max() + 1
    good = np.isfinite(x)
    count = np.stack([np.bincount(sec, good[:, c], minlength=n) for c in range(x.shape[1])], 1)
    sums = np.stack([np.bincount(sec, np.where(good[:, c], x[:, c], 0.0), minlength=n)
                     for c in range(x.shape[1])], 1)
    full = span / float(np.median(np.diff(t)))
    means = np.where(count >= 0.5 * full, sums / np.maximum(count, 1), np.nan)
    return t[0] + (np.arange(n) + 0.5) * span, means


def spans(t, rows, condition, gap_s=2.0, max_spans=20):
    """[{"t0", "t1", "condition"}] of the contiguous runs of rows (gaps below gap_s merged;
    rows with no other row between them one run however far apart: the two sides of a
    1.92 s hole in a drive's stamps had been listed as two spans)."""
    if not rows.any():
        return []
    idx = np.flatnonzero(rows)
    breaks = np.flatnonzero((np.diff(t[idx]) > gap_s) & (np.diff(idx) > 1))
    starts, ends = np.r_[idx[0], idx[breaks + 1]], np.r_[idx[breaks], idx[-1]]
    return [{"t0": float(t[a]), "t1": float(t[b]), "condition": condition}
            for a, b in list(zip(starts, ends))[:max_spans]]


def counted_clips(t, recording):
    """(N,) bool: the samples at times t (s) inside a span where the recording's IMU - or
    its reference IMU - counted clipped samples of its own (the `recording` metadata's
    clip_spans_s, `importers.clip_counts`): short of the motion without being flat or at a
    range, so no test here finds them."""
    out = np.zeros(len(t), bool)
    for t0, t1, _ in (recording or {}).get("clip_spans_s") or []:
        out |= (t >= t0) & (t <= t1)
    return out


"""Sensor-level diagnosis: the recorded MIMU, compensated with the user's calibration, against
what the reference motion says it should have read (`reference.predicted_mimu`).

Model of the residual (6 channels: accel x y z in m/s^2, gyro x y z in rad/s, on 10 ms bin
means - longer where the reference's own error is correlated longer, `diagnose`'s bin_s),
per channel c:
    r_c = sum_j X_cj beta_j  +  x_ref,c' gamma  +  b_c(t)  +  white noise
  - X_cj: the candidate terms of the library (`library`, regressors `effects.regressor`);
  - gamma: the reference IMU's own linear error (scale factor and axis misalignment of each
    triad, seen in the MIMU's axes) with a Gaussian prior of the reference's stated accuracy
    (`sensors.accuracy.Accuracy`: from the log's `sensor/fog` metadata, the command line, or seed
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
    (`sensors.accuracy.Accuracy`, the calibration file's covariance) added to their variance;
    so must the terms the model itself carries (g-sensitivity C, nonlinearity A2/A3/W2/W3,
    temperature ct/cw) against the calibration's stated covariance of them
    (`model_allowance`), and so must a lever arm or a proof-mass offset against the
    reference's stated gyro error carried into the predicted specific force by the lever-arm
    transfer (`transfer_allowance`); those significant against the noise alone are listed as
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
import dataclasses
import math
import tempfile
from contextlib import nullcontext
from dataclasses import dataclass
from functools import cache

import numpy as np

from ..compensation.wild_values import REPLACED, UNUSABLE
from ..compensation.effects import AXES
from ..frames import attitude
from . import errors_in_variables, library, outputs, track_reference, wander
from ..sensors.accuracy import accuracy_of
from .reference import across_gaps, agreement, transfer_doubt, transfer_shocks
from ..errors import InputError
from ..flightlog.stamps import stamp_tick
from ..compensation.model import poly2
from .design import (Binning, CHANNELS, Design, add_clock_nuisance, detrended,
                     term_contribution, vibration_bin_s, make_design, reference_error, bins,
                     calibration_prior)
from .samples import binned, sample_stage, temperature_references
from .fitting import Fitter, term_test
from .scan import (SCAN_WINDOW_S, condition_masks, condition_map, excursions,
                   excursions_left_out, near_spans)
from .confirmation import (Extremes, beta_of, beyond_range, beyond_range_reasons,
                           clock_doubt, clock_reading, confirmed, out_of_the_shadow,
                           outputs_judged, set_aside_reasons, position_of)
from .removal import (REFERENCE_BEYOND_SIGMA, beside_reference, held_excursions,
                      offset_readings, read_every_way, reference_beyond_stated,
                      removal_sigma)
from .rails import short_rails
from .reference_grade import rest_graded
from .selection import select


SPLIT_BLOCK_S = 0.5
# findings that carry an offset of their own, so a channel that has one is not tested for a
# bias shift or wander (`outputs.bias_tests`): a clip, a lattice its own noise does not dither
# (`outputs.undithered`: its mean error depends on the input), and the temperature terms,
# whose reference offset the contract leaves to the bias (T0 the log's mean). A dithered
# lattice's mean error is independent of its input (Widrow): its channel is tested (skipped,
# 3-6 mg accelerometer biases beside a 0.25 mg lattice had gone unsaid)
OWN_OFFSET = ("saturation", "temperature_bias", "temperature_scale", "temperature_rate",
              "thermal_hysteresis")


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
    compensated: tuple = None   # (flight, w rad/s, f m/s^2 (N, 3) sensor axes): the MIMU through
                                # the calibration, for the report; None: the flight streamed
    library_inflation: dict = None  # a recording's: the library beside the findings
                                    # (`confirmation.recording_checks`), None when not measured
    reference_clock: dict = None    # the reference IMU's clock beside the findings
                                    # (`confirmation.clock_reading`), None when not fitted
    untested: list = dataclasses.field(default_factory=list)  # [what went untested, in
                                    # words] beside findings (without any: inconclusive)


def diagnose(flight, cal, alpha=0.05, candidates=None, accuracy=None, max_wander=None,
             output_tests=True, noise=None, vibration=None, bin_s=None,
             block_s=SPLIT_BLOCK_S, noise_shape=None, wander_steps=None, check_reference=True,
             unusable_because=None):
    """Sensor-level diagnosis of `flight` (an `evaluation.Flight` with a reference IMU)
    against calibration `cal`. `candidates`: the library to test (default
    `library.candidates()`); `max_wander`: the largest wander level (random-walk step
    variance over the white variance of a bin) the fits may choose - for a reference whose
    own errors are structured and would otherwise pass for wander (`track`); `accuracy`:
    the reference's `sensors.accuracy.Accuracy` (default: the log's metadata, else Table
    4); `output_tests`: also test the effects that are no
    regressor (`outputs`: saturation, quantization, the bias's wander and level against the
    MEMS class - not for a reference made from a vehicle's track); `noise`: the unit's
    measured random errors for those bias tests (`outputs.bias_tests`); `vibration`: (N, 3)
    the MIMU's vibration power, (m/s^2)^2, when its outputs in `flight` were filtered into
    the reference's band (`track`: a smoothed track's); `bin_s`, `block_s`: the bins' and
    the split blocks' lengths (s; bin_s None: `design.vibration_bin_s`) - longer where the
    reference's own error is correlated over more than a bin (`track`: a smoothed track's
    rates), so that bins are independent as the fit assumes and the held-out blocks do not
    share the training blocks' noise;
    `noise_shape`: (N, 6) each sample's white variance relative to its channel's, where the
    reference's own error varies along the record (`track`: a yaw rate from the course
    errs as 1/speed): the fit weighs and the scan judges each bin by it (a pair: the fit's,
    the scan's); `wander_steps`: (6,) the largest step variance of each channel's bias
    wander per bin, SI units squared, whatever white variance the fit finds (`track`: a
    level capped by `max_wander` alone grows with the vehicle model's own errors, which
    swell that white variance; for a MEMS-grade reference the same cap by default: its
    noise, in the residual and in its own input columns, would let a free wander fit the
    bins' differences - a tractor's reference gyro.z scale read -0.22 and every turn an
    excursion of 0.1 rad/s the two IMUs' outputs do not hold); `unusable_because`: why
    most samples may be unusable, for the refusal when too few are left (`track`: outside
    the motion its model trusts).
    Nothing here is random."""
    if flight.mimu_platform is not None:
        raise InputError(f"{flight.path}: the MIMU turns on a platform (/mimu/platform); "
                         "this analysis does not follow the rotation yet - replay and table do")
    acc = accuracy_of(flight.fog_meta, accuracy)
    prep = _prepare(flight, cal, acc, candidates, output_tests, vibration, bin_s, noise_shape,
                    max_wander, wander_steps, check_reference)
    output_tests, design = prep.output_tests, prep.design
    if len(design.t) < 4 * block_s / (bin_s := design.bin_s):
        raise _too_little(flight, prep, bin_s, block_s, unusable_because)
    held = ~(train := outputs.block_index(design.t, block_s) % 2 == 0)
    whole = cache(lambda: Fitter(design, np.ones(len(design.t), bool)))    # all rows, as needed
    chosen, within, beyond = select(design, train, alpha, prep.full_scale, whole)
    findings, rejected, aside, doubts, library = _confirmed(
        flight, design, chosen, (train, held, block_s), alpha, prep, acc.mems_grade,
        lambda noisier: _prepare(noisier, cal, acc, candidates, False, vibration, bin_s,
                                 noise_shape, max_wander, wander_steps, False).design)
    rejected = rejected + beyond_range(design, beyond)
    before, removed, fit_found = _residuals(design, everything := whole(), findings)
    conds = condition_masks(design, prep.norms)
    unexplained, on_outputs, read_twice = _after_the_fit(
        design, (removed, fit_found, everything), conds, (findings, rejected + within), prep,
        alpha, cal, noise, output_tests)
    on_outputs, outputs_aside = outputs_judged(on_outputs, library)
    shadow = transfer_doubt(flight, design, findings := findings + on_outputs)
    findings, shadowed = out_of_the_shadow(findings, shadow)
    rejected = rejected + outputs_aside + shadowed
    for f in (f for f in on_outputs if f["effect"] == "bias_shift"):
        removed[:, CHANNELS.index((f["sensor"], f["axis"]))] -= f["coefficient"]
    after = detrended(design, removed)
    diag = SensorDiagnosis(findings, unexplained, rejected, within, design, train, conds,
                           {"before": condition_map(design, before, conds),
                            "after": condition_map(design, after, conds)},
                           before, after, design.reference.as_dict(), len(design.terms),
                           design.terms, everything,
                           outputs.bias_null(noise) if output_tests else None,
                           prep.compensated and (flight, *prep.compensated), library,
                           clock := clock_reading(everything, fit_found.terms))
    diag.inconclusive = [why for why in prep.jitter + doubts + read_twice
                         + [shadow, design.bins_doubt, not shadow and clock_doubt(clock)]
                         if why]
    untested = [w for w in [output_tests and outputs.bias_untested(int(conds["quiet"].sum()))] if w]
    if not findings:        # what the halves set aside was there, but not the same throughout
        diag.inconclusive += set_aside_reasons(aside) + beyond_range_reasons(rejected) + untested
    diag.untested = untested if findings else []    # a review's spinning IMU's bias unsaid
    if prep.agreement is not None:
        _judged_by(diag, prep.agreement)
    return diag


def _judged_by(diag, agreement):
    """The diagnosis with the reference's `agreement` beside it: its failures and what it
    left untested make it inconclusive; a channel's residual of rounding holds no excursion."""
    diag.reference_agreement = agreement
    if "alike" in agreement:
        diag.unexplained = [u for u in diag.unexplained
                            if f"{u.get('sensor')}.{u.get('axis')}" not in agreement["alike"]]
    diag.inconclusive = (diag.inconclusive + agreement["failures"]
                         + agreement.get("untested", []))


@dataclass
class _Prepared:
    """What `diagnose` fits: the design and what of the samples the later steps read."""
    design: Design
    t: np.ndarray               # (N,) the MIMU's stamps, s
    usable: np.ndarray          # (N,) bool: samples in the fit
    norms: np.ndarray           # (nb, 4) the design's bins' `samples.Bins.norms`
    extremes: Extremes          # the flight conditions over the raw bins (`term_spans`)
    compensated: tuple | None   # (w rad/s, f m/s^2) (N, 3) sensor axes: the MIMU through the
                                # calibration, for the report (None: the flight streamed)
    full_scale: dict            # {"accel": m/s^2, "gyro": rad/s}
    on_outputs: list            # saturation and quantization findings
    quantized: set              # channels found quantized
    output_tests: bool          # the tests on the outputs were made
    agreement: dict | None      # `reference.agreement`, when checked
    jitter: list = dataclasses.field(default_factory=list)  # why stamps jitter (`stamp_jitter`), or ''


def _prepare(flight, cal, acc, candidates, output_tests, vibration, bin_s, noise_shape,
             max_wander, wander_steps, check_reference):
    """`_Prepared` of `diagnose`: the samples (`samples.sample_stage`: a streamed flight's
    spilled to scratch files for as long as this runs), whether the reference predicts the
    MIMU at all (`reference.agreement`: when it does not, no test on the outputs and no
    candidate but the gyros' free of specific force where only the accelerometers fail -
    `library.on_agreeing_gyros` - and the diagnosis says why), the tests on the outputs
    themselves, the design of the candidates on the bins with the stated accuracies as
    priors."""
    why = doubt = ""
    jitter = [stamp_jitter(flight.mimu_t, "the MIMU's"),  # before the bins are held: a
              stamp_jitter(flight.fog_t, "the reference IMU's")]  # stamp's steps are 8 B each
    if bin_s is None:
        bin_s, why, doubt = vibration_bin_s(flight.mimu_t, flight.fog_t, flight.fog_f)
    with tempfile.TemporaryDirectory(prefix="mimunav-diagnose-") \
            if flight.stream_block is not None else nullcontext() as folder:
        samples = sample_stage(flight, cal, folder)
        samples.vibration = vibration
        prep = _prepared(flight, cal, acc, candidates, output_tests, samples, bin_s,
                         noise_shape, max_wander, wander_steps, check_reference)
    prep.design.bins_why, prep.design.bins_doubt, prep.jitter = why, doubt, jitter
    return prep


def _prepared(flight, cal, acc, candidates, output_tests, samples, bin_s, noise_shape,
              max_wander, wander_steps, check_reference):
    q_sf = np.conjugate(flight.mimu_mounting.q_vs) * flight.fog_mounting.q_vs
    t, spill = samples.t, samples.spill
    finite = _finite(samples)
    usable = samples.inside & (samples.flags == 0) & finite
    usable[0] = False                       # the sample at the first stamp has no interval
    m = bins(t, flight.fog_t, bin_s)
    full_scale = library.full_scale(flight.mimu_range)
    declared = {k: flight.mimu_range[key] for k, key in (("accel", "accel_m_s2"),
                                                        ("gyro", "gyro_rad_s"))
                if key in flight.mimu_range}
    usable &= ~outputs.at_declared_range(spill.series("measured"), spill.series("predicted"),
                                         declared)
    lever = attitude.rotate(np.conjugate(flight.mimu_mounting.q_vs),
                            flight.mimu_mounting.lever_arm_m - flight.fog_mounting.lever_arm_m)
    gapped = across_gaps(t, flight.fog_t)       # first: a gap's bins are no shock's
    shocks = transfer_shocks(t, spill.series("measured"), spill.series("predicted"), lever, m,
                             usable & ~gapped)
    counted = outputs.counted_clips(t, flight.recording)
    usable &= ~shocks & ~counted & ~gapped
    on_outputs, quantized, rails = [], set(), np.zeros(len(t), bool)
    acc = rest_graded(flight, measured_steps(flight, acc, spill))
    cands = library.candidates() if candidates is None else candidates
    check = agreement(t, spill.series("measured"), spill.series("predicted"), usable,
                      CHANNELS) if check_reference else None
    if check is not None and check["failures"]:
        output_tests = False
        cands, check["untested"] = library.on_agreeing_gyros(cands, check["failed"])
    if output_tests:
        on_outputs, clipped, quantized, rails = _output_findings(cal, samples, finite,
                                                                 full_scale)
        usable = usable & ~clipped & ~rails
        # a quantized output's error depends on where its input falls between two steps:
        # terms of that channel alone would fit the lattice, not physics
        cands = [c for c in cands if not _on_channels_only(c, quantized)]
    prior = acc.prior(q_sf)
    terms = temperature_references(cands, samples, usable)
    binned_ = binned(samples, usable, m, terms, flight.stream_block if samples.streamed else None,
                     scratch=samples.streamed)
    design = make_design(binned_, terms, prior + calibration_prior(cal), cal,
                         transfer=(lever, prior[9:, 9:]))
    clock_se = (flight.recording or {}).get("reference_imu_clock_se_s")
    if clock_se:                    # the reference's clock, as measured by the import
        add_clock_nuisance(design, clock_se)
    design.q_vs = flight.mimu_mounting.attitude_wxyz
    design.bin_s = bin_s
    design.calibrated = not cal.is_identity
    design.arm_given = bool(np.any(lever))
    design.reference = acc
    design.shocks = outputs.spans(t, shocks, "the lever-arm transfer misses a shock: left out")
    design.rails = outputs.spans(t, rails, "an output at its extreme, bit for bit, where the "
                                 "reference reads beyond: a rail too short to name, left out")
    design.clips_counted = outputs.spans(t, counted, "the IMU's own clip counter rose: left out",
                                         gap_s=0.5)
    design.gaps = outputs.spans(t, gapped, "an IMU misses samples: left out", gap_s=0.5)
    if noise_shape is not None:
        fit_shape, scan_shape = noise_shape if isinstance(noise_shape, tuple) else \
            (noise_shape, noise_shape)
        design.shape, design.scan_shape = (Binning(m, usable)(np.asarray(x, float))[design.kept]
                                           for x in (fit_shape, scan_shape))
    if max_wander is not None:
        design.levels = wander.LAMBDA_GRID[wander.LAMBDA_GRID <= max_wander]
    design.wander_steps = wander_steps if wander_steps is not None or not acc.mems_grade \
        else track_reference.wander_steps(bin_s=bin_s)
    measured = None if samples.streamed else spill.column("measured")
    return _Prepared(design, t, usable, binned_.norms[design.kept],
                     Extremes(binned_.centres, *binned_.extremes.T),
                     None if measured is None else (np.ascontiguousarray(measured[:, 3:]),
                                                    np.ascontiguousarray(measured[:, :3])),
                     full_scale, on_outputs, quantized, output_tests, check)


def _finite(samples):
    """(N,) bool: the samples whose measured and predicted outputs are all finite, read a
    column at a time."""
    measured, predicted = samples.spill.series("measured"), samples.spill.series("predicted")
    finite = np.ones(len(samples.t), bool)
    for c in range(6):
        finite &= np.isfinite(measured[:, c]) & np.isfinite(predicted[:, c])
    return finite


def measured_steps(flight, acc, spill=None):
    """`acc` with the step a recording's reference IMU was logged in, where its data show one
    larger than stated (`outputs.lattice_step`; the triad's largest): a logger's values
    rounded to a step (a VN-300 written with 2 decimals: 0.01 rad/s) carry a rounding error
    that does not average away where the input moves slower than a step per sample. Not for
    a simulated or contract log, whose reference IMU counts pulses: its increments carry
    their rounding on (a 1 arcsec quantum at 1 kHz sits on a 0.005 rad/s lattice whose error
    does not accumulate)."""
    if flight.source != "recording":
        return acc
    steps = {}
    for k, sensor in enumerate(("gyro", "accel")):
        found = [q for q in (outputs.lattice_step(_reference_column(flight, spill, 3 * k + i))
                             for i in range(3)) if q]
        if found and max(found) > getattr(acc, f"{sensor}_step") * (1 + 1e-6):   # round-off
            steps[f"{sensor}_step"] = max(found)
    if not steps:
        return acc
    said = ", ".join(f"{k} {v:.4g}" for k, v in steps.items())
    return dataclasses.replace(acc, **steps, source=f"{acc.source}; logging steps measured from "
                               f"its outputs: {said}")


def _reference_column(flight, spill, c):
    """(M,) column c of the reference IMU's outputs [w rad/s, f m/s^2]: held by the flight,
    or spilled by a streamed one's `samples.sample_stage` (a recording's are not pulse
    counted: the spilled values are the log's)."""
    if flight.stream_block is not None:
        return spill.column("reference", c)
    return (flight.fog_w if c < 3 else flight.fog_f)[:, c % 3]


def _confirmed(flight, design, chosen, split, alpha, prep, mems_grade, remake):
    """`confirmation.confirmed` (a record's halves and noise too), and its findings read back
    to a noiseless reference (`errors_in_variables`: those its noise can make set aside with
    the halves') where they are at risk (`errors_in_variables.at_risk`): beside a MEMS-grade
    reference with the residual's white noise added (an upper bound), beside another in a
    recording with its own (`reference_white_noise`). split: (train, held rows, block s);
    remake(flight): the design of another flight as this one's was made."""
    train, held, block_s = split
    family, again, noisy = len(chosen), None, []
    while True:         # those the noise can make leave the fit, as the checks' do
        findings, rejected, aside, doubts, record = confirmed(
            design, chosen, train, held, alpha, prep, flight.source == "recording", family)
        own = not mems_grade and flight.source == "recording"
        if not errors_in_variables.at_risk(flight, findings, mems_grade):
            break
        if flight.fog_w is None:        # streamed: its reference is not held to add noise to
            doubts = doubts + [errors_in_variables.NOT_READ_BACK]
            break
        if again is None:
            added = errors_in_variables.reference_white_noise(
                flight.fog_t, flight.fog_w, flight.fog_f) if own else \
                errors_in_variables.white_per_sample(
                    design, 1.0 / float(np.median(np.diff(flight.fog_t))))
            again = remake(errors_in_variables.noisier(flight, added))
        findings, made = errors_in_variables.read_back(
            design, again, findings, lambda d: outputs.block_index(d.t, block_s) % 2 == 1,
            added, own)
        if not made:
            break
        noisy += made
        chosen = [c for c in chosen if c["j"] not in {position_of(design, f) for f in made}]
    return findings, rejected + noisy, aside + noisy, doubts, record


def _residuals(design, everything, findings, pinned=False):
    """(before, removed, fit): (nb, 6) the residual less the reference's fitted error
    without the found terms, detrended, and less the fitted error and the found terms with
    them (the all-rows `Fitter` everything), and that all-rows fit of the found terms;
    pinned: the reference's error held at zero in that fit."""
    before = detrended(design, design.residual - reference_error(design, everything.fit([])))
    found = [position_of(design, f) for f in findings]
    fit = everything.fit(found, pinned=pinned)
    removed = design.residual - reference_error(design, fit)
    for f, j in zip(findings, found):
        removed = removed - term_contribution(design, j, beta_of(f))
    return before, removed, fit


def _after_the_fit(design, residual, conds, terms, prep, alpha, cal, noise, output_tests):
    """(unexplained excursions, findings on the outputs, why offsets read two ways were set
    aside): localized excursions of the residual (`residual`: the residual with the found
    terms removed, their all-rows fit and the all-rows `Fitter`; `_residuals`) against a
    local baseline (the constant of a bias_shift removed later does not move them), then
    the bias tests on quiet flight away from them, whose offset null carries the found
    terms' removal error (`removal.removal_sigma`) and whose offset's interval holds its
    other readings (`removal.offset_readings`: with the terms neither found nor ruled out,
    with the reference's fitted error held to its stated accuracy); a wander read after a
    reference error beyond it is set aside (`removal.beside_reference`). An offset set aside
    for its readings makes the verdict inconclusive. terms: (findings, those not
    confirmed)."""
    (removed, fit_found, everything), (findings, unconfirmed) = residual, terms
    read_twice = []

    def scanned(x):                 # the residual as the scan reads it
        x = x.copy()
        if output_tests:
            x[:, sorted(prep.quantized)] = 0.0      # a lattice's own error is no excursion
        return x
    unexplained = excursions_left_out(
        design, lambda rows: scanned(_residuals(design, Fitter(design, rows), findings)[1]),
        alpha, excursions(design, scanned(removed), alpha))
    beyond = reference_beyond_stated(design, fit_found)
    if max(z for z, _ in beyond) > REFERENCE_BEYOND_SIGMA:
        unexplained, read_twice = held_excursions(unexplained, excursions(design, scanned(
            _residuals(design, everything, findings, pinned=True)[1]), alpha), beyond)
    on_outputs = list(prep.on_outputs)
    if output_tests:
        # an excursion is no wander of the bias, and no offset: its bins (and a scan window
        # either side) are left out of the bias tests - a 2 s bias pulse outside the
        # vocabulary had been named bias_instability beside the excursion it is
        quiet = conds["quiet"] & ~near_spans(design.t, unexplained, SCAN_WINDOW_S)
        skip = {(f["sensor"], f["axis"]) for f in on_outputs + findings
                if f["effect"] in OWN_OFFSET} | {CHANNELS[c] for c in prep.quantized}
        tested = outputs.bias_tests(
            design, removed, quiet, alpha / (len(design.terms) + 12), cal, skip=skip,
            noise=noise, carried=removal_sigma(design, fit_found, findings, quiet))
        tested = beside_reference(read_every_way(tested, offset_readings(
            design, everything, fit_found, unconfirmed, quiet, prep.full_scale)), beyond)
        on_outputs += tested
        read_twice += [f"{f['label']}: {f['rejected']}" for f in tested if "rejected" in f
                       and ("other_readings" in f or "reference_fitted_beyond_stated" in f)]
    return unexplained, on_outputs, read_twice


STAMP_JITTER = 0.25     # the stamps' error (robust sigma) over the period: beyond it a
                        # stamp does not tell which interval its sample averages


def stamp_jitter(t, whose):
    """Why the stamps `t` (s) cannot carry a sample-by-sample comparison, or '': their error
    against a uniform clock (robust sigma, from the steps' scatter: a step holds two stamps'
    errors) exceeds STAMP_JITTER of the median step (a recording stamped +-5 ms at 100 Hz
    gave spurious scale terms on the accelerometers). Stamps in whole ticks (`stamp_tick`:
    a logger that writes whole ms) whose steps stay within a tick of the period are a
    uniform clock rounded: their error is the rounding's, tick / sqrt 12, not jitter."""
    if t is None or len(t) < 10:
        return ""
    step = np.diff(t)
    period = float(np.median(step))
    spread = float(np.percentile(np.abs(step - period), 99))
    tick = stamp_tick(t)
    if tick and spread <= 1.001 * tick:     # whole ticks: the rounding's error, or none when
        sigma = tick / np.sqrt(12.0) if spread >= 0.5 * tick else 0.0    # the steps are equal
    else:
        sigma = float(np.median(np.abs(step - period))) / 0.6745 / np.sqrt(2.0)
    if period > 0 and sigma > STAMP_JITTER * period:
        rounded = f" (stamped in whole {tick * 1e3:g} ms)" if tick else ""
        return (f"{whose} stamps jitter by {sigma * 1e3:.2g} ms{rounded} (robust sigma of their "
                f"error) on a {period * 1e3:.3g} ms period: a stamp does not say which interval "
                "its sample averages, and terms driven by fast motion may be that jitter")
    return ""


def _too_little(flight, prep, bin_s, block_s, because):
    """The InputError of a flight with under four split blocks of usable bins: how much
    there is, and why most samples are unusable when they are (`because`, else the
    compensation's flags)."""
    inside = (prep.t >= flight.fog_t[0]) & (prep.t <= flight.fog_t[-1])
    flagged = float(np.mean(~prep.usable[inside])) if inside.any() else 0.0
    whose = "the vehicle model's" if because else "the reference IMU's"
    level = "the track level" if because else "the sensor level"
    return InputError(f"{flight.path}: {len(prep.design.t) * bin_s:.1f} s of usable MIMU "
                      f"samples inside {whose} span; {level} needs at "
                      f"least {4 * block_s:g} s" + (
                          f" ({flagged:.0%} of the samples unusable: "
                          + (because or "flagged saturated or wild by the compensation - "
                             "is the calibration this unit's?") + ")" if flagged > 0.5 else ""))


def _output_findings(cal, samples, finite, full_scale):
    """(saturation and quantization findings, samples clipped (N,) bool, quantized channels
    {channel index}, samples at a rail too short to name (N,) bool: `outputs.short_rails`):
    the tests on the outputs themselves (`outputs`), on every sample the
    compensation did not repair (a sample stuck at an extreme is flagged SATURATED there and
    is tested here), a column at a time. Quantization first: a quantized channel's clip test
    allows its step."""
    t, spill, flags = samples.t, samples.spill, samples.flags
    measured, predicted = spill.series("measured"), spill.series("predicted")
    rows = samples.inside & ((flags & (REPLACED | UNUSABLE)) == 0) & finite
    rows[0] = False
    live = rows & (flags == 0)
    sigma = outputs.noise_sigma_of(
        lambda c: np.where(live, measured[:, c] - predicted[:, c], np.nan), 6)
    volts = spill.series("volts") if "volts" in spill else None
    found = outputs.quantization(t, measured, volts, _volt_gains(cal, spill, live), live, sigma)
    steps = np.zeros(6)
    for f in found:
        steps[CHANNELS.index((f["sensor"], f["axis"]))] = f["coefficient"]
    train = outputs.block_index(t, SPLIT_BLOCK_S) % 2 == 0
    clips, clipped = outputs.saturation(t, measured, predicted, rows, train, full_scale, steps,
                                        sigma if np.array_equal(live, rows) else None)
    rails = short_rails(measured, predicted, rows, sigma,
                                {(c["sensor"], c["axis"]) for c in clips}) & ~clipped
    own = outputs.noise_sigma_of(lambda c: np.where(live, measured[:, c], np.nan), 6)
    return clips + found, clipped, outputs.undithered(steps, sigma, own), rails


def _on_channels_only(term, channels):
    """Whether `term` acts on one channel and it is among `channels` (indices)."""
    if term.get("sensor") not in ("accel", "gyro") or term.get("axis") not in AXES:
        return False
    return CHANNELS.index((term["sensor"], term["axis"])) in channels


def _volt_gains(cal, spill, rows):
    """(6, 3) the slope of each channel's output in SI per V of its own raw volts over the
    samples `rows` (median, smallest, largest magnitude): A1_ii + 2 A2_i V + 3 A3_i V^2 at
    the temperature-compensated V (eqs. 1-4; W for the gyros), from the `samples` spill's
    volts and temperatures, an axis at a time; ones without raw volts."""
    if "volts" not in spill or cal is None or cal.base_model not in ("entire-63", "linear"):
        return np.ones((6, 3))
    out = []
    for k, ((a1, a2, a3), poly, reading) in enumerate((
            ((cal.A1, cal.A2, cal.A3), cal.ct, "temperature"),
            ((cal.W1, cal.W2, cal.W3), cal.cw, "frequency"))):
        for i in range(3):
            temp = spill.column(reading, i)
            v = (spill.column("volts", 3 * k + i) - poly2(poly[i:i + 1], temp[:, None])[:, 0])[rows]
            slope = np.abs(a1[i, i] + 2 * a2[i] * v + 3 * a3[i] * v * v)
            out.append((np.median(slope), slope.min(), slope.max()))
    return np.asarray(out)


def verdict(diag):
    """The contract verdict: missing-physics when a term is confirmed, otherwise
    unexplained-residual when a localized excursion remains or the reference cannot explain
    the recording (an inconclusive track level), otherwise no-missing-physics."""
    if diag.findings:
        return "missing-physics"
    if diag.unexplained or getattr(diag, "inconclusive", None):
        return "unexplained-residual"
    return "no-missing-physics"


def term_z(diag, term):
    """How detectable `term` is on this flight: its Wald z (sqrt of the statistic) fitted
    alone on all rows; NaN when it is not among the candidates."""
    labels = [library.label(t) for t in diag.design.terms]
    if library.label(term) not in labels:
        return float("nan")
    j = labels.index(library.label(term))
    res = term_test(diag.fitter, [j], j)
    return math.sqrt(res["stat"])

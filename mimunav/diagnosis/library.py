"""The candidate library: every term of the effect vocabulary (`mimunav.compensation.effects`) that the
recorded conditions can drive, per channel and input axis, and the physical range of each.

Terms the conditions cannot drive on a flight (a column with no variation) are left out by
the diagnosis, and so is vibration_rectification on a flight that does not vibrate
(`vibrating`). Not in the library, because they are no regressor: saturation and
quantization (tests on the outputs themselves, `sensor.output_limits`), bias_shift and
bias_instability (the level and the wander of the fitted bias, `sensor.bias_tests`).
A lever_arm (the whole unit's position, one vector for the three accelerometers) competes
with each accelerometer's own size_effect: the data say which.
Time skews come three ways: the whole unit against the reference (`imu`), and each triad
alone (`accel`, `gyro`) - a lag of one triad against the other has a different signature
from the unit lagging the reference.
"""
import math
from itertools import combinations_with_replacement

import numpy as np

from ..compensation.effects import AXES
from ..sensors.mimu import MimuUnit

TEMPERATURE_RATE_WINDOWS_S = (60.0, 120.0, 300.0)
G0 = 9.80665
DEG = math.pi / 180
# effects of the temperature, slower than the diagnosis' blocks: tested against the bias
# wander by their likelihood, which a residual rms with the bias taken out does not show
SLOW_EFFECTS = ("temperature_bias", "temperature_rate", "temperature_scale",
                "thermal_hysteresis")


def candidates():
    """[term], terms without coefficients."""
    out = []
    for sensor in ("accel", "gyro"):
        for i, axis in enumerate(AXES):
            base = {"sensor": sensor, "axis": axis}
            out += [dict(base, effect="scale_factor")]
            out += [dict(base, effect="cross_coupling", input_axis=AXES[j])
                    for j in range(3) if j != i]
            out += [dict(base, effect="scale_asymmetry"),
                    dict(base, effect="scale_nonlinearity", order=2),
                    dict(base, effect="scale_nonlinearity", order=3),
                    dict(base, effect="temperature_scale")]
            if sensor == "gyro":
                out += [dict(base, effect="g_sensitivity", input_axis=a) for a in AXES]
                out += [dict(base, effect="g2_sensitivity", input_axis=a + b)
                        for a, b in combinations_with_replacement(AXES, 2)]
            else:
                out.append(dict(base, effect="size_effect"))
            out += [dict(base, effect="temperature_bias"), dict(base, effect="thermal_hysteresis")]
            out += [dict(base, effect="temperature_rate", window_s=n)
                    for n in TEMPERATURE_RATE_WINDOWS_S]
            out.append(dict(base, effect="vibration_rectification"))
    out += [{"effect": "time_skew", "sensor": s, "axis": "all"} for s in ("imu", "accel", "gyro")]
    out.append({"effect": "mounting_misalignment", "sensor": "imu", "axis": "all"})
    out.append({"effect": "lever_arm", "sensor": "imu", "axis": "all"})
    return out


VIBRATION_MIN_RMS_G = 0.1       # vibration_rectification is tested only on a flight whose
VIBRATION_MIN_SHARE = 0.05      # band-passed specific force reaches this rms on some axis over
# at least this share of the flight: below, the regressor is the reference's noise and the
# edges of manoeuvres leaking through the filter, which no airframe vibration makes


def vibrating(power):
    """Whether a vibration-power column (m/s^2)^2 shows vibration worth a rectification term."""
    return float(np.quantile(power, 1 - VIBRATION_MIN_SHARE)) > (VIBRATION_MIN_RMS_G * G0) ** 2


def label(term):
    """A short readable name with the input's physical symbol (f specific force, w angular
    rate): 'g_sensitivity gyro.x <- f_z', 'cross_coupling gyro.z <- w_x'."""
    s = f"{term['effect']} {term['sensor']}.{term['axis']}"
    if "input_axis" in term:
        symbol = "f" if term["effect"].startswith("g") or term["sensor"] == "accel" else "w"
        s += f" <- {symbol}_{term['input_axis']}"
    if "order" in term:
        s += f" (x^{term['order']})"
    if "window_s" in term:
        s += f" (n = {term['window_s']:g} s)"
    return s


def inputs(term):
    """The reference inputs a term is driven by, {(sensor, axis)}, when it is driven by
    single axes of the motion (scale terms: its own; cross-coupling: the input axis;
    g-sensitivity: the specific-force axes); None for terms of the whole motion
    (misalignment, time skew, proof-mass offsets) or of temperature alone."""
    effect, sensor, axis = term["effect"], term["sensor"], term["axis"]
    if effect in ("scale_factor", "scale_asymmetry", "scale_nonlinearity", "temperature_scale"):
        return {(sensor, axis)}
    if effect == "cross_coupling":
        return {(sensor, term["input_axis"])}
    if effect in ("g_sensitivity", "g2_sensitivity"):
        return {("accel", a) for a in term["input_axis"]}
    if effect == "vibration_rectification":
        return {("accel", axis)}
    return None


def channel_inputs(term):
    """For a term of the whole motion fitted on several output channels: {output channel
    (sensor, axis): the reference inputs its column is made of}; None for the others.
    mounting_misalignment: the rows of [x x] (channel i of a triad from the triad's two other
    inputs); time_skew: each channel from its own input's derivative. (size_effect and
    lever_arm take every rate of the gyros on every accelerometer channel.)"""
    effect, sensor = term["effect"], term["sensor"]
    triads = ("accel", "gyro") if sensor in ("imu", "all") else (sensor,)
    if effect == "mounting_misalignment":
        return {(s, a): {(s, b) for b in AXES if b != a} for s in triads for a in AXES}
    if effect == "time_skew":
        return {(s, a): {(s, a)} for s in triads for a in AXES}
    return None


def reads_own_outputs(term):
    """Whether the term's regressor is made of the outputs of the triad it acts on (`inputs`,
    `channel_inputs`: a scale or cross term, a misalignment, a time skew): measured from those
    outputs, the regressor carries the same noise as the error it drives (errors in
    variables). A vibration power does not (a mean square does not follow the noise's sign);
    nor do the gyros' rates on the accelerometers (lever arm) or the specific force on the
    gyros (g-sensitivity)."""
    if term["effect"] == "vibration_rectification":
        return False
    per_channel = channel_inputs(term)
    if per_channel is not None:
        return any(s == channel[0] for channel, ins in per_channel.items() for s, _ in ins)
    ins = inputs(term)
    return ins is not None and any(s == term["sensor"] for s, _ in ins)


def on_channels(term, channels):
    """`term` restricted to the output channels `channels` [(sensor, axis)] (its `channels`
    key, "sensor.axis" names, which the design honours); the others' columns are not fitted."""
    return dict(term, channels=sorted(f"{s}.{a}" for s, a in channels))


# A finding must show in the numbers the report prints: removing it must lower the held-out
# residual's rms in its third significant digit (rms ratio <= 0.9995, variance share >= 0.1 %).
# Below that, a term is significant only because the record is long (its statistic grows
# with the rows while its share does not) and changes nothing a user could check. The same
# share decides whether a lattice the outputs sit on matters (`outputs.quantization`).
MIN_VARIANCE_SHARE = 1e-3


# The physical range of each term for a MEMS unit (magnitude, SI units of the coefficient).
# Generous on purpose - several times the seeds' largest figure - so that a real term is never
# refused; a fitted value beyond it is a sign that a look-alike term is absorbing another's
# signature (a lag of the accelerometers fitted as a 0.2 m proof-mass offset), not a finding.
PHYSICAL_RANGE = {
    "scale_factor": 0.05,               # 5 %: Table 1/2 scale and cross terms are <= 2 %
    "cross_coupling": 0.05,             # Table 2: 0.1-2 % before calibration
    # k of k |x| (IEEE Std 528's asymmetry, the difference of the two slopes, is 2k):
    # datasheets seldom state it; a |x| kink of k shows as a best-fit nonlinearity of about
    # k/2 of full scale, which tactical MEMS parts keep within 0.05-0.3 % (consumer parts
    # 0.5-1 %), and this project's units draw 50-200 ppm: 1 % is a heuristic bound, set
    # after a foreign-03 transplant (development flights) where a 0.2 mg feature of the
    # lateral channel (|f_y| a few 0.01 m/s^2) passed for a 3.8 % asymmetry beside a
    # temperature term; checked on transplants of a fresh seed
    "scale_asymmetry": 0.01,
    "mounting_misalignment": 0.35,      # rad (20 deg): a mounting, not a machining error
    "size_effect": 0.05,                # m: proof masses sit within a few cm of the origin
    "lever_arm": 1.0,                   # m: a unit's position mis-measured in the airframe
    "time_skew": 1.0,                   # s
    # a consumer gyro as recorded: datasheets state a typical linear-acceleration
    # sensitivity of 0.1 (deg/s)/g (InvenSense MPU-6000) to 0.2 (Analog Devices ADXRS150,
    # ADXRS300) and seldom a maximum: 2.5 times the largest typical is this bound. A
    # unit compensated by its calibration is held to seed S1 Table 2's class
    # (CALIBRATED_RANGE); at 0.1 for both, true terms of 0.112 and 0.3 (deg/s)/g on two
    # independent simulators' recordings were measured (0.000222, 0.000516) and set aside
    "g_sensitivity": 0.5 * DEG / G0,
    "g2_sensitivity": 0.05 * DEG / G0 ** 2,   # datasheet class <= 0.01 (deg/s)/g^2
    ("temperature_bias", "accel"): 5e-3 * G0,     # 5 mg/degC (unit draws: <= 0.5 mg/degC)
    ("temperature_bias", "gyro"): 1.0 * DEG,      # 1 (deg/s)/Hz (draws <= 0.1 (deg/s)/Hz)
    ("temperature_rate", "accel"): 5e-3 * G0,
    ("temperature_rate", "gyro"): 1.0 * DEG,
    ("temperature_scale", "accel"): 1e-2,         # 1/degC
    ("temperature_scale", "gyro"): 1e-2,          # 1/Hz
    ("thermal_hysteresis", "accel"): 0.01 * G0,   # 10 mg
    ("thermal_hysteresis", "gyro"): 1.0 * DEG,    # 1 deg/s
    # 0.1 g (accel) and 5 deg/s (gyro) of DC shift from 1 g rms of vibration
    ("vibration_rectification", "accel"): 0.1 * G0 / G0 ** 2,
    ("vibration_rectification", "gyro"): 5 * DEG / G0 ** 2,
}
TRAJECTORY_LEVER_ARM = 10.0     # m: from a reference trajectory's point (a GNSS antenna, an
#                                 INS's reference point) to the MIMU, within one vehicle - a
#                                 car's 5 m, a boat's or a light aircraft's 10; an undeclared
#                                 1.4 m boat lever arm, found at its truth, had been refused
#                                 against the 1 m a unit beside a reference IMU may be off
NONLINEARITY_OF_RANGE = 0.2     # k2 x^2 or k3 x^3 at full scale: <= 20 % of full scale
# What a calibration leaves of the linear terms it estimates: seed S1 Table 1 bounds the
# scale-factor fit residual of a MEMS part by 0.05 % FS (accelerometer) and 0.2 % FS (gyro);
# ten times that is the most a unit compensated by its own calibration can still carry in a
# scale factor or an axis coupling. A larger term is a nuisance leaking into a weakly excited
# regressor (a lateral accelerometer in coordinated flight: a -2.8 % scale factor on an
# effect-free foreign flight) - or a calibration of another unit, which the report says.
CALIBRATED_RANGE = {("scale_factor", "accel"): 5e-3, ("scale_factor", "gyro"): 2e-2,
                    ("cross_coupling", "accel"): 5e-3, ("cross_coupling", "gyro"): 2e-2,
                    ("g_sensitivity", "gyro"): 0.1 * DEG / G0}   # Table 2: 0.01-0.04 (deg/s)/g


def full_scale(mimu_range):
    """{"accel": m/s^2, "gyro": rad/s}: the MIMU's full scale from a log's `range` metadata
    (`Flight.mimu_range`), the simulated unit's where the log does not say."""
    return {"accel": float(mimu_range.get("accel_m_s2", MimuUnit.range_accel)),
            "gyro": float(mimu_range.get("gyro_rad_s", MimuUnit.range_gyro))}


def physical_limit(term, full_scale, calibrated=False, arm_given=True):
    """The largest plausible magnitude of the term's coefficient (vector: its norm);
    `full_scale`: {"accel": m/s^2, "gyro": rad/s} of the MIMU (for nonlinearity);
    `calibrated`: the MIMU's outputs are compensated by a calibration of the unit (not the
    identity of a recording's outputs), which bounds its linear terms (CALIBRATED_RANGE);
    `arm_given`: a lever arm was given between the MIMU and its reference - else the arm is
    anywhere in one vehicle (TRAJECTORY_LEVER_ARM), not a place mis-measured (a survey
    ship's MEMS 1.58 m from its INS, no arm given, had its arm refused at 1 m and two gyro
    cross-couplings of 0.026 named in its place)."""
    effect = term["effect"]
    if effect == "lever_arm" and not arm_given:
        return TRAJECTORY_LEVER_ARM
    if effect == "scale_nonlinearity":
        x = full_scale[term["sensor"]]
        return NONLINEARITY_OF_RANGE / x ** (term["order"] - 1)
    if calibrated and (effect, term["sensor"]) in CALIBRATED_RANGE:
        return CALIBRATED_RANGE[(effect, term["sensor"])]
    return PHYSICAL_RANGE.get((effect, term["sensor"]), PHYSICAL_RANGE.get(effect, np.inf))


SECOND_ORDER = ("scale_asymmetry", "g2_sensitivity", "temperature_scale", "temperature_rate",
                "thermal_hysteresis", "size_effect", "lever_arm", "vibration_rectification")


def order(term):
    """The order of a term's physics, for parsimony among terms this flight cannot tell
    apart: 1 first-order (bias-like, linear in an input), 2 second-order (products, rates,
    proof-mass offsets), 3 cubic."""
    if term["effect"] == "scale_nonlinearity":
        return term["order"]
    return 2 if term["effect"] in SECOND_ORDER else 1


def beyond_range_said(term, size, limit, units):
    """A term's estimate `size` (its norm, in `units`) beyond its physical range `limit`, in
    words: for a mounting or a lever arm, what a given value wrong by more than the term
    holds would be, and where to give it again."""
    if term["effect"] == "mounting_misalignment":
        return (f"{math.degrees(size):.1f} deg, beyond the {math.degrees(limit):.0f} deg a "
                "small-angle term holds: either the mounting given is off by more than the "
                "diagnosis fits (this estimate falls short of such a turn: turn it back at "
                "import - --mounting-rpy-deg, or the spec's mounting_rpy_deg - and diagnose "
                "again), or the reference cannot carry the term here")
    if term["effect"] == "lever_arm" and limit >= TRAJECTORY_LEVER_ARM:
        return (f"{size:.3g} m, beyond the {limit:g} m of one vehicle: the reference cannot "
                "carry the term here")
    if term["effect"] == "lever_arm":
        return (f"{size:.3g} m, beyond the {limit:g} m a unit's place is mis-measured by: a "
                "lever arm between the two IMUs declared with a sign wrong errs by twice it "
                "- check the lever arms given at import (a table spec's lever_arm_m of [imu] "
                "and [reference_imu]; `mimunav import --reference-imu-lever-arm-m`) - or the "
                "reference cannot carry the term here")
    return f"{size:.3g} {units}, beyond its physical range ({limit:.3g})"


def apart_reasons(rejected, flight):
    """Why no finding on the accelerometers can stand: a lever arm fitted beyond its physical
    range (`beyond_range`) between the two IMUs - given at one point (their lever arms'
    difference all zero: the data put them apart) or given wrong by that much - every term
    is fitted through the transfer that arm leaves out (a train's cab IMU 8.3 m from its
    INS, no arm given: its arm fitted at 8.2 m and passed over, a time skew of -0.2 s named
    in its place and the verdict conclusive; a flight's reference declared 5 m from where it
    was: its arm fitted at 5.01 m, and a time skew, three cross-couplings and two bias
    instabilities of the accelerometers named beside it)."""
    given = bool(np.any(flight.mimu_mounting.lever_arm_m - flight.fog_mounting.lever_arm_m))
    return [f"{r['label']} {r['rejected']} - " + (
                "the lever arm given between the two IMUs is off by that much" if given else
                "and no lever arm was given between the two IMUs")
            for r in rejected if "beyond_range" in r and r["effect"] == "lever_arm"]


# the gyros' effects a unit's own mounting misalignment and time skew make too: without
# the accelerometers beside them they cannot be told apart (a MIMU mounted 1 deg off, its
# accelerometers failing the agreement, had been named four gyro cross-couplings; a unit's
# time skew, a gyro time skew)
UNIT_LOOKALIKES = ("cross_coupling", "time_skew")


def on_agreeing_gyros(cands, failed):
    """(the candidates that stand where the reference does not predict the MIMU's `failed`
    sensors ("accel", "gyro": `reference.agreement`), [why gyro candidates are not
    tested]): none where a gyro fails; where only the accelerometers do, the gyros' terms
    driven by no specific force (`inputs`) and not UNIT_LOOKALIKES - a lever arm
    not declared leaves the rates as they are (a ship's 14 m, not given, had left its
    gyro.z scale of 1 % untested: every candidate dropped)."""
    if "gyro" in failed:
        return [], []
    gyros = [c for c in cands if c["sensor"] == "gyro" and
             all(s == "gyro" for s, _ in (inputs(c) or ()))]
    kept = [c for c in gyros if c["effect"] not in UNIT_LOOKALIKES]
    return kept, [] if len(kept) == len(gyros) else [
        f"the gyros' {' and '.join(UNIT_LOOKALIKES)} not tested: with the accelerometers "
        "failing they cannot be told from the unit's mounting_misalignment and time_skew"]

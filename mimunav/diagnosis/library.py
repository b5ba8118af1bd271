"""The candidate library: every term of the effect vocabulary (`mimunav.effects`) that the
recorded conditions can drive, per channel and input axis, sorted into two tiers by the
time scale on which it acts:
    linear the terms linear in the sensor's own input - scale factor, cross-coupling,
           mounting misalignment - which the reference IMU also carries at its own accuracy.
           Tested on 100 Hz bins against a slowly varying bias (the wander nuisance, a
           piecewise-linear function of time) and the fast terms already chosen.
    fast   the rest that varies with the flight's manoeuvres (seconds): nonlinearity,
           asymmetry, g and g^2 sensitivity, temperature x input, time skew, proof-mass
           offsets. Tested on the same bins against the wander and a full linear response
           (`inference`: the reference's own scale and cross-coupling error must not pass
           for a non-linear term).
    slow   varies with temperature (minutes): temperature bias, temperature rate (several
           windows), thermal hysteresis. Tested on 1 s bins against a constant bias plus
           the unit's flicker wander and white noise as a covariance.
Terms the conditions cannot drive on this flight (a column with no variation) are left out.
Not in the library: saturation and quantization (visible in the raw log, not as a
regressor), vibration_rectification (no vibration channel in mimunav's logs),
bias_instability (a noise level, not a term), lever_arm (for an IMU-wide separation the
size_effect of each axis is tested; a joint one adds nothing the three cannot show).
"""
from itertools import combinations_with_replacement

from ..effects import AXES

TEMPERATURE_RATE_WINDOWS_S = (60.0, 120.0, 300.0)


def candidates():
    """[(tier, term)], terms without coefficients."""
    out = []
    for sensor in ("accel", "gyro"):
        for i, axis in enumerate(AXES):
            base = {"sensor": sensor, "axis": axis}
            linear = [dict(base, effect="scale_factor")]
            linear += [dict(base, effect="cross_coupling", input_axis=AXES[j])
                       for j in range(3) if j != i]
            fast = [dict(base, effect="scale_asymmetry"),
                    dict(base, effect="scale_nonlinearity", order=2),
                    dict(base, effect="scale_nonlinearity", order=3),
                    dict(base, effect="temperature_scale")]
            if sensor == "gyro":
                fast += [dict(base, effect="g_sensitivity", input_axis=a) for a in AXES]
                fast += [dict(base, effect="g2_sensitivity", input_axis=a + b)
                         for a, b in combinations_with_replacement(AXES, 2)]
            else:
                fast.append(dict(base, effect="size_effect"))
            slow = [dict(base, effect="temperature_bias"), dict(base, effect="thermal_hysteresis")]
            slow += [dict(base, effect="temperature_rate", window_s=n)
                     for n in TEMPERATURE_RATE_WINDOWS_S]
            out += [("linear", term) for term in linear] + [("fast", term) for term in fast]
            out += [("slow", term) for term in slow]
    out.append(("fast", {"effect": "time_skew", "sensor": "imu", "axis": "all"}))
    out.append(("linear", {"effect": "mounting_misalignment", "sensor": "imu", "axis": "all"}))
    return out


def label(term):
    """A short readable name: 'g_sensitivity gyro.x <- f_z'."""
    s = f"{term['effect']} {term['sensor']}.{term['axis']}"
    if "input_axis" in term:
        s += f" <- {'f' if term['effect'].startswith('g') else term['sensor'][0]}_{term['input_axis']}"
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
    return None

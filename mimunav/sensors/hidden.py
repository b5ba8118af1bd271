"""Physics the 63-coefficient model lacks, written as sensor behaviour: what a real MIMU does
to its true inputs (exact interval-mean specific force and rate at the sensor, true sensor
temperatures) beyond the model - for simulated recordings that hide an effect from the
diagnosis (`mimunav simulate --hide`, the concealed-data proof).

This is deliberately not `mimunav.compensation.effects`: the diagnosis builds its regressors there from
what the *reference IMU* says the motion was (Savitzky-Golay derivatives, the gyro's
resonance frequency as its thermometer); here each effect is computed from the truth the
simulator holds, each in its own few lines, and tested against closed forms
(tests/test_hidden.py). A shared mistake would otherwise prove itself.

A hidden effect is given in the contract's terms (log contract section 3: effect, sensor,
axis, input axis, coefficient in SI per unit of the contract's regressor; vectors for
size_effect and mounting_misalignment), so its answer key compares directly with a
diagnosis. Gyro temperature coefficients are per Hz of resonance frequency in the contract;
the behaviour acts on the gyro's true temperature through the unit's frequency slope
(f = f0 (1 + tcf (T - 25)), `sensors.thermal`). One effect outside the vocabulary,
`bias_pulse` (a transient offset over [t0, t1], e.g. after a shock), lets the proof check that
physics the library cannot name is reported as an unexplained residual with its place.

Syntax of `--hide` (units: the contract's SI units of the coefficient):
    EFFECT:SENSOR:AXIS[:INPUT]=VALUE[@KEY=VALUE...]
    g_sensitivity:gyro:x:z=1.8e-5            (rad/s)/(m/s^2), gyro x picks up f_z
    cross_coupling:gyro:z:x=6e-4             1, gyro z picks up w_x
    scale_nonlinearity:accel:y=2e-6@order=2  1/(m/s^2)
    temperature_rate:accel:x=2e-3@window_s=120
    time_skew:accel:all=5e-4                 s, the accelerometer triad lags
    size_effect:accel:z=0.004/0/-0.002       m, proof-mass offset (vector: a/b/c)
    mounting_misalignment:imu:all=1e-3/0/0   rad, small rotation vector (sensor axes)
    bias_pulse:gyro:y=2e-3@t0=40@t1=43       rad/s over [t0, t1] s (outside the vocabulary)
"""
import math

import numpy as np
from ..errors import InputError

AXES = "xyz"
VECTOR = ("size_effect", "mounting_misalignment")
WHOLE = ("mounting_misalignment",)
EFFECTS = ("bias_shift", "scale_factor", "cross_coupling", "scale_nonlinearity",
           "scale_asymmetry", "g_sensitivity", "g2_sensitivity", "temperature_bias",
           "temperature_scale", "temperature_rate", "thermal_hysteresis", "time_skew",
           "size_effect", "mounting_misalignment", "bias_pulse")
OUTSIDE_VOCABULARY = ("bias_pulse",)
HYSTERESIS_WINDOW_S = 10.0      # sign of the temperature's slope over this window


class HiddenPhysics:
    """One hidden effect; callable as the `hidden` hook of `MimuUnit.simulate`
    (f, w, ctx) -> (f, w). `thermal`: the unit's `ThermalModel` (for gyro temperature
    terms, per Hz -> per degC)."""

    def __init__(self, term, thermal=None):
        self.term = dict(term)
        self.thermal = thermal
        _check(self.term)

    @classmethod
    def parse(cls, text, thermal=None):
        """From the `--hide` syntax (module doc)."""
        return cls(parse_term(text), thermal)

    def as_dict(self):
        out = dict(self.term)
        out["outside_vocabulary"] = self.term["effect"] in OUTSIDE_VOCABULARY
        return out

    def __call__(self, f, w, ctx):
        """The outputs f (m/s^2), w (rad/s), (N, 3) sensor axes, with the effect added (new
        arrays; ctx: the record's truth, `MimuRecorder`)."""
        f, w = f.copy(), w.copy()
        self.add_to(f, w, ctx)
        return f, w

    def add_to(self, f, w, ctx):
        """Add the effect to the outputs f, w in place."""
        t, f_true, w_true = ctx["t"], ctx["f_true"], ctx["w_true"]
        term, effect = self.term, self.term["effect"]
        out = {"accel": f, "gyro": w}
        true = {"accel": f_true, "gyro": w_true}
        if effect == "time_skew":
            for s in (("accel", "gyro") if term["sensor"] == "imu" else (term["sensor"],)):
                out[s] += delayed(t, true[s], term["coefficient"]) - true[s]
        elif effect == "mounting_misalignment":    # sensor frame turned by phi: x' = R(phi)' x
            from scipy.spatial.transform import Rotation    # an independent rotation oracle
            turn = Rotation.from_rotvec(term["vector"]).inv()
            for s in ("accel", "gyro"):
                out[s] += turn.apply(true[s]) - true[s]
        elif effect == "size_effect":              # proof mass at r: rigid-body acceleration
            r = np.asarray(term["vector"], float)
            w_dot = np.gradient(w_true, t, axis=0)
            i = AXES.index(term["axis"])
            extra = np.cross(w_true, np.cross(w_true, r)) + np.cross(w_dot, r)
            f[:, i] += extra[:, i]
        else:
            i = AXES.index(term["axis"])
            out[term["sensor"]][:, i] += self._scalar(t, true, ctx) * term["coefficient"]

    def _scalar(self, t, true, ctx):
        """The effect's signal per unit coefficient on the named axis."""
        term, effect = self.term, self.term["effect"]
        sensor, i = term["sensor"], AXES.index(term["axis"])
        x = true[sensor]
        inputs = [AXES.index(a) for a in term.get("input_axis", "")]
        if effect == "bias_shift":
            return np.ones(len(t))
        if effect == "bias_pulse":
            return ((t >= term["t0"]) & (t <= term["t1"])).astype(float)
        if effect == "scale_factor":
            return x[:, i]
        if effect == "cross_coupling":
            return x[:, inputs[0]]
        if effect == "scale_asymmetry":
            return np.abs(x[:, i])
        if effect == "scale_nonlinearity":
            return x[:, i] ** int(term["order"])
        if effect == "g_sensitivity":
            return true["accel"][:, inputs[0]]
        if effect == "g2_sensitivity":
            return true["accel"][:, inputs[0]] * true["accel"][:, inputs[1]]
        reading = self._temperature_reading(ctx, sensor, i)
        if effect == "temperature_bias":          # from the record's first reading
            first = ctx.get("first")
            return reading - (reading[0] if first is None else
                              self._temperature_reading(first, sensor, i)[0])
        if effect == "temperature_scale":        # about the flight's mean, as the contract's
            return (reading - reading.mean()) * x[:, i]     # regressor: no scale factor added
        if effect == "temperature_rate":
            before = np.interp(t - term["window_s"], t, reading)   # held at the start
            return reading - before
        if effect == "thermal_hysteresis":
            half = HYSTERESIS_WINDOW_S / 2
            slope = np.interp(t + half, t, reading) - np.interp(t - half, t, reading)
            return np.sign(slope)
        raise InputError(f"hidden effect {effect!r} has no behaviour here")

    def reach(self):
        """(s before, s after, whole): how far in time the effect at a sample looks back and
        ahead; whole: it needs a statistic of the whole record (the flight's mean
        temperature of temperature_scale), so the record cannot be made block by block."""
        term, effect = self.term, self.term["effect"]
        if effect == "time_skew":
            tau = float(term["coefficient"])
            return max(tau, 0.0), max(-tau, 0.0), False
        if effect == "temperature_rate":
            return float(term["window_s"]), 0.0, False
        if effect == "thermal_hysteresis":
            return HYSTERESIS_WINDOW_S / 2, HYSTERESIS_WINDOW_S / 2, False
        return 0.0, 0.0, effect == "temperature_scale"

    def _temperature_reading(self, ctx, sensor, i):
        """The true temperature in the contract's regressor units: degC for accelerometers;
        for gyros the noise-free resonance frequency of the true gyro temperature, Hz."""
        if sensor == "accel":
            return ctx["accel_temperature"][:, i]
        if self.thermal is None:
            raise InputError("a gyro temperature effect needs the unit's thermal model")
        f0, tcf = self.thermal.f0[i], self.thermal.tcf[i]
        return f0 * (1 + tcf * (ctx["gyro_temperature"][:, i] - 25.0))


class HiddenSet:
    """Several hidden effects, applied in turn (each to the outputs the previous left)."""

    def __init__(self, effects):
        self.effects = list(effects)

    def __call__(self, f, w, ctx):
        f, w = f.copy(), w.copy()
        self.add_to(f, w, ctx)
        return f, w

    def add_to(self, f, w, ctx):
        """Add the effects to f, w in place (a plain callable's result is written back)."""
        for effect in self.effects:
            if hasattr(effect, "add_to"):
                effect.add_to(f, w, ctx)
            else:                       # on copies: it may return its inputs, crosswise
                f_new, w_new = effect(f.copy(), w.copy(), ctx)
                f[...], w[...] = f_new, w_new

    def as_dict(self):
        return [e.as_dict() for e in self.effects]


def parse_term(text):
    """A hidden effect's term (dict) from the `--hide` syntax (module doc), checked."""
    try:
        head, rest = text.split("=", 1)
        parts = head.split(":")
        value, *options = rest.split("@")
        term = {"effect": parts[0], "sensor": parts[1], "axis": parts[2]}
        if len(parts) > 3:
            term["input_axis"] = parts[3]
        numbers = [float(v) for v in value.split("/")]
        if term["effect"] in VECTOR:
            term["vector"] = numbers
        else:
            (term["coefficient"],) = numbers
        for opt in options:
            key, v = opt.split("=", 1)
            term[key] = int(v) if key == "order" else float(v)
    except (ValueError, IndexError):
        raise InputError(f"--hide {text!r}: expected EFFECT:SENSOR:AXIS[:INPUT]=VALUE"
                         "[@KEY=VALUE...] (see `mimunav simulate --help`)") from None
    _check(term)
    return term


def delayed(t, x, tau):
    """Interval means over (t[k-1] - tau, t[k] - tau] of a signal given as interval means x
    (N, k) over (t[k-1], t[k]]: its running integral at the shifted edges, differenced (the
    integral is piecewise linear between the samples' edges; the ends hold)."""
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0]))
    edges = np.concatenate([[t[0] - dt[0]], t])
    area = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x * dt[:, None], axis=0)])
    at = np.column_stack([np.interp(edges - tau, edges, area[:, j]) for j in range(x.shape[1])])
    return np.diff(at, axis=0) / dt[:, None]


def _check(term):
    effect = term.get("effect")
    if effect not in EFFECTS:
        raise InputError(f"hidden effect {effect!r}: one of {', '.join(EFFECTS)}")
    sensor = term.get("sensor")
    allowed = (("imu",) if effect in WHOLE else ("accel",) if effect == "size_effect" else
               ("gyro",) if effect.startswith("g") and effect.endswith("sensitivity") else
               ("imu", "accel", "gyro") if effect == "time_skew" else ("accel", "gyro"))
    if sensor not in allowed:
        raise InputError(f"{effect}: sensor must be one of {allowed}")
    if effect in WHOLE + ("time_skew",):
        if term.get("axis") != "all":
            raise InputError(f"{effect}: axis must be 'all' (it acts on whole triads)")
    elif term.get("axis") not in tuple(AXES):
        raise InputError(f"{effect}: axis must be x, y or z")
    need = {"cross_coupling": 1, "g_sensitivity": 1, "g2_sensitivity": 2}.get(effect, 0)
    if len(term.get("input_axis", "")) != need or any(a not in AXES for a in term.get("input_axis", "")):
        raise InputError(f"{effect}: needs {need} input axis letter(s) of x, y, z")
    if effect == "scale_nonlinearity" and term.get("order") not in (2, 3):
        raise InputError("scale_nonlinearity: @order=2 or @order=3")
    if effect == "temperature_rate" and not term.get("window_s", 0) > 0:
        raise InputError("temperature_rate: @window_s=SECONDS (> 0)")
    if effect == "bias_pulse" and not term.get("t1", -math.inf) > term.get("t0", math.inf):
        raise InputError("bias_pulse: @t0=S@t1=S with t1 > t0 (s since the flight's start)")
    value = np.atleast_1d(np.asarray(term.get("vector", term.get("coefficient", np.nan)), float))
    if value.shape != ((3,) if effect in VECTOR else (1,)) or not np.isfinite(value).all():
        raise InputError(f"{effect}: needs a finite {'vector a/b/c' if effect in VECTOR else 'value'}")

"""Transplants: the foreign development flights (`shared/data/foreign-flights`, written by an
independent simulator) with their own hidden effect taken out and another effect of the
contract's vocabulary put in - so the diagnosis can be tried on every effect class over
flights, reference IMUs, noise and units this project did not write.

How a transplant is made, and what it shares with the diagnosis:
  1. the log's raw MIMU outputs are compensated with its calibration file (the unit's true
     coefficients, so the result is the true motion plus the unit's noise and wander plus the
     foreign hidden effect), and the foreign effect's own per-sample signal
     (`NN.effect.npz`, SI at the MIMU's stamps) is subtracted: an effect-free carrier;
  2. the new effect is sensor behaviour written here in a few lines each, acting on the
     carrier's own outputs (clipping, quantizing, offsets, wander: what a sensor does to what
     it measures) or, for the lever arm, on the rigid-body motion that scipy's RotationSpline
     derives from the log's own /truth/state attitudes - never on the reference IMU's
     outputs, from which the diagnosis builds its regressors (`mimunav.compensation.effects`);
  3. the outputs go back to raw volts through the calibration (`raw_from_physics`): that
     inverse is this project's, which is why the foreign logs themselves, not transplants, are
     the development set's score.
Vibration (for `vibration_rectification`) is added to both IMUs as an exact interval mean of
a sinusoidal linear vibration of the airframe, as it would be recorded by both.

Every effect of the vocabulary has a behaviour here (temperature terms on the log's own
temperature readings, about their mean as the contract's regressors are). A spec is
`EFFECT:SENSOR:AXIS[:INPUT]=VALUE[@KEY=VALUE]` (the `--hide` syntax of `sensors.hidden`), with
`saturation` VALUE the clip level (SI), `quantization` the step (SI), `bias_instability` the
stationary sigma of an added first-order Gauss-Markov wander (tau 100 s), `lever_arm`
(`imu:all=a/b/c`) the position error in the vehicle frame (m).
"""
import dataclasses
import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, RotationSpline

from ..compensation.calibration_file import Calibration
from ..compensation.model import compensate, raw_from_physics
from ..evaluation.flight import Flight
from ..sensors.hidden import parse_term
from ..frames import attitude

AXES = "xyz"
GM_TAU_S = 100.0
VIBRATION_HZ = 117.0            # airframe vibration (transplants of vibration_rectification)
VIBRATION_G = 2.0               # its amplitude per axis, g, during the vibrating spans
G0 = 9.80665


def carrier(base):
    """(Flight, Calibration, f0 m/s^2, w0 rad/s): foreign log `base` (path without .mcap)
    compensated with its calibration, its own hidden effect removed (sensor axes; a log
    without an NN.effect.npz hides none)."""
    base = str(base)
    flight = Flight.load(base + ".mcap")
    cal = Calibration.load(base + ".cal.json")
    raw = flight.mimu_raw
    f, w, _ = compensate(cal, raw["accel_volts"], raw["gyro_volts"], raw["accel_temperature"],
                         raw["gyro_frequency"], filter_outliers=False)
    if not Path(base + ".effect.npz").exists():      # an effect-free log has none to take out
        return flight, cal, f, w
    effect = np.load(base + ".effect.npz")
    if len(effect["t"]) != len(flight.mimu_t) or \
            np.max(np.abs(effect["t"] - flight.mimu_t)) > 1e-6:
        raise ValueError(f"{base}.effect.npz is not at the log's MIMU stamps")
    return flight, cal, f - effect["d_accel"], w - effect["d_gyro"]


def transplant(base, spec, seed=0):
    """(Flight with the effect of `spec` hidden in its MIMU, calibration, answer key)."""
    flight, cal, f, w = carrier(base)
    term = parse_spec(spec)
    rng = np.random.default_rng(seed)
    out = {"accel": f.copy(), "gyro": w.copy()}
    effect, sensor = term["effect"], term["sensor"]
    i = AXES.index(term["axis"]) if term["axis"] in AXES else None
    value = term.get("coefficient")
    if effect == "lever_arm":
        out["accel"] += lever_arm_specific_force(flight, np.asarray(term["vector"]))
    elif effect == "vibration_rectification":
        flight, vibration = vibrate(flight, out)
        m = max(1, int(round(0.5 / np.median(np.diff(flight.mimu_t)))))
        power = np.convolve(vibration[:, i] ** 2, np.ones(m) / m, "same")
        out[sensor][:, i] += value * power
    elif effect == "saturation":
        out[sensor][:, i] = np.clip(out[sensor][:, i], -value, value)
    elif effect == "quantization":
        out[sensor][:, i] = value * np.round(out[sensor][:, i] / value)
    elif effect == "bias_shift":
        out[sensor][:, i] += value
    elif effect == "bias_instability":
        out[sensor][:, i] += gauss_markov(flight.mimu_t, value, GM_TAU_S, rng)
    elif effect in ("time_skew", "mounting_misalignment", "size_effect"):
        _whole_unit(flight, term, out)
    else:
        out[sensor][:, i] += value * _per_unit(flight, term, out)
    raw = dict(flight.mimu_raw)
    raw["accel_volts"], raw["gyro_volts"] = raw_from_physics(
        cal, out["accel"], out["gyro"], raw["accel_temperature"], raw["gyro_frequency"])
    name = f"{Path(str(base)).name}+{spec}"
    flight = dataclasses.replace(flight, mimu_raw=raw, name=name, path=name)
    return flight, cal, dict(term, spec=spec, carrier=Path(str(base)).name)


def _per_unit(flight, term, out):
    """(N,) an axis effect's behaviour per unit coefficient, from the carrier's own outputs
    `out` and temperature readings (the accelerometer case thermistors; the gyro's resonance
    frequency), each about the log's mean where the contract says so."""
    effect, sensor = term["effect"], term["sensor"]
    i = AXES.index(term["axis"])
    j = [AXES.index(a) for a in term.get("input_axis", "")]
    x = out[sensor]
    raw = flight.mimu_raw
    theta = (raw["accel_temperature"] if sensor == "accel" else raw["gyro_frequency"])[:, i]
    t = flight.mimu_t
    if effect == "scale_asymmetry":
        return np.abs(x[:, i])
    if effect == "scale_factor":
        return x[:, i].copy()
    if effect == "cross_coupling":
        return x[:, j[0]].copy()
    if effect == "scale_nonlinearity":
        return x[:, i] ** int(term["order"])
    if effect == "g_sensitivity":
        return out["accel"][:, j[0]].copy()
    if effect == "g2_sensitivity":
        return out["accel"][:, j[0]] * out["accel"][:, j[1]]
    if effect == "temperature_bias":
        return theta - theta.mean()
    if effect == "temperature_scale":
        return (theta - theta.mean()) * x[:, i]
    if effect == "temperature_rate":                # T(t) - T(t - n), held at the start
        return theta - np.interp(t - float(term["window_s"]), t, theta)
    if effect == "thermal_hysteresis":              # sign of the slope over 10 s
        slope = np.interp(t + 5.0, t, theta) - np.interp(t - 5.0, t, theta)
        return np.sign(slope)
    raise ValueError(f"transplant has no behaviour for {effect!r}")


def _whole_unit(flight, term, out):
    """Effects of a triad or the whole unit, in place on `out`: a time skew (the outputs
    describe the motion tau earlier: their cumulative increments through a cubic spline at
    t - tau, differenced), a mounting misalignment (every output turned by R(phi)^T, scipy's
    Rotation), a proof-mass offset r (sensor axes) of one accelerometer (the rigid-body term
    of `lever_arm_specific_force`, that axis only)."""
    effect = term["effect"]
    if effect == "time_skew":
        from scipy.interpolate import CubicSpline
        t = flight.mimu_t
        dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
        edges = np.concatenate([[t[0] - dt[0]], t])
        tau = float(term["coefficient"])
        for s in (("accel", "gyro") if term["sensor"] == "imu" else (term["sensor"],)):
            cum = np.vstack([np.zeros((1, 3)), np.cumsum(out[s] * dt[:, None], axis=0)])
            moved = CubicSpline(edges, cum, axis=0)(np.clip(edges - tau, edges[0], edges[-1]))
            out[s][:] = np.diff(moved, axis=0) / dt[:, None]
    elif effect == "mounting_misalignment":
        turn = Rotation.from_rotvec(term["vector"]).inv()
        for s in ("accel", "gyro"):
            out[s][:] = turn.apply(out[s])
    else:                                   # size_effect: r in sensor axes, one accelerometer
        i = AXES.index(term["axis"])
        r_v = attitude.as_scipy(flight.mimu_mounting.q_vs).apply(np.asarray(term["vector"], float))
        out["accel"][:, i] += lever_arm_specific_force(flight, r_v)[:, i]


def parse_spec(spec):
    """The answer-key term (dict) of a transplant spec (module doc): the `--hide` syntax,
    plus the classes only a transplant hides (saturation level, quantization step, wander
    sigma, vibration rectification, lever arm vector)."""
    effect = spec.split(":", 1)[0]
    if effect in ("saturation", "quantization", "bias_instability", "vibration_rectification",
                  "lever_arm"):
        head, value = spec.split("=")
        effect, sensor, axis = head.split(":")
        if effect == "lever_arm":
            return {"effect": effect, "sensor": "imu", "axis": "all",
                    "vector": [float(v) for v in value.split("/")]}
        return {"effect": effect, "sensor": sensor, "axis": axis, "coefficient": float(value)}
    return parse_term(spec)


def gauss_markov(t, sigma, tau, rng):
    """First-order Gauss-Markov sequence at times t (s) with stationary sigma, started from
    its stationary distribution."""
    dt = np.diff(t, prepend=t[0])
    phi = np.exp(-dt / tau)
    drive = rng.standard_normal(len(t)) * sigma * np.sqrt(1 - phi ** 2)
    drive[0] = rng.standard_normal() * sigma
    out = np.empty(len(t))
    acc = 0.0
    for k in range(len(t)):
        acc = phi[k] * acc + drive[k]
        out[k] = acc
    return out


def lever_arm_specific_force(flight, r_v):
    """(N, 3) m/s^2, sensor axes: the extra specific force of a sensor r_v (m, vehicle
    frame) further from the vehicle origin than its metadata says, w x (w x r) + dw/dt x r,
    as the MIMU records it: the mean over each sample's interval (t[k-1], t[k]] (log
    contract; Simpson's rule - the value at the stamp is the motion half a sample later,
    which at z ~ 3000 moved a fitted arm by 2-3 sigma), with the body rate and its
    derivative from scipy's RotationSpline through the /truth/state attitudes. Earth and
    transport rates are left out: beside the body rate they add ~1e-5 m/s^2 at these arms,
    moving a fitted arm by < 0.01 mm."""
    tr = flight.truth
    spline = RotationSpline(tr.t, attitude.as_scipy(tr.q_nb))
    t = flight.mimu_t
    dt = np.diff(t, prepend=t[0] - np.median(np.diff(t))) if len(t) > 1 else np.zeros(len(t))

    def rigid_body(s):                  # at times s (held at the truth's ends), vehicle frame
        s = np.clip(s, tr.t[0], tr.t[-1])
        w, dw = spline(s, 1), spline(s, 2)
        return np.cross(w, np.cross(w, r_v)) + np.cross(dw, r_v)
    extra_v = (rigid_body(t - dt) + 4 * rigid_body(t - dt / 2) + rigid_body(t)) / 6
    extra_v[(t < tr.t[0]) | (t > tr.t[-1])] = 0.0       # samples beyond the truth: none
    return _to_sensor(flight.mimu_mounting, extra_v)


def _to_sensor(mounting, x_v):
    """Vehicle-frame vectors (N, 3) in the sensor axes of `mounting`."""
    return attitude.as_scipy(mounting.q_vs).inv().apply(x_v)


def vibrate(flight, out):
    """(a copy of `flight` whose reference IMU carries a sinusoidal linear vibration of the
    airframe, the vibration the MIMU feels (N, 3) m/s^2 in its axes): VIBRATION_G per vehicle
    axis at VIBRATION_HZ (phases 0, 1, 2 rad), switched on over the middle third of the
    MIMU's record and its last tenth - one airframe signal, integrated exactly over each
    sample's own interval by either IMU (so IMUs at different rates record the same
    switching); the MIMU's outputs `out` get it in place. Its power on an axis is the mean
    square of this known signal, no filter needed."""
    t_m = flight.mimu_t
    span = t_m[-1] - t_m[0]
    spans = [(t_m[0] + span / 3, t_m[0] + 2 * span / 3), (t_m[0] + 0.9 * span, np.inf)]
    om = 2 * math.pi * VIBRATION_HZ
    phase = np.arange(3)[None, :]

    def integral(t):            # int_-inf^t of the switched vibration, (N, 3)
        total = np.zeros((len(t), 3))
        for a, b in spans:
            upper = np.clip(t, a, b)[:, None]
            total += (np.cos(om * a + phase) - np.cos(om * upper + phase)) / om
        return VIBRATION_G * G0 * total

    def interval_mean(t):
        dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
        return (integral(t) - integral(t - dt)) / dt[:, None]
    vibration = _to_sensor(flight.mimu_mounting, interval_mean(t_m))
    out["accel"] += vibration
    fog_f = flight.fog_f + _to_sensor(flight.fog_mounting, interval_mean(flight.fog_t))
    return dataclasses.replace(flight, fog_f=fog_f), vibration


# ---- effect-free variants: the false-alarm bench's nulls ---------------------------------
DEG_H = math.pi / 180 / 3600
MG = G0 * 1e-3
# in-class wander of a calibrated MEMS unit (seed S1 Table 1: zero drift <= 30 deg/h, ~1 mg):
# per channel a stationary sigma drawn log-uniform in these bounds, well inside the class
NULL_WANDER = {"gyro": (3 * DEG_H, 15 * DEG_H), "accel": (0.05 * MG, 0.5 * MG)}
NULL_TAU_S = (30.0, 600.0)      # its correlation time (or a random walk's time scale), s
REFERENCE_SCALE, REFERENCE_MISALIGNMENT = 2.5e-4, 1e-4     # `sensors.accuracy.Accuracy`'s defaults


def null_variant(base, seed):
    """(Flight, Calibration, what was drawn): foreign log `base` made effect-free (`carrier`)
    and then varied as real flights vary, without any effect outside the models: the MIMU's
    bias wanders in its class on every channel (first-order Gauss-Markov with a correlation
    time of 30-600 s, or a random walk of that time scale); the reference IMU carries
    scale-factor and misalignment errors drawn at the accuracy the diagnosis assumes; and,
    each with probability 1/3, airframe vibration on both IMUs, both IMUs at half their
    rate (exact: interval means of pairs), the MIMU mounted in another orientation (its
    outputs and mounting turned together)."""
    rng = np.random.default_rng([seed, 11])
    flight, cal, f, w = carrier(base)
    out = {"accel": f.copy(), "gyro": w.copy()}
    what = {"carrier": Path(str(base)).name, "seed": seed}
    what["wander"] = _wander(flight.mimu_t, out, rng)
    errors = what["reference_error"] = _reference_errors(rng)
    if rng.uniform() < 1 / 3:
        flight, _ = vibrate(flight, out)
        what["vibration_g"] = VIBRATION_G
    # after the vibration: the reference's scale and axis errors act on all it senses (they
    # had been drawn onto its outputs before the vibration was added, so its vibration was
    # sensed without them: a reference scale that differs between a boost and the vibrating
    # spans, which a temperature_scale term fitted on foreign-03 - 3 of 96 nulls)
    flight = _through_reference_errors(flight, errors)
    raw = dict(flight.mimu_raw)
    t = flight.mimu_t
    if rng.uniform() < 1 / 3 and len(t) > 1000:
        flight, raw, out = _halved(flight, raw, out)
        what["rate"] = "both IMUs at half rate"
    if rng.uniform() < 1 / 3:
        turn = Rotation.random(random_state=rng)
        for s_ in ("accel", "gyro"):
            out[s_] = turn.apply(out[s_])
        q_vs = attitude.from_scipy(attitude.as_scipy(flight.mimu_mounting.q_vs) * turn.inv())
        flight = dataclasses.replace(flight, mimu_mounting=dataclasses.replace(
            flight.mimu_mounting, attitude_wxyz=attitude.as_wxyz(q_vs)))
        what["mounting_turned_deg"] = float(np.degrees(turn.magnitude()))
    raw["accel_volts"], raw["gyro_volts"] = raw_from_physics(
        cal, out["accel"], out["gyro"], raw["accel_temperature"], raw["gyro_frequency"])
    name = f"{what['carrier']}+null{seed}"
    return dataclasses.replace(flight, mimu_raw=raw, name=name, path=name), cal, what


def _wander(t, out, rng):
    """In place on `out`: each channel's in-class bias wander (NULL_WANDER, NULL_TAU_S)."""
    tau = float(np.exp(rng.uniform(*np.log(NULL_TAU_S))))
    kind = str(rng.choice(["gauss-markov", "random-walk"]))
    dt = np.diff(t, prepend=t[0])
    for sensor, bounds in NULL_WANDER.items():
        for i in range(3):
            sigma = float(np.exp(rng.uniform(*np.log(bounds))))
            if kind == "gauss-markov":
                out[sensor][:, i] += gauss_markov(t, sigma, tau, rng)
            else:                           # sigma reached after tau
                out[sensor][:, i] += np.cumsum(rng.standard_normal(len(t)) * sigma
                                               * np.sqrt(dt / tau))
    return {"kind": kind, "tau_s": tau}


def _reference_errors(rng):
    """The reference IMU's drawn errors {"fog_w", "fog_f"}: per triad E with its diagonal
    N(0, REFERENCE_SCALE), off-diagonal N(0, REFERENCE_MISALIGNMENT) (lists)."""
    return {name: np.where(np.eye(3, dtype=bool), rng.normal(0, REFERENCE_SCALE, (3, 3)),
                           rng.normal(0, REFERENCE_MISALIGNMENT, (3, 3))).tolist()
            for name in ("fog_w", "fog_f")}


def _through_reference_errors(flight, errors):
    """The flight with its reference IMU's outputs through (I + E) per triad (`errors`)."""
    return dataclasses.replace(flight, **{
        name: getattr(flight, name) @ (np.eye(3) + np.asarray(e)).T for name, e in errors.items()})


def _halved(flight, raw, out):
    """Both IMUs at half their rate: each pair of interval means averaged into the mean over
    the two intervals, stamped at the second's end."""
    def pairs(x):
        m = len(x) // 2 * 2
        return 0.5 * (x[:m:2] + x[1:m:2])
    raw = {k: pairs(v) for k, v in raw.items()}
    out = {k: pairs(v) for k, v in out.items()}
    m, mf = len(flight.mimu_t) // 2 * 2, len(flight.fog_t) // 2 * 2
    flight = dataclasses.replace(flight, mimu_t=flight.mimu_t[1:m:2], fog_t=flight.fog_t[1:mf:2],
                                 fog_w=pairs(flight.fog_w), fog_f=pairs(flight.fog_f))
    return flight, raw, out

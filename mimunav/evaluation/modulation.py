"""Rotation modulation (seed S4): a MIMU on a single-axis platform (`motion.platform`)
that turns - continuously or back and forth - so that constant sensor errors perpendicular to
the axis change sign in the vehicle frame and average out, and what that buys in
free-inertial navigation; the IMU's installation tilt on the platform fitted against the
platform angle and compensated (Gao, Guan, Wang 2013).

Navigation through the rotation: the same strapdown navigator integrates the sensor frame at
the IMU's point; the vehicle attitude is q_nb = q_ns q_bs(theta)^-1 with the platform angle
at each epoch, and the vehicle origin's position and velocity those of the point less
C_nb r and C_nb (w x r + r') (`evaluation.replay.VehicleNavigator`).
"""
import math
from dataclasses import replace

import numpy as np

from ..frames import attitude
from ..motion import truth
from ..errors import InputError
from ..motion.platform import Platform, RotatingMotion, rotation_about_z, vehicle_attitude


# The study's configurations (seed S4): fixed, continuous and back-and-forth rotation about
# the vehicle's vertical (back and forth over a full turn without dwells: a dwell leaves its
# orientation's bias unmodulated, and a 180 deg swing leaves the sweep's mean direction - both
# measured worse), with the IMU orthogonal on the platform or inclined so that its
# three axes make equal angles (54.74 deg) with the turning axis: every axis modulated.
MAGIC_INCLINATION = math.acos(1 / math.sqrt(3))
MAGIC_AZIMUTH = -math.pi / 4
_INCLINED = {"inclination_rad": MAGIC_INCLINATION, "tilt_azimuth_rad": MAGIC_AZIMUTH}
CONFIGURATIONS = {
    "fixed": Platform("fixed"),
    "continuous": Platform("continuous", math.radians(10.0)),
    "back-and-forth": Platform("back-and-forth", math.radians(10.0)),
    "continuous, inclined": Platform("continuous", math.radians(10.0), **_INCLINED),
    "back-and-forth, inclined": Platform("back-and-forth", math.radians(10.0), **_INCLINED),
}
# Error sources, 1 sigma per axis, drawn per unit (the unit class of seed S1 Table 1,
# `sensors.mimu` grade table1): constant biases (turn-on), bias instability (flicker),
# scale factor (the datasheet tolerance after calibration is assumed 0.1 %), and a periodic
# bias synchronous with the rotation, A sin(theta + phi) per sensor axis (phi uniform; the
# constant bias's size, assumed: a platform motor's field, a slip ring, the g-sensitivity of
# an axis that is not vertical - seed S4 names periodic bias terms as a limit of modulation).
ERRORS = {"constant bias": {"gyro_bias": math.radians(10 / 3600), "accel_bias": 0.2e-3 * 9.80665},
          "bias instability": {"gyro_flicker": math.radians(15 / 3600),
                               "accel_flicker": 0.5e-3 * 9.80665},
          "scale factor": {"gyro_scale": 1e-3, "accel_scale": 1e-3},
          "periodic bias": {"gyro_periodic": math.radians(10 / 3600),
                            "accel_periodic": 0.2e-3 * 9.80665}}


def free_inertial(profile, platform, errors, seed, duration_s=600.0, rate_hz=100.0):
    """One unit on `platform` through `profile` (a `profile.Profile`) for duration_s, its
    sensor-axis increments made exactly (`RotatingMotion`), errors drawn from `errors`
    (ERRORS-style keys, 1 sigma per axis) added, navigated free-inertial by the strapdown
    navigator: end-point horizontal position error (m), tilt and heading errors of the
    vehicle attitude (rad)."""
    motion, vehicle, ref = _fly(profile, platform, errors, seed, duration_s, rate_hz)
    pos = vehicle.position_error(ref)[-1]
    att = vehicle.attitude_error(ref)[-1]
    return {"horizontal_m": float(np.hypot(pos[0], pos[1])),
            "tilt_rad": float(np.hypot(att[0], att[1])), "heading_rad": float(abs(att[2]))}


def _fly(profile, platform, errors, seed, duration_s, rate_hz, q_bs=None):
    """(motion, navigated vehicle trajectory, true vehicle trajectory) of `free_inertial`;
    the navigated vehicle attitude from q_bs(motion, t) (default the true one)."""
    from .replay import navigate, resample
    from ..frames.mounting import Mounting
    from ..sensors import noise
    from ..motion.trajectory import Trajectory
    motion = RotatingMotion(profile.motion(), platform, duration_s)
    t = np.arange(0, int(round(duration_s * rate_hz)) + 1) / rate_hz
    run = truth.generate(motion, t)
    rng = np.random.default_rng(seed)
    n = len(t) - 1
    w = run.dtheta * rate_hz
    f = run.dv * rate_hz
    w = w * (1 + rng.normal(0, errors.get("gyro_scale", 0.0), 3)) \
        + rng.normal(0, errors.get("gyro_bias", 0.0), 3) \
        + noise.flicker(rng, n, rate_hz, [errors.get("gyro_flicker", 0.0)] * 3)
    f = f * (1 + rng.normal(0, errors.get("accel_scale", 0.0), 3)) \
        + rng.normal(0, errors.get("accel_bias", 0.0), 3) \
        + noise.flicker(rng, n, rate_hz, [errors.get("accel_flicker", 0.0)] * 3)
    if "gyro_periodic" in errors:
        w = w + _periodic_bias(rng, motion.angle(t), errors["gyro_periodic"])
        f = f + _periodic_bias(rng, motion.angle(t), errors["accel_periodic"])
    tr = run.trajectory
    start = tr.state(0)
    initial = replace(start, t=0.0)
    nav = navigate(t[1:], w, f, Mounting(), initial)
    q_true = motion.q_bs(nav.t)
    vehicle = Trajectory(nav.t, nav.lat, nav.lon, nav.h, nav.v_ned,
                         vehicle_attitude(nav.q_nb, q_true if q_bs is None else q_bs(motion, nav.t)))
    ref = resample(tr, nav.t)
    ref = Trajectory(ref.t, ref.lat, ref.lon, ref.h, ref.v_ned,
                     vehicle_attitude(ref.q_nb, q_true))
    return motion, vehicle, ref


def _periodic_bias(rng, theta, sigma):
    """Interval means (N-1, 3) of A sin(theta + phi) per axis over the platform angles theta
    (N,) at the sample times: A ~ N(0, sigma), phi uniform; the closed-form mean of the sine
    over each interval's angle change (a constant A sin phi on a platform at rest)."""
    amp, phi = rng.normal(0, sigma, 3), rng.uniform(0, 2 * math.pi, 3)
    a, b = theta[:-1, None] + phi, theta[1:, None] + phi
    d = b - a
    still = np.abs(d) < 1e-9
    mean = np.where(still, np.sin(a), (np.cos(a) - np.cos(b)) / np.where(still, 1.0, d))
    return amp * mean


def study(profile, units=8, seed=0, duration_s=600.0, progress=False):
    """Every configuration against every error source (each alone), `units` units each:
    {source: {configuration: [result per unit]}} (`free_inertial`)."""
    from tqdm import tqdm
    out = {}
    jobs = [(s, c) for s in ERRORS for c in CONFIGURATIONS]
    for source, config in tqdm(jobs, desc="modulation", disable=not progress):
        out.setdefault(source, {})[config] = [
            free_inertial(profile, CONFIGURATIONS[config], ERRORS[source], seed + k, duration_s)
            for k in range(units)]
    return out


# ---- installation tilt deviation (seed S4: Gao, Guan, Wang 2013) --------------------------
def installation_tilt(t, theta, q_ns, platform, q_nb_reference=None, iterations=3):
    """The installation deviation (`tilt_deviation`) by Gauss-Newton: the vehicle attitude
    q_ns q_bs(theta)^-1 recomputed with the deviation found so far and the remainder fitted
    again, so the fit's small-angle algebra meets only a small remainder (a 2 deg deviation
    composed with a 1 deg heading drift is otherwise off by ~0.03 deg). q_ns: the navigated
    sensor attitude (quaternion array (n,)); platform: the design `Platform`. Returns
    `tilt_deviation`'s dict with the total deviation."""
    delta = np.zeros(2)
    for _ in range(iterations):
        fixed = Platform(**{**platform.__dict__, "imu_deviation_rad": (*delta, 0.0)})
        q_nb = vehicle_attitude(q_ns, fixed.q_bp0() * rotation_about_z(theta) * fixed.q_ps())
        fit = tilt_deviation(t, theta, q_nb, platform.q_bp0(), q_nb_reference)
        delta = delta + fit["delta_rad"]
    return dict(fit, delta_rad=delta)


# a continuous rotation's tilt fit holds the modulated gyro bias b / rate: its uncertainty
# takes the class's turn-on bias (seed S1 Table 1 as read in `calibration.TURN_ON`)
TILT_GYRO_BIAS_RAD_S = math.radians(10 / 3600)


def tilt_deviation(t, theta, q_nb, q_bp0, q_nb_reference=None,
                   gyro_bias_rad_s=TILT_GYRO_BIAS_RAD_S):
    """The IMU's installation deviation on the platform from the vehicle attitude computed
    with the design mounting (seed S4, Gao, Guan, Wang 2013: fit the tilt against the
    indexing angle). A true mounting exp(delta) q_ps makes the computed attitude
    q_nb exp(C_bp0 Rz(theta) delta): an error that turns with the platform angle theta. A
    gyro bias b perpendicular to the turning axis (platform axes) adds the free-inertial
    attitude error int Rz(theta) b dt, which also turns with theta. In the platform's base
    frame, x and y of the error are
        e = Rz(theta) delta + J(t) b + c,   J(t) = int_0^t Rz(theta) dt'
    with c the vehicle's attitude against the reference (constant for a vehicle at rest);
    delta_z, about the axis, is a constant heading offset no platform angle reveals.
    Fitted by least squares on every two whole turns of travel (each with its own c, so the
    slow drift of a free-inertial attitude stays out); delta (and b) are the means over these
    pieces and their standard errors the pieces' scatter / sqrt(pieces): the drift makes
    neighbouring epochs' errors correlated, pieces much less so. At a constant rate J is
    Rz(theta - 90 deg) / theta' + const: a continuous rotation cannot tell delta from b, and
    the fitted delta then holds the bias's b / theta' ("bias_separated": False; its standard
    error then adds gyro_bias_rad_s / theta', the size of that confusion); a back-and-forth
    rotation reverses J and separates them. "dof": the pieces less one (the scatter's).
    t: times (s, (n,)); theta: platform angles (rad, (n,)); q_nb: the computed vehicle
    attitude (quaternion array (n,)); q_bp0: the platform's base attitude; q_nb_reference:
    the vehicle's attitude from a reference (default: the first computed epoch, for a
    vehicle at rest). Returns {"delta_rad": (2,), "se_rad": (2,), "bias_rad_s": (2,) or None,
    "bias_separated": bool, "pieces": n}."""
    from scipy.integrate import cumulative_trapezoid
    t, theta = np.asarray(t, float), np.asarray(theta, float)
    q_ref = (np.full(len(q_nb), q_nb[0]) if q_nb_reference is None else q_nb_reference)
    e_n = attitude.rotation_vector_error(q_nb, q_ref)
    e_p = attitude.rotate(np.conjugate(q_bp0), attitude.rotate(np.conjugate(q_ref), e_n))
    c, s = np.cos(theta), np.sin(theta)
    jc = cumulative_trapezoid(c, t, initial=0.0)
    js = cumulative_trapezoid(s, t, initial=0.0)
    travelled = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(theta)))])
    piece = np.floor(travelled / (4 * math.pi)).astype(int)

    def design(sel, with_bias):
        one, zero = np.ones(sel.sum()), np.zeros(sel.sum())
        cols_x = [c[sel], -s[sel]] + ([jc[sel], -js[sel]] if with_bias else []) + [one, zero]
        cols_y = [s[sel], c[sel]] + ([js[sel], jc[sel]] if with_bias else []) + [zero, one]
        return np.vstack([np.column_stack(cols_x), np.column_stack(cols_y)])
    pieces = [piece == k for k in range(piece.max())]        # whole pieces only
    if len(pieces) < 3:
        raise InputError(f"the platform travelled {travelled[-1] / (2 * math.pi):.1f} turns; "
                         "the installation tilt needs at least 6 (three pieces of two turns: "
                         "its uncertainty comes from their scatter)")
    separated = all(np.linalg.matrix_rank(design(sel, True), tol=1e-9 * len(t)) == 6
                    for sel in pieces)
    estimates = []
    for sel in pieces:
        y = np.concatenate([e_p[sel, 0], e_p[sel, 1]])
        estimates.append(np.linalg.lstsq(design(sel, separated), y, rcond=None)[0])
    est = np.array(estimates)
    se = est.std(axis=0, ddof=1)[:2] / math.sqrt(len(est))
    if not separated:       # the same b / rate in every piece: no scatter shows it
        rate = float(np.median(np.abs(np.diff(theta) / np.diff(t))))
        se = np.hypot(se, gyro_bias_rad_s / rate)
    return {"delta_rad": est[:, :2].mean(axis=0), "se_rad": se, "dof": len(est) - 1,
            "bias_rad_s": est[:, 2:4].mean(axis=0) if separated else None,
            "bias_separated": separated, "pieces": len(est)}


def tilt_compensation(profile, platform, deviation_rad, errors, seed, duration_s=600.0,
                      rate_hz=100.0):
    """One unit whose true mounting on `platform` deviates by `deviation_rad` (rotation
    vector, platform axes) from the design: the vehicle attitude computed with the design
    mounting, the deviation fitted from it (`installation_tilt`, vehicle at rest) and
    compensated. Returns the RMS tilt and heading deviation of the vehicle attitude against
    the truth (rad) before, after, and with the true mounting known ("floor": the unit's own
    free-inertial error), the fitted deviation with its standard error and the true one."""
    true = Platform(**{**platform.__dict__, "imu_deviation_rad": tuple(deviation_rad)})
    def designed(motion, t):
        return platform.q_bp0() * rotation_about_z(motion.angle(t)) * platform.q_ps_nominal()
    motion, vehicle, ref = _fly(profile, true, errors, seed, duration_s, rate_hz, designed)
    theta = motion.angle(vehicle.t)
    q_ns = vehicle.q_nb * designed(motion, vehicle.t)
    fit = installation_tilt(vehicle.t, theta, q_ns, platform)
    fixed = Platform(**{**platform.__dict__,
                        "imu_deviation_rad": (*fit["delta_rad"], 0.0)})
    after = vehicle_attitude(q_ns, fixed.q_bp0() * rotation_about_z(theta) * fixed.q_ps())

    def rms(q):
        e = attitude.rotation_vector_error(q, ref.q_nb)
        return {"tilt_rad": float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))),
                "heading_rad": float(np.sqrt(np.mean(e[:, 2] ** 2)))}
    floor = vehicle_attitude(q_ns, motion.q_bs(vehicle.t))
    return {"before": rms(vehicle.q_nb), "after": rms(after), "floor": rms(floor),
            "fitted_rad": fit["delta_rad"], "se_rad": fit["se_rad"],
            "bias_separated": fit["bias_separated"],
            "true_rad": np.asarray(deviation_rad, float)}


# The tilt study (`tilt_study`, `mimunav report modulation`): a 2 deg installation deviation
# (the seed's uncompensated level error) in a random direction of the platform plane, the
# unit ideal or with the class's constant bias and bias instability together.
TILT_DEVIATION_RAD = math.radians(2.0)
TILT_ERRORS = {"ideal IMU": {},
               "bias + instability": {**ERRORS["constant bias"], **ERRORS["bias instability"]}}
TILT_PLATFORMS = ("continuous", "back-and-forth")


def tilt_study(profile, units=8, seed=0, duration_s=600.0, progress=False):
    """{(errors, platform): [tilt_compensation result per unit]} for TILT_ERRORS x
    TILT_PLATFORMS, each unit's deviation direction drawn from its seed."""
    from tqdm import tqdm
    out = {}
    jobs = [(e, p, k) for e in TILT_ERRORS for p in TILT_PLATFORMS for k in range(units)]
    for e, p, k in tqdm(jobs, desc="tilt", disable=not progress):
        a = np.random.default_rng([seed, k, 7]).uniform(0, 2 * math.pi)
        dev = TILT_DEVIATION_RAD * np.array([math.cos(a), math.sin(a), 0.0])
        out.setdefault((e, p), []).append(tilt_compensation(
            profile, CONFIGURATIONS[p], dev, TILT_ERRORS[e], seed + k, duration_s))
    return out

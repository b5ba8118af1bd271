"""The track level's reference: the ideal IMU simulated along a land vehicle's
trajectory (`motion.vehicle.TrackMotion`), the MIMU put into the track's band, the vehicle
model's stated accuracy, the noise shape of a course-derived yaw rate, the wander the model's
own errors allow, and the stretches a gap or a reversing move leaves out.
"""
import math
from dataclasses import replace

import numpy as np
import quaternion

from ..motion import truth as truth_mod
from ..frames.mounting import Mounting
from ..sensors.mimu import DEG, G0
from ..motion.vehicle import HOLD_SPEED, TRUSTED_SPEED, TrackMotion
from ..sensors.accuracy import Accuracy
from .design import CHANNELS
from .track_fixes import refuted_fixes, without_refuted, worst_of_runs
from ..errors import InputError


# The reference here is a vehicle model, not a FOG-IMU: its attitude comes from the velocity
# under no side slip and zero roll, so its own "scale and misalignment" are those of the
# assumption - road bank and grade, tyre slip: about 1 % and 10 mrad (assumed, a car on
# ordinary roads). Linear terms must beat that to be charged to the IMU. But the yaw rate is
# the course's rate, which has no scale error of its own: the z gyro of a body tilted by phi
# (road superelevation and body roll, which roll = 0 lacks) reads it times cos(phi) - 0.5 %
# at 5.7 deg (a 10 % superelevation, above the 8 % most design codes allow): 0.5 % for the
# gyros' scale (their other axes are rarely predicted; at 1 % a 2 % yaw-gyro scale of an
# independent drive, found at 0.0206, was set aside as the vehicle model's own).
# The accelerometers' scale is not observable against the model beyond the body's own tilt on
# its springs: braking and cornering pitch and roll the body in proportion to the
# acceleration (a gradient of k rad per m/s^2), tilting g into the same axis - the outputs
# read the acceleration times (1 +- g k), a scale error the model cannot tell from the
# part's. Passenger cars roll 3-7 deg/g (Gillespie, Fundamentals of Vehicle Dynamics, 1992,
# ch. 8), and pitch less: 7 deg/g, g k = 0.12, bounds both. An independent new user's drive
# with its body pitching 0.3 deg per m/s^2 (2.9 deg/g) had been found to hold an accel.x
# scale of 0.048 [0.005, 0.091], charged to the IMU (its truth: none).
BODY_TILT_GRADIENT = math.radians(7.0)      # rad per g of acceleration: g k, the scale it reads
VEHICLE_MODEL_ACCURACY = Accuracy(gyro_scale=5e-3, accel_scale=BODY_TILT_GRADIENT,
                                  gyro_misalignment_rad=1e-2, accel_misalignment_rad=1e-2,
                                  source="track level: land-vehicle model (assumed: gyro scale "
                                         "0.5 %, accel scale 12 % - the body's roll and pitch "
                                         "on its springs, 7 deg/g -, 10 mrad)",
                                  given=Accuracy.KEYS)
# recorded 1 s means, the rms that no linear error of the unit explains (`reference_check`)
# over the simulated means' rms - the share the model leaves unexplained at that correlation,
# measured against the channel's size, not its variation: gravity on accel.z is predicted
# though it hardly varies (`_carried_channels`)
CHECK_BIN_S = 1.0
IMU_GAP_S = 0.1            # an IMU step this long is a gap (a car moves ~3 m): not interpolated
IMU_GAP_STEPS = 2.5         # nor shorter than this many of the IMU's own steps (a 10 Hz IMU's
#                             every step had been a gap, and nothing left to compare)
REFERENCE_GAP_S = 2.0      # a reference step this long is an outage (1 Hz fixes are not)
GAP_MARGIN_S = 2.0         # s left out on each side of a gap: the 1 s bins, the 0.5 s lag
# Noise of the consumer part (shared/data/rtklib-drive/README: the author's settings, an
# LSM6DSO-class device): white densities, accel m/s^2/sqrt(Hz), gyro rad/s/sqrt(Hz); its
# flicker instability B is not published: seed S1 Table 1's class (accel 0.5 mg, gyro
# 15 deg/h, as `calibration.INSTABILITY`) is assumed. Bounds the wander level below; the
# diagnosis fits the noise and wander levels themselves from the data.
CONSUMER_NOISE = {"accel_white": 70e-6 * G0, "gyro_white": 0.0038 * DEG,
                  "accel_flicker": 0.5e-3 * G0, "gyro_flicker": 15 * DEG / 3600}


def wander_steps(noise=CONSUMER_NOISE, bin_s=0.01, span_s=100.0):
    """(6,) the largest step variance per bin of each channel's bias wander (accel.x-z in
    (m/s^2)^2, then gyro.x-z in (rad/s)^2): a random walk that reaches the part's datasheet
    instability B in span_s. `wander_limit` caps the level, the step over the white variance
    the fit finds; the vehicle model's own errors swell that white variance (on the RTKLIB
    drive accel.x's 1 s bins hold ~0.1 m/s^2 of them against the part's 0.0007), and the
    wander it allows with it - thousands of times the part's - weighs the bins' changes,
    where those errors are most of the model's specific force: the IMU's pitch on the car
    read -5.2 deg [-6.4, -4.0] against -6.7 to -6.8 from plain least squares on the same
    model and from the data's author; with its step capped too, -5.7 [-6.9, -4.4]."""
    return np.array([noise["accel_flicker"] ** 2 * bin_s / span_s] * 3
                    + [noise["gyro_flicker"] ** 2 * bin_s / span_s] * 3)


def wander_limit(noise=CONSUMER_NOISE, bin_s=0.01, span_s=100.0):
    """The largest bias-wander level of the track level's fits: a random walk that reaches
    the part's datasheet instability B in span_s, over the white variance of a bin, the
    larger of the two triads' (the sensor level fits the level freely; here the vehicle
    model's own errors - body roll in corners, suspension - are fast and structured, and a
    freely fitted wander takes their level: on the RTKLIB drive it came out 10^3 times the
    part's and turned the found pitch misalignment's sign)."""
    step = wander_steps(noise, bin_s, span_s)
    return max(step[0] / (noise["accel_white"] ** 2 / bin_s),
               step[3] / (noise["gyro_white"] ** 2 / bin_s))


def simulated_reference(flight, backward=None):
    """(flight with the ideal IMU simulated from its /truth/state as the reference IMU at
    the vehicle origin, trusted (N,) bool over the MIMU's samples, the `TrackMotion` - whose
    `in_band` puts the MIMU's outputs in the same band). `backward`: the `reversing` mask
    when already made."""
    tr = flight.truth
    if tr is None:
        raise InputError(f"{flight.path}: no /truth/state to simulate the reference IMU from")
    differenced = velocity_is_differenced(tr)
    tr = without_refuted(tr, worst_of_runs(refuted_fixes(flight)), differenced)
    motion = TrackMotion(tr.t, tr.lat, tr.lon, tr.h, tr.v_ned, differenced=differenced)
    t = flight.mimu_t
    inside = (t > motion.t0) & (t <= motion.t1)
    if inside.sum() < 2:
        raise InputError(f"{flight.path}: the reference trajectory does not cover the MIMU")
    stamps = np.concatenate([[motion.t0], t[inside]])
    run = truth_mod.generate(motion, stamps)
    dt = np.diff(stamps)[:, None]
    # the vehicle model's outputs are on the track's clock: the reference IMU's, as the
    # import measured it, is not theirs to fit (`design.add_clock_nuisance`)
    ref = replace(flight, fog_t=t[inside], fog_w=run.dtheta / dt, fog_f=run.dv / dt,
                  fog_mounting=Mounting(), recording={
                      k: v for k, v in (flight.recording or {}).items()
                      if k != "reference_imu_clock_se_s"})
    backward = reversing(flight) if backward is None else backward
    # not within edge_s of where the track or the IMU ends: the smoothing is one-sided
    # there, and beyond the IMU's own ends its banded outputs hold still (an IMU ending in
    # a turn had its last second 9 deg/s off the model)
    start, end = max(motion.t0, t[0]) + motion.edge_s, min(motion.t1, t[-1]) - motion.edge_s
    trusted = inside & motion.trusted(t) & ~near_gaps(t, tr.t) & ~backward & \
        (t > start) & (t < end)
    if not trusted.any():
        raise InputError(f"{flight.path}: no IMU sample lies in motion the vehicle model "
                         f"trusts (faster than {TRUSTED_SPEED:g} m/s or at rest, "
                         f"{motion.edge_s:.3g} s or more from the ends of the track and of "
                         "the IMU's record, away from gaps and reversing): nothing to compare "
                         "at the track level")
    return ref, trusted, motion


DIFFERENCED_SHARE = 0.9     # epochs that must agree for a track to count as differenced


def velocity_is_differenced(tr):
    """True when the reference trajectory's velocities (a Trajectory: t s, lat, lon rad, h
    m, v_ned m/s) are central differences of its positions, as an importer makes them from
    fixes without velocity (`importers.velocity_from_positions`, computed again here): at
    least DIFFERENCED_SHARE of the epochs agree within 1e-6 m/s (the rest: epochs beside a
    gap, whose neighbours across it were left out after the differencing; fixes dropped
    before it, as an importer drops float fixes, leave uneven steps that agree). A
    receiver's own velocity (Doppler, a filter's state) is a point sample and agrees at
    7-17 % of the epochs."""
    from ..motion.track import velocity_from_positions
    if len(tr.t) < 3:
        return False
    again = velocity_from_positions(np.round((tr.t - tr.t[0]) * 1e9).astype(np.int64),
                                    tr.lat, tr.lon, tr.h)
    agree = np.all(np.abs(again - tr.v_ned) < 1e-6, axis=1)
    return bool(agree.mean() >= DIFFERENCED_SHARE)


def in_band(motion, t, outputs, q_vs):
    """The MIMU's outputs (w rad/s, f m/s^2; (N, 3) each, sensor axes, at its stamps t s;
    q_vs: sensor -> vehicle) through the operations the vehicle model applies to the track,
    so that what it blunts is blunted on both sides. In NED, turned by the model's own
    attitude: the specific force's three axes by the horizontal velocity's smoothing
    (`TrackMotion.in_band`: the model's acceleration is the derivative of the smoothed
    velocities). Its down is not put through the vertical velocity's smoothing, though the
    model's vertical acceleration is: a mounting tilted by d turns d times the forward or
    lateral specific force into it, and the regressors of such a leak are the model's
    horizontal specific force - in the horizontal band. On a level road the vertical's
    smoothing, all noise, is a straight line: it had erased the leak (an independent drive's
    6.8 deg pitch read as 1.7 deg [0.5, 2.8], a 3 deg one was set aside). What it costs:
    the vehicle's own vertical acceleration between the two bands, 0.004 m/s^2 rms over 2 m
    hills under 5 cm fixes (0.0016 in the vertical's band) - not noise: it follows the
    vertical acceleration, so on hilly roads it reads as an accel.z scale of 3-4 % (an
    independent review's 1-2 m hills: set aside within the reference's accuracy, or not
    confirmed by navigation; the model's vertical in the horizontal band too would remove it
    and put the vertical fixes' noise there, 0.023 m/s^2 rms with 5 cm fixes). The rates'
    north and east by the horizontal smoothing (the model's pitch rate comes from the
    vertical velocity's: on a hilly road with 5 cm fixes gyro.y is left 0.041 deg/s rms off,
    0.013 if banded by the vertical smoothing - which would also smooth away the body roll
    the model lacks, so it is not done), the yaw rate where the model has one (faster than
    HOLD_SPEED) as the model makes it (`TrackMotion.course_rate_in_band`). Then back to
    sensor axes by the same attitude.
    The model's heading error turns the horizontal specific force with it (in a 20 deg/s
    turn under 5 cm fixes accel.x is 0.035 m/s^2 rms off the model, 0.023 turned by the
    true attitude). Smoothing the body-frame outputs does not commute with the turning:
    under 5 cm fixes, lambda 1.3, it left 0.3 deg/s and 0.09 m/s^2 at sharp turns and
    departures, excursions at z 8 on null drives. NaN where an output is not finite."""
    from ..frames import attitude
    w_s, f_s = (np.asarray(x, float) for x in outputs)
    kin = motion.kinematics(t)
    q_ns = kin.q_nb * q_vs
    f_n, w_n = attitude.rotate(q_ns, f_s), attitude.rotate(q_ns, w_s)
    f_n = np.column_stack([motion.in_band(t, f_n[:, :2]),
                           motion.in_band(t, f_n[:, 2:])])
    w_band = motion.in_band(t, w_n)
    moving = np.hypot(kin.v_ned[:, 0], kin.v_ned[:, 1]) >= HOLD_SPEED
    w_band[moving, 2] = motion.course_rate_in_band(t, w_n[:, 2])[moving]
    q_sn = np.conjugate(q_ns)
    w_out, f_out = attitude.rotate(q_sn, w_band), attitude.rotate(q_sn, f_n)
    bad = ~np.isfinite(np.hstack([w_s, f_s])).all(axis=1)
    w_out[bad] = f_out[bad] = np.nan
    return w_out, f_out


def reversing(flight, step_s=1.0):
    """(N,) bool over the MIMU's stamps: where the vehicle drives in reverse. A vehicle
    changes its direction of travel only through a stop, so the track is cut into moves
    between stops - epochs whose mean velocity over alignment.STATIC_AVERAGE_S is below
    alignment.STATIC_SPEED, as the alignment finds rests (a differenced RTK fix's speed at
    rest is noise of tenths of m/s, rarely below vehicle.REST_SPEED: a drive forward, a
    stop and backwards had been one move, judged forward) - and each move is judged whole:
    reversing when most of the `travel.travel_sign` verdicts that decide on a step_s grid
    of its epochs faster than alignment.COURSE_SPEED say so (at a constant speed on a
    straight road none decides: such verdicts had counted as forward). The vehicle model
    takes the attitude from the velocity, so reversing it faces the wrong way and predicts
    nothing: those samples are left out (a drive that reversed over 150 s had been
    inconclusive, '1 of 6 channels predicted', and its lag averaged with the reversed
    stretch's)."""
    from ..navigation import alignment
    from ..navigation.rests import STATIC_AVERAGE_S, STATIC_SPEED, means_around
    from ..navigation.travel import travel_sign
    from ..evaluation.windows import track_of
    t, tr = flight.mimu_t, flight.truth
    track = track_of(tr)
    speed = np.hypot(tr.v_ned[:, 0], tr.v_ned[:, 1])
    mean = means_around(tr.t, tr.v_ned[:, :2], tr.t, STATIC_AVERAGE_S / 2)
    moving = np.linalg.norm(mean, axis=1) > STATIC_SPEED
    edges = np.flatnonzero(np.diff(np.concatenate([[0], moving.astype(int), [0]])))
    out = np.zeros(len(t), bool)
    for a, b in zip(edges[::2], edges[1::2]):                 # epochs a .. b - 1 move
        grid = np.arange(tr.t[a], tr.t[b - 1], step_s)
        fast = grid[np.interp(grid, tr.t, speed) >= alignment.COURSE_SPEED]
        fast = fast[(fast > t[0]) & (fast < t[-1])]
        signs = [travel_sign(t, flight.mimu_imu[1], flight.mimu_mounting, track, x,
                                       undecided=0.0) for x in fast]
        if np.sum(signs) < 0:           # the decided verdicts (a straight cruise: none)
            out |= (t >= tr.t[a]) & (t <= tr.t[b - 1])
    return out


def near_gaps(t, t_reference):
    """(N,) bool over the MIMU's stamps t (s): within GAP_MARGIN_S of a gap - an IMU step
    longer than IMU_GAP_S and IMU_GAP_STEPS of its median, or a reference step longer than
    REFERENCE_GAP_S. Across a gap the
    simulated reference IMU is an interval mean over the whole gap and the derivative
    filters, the lag search and the 1 s bins would mix its two sides (a 5 s IMU gap turned
    a clear 80 ms lag into an inconclusive one), so those samples are left out instead of
    the recording being refused."""
    t = np.asarray(t, float)
    step, ref_step = np.diff(t), np.diff(t_reference)
    longest = max(IMU_GAP_S, IMU_GAP_STEPS * float(np.median(step))) if len(step) else IMU_GAP_S
    edges = [(t[k], t[k + 1]) for k in np.flatnonzero(step > longest)]
    edges += [(t_reference[k], t_reference[k + 1])
              for k in np.flatnonzero(ref_step > REFERENCE_GAP_S)]
    near = np.zeros(len(t), bool)
    for a, b in edges:
        near |= (t > a - GAP_MARGIN_S) & (t < b + GAP_MARGIN_S)
    return near


SPEED_BANDS = 5                 # of the trusted bins, by 1/v^2, for the yaw-rate noise's law


def rate_noise_shape(ref, trusted, motion, bin_s):
    """(the fit's, the scan's) (N, 6) each: each sample's white variance relative to its
    channel's floor, in bins of bin_s (s), for `sensor.diagnose`. The vehicle model's yaw
    rate is, moving, the track's smoothed
    lateral acceleration over the speed (yaw' = a_lateral / v), so its error grows as 1/v
    where the part's own noise does not: the yaw-rate residual's variance in a moving bin is
    F + sigma_a^2 / v^2, measured here - a line through the robust variances (MAD^2) of the
    residual of the trusted bins faster than TRUSTED_SPEED in SPEED_BANDS bands of 1/v^2, F
    at least the part's own noise in a bin (`noise_floor`). On the gyro channels along the
    vehicle's down axis (the mounting's column) the shape is 1 + (sigma_a^2 / F) / v^2
    where the rates are modelled (v >= HOLD_SPEED), 1 at rest (held at zero there, the
    model is exact: its bins are taken as no better than the moving floor - a rest's own
    variance, measured from the banded outputs' smooth noise, had made still windows of a
    null drive stand out at z 9); 1 on the other channels - the roll and pitch rates the
    model lacks are its error, not this noise, and the track's acceleration error does not
    depend on the speed - and everywhere when the data show no such law (a noise-free track).
    On an independent 10 Hz drive with 2 cm fixes the residual times the speed was 0.019
    m/s^2 rms per sample at every speed from 2 to 30 m/s; on the RTKLIB drive the variance
    grows as 1/v^2 from a floor below the part's noise.
    The scan's shape adds the pitch rate's law the same way: moving, it is -a_D / v (the
    vertical acceleration's error over the speed). Without it, arriving at and leaving a
    stop on a slope stood out at z 8-11 on gyro.y in 6 of 10 null hilly drives. The fit's
    weights leave it out: weighted by it, the fit leans on the fast bins, where the vertical
    velocity's smoothing blunts the model's pitch rate against the MIMU's (banded by the
    horizontal smoothing, `in_band`) - a gyro.y scale of 3.4 % the model made was found on
    a null drive under 5 cm fixes."""
    from ..frames import attitude
    from .reference import predicted_mimu
    t = ref.mimu_t
    shape = np.ones((len(t), 6))
    _, w_p, _ = predicted_mimu(ref)
    q_vs = ref.mimu_mounting.q_vs
    rate_error = attitude.rotate(q_vs, ref.mimu_imu[0] - w_p)
    speed = motion.speed(t)
    modelled = speed >= HOLD_SPEED
    shapes = []
    for axis in (2, 1):                                 # the vehicle's yaw and pitch rates
        law = _rate_law(t, rate_error[:, axis], trusted & (speed > TRUSTED_SPEED), speed,
                        bin_s)
        if law is not None:
            slope, floor = law
            along = quaternion.as_rotation_matrix(q_vs)[axis] ** 2   # in sensor axes
            shape[modelled, 3:] += (slope / floor) * along / speed[modelled, None] ** 2
        shapes.append(shape.copy())
    return shapes[0], shapes[1]


def _rate_law(t, error, fast, speed, bin_s):
    """`yaw_error_law` of one vehicle rate's residual `error` (rad/s, per sample) in bins of
    bin_s over the samples `fast`."""
    fast = fast & np.isfinite(error)
    k = np.floor((t[fast] - t[0]) / bin_s).astype(int)
    count = np.bincount(k)
    full = count >= 0.5 * np.max(count, initial=0)
    mean = (np.bincount(k, error[fast]) / np.maximum(count, 1))[full]
    inverse = (np.bincount(k, speed[fast] ** -2) / np.maximum(count, 1))[full]
    return yaw_error_law(mean, inverse, noise_floor(bin_s=bin_s)["gyro.z"] ** 2)


def yaw_error_law(error, inverse, part):
    """(sigma_a^2 (m/s^2)^2, F (rad/s)^2) of the yaw-rate residual's variance F + sigma_a^2 u
    in bins (`rate_noise_shape`): error (n,) the bins' residual (rad/s), inverse (n,) their
    mean 1/v^2 (s^2/m^2); a line through the robust variances (MAD^2) of SPEED_BANDS bands
    of u, F at least `part` (the part's own variance in a bin: the RTKLIB drive's line met
    u = 0 below zero). None when there are fewer than 40 bins or the variance does not grow
    with 1/v^2."""
    bands = min(SPEED_BANDS, len(error) // 20)
    if bands < 2:
        return None
    order = np.array_split(np.argsort(inverse), bands)
    u = [float(np.mean(inverse[i])) for i in order]
    law = np.ones(len(error))           # the law so far: a band's MAD is taken of the errors
    for _ in range(4):                  # over it, so that its spread of 1/v^2 in the band
        scaled = error / np.sqrt(law)   # does not bias it (a mixture's MAD is no mean)
        variance = [(1.4826 * float(np.median(np.abs(scaled[i] - np.median(scaled[i]))))) ** 2
                    * float(np.mean(law[i])) for i in order]
        slope, floor = np.polyfit(u, variance, 1)
        if not slope > 0:
            return None
        law = max(floor, part) + slope * inverse
    return float(slope), max(float(floor), part)


# a channel whose 1 s means the model leaves more than this many times the part's own noise
# unexplained is not followed by the model (a channel that merely hardly moves - accel.z on a
# level road, the pitch rate - is followed: its correlation is noise's, its residual too)
NOT_FOLLOWED = 3.0


def noise_floor(noise=CONSUMER_NOISE, bin_s=CHECK_BIN_S):
    """{channel label: the part's own noise in a CHECK_BIN_S mean, SI}: white noise of the
    mean and the bias instability B, which a constant does not remove over a drive."""
    return {f"{s}.{a}": math.hypot(noise[f"{s}_white"] / math.sqrt(bin_s),
                                   noise[f"{s}_flicker"]) for s, a in CHANNELS}


MODEL_STEP_Z = 3.0      # a stop's held pitch error (measured: a sigma) counts 3 times (a
#                         normal bound: 0.3 % of the model's steps lie beyond)


def model_excursions(spans, t, held_sd, f_model, q_vs, moving_sd=None):
    """(kept, set aside): the scan's excursions `spans` (`scan.excursions`) with those the
    vehicle model's own errors may make there set aside, the two it states for an
    accelerometer together (root sum square):
      - a stop's held pitch: the road's grade over the metres around the stop
        (`vehicle._road_pitch`), not measured at the stop itself - its error d_theta tilts g
        onto the forward axis for the whole stop, so a window at the stop steps against a
        baseline in motion by g d_theta (an independent drive on a curving 1-3 % grade:
        accel.x -0.019 m/s^2 at its first departure, z -7.3 on a drive with no error);
      - the body's tilt on its springs, at most BODY_TILT_GRADIENT per g of horizontal
        acceleration (passenger cars' bound, taken as one here, not as a sigma): a step of
        the horizontal specific force by a moves a horizontal output by up to 0.12 a, the
        vertical by 0.12 a^2 / g (the RTKLIB drive's departure, +0.52 m/s^2 at z 12.5, is
        beyond its 0.22: it stays unexplained).
      - a moving vehicle's pitch, from its smoothed vertical velocity over its speed: its
        error at the window and at the baseline's, each up to MODEL_STEP_Z sigma
        (`TrackMotion.moving_pitch_sd`; a train's from 1-3 m heights at 4 m/s, 0.64 m/s^2);
    and for a gyro, the rate of that tilt: its change over the window, at most the gradient
    times the change of the horizontal specific force, on the axis as it lies in the vehicle.
    t: the design's bin times (s); held_sd: the held pitch's 1 sigma at them (rad,
    `TrackMotion.held_pitch_sd`); f_model: the model's specific force in the bins (m/s^2,
    MIMU sensor axes); q_vs: the MIMU's mounting (sensor to vehicle); moving_sd: the moving
    pitch's 1 sigma at the bins (rad; None: 0)."""
    turn_back = np.conj(q_vs)
    forward, right = quaternion.rotate_vectors(turn_back, np.eye(3)[:2])
    f_v = quaternion.rotate_vectors(q_vs, f_model)
    # tilted by theta = k a, the body's forward and right axes take g theta, its down the
    # acceleration itself a theta (a car pitching 0.4 deg per m/s^2 had its accel.z read
    # -0.12 m/s^2 at z 16 at every hard start and stop)
    tilt = quaternion.rotate_vectors(turn_back, BODY_TILT_GRADIENT * np.column_stack(
        [f_v[:, 0], f_v[:, 1], (f_v[:, 0] ** 2 + f_v[:, 1] ** 2) / G0]))    # sensor axes
    # the body's roll and pitch rates on its springs, at most k = BODY_TILT_GRADIENT / g
    # per (m/s^2)/s of the horizontal specific force's change: roll -k df_y/dt about the
    # forward axis, pitch k df_x/dt about the right (a tilted phone's gyro.x and gyro.y
    # had read them at every onset, z 9-14, as unexplained: its drive without springs none)
    rates = BODY_TILT_GRADIENT / G0 * np.gradient(f_v[:, :2], t, axis=0) \
        if len(t) > 1 else np.zeros((len(t), 2))       # a window's mean: its tilt's change
    kept, aside = [], []
    for span in spans:
        sensor, axis = span["channel"].split(".")
        i = "xyz".index(axis)
        if sensor == "gyro":
            bound = abs(forward[i]) * _window_step(t, rates[:, 1], span["peak_t0"]) + \
                abs(right[i]) * _window_step(t, rates[:, 0], span["peak_t0"])
            bound = float(np.nan_to_num(bound))
            if abs(span["size"]) <= bound:
                aside.append(dict(span, bound=bound, why=(
                    f"the rate of the body's roll and pitch on its springs (at most "
                    f"{math.degrees(BODY_TILT_GRADIENT):g} deg/g) may make {bound:.2g} rad/s "
                    "there: the model's, not the IMU's")))
            else:
                kept.append(span)
            continue
        held = G0 * abs(forward[i]) * _window_step(t, held_sd, span["peak_t0"])
        body = _window_step(t, tilt[:, i], span["peak_t0"])
        moving = 0.0 if moving_sd is None else \
            G0 * abs(forward[i]) * math.sqrt(2) * _window_peak(t, moving_sd, span["peak_t0"])
        bound = math.hypot(MODEL_STEP_Z * np.nan_to_num(held), np.nan_to_num(body),
                           MODEL_STEP_Z * moving)
        if abs(span["size"]) <= bound:
            aside.append(dict(span, bound=bound,
                              why=f"the step the vehicle model's own errors may make there "
                                  f"({MODEL_STEP_Z:g} sigma of a stop's held pitch, "
                                  f"{_said_step(MODEL_STEP_Z * np.nan_to_num(held))}, and of "
                                  f"a moving one's, {_said_step(MODEL_STEP_Z * moving)}; the "
                                  f"body's tilt on its springs at most {body:.2g} m/s^2): the "
                                  "model's, not the IMU's"))
        else:
            kept.append(span)
    return kept, aside


def _said_step(x):
    """A model step's size in words: m/s^2, or 'none here' (no stop, no moving pitch there)."""
    return f"{x:.2g} m/s^2" if x > 0 else "none here"


def _window_peak(t, series, t0, window_s=2.0, reach=5.0):
    """The series' largest value over the scan's window at t0 (s) and its baselines (within
    `reach` s of it either side); 0 where no bin lies there."""
    k = (t >= t0 - reach) & (t <= t0 + window_s + reach)
    return float(np.nanmax(series[k])) if k.any() else 0.0


def _window_step(t, series, t0, window_s=2.0, around=(-5, -4, 4, 5)):
    """|the series' mean over the scan's window at t0 (s) less its mean over the baseline
    windows| (`scan.excursions`: those starting 4 and 5 s either side) - a model error
    constant over a stretch moves a window's mean by the share of its bins in it; NaN where
    the series is not known."""
    def mean(start):
        inside = (t >= start) & (t < start + window_s)
        return np.mean(series[inside]) if inside.any() else math.nan
    base = np.array([mean(t0 + d) for d in around])
    if np.isfinite(base).sum() < 2:
        return math.nan
    return abs(mean(t0) - np.mean(base[np.isfinite(base)]))

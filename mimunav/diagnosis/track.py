"""Track-level diagnosis: a recording with no reference IMU, only a land vehicle's reference
trajectory (RTK GNSS position and velocity, no attitude).

The ideal IMU is simulated along the trajectory - `vehicle.TrackMotion` (attitude from the
velocity under the no-side-slip and zero-roll assumptions) through `truth.generate`, the
same exact-increment generator as every simulated flight - and stands in for the reference
IMU of the sensor level (`sensor.diagnose`: residual, library, Holm selection, held-out
confirmation, bootstrap). Where the vehicle model is not trusted (crawling between rest
and TRUSTED_SPEED, where the course is noise) the MIMU's samples are left out. The MIMU's
outputs are compared in the track's band: passed through the operations the model applies
to the track (`in_band`: in NED, turned by the model's attitude, the specific force smoothed
as the velocity it is the derivative of, the yaw rate as the course rate of a smoothed
velocity), so that the spline's blunting of sharp turns and departures is on both sides and
not read as a scale or an excursion (its vibration power is taken before, from the outputs
as recorded); not within `TrackMotion.edge_s` of the track's ends, where its smoothing is
one-sided; in bins BIN_ERROR_TIMES times as long as the track's errors stay correlated
(`TrackMotion.error_time_s`: the fit takes its bins as independent, and a bin-to-bin change
of a regressor must be more than the model's own error), with training and held-out blocks
two bins long; and with each bin weighted by the yaw rate's own error law (`rate_noise_
shape`: a course-derived yaw rate errs as 1/speed). On an independent car drive (2 cm fixes
at 10 Hz) these took null drives from unexplained residuals at the sharp turns and the
departures to quiet, and a 2 % yaw-gyro scale from 0.044 [0.025, 0.064] to its value.

What this reference cannot carry, and so what a finding may partly be:
  - body roll and road camber (roll = 0 assumed): a lateral specific force and a roll rate
    the model lacks, proportional to lateral acceleration - they look like accel.y and
    gyro.x terms driven by the yaw rate or lateral acceleration;
  - pitch of the body on its springs under braking and acceleration;
  - motion above ~1 Hz (the 4 Hz track is smoothed), i.e. vibration: noise to the fit;
  - the lever arm between antenna and IMU (assumed zero).
So before the search the reference is checked channel by channel against the recording:
the correlation of the 1 s means of the MIMU's output and of the simulated one over the
trusted samples. An input axis whose correlation is below PREDICTED_CORRELATION (the model
explains less than 81 % of what the MIMU saw on it) is not predicted, and the terms driven
by that axis alone (`library.inputs`) are left out of the library: their regressor would be
mostly the reference's own error (errors in variables: a scale factor fitted against a noisy
input tends to -1). They are reported as not resolvable on this recording. A term of the
whole motion (mounting misalignment, time skew) is fitted only on the channels whose
recorded 1 s means the simulated ones explain, up to the unit's own linear errors, to within
MODEL_ERROR_SHARE of their size, with columns made of such inputs (`_carried_channels`;
`fitted_on_channels`): the gyros' roll and pitch rates, which the model lacks, are left out,
and gravity on accel.z, which it predicts though it hardly varies, is kept. A term with no
such channel is not tested.

After the search every finding must also hold where the reference is weakest (`screen`):
  - it acts on at least one output channel the reference predicts (else its residual is
    mostly the vehicle model's own error);
  - removing it lowers the held-out residual rms where it acts;
  - removing it makes the IMU navigate better: the median of the paired differences of the
    10 s free-inertial windows' end errors (`windows`) with and without it is negative and
    the median end error not up (`navigation_check`). A term that acts only in turns (a
    yaw-gyro scale) changes the median window - straight - by micrometres, and where the
    windows' own errors swamp what it does in the turns it is not confirmed: an
    independent drive's true 2 % yaw scale, found with 1 Hz or 5 cm fixes, changed the
    windows turning over 45 deg by a median -0.045 and +0.010 m (with 2 cm fixes at 10 Hz:
    -0.18 m, confirmed); weighting the windows by how much the term changes them gave
    -6e-5 and +0.008 m - no evidence either way, so such a drive is inconclusive. A
    mounting's tilt (roll, pitch) is not checked so: the windows level themselves on the
    IMU's own specific force and cannot see one (`_tilt`).
A finding that fails one is not confirmed; when none survives, the diagnosis is then
**inconclusive** (something was seen that this reference cannot support); so it is when the reference predicts fewer than MIN_PREDICTED of the six channels or fewer than
MIN_TRUSTED of the samples are usable, and when nothing is found while the model does not
follow a channel (`untested`: its 1 s means unexplained beyond NOT_FOLLOWED times the part's
noise - the terms it drives were never tested, and 'nothing is missing' cannot be said of
them). The contract's verdict has no such word: an
inconclusive diagnosis keeps its findings' verdict if any survive, otherwise
"unexplained-residual" (the reference does not explain the recording), with
`conclusive: false` and the reasons in the document.
"""
import math
from dataclasses import dataclass, replace

import numpy as np
import quaternion

from .. import truth as truth_mod
from ..sensors import Mounting
from ..sensors.mimu import DEG, G0
from ..vehicle import HOLD_SPEED, TRUSTED_SPEED, TrackMotion
from . import library, sensor
from .reference import Accuracy
from .sensor import CHANNELS
from ..errors import InputError
from ..evaluation import compensated_mimu
from ..effects import vibration_power

# The reference here is a vehicle model, not a FOG-IMU: its attitude comes from the velocity
# under no side slip and zero roll, so its own "scale and misalignment" are those of the
# assumption - road bank and grade, tyre slip: about 1 % and 10 mrad (assumed, a car on
# ordinary roads). Linear terms must beat that to be charged to the IMU. But the yaw rate is
# the course's rate, which has no scale error of its own: the z gyro of a body tilted by phi
# (road superelevation and body roll, which roll = 0 lacks) reads it times cos(phi) - 0.5 %
# at 5.7 deg (a 10 % superelevation, above the 8 % most design codes allow): 0.5 % for the
# gyros' scale (their other axes are rarely predicted; at 1 % a 2 % yaw-gyro scale of an
# independent drive, found at 0.0206, was set aside as the vehicle model's own).
VEHICLE_MODEL_ACCURACY = Accuracy(gyro_scale=5e-3, accel_scale=1e-2, gyro_misalignment_rad=1e-2,
                                  accel_misalignment_rad=1e-2,
                                  source="track level: land-vehicle model (assumed: gyro scale "
                                         "0.5 %, accel scale 1 %, 10 mrad)",
                                  given=Accuracy.KEYS)
PREDICTED_CORRELATION = 0.9
MODEL_ERROR_SHARE = math.sqrt(1 - PREDICTED_CORRELATION ** 2)   # 0.44: of a channel's
# recorded 1 s means, the rms that no linear error of the unit explains (`reference_check`)
# over the simulated means' rms - the share the model leaves unexplained at that correlation,
# measured against the channel's size, not its variation: gravity on accel.z is predicted
# though it hardly varies (`_carried_channels`)
CHECK_BIN_S = 1.0
BIN_ERROR_TIMES = 2     # bins of the fit, in the track's error times: a wandering bias's GLS
# weighs the bin-to-bin changes, and over one error time those of the model's horizontal
# specific force are mostly its own error (errors in variables: each regressor made from it
# shrinks). On the RTKLIB drive the pitch of the IMU, by plain least squares on the model's
# bin means, is -6.2 to -6.6 deg at 0.2-1 s bins; on their bin-to-bin changes -0.4 at 0.2 s,
# -2.4 at 0.5 s (one error time), -6.4 at 1 s. With bins of one error time the diagnosis
# read -4.7 [-6.0, -3.5] deg against the data author's -6.79; with two, -5.9 [-7.2, -4.7].
# A choice measured there and on the independent drives (bench/track_drive.py: level nulls
# quiet 6 of 6, the noise-free reference's gyro.z excursion gone; the effects as before), not
# a derived constant.
MIN_PREDICTED = 3           # of six channels: fewer, and the reference cannot carry a verdict
MIN_TRUSTED = 0.25          # fraction of the MIMU's samples inside the trusted motion
CHECK_WINDOW_S = 10.0       # free-inertial windows of the navigation check
MIN_CHECK_WINDOWS = 5       # fewer windows cannot confirm a term in navigation
IMU_GAP_S = 0.1            # an IMU step this long is a gap (a car moves ~3 m): not interpolated
REFERENCE_GAP_S = 2.0      # a reference step this long is an outage (1 Hz fixes are not)
GAP_MARGIN_S = 2.0         # s left out on each side of a gap: the 1 s bins, the 0.5 s lag
                           # search and the derivative filters reach no farther
SCALE_CHECK = 0.2           # a predicted channel recording 20 % more or less than the reference
                            # predicts: beyond any MEMS scale error (about 1-3 %, seed S1) and
                            # the vehicle model's own

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
    motion = TrackMotion(tr.t, tr.lat, tr.lon, tr.h, tr.v_ned,
                         differenced=velocity_is_differenced(tr))
    t = flight.mimu_t
    inside = (t > motion.t0) & (t <= motion.t1)
    if inside.sum() < 2:
        raise InputError(f"{flight.path}: the reference trajectory does not cover the MIMU")
    stamps = np.concatenate([[motion.t0], t[inside]])
    run = truth_mod.generate(motion, stamps)
    dt = np.diff(stamps)[:, None]
    ref = replace(flight, fog_t=t[inside], fog_w=run.dtheta / dt, fog_f=run.dv / dt,
                  fog_mounting=Mounting())
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
    from ..importers import velocity_from_positions
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
    from .. import attitude
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
    reversing when most of the `alignment.travel_sign` verdicts that decide on a step_s grid
    of its epochs faster than alignment.COURSE_SPEED say so (at a constant speed on a
    straight road none decides: such verdicts had counted as forward). The vehicle model
    takes the attitude from the velocity, so reversing it faces the wrong way and predicts
    nothing: those samples are left out (a drive that reversed over 150 s had been
    inconclusive, '1 of 6 channels predicted', and its lag averaged with the reversed
    stretch's)."""
    from .. import alignment
    from ..windows import track_of
    t, tr = flight.mimu_t, flight.truth
    track = track_of(tr)
    speed = np.hypot(tr.v_ned[:, 0], tr.v_ned[:, 1])
    mean = alignment.means_around(tr.t, tr.v_ned[:, :2], tr.t, alignment.STATIC_AVERAGE_S / 2)
    moving = np.linalg.norm(mean, axis=1) > alignment.STATIC_SPEED
    edges = np.flatnonzero(np.diff(np.concatenate([[0], moving.astype(int), [0]])))
    out = np.zeros(len(t), bool)
    for a, b in zip(edges[::2], edges[1::2]):                 # epochs a .. b - 1 move
        grid = np.arange(tr.t[a], tr.t[b - 1], step_s)
        fast = grid[np.interp(grid, tr.t, speed) >= alignment.COURSE_SPEED]
        fast = fast[(fast > t[0]) & (fast < t[-1])]
        signs = [alignment.travel_sign(t, flight.mimu_imu[1], flight.mimu_mounting, track, x,
                                       undecided=0.0) for x in fast]
        if np.sum(signs) < 0:           # the decided verdicts (a straight cruise: none)
            out |= (t >= tr.t[a]) & (t <= tr.t[b - 1])
    return out


def near_gaps(t, t_reference):
    """(N,) bool over the MIMU's stamps t (s): within GAP_MARGIN_S of a gap - an IMU step
    longer than IMU_GAP_S or a reference step longer than REFERENCE_GAP_S. Across a gap the
    simulated reference IMU is an interval mean over the whole gap and the derivative
    filters, the lag search and the 1 s bins would mix its two sides (a 5 s IMU gap turned
    a clear 80 ms lag into an inconclusive one), so those samples are left out instead of
    the recording being refused."""
    t = np.asarray(t, float)
    step, ref_step = np.diff(t), np.diff(t_reference)
    edges = [(t[k], t[k + 1]) for k in np.flatnonzero(step > IMU_GAP_S)]
    edges += [(t_reference[k], t_reference[k + 1])
              for k in np.flatnonzero(ref_step > REFERENCE_GAP_S)]
    near = np.zeros(len(t), bool)
    for a, b in edges:
        near |= (t > a - GAP_MARGIN_S) & (t < b + GAP_MARGIN_S)
    return near


def reference_check(ref, trusted):
    """({channel label: correlation of the CHECK_BIN_S means of the recorded and the
    simulated output over trusted samples}, {channel label: [cov / var(simulated),
    var(recorded) / cov], the two least-squares slopes of the recorded means on the
    simulated ones, between which the true one lies when both carry noise}, {label: the
    model error (below)}, {label: the rms of the recorded means no linear error of the unit
    explains, SI units}, {label: the standard deviation of the simulated means, SI}) (channels
    in `sensor.CHANNELS` order)."""
    from .reference import predicted_mimu
    f_p, w_p, _ = predicted_mimu(ref)
    w, f = ref.mimu_imu
    t = ref.mimu_t
    m = max(1, round(CHECK_BIN_S / np.median(np.diff(t))))
    k = np.flatnonzero(trusted)
    k = k[:len(k) // m * m]
    mean = lambda x: x[k].reshape(-1, m, 6).mean(axis=1)                     # noqa: E731
    meas, pred = mean(np.hstack([f, w])), mean(np.hstack([f_p, w_p]))

    def correlation(x, y):            # nan, not a warning, when there is nothing to correlate
        if len(x) < 3 or not (np.std(x) > 0 and np.std(y) > 0):
            return math.nan
        return float(np.corrcoef(x, y)[0, 1])

    def slope(x, y):
        if len(x) < 3 or not (np.std(x) > 0 and np.std(y) > 0):
            return [math.nan, math.nan]
        c = float(np.cov(x, y)[0, 1])
        return [c / float(np.var(y, ddof=1)), float(np.var(x, ddof=1)) / c if c else math.nan]
    def model_error(c):
        # what no linear error of the unit (bias, scale, misalignment: a constant and the
        # triad's predicted means) explains of the channel's recorded means, rms, over the
        # predicted means' rms (the recording's rms would count the sensor's own bias:
        # comma2k19's 0.6 deg/s on gyro.x passed a channel the model does not predict; and
        # the unexplained spread without the triad, the mounting's own yaw on accel.x)
        size = float(np.sqrt(np.mean(pred[:, c] ** 2))) if len(pred) >= 5 else 0.0
        if not size > 0:
            return math.nan
        return unexplained(c) / size

    def unexplained(c):
        if len(pred) < 5:
            return math.nan
        triad = pred[:, :3] if c < 3 else pred[:, 3:]
        x = np.column_stack([triad, np.ones(len(triad))])
        rest = meas[:, c] - x @ np.linalg.lstsq(x, meas[:, c], rcond=None)[0]
        return float(np.sqrt(np.mean(rest ** 2)))
    labels = [f"{s}.{a}" for s, a in CHANNELS]
    return ({n: correlation(meas[:, c], pred[:, c]) for c, n in enumerate(labels)},
            {n: slope(meas[:, c], pred[:, c]) for c, n in enumerate(labels)},
            {n: model_error(c) for c, n in enumerate(labels)},
            {n: unexplained(c) for c, n in enumerate(labels)},
            {n: float(np.std(pred[:, c])) if len(pred) >= 5 else math.nan
             for c, n in enumerate(labels)})


def diagnose(flight, cal, alpha=0.05, reference=None, accuracy=None):
    """Sensor-level diagnosis of `flight` against the ideal IMU simulated along its
    reference trajectory (`reference`: a `simulated_reference(flight)` already made);
    untrusted samples and the terms of unpredicted input axes (see the module) are left out.
    The returned diagnosis carries `reference_check`."""
    if flight.mimu_platform is not None:
        raise InputError(f"{flight.path}: the MIMU turns on a platform (/mimu/platform); "
                         "this analysis does not follow the rotation yet - replay and table do")
    if flight.mimu_raw is not None:
        raise InputError(f"{flight.path}: the track level takes a recorded /mimu/imu; a raw "
                         "MIMU with a reference trajectory goes to the navigation level")
    back = reversing(flight)
    reversing_s = float(np.sum(np.diff(flight.mimu_t, prepend=flight.mimu_t[0])[back]))
    ref, trusted, motion = reference or simulated_reference(flight, back)
    # the outputs through the model (a CAL+found.json's terms removed) on the whole record,
    # before the untrusted samples are blanked: a found time skew's derivative window would
    # spread each blank over its neighbours (re-diagnosing the RTKLIB drive with its own
    # found terms kept 34 of 522 s), and the reference check and the lag judge what the
    # model leaves (the lag had been found again on the outputs as recorded); then in the
    # track's band, on the whole record too (a blank would be bridged by interpolation)
    outputs = compensated_mimu(flight, cal, warn=False)[:2]
    banded = in_band(motion, flight.mimu_t, outputs, flight.mimu_mounting.q_vs)
    w, f = (np.where(trusted[:, None], x, np.nan) for x in banded)
    vibration = vibration_power(flight.mimu_t, np.nan_to_num(outputs[1]))
    ref = replace(ref, mimu_imu=(w, f))
    bin_s = max(sensor.FAST_BIN_S, BIN_ERROR_TIMES * motion.error_time_s)
    block_s = max(sensor.SPLIT_BLOCK_S, 2 * bin_s)
    corr, slopes, spread, rest, moves = reference_check(replace(ref, mimu_imu=banded), trusted)
    unpredicted = {tuple(c.split(".")) for c, r in corr.items() if not r >= PREDICTED_CORRELATION}
    loose = {tuple(c.split(".")) for c, r in spread.items() if not r <= MODEL_ERROR_SHARE}
    kept, left_out, narrowed = [], [], {}
    because = {}                # label of a left-out term: the channels it was left out for
    for term in library.candidates():
        drivers = library.inputs(term)
        # a lever arm is the antenna's and the reference point's business here: the vehicle
        # model's rates cannot tell it from the track's own offsets (on the RTKLIB drive it
        # was chosen and then rejected by the navigation check, after a time skew had been
        # confirmed beside it)
        unknowable = term["effect"] == "lever_arm"
        if unknowable or drivers and drivers & unpredicted:
            left_out.append(term)
            because[library.label(term)] = set() if unknowable else drivers & unpredicted
            continue
        carried = _carried_channels(term, loose)
        if carried is not None and not carried:
            left_out.append(term)
            because[library.label(term)] = loose
            continue
        if carried is not None:
            term = library.on_channels(term, carried)
            narrowed[library.label(term)] = term["channels"]
        kept.append(term)
    diag = sensor.diagnose(ref, replace(cal, model=cal.base_model, found=[]), alpha=alpha,
                           candidates=kept,
                           accuracy=VEHICLE_MODEL_ACCURACY.merged(accuracy),
                           max_wander=wander_limit(bin_s=bin_s), output_tests=False,
                           wander_steps=wander_steps(bin_s=bin_s),
                           vibration=vibration, bin_s=bin_s, block_s=block_s,
                           noise_shape=rate_noise_shape(ref, trusted, motion, bin_s))
    diag.level = "track"
    diag.reference_check = {
        "correlation_1s": corr, "threshold": PREDICTED_CORRELATION, "slope_1s": slopes,
        "model_error_1s": spread, "model_error_threshold": MODEL_ERROR_SHARE,
        "unexplained_1s": rest, "noise_1s": noise_floor(), "predicted_spread_1s": moves,
        "unpredicted_inputs": sorted(".".join(c) for c in unpredicted),
        "not_tested": [library.label(term) for term in left_out],
        "not_tested_for": {label: sorted(".".join(c) for c in chans)
                           for label, chans in because.items()},
        "fitted_on_channels": narrowed,
        "trusted_fraction": float(trusted.mean()),
        "bin_s": bin_s, "block_s": block_s,
        "reversing_s": float(reversing_s),
        "usable_s": float(len(diag.design.t) * np.median(np.diff(diag.design.t)))}
    reasons, demoted = screen(diag, flight, cal)
    if corr["gyro.z"] >= PREDICTED_CORRELATION:
        tau, ci, segments = time_lag(replace(flight, mimu_imu=outputs), (ref, trusted, motion))
        diag.time_lag = ({"tau_s": tau, "ci95": list(ci)} if math.isfinite(tau) else
                         {"not_estimated": _unplaced(segments)})
        diag.time_lag.update({
            "segments_s": segments.values.tolist(),
            "segments_se_s": np.sqrt(segments.variances).tolist(),
            "segments_unplaced": segments.unplaced,
            "channel": "gyro.z (the vehicle's yaw rate, the model's best channel)",
            "sign": "positive: the IMU's samples describe motion tau s earlier than their "
                    "stamps (it lags), as time_skew"})
        late = _velocity_lag(flight)
        if math.isfinite(tau) and late is not None and abs(late) >= VELOCITY_LAG_NOTE_S:
            diag.time_lag["reference_velocity_lag_s"] = late
            diag.time_lag["relative_to"] = (
                f"the reference's velocity, which lags its own positions by {late * 1e3:.0f} "
                f"ms (reference metadata velocity_lag_s, a filtered velocity): against the "
                f"positions the IMU lags by about {(tau + late) * 1e3:.0f} ms")
        demoted += lag_finding(diag, flight, cal, segments, alpha)
    else:
        diag.time_lag = {"not_estimated": f"the yaw rate is not predicted (1 s correlation "
                                          f"{corr['gyro.z']:.2f} < {PREDICTED_CORRELATION:g})"}
    # terms that failed the checks, and channels the model does not follow, make the
    # diagnosis inconclusive only when nothing held: a finding stands on its own tests,
    # 'nothing is missing' needs the terms of every channel the recording moves tested
    diag.inconclusive = reasons + ([] if diag.findings else demoted + untested(diag))
    return diag


SPEED_BANDS = 5                 # of the trusted bins, by 1/v^2, for the yaw-rate noise's law


def rate_noise_shape(ref, trusted, motion, bin_s):
    """(N, 6): each sample's white variance relative to its channel's floor, in bins of bin_s
    (s), for `sensor.diagnose`. The vehicle model's yaw rate is, moving, the track's smoothed
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
    grows as 1/v^2 from a floor below the part's noise."""
    from .. import attitude
    from .reference import predicted_mimu
    t = ref.mimu_t
    shape = np.ones((len(t), 6))
    _, w_p, _ = predicted_mimu(ref)
    q_vs = ref.mimu_mounting.q_vs
    yaw_error = attitude.rotate(q_vs, ref.mimu_imu[0] - w_p)[:, 2]
    speed = motion.speed(t)
    fast = trusted & (speed > TRUSTED_SPEED) & np.isfinite(yaw_error)
    k = np.floor((t[fast] - t[0]) / bin_s).astype(int)
    count = np.bincount(k)
    full = count >= 0.5 * np.max(count, initial=0)
    error = (np.bincount(k, yaw_error[fast]) / np.maximum(count, 1))[full]
    inverse = (np.bincount(k, speed[fast] ** -2) / np.maximum(count, 1))[full]
    law = yaw_error_law(error, inverse, noise_floor(bin_s=bin_s)["gyro.z"] ** 2)
    if law is None:
        return shape
    slope, floor = law
    along = quaternion.as_rotation_matrix(q_vs)[2] ** 2     # vehicle down in sensor axes
    modelled = speed >= HOLD_SPEED
    shape[modelled, 3:] += (slope / floor) * along / speed[modelled, None] ** 2
    return shape


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


def untested(diag):
    """Why 'nothing found' says nothing of some channels: those the model does not follow
    (their 1 s means unexplained beyond NOT_FOLLOWED times the noise), whose driven terms
    were left out (`reference_check`'s not_tested_for)."""
    check = diag.reference_check
    rest, floor = check["unexplained_1s"], check["noise_1s"]
    lost = sorted(c for c in set(check["unpredicted_inputs"]) | {
        c for chans in check["not_tested_for"].values() for c in chans}
        if not rest[c] <= NOT_FOLLOWED * floor[c])
    terms = [label for label, chans in check["not_tested_for"].items() if set(chans) & set(lost)]
    if not terms:
        return []
    said = ", ".join(f"{c} {rest[c]:.3g} against {floor[c]:.3g}" for c in lost)
    return [f"no term driven by {', '.join(lost)} was tested: the reference does not follow "
            f"them (rms of their 1 s means that no linear error of the unit explains, against "
            f"the part's own noise, m/s^2 or rad/s: {said}), so {len(terms)} candidate terms "
            "were left out, and nothing found among the others says nothing of them"]


def _carried_channels(term, loose):
    """The output channels [(sensor, axis)] a term of the whole motion is fitted on here:
    those not in `loose` (the channels whose model error, what no linear error of the unit
    explains, exceeds MODEL_ERROR_SHARE of their predicted size), whose column is made of
    inputs not in it either (`library.channel_inputs`); None when the term is not such a
    term or keeps them all.
    Elsewhere a column is the vehicle model's own error - the roll and pitch rates it does
    not have (zero roll, pitch from the grade): on the RTKLIB drive the gyros' columns of
    mounting_misalignment (gyro.y <- w_z phi_x: the body's roll in corners) carried its
    roll angle, which then followed the road (ten 55 s segments from -2.4 to +6.4 deg; the
    whole drive's and its first 316 s 95 % intervals disjoint), while the accelerometers'
    alone gave one angle in every window."""
    carried = library.channel_inputs(term)
    if carried is None:
        return None
    kept = [ch for ch, inputs in carried.items() if ch not in loose and not inputs & loose]
    return kept if len(kept) < len(carried) else None


def screen(diag, flight, cal):
    """Move the findings that fail the module's checks to `diag.rejected`; returns (the
    reasons the diagnosis is inconclusive whatever it finds, the demoted findings with
    why)."""
    check = diag.reference_check
    unpredicted = set(check["unpredicted_inputs"])
    reasons = []
    predicted = 6 - len(unpredicted)
    if predicted < MIN_PREDICTED:
        reasons.append(f"the reference predicts {predicted} of 6 channels (1 s correlation >= "
                       f"{PREDICTED_CORRELATION:g}; not: {', '.join(sorted(unpredicted))})")
    for name, (low, high) in check["slope_1s"].items():
        # a channel whose predicted means hardly move (within NOT_FOLLOWED times the part's
        # noise) shows no scale: a mounting misalignment - a term of the model - turns the
        # other axes into it (on a level noise-free drive with the mounting 10 deg off in
        # yaw, gyro.x, 0.18 times the noise, recorded 1.22 times its Earth-rate prediction)
        if name in unpredicted or not check["predicted_spread_1s"][name] > \
                NOT_FOLLOWED * check["noise_1s"][name]:
            continue
        if min(low, high) > 1 + SCALE_CHECK or max(low, high) < 1 - SCALE_CHECK:
            reasons.append(f"{name} records {math.sqrt(low * high):.3g} times what the "
                           f"reference predicts (1 s means, correlation "
                           f"{check['correlation_1s'][name]:.3f}): a unit, scale or axis "
                           "error far beyond any term of the model")
    if check["trusted_fraction"] < MIN_TRUSTED:
        reasons.append(f"{100 * check['trusted_fraction']:.0f} % of the samples are in trusted "
                       f"motion (need {100 * MIN_TRUSTED:.0f} %)")
    kept, demoted = [], []
    baseline = None
    for finding in diag.findings:
        j = sensor._position(diag.design, finding)
        acts_on = {".".join(CHANNELS[ch]) for ch in diag.design.columns[j]}
        fit = finding["fit"]
        why = None
        half_sample = 0.5 * float(np.median(np.diff(flight.mimu_t)))
        if acts_on <= unpredicted:
            why = f"acts only on channels the reference does not predict ({', '.join(sorted(acts_on))})"
        elif finding["effect"] == "time_skew" and not abs(finding["coefficient"]) > half_sample:
            # the reference is a smoothed GNSS track: its own timing is not known to better
            # than half an IMU sample (a 0.23 ms 'skew' of an ideal drive was this)
            why = (f"{finding['coefficient'] * 1e3:.2g} ms is within half a sample interval "
                   f"({half_sample * 1e3:.2g} ms): finer than the track reference's timing")
        elif not fit["heldout_rms_after"] < fit["heldout_rms_before"]:
            why = (f"does not lower the held-out residual where it acts "
                   f"({fit['heldout_rms_before']:.4g} -> {fit['heldout_rms_after']:.4g} "
                   f"{fit['units']})")
        elif _tilt(finding):
            finding["navigation_check"] = {"not_applicable": TILT_UNSEEN}
        else:
            if baseline is None:
                baseline = _window_ends(flight, cal, [])
            why = navigation_check(flight, cal, finding, baseline)
        if why is None:
            kept.append(finding)
        else:
            diag.rejected.append(dict(finding, rejected=why))
            demoted.append(f"{finding['label']} {why}")
    diag.findings = kept
    return reasons, demoted


TILT_UNSEEN = ("a tilt (its turn about the vehicle's down axis holds 0): the windows take "
               "their attitude from the IMU's own velocity increments, whose gravity sets the "
               "roll and pitch, so no window sees it; confirmed on the held-out residual only")


def _tilt(finding):
    """True for a mounting misalignment whose turn about the vehicle's down axis is not
    told from 0 (its 95 % interval holds 0): a roll or pitch of the IMU on the vehicle, which
    the free-inertial windows cannot see - `alignment.moving_attitude` levels each window on
    the IMU's own specific force. On an independent level drive a 3 deg pitch, found at
    -0.0525 [-0.072, -0.033] (truth -sin 3 deg), changed the windows' median paired end
    error by +5 mm and their vertical by 0 (a 6.8 deg one by -8 mm), where a 3 deg yaw
    changes them by metres: the check cannot confirm a tilt, nor refute one. A yaw too
    poorly determined to be told from 0 passes with it unchecked."""
    if finding["effect"] != "mounting_misalignment" or "vector_vehicle_ci95" not in finding:
        return False
    low, high = finding["vector_vehicle_ci95"][2]
    return low <= 0.0 <= high


def navigation_check(flight, cal, finding, baseline):
    """Why `finding` is not confirmed in navigation, or None when it is: the CHECK_WINDOW_S
    free-inertial windows with it removed must end nearer the reference - the median of the
    paired changes below 0 and the median end error not up - over at least
    MIN_CHECK_WINDOWS windows (fewer cannot say; a 20 s recording confirmed a term that
    tripled its navigation error). Writes finding["navigation_check"] when it ran.
    baseline: `_window_ends` without it."""
    ends = _window_ends(flight, cal, [finding])
    both = [] if ends is None or baseline is None else sorted(set(ends) & set(baseline))
    n = len(both)
    if n < MIN_CHECK_WINDOWS:
        return (f"cannot be checked in navigation: {n} free-inertial {CHECK_WINDOW_S:g} s "
                f"windows (need {MIN_CHECK_WINDOWS})")
    ends, baseline = (np.array([x[t0] for t0 in both]) for x in (ends, baseline))
    paired = float(np.median(ends - baseline))
    before, after = float(np.median(baseline)), float(np.median(ends))
    finding["navigation_check"] = {
        "windows": n, "window_s": CHECK_WINDOW_S, "median_end_error_m": [before, after],
        "median_paired_change_m": paired}
    if not (paired < 0 and after <= before):
        return (f"does not navigate better: over {n} {CHECK_WINDOW_S:g} s windows the median "
                f"end error goes {before:.4g} -> {after:.4g} m (median paired change "
                f"{paired:+.3g} m)")
    return None


def _window_ends(flight, cal, findings):
    """{start t0 (s): horizontal end error (m)} of the CHECK_WINDOW_S free-inertial windows
    with the findings removed from the MIMU, or None when the recording holds no window.
    Keyed by the start: the windows start where the IMU is quiet enough to align, and a term
    removed can move a start across that bound (a drive over 1 m hills had 87 windows with a
    gyro.y scale removed and 85 without; paired by position they had ended the diagnosis in
    a traceback)."""
    from .. import windows
    from . import with_found
    found = with_found(cal, findings) if findings else None
    try:
        results, _ = windows.run_all(flight, found, lengths=(CHECK_WINDOW_S,))
    except InputError:
        return None
    return {round(w.t0, 6): float(w.horizontal[-1]) for w in results[CHECK_WINDOW_S]}


LAG_SEARCH_S = 0.5
LAG_SEARCH_MAX_S = GAP_MARGIN_S     # s: a segment least at +-LAG_SEARCH_S is searched on to here
VELOCITY_LAG_NOTE_S = 0.02      # s: a reference velocity this late is named beside the lag
LAG_REFERENCE_STEP_S = 0.5      # s: a track with sparser epochs cannot place the lag (its
                                # bandwidth shifts the yaw rate's phase by tens of ms)
LAG_STEP_S = 0.005
LAG_SEGMENTS = 10
MIN_HALF_SEGMENTS = 2           # placed segments in each half (a t test needs 2)


def lag_finding(diag, flight, cal, segments, alpha):
    """The yaw-rate lag as a `time_skew imu.all` finding when the data support it: its value
    and interval from all segments (`time_lag`), significant in each half alone (alternate
    segments among those that place a lag, at least MIN_HALF_SEGMENTS each; a t test of each
    half against 0 at level alpha: replicated), and the
    free-inertial windows navigate better with the IMU's stamps shifted by it (the module's
    navigation check). The sensor level's time_skew over all channels may be rejected beside
    it: the vehicle model predicts the other channels too poorly to show a lag. A track
    whose epochs are more than LAG_REFERENCE_STEP_S apart cannot place the lag. Returns the
    descriptions of the findings it demoted (`_no_lag`)."""
    step = float(np.median(np.diff(flight.truth.t)))
    if step > LAG_REFERENCE_STEP_S:
        return _no_lag(diag, f"the reference's epochs are {step:.2g} s apart: its track "
                             "cannot place a lag of tens of ms (the RTKLIB drive's 1 Hz "
                             "subset moved the lag by 17-54 ms, beyond its interval)")
    if len(segments.values) < 2 * MIN_HALF_SEGMENTS:
        return _no_lag(diag, _unplaced(segments))
    train, held = segments.part(slice(0, None, 2)), segments.part(slice(1, None, 2))
    p_train, p_held = train.p_value(), held.p_value()
    if not (p_train < alpha and p_held < alpha):
        return _no_lag(diag, f"the segments' lag is not significant in both halves (p "
                             f"{p_train:.2g} training, {p_held:.2g} held out)")
    value, ci = segments.mean_and_interval()      # all segments; the halves: replication
    finding = {"effect": "time_skew", "sensor": "imu", "axis": "all",
               "coefficient": value, "ci95": [float(ci[0]), float(ci[1])], "units": "s",
               "ci95_method": "student-t over segments",
               "label": "time_skew imu.all", "p_train": p_train,
               "holm_threshold": alpha,               # one test: Holm's limit is alpha
               "p_heldout": p_held, "attribution": "mimu-or-reference",
               "indistinguishable_from": [],
               "basis": "the yaw rate against the vehicle model (time_lag): value and interval "
                        "from all segments (random-effects weighted, Segments.mean_and_se), "
                        "significant in the even and in the odd ones alone",
               "where": [{"t0": float(flight.mimu_t[0]), "t1": float(flight.mimu_t[-1]),
                          "condition": "every sample: a shift of the IMU's stamps"}],
               "fit": {"channels": ["gyro.z"], "units": "s",
                       "heldout_rms_before": held.weighted_rms(0.0),
                       "heldout_rms_after": held.weighted_rms(train.mean_and_se()[0]),
                       "basis": "inverse-variance weighted rms of the held-out segments' lags "
                                "about 0 and about the training value"}}
    fit = finding["fit"]
    if not fit["heldout_rms_after"] < fit["heldout_rms_before"]:
        return _no_lag(diag, f"the held-out segments' lags lie nearer 0 than the training "
                             f"value (rms {fit['heldout_rms_before']:.3g} -> "
                             f"{fit['heldout_rms_after']:.3g} s)")
    why = navigation_check(flight, cal, finding, _window_ends(flight, cal, []))
    if why is not None:
        return _no_lag(diag, why)
    diag.findings = [f for f in diag.findings if f["effect"] != "time_skew"] + [finding]
    for r in diag.rejected:
        if r["effect"] == "time_skew" and r.get("sensor") in ("imu", "gyro"):
            r["rejected"] += ("; the lag itself is found from the yaw rate, the channel the "
                              "vehicle model predicts best (time_skew imu.all above)")
    return []


def _unplaced(segments):
    """Why `segments` (fewer than 2 x MIN_HALF_SEGMENTS placed) give no lag, in words."""
    at = ", ".join(f"{v:.3f}" for v in segments.values)
    return (f"{len(segments.values)} of {LAG_SEGMENTS} segments place a lag within "
            f"+-{LAG_SEARCH_MAX_S:g} s" + (f" (at {at} s)" if at else "") +
            f"; in the other {segments.unplaced} the yaw rate's rms is least at the search's "
            "edge or places the lag no better than that (the vehicle hardly turns there, or "
            "the lag is larger): "
            f"{2 * MIN_HALF_SEGMENTS} are needed to bound it and replicate it in two halves")


def _velocity_lag(flight):
    """The reference's velocity lag behind its positions (s) from the log's `reference`
    metadata (written at import, `importers.velocity_lag_s`), or None."""
    try:
        return float((flight.reference_meta or {})["velocity_lag_s"])
    except (KeyError, TypeError, ValueError):
        return None


def _no_lag(diag, why):
    """The yaw-rate lag is not a finding (`why`): say so, and move the sensor level's
    time_skew findings to the rejected - the lag is judged on the yaw rate, the channel the
    vehicle model predicts best; a time_skew on the other channels is a vehicle-model
    artefact that can pass (the RTKLIB drive's accelerometers gave 0.024-0.073 s for a
    0.102 s lag, depending on the IMU's rate). Returns the demotions' descriptions."""
    if "not_estimated" not in diag.time_lag:            # else it says why already
        diag.time_lag["not_a_finding"] = why
    demoted = []
    for finding in [f for f in diag.findings if f["effect"] == "time_skew"]:
        reason = f"the lag is judged on the yaw rate, and there it is not a finding: {why}"
        diag.findings.remove(finding)
        diag.rejected.append(dict(finding, rejected=reason))
        demoted.append(f"{finding['label']}: {reason}")
    return demoted


def time_lag(flight, reference=None):
    """The IMU's time-stamp lag tau (s, positive: its samples describe motion tau seconds
    earlier than their stamps, as `time_skew`) from the vehicle's yaw rate alone - the
    channel the land-vehicle model predicts best: the tau minimising the rms of
    w_z,IMU(t) - w_z,model(t - tau) over trusted moving samples (grid of LAG_STEP_S, refined
    by a parabola), per LAG_SEGMENTS contiguous segments. A segment's lag is known to
    var = s^2 / sum (dw_z/dt)^2 (s: its residual rms at the minimum; the lag's regressor is
    the yaw acceleration; s at least the part's white noise, CONSUMER_NOISE), so a segment
    where the vehicle hardly turns weighs little. A segment whose rms is least at the edge of
    the +-LAG_SEARCH_S search is searched on to +-LAG_SEARCH_MAX_S (a lag beyond the first
    search); one still least at that edge, or known no better than +-LAG_SEARCH_MAX_S,
    places no lag and is left out (`Segments.unplaced`): on a noise-free drive with one
    sharp turn the straight segments' model error sloped the rms across the whole search,
    their end parabolas said -14.6 and +28 s, and the mean came out 2.5 s [-3.7, 8.8] for a
    0.1 s lag (the turn's two segments: 0.100).
    Returns (tau: the weighted mean, its 95 % interval (Student t, the standard error
    scaled by the segments' Birge ratio when above 1), `Segments`); NaN and a NaN interval
    when fewer than 2 x MIN_HALF_SEGMENTS segments place a lag (two agreeing halves of one
    turn gave 117 ms [110, 124] for 100: the track's own phase error, which only the
    scatter of more segments shows).
    The IMU's yaw rate is compared in the track's band (`TrackMotion.in_band`).
    `reference`: a `simulated_reference(flight)` already made."""
    from .. import attitude
    ref, trusted, motion = reference or simulated_reference(flight)
    t = flight.mimu_t
    q_vs = flight.mimu_mounting.q_vs
    w_imu = attitude.rotate(q_vs, in_band(motion, t, flight.mimu_imu, q_vs)[0])[:, 2]
    w_model = np.interp(t, ref.fog_t, ref.fog_w[:, 2])
    moving = trusted & (np.abs(w_model) > 0) & (t > ref.fog_t[0] + LAG_SEARCH_MAX_S) & \
        (t < ref.fog_t[-1] - LAG_SEARCH_MAX_S)
    k = np.flatnonzero(moving)
    accel = np.gradient(w_model, t)[k]
    # each sample weighs its own interval and the segments are equal shares of the moving
    # time, not of the samples: a logger switched from 100 to 50 Hz had put its segment
    # boundaries elsewhere and one 30 s stretch had swung the mean (0.078 for 0.102 s)
    step = np.diff(t, prepend=t[0] - np.median(np.diff(t)))[k]
    weight = np.minimum(step, 2 * np.median(step)) / np.median(step)
    share = np.cumsum(weight) / np.sum(weight)
    part = np.minimum((share * LAG_SEGMENTS).astype(int), LAG_SEGMENTS - 1)

    imu = w_imu[k] - w_imu[k].mean()
    total = np.maximum(np.bincount(part, weight, LAG_SEGMENTS), 1e-300)

    def curves(taus):           # (len(taus), LAG_SEGMENTS): each segment's weighted mse
        out = np.empty((len(taus), LAG_SEGMENTS))
        for j, tau in enumerate(taus):
            model = np.interp(t[k] - tau, ref.fog_t, ref.fog_w[:, 2])
            err = imu - (model - model.mean())
            out[j] = np.bincount(part, weight * err * err, LAG_SEGMENTS) / total
        return out
    taus = np.arange(-LAG_SEARCH_S, LAG_SEARCH_S + 1e-12, LAG_STEP_S)
    mse = curves(taus)
    values = np.array([_parabola_min(taus, mse[:, i]) for i in range(LAG_SEGMENTS)])
    lowest = mse.min(axis=0)
    if not np.isfinite(values).all():
        # a segment least at the search's edge is searched on to LAG_SEARCH_MAX_S: a lag
        # beyond the first search is a lag (0.7 s on the weaving drive), not a straight road
        side = np.arange(LAG_SEARCH_S + LAG_STEP_S, LAG_SEARCH_MAX_S + 1e-12, LAG_STEP_S)
        wide = np.concatenate([-side[::-1], taus, side])
        wide_mse = np.concatenate([curves(-side[::-1]), mse, curves(side)])
        for i in np.flatnonzero(~np.isfinite(values)):
            values[i] = _parabola_min(wide, wide_mse[:, i])
            lowest[i] = wide_mse[:, i].min()
    # a residual below the part's own white noise is the vehicle model's error, not a
    # precision: on a noise-free drive, straight segments (a yaw rate of the Earth's and the
    # transport rate, 5e-5 rad/s; the model's residual 1e-6) had put their lags at 0.28 +-
    # 0.003 and -0.33 +- 0.0005 s, and the mean at 0.065 s [-0.25, 0.38] for 0.1 s
    white = CONSUMER_NOISE["gyro_white"] ** 2 / np.median(step)
    info = np.bincount(part, weight * accel * accel, LAG_SEGMENTS)
    variances = np.maximum(lowest, white) / np.maximum(info, 1e-300)
    # a segment whose lag is known no better than the search's reach places none: its least
    # rms anywhere inside is where noise put it (the one-turn drive's straight segments,
    # smoothed into the track's band, had been 'placed' at 1.7 s +- 2.5e5 s and made the
    # turn's two halves count as four)
    placed = np.isfinite(values) & (np.sqrt(variances) <= LAG_SEARCH_MAX_S)
    segments = Segments(values[placed], variances[placed], unplaced=int(np.sum(~placed)))
    if len(segments.values) < 2 * MIN_HALF_SEGMENTS:
        return math.nan, (math.nan, math.nan), segments
    tau, (lo, hi) = segments.mean_and_interval()
    return tau, (lo, hi), segments


@dataclass
class Segments:
    """Per-segment lags (s) and their variances (s^2) of the segments that place a lag inside
    the search; `unplaced`: how many did not (their rms least at the search's edge, or their
    standard error beyond its reach)."""
    values: np.ndarray
    variances: np.ndarray
    unplaced: int = 0

    def part(self, sl):
        """The segments `sl` of those placed (the halves alternate among them)."""
        return Segments(self.values[sl], self.variances[sl])

    def mean_and_se(self):
        """Random-effects mean and its standard error (DerSimonian & Laird 1986): when the
        segments scatter more than their variances say (Cochran's Q > k - 1), that excess
        tau^2 is a variance every segment shares, and the weights are 1 / (var + tau^2) - so
        one segment whose lag looks known to 1 ms cannot carry the mean against the others
        (a 120 s drive's lag came out 474 [343, 606] ms with its segments at 5-580 ms); with
        consistent segments, the inverse-variance mean. The standard error also takes the
        Birge ratio of the re-weighted scatter when above 1."""
        w = self._weights()
        k = len(w)
        mean = float(np.sum(w * self.values) / np.sum(w))
        # and the Birge ratio of what is left (the moment estimate of tau^2 can fall short)
        birge = float(np.sum(w * (self.values - mean) ** 2)) / max(k - 1, 1)
        return mean, float(np.sqrt(max(birge, 1.0) / np.sum(w)))

    def _weights(self):
        """1 / (var + tau^2), tau^2 the DerSimonian-Laird excess of the segments' scatter."""
        w = 1.0 / self.variances
        mean = float(np.sum(w * self.values) / np.sum(w))
        q = float(np.sum(w * (self.values - mean) ** 2))
        tau2 = max(0.0, (q - (len(w) - 1)) / max(np.sum(w) - np.sum(w ** 2) / np.sum(w),
                                                 1e-300))
        return 1.0 / (self.variances + tau2)

    def weighted_rms(self, about):
        """Weighted rms of the lags about `about` (s), the mean's random-effects weights: a
        segment where the vehicle hardly turns (its lag known to seconds) weighs nothing."""
        w = self._weights()
        return float(np.sqrt(np.sum(w * (self.values - about) ** 2) / np.sum(w)))

    def mean_and_interval(self):
        from scipy import stats
        mean, se = self.mean_and_se()
        half = stats.t.ppf(0.975, len(self.values) - 1) * se
        return mean, (mean - half, mean + half)

    def p_value(self):
        """Two-sided p of mean = 0 (Student t with the segments' dof)."""
        from scipy import stats
        mean, se = self.mean_and_se()
        return float(2 * stats.t.sf(abs(mean) / se, len(self.values) - 1))


def _parabola_min(x, y):
    """Abscissa of the minimum of y(x) on a uniform grid, refined by a parabola through the
    smallest value and its neighbours; NaN when the smallest value is at either end of the
    grid (the minimum is not bracketed: a parabola through the end and its two neighbours had
    put a straight stretch's lag at -14.6 s for a +-0.5 s search)."""
    j = int(np.argmin(y))
    if j in (0, len(y) - 1):
        return math.nan
    a, b, c = y[j - 1], y[j], y[j + 1]
    den = a - 2 * b + c
    return float(x[j] + (0.5 * (a - c) / den if den > 0 else 0.0) * (x[1] - x[0]))

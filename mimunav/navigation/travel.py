"""The track's horizontal acceleration against the IMU's specific force: how the IMU feels its
track - the complex gain that turns one into the other, its gains along and across, the
angle's standard error - and which way the vehicle travels (forward or reversing).
"""
import math

import numpy as np

from ..frames import attitude
from .rests import means_around

DIRECTION_SPAN_S = 5.0      # s either side: the track's acceleration that tells reversing
DIRECTION_STEP_S = 1.0      # s: the means it is compared in (`travel_sign`)
DIRECTION_ACCEL = 0.1       # m/s^2: horizontal acceleration (std over the span) that can
#                             tell it: a gentle start or stop reaches it, a steady cruise not


def track_acceleration(t, v_ned):
    """(horizontal speed m/s, course rate rad/s, horizontal acceleration in the direction of
    travel as along + 1j * across m/s^2 - along = d speed/dt, across = speed x course rate,
    positive to the right) of a track at epochs t (s) with velocity v_ned (m/s)."""
    v = np.asarray(v_ned, float)
    speed = np.hypot(v[:, 0], v[:, 1])
    course = np.unwrap(np.arctan2(v[:, 1], v[:, 0]))
    course_rate = np.gradient(course, t)
    return speed, course_rate, np.gradient(speed, t) + 1j * speed * course_rate


def acceleration_match(z_imu, z_track):
    """(gain, coherence 0..1) of the vehicle-frame horizontal specific force z_imu regressed
    on the track's horizontal acceleration z_track (both x + 1j y, `track_acceleration`),
    each less its mean (the tilt's gravity leak): gain = sum(z_imu conj(z_track)) /
    sum|z_track|^2, complex - its angle is the yaw that turns the track's acceleration into
    the IMU's, its size their ratio (1 for a car's IMU mounted as stated); nan and 0 for a
    track that holds still."""
    z_imu, z_track = z_imu - z_imu.mean(), z_track - z_track.mean()
    cross = np.sum(z_imu * np.conj(z_track))
    track = float(np.sum(abs(z_track) ** 2))
    power = math.sqrt(np.sum(abs(z_imu) ** 2) * track)
    if not track:                           # a track that holds still: no gain to it
        return complex(math.nan, math.nan), 0.0
    return complex(cross / track), float(abs(cross) / power) if power else 0.0


def along_across_gains(z_imu, z_ref):
    """(gain along, gain across): the least-squares slopes of the IMU's horizontal specific
    force (x + 1j y, turned onto the track's axes) on the track's acceleration (along + 1j
    across), each component on its own, less their means. A car's are alike (the RTKLIB
    drive 1.04 and 1.04, a phone's 0.98 and 0.88, a noisy 10 Hz track's 0.33 and 0.51); a
    train on canted curves felt 0.94 along and -0.17 across."""
    z_imu, z_ref = z_imu - z_imu.mean(), z_ref - z_ref.mean()
    return (float(z_imu.real @ z_ref.real / (z_ref.real @ z_ref.real)),
            float(z_imu.imag @ z_ref.imag / (z_ref.imag @ z_ref.imag)))


def match_angle_se(z_imu, z_ref, blocks=10):
    """The standard error (rad) of the angle of `acceleration_match`'s gain: the jackknife
    over `blocks` consecutive blocks of the epochs."""
    block = np.arange(len(z_ref)) * blocks // len(z_ref)
    parts = np.array([np.angle(acceleration_match(z_imu[block != b], z_ref[block != b])[0])
                      for b in range(blocks)])
    parts = np.angle(np.exp(1j * (parts - np.angle(np.mean(np.exp(1j * parts))))))
    return math.sqrt((blocks - 1) / blocks * np.sum(parts ** 2))


TRACK_FORCE_RATIO = 1.25   # a car's IMU reads its track's horizontal acceleration at 1 up to
#                            its body's lean and the road's camber (a few degrees of g: 0.92-
#                            1.07 on the RTKLIB drive, its excerpt and a phone's); beyond
#                            0.8-1.25 the specific force is not the track's (a railway's cant
#                            took a train's to 0.39) and its angle tells neither a mounting
#                            nor a direction of travel


def travel_sign(t, f, mounting, track, t0, span=DIRECTION_SPAN_S, undecided=1.0):
    """+1 when the vehicle moves forward at t0 (s), -1 when it reverses (the course is the
    heading + 180 deg: speed changes and the centripetal force act the other way in the
    vehicle frame). Over t0 +- span, where the along-track acceleration varies by
    DIRECTION_ACCEL: the IMU's forward specific force (vehicle x) regressed on it (each less
    its mean), a gain beyond +-0.5 at a correlation beyond 0.5. Else the horizontal
    specific force (x + 1j y) on the track's acceleration (along + 1j across,
    `track_acceleration`): a complex gain whose real part lies beyond +-0.5 at coherence
    above 0.5 - and whose size may be 1 (`follows_track`), the vehicle's specific force its
    track's: a banked road, a railway's cant, an aircraft's coordinated turn take up the
    centripetal force (gain -0.03 to -0.24 on a simulated copter-like flight).
    `undecided` where the data cannot tell (a constant speed on a straight road; fewer than
    5 epochs): forward (1) for an alignment, which must face somewhere; 0 for a vote
    (`diagnosis.track.reversing`)."""
    k = np.flatnonzero((track["t"] >= t0 - span) & (track["t"] <= t0 + span))
    if len(k) < 5:
        return undecided
    # both sides as means over steps of at least DIRECTION_STEP_S: a 10 Hz track with 5 cm
    # fixes differenced has 3-5 m/s^2 of acceleration noise epoch to epoch, and no move of
    # a car was ever coherent with it
    step = max(float(np.median(np.diff(track["t"][k]))), DIRECTION_STEP_S)
    grid = np.arange(t0 - span, t0 + span + 1e-9, step)
    v = means_around(track["t"], track["v_ned"], grid, step / 2)
    known = np.isfinite(v).all(axis=1)
    grid, v = grid[known], v[known]
    if len(grid) < 5:
        return undecided
    _, _, z_track = track_acceleration(grid, v)
    near = slice(*np.searchsorted(t, [t0 - span - step, t0 + span + step]))   # the IMU
    f_v = attitude.rotate(mounting.q_vs, means_around(t[near], f[near], grid, step / 2))
    if not np.isfinite(f_v).all():
        return undecided
    # along the track first: across it a banked road or a railway's cant takes up the turn
    # (a train entering canted curves had read -1 there: three windows faced backwards)
    along = z_track.real - z_track.real.mean()
    if np.std(along) >= DIRECTION_ACCEL:
        forward = f_v[:, 0] - f_v[:, 0].mean()
        gain = float(forward @ along / (along @ along))
        if abs(float(np.corrcoef(forward, along)[0, 1])) > 0.5 and abs(gain) > 0.5:
            return float(np.sign(gain))
    # at a steady speed, the turns - where the vehicle's specific force is its track's
    # acceleration in size (TRACK_FORCE_RATIO): a flat road's car, not a canted track's
    if np.std(z_track) < DIRECTION_ACCEL:
        return undecided
    gain, coherence = acceleration_match(f_v[:, 0] + 1j * f_v[:, 1], z_track)
    if coherence > 0.5 and abs(gain.real) > 0.5 and follows_track(gain, coherence):
        return float(np.sign(gain.real))
    return undecided


def follows_track(gain, coherence):
    """Whether a vehicle's horizontal specific force is its track's acceleration in size
    (`acceleration_match`'s gain and coherence): the gain is the least-squares slope on the
    track, shrunk by the track's own noise, and gain / coherence^2 the reverse slope,
    swollen by the IMU's; the true size lies between, and must reach into
    1/TRACK_FORCE_RATIO .. TRACK_FORCE_RATIO (a noisy 10 Hz car track: 0.43 .. 0.99; a
    canted railway's train at a steady speed: its lateral force a fraction of the turn's)."""
    size = abs(gain)
    return size <= TRACK_FORCE_RATIO and size / max(coherence, 1e-9) ** 2 >= 1 / TRACK_FORCE_RATIO

"""The initial state of a recording and its rests (`navigation.alignment`, `navigation.rests`)."""
import math
import re

import numpy as np
import pytest
import quaternion

from mimunav.navigation import alignment, attitude_biases, rest_biases
from mimunav.navigation.rests import MIN_STATIC_S, STATIC_SPEED, quiet_stretches, rest_intervals
from mimunav.frames import attitude, earth
from mimunav.evaluation import windows
from mimunav.errors import InputError
from mimunav.evaluation.flight import Flight
from mimunav.flightlog import FlightLog
from mimunav.importers import rtklib
from mimunav.importers.write import write_log
from mimunav.frames.mounting import Mounting
from drives import (DEG, DRIVE, H0, LAT0, LON0, MOUNT, ideal_flight, smoothstep, stop_track,
                    straight_track, track_from_velocity, under_a_noisy_fix, under_two_cm)


def test_alignment_recovers_attitude_and_bias_of_a_synthetic_drive(tmp_path):
    """Level, heading (GNSS course after the rest), gyro bias and the moving two-vector
    attitude against the truth of the synthetic drive, seen through the rtklib mounting."""
    bias = np.array([0.01, -0.02, 0.03])
    path, motion, run = ideal_flight(tmp_path, MOUNT, gyro_bias=bias)
    flight = Flight.load(path, reference_imu=False)
    true_yaw, true_pitch, true_roll = attitude.as_euler(motion.kinematics(np.array([0.0])).q_nb)
    yaw, pitch, roll = attitude.as_euler(flight.initial.q_nb)
    assert abs(roll - true_roll[0]) < 1e-4 and abs(pitch - true_pitch[0]) < 1e-4
    assert abs(yaw - true_yaw[0]) < 0.2 * DEG          # course after the smooth start
    w, f = flight.mimu_imu
    rest = alignment.initial_alignment(flight.mimu_t, w, f, flight.mimu_mounting,
                                       windows.track_of(flight.truth))
    assert np.allclose(rest.gyro_bias, bias, atol=1e-7)
    assert np.allclose(rest.accel_bias, 0.0, atol=1e-4)
    for t0, half in ((40.0, 0.25), (77.3, 0.25), (101.0, 0.25), (77.3, 5.0), (101.0, 5.0)):
        q = alignment.moving_attitude(flight.mimu_t, w - rest.gyro_bias, f, flight.mimu_mounting,
                                      windows.track_of(flight.truth), t0, half)
        q_true = motion.kinematics(np.array([t0])).q_nb[0]
        err = attitude.rotation_vector_error(quaternion.from_float_array(q), q_true)
        # velocity matching with the gyro's rotation followed: the level exact up to the
        # sampling, also over 10 s of weaving (a mean specific force over the turning
        # interval had 8e-4 rad at 0.25 s); the heading is the 4 Hz track's interpolated
        # velocity direction's (0.02 deg)
        assert np.abs(err[:2]).max() < 0.005 * DEG, (t0, half, np.degrees(err))
        assert abs(err[2]) < 0.1 * DEG, (t0, half, np.degrees(err))


def test_after_a_rest_the_heading_is_the_references_attitude_turned_back_not_the_course(tmp_path):
    """A reference that carries attitude gives the heading at the rest, not the course (which
    holds only without side slip): the vehicle turns 20 deg as it drives off (to 10 m/s, from
    the rest's end at 20 s); the reference's heading, 10 deg off the truth throughout (a
    crab), taken at the first epoch faster than COURSE_SPEED and turned back to the rest by
    the gyro, is the truth's at rest + 10 - the course would give the truth's, the
    reference's heading unturned that + 10 + the turn so far."""
    t = np.arange(0.0, 60.0 + 1e-9, 0.1)
    speed = 10.0 * smoothstep((t - 20.0) / 5.0)
    yaw = 30 * DEG + 20 * DEG * smoothstep((t - 21.2) / 2.0)    # from 0.9 m/s (HOLD_SPEED 0.5)
    track = track_from_velocity(t, np.column_stack([speed * np.cos(yaw), speed * np.sin(yaw),
                                                    0 * t]))
    path, motion, run = ideal_flight(tmp_path, MOUNT, track=track, with_attitude=True)
    flight = Flight.load(path, reference_imu=False)
    w, f = flight.mimu_imu
    ref = windows.track_of(flight.truth)
    crab = quaternion.from_rotation_vector([0.0, 0.0, 10 * DEG])      # about down: heading +10
    ref["q_nb"] = quaternion.as_float_array(crab * attitude.from_wxyz(ref["q_nb"]))
    align = alignment.initial_alignment(flight.mimu_t, w, f, flight.mimu_mounting, ref)
    heading, _, _ = attitude.as_euler(attitude.from_wxyz(np.asarray(align.q_nb)[None]))
    assert align.heading == "reference" and "turned back to the rest" in align.method
    # leveled on the reference's attitude at the rest; the gyro bias's Earth rate removed
    # at it, the accelerometer's whole bias measured against it: what the metadata says
    assert align.attitude_from == "reference_level"
    assert align.bias_basis["gyro"] == "reference_attitude"
    up = np.asarray(align.bias_basis["gravity_sensor_axes"])
    assert align.bias_basis["accel"] == "all"
    assert np.allclose(up, f[0] / np.linalg.norm(f[0]), atol=1e-6)
    assert flight.recording["bias_basis"]["gyro"] == "reference_attitude"   # the import too
    assert flight.recording["initial_attitude"] == "reference_level"
    t_k = float(align.method.split("heading from the reference's attitude at t = ")[1]
                .split(" s")[0])
    at_rest, at_k = attitude.as_euler(motion.kinematics(np.array([0.0, t_k])).q_nb)[0]
    assert at_k - at_rest > 5 * DEG             # it had turned by then: the turn-back counts
    assert abs(heading[0] - (at_rest + 10 * DEG)) < 0.01 * DEG, np.degrees(heading)


@pytest.mark.parametrize("with_attitude", [True, False])
def test_a_rest_beside_a_reference_attitude_measures_the_whole_accelerometer_bias(
        tmp_path, with_attitude):
    """The synthetic drive's exact increments plus an accelerometer bias of 40 mg across
    gravity and 10 mg along it (a phone's): with the reference's attitude at the rest, its
    level gives the whole bias (an independent trial's windows beside that attitude had
    kept 41 mg: 21 m at 10 s, 1.3 m levelled on the IMU); without it, only the part along
    gravity (T&W 10.2.1) - across it the bias reads as tilt, and the level holds it."""
    bias = np.array([0.3, -0.25, 0.1])
    path, motion, run = ideal_flight(tmp_path, MOUNT, accel_bias=bias,
                                     with_attitude=with_attitude)
    flight = Flight.load(path, reference_imu=False)
    w, f = flight.mimu_imu
    align = alignment.initial_alignment(flight.mimu_t, w, f, flight.mimu_mounting,
                                        windows.track_of(flight.truth))
    q_true = motion.kinematics(np.array([0.0])).q_nb[0]
    up = attitude.rotate(np.conjugate(q_true * MOUNT.q_vs), np.array([0.0, 0.0, -1.0]))
    if with_attitude:
        assert np.allclose(align.accel_bias, bias, atol=1e-4), align.accel_bias
        err = attitude.rotation_vector_error(attitude.from_wxyz(np.asarray(align.q_nb)), q_true)
        assert np.abs(err[:2]).max() < 1e-4
        assert align.bias_basis["accel"] == "all" and align.attitude_from == "reference_level"
        return
    # along gravity (to |b_across|^2 / 2g = 8 mm/s^2), nothing of the 0.39 m/s^2 across it
    across = align.accel_bias - (align.accel_bias @ up) * up
    assert abs(align.accel_bias @ up - bias @ up) < 0.01 and np.linalg.norm(across) < 0.01
    assert align.bias_basis["accel"] == "along_gravity" and align.attitude_from == "leveled"


def test_a_frame_of_unknown_azimuth_leaves_the_earth_rates_horizontal_part_in_the_gyro_bias(
        tmp_path):
    """The synthetic drive's exact increments (the rotating Earth's rate in them) with a
    gyro bias, its reference's north not true north: the bias at the rest is the true one
    plus the Earth rate's horizontal part, Omega cos(lat) north (WGS-84's 7.292115e-5 rad/s),
    turned into sensor axes by the true attitude - not removed at a heading nobody measured."""
    bias = np.array([0.01, -0.02, 0.03])
    path, motion, run = ideal_flight(tmp_path, MOUNT, gyro_bias=bias, with_attitude=True)
    flight = Flight.load(path, reference_imu=False)
    w, f = flight.mimu_imu
    track = dict(windows.track_of(flight.truth), heading_known=False)
    align = alignment.initial_alignment(flight.mimu_t, w, f, flight.mimu_mounting, track)
    q_ns = motion.kinematics(np.array([0.0])).q_nb[0] * MOUNT.q_vs
    north = np.array([7.292115e-5 * math.cos(LAT0), 0.0, 0.0])
    want = bias + attitude.rotate(np.conjugate(q_ns), north)
    assert np.allclose(align.gyro_bias, want, atol=2e-8), (align.gyro_bias - want)
    assert align.bias_basis["gyro"] == "vertical_earth_rate"


def cut_track(track, t0):
    return tuple(x[track[0] >= t0] for x in track)


def test_alignment_in_motion_without_a_rest(tmp_path):
    """A recording that starts on the move (the synthetic drive from 40 s, weaving): the
    initial state is the moving two-vector alignment at the first fast epoch, its attitude
    within 0.1 deg of the truth; the biases, never observed, are 0 and the metadata says
    so. With the reference's own attitude the state is the reference's, exactly."""
    bias = np.array([0.001, -0.002, 0.003])
    track = cut_track(straight_track(), 40.0)
    path, motion, _ = ideal_flight(tmp_path / "moving", MOUNT, gyro_bias=bias, track=track)
    flight = Flight.load(path, reference_imu=False)
    t0 = flight.initial.t
    assert t0 == pytest.approx(40.5 - 40.01, abs=1e-6)     # first fast epoch half a window in
    q_true = motion.kinematics(np.array([t0 + 40.0])).q_nb[0]
    err = attitude.rotation_vector_error(flight.initial.q_nb,
                                         q_true)
    assert np.degrees(np.linalg.norm(err)) < 0.1
    with FlightLog(path) as log:
        meta = log.metadata()["recording"]
    assert "moving alignment" in meta["assumed"]["initial_state"]
    assert "biases taken as 0" in meta["assumed"]["initial_state"]
    assert meta["static_s"] is None and meta["gyro_bias_static_rad_s"] == [0.0, 0.0, 0.0]

    oblique = Mounting.from_rpy_deg((170.0, 20.0, 150.0))
    accel_bias = np.array([0.05, -0.1, 0.2])
    path, motion, _ = ideal_flight(tmp_path / "attitude", oblique, track=track,
                                    with_attitude=True, gyro_bias=bias, accel_bias=accel_bias)
    flight = Flight.load(path, reference_imu=False)
    t0 = flight.initial.t            # the first reference epoch after the first IMU stamp
    assert t0 == pytest.approx(40.25 - 40.01, abs=1e-6)
    assert np.allclose(quaternion.as_float_array(flight.initial.q_nb), quaternion.as_float_array(
        motion.kinematics(np.array([40.25])).q_nb[0]), atol=1e-9)
    # no rest, but the reference's attitude: the gyro bias from its rate (a phone's of
    # several deg/s went unnoticed before), to a fraction of a deg/h on this ideal IMU
    with FlightLog(path) as log:
        meta = log.metadata()["recording"]
    assert "biases from the reference's attitude and velocity" in \
        meta["assumed"]["initial_state"]
    got = np.array(meta["gyro_bias_static_rad_s"])
    assert np.abs(got - bias).max() < 1e-6, got - bias
    # and the accelerometers': the specific force the reference's velocity and attitude
    # imply (T&W eq. 3.70) against the IMU's, on an oblique mounting
    assert np.abs(np.array(meta["accel_bias_m_s2"]) - accel_bias).max() < 1e-5


def test_gyro_bias_from_a_rest_in_the_middle(tmp_path):
    """No rest at the start, 20 s of rest in the middle: the gyro bias comes from that rest,
    exact up to the horizontal Earth rate its unknown heading leaves (Omega cos lat); with
    the reference's attitude the Earth rate is removed whole."""
    bias = np.array([0.01, -0.02, 0.03])
    for with_attitude, tol in ((False, earth.OMEGA * math.cos(LAT0) + 1e-7), (True, 1e-7)):
        path, _, _ = ideal_flight(tmp_path / str(with_attitude), MOUNT, gyro_bias=bias,
                                   track=stop_track(), with_attitude=with_attitude)
        flight = Flight.load(path, reference_imu=False)
        w, f = flight.mimu_imu
        align = alignment.initial_alignment(flight.mimu_t, w, f, flight.mimu_mounting,
                                            windows.track_of(flight.truth))
        assert not align.at_rest_start
        assert 25.0 < align.static[0] < align.static[1] < 45.0 and \
            align.static[1] - align.static[0] > 15.0
        assert np.abs(align.gyro_bias - bias).max() < tol, (with_attitude, align.gyro_bias - bias)
    assert np.abs(align.accel_bias).max() < 1e-4


def test_quiet_stretches_found_from_the_imu_alone():
    """Rest - motion - rest at 100 Hz with a consumer part's noise: the IMU-only test finds
    both rests (to a window) and nothing in the motion, a turn at a steady 20 deg/s included."""
    from mimunav.navigation.rests import (quiet_stretches)
    rng = np.random.default_rng(2)
    t = np.arange(0, 40, 0.01)
    moving = (t >= 10) & (t < 32)
    w = rng.normal(0, 0.005, (len(t), 3)) + [0.002, -0.001, 0.003]
    f = rng.normal(0, 0.02, (len(t), 3)) + [0.0, 0.0, -9.81]
    w[moving, 2] += np.where(t[moving] < 20, 0.3 * np.sin(t[moving]), math.radians(20))
    f[moving, 0] += 1.5 * np.sin(0.7 * t[moving]) + rng.normal(0, 0.3, moving.sum())
    found = quiet_stretches(t, w, f)
    assert len(found) == 2
    (a0, a1), (b0, b1) = found
    assert a0 == 0 and abs(a1 - 10) <= 0.5 and abs(b0 - 32) <= 0.5 and b1 > 39.4
    # a drive that never stops, on a smooth road with a slow 0.6 deg/s bend, passes the
    # IMU's relative test; a reference that covers it and moves says it is no rest
    drive = (rng.normal(0, 0.005, (len(t), 3)) + [0.0, 0.0, math.radians(0.6)],
             rng.normal(0, 0.05, (len(t), 3)) + [0.0, 0.0, -9.81])
    assert quiet_stretches(t, *drive)
    track = {"t": t[::25], "v_ned": np.tile([8.0, 0.0, 0.0], (len(t[::25]), 1))}
    assert quiet_stretches(t, *drive, track) == []


def test_a_rest_is_judged_by_what_the_specific_force_shows_not_by_the_gyros_bias():
    """EuRoC's ADIS16448 at rest before take-off reads (-0.12, 1.19, 4.47) deg/s, 4.3 of them
    across gravity - which would turn the specific force 13 deg over the 5 s, and it moves
    0.02 (its x axis up): a bias, and the rest is one (it had been refused by a 1 deg/s
    limit on the whole rate). The 1.8 deg/s about the vertical, which f cannot show, is
    taken as bias and said to be indistinguishable from a steady turn; one beyond a
    consumer gyro's bias (12 deg/s) is a turn. A slow pitch-over at 4 deg/s is no rest."""
    from mimunav.navigation.rests import vertical_rate_said
    rng = np.random.default_rng(6)
    t = np.arange(0.0, 12.0, 0.005)
    up = np.array([0.93, 0.01, -0.37])                 # sensor axes; x nearly up
    bias = np.radians([-0.12, 1.19, 4.47])
    w = bias + rng.normal(0.0, np.radians(0.2), (len(t), 3))
    f = 9.81 * up / np.linalg.norm(up) + rng.normal(0.0, 0.03, (len(t), 3))
    (t0, t1), = quiet_stretches(t, w, f)
    assert t0 < 0.5 and t1 > 11.0
    said = vertical_rate_said(t, w, f, t0, t1)
    assert "1.7" in said and "a steady turn about the vertical reads alike" in said, said
    spin = w + np.radians(12.0) * up / np.linalg.norm(up)       # about the vertical
    assert quiet_stretches(t, spin, f) == []
    # 30 deg/s across gravity, f held: beyond any gyro's bias, a turn
    assert quiet_stretches(t, np.radians([30.0, 0, 0]) + w - bias, f) == []
    # a coordinated turn at 6 deg/s banked 30 deg: f holds still in the body as at a rest,
    # but reads 1.15 g - the rest it had been, with a 6 deg/s 'bias' and a level 30 deg off
    bank = np.radians(30.0)
    banked = np.radians(6.0) * np.array([0.0, math.sin(bank), math.cos(bank)]) + w - bias
    assert quiet_stretches(t, banked, np.tile([0.0, 0.0, -9.81 / math.cos(bank)], (len(t), 1))
                           + rng.normal(0.0, 0.03, (len(t), 3))) == []
    # a steady level turn reads its rate about a specific force tilted by its centripetal
    # acceleration, g / cos of that tilt in size: no rest though f holds still - a car
    # circling at 5 deg/s and 5 m/s, an aircraft banked 15 deg at 20 m/s (7.5 deg/s), a
    # turntable all record long (a rest, with the table's rate as bias, they had been)
    for rate, speed in ((5.0, 5.0), (7.53, 20.0), (5.0, 0.0)):
        centripetal = np.radians(rate) * speed
        tilt = math.atan2(centripetal, 9.81)
        turning = np.radians(rate) * np.array([0.0, math.sin(tilt), math.cos(tilt)])
        felt = [0.0, 0.0, -math.hypot(9.81, centripetal)] + rng.normal(0.0, 0.03, (len(t), 3))
        assert quiet_stretches(t, turning + w - bias, felt) == [], (rate, speed)
    # a true rest, then a turntable at 5 deg/s: the rest alone (the turn had been the longer)
    level = np.tile([0.0, 0.0, -9.81], (len(t), 1)) + rng.normal(0.0, 0.03, (len(t), 3))
    table = w - bias + np.where(t[:, None] < 4.0, 0.0, np.radians([0.0, 0.0, 5.0]))
    (t0, t1), = quiet_stretches(t, table, level)
    assert t1 <= 4.0
    angle = np.radians(4.0) * t                                  # pitching over, quietly
    pitched = np.column_stack([9.81 * np.sin(angle), np.zeros_like(t), -9.81 * np.cos(angle)])
    turning = np.radians([0.0, 4.0, 0.0]) + rng.normal(0.0, np.radians(0.2), (len(t), 3))
    assert quiet_stretches(t, turning, pitched + rng.normal(0.0, 0.03, (len(t), 3))) == []


def test_a_rest_the_reference_shows_turning_measures_no_bias_about_the_vertical():
    """A turntable at 5 deg/s for 60 s beside a reference whose attitude turns with it (its
    position still): the 300 deg it turns is counted epoch to epoch (from its first and last
    headings it had read -60, 'held', and the table's rate passed as the gyro's bias); the
    words say the rate about the vertical is the turn's and no bias is measured there. A
    reference heading held still leaves the rate as bias, unsaid."""
    from mimunav.frames import attitude
    from mimunav.navigation.rest_biases import vertical_note
    t = np.arange(0.0, 60.0, 0.01)
    w = np.tile(np.radians([0.2, -0.3, 5.25]), (len(t), 1))
    f = np.tile([0.0, 0.0, -9.81], (len(t), 1))
    epochs = np.arange(0.0, 60.0, 0.1)
    turning = {"t": epochs, "q_nb": attitude.as_wxyz(attitude.from_euler(
        np.radians(5.0) * epochs, 0 * epochs, 0 * epochs))}
    said = vertical_note(turning, t, w, f, 0.0, 59.9)
    assert "turns +299.0 deg" in said and "is that turn's" in said, said
    # an AHRS's heading settling by 3.5 deg over a rest its gyro reads still (-0.01 deg/s):
    # the two disagree, said so (it had been 'the IMU's -0.01 deg/s ... is that turn's')
    still = np.tile(np.radians([0.0, 0.0, -0.01]), (len(t), 1))
    settling = dict(turning, q_nb=attitude.as_wxyz(attitude.from_euler(
        np.radians(-3.5) * (1 - np.exp(-epochs / 3)), 0 * epochs, 0 * epochs)))
    said = vertical_note(settling, t[t < 6.0], still[t < 6.0], f[t < 6.0], 0.0, 5.99)
    assert "where the IMU reads -0.01 deg/s" in said and "not confirmed" in said, said
    held = dict(turning, q_nb=attitude.as_wxyz(attitude.from_euler(0 * epochs, 0 * epochs,
                                                                  0 * epochs)))
    assert vertical_note(held, t, w, f, 0.0, 59.9) == ""
    assert "the IMU alone cannot tell" in vertical_note({}, t, w, f, 0.0, 59.9)


def test_no_initial_state_is_a_clear_error():
    """Never at rest, no attitude, never faster than the course speed: the error says all
    three."""
    t = np.arange(0.0, 20.0, 0.01)
    n = len(t)
    r_n, _ = earth.radii(LAT0)
    track = dict(t=t[::25], lat=LAT0 + 1.0 * t[::25] / (r_n + H0), lon=np.full(n // 25, LON0),
                 h=np.full(n // 25, H0), v_ned=np.tile([1.0, 0.0, 0.0], (n // 25, 1)))
    with pytest.raises(InputError, match="no attitude.*does not start with a rest.*its "
                                         "speed peaks at 1.00 m/s, below 3 m/s"):
        alignment.initial_alignment(t, np.zeros((n, 3)), np.tile([0, 0, -9.8], (n, 1)),
                                    Mounting(), track)
    # a record shorter than the moving alignment's two windows: said, not a speed of 0.00
    short = t < 0.45
    cut = {k: v[track["t"] < 0.45] for k, v in track.items()}
    with pytest.raises(InputError, match=r"none of its epochs has .* s of IMU and of it on "
                                         r"both sides \(the IMU's record is 0.44 s"):
        alignment.initial_alignment(t[short], np.zeros((short.sum(), 3)),
                                    np.tile([0, 0, -9.8], (short.sum(), 1)), Mounting(), cut)


def test_a_rest_under_a_noisy_fix_is_found_from_the_imu_and_the_positions(tmp_path):
    """The synthetic drive's 20 s start at rest (a consumer IMU's noise) under a plain 1 Hz
    fix with 1.5 m of position noise (velocity by differences: about 2 m/s of noise, no
    epoch below 0.2 m/s): the rest is judged from the quiet IMU and the positions' straight-
    line fit, and the state starts at rest with the gyro bias from it (it was a 'moving
    alignment' while parked, biases 0)."""
    bias = np.array([0.001, -0.002, 0.003])
    rec = under_a_noisy_fix(straight_track(), np.random.default_rng(7), bias)
    rests = rest_intervals((rec.reference["ns"] - rec.reference["ns"][0]) / 1e9,
                                     rec.reference["v_ned"], 0.0, 120.0)
    assert not rests or rests[0][0] > 0.0                           # the fix shows no rest
    write_log(rec, tmp_path / "noisy.mcap")
    with FlightLog(tmp_path / "noisy.mcap") as log:
        meta = log.metadata()["recording"]
    assert "judged from the IMU and the reference's positions" in meta["assumed"]["initial_state"]
    # the rest's end may take in the first half second of the smooth start (under 0.1 m/s,
    # the level's mean then off by 0.006 m/s^2, 0.04 deg): the louder windows of an idling
    # engine are taken in too (QUIET_SPREAD_TRACKED, QUIET_HOLE)
    assert meta["static_s"][0] < 0.1 and 10 < meta["static_s"][1] < 20.5
    # the heading from the courses of the first 2 s of fast epochs (one noisy course was
    # 6-22 deg off): the drive leaves heading 30 deg
    with FlightLog(tmp_path / "noisy.mcap") as log:
        q0 = log.metadata()["flight"]["initial_state"]["attitude_wxyz"]
    yaw = math.degrees(attitude.as_euler(quaternion.from_float_array(q0))[0])
    assert abs(yaw - 30.0) < 10.0, yaw
    # 0.005 rad/s white noise over ~2000 samples: 1.1e-4 per axis, plus up to 5e-5 of the
    # horizontal Earth rate the rest's unknown heading leaves
    assert np.abs(np.array(meta["gyro_bias_static_rad_s"]) - bias).max() < 4.5e-4


def test_the_real_excerpts_idling_rest_is_found_under_a_noisy_fix(tmp_path):
    """The RTKLIB excerpt (a real consumer IMU, engine idling at the start: its spread 3.4
    times that of the drive's quietest stops) with its RTK reference replaced by a plain
    1 Hz fix of 1.5 m noise: the start rest is found from the IMU and the positions, and
    the recording aligns at rest, not 'moving' while parked."""
    from dataclasses import replace

    from mimunav.motion.track import velocity_from_positions
    rec = rtklib.read_drive(DRIVE)
    ref, k = rec.reference, slice(0, None, 4)
    rng = np.random.default_rng(4)
    r_n, r_e = earth.radii(float(ref["lat"][0]))
    lat = ref["lat"][k] + rng.normal(0, 1.5, len(ref["lat"][k])) / r_n
    lon = ref["lon"][k] + rng.normal(0, 1.5, len(ref["lat"][k])) / (r_e * np.cos(ref["lat"][0]))
    v = velocity_from_positions(ref["ns"][k], lat, lon, ref["h"][k])
    ok = np.isfinite(v).all(axis=1)
    noisy = replace(rec, fixes=None, reference=dict(ns=ref["ns"][k][ok], lat=lat[ok],
                                                    lon=lon[ok], h=ref["h"][k][ok],
                                                    v_ned=v[ok]))
    write_log(noisy, tmp_path / "noisy.mcap")
    with FlightLog(tmp_path / "noisy.mcap") as log:
        meta = log.metadata()["recording"]
    assert "judged from the IMU and the reference's positions" in meta["assumed"]["initial_state"]
    assert meta["static_s"][0] < 0.5 and meta["static_s"][1] > 25.0, meta["static_s"]


def test_a_turn_on_the_spot_inside_a_rest_is_not_rest():
    """30 s standing under a noisy 1 Hz fix with a 1 s turn of 30 deg/s on the spot at 10 s
    (a steady rate: its spread is small): the rest the IMU shows starts after the turn,
    and the gyro bias taken from it is the truth's (0) within the noise - filling short
    louder moments inside a rest must not fill in a turn (review: 1.004 deg/s of bias)."""
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 30.0, 0.01)
    w = 0.003 * rng.standard_normal((len(t), 3))
    f = np.column_stack([0 * t, 0 * t, -9.80665 + 0 * t]) + 0.02 * rng.standard_normal((len(t), 3))
    w[(t >= 10.0) & (t < 11.0), 2] += math.radians(30.0)
    tt = np.arange(0.0, 30.0, 1.0)
    track = dict(t=tt, lat=LAT0 + 1.5 * rng.standard_normal(len(tt)) / 6.37e6,
                 lon=LON0 + 1.5 * rng.standard_normal(len(tt)) / 4.9e6, h=H0 + 0 * tt,
                 v_ned=1.5 * rng.standard_normal((len(tt), 3)) * [1, 1, 0])
    rests = quiet_stretches(t, w, f, track)
    assert rests and all(a >= 11.0 or b <= 10.0 for a, b in rests), rests
    bias = rest_biases.biases_at_a_rest(t, w, f, Mounting(), track, [], None)[0]
    assert np.abs(np.degrees(bias)).max() < 0.05, np.degrees(bias)


def test_a_rest_under_a_ten_hertz_rtk_fix_is_found_from_the_track():
    """The synthetic drive at 10 Hz under 2 cm RTK fixes, the velocity by central differences
    (0.14 m/s of noise per axis and epoch: half its resting epochs read above STATIC_SPEED):
    the 20 s start rest had broken into pieces (here 4.2-7.8 and 15.7-19.7 s, the state then
    not at rest at the start; on an independent drive without engine vibration into none,
    the biases taken as 0 and 10 s windows ending 5.1 m off instead of 2.1). Averaged over
    STATIC_AVERAGE_S the track shows the rest whole."""
    t, lat, lon, h, v = under_two_cm(straight_track(rate=10.0), seed=11)
    assert max(b - a for a, b in runs_of(np.linalg.norm(v, axis=1) <= STATIC_SPEED,
                                       t)) < MIN_STATIC_S     # epoch by epoch: none
    rests = rest_intervals(t, v, 0.0, 120.0)
    assert rests and rests[0][0] == 0.0 and 18.0 < rests[0][1] < 20.0, rests
    assert len(rests) == 1                  # and no rest where it moves


def runs_of(mask, t):
    """[(t0, t1)] of the runs of True in mask (at the epochs t)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(t[a], t[b - 1]) for a, b in zip(edges[::2], edges[1::2])] or [(0.0, 0.0)]


def _rocking_hull(amplitude_deg, period_s=6.0, span_s=60.0, rate=100.0):
    """A hull moored at LAT0 (the reference still, its attitude given at 10 Hz) rolling
    amplitude_deg sin(2 pi t / period_s): the IMU's rates (the roll rate's exact interval
    means plus the Earth's, body axes) with a gyro bias, and its specific force (gravity turned into the
    body); (t, w, f, track, bias)."""
    t = np.arange(0.0, span_s, 1.0 / rate)
    omega = 2 * math.pi / period_s
    roll = math.radians(amplitude_deg) * np.sin(omega * t)
    q_nb = attitude.from_euler(np.zeros_like(t), np.zeros_like(t), roll)
    q_bn = np.conjugate(q_nb)
    bias = np.array([2e-4, -3e-4, 1e-4])
    roll_rate = np.diff(roll, prepend=0.0) * rate        # interval means, as the contract's
    w = np.column_stack([roll_rate, np.zeros_like(t), np.zeros_like(t)]) \
        + attitude.rotate(q_bn, earth.earth_rate_ned(LAT0)) + bias
    g = float(earth.normal_gravity(LAT0, H0))
    f = attitude.rotate(q_bn, np.array([0.0, 0.0, -g]))
    k = np.arange(0, len(t), 10)
    track = {"t": t[k], "lat": np.full(len(k), LAT0), "lon": np.full(len(k), LON0),
             "h": np.full(len(k), H0), "v_ned": np.zeros((len(k), 3)),
             "q_nb": attitude.as_wxyz(q_nb[k])}
    return t, w, f, track, bias


def test_a_rocking_hull_is_no_rest():
    """A moored hull rolling 2.6 deg at 6 s (its GNSS still, its mean rate 0.3 deg/s) had
    been taken as a rest, its gyro bias 20 times the truth: the IMU's 1 s means tilt 2.6 deg
    and turn 2.7 deg/s about their means (2.48 deg, 2.3 deg/s in 1 s means) - refused, the reason in numbers; still water
    (no roll) is a rest."""
    from mimunav.navigation.rests import felt_at_rest
    t, w, f, _, _ = _rocking_hull(2.6)
    kept, refused = felt_at_rest(t, w, f, [(0.0, 59.9)])
    assert kept == [] and "tilt up to 2.5" in refused[0][2] and "it rocks" in refused[0][2]
    t, w, f, _, _ = _rocking_hull(0.0)
    assert felt_at_rest(t, w, f, [(0.0, 59.9)]) == ([(0.0, 59.9)], [])


def test_a_gently_rocking_rest_gives_way_to_the_reference_attitude():
    """A hull rolling 0.6 deg (its 1 s means within a rest's tolerances): a rest, but one
    whose gyro bias is worth 1 s means' scatter over sqrt n (170 deg/h here) - the
    reference's attitude measures it better, and the bias comes from that, exact on these
    exact increments; in still water the rest gives it."""
    for amplitude, basis in ((0.6, "the reference's attitude and velocity"), (0.0, "the rest")):
        t, w, f, track, bias = _rocking_hull(amplitude)
        gyro, _, _, note, _ = rest_biases.biases_at_a_rest(t, w, f, Mounting(), track,
                                                         [(0.0, 59.9)])
        assert f"biases from {basis}" in note, note
        assert np.abs(gyro - bias).max() < 2e-6, (amplitude, gyro - bias)


def test_the_reference_attitudes_accelerometer_bias_allows_for_the_lever_arm():
    """The IMU 1.2 m forward, 0.4 m right and 0.6 m above the point a rolling hull's
    reference describes (roll 2.6 deg at 6 s): it feels dw/dt x r + w x (w x r) besides
    gravity, whose windows' median does not vanish - the accelerometer bias from the
    reference's attitude (none in truth) stays within 1e-4 m/s^2 of 0 on every axis (with
    gravity averaged over each window: at its mid-rotation it was 0.04 off); leaving the
    lever arm out leaves 0.013."""
    t, w, f, track, _ = _rocking_hull(2.6)
    r = np.array([1.2, 0.4, -0.6])
    omega = 2 * math.pi / 6.0
    roll_rate = math.radians(2.6) * omega * np.cos(omega * t)
    roll_acc = -math.radians(2.6) * omega ** 2 * np.sin(omega * t)
    w_x = np.column_stack([roll_rate, np.zeros_like(t), np.zeros_like(t)])
    f = f + np.cross(np.column_stack([roll_acc, 0 * t, 0 * t]), r) \
        + np.cross(w_x, np.cross(w_x, r))
    _, (accel, _), _ = attitude_biases.biases_from_attitude(t, w, f, Mounting(lever_arm_m=r), track)
    assert np.abs(accel).max() < 1e-4, accel
    _, (unaware, _), _ = attitude_biases.biases_from_attitude(t, w, f, Mounting(), track)
    assert np.abs(unaware).max() > 5e-3, unaware


def test_windows_that_turn_far_give_no_biases_from_the_reference_attitude(monkeypatch):
    """A foot swinging through 30 deg of roll and pitch a quarter cycle apart once a second
    (coning; its reference attitude exact at 100 Hz, the IMU's rates the exact interval
    means at 1 kHz, no bias): a window's mean rate is no longer its net turn over its span,
    nor its attitude at mid-window the others' - a walker's foot had given 'biases' of 8
    deg/s and 4.6 m/s^2 with standard errors of 1 deg/s and 22 mg. Every window turns
    beyond WINDOW_TURN: no biases from the reference (the caller takes 0 and says so);
    allowed any turn, the same windows read a gyro bias of tenths of a rad/s."""
    rate, amplitude = 1000.0, math.radians(30.0)
    t = np.arange(0.0, 30.0, 1.0 / rate)
    phase = 2 * math.pi * t
    q_nb = attitude.from_euler(0 * t, amplitude * np.cos(phase), amplitude * np.sin(phase))
    step = attitude.as_scipy(q_nb[:-1]).inv() * attitude.as_scipy(q_nb[1:])
    w = np.vstack([np.zeros((1, 3)), step.as_rotvec() * rate])
    g = float(earth.normal_gravity(LAT0, H0))
    f = attitude.rotate(np.conjugate(q_nb), np.array([0.0, 0.0, -g]))
    k = np.arange(0, len(t), 10)
    track = {"t": t[k], "lat": np.full(len(k), LAT0), "lon": np.full(len(k), LON0),
             "h": np.full(len(k), H0), "v_ned": np.zeros((len(k), 3)),
             "q_nb": attitude.as_wxyz(q_nb[k])}
    assert attitude_biases.biases_from_attitude(t, w, f, Mounting(), track) is None
    monkeypatch.setattr(attitude_biases, "WINDOW_TURN", math.inf)
    (gyro, _), _, _ = attitude_biases.biases_from_attitude(t, w, f, Mounting(), track)
    assert np.abs(gyro).max() > 0.1, gyro


def test_a_vibrating_hulls_windows_give_the_biases_from_the_reference_attitude():
    """The rocking hull with an engine's 37 Hz vibration of 4 mrad about its roll axis in its
    attitude too (rates of 0.66 rad/s rms, the 100 Hz interval means' 0.55): its windows' attitude
    strays by 0.06 rad at most, so every window is kept and the gyro bias read exactly -
    the windows' mean |w| had counted as a turn beyond WINDOW_TURN (a review's 0.3 rad/s
    rms of vibration, 0.8 mrad of angle: every window left out, the biases taken as 0)."""
    rate, span = 100.0, 60.0
    t = np.arange(0.0, span, 1.0 / rate)
    roll = math.radians(2.6) * np.sin(2 * math.pi * t / 6.0) + 4e-3 * np.sin(2 * math.pi * 37 * t)
    q_nb = attitude.from_euler(np.zeros_like(t), np.zeros_like(t), roll)
    q_bn = np.conjugate(q_nb)
    bias = np.array([2e-4, -3e-4, 1e-4])
    w = np.column_stack([np.diff(roll, prepend=0.0) * rate, 0 * t, 0 * t]) \
        + attitude.rotate(q_bn, earth.earth_rate_ned(LAT0)) + bias
    f = attitude.rotate(q_bn, np.array([0.0, 0.0, -float(earth.normal_gravity(LAT0, H0))]))
    k = np.arange(0, len(t), 10)
    track = {"t": t[k], "lat": np.full(len(k), LAT0), "lon": np.full(len(k), LON0),
             "h": np.full(len(k), H0), "v_ned": np.zeros((len(k), 3)),
             "q_nb": attitude.as_wxyz(q_nb[k])}
    assert np.mean(np.abs(w[1:, 0])) > attitude_biases.WINDOW_TURN
    (gyro, _), _, windows = attitude_biases.biases_from_attitude(t, w, f, Mounting(), track)
    assert windows == len(k) // 10 - 1, windows
    assert np.abs(gyro - bias).max() < 2e-6, gyro - bias


def test_a_hand_held_rest_with_tremor_and_bias_is_a_rest():
    """A phone held still for 30 s in a walker's hand: a gyro bias of 0.82 deg/s and a
    1.5 Hz tremor of 1 deg/s lift some 0.5 s windows' mean rate past QUIET_RATE (1 deg/s),
    which had split the rest into pieces too short to keep (then a standing walker was
    aligned as moving at 3.1 m/s on its noisy fixes); the rate is judged on the run's mean:
    the rest is found, and the walking after it is not; and where a noisy 1 Hz fix's
    differenced speed passes COURSE_SPEED while the walker stands, its mean over the
    alignment's interval (`mean_speed`) does not."""
    from mimunav.navigation.rests import QUIET_RATE
    rng = np.random.default_rng(47)
    t = np.arange(0.0, 60.0, 0.01)
    bias = np.radians([0.4, -0.5, 0.5])
    tremor = np.radians(1.0) * np.sin(2 * math.pi * 1.5 * t)
    w = bias + tremor[:, None] * bias / np.linalg.norm(bias) \
        + rng.normal(0.0, np.radians(0.05), (len(t), 3))
    f = np.tile([0.0, 0.0, -9.80665], (len(t), 1)) + rng.normal(0.0, 0.02, (len(t), 3))
    walking = t >= 30.0
    f[walking, 2] += 3.0 * np.sin(2 * math.pi * 2.0 * t[walking])
    w[walking, 0] += np.radians(20.0) * np.sin(2 * math.pi * 2.0 * t[walking])
    windows = w[:3000].reshape(-1, 50, 3).mean(axis=1)
    assert (np.linalg.norm(windows, axis=1) > QUIET_RATE).any()     # the old test's failure
    stretches = quiet_stretches(t, w, f)
    assert len(stretches) == 1 and stretches[0][0] < 1.0 and 28.0 < stretches[0][1] <= 30.0
    # the walker's 4 m fixes at 1 Hz: standing 30 s, then 1.4 m/s east
    t_fix = np.arange(0.0, 120.0, 1.0)
    east = np.where(t_fix < 30.0, 0.0, 1.4 * (t_fix - 30.0)) + rng.normal(0.0, 4.0, len(t_fix))
    north = rng.normal(0.0, 4.0, len(t_fix))
    v = np.column_stack([np.gradient(north, t_fix), np.gradient(east, t_fix),
                         np.zeros_like(t_fix)])
    track = {"t": t_fix, "v_ned": v}
    standing = t_fix < 25.0
    assert (np.hypot(v[standing, 0], v[standing, 1]) > alignment.COURSE_SPEED).sum() >= 3
    assert (alignment.mean_speed(track, 5.0)[standing] < alignment.COURSE_SPEED).all()


def test_a_still_rest_is_kept_beside_a_turning_drives_attitude():
    """A still 30 s rest and 600 s on a loop that turns left 60 % of the time, a perfect
    reference attitude, a consumer gyro (0.1 deg/s per sample) with a 1 % z scale error
    (an independent review's case): the attitude's standard error counts its noise only,
    not the scale times the loop's mean turn - giving the still rest up for it had left
    134 deg/h on z. The rest's 1 s means scatter as its samples' noise predicts: it is
    kept, its bias within 20 deg/h."""
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 630.0, 0.01)
    turn = np.where(t < 30.0, 0.0, np.where(((t - 30.0) % 10) < 6, math.radians(5), 0.0))
    yaw = np.cumsum(turn) * 0.01
    speed = np.where(t < 30.0, 0.0, np.minimum((t - 30.0) * 2, 10.0))
    v = np.column_stack([speed * np.cos(yaw), speed * np.sin(yaw), np.zeros_like(t)])
    r_n, r_e = earth.radii(LAT0)
    lat = LAT0 + np.cumsum(v[:, 0]) * 0.01 / r_n
    lon = LON0 + np.cumsum(v[:, 1]) * 0.01 / (r_e * math.cos(LAT0))
    rot = Rotation.from_euler("ZYX", np.column_stack([yaw, 0 * yaw, 0 * yaw]))
    bias = np.radians([0.05, -0.03, 0.08])
    w = (np.column_stack([0 * t, 0 * t, turn]) + rot.inv().apply(earth.earth_rate_ned(LAT0))) \
        * [1.0, 1.0, 1.01] + bias + rng.normal(0.0, math.radians(0.1), (len(t), 3))
    f = rot.inv().apply(np.gradient(v, t, axis=0) - earth.gravity_ned(LAT0, H0)) \
        + rng.normal(0.0, 0.02, (len(t), 3))
    k = slice(0, None, 10)
    track = dict(t=t[k], lat=lat[k], lon=lon[k], h=np.full(len(t[k]), H0), v_ned=v[k],
                 q_nb=rot[k].as_quat()[:, [3, 0, 1, 2]])
    gyro, _, static, note, _ = rest_biases.biases_at_a_rest(t, w, f, Mounting(), track,
                                                          [(0.0, 29.0)])
    assert static == (0.0, 29.0) and note.startswith("biases from the rest"), note
    assert np.abs(np.degrees(gyro - bias) * 3600).max() < 20.0


def test_a_car_circling_a_skidpad_under_a_plain_fix_is_moving():
    """An 8 m/s circle of 15 m under a 1 Hz fix with 1 m/s of velocity noise: its velocity's
    mean over +-5 s turns away (1.4 m/s: below COURSE_SPEED, no window, no course) - the
    mean of its speed less what the noise alone makes of it holds it (an independent
    review's case)."""
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 60.0, 1.0)
    rate = 8.0 / 15.0
    v = np.column_stack([8 * np.cos(rate * t), 8 * np.sin(rate * t), 0 * t]) \
        + rng.normal(0.0, 1.0, (len(t), 3)) * [1, 1, 0]
    assert (alignment.mean_speed({"t": t, "v_ned": v}, 5.0)[6:-6] > 6.0).all()


def test_a_slow_robot_under_rtk_gets_its_heading_from_the_course(tmp_path):
    """A ground robot: 20 s at rest, then 1.2 m/s (never 3) under 2 cm fixes at 10 Hz
    (velocity by differences: about 0.3 m/s of noise per epoch). Its velocity's 5 s means at
    the rest scatter by millimetres per second, so its courses averaged over COURSE_SPAN_S
    hold the heading well below COURSE_SIGMA_DEG: the course speed is the least (1 m/s) and
    the heading at rest is measured (a fixed 3 m/s had left it assumed 0); a rest of two
    blocks measures nothing and keeps 3 m/s."""
    t = np.arange(0.0, 60.0 + 1e-9, 0.1)
    speed = 1.2 * smoothstep((t - 20.0) / 3.0)
    yaw = 70 * DEG
    track = under_two_cm(track_from_velocity(t, np.column_stack(
        [speed * np.cos(yaw), speed * np.sin(yaw), 0 * t])))
    ref = dict(zip(("t", "lat", "lon", "h", "v_ned"), track))
    assert alignment.course_speed(ref, (0.0, 19.0)) == alignment.COURSE_SPEED_MIN
    assert alignment.course_speed(ref, (0.0, 14.0)) == alignment.COURSE_SPEED  # 2 blocks
    path, motion, _ = ideal_flight(tmp_path, MOUNT, track=track)
    flight = Flight.load(path, reference_imu=False)
    heading = attitude.as_euler(flight.initial.q_nb)[0]
    assert flight.recording["initial_heading"] == "course"
    assert abs(heading - 70 * DEG) < 0.5 * DEG, np.degrees(heading)


def test_a_rest_ends_where_its_imu_starts_to_move():
    """A reference's rest that runs 0.4 s into the robot's setting off (its 1 s window mean
    turned 0.4 deg/s, within REST_TURN's 1 deg/s): cut back to the last still window, and
    the gyro bias over what is left is the still one's (it had moved 0.006 deg/s, 6 of its
    standard errors). Still to the end, 200 noise draws are never cut (SETTLED_Z)."""
    from mimunav.navigation.rests import settled_until
    t = np.arange(0.005, 59.9, 0.01)
    bias = np.radians([0.25, -0.40, 0.15])
    f0 = np.array([0.0, 0.0, -9.81])
    cut = []
    for seed in range(200):
        rng = np.random.default_rng(seed)
        w = bias + rng.normal(0, np.radians(0.1), (len(t), 3))
        f = f0 + rng.normal(0, 0.025, (len(t), 3))
        cut.append(settled_until(t, w, f, 0.0, 59.9) < 59.9)
    assert sum(cut) == 0
    moving = t > 59.5
    w[moving, 0] += np.radians(2.0) * (t[moving] - 59.5) / 0.4       # setting off
    end = settled_until(t, w, f, 0.0, 59.9)
    assert 58.0 <= end <= 59.5
    kept = t <= end
    se = np.radians(0.1) / math.sqrt(kept.sum())
    assert abs(w[kept, 0].mean() - bias[0]) < 4 * se
    assert abs(w[:, 0].mean() - bias[0]) > 4 * se                  # the whole reference rest


def test_the_heading_at_rest_comes_from_courses_driven_straight(tmp_path):
    """A car pulls out of its rest turning (40 deg at up to 12 deg/s, 1-5 m/s) and then
    drives straight; its GNSS antenna sits 1.5 m ahead of the point that moves without side
    slip, so while it turns the antenna's course runs w x r off its heading (the RTKLIB
    drive's pull-out put its heading 2-3 deg from what its straight driving gives). The
    heading at rest from the courses of straight driving (yaw rate under STRAIGHT_RATE) is
    the truth's; the first courses, turning, would miss it by degrees."""
    from mimunav.importers.recording import Recording
    from mimunav.motion import truth
    from mimunav.motion.vehicle import TrackMotion
    t_tr = np.arange(0.0, 70.0 + 1e-9, 0.1)
    speed = 1.0 * smoothstep((t_tr - 20.0) / 2.0) + 7.0 * smoothstep((t_tr - 27.0) / 8.0)
    yaw = 50 * DEG + 40 * DEG * smoothstep((t_tr - 28.0) / 6.0)
    t_tr, lat, lon, h, v = track_from_velocity(t_tr, np.column_stack(
        [speed * np.cos(yaw), speed * np.sin(yaw), 0 * t_tr]))
    motion = TrackMotion(t_tr, lat, lon, h, v)
    t = np.arange(t_tr[0], t_tr[-1] + 1e-9, 0.01)
    dth, dv = MOUNT.sensor_increments(truth.generate(motion, t))
    arm_n = attitude.rotate(motion.kinematics(t_tr).q_nb, np.array([1.5, 0.0, 0.0]))
    r_n, r_e = earth.radii(LAT0)
    v_ant = v + np.gradient(arm_n, t_tr, axis=0)
    epoch = 1_700_000_000_000_000_000
    rec = Recording("pull-out", "a car pulling out turning", epoch + np.round(t[1:] * 1e9)
                    .astype(np.int64), dth * 100, dv * 100, MOUNT,
                    reference=dict(ns=epoch + np.round(t_tr * 1e9).astype(np.int64),
                                   lat=lat + arm_n[:, 0] / (r_n + H0),
                                   lon=lon + arm_n[:, 1] / ((r_e + H0) * math.cos(LAT0)),
                                   h=h, v_ned=v_ant))
    course_off = np.degrees(np.arctan2(v_ant[:, 1], v_ant[:, 0]) - yaw)
    assert np.abs(course_off[(t_tr > 29) & (t_tr < 33)]).max() > 3      # turning: degrees off
    write_log(rec, tmp_path / "pull-out.mcap")
    flight = Flight.load(tmp_path / "pull-out.mcap", reference_imu=False)
    heading = attitude.as_euler(flight.initial.q_nb)[0]
    assert abs(heading - 50 * DEG) < 0.2 * DEG, np.degrees(heading)
    assert "driving straight" in flight.recording["assumed"]["initial_state"]


def test_an_ideal_imus_rest_is_quiet():
    """An ideal IMU (a simulation's exact outputs): still for 20 s up to rounding (1e-15),
    then a steady turn whose outputs are exactly constant. The quietest twentieth's spread
    is exactly 0, and 'at most 4 times it' had held no window of the rest - no rest, no
    initial state (a new user's noise-free robot). Below SETTLED_FLOOR (under any real
    unit's noise) a window is still: the rest is found; the steady turn is not one."""
    t = np.arange(0.01, 40.0, 0.01)
    rng = np.random.default_rng(1)
    still = t < 20.0
    w = np.where(still[:, None], 1e-3 + rng.normal(0, 1e-16, (len(t), 3)),
                 [0.0, 0.0, np.radians(20.0)])
    f = np.where(still[:, None], [0.0, 0.0, -9.81] + rng.normal(0, 1e-15, (len(t), 3)),
                 [0.0, 2.0, -9.81])
    rests = quiet_stretches(t, w, f)
    assert len(rests) == 1 and rests[0][0] < 0.1 and 19.0 <= rests[0][1] <= 20.05, rests


def test_a_train_entering_a_canted_curve_travels_forward():
    """A train speeding up from 20 to 23 m/s into a curve whose cant is steeper than its
    speed needs: its lateral specific force runs against the turn (f_y = -a_across), as a
    reversing car's would, while its forward one follows its speed (f_x = a_along). The
    along-track acceleration decides: forward (the horizontal force's complex gain had said
    reversing, and three windows of a train faced backwards)."""
    from mimunav.navigation.travel import track_acceleration, travel_sign
    t_tr = np.arange(0.0, 20.0 + 1e-9, 0.2)
    speed = 20.0 + 3.0 * smoothstep((t_tr - 6.0) / 8.0)
    course = np.radians(30.0) + np.cumsum(np.r_[0.0, np.diff(t_tr)] * np.radians(5.0)
                                          * smoothstep((t_tr - 4.0) / 6.0))
    v = np.column_stack([speed * np.cos(course), speed * np.sin(course), 0 * t_tr])
    _, _, z = track_acceleration(t_tr, v)
    t = np.arange(0.0, 20.0, 0.01)
    along, across = np.interp(t, t_tr, z.real), np.interp(t, t_tr, z.imag)
    f = np.column_stack([along, -across, np.full_like(t, -9.81)])       # FRD, as mounted
    track = {"t": t_tr, "v_ned": v}
    assert travel_sign(t, f, Mounting(), track, 10.0, undecided=0.0) == 1.0
    reversing = np.column_stack([-along, -across, np.full_like(t, -9.81)])
    assert travel_sign(t, reversing, Mounting(), track, 10.0, undecided=0.0) == -1.0


def test_a_rest_split_by_noisy_speeds_is_joined_where_the_imu_holds_still():
    """A train's 90 s in a station under a 1 Hz fix whose speed spikes past STATIC_SPEED at
    three epochs, and whose vertical velocity - differenced from heights with 2 m of noise
    - is metres per second: the reference's rest had broken into 2-6 s pieces and the gyro
    bias came from one of them. The vertical judges a rest only beyond its own noise, the
    pieces a spike splits are joined, and the still IMU keeps the whole 0-90 s."""
    from mimunav.navigation.rests import felt_at_rest
    rng = np.random.default_rng(4)
    t_tr = np.arange(0.0, 120.0 + 1e-9, 1.0)
    speed = np.where(t_tr < 90.0, 0.0, 0.5 * (t_tr - 90.0))
    v = np.column_stack([speed + rng.normal(0, 0.03, len(t_tr)), rng.normal(0, 0.03, len(t_tr)),
                         np.gradient(rng.normal(0, 2.0, len(t_tr)), t_tr)])
    v[[5, 20, 27], 0] += 0.5                                    # three spiky epochs
    rests = rest_intervals(t_tr, v, 0.0, 120.0)
    t = np.arange(0.005, 120.0, 0.01)
    w = np.radians([0.02, -0.035, 0.025]) + rng.normal(0, np.radians(0.05), (len(t), 3))
    f = np.column_stack([np.where(t < 90.0, 0.0, 0.5), np.zeros_like(t), np.full_like(t, -9.81)])
    f = f + rng.normal(0, 0.02, f.shape)
    kept, _ = felt_at_rest(t, w, f, rests)
    assert kept and kept[0][0] == 0.0 and 86.0 <= kept[0][1] <= 90.0, (rests, kept)


def test_a_car_backing_out_slowly_and_straight_keeps_its_heading():
    """A car at rest facing 30 deg backs straight out, speeding up smoothly to 1.6 m/s (its
    course 210 deg), stops, and drives off forward at 10 m/s; 2 cm fixes at 10 Hz. Below
    COURSE_SPEED which way it moves must be read off the data, and a near-constant reversing
    acceleration reads neither: the heading at rest had been -149.7 deg, its reversing
    courses taken as forward. Undecided, the courses wait for COURSE_SPEED: 30 deg.
    (A review's case, its numbers.)"""
    from mimunav.motion import truth
    from drives import FacingMotion
    t_tr = np.arange(0.0, 90.0 + 1e-9, 0.1)
    speed = -1.6 * (smoothstep((t_tr - 20.0) / 15.0) - smoothstep((t_tr - 50.0) / 5.0)) + \
        10.0 * smoothstep((t_tr - 60.0) / 5.0)
    exact = track_from_velocity(t_tr, speed[:, None] * [math.cos(30 * DEG),
                                                        math.sin(30 * DEG), 0.0])
    t = np.arange(0.0, 90.0 + 1e-9, 0.01)
    dth, dv = MOUNT.sensor_increments(truth.generate(FacingMotion(*exact), t))
    rng = np.random.default_rng(1)
    fix = under_two_cm(exact)
    align = alignment.initial_alignment(
        t[1:], dth / 0.01 + rng.normal(0, 0.002, dth.shape),
        dv / 0.01 + rng.normal(0, 0.02, dv.shape), MOUNT,
        dict(zip(("t", "lat", "lon", "h", "v_ned"), fix)))
    yaw = math.degrees(attitude.as_euler(attitude.from_wxyz(align.q_nb))[0])
    assert align.heading == "course" and abs(yaw - 30.0) < 0.5, (yaw, align.method)


def test_a_copters_steady_climb_is_no_rest():
    """A copter at rest 0-20 s lifts off straight up (to 2 m/s over 2 s), climbs steadily to
    60 s, then flies north; a 1 Hz fix with 2 m of height noise, its vertical by differences
    (metres per second epoch by epoch, so the vertical judges a rest only beyond its own
    noise). A steady climb is still to the IMU's direction of g, but its lift-off is not
    to the size of g (REST_HEAVE) and its heights climb (`_level_run`): the rest ends at
    the lift-off, and its accelerometer bias is the still one's (a review's case: the rest
    had run through the climb, 2/60 m/s^2 read as a bias)."""
    rng = np.random.default_rng(2)
    t = np.arange(0.01, 100.0 + 1e-9, 0.01)
    up_v = 2.0 * (smoothstep((t - 20) / 2) - smoothstep((t - 60) / 2))
    up_a = np.gradient(up_v, t)
    north_v = 5 * smoothstep((t - 62) / 3)
    f = np.column_stack([np.gradient(north_v, t), 0 * t, -earth.gravity_ned(LAT0, H0)[2]
                         - up_a]) + rng.normal(0, 0.02, (len(t), 3))
    w = rng.normal(0, 0.002, (len(t), 3))
    tt = np.arange(0.0, 100.0 + 1e-9, 1.0)
    h = H0 + np.interp(tt, t, np.cumsum(up_v) * 0.01) + rng.normal(0, 2.0, len(tt))
    north = np.interp(tt, t, np.cumsum(north_v) * 0.01) + rng.normal(0, 0.02, len(tt))
    r_n, _ = earth.radii(LAT0)
    track = dict(t=tt, lat=LAT0 + north / (r_n + H0), lon=np.full(len(tt), LON0), h=h,
                 v_ned=np.column_stack([np.gradient(north, tt), rng.normal(0, 0.02, len(tt)),
                                        -np.gradient(h, tt)]))
    align = alignment.initial_alignment(t, w, f, Mounting(), track)
    assert align.static[0] < 0.1 and 18.0 <= align.static[1] <= 20.5, align.static
    assert abs(align.accel_bias[2]) < 0.003, align.accel_bias


def test_without_a_track_the_rest_is_the_one_the_imu_shows():
    """No GNSS, no reference: a rate table's record that starts turning at 20 deg/s about
    its vertical for 5 s and then stands 60 s. The state starts at the rest the IMU shows,
    its gyro bias the rest's mean (the table's +0.26, -0.12, +0.22 deg/s); a rest assumed
    for the first 2 s had read -11 deg/s. A record that never stands is leveled on its
    first 2 s, said to be no rest, its biases not observed."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 65.0, 0.005)
    bias = np.radians([0.26, -0.12, 0.22])
    turning = t < 5.0
    w = bias + rng.normal(0, 2e-4, (len(t), 3))
    w[turning, 2] += math.radians(20.0)
    f = np.array([0.0, 0.0, -9.80665]) + rng.normal(0, 5e-3, (len(t), 3))
    align = alignment.initial_alignment(t, w, f, Mounting(), None)
    assert 5.0 <= align.static[0] <= 6.0 and align.static[1] >= 60.0
    assert align.t == align.static[0] and not align.at_rest_start
    assert np.allclose(align.gyro_bias, bias, atol=1e-4)
    assert align.bias_basis["gyro"] == "earth_rate_left"
    assert "judged from the IMU alone" in align.method and "moves before it" in align.method
    w[:, 2] += math.radians(20.0)                                   # turning throughout
    align = alignment.initial_alignment(t, w, f, Mounting(), None)
    assert np.isnan(align.static[0]) and not np.any(align.gyro_bias)
    assert re.search("no rest of 2 s anywhere.*40.2 deg/s.*no rest's", align.method)


def test_the_references_level_at_a_rest_is_its_mean_over_the_rest(tmp_path):
    """A reference attitude whose first epoch at the rest is 0.5 deg off in roll (an INS
    still converging) and right after: the rest's level and the accelerometer bias measured
    against it come from the mean over the rest's epochs (20 s at 4 Hz: 0.006 deg off, 0.1
    mg), not the first epoch's (0.5 deg: 8.6 mg of bias that is none)."""
    path, motion, run = ideal_flight(tmp_path, MOUNT, with_attitude=True)
    flight = Flight.load(path, reference_imu=False)
    w, f = flight.mimu_imu
    track = windows.track_of(flight.truth)
    first = np.flatnonzero(track["t"] >= flight.mimu_t[0])[0]
    track["q_nb"][first] = quaternion.as_float_array(
        attitude.from_wxyz(track["q_nb"][first]) * quaternion.from_rotation_vector(
            [0.5 * DEG, 0.0, 0.0]))
    align = alignment.initial_alignment(flight.mimu_t, w, f, flight.mimu_mounting, track)
    assert align.attitude_from == "reference_level" and "the mean of its" in align.method
    assert np.linalg.norm(align.accel_bias) < 0.2e-3 * 9.80665, align.accel_bias
    bias = rest_biases.biases_at_a_rest(flight.mimu_t, w, f, flight.mimu_mounting, track,
                                        [align.static])[1]
    assert np.linalg.norm(bias) < 0.2e-3 * 9.80665, bias

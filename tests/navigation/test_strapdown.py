"""Strapdown navigator against truth: exact increments of analytic and profile motions."""

import math
from dataclasses import replace

import numpy as np
import pytest
import quaternion

from mimunav.frames import earth
from mimunav.navigation import strapdown
from mimunav.motion import truth
from mimunav.motion.profile import Profile
from mimunav.motion.trajectory import State
from motions import Coning, GreatCircle, Sculling
from places import FLIGHTS

FLIGHTS = FLIGHTS


def _fly(motion, rate, duration=None, **kw):
    duration = motion.t1 if duration is None else duration
    t = np.arange(0, int(np.floor(duration * rate + 1e-9)) + 1) / rate
    run = truth.generate(motion, t)
    nav = strapdown.integrate(t[1:], run.dtheta, run.dv, run.trajectory.state(0), **kw)
    return nav, run.trajectory, run


def test_static_hour_at_45_deg_stays_put():
    motion = Profile.load(FLIGHTS / "static.toml").motion()
    nav, ref, _ = _fly(motion, 100.0)
    err = nav.position_error(ref)
    assert np.hypot(err[:, 0], err[:, 1]).max() < 0.01        # horizontal < 1 cm
    assert np.abs(err[:, 2]).max() < 0.10                     # vertical < 10 cm


def test_coning_drift_one_sample_analytic_and_two_sample_near_zero():
    """Coning of half-angle a at W: a single-sample algorithm drifts about the cone axis at
    a^2 W/2 (1 - sin(l)/l), l = W h; the two-sample algorithm leaves
    (a^2/2 (l - sin l) - a^2/3 sin^2(l/2) sin l)/h = a^2 W l^4/60 + ... (closed forms from the
    second-order rotation-vector equation)."""
    alpha, omega, h, dur = 0.004, 2 * np.pi * 20, 1e-3, 10.0
    lam = omega * h
    one = 0.5 * alpha**2 * omega * (1 - np.sin(lam) / lam)
    two = (0.5 * alpha**2 * (lam - np.sin(lam))
           - alpha**2 * np.sin(lam / 2) ** 2 * np.sin(lam) / 3) / h
    motion = Coning(alpha, omega, duration=dur)
    nav1, ref, _ = _fly(motion, 1 / h, two_sample=False)
    nav2, _, _ = _fly(motion, 1 / h)
    drift1 = -nav1.attitude_error(ref)[-1, 0] / dur       # about north, the cone axis
    drift2 = -nav2.attitude_error(ref)[-1, 0] / dur
    assert drift1 == pytest.approx(one, rel=1e-2)
    assert drift2 == pytest.approx(two, rel=0.1)
    assert abs(drift2) < 0.01 * one


def test_sculling_drift_one_sample_analytic_and_two_sample_near_zero():
    """Yaw oscillation a sin(Wt) in phase with a north acceleration A sin(Wt): a
    single-sample velocity update drifts east at a A/2 (1 - sin(l)/l); the two-sample
    sculling term leaves the same fraction as for coning (Ignagni's duality)."""
    alpha, omega, accel, h, dur = 0.02, 2 * np.pi * 20, 10.0, 1e-3, 10.0
    lam = omega * h
    one = 0.5 * alpha * accel * (1 - np.sin(lam) / lam)
    residual = (0.5 * (lam - np.sin(lam)) - np.sin(lam / 2) ** 2 * np.sin(lam) / 3) \
        / (0.5 * (lam - np.sin(lam)))
    motion = Sculling(alpha, omega, accel, duration=dur)
    nav1, ref, run = _fly(motion, 1 / h, two_sample=False)
    drift1 = -nav1.velocity_error(ref)[-1, 1] / dur
    assert drift1 == pytest.approx(one, rel=1e-2)
    # the same flight sensed in body axes turned cyclically (x y z -> y z x, z x y): the
    # sculling correction then acts on each body axis in turn (yaw alone: on y only)
    t = run.trajectory.t
    for turn in range(3):
        p = np.roll(np.eye(3), turn, axis=0)               # v_turned = p v_body
        start = run.trajectory.state(0)
        start.q_nb = start.q_nb * quaternion.from_rotation_matrix(p).conj()
        nav2 = strapdown.integrate(t[1:], run.dtheta @ p.T, run.dv @ p.T, start)
        drift2 = -nav2.velocity_error(ref)[-1, 1] / dur
        assert drift2 == pytest.approx(one * residual, rel=0.1), turn


def test_high_dynamic_flight_ends_within_1cm_and_5urad():
    motion = Profile.load(FLIGHTS / "high-dynamic.toml").motion()
    nav, ref, _ = _fly(motion, 1000.0)
    assert np.linalg.norm(nav.position_error(ref)[-1]) < 0.01
    assert np.linalg.norm(nav.attitude_error(ref)[-1]) < 5e-6


def test_convergence_order_when_the_rate_doubles():
    """Errors of the algorithm fall at least as the square of the interval (two-sample
    forms are second order; with the second-order rotation term it reaches third)."""
    prof = Profile.from_dict({"name": "c", "start": dict(
        latitude_deg=40, longitude_deg=0, height_m=2000, speed_m_s=300, heading_deg=10),
        "segment": [{"kind": "roll", "rate_deg_s": 400, "angle_deg": 720, "ramp_s": 0.2},
                    {"kind": "turn", "load_factor": 12, "heading_change_deg": 90,
                     "roll_rate_deg_s": 300, "ramp_s": 0.1},
                    {"kind": "coast", "duration_s": 5}]})
    errs = []
    for rate in (250.0, 500.0, 1000.0):
        nav, ref, _ = _fly(prof.motion(), rate)
        errs.append(np.linalg.norm(nav.velocity_error(ref)[-1]))
    order = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(order > 1.8), (errs, order)


def test_great_circle_flights_follow_the_closed_form():
    for motion in (GreatCircle(250.0, "east", duration=600.0),
                   GreatCircle(250.0, "north", lat=np.radians(20.0), duration=600.0),
                   # southern, 1 deg from the pole: the kernel's latitude sine and cosine
                   # (angle addition from a grid) where cos lat = 0.017
                   GreatCircle(250.0, "north", lat=np.radians(-89.0), duration=600.0)):
        nav, ref, _ = _fly(motion, 100.0)
        lat, lon, h = motion.exact_position(nav.t[-1:])
        end = earth.ned_difference(nav.lat[-1], nav.lon[-1], nav.h[-1], lat[0], lon[0], h[0])
        assert np.linalg.norm(end) < 0.01


def test_accelerometer_bias_follows_the_schuler_closed_form():
    """A north specific-force error b on a static IMU (perfect gyros) gives the classical
    north position error b/ws^2 (1 - cos ws t), ws^2 = g/R (T&W sec. 12.3)."""
    motion = Profile.load(FLIGHTS / "static.toml").motion()
    t = np.arange(0, 120001) / 100.0
    run = truth.generate(motion, t)
    b = 1e-3
    dv = run.dv + np.array([b, 0, 0]) * 0.01          # body x = north, level
    nav = strapdown.integrate(t[1:], run.dtheta, dv, run.trajectory.state(0))
    err = nav.position_error(run.trajectory)
    lat = motion.lat0
    r = np.sqrt(np.prod(earth.radii(lat))) + motion.h0
    ws = np.sqrt(earth.normal_gravity(lat, motion.h0) / r)
    expected = b / ws**2 * (1 - np.cos(ws * nav.t))
    np.testing.assert_allclose(err[:, 0], expected, rtol=0, atol=0.02 * expected.max())


def test_height_aiding_bounds_the_vertical_channel():
    """With a vertical accelerometer bias b, the free-inertial height diverges, while the
    aided loop settles to the closed-form steady state b tau^2."""
    motion = Profile.load(FLIGHTS / "static.toml").motion()
    t = np.arange(0, 60001) / 100.0
    run = truth.generate(motion, t)
    b, tau = 1e-3, 10.0
    dv = run.dv + np.array([0, 0, b]) * 0.01
    start = run.trajectory.state(0)
    free = strapdown.integrate(t[1:], run.dtheta, dv, start)
    aided = strapdown.integrate(t[1:], run.dtheta, dv, start, h_aid=run.trajectory.h[1:],
                                h_aid_tau=tau)
    assert abs(free.h[-1] - motion.h0) > 150.0
    assert aided.h[-1] - motion.h0 == pytest.approx(-b * tau**2, rel=0.02)


@pytest.fixture(scope="module")
def short():
    motion = Profile.load(FLIGHTS / "gentle.toml").motion()
    t = np.arange(0, 2001) / 100.0
    run = truth.generate(motion, t)
    return t[1:], run.dtheta, run.dv, run.trajectory.state(0)


def _raises(match, t, dth, dv, start, **kw):
    with pytest.raises(strapdown.IncrementError, match=match):
        strapdown.integrate(t, dth, dv, start, **kw)


def test_bad_inputs_get_clear_errors_naming_the_sample(short):
    t, dth, dv, start = short
    bad = dth.copy()
    bad[123, 1] = np.nan
    _raises(r"dtheta is not finite at sample 123 \(t = 1.24 s\)", t, bad, dv, start)
    bad = dv.copy()
    bad[7, 2] = np.inf
    _raises("dv is not finite at sample 7", t, dth, bad, start)
    tt = t.copy()
    tt[9] = np.nan
    _raises("time is not finite at sample 9|t is not finite at sample 9", tt, dth, dv, start)
    tt = t.copy()
    tt[50] = tt[49]
    _raises("time does not increase at sample 50", tt, dth, dv, start)
    _raises(r"shape \(N, 3\)", t, dth[:, :2], dv, start)
    _raises(r"shape \(N, 3\)", t, dth, dv[:-1], start)
    # a 60 deg/s roll given in degrees reads as 60 "rad/s" (slower motion in degrees
    # cannot be told from magnitudes alone)
    _raises("in degrees", t, np.degrees(dth + [np.radians(60.0) * 0.01, 0, 0]), dv, start)
    _raises("rates", t, dth, dv * 100, start)
    _raises("in g", t, dth, dv / 9.81, start)
    _raises("must be in rad", t, dth, dv, replace(start, lat=45.0))
    _raises("must be in rad", t, dth, dv, replace(start, lat=1.6))       # 91.7 deg
    _raises("must be in rad", t, dth, dv, replace(start, lon=6.3))       # 361 deg
    # the rate is reported as the rate (|dtheta| / T), not the increment
    fast = dth.copy()
    fast[40] = [60.0 * 0.01, 0.0, 0.0]
    _raises(r"angular rate 60 rad/s at sample 40", t, fast, dv, start)
    _raises("not a unit quaternion", t, dth, dv, replace(start, q_nb=np.quaternion(1, 0.1, 0, 0)))
    _raises(r"first sample time 0.01 s is not after the initial", t, dth, dv,
            replace(start, t=t[0]))
    _raises(r"shape|1-D|one time", t[:, None], dth, dv, start)
    _raises("initial state needs", t, dth, dv, {"t": 0.0})
    _raises("one finite height", t, dth, dv, start, h_aid=np.zeros(3))
    nav = strapdown.integrate(t, dth, dv / 9.81, start, check_units=False)
    assert len(nav) == len(t) + 1


def test_every_output_sample_is_the_state_at_its_time():
    """The navigator's output starts with the initial state exactly (velocity and attitude
    included) and carries each step's attitude at its own sample: on a coning motion
    sampled at 1 kHz the attitude error stays below 5e-8 rad at every sample (the
    two-sample algorithm's drift, 1.1e-8 rad after 1 s; an output shifted by one sample,
    alpha W h = 5e-4 rad here, or a component stored in the wrong place, shows)."""
    motion = Coning(0.004, 2 * np.pi * 20, duration=1.0)
    nav, ref, run = _fly(motion, 1000.0)
    start = run.trajectory.state(0)
    np.testing.assert_array_equal(nav.v_ned[0], start.v_ned)
    np.testing.assert_array_equal(quaternion.as_float_array(nav.q_nb[0]),
                                  quaternion.as_float_array(start.q_nb))
    assert np.abs(nav.attitude_error(ref)).max() < 5e-8
    assert np.abs(nav.velocity_error(ref)).max() < 1e-6


def test_unit_checks_act_at_their_thresholds_on_every_axis(short):
    """Rates above MAX_RATE and specific forces above MAX_SPECIFIC_FORCE are refused on any
    single axis, just below them accepted - at the first sample too (its interval runs from
    the initial state's time); a median specific force over 20 g reads as rates given for
    increments."""
    t, dth, dv, start = short
    dt = t[1] - t[0]
    assert t[0] - start.t == pytest.approx(dt)
    for k, axis in ((k, axis) for k in (0, 40) for axis in range(3)):
        over, under = dth.copy(), dth.copy()
        over[k] = 0.0
        over[k, axis] = 1.001 * strapdown.MAX_RATE * dt
        under[k] = 0.0
        under[k, axis] = 0.999 * strapdown.MAX_RATE * dt
        _raises("angular rate", t, over, dv, start)
        strapdown.integrate(t, under, dv, start)
        over, under = dv.copy(), dv.copy()
        over[k] = 0.0
        over[k, axis] = 1.001 * strapdown.MAX_SPECIFIC_FORCE * dt
        under[k] = 0.0
        under[k, axis] = 0.999 * strapdown.MAX_SPECIFIC_FORCE * dt
        _raises("specific force", t, dth, over, start)
        strapdown.integrate(t, dth, under, start)
    up = np.zeros_like(dv)
    up[:, 2] = -20.5 * 9.8 * dt              # 20.5 g for the whole flight
    _raises("over 20 g", t, dth, up, start)
    up[:, 2] = -19.5 * 9.8 * dt
    strapdown.integrate(t, dth, up, start)


class _YawSpin(truth.Motion):
    """Parked, level, spinning about body z = NED down at a constant rate: q_nb = Rz(W t)."""

    def __init__(self, rate, duration):
        self.rate, self.t1, self.lat0, self.lon0, self.h0 = rate, duration, 0.7, 0.1, 50.0

    def kinematics(self, t):
        t = np.asarray(t, float)
        zero = np.zeros((len(t), 3))
        w = zero.copy()
        w[:, 2] = self.rate
        q = quaternion.from_rotation_vector(w * t[:, None])
        return truth.Kinematics(zero, zero, q, w, zero)


def test_large_rotation_steps_use_the_exact_rotation_vector_update():
    """0.5 rad per step (1 rad/s at 2 Hz): the attitude update exp(phi/2) must be the exact
    cos/sin form (a series in |phi| truncated after |phi|^4 errs 3e-7 rad per step here);
    after 40 steps the heading (rotation about NED down) is within 1e-7 rad of the truth
    (measured 3e-9; the tilt errs by 5e-6 rad from the Earth rate's coupling with the spin at
    this coarse rate, second order, checked at fine rates elsewhere). The series branch
    (|phi| < 0.1 rad) is checked by the next test and every other one."""
    nav, ref, _ = _fly(_YawSpin(1.0, 20.0), 2.0)
    assert np.abs(nav.attitude_error(ref)[:, 2]).max() < 1e-7


def test_rotation_steps_below_0_1_rad_take_the_half_angle_series_to_phi_8():
    """0.09 rad per step (0.9 rad/s at 10 Hz) is inside the kernel's series branch of
    exp(phi/2) (|phi| < 0.1 rad, terms to |phi|^8): after 200 steps the heading is within
    1e-9 rad of the truth (measured 2e-11; a slip in a |phi|^4 coefficient, 1/348 for
    1/384, turns it red). Its |phi|^6 and |phi|^8 terms move the heading by less than
    1e-12 rad per step here: below what this test, or a navigation, can show."""
    nav, ref, _ = _fly(_YawSpin(0.9, 20.0), 10.0)
    assert np.abs(nav.attitude_error(ref)[:, 2]).max() < 1e-9


def test_free_fall_is_not_mistaken_for_g_units(short):
    """A median specific force below 0.3 m/s^2 (free fall, a drop test, orbit) is what it
    is: only 0.3-3 m/s^2, where a 1 g vehicle logged in g would sit, is refused."""
    t, dth, _, start = short
    falling = np.zeros((len(t), 3))
    falling[:, 2] = -0.1 * (t[1] - t[0])                 # 0.1 m/s^2
    nav = strapdown.integrate(t, dth, falling, start)
    assert len(nav) == len(t) + 1


def test_unit_check_thresholds_are_the_documented_magnitudes(short):
    """50 rad/s and 2000 m/s^2 (above any navigation IMU's range) as the docstring says:
    50.5 rad/s and 2010 m/s^2 are refused, 49.5 rad/s and 1990 m/s^2 taken."""
    t, dth, dv, start = short
    dt = t[1] - t[0]
    for k, message, over, under in ((0, "angular rate", 50.5, 49.5),
                                    (1, "specific force", 2010.0, 1990.0)):
        for value in (over, under):
            inputs = [dth.copy(), dv.copy()]
            inputs[k][40] = [value * dt, 0.0, 0.0]
            if value == under:
                strapdown.integrate(t, *inputs, start)
            else:
                _raises(message, t, *inputs, start)


def test_navigating_in_blocks_equals_navigating_whole_bit_for_bit():
    """`Navigator.step` over blocks of uneven length (one sample, then primes) carries the
    kernel's memory - coning, sculling, the mid-epoch extrapolation and the height loop -
    exactly: a block boundary that dropped any of them would move the solution of this
    coning-sculling motion."""
    nav, _, run = _fly(Sculling(0.05, 2 * np.pi * 5, 3.0, duration=20.0), 200.0)
    t = run.trajectory.t[1:]
    h_aid = run.trajectory.h[1:] + 5.0
    whole = strapdown.integrate(t, run.dtheta, run.dv, run.trajectory.state(0), h_aid=h_aid)
    blocks = strapdown.Navigator(run.trajectory.state(0))
    edges = [0, 1, 8, 105, 1306, 2700, len(t)]
    parts = [blocks.step(t[a:b], run.dtheta[a:b], run.dv[a:b], h_aid=h_aid[a:b])
             for a, b in zip(edges[:-1], edges[1:])]
    for name in ("t", "lat", "lon", "h", "v_ned"):
        got = np.concatenate([getattr(p, name) for p in parts])
        assert np.array_equal(got, getattr(whole, name)[1:]), name
    q = np.concatenate([quaternion.as_float_array(p.q_nb) for p in parts])
    assert np.array_equal(q, quaternion.as_float_array(whole.q_nb[1:]))
    assert not np.allclose(whole.h, nav.h, atol=1e-3)        # the height loop acted
    with pytest.raises(strapdown.IncrementError, match="not after the latest state"):
        blocks.step(t[-1:], run.dtheta[-1:], run.dv[-1:])


def test_a_first_block_at_launch_g_is_not_taken_for_rates():
    """Found on a foreign flight streamed in blocks: its first second after the initial
    state is a 20 g launch. A whole record at 20 g for most of it is refused (rates given as
    increments?); a first block of a longer record is not judged on its median."""
    t = np.arange(1, 1001) / 1000.0
    dth, dv = np.zeros((1000, 3)), np.tile([200.0e-3, 0.0, -9.8e-3], (1000, 1))
    start = State(0.0, 0.7, 0.1, 100.0, np.zeros(3), np.quaternion(1.0, 0, 0, 0))
    with pytest.raises(strapdown.IncrementError, match="over 20 g"):
        strapdown.Navigator(start).step(t, dth, dv)
    nav = strapdown.Navigator(start, whole_record=False).step(t, dth, dv)
    assert nav.v_ned[-1, 0] == pytest.approx(200.0, rel=1e-3)      # 200 m/s^2 for 1 s


def test_a_free_falling_piece_of_a_record_is_no_units_error():
    """A balloon's burst: a window over its free fall has a median |f| of 2.6 m/s^2, where a
    record in g has 1 (m/s^2 read as g). The check is of a whole record: a piece navigated as
    one (`replay.navigate(whole_record=False)`, the free-inertial windows) is not judged on
    its median, and the free fall falls at 9.8 m/s^2; the whole record in g is still refused."""
    from mimunav.evaluation.replay import navigate
    from mimunav.frames.mounting import Mounting
    t = np.arange(1, 1001) / 100.0
    w, f = np.zeros((1000, 3)), np.tile([0.0, 0.0, -2.6], (1000, 1))     # 0.27 g of drag
    start = State(0.0, 0.7, 0.1, 20000.0, np.zeros(3), np.quaternion(1.0, 0, 0, 0))
    with pytest.raises(strapdown.IncrementError, match="near 1 g expressed in g"):
        navigate(t, w, f, Mounting(), start)
    fell = navigate(t, w, f, Mounting(), start, whole_record=False)
    s2 = math.sin(0.7) ** 2               # Somigliana, and 3.086e-6 s^-2 of free air
    g = 9.7803253359 * (1 + 0.00193185265241 * s2) / math.sqrt(1 - 0.00669437999013 * s2) \
        - 3.086e-6 * 20000.0
    assert fell.v_ned[-1, 2] == pytest.approx(10 * (g - 2.6), rel=2e-3)
    with pytest.raises(strapdown.IncrementError, match="near 1 g expressed in g"):
        strapdown.check_median_force(t, f * 0.01)

"""Truth generator: exact increments and positions against closed forms."""
import numpy as np
import pytest

from mimunav.frames import attitude, earth
from mimunav.motion import truth
from mimunav.motion.profile import Profile
from motions import Coning, GreatCircle


def _profile(segments, **start):
    base = dict(latitude_deg=45.0, longitude_deg=10.0, height_m=1000.0, speed_m_s=200.0,
                heading_deg=0.0)
    base.update(start)
    return Profile.from_dict({"name": "t", "start": base, "segment": segments})


def test_static_increments_are_earth_rate_and_gravity():
    prof = _profile([{"kind": "hold", "duration_s": 5.0}], speed_m_s=0.0, heading_deg=37.0,
                    flight_path_deg=4.0, roll_deg=-3.0)
    t = np.arange(0, 501) / 100.0
    run = truth.generate(prof.motion(), t)
    lat, h = np.radians(45.0), 1000.0
    q_bn = np.conjugate(attitude.from_euler(np.radians(37.0), np.radians(4.0), np.radians(-3.0)))
    w_b = attitude.rotate(q_bn, earth.earth_rate_ned(lat))
    f_b = attitude.rotate(q_bn, -earth.gravity_ned(lat, h))
    np.testing.assert_allclose(run.dtheta, np.tile(w_b * 0.01, (500, 1)), rtol=1e-13, atol=1e-21)
    np.testing.assert_allclose(run.dv, np.tile(f_b * 0.01, (500, 1)), rtol=1e-13, atol=0)
    assert np.ptp(run.trajectory.lat) == 0 and np.ptp(run.trajectory.h) == 0


def test_equator_flight_position_and_increments_in_closed_form():
    v, h = 250.0, 1000.0
    motion = GreatCircle(v, "east", h=h, duration=600.0)
    t = np.arange(0, 6001) / 10.0
    run = truth.generate(motion, t)
    lat, lon, hh = motion.exact_position(t)
    assert np.abs(run.trajectory.lon - lon).max() * earth.A < 1e-6
    assert np.abs(run.trajectory.lat).max() == 0 and np.abs(run.trajectory.h - h).max() < 1e-9
    # heading east: body x = east, y = south, z = down. w_ib = (W + v/(a+h)) north.
    rho = v / (earth.A + h)
    w_b = np.array([0.0, -(earth.OMEGA + rho), 0.0])
    # f^n = (2 W + rho) x v - g: the centripetal/Coriolis lift (2 W + rho) v upward
    f_b = np.array([0.0, 0.0, (2 * earth.OMEGA + rho) * v - earth.normal_gravity(0.0, h)])
    np.testing.assert_allclose(run.dtheta / 0.1, np.tile(w_b, (6000, 1)), atol=1e-17)
    np.testing.assert_allclose(run.dv / 0.1, np.tile(f_b, (6000, 1)), atol=1e-12)


def test_meridian_flight_latitude_matches_the_meridian_arc():
    motion = GreatCircle(300.0, "north", h=500.0, lat=np.radians(30.0), duration=1000.0)
    t = np.arange(0, 10001) / 10.0
    traj = truth.generate(motion, t).trajectory
    lat, _, _ = motion.exact_position(t[::1000])
    assert np.abs(traj.lat[::1000] - lat).max() * earth.A < 1e-6     # < 1 um over 300 km


def test_increments_are_additive_across_rates_and_knots():
    """Exact integrals add: the 1 kHz increments summed in fours equal 250 Hz ones. The
    250 Hz grid is offset so that segment knots fall inside intervals (split quadrature)."""
    prof = _profile([{"kind": "accelerate", "accel_g": 20.0, "duration_s": 1.0, "ramp_s": 0.1},
                     {"kind": "roll", "rate_deg_s": 400.0, "angle_deg": 180.0, "ramp_s": 0.05},
                     {"kind": "turn", "load_factor": 8.0, "heading_change_deg": 60.0,
                      "roll_rate_deg_s": 300.0, "ramp_s": 0.05}])
    motion = prof.motion()
    t_end = np.floor(prof.duration * 250) / 250
    t_fine = np.concatenate([[0.0], np.arange(0.0013, t_end, 0.001)])
    t_coarse = np.concatenate([[0.0], t_fine[1::4]])
    fine, coarse = truth.generate(motion, t_fine), truth.generate(motion, t_coarse)
    assert np.any([(k > a) & (k < b) for k in motion.knots
                   for a, b in zip(t_coarse[:-1], t_coarse[1:])])
    n = (len(t_fine) - 2) // 4
    sum_th = fine.dtheta[1:1 + 4 * n].reshape(n, 4, 3).sum(axis=1)
    sum_dv = fine.dv[1:1 + 4 * n].reshape(n, 4, 3).sum(axis=1)
    np.testing.assert_allclose(sum_th, coarse.dtheta[1:1 + n], rtol=0, atol=1e-13)
    np.testing.assert_allclose(sum_dv, coarse.dv[1:1 + n], rtol=0, atol=1e-11)
    np.testing.assert_allclose(fine.dtheta[0], coarse.dtheta[0], atol=1e-13)   # same interval


@pytest.mark.slow
def test_coning_increments_match_the_analytic_integral():
    # w_nb^b of the coning motion integrates in closed form; Earth rate is added exactly
    alpha, omega, h = 0.05, 2 * np.pi * 5, 1e-3
    motion = Coning(alpha, omega, duration=1.0)
    t = np.arange(0, 1001) * h
    run = truth.generate(motion, t)
    ca = np.cos(omega * t)
    sa = np.sin(omega * t)
    dth_cone = np.stack([np.full(1000, -2 * omega * np.sin(alpha / 2) ** 2 * h),
                         np.sin(alpha) * np.diff(ca), np.sin(alpha) * np.diff(sa)], -1)
    w_ie = earth.earth_rate_ned(motion.lat0)
    # Earth-rate part: integral of C_bn(t) w_ie, by dense midpoint rule
    tm = (t[:-1, None] + h * (np.arange(200) + 0.5) / 200).ravel()
    q = motion.kinematics(tm).q_nb
    earth_part = attitude.rotate(np.conjugate(q), np.tile(w_ie, (len(tm), 1)))
    earth_part = earth_part.reshape(1000, 200, 3).mean(axis=1) * h
    np.testing.assert_allclose(run.dtheta, dth_cone + earth_part, rtol=0, atol=1e-14)


def test_body_rate_derivative_is_consistent():
    prof = _profile([{"kind": "turn", "load_factor": 6.0, "heading_change_deg": 90.0,
                      "roll_rate_deg_s": 200.0}])
    m = prof.motion()
    t = np.linspace(0.05, prof.duration - 0.05, 400)
    e = 1e-5
    num = (m.kinematics(t + e).w_nb_b - m.kinematics(t - e).w_nb_b) / (2 * e)
    np.testing.assert_allclose(m.kinematics(t).dw_nb_b, num, atol=1e-6)
    num_a = (m.kinematics(t + e).v_ned - m.kinematics(t - e).v_ned) / (2 * e)
    np.testing.assert_allclose(m.kinematics(t).a_ned, num_a, atol=1e-5)


def test_generate_rejects_times_outside_the_motion():
    m = _profile([{"kind": "hold", "duration_s": 1.0}]).motion()
    with pytest.raises(ValueError, match="increase from the motion's start"):
        truth.generate(m, np.array([0.0, 0.5, 0.4]))
    with pytest.raises(ValueError):
        truth.generate(m, np.array([0.0, 2.0]))
    with pytest.raises(ValueError):                 # not from the motion's start
        truth.generate(m, np.array([0.1, 0.5]))
    with pytest.raises(ValueError):                 # a repeated time
        truth.generate(m, np.array([0.0, 0.5, 0.5, 0.7]))


def test_east_flight_at_45_deg_is_a_circle_about_the_earth_axis():
    """Independent closed form at a general latitude (every term of the navigation equations
    non-zero, the vertical transport rate included): flying east at constant latitude and
    height, the vehicle circles the Earth's axis at radius rho = (R_N + h) cos(lat) with rate
    W + v / rho. Its specific force is that circle's centripetal acceleration less the
    gravitation: f = (2 W v + v^2 / rho) (sin lat, 0, cos lat) - (0, 0, g) in NED; its body
    rate is (W + v / rho) about the axis direction (cos lat, 0, -sin lat). Neither uses the
    project's Earth- or transport-rate kernel (`earth.nav_rates`)."""
    lat_deg, v, h = 45.0, 250.0, 1000.0
    prof = _profile([{"kind": "coast", "duration_s": 60.0}], latitude_deg=lat_deg,
                    heading_deg=90.0, speed_m_s=v, height_m=h)
    t = np.arange(0, 6001) / 100.0
    run = truth.generate(prof.motion(), t)
    lat = np.radians(lat_deg)
    assert np.abs(run.trajectory.lat - lat).max() * earth.A < 1e-6        # a parallel
    rho = (earth.prime_vertical_radius(lat) + h) * np.cos(lat)
    axis = np.array([np.cos(lat), 0.0, -np.sin(lat)])                    # Earth axis, NED
    inward = np.array([np.sin(lat), 0.0, np.cos(lat)])                   # towards the axis
    f_n = (2 * earth.OMEGA * v + v * v / rho) * inward - [0, 0, earth.normal_gravity(lat, h)]
    w_n = (earth.OMEGA + v / rho) * axis
    q_bn = np.conjugate(run.trajectory.q_nb[1:])
    np.testing.assert_allclose(run.dv / 0.01, attitude.rotate(q_bn, np.tile(f_n, (6000, 1))),
                               atol=2e-9)
    np.testing.assert_allclose(run.dtheta / 0.01, attitude.rotate(q_bn, np.tile(w_n, (6000, 1))),
                               atol=1e-14)
    # the north term v^2 tan(lat) / (R_N + h) alone is 1 mg here: a sign error cannot hide
    assert v * v * np.tan(lat) / (earth.prime_vertical_radius(lat) + h) > 9e-3


def test_transport_rate_is_the_turn_rate_of_the_ned_frame():
    """w_en^n from the NED->ECEF matrix differentiated along a path (north-east, 45 deg):
    Omega = C_ne dC_en/dt, skew-symmetric, against `earth.transport_rate_ned` and the
    Earth-rate kernel of the navigator and the truth generator (`earth.nav_rates_at`), whose
    position rates per unit velocity are dlat/dvN and dlon/dvE of the same path."""
    lat0, lon0, h = np.radians(45.0), 0.2, 800.0
    vn, ve = 150.0, 220.0
    r_m, r_n = earth.radii(lat0)
    dlat, dlon = vn / (r_m + h), ve / ((r_n + h) * np.cos(lat0))
    dt = 1e-3
    c = [earth.ned_to_ecef_matrix(lat0 + k * dlat * dt, lon0 + k * dlon * dt) for k in (-1, 1)]
    c0 = earth.ned_to_ecef_matrix(lat0, lon0)
    omega = c0.T @ (c[1] - c[0]) / (2 * dt)
    w_en = np.array([omega[2, 1], omega[0, 2], omega[1, 0]])
    expected = earth.transport_rate_ned(lat0, h, np.array([vn, ve, 0.0]))
    np.testing.assert_allclose(w_en, expected, rtol=1e-6, atol=1e-12)
    rates = earth.nav_rates(lat0, h, vn, ve)
    np.testing.assert_allclose([rates[2], rates[3], rates[4]], expected, rtol=1e-12)
    # the position rates against the radii written out here (WGS-84, not earth.radii, which
    # shares its core with the kernel): R_N = a (1 - e^2) / w^3, R_E = a / w
    w = np.sqrt(1 - earth.E2 * np.sin(lat0) ** 2)
    r_north, r_east = earth.A * (1 - earth.E2) / w**3, earth.A / w
    np.testing.assert_allclose([rates[6] * vn, rates[7] * ve],
                               [vn / (r_north + h), ve / ((r_east + h) * np.cos(lat0))],
                               rtol=1e-12)


class _CubicClimb(truth.Motion):
    """Level attitude, no horizontal motion, vertical velocity v_D = -c t^3 (climbing):
    h(t) = h0 + c t^4 / 4 exactly."""

    def __init__(self, c=0.02, duration=10.0):
        self.c, self.t1, self.lat0, self.lon0, self.h0 = c, duration, 0.5, 0.2, 100.0

    def kinematics(self, t):
        t = np.asarray(t, float)
        zero = np.zeros((len(t), 3))
        v, a = zero.copy(), zero.copy()
        v[:, 2], a[:, 2] = -self.c * t ** 3, -3 * self.c * t ** 2
        q = np.full(len(t), np.quaternion(1, 0, 0, 0))
        return truth.Kinematics(v, a, q, zero, zero)


def test_position_integration_is_exact_for_cubic_velocity():
    """The corrected trapezoid h/2 (v0 + v1) + h^2/12 (a0 - a1) integrates a cubic velocity
    exactly: the height of a t^3 climb at 1 Hz steps matches c t^4 / 4 to round-off (the
    plain trapezoid errs by c h^2 t^2 / 4 = 0.5 m at 10 s)."""
    m = _CubicClimb()
    t = np.arange(0.0, 10.0 + 1e-9, 1.0)
    _, _, h = truth.integrate_position(m, t)
    np.testing.assert_allclose(h, m.h0 + m.c * t ** 4 / 4, rtol=0, atol=1e-9)


def test_increments_at_a_lever_arm_match_a_quadrature_of_the_rigid_body_terms():
    """dv at lever arm r minus dv at the origin = the integral of dw/dt x r + w x (w x r)
    over each interval (w = w_ib^b), here by 64-point Gauss-Legendre quadrature of the
    coning motion's analytic rates - independent of the closed form (w_k - w_k-1) x r +
    (M - tr(M) I) r with M the integral of w w^T (the generator's 3-point Gauss rule)."""
    motion = Coning(0.3, 2 * np.pi * 2.0, duration=1.0)
    t = np.linspace(0.0, 1.0, 401)          # 2.5 ms: the generator's 3-point rule exact to 1e-14
    run = truth.generate(motion, t)
    r = np.array([0.3, -0.2, 0.5])
    got = run.dv_at(r) - run.dv
    nodes, weights = np.polynomial.legendre.leggauss(64)

    def w_ib(s):
        kin = motion.kinematics(s)
        w_ie = earth.earth_rate_ned(np.full(len(s), motion.lat0))
        return kin.w_nb_b + attitude.rotate(np.conjugate(kin.q_nb), w_ie), kin

    want = []
    for a, b in zip(t[:-1], t[1:]):
        s = 0.5 * (b - a) * nodes + 0.5 * (a + b)
        w, _ = w_ib(s)
        centripetal = np.cross(w, np.cross(w, r))
        want.append(np.cross(w_ib(np.array([b]))[0][0] - w_ib(np.array([a]))[0][0], r)
                    + 0.5 * (b - a) * weights @ centripetal)
    np.testing.assert_allclose(got, np.array(want), rtol=0, atol=1e-12)


def test_generate_refuses_a_last_time_past_the_motions_end():
    m = _profile([{"kind": "hold", "duration_s": 1.0}]).motion()
    with pytest.raises(ValueError, match="at most its end"):
        truth.generate(m, np.array([0.0, 0.5, 1.0 + 1e-6]))
    truth.generate(m, np.array([0.0, 0.5, 1.0]))


def test_quadrature_node_positions_are_exact_for_cubic_latitude_and_height():
    """The generator's latitude and height at its quadrature nodes (cubic Hermite between
    samples, end slopes lat' = v_N / (R_M + h), h' = -v_D) are exact for cubic lat(t), h(t):
    checked against the polynomials at the interior of 10 s intervals of a fast climb
    (500 m/s north, 100 m/s up), where an end slope from the wrong radius (sin lat instead of
    sin^2 lat) or the wrong end's height errs by 1e-8 rad or more."""
    t = np.arange(0.0, 50.1, 10.0)
    lat_c = np.array([0.6, 7.8e-5, 2e-8, -3e-10])            # rad, rad/s, rad/s^2, rad/s^3
    h_c = np.array([1000.0, 100.0, 0.5, -0.01])              # m, m/s, ...
    poly = lambda c, x: c[0] + x * (c[1] + x * (c[2] + x * c[3]))            # noqa: E731
    dpoly = lambda c, x: c[1] + x * (2 * c[2] + x * 3 * c[3])                # noqa: E731
    lat, h = poly(lat_c, t), poly(h_c, t)
    r_m = earth.radii(lat)[0]
    v_ned = np.stack([dpoly(lat_c, t) * (r_m + h), np.zeros_like(t), -dpoly(h_c, t)], -1)
    k_node = np.repeat(np.arange(len(t) - 1), 3)
    tq = t[k_node] + np.tile([1.3, 5.0, 8.9], len(t) - 1)
    lat_q, h_q = truth.hermite_position(t, lat, truth.latitude_rate(lat, h, v_ned), h, v_ned,
                                         k_node, tq)
    np.testing.assert_allclose(lat_q, poly(lat_c, tq), rtol=0, atol=1e-13)
    np.testing.assert_allclose(h_q, poly(h_c, tq), rtol=0, atol=1e-7)


def test_a_knot_inside_the_last_interval_is_integrated_across():
    """The last interval (3.99, 4.005] s holds the hold -> turn knot at 4 s: its increment
    equals the sum of the fine (1 ms) increments over it, as in every other interval (the
    quadrature is split at the knot, where the rate's derivative jumps)."""
    motion = _profile([{"kind": "hold", "duration_s": 4.0},
                       {"kind": "turn", "load_factor": 3.0, "heading_change_deg": 90.0,
                        "ramp_s": 0.2}]).motion()
    coarse_t = np.r_[np.arange(400) * 0.01, 4.005]
    assert np.any((motion.knots > coarse_t[-2]) & (motion.knots < coarse_t[-1]))
    coarse = truth.generate(motion, coarse_t)
    fine = truth.generate(motion, np.arange(4006) * 0.001)
    np.testing.assert_allclose(coarse.dtheta[-1], fine.dtheta[3990:].sum(axis=0), atol=1e-14)
    np.testing.assert_allclose(coarse.dv[-1], fine.dv[3990:].sum(axis=0), atol=1e-12)

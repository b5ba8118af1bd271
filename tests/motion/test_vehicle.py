"""A land vehicle's motion from a GNSS track (`motion.vehicle`, `motion.track`)."""
import math

import numpy as np
import pytest

from mimunav.frames import attitude, earth
from mimunav.motion import truth
from mimunav.errors import InputError
from mimunav.motion.vehicle import TrackMotion
from drives import H0, LAT0, LON0, straight_track, track_from_velocity


def test_track_motion_circle_matches_closed_form():
    """Constant speed v on a circle of radius R turning right: yaw rate v/R about down,
    specific force v^2/R to the right and g up, exactly (up to the spline's fit of the
    4 Hz samples)."""
    v0, radius = 12.0, 80.0
    t = np.arange(0.0, 60.0, 0.25)
    yaw = v0 / radius * t
    vel = np.column_stack([v0 * np.cos(yaw), v0 * np.sin(yaw), np.zeros_like(t)])
    r_n, r_e = earth.radii(LAT0)
    north, east = radius * np.sin(yaw), radius * (1 - np.cos(yaw))
    motion = TrackMotion(t, LAT0 + north / (r_n + H0), LON0 + east / ((r_e + H0) * math.cos(LAT0)),
                         np.full_like(t, H0), vel)
    ts = np.arange(10.0, 50.0, 0.01)
    kin = motion.kinematics(ts)
    assert np.allclose(kin.w_nb_b[:, 2], v0 / radius, rtol=1e-4)
    assert np.allclose(kin.w_nb_b[:, :2], 0.0, atol=1e-6)
    motion.t0 = 10.0
    run = truth.generate(motion, ts)
    f = run.dv / 0.01
    g = earth.normal_gravity(LAT0, H0)
    # earth rate and Coriolis terms are < 2e-3 m/s^2 at 12 m/s
    assert np.allclose(f[:, 1], v0 ** 2 / radius, atol=3e-3)
    assert np.allclose(f[:, 0], 0.0, atol=3e-3)
    assert np.allclose(f[:, 2], -g, atol=3e-3)


def test_track_motion_rate_derivative_matches_a_difference_of_its_rates():
    """dw_nb_b (analytic, from the spline's jerk) against a central difference of w_nb_b on
    the weaving climb of the synthetic drive."""
    motion = TrackMotion(*straight_track())
    t = np.linspace(31.0, 110.0, 400)
    h = 1e-4
    numeric = (motion.kinematics(t + h).w_nb_b - motion.kinematics(t - h).w_nb_b) / (2 * h)
    dw = motion.kinematics(t).dw_nb_b
    assert np.abs(dw - numeric).max() < 1e-6 * max(1.0, np.abs(dw).max() * 1e3)


@pytest.mark.slow
def test_the_track_smoothing_is_scipys_gcv_choice():
    """`vehicle.gcv` against the GCV score of the smoother matrix built column by column
    from scipy's own spline (N |y - A y|^2 / tr(I - A)^2), `gcv_smoothing`'s spline
    against scipy's `make_smoothing_spline(t, y)` (its own GCV search) on uneven knots, and
    `smoothing_spline` against scipy's with the same lambda."""
    from scipy.interpolate import make_smoothing_spline
    from mimunav.motion.vehicle import gcv, gcv_smoothing, smoothing_spline
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 12.0, 120))
    y = np.sin(t) + rng.normal(0.0, 0.2, len(t))
    for lam in (1e-4, 0.02, 0.7, 40.0):
        a = np.column_stack([make_smoothing_spline(t, e, lam=lam)(t) for e in np.eye(len(t))])
        r = y - a @ y
        dense = len(t) * (r @ r) / np.trace(np.eye(len(t)) - a) ** 2
        assert gcv(lam, np.diff(t), y) == pytest.approx(dense, rel=1e-7)
    t = np.sort(rng.uniform(0.0, 60.0, 400))
    y = np.sin(t / 3.0) + rng.normal(0.0, 0.1, len(t))
    lam = gcv_smoothing(t, y)
    assert 0.1 < lam < 100
    for bad_t, bad_y in ((t[:4], y[:4]), (t, np.where(t > 30, np.nan, y)),
                         (t[::-1], y), (t, y[:-1])):
        with pytest.raises(InputError, match="smoothing spline"):
            gcv_smoothing(bad_t, bad_y)
    chosen = make_smoothing_spline(t, y)
    assert np.abs(make_smoothing_spline(t, y, lam=lam)(t) - chosen(t)).max() < 1e-4
    # the spline itself against scipy's, on epochs as a receiver gives them (10 Hz, 10 us
    # of jitter), two columns at once, up to the second derivative (the model's jerk)
    t = np.arange(3000) * 0.1 + rng.normal(0.0, 1e-5, 3000)
    y = np.column_stack([10 * np.sin(t / 5), np.cos(t / 3)]) + rng.normal(0.0, 0.02, (3000, 2))
    at = np.linspace(t[0], t[-1], 7000)
    for lam in (1e-5, 0.7, 3000.0):
        mine, theirs = smoothing_spline(t, y, lam), make_smoothing_spline(t, y, lam=lam)
        for nu in (0, 1, 2):
            assert np.abs(mine(at, nu) - theirs.derivative(nu)(at) if nu else
                          mine(at) - theirs(at)).max() < 1e-8, (lam, nu)


def test_the_running_integral_of_piecewise_constant_outputs_is_exact():
    """`intervals.RunningIntegral` against quadrature on a grid holding every edge and query
    time (midpoint values of x: exact for its integral; trapezoids of that: exact for the
    second), before, between and beyond uneven edges; its means over other intervals."""
    from mimunav.motion.intervals import RunningIntegral
    rng = np.random.default_rng(1)
    edges = np.cumsum(rng.uniform(0.5, 1.5, 50))
    x = rng.normal(size=(49, 2))
    times = np.sort(rng.uniform(edges[0] - 3, edges[-1] + 3, 300))
    grid = np.union1d(np.union1d(edges, times), np.linspace(edges[0] - 3, edges[-1] + 3, 1001))
    mid = 0.5 * (grid[1:] + grid[:-1])
    x_mid = x[np.clip(np.searchsorted(edges, mid) - 1, 0, 48)]
    step = np.diff(grid)[:, None]
    once = np.vstack([np.zeros(2), np.cumsum(x_mid * step, axis=0)])
    once -= once[np.searchsorted(grid, edges[0])]
    twice = np.vstack([np.zeros(2), np.cumsum(0.5 * (once[1:] + once[:-1]) * step, axis=0)])
    twice -= twice[np.searchsorted(grid, edges[0])]
    at = np.searchsorted(grid, times)
    integral = RunningIntegral(edges, x)
    assert np.abs(integral.once(times) - once[at]).max() < 1e-12
    assert np.abs(integral.twice(times) - twice[at]).max() < 1e-11
    means = np.diff(once[at], axis=0) / np.diff(times)[:, None]    # over (times[k-1], times[k]]
    assert np.abs(integral.means(times) - np.vstack([means[:1], means])).max() < 1e-11


def test_smooth_means_over_shifted_intervals_are_fourth_order():
    """Closed form: interval means of a 2 Hz sinusoid at 400 Hz, re-expressed over 200 Hz
    intervals whose ends fall 0.4 of a step between theirs. The piecewise-constant reading is
    off by w'' a (1 - a) h^2 / 2 (1.2e-4 of the swing, a rate table's false scale factor);
    the smooth one by under 1e-6 of it, and both are exact where the ends meet edges."""
    from mimunav.motion.intervals import RunningIntegral
    omega, h = 2 * np.pi * 2.0, 0.0025
    edges = np.arange(0.0, 20.0 + h / 2, h)
    x = (np.cos(omega * edges[:-1]) - np.cos(omega * edges[1:]))[:, None] / (omega * h)
    times = np.arange(1.0, 19.0, 0.005) + 0.4 * h
    exact = (np.cos(omega * times[:-1]) - np.cos(omega * times[1:])) / (omega * 0.005)
    integral = RunningIntegral(edges, x)
    plain = integral.means(times)[1:, 0] - exact
    smooth = integral.means(times, smooth=True)[1:, 0] - exact
    assert np.abs(plain).max() > 1e-4
    assert np.abs(smooth).max() < 1e-6
    on_edges = edges[400:7000:2]
    exact = (np.cos(omega * on_edges[:-1]) - np.cos(omega * on_edges[1:])) / (omega * 2 * h)
    assert np.abs(integral.means(on_edges, smooth=True)[1:, 0] - exact).max() < 1e-12


def test_reference_velocity_is_in_each_epochs_own_ned():
    """Closed form (an independent user's oracle): a drive due east along the 48.1 deg N
    parallel at 25 m/s for 50 km, fixes at 5 Hz, has velocity (0, 25, 0) in every epoch's
    NED. Differences taken in the first fix's NED tilted it by the arc travelled: 0.2 m/s
    north and down at 50 km, twice the sigma the import states."""
    from mimunav.frames import earth
    from mimunav.motion.track import velocity_from_positions
    lat, h = math.radians(48.1), 520.0
    t = np.arange(0.0, 2000.0, 0.2)
    _, r_e = earth.radii(lat)
    lon = math.radians(11.5) + 25.0 * t / ((r_e + h) * math.cos(lat))
    v = velocity_from_positions((1.7e18 + t * 1e9).astype(np.int64), np.full_like(t, lat),
                                lon, np.full_like(t, h))
    assert np.abs(v - [0.0, 25.0, 0.0]).max() < 1e-4          # m/s (one-sided ends: 2e-5)


@pytest.mark.parametrize("curve", [0.0, 1e-4])
def test_a_stopped_cars_pitch_error_is_measured_against_the_roads_curve(curve):
    """A car at rest for 20 s at the foot of a road whose height is 0.02 s + curve s^2 over
    the distance s (m) driven: the grade at the stop is 0.02 exactly, the line over the
    HOLD_DISTANCE_M ahead reads 0.02 + curve x (its points' spread) - its error is the
    quadratic's slope at the stop less the line's, which `held_pitch_sd` reports whole (with
    the line's standard error beside it): the true error within 5 % (the track's trapezoid
    positions) and at most twice it; on a straight grade the held pitch is exact and its
    error ~0."""
    t = np.arange(0.0, 80.0 + 1e-9, 0.1)
    speed = 10.0 * np.clip((t - 20.0) / 5.0, 0.0, 1.0) ** 2 * (3 - 2 * np.clip(
        (t - 20.0) / 5.0, 0.0, 1.0))
    s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])
    grade = 0.02 + 2 * curve * s
    v = np.column_stack([speed, np.zeros_like(t), -grade * speed])
    _, lat, lon, h, _ = track_from_velocity(t, v)
    motion = TrackMotion(t, lat, lon, h, v)
    at_rest = np.array([5.0, 10.0, 15.0])
    pitch = attitude.as_euler(motion.kinematics(at_rest).q_nb)[1]
    error = np.abs(pitch - math.atan(0.02))
    sd = motion.held_pitch_sd(at_rest)
    assert np.all(motion.held_pitch_sd(np.array([40.0, 60.0])) == 0.0)      # moving
    if curve == 0.0:
        assert np.all(error < 1e-5) and np.all(sd < 5e-5)          # 0.003 deg
    else:
        assert np.all(error > 1e-3)                      # the line's error: 0.1 deg and more
        assert np.all(sd > 0.95 * error) and np.all(sd < 2 * error), (sd, error)


def test_the_moving_pitchs_error_is_the_smoothed_verticals_over_the_speed():
    """White noise on a drive's vertical velocity (1 Hz at 1.5 m/s, 10 Hz at 0.05, 5 Hz at
    0.3): the smoothing spline's error, predicted through its equivalent kernel
    (`_smoothed_noise`), against the error it makes (the smoothed vertical less the true
    one), five draws each - within 15 %; the moving pitch's sigma is it over the speed."""
    from drives import straight_track
    for rate, sigma in ((1.0, 1.5), (10.0, 0.05), (5.0, 0.3)):
        made, said = [], []
        for seed in range(5):
            t, lat, lon, h, v = straight_track(duration=600.0, rate=rate)
            noisy = v.copy()
            noisy[:, 2] += np.random.default_rng(seed).normal(0, sigma, len(t))
            motion = TrackMotion(t, lat, lon, h, noisy)
            tt = np.linspace(60.0, 540.0, 2000)
            made.append(np.std(motion.kinematics(tt).v_ned[:, 2] - np.interp(tt, t, v[:, 2])))
            said.append(motion.moving_pitch_sd(np.array([100.0]))[0] * motion.speed([100.0])[0])
        assert np.mean(said) == pytest.approx(np.mean(made), rel=0.15), (rate, said, made)


def test_the_white_noise_of_a_moving_series_is_its_noise():
    """0.3 of white noise on a slow sine of amplitude 50 (a velocity while driving), and on
    two columns at once: the second differences' MAD gives the noise, not the motion."""
    from mimunav.motion.track import white_noise
    t = np.arange(0.0, 600.0, 0.1)
    rng = np.random.default_rng(3)
    x = 50 * np.sin(2 * np.pi * t / 120.0) + rng.normal(0, 0.3, len(t))
    assert white_noise(x) == pytest.approx(0.3, rel=0.05)
    both = np.column_stack([x, 10 + rng.normal(0, 0.3, len(t))])
    assert white_noise(both) == pytest.approx(0.3, rel=0.05)
    assert white_noise(x[:4]) == 0.0

"""Rotation modulation (seed S4, `mimunav.evaluation.modulation`): the rotating IMU's increments against
closed-form interval means, and what modulation does to known errors in closed form - a
scale-factor error under continuous rotation is heading drift k x turned angle, a bias along
the axis is never modulated, a horizontal bias is."""
import math
from dataclasses import replace

import numpy as np
import pytest

from mimunav.frames import attitude, earth
from mimunav.motion import truth
from mimunav.evaluation.flight import Flight
from mimunav.evaluation.replay import comparison_times, errors_at, navigate, replay, resample
from mimunav.evaluation.modulation import CONFIGURATIONS, TILT_ERRORS, tilt_compensation
from mimunav.motion.platform import (ENCODER_RESOLUTION_RAD, Platform, RotatingMotion,
                                     vehicle_attitude)
from mimunav.motion.profile import Profile
from mimunav.frames.mounting import Mounting
from mimunav.motion.trajectory import Trajectory

LAT = 45.0
RATE = math.radians(36.0)


def _parked(duration):
    return Profile.from_dict({"name": "parked", "start": {
        "latitude_deg": LAT, "longitude_deg": 10.0, "height_m": 100.0, "speed_m_s": 0.0,
        "heading_deg": 0.0}, "segment": [{"kind": "hold", "duration_s": duration}]})


def test_rotating_imu_increments_are_the_closed_form_interval_means():
    """Parked level, heading north, platform turning at 36 deg/s about the vertical: each
    interval's mean rate is the Earth rate turned by -theta, averaged over the interval in
    closed form (mean of cos/sin over [theta0, theta1]), plus the platform rate; the mean
    specific force likewise (only its vertical part: unchanged)."""
    p = Platform("continuous", RATE, ramp_s=1.0)
    m = RotatingMotion(_parked(20.0).motion(), p, 20.0)
    t = np.arange(0, 2001) / 100.0
    run = truth.generate(m, t)
    k = np.arange(200, 2000)                                # after the ramp: constant rate
    th0, th1 = m.angle(t[k]), m.angle(t[k + 1])
    dth = th1 - th0
    c, s = (np.sin(th1) - np.sin(th0)) / dth, (np.cos(th0) - np.cos(th1)) / dth
    w_ie = earth.earth_rate_ned(math.radians(LAT))       # body = NED axes (level, north)
    expect = np.column_stack([c * w_ie[0] + s * w_ie[1], -s * w_ie[0] + c * w_ie[1],
                              np.full(len(k), w_ie[2] + RATE)])     # platform z = down
    np.testing.assert_allclose(run.dtheta[k] * 100.0, expect, rtol=0, atol=1e-11)
    g = earth.gravity_ned(math.radians(LAT), 100.0)
    np.testing.assert_allclose(run.dv[k] * 100.0, np.tile(-g, (len(k), 1)), atol=1e-9)


def test_an_imu_off_the_axis_feels_the_platform_turning_in_closed_form():
    """The same parked platform with the IMU 0.2 m out along platform x: at constant rate
    its point circles the axis; the mean specific force in sensor (= platform) axes is the
    centripetal -W^2 r plus the Coriolis of its circling against the Earth's vertical rate,
    +2 W w_ie sin(lat) r (platform z down), tangential 0; the point starts 0.2 m north."""
    r = 0.2
    p = Platform("continuous", RATE, ramp_s=1.0, lever_arm_m=(r, 0.0, 0.0))
    m = RotatingMotion(_parked(20.0).motion(), p, 20.0)
    t = np.arange(0, 2001) / 100.0
    run = truth.generate(m, t)
    f = run.dv[200:2000] * 100.0
    w_ie = earth.OMEGA * math.sin(math.radians(LAT))
    assert f[:, 0].mean() == pytest.approx(-RATE**2 * r + 2 * RATE * w_ie * r, abs=1e-8)
    assert np.abs(f[:, 1]).max() < 1e-8
    r_n, _ = earth.radii(math.radians(LAT))
    assert (run.trajectory.lat[0] - math.radians(LAT)) * (r_n + 100.0) == pytest.approx(r)


def _navigate(platform, duration, disturb):
    """Free-inertial run of an IMU on `platform`, parked; disturb(w, f) adds the errors.
    Returns (vehicle attitude error rotation vectors NED, rad, at the end; turned angle)."""
    m = RotatingMotion(_parked(duration).motion(), platform, duration)
    t = np.arange(0, int(duration * 100) + 1) / 100.0
    run = truth.generate(m, t)
    w, f = disturb(run.dtheta * 100.0, run.dv * 100.0)
    s0 = run.trajectory.state(0)
    nav = navigate(t[1:], w, f, Mounting(), replace(s0, t=0.0))
    q_bs = m.q_bs(nav.t)
    ref = resample(run.trajectory, nav.t)
    est = Trajectory(nav.t, nav.lat, nav.lon, nav.h, nav.v_ned,
                     vehicle_attitude(nav.q_nb, q_bs))
    true = Trajectory(ref.t, ref.lat, ref.lon, ref.h, ref.v_ned,
                      vehicle_attitude(ref.q_nb, q_bs))
    return est.attitude_error(true)[-1], float(m.angle(nav.t[-1]))


def test_continuous_rotation_turns_a_scale_error_into_heading_drift():
    k = 1e-3
    err, turned = _navigate(Platform("continuous", RATE, ramp_s=1.0), 60.0,
                            lambda w, f: (w * [1, 1, 1 + k], f))
    assert abs(err[2]) == pytest.approx(k * abs(turned), rel=0.02)
    # back and forth: after whole swings (4 x (10 s + 1 s ramp)) the platform is home and
    # the scale error's heading has cancelled
    back, home = _navigate(Platform("back-and-forth", RATE, swing_rad=2 * math.pi,
                                               ramp_s=1.0), 44.0,
                           lambda w, f: (w * [1, 1, 1 + k], f))
    assert abs(home) < 1e-6 and abs(back[2]) < 0.05 * abs(err[2])


def test_a_bias_along_the_axis_is_never_modulated_a_horizontal_one_is():
    b = math.radians(10 / 3600)
    axial = lambda w, f: (w + [0, 0, b], f)                                   # noqa: E731
    for p in (Platform("fixed"), Platform("continuous", RATE)):
        err, _ = _navigate(p, 120.0, axial)
        assert abs(err[2]) == pytest.approx(b * 120.0, rel=0.02)          # heading b T
    horizontal = lambda w, f: (w + [b, 0, 0], f)                              # noqa: E731
    fixed, _ = _navigate(Platform("fixed"), 120.0, horizontal)
    turning, _ = _navigate(Platform("continuous", RATE), 120.0, horizontal)
    assert np.hypot(*turning[:2]) < 0.1 * np.hypot(*fixed[:2])


def test_a_bias_that_follows_the_platform_angle_is_not_modulated():
    """Seed S4's periodic bias terms: A sin(theta) on the sensor x gyro turns with the IMU
    into C_bs (A sin theta, 0, 0) = A sin(theta) (cos theta, sin theta, 0), whose mean is
    (0, A/2, 0) in the vehicle frame - a constant, so the tilt grows as A/2 T (closed form),
    where a constant A on that axis is averaged away (`modulation._periodic_bias` draws such
    terms for the report)."""
    b, duration = math.radians(10 / 3600), 120.0
    p = Platform("continuous", RATE)
    m = RotatingMotion(_parked(duration).motion(), p, duration)
    theta = m.angle(np.arange(0, int(duration * 100) + 1) / 100.0)
    a, c = theta[:-1], theta[1:]
    periodic = lambda w, f: (w + np.column_stack([                          # noqa: E731
        b * (np.cos(a) - np.cos(c)) / (c - a), np.zeros((len(a), 2))]), f)
    err, _ = _navigate(p, duration, periodic)
    assert np.hypot(*err[:2]) == pytest.approx(0.5 * b * (duration - 1.0), rel=0.05)
    constant, _ = _navigate(p, duration, lambda w, f: (w + [b, 0, 0], f))
    assert np.hypot(*constant[:2]) < 0.1 * np.hypot(*err[:2])


def test_platform_refuses_an_unknown_mode():
    from mimunav.errors import InputError
    with pytest.raises(InputError, match="platform mode"):
        Platform("wobble")


@pytest.mark.slow
def test_a_rotating_mimu_is_logged_and_replayed_through_its_platform(tmp_path, capsys):
    """`simulate --platform`: a perfect MIMU (exactly the model, no noise) turning at 10
    deg/s on a pull-up and roll: /mimu/platform is a sensor_msgs/msg/JointState that the
    independent ROS 2 decoder reads, and the replay - navigating the sensor frame, the
    vehicle attitude from the logged angle - follows the truth to the navigator's own
    accuracy (a wrong angle or sign would leave degrees and kilometres)."""
    import json
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from mimunav.cli import main
    from mimunav.sensors.simulation import simulate_flight
    from motions import pull_roll
    from test_evaluation import perfect_unit
    prof = pull_roll(100.0, 20.0)
    unit = perfect_unit()
    path = tmp_path / "rot.mcap"
    simulate_flight(prof, path, seed=3, unit=unit, progress=False,
                    platform=Platform("continuous", math.radians(10.0)))
    with open(path, "rb") as fh:
        decoded = [ros for _, _, _, ros in make_reader(
            fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=["/mimu/platform"])]
    assert decoded[0].name == ["platform"]
    assert decoded[-1].velocity[0] == pytest.approx(math.radians(10.0))
    flight = Flight.load(path)
    assert flight.mimu_platform is not None
    rep = replay(flight, unit.coefficients)
    err = errors_at(rep, comparison_times(flight))["mimu-truth"]
    assert np.abs(err["position"]).max() < 0.05
    assert np.abs(err["attitude"]).max() < 2e-5
    cal = tmp_path / "cal.json"
    unit.coefficients.save(cal)
    assert main(["replay", str(path), "--cal", str(cal), "-o", str(tmp_path / "r")]) == 0
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["mimu_platform"]["mode"] == "continuous"
    capsys.readouterr()
    assert main(["info", str(path)]) == 0
    assert "on a rotation platform: continuous, 10 deg/s" in capsys.readouterr().out
    assert main(["windows", str(path), "--cal", str(cal), "-o", str(tmp_path / "w")]) == 2
    assert main(["diagnose", str(path), "--model", str(cal), "--level", "navigation"]) == 2
    assert main(["noise", str(path), "--channel", "/mimu/raw", "--cal", str(cal),
                 "-o", str(tmp_path / "n")]) == 2             # turning is not rest


def test_the_inclined_mount_puts_every_axis_at_the_magic_angle():
    q = CONFIGURATIONS["continuous, inclined"].q_ps()
    angles = [math.degrees(math.acos(attitude.rotate(q, e)[2])) for e in np.eye(3)]
    np.testing.assert_allclose(angles, math.degrees(math.acos(1 / math.sqrt(3))), atol=1e-9)


@pytest.mark.slow
def test_installation_tilt_fitted_and_compensated():
    """Seed S4 (Gao, Guan, Wang 2013): a 2 deg deviation of the IMU's mounting on the
    platform, fitted from the vehicle attitude computed with the design mounting. With an
    ideal IMU the fit is the deviation itself (truth: the simulator's mounting); with MEMS
    biases on a back-and-forth platform it is within its stated uncertainty and the level
    error falls to the unit's own floor."""
    from mimunav.reports.modulation import PARKED
    prof = Profile.from_dict(PARKED)
    dev = np.radians(2.0) * np.array([0.6, -0.8, 0.0])
    r = tilt_compensation(prof, CONFIGURATIONS["continuous"], dev, {},
                                     seed=1, duration_s=300.0)
    assert np.abs(r["fitted_rad"] - dev[:2]).max() < 1e-6
    assert r["before"]["tilt_rad"] > 0.03 and r["after"]["tilt_rad"] < 1e-5
    errors = TILT_ERRORS["bias + instability"]
    r = tilt_compensation(prof, CONFIGURATIONS["back-and-forth"], dev,
                                     errors, seed=3)
    assert r["bias_separated"]
    assert (np.abs(r["fitted_rad"] - dev[:2]) < 4 * r["se_rad"]).all()
    assert r["after"]["tilt_rad"] < 1.05 * r["floor"]["tilt_rad"] < 0.2 * r["before"]["tilt_rad"]
    # a continuous rotation cannot separate a modulated bias from the deviation
    r = tilt_compensation(prof, CONFIGURATIONS["continuous"], dev,
                                     errors, seed=3)
    assert not r["bias_separated"]


def test_encoder_reads_the_same_angles_however_the_record_is_cut():
    """The platform angle's read-out noise is drawn per sample index (a counter-based
    generator), so blocks of any size read what the whole record reads; its spread is the
    stated noise, and the grating's resolution rounds it."""
    p = Platform("continuous", encoder_noise_rad=1e-4, encoder_seed=9,
                            encoder_resolution_rad=ENCODER_RESOLUTION_RAD)
    angle = np.linspace(0.0, 50.0, 20001)
    whole = p.encoder(angle)
    cut = np.concatenate([p.encoder(angle[:777]), p.encoder(angle[777:5000], 777),
                          p.encoder(angle[5000:], 5000)])
    np.testing.assert_array_equal(whole, cut)
    assert np.std(whole - angle) == pytest.approx(1e-4, rel=0.03)
    steps = whole / ENCODER_RESOLUTION_RAD
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    other = Platform("continuous", encoder_noise_rad=1e-4, encoder_seed=10)
    assert not np.allclose(other.encoder(angle), p.encoder(angle))


def test_an_imu_off_the_axis_is_replayed_to_the_vehicle_origin(tmp_path):
    """A perfect MIMU turning at 36 deg/s 0.19 m off the axis on a pull-up and roll: the
    replay navigates the IMU's circling point and brings it back to the vehicle origin with
    the recorded angle and rate (r = C_bp0 Rz(theta) r_p, velocity w x r + theta' a x r):
    within 1 mm and 0.1 mm/s of the truth (left out, the lever arm leaves 0.35 m, 0.28 m/s)."""
    from mimunav.sensors.simulation import simulate_flight
    from motions import pull_roll
    from test_evaluation import perfect_unit
    unit = perfect_unit()
    path = tmp_path / "arm.mcap"
    simulate_flight(pull_roll(100.0, 20.0), path, seed=3, unit=unit, progress=False,
                    platform=Platform("continuous", math.radians(36.0),
                                                 lever_arm_m=(0.15, -0.1, 0.05)))
    flight = Flight.load(path)
    assert flight.mimu_platform.meta["lever_arm_m"] == [0.15, -0.1, 0.05]
    rep = replay(flight, unit.coefficients)
    err = errors_at(rep, comparison_times(flight))["mimu-truth"]
    assert np.abs(err["position"]).max() < 1e-3
    assert np.abs(err["velocity"]).max() < 1e-4
    assert np.abs(err["attitude"]).max() < 1e-8

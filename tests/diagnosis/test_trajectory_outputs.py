"""What an ideal MIMU reads on a reference trajectory with attitude
(`diagnosis.reference.trajectory_outputs`: the navigation level's regressors, free of the
MIMU's own noise) against the truth generator's exact increments (`motion.truth.generate`,
tested against closed forms in tests/motion/test_truth.py)."""
import numpy as np

from mimunav.diagnosis.reference import has_attitude, trajectory_outputs
from mimunav.frames import attitude
from mimunav.frames.mounting import Mounting
from mimunav.motion import truth
from mimunav.motion.profile import Profile


def _manoeuvres():
    """A roll, a coordinated turn, a pull and a push of the throttle, all with ramps (rates
    C2): 1 kHz truth."""
    prof = Profile.from_dict({
        "name": "m", "start": dict(latitude_deg=45.0, longitude_deg=10.0, height_m=1000.0,
                                   speed_m_s=100.0, heading_deg=30.0),
        "segment": [{"kind": "roll", "angle_deg": 30, "rate_deg_s": 30, "ramp_s": 0.3},
                    {"kind": "turn", "load_factor": 1.5, "heading_change_deg": 90,
                     "ramp_s": 0.5},
                    {"kind": "pull", "load_factor": 1.5, "flight_path_change_deg": 10,
                     "ramp_s": 0.5},
                    {"kind": "accelerate", "accel_g": 0.5, "duration_s": 3, "ramp_s": 0.5}]})
    t = np.arange(0, 20001) / 1000.0
    return truth.generate(prof.motion(), t), t


def test_the_outputs_are_the_exact_interval_means_on_10_ms_bins():
    run, t = _manoeuvres()
    m = 10                                                  # 10 ms bins of 1 kHz truth
    n = (len(t) - 1) // m
    for r in ((0.0, 0.0, 0.0), (0.3, -0.2, 0.1)):
        mounting = Mounting(attitude.as_wxyz(attitude.from_euler(0.1, -0.05, 0.2)),
                            np.array(r))
        f_s, w_s = trajectory_outputs(run.trajectory, t[::m], mounting)
        q_sv = np.conjugate(mounting.q_vs)
        w_true = attitude.rotate(q_sv, run.dtheta.reshape(n, m, 3).sum(axis=1) / 0.01)
        f_true = attitude.rotate(q_sv, run.dv_at(np.array(r)).reshape(n, m, 3).sum(axis=1) / 0.01)
        assert np.abs(w_true).max() > 0.5 and np.ptp(f_true) > 5.0       # it manoeuvres
        # second order in the bin: 1e-10 rad/s at the median, 2.4e-5 where a 1.8 rad/s
        # roll-in steps inside one bin (the Earth's rate, 5e-5 per axis here, is far above)
        w_err = np.abs(w_s - w_true).max(axis=1)
        assert np.median(w_err) < 1e-9 and w_err.max() < 4e-5
        # the specific force at the origin to 0.01 m/s^2 where the rates step, 2e-4 (99 %)
        # elsewhere; at a lever arm the angular acceleration over TRANSFER_WINDOW_S
        err = np.abs(f_s - f_true).max(axis=1)
        assert np.quantile(err, 0.99) < (3e-4 if not any(r) else 3e-3)
        if not any(r):
            assert err.max() < 1e-2


def test_a_trajectory_without_attitude_gives_no_outputs():
    run, _ = _manoeuvres()
    traj = run.trajectory
    assert has_attitude(traj, 0.0, 20.0)
    assert not has_attitude(traj, -1.0, 20.0)               # it must cover the span
    q = attitude.as_wxyz(traj.q_nb).copy()
    q[5000] = np.nan
    blind = traj[np.arange(len(traj))]
    blind.q_nb = attitude.from_wxyz(q)
    assert not has_attitude(blind, 0.0, 20.0) and has_attitude(blind, 6.0, 20.0)


def test_at_rest_the_outputs_are_the_earths_rate_and_gravity_in_closed_form():
    """A trajectory written by hand - at rest, tilted, at 45 deg N - against the closed form
    w = C_bn w_ie, f = -C_bn g (`frames.earth`), without the truth generator's
    `body_rate_and_specific_force` that `trajectory_outputs` calls (the exact-increment test
    above shares it)."""
    from mimunav.frames import earth
    from mimunav.motion.trajectory import Trajectory
    n, lat, h = 101, np.radians(45.0), 150.0
    q = attitude.from_euler(np.radians(37.0), np.radians(4.0), np.radians(-3.0))
    traj = Trajectory(np.arange(n) * 0.01, np.full(n, lat), np.full(n, 0.3), np.full(n, h),
                      np.zeros((n, 3)), np.full(n, q))
    mounting = Mounting(attitude.as_wxyz(attitude.from_euler(0.1, -0.05, 0.2)), np.zeros(3))
    f_s, w_s = trajectory_outputs(traj, traj.t, mounting)
    q_sn = np.conjugate(mounting.q_vs) * np.conjugate(q)
    np.testing.assert_allclose(w_s, np.tile(attitude.rotate(q_sn, earth.earth_rate_ned(lat)),
                                            (n - 1, 1)), atol=1e-15)
    np.testing.assert_allclose(f_s, np.tile(attitude.rotate(q_sn, -earth.gravity_ned(lat, h)),
                                            (n - 1, 1)), atol=1e-12)

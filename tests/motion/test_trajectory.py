"""The Trajectory container: its first sample and its refusal to compare trajectories
sampled at different times."""
import numpy as np
import pytest
import quaternion  # noqa: F401  (np.quaternion)


def test_trajectories_compared_only_at_the_same_times():
    from mimunav.errors import InputError
    from mimunav.motion.trajectory import Trajectory
    t = np.arange(5.0)
    q = np.full(5, np.quaternion(1, 0, 0, 0))
    a = Trajectory(t, np.full(5, 0.7), np.zeros(5), np.zeros(5), np.zeros((5, 3)), q)
    assert a.state().t == 0.0 and a.state(-1).t == 4.0      # the first by default
    for other_t in (t + 2e-9, t[:4], np.arange(6.0), np.array([0, 1, 2, 3, 4.5])):
        n = len(other_t)
        b = Trajectory(other_t, np.full(n, 0.7), np.zeros(n), np.zeros(n), np.zeros((n, 3)),
                       np.full(n, np.quaternion(1, 0, 0, 0)))
        for method in (a.position_error, a.velocity_error, a.attitude_error):
            with pytest.raises(InputError, match="not sampled at the same times"):
                method(b)
    close = Trajectory(t + 5e-10, np.full(5, 0.7), np.zeros(5), np.zeros(5), np.zeros((5, 3)), q)
    assert np.abs(a.position_error(close)).max() == 0.0

"""Whether a reference attitude holds its own IMU's gyro, axis by axis
(`importers.attitude_check.check_rates_along`), on motions that fold or repeat: a car's
bumps beside a 1 Hz attitude, a bounce half a period late. The truth: an attitude series
drawn here, the gyro's interval means made from it exactly (each sample the turn over the
interval its stamp ends)."""
import numpy as np
import pytest
import quaternion

from mimunav.frames import attitude
from mimunav.frames.mounting import Mounting
from mimunav.importers import checks
from mimunav.importers.attitude_check import RUNS_AGAINST, rates_along
from mimunav.importers.recording import Recording, RecordingError

RATE = 100.0
EPOCH_NS = 1_700_000_000_000_000_000


def _bumpy(seconds, bounce_s, seed=7):
    """(t s, q_nb, w rad/s) of a vehicle on the spot at RATE: roll and pitch bumps (a sum of
    sines within 20 % of the period bounce_s, random phases; 0.6 deg), slow yaw turns that
    never repeat (20 deg, periods of 23-71 s); w each sample's interval mean, exact."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / RATE)

    def wobble(period_s, size, count):
        periods = period_s * rng.uniform(0.8, 1.2, count)
        return size * sum(np.sin(2 * np.pi * t / p + rng.uniform(0, 2 * np.pi))
                          for p in periods) / np.sqrt(count)

    roll, pitch = (wobble(bounce_s, np.radians(0.6), 6) for _ in range(2))
    yaw = sum(np.radians(20.0) * np.sin(2 * np.pi * t / p + rng.uniform(0, 6.3))
              for p in (23.0, 41.0, 71.0))
    q = attitude.from_euler(yaw, pitch, roll)
    turn = attitude.rotation_vector_error(np.conjugate(q[:-1]), np.conjugate(q[1:]))
    return t[1:], q[1:], turn * RATE


def _recording(t, q, w, every, late_s):
    """A Recording of the IMU (given right: the vehicle's axes) and a reference on the spot
    whose attitude is every `every`-th epoch, stamped late_s s late."""
    ns = EPOCH_NS + np.round(t * 1e9).astype(np.int64)
    f = attitude.rotate(np.conjugate(q), np.tile([0.0, 0.0, -9.80665], (len(t), 1)))
    k = slice(0, None, every)
    m = len(t[k])
    ref = dict(ns=ns[k] + int(round(late_s * 1e9)), lat=np.full(m, 0.7), lon=np.full(m, 0.2),
               h=np.full(m, 10.0), v_ned=np.zeros((m, 3)), q_nb=quaternion.as_float_array(q[k]))
    return Recording("bumpy", "test", ns, w, f, Mounting(), reference=ref, vehicle="ship")


def test_bumps_beside_a_1_hz_attitude_follow_the_gyro():
    """Bumps every 1.4 s beside an attitude sampled at 1 Hz: its turns between epochs
    against the gyro's mean over exactly those spans follow it on every axis (whole-second
    means beside the epochs' turns had read the roll axis at -0.57 in a review's car, and
    refused it as a sign read wrong); the roll read as its negative still runs against."""
    t, q, w = _bumpy(300.0, 1.4)
    ns = EPOCH_NS + np.round(t * 1e9).astype(np.int64)
    k = slice(0, None, int(RATE))
    ref = dict(ns=ns[k], q_nb=quaternion.as_float_array(q[k]))
    along = rates_along(ref, ns, w, Mounting())
    assert set(along) == set("xyz"), along
    assert all(r > 0.99 and abs(gain - 1) < 0.03 for r, gain, _ in along.values()), along
    yaw, pitch, roll = attitude.as_euler(q[k])
    ref["q_nb"] = quaternion.as_float_array(attitude.from_euler(yaw, pitch, -roll))
    assert rates_along(ref, ns, w, Mounting())["x"][0] < -RUNS_AGAINST
    checks.check_recording(_recording(t, q, w, int(RATE), 0.0))


@pytest.mark.parametrize("read_as", ["as recorded", "roll negated"])
def test_a_bounce_half_a_period_late_is_judged_at_the_clock_s_lag(read_as):
    """Bumps every 1.4 s, the reference's 10 Hz attitude stamped 0.7 s late: at its stamps
    the roll runs against the gyro (half a bounce), at the lag the clock check finds it
    follows, and the recording is taken (it had been refused as a sign read wrong); its
    roll read as its negative runs against at that lag too, and is refused."""
    t, q, w = _bumpy(300.0, 1.4)
    every = int(RATE / 10)
    late = _recording(t, q, w, every, 0.7)
    ref = dict(ns=late.reference["ns"], q_nb=late.reference["q_nb"])
    assert rates_along(ref, late.imu_ns, w, Mounting())["x"][0] < -RUNS_AGAINST
    if read_as == "roll negated":
        yaw, pitch, roll = attitude.as_euler(attitude.from_wxyz(late.reference["q_nb"]))
        late.reference["q_nb"] = quaternion.as_float_array(attitude.from_euler(yaw, pitch,
                                                                               -roll))
        with pytest.raises(RecordingError, match="turns against that gyro about x"):
            checks.check_recording(late)
        return
    checks.check_recording(late)
    said = late.real["reference_attitude_rates"]
    assert "its stamps taken +0.70 s late" in said, (late.real["reference_clock"], said)
    assert "x: correlation +1.00" in said, said


def test_the_specific_force_in_ned_is_compared_with_gravity_not_the_imus_size():
    """An IMU 0.2 m off the axis of a table turning once a second: it feels 7.9 m/s^2 toward
    the axis besides gravity, |f| 12.6 m/s^2 (a walker's foot read 13.3), while its specific
    force turned into NED by the right attitude is gravity in the median - taken (it had
    been refused as 'not [0, 0, -12.6]'); the attitude turned upside down is refused."""
    from types import SimpleNamespace
    t = np.arange(0.0, 30.0, 0.01)
    q_nb = attitude.from_euler(2 * np.pi * t, 0 * t, 0 * t)
    f_b = np.array([-(2 * np.pi) ** 2 * 0.2, 0.0, 0.0]) + \
        attitude.rotate(np.conjugate(q_nb), np.array([0.0, 0.0, -9.81]))
    assert np.linalg.norm(f_b, axis=1).mean() > 12.5
    rec = SimpleNamespace(name="table", reference_meta={}, mounting=Mounting(), f=f_b)
    checks.check_down(rec, attitude.rotate(q_nb, f_b))
    flipped = q_nb * np.quaternion(0.0, 1.0, 0.0, 0.0)
    with pytest.raises(RecordingError, match=r"not \[0, 0, -9.8\]"):
        checks.check_down(rec, attitude.rotate(flipped, f_b))

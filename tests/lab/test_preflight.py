"""The pre-flight gyro zero (`lab.preflight`, issue 54): taken still in the launch attitude,
it sets the compensated rate to the Earth's rate there."""
import math
from dataclasses import replace

import numpy as np
import pytest

from mimunav.compensation.model import compensate, raw_from_physics
from mimunav.frames import attitude
from mimunav.frames.mounting import Mounting
from mimunav.lab.preflight import gyro_zero
from mimunav.sensors.mimu import MimuUnit
from mimunav.sensors.simulation import still_rates

LAT, H = math.radians(40.0), 3000.0


def _still(unit, q_nb, n, temperature_c):
    """Raw outputs of `unit` standing still at q_nb (noise-free, the model's exact inverse)."""
    w, f = still_rates(unit.mounting, q_nb, LAT, H)
    temp = np.full((n, 3), temperature_c)
    freq = unit.thermal.resonance_frequency(np.full((n, 3), temperature_c))
    u_a, u_w = raw_from_physics(unit.coefficients, np.tile(f, (n, 1)), np.tile(w, (n, 1)),
                                temp, freq)
    return w, {"accel_volts": u_a, "gyro_volts": u_w, "accel_temperature": temp,
               "gyro_frequency": freq}


def test_the_zero_of_a_still_unit_is_its_true_zero():
    """A unit exactly the 63-coefficient model, its W0 off by about 400-900 deg/h in the
    calibration: the zero taken still in a turned launch attitude is the true W0 to
    round-off, and the compensated rate the Earth's rate in sensor axes."""
    unit = MimuUnit.draw(5, beyond_model=False)
    unit.mounting = Mounting.from_rpy_deg((2.0, -1.0, 3.0))
    q_nb = attitude.from_euler(math.radians(30.0), math.radians(10.0), math.radians(-5.0))
    w_true, raw = _still(unit, q_nb, 200, 31.0)
    off = replace(unit.coefficients, W0=unit.coefficients.W0 + [2e-3, -4e-3, 3e-3])
    zeroed, stats = gyro_zero(off, raw, w_true, 100.0)
    np.testing.assert_allclose(zeroed.W0, unit.coefficients.W0, atol=1e-12)
    _, w, _ = compensate(zeroed, raw["accel_volts"], raw["gyro_volts"],
                         raw["accel_temperature"], raw["gyro_frequency"], filter_outliers=False)
    np.testing.assert_allclose(w.mean(axis=0), w_true, atol=1e-13)
    assert stats["samples"] == 200
    assert np.all(np.asarray(stats["standard_error_rad_s"]) < 1e-12)     # noise-free
    assert not np.allclose(off.W0, zeroed.W0)


def test_the_earth_rate_and_gravity_of_rest_in_sensor_axes():
    """Level, heading north, sensor = vehicle: w = (W cos lat, 0, -W sin lat), f = (0, 0, -g);
    heading east turns the Earth's rate onto -y."""
    from mimunav.frames import earth
    level = attitude.from_euler(0.0, 0.0, 0.0)
    w, f = still_rates(Mounting.from_rpy_deg((0.0, 0.0, 0.0)), level, LAT, H)
    np.testing.assert_allclose(w, [earth.OMEGA * math.cos(LAT), 0.0,
                                   -earth.OMEGA * math.sin(LAT)], atol=1e-18)
    np.testing.assert_allclose(f, [0.0, 0.0, -earth.normal_gravity(LAT, H)], atol=1e-12)
    east = attitude.from_euler(math.radians(90.0), 0.0, 0.0)
    w, _ = still_rates(Mounting.from_rpy_deg((0.0, 0.0, 0.0)), east, LAT, H)
    np.testing.assert_allclose(w, [0.0, -earth.OMEGA * math.cos(LAT),
                                   -earth.OMEGA * math.sin(LAT)], atol=1e-18)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 4, 5])
def test_a_zero_taken_before_take_off_holds_the_first_seconds_of_flight(seed):
    """A simulated unit (its physics beyond the model included) through the traditional lab
    calibration, powered 600 s before take-off: the zero of its last 10 s still in the launch
    attitude (one record with the flight: the same turn-on bias and thermal history) leaves
    the first 10 s of flight a mean gyro error within 5 sigma of the two 10 s means'
    difference (sqrt(2) x the zero's standard error per axis), where the lab's zero, fitted
    at 25 degC, is off by hundreds of deg/h."""
    from mimunav.evaluation import campaign
    from mimunav.motion.profile import Profile
    from mimunav.sensors import simulation
    from places import FLIGHTS
    unit = campaign.Scenario().draw_unit(seed, "u")
    lab = campaign.lab_calibration(unit, "traditional", 1, seed)
    unit, fog, rng_mimu, rng_fog = simulation.flight_units(seed, unit)
    profile = Profile.load(FLIGHTS / "high-dynamic.toml")
    profile.segments = profile.segments[:1]                 # 10 s of level coast
    fm = simulation.flight_motion(profile, unit.mounting, unit.rate_hz, fog.mounting,
                                  fog.rate_hz, 100.0)
    pre, raw, _ = simulation.record_with_preflight(fm, unit, fog, rng_mimu, rng_fog, 10.0, 600.0)
    tr = fm.run.trajectory
    w_still, _ = still_rates(unit.mounting, tr.q_nb[0], tr.lat[0], tr.h[0])
    zeroed, stats = gyro_zero(lab, pre, w_still, unit.rate_hz)
    w_true = fm.mimu[1][1:] * unit.rate_hz
    n = int(10 * unit.rate_hz)
    error = {}
    for name, cal in (("lab", lab), ("pre-flight", zeroed)):
        _, w, _ = compensate(cal, raw["accel_volts"], raw["gyro_volts"],
                             raw["accel_temperature"], raw["gyro_frequency"],
                             filter_outliers=False)
        error[name] = (w[1:] - w_true)[:n].mean(axis=0)
    sigma = math.sqrt(2) * np.asarray(stats["standard_error_rad_s"])
    assert np.all(np.abs(error["pre-flight"]) < 5 * sigma), (error, sigma)
    deg_h = math.pi / 180 / 3600
    assert np.linalg.norm(error["lab"]) > 200 * deg_h > np.linalg.norm(error["pre-flight"])

"""Replay and the normalised table against analytic truth: a perfect MIMU leaves only the
FOG-IMU's noise in the normalised errors; a lone accelerometer bias b gives 0.5 b t^2 along
its axis; bad inputs are refused with the reason and leave nothing behind."""
import json

import numpy as np
import pytest

from mimunav.evaluation.flight import Flight
from mimunav.evaluation.replay import (Sampler, VehicleNavigator, comparison_times,
                                       compensated_mimu, errors_at, navigate, replay, resample)
from mimunav.evaluation.table import error_budget, normalised_table, table_markdown
from mimunav.cli import main
from mimunav.compensation.calibration_file import Calibration
from mimunav.compensation.model import CalibrationError
from mimunav.flightlog import FlightLog, LogError, LogWriter
from mimunav.errors import InputError
from mimunav.motion.profile import Profile
from mimunav.motion.trajectory import Trajectory
from mimunav.sensors.mimu import MimuUnit
from mimunav.sensors.mimu import NoiseModel
from mimunav.sensors.simulation import simulate_flight

T_HOLD = 60.0


def perfect_unit():
    unit = MimuUnit.draw(4, beyond_model=False)      # exactly the model: closed forms
    unit.noise = NoiseModel(*(0.0,) * 6)
    unit.thermal.thermistor_noise = unit.thermal.frequency_noise = 0.0
    unit.adc_lsb = 1e-15
    unit.coefficients.C[:] = 0.0        # no g-sensitivity: a lone bias stays a lone error
    return unit


@pytest.fixture(scope="module")
def static_flight(tmp_path_factory):
    """60 s parked, level, heading north, perfect MIMU at the default lever arm."""
    prof = Profile.from_dict({"name": "parked", "start": {
        "latitude_deg": 45.0, "longitude_deg": 10.0, "height_m": 100.0, "speed_m_s": 0.0,
        "heading_deg": 0.0}, "segment": [{"kind": "hold", "duration_s": T_HOLD}]})
    unit = perfect_unit()
    from mimunav.sensors.simulation import MIMU_MOUNTING
    from mimunav.frames.mounting import Mounting
    unit.mounting = Mounting.from_dict(MIMU_MOUNTING)
    path = tmp_path_factory.mktemp("flight") / "parked.mcap"
    simulate_flight(prof, path, seed=2, unit=unit, progress=False)
    return str(path), unit


def test_perfect_mimu_leaves_only_fog_noise(static_flight):
    path, unit = static_flight
    doc = normalised_table(Flight.load(path), {"perfect": unit.coefficients})
    row, fog = doc["variants"]["perfect"], doc["fog"]
    assert row["norm_m"] < 1e-3                       # the navigator's own error
    assert fog["norm_m"] > 20 * row["norm_m"]         # FOG noise dominates
    assert max(row["normalised_enu"]) < 0.1


def test_accelerometer_bias_gives_half_b_t_squared(static_flight):
    """A 1 mg bias on the north-pointing accelerometer, nothing else wrong."""
    path, unit = static_flight
    b = 1e-3 * 9.80665                                # 1 mg on the x (north) accelerometer
    cal = Calibration.from_dict(unit.coefficients.as_dict())
    cal.A0 = cal.A0 + np.array([b, 0.0, 0.0])
    doc = normalised_table(Flight.load(path), {"biased": cal})
    east, north, up = doc["variants"]["biased"]["enu_m"]
    t = doc["duration_s"]
    assert north == pytest.approx(0.5 * b * t**2, rel=2e-3)
    # Coriolis on the growing north velocity b t: east = 2 W sin(lat) b t^3 / 6
    assert east == pytest.approx(2 * 7.292115e-5 * np.sin(np.radians(45)) * b * t**3 / 6,
                                 rel=0.02)
    assert abs(up) < 1e-3 * north


def test_gyro_bias_tilt_gives_g_eps_t_cubed_over_6(static_flight):
    """A y-gyro bias e tilts the platform about east at e t; the north error is then
    -g e t^3 / 6 (first term of the Schuler response)."""
    path, unit = static_flight
    eps = np.radians(10.0 / 3600)
    cal = Calibration.from_dict(unit.coefficients.as_dict())
    cal.W0 = cal.W0 + np.array([0.0, eps, 0.0])
    doc = normalised_table(Flight.load(path), {"biased": cal})
    north = doc["variants"]["biased"]["enu_m"][1]
    g = 9.8066
    assert north == pytest.approx(-g * eps * doc["duration_s"] ** 3 / 6, rel=1e-2)


def test_error_budget_prices_each_group_on_this_flight(static_flight):
    """Parked after a cold power-on: the warm-up drift makes temperature worth metres; the
    unit has no g-sensitivity, so that group is worth exactly nothing."""
    path, unit = static_flight
    budget = error_budget(Flight.load(path), unit.coefficients)
    rows = budget["variants"]
    assert rows["full"]["norm_m"] < 1e-3
    assert rows["without temperature"]["worth_m"] > 0.1
    assert rows["without g-sensitivity"]["worth_m"] == 0.0
    assert rows["without cross-coupling"]["worth_m"] > 0.1


def test_bad_inputs_are_refused_and_leave_nothing(static_flight, tmp_path, capsys):
    path, unit = static_flight
    cal_path = tmp_path / "cal.json"
    unit.coefficients.save(cal_path)
    # a log without the FOG channel
    no_fog = tmp_path / "nofog.mcap"
    with FlightLog(path) as log, LogWriter(no_fog) as out:
        for name, values in log.metadata().items():
            out.metadata(name, values)
        raw = log.read("/mimu/raw")
        from mimunav.flightlog import schemas as S
        out.write("/mimu/raw", S.RAW_MIMU, "mimu", raw["log_time"].astype(np.int64),
                  **{k: raw[k] for k, _, _ in S.BODIES[S.RAW_MIMU]})
    with pytest.raises(LogError, match="/fog/imu"):
        Flight.load(no_fog)
    assert main(["replay", str(no_fog), "--cal", str(cal_path), "-o", str(tmp_path / "o")]) == 2
    assert "no /fog/imu channel" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tmp")]
    # a calibration for another model
    other = tmp_path / "other.json"
    other.write_text(json.dumps(dict(unit.coefficients.as_dict(), model="rotation-s4")))
    with pytest.raises(CalibrationError, match="rotation-s4"):
        Calibration.load(other)
    # an end point after the flight
    flight = Flight.load(path)
    with pytest.raises(ValueError, match="after the end of the recorded flight"):
        normalised_table(flight, {"x": unit.coefficients}, end=T_HOLD + 5)
    assert main(["table", path, "--cal", f"x={cal_path}", "--end", "1000",
                 "-o", str(tmp_path / "tab")]) == 2
    assert not list(tmp_path.glob("tab*"))


def test_without_truth_the_table_says_so_and_gives_mimu_minus_fog(static_flight):
    path, unit = static_flight
    b = 1e-3 * 9.80665
    cal = Calibration.from_dict(unit.coefficients.as_dict())
    cal.A0 = cal.A0 + np.array([b, 0.0, 0.0])
    flight = Flight.load(path)
    with_truth = normalised_table(flight, {"biased": cal})
    flight.truth = None
    doc = normalised_table(flight, {"biased": cal})
    assert doc["reference"] == "fog" and "fog" not in doc
    assert "normalised_enu" not in doc["variants"]["biased"]
    expect = np.subtract(with_truth["variants"]["biased"]["enu_m"], with_truth["fog"]["enu_m"])
    np.testing.assert_allclose(doc["variants"]["biased"]["enu_m"], expect, atol=1e-4)
    assert "No `/truth/state`" in table_markdown(doc)


def test_mounting_and_lever_arm_are_applied_under_rotation(tmp_path, monkeypatch):
    """A perfect MIMU mounted turned (30, 10, -20 deg) and 0.33 m from the vehicle origin,
    through a 2 g pull and a 200 deg/s roll: after the mounting is undone the replayed
    vehicle trajectory matches the truth to the navigator's own accuracy (ignoring the lever
    arm would leave the 0.33 m offset and metres per second of velocity in the roll)."""
    from mimunav.frames import attitude
    from mimunav.frames.mounting import Mounting
    from motions import pull_roll
    prof = pull_roll(200.0, 3.0)
    unit = perfect_unit()
    q_vs = attitude.from_euler(np.radians(30), np.radians(10), np.radians(-20))
    unit.mounting = Mounting(np.asarray(q_vs.components), [0.30, -0.10, 0.05])
    path = tmp_path / "pull-roll.mcap"
    simulate_flight(prof, path, seed=3, unit=unit, progress=False)
    flight = Flight.load(path)
    err = errors_at(replay(flight, unit.coefficients),
                            comparison_times(flight))["mimu-truth"]
    assert np.abs(err["position"]).max() < 5e-3
    assert np.abs(err["velocity"]).max() < 5e-3
    assert np.abs(err["attitude"]).max() < 1e-6
    # streamed in blocks of 777 samples (and margins), sampled at the comparison times only:
    # the same solution - the navigator's memory and the lever arm's look-ahead carried
    from mimunav.evaluation import flight as flight_module
    monkeypatch.setattr(flight_module, "STREAM_BLOCK", 777)
    monkeypatch.setattr(flight_module, "STREAM_ABOVE", 777)
    streamed = Flight.load(path, stream=True)
    assert streamed.stream_block == 777 and streamed.fog_w is None and streamed.mimu_raw is None
    t = comparison_times(flight)
    whole = errors_at(replay(flight, unit.coefficients), t)
    blocks = errors_at(replay(streamed, unit.coefficients, at=t), t)
    for pair in ("mimu-truth", "fog-truth"):
        for quantity in ("position", "velocity", "attitude"):
            np.testing.assert_allclose(blocks[pair][quantity], whole[pair][quantity],
                                       rtol=0, atol=1e-9)
    w, f, _ = compensated_mimu(flight, unit.coefficients)
    nav = VehicleNavigator(flight.mimu_mounting, flight.initial)
    edges = np.unique(np.r_[0, np.random.default_rng(1).integers(0, len(w), 40), len(w)])
    parts = [nav.feed(flight.mimu_t[a:b], w[a:b], f[a:b]) for a, b in zip(edges, edges[1:])]
    fed = Trajectory.concatenate([p for p in parts if p is not None] + [nav.finish()])
    one = navigate(flight.mimu_t, w, f, flight.mimu_mounting, flight.initial)
    for name in ("t", "lat", "lon", "h", "v_ned"):
        assert np.array_equal(getattr(fed, name), getattr(one, name)), name
    table = normalised_table(streamed, {"unit": unit.coefficients})
    assert table == normalised_table(flight, {"unit": unit.coefficients})


def test_sampling_at_times_within_a_nanosecond_of_the_last_state():
    """Without a truth channel the comparison grid's last time can be one ulp past the last
    state (np.arange): it is taken, as `resample` takes it, and never twice."""
    from mimunav.motion.trajectory import Trajectory
    import quaternion
    t = np.linspace(0.0, 15.03, 1504)
    traj = Trajectory(t, t * 0 + 0.5, t * 0, t, np.zeros((len(t), 3)),
                      quaternion.from_rotation_vector(np.zeros((len(t), 3))))
    at = np.append(np.arange(0.0, 15.0, 0.01), 15.03 + 1e-12)
    keep = Sampler(at)
    for a, b in ((0, 700), (700, 701), (701, len(t))):
        keep.add(traj[a:b])
    out = keep.trajectory()
    np.testing.assert_allclose(out.h, np.minimum(at, 15.03), atol=1e-9)
    with pytest.raises(InputError, match="outside the navigated"):
        Sampler(np.array([20.0])).trajectory()


def test_resampling_goes_the_short_way_across_the_antimeridian_and_between_q_and_minus_q():
    """A reference written with longitude in (-pi, pi] and attitudes kept at w >= 0 (both the
    same positions and rotations as continuous ones) resamples to the same states: between
    two samples astride the antimeridian the point lies between them, not half a world away,
    and between q and the next sample written as -q the attitude turns the small angle."""
    from mimunav.frames import attitude, earth
    from mimunav.motion.trajectory import Trajectory
    import quaternion
    t = np.arange(0.0, 10.0, 1.0)
    lon = np.pi - 0.003 + 0.001 * t                           # crosses +pi at t = 3
    yaw = np.pi - 0.3 + 0.1 * t                               # crosses 180 deg: w changes sign
    q = quaternion.from_rotation_vector(np.column_stack([0 * t, 0 * t, yaw]))
    smooth = Trajectory(t, 0.5 + 1e-5 * t, lon, 100 + t, np.ones((len(t), 3)), q)
    written = Trajectory(t, smooth.lat, np.remainder(lon + np.pi, 2 * np.pi) - np.pi,
                         smooth.h, smooth.v_ned, q * np.sign(quaternion.as_float_array(q)[:, 0]))
    assert np.ptp(written.lon) > 6 and (quaternion.as_float_array(written.q_nb)[:, 0] >= 0).all()
    at = np.arange(0.0, 9.0, 0.25) + 0.125
    a, b = resample(smooth, at), resample(written, at)
    gap = earth.ned_difference(b.lat, b.lon, b.h, a.lat, a.lon, a.h)
    assert np.abs(gap).max() < 1e-6                                       # m
    assert np.abs(b.attitude_error(a)).max() < 1e-12                      # rad
    yaw_at = quaternion.from_rotation_vector(np.column_stack([0 * at, 0 * at,
                                                            np.pi - 0.3 + 0.1 * at]))
    assert np.abs(attitude.rotation_vector_error(b.q_nb, yaw_at)).max() < 1e-12  # the turn
    assert np.abs(attitude.rotation_vector_error(yaw_at, -yaw_at)).max() == 0.0  # q vs -q
    # the alignment's interpolation of a track: continuous across, a NaN stays its own
    from mimunav.navigation.alignment import unwrapped_longitude
    lon_u = unwrapped_longitude(np.r_[written.lon[:2], np.nan, written.lon[2:]])
    assert np.isnan(lon_u[2]) and np.isnan(lon_u).sum() == 1
    np.testing.assert_allclose(np.delete(lon_u, 2), lon, rtol=0, atol=1e-12)


def test_a_recordings_reference_imu_is_levelled_on_its_own_specific_force():
    """An imported recording whose shared start was levelled on the MIMU's specific force
    (its 2 mg horizontal biases: 0.13 deg of tilt) over a 30 s rest: the reference IMU, level
    and still for 60 s, is navigated from its own levelling over that rest and stays within
    a metre, its heading the shared one. Navigated from the MIMU's tilt it would run
    0.5 g sin(0.13 deg) t^2 = 40 m away; a simulated flight keeps its (true) start."""
    from dataclasses import replace
    from mimunav.evaluation.replay import navigate_fog, reference_initial
    from mimunav.frames import attitude, earth
    from mimunav.frames.mounting import Mounting
    from mimunav.motion.trajectory import State
    lat, h, rate = np.radians(47.0), 300.0, 100.0
    t = np.arange(0.0, 60.0, 1.0 / rate) + 1.0 / rate
    true = attitude.from_euler(np.radians(30.0), 0.0, 0.0)     # level, heading 30 deg
    f = np.tile(-earth.gravity_ned(lat, h), (len(t), 1))
    w = np.tile(attitude.rotate(np.conjugate(true), earth.earth_rate_ned(lat)), (len(t), 1))
    tilted = attitude.from_euler(np.radians(30.0), np.radians(0.13), 0.0)
    flight = Flight("rec.mcap", "rec", 0, State(0.0, lat, 0.1, h, np.zeros(3), tilted),
                    t, None, Mounting(), {}, t, w, f, Mounting(), None,
                    source="recording", recording={"initial_attitude": "leveled",
                                                   "static_s": [0.0, 30.0]})
    start = reference_initial(flight)
    yaw, pitch, roll = attitude.as_euler(start.q_nb)
    assert np.degrees(yaw) == pytest.approx(30.0, abs=1e-9)
    assert abs(pitch) < 1e-9 and abs(roll) < 1e-9
    end = navigate_fog(flight)
    drift = earth.ned_difference(end.lat[-1], end.lon[-1], end.h[-1], lat, 0.1, h)
    assert np.linalg.norm(drift) < 1.0, drift
    assert reference_initial(replace(flight, source="simulation")) is flight.initial

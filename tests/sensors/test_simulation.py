"""`mimunav simulate` and `mimunav info`: a simulated log follows the contract and holds
what the sensor models produced, with the unit's truth kept outside the log."""
import json
import math

import numpy as np
import pytest

from mimunav.motion import truth
from mimunav.cli import main
from mimunav.compensation.calibration_file import Calibration
from mimunav.compensation.model import compensate
from mimunav.flightlog import FlightLog
from mimunav.motion.profile import Profile, dumps
from mimunav.frames.mounting import Mounting
from mimunav.sensors.simulation import MIMU_MOUNTING, epoch_ns

PROFILE = {"name": "short", "description": "a short test flight",
           "start": {"latitude_deg": 30, "longitude_deg": 20, "height_m": 500,
                     "speed_m_s": 150, "heading_deg": 45},
           "segment": [{"kind": "coast", "duration_s": 2},
                       {"kind": "roll", "rate_deg_s": 200, "angle_deg": 180, "ramp_s": 0.2},
                       {"kind": "turn", "load_factor": 4, "heading_change_deg": 40,
                        "roll_rate_deg_s": 100, "ramp_s": 0.2}]}


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sim")
    prof = folder / "short.toml"
    prof.write_text(dumps(PROFILE))
    log = folder / "short.mcap"
    assert main(["simulate", str(prof), "-o", str(log), "--seed", "5"]) == 0
    return prof, log, folder / "short.truth.json"




def test_log_follows_the_contract_and_keeps_the_truth_outside(simulated):
    _, log_path, truth_path = simulated
    with FlightLog(log_path) as log:
        meta = log.metadata()
        assert set(log.channels) == {"/mimu/raw", "/fog/imu", "/truth/state"}
        flight = meta["flight"]
        assert flight["format"] == "mimunav-log/1" and flight["source"] == "simulation"
        assert flight["initial_state"]["t"] == 0.0
        epoch = int(flight["epoch_unix_ns"])
        for topic in ("/mimu/raw", "/fog/imu"):
            t = log.read(topic)["log_time"].astype(np.int64)
            assert t[0] == epoch                       # a sample on the initial state's time
            assert np.all(np.diff(t) == 1_000_000)
        assert meta["sensor/mimu"]["mounting"] == MIMU_MOUNTING
        text = json.dumps(meta)
    unit = json.loads(truth_path.read_text())["mimu"]
    # no coefficient of the unit appears anywhere in the log's metadata
    for value in np.ravel(unit["coefficients"]["gyro"]["C"]):
        assert repr(value) not in text and f"{value:.6g}" not in text


def test_logged_channels_hold_the_simulated_physics(simulated):
    prof_path, log_path, truth_path = simulated
    doc = json.loads(truth_path.read_text())
    cal = Calibration.from_dict(doc["mimu"]["coefficients"])
    prof = Profile.load(prof_path)
    with FlightLog(log_path) as log:
        raw = log.read("/mimu/raw")
        fog = log.read("/fog/imu")
        state = log.read("/truth/state")
        epoch = int(log.metadata()["flight"]["epoch_unix_ns"])
    t = (raw["log_time"].astype(np.int64) - epoch) / 1e9
    run = truth.generate(prof.motion(), t)
    # /truth/state is the trajectory, sampled at 100 Hz
    ts = (state["log_time"].astype(np.int64) - epoch) / 1e9
    k = np.searchsorted(t, ts)
    np.testing.assert_allclose(state["latitude"], run.trajectory.lat[k], rtol=0, atol=1e-12)
    np.testing.assert_allclose(state["velocity_ned"], run.trajectory.v_ned[k], atol=1e-9)
    # the MIMU, compensated with its true coefficients, reads the motion at its lever arm
    f, w, flags = compensate(cal, raw["accel_volts"], raw["gyro_volts"],
                             raw["accel_temperature"], raw["gyro_frequency"])
    _, dv = Mounting.from_dict(MIMU_MOUNTING).sensor_increments(run)
    err = f[1:] - dv * 1000
    nz = doc["mimu"]["noise"]
    white = nz["accel_white"] * math.sqrt(1000)
    assert not flags.any()
    np.testing.assert_allclose(err.std(axis=0), white, rtol=0.1)
    assert np.all(np.abs(err.mean(axis=0)) < 5 * nz["accel_turn_on"] + 3 * nz["accel_flicker"])
    # the FOG reads the vehicle origin's motion within its grade
    fog_err = fog["angular_velocity"][1:] - run.dtheta * 1000
    assert np.all(np.abs(fog_err.mean(axis=0)) < math.radians(5 / 3600) + 1e-4)


def test_info_reports_channels_and_refuses_nothing_silently(simulated, capsys, tmp_path):
    _, log_path, _ = simulated
    assert main(["info", str(log_path)]) == 0
    out = capsys.readouterr().out
    assert "/mimu/raw" in out and "1000.000 Hz" in out and "no gaps" in out
    assert main(["simulate", str(simulated[0]), "-o", str(log_path)]) == 2
    assert "exists; use --force" in capsys.readouterr().err
    assert main(["info", str(tmp_path / "missing.mcap")]) == 2


def test_epoch_is_absolute_utc():
    assert epoch_ns("2026-01-01T00:00:00Z") == 1_767_225_600 * 10**9


def test_compensate_writes_mimu_imu_and_copies_everything_else(simulated, tmp_path, capsys):
    _, log_path, truth_path = simulated
    cal_path = tmp_path / "true.cal.json"
    cal_path.write_text(json.dumps(json.loads(truth_path.read_text())["mimu"]["coefficients"]))
    out = tmp_path / "comp.mcap"
    assert main(["compensate", str(log_path), "--cal", str(cal_path), "-o", str(out)]) == 0
    assert "replaced (wild values) 0" in capsys.readouterr().out
    cal = Calibration.load(cal_path)
    with FlightLog(log_path) as a, FlightLog(out) as b:
        assert b.metadata() == a.metadata()
        for topic in a.channels:
            x, y = a.read(topic), b.read(topic)
            assert all(np.array_equal(x[n], y[n]) for n in x.dtype.names), topic
        raw, imu = a.read("/mimu/raw"), b.read("/mimu/imu")
    f, w, _ = compensate(cal, raw["accel_volts"], raw["gyro_volts"], raw["accel_temperature"],
                         raw["gyro_frequency"])
    assert np.array_equal(imu["linear_acceleration"], f)
    assert np.array_equal(imu["angular_velocity"], w)
    assert np.array_equal(imu["log_time"], raw["log_time"])
    assert np.all(imu["orientation_covariance"][:, 0] == -1)
    assert main(["compensate", str(log_path), "--cal", str(cal_path), "-o", str(out)]) == 2
    assert main(["compensate", str(out), "--cal", str(cal_path), "-o",
                 str(tmp_path / "again.mcap")]) == 2
    assert "already has /mimu/imu" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "mimunav-calibration/1", "model": "nope"}')
    assert main(["compensate", str(log_path), "--cal", str(bad), "-o",
                 str(tmp_path / "x.mcap")]) == 2
    assert "model 'nope'" in capsys.readouterr().err
    assert not (tmp_path / "x.mcap").exists() and not (tmp_path / "again.mcap").exists()


def test_a_flight_made_in_blocks_equals_the_flight_made_whole(tmp_path, monkeypatch):
    """`simulate_flight` makes the flight 2 s at a time (bounded memory); the same seed made
    whole in memory (`flight_motion` + `record_flight`, what campaigns use) gives the same log:
    every random error has its own generator and the flicker noise is shaped over the whole
    record, the thermal lags carry their state, and hidden effects that look back (a 5 ms
    lag), ahead (a 5 ms lead) or both (thermal hysteresis, 5 s either side) see across the
    block edges."""
    from mimunav.sensors import simulation
    from mimunav.sensors.hidden import HiddenPhysics, HiddenSet, parse_term
    monkeypatch.setattr(simulation, "BLOCK_S", 2)
    prof = Profile.from_dict(PROFILE)
    unit, fog, rng_mimu, rng_fog = simulation.flight_units(9)
    hidden = HiddenSet([HiddenPhysics(parse_term(text), unit.thermal) for text in
                        ("time_skew:accel:all=5e-3", "time_skew:gyro:all=-5e-3",
                         "thermal_hysteresis:gyro:x=1e-4")])
    simulation.simulate_flight(prof, tmp_path / "blocks.mcap", 9, progress=False,
                               hidden=hidden, warm_up_s=20.0)
    fm = simulation.flight_motion(prof, unit.mounting, unit.rate_hz, fog.mounting,
                                  fog.rate_hz, 100.0)
    raw, fog_out = simulation.record_flight(fm, unit, fog, rng_mimu, rng_fog, hidden, 20.0)
    with FlightLog(tmp_path / "blocks.mcap") as log:
        mimu, ref, state = log.read("/mimu/raw"), log.read("/fog/imu"), log.read("/truth/state")
    for name in ("accel_volts", "gyro_volts", "sample_index"):
        assert np.array_equal(mimu[name], raw[name]), name
    for name, tol in (("accel_temperature", 1e-12), ("gyro_frequency", 1e-9)):
        np.testing.assert_allclose(mimu[name], raw[name], rtol=0, atol=tol)
    assert np.array_equal(ref["angular_velocity"], fog_out["angular_velocity"])
    assert np.array_equal(ref["linear_acceleration"], fog_out["linear_acceleration"])
    k = fm.k_truth
    np.testing.assert_allclose(state["height"], fm.run.trajectory.h[k], rtol=0, atol=1e-8)
    np.testing.assert_allclose(state["latitude"], fm.run.trajectory.lat[k], rtol=0, atol=1e-14)
    assert len(mimu) == len(raw["t"]) and len(state) == len(k)


def test_block_edges_of_other_rates_and_of_hidden_physics_that_says_nothing(tmp_path):
    """Found by a review of the block-wise simulation: a flight whose last block would be
    shorter than a 400 Hz FOG interval (60.002 s), and hidden physics given as a bare callable
    (it cannot say how far it looks: the record is made in one block), both simulate; a
    unit whose own physics needs the whole record is made in one block."""
    from mimunav.sensors import simulation
    from mimunav.sensors.mimu import MimuUnit
    from mimunav.sensors.mimu import MimuRecorder
    prof = Profile.from_dict({"name": "hold", "start": PROFILE["start"] | {"speed_m_s": 0},
                              "segment": [{"kind": "hold", "duration_s": 60.002}]})
    log, _ = simulation.simulate_flight(prof, tmp_path / "h.mcap", 1, fog_rate=400.0,
                                        progress=False)
    with FlightLog(log) as lg:
        assert lg.count("/fog/imu") == 24001 and lg.count("/mimu/raw") == 60003
    unit = MimuUnit.draw(3)
    t = np.arange(1, 201) / 1000.0
    raw = unit.simulate(t, np.zeros((200, 3)), np.tile([0, 0, -9.8e-3], (200, 1)),
                        np.full(200, 20.0), np.random.default_rng(0),
                        hidden=lambda f, w, ctx: (f, w + 1e-3))
    assert len(raw["gyro_volts"]) == 200
    assert MimuRecorder.needs_whole_record(unit, lambda f, w, ctx: (f, w))
    assert not MimuRecorder.needs_whole_record(unit, None)
    unit.beyond_model = unit.beyond_model + [{"effect": "temperature_scale", "sensor": "accel",
                                              "axis": "x", "coefficient": 1e-5}]
    assert MimuRecorder.needs_whole_record(unit, None)


def test_a_default_units_own_physics_sees_across_block_edges():
    """A default unit's own physics beyond the model (seed S3's dT term looks back 60 s)
    with no hidden effect given: the record made in 60 s blocks equals the record made whole
    (a review found the look-back taken from the given effects only)."""
    from dataclasses import replace
    from mimunav.sensors.mimu import MimuUnit
    from mimunav.sensors.mimu import MimuRecorder
    unit = replace(MimuUnit.draw(3), rate_hz=100.0)
    n = 15000
    t, env = np.arange(1, n + 1) / 100.0, np.linspace(15.0, 5.0, n)       # the bay cools
    dtheta, dv = np.tile([1e-4, 0, 0], (n, 1)), np.tile([0, 0, -0.098], (n, 1))
    whole = unit.simulate(t, dtheta, dv, env, np.random.default_rng(2))
    rec = MimuRecorder(unit, n, np.random.default_rng(2))
    cuts = [0, 6000, 12000, n]
    parts = [rec.record(t[a:b], dtheta[a:b], dv[a:b], env[a:b]) for a, b in zip(cuts, cuts[1:])]
    parts.append(rec.finish())
    for name in ("accel_volts", "gyro_volts"):
        assert np.array_equal(np.concatenate([p[name] for p in parts]), whole[name]), name

"""`mimunav cut`: a log cut to a span, so that a message that tells the user to cut names a
command that does it. The cut keeps every channel's messages inside the span, the metadata,
and an initial state inside it (the reference's there), and the cut log navigates."""
import numpy as np
import pytest

from mimunav.cli import main
from mimunav.evaluation.flight import Flight
from mimunav.evaluation.replay import comparison_times, errors_at, replay
from mimunav.flightlog import FlightLog
from mimunav.motion.profile import Profile
from mimunav.sensors.mimu import MimuUnit
from mimunav.sensors.simulation import simulate_flight
from places import FLIGHTS


@pytest.mark.slow
def test_a_cut_log_holds_the_span_and_navigates_from_the_reference_state(tmp_path):
    unit = MimuUnit.draw(3)
    path = tmp_path / "gentle.mcap"
    profile = Profile.load(FLIGHTS / "gentle.toml")
    profile.segments = profile.segments[:3]         # coast, climb, turn: 100-160 s inside
    simulate_flight(profile, path, seed=3, unit=unit, progress=False)
    out = tmp_path / "cut.mcap"
    assert main(["cut", str(path), "--span", "100:160", "-o", str(out)]) == 0
    with FlightLog(out) as log:
        meta = log.metadata()
        epoch = int(meta["flight"]["epoch_unix_ns"])
        for topic in ("/mimu/raw", "/fog/imu", "/truth/state"):
            t = (log.read(topic, fields=())["log_time"].astype(np.int64) - epoch) / 1e9
            assert 100.0 <= t[0] < 100.01 and 159.99 < t[-1] <= 160.0, topic
        assert meta["cut"]["span_s"] == [100.0, 160.0]
    flight = Flight.load(out)
    assert flight.initial.t == pytest.approx(100.0)
    whole = Flight.load(path)
    k = np.searchsorted(whole.truth.t, 100.0)
    assert flight.initial.lat == whole.truth.lat[k] and flight.initial.h == whole.truth.h[k]
    err = errors_at(replay(flight, unit.coefficients), comparison_times(flight))
    # 60 s of a Table 4 FOG-IMU from the reference state: metres (a wrong start: kilometres)
    assert np.abs(err["fog-truth"]["position"][-1]).max() < 10.0
    assert main(["cut", str(path), "--span", "100:160", "-o", str(out)]) == 2   # not over it


def test_a_span_without_a_start_is_refused(tmp_path):
    from mimunav.flightlog import LogWriter
    from mimunav.flightlog import schemas as S
    path = tmp_path / "bare.mcap"
    with LogWriter(path) as log:
        log.metadata("flight", {"epoch_unix_ns": "0", "initial_state": {"t": 0.0}})
        t = np.arange(1, 101) * 10_000_000
        log.write("/mimu/imu", S.IMU, "mimu", t, **S.imu_fields(np.zeros((100, 3)),
                                                                np.zeros((100, 3))))
    assert main(["cut", str(path), "--span", "0.5:0.9", "-o", str(tmp_path / "o.mcap")]) == 2
    assert not (tmp_path / "o.mcap").exists()


@pytest.mark.slow
def test_a_cut_recording_is_aligned_again_on_its_imports_biases(tmp_path):
    """The weaving synthetic drive's ideal IMU with a gyro bias of 0.5 deg/s on every axis,
    measured by the import at the drive's 20 s rest: a span cut in motion (no rest, no
    reference attitude) is aligned again on the outputs less that bias. The moving alignment
    turns the velocity increment by the gyro over 1.6 s: with the bias left in (the cut had
    said 'biases taken as 0' beside a recording whose biases were measured) its attitude was
    2.6e-4 deg off, with it out 2e-6 deg (small here: the increment's turn is what the bias
    moves, over 1.6 s; an accelerometer bias moves the level directly)."""
    from drives import MOUNT, straight_track
    from mimunav.frames import attitude
    from mimunav.importers.recording import Recording
    from mimunav.importers.write import write_log
    from mimunav.motion import truth
    from mimunav.motion.vehicle import TrackMotion
    from mimunav.navigation.alignment import initial_alignment
    t_tr, lat, lon, h, v = straight_track()
    run = truth.generate(TrackMotion(t_tr, lat, lon, h, v),
                         np.arange(t_tr[0], t_tr[-1] + 1e-9, 0.01))
    dth, dv = MOUNT.sensor_increments(run)
    bias = np.radians(0.5) * np.ones(3)
    epoch = 1_700_000_000_000_000_000
    ns = lambda t: epoch + np.round(t * 1e9).astype(np.int64)          # noqa: E731
    rec = Recording("biased", "", ns(run.trajectory.t[1:]), dth * 100.0 + bias, dv * 100.0,
                    MOUNT, reference=dict(ns=ns(t_tr), lat=lat, lon=lon, h=h, v_ned=v))
    log, out = tmp_path / "biased.mcap", tmp_path / "cut.mcap"
    write_log(rec, log)
    with FlightLog(log) as fl:
        meta = fl.metadata()
    measured = np.asarray(meta["recording"]["gyro_bias_static_rad_s"])
    np.testing.assert_allclose(measured, bias, atol=np.radians(0.01))
    t0 = (ns(60.0) - int(meta["flight"]["epoch_unix_ns"])) / 1e9
    assert main(["cut", str(log), "--span", f"{t0}:{t0 + 40}", "-o", str(out)]) == 0
    with FlightLog(out) as fl:
        cut = fl.metadata()
    assert "less the biases the import measured" in cut["cut"]["initial_state"]
    # the recording's account of its initial state is the span's (what diagnose judges by)
    assert cut["recording"]["assumed"]["initial_state"] == cut["cut"]["initial_state"]
    assert cut["recording"]["initial_heading"] == "course"
    assert meta["recording"]["assumed"]["initial_state"].startswith("level from the mean")
    assert cut["recording"]["assumed"]["import_initial_state"] == \
        meta["recording"]["assumed"]["initial_state"]       # whose biases the metadata keeps
    start = cut["flight"]["initial_state"]
    t_start = start["t"] + int(meta["flight"]["epoch_unix_ns"]) / 1e9 - epoch / 1e9
    k = int(np.argmin(np.abs(run.trajectory.t - t_start)))
    q_true = run.trajectory.q_nb[k]

    def off(q_wxyz):
        return np.degrees(np.linalg.norm(attitude.rotation_vector_error(
            attitude.from_wxyz(np.asarray(q_wxyz)), q_true)))
    # the same alignment on the outputs with the bias left in
    inside = (run.trajectory.t[1:] >= 60.0) & (run.trajectory.t[1:] <= 100.0)
    on_ref = (t_tr >= 60.0) & (t_tr <= 100.0)
    left_in = initial_alignment(run.trajectory.t[1:][inside], (dth * 100.0 + bias)[inside],
                                (dv * 100.0)[inside], MOUNT,
                                {"t": t_tr[on_ref], "lat": lat[on_ref], "lon": lon[on_ref],
                                 "h": h[on_ref], "v_ned": v[on_ref]})
    assert off(start["attitude_wxyz"]) < 0.5 * off(attitude.as_wxyz(
        attitude.from_wxyz(np.asarray(left_in.q_nb)))), (off(start["attitude_wxyz"]),)


def test_an_imu_recorded_alone_is_cut_anywhere_aligned_again_on_the_span(tmp_path):
    """An IMU imported alone (no reference trajectory: the import levels it on its mean
    specific force, position and heading assumed 0) cut from 10 s: aligned again on the
    span's IMU as the import did on the whole - a Shimmer's recording could be cut only from
    0 s ('no reference to start the span from')."""
    from mimunav.frames.mounting import Mounting
    from mimunav.importers.recording import Recording
    from mimunav.importers.write import write_log
    t = np.arange(1, 3001) * 0.01
    rng = np.random.default_rng(4)
    w = rng.normal(0, 1e-3, (len(t), 3)) + [0.0, 0.0, 0.3 * np.sin(0.5)]
    f = rng.normal(0, 1e-2, (len(t), 3)) + [0.0, 0.0, -9.80]
    epoch = 1_700_000_000_000_000_000
    log, out = tmp_path / "alone.mcap", tmp_path / "cut.mcap"
    write_log(Recording("alone", "", epoch + np.round(t * 1e9).astype(np.int64), w, f,
                        Mounting.from_axes("FRD")), log)
    assert main(["cut", str(log), "--span", "10:20", "-o", str(out)]) == 0
    with FlightLog(out) as fl:
        cut = fl.metadata()
    assert 10.0 <= cut["flight"]["initial_state"]["t"] <= 10.02
    assert cut["cut"]["initial_state"].startswith("the alignment redone on the span")

"""The ArduPilot DataFlash importer on a log written in ArduPilot's record layout from a
simulated flight (tests/dataflash_log.py) and parsed by pymavlink's DFReader: time base,
axes, units and references against the flight's truth, then through import -> windows."""
import json

import numpy as np
import pytest

from mimunav.frames import attitude
from mimunav.cli import main
from mimunav.importers.recording import RecordingError
from mimunav.importers import dataflash

import dataflash_log


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dataflash")
    data, run, t, unix_t0 = dataflash_log.flight()
    path = folder / "flight.bin"
    path.write_bytes(data)
    return path, run, t, unix_t0


@pytest.fixture(scope="module")
def text_log():
    """The fixture's flight as a ground station writes it: the text `.log` (bytes)."""
    return dataflash_log.flight(text=True)[0]


@pytest.mark.slow
def test_time_axes_units_and_the_autopilot_reference(log):
    path, run, t, unix_t0 = log
    rec = dataflash.read(str(path))
    # boot time from GPS week time (leap seconds removed): the first IMU sample's UNIX time
    assert abs(rec.imu_ns[0] - round((unix_t0 + t[1]) * 1e9)) < 1000        # < 1 us
    assert rec.sample_rate_hz == pytest.approx(400.0)
    # FRD body axes, rad/s and m/s^2: the recorded rate minus the truth is the fixture's
    # bias (1e-3, -2e-3, 5e-4) rad/s within the mean's noise (2e-3 / sqrt(26000))
    w_true = run.dtheta / np.diff(t)[:, None]
    np.testing.assert_allclose((rec.w - w_true).mean(axis=0), [1e-3, -2e-3, 5e-4], atol=5e-5)
    f_true = run.dv / np.diff(t)[:, None]
    np.testing.assert_allclose((rec.f - f_true).mean(axis=0), [0.02, -0.01, 0.03], atol=5e-4)
    assert rec.reference_meta["independent"].startswith("no")
    ref, tr = rec.reference, run.trajectory
    k = np.arange(0, len(t), 80)                      # the fixture's 5 Hz epochs
    np.testing.assert_allclose(ref["lat"], tr.lat[k], atol=np.radians(1.5e-7))
    np.testing.assert_allclose(ref["v_ned"], tr.v_ned[k], atol=1e-5)
    q = np.array([np.quaternion(*row) for row in ref["q_nb"]])
    err = attitude.rotation_vector_error(q, tr.q_nb[k])
    assert np.abs(err).max() < np.radians(0.02)       # ATT in 0.01 deg
    assert "INS_GYRO_FILTER 20 Hz, INS_ACCEL_FILTER 10 Hz" in rec.assumed["imu_values"]
    assert rec.real["imu_instances"] == "0, 1"


@pytest.mark.slow
@pytest.mark.parametrize("name", ["GPS_DELAY_MS", "GPS1_DELAY_MS"])
def test_a_declared_gps_lag_places_the_boot_clock(tmp_path, name):
    """GPS messages logged 65 ms after their epochs, the lag declared (its name before and
    from ArduPilot 4.5): the IMU's UNIX times are the truth's to 1 us (placed by the
    messages' logging times they had been 65 ms early, as a tractor's log was), and the
    fixes stay at their epochs."""
    data, run, t, unix_t0 = dataflash_log.flight(gps_lag_ms=65, lag_name=name)
    path = tmp_path / "lag.bin"
    path.write_bytes(data)
    rec = dataflash.read(str(path), reference="gnss", reference_status=6)
    assert abs(rec.imu_ns[0] - round((unix_t0 + t[1]) * 1e9)) < 1000
    assert abs(rec.fixes["ns"][0] - round(unix_t0 * 1e9)) < 1000
    assert f"{name} 65 ms" in rec.assumed["time"]


@pytest.mark.slow
def test_gnss_reference_keeps_the_fixes_status_and_accuracy(log):
    path, run, t, _ = log
    rec = dataflash.read(str(path), reference="gnss", reference_status=6)
    assert rec.reference_meta["independent"].startswith("yes")
    assert "q_nb" not in rec.reference
    assert set(rec.fixes["status"]) == {2}               # RTK fixed -> NavSatStatus GBAS_FIX
    np.testing.assert_allclose(np.sqrt(rec.fixes["covariance"][:, [0, 4]].sum(axis=1)), 0.02,
                               atol=1e-3)                 # GPA HAcc
    k = np.arange(0, len(t), 80)
    np.testing.assert_allclose(rec.reference["v_ned"], run.trajectory.v_ned[k], atol=0.01)


@pytest.mark.slow
def test_import_and_windows_through_the_cli(log, tmp_path, capsys):
    """Free-inertial 10 s windows restarted from each reference: with the autopilot's
    attitude at the rest, the horizontal bias |b_h| = 0.022 m/s^2 is
    measured against its level and removed - left in, it acted in full, 0.5 |b_h| T^2 =
    1.1 m. A course, VZ or time-base mistake gives tens of metres. Its progress bar is a
    terminal's: to a file (here captured) none is written (a captured log had held one
    line of hundreds of updates). The GNSS reference carries no attitude, and the flight
    banks into its turns and climbs - judged no car, its course is no heading (a wind's
    crab): its windows are refused, naming what they need."""
    path = log[0]
    out = tmp_path / "gnss.mcap"
    assert main(["import", "dataflash", str(path), "-o", str(out), "--reference", "gnss"]) == 0
    capsys.readouterr()
    assert main(["windows", str(out), "-o", str(tmp_path / "w-gnss")]) == 2
    assert "judge no car" in capsys.readouterr().err
    for kind, lo, hi in (("ekf", 0.0, 0.5),):
        out = tmp_path / f"{kind}.mcap"
        assert main(["import", "dataflash", str(path), "-o", str(out), "--reference", kind]) == 0
        capsys.readouterr()
        assert main(["windows", str(out), "-o", str(tmp_path / f"w-{kind}")]) == 0
        assert "window/s" not in capsys.readouterr().err
        doc = json.loads((tmp_path / f"w-{kind}" / "windows.json").read_text())
        row = doc["summary"]["10"]
        assert lo < row["horizontal_m"]["p50"] < hi, (kind, row)
        assert row["vertical_m"]["p95"] < 0.5, (kind, row)


@pytest.mark.slow
def test_a_log_cut_short_is_read_to_its_last_record_and_says_so(log, tmp_path):
    """The log cut at 60 % mid-record (power lost): DFReader stops silently before the
    partial record; the metadata says the file was cut short. The whole log says nothing.
    (The fixture writes its records type by type, so the cut loses the later types.)"""
    path = log[0]
    assert "file" not in dataflash.read(str(path)).real
    data = path.read_bytes()
    cut = tmp_path / "cut.bin"
    cut.write_bytes(data[:int(0.6 * len(data)) + 7])
    assert "was cut short" in dataflash.read(str(cut)).real["file"]


@pytest.mark.slow
def test_refusals_name_the_problem(log, tmp_path, capsys):
    path = log[0]
    assert main(["import", "dataflash", str(path), "-o", str(tmp_path / "x.mcap"),
                 "--imu-instance", "2"]) == 2
    assert "instances logged: [0, 1]" in capsys.readouterr().err
    foreign = tmp_path / "foreign.bin"
    foreign.write_bytes(b"not a dataflash log" * 100)
    with pytest.raises(RecordingError):
        dataflash.read(str(foreign))
    assert not (tmp_path / "x.mcap").exists()


def test_older_logs_number_their_instances_by_type(tmp_path):
    """ArduPilot before 4.1 logs IMU (no I field) and IMU2: the second instance is found
    by its type, and instance 0 is not mixed with it."""
    w = dataflash_log.Writer()
    fmt, cols = "QffffffIIf", "TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T"
    dataflash_log.FORMATS["IMU_OLD"] = (20, fmt, cols)
    dataflash_log.FORMATS["IMU2"] = (21, fmt, cols)
    try:
        w.parts = [w._fmt(128, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns"),
                   w._fmt(20, "IMU", fmt, cols), w._fmt(21, "IMU2", fmt, cols)]
        for k in range(200):
            w.add("IMU_OLD", TimeUS=1000 + 2500 * k, GyrX=0.01, AccZ=-9.8)
            w.add("IMU2", TimeUS=1000 + 2500 * k, GyrX=0.02, AccZ=-9.81)
    finally:
        del dataflash_log.FORMATS["IMU_OLD"], dataflash_log.FORMATS["IMU2"]
    path = tmp_path / "old.bin"
    path.write_bytes(w.bytes())
    for instance, gyro in ((0, 0.01), (1, 0.02)):
        rec = dataflash.read(str(path), instance=instance, reference="none")
        assert len(rec.imu_ns) == 200
        np.testing.assert_allclose(rec.w[:, 0], gyro, rtol=1e-6)


def test_import_never_writes_over_its_input(log, tmp_path, capsys):
    """`import ... -o SOURCE --force` (or a file of a source folder) is refused and the
    source is left as it was."""
    copy = tmp_path / "flight.bin"
    copy.write_bytes(log[0].read_bytes())
    before = copy.read_bytes()
    assert main(["import", "dataflash", str(copy), "-o", str(copy), "--force"]) == 2
    assert "would replace the input" in capsys.readouterr().err
    assert main(["import", "rtklib", str(tmp_path), "-o", str(copy), "--force"]) == 2
    assert copy.read_bytes() == before


def test_a_2014_log_stamped_in_ms_with_its_old_gps_message(tmp_path):
    """ArduCopter 3.x logs (2014) stamp TimeMS, log IMU2 as its own type and a GPS message of
    TimeMS (time of week), Week and T (boot ms): read with the time base from the GPS week
    time, both IMUs found, the fixes as the reference (no EKF position in that release).
    These had ended in `KeyError: 'TimeUS'`."""
    data, run, t, unix_t0 = dataflash_log.flight_2014()
    path = tmp_path / "2014.bin"
    path.write_bytes(data)
    rec = dataflash.read(str(path))
    stamps = (rec.imu_ns - int(round(unix_t0 * 1e9))) / 1e9
    np.testing.assert_allclose(stamps, t[1:], atol=2e-3)            # ms stamps
    np.testing.assert_allclose(rec.w, run.dtheta / np.diff(t)[:, None], atol=1e-5)
    assert "GPS fixes" in rec.reference_meta["source"]
    assert rec.real["imu_instances"] == "0, 1"
    second = dataflash.read(str(path), instance=1, reference="none")
    np.testing.assert_allclose(second.w[:, 0] - rec.w[:, 0], 1e-3, atol=1e-6)


@pytest.mark.slow
def test_a_text_log_reads_as_its_binary_and_damage_is_counted_not_printed(log, text_log,
                                                                         tmp_path, capsys):
    """The text form of the same flight (`.log`, as a ground station writes it: values to 7
    digits) gives the binary's recording; bytes pymavlink cannot read in a binary log are
    said once in the metadata, not printed byte by byte."""
    path = log[0]
    binary = dataflash.read(str(path))
    text_path = tmp_path / "flight.log"
    text_path.write_bytes(text_log)
    text = dataflash.read(str(text_path))
    assert np.array_equal(text.imu_ns, binary.imu_ns)
    np.testing.assert_allclose(text.w, binary.w, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(text.f, binary.f, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(text.fixes["lat"], binary.fixes["lat"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(text.reference["v_ned"], binary.reference["v_ned"], rtol=1e-6,
                               atol=1e-6)
    raw = path.read_bytes()
    junk = tmp_path / "junk.bin"
    junk.write_bytes(raw[:len(raw) // 2] + b"\x00" * 300 + raw[len(raw) // 2:])
    capsys.readouterr()
    damaged = dataflash.read(str(junk))
    said = capsys.readouterr()
    assert "bad header" not in said.out + said.err and "Skipped" not in said.out + said.err
    assert "skipped unreadable bytes" in damaged.real["file"]
    assert len(damaged.imu_ns) >= len(binary.imu_ns) - 2


@pytest.mark.slow
def test_an_older_ekfs_velocity_message_is_the_reference_too(text_log, tmp_path):
    """ArduPilot up to 4.0 logs EKF2's velocity as NKF1 (3.x: EKF1), in XKF1's layout: the
    same reference, named (an older log's had been left for the GPS fixes without a word)."""
    (tmp_path / "new.log").write_bytes(text_log)
    (tmp_path / "old.log").write_bytes(text_log.replace(b"XKF1", b"NKF1"))
    new, old = (dataflash.read(str(tmp_path / name)) for name in ("new.log", "old.log"))
    np.testing.assert_allclose(old.reference["v_ned"], new.reference["v_ned"])
    assert "velocity from EKF2's NKF1 core 0" in old.reference_meta["source"]


def test_a_second_imu_instance_is_the_reference_imu_of_mems_grade(log, tmp_path):
    """--reference-imu-instance 1: instance 1 is the reference IMU (its own samples, the
    body frame, the log's clock - the two IMUs' clocks measured equal), stated of MEMS
    grade (an autopilot's part: `AUTOPILOT_MEMS`, not the FOG defaults, so what the two
    disagree on is not charged to the IMU alone); its own instance is refused as one."""
    from mimunav.flightlog import FlightLog
    from mimunav.sensors.accuracy import AUTOPILOT_MEMS, accuracy_of
    path, run, t, _ = log
    rec = dataflash.read(str(path), reference_instance=1)
    ref = rec.reference_imu
    assert np.array_equal(ref["ns"], rec.imu_ns) and not np.allclose(ref["w"], rec.w)
    np.testing.assert_allclose(ref["w"].mean(axis=0), rec.w.mean(axis=0), atol=5e-4)
    assert "IMU instance 1" in rec.real["reference_imu"]
    # where the log's parameters put each IMU (INS_POSn_*, absent: the origin)
    np.testing.assert_allclose(ref["mounting"].lever_arm_m, [0.001, 0.0, 0.0], rtol=1e-6)  # f32
    np.testing.assert_array_equal(rec.mounting.lever_arm_m, [0.0, 0.0, 0.0])
    assert "at INS_POS2 [0.001, 0, 0] m" in rec.assumed["reference_imu_mounting"]
    out = tmp_path / "pair.mcap"
    assert main(["import", "dataflash", str(path), "--reference-imu-instance", "1",
                 "-o", str(out)]) == 0
    with FlightLog(out) as fl:
        meta = fl.metadata()
        assert len(fl.read("/fog/imu")["log_time"]) == len(ref["ns"])
    assert "refined to" in meta["recording"]["real"]["reference_imu_clock"]
    accuracy = accuracy_of(meta["sensor/fog"])
    assert accuracy.mems_grade and accuracy.gyro_scale == AUTOPILOT_MEMS["gyro_scale"]
    with pytest.raises(RecordingError, match="the IMU's own"):
        dataflash.read(str(path), instance=1, reference_instance=1)


@pytest.mark.slow
def test_clips_counted_and_either_imus_gaps_are_left_out_of_the_diagnosis(tmp_path, capsys):
    """IMU 0's accelerometer at its range inside the logged values for 0.1 s (AccZ short by
    3 m/s^2, neither flat nor at a range: no test on the outputs finds it), and its VIBE clip
    count up by 18 at the next record; IMU 1 (the reference) silent 30-40 s, IMU 0 45-46 s.
    The import says the clips; the diagnosis against IMU 1 leaves out the clipped span and
    the samples beside each gap, and finds no unexplained residual. Before, the clip was an
    accel.z excursion of 0.14 m/s^2 over its 2 s window, a reference silent for 60 s had
    been bridged (excursions of z 1400 in it) and a gap in the MIMU refused the sensor level,
    which navigates nothing across it."""
    data = dataflash_log.flight(rate=100.0, clip=(20.0, 20.1, -3.0),
                                lost=[(1, 30.0, 40.0), (0, 45.0, 46.0)])[0]
    path, out = tmp_path / "clipped.bin", tmp_path / "clipped.mcap"
    path.write_bytes(data)
    assert main(["import", "dataflash", str(path), "--reference-imu-instance", "1",
                 "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert ("clipped: 18 samples counted clipped by the autopilot (VIBE.Clip of IMU 0 or 1) "
            "in 1 span(s)") in said
    assert main(["diagnose", str(out), "--json", str(tmp_path / "d.json")]) in (0, 1)
    doc = json.loads((tmp_path / "d.json").read_text())
    first = 0.01                                    # t = 0 is the first stamp, at 10 ms
    (span,) = doc["clips_counted_left_out"]
    assert span["t0"] <= 20.0 - first + 1e-6 and 20.1 - first <= span["t1"] <= 20.25, span
    gaps = [(g["t0"] + first, g["t1"] + first) for g in doc["gaps_left_out"]]
    assert [(round(a, 1), round(b, 1)) for a, b in gaps] == [(29.9, 40.1), (44.9, 46.1)], gaps
    assert doc["unexplained"] == [], doc["unexplained"]
    printed = capsys.readouterr().out
    assert "where the IMU's own clip counter rose" in printed
    assert "where an IMU misses samples" in printed

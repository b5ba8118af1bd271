"""Recordings nobody here wrote (../shared/data): comma2k19 (phone IMU, fused pose, by the
table importer) and two PX4 ULogs (autopilot estimate as reference), through import -> info
-> windows -> diagnose. The checks are facts of the data's own documentation (dates, rates,
the README's measured heading offset, PX4's logged temperatures), not our outputs."""
import datetime
import json
import math
import re

import numpy as np
import pytest
import quaternion

from mimunav.frames import attitude, earth
from mimunav.cli import main
from mimunav.evaluation.flight import Flight
from mimunav.flightlog import FlightLog
from mimunav.importers.recording import RecordingError, gps_to_unix_s
from mimunav.importers.checks import check_recording
from mimunav.importers import table, ulog
from mimunav.importers.write import write_log
from places import DATA, SHARED

SHARED = SHARED
COMMA_SPEC = DATA / "comma2k19.toml"
ONSPEED_SPEC = DATA / "onspeed-vn300.toml"
PX4 = SHARED / "px4-ulog"


def _need(path):
    if not path.exists():
        pytest.skip(f"{path} is not beside the repository")


def test_gps_time_to_utc_at_known_dates():
    """GPS - UTC is 13 s in 2005, 17 s in 2016, 18 s from 2017 (IERS Bulletin C): the GPS
    time of a UTC instant is its UNIX time - 315964800 + the leap seconds."""
    for iso, leap in (("2005-06-01T00:00:00", 13), ("2016-06-01T00:00:00", 17),
                      ("2018-08-02T16:14:47", 18), ("2026-01-01T00:00:00", 18)):
        unix = datetime.datetime.fromisoformat(iso).replace(tzinfo=datetime.UTC).timestamp()
        assert gps_to_unix_s(unix - 315964800 + leap) == pytest.approx(unix, abs=1e-6)


@pytest.mark.slow
def test_comma2k19_through_the_table_importer(tmp_path):
    _need(SHARED / "comma2k19")
    rec = table.read(COMMA_SPEC)
    # The segment is minute 40 of a drive that started 2018-08-02 08:34:47 PDT (its folder
    # name): 16:14:47 UTC, give or take the second the folder name rounds.
    start = datetime.datetime(2018, 8, 2, 16, 14, 47, tzinfo=datetime.UTC).timestamp()
    assert abs(rec.imu_ns[0] / 1e9 - start) < 2.0
    # the mean rate over the span, missing samples counted (104.36 Hz by the median step)
    span_s = (rec.imu_ns[-1] - rec.imu_ns[0]) / 1e9
    assert rec.sample_rate_hz == pytest.approx(104.26, abs=0.05)
    assert rec.sample_rate_hz >= (len(rec.imu_ns) - 1) / span_s
    assert np.linalg.norm(rec.f.mean(axis=0)) == pytest.approx(9.8, abs=0.3)
    ref = rec.reference
    # velocity turned from ECEF to NED agrees with the positions' own differences
    t = (ref["ns"] - ref["ns"][0]) / 1e9
    ned = earth.ned_difference(ref["lat"], ref["lon"], ref["h"], ref["lat"][0], ref["lon"][0],
                               ref["h"][0])
    assert np.median(np.abs(np.gradient(ned, t, axis=0) - ref["v_ned"])) < 0.1
    # the README: yaw from the quaternion minus the velocity's heading = -0.90 +- 0.11 deg
    yaw = attitude.as_euler(quaternion.from_float_array(ref["q_nb"]))[0]
    course = np.arctan2(ref["v_ned"][:, 1], ref["v_ned"][:, 0])
    offset = np.degrees(np.median(np.angle(np.exp(1j * (yaw - course)))))
    assert offset == pytest.approx(-0.90, abs=0.25)

    log = tmp_path / "comma.mcap"
    assert main(["import", "table", str(COMMA_SPEC), "-o", str(log)]) == 0
    with FlightLog(log) as fl:
        meta = fl.metadata()
    assert meta["reference"]["independent"].startswith("no")
    assert meta["reference"]["attitude"].startswith("given by the reference")
    assert "whole state from the reference" in meta["recording"]["assumed"]["initial_state"]
    assert main(["info", str(log)]) == 0
    assert main(["windows", str(log), "-o", str(tmp_path / "w"), "--lengths", "10"]) == 0
    doc = json.loads((tmp_path / "w" / "windows.json").read_text())
    assert doc["summary"]["10"]["windows"] >= 5
    # the pose has an attitude: the automatic level uses it (navigation), not a car model
    auto = tmp_path / "auto.json"
    assert main(["diagnose", str(log), "--json", str(auto)]) == 0
    chosen = json.loads(auto.read_text())
    assert chosen["level"] == "navigation" and "attitude" in chosen["level_choice"]
    # comma's pose fuses this IMU: what it absorbed does not show against it, so finding
    # nothing is no clean bill (it had said 'no-missing-physics', conclusive)
    if not chosen["findings"]:
        assert not chosen["conclusive"] and chosen["verdict"] != "no-missing-physics"
        assert any("not known to be independent" in r for r in chosen["inconclusive_reasons"])
    out = tmp_path / "diag.json"
    assert main(["diagnose", str(log), "--level", "track", "--json", str(out)]) == 0
    diag = json.loads(out.read_text())
    assert diag["level"] == "track"
    # whatever it concludes, nothing it confirms makes the IMU navigate worse
    for f in diag["findings"]:
        assert f["navigation_check"]["median_paired_change_m"] <= 0
        assert f["fit"]["heldout_rms_after"] < f["fit"]["heldout_rms_before"]
    if not diag["conclusive"]:
        assert diag["verdict"] in ("unexplained-residual", "missing-physics")
        assert diag["inconclusive_reasons"]
    # the phone's roll-rate gyro is not predicted by a vehicle model without roll (1 s
    # correlation -0.12): 'no-missing-physics' would speak for terms never tested
    unpredicted = diag["reference_check"]["unpredicted_inputs"]
    assert "gyro.x" in unpredicted
    assert diag["verdict"] != "no-missing-physics"
    assert diag["findings"] or not diag["conclusive"] and any(
        r.startswith("no term driven by") and "gyro.x" in r for r in diag["inconclusive_reasons"])
    # what it finds is the phone IMU's timing against comma's pose: with the track's first
    # and last 3-16 epochs left out (0.15-0.8 s) a time_skew of accel.all or imu.all, -11 to
    # -14 ms, held out in both halves; with 0-2 epochs the end samples spoiled the held-out
    # fit (p 0.5) and the drive was inconclusive
    for f in diag["findings"]:
        assert f["effect"] == "time_skew" and -0.02 < f["coefficient"] < -0.005, f


@pytest.mark.slow
def test_px4_v6c_autopilot_reference_and_imu_instances(tmp_path):
    """The Pixhawk 6C log: 6.5 s, never at rest, never fast - the autopilot's attitude gives
    the initial state; the reference is labelled as not independent; both IMU instances
    with PX4's logged temperatures (11.0 degC and 12.2-12.4 degC, the data README)."""
    path = PX4 / "mcap_test_ulog_v6c.ulg"
    _need(path)
    rec = ulog.read(str(path))
    inst = rec.real["imu_instances"]
    assert set(inst) == {"sensor_accel:0", "sensor_accel:1", "sensor_gyro:0", "sensor_gyro:1"}
    assert "temperature 11.00 to 11.00 degC" in inst["sensor_accel:0"]
    low, high = map(float, inst["sensor_gyro:1"].split("temperature ")[1].split(" degC")[0]
                    .split(" to "))
    assert 12.1 <= low <= high <= 12.5
    assert rec.reference is not None and np.isfinite(rec.reference["q_nb"]).all()
    # Daejeon, KR (the README): about 36.37 N, 127.37 E
    assert math.degrees(rec.reference["lat"][0]) == pytest.approx(36.37, abs=0.01)
    assert math.degrees(rec.reference["lon"][0]) == pytest.approx(127.37, abs=0.01)
    log = tmp_path / "v6c.mcap"
    assert main(["import", "ulog", str(path), "-o", str(log)]) == 0
    with FlightLog(log) as fl:
        meta = fl.metadata()
    assert meta["reference"]["source"].startswith("autopilot estimate")
    assert meta["reference"]["independent"].startswith("no")
    flight = Flight.load(log, reference_imu=False)
    # the initial attitude is the autopilot's, which has the vehicle level within 10 deg
    yaw, pitch, roll = np.degrees(attitude.as_euler(
        flight.initial.q_nb))
    assert abs(pitch) < 10 and abs(roll) < 10
    assert main(["windows", str(log), "-o", str(tmp_path / "w"), "--min-speed", "0",
                 "--lengths", "3", "--step", "1"]) == 0
    # its sensor_accel / sensor_gyro instances are logged at 1 Hz (status snapshots): a new
    # user imported one as the IMU without a word and diagnosed 5 samples
    with pytest.raises(RecordingError, match="5 samples at 1 Hz"):
        check_recording(ulog.read(str(path), instance=1))


def test_px4_sample_without_gnss(tmp_path):
    """pyulog's sample: 69 s of sensor_combined at 250 Hz, no GNSS and no global position:
    imported with the rest its IMU shows at the start and position 0, and says so - and that its
    vehicle_attitude is not used without a global position."""
    path = PX4 / "pyulog_sample.ulg"
    _need(path)
    log = tmp_path / "sample.mcap"
    assert main(["import", "ulog", str(path), "-o", str(log)]) == 0
    with FlightLog(log) as fl:
        meta = fl.metadata()
        n = len(fl.read("/mimu/imu")["log_time"])
    assert "no GNSS track" in meta["recording"]["assumed"]["initial_state"]
    assert "reference" not in meta
    # the attitude and local position it does log are named as not used, and why
    unused = meta["recording"]["assumed"]["reference"]
    assert "vehicle_attitude" in unused and "not vehicle_global_position" in unused
    # its mean rate: 17069 steps and 51 samples missing (eight long steps) over 68.879 s -
    # below the 250 Hz of its median step (4.000 ms), above 17069 / 68.879 s = 247.8 Hz
    assert float(meta["sensor/mimu"]["sample_rate_hz"]) == pytest.approx(248.55, abs=0.01)
    assert n == 17070                   # every sensor_combined sample (the README's count)
    assert "file" not in meta["recording"]["real"]
    # no reference at all: the recording report still says what it is, and why there are
    # no windows and no diagnosis (it refused the whole report before)
    assert main(["report", "recording", str(log), "-o", str(tmp_path / "report")]) == 0
    text = (tmp_path / "report" / "recording.md").read_text()
    assert "## Channels" in text and "/mimu/imu" in text
    assert "No window: " in text and "no reference trajectory" in text
    assert "Not run: " in text and "no reference IMU" in text
    # the same file cut at 60 % (power lost): imported up to its last whole message, and the
    # metadata says the file was cut short (pyulog reads it silently)
    cut = tmp_path / "cut.ulg"
    data = path.read_bytes()
    cut.write_bytes(data[:int(0.6 * len(data))])
    rec = ulog.read(str(cut))
    assert "was cut short" in rec.real["file"] and len(rec.imu_ns) < 0.65 * n


@pytest.mark.parametrize("old, new, message", [
    ('value", unit = "m/s^2"', 'value", unit = "g"', r"accelerometer's unit \(g or m/s\^2\)"),
    ('axes = "FRD"', 'axes = "FLU"', "not pointing|not \\[0, 0, -"),
    ('rotates = "body_to_ecef"', 'rotates = "body_to_ned"', "convention"),
    ('gyro_uncalibrated/value", unit = "rad/s"', 'gyro_uncalibrated/value", unit = "deg/s"',
     r"gyro's unit \(deg/s or rad/s\)"),
    ('gyro_uncalibrated/t", unit = "s"', 'gyro_uncalibrated/t", unit = "ms"', "do not overlap"),
])
def test_comma2k19_spec_mistakes_are_refused(tmp_path, old, new, message):
    """The mistakes a new user made writing a spec for this data (each silently accepted
    before): a wrong unit, axes or quaternion convention is refused with the reason."""
    _need(SHARED / "comma2k19")
    text = COMMA_SPEC.read_text()
    assert old in text
    spec = tmp_path / "spec.toml"
    spec.write_text(text.replace(old, new).replace(
        'root = "../../../shared/data/comma2k19"', f'root = "{SHARED / "comma2k19"}"'))
    with pytest.raises(RecordingError, match=message):
        write_log(table.read(spec), tmp_path / "x.mcap")
    assert not (tmp_path / "x.mcap").exists()


def _part(flight, t0, t1):
    """The flight's MIMU samples with t0 <= t <= t1 (s) and its reference track a second
    beyond, in memory (what a cut log holds for the track level)."""
    from dataclasses import replace
    k = (flight.mimu_t >= t0) & (flight.mimu_t <= t1)
    j = np.flatnonzero((flight.truth.t >= t0 - 1.0) & (flight.truth.t <= t1 + 1.0))
    w, f = flight.mimu_imu
    return replace(flight, mimu_t=flight.mimu_t[k], mimu_imu=(w[k], f[k]),
                   truth=flight.truth[j])


@pytest.mark.slow
def test_the_rtklib_drives_mounting_is_one_angle_in_every_window(tmp_path):
    """The car's IMU does not turn in its mount during the drive: the track level's
    mounting misalignment of four 137 s windows of the RTKLIB drive scatters as their 95 %
    intervals say (chi-square of each component about the weighted mean below 11.3, the
    99 % point of 3 dof) and the whole drive's interval overlaps every window's. Fitted on
    the gyros too, their roll and pitch rates (which the vehicle model lacks: model error
    1.0-1.1 of those channels' size) made the roll angle follow the road: chi-square
    73 / 2.3 / 39 here, and the whole drive's x interval [0.02, 1.43] deg disjoint from
    that of its first 316 s, [1.25, 2.91] (now [-1.13, 1.36] and [-1.80, 1.53])."""
    from mimunav.compensation.calibration_file import Calibration
    from mimunav.diagnosis import track
    from mimunav.diagnosis.document import document
    drive = SHARED / "rtklib-drive" / "drive_0708"
    _need(drive)
    log = tmp_path / "drive.mcap"
    assert main(["import", "rtklib", str(drive), "-o", str(log)]) == 0
    flight = Flight.load(log, reference_imu=False, max_gap_s=np.inf)

    def mounting(part):
        doc = document("part", track.diagnose(part, Calibration.identity()))
        found = [f for f in doc["findings"] + doc["not_confirmed"]
                 if f["effect"] == "mounting_misalignment"]
        assert len(found) == 1, [f["label"] for f in doc["findings"]]
        assert set(doc["reference_check"]["fitted_on_channels"][found[0]["label"]]) <= \
            {"accel.x", "accel.y", "accel.z", "gyro.z"}
        return np.degrees(found[0]["vector"]), np.degrees(np.asarray(found[0]["vector_ci95"]))

    start = float(flight.truth.t[0])
    parts = [mounting(_part(flight, start + a, start + a + 137.0)) for a in (0, 137, 274, 411)]
    vectors = np.array([v for v, _ in parts])
    se = np.array([(ci[:, 1] - ci[:, 0]) / (2 * 1.96) for _, ci in parts])
    weights = 1 / se ** 2
    mean = (weights * vectors).sum(axis=0) / weights.sum(axis=0)
    chi2 = (((vectors - mean) / se) ** 2).sum(axis=0)
    assert np.all(chi2 < 11.3), (vectors, se, chi2)
    _, whole = mounting(flight)
    for _, ci in parts:
        assert np.all((whole[:, 0] <= ci[:, 1]) & (ci[:, 0] <= whole[:, 1])), (whole, ci)


@pytest.mark.slow
def test_the_rtklib_drives_mounting_agrees_with_its_authors(tmp_path):
    """The RTKLIB drive's IMU sits on its car, by the data's author (shared/data README, from
    his own filter), turned [0, -6.79, 5.35] deg about the car's forward, right, down axes;
    a plain least-squares fit from the raw CSV, time tags and RTK velocities (numpy alone,
    the stamps moved by -0.1 s) gave [0.0, -6.67, 5.75] (1 sigma 0.35, 0.45, 0.28). The
    track level's mounting holds the author's angles in its intervals. With the fit's bins
    one track error time long (0.5 s here) the pitch was -4.7 deg [-6.0, -3.5]: the
    bin-to-bin changes of the model's forward acceleration over so short a bin are mostly
    the model's own error, which shrinks the regressor's coefficient
    (`track.BIN_ERROR_TIMES`). The car's roll and its pitch on the springs are not in the
    vehicle model: the library's other terms beside the mounting stand out 8.4 times their
    chance level (0.3-2.0 on bench/track_drive.py's independent drives), so the intervals
    are sqrt(lambda) wider and 'nothing else is missing' is not said - without that check
    the pitch read -5.67 deg [-6.90, -4.44]."""
    from mimunav.compensation.calibration_file import Calibration
    from mimunav.diagnosis import track
    from mimunav.diagnosis.document import document
    drive = SHARED / "rtklib-drive" / "drive_0708"
    _need(drive)
    log = tmp_path / "drive.mcap"
    assert main(["import", "rtklib", str(drive), "-o", str(log)]) == 0
    flight = Flight.load(log, reference_imu=False, max_gap_s=np.inf)
    doc = document("drive", track.diagnose(flight, Calibration.identity()))
    found = [f for f in doc["findings"] if f["effect"] == "mounting_misalignment"]
    assert len(found) == 1, [f["label"] for f in doc["findings"]]
    ci = np.degrees(np.asarray(found[0]["vector_vehicle_ci95"]))
    for (lo, hi), author in zip(ci, (0.0, -6.79, 5.35)):
        assert lo <= author <= hi, (ci, author)
    library = doc["library_inflation"]
    assert library["lambda"] > library["limit"], library
    assert library["widened_by"] == pytest.approx(np.sqrt(library["lambda"]))
    assert not doc["conclusive"] and any("stand out" in r for r in doc["inconclusive_reasons"])


def test_a_table_spec_copied_elsewhere_names_its_data_folder(tmp_path, capsys):
    """The README's comma2k19 example run from a clone in another folder: the spec's relative
    root then points nowhere - refused with the folder it tried and the option that gives
    the right one (`--root`), which imports it."""
    _need(SHARED / "comma2k19")
    spec = tmp_path / "comma2k19.toml"
    spec.write_text(COMMA_SPEC.read_text())
    assert main(["import", "table", str(spec), "-o", str(tmp_path / "a.mcap")]) == 2
    err = capsys.readouterr().err
    assert "does not exist: give the folder with --root" in err, err
    assert main(["import", "table", str(spec), "--root", str(SHARED / "comma2k19"),
                 "-o", str(tmp_path / "b.mcap")]) == 0
    assert main(["import", "ulog", str(PX4 / "pyulog_sample.ulg"), "--root", str(tmp_path),
                 "-o", str(tmp_path / "c.mcap")]) == 2        # not read by that importer


@pytest.mark.slow
def test_onspeed_cheap_imu_beside_a_quantized_vn300(tmp_path):
    """The light aircraft of shared/data/onspeed-vn300 (a cheap MEMS IMU beside a VN-300
    logged with 2 decimals, 30 s to a stall): the spec's per-column signs give two FRD
    triads whose 0.5 s means correlate on every axis; the VN-300 rows written twice are one
    sample; the two boxes' turn (about 4.4 deg of pitch) is measured and, the attitude
    being the VN-300's own, put on the cheap IMU's mounting; the VN-300's stamps lag by its
    data age and a few ms more (its README: tens of ms). The diagnosis against a MEMS
    reference charges nothing to the cheap IMU alone that the VN-300 could carry, and
    checks each term on the two halves of the 30 s."""
    _need(SHARED / "onspeed-vn300")
    rec = table.read(ONSPEED_SPEC)
    assert "50 rows repeating" in rec.real["repeated [reference]"]
    check_recording(rec)
    yaw, pitch, roll = np.degrees(attitude.as_euler(rec.mounting.q_vs))
    # about 4.4 deg of pitch: 4.3 by the 1 s means about their own means, where no bias
    # enters, 4.6-4.8 with gravity among the vectors (a 5 mg accelerometer bias difference
    # across gravity reads as the difference); the cheap IMU's own triads differ by more than
    # 0.2 deg, so the turn (beyond 3 deg) is taken from both kinds together
    assert pitch == pytest.approx(4.4, abs=0.5) and abs(roll) < 1 and abs(yaw) < 1.5
    assert "IMU's mounting was turned" in rec.real["reference_imu_mounting"]
    assert "refined to" in rec.real["reference_imu_clock"]
    log = tmp_path / "onspeed.mcap"
    assert main(["import", "table", str(ONSPEED_SPEC), "-o", str(log)]) == 0
    with FlightLog(log) as fl:
        bias = fl.metadata()["recording"]["accel_bias_m_s2"]
    assert max(abs(b) for b in bias) < 0.5     # not the 4.8 deg tilt's 0.8 m/s^2
    out = tmp_path / "d.json"
    assert main(["diagnose", str(log), "--json", str(out)]) == 0
    diag = json.loads(out.read_text())
    assert diag["level"] == "sensor" and not diag["reference_agreement"]["failures"]
    assert diag["reference_accuracy"]["gyro_step"] == 0.01
    # its accelerometer z offset against the VN-300 (-0.34 m/s^2 [-0.41, -0.26] by the
    # offset test) is read with its interval widened as the library's terms are, the
    # residual standing beyond the tests' noise (39 times in 0.01 s bins; 5 times in the
    # 0.2 s bins the VN-300's vibration on another clock chooses): the verdict is
    # inconclusive and the offset, set aside or found, is no finding on the cheap IMU alone
    # (it had been found at p 1e-18; a helicopter's like it missed its truth by 3 half-widths)
    assert diag["bins"]["bin_s"] > 0.02 and not diag["conclusive"]
    offset = [r for r in diag["not_confirmed"] + diag["findings"]
              if r["label"] == "bias_shift accel.z"]
    assert offset and offset[0]["library_inflation"]["widened_by"] > 2, diag["not_confirmed"]
    assert -0.45 < offset[0]["coefficient"] < -0.2
    for f in diag["findings"]:
        assert f["attribution"] in ("mimu-or-reference", "installation", "timing"), f["label"]
        if f["effect"] == "bias_shift":     # beside the import's, its reference named; the
            assert "import_measured" in f   # part's turn-on bias said to show whole
            assert "taken as recorded" in f["note"]
        if "held-out statistic" in f.get("effect_size", {}).get("basis", ""):
            assert f["halves"]["widened_by"] >= 1.0    # a library term, refitted per half
            assert f["effect_size"]["heldout_variance_removed"] >= 1e-3
    # its first 8 s: a mounting is read off the gyros with a roll of -2 deg [-4.1, +0.1];
    # removed at its estimate it tilted g into accel.y, and a bias shift of -0.197 m/s^2
    # [-0.275, -0.119] was found there that the whole 30 s do not show (their raw mean
    # difference -0.026). The offset test carries the removal's error: every bias shift of
    # the cut is one of the whole recording's, their intervals overlapping
    cut, cut_out = tmp_path / "first-8s.mcap", tmp_path / "cut.json"
    assert main(["cut", str(log), "--span", "0:8", "-o", str(cut)]) == 0
    assert main(["diagnose", str(cut), "--json", str(cut_out)]) == 0
    whole = {f["label"]: f["ci95"] for f in diag["findings"] if f["effect"] == "bias_shift"}
    cut_doc = json.loads(cut_out.read_text())
    # beside its library findings the library's other terms stand out 5 times their chance
    # level over the 30 s (35 times in 0.01 s bins): the tests' noise model does not hold
    # here (a reference in 0.01 steps, a lag, a cheap unit's errors) - said, and the
    # library's findings judged with intervals sqrt(lambda) wider. The 8 s cut's motion is
    # too small beside the engine for any bins to average it out (0.2 of it left in 0.2 s
    # bins, 0.04 in whole periods of its strongest line): inconclusive, said; its 6.5 deg [2.2, 10.8] yaw mounting of 0.01 s bins (held-
    # out p 0.007), which the whole 30 s did not name and the import's box-to-box
    # measurement (within 1.5 deg, above) contradicts, is no finding
    assert any("times their chance level" in r for r in diag["inconclusive_reasons"]), diag
    assert diag["library_inflation"]["lambda"] > diag["library_inflation"]["limit"]
    assert any(re.search(r"even in [0-9.]+ s bins", r)
               for r in cut_doc["inconclusive_reasons"]), cut_doc
    assert "mounting_misalignment imu.all" not in [f["label"] for f in cut_doc["findings"]]
    for f in cut_doc["findings"]:
        if f["effect"] == "bias_shift":
            lo, hi = whole.get(f["label"], (np.inf, -np.inf))
            assert f["ci95"][0] <= hi and lo <= f["ci95"][1], (f["label"], f["ci95"], whole)

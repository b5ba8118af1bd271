"""Free-inertial windows restarted from a reference trajectory (`evaluation.windows`)."""
import math

import numpy as np
import pytest
import quaternion

from mimunav.navigation import alignment
from mimunav.evaluation import windows
from mimunav.cli import main
from mimunav.evaluation.flight import Flight
from mimunav.importers.write import write_log
from drives import (MOUNT, ideal_flight, stop_track, straight_track, track_from_velocity,
                    under_a_noisy_fix)


def test_windows_of_an_ideal_imu_stay_at_the_alignment_error(tmp_path):
    """Free-inertial windows of an ideal IMU on the synthetic drive: what remains is the
    moving alignment's own error. A tilt of 1e-4 rad (the averaging error on this gentle
    weave) grows as g theta t^2 / 2: 0.05 m at 10 s, 0.44 m at 30 s - not the metres of the
    real drive."""
    path, _, _ = ideal_flight(tmp_path, MOUNT)
    flight = Flight.load(path, reference_imu=False)
    results, rest = windows.run_all(flight, lengths=(10.0, 30.0), step=10.0)
    assert len(results[10.0]) >= 8
    ends10 = [w.horizontal[-1] for w in results[10.0]]
    ends30 = [w.horizontal[-1] for w in results[30.0]]
    assert max(ends10) < 0.05 and max(ends30) < 0.44, (max(ends10), max(ends30))
    # a recording that holds no window says why and what option would help (issue 16: a walk
    # returned zero windows and exit 0)
    with pytest.raises(ValueError, match="peaks at .* m/s over .* s: mimunav windows --min-speed"):
        windows.run_all(flight, lengths=(10.0,), min_speed=1e3)
    assert main(["windows", str(path), "--min-speed", "1000"]) == 2


def test_reference_floor_of_a_window_from_the_stated_sigmas():
    """The end error a window inherits from its reference alone: start and end positions
    (sigma_p each) and the start velocity (sigma_v * L), independent - checked against a
    Monte Carlo of exactly that error budget; unstated sigmas are named, not invented."""
    floor = windows.reference_floor({"position_sigma_m": "0.02", "velocity_sigma_m_s": "0.05"},
                                    30.0)
    rng = np.random.default_rng(0)
    n = 200000
    e = (rng.normal(0, 0.02 / math.sqrt(2), (n, 2)) + rng.normal(0, 0.05 / math.sqrt(2), (n, 2))
         * 30.0 - rng.normal(0, 0.02 / math.sqrt(2), (n, 2)))        # 2-D rms sigmas
    assert floor["horizontal_m"] == pytest.approx(np.sqrt(np.mean(np.sum(e**2, axis=1))),
                                                  rel=0.01)
    assert floor["not_stated"] == []
    only_p = windows.reference_floor({"position_sigma_m": "0.5"}, 60.0)
    assert only_p == {"horizontal_m": pytest.approx(0.5 * math.sqrt(2)),
                      "position_ends_m": pytest.approx(0.5 * math.sqrt(2)),
                      "not_stated": ["velocity"], "estimated": []}
    # the position's part is said as the stated sigma at both ends, taken independent (an
    # INS+DVL's 1.41 m for every length read as the floor, its drift over 10 s 6 cm)
    row = {"windows": 3, "disjoint": 1, "median_rate_m_s": 0.1, "reference_floor": only_p,
           "horizontal_m": {"p50": 1.0, "p68": 1.0, "p95": 1.0, "max": 1.0},
           "vertical_m": {"p50": 0.1, "p95": 0.1}}
    from mimunav.reports.windows import markdown_table
    said = markdown_table({"summary": {"60": row}})
    assert "0.707 m the stated position sigma at both ends, taken independent" in said
    # a floor that leaves out the reference attitude's error at each start says so, sized
    # (an autopilot's EKF: 0.022 m at 10 s read as its floor, its own part 2.3 m)
    assert f"the reference attitude's own error at each start is not stated " \
        f"and not counted - 0.1 deg of it adds {9.80665 * math.radians(0.1) * 1800:.2g} m" in said
    # and no claim of a bound: the stated sigmas may be pessimistic (a ship's bag's read
    # 0.147 m above its null windows' observed 0.135 m, "a lower bound")
    assert "a lower bound" not in said and "taken as true" in said
    # an unstated velocity sigma from the track's noise (0.3 m/s per axis), said; with a
    # moving alignment over +-2 s its tilt, checked by a Monte Carlo of the alignment's
    # velocity difference: (v(t0 + 2) - v(t0 - 2)) / 4 s per axis, over 10^2 / 2 s^2
    est = windows.reference_floor({"position_sigma_m": "0.5"}, 10.0, 0.3, 2.0)
    assert est["estimated"] == ["velocity"] and est["not_stated"] == []
    assert est["alignment_tilt_m"] == pytest.approx(2 * 0.3 / 4.0 * 50.0)     # 2-D rms
    tilt = (rng.normal(0, 0.3, (n, 2)) - rng.normal(0, 0.3, (n, 2))) / 4.0 * 50.0
    start_v = rng.normal(0, 0.3, (n, 2)) * 10.0
    ends = rng.normal(0, 0.5 / math.sqrt(2), (n, 2)) - rng.normal(0, 0.5 / math.sqrt(2), (n, 2))
    assert est["horizontal_m"] == pytest.approx(
        np.sqrt(np.mean(np.sum((tilt + start_v + ends) ** 2, axis=1))), rel=0.01)
    assert windows.reference_floor({"position_sigma_m": "unknown"}, 10.0)["horizontal_m"] is None


def test_no_window_says_which_condition_the_recording_fails():
    """A reference that moves (0.85 m/s at most, above a 0.5 m/s gate) but spans 6.4 s after
    its rest, for 10 s windows (the Pixhawk log): the refusal names the span as what it
    lacks and the speed as met - it had listed speed, gaps and span as needs, the speed
    first, as if the speed had failed; a gate of 0 m/s (a reference with attitude) is no
    condition, not named (its 'speed of 0 m/s' had read as a cause); a reference gap leaves
    out only the windows it meets, so it is said as that, not as a lack."""
    from types import SimpleNamespace

    from mimunav.evaluation.windows import why_no_windows
    t = np.arange(0.0, 8.4, 0.2)
    truth = SimpleNamespace(t=t, v_ned=np.column_stack([0.85 * np.sin(t / 3), 0 * t, 0 * t]))
    said = why_no_windows(truth, [10.0, 30.0], 1.8, 0.5, 1.0, 0.25)
    lacks, has = said.split("it lacks ")[1].split(" (it has ")
    assert lacks.startswith("10 s of reference after the rest and the alignment's 0.25 s "
                            "(it holds 6.4 s")
    assert "speed" in has and "gap" not in said and "speed" not in lacks
    assert "speed" not in why_no_windows(truth, [10.0, 30.0], 1.8, 0.0, 1.0, 0.25)
    # 10.2 s of reference: not enough for 10 s windows and the alignment's 0.25 s before them
    t10 = np.arange(0.0, 10.21, 0.2)
    short = SimpleNamespace(t=t10, v_ned=np.column_stack([0 * t10 + 5.0, 0 * t10, 0 * t10]))
    assert "it lacks 10 s of reference" in why_no_windows(short, [10.0], 0.0, 0.0, 1.0, 0.25)
    moving = why_no_windows(truth, [5.0], 1.8, 0.0, 1.0, 0.25)
    assert "it lacks" not in moving and "leave no window" in moving
    # a gap leaves out the windows it meets: said, never as what the recording lacks
    gappy = SimpleNamespace(t=np.delete(t, range(20, 30)), v_ned=np.delete(truth.v_ned,
                                                                          range(20, 30), 0))
    said = why_no_windows(gappy, [10.0], 1.8, 0.5, 1.0, 0.25)
    assert "lacks" in said and "gap" not in said.split(" (it has ")[0]
    assert "gaps above 1 s (the largest 2.20 s: mimunav windows --max-gap) leave out" in said


def test_windows_leave_out_every_window_an_imu_gap_meets(tmp_path):
    """A 5 s IMU gap in the middle of the synthetic drive: no 10 s window (with its
    alignment interval before it) may meet the gap; windows far from it remain."""
    t_tr, lat, lon, h, v = straight_track()
    from mimunav.motion.trajectory import Trajectory
    truth_traj = Trajectory(t_tr, lat, lon, h, v, quaternion.from_float_array(
        np.tile([1.0, 0.0, 0.0, 0.0], (len(t_tr), 1))))
    t_imu = np.arange(0.0, 120.0, 0.01)
    t_imu = t_imu[(t_imu < 60.0) | (t_imu > 65.0)]
    got = windows.starts(truth_traj, 10.0, step=0.5, t_imu=t_imu, max_gap=0.5)
    half = alignment.MOVING_HALF_WINDOW_S
    assert len(got) and not np.any((got + 10.0 > 60.0) & (got - half < 65.0)), got
    assert got.max() > 65.0 and got.min() < 50.0
    # an IMU that stops before the reference: windows up to the IMU's end (there were none)
    early = windows.starts(truth_traj, 10.0, step=0.5, t_imu=t_imu[t_imu < 100.0], max_gap=0.5)
    assert len(early) and early.max() + 10.0 <= 100.0 and early.max() > 85.0


def test_no_window_starts_where_the_reference_misses_epochs():
    """A 100 Hz reference missing 0.5 s (a mocap dropout, under the 1 s a window may hold):
    no window's alignment interval meets it - its start state would be interpolated across
    the dropout (a multicopter's window started there ended 76 m off, its neighbours 22)."""
    t_tr, lat, lon, h, v = straight_track()
    from mimunav.motion.trajectory import Trajectory
    fine = np.arange(t_tr[0], t_tr[-1], 0.01)
    keep = (fine < 70.0) | (fine > 70.5)
    fine = fine[keep]
    at = [np.interp(fine, t_tr, x) for x in (lat, lon, h)]
    v_fine = np.column_stack([np.interp(fine, t_tr, v[:, i]) for i in range(3)])
    truth = Trajectory(fine, *at, v_fine, quaternion.from_float_array(
        np.tile([1.0, 0.0, 0.0, 0.0], (len(fine), 1))))
    got = windows.starts(truth, 10.0, step=0.05, max_gap=1.0)
    half = alignment.MOVING_HALF_WINDOW_S
    assert len(got) and not np.any((got + half > 70.0) & (got - half < 70.5)), got
    assert np.any((got > 60.0) & (got < 70.5)) or np.any(got + 10.0 > 70.5)


def test_no_window_spans_a_jump_of_the_reference(tmp_path):
    """The synthetic drive's reference moved 2 m north from t = 60 s on, its velocity left as
    it was (an INS back on its fixes after an outage): no window's alignment interval or run
    meets 60 s, the others stay at the ideal IMU's alignment error, and the document names
    the jump and its size; without the jump windows do span 60 s."""
    from dataclasses import replace
    from mimunav.reports import windows as report
    path, _, _ = ideal_flight(tmp_path, MOUNT)
    flight = Flight.load(path, reference_imu=False)
    tr = flight.truth
    spans = lambda res: [w.t0 for w in res[10.0] if w.t0 - half < 60.0 <= w.t0 + 10.0]  # noqa
    half = alignment.MOVING_HALF_WINDOW_S
    plain, _ = windows.run_all(flight, lengths=(10.0,), step=2.5)
    assert spans(plain)
    north = 2.0 / (6378137.0 + float(tr.h[0]))                  # rad: 2 m, to a part in 1e3
    jumped = replace(flight, truth=replace(tr, lat=np.where(tr.t >= 60.0, tr.lat + north,
                                                            tr.lat)))
    results, rest = windows.run_all(jumped, lengths=(10.0,), step=2.5)
    assert not spans(results) and len(results[10.0]) >= len(plain[10.0]) - 6
    assert max(w.horizontal[-1] for w in results[10.0]) < 0.05
    doc = report.document(jumped, results, rest, None, 0.0)
    (jump,) = doc["reference_jumps"]
    assert abs(jump["t_s"] - 60.0) < 0.5 and abs(jump["off_m"] - 2.0) < 0.01, jump
    assert "no window spans one" in report.markdown_table(doc)


def test_windows_of_a_reversing_vehicle_face_backwards(tmp_path):
    """The synthetic drive driven in reverse (the vehicle faces 180 deg from its course;
    its ideal IMU is that of the track's motion mounted turned half a turn in yaw): each
    window's moving alignment must face the vehicle against its velocity. Taking heading =
    course, the 10 s windows end 31-37 m off; facing backwards, within the
    forward drive's 0.05 m."""
    t, _, _, _, v = straight_track()
    track = track_from_velocity(t, -v)
    half_turn = quaternion.from_rotation_vector([0.0, 0.0, math.pi])
    from dataclasses import replace
    as_moved = replace(MOUNT, attitude_wxyz=quaternion.as_float_array(half_turn * MOUNT.q_vs))
    path, _, _ = ideal_flight(tmp_path, as_moved, track=track)
    flight = replace(Flight.load(path, reference_imu=False), mimu_mounting=MOUNT)
    results, _ = windows.run_all(flight, lengths=(10.0,), step=10.0)
    ends = [w.horizontal[-1] for w in results[10.0]]
    assert len(ends) >= 8 and max(ends) < 0.05, ends
    # the track level leaves the reversing move out (its vehicle model would face the
    # wrong way), and nothing of the same drive driven forward
    from mimunav.diagnosis.track_reference import reversing
    moving = flight.mimu_t > 21.0
    assert reversing(flight)[moving].all()
    forward, _, _ = ideal_flight(tmp_path / "forward", MOUNT)
    assert not reversing(Flight.load(forward, reference_imu=False)).any()


def test_no_window_starts_while_parked_under_a_noisy_fix(tmp_path):
    """The stop-and-go drive (at rest 25-45 s) under a plain 1 Hz fix with 1.5 m of
    position noise: its differenced speed passes a 2 m/s gate (--min-speed) at rest, but no
    window may start (align on a course of noise) inside the rest the IMU and the positions
    show."""
    rec = under_a_noisy_fix(stop_track(), np.random.default_rng(11))
    t_fix, v_n = (rec.reference["ns"] - rec.reference["ns"][0]) / 1e9, rec.reference["v_ned"]
    at_rest = (t_fix > 26.0) & (t_fix < 44.0)
    assert np.any(np.hypot(v_n[at_rest, 0], v_n[at_rest, 1]) > 2.0)     # the gate is fooled
    write_log(rec, tmp_path / "noisy.mcap")
    flight = Flight.load(tmp_path / "noisy.mcap", reference_imu=False)
    results, _ = windows.run_all(flight, lengths=(5.0,), step=0.5, min_speed=2.0)
    first = np.array([x.t0 for x in results[5.0]])
    assert len(first) and not np.any((first > 26.0) & (first < 44.0)), first


def test_windows_under_a_noisy_fix_align_over_a_longer_interval(tmp_path):
    """The weaving drive under a plain 1 Hz fix (1.5 m of position noise, velocity by
    differences: about 1 m/s of noise): the moving alignment follows the gyro over +-5 s
    (`moving_half_window`) instead of differencing a noisy velocity over 0.5 s, which had
    tilted every window by degrees (10 s windows: 69 m p50); now the 10 s windows end
    within the reference's own floor (its start velocity alone: ~10 m), which the summary
    estimates from the track and says so."""
    rec = under_a_noisy_fix(straight_track(), np.random.default_rng(7))
    write_log(rec, tmp_path / "noisy.mcap")
    flight = Flight.load(tmp_path / "noisy.mcap", reference_imu=False)
    track = windows.track_of(flight.truth)
    half = alignment.moving_half_window(track)
    assert half == alignment.MOVING_HALF_WINDOW_MAX_S
    # a window every second: the median of 17 windows 5 s apart moved by 7 m with where
    # the drive's rest ends (the windows' starts against the fix's epochs)
    results, _ = windows.run_all(flight, lengths=(10.0,), step=1.0)
    row = windows.summary(results, flight.reference_meta, track, half)[10.0]
    floor = row["reference_floor"]
    assert floor["estimated"] == ["velocity"] and 5.0 < floor["horizontal_m"] < 30.0
    assert row["windows"] >= 50 and row["horizontal_m"]["p50"] < floor["horizontal_m"], row


def test_the_gap_a_window_may_hold_follows_the_references_own_rate():
    """A 1 Hz GNSS track (steps of 1 s +- 20 ms) is no run of gaps: the limit is 2.5 of its
    steps, so one missed epoch (2 s) passes and two (3 s) do not; a 10 Hz track keeps 1 s; a
    limit given is the limit."""
    from types import SimpleNamespace
    from mimunav.evaluation.windows import gap_allowed
    rng = np.random.default_rng(0)
    gnss = SimpleNamespace(t=np.cumsum(1.0 + rng.uniform(-0.02, 0.02, 600)))
    limit = gap_allowed(gnss)
    assert 2.0 < limit < 3.0 and np.diff(gnss.t).max() < limit
    assert gap_allowed(SimpleNamespace(t=np.arange(6000) * 0.1)) == 1.0
    assert gap_allowed(gnss, 0.5) == 0.5


def test_a_stated_position_sigma_is_read_from_its_leading_number():
    """A table spec's position_sigma_m is text for the metadata: "3 (horizontalAccuracy
    column)" had been taken as not stated; its leading number is the sigma (m), and text
    without one is still not stated."""
    with_text = windows.reference_floor({"position_sigma_m": "3 (horizontalAccuracy column)"},
                                        10.0)
    assert with_text["not_stated"] == ["velocity"]
    assert with_text["horizontal_m"] == pytest.approx(3.0 * 2 ** 0.5)
    assert windows.reference_floor({"position_sigma_m": "unknown"}, 10.0)["horizontal_m"] \
        is None


def test_the_disjoint_windows_are_counted_among_those_run():
    """The count in brackets is of the windows run that do not overlap (it had been the
    span's capacity: '13 (45)'): starts 0, 5, 10, 15, 20 s of 10 s windows hold 3."""
    from types import SimpleNamespace
    wins = [SimpleNamespace(t0=t0, horizontal=np.array([1.0]), error_ned=np.zeros((1, 3)))
            for t0 in (20.0, 0.0, 5.0, 10.0, 15.0)]
    assert windows.summary({10.0: wins})[10.0]["disjoint"] == 3


def test_the_earth_rate_a_rest_without_heading_keeps_is_said_beside_the_floor():
    """A rest whose heading was not known keeps the Earth rate's horizontal part in its gyro
    bias (said at import): a window drifts by up to g Omega cos(lat) L^3 / 6 from it (17 m at
    60 s at 45 deg - a new user's ideal IMU had shown 15 m there, charged to it); the
    windows' table says so; with a measured heading, nothing."""
    from types import SimpleNamespace
    from mimunav.frames import earth
    from mimunav.reports.windows import earth_rate_left, markdown_table
    rest = SimpleNamespace(bias_basis={"gyro": "vertical_earth_rate"}, lat=math.radians(45.0))
    left = earth_rate_left(rest, 60.0)
    assert left == pytest.approx(9.80665 * earth.OMEGA * math.cos(math.radians(45.0))
                                 * 60.0 ** 3 / 6)
    assert earth_rate_left(SimpleNamespace(bias_basis={"gyro": "course"}, lat=0.8), 60.0) == 0
    row = {"windows": 3, "disjoint": 1, "horizontal_m": dict.fromkeys(
        ("p50", "p68", "p95", "max"), 1.0), "vertical_m": {"p50": 0.1, "p95": 0.2},
        "median_rate_m_s": 0.1, "reference_floor": {"horizontal_m": 2.0, "not_stated": [],
                                                    "estimated": []},
        "earth_rate_left_m": left}
    assert f"up to {left:.3g} m of drift" in markdown_table({"summary": {"60": row}})


def test_windows_on_a_trajectory_clock_the_import_left_open_say_so():
    """A recording whose reference trajectory's clock the import left open (the data peak
    0.7 s from its stamps among rivals: a ship's rolls) - its windows hold the lag: a ship's
    60 s windows had read 695 m with no word (17 m once shifted). The table ends in a
    warning naming --time-shift; once a shift is given, nothing is said."""
    from types import SimpleNamespace
    from mimunav.reports.windows import doubts, markdown_table
    flight = SimpleNamespace(recording={"reference_clock_open": "not decided (... 0.70 s "
                                                                "early ...)"})
    (why,) = doubts(flight, 0.0)
    assert "could not decide the reference trajectory's clock" in why and "0.70 s early" in why
    assert "mimunav windows --time-shift S" in why
    assert doubts(flight, -0.7) == [] and doubts(SimpleNamespace(recording={}), 0.0) == []
    # an IMU its own forces place off its lever arm given (`importers.trajectory_point`)
    (off,) = doubts(SimpleNamespace(recording={"imu_point_off": "the IMU's own ... 12 m"}), 0.0)
    assert off == "the IMU's own ... 12 m: these errors hold that arm's transfer too"
    # a trajectory whose point is measured off the origin, left there
    (off,) = doubts(SimpleNamespace(recording={"trajectory_point_off": "... 3.30 m off"}), 0.0)
    assert off == "... 3.30 m off: these errors may hold the transfer of an arm from that point"
    row = {"windows": 3, "disjoint": 1, "horizontal_m": dict.fromkeys(
        ("p50", "p68", "p95", "max"), 1.0), "vertical_m": {"p50": 0.1, "p95": 0.2},
        "median_rate_m_s": 0.1, "reference_floor": {"horizontal_m": 2.0, "not_stated": [],
                                                    "estimated": []}}
    assert markdown_table({"summary": {"60": row}, "doubts": [why]}).endswith(
        f"\nwarning: {why}\n")

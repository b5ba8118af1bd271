"""Plausibility guards: numbers that cannot be what the contract says are refused in one
line (or warned about loudly), options out of range are refused at parse time, profiles
with unknown keys or impossible values are refused - each on a log or profile made wrong in
the way people make them wrong."""
import json
import math
from dataclasses import replace

import numpy as np
import pytest

import fuzzing
from mimunav.evaluation.flight import Flight, check_plausible
from mimunav.cli import main
from mimunav.compensation.calibration_file import Calibration
from mimunav.flightlog import FlightLog, LogError, LogWriter
from mimunav.motion.profile import Profile, ProfileError

DEG = math.pi / 180


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    folder = tmp_path_factory.mktemp("guards")
    return fuzzing.corpus_log(folder)


def _rewrite(src, dst, change):
    """A copy of log `src` with `change(topic, messages)` applied to every channel."""
    with FlightLog(src) as log, LogWriter(dst) as out:
        for name, values in log.metadata().items():
            out.metadata(name, values)
        for topic in log.channels:
            msgs = change(topic, log.read(topic).copy())
            schema = log.schema_name(topic)
            from mimunav.flightlog import schemas as S
            fields = {n: msgs[n] for n, _, _ in S.BODIES[schema]}
            out.write(topic, schema, msgs["frame_id"][0].decode(),
                      msgs["log_time"].astype(np.int64), **fields)
    return dst


@pytest.mark.parametrize("what, change, message", [
    ("reference IMU in deg/s",
     lambda t, m: _scaled(m, t, "/fog/imu", "angular_velocity", 1 / DEG), "deg/s"),
    ("reference IMU in g",
     lambda t, m: _scaled(m, t, "/fog/imu", "linear_acceleration", 1 / 9.80665), "in g"),
    ("truth latitude in degrees",
     lambda t, m: _scaled(m, t, "/truth/state", "latitude", 1 / DEG), "degrees written"),
    ("truth an hour late",
     lambda t, m: _shifted(m, t, "/truth/state", 3600 * 10 ** 9), "do not overlap"),
    ("5 s of MIMU samples missing",
     lambda t, m: m[(m["log_time"] - m["log_time"][0] < 4 * 10 ** 9) |
                    (m["log_time"] - m["log_time"][0] > 9 * 10 ** 9)] if t == "/mimu/raw" else m,
     "misses"),
])
def test_a_log_with_wrong_numbers_is_refused_by_name(good, tmp_path, capsys, what, change,
                                                     message):
    """A log whose numbers cannot be what the contract says is refused by name when it is
    loaded and navigated (`table`), and by the sensor level - but for a gap: that level
    navigates nothing across one and leaves the samples beside it out (it had refused, as
    navigation must)."""
    log, cal = good
    bad = _rewrite(log, tmp_path / "bad.mcap", change)
    with pytest.raises(LogError, match=message):
        Flight.load(bad)
    assert main(["table", str(bad), "--cal", f"true={cal}"]) == 2
    capsys.readouterr()
    if message == "misses":
        assert main(["diagnose", str(bad), "--model", str(cal)]) in (0, 1)
        assert "1 span(s) where an IMU misses samples (either IMU's stamps step over a gap) "\
               "(3.9-9.1 s)" in capsys.readouterr().out        # the hole and its sides
    else:
        assert main(["diagnose", str(bad), "--model", str(cal)]) == 2


def _scaled(m, topic, want, field, k):
    if topic == want:
        m[field] = m[field] * k
    return m


def _shifted(m, topic, want, ns):
    if topic == want:
        m["log_time"] += np.uint64(ns)
        m["sec"] = (m["log_time"] // 10 ** 9).astype(m["sec"].dtype)
    return m


def test_duplicate_stamps_and_nan_truth_are_named(good):
    log, _ = good
    flight = Flight.load(log)
    t = flight.mimu_t.copy()
    t[100] = t[99]
    with pytest.raises(LogError, match=r"MIMU stamps do not increase at t = .* \(a duplicate\)"):
        check_plausible(replace(flight, mimu_t=t))
    lat = flight.truth.lat.copy()
    lat[50] = np.nan
    with pytest.raises(LogError, match="/truth/state is not finite at t = "):
        check_plausible(replace(flight, truth=replace(flight.truth, lat=lat)))


def test_a_calibration_in_other_units_is_warned_about(good, tmp_path, capsys):
    """A0 written in mg (the numbers 1000/g too large) and the unit's true file: only the
    first gets the warning."""
    log, cal = good
    assert main(["table", str(log), "--cal", f"true={cal}"]) == 0
    assert "warning" not in capsys.readouterr().err
    doc = json.loads(cal.read_text())
    doc["accel"]["A0"] = (np.asarray(doc["accel"]["A0"]) * 1e3 / 9.80665 + 3.0).tolist()
    mg = tmp_path / "mg.json"
    mg.write_text(json.dumps(doc))
    Calibration.load(mg)
    assert main(["table", str(log), "--cal", f"mg={mg}"]) == 0
    assert "units other than mimunav-calibration/1's (A0 in mg" in capsys.readouterr().err
    assert main(["table", str(log), "--cal", f"a={cal}", "--cal", f"a={mg}"]) == 2


@pytest.mark.parametrize("argv", [
    ["demo", "--rate", "-100"], ["demo", "--rate", "inf"], ["demo", "--rate", "1e9"],
    ["replay", "x.mcap", "--cal", "c.json", "-o", "o", "--nav-rate", "0"],
    ["replay", "x.mcap", "--cal", "c.json", "-o", "o", "--end", "nan"],
    ["diagnose", "x.mcap", "--alpha", "2"], ["campaign", "-o", "r.jsonl", "--units", "0"],
    ["windows", "x.mcap", "--lengths", "-10"], ["simulate", "p.toml", "-o", "x", "--seed", "-1"],
])
def test_options_out_of_range_are_refused_at_parse_time(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert "error: argument" in capsys.readouterr().err


START = {"latitude_deg": 40.0, "longitude_deg": 0.0, "height_m": 0.0, "speed_m_s": 100.0,
         "heading_deg": 0.0}


@pytest.mark.parametrize("start, segment, message", [
    ({"latitude_deg": "forty"}, {"kind": "hold", "duration_s": 10}, "a finite number"),
    ({"latitude_deg": float("nan")}, {"kind": "hold", "duration_s": 10}, "a finite number"),
    ({}, {"kind": "hold", "duration_s": 1e7}, r"outside \[0, 86400\]"),
    ({}, {"kind": "hold", "duraton_s": 10}, "unknown key"),
    ({"lattitude_deg": 3}, {"kind": "hold", "duration_s": 10}, "unknown key"),
    ({}, {"kind": "turn", "load_factor": 2, "heading_change_deg": 90, "roll_rate_deg_s": 0},
     r"outside \[0.001"),
    ({}, {"kind": "loop", "duration_s": 10}, "unknown kind"),
])
def test_profiles_with_impossible_values_are_refused(start, segment, message):
    doc = {"name": "x", "start": {**START, **start}, "segment": [segment]}
    with pytest.raises(ProfileError, match=message):
        Profile.from_dict(doc)


def test_demo_at_any_rate_ends_inside_the_profile(capsys):
    """The shipped high-dynamic profile at 100, 50 and 400 Hz (its 144.437 s is not a whole
    number of samples at any of them)."""
    for rate in ("100", "50", "400"):
        assert main(["demo", "flights/high-dynamic.toml", "--rate", rate]) == 0
    assert capsys.readouterr().out.count("end error") == 3


def test_a_new_users_slips_get_one_line_and_lose_nothing(good, tmp_path, capsys):
    """What a new user did on the foreign flights (exit 1 with a traceback, or a calibration
    overwritten): a log given where the calibration goes, a raw log's windows without
    --cal, an output stem that names an input, a run written over by its own fit."""
    good = str(good[0])
    cal = tmp_path / "x.cal.json"
    Calibration.identity().save(cal)
    kept = cal.read_bytes(), open(good, "rb").read()
    for argv, words in (
            (["replay", good, "--cal", good, "-o", str(tmp_path / "r")], "not a calibration"),
            (["diagnose", good, "--model", good], "not a calibration"),
            (["windows", good, "-o", str(tmp_path / "w")], "--cal CAL.json"),
            (["table", good, "--cal", f"a={cal}", "-o", str(cal)[:-5], "--force"],
             "would replace the input"),
            (["calibrate", good, "--method", "entire", "-o", good, "--force"],
             "would replace the input"),
            (["import", "rtklib", str(tmp_path / "nowhere"), "-o", str(tmp_path / "i.mcap")],
             "no such folder"),
            (["import", "rtklib", good, "-o", str(tmp_path / "i.mcap")],   # a file given
             "a file, not a folder")):
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1, (argv, err)
    assert (cal.read_bytes(), open(good, "rb").read()) == kept
    assert not (tmp_path / "r").exists() and not (tmp_path / "w").exists()


def test_an_initial_state_at_power_on_starts_the_first_interval(good):
    """A sample stamped t_k is the mean over (t_k-1, t_k]: a state at the left edge of the
    first interval (one step before the first stamp) is the flight's start, not an error;
    three steps before is (foreign-flights-2 class: initial_state.t = 0, first stamp dt)."""
    log, _ = good
    flight = Flight.load(log)
    t = flight.mimu_t
    step = t[1] - t[0]
    check_plausible(replace(flight, initial=replace(flight.initial, t=t[0] - step)))
    with pytest.raises(LogError, match="interval before the first"):
        check_plausible(replace(flight, initial=replace(flight.initial, t=t[0] - 3 * step)))


def test_a_shipped_flight_is_found_by_its_name_from_any_folder_and_a_ground_start_needs_one(
        tmp_path, monkeypatch, capsys):
    """`--flight flights/NAME.toml` as the help and the messages write it works outside the
    checkout; a name that is no file and no shipped profile is refused naming the shipped
    ones; a ground start of the default flight (it starts in the air) is refused before any
    work, naming the flight and what would do."""
    from mimunav import FLIGHTS
    from mimunav.cli import main
    from mimunav.cli.options import flight_path
    from mimunav.errors import InputError
    monkeypatch.chdir(tmp_path)
    assert flight_path("flights/boost-coast.toml") == FLIGHTS / "boost-coast.toml"
    with pytest.raises(InputError, match="no such file, nor a shipped profile.*boost-coast.toml"):
        flight_path("flights/no-such.toml")
    code = main(["reproduce", "--start", "ground", "-o", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert code == 2 and "flight high-dynamic: a ground start" in err and "250 m/s" in err
    assert not (tmp_path / "r").exists()                # refused before any work
    assert "boost-coast.toml" in err and "--start air" in err and "(in memory)" not in err

"""The level a recording is diagnosed at follows from what it is (`diagnosis.levels`,
`diagnosis.vehicle_kind`): the track level's vehicle model is a car's, a reference attitude
is used as attitude, and no navigation-level finding stands on an unmeasured heading. Found
on real recordings: the track level had been chosen for a rocket, a multicopter, a walk and a
car with a full attitude reference; the navigation level had named a 78 % accelerometer scale
on a walk aligned with "heading assumed 0"."""
from types import SimpleNamespace

import numpy as np
import pytest

from mimunav.diagnosis import levels, vehicle_kind
from mimunav.motion.trajectory import Trajectory

G = 9.80665


def _flight(v_ned, f=None, attitude=False, recording=None, dt=0.1):
    """A recording-like flight with a reference track of velocities v_ned (N, 3) every dt s
    and an IMU feeling f (N, 3) at the same stamps (default: 1 g, level)."""
    n = len(v_ned)
    t = np.arange(n) * dt
    q = np.full(n, np.quaternion(1, 0, 0, 0) if attitude else
                np.quaternion(np.nan, np.nan, np.nan, np.nan))
    truth = Trajectory(t, np.full(n, 0.7), np.zeros(n), np.zeros(n), np.asarray(v_ned, float), q)
    f = np.tile([0.0, 0.0, -G], (n, 1)) if f is None else f
    return SimpleNamespace(truth=truth, mimu_t=t, mimu_imu=(np.zeros((n, 3)), f),
                           recording=recording or {}, fog_t=None, mimu_raw=None,
                           source="recording")


def _ramp(n, top, axis=0):
    v = np.zeros((n, 3))
    v[:, axis] = top * np.clip(np.arange(n) / (0.1 * n), 0, 1)
    return v


def test_a_car_drive_is_judged_a_car_and_goes_to_the_track_level():
    flight = _flight(_ramp(3000, 15.0))
    kind, how, _ = vehicle_kind.kind(flight)
    assert kind == "car" and how.startswith("judged a car")
    assert levels.choose(flight)[0] == "track"


@pytest.mark.parametrize("what, v, f, says", [
    ("a walk", _ramp(3000, 1.4), None, "95th percentile is 1.4 m/s"),
    ("an airliner", _ramp(3000, 230.0), None, "99th percentile is 230 m/s"),
    ("a multicopter's climb on the spot", _ramp(3000, 3.0, axis=2) * -1, None,
     "while hardly moving horizontally"),
    ("a rocket's boost", np.column_stack([np.full(3000, 10.0), np.zeros(3000),
                                          -np.linspace(0, 300, 3000)]),
     np.tile([0.0, 0.0, -4 * G], (3000, 1)), "g off 1 g"),
])
def test_what_is_not_a_car_is_not_given_the_track_level(what, v, f, says):
    flight = _flight(v, f)
    kind, how, _ = vehicle_kind.kind(flight)
    assert kind == "other" and says in how, (what, how)
    level, why = levels.choose(flight)
    assert level == "navigation" and "not of a car" in why


def test_a_declared_vehicle_is_taken_and_an_attitude_reference_is_used_as_attitude():
    walk = _flight(_ramp(3000, 1.4), recording={"vehicle": "car"})
    assert levels.choose(walk)[0] == "track"            # declared: the user's word
    assert levels.choose(walk, vehicle="pedestrian")[0] == "navigation"
    car = _flight(_ramp(3000, 15.0), attitude=True)
    level, why = levels.choose(car)
    assert level == "navigation" and "carries the vehicle's attitude" in why


def test_a_car_declared_against_its_data_is_said_and_the_track_levels_findings_fall():
    """A motorcycle declared a car (--vehicle car): its track turns while its IMU feels none
    of that turn across its down (it leans into it) - the track level's no-lean model had
    charged the lean to the gyros, unsaid. The declaration is taken, and contradicted in
    words with the failed tests; a real car's declaration is not."""
    t = np.arange(3000) * 0.1
    yaw = 0.5 * np.sin(2 * np.pi * t / 20.0)
    v = 15.0 * np.column_stack([np.cos(yaw), np.sin(yaw), np.zeros_like(t)])
    bike = _flight(v)                                   # its IMU reads 1 g down only
    said = vehicle_kind.contradicted_car(vehicle_kind.kind(bike, "car"))
    assert said.startswith("declared car (--vehicle), but its track and IMU are not a car's")
    assert "across its down" in said and "none of its findings stands" in said
    car = _flight(_ramp(3000, 15.0))
    assert vehicle_kind.contradicted_car(vehicle_kind.kind(car, "car")) == ""
    assert vehicle_kind.contradicted_car(vehicle_kind.kind(bike, "train")) == ""
    parked = _flight(_ramp(3000, 0.3))                  # a car that hardly moved is a car
    assert vehicle_kind.kind(parked, "car").contradiction == ""


def _turning_car(n=3000, dt=0.1):
    """A car at 15 m/s weaving (2 m/s^2 peak lateral) whose IMU feels its turns sideways:
    velocities (N, 3) and specific force (N, 3) in a frame whose x is the course."""
    t = np.arange(n) * dt
    yaw = 0.5 * np.sin(2 * np.pi * t / 20.0)
    v = 15.0 * np.column_stack([np.cos(yaw), np.sin(yaw), np.zeros_like(t)])
    lateral = 15.0 * np.gradient(yaw, t)
    return v, np.column_stack([np.zeros_like(t), lateral, np.full_like(t, -G)])


@pytest.mark.parametrize("vehicle, says", [
    ("pedestrian", "no one walks or runs faster than"),
    ("aircraft", "as an aircraft's do that only taxied"), ("two-wheeler", "pass every test of a car's"),
    ("train", None), ("car", None)])
def test_a_declaration_the_track_and_imu_contradict_is_said(vehicle, says):
    """An independent trial declared its car drive a pedestrian (25 m/s, 3 m/s^2 turns felt
    sideways) and the declaration went unchecked: a car's drive declared anything but a car
    (or a train, whose track passes as a car's) is said to pass every car test, a walker at
    15 m/s is said too fast; the declaration itself is kept."""
    v, f = _turning_car()
    flight = _flight(v, f)
    kind, how, _ = vehicle_kind.kind(flight, vehicle)
    assert kind == vehicle
    assert (", but " in how) == (says is not None) and (says is None or says in how), how
    walk = _flight(_ramp(3000, 1.4))
    assert vehicle_kind.kind(walk, "pedestrian").contradiction == ""


@pytest.mark.parametrize("heading, vehicle, stands", [
    ("reference", "pedestrian", True), ("course", "car", True), ("course", "train", True),
    ("course", "two-wheeler", True),
    ("course", "pedestrian", False), ("assumed", "car", False)])
def test_a_navigation_finding_needs_a_measured_heading(heading, vehicle, stands):
    """A course is a heading for what moves along its forward axis - a car, a train on its
    rails, a two-wheeler (a declared train's had been refused as 'the heading of a car
    only')."""
    flight = _flight(_ramp(3000, 1.4), recording={"initial_heading": heading,
                                                   "vehicle": vehicle})
    why = levels.unmeasured_heading(flight)
    assert (why == "") == stands, why
    if not stands:
        assert "no finding is made" in why


def test_an_older_log_says_its_heading_in_words():
    said = {"assumed": {"initial_state": "rest assumed ...; heading assumed 0 (the track ...)"}}
    flight = _flight(_ramp(3000, 15.0), recording=said)
    assert "assumed: nothing measured it" in levels.unmeasured_heading(flight)


@pytest.mark.parametrize("independent, said", [
    ("yes: GNSS only", None), ("no: the autopilot fuses this IMU", "the autopilot fuses"),
    (None, "not stated")])
def test_nothing_found_against_a_reference_that_fuses_the_imu_is_no_clean_bill(
        monkeypatch, independent, said):
    """A recording's reference trajectory not stated independent of the IMU (an autopilot's
    or an optimiser's solution fuses it): finding nothing is inconclusive, saying why; a
    finding stands; a simulation's truth is independent by construction."""
    meta = {} if independent is None else {"independent": independent}
    flight = SimpleNamespace(source="recording", reference_meta=meta, recording={
        "initial_heading": "reference"})
    empty = SimpleNamespace(findings=[], inconclusive=[], rejected=[])
    monkeypatch.setattr(levels.navigation, "diagnose", lambda *a, **k: empty)
    diag = levels.diagnose(flight, None, "navigation")
    assert (said is None) == (not diag.inconclusive)
    if said:
        assert said in diag.inconclusive[0] and "not known to be independent" in \
            diag.inconclusive[0]
    found = SimpleNamespace(findings=[{"label": "x"}], inconclusive=[], rejected=[])
    monkeypatch.setattr(levels.navigation, "diagnose", lambda *a, **k: found)
    assert levels.diagnose(flight, None, "navigation").inconclusive == []
    assert levels.fused_reference(SimpleNamespace(source="simulation", reference_meta={})) == ""


def test_a_bias_found_on_a_recording_says_what_its_import_measured():
    """The light aircraft's accel.z bias: -0.319 m/s^2 against the VN-300's accelerometers,
    -0.178 from its import (against the VN-300's attitude and velocity) - the finding says
    the import's value and that the two references differ; not where the import took the
    biases as 0, nor where a rest leveled on the outputs could not see a horizontal one."""
    from types import SimpleNamespace

    from mimunav.compensation.calibration_file import Calibration
    from mimunav.diagnosis.levels import beside_the_imports_biases

    def flight(how):
        return SimpleNamespace(source="recording", recording={
            "assumed": {"initial_state": how}, "accel_bias_m_s2": [0.02, -0.04, -0.1776],
            "gyro_bias_static_rad_s": [1e-3, -1e-3, 3e-4]})

    def found():
        return [{"effect": "bias_shift", "sensor": "accel", "axis": "z", "units": "m/s^2",
                 "coefficient": -0.319},
                {"effect": "bias_instability", "sensor": "gyro", "axis": "x", "units": "rad/s"}]
    measured = found()
    beside_the_imports_biases(measured, flight(
        "no rest of 2 s ...: biases from the reference's attitude and velocity, the medians"),
        Calibration.identity())
    assert measured[0]["import_measured"]["value"] == -0.1776
    assert "against the reference IMU" in measured[0]["import_measured"]["basis"]
    assert "import_measured" not in measured[1]             # a wander is no constant
    for how in ("biases taken as 0: no rest", "biases from the rest 0.00-30.00 s (only the "
                "Earth rate's vertical part removed ...)"):
        unseen = found()
        beside_the_imports_biases(unseen, flight(how), Calibration.identity())
        assert "import_measured" not in unseen[0], how
    # what the metadata says the import measured (`bias_basis`): a rest's accelerometer bias
    # along gravity is an axis' own only on an axis near the vertical; a gyro's with the
    # Earth rate removed at the reference's attitude, not at an assumed heading
    rest = flight("biases from the rest 0.00-30.00 s (its Earth rate removed with the "
                  "reference's attitude)")
    rest.recording["bias_basis"] = {"gyro": "reference_attitude", "accel": "along_gravity",
                                    "gravity_sensor_axes": [0.02, -0.03, -0.9993]}
    both = found() + [{"effect": "bias_shift", "sensor": "accel", "axis": "x",
                       "units": "m/s^2"},
                      {"effect": "bias_shift", "sensor": "gyro", "axis": "y", "units": "rad/s"}]
    beside_the_imports_biases(both, rest, Calibration.identity())
    assert "along gravity" in both[0]["import_measured"]["basis"]
    assert "import_measured" not in both[2]             # horizontal: not measured at a rest
    assert both[3]["import_measured"]["value"] == -1e-3
    rest.recording["bias_basis"]["gyro"] = "vertical_earth_rate"
    rest.recording["bias_basis"]["gravity_sensor_axes"] = [0.2, 0.0, -0.98]    # 11.5 deg
    tilted = found() + [dict(both[3])]
    tilted[2].pop("import_measured", None)
    beside_the_imports_biases(tilted, rest, Calibration.identity())
    assert not any("import_measured" in f for f in tilted)
    # a cut log: the biases in its metadata are the import's, judged by the import's own
    # alignment, not by the span's (which said nothing of them)
    cut = flight("the alignment redone on the span: ... biases taken as 0: no rest")
    cut.recording["assumed"]["import_initial_state"] = \
        "no rest of 2 s ...: biases from the reference's attitude and velocity"
    kept = found()
    beside_the_imports_biases(kept, cut, Calibration.identity())
    assert kept[0]["import_measured"]["value"] == -0.1776


def test_a_mounting_beyond_the_small_angle_term_is_judged_by_the_imports_yaw():
    """The small-angle mounting term fitted beyond its 20 deg range: where the import
    measured a yaw against the course beyond that range, the diagnosis names it (the mounting
    given is off); where the import measured one within it, the fit's size is not the
    mounting's where the fit turns about down (an independent drive under 0.5 m fixes fitted a
    true 10 deg yaw as 33 deg), while a fit about the level axes may be a tilt the import
    does not measure; without such a term, or without the import's measure, nothing is
    added."""
    import json
    beyond = [{"effect": "mounting_misalignment", "beyond_range": 0.35,
               "vector_vehicle": [0.05, 0.1, 0.5]}]               # mostly about down
    flight = lambda yaw: SimpleNamespace(recording={"real": json.dumps(   # noqa: E731
        {"mounting_yaw_against_course": f"{yaw:+.1f} deg about the vehicle's down axis"})})
    said = vehicle_kind.mounting_beyond_range(beyond, flight(-29.7))
    assert len(said) == 1 and "off by more than the diagnosis fits" in said[0]
    said = vehicle_kind.mounting_beyond_range(beyond, flight(10.1))
    assert len(said) == 1 and "not the mounting's" in said[0] and "+10.1 deg" in said[0]
    # a fit mostly about the level axes (a cradle tilted back 30 deg): the import's yaw
    # says nothing of it - the tilt may be the cause, not only the reference
    tilted = [dict(beyond[0], vector_vehicle=[0.0, 0.52, 0.01])]
    said = vehicle_kind.mounting_beyond_range(tilted, flight(1.0))
    assert "measures nothing of its roll and pitch" in said[0] and "tilted" in said[0]
    assert vehicle_kind.mounting_beyond_range([{"effect": "lever_arm", "beyond_range": 1}],
                                              flight(-29.7)) == []
    assert vehicle_kind.mounting_beyond_range(beyond, SimpleNamespace(recording={})) == []


def test_a_lever_arm_against_a_trajectory_is_reported_in_the_vehicle_frame():
    """The navigation level fits a lever arm in the sensor axes; it is reported, with its
    interval, in the vehicle frame of the metadata's lever_arm_m (a boat's IMU declared FLU:
    [1.2, -0.4, 0.6] sensor is [1.2, 0.4, -0.6] FRD - read as FRD the signs of y and z had
    looked wrong), the sensor-axes vector kept for the compensation; and its physical range
    is the vehicle's size (10 m), not the 1 m a unit beside a reference IMU may be off (a
    found 1.4 m boat lever arm had been refused)."""
    from mimunav.diagnosis import library, navigation
    from mimunav.frames.mounting import Mounting
    q_vs = Mounting.from_axes("FLU").q_vs
    finding = {"effect": "lever_arm", "sensor": "imu", "axis": "all",
               "vector": [1.2, -0.4, 0.6], "coefficient": 1.2,
               "vector_ci95": [[1.1, 1.3], [-0.5, -0.3], [0.55, 0.65]]}
    turned = navigation.in_vehicle_frame(finding, q_vs)
    assert turned["frame"] == "vehicle" and turned["vector_sensor_axes"] == [1.2, -0.4, 0.6]
    assert np.allclose(turned["vector"], [1.2, 0.4, -0.6])
    assert np.allclose(turned["vector_ci95"], [[1.1, 1.3], [0.3, 0.5], [-0.65, -0.55]])
    assert navigation.in_vehicle_frame(turned, q_vs) is turned
    limit = navigation.physical_limits(SimpleNamespace(mimu_range={}),
                                       SimpleNamespace(is_identity=True))
    assert limit({"effect": "lever_arm", "sensor": "imu"}) == library.TRAJECTORY_LEVER_ARM
    assert library.physical_limit({"effect": "lever_arm", "sensor": "imu"}, {}) == 1.0


def test_a_pair_without_a_trajectory_is_sent_to_the_sensor_level(tmp_path):
    """A rate table's two IMUs and no GNSS: --level navigation is refused naming the level
    that works on it (it had said 'and no /fog/imu for the sensor level' of a log with one)."""
    from mimunav.errors import InputError
    from mimunav.frames.mounting import Mounting
    from mimunav.importers.recording import Recording
    from mimunav.importers.write import write_log
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 60.0, 0.01)
    w = np.column_stack([0.3 * np.sin(0.7 * t), 0.2 * np.cos(0.3 * t), 0.5 * np.sin(0.1 * t)])
    f = np.tile([0.0, 0.0, -9.81], (len(t), 1))
    ns = 1_700_000_000_000_000_000 + np.round(t * 1e9).astype(np.int64)
    rec = Recording("pair", "test", ns, w + rng.normal(0, 1e-3, w.shape), f, Mounting(),
                    reference_imu=dict(ns=ns, w=w, f=f, mounting=Mounting(), model="fog"))
    write_log(rec, tmp_path / "pair.mcap")
    with pytest.raises(InputError, match="navigation level: --level sensor diagnoses it"):
        levels.load(tmp_path / "pair.mcap", level="navigation")


def test_a_bias_on_an_axis_that_reads_gravity_says_a_scale_error_is_in_it():
    """A rail car's accel.z reads -9.81 m/s^2 give or take 0.03: a bias b and a scale error k
    of it are one number there, b + k (-9.81) (its 0.20 m/s^2 bias with +0.4 % read 0.161).
    The finding says so, with the mean and spread of its input; a level axis' bias does
    not, nor a bias whose axis' scale was found beside it."""
    from mimunav.diagnosis.document import scale_alike_text
    from mimunav.diagnosis.levels import beside_the_scales
    rng = np.random.default_rng(2)
    inputs = np.column_stack([rng.normal(0, 0.3, 1000), rng.normal(0, 0.3, 1000),
                              -9.81 + rng.normal(0, 0.03, 1000), np.zeros((1000, 3))])
    found = [{"effect": "bias_shift", "sensor": "accel", "axis": a} for a in "xz"]
    beside_the_scales(found, inputs)
    assert "scale_alike" not in found[0]
    alike = found[1]["scale_alike"]
    assert alike["mean_input_m_s2"] == pytest.approx(-9.81, abs=0.01)
    assert alike["spread_m_s2"] == pytest.approx(0.03, rel=0.1)
    assert "k x -9.81" in scale_alike_text(alike) and "0.049 m/s^2" in scale_alike_text(alike)
    with_scale = [{"effect": "bias_shift", "sensor": "accel", "axis": "z"},
                  {"effect": "scale_factor", "sensor": "accel", "axis": "z"}]
    beside_the_scales(with_scale, inputs)
    assert "scale_alike" not in with_scale[0]


def test_a_rectification_beside_vibration_below_its_corner_says_its_band():
    """A helicopter's reference: a 6.6 Hz once-per-rev and a 26.4 Hz line. The regressor
    of a vibration rectification is the power above 10 Hz; the rest of the vibration
    rectifying reads into its coefficient (0.0096 found where 0.008 of the whole was
    hidden): the finding says its band and the share below it. A rotor at 26.4 Hz alone
    leaves nothing below the corner: nothing said."""
    from mimunav.diagnosis.document import band_text
    t = np.arange(0.0, 120.0, 0.005)
    f = np.zeros((len(t), 3))
    f[:, 2] = -9.81 + 1.5 * np.sin(2 * np.pi * 6.6 * t) + 0.8 * np.sin(2 * np.pi * 26.4 * t)
    found = [{"effect": "vibration_rectification", "sensor": "accel", "axis": "z"},
             {"effect": "bias_shift", "sensor": "accel", "axis": "z"}]
    levels.beside_the_band(found, SimpleNamespace(fog_t=t, fog_f=f))
    band = found[0]["band_left_out"]
    assert band["line_hz"] == pytest.approx(6.6, abs=0.1) and band["share"] == \
        pytest.approx(1.5 ** 2 / (1.5 ** 2 + 0.8 ** 2), abs=0.02)
    assert "per the vibration power above 10 Hz" in band_text(band)
    assert "band_left_out" not in found[1]
    f[:, 2] = -9.81 + 0.8 * np.sin(2 * np.pi * 26.4 * t)
    alone = [{"effect": "vibration_rectification", "sensor": "accel", "axis": "z"}]
    levels.beside_the_band(alone, SimpleNamespace(fog_t=t, fog_f=f))
    assert "band_left_out" not in alone[0]


def test_findings_beside_a_clock_the_import_could_not_decide_are_set_aside():
    """A train's IMU 1.5 s off its reference, the import's clock search not decided and the
    stamps kept as given: the sensor level had named a 3.5 deg mounting and an accel.x offset
    of -0.54 m/s^2 (truth: the mounting exact, the offset 0.012) and never the clock. Every
    finding is set aside with the import's words and the option that gives the clock, and
    so are its excursions (one of z -48.5 there); where the import left nothing open (the
    data peak at the stamps given) nothing is set aside."""
    found = [{"effect": "mounting_misalignment", "sensor": "imu", "axis": "all"}]
    said = "not decided (the two IMUs (|w|) correlate 0.93 ...)"
    spans = [{"channel": "accel.x", "t0": 40.1, "t1": 42.1, "z": -48.5}]
    diag = SimpleNamespace(findings=list(found), rejected=[], inconclusive=[], unexplained=spans)
    levels.set_aside_undecided_clock(diag, SimpleNamespace(recording={
        "reference_imu_clock_open": said}))
    assert diag.findings == [] and diag.rejected[0]["effect"] == "mounting_misalignment"
    (why,) = diag.inconclusive
    assert said in why and "--reference-imu-time-offset" in why
    assert diag.unexplained == [] and why.endswith(
        "; its 1 excursion(s) set aside with it (accel.x 40.1-42.1 s)")    # a wrong clock's
    kept = SimpleNamespace(findings=list(found), rejected=[], inconclusive=[])
    levels.set_aside_undecided_clock(kept, SimpleNamespace(recording={
        "reference_imu_clock_open": ""}))
    assert kept.findings == found and kept.inconclusive == []


def test_accelerometer_findings_beside_an_arm_beyond_range_between_imus_at_one_point():
    """A train's cab IMU 8.3 m from its INS, no arm given: beside the arm fitted beyond range
    a time skew of -0.2 s had been named on the accelerometers. Those findings (and the
    unit's) are set aside with the arm's words, the accelerometers' excursions named at its
    end; the gyros' stay. With an arm given, fitted beyond range, it is off by that much:
    set aside too, saying so (a flight's reference declared 5 m off had had an accelerometer
    time skew named beside it)."""
    from mimunav.frames.mounting import Mounting
    arm = {"effect": "lever_arm", "sensor": "imu", "axis": "all", "label": "lever_arm imu.all",
           "beyond_range": 1.0, "rejected": "significant on the training half (p 0) at 8.3 m"}
    skew = {"effect": "time_skew", "sensor": "accel", "axis": "all"}
    gyro = {"effect": "bias_shift", "sensor": "gyro", "axis": "x"}
    def flight(arm_m):
        return SimpleNamespace(mimu_mounting=Mounting(lever_arm_m=arm_m), fog_mounting=Mounting())
    spans = [{"channel": "accel.x", "t0": 40.0, "t1": 42.0}, {"channel": "gyro.z", "t0": 9.0,
                                                              "t1": 11.0}]
    from mimunav.diagnosis.library import apart_reasons
    (reason,) = apart_reasons([arm], flight([0.0, 0.0, 0.0]))
    diag = SimpleNamespace(findings=[skew, gyro], rejected=[arm], inconclusive=[],
                           unexplained=list(spans))
    levels.set_aside_apart(diag, flight([0.0, 0.0, 0.0]))
    assert diag.findings == [gyro] and diag.rejected[0] is arm
    assert diag.unexplained == spans[1:] and diag.inconclusive == [
        reason + "; its 1 excursion(s) set aside with it (accel.x 40.0-42.0 s)"]
    (aside,) = diag.rejected[1:]
    assert aside["effect"] == "time_skew" and aside["rejected"].endswith(
        "no lever arm was given between the two IMUs")
    given = SimpleNamespace(findings=[skew, gyro], rejected=[arm], inconclusive=[])
    levels.set_aside_apart(given, flight([8.0, 0.0, 0.0]))
    assert given.findings == [gyro] and given.rejected[0] is arm
    assert given.rejected[1]["rejected"].endswith(
        "the lever arm given between the two IMUs is off by that much")


def test_a_clock_timed_by_the_same_motions_leaves_the_latency_untested():
    """Where the import timed the reference IMU by the motions the diagnosis reads (a clock
    nuisance) and nothing is found, the MIMU's latency went into that clock: inconclusive,
    saying so (a motorcycle's MEMS 30 ms late had read no-missing-physics). A finding
    stands on its own, the latency said untested beside the clock (a phone 20 ms late had
    gone unsaid); without a clock fitted there is nothing to say."""
    from types import SimpleNamespace
    for findings, fitted, said in (([], True, True), ([{"label": "x"}], True, False),
                                   ([], False, False)):
        clock = {"import_1sigma_s": 2.7e-5} if fitted else None
        diag = SimpleNamespace(reference_clock=clock, findings=findings, inconclusive=[])
        levels.latency_untested(diag)
        assert bool(diag.inconclusive) == said
        assert not said or "latency against the reference IMU) is not tested" in \
            diag.inconclusive[0]
        assert ("is not tested" in clock.get("latency", "")) == bool(fitted and findings) \
            if fitted else True


def test_a_lag_the_import_left_as_latency_stops_the_navigation_level():
    """The import measured the reference trajectory 0.2 s late and left it as the IMU's
    latency (`reference_clock_unapplied_s`): the navigation level cannot test a time skew,
    so its findings are set aside and the verdict is inconclusive, naming the offset that
    takes it out (a mocap pose 0.2 s late had a g2_sensitivity blamed); the windows say
    the lag is in their errors, with the --time-shift that removes it, unless one is given."""
    from types import SimpleNamespace
    from mimunav.reports.windows import doubts
    flight = SimpleNamespace(recording={"reference_clock_unapplied_s": 0.2})
    diag = SimpleNamespace(findings=[{"label": "x"}], rejected=[], inconclusive=[])
    levels.set_aside_unapplied_lag(diag, flight)
    assert not diag.findings and diag.rejected[0]["rejected"] == diag.inconclusive[0]
    assert "200 ms late" in diag.inconclusive[0] and "--reference-time-offset" in \
        diag.inconclusive[0]
    said = doubts(flight, 0.0)
    assert len(said) == 1 and "--time-shift +0.200" in said[0]
    assert doubts(flight, 0.2) == []
    clean = SimpleNamespace(findings=[{"label": "x"}], rejected=[], inconclusive=[])
    levels.set_aside_unapplied_lag(clean, SimpleNamespace(recording={}))
    assert clean.findings and not clean.inconclusive

"""Diagnosis: the effect regressors and the reference transfer against exact truth, the
found-term compensation, the command's contract output, the foreign flights of an independent
simulator (development set), and the concealed-data proof in its reduced (CI) form: the
required effects hidden one per recording (one outside the vocabulary), plus nulls."""
import json
import math
import os
from types import SimpleNamespace

import numpy as np
import quaternion
import pytest

from mimunav.frames import attitude
from mimunav.compensation import effects
from mimunav.sensors import simulation
from mimunav.cli import main
from mimunav.cli.diagnosis import finding_line, not_confirmed_lines, set_aside_line
from mimunav.compensation.calibration_file import Calibration
from mimunav.compensation.model import CalibrationError, compensate
from mimunav.diagnosis import concealed
from mimunav.diagnosis.reference import predicted_mimu
from mimunav.motion.profile import Profile
from mimunav.frames.mounting import Mounting
from mimunav.sensors.hidden import HiddenPhysics
from places import FLIGHTS, SHARED

PROOF = str(FLIGHTS / "diagnosis-proof.toml")
# the navigation level (velocity error over minutes, contiguous tenths) on repeated blocks
BLOCKS = str(FLIGHTS / "repeated-blocks.toml")
PULL_ROLL = {"name": "pull-roll", "start": {
    "latitude_deg": 30.0, "longitude_deg": 104.0, "height_m": 1000.0, "speed_m_s": 200.0,
    "heading_deg": 45.0}, "segment": [
        {"kind": "pull", "load_factor": 3.0, "flight_path_change_deg": 15.0},
        {"kind": "roll", "rate_deg_s": 240.0, "angle_deg": 360.0},
        {"kind": "hold", "duration_s": 2.0}]}


def _ideal(mounting, fm_kwargs=None):
    """Exact interval-mean (t, f, w) of a sensor at `mounting` on the pull-roll, 1 kHz."""
    fm = simulation.flight_motion(Profile.from_dict(PULL_ROLL), mounting, 1000.0,
                                  Mounting(), 1000.0, 100.0)
    t, dth, dv = fm.mimu
    return t, dv * 1000.0, dth * 1000.0, fm


def test_reference_moved_to_the_mimu_mounting_matches_its_exact_increments():
    """FOG at the origin, MIMU turned (30, 20, 45 deg) and 0.33 m away, a 3 g pull and a
    240 deg/s roll: the transferred FOG output equals the MIMU's exact interval means to
    the derivative's accuracy (the lever-arm terms reach 0.2 g here; the 100 ms derivative
    window, set against the FOG's quantization noise, leaves up to 0.5 mg at the ends of the
    roll ramps and under 0.1 mg rms)."""
    q = attitude.from_euler(*np.radians([30.0, 20.0, 45.0]))
    mount = Mounting(np.asarray(q.components), [0.30, -0.10, 0.05])
    t, f, w, fm = _ideal(mount)
    _, dth_fog, dv_fog = fm.fog
    flight = SimpleNamespace(path="x", mimu_t=t, mimu_mounting=mount, fog_t=fm.fog[0],
                             fog_w=dth_fog * 1000.0, fog_f=dv_fog * 1000.0, fog_mounting=Mounting(),
                             source="simulation", mimu_lag_s=(0.0, 0.0))
    f_p, w_p, inside = predicted_mimu(flight)
    k = inside & (t > 0.1) & (t < t[-1] - 0.1)
    assert np.abs(w_p[k] - w[k]).max() < 1e-9
    err = np.abs(f_p[k] - f[k]).max(axis=1)
    assert err.max() < 5e-3 and np.sqrt(np.mean(err ** 2)) < 1e-3       # 0.5 mg, 0.1 mg rms
    centripetal = np.linalg.norm(f[k] - attitude.rotate(np.conjugate(mount.q_vs), dv_fog[k] * 1000.0),
                                 axis=1).max()
    assert centripetal > 1.5


def test_size_effect_regressor_equals_an_exactly_simulated_proof_mass_offset():
    """An accelerometer 8 mm off the sensor origin, simulated exactly (truth increments at
    the moved point), against the effects regressor K r built from the rates."""
    r = np.array([0.004, -0.006, 0.003])
    base, moved = Mounting(lever_arm_m=[0.2, 0.0, 0.0]), Mounting(lever_arm_m=[0.2, 0.0, 0.0] + r)
    t, f0, w, _ = _ideal(base)
    _, f1, _, _ = _ideal(moved)
    cond = effects.Conditions.from_outputs(t, f0, w, np.zeros((len(t), 3)), np.zeros((len(t), 3)))
    for i, axis in enumerate("xyz"):
        cols = effects.regressor({"effect": "size_effect", "sensor": "accel", "axis": axis},
                                 cond)[("accel", i)]
        k = slice(100, -100)
        assert np.abs((cols @ r)[k] - (f1 - f0)[k, i]).max() < 1e-3 * np.abs(f1 - f0).max() + 1e-5


def test_mounting_misalignment_is_the_exact_rotation_of_the_mounting():
    """A sensor mounted 7 deg off (q_vs = q_vs,nominal exp(phi/2)), simulated exactly: the
    effect applied to the nominal outputs reproduces it to round-off, removing it restores the
    nominal ones, and the regressor is its first order (phi^2 / 2 of the input left)."""
    phi = np.radians([1.0, -6.8, 5.3])
    base = Mounting()
    moved = Mounting(quaternion.as_float_array(base.q_vs * quaternion.from_rotation_vector(phi)))
    t, f0, w0, _ = _ideal(base)
    _, f1, w1, _ = _ideal(moved)
    zeros = np.zeros((len(t), 3))
    term = {"effect": "mounting_misalignment", "sensor": "imu", "axis": "all",
            "vector": phi.tolist()}
    f, w = effects.apply([term], effects.Conditions.from_outputs(t, f0, w0, zeros, zeros))
    assert np.abs(f - f1).max() < 1e-9 and np.abs(w - w1).max() < 1e-9
    back = effects.apply([term], effects.Conditions.from_outputs(t, f1, w1, zeros, zeros), -1.0)
    assert np.abs(back[0] - f0).max() < 1e-9 and np.abs(back[1] - w0).max() < 1e-9
    cond = effects.Conditions.from_outputs(t, f0, w0, zeros, zeros)
    first = f0 + np.column_stack([effects.regressor(term, cond)[("accel", i)] @ phi
                                  for i in range(3)])
    assert np.abs(first - f1).max() < 0.6 * np.linalg.norm(phi) ** 2 * np.abs(f0).max()


def test_a_mounting_finding_gives_its_turn_about_the_vehicle_axes_too():
    """A sensor turned by phi about its own axes (q_vs exp(phi/2), the contract's vector) is
    the vehicle's axes turned by C_vs phi (exp(phi_v/2) q_vs): the finding carries both, the
    vehicle's with its interval by the same covariance turned, computed here by quaternion
    composition on a mounting with no symmetry (3, -2, 95 deg: C_vs and its transpose
    differ), and the terminal line says which axes each is about."""
    from mimunav.diagnosis.confirmation import interval_estimate
    q_vs = Mounting.from_rpy_deg((3.0, -2.0, 95.0)).q_vs
    phi = np.radians([0.4, -1.1, 2.3])
    term = {"effect": "mounting_misalignment", "sensor": "imu", "axis": "all"}
    cov = np.diag(np.radians([0.1, 0.2, 0.3]) ** 2)
    found = interval_estimate(SimpleNamespace(q_vs=quaternion.as_float_array(q_vs)), term, phi, cov)
    phi_v = quaternion.as_rotation_vector(q_vs * quaternion.from_rotation_vector(phi)
                                          * q_vs.conjugate())
    assert found["frame"] == "sensor" and np.allclose(found["vector"], phi)
    assert np.abs(np.asarray(found["vector_vehicle"]) - phi_v).max() < 1e-12
    half = np.diff(np.asarray(found["vector_vehicle_ci95"]), axis=1)[:, 0] / 2
    c_vs = quaternion.as_rotation_matrix(q_vs)
    assert np.allclose(half, 1.96 * np.sqrt(np.diag(c_vs @ cov @ c_vs.T)))
    line = finding_line(dict(found, label="mounting_misalignment imu.all", p_heldout=1e-9))
    assert "(rad, sensor axes x, y, z)" in line
    assert f"forward, right, down axes {np.degrees(phi_v[0]):+.2f} deg" in line
    # the headline's coefficient is the largest component (the contract's), said so beside
    # the vector's size (a lever arm's z had read as its size)
    assert f"its largest component, of a vector of size {np.linalg.norm(phi):.4g} rad" in line


def test_the_terminal_names_the_terms_not_confirmed_and_why():
    """A recording with a finding kept, one term set aside by its library check (the RTKLIB
    drive's kind) and one beyond its physical range (comma2k19's accel.x scale at the track
    level): the terminal names both and why; what the inconclusive reasons already say is
    not said twice - the terms set aside for it are named in one line."""
    aside = {"label": "scale_factor accel.x", "coefficient": 0.04,
             "library_inflation": {"lambda": 8.4, "widened_by": 2.9},
             "rejected": "its interval widened 2.90x holds zero - inconclusive"}
    other = {"label": "scale_factor accel.y", "rejected": "held-out magnitude 0.0566 beyond "
                                                          "the physical range 0.05"}
    doc = {"findings": [{"label": "mounting_misalignment imu.all"}],
           "not_confirmed": [aside, other], "inconclusive_reasons": ["the library stands out"]}
    assert not_confirmed_lines(doc) == [
        "  not confirmed: scale_factor accel.x: its interval widened 2.90x holds zero - "
        "inconclusive",
        "  not confirmed: scale_factor accel.y: held-out magnitude 0.0566 beyond the physical "
        "range 0.05"]
    doc = dict(doc, findings=[], inconclusive_reasons=[
        "scale_factor accel.x: its interval widened 2.90x holds zero - inconclusive"])
    assert not_confirmed_lines(doc)[1:] == [
        "  not confirmed, for a reason the diagnosis is inconclusive: scale_factor accel.x"]


def test_a_set_aside_term_is_said_with_the_sigma_its_test_used():
    """foreign-06's gyro.z scale, set aside at -0.0018: the reference's stated 1 sigma along it
    is 0.00025 (7 times smaller), the test's 1 sigma with the reference's and the
    calibration's priors 0.00131 - the line must quote the latter, which decided it (it had
    quoted only the former: 'within the reference's stated accuracy (1 sigma 0.00025)')."""
    w = {"label": "scale_factor gyro.z", "coefficient": -0.001794855749895373,
         "reference_1sigma": [0.00025], "total_1sigma": [0.0013103030530459633],
         "p_train": 0.0002312278746599149}
    line = set_aside_line(w)
    assert "-0.001795" in line and "p 0.00023" in line
    first, said = line.split("\n")
    assert "the reference's (1 sigma 0.00025)" in first and first.endswith("its 1 sigma is 0.00131")
    # and it says plainly that the two IMUs disagree, what accuracy would charge it, and
    # the option that states the reference's (a KAIST-layout drive's gyro.z scale, set aside
    # within the track level's assumed vehicle model, had named none)
    option = ("; where the reference's errors are known better, --reference-accuracy states "
              "them")
    assert said.strip() == "the MIMU and the reference disagree along it" + option
    line = set_aside_line(dict(w, charged_at_accuracy=0.033, charged_at_1sigma=[8.3e-6]))
    assert line.endswith("it would pass the selection's test with the reference's and the "
                         "calibration's stated linear errors together at 0.033 of the stated "
                         "(1 sigma 8.3e-06)" + option)
    line = set_aside_line(dict(w, charged_at_accuracy=0.033, charged_at_1sigma=[8.3e-6],
                               charged_at_monotone=False))
    assert line.endswith("though not at every smaller value (the test is not monotone here)"
                         + option)
    assert "even 1e4 times smaller it would not pass" in set_aside_line(
        dict(w, charged_at_accuracy=0.0, charged_at_1sigma=[0.0]))
    # a 1 sigma beyond the term's physical range is a term the flight cannot identify (a
    # balloon's accel.z asymmetry at 1 sigma 531 had read as within the stated errors)
    assert "physical range" not in set_aside_line(dict(w, physical_range=0.05))
    first = set_aside_line(dict(w, total_1sigma=[531.0], physical_range=0.01)).split("\n")[0]
    assert first.endswith("its 1 sigma is 531, beyond its physical range 0.01: the flight "
                          "cannot identify it")
    # a term the model carries (g-sensitivity), set aside against the calibration's own
    # covariance: that is the stated sigma, not the reference's
    line = set_aside_line({"label": "g_sensitivity gyro.x <- f_z", "coefficient": 2e-5,
                           "calibration_1sigma": [1e-5], "total_1sigma": [1.2e-5],
                           "p_train": 1e-4})
    first = line.split("\n")[0]
    assert "reference" not in first and "covariance (1 sigma 1e-05)" in first
    # a term no smaller stated error lets pass (a hexacopter's gyro.x x^2 beside the clock:
    # its likelihood ratio and its estimate's Wald test disagree) is not said to be within
    # the stated errors
    line = set_aside_line({"label": "scale_nonlinearity gyro.x (x^2)", "coefficient": 0.00127,
                           "clock_1sigma_s": [6.9e-5], "total_1sigma": [0.000565],
                           "p_train": 0.00024, "charged_at_accuracy": 0.0,
                           "charged_at_1sigma": [0.0]})
    assert line.startswith("  set aside: scale_nonlinearity gyro.x (x^2) 0.00127: its "
                           "likelihood ratio against the noise alone is significant (p 0.00024)")
    assert line.endswith("the two tests disagree on this flight - not a finding")


def test_time_shift_is_exact_for_linear_motion_and_has_the_contract_sign():
    t = np.arange(1, 2001) / 1000.0
    rate = 0.5 + 3.0 * (t - 0.0005)[:, None] * np.array([1.0, -2.0, 0.5])  # interval means of a ramp
    tau = 0.0007
    lagged = effects.shift(t, rate, tau)
    expect = 0.5 + 3.0 * (t - 0.0005 - tau)[:, None] * np.array([1.0, -2.0, 0.5])
    assert np.abs(lagged[5:] - expect[5:]).max() < 1e-10
    # the regressor: lagged - true = tau * (-dx/dt), coefficient tau > 0 for a lag
    cond = effects.Conditions.from_outputs(t, rate, rate, rate, rate)
    col = effects.regressor({"effect": "time_skew", "sensor": "accel", "axis": "all"}, cond)
    assert np.allclose(col[("accel", 0)][10:-10, 0] * tau, (lagged - rate)[10:-10, 0], atol=1e-12)


def test_found_terms_round_trip_and_remove_the_effect_they_name():
    """A noise-free unit with a hidden g-sensitivity: its own model leaves the term in the
    output; model + found term removes it to rounding."""
    from mimunav.sensors.mimu import MimuUnit
    from mimunav.sensors.mimu import NoiseModel
    unit = MimuUnit.draw(3, beyond_model=False)
    unit.noise = NoiseModel(*(0.0,) * 6)
    unit.thermal.thermistor_noise = unit.thermal.frequency_noise = 0.0
    unit.adc_lsb = 0.0
    term = {"effect": "g_sensitivity", "sensor": "gyro", "axis": "y", "input_axis": "z",
            "coefficient": 4e-5}
    t, f, w, fm = _ideal(unit.mounting)
    raw = unit.simulate(t, w / 1000.0, f / 1000.0, np.full(len(t), 20.0),
                        np.random.default_rng(0), hidden=HiddenPhysics(term))
    doc = unit.coefficients.as_dict()
    doc.update(model="entire-63+found", found=[term])
    cal = Calibration.from_dict(json.loads(json.dumps(doc)))
    assert Calibration.from_dict(cal.as_dict()).found == [term]
    args = [raw[k] for k in ("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency")]
    _, w_model, _ = compensate(unit.coefficients, *args, t=t)
    _, w_found, _ = compensate(cal, *args, t=t)
    k = slice(1, None)
    assert np.abs(w_model[k, 1] - w[k, 1]).max() > 1e-3           # 3 g x 4e-5
    assert np.abs(w_found[k] - w[k]).max() < 1e-9
    bad = dict(doc, found=[dict(term, effect="warp_drive")])
    with pytest.raises(CalibrationError, match="found\\[0\\]"):
        Calibration.from_dict(bad)


@pytest.fixture(scope="module")
def skewed_log(tmp_path_factory):
    """A proof-flight log with a hidden 0.6 ms time skew, and the unit's own model."""
    from mimunav.sensors.mimu import MimuUnit
    d = tmp_path_factory.mktemp("diag")
    unit = MimuUnit.draw(11)
    unit.mounting = concealed.proof_mounting()
    hidden = {"effect": "time_skew", "sensor": "imu", "axis": "all", "coefficient": 6e-4}
    log, truth = simulation.simulate_flight(Profile.load(PROOF), d / "f.mcap", 11, unit=unit,
                                            hide=[hidden], progress=False)
    unit.coefficients.save(str(d / "model.json"))
    return d, log, truth


@pytest.mark.slow
def test_diagnose_command_writes_the_contract_and_a_report(skewed_log, capsys):
    d, log, truth_file = skewed_log
    with open(log, "rb") as fh:                  # the log hides the effect
        assert b"time_skew" not in fh.read()
    assert json.load(open(truth_file))["hidden"][0]["effect"] == "time_skew"
    rc = main(["diagnose", str(log), "--model", str(d / "model.json"), "--json",
               str(d / "out.json"), "-o", str(d / "report")])
    assert rc == 0
    doc = json.load(open(d / "out.json"))
    assert doc["format"] == "mimunav-diagnosis/1" and doc["verdict"] == "missing-physics"
    f = doc["findings"][0]
    for key in ("effect", "sensor", "axis", "coefficient", "ci95", "units", "where", "fit"):
        assert key in f
    assert (f["effect"], f["sensor"], f["axis"], f["units"]) == ("time_skew", "imu", "all", "s")
    assert f["ci95"][0] <= 6e-4 <= f["ci95"][1]
    assert all(set(w) >= {"t0", "t1", "condition"} for w in f["where"])
    fit = f["fit"]
    assert fit["heldout_rms_after"] < fit["heldout_rms_before"]
    for name in ("diagnosis.md", "residual-map.png", "timeline.png", "navigation.png",
                 "CAL+found.json", "diagnosis.json"):
        assert (d / "report" / name).exists(), name
    found = Calibration.load(str(d / "report" / "CAL+found.json"))
    assert found.model == "entire-63+found" and found.found[0]["effect"] == "time_skew"
    assert main(["table", str(log), "--cal", f"model={d / 'model.json'}",
                 "--cal", f"found={d / 'report' / 'CAL+found.json'}"]) == 0
    # without the FOG-IMU: the navigation level, from the truth trajectory
    rc = main(["diagnose", str(log), "--model", str(d / "model.json"), "--level", "navigation",
               "--json", str(d / "nav.json"), "-o", str(d / "nav")])
    doc = json.load(open(d / "nav.json"))
    assert rc == 0 and doc["level"] == "navigation" and doc["format"] == "mimunav-diagnosis/1"
    for name in ("diagnosis.md", "timeline.png", "navigation.png", "diagnosis.json"):
        assert (d / "nav" / name).exists(), name
    # outputs are never overwritten silently
    assert main(["diagnose", str(log), "--model", str(d / "model.json"), "--json",
                 str(d / "out.json")]) == 2
    assert "exists" in capsys.readouterr().err


def test_the_terminal_names_what_a_finding_is_not_told_apart_from():
    f = {"label": "scale_nonlinearity gyro.x (x^2)", "coefficient": 5.35e-5,
         "units": "1/(rad/s)", "ci95": [3.0e-5, 7.7e-5], "p_heldout": 9.8e-6,
         "attribution": "mimu", "indistinguishable_from": [
             {"effect": "scale_asymmetry", "sensor": "gyro", "axis": "x",
              "label": "scale_asymmetry gyro.x"}]}
    first, second = finding_line(f).splitlines()
    assert first.startswith("  scale_nonlinearity gyro.x (x^2): 5.35e-05 1/(rad/s) [3e-05, 7.7e-05]")
    assert second == "    not told apart on this flight from scale_asymmetry gyro.x"
    f["indistinguishable_from"] = []
    assert len(finding_line(f).splitlines()) == 1


def test_diagnose_refuses_a_log_without_a_reference(tmp_path, capsys):
    from mimunav.flightlog import LogWriter
    from mimunav.flightlog import schemas as S
    path = tmp_path / "bare.mcap"
    with LogWriter(path) as log:
        log.metadata("flight", {"format": "mimunav-log/1", "epoch_unix_ns": "0",
                                "initial_state": {"t": 0.0, "latitude": 0.5, "longitude": 0.1,
                                                  "height": 0.0, "velocity_ned": [0, 0, 0],
                                                  "attitude_wxyz": [1, 0, 0, 0]}})
        n = 10
        log.write("/mimu/raw", S.RAW_MIMU, "mimu", np.arange(n, dtype=np.int64) * 10**6,
                  sample_index=np.arange(n, dtype=np.uint64), gyro_volts=np.zeros((n, 3)),
                  accel_volts=np.zeros((n, 3)), accel_temperature=np.zeros((n, 3)),
                  gyro_frequency=np.zeros((n, 3)))
    Calibration().save(str(tmp_path / "c.json"))
    assert main(["diagnose", str(path), "--model", str(tmp_path / "c.json"),
                 "-o", str(tmp_path / "r")]) == 2
    assert "/fog/imu" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


G_SENSITIVITY = {"effect": "g_sensitivity", "sensor": "gyro", "axis": "x", "input_axis": "z",
                 "coefficient": -0.1 * math.pi / 180 / 9.80665}       # 0.1 deg/s per g


@pytest.fixture(scope="module")
def null_recording():
    """The proof flight, nothing hidden and no calibration fitted, in memory."""
    return concealed.recording(BLOCKS, None, 901, calibrate=False)


@pytest.mark.slow
def test_navigation_signature_matches_the_strapdown_navigator(null_recording):
    """The linearised error equations of the navigation level against the full strapdown
    navigator: the same outputs navigated with and without a g-sensitivity and an
    accelerometer bias; the velocity difference equals the signature to 1 % over 2 min."""
    from mimunav.diagnosis import error_equations
    from mimunav.evaluation.replay import navigate, resample
    flight, unit, _, _ = null_recording
    nav, w, f = error_equations.observed_error(flight, unit.coefficients)
    model, cond = error_equations.error_model(flight, nav, w, f)
    term = dict(G_SENSITIVITY, coefficient=2e-5)
    full = effects.Conditions.from_outputs(flight.mimu_t, f, w, flight.mimu_raw["accel_temperature"],
                                           flight.mimu_raw["gyro_frequency"])
    d_w = np.zeros_like(w)
    d_w[:, 0] = effects.regressor(term, full)[("gyro", 0)][:, 0] * 2e-5
    d_f = np.zeros_like(f)
    d_f[:, 1] = 5e-3                                                  # 0.5 mg
    moved = navigate(flight.mimu_t, w + d_w, f + d_f, flight.mimu_mounting, flight.initial)
    reg = effects.regressor(term, cond)[("gyro", 0)] * 2e-5
    sig = error_equations.signature(model, {("gyro", 0): reg,
                                            ("accel", 1): np.full((len(model.t), 1), 5e-3)},
                                    1)[:, :, 0]
    for span in (30.0, 60.0, 120.0):
        t = np.array([model.t[0] + span])
        k = np.searchsorted(model.t, t[0])
        t = model.t[k:k + 1]
        true = resample(moved, t).v_ned - resample(nav, t).v_ned
        assert np.linalg.norm(true[0]) > 0.3
        assert np.linalg.norm(sig[k] - true[0]) < 0.01 * np.linalg.norm(true[0]), span


NAVIGATION_SEEDS = range(801, 809)


def _navigation_g_sensitivity(seed):
    """The navigation level on one recording with the g-sensitivity hidden: (labels named,
    ratio of the estimate to the truth, z against the truth, held-out rms improved, the
    halves' widening) - the last four nan / False when it is not named. The flight is
    treated as a recording (`source`), so its findings pass the halves check too: the effect
    is the same all through, so the halves must let it stand. As a recording's, its
    regressors are made of the MIMU's own outputs, so a term that level cannot test may
    stand in for it (`untested`): set aside beside one, with its interval widened, it counts
    as found here - the level said it saw the effect and why it cannot name it."""
    from mimunav.diagnosis import navigation
    flight, unit, _, _ = concealed.recording(BLOCKS, None, seed, HiddenPhysics(dict(G_SENSITIVITY)),
                                             calibrate=False)
    flight.source = "recording"
    diag = navigation.diagnose(flight, unit.coefficients)
    findings = diag.findings + [r for r in diag.rejected if "untested" in r and
                                r["label"] == "g_sensitivity gyro.x <- f_z"]
    labels = [f["label"] for f in findings]
    found = [f for f in findings if f["label"] == "g_sensitivity gyro.x <- f_z"]
    if not found:
        return labels, math.nan, math.nan, False, math.nan
    f, truth = found[0], G_SENSITIVITY["coefficient"]
    return (labels, f["coefficient"] / truth,
            (f["coefficient"] - truth) / ((f["ci95"][1] - f["ci95"][0]) / 3.92),
            f["fit"]["heldout_rms_after"] < f["fit"]["heldout_rms_before"],
            f["halves"]["widened_by"])


@pytest.fixture(scope="module")
def navigation_g_runs():
    """`_navigation_g_sensitivity` on recordings 801-808 (the proof flight with an
    uncompensated 0.1 deg/s/g gyro g-sensitivity, a MEMS gyro's raw class), two at a time."""
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(2) as pool:
        return list(pool.map(_navigation_g_sensitivity, NAVIGATION_SEEDS))


@pytest.mark.slow
def test_navigation_level_names_a_g_sensitivity_and_stays_quiet_on_a_null(null_recording,
                                                                          navigation_g_runs):
    """Without the FOG-IMU, from the velocity error against the truth alone. Its power on
    this 0.1 deg/s/g effect is about 3 in 4 recordings (801-806: 5 of 6 with one noise
    realisation, 4 of 6 with another), so one recording proves nothing either way: over 8,
    named in at least 3 (a chance failure at power 3/4: 0.4 %), with a held-out improvement
    each time, nothing else ever named, and the null recording quiet."""
    from mimunav.diagnosis import navigation
    null, null_unit, _, _ = null_recording
    named = [r for r in navigation_g_runs if r[0]]
    assert len(named) >= 3, navigation_g_runs
    assert all(r[0] in ([], ["g_sensitivity gyro.x <- f_z"]) for r in navigation_g_runs), \
        navigation_g_runs
    assert all(r[3] for r in navigation_g_runs if r[0]), navigation_g_runs
    # the halves of a constant effect agree (at 95 %: 1 of 6 named at 801-808 was widened,
    # 1.07x); they never widen it by half
    assert all(r[4] < 1.5 for r in navigation_g_runs if r[0]), navigation_g_runs
    assert navigation.diagnose(null, null_unit.coefficients).findings == []


@pytest.mark.slow
def test_navigation_level_estimates_are_unbiased_and_cover_the_true_g_sensitivity(
        navigation_g_runs):
    """Over the recordings where it is named (its power is the test above's): the estimates
    average within 5 % of the truth and the 95 % intervals hold it in all but one. The
    estimates are refitted about themselves (`navigation._relinearized`): from the first
    linearization, along a navigation whose attitude drifts with the g-sensitivity itself,
    they came out 0.84-0.97 of the truth (mean 0.91), after it 0.94-1.03."""
    named = [r for r in navigation_g_runs if r[0]]
    assert len(named) >= 3, navigation_g_runs
    assert sum(abs(r[2]) <= 1.96 for r in named) >= len(named) - 1, navigation_g_runs
    assert abs(np.mean([r[1] for r in named]) - 1) < 0.05, navigation_g_runs


@pytest.mark.slow
def test_concealed_effects_are_found_and_nulls_stay_quiet():
    """Reduced proof (CI): the required effects (one outside the vocabulary), one recording
    each, and four nulls, on the ordinary proof flight with lab-fitted calibrations. Every
    hidden effect the flight makes detectable (its z on the whole flight > 8) must be named,
    with the true value in the interval and a held-out improvement; the effect outside the
    vocabulary must be located as an unexplained residual, not named; no null may raise a
    verdict against the unit's true coefficients (at most one against its lab fit, whose
    errors are real); no effect recording may name another effect against the true
    coefficients (at most one, over all of them, against the lab fit)."""
    cases = concealed.run_suite(PROOF, hidden=concealed.REQUIRED, repeats=1, nulls=4,
                                workers=2, seed=0, progress=False)
    s = concealed.summary(cases)
    assert s["false_alarms_true_model"]["k"] == 0, [c for c in cases if not c["effect"]]
    assert s["false_alarms"]["k"] <= 1, [c for c in cases if not c["effect"]]
    others = [(c["others"], c.get("others_true_model")) for c in cases if c["effect"]]
    assert s["other_findings_true_model"] == 0, others
    assert s["other_findings_in_effect_recordings"] <= 1, others
    strong = [c for c in cases if c["effect"] and c["z_detectable"] > 8]
    assert len(strong) >= 4
    for c in strong:
        assert c["identified"], c
        if c["exact"]:
            assert c["heldout_rms_ratio"] < 1.0, c
    outside = [c for c in cases if c["effect"] == "bias_pulse"]
    assert outside and all(c["identified"] and (c["verdict"] == "unexplained-residual" or
                                                c["findings"] and not c["others_true_model"])
                           for c in outside), outside      # or a lab-fit error found beside
    assert s["interval_coverage"]["k"] >= s["interval_coverage"]["n"] - 1
    assert s["identified"]["k"] >= 5
    assert math.isfinite(s["heldout_rms_ratio_median"])


FOREIGN = str(SHARED / "foreign-flights")


@pytest.mark.slow
def test_foreign_flights_are_diagnosed_right():
    """The development set of an independent simulator (shared/data/foreign-flights: no code
    shared with mimunav, answer keys beside the logs): at least 4 of the 5 hidden effects
    named (effect, sensor, axis) with the truth inside the 95 % interval, and the
    effect-free log quiet. Gyro temperature coefficients compare per Hz (the contract's)."""
    from mimunav.diagnosis import sensor
    from mimunav.evaluation.flight import Flight
    if not os.path.isdir(FOREIGN):
        pytest.skip("shared/data/foreign-flights is not beside the repository")
    named, quiet = 0, None
    for n in range(1, 7):
        base = os.path.join(FOREIGN, f"foreign-{n:02d}")
        key = json.load(open(base + ".key.json"))["hidden"]
        diag = sensor.diagnose(Flight.load(base + ".mcap"), Calibration.load(base + ".cal.json"))
        if key is None:
            quiet = sensor.verdict(diag) == "no-missing-physics" and not diag.findings
            continue
        truth = key.get("coefficient_per_hz", key["coefficient"])
        named += any((f["effect"], f["sensor"], f["axis"]) == (key["effect"], key["sensor"], key["axis"])
                     and f["ci95"][0] <= truth <= f["ci95"][1] for f in diag.findings)
    assert quiet is True
    assert named >= 4, named


@pytest.mark.slow
def test_a_truth_written_in_another_convention_gives_the_same_answers(tmp_path):
    """foreign-02 with its truth rewritten as another writer might keep it - the flight moved
    20.4 deg west so that it crosses the antimeridian, longitudes wrapped into (-pi, pi],
    attitudes negated on alternate 10 s spans (q and -q: one rotation) - is the same flight:
    the replay's errors against the truth and the sensor level's findings are the original's
    (the resampling's longitude lerp had put a state half a world away, and the attitude
    error of q against -q had read 2 pi)."""
    from mimunav.evaluation.replay import comparison_times, errors_at, replay, resample
    from mimunav.diagnosis import sensor
    from mimunav.evaluation.flight import Flight
    from mimunav.flightlog import FlightLog, LogWriter
    from mimunav.flightlog import schemas as S
    from mcap.reader import make_reader
    if not os.path.isdir(FOREIGN):
        pytest.skip("shared/data/foreign-flights is not beside the repository")
    base = os.path.join(FOREIGN, "foreign-02")
    shift, wrap = np.radians(-20.4), lambda x: np.remainder(x + np.pi, 2 * np.pi) - np.pi
    with open(base + ".mcap", "rb") as fh:
        meta = {m.name: dict(m.metadata) for m in make_reader(fh).iter_metadata()}
    init = json.loads(meta["flight"]["initial_state"])
    meta["flight"]["initial_state"] = json.dumps(dict(init, longitude=wrap(init["longitude"]
                                                                           + shift)))
    moved = tmp_path / "moved.mcap"
    with FlightLog(base + ".mcap") as log, LogWriter(moved) as out:
        for name, values in meta.items():
            out.metadata(name, values)
        for topic in log.channels:
            msgs, schema = log.read(topic), log.schema_name(topic)
            fields = {n: msgs[n].copy() for n, _, _ in S.BODIES[schema]}
            if topic == "/truth/state":
                fields["longitude"] = wrap(fields["longitude"] + shift)
                span = (msgs["log_time"] - msgs["log_time"][0]) // 10_000_000_000
                fields["attitude_wxyz"][span % 2 == 1] *= -1
                assert np.ptp(fields["longitude"]) > 6           # it does cross
            out.write(topic, schema, msgs["frame_id"][0].decode(),
                      msgs["log_time"].astype(np.int64), **fields)
    cal = Calibration.load(base + ".cal.json")
    answers = []
    for path in (base + ".mcap", str(moved)):
        flight = Flight.load(path)
        t = comparison_times(flight)
        err = errors_at(replay(flight, cal), t)
        at_imu = resample(flight.truth, flight.mimu_t[flight.mimu_t < t[-1]])
        answers.append((err, sensor.diagnose(flight, cal).findings, at_imu))
    (err0, found0, at0), (err1, found1, at1) = answers
    from mimunav.frames import earth            # the truth between its samples, as windows take it
    moved_back = earth.ned_difference(at1.lat, at1.lon - shift, at1.h, at0.lat, at0.lon, at0.h)
    assert np.abs(moved_back).max() < 1e-6                                       # m
    assert np.abs(at1.attitude_error(at0)).max() < 1e-12                          # rad
    for pair in ("mimu-truth", "fog-truth", "mimu-fog"):
        np.testing.assert_allclose(err1[pair]["position"], err0[pair]["position"], rtol=0,
                                   atol=1e-6)                                    # m
        np.testing.assert_allclose(err1[pair]["attitude"], err0[pair]["attitude"], rtol=0,
                                   atol=1e-12)                                   # rad
    assert [f["label"] for f in found1] == [f["label"] for f in found0] != []
    np.testing.assert_allclose([f["coefficient"] for f in found1],
                               [f["coefficient"] for f in found0], rtol=1e-9)


def test_effective_blocks_count_the_blocks_a_regressor_lives_in():
    """Satterthwaite's df in closed form: a regressor spread evenly over 40 blocks has 40;
    one that is non-zero in 3 blocks of equal weight has 3 (whatever the others hold)."""
    from mimunav.diagnosis.inference import effective_blocks
    blocks = np.repeat(np.arange(40), 25)
    even = np.ones((len(blocks), 1))
    assert effective_blocks(even, blocks, 40, slice(0, 1)) == pytest.approx(40.0)
    few = np.where(np.isin(blocks, [3, 17, 30]), 1.0, 0.0)[:, None]
    assert effective_blocks(few, blocks, 40, slice(0, 1)) == pytest.approx(3.0)


@pytest.mark.slow
def test_a_term_inside_the_stated_reference_accuracy_is_listed_not_charged():
    """foreign-06's 600 ppm gyro cross-coupling: charged to the MIMU with the default
    reference accuracy (Table 4; misalignment 1e-4 rad); with the reference stated at 1e-3 rad
    it can no longer be told from the reference's own error, so it is listed within the
    stated accuracies and the verdict does not claim missing physics from it - and it says
    what reference accuracy would let it be charged."""
    from mimunav.diagnosis import sensor
    from mimunav.sensors.accuracy import Accuracy
    from mimunav.evaluation.flight import Flight
    if not os.path.isdir(FOREIGN):
        pytest.skip("shared/data/foreign-flights is not beside the repository")
    base = os.path.join(FOREIGN, "foreign-06")
    flight, cal = Flight.load(base + ".mcap"), Calibration.load(base + ".cal.json")
    loose = Accuracy.parse("gyro_misalignment_rad=1e-3")
    diag = sensor.diagnose(flight, cal, accuracy=loose)
    label = "cross_coupling gyro.z <- w_x"
    assert label not in [f["label"] for f in diag.findings]
    (w,) = [w for w in diag.within_reference if w["label"] == label]
    # the accuracy it names as the one that would charge the term (issue 56, class 6),
    # checked by the diagnosis itself: a reference stated a little better is charged, a
    # little worse is not (measured: 1.73e-4 rad; 1.2e-4 charged, 2.4e-4 set aside)
    (sigma,) = w["charged_at_1sigma"]
    assert 1e-4 < sigma < 1e-3 and w["charged_at_accuracy"] == pytest.approx(sigma / 1e-3)
    tighter = Accuracy.parse(f"gyro_misalignment_rad={0.7 * sigma}")
    assert label in [f["label"] for f in sensor.diagnose(flight, cal, accuracy=tighter).findings]
    looser = Accuracy.parse(f"gyro_misalignment_rad={1.4 * sigma}")
    assert label in [w["label"] for w in
                     sensor.diagnose(flight, cal, accuracy=looser).within_reference]


@pytest.mark.slow
def test_navigation_level_says_why_a_chosen_term_is_unsettled():
    """The foreign flights without their reference IMU, at the navigation level (a new
    user's trial): foreign-02's g-sensitivity acts in the one boost, whose training segment
    chose a term that the held-out segments can neither confirm nor refute; foreign-01's
    too (it had held there, but the bootstrap did not choose it). Both said
    'no-missing-physics' and conclusive; both are inconclusive now (contract verdict
    unexplained-residual) with the reason, while the effect-free foreign-05 keeps its clean
    bill. (An effect never chosen still gets 'no-missing-physics': nothing detected, no
    statement of power - foreign-03 and -06 at this level.)"""
    from mimunav.diagnosis import navigation, sensor
    from mimunav.evaluation.flight import Flight
    if not os.path.isdir(FOREIGN):
        pytest.skip("shared/data/foreign-flights is not beside the repository")
    verdicts = {}
    for n in (1, 2, 5):
        base = os.path.join(FOREIGN, f"foreign-{n:02d}")
        diag = navigation.diagnose(Flight.load(base + ".mcap", reference_imu=False),
                                   Calibration.load(base + ".cal.json"))
        verdicts[n] = (sensor.verdict(diag), diag.findings, " ".join(diag.inconclusive))
    assert verdicts[5] == ("no-missing-physics", [], ""), verdicts[5]
    for n in (1, 2):
        verdict, findings, why = verdicts[n]
        assert verdict != "no-missing-physics", verdicts[n]
        # named one day, or said why not (foreign-01's term is chosen on the training
        # segments and held out not confirmed since the variance inflation, 2026-11-29)
        assert findings or "cannot name" in why or "cannot confirm" in why, verdicts[n]


def test_navigation_level_is_inconclusive_beyond_small_angles():
    """A velocity error growing as g phi t (a constant tilt phi, closed form): within the
    psi-angle equations' range it is judged, beyond it the level says inconclusive; white
    velocity noise of 0.3 m/s with no growth is no tilt."""
    from mimunav.diagnosis.error_equations import G0
    from mimunav.diagnosis.navigation import EPOCH_S, MAX_IMPLIED_TILT_RAD, beyond_small_angles
    t = np.arange(0, 120, EPOCH_S)
    for phi, reasons in ((0.5 * MAX_IMPLIED_TILT_RAD, 0), (2 * MAX_IMPLIED_TILT_RAD, 1)):
        dv = np.zeros((len(t), 3))
        dv[:, 0] = G0 * phi * t * 0.6
        dv[:, 1] = -G0 * phi * t * 0.8
        assert len(beyond_small_angles(dv)) == reasons
    noise = np.random.default_rng(1).normal(0, 0.3, (len(t), 3))
    assert beyond_small_angles(noise) == []
    # the vertical channel diverges: a constant accelerometer error b makes the down error
    # b tau sinh(t / tau), tau = sqrt(R / 2 g) - over an hour a 10 mg error's slopes reach
    # 118 mg (an independent review's closed form); read back to b, 10 mg is judged and
    # 0.2 g (another unit's calibration: 1.1 g on a gentle flight) is not
    from mimunav.diagnosis.error_equations import EARTH_RADIUS_M
    tau = math.sqrt(EARTH_RADIUS_M / (2 * G0))
    hour = np.arange(0, 3600, EPOCH_S)
    for b, reasons in ((0.01 * G0, 0), (2 * MAX_IMPLIED_TILT_RAD * G0, 1)):
        dv = np.zeros((len(hour), 3))
        dv[:, 2] = b * tau * np.sinh(hour / tau)
        said = beyond_small_angles(dv)
        assert len(said) == reasons and all("vertical" in r for r in said), said
    # a recording's outputs take no calibration of raw outputs: its remedy is a reference IMU
    (recorded,) = beyond_small_angles(dv, "recording")
    assert "reference IMU" in recorded and "calibrate the MIMU first" not in recorded
    assert "calibrate the MIMU first" in said[0]


def test_a_parked_flight_with_its_true_model_names_nothing_at_the_navigation_level(tmp_path):
    """120 s parked, the unit's exact model. With its regressors made of the MIMU's own
    outputs, a scale factor's regressor is that output's noise once the bias wander takes the
    constant part, and the velocity error integrates the same noise: a new user's parked and
    boost-coast flights had 'scale_factor accel.x 1.0, held-out p 1e-14' (errors in
    variables). Made from the reference trajectory's motion and attitude (independent of the
    MIMU) nothing is found and nothing is left to doubt; from a reference without attitude the
    level still names nothing, and says it cannot tell such terms from that noise."""
    from mimunav.diagnosis import levels, navigation, sensor
    from mimunav.evaluation.flight import Flight
    from mimunav.frames import attitude
    from mimunav.sensors.mimu import MimuUnit
    from mimunav.sensors.simulation import simulate_flight
    prof = Profile.from_dict({"name": "parked", "description": "parked 120 s",
                              "start": {"latitude_deg": 45.0, "longitude_deg": 126.6,
                                        "height_m": 150.0, "speed_m_s": 0.0,
                                        "heading_deg": 0.0},
                              "segment": [{"kind": "hold", "duration_s": 120.0}]})
    unit = MimuUnit.draw(11, beyond_model=False)
    path = tmp_path / "parked.mcap"
    simulate_flight(prof, path, 1, unit=unit, progress=False, force=True)
    flight = Flight.load(path, reference_imu=False)
    diag = levels.diagnose(flight, unit.coefficients, "navigation")
    assert sensor.verdict(diag) == "no-missing-physics", (diag.findings, diag.inconclusive)
    assert not [r for r in diag.rejected if "beyond_range" in r or "errors_in_variables" in r]
    blind = flight.truth[np.arange(len(flight.truth))]
    blind.q_nb = attitude.from_wxyz(np.full((len(blind), 4), np.nan))
    diag = navigation.diagnose(flight, unit.coefficients, reference=blind)
    assert diag.findings == []
    doubts = [r for r in diag.rejected if "beyond_range" in r or "errors_in_variables" in r]
    assert doubts and any("cannot name" in why or "errors in variables" in why
                          for why in diag.inconclusive), diag.inconclusive
    # and 'nothing found' would not cover the terms it cannot test (the RTKLIB drive forced
    # to this level had said no-missing-physics with 53-61 m/s of velocity error)
    assert any("does not cover them" in why for why in diag.inconclusive), diag.inconclusive
    # only a simulation's exact truth gives the inputs: a recorded reference's velocity noise
    # would sit in the velocity error and, differenced, in the inputs (a review's 10 Hz
    # reference with 0.02 m/s of noise gave a gentle flight a time skew of -0.127 s, held-out
    # p 5e-8); the same samples with 0.01 m/s of noise, or the flight called a recording
    from mimunav.diagnosis.error_equations import independent_inputs
    noisy = flight.truth[np.arange(0, len(flight.truth), 10)]
    noisy.v_ned = noisy.v_ned + np.random.default_rng(3).normal(0, 0.01, noisy.v_ned.shape)
    assert independent_inputs(flight, flight.truth) is flight.truth
    assert independent_inputs(flight, noisy) is None
    flight.source = "recording"
    assert independent_inputs(flight, flight.truth) is None


def test_stamps_that_jitter_make_the_sensor_level_inconclusive():
    """+-5 ms of uniform jitter on 100 Hz stamps (a stamp error of 2.9 ms on a 10 ms period)
    cannot carry a sample-by-sample comparison with a reference IMU (a trial's recording
    gave spurious accelerometer scale terms): named; +-1 ms is not; exact stamps are not;
    a 400 Hz clock written in whole ms (steps of 2 and 3 ms) is a rounding of +-0.5 ms, not
    jitter, while at 1.6 kHz the same rounding is a third of a period."""
    from mimunav.diagnosis import sensor
    from mimunav.flightlog import stamps
    rng = np.random.default_rng(1)
    t = np.arange(20000) * 0.01
    assert "jitter by 3" in sensor.stamp_jitter(t + rng.uniform(-5e-3, 5e-3, len(t)), "the MIMU's")
    assert sensor.stamp_jitter(t + rng.uniform(-1e-3, 1e-3, len(t)), "the MIMU's") == ""
    assert sensor.stamp_jitter(t, "the MIMU's") == ""
    whole_ms = np.round(np.arange(20000) / 400.0 * 1e3) / 1e3 + 1700000000.0
    assert stamps.stamp_tick(whole_ms) == 1e-3
    assert sensor.stamp_jitter(whole_ms, "the MIMU's") == ""
    assert sensor.stamp_jitter(np.arange(20000) * 1e-3, "the MIMU's") == ""   # 1 kHz exact
    fast = np.round(np.arange(20000) / 1600.0 * 1e3) / 1e3
    assert "stamped in whole 1 ms" in sensor.stamp_jitter(fast, "the MIMU's")


def test_split_blocks_do_not_depend_on_the_last_bit_of_a_stamp():
    """The training / held-out split (alternate 0.5 s blocks) puts a bin whose time falls on
    a block boundary in the block it opens, whatever rounding the bin time carries: stamps
    of a 1 kHz flight and their 10-sample means, each moved by +-2 ulp, keep their blocks
    (a plain floor of (t - t0) / 0.5 had sent about half of the boundary bins either way)."""
    from mimunav.diagnosis.outputs import block_index
    from mimunav.diagnosis.sensor import SPLIT_BLOCK_S
    rng = np.random.default_rng(5)
    stamps = 1000.0 + np.arange(200_000) / 1000.0
    for t in (stamps, stamps.reshape(-1, 10).mean(axis=1)):
        exact = np.round((t - t[0]) * 1000).astype(np.int64) // 500      # ms, integer blocks
        for _ in range(3):
            nudged = t + rng.integers(-2, 3, len(t)) * np.spacing(t)
            nudged[0] = t[0]
            assert np.array_equal(block_index(nudged, SPLIT_BLOCK_S), exact)


@pytest.mark.slow
def test_a_bias_pulse_is_an_excursion_not_a_bias_wander():
    """A 2 s bias pulse outside the vocabulary (the proof suite's recording 511: 3.6e-3 rad/s
    on gyro.x in quiet flight) is located as an unexplained residual and nothing is named:
    its bins are left out of the bias tests (it had been named bias_instability gyro.x, its
    2 s means passing for a Gauss-Markov wander)."""
    k = concealed.PROOF_EFFECTS.index("bias_pulse")
    case = concealed.run_case((PROOF, "bias_pulse", 500 + k))
    assert case["verdict"] == "unexplained-residual", case["findings"]
    assert case["identified"] and not case["findings"] and not case["others"]
    assert [u["channel"] for u in case["unexplained"]] == ["gyro.x"]


FOREIGN_2 = str(SHARED / "foreign-flights-2")


@pytest.mark.slow
def test_second_foreign_set_is_named_its_nulls_quiet_and_every_log_answered():
    """shared/data/foreign-flights-2 (the same independent simulator; answer keys beside the
    logs): a 1.8 mg accelerometer ADC step named (7 % of the channel's white variance, under a
    10 % bar before); a weak gyro g-sensitivity (z ~ 15) named as such, not as the pitch-rate
    cross-coupling it looks like in a pull; the three effect-free logs - a cold soak whose lateral accelerometer sees almost no
    specific force, a 600 s low-dynamic transport flight, a 25 g flight whose initial state
    stands at power-on (t = 0, one step before the first stamp) - answered and quiet; both
    effects of the two-effect log named with the truth inside their intervals, each finding
    with its effect size."""
    from mimunav.diagnosis import sensor
    from mimunav.evaluation.flight import Flight
    if not os.path.isdir(FOREIGN_2):
        pytest.skip("shared/data/foreign-flights-2 is not beside the repository")
    for n in range(1, 7):
        base = os.path.join(FOREIGN_2, f"foreign2-{n:02d}")
        hidden = json.load(open(base + ".key.json"))["hidden"]
        diag = sensor.diagnose(Flight.load(base + ".mcap"), Calibration.load(base + ".cal.json"))
        if not hidden:
            assert sensor.verdict(diag) == "no-missing-physics" and not diag.findings, n
            continue
        for h in hidden:            # (a quantization's coefficient: its step in SI)
            truth = h.get("step_si", h.get("coefficient_per_hz", h["coefficient"]))
            assert any((f["effect"], f["sensor"], f["axis"]) == (h["effect"], h["sensor"],
                                                                h["axis"])
                       and f["ci95"][0] <= truth <= f["ci95"][1] for f in diag.findings), h
        assert all(f["effect_size"]["heldout_variance_removed"] >= 1e-3
                   and 0 < f["effect_size"].get("of_physical_range", 0.5) < 1
                   for f in diag.findings)


def test_effect_size_is_the_variance_share_of_the_held_out_statistic():
    """Cox and Snell's R^2: a statistic of rows x ln 2 takes half the variance, none takes
    nothing; the magnitude is set against its range."""
    from mimunav.diagnosis.confirmation import effect_size
    size = effect_size(1000 * math.log(2), 1000, 0.01, 0.05)
    assert size["heldout_variance_removed"] == pytest.approx(0.5)
    assert size["of_physical_range"] == pytest.approx(0.2)
    assert effect_size(0.0, 1000, 0.0, np.inf)["heldout_variance_removed"] == 0.0


def test_a_calibrated_unit_bounds_its_linear_terms_by_the_seed_fit_residual():
    """Table 1's scale-factor fit residual (0.05 % FS accelerometer, 0.2 % gyro) x 10 bounds
    a calibrated unit's scale and coupling terms; a recording's uncompensated outputs keep
    the MEMS class's 5 %."""
    from mimunav.diagnosis.library import physical_limit
    scale = {"effect": "scale_factor", "sensor": "accel", "axis": "y"}
    full = {"accel": 300.0, "gyro": 7.0}
    assert physical_limit(scale, full, calibrated=True) == pytest.approx(5e-3)
    assert physical_limit(dict(scale, sensor="gyro"), full, calibrated=True) == pytest.approx(2e-2)
    assert physical_limit(scale, full) == pytest.approx(0.05)
    # a gyro's g-sensitivity: seed S1 Table 2's class (0.01-0.04 (deg/s)/g, bound 0.1) for a
    # calibrated unit; a consumer part as recorded to 2.5 times the largest typical
    # datasheet value (0.2 (deg/s)/g): two simulators' 0.112 and 0.3 (deg/s)/g fit within
    g_sens = {"effect": "g_sensitivity", "sensor": "gyro", "axis": "y", "input_axis": "x"}
    per_g = math.radians(1.0) / 9.80665
    assert physical_limit(g_sens, full, calibrated=True) == pytest.approx(0.1 * per_g)
    assert physical_limit(g_sens, full) == pytest.approx(0.5 * per_g)
    assert 0.3 * per_g < physical_limit(g_sens, full)


def test_a_lever_arm_beyond_its_range_names_the_lever_arms_given():
    """An AUV's 0.85 m lever arm declared with its sign wrong (a 1.7 m error) fitted its
    lever_arm term at 1.68 m, beyond the 1 m a unit's place is mis-measured by, and was set
    aside unsaid but for a list in the JSON: the words name the sign and where the arms are
    given; a mounting names its option; another term its range."""
    from mimunav.diagnosis.library import beyond_range_said
    arm = {"effect": "lever_arm", "sensor": "imu", "axis": "all"}
    said = beyond_range_said(arm, 1.68, 1.0, "m")
    assert said.startswith("1.68 m, beyond the 1 m") and "sign wrong errs by twice" in said
    assert "lever_arm_m of [imu] and [reference_imu]" in said
    assert "--reference-imu-lever-arm-m" in said
    # no arm given between the MIMU and its reference: anywhere in one vehicle (a survey
    # ship's 1.58 m had been refused at 1 m and two gyro cross-couplings named instead)
    from mimunav.diagnosis.library import TRAJECTORY_LEVER_ARM, physical_limit
    assert physical_limit(arm, {}) == 1.0
    assert physical_limit(arm, {}, arm_given=False) == TRAJECTORY_LEVER_ARM
    far = beyond_range_said(arm, 12.0, TRAJECTORY_LEVER_ARM, "m")
    assert far.startswith("12 m, beyond the 10 m of one vehicle") and "sign" not in far
    turn = beyond_range_said({"effect": "mounting_misalignment"}, 0.40, 0.35, "rad")
    assert turn.startswith("22.9 deg, beyond the 20 deg") and "--mounting-rpy-deg" in turn
    assert beyond_range_said({"effect": "size_effect"}, 1.69, 0.05, "m") == \
        "1.69 m, beyond its physical range (0.05)"


def test_a_lever_arm_beyond_its_range_between_imus_given_at_one_point_is_inconclusive():
    """A train's cab IMU 8.3 m from its INS, no arm given: its lever_arm fitted at 8.2 m,
    beyond range, had been passed over and a time skew of -0.2 s named in its place, the
    verdict conclusive. Where the two IMUs are given at one point, the arm beyond range is
    a reason the diagnosis cannot conclude, whatever else it found; with an arm given, the
    arm given is off by that much (a flight's reference declared 5 m off: a time skew and
    cross-couplings of the accelerometers had been named beside it) - a reason too."""
    from mimunav.diagnosis.library import apart_reasons
    arm = {"effect": "lever_arm", "label": "lever_arm imu.all", "beyond_range": 1.0,
           "rejected": "significant on the training half (p 0) at 8.3 m, beyond the 1 m"}
    other = dict(arm, effect="size_effect", label="size_effect accel.x")
    from types import SimpleNamespace
    at = lambda arm_m: SimpleNamespace(mimu_mounting=Mounting(lever_arm_m=arm_m),  # noqa: E731
                                       fog_mounting=Mounting())
    (why,) = apart_reasons([arm, other], at([0.0, 0.0, 0.0]))
    assert why.startswith("lever_arm imu.all significant") and why.endswith(
        "no lever arm was given between the two IMUs")
    (why,) = apart_reasons([arm], at([0.3, 0.0, 0.0]))
    assert why.endswith("the lever arm given between the two IMUs is off by that much")
    assert apart_reasons([dict(arm, effect="mounting_misalignment")], at([0.0] * 3)) == []


def test_the_tests_on_the_outputs_beside_a_residual_that_is_not_noise():
    """Where the library's check finds the residual beyond the tests' noise (its intervals
    widened 2x): a bias's wander is set aside (a random walk follows any slow structure: a
    helicopter's unmodelled mounting had read as bias instability at p 1e-84); a bias offset
    is read with its interval as widened - kept when its held-out p still holds, set aside
    when not; a lattice stands. Without the check's widening all stand as found."""
    from mimunav.diagnosis.confirmation import outputs_judged
    base = {"sensor": "gyro", "axis": "y", "heldout_threshold": 0.01}
    wander = dict(base, effect="bias_instability", coefficient=8.5e-4, ci95=(7e-4, 9.5e-4),
                  p_heldout=1e-84)
    strong = dict(base, effect="bias_shift", coefficient=1.0, ci95=(0.95, 1.05), p_heldout=1e-20)
    weak = dict(base, effect="bias_shift", axis="z", coefficient=0.1, ci95=(0.05, 0.15),
                p_heldout=1e-4)
    lattice = dict(base, effect="quantization", coefficient=1e-4, ci95=(1e-4, 1e-4))
    found = [wander, strong, weak, lattice]
    assert outputs_judged(found, None) == (found, [])
    assert outputs_judged(found, {"lambda": 2.0, "widened_by": 1.0}) == (found, [])
    kept, aside = outputs_judged(found, {"lambda": 4.0, "widened_by": 2.0})
    assert [f["effect"] + f["axis"] for f in kept] == ["bias_shifty", "quantizationy"]
    assert kept[0]["ci95"] == pytest.approx((0.9, 1.1))
    assert [f["effect"] + f["axis"] for f in aside] == ["bias_instabilityy", "bias_shiftz"]
    assert "a wander follows whatever slow structure" in aside[0]["rejected"]

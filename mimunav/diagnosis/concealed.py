"""Proof on concealed data: simulated recordings of an ordinary flight (`flights/diagnosis-
proof.toml`: one boost, turns, two rolls, a climb and a dive, each flown once), each with one
effect hidden in its MIMU (random axis, sign and a realistic magnitude), and null recordings
with none. The diagnosis sees the recording and a **lab-fitted** calibration of the unit
(`campaign.lab_calibration`, "entire": thermal chamber, rate table, centrifuge - never the
unit's true coefficients), exactly like `mimunav diagnose LOG --model CAL`.

What the suite shares with the diagnosis, and what it does not:
  - the hidden effects are sensor behaviour (`sensors.hidden.HiddenPhysics`), computed from
    the simulator's truth (exact increments, true temperatures), not from the regressors the
    diagnosis fits (`mimunav.compensation.effects`, built from the reference IMU); both are tested against
    closed forms separately;
  - one effect lies outside the vocabulary (`bias_pulse`, a transient offset): the right
    answer there is an unexplained residual at its place, not a name;
  - shared: the simulator's MIMU is the exact inverse of the 63-coefficient compensation and
    its noise model is the project's (`sensors.mimu`, `sensors.noise`); the flight, truth
    generator and reference-IMU model are the project's. The independent check of those is
    the development set of foreign flights (`shared/data/foreign-flights`), run beside this
    suite (`bench/diagnosis.py`, tests/test_diagnosis.py).

Magnitudes (uniform in log between the bounds, random sign): what a unit calibrated to the
seed's Table 1 can still carry, or, for effects the 63-coefficient model lacks entirely,
datasheet-class values:
    g_sensitivity         0.01-0.04 (deg/s)/g    (Table 2's C: as if the model lacked it)
    g2_sensitivity        2e-3-1e-2 (deg/s)/g^2  (anisoelasticity, datasheet class)
    temperature_rate      accel 0.2-1 mg/degC; gyro 20-100 (deg/h)/degC; window 120 s
                          (seed S3's e dT term, of the order of the static slopes the unit
                          draws: accel 0.05-0.5 mg/degC, gyro 18-180 (deg/h)/degC)
    temperature_bias      accel 0.1-0.4 mg/degC; gyro 20-80 (deg/h)/degC (a chamber fit off
                          by 20-80 % of the unit's static slopes)
    scale_nonlinearity    accel k2 20-100 ug/g^2; gyro k2 1e-6-5e-6 /(deg/s) (order 2)
    scale_asymmetry       300-1000 ppm
    scale_factor          1000-3000 ppm;  cross_coupling 1000-3000 ppm: Table 1's 0.05-0.2 %
                          FS class, beyond the reference's own accuracy
    time_skew             0.2-1 ms, the whole unit or one triad (a filter or stamp delay)
    size_effect           5-15 mm proof-mass offset of one accelerometer, random direction
    mounting_misalignment 1-3 mrad about a random axis
    bias_pulse            accel 5-15 mg, gyro 0.2-0.5 deg/s for 2-4 s (outside the vocabulary)
Gyro temperature coefficients are stated per degC and converted to the contract's per-Hz
through the unit's resonance-frequency slope. thermal_hysteresis and temperature_scale are
not drawn: the flight's temperature only rises (a cold start), so sign(dT/dt) is constant,
and a 3 minute warm-up of a few degC gives a temperature_scale no flight of this kind reveals.
"""
import math
import numpy as np

from ..compensation.effects import AXES
from ..sensors.hidden import HiddenPhysics
from ..sensors.mimu import G0
from ..errors import InputError
from ..evaluation.proportions import proportion

DEG = math.pi / 180
MG = 1e-3 * G0
PROOF_EFFECTS = ("g_sensitivity", "g2_sensitivity", "temperature_rate", "scale_nonlinearity",
                 "scale_asymmetry", "time_skew", "size_effect", "temperature_bias",
                 "cross_coupling", "scale_factor", "mounting_misalignment", "bias_pulse")
REQUIRED = ("g_sensitivity", "time_skew", "temperature_bias", "cross_coupling", "size_effect",
            "bias_pulse")
# The proof flight's MIMU is mounted turned (yaw 30, pitch 20, roll 45 deg), as units often
# are, so that every sensor axis sees the vertical load, the longitudinal accelerations and
# the rolls (a coordinated flight has no lateral specific force in the vehicle frame).
PROOF_MOUNTING_EULER_DEG = (30.0, 20.0, 45.0)


def draw(effect, rng, unit, duration_s):
    """A hidden `effect` (`HiddenPhysics`) with random axis, sign and magnitude (module doc)
    for `unit`, on a flight of `duration_s`."""
    sign = rng.choice([-1.0, 1.0])
    mag = lambda lo, hi: sign * math.exp(rng.uniform(math.log(lo), math.log(hi)))  # noqa: E731
    sensor = str(rng.choice(["accel", "gyro"]))
    i = int(rng.integers(3))
    # per degC -> per Hz for gyro temperature terms: f = f0 (1 + tcf (T - 25))
    per_hz = 1.0 / (unit.thermal.f0[i] * unit.thermal.tcf[i])
    term = {"effect": effect, "sensor": sensor, "axis": AXES[i]}
    if effect == "g_sensitivity":
        term.update(sensor="gyro", input_axis=AXES[rng.integers(3)],
                    coefficient=mag(0.01, 0.04) * DEG / G0)
    elif effect == "g2_sensitivity":
        a, b = sorted(rng.choice(3, 2))
        term.update(sensor="gyro", input_axis=AXES[a] + AXES[b],
                    coefficient=mag(2e-3, 1e-2) * DEG / G0 ** 2)
    elif effect in ("temperature_rate", "temperature_bias"):
        if effect == "temperature_rate":
            term["window_s"] = 120.0
        lo, hi = (0.2, 1.0) if effect == "temperature_rate" else (0.1, 0.4)
        term["coefficient"] = (mag(lo, hi) * MG if sensor == "accel"
                               else mag(100 * lo, 100 * hi) * DEG / 3600 * per_hz)
    elif effect == "scale_nonlinearity":
        term["order"] = 2
        term["coefficient"] = (mag(20e-6, 100e-6) / G0 if sensor == "accel"
                               else mag(1e-6, 5e-6) / DEG)
    elif effect == "scale_asymmetry":
        term["coefficient"] = mag(300e-6, 1000e-6)
    elif effect == "scale_factor":
        term["coefficient"] = mag(1000e-6, 3000e-6)
    elif effect == "cross_coupling":
        term["input_axis"] = AXES[(i + int(rng.integers(1, 3))) % 3]
        term["coefficient"] = mag(1000e-6, 3000e-6)
    elif effect == "time_skew":
        term.update(sensor=str(rng.choice(["imu", "accel", "gyro"])), axis="all",
                    coefficient=abs(mag(0.2e-3, 1e-3)) * sign)
    elif effect == "size_effect":
        term["sensor"] = "accel"
        term["vector"] = (_random_direction(rng) * abs(mag(5e-3, 15e-3))).tolist()
    elif effect == "mounting_misalignment":
        term.update(sensor="imu", axis="all",
                    vector=(_random_direction(rng) * abs(mag(1e-3, 3e-3))).tolist())
    elif effect == "bias_pulse":
        t0 = float(rng.uniform(0.2, 0.8) * duration_s)
        term.update(t0=t0, t1=t0 + float(rng.uniform(2.0, 4.0)),
                    coefficient=mag(5, 15) * MG if sensor == "accel" else mag(0.2, 0.5) * DEG)
    else:
        raise InputError(f"no concealed-data recipe for {effect!r}")
    return HiddenPhysics(term, unit.thermal)


def _random_direction(rng):
    v = rng.standard_normal(3)
    return v / np.linalg.norm(v)


# ---- the suite ----------------------------------------------------------------------------
PROOF_PROFILE = "diagnosis-proof.toml"
_MOTION = {}


def proof_mounting():
    from ..frames import attitude
    from ..frames.mounting import Mounting
    q = attitude.from_euler(*[math.radians(a) for a in PROOF_MOUNTING_EULER_DEG])
    return Mounting(attitude.as_wxyz(q), [0.30, -0.10, 0.05])


def proof_motion(profile_path):
    """The proof flight's truth and ideal increments (cached per process)."""
    if profile_path not in _MOTION:
        from ..sensors import simulation
        from ..motion.profile import Profile
        from ..frames.mounting import Mounting
        _MOTION[profile_path] = simulation.flight_motion(
            Profile.load(profile_path), proof_mounting(), 1000.0,
            Mounting.from_dict(simulation.FOG_MOUNTING), 1000.0, 100.0)
    return _MOTION[profile_path]


def recording(profile_path, effect, seed, hidden=None, calibrate=True):
    """(Flight, unit, HiddenPhysics | None, calibration): one concealed-data recording in
    memory (with `hidden` given, that effect instead of one drawn for `effect`) and the
    unit's lab-fitted entire calibration (`calibrate=False`: its true coefficients)."""
    from ..sensors import simulation
    from ..evaluation.campaign import lab_calibration
    from ..evaluation.flight import Flight
    from ..sensors.mimu import MimuUnit
    fm = proof_motion(profile_path)
    s_unit, s_effect = np.random.SeedSequence([seed, 7]).spawn(2)
    # exactly the 63-coefficient model: each answer key holds only what its log hides
    unit = MimuUnit.draw(int(s_unit.generate_state(1)[0]), name=f"MIMU-P{seed:04d}",
                         beyond_model=False)
    unit.mounting = proof_mounting()
    cal = lab_calibration(unit, "entire", seed, seed + 11, propagate=True) if calibrate \
        else unit.coefficients
    unit, fog, rng_m, rng_f = simulation.flight_units(seed, unit)
    if hidden is None and effect:
        hidden = draw(effect, np.random.default_rng(s_effect), unit, fm.t_base[-1])
    raw, fog_out = simulation.record_flight(fm, unit, fog, rng_m, rng_f, hidden)
    return Flight.from_simulation(fm, unit, fog, raw, fog_out), unit, hidden, cal


def run_case(args):
    """Diagnose one recording and score it against what was hidden."""
    profile_path, effect, seed = args
    from . import sensor
    flight, unit, hidden, cal = recording(profile_path, effect, seed)
    diag = sensor.diagnose(flight, cal)
    verdict = sensor.verdict(diag)
    case = {"effect": effect, "seed": seed, "verdict": verdict,
            "findings": [f["label"] for f in diag.findings],
            "unexplained": diag.unexplained[:5],
            "within_reference": [w["label"] for w in diag.within_reference]}
    if hidden is None:
        case["false_alarm"] = verdict != "no-missing-physics"
        # the same recording against the unit's true coefficients: the diagnosis' own false
        # alarm, apart from a lab fit that is off by more than its stated covariance
        exact = sensor.diagnose(flight, unit.coefficients)
        case["false_alarm_true_model"] = sensor.verdict(exact) != "no-missing-physics"
        case["findings_true_model"] = [f["label"] for f in exact.findings]
        return case
    true = hidden.as_dict()
    case["hidden"] = true
    if true["outside_vocabulary"]:                  # the answer is a place, not a name
        channel = f"{true['sensor']}.{true['axis']}"
        located = [u for u in diag.unexplained if u["channel"] == channel
                   and u["t0"] < true["t1"] and u["t1"] > true["t0"]]
        # a finding is a misnaming of the pulse unless it is the lab fit's own error (gone
        # against the unit's true coefficients, as for the nulls)
        wrong = [f["label"] for f in sensor.diagnose(flight, unit.coefficients).findings] \
            if diag.findings else []
        case.update(identified=bool(located) and not wrong, exact=False,
                    others=case["findings"], others_true_model=wrong,
                    z_detectable=float("nan"))
        return case
    case["z_detectable"] = _true_term_z(diag, true)
    match = [f for f in diag.findings if _same(f, true)]
    ambiguous = [f for f in diag.findings if any(_same(a, true) for a in f["indistinguishable_from"])]
    case["identified"] = bool(match or ambiguous)
    case["exact"] = bool(match)
    case["others"] = [f["label"] for f in diag.findings if f not in match and f not in ambiguous
                      and not _offset_of(f, true)]
    if case["others"]:      # the lab fit's own errors, or the diagnosis' (as for the nulls)?
        exact = sensor.diagnose(flight, unit.coefficients)
        case["others_true_model"] = [f["label"] for f in exact.findings if not _same(f, true)
                                     and not any(_same(a, true) for a in
                                                 f["indistinguishable_from"])
                                     and not _offset_of(f, true)]
    if match:
        f = match[0]
        p = np.atleast_1d(true.get("vector", true.get("coefficient")))
        ci = np.asarray(f.get("vector_ci95", [f["ci95"]]))
        case["covered"] = bool(np.all((ci[:, 0] <= p) & (p <= ci[:, 1])))
        case["coefficient"], case["ci95"] = f.get("vector", f["coefficient"]), f.get(
            "vector_ci95", f["ci95"])
        fit = f["fit"]
        case["heldout_rms_ratio"] = fit["heldout_rms_after"] / fit["heldout_rms_before"]
    return case


def _offset_of(found, true):
    """A bias shift on the channel of a hidden temperature term is that term's constant part:
    the simulator's behaviour counts temperature from the record's first reading, the
    contract's regressor from the log's mean, and the difference is an offset the data show
    (named when the slope itself is too weak to be)."""
    return (found["effect"] == "bias_shift" and true["effect"].startswith(("temperature",
                                                                         "thermal"))
            and (found["sensor"], found["axis"]) == (true["sensor"], true["axis"]))


def _same(found, true):
    keys = ["effect", "sensor", "axis"] + [k for k in ("input_axis", "order", "window_s")
                                          if k in true]
    return all(found.get(k) == true.get(k) for k in keys)


def _true_term_z(diag, true):
    """How detectable the hidden term was on this recording: its Wald z fitted alone on all
    rows (`sensor.term_z`)."""
    from . import sensor
    return sensor.term_z(diag, {k: v for k, v in true.items() if k != "outside_vocabulary"})


def run_suite(profile_path, hidden=PROOF_EFFECTS, repeats=1, nulls=12, workers=2, seed=0,
              progress=True):
    """Each effect of `hidden` `repeats` times and `nulls` null recordings; list of cases."""
    from concurrent.futures import ProcessPoolExecutor
    from tqdm import tqdm
    from ..evaluation.campaign import one_blas_thread
    jobs = [(profile_path, e, seed + 1000 * r + k) for r in range(repeats)
            for k, e in enumerate(hidden)]
    jobs += [(profile_path, None, seed + 500000 + k) for k in range(nulls)]
    bar = tqdm(total=len(jobs), desc="concealed-data suite", unit="rec", disable=not progress)
    out = []
    if workers <= 1:
        for job in jobs:
            out.append(run_case(job))
            bar.update()
    else:
        with ProcessPoolExecutor(workers, initializer=one_blas_thread) as pool:
            for case in pool.map(run_case, jobs):
                out.append(case)
                bar.update()
    bar.close()
    return out


def summary(cases):
    """Identification rate, false alarms, coverage, held-out improvement (with binomial
    95 % intervals where they are rates)."""
    eff = [c for c in cases if c["effect"]]
    nul = [c for c in cases if not c["effect"]]
    cov = [c["covered"] for c in eff if "covered" in c]
    ratios = [c["heldout_rms_ratio"] for c in eff if "heldout_rms_ratio" in c]
    return {"recordings": len(cases), "with_effect": len(eff), "nulls": len(nul),
            "identified": proportion([c["identified"] for c in eff]),
            "identified_exact": proportion([c["exact"] for c in eff]),
            "false_alarms": proportion([c["false_alarm"] for c in nul]),
            "false_alarms_true_model": proportion([c["false_alarm_true_model"] for c in nul]),
            "other_findings_in_effect_recordings": sum(len(c["others"]) for c in eff),
            "other_findings_true_model": sum(len(c.get("others_true_model", []))
                                             for c in eff if "others" in c),
            "interval_coverage": proportion(cov),
            "heldout_rms_ratio_median": float(np.median(ratios)) if ratios else None}

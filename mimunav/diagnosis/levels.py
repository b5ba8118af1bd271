"""The levels of the diagnosis and the choice among them: a log loaded for the level it is
diagnosed at, and that level's diagnosis - what `mimunav diagnose` runs.

    sensor       a reference IMU (/fog/imu) predicts the MIMU's outputs (`sensor`)
    navigation   only a reference trajectory (/truth/state): the MIMU's free-inertial velocity
                 error against it (`navigation`); on a recording its findings need a measured
                 initial heading (the reference's attitude, or a car's course)
    track        a car's recorded trajectory without attitude, simulated into an ideal IMU
                 that stands in for the reference IMU (`track`): a car's only (`vehicle_kind`)
"""
import json

import numpy as np

from ..compensation.calibration_file import Calibration
from ..errors import InputError
from ..evaluation.flight import Flight, no_reference, refuse_gaps
from . import navigation, skew, track, vehicle_kind
from ..compensation.effects import VIBRATION_CUTOFF_HZ
from ..motion.carrier import ALONG_COURSE
from .design import MOTION_HZ, reference_spectrum
from .library import apart_reasons
from .scan import spans_said
from ..sensors.mimu import G0

LEVELS = ("sensor", "navigation", "track")


def choose(flight, level="auto", vehicle=None):
    """(level, why) for `flight` (an `evaluation.flight.Flight`): `level` when given, else
    (auto) sensor with a reference IMU; for a recording, navigation when its reference carries
    the vehicle's attitude (used as attitude, not replaced by a vehicle model), track when
    what carried the IMU is a car (declared - `vehicle` overrides the metadata - or judged:
    `vehicle_kind`), navigation otherwise; navigation for a simulation."""
    if level != "auto":
        return level, "given (--level)"
    if flight.fog_t is not None:
        return "sensor", "a reference IMU (/fog/imu) flew with the MIMU"
    recorded = flight.mimu_imu is not None      # an imported /mimu/imu
    if not (recorded and flight.truth is not None):
        return "navigation", "a reference trajectory (/truth/state) and no reference IMU"
    if _has_attitude(flight):
        return "navigation", "the reference trajectory carries the vehicle's attitude"
    if flight.source == "recording" or np.isnan(flight.truth.q_nb[0].w):
        kind, how, _ = vehicle_kind.kind(flight, vehicle)
        if kind == vehicle_kind.LAND:
            return "track", f"a reference track without attitude, of a car ({how})"
        return "navigation", (f"a reference track without attitude, not of a car ({how}): the "
                              "track level's vehicle model does not hold")
    return "navigation", "a reference trajectory and no reference IMU"


def _has_attitude(flight):
    q = flight.truth.q_nb
    finite = np.isfinite(np.stack([q[k].components for k in range(min(len(q), 50))]))
    return bool(finite.all())


def load(log_path, model_path=None, level="auto", vehicle=None, stream=False):
    """(flight, calibration, level, why) of the log at `log_path` for the diagnosis: the
    calibration file at `model_path` (required for a raw /mimu/raw; the identity for a
    recorded /mimu/imu without one) and the level (`choose`). Gaps are refused at the
    navigation level only: the sensor and track levels leave their surroundings out
    instead of navigating across them. The track level is refused for a vehicle that is
    not a car. stream: a long flight diagnosed at the sensor level is read from its log block
    by block (`Flight.load(stream=True)`, `sensor.diagnose`) instead of held."""
    flight = Flight.load(log_path, reference_imu=level == "sensor", max_gap_s=np.inf,
                         stream=stream and level in ("auto", "sensor"))
    recorded = flight.mimu_imu is not None      # an imported /mimu/imu: already compensated
    if model_path is None and not recorded:
        raise InputError(f"{log_path}: the log has /mimu/raw; --model CAL is required")
    cal = Calibration.load(model_path) if model_path else Calibration.identity()
    level, why = choose(flight, level, vehicle)
    if flight.stream_block is not None and level != "sensor":       # those levels hold it
        flight = Flight.load(log_path, reference_imu=False, max_gap_s=np.inf)
    refuse_level(flight, log_path, level, vehicle)
    return flight, cal, level, why


def refuse_level(flight, log_path, level, vehicle=None):
    """Raise `InputError` when `flight` (of the log at `log_path`) cannot be diagnosed at
    `level`: the sensor level without a reference IMU, the navigation and track levels
    without a reference trajectory, the track level for what is no car (`vehicle` declared
    over the metadata), the navigation level across gaps."""
    if level == "sensor" and (flight.fog_t is None or not len(flight.fog_t)):
        raise InputError(f"{log_path}: the sensor level needs a reference IMU (/fog/imu) and "
                         "the log has none" + (": --level navigation or track diagnoses it "
                                               "against its reference trajectory"
                                               if flight.truth is not None else ""))
    if level == "track" and flight.truth is not None:
        kind, how, _ = vehicle_kind.kind(flight, vehicle)
        if kind != vehicle_kind.LAND:
            raise InputError(f"{log_path}: --level track models a car (no side slip, roll 0); "
                             f"this recording is not one ({how}): --level navigation, or "
                             "--vehicle car if it is a car")
    if level == "navigation":   # the sensor level leaves the samples beside a gap out
        refuse_gaps(flight)     # (`reference.across_gaps`), the track level their
                                # surroundings (`track_reference.near_gaps`)
    if level in ("navigation", "track") and flight.truth is None:
        raise no_reference(log_path, f"the {level} level" + (
            ": --level sensor diagnoses it against its reference IMU (/fog/imu)"
            if flight.fog_t is not None and len(flight.fog_t) else
            " (and no /fog/imu for the sensor level): nothing to diagnose against"))


def diagnose(flight, cal, level, alpha=0.05, seed=0, accuracy=None, noise=None, vehicle=None):
    """The diagnosis of `flight` against calibration `cal` at `level`: alpha the family-wise
    error rate; seed the navigation level's block bootstrap; accuracy the reference's
    `sensors.accuracy.Accuracy` (sensor and track levels); noise the unit's measured random errors
    for the sensor level's bias tests; vehicle (navigation level) what carried the IMU, when
    the command line says."""
    if level == "sensor":
        diag = skew.diagnose(flight, cal, alpha=alpha, accuracy=accuracy, noise=noise)
        set_aside_aliased(diag, flight)
        set_aside_moved(diag, flight)
        set_aside_undecided_clock(diag, flight)
        set_aside_apart(diag, flight)
        latency_untested(diag)      # once the set-asides have left what stands
        beside_the_band(diag.findings, flight)
        beside_the_imports_biases(diag.findings, flight, cal)
        beside_the_scales(diag.findings, diag.design.inputs)
        return diag
    if level == "navigation":
        diag = navigation.diagnose(flight, cal, alpha=alpha, seed=seed)
        unmeasured = unmeasured_heading(flight, vehicle)
        if unmeasured:
            diag.rejected = diag.rejected + [dict(f, rejected=unmeasured) for f in diag.findings]
            diag.findings = []
            diag.inconclusive = list(getattr(diag, "inconclusive", None) or []) + [unmeasured]
        set_aside_unapplied_lag(diag, flight)
    else:
        diag = track.diagnose(flight, cal, alpha=alpha, accuracy=accuracy)
        contradicted = vehicle_kind.contradicted_car(vehicle_kind.kind(flight, vehicle))
        if contradicted:
            diag.rejected = diag.rejected + [dict(f, rejected=contradicted)
                                             for f in diag.findings]
            diag.findings = []
            diag.inconclusive = list(getattr(diag, "inconclusive", None) or []) + [contradicted]
    set_aside_trajectory_clock(diag, flight)
    fused = fused_reference(flight)
    if fused and not diag.findings:
        diag.inconclusive = list(getattr(diag, "inconclusive", None) or []) + [fused]
    return diag


def set_aside_aliased(diag, flight):
    """The sensor level's findings on the sensors whose instantaneous samples folded the
    reference IMU's vibration into their band, as the import measured it (the recording's
    `aliased`: `importers.aliasing`) but a constant bias, set aside with its words, which
    make the diagnosis inconclusive (a helicopter's 26.4 Hz rotor line, sampled at 50 Hz, had named an accel.z
    scale of +1.6 % at p 7e-14; truth 0)."""
    said = (flight.recording or {}).get("aliased") or {}
    said = json.loads(said) if isinstance(said, str) else said
    if said:
        _set_aside(diag, lambda f: (f.get("sensor") in said or f.get("sensor") == "imu")
                   and f.get("effect") != "bias_shift",        # the unit's: both; folded tones
                   lambda f: said.get(f["sensor"], "; ".join(said.values())),  # average to
                   list(said.values()))                                        # no constant


def set_aside_moved(diag, flight):
    """Every finding of the sensor level set aside where the import found one IMU turned
    against the other during the recording (the recording's `reference_imu_moved`:
    `importers.pairing`): no one mounting holds the pair, and what the turn leaves reads as
    the unit's terms (an independent review: a reference turned 15 deg halfway had named a
    saturation accel.x on the MIMU at p < 1e-300)."""
    said = (flight.recording or {}).get("reference_imu_moved")
    if said:
        _set_aside(diag, lambda f: True, lambda f: said, [said + _excursions_too(diag)])


def set_aside_undecided_clock(diag, flight):
    """Every finding of the sensor level set aside where the import could not decide the
    two IMUs' clocks and the stamps as given are not where the data peak (the recording's
    `reference_imu_clock_open`: `importers.pairing`): a reference seconds off moves every
    term (a train's IMU 1.5 s off, not decided, had named a 3.5 deg mounting and an accel.x
    offset of -0.54 m/s^2 at p < 1e-300, the clock never named). Where the data peak at the
    stamps as given, among rivals (a train's slow turns), its findings stand beside the
    clock the sensor level fits."""
    _set_aside_open_clock(diag, flight, "reference_imu_clock_open", "reference IMU's",
                          "--reference-imu-time-offset")


def latency_untested(diag):
    """Where the import timed the reference IMU by these same motions (the clock fitted as a
    nuisance: `design.add_clock_nuisance`): that the MIMU's latency against it went into that
    clock, untested - beside the clock's reading, and where nothing was found as why the
    diagnosis is inconclusive. An independent trial's
    motorcycle, its MEMS 30 ms late against its INS (whose IMU ran 0.3 s off, given), had
    the import shift the INS's IMU by the 30 ms too and the verdict read no-missing-physics."""
    clock = diag.reference_clock
    if clock is None:
        return
    said = ("time_skew imu.all (the MIMU's latency against the reference IMU) is not tested: "
            "the import timed the reference IMU by these same motions (to 1 sigma "
            f"{clock['import_1sigma_s'] * 1e3:.2g} ms, the recording's reference_imu_time), "
            "which takes such a latency into that clock")
    if diag.findings:           # said beside the clock (a phone 20 ms late had gone unsaid)
        clock["latency"] = said
        return
    diag.inconclusive = diag.inconclusive + [said + " - 'nothing found' does not cover it"]


def set_aside_trajectory_clock(diag, flight):
    """Every finding of the navigation and track levels set aside where the import could not
    decide the reference trajectory's clock against the IMU's and the data peak away from
    its stamps (the recording's `reference_clock_open`: `importers.checks`): the trajectory
    they fit against may be that far off (a ship's MEMS 0.7 s ahead, its rolls repeating,
    had a 7 m lever arm named conclusively, the clock unnamed)."""
    _set_aside_open_clock(diag, flight, "reference_clock_open", "reference trajectory's",
                          "--reference-time-offset")


def _set_aside_open_clock(diag, flight, key, whose, option):
    """Every finding set aside, with the import's words (the recording's `key`) on the
    clock of `whose` it left open and the import's `option` that gives it."""
    said = (flight.recording or {}).get(key)
    if said:
        why = (f"the import could not decide the {whose} clock against the IMU's ({said}); "
               f"where the recording's own notes confirm it, {option} S at import gives it")
        _set_aside(diag, lambda f: True, lambda f: why, [why + _excursions_too(diag)])


def set_aside_unapplied_lag(diag, flight):
    """The navigation level's findings set aside where the import measured the reference
    trajectory's clock off the IMU's by two grid steps or more and left it to the diagnosis
    as the IMU's latency (the recording's `reference_clock_unapplied_s`): this level cannot
    test a time skew (its regressor is made of the MIMU's outputs), and its terms would fit
    what that lag makes - 'nothing found' does not cover it either (a mocap pose 0.2 s late,
    so left, had a g2_sensitivity blamed and the import's words promise a time skew)."""
    late = (flight.recording or {}).get("reference_clock_unapplied_s")
    if late:
        why = (f"the import measured the reference trajectory's stamps {abs(late) * 1e3:.0f} ms "
               f"{'late' if late > 0 else 'early'} on the IMU's and left it as the IMU's "
               "latency, which this level cannot test (its time skew regressor is made of the "
               "MIMU's outputs): its terms would fit what that lag makes - where it is the two "
               "clocks' offset, --reference-time-offset at import takes it out; a reference "
               "IMU beside it (the sensor level), or a car's track (--level track), measures it")
        _set_aside(diag, lambda f: True, lambda f: why, [why])


def set_aside_apart(diag, flight):
    """The sensor level's findings on the accelerometers (and the unit's) set aside where a
    lever arm fitted beyond its range lies between the two IMUs, given at one point or
    wrong by that much (`library.apart_reasons`: a reason the diagnosis cannot conclude):
    the transfer it leaves out is in every accelerometer's residual (a train's cab IMU 8.3 m from its INS
    had a time skew of -0.2 s named on its accelerometers in the arm's place); so are the
    accelerometers' excursions, named at the end of the arm's reason."""
    why = apart_reasons(diag.rejected, flight)
    if why:
        _set_aside(diag, lambda f: f.get("sensor") in ("accel", "imu"), lambda f: why[0],
                   [why[0] + _excursions_too(diag, "accel.")])


def _excursions_too(diag, channels=""):
    """The diagnosis's excursions on the channels named starting `channels` ('': all), taken
    out of it (read on a geometry or a clock that does not hold, they locate nothing: a
    train's 1.5 s clock had left one of z -48) and named in words to end a reason with, or
    ''."""
    every = list(getattr(diag, "unexplained", None) or [])
    spans = [u for u in every if u["channel"].startswith(channels)]
    diag.unexplained = [u for u in every if not u["channel"].startswith(channels)]
    return f"; its {len(spans)} excursion(s) set aside with it ({spans_said(spans)})" \
        if spans else ""


def _set_aside(diag, hit, why, reasons):
    """The findings `hit` (a test of one) moved to the rejected with `why` (of one), and
    `reasons` added to the diagnosis's inconclusive ones."""
    diag.rejected = diag.rejected + [dict(f, rejected=why(f)) for f in diag.findings if hit(f)]
    diag.findings = [f for f in diag.findings if not hit(f)]
    diag.inconclusive = list(getattr(diag, "inconclusive", None) or []) + reasons


def fused_reference(flight):
    """Why a recording's reference trajectory may carry its IMU's own errors, or '': its
    `reference` metadata does not say it is independent of the IMU ("no: the autopilot
    fuses this IMU", "unknown: ...", or nothing said). A filter that fuses the IMU estimates
    and takes out part of the IMU's errors, so what it took out does not show against it:
    'nothing is missing' cannot be said from it (a term that shows still stands on its tests,
    its size perhaps shrunk)."""
    if flight.source != "recording":
        return ""
    said = str((flight.reference_meta or {}).get("independent") or "not stated")
    if said.lower().startswith("yes"):
        return ""
    return (f"the reference trajectory is not known to be independent of this IMU ({said}): "
            "a filter that fuses the IMU takes out part of its errors, and what it took out "
            "does not show against it - finding nothing here does not mean nothing is missing "
            "(where it is independent, the import says so: a table spec's [reference] "
            "independent = \"yes: ...\", ros2's --reference-independent \"yes: ...\")")


def unmeasured_heading(flight, vehicle=None):
    """Why the navigation level's findings cannot stand on this recording's initial state, or
    '': its heading was assumed (nothing measured it), or taken from the GNSS course - which
    holds for a car or a train (`motion.carrier.ALONG_COURSE`), not for what else may carry
    an IMU (a walker's phone points anywhere, a multicopter flies sideways). A simulation's
    initial state is the truth's."""
    if flight.source != "recording":
        return ""
    heading = (flight.recording or {}).get("initial_heading") or _heading_from_text(flight)
    if heading == "reference":
        return ""
    kind, how, _ = vehicle_kind.kind(flight, vehicle)
    if heading == "course" and kind in ALONG_COURSE:
        return ""
    why = ((flight.recording or {}).get("assumed") or {}).get("initial_heading")
    said = ((why or "assumed: nothing measured it") if heading == "assumed" else
            f"taken from the GNSS course, which is the heading only of what moves along its "
            f"forward axis (a car, a train, a two-wheeler), and this recording is not known "
            f"to be one of them ({how}" + ("; if it is one, say so: --vehicle"
                                          if "declared" not in how else "") + ")")
    return (f"the initial heading was {said}: the MIMU's velocity error against the reference "
            "would fit that heading's error, not the MIMU's, so no finding is made from it")


IMPORT_BIASES = {"accel": ("accel_bias_m_s2", "m/s^2"), "gyro": ("gyro_bias_static_rad_s", "rad/s")}
# an axis this close to the vertical at a rest (cos 5 deg): the bias the rest measured along
# gravity, b.g g_i, is the axis' own within 0.4 % and holds under 9 % of the other axes'
VERTICAL_AXIS = 0.9962


def beside_the_imports_biases(findings, flight, cal):
    """Give each constant bias found on a recording's outputs as recorded (`cal` an identity)
    the bias its import's alignment measured on that axis (`import_measured`) where the
    alignment measured it against the reference's attitude (`bias_basis`: a gyro's with the
    Earth rate removed by that attitude; an accelerometer's from the reference's attitude
    and velocity, or at a rest along gravity on an axis within 5 deg of the vertical): the
    finding is against the reference IMU - two references, whose difference is the
    reference IMU's own bias or a bias that moved."""
    rec = flight.recording or {}
    if flight.source != "recording" or not cal.is_identity or cal.found:
        return
    basis = bias_basis(flight)
    for f in findings:
        key, units = IMPORT_BIASES.get(f.get("sensor"), (None, None))
        values = rec.get(key) if key else None
        if f["effect"] != "bias_shift" or values is None or f.get("units") != units:
            continue
        i = "xyz".index(f["axis"])
        how = _measured_how(basis, f["sensor"], i)
        if how:
            f["import_measured"] = {
                "value": float(values[i]), "units": units,
                "basis": f"the import's alignment (recording metadata {key}), {how}; this "
                         "finding is against the reference IMU: a difference is that IMU's "
                         "own bias, or a bias that moved"}


SCALED_INPUT = 0.5 * G0     # m/s^2: an accelerometer whose mean input is beyond it reads
#                             a scale error k as a bias of k times that mean


def beside_the_band(findings, flight):
    """Give each vibration rectification found `band_left_out` where the reference IMU's
    vibration (its specific force's power above design.MOTION_HZ,
    `design.reference_spectrum`) lies below the regressor's corner (`effects.VIBRATION_CUTOFF_HZ`) by more
    than BAND_SHARE: its coefficient is per the power above the corner, and what rectifies
    below it reads into it (a helicopter's 6.6 Hz once-per-rev: 0.0096 per the power above
    10 Hz where its rectification of the whole vibration was 0.008)."""
    vre = [f for f in findings if f["effect"] == "vibration_rectification"]
    if not vre or flight.fog_f is None or len(flight.fog_t) < 64:
        return
    spectrum = reference_spectrum(flight.fog_t, flight.fog_f)
    if spectrum is None:
        return
    hz, power = spectrum
    vibration = hz > MOTION_HZ
    below = vibration & (hz < VIBRATION_CUTOFF_HZ)
    share = float(power[below].sum() / max(power[vibration].sum(), 1e-300))
    if share <= BAND_SHARE:
        return
    line = float(hz[below][np.argmax(power[below])])
    for f in vre:
        f["band_left_out"] = {"share": share, "corner_hz": VIBRATION_CUTOFF_HZ, "line_hz": line}


BAND_SHARE = 0.2    # of the vibration's power below the regressor's corner: a fifth of it
#                     rectifying unseen moves the coefficient by up to a fifth


def beside_the_scales(findings, inputs):
    """Give each accelerometer bias found on an axis that reads a mean input beyond
    SCALED_INPUT (gravity along it) and no scale factor found on it `scale_alike`: its
    mean and spread (m/s^2, the design's predicted inputs, MIMU axes) - a scale error k
    of the axis is in the bias as k times that mean, and only the input's spread tells them
    apart (a rail car's accel.z: a 0.20 m/s^2 bias with a +0.4 % scale
    read 0.161 = 0.20 - 0.004 x 9.81, its interval holding neither alone)."""
    scaled = {f["axis"] for f in findings if f["effect"] == "scale_factor"
              and f["sensor"] == "accel"}
    for f in findings:
        if f["effect"] != "bias_shift" or f["sensor"] != "accel" or f["axis"] in scaled:
            continue
        x = inputs[:, "xyz".index(f["axis"])]
        mean = float(np.mean(x))
        if abs(mean) > SCALED_INPUT:
            f["scale_alike"] = {"mean_input_m_s2": mean, "spread_m_s2": float(np.std(x))}


def _measured_how(basis, sensor, i):
    """How the import measured the bias of `sensor` axis i against the reference's attitude,
    or '' where it did not (taken as 0, the Earth rate removed at a heading not measured,
    an axis a rest's gravity did not lie along)."""
    if sensor == "gyro":
        return "the Earth rate removed with the reference's attitude" \
            if basis.get("gyro") == "reference_attitude" else ""
    if basis.get("accel") == "all":
        return "against the reference's attitude and velocity"
    up = basis.get("gravity_sensor_axes")
    if basis.get("accel") == "along_gravity" and up and abs(up[i]) >= VERTICAL_AXIS:
        return "at a rest, along gravity (this axis within 5 deg of the vertical)"
    return ""


def bias_basis(flight):
    """What the import's alignment measured of each bias: the recording metadata's
    `bias_basis` ({gyro: reference_attitude | course | vertical_earth_rate | earth_rate_left |
    none, accel: all | along_gravity | none, gravity_sensor_axes: the rest's up in sensor
    axes}); for a log
    imported before it was written, read from the alignment's words (the rest's gravity
    axis then unknown)."""
    given = (flight.recording or {}).get("bias_basis")
    if isinstance(given, dict):
        return given
    said = alignment_said(flight, of_the_import=True)
    if "biases from the reference's attitude and velocity" in said:
        return {"gyro": "reference_attitude", "accel": "all"}
    if "removed with the reference's attitude" in said:
        return {"gyro": "reference_attitude", "accel": "along_gravity"}
    return {"gyro": "none", "accel": "none"}


def leveled_on_its_outputs(flight):
    """Whether a recording's initial attitude was leveled on the MIMU's own specific force (a
    rest's mean, a moving alignment's two vectors) rather than taken whole from the
    reference (the recording metadata's `initial_attitude`; for a log imported before it
    was written, the alignment's words): a found term that turns the outputs (a mounting)
    then turns them away from the attitude the navigation starts from."""
    if flight.source != "recording":
        return False
    given = (flight.recording or {}).get("initial_attitude")
    if given:
        return given not in ("reference", "reference_level")
    return "whole state from the reference" not in alignment_said(flight)


def alignment_said(flight, of_the_import=False):
    """How a recording's initial state was found, as its metadata says it (`assumed`'s
    initial_state: the import's alignment, or a cut's); of_the_import: the import's own,
    whose measured biases the metadata keeps after a cut ('' when none is said)."""
    assumed = (flight.recording or {}).get("assumed") or {}
    return str(assumed.get("import_initial_state", assumed.get("initial_state", ""))
               if of_the_import else assumed.get("initial_state", ""))


def _heading_from_text(flight):
    """The heading source of a log imported before `initial_heading` was written: from the
    alignment's words in the `assumed` metadata."""
    said = alignment_said(flight)
    if "heading assumed" in said:
        return "assumed"
    if "heading from the reference" in said or "whole state from the reference" in said:
        return "reference"
    return "course" if said else "assumed"

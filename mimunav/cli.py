"""Command-line interface: `mimunav <command> ...` (also `python -m mimunav`)."""
import argparse
import contextlib
import os
import signal
import sys
import threading
import time
from pathlib import Path

# One BLAS thread unless the user chose (before numpy loads OpenBLAS): processes that each
# run OpenBLAS's threads on a small machine spin against each other (a 24000 x 100 Gram
# matrix 50x slower beside two such scripts); alone, one thread costs nothing measurable on
# this work of many mid-size products (bench/blas.py)
if not any(v in os.environ for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")):
    os.environ["OPENBLAS_NUM_THREADS"] = "1"

import numpy as np                                    # noqa: E402
from . import import_quaternion                        # noqa: E402
from .errors import InputError                        # noqa: E402

FLIGHTS = Path(__file__).resolve().parent.parent / "flights"
DEMO_MAX_SAMPLES = 20_000_000      # ~150 bytes per sample held (truth, increments, navigation)


def _demo(args):
    """Fly a profile with an ideal IMU through the navigator and print its end error."""
    from . import strapdown, truth
    from .profile import Profile, ProfileError

    try:
        profile = Profile.load(args.profile)
    except (OSError, ProfileError) as exc:
        print(f"mimunav demo: {exc}", file=sys.stderr)
        return 2
    n = int(np.floor(profile.duration * args.rate * (1 + 1e-12)))
    if n > DEMO_MAX_SAMPLES:
        raise InputError(f"{n:.3g} samples ({profile.duration:g} s at {args.rate:g} Hz): the "
                         f"demo holds every sample in memory, at most {DEMO_MAX_SAMPLES:.0e}")
    t = np.minimum(np.arange(n + 1) / args.rate, profile.duration)
    t0 = time.perf_counter()
    run = truth.generate(profile.motion(), t)
    t1 = time.perf_counter()
    nav = strapdown.integrate(t[1:], run.dtheta, run.dv, run.trajectory.state(0))
    t2 = time.perf_counter()
    dp = nav.position_error(run.trajectory)[-1]
    da = np.abs(nav.attitude_error(run.trajectory)[-1]).max()
    f = np.linalg.norm(run.dv, axis=1).max() * args.rate / 9.80665
    w = np.degrees(np.linalg.norm(run.dtheta, axis=1).max() * args.rate)
    print(f"flight        {profile.name}: {profile.description}")
    print(f"samples       {len(t) - 1} at {args.rate:g} Hz over {profile.duration:.1f} s; "
          f"peak specific force {f:.1f} g, peak rate {w:.0f} deg/s")
    print(f"truth         {t1 - t0:.2f} s (trajectory + exact increments)")
    print(f"navigation    {t2 - t1:.3f} s ({(len(t) - 1) / (t2 - t1) / 1e6:.1f} M samples/s, "
          "incl. compilation on a first run)")
    print(f"end error     north {dp[0]:+.2e} m, east {dp[1]:+.2e} m, down {dp[2]:+.2e} m, "
          f"attitude {da:.2e} rad (ideal IMU: the navigator's own error)")
    return 0


def _simulate(args):
    """Simulate a flight profile into an MCAP log and a separate truth file."""
    from .profile import Profile
    from .sensors import MimuUnit
    from .sensors.hidden import parse_term
    from .files import refuse_inputs
    from .simulation import simulate_flight, truth_file
    try:
        refuse_inputs([args.output, truth_file(args.output)], [args.profile, args.unit])
        profile = Profile.load(args.profile)
        unit = MimuUnit.load(args.unit) if args.unit else None
        hide = [parse_term(text) for text in args.hide]
        platform = None
        given = [o for o, v, d in (("--platform-rate-deg-s", args.platform_rate_deg_s, 10.0),
                                   ("--platform-swing-deg", args.platform_swing_deg, 360.0),
                                   ("--platform-dwell-s", args.platform_dwell_s, 0.0),
                                   ("--inclination-deg", args.inclination_deg, 0.0),
                                   ("--platform-encoder-arcsec", args.platform_encoder_arcsec,
                                    1.58),
                                   ("--platform-encoder-noise-arcsec",
                                    args.platform_encoder_noise_arcsec, 0.0),
                                   ("--platform-lever-arm-m", args.platform_lever_arm_m,
                                    None)) if v != d]
        if given and not args.platform:
            raise InputError(f"{', '.join(given)} describe a platform: give --platform too")
        if args.platform == "continuous" and any(o in given for o in ("--platform-swing-deg",
                                                                       "--platform-dwell-s")):
            raise InputError("--platform-swing-deg and --platform-dwell-s apply to "
                             "back-and-forth rotation only")
        if args.platform:
            from .modulation import Platform
            platform = Platform(args.platform, np.radians(args.platform_rate_deg_s),
                                swing_rad=np.radians(args.platform_swing_deg),
                                dwell_s=args.platform_dwell_s,
                                inclination_rad=np.radians(args.inclination_deg),
                                encoder_resolution_rad=np.radians(args.platform_encoder_arcsec
                                                                  / 3600),
                                encoder_noise_rad=np.radians(args.platform_encoder_noise_arcsec
                                                             / 3600),
                                encoder_seed=args.seed,
                                lever_arm_m=tuple(args.platform_lever_arm_m or (0.0,) * 3))
        log, truth = simulate_flight(profile, args.output, args.seed, unit=unit,
                                     fog_rate=args.fog_rate, force=args.force, hide=hide,
                                     platform=platform)
    except (OSError, InputError) as exc:
        print(f"mimunav simulate: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {log}\nwrote {truth} (the unit's true coefficients: keep it apart "
          "from the log to diagnose blind)")
    return 0


def _info(args):
    """What an engineer checks first in a log; for a damaged one, what is intact."""
    from .flightlog import FlightLog, LogError
    from .flightlog.inspect import describe
    from .flightlog.recover import describe_scan, recover, scan
    if args.recover:
        report = recover(args.log, args.recover, force=args.force)
        print(describe_scan(report))
        print(f"wrote the intact part to {args.recover}")
        with FlightLog(args.recover) as log:
            if "flight" not in log.metadata():
                print(f"mimunav info: the intact part holds no `flight` metadata (its writer put "
                      f"it in the lost part): {args.recover} keeps the channels for inspection, "
                      "but replay, table and diagnose cannot place its navigation start",
                      file=sys.stderr)
        return 0
    unreadable = []
    try:
        with FlightLog(args.log) as log:
            print(describe(log, unreadable))
    except LogError as exc:
        report = scan(args.log)         # a file that is no MCAP at all: that one error
        print(f"mimunav info: {exc}", file=sys.stderr)
        print(describe_scan(report))
        return 2
    if unreadable:
        print(f"mimunav info: {args.log}: damaged {', '.join(unreadable)} (above); "
              "`mimunav info LOG --recover OUT.mcap` keeps every intact chunk", file=sys.stderr)
        return 2
    return 0


def _compensate(args):
    """Apply a calibration file to a log's raw MIMU channel."""
    from .compensation import Calibration, CalibrationError, compensate_log
    from .files import refuse_inputs
    from .flightlog import LogError
    try:
        refuse_inputs([args.output], [args.log, args.cal])
        counts = compensate_log(args.log, Calibration.load(args.cal), args.output, args.force,
                                skip_damaged=args.skip_damaged)
    except (OSError, LogError, CalibrationError) as exc:
        print(f"mimunav compensate: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.output} with /mimu/imu; samples replaced (wild values) "
          f"{counts['replaced']}, saturated {counts['saturated']}, unusable {counts['unusable']}")
    return 0


def _unit(args):
    """Draw a MIMU unit (seed S1 Table 2 and datasheet values) into a unit file."""
    from .sensors import MimuUnit
    MimuUnit.draw(args.seed, nonlinearity=args.nonlinearity, grade=args.grade,
                  beyond_model=not args.exact_model).save(args.output, args.force)
    print(f"wrote {args.output} (the unit's true coefficients)")
    return 0


def _lab(args):
    """Run a calibration-lab procedure on a unit and record it as a log."""
    from . import lab
    from .files import refuse_inputs
    from .sensors import MimuUnit
    from .simulation import truth_file
    refuse_inputs([args.output, truth_file(args.output)], [args.unit])
    log, truth = lab.run(lab.plan(args.procedure), MimuUnit.load(args.unit), args.output,
                              args.seed, force=args.force)
    print(f"wrote {log}\nwrote {truth} (unit and drawn setting errors)")
    return 0


def _drift(args):
    """Seed S4's AR + Kalman treatment of the gyro drift."""
    from .reports.drift import write
    out = write(args.log, args.output, channel=args.channel, cal_path=args.cal,
                static=args.static, dynamic=args.dynamic, window_s=args.window_s,
                max_order=args.max_order, force=args.force)
    print(f"wrote {out}/drift.md, drift.json, drift.png")
    return 0


def _calibration_compare(args):
    """A fitted calibration against the unit's truth file, coefficient by coefficient."""
    from .compensation import Calibration
    from .files import read_json
    from .reports.calibration import compare
    from .sensors import MimuUnit
    from . import rotation_calibration
    unit = MimuUnit.load(args.unit)
    doc = read_json(args.fit, "calibration file")
    if isinstance(doc, dict) and doc.get("model") == rotation_calibration.MODEL:
        rows, families = rotation_calibration.compare(
            rotation_calibration.RotationCalibration.from_dict(doc, args.fit), unit)
    else:
        rows, families = compare(Calibration.load(args.fit), unit)
    print(f"{'coefficient':14s} {'fitted':>13s} {'true (fit gauge)':>17s} {'std error':>11s} "
          f"{'z':>7s}")
    for name, fitted, true, se, z in rows:
        print(f"{name:14s} {fitted:13.6g} {true:17.6g} {se:11.3g} {z:7.2f}")
    print("RMS z per family: " + ", ".join(f"{k} {v:.2f}" for k, v in families.items()))
    all_z = np.array([r[4] for r in rows])
    print(f"all: n = {len(all_z)}, RMS z {np.sqrt(np.mean(all_z**2)):.2f}, max |z| "
          f"{np.abs(all_z).max():.2f}")
    if unit.beyond_model:
        print(f"note: {args.unit} has {len(unit.beyond_model)} terms of physics beyond the "
              "63-coefficient model (its `beyond_model`), which the fit absorbs where it can: "
              "z above 1 is expected there (reports/calibration.md); `mimunav unit "
              "--exact-model` draws a unit without them")
    return 0


def _noise(args):
    """Allan deviation and IEEE-952 terms of a static span."""
    from .reports.noise import write
    out = write(args.log, args.output, channel=args.channel, cal_path=args.cal, span=args.span,
                force=args.force)
    print(f"wrote {out}/noise.json, noise.md, noise.png")
    return 0


def _span(text):
    try:
        t0, t1 = (float(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected T0:T1 in s, got {text!r}") from None
    if not (np.isfinite(t0) and np.isfinite(t1) and t1 > t0 >= 0):
        raise argparse.ArgumentTypeError(f"need 0 <= T0 < T1 (finite), got {text!r}")
    return t0, t1


def _calibrate(args):
    """Fit a calibration method to lab runs and write the calibration file."""
    from .calibration import calibrate, standard_errors
    from .files import refuse_inputs
    refuse_inputs([args.output], [*args.runs, args.noise])
    noise = None
    if args.noise:
        from .reports.noise import load
        noise = load(args.noise)
        print(f"noise model: {noise['source']}")
    cal = calibrate(args.runs, args.method, unit=args.unit_name, noise=noise)
    cal.save(args.output, force=args.force)
    rms = cal.covariance.get("residual_rms", {})
    for stage, per_axis in rms.items():
        print(f"{stage:24s} residual rms " + ", ".join(f"{k} {v:.3g}" for k, v in
                                                        per_axis.items()))
    fitted = sum(1 for se in standard_errors(cal).values() if se > 0)
    print(f"wrote {args.output} ({cal.model}, {fitted} terms with standard errors and "
          "covariance; the others fixed at nominal values)")
    return 0


def _replay(args):
    """Compensate, navigate both IMUs and compare; outputs into a new folder, atomically."""
    import json

    import quaternion

    from . import evaluation
    from .compensation import Calibration
    from .files import atomic_folder, refuse_folder_early, refuse_inputs
    from .flightlog import LogWriter
    from .flightlog import schemas as S
    from .reports.plots import Painter, navigation_errors
    out = Path(args.output)
    refuse_inputs([out], [args.log, args.cal])
    refuse_folder_early(out, args.force, ("nav.mcap", "summary.json", "errors.png"))
    with Painter() as painter:                  # forked now: matplotlib loads beside the work
        flight = evaluation.Flight.load(args.log, stream=True)      # bounded memory
        cal = Calibration.load(args.cal)
        t = evaluation.comparison_times(flight, args.end)
        t_nav = np.append(np.arange(t[0], t[-1], 1.0 / args.nav_rate), t[-1])
        rep = evaluation.replay(flight, cal, check="the calibration", at=np.union1d(t, t_nav))
        err = evaluation.errors(rep, t)
        # the painter left first: the figure drawn before the folder commits, or the child
        # stopped before a failed folder is removed
        with atomic_folder(out, force=args.force, inputs=[args.log, args.cal]) as tmp, painter:
            series = {k: dict(v, t=t) for k, v in err.items() if k != "t"}
            navigation_errors(series, str(tmp / "errors.png"), f"{flight.name}: {args.cal}",
                              painter)
            with LogWriter(tmp / "nav.mcap") as log:
                for topic, traj in (("/mimu/nav", evaluation.resample(rep.mimu, t_nav)),
                                    ("/fog/nav", evaluation.resample(rep.fog, t_nav))):
                    log.write(topic, S.NAV_STATE, "vehicle",
                              flight.epoch_ns + np.round(traj.t * 1e9).astype(np.int64),
                              latitude=traj.lat, longitude=traj.lon, height=traj.h,
                              velocity_ned=traj.v_ned,
                              attitude_wxyz=quaternion.as_float_array(traj.q_nb))
            summary = {"format": "mimunav-replay/2", "log": args.log, "calibration": args.cal,
                       "end_t_s": float(t[-1]), "flags": rep.flags,
                       "end": {k: {"position_enu_m": evaluation.ned_to_enu(
                                       v["position"][-1]).tolist(),
                                   "velocity_enu_m_s": evaluation.ned_to_enu(
                                       v["velocity"][-1]).tolist(),
                                   "attitude_ned_rad": v["attitude"][-1].tolist()}
                               for k, v in err.items() if k != "t"},
                       "frames": "_enu: east, north, up; attitude_ned_rad: the attitude "
                                 "error's rotation vector about north, east, down",
                       "mimu_platform": (flight.mimu_platform["meta"] if flight.mimu_platform
                                         else None)}
            (tmp / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    end = summary["end"]
    for key, v in end.items():
        e = v["position_enu_m"]
        print(f"{key:11s} end position error east {e[0]:+.3g} m, north {e[1]:+.3g} m, "
              f"up {e[2]:+.3g} m")
    if args.json:
        print(json.dumps(summary))
    print(f"wrote {out}/nav.mcap, summary.json, errors.png")
    return 0


def _diagnose(args):
    """Diagnosis of a log against a calibration (sensor level with a reference IMU,
    navigation level with only a reference trajectory); JSON and report."""
    from .files import refuse_inputs
    refuse_inputs([args.json, args.output], [args.log, args.model, args.noise])
    inside = args.json and args.output and \
        Path(args.output).resolve() in Path(args.json).resolve().parents
    if inside:
        raise InputError(f"--json {args.json} lies inside the report folder {args.output}, which "
                         "gets its own diagnosis.json: give -o alone, or --json elsewhere")
    if args.json and Path(args.json).exists() and not args.force:   # before the work
        raise FileExistsError(f"{args.json} exists; use --force to replace it")
    if not args.output:
        return _diagnosed(args, None)
    from .reports.plots import Painter
    with Painter() as painter:              # forked now: matplotlib loads beside the work
        return _diagnosed(args, painter)


def _diagnosed(args, painter):
    """`_diagnose` once its arguments are checked; the report's figures by `painter`."""
    from . import diagnosis, evaluation
    from .compensation import Calibration
    from .diagnosis import navigation, sensor, track
    from .diagnosis.reference import Accuracy
    from .files import refuse_folder_early, write_atomic
    from .reports import diagnosis as report
    if args.output:                 # here, after the fork: the child's import runs beside these
        refuse_folder_early(args.output, args.force, report.FILES)
    # gaps are refused below unless the track level takes the log: it leaves their
    # surroundings out (`track.near_gaps`) instead of navigating across them
    flight = evaluation.Flight.load(args.log, reference_imu=args.level == "sensor",
                                    max_gap_s=np.inf)
    recorded = flight.mimu_raw is None          # an imported /mimu/imu: already compensated
    if args.model is None and not recorded:
        raise InputError(f"{args.log}: the log has /mimu/raw; --model CAL is required")
    cal = Calibration.load(args.model) if args.model else Calibration.identity()
    level = args.level
    if level == "auto":
        level = ("sensor" if flight.fog_t is not None else
                 "track" if recorded and flight.truth is not None and
                 (flight.source == "recording" or np.isnan(flight.truth.q_nb[0].w))
                 else "navigation")
    if level != "track":
        evaluation.refuse_gaps(flight)
    if level in ("navigation", "track") and flight.truth is None:
        raise evaluation.no_reference(args.log, f"the {level} level (and no /fog/imu for the "
                                      "sensor level): nothing to diagnose against")
    accuracy = Accuracy.parse(args.reference_accuracy) if args.reference_accuracy else None
    noise = None
    if args.noise:
        if level != "sensor":
            raise InputError(f"--noise sets the bias tests of the sensor level; {args.log} is "
                             f"diagnosed at the {level} level, which has none")
        from .reports.noise import load
        noise = load(args.noise)
        print(f"bias tests' normal wander: {noise['source']}")
    # the report's navigation of the model needs nothing the diagnosis finds: it runs on
    # the other core beside the diagnosis
    model = report.model_navigation_beside(flight, cal) if args.output else None
    if level == "navigation":
        diag = navigation.diagnose(flight, cal, alpha=args.alpha, seed=args.seed)
    elif level == "sensor":
        diag = sensor.diagnose(flight, cal, alpha=args.alpha, accuracy=accuracy, noise=noise)
    else:
        diag = track.diagnose(flight, cal, alpha=args.alpha, accuracy=accuracy)
    doc = diagnosis.document(args.log, diag, args.alpha)
    found = diagnosis.with_found(cal, doc["findings"])
    if args.output:
        report.write(args.output, doc, diag, flight, cal, found,
                     args.model or "identity (the log's /mimu/imu as recorded)", force=args.force,
                     painter=painter, model=model)
    if args.json:
        write_atomic(args.json, diagnosis.dumps(doc), force=args.force)
    if doc["conclusive"]:
        print(f"verdict: {doc['verdict']} ({doc['candidates_tested']} candidates)")
    else:
        print(f"verdict: inconclusive (contract verdict {doc['verdict']}; "
              f"{doc['candidates_tested']} candidates)")
        for reason in doc["inconclusive_reasons"]:
            print(f"  because {reason}")
    for f in doc["findings"]:
        print(finding_line(f))
    lag = doc.get("time_lag", {})
    if "tau_s" in lag:
        print(f"  time lag from the yaw rate: {lag['tau_s'] * 1e3:.1f} ms "
              f"[{lag['ci95'][0] * 1e3:.1f}, {lag['ci95'][1] * 1e3:.1f}] (positive: the IMU lags)"
              + (f"; not a finding: {lag['not_a_finding']}" if "not_a_finding" in lag else ""))
    elif "not_estimated" in lag:
        print(f"  time lag from the yaw rate not estimated: {lag['not_estimated']}")
    for u in doc["unexplained"][:10]:
        print(f"  unexplained residual {u['channel']} {u['t0']:.1f}-{u['t1']:.1f} s (z {u['z']:.1f})")
    for w in doc.get("within_reference_accuracy", []):
        print(set_aside_line(w))
    if args.output:
        print(f"wrote {args.output}/diagnosis.md" + (" and CAL+found.json" if found else ""))
    return 0


@contextlib.contextmanager
def _remembered_interrupts():
    """Ctrl-C raises KeyboardInterrupt as usual and is also remembered (the list yielded):
    one raised inside a callback from C - numba loading its cache through llvmlite's ctypes
    callback - is swallowed there ("Exception ignored"), and the command would end as if it
    had never been interrupted. Only in the main thread, and only over Python's own handler."""
    caught = []
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield caught
        return

    def remember(signum, frame):
        caught.append(signum)
        raise KeyboardInterrupt
    signal.signal(signal.SIGINT, remember)
    try:
        yield caught
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def finding_line(f):
    """A finding for the terminal: term, coefficient and units, 95 % interval, held-out p,
    attribution, a vector's components with the axes they are about (a mounting's turn also
    about the vehicle's axes, in degrees), and the terms this flight cannot tell it from
    (they explain the same residual: the name is the likelier of them, not a certainty)."""
    from .diagnosis.inference import p_text
    units = "" if f["units"] == "1" else f" {f['units']}"
    line = (f"  {f['label']}: {f['coefficient']:.4g}{units} "
            f"[{f['ci95'][0]:.4g}, {f['ci95'][1]:.4g}] (held-out p {p_text(f['p_heldout'])}; "
            f"{f.get('attribution', 'navigation level')})")
    if "vector" in f:
        line += (f"\n    vector ({f['units']}, {f.get('frame', 'sensor')} axes x, y, z) "
                 + ", ".join(f"{v:.4g} [{lo:.4g}, {hi:.4g}]"
                             for v, (lo, hi) in zip(f["vector"], f["vector_ci95"])))
    if "vector_vehicle" in f:           # the mounting's turn: about the vehicle's x, y, z
        line += ("\n    the sensor turned about the vehicle's forward, right, down axes "
                 + ", ".join(f"{np.degrees(v):+.2f} deg [{np.degrees(lo):+.2f}, "
                             f"{np.degrees(hi):+.2f}]"
                             for v, (lo, hi) in zip(f["vector_vehicle"],
                                                    f["vector_vehicle_ci95"])))
    alike = [a["label"] for a in f.get("indistinguishable_from", [])]
    if alike:
        line += "\n    not told apart on this flight from " + ", ".join(alike)
    return line


def set_aside_line(w):
    """A term set aside as within the stated accuracies (`within_reference_accuracy`), for
    the terminal: its value, its p against the noise alone, the reference's stated 1 sigma
    along it and the 1 sigma the test used - the estimate's with the reference's and the
    calibration's stated errors as priors, which can exceed both."""
    value = w.get("coefficient", w.get("vector"))
    said = (f"{value:.4g}" if isinstance(value, float) else
            "[" + ", ".join(f"{v:.3g}" for v in value) + "]")
    sigmas = lambda key: ", ".join(f"{v:.3g}" for v in w[key])     # noqa: E731
    stated = (f"the reference's (1 sigma {sigmas('reference_1sigma')}) and the calibration's"
              if "reference_1sigma" in w else
              f"the calibration's stated covariance (1 sigma {sigmas('calibration_1sigma')})")
    return (f"  set aside: {w['label']} {said}: significant against the noise alone (p "
            f"{w['p_train']:.2g}), not once the stated errors that may share it - {stated} - "
            f"are allowed: with them its 1 sigma is {sigmas('total_1sigma')}")


# import options -> (the importers that read them, their default): one given to another
# importer is refused, not silently ignored
IMPORT_OPTIONS = {
    "imu_instance": (("dataflash", "ulog"), None), "reference": (("dataflash",), "auto"),
    "reference_imu_instance": (("ulog",), None),
    "reference_imu_time_offset": (("ros2", "table", "ulog"), 0.0),
    "gps_status": (("dataflash",), 3), "imu_topic": (("ros2",), None),
    "fix_topic": (("ros2",), None), "pose_topic": (("ros2",), None), "origin": (("ros2",), None),
    "reference_status": (("ros2",), None), "reference_sigma": (("ros2",), np.inf),
    "reference_imu_topic": (("ros2",), None), "reference_imu_rpy_deg": (("ros2",), None),
    "solutions": (("rtklib",), ["fix"]), "root": (("table",), None)}


def _refuse_foreign_options(args, options):
    given = [f"--{name.replace('_', '-')}" for name, (kinds, default) in options.items()
             if args.kind not in kinds and getattr(args, name) != default]
    if given:
        raise InputError(f"{', '.join(given)}: not read by the {args.kind} importer "
                         f"(see `mimunav import --help`: each option names its importers)")


def _import(args):
    """A foreign recording into a contract log."""
    from . import importers
    from .files import refuse_inputs
    from .importers import rtklib
    from .sensors import Mounting
    source = Path(args.source)
    refuse_inputs([args.output], [args.source] + (sorted(map(str, source.iterdir()))
                                                  if source.is_dir() else []))
    mounting = (Mounting.from_rpy_deg(args.mounting_rpy_deg) if args.mounting_rpy_deg
                else None)
    _refuse_foreign_options(args, IMPORT_OPTIONS)
    if args.kind == "rtklib":
        names = {v: k for k, v in rtklib.SOLUTION_NAMES.items()}
        rec = rtklib.read_drive(args.source, mounting=mounting,
                                solutions=tuple(names[s] for s in args.solutions))
    elif args.kind == "ros2":
        from .importers import ros2
        rec = ros2.read(args.source, args.imu_topic, args.fix_topic, mounting=mounting,
                        reference_status=args.reference_status,
                        reference_sigma_m=args.reference_sigma, pose_topic=args.pose_topic,
                        origin=args.origin, reference_imu_topic=args.reference_imu_topic,
                        reference_imu_mounting=(Mounting.from_rpy_deg(args.reference_imu_rpy_deg)
                                                if args.reference_imu_rpy_deg else None))
    elif args.kind == "table":
        from .importers import table
        rec = table.read(args.source, mounting=mounting, root=args.root)
    elif args.kind == "dataflash":
        from .importers import dataflash
        rec = dataflash.read(args.source, mounting=mounting, instance=args.imu_instance or 0,
                             reference=args.reference, reference_status=args.gps_status)
    else:
        from .importers import ulog
        rec = ulog.read(args.source, mounting=mounting, instance=args.imu_instance,
                        reference_instance=args.reference_imu_instance)
    if args.reference_imu_time_offset:
        if rec.reference_imu is None:
            raise InputError("--reference-imu-time-offset: the recording has no reference IMU "
                             "(--reference-imu-topic, [reference_imu], --reference-imu-instance)")
        rec.reference_imu["ns"] = rec.reference_imu["ns"] + \
            int(round(args.reference_imu_time_offset * 1e9))
        rec.assumed["reference_imu_time"] = (f"its stamps shifted by "
                                             f"{args.reference_imu_time_offset:+.4f} s "
                                             "(command line)")
    align = importers.write_log(rec, args.output, force=args.force)
    from .flightlog.inspect import rate_segments
    runs = rate_segments(rec.imu_ns - rec.imu_ns[0])
    rates = " then ".join(f"{1e9 / p:.1f}" for _, _, p in runs) if len(runs) > 1 else \
        f"{rec.sample_rate_hz:.1f}"
    print(f"wrote {args.output}: {len(rec.imu_ns)} IMU samples at {rates} Hz"
          + (f", {len(rec.reference['ns'])} reference epochs" if rec.reference else "")
          + (f", {len(rec.fixes['ns'])} GNSS fixes" if rec.fixes else ""))
    for key, value in rec.assumed.items():      # what is not measured, said where it is made
        print(f"assumed {key}: {value}")
    if "mounting_yaw_against_course" in rec.real:
        print(f"measured mounting yaw: {rec.real['mounting_yaw_against_course']}")
    print(f"initial state at t = {align.t:.3f} s: {align.method}")
    if np.isnan(align.static[0]) and np.any(align.gyro_bias):
        print("biases from the reference's attitude and velocity (sensor axes): gyro "
              + ", ".join(f"{np.degrees(b):+.4f}" for b in align.gyro_bias) + " deg/s, "
              "accelerometer " + ", ".join(f"{b:+.4f}" for b in align.accel_bias) + " m/s^2")
    elif np.isnan(align.static[0]):
        print("gyro bias: not observed (no rest of 2 s in the recording)")
    else:
        print(f"gyro bias at rest {align.static[0]:.1f}-{align.static[1]:.1f} s (sensor axes) "
              + ", ".join(f"{np.degrees(b):+.4f}" for b in align.gyro_bias) + " deg/s")
    return 0


def _windows(args):
    """Free-inertial windows against the reference trajectory."""
    import json

    from . import evaluation, windows
    from .compensation import Calibration
    from .files import atomic_folder, refuse_inputs
    from .reports import windows as report
    refuse_inputs([args.output], [args.log, args.cal])
    if args.output and Path(args.output).exists() and not args.force:
        raise FileExistsError(f"{args.output} exists; use --force to replace it")
    flight = evaluation.Flight.load(args.log, reference_imu=False, max_gap_s=np.inf)
    cal = Calibration.load(args.cal) if args.cal else None
    results, rest = windows.run_all(flight, cal, args.lengths, args.step, args.time_shift,
                                    progress=True, min_speed=args.min_speed,
                                    max_gap=args.max_gap)
    doc = report.document(flight, results, rest, args.cal, args.time_shift)
    print(report.markdown_table(doc), end="")
    if args.output:
        with atomic_folder(args.output, force=args.force, inputs=[args.log, args.cal]) as tmp:
            (tmp / "windows.json").write_text(json.dumps(doc, indent=1) + "\n")
            report.plot({"": results}, str(tmp / "windows.png"))
        print(f"wrote {args.output}/windows.json, windows.png")
    return 0


def _variant_paths(specs):
    """{label: calibration path} of --cal LABEL=FILE (or FILE, labelled by its stem)."""
    paths = {}
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep:
            name, path = Path(spec).stem, spec
        if name in paths:
            raise InputError(f"two calibrations are labelled {name!r}: give each its own "
                             "label (--cal LABEL=FILE)")
        paths[name] = path
    return paths


def _variants(specs):
    from .compensation import Calibration
    return {name: Calibration.load(path) for name, path in _variant_paths(specs).items()}


def _table(args):
    """The normalised end-point table (seed S1 Table 3) for any number of variants."""
    import json

    from . import evaluation
    from .files import refuse_inputs, write_atomic
    written = [args.output + ext for ext in (".md", ".csv", ".json")] if args.output else []
    refuse_inputs(written, [args.log, *_variant_paths(args.cal).values()])
    for path in written:                                        # before the work
        if Path(path).exists() and not args.force:
            raise FileExistsError(f"{path} exists; use --force")
    flight = evaluation.Flight.load(args.log, stream=True)      # bounded memory
    doc = evaluation.table(flight, _variants(args.cal), args.end, check=True)
    text = evaluation.table_markdown(doc)
    if args.output:
        outputs = {".md": text, ".csv": evaluation.table_csv(doc),
                   ".json": json.dumps(doc, indent=1) + "\n"}
        for ext, content in outputs.items():
            write_atomic(args.output + ext, content, force=args.force)
    print(text, end="")
    return 0


def _budget(args):
    """Error budget: end-point error with each group of a calibration's terms off."""
    from . import evaluation
    flight = evaluation.Flight.load(args.log)
    (cal,) = _variants([args.cal]).values()
    print(evaluation.budget_markdown(evaluation.error_budget(flight, cal, args.end)), end="")
    return 0


def _reproduce(args):
    """The main job: seed S1 Table 3 for a drawn unit, budget and Monte Carlo."""
    from .reports.table3 import reproduce
    if args.regime_map:
        from .reports.regime import regime_map
        md = regime_map(args.output, seed=args.seed, units=args.units, workers=args.workers,
                        scheduler=args.scheduler, base=_scenario(args))
    else:
        md = reproduce(args.output, seed=args.seed, mc_units=args.units, force=True,
                       scenario=_scenario(args), workers=args.workers)
    print(f"wrote {md}")
    return 0


def _imu_channel_arguments(p):
    """A log's IMU channel in SI units and the output folder (`noise`, `drift`)."""
    p.add_argument("log", help="log (.mcap): a lab run, a simulated flight, an imported recording")
    p.add_argument("--channel", default="/mimu/imu",
                   help="/mimu/imu (default), /fog/imu, or /mimu/raw with --cal")
    p.add_argument("--cal", help="calibration file, to read /mimu/raw in SI units")
    p.add_argument("-o", "--output", required=True, help="folder to write")
    p.add_argument("--force", action="store_true", help="replace an existing folder")


def _scenario(args):
    from .campaign import Scenario
    return Scenario(flight=str(Path(args.flight).resolve()), severity=args.severity,
                    ground_temperature_c=args.ground_temperature_c, warm_up_s=args.warm_up_s,
                    mimu_grade=args.mimu_grade,
                    nonlinearity=args.nonlinearity, fog_grade=args.fog_grade,
                    beyond_model=not args.exact_model)


def _scenario_options(p, flight=True):
    """The options of `campaign.Scenario`: what shapes a Table 3 comparison."""
    if flight:
        p.add_argument("--flight", default=str(FLIGHTS / "high-dynamic.toml"),
                       help="flight profile TOML (default: flights/high-dynamic.toml, seed S1 "
                       "4.2)")
    p.add_argument("--severity", type=_number(1e-3, 10.0), default=1.0,
                   help="scale the flight's dynamics: g exposure (n - 1), accelerations and "
                   "rates x S (default 1)")
    p.add_argument("--ground-temperature-c", type=_number(-60.0, 60.0), default=15.0,
                   help="air temperature at the start height, degC (default 15, ISA)")
    p.add_argument("--warm-up-s", type=_number(0.0, 86400.0), default=600.0,
                   help="MIMU powered on this long before take-off, s (default 600: the "
                   "reference's ground alignment; 0 = cold at take-off)")
    p.add_argument("--mimu-grade", default="table1",
                   help="MIMU random errors (default table1: seed S1 Table 1 at its bound; "
                   "tactical: ADIS16488A class; stim300: STIM300 class)")
    p.add_argument("--nonlinearity", default="table1",
                   help="nonlinear scale factors: table1 = Table 2 scaled to Table 1's fit "
                   "residual (default), table2 = Table 2 literally")
    p.add_argument("--fog-grade", default="table4",
                   help="reference FOG-IMU (default table4: Table 4 medium accuracy; "
                   "table4-bound: its bounds as 1 sigma; navigation: 0.01 deg/h class)")
    p.add_argument("--exact-model", action="store_true",
                   help="MIMU exactly the 63-coefficient model (no scale asymmetry, no dT term)")


def _campaign(args):
    """Monte Carlo over units: the distribution of every normalised end error."""
    from . import campaign
    scenario = _scenario(argparse.Namespace(**dict(vars(args), flight=args.profile)))
    records = campaign.run_campaign(scenario, args.units, args.seed, args.output,
                                    workers=args.workers, scheduler=args.scheduler)
    print(campaign.summary_markdown(campaign.summary(records), len(records)), end="")
    return 0


def _report(args):
    """Write a generated report into a folder."""
    if args.kind == "recording":
        from .reports import recording
        if not args.log:
            raise InputError("report recording needs the log: mimunav report recording "
                             "LOG.mcap -o DIR (a log from mimunav import ...)")
        if args.output == "reports":
            raise InputError("report recording needs its own folder: -o DIR")
        md = recording.write(args.log, args.output, force=args.force, min_speed=args.min_speed)
        print(f"wrote {md}")
        return 0
    if args.kind == "rotation-calibration":
        from .reports import rotation_calibration
        md, png = rotation_calibration.write(args.output, n_units=args.units,
                                             first_seed=args.seed, force=args.force)
        print(f"wrote {md}\nwrote {png}")
        return 0
    if args.kind == "modulation":
        from .reports import modulation
        md = modulation.write(args.output, units=min(args.units, 50), seed=args.seed,
                              force=args.force)
        print(f"wrote {md}")
        return 0
    from .reports import calibration
    md, png = calibration.write(args.output, n_units=args.units, first_seed=args.seed,
                                force=args.force)
    print(f"wrote {md}\nwrote {png}")
    return 0


def _flight_arguments(p):
    p.add_argument("log", help="flight log (.mcap) with /mimu/raw and /fog/imu")
    p.add_argument("--end", type=_number(-1e9, 1e9), help="end point, s since the log's epoch "
                   "(default: the last instant every channel covers)")


def build_parser():
    parser = argparse.ArgumentParser(
        prog="mimunav", description="Flight-test evaluation of MEMS IMUs against a FOG-IMU.")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("demo", help="fly a profile with an ideal IMU through the navigator")
    p.add_argument("profile", nargs="?", default=str(FLIGHTS / "high-dynamic.toml"),
                   help="flight profile TOML (default: flights/high-dynamic.toml)")
    p.add_argument("--rate", type=RATE_HZ, default=1000.0, help="IMU sample rate, Hz")
    p.set_defaults(func=_demo)
    p = sub.add_parser("simulate", help="simulate a flight profile into an MCAP log "
                       "(/mimu/raw, /fog/imu, /truth/state) and LOG.truth.json")
    p.add_argument("profile", help="flight profile TOML, e.g. flights/high-dynamic.toml")
    p.add_argument("-o", "--output", required=True, help="log to write (.mcap)")
    p.add_argument("--seed", type=SEED, default=0, help="draws the units and the noise")
    p.add_argument("--unit", help="MIMU unit file (mimunav-unit/1 JSON) instead of a drawn one")
    p.add_argument("--fog-rate", type=RATE_HZ, default=1000.0, help="FOG-IMU sample rate, Hz")
    p.add_argument("--platform", choices=("continuous", "back-and-forth"),
                   help="the MIMU turns on a single-axis platform about the vehicle z axis "
                   "(seed S4; angle logged as /mimu/platform, sensor_msgs/msg/JointState)")
    p.add_argument("--platform-rate-deg-s", type=_number(1e-3, 1000.0), default=10.0,
                   help="platform rate, deg/s (default 10)")
    p.add_argument("--platform-swing-deg", type=_number(1.0, 36000.0), default=360.0,
                   help="back-and-forth: turn this far each way, deg (default 360)")
    p.add_argument("--platform-encoder-arcsec", type=_number(0.0, 3600.0), default=1.58,
                   help="resolution of the recorded platform angle, arcsec (default 1.58, the "
                   "seed S4 circular grating; 0: exact)")
    p.add_argument("--platform-encoder-noise-arcsec", type=_number(0.0, 3600.0), default=0.0,
                   help="white read-out noise of the platform angle, arcsec 1 sigma (default 0)")
    p.add_argument("--platform-lever-arm-m", type=_number(-10.0, 10.0), nargs=3,
                   metavar=("X", "Y", "Z"), help="the IMU's origin from the platform axis "
                   "point (the vehicle origin), m, platform axes turning with it (default 0)")
    p.add_argument("--platform-dwell-s", type=_number(0.0, 3600.0), default=0.0,
                   help="back-and-forth: pause at each end, s (default 0)")
    p.add_argument("--inclination-deg", type=_number(-90.0, 90.0), default=0.0,
                   help="the IMU tilted on the platform about its x axis, deg (default 0)")
    p.add_argument("--hide", action="append", default=[], metavar="EFFECT:SENSOR:AXIS=VALUE",
                   help="hide physics the 63-coefficient model lacks in the MIMU (repeatable; "
                   "written to LOG.truth.json, never to the log): "
                   "EFFECT:SENSOR:AXIS[:INPUT]=VALUE[@KEY=VALUE...], VALUE the coefficient in "
                   "the contract's SI units (log contract section 3; gyro temperature terms "
                   "per Hz of resonance frequency; vectors a/b/c). Examples: "
                   "g_sensitivity:gyro:x:z=1.8e-5 ((rad/s)/(m/s^2)), "
                   "cross_coupling:gyro:z:x=6e-4 (1), time_skew:accel:all=5e-4 (s), "
                   "temperature_rate:accel:x=2e-3@window_s=120 ((m/s^2)/degC), "
                   "size_effect:accel:z=0.004/0/-0.002 (m), "
                   "bias_pulse:gyro:y=2e-3@t0=40@t1=43 (rad/s; outside the vocabulary)")
    p.add_argument("--force", action="store_true", help="replace existing output files")
    p.set_defaults(func=_simulate)
    p = sub.add_parser("compensate", help="apply a calibration to /mimu/raw and write the "
                       "compensated MIMU as /mimu/imu (rad/s, m/s^2, sensor axes)")
    p.add_argument("log", help="MCAP flight log with /mimu/raw")
    p.add_argument("--cal", required=True, help="calibration file (mimunav-calibration/1)")
    p.add_argument("-o", "--output", required=True, help="log to write (.mcap)")
    p.add_argument("--skip-damaged", action="store_true", help="leave out the messages of "
                   "damaged chunks (listed in the output's `damage` metadata) instead of "
                   "refusing the log")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.set_defaults(func=_compensate)
    p = sub.add_parser("info", help="channels, rates, gaps, dropped samples and metadata "
                       "of a log")
    p.add_argument("log", help="MCAP flight log")
    p.add_argument("--recover", metavar="OUT.mcap",
                   help="write the intact part of a damaged (e.g. truncated) log to OUT")
    p.add_argument("--force", action="store_true", help="replace an existing OUT")
    p.set_defaults(func=_info)
    p = sub.add_parser("unit", help="draw a simulated MIMU into a unit file (true coefficients)")
    p.add_argument("-o", "--output", required=True, help="unit file to write (.json)")
    p.add_argument("--seed", type=SEED, default=0, help="draws the unit")
    p.add_argument("--nonlinearity", choices=("table1", "table2"), default="table1",
                   help="nonlinear scale factors: Table 2 scaled to Table 1's fit residual "
                   "(default) or Table 2 literally (sensors.mimu)")
    p.add_argument("--grade", choices=("table1", "tactical", "stim300"), default="table1",
                   help="random errors: Table 1 at its bound (default), ADIS16488A class, "
                   "STIM300 class (sensors.mimu.MIMU_GRADES)")
    p.add_argument("--exact-model", action="store_true",
                   help="exactly the 63-coefficient model (no physics beyond it)")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.set_defaults(func=_unit)
    p = sub.add_parser("lab", help="run a calibration-lab procedure on a unit into a log "
                       "(/mimu/raw + /lab/state; see mimunav.lab)")
    p.add_argument("procedure", help="thermal-chamber, rate-table, centrifuge, multi-position, "
                   "single-axis-rate, twelve-position, cold-start, rotation or hand-held")
    p.add_argument("--unit", required=True, help="unit file (mimunav-unit/1 JSON)")
    p.add_argument("-o", "--output", required=True, help="run log to write (.mcap)")
    p.add_argument("--seed", type=SEED, default=0, help="draws setting errors and noise")
    p.add_argument("--force", action="store_true", help="replace existing outputs")
    p.set_defaults(func=_lab)
    p = sub.add_parser("calibrate", help="fit lab runs into a calibration file "
                       "(mimunav-calibration/1, SI units, covariance included)")
    p.add_argument("runs", nargs="+", help="lab run logs (.mcap)")
    p.add_argument("--method", required=True,
                   help="entire: chamber + rate-table + centrifuge; traditional: "
                   "multi-position + single-axis-rate; twelve-position; cold-start; ellipsoid: "
                   "a hand-held run; rotation: a rotation run -> the gyros' k0..k3 (seed S4, "
                   "model rotation-cubic)")
    p.add_argument("-o", "--output", required=True, help="calibration file to write (.json)")
    p.add_argument("--unit-name", default="", help="unit name written to the file")
    p.add_argument("--noise", help="the unit's measured random errors (mimunav-noise/1 from "
                   "`mimunav noise`): its bias instability weights the fits instead of the "
                   "unit class's assumed one")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.set_defaults(func=_calibrate)
    p = sub.add_parser("calibration", help="work with calibration files: compare FIT UNIT")
    compare_sub = p.add_subparsers(dest="action", required=True)
    q = compare_sub.add_parser("compare", help="a fitted entire-63 (or rotation-cubic) file "
                               "against the unit's "
                               "truth file (mimunav-unit/1), in the fit's gauge: fitted, true, "
                               "standard error and z of every coefficient, RMS z per family")
    q.add_argument("fit", help="fitted calibration (mimunav-calibration/1, entire-63)")
    q.add_argument("unit", help="unit file (mimunav-unit/1) or the truth file's unit")
    q.set_defaults(func=_calibration_compare)
    p = sub.add_parser("noise", help="random errors of an IMU channel over a static span: "
                       "Allan deviation per axis with 68 %% bands, IEEE-952 terms with "
                       "intervals -> DIR/noise.json (mimunav-noise/1, SI), noise.md, noise.png")
    _imu_channel_arguments(p)
    p.add_argument("--span", type=_span, help="T0:T1, s since the channel's first sample "
                   "(default: the longest rest of /truth/state, else the longest still stretch)")
    p.set_defaults(func=_noise)
    p = sub.add_parser("drift", help="seed S4: an AR model of the gyro drift at rest and its "
                       "Kalman filter; variance reduction at rest, what the filter does under "
                       "motion, what it cannot remove -> DIR/drift.md, drift.json, drift.png")
    _imu_channel_arguments(p)
    p.add_argument("--static", type=_span, help="T0:T1 s of a rest (default: found as by "
                   "`mimunav noise`)")
    p.add_argument("--dynamic", type=_span, help="T0:T1 s of a span with motion, to see what "
                   "the filter does there")
    p.add_argument("--window-s", type=_number(1e-3, 600.0), default=1.0,
                   help="averaging before the model, s (default 1)")
    p.add_argument("--max-order", type=_number(1, 10, int), default=2,
                   help="highest AR order tried (BIC chooses; default 2; the rest must hold "
                   "50 x order averaged samples)")
    p.set_defaults(func=_drift)
    p = sub.add_parser("replay", help="compensate the MIMU, navigate MIMU and FOG-IMU with "
                       "the same navigator, compare with the truth and each other")
    _flight_arguments(p)
    p.add_argument("--cal", required=True, help="calibration file (mimunav-calibration/1)")
    p.add_argument("-o", "--output", required=True, help="folder for nav.mcap (NavState "
                   "/mimu/nav, /fog/nav, vehicle origin), summary.json, errors.png")
    p.add_argument("--nav-rate", type=_number(0.0, 1e4, open_low=True), default=10.0,
                   help="rate of the NavState channels written to nav.mcap, Hz (default 10)")
    p.add_argument("--json", action="store_true", help="also print the summary as JSON")
    p.add_argument("--force", action="store_true", help="replace an existing folder")
    p.set_defaults(func=_replay)
    p = sub.add_parser("diagnose", help="find the physics the model leaves out: test the "
                       "MIMU's residual against the reference IMU (or, without one, its "
                       "navigation error against the reference trajectory) for every term of "
                       "the effect vocabulary (log contract section 3)")
    p.add_argument("log", help="flight log (MCAP) with /mimu/raw or /mimu/imu, and /fog/imu "
                   "(sensor level) or /truth/state (navigation and track levels)")
    p.add_argument("--level", choices=("auto", "sensor", "navigation", "track"), default="auto",
                   help="sensor: MIMU outputs (m/s^2, rad/s) against the FOG-IMU's; navigation: "
                   "NED velocity error (m/s) against /truth/state; track: MIMU outputs against "
                   "the ideal IMU simulated along a land vehicle's /truth/state without attitude "
                   "(a recording); auto (default): sensor with /fog/imu, track for a recorded "
                   "/mimu/imu with such a reference, else navigation")
    p.add_argument("--model", help="the calibration the user believes (mimunav-calibration/1); "
                   "required for /mimu/raw, optional for a recorded /mimu/imu (identity)")
    p.add_argument("--json", help="write the mimunav-diagnosis/1 document here (with -o: the "
                   "report's diagnosis.json, whose `navigation` section - the MIMU navigated "
                   "with and without the found terms - only a report computes)")
    p.add_argument("-o", "--output", help="report folder: diagnosis.md, plots, diagnosis.json, "
                   "CAL+found.json (the model with the found terms)")
    p.add_argument("--alpha", type=_probability, default=0.05,
                   help="family-wise error rate over the candidate library, 0 < alpha < 1 "
                   "(default 0.05)")
    p.add_argument("--reference-accuracy", metavar="KEY=VALUE,...",
                   help="the reference IMU's 1-sigma accuracy; the keys given override the log's "
                   "sensor/fog `accuracy` metadata, which overrides the defaults (seed S1 Table "
                   "4: scale 2.5e-4; "
                   "misalignment 1e-4 rad, assumed): gyro_scale, accel_scale (1), "
                   "gyro_misalignment_rad, accel_misalignment_rad (rad)")
    p.add_argument("--noise", metavar="NOISE.json",
                   help="the unit's measured random errors (a `mimunav noise` file of its "
                   "/mimu/raw or /mimu/imu at rest): its bias instability B (SI) replaces the "
                   "class's zero drift as the wander the sensor level's bias tests take as "
                   "normal")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the navigation level's block "
                   "bootstrap (the sensor and track levels draw nothing)")
    p.add_argument("--force", action="store_true", help="replace existing outputs")
    p.set_defaults(func=_diagnose)
    p = sub.add_parser("import", help="turn a recording nobody here wrote into a contract log "
                       "(/mimu/imu in SI sensor axes, /truth/state, /gnss/fix, metadata of what "
                       "is real and what is assumed)")
    p.add_argument("kind", choices=("rtklib", "ros2", "ulog", "dataflash", "table"),
                   help="rtklib: folder with imu_*.csv, its RTKLIB .tag and an RTKLIB .pos; "
                   "ros2: an MCAP with sensor_msgs/msg/Imu (+ NavSatFix); ulog: a PX4 .ulg "
                   "(its EKF2 estimate as a reference that is not independent); dataflash: an "
                   "ArduPilot .bin (IMU, GPS/GPA; reference EKF3 POS/XKF1/ATT or the GPS); "
                   "table: a TOML spec of CSV / NumPy columns with units, axes, time base and "
                   "reference (see mimunav/importers/table.py; example tests/data/comma2k19.toml)")
    p.add_argument("source", help="the folder (rtklib), file (ros2, ulog, dataflash) or spec "
                   "(table)")
    p.add_argument("--imu-instance", type=_number(0, 9, int),
                   help="dataflash: the IMU instance (field I; IMU2 = 1), default 0; ulog: "
                   "the sensor_accel/sensor_gyro instance instead of sensor_combined")
    p.add_argument("--reference-imu-instance", type=_number(0, 9, int),
                   help="ulog: another sensor_accel/sensor_gyro instance as the reference IMU "
                   "(/fog/imu: diagnose then works at the sensor level)")
    p.add_argument("--reference", choices=("auto", "ekf", "gnss", "none"), default="auto",
                   help="dataflash: the reference trajectory: ekf = the autopilot's estimate "
                   "(POS, XKF1, ATT; not independent), gnss = the GPS fixes (independent, no "
                   "attitude), auto = ekf when logged, else gnss")
    p.add_argument("--gps-status", type=_number(3, 6, int), default=3,
                   help="dataflash: the lowest GPS Status that serves as the gnss reference "
                   "(3 3D, 4 DGPS, 5 RTK float, 6 RTK fixed), default 3")
    p.add_argument("-o", "--output", required=True, help="log to write (.mcap)")
    p.add_argument("--imu-topic", help="ros2: the sensor_msgs/msg/Imu topic (default: the only one)")
    p.add_argument("--fix-topic", help="ros2: the sensor_msgs/msg/NavSatFix topic (default: the "
                   "only one, if any)")
    p.add_argument("--mounting-rpy-deg", type=_number(-360.0, 360.0), nargs=3, metavar=("ROLL", "PITCH", "YAW"),
                   help="sensor -> vehicle (FRD) rotation, deg (default: rtklib the README's "
                   "180 0 180; ros2 180 0 0, REP-103 x forward, y left, z up; ulog and "
                   "dataflash 0 0 0, the autopilot's FRD body frame; table: the spec's axes)")
    p.add_argument("--reference-imu-topic", help="ros2: a second sensor_msgs/msg/Imu topic, a "
                   "better IMU flown with it, as the reference IMU (/fog/imu: `diagnose` then "
                   "works at the sensor level)")
    p.add_argument("--reference-imu-time-offset", type=_number(-60.0, 60.0), default=0.0,
                   metavar="S", help="ros2, table, ulog: added to the reference IMU's stamps, "
                   "s (the import measures the two IMUs' offset and refuses one beyond 10 ms)")
    p.add_argument("--reference-imu-rpy-deg", type=_number(-360.0, 360.0), nargs=3,
                   metavar=("ROLL", "PITCH", "YAW"), help="ros2: the reference IMU's sensor -> "
                   "vehicle (FRD) rotation, deg (default 180 0 0, REP-103)")
    p.add_argument("--pose-topic", help="ros2: a nav_msgs/msg/Odometry or geometry_msgs/msg/"
                   "PoseStamped topic (local ENU frame) as the reference; needs --origin")
    p.add_argument("--origin", type=_number(-360.0, 1e5), nargs=3,
                   metavar=("LAT_DEG", "LON_DEG", "H_M"),
                   help="ros2: geodetic origin of the pose topic's frame (deg, deg, m)")
    p.add_argument("--reference-status", type=_number(-1, 2, int),
                   help="ros2: NavSatFix fixes of at least this status (2 = GBAS_FIX, RTK "
                   "grade) serve as the reference trajectory (/truth/state)")
    p.add_argument("--reference-sigma", type=_number(0.0, 1e4, open_low=True), default=np.inf,
                   help="ros2: and with a horizontal sigma from position_covariance of at most "
                   "this, m")
    p.add_argument("--solutions", nargs="+", default=["fix"],
                   choices=("fix", "float", "sbas", "dgps", "single", "ppp"),
                   help="rtklib: the solution kinds (RTKLIB Q) that serve as the reference "
                   "(default fix; every epoch is kept in /gnss/fix with its sigmas)")
    p.add_argument("--root", metavar="DIR", help="table: the folder of the spec's data files "
                   "(default: the spec's `root`, relative to the spec file)")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.set_defaults(func=_import)
    p = sub.add_parser("windows", help="free-inertial windows of 10/30/60 s restarted from the "
                       "reference (/truth/state) along a recording: position error growth")
    p.add_argument("log", help="log with /mimu/imu (or /mimu/raw and --cal) and /truth/state")
    p.add_argument("--cal", help="calibration: for /mimu/raw the unit's; for /mimu/imu only "
                   "found terms on an identity base (a diagnosis's CAL+found.json)")
    p.add_argument("--lengths", type=SECONDS, nargs="+", default=[10.0, 30.0, 60.0],
                   help="window lengths, s")
    p.add_argument("--step", type=SECONDS, default=5.0, help="spacing of window starts, s")
    p.add_argument("--time-shift", type=_number(-60.0, 60.0), default=0.0,
                   help="added to the IMU stamps, s (negative: the IMU lags)")
    p.add_argument("--min-speed", type=_number(0.0, 1000.0),
                   help="horizontal speed a window must start above, m/s (default: 3 when the "
                   "heading must come from the reference's course, 0 when the reference has "
                   "an attitude)")
    p.add_argument("--max-gap", type=SECONDS, default=1.0,
                   help="longest reference gap allowed inside a window, s (default 1)")
    p.add_argument("-o", "--output", help="folder: windows.json, windows.png")
    p.add_argument("--force", action="store_true", help="replace an existing folder")
    p.set_defaults(func=_windows)
    p = sub.add_parser("table", help="end-point east/north/up errors of calibration variants "
                       "normalised by the FOG-IMU's (seed S1 Table 3)")
    _flight_arguments(p)
    p.add_argument("--cal", action="append", required=True, metavar="NAME=CAL.json",
                   help="a calibration variant (repeat for more)")
    p.add_argument("-o", "--output", help="write OUTPUT.md, OUTPUT.csv, OUTPUT.json")
    p.add_argument("--force", action="store_true", help="replace existing outputs")
    p.set_defaults(func=_table)
    p = sub.add_parser("budget", help="error budget: end-point error with each group of a "
                       "calibration's terms switched off")
    _flight_arguments(p)
    p.add_argument("--cal", required=True, help="calibration file")
    p.set_defaults(func=_budget)
    p = sub.add_parser("reproduce", help="the main job: draw a unit, run the traditional and "
                       "entire lab, fly the high-dynamic profile, write reports/table3.md")
    p.add_argument("-o", "--output", default="reports", help="folder (default: reports)")
    p.add_argument("--seed", type=SEED, default=1, help="draws the unit, lab and noise")
    p.add_argument("--units", type=COUNT, default=16,
                   help="Monte Carlo units (per point with --regime-map; default 16)")
    p.add_argument("--workers", type=_number(1, 256, int), default=2,
                   help="local processes (default 2)")
    p.add_argument("--regime-map", action="store_true",
                   help="instead: the regime map (normalised errors against MIMU grade, FOG "
                   "grade, g exposure and temperature, each point a small Monte Carlo; "
                   "reports/regime.md, resumable)")
    p.add_argument("--scheduler", help="Dask scheduler address for --regime-map")
    _scenario_options(p)
    p.set_defaults(func=_reproduce)
    p = sub.add_parser("campaign", help="Monte Carlo: many units through the same lab and "
                       "flight; results stream to a JSON-lines file and resume")
    p.add_argument("profile", nargs="?", default=str(FLIGHTS / "high-dynamic.toml"),
                   help="flight profile TOML (default: flights/high-dynamic.toml)")
    p.add_argument("-o", "--output", required=True, help="results file (.jsonl), resumed")
    p.add_argument("--units", type=COUNT, default=200, help="units to draw (default 200)")
    p.add_argument("--seed", type=SEED, default=1,
                   help="draws the units, the lab's setting errors and all noise (default 1)")
    p.add_argument("--workers", type=_number(1, 256, int), default=2,
                   help="local processes (default 2)")
    p.add_argument("--scheduler", help="Dask scheduler address (runs there instead)")
    _scenario_options(p, flight=False)
    p.set_defaults(func=_campaign)
    p = sub.add_parser("report", help="generate a report (calibration: the entire lab on "
                       "many units, z-scores of every coefficient, held-out check; recording: "
                       "an imported recording's metadata, channels, free-inertial windows and "
                       "diagnosis; modulation: seed S4's rotation modulation measured - "
                       "platform configurations against error sources, the seed's claims "
                       "checked; rotation-calibration: seed S4's gyro k0..k3 from the rotation "
                       "lab on many units, z-scores and held-out check)")
    p.add_argument("kind", choices=("calibration", "recording", "modulation",
                                    "rotation-calibration"),
                   help="calibration; recording: LOG (a contract log with /mimu/imu and "
                   "/truth/state, e.g. from mimunav import) into the folder -o")
    p.add_argument("log", nargs="?", help="recording: the log (.mcap)")
    p.add_argument("--min-speed", type=_number(0.0, 1000.0), help="recording: horizontal speed (m/s) a window "
                   "needs at its start (default: 3, the alignment's course speed, when the "
                   "reference has no attitude; 0 when it has one)")
    p.add_argument("-o", "--output", default="reports", help="folder (default: reports)")
    p.add_argument("--units", type=COUNT, default=20, help="number of drawn units")
    p.add_argument("--seed", type=SEED, default=1000, help="seed of the first unit")
    p.add_argument("--force", action="store_true", help="replace an existing report")
    p.set_defaults(func=_report)
    return parser


def _probability(text):
    """argparse type: a number strictly between 0 and 1."""
    import argparse
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"{value:g} is not between 0 and 1")
    return value


def _number(lo, hi, kind=float, open_low=False):
    """An argparse type: a finite `kind` number within [lo, hi] ((lo, hi] with open_low),
    checked at parse time."""
    import argparse

    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a{'n integer' if kind is int else ' number'}") from None
        if not np.isfinite(value) or value < lo or value > hi or (open_low and value == lo):
            raise argparse.ArgumentTypeError(
                f"{text} is outside {'(' if open_low else '['}{lo:g}, {hi:g}]")
        return value
    return parse


RATE_HZ = _number(0.0, 1e5, open_low=True)          # sample rates: above 0, at most 100 kHz
SEED = _number(0, 2 ** 32 - 1, int)
COUNT = _number(1, 100000, int)
SECONDS = _number(0.0, 86400.0, open_low=True)


def run():
    """The `mimunav` program (console script and `python -m mimunav`): `main`, then
    `end_process`."""
    end_process(main())


def end_process(status):
    """End the process with exit `status` (None: 0) once a command has returned and written
    its outputs: the atexit handlers run (logging, matplotlib, numba, multiprocessing) and
    the standard streams are flushed, but the interpreter's teardown of every module object
    by object - 0.3-0.6 s after a command that loaded numba's type registries and
    matplotlib - is skipped. With any other thread alive (it would be cut off), a tracer or
    profiler watching (it writes its results at the ordinary exit), a status that is no
    number, or a stream that cannot be flushed (a closed pipe): the ordinary exit instead."""
    import atexit
    # cProfile, pdb, trace, coverage: they write their results at the ordinary exit
    watched = sys.gettrace() is not None or sys.getprofile() is not None
    if threading.active_count() == 1 and not watched and \
            (status is None or isinstance(status, int)):
        atexit._run_exitfuncs()
        try:
            for stream in (sys.stdout, sys.stderr):
                if stream is not None:          # None: the descriptor was closed at start
                    stream.flush()
        except BrokenPipeError:                 # the reader left before the last lines
            os._exit(141)                       # quietly, as `main` ends on one
        except (OSError, ValueError):           # a closed stream
            raise SystemExit(status)
        os._exit(status or 0)
    raise SystemExit(status)


def main(argv=None):
    """Run a command; input errors (the project's `errors.InputError`, the base of every
    mimunav error type, and the operating system's file errors) end with one line naming the
    command and exit status 2, Ctrl-C with one line and 130, a closed stdout pipe quietly
    with 141; anything else is a bug and shows its traceback."""
    args = build_parser().parse_args(argv)
    if args.func not in (_compensate, _info):       # the commands that never turn attitudes
        import_quaternion()
    try:
        with _remembered_interrupts() as interrupted:
            status = args.func(args)
        if interrupted:
            print(f"mimunav {args.command}: interrupted too late to stop (a library's "
                  "callback swallowed it); the outputs are written whole", file=sys.stderr)
            return 130
        return status
    except KeyboardInterrupt:           # outputs are written whole or not at all
        print(f"mimunav {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:             # the reader of stdout left (| head): nothing to say
        if sys.stdout is not None:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141                      # as a process ended by SIGPIPE
    except (OSError, InputError) as exc:
        print(f"mimunav {args.command}: {exc}", file=sys.stderr)
        return 2

"""Command-line interface: `mimunav <command> ...` (also `python -m mimunav`)."""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

FLIGHTS = Path(__file__).resolve().parent.parent / "flights"


def _demo(args):
    """Fly a profile with an ideal IMU through the navigator and print its end error."""
    from . import strapdown, truth
    from .profile import Profile, ProfileError

    try:
        profile = Profile.load(args.profile)
    except (OSError, ProfileError) as exc:
        print(f"mimunav demo: {exc}", file=sys.stderr)
        return 2
    t = np.arange(0, int(round(profile.duration * args.rate)) + 1) / args.rate
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
    from .profile import Profile, ProfileError
    from .sensors import MimuUnit
    from .simulation import simulate_flight
    try:
        profile = Profile.load(args.profile)
        unit = MimuUnit.load(args.unit) if args.unit else None
        log, truth_file = simulate_flight(profile, args.output, args.seed, unit=unit,
                                          fog_rate=args.fog_rate, force=args.force)
    except (OSError, ProfileError, ValueError) as exc:
        print(f"mimunav simulate: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {log}\nwrote {truth_file} (the unit's true coefficients: keep it apart "
          "from the log to diagnose blind)")
    return 0


def _info(args):
    """What an engineer checks first in a log; for a damaged one, what is intact."""
    from .flightlog import FlightLog, LogError
    from .flightlog.inspect import describe
    from .flightlog.recover import describe_scan, recover, scan
    try:
        if args.recover:
            report = recover(args.log, args.recover, force=args.force)
            print(describe_scan(report))
            print(f"wrote the intact part to {args.recover}")
            return 0
        with FlightLog(args.log) as log:
            print(describe(log))
    except LogError as exc:
        print(f"mimunav info: {exc}", file=sys.stderr)
        print(describe_scan(scan(args.log)))
        return 2
    except OSError as exc:
        print(f"mimunav info: {exc}", file=sys.stderr)
        return 2
    return 0


def _compensate(args):
    """Apply a calibration file to a log's raw MIMU channel."""
    from .compensation import Calibration, CalibrationError, compensate_log
    from .flightlog import LogError
    try:
        counts = compensate_log(args.log, Calibration.load(args.cal), args.output, args.force)
    except (OSError, LogError, CalibrationError) as exc:
        print(f"mimunav compensate: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.output} with /mimu/imu; samples replaced (wild values) "
          f"{counts['replaced']}, saturated {counts['saturated']}, unusable {counts['unusable']}")
    return 0


def _unit(args):
    """Draw a MIMU unit (seed S1 Table 2 and datasheet values) into a unit file."""
    from .sensors import MimuUnit
    MimuUnit.draw(args.seed, nonlinearity=args.nonlinearity).save(args.output, args.force)
    print(f"wrote {args.output} (the unit's true coefficients)")
    return 0


def _lab(args):
    """Run a calibration-lab procedure on a unit and record it as a log."""
    from . import lab
    from .sensors import MimuUnit
    log, truth_file = lab.run(lab.plan(args.procedure), MimuUnit.load(args.unit), args.output,
                              args.seed, force=args.force)
    print(f"wrote {log}\nwrote {truth_file} (unit and drawn setting errors)")
    return 0


def _calibrate(args):
    """Fit a calibration method to lab runs and write the calibration file."""
    from .calibration import calibrate, standard_errors
    cal = calibrate(args.runs, args.method, unit=args.unit_name)
    cal.save(args.output, force=args.force)
    rms = cal.covariance.get("residual_rms", {})
    for stage, per_axis in rms.items():
        print(f"{stage:24s} residual rms " + ", ".join(f"{k} {v:.3g}" for k, v in
                                                        per_axis.items()))
    print(f"wrote {args.output} ({cal.model}, {len(standard_errors(cal))} fitted terms "
          "with standard errors and covariance)")
    return 0


def _report(args):
    """Write a generated report into a folder."""
    from .reports import calibration
    md, png = calibration.write(args.output, n_units=args.units, first_seed=args.seed,
                                force=args.force)
    print(f"wrote {md}\nwrote {png}")
    return 0


def build_parser():
    parser = argparse.ArgumentParser(
        prog="mimunav", description="Flight-test evaluation of MEMS IMUs against a FOG-IMU.")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("demo", help="fly a profile with an ideal IMU through the navigator")
    p.add_argument("profile", nargs="?", default=str(FLIGHTS / "high-dynamic.toml"),
                   help="flight profile TOML (default: flights/high-dynamic.toml)")
    p.add_argument("--rate", type=float, default=1000.0, help="IMU sample rate, Hz")
    p.set_defaults(func=_demo)
    p = sub.add_parser("simulate", help="simulate a flight profile into an MCAP log "
                       "(/mimu/raw, /fog/imu, /truth/state) and LOG.truth.json")
    p.add_argument("profile", help="flight profile TOML, e.g. flights/high-dynamic.toml")
    p.add_argument("-o", "--output", required=True, help="log to write (.mcap)")
    p.add_argument("--seed", type=int, default=0, help="draws the units and the noise")
    p.add_argument("--unit", help="MIMU unit file (mimunav-unit/1 JSON) instead of a drawn one")
    p.add_argument("--fog-rate", type=float, default=1000.0, help="FOG-IMU sample rate, Hz")
    p.add_argument("--force", action="store_true", help="replace existing output files")
    p.set_defaults(func=_simulate)
    p = sub.add_parser("compensate", help="apply a calibration to /mimu/raw and write the "
                       "compensated MIMU as /mimu/imu (rad/s, m/s^2, sensor axes)")
    p.add_argument("log", help="MCAP flight log with /mimu/raw")
    p.add_argument("--cal", required=True, help="calibration file (mimunav-calibration/1)")
    p.add_argument("-o", "--output", required=True, help="log to write (.mcap)")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.set_defaults(func=_compensate)
    p = sub.add_parser("info", help="channels, rates, gaps, dropped samples and metadata "
                       "of a log")
    p.add_argument("log", help="MCAP flight log")
    p.add_argument("--recover", metavar="OUT.mcap",
                   help="write the intact part of a damaged (e.g. truncated) log to OUT")
    p.add_argument("--force", action="store_true", help="replace an existing OUT")
    p.set_defaults(func=_info)
    from .calibration import METHODS
    from .lab import PROCEDURES
    p = sub.add_parser("unit", help="draw a simulated MIMU into a unit file (true coefficients)")
    p.add_argument("-o", "--output", required=True, help="unit file to write (.json)")
    p.add_argument("--seed", type=int, default=0, help="draws the unit")
    p.add_argument("--nonlinearity", choices=("table2", "datasheet"), default="table2",
                   help="gyro 2nd-order scale factor: seed Table 2 literally, or /100")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.set_defaults(func=_unit)
    p = sub.add_parser("lab", help="run a calibration-lab procedure on a unit into a log "
                       "(/mimu/raw + /lab/state; see mimunav.lab)")
    p.add_argument("procedure", choices=PROCEDURES)
    p.add_argument("--unit", required=True, help="unit file (mimunav-unit/1 JSON)")
    p.add_argument("-o", "--output", required=True, help="run log to write (.mcap)")
    p.add_argument("--seed", type=int, default=0, help="draws setting errors and noise")
    p.add_argument("--force", action="store_true", help="replace existing outputs")
    p.set_defaults(func=_lab)
    p = sub.add_parser("calibrate", help="fit lab runs into a calibration file "
                       "(mimunav-calibration/1, SI units, covariance included)")
    p.add_argument("runs", nargs="+", help="lab run logs (.mcap)")
    p.add_argument("--method", required=True, choices=METHODS,
                   help="entire: chamber + rate-table + centrifuge; traditional: "
                   "multi-position + single-axis-rate; twelve-position; cold-start")
    p.add_argument("-o", "--output", required=True, help="calibration file to write (.json)")
    p.add_argument("--unit-name", default="", help="unit name written to the file")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.set_defaults(func=_calibrate)
    p = sub.add_parser("report", help="generate a report (calibration: the entire lab on "
                       "many units, z-scores of every coefficient, held-out check)")
    p.add_argument("kind", choices=("calibration",))
    p.add_argument("-o", "--output", default="reports", help="folder (default: reports)")
    p.add_argument("--units", type=int, default=20, help="number of drawn units")
    p.add_argument("--seed", type=int, default=1000, help="seed of the first unit")
    p.add_argument("--force", action="store_true", help="replace an existing report")
    p.set_defaults(func=_report)
    return parser


def main(argv=None):
    """Run a command; input errors (files, formats, fits: OSError and ValueError, the base
    of every mimunav error type) end with one line naming the command and exit status 2."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (OSError, ValueError) as exc:
        print(f"mimunav {args.command}: {exc}", file=sys.stderr)
        return 2

"""Lab commands: calibrate, calibration compare, noise, drift."""
import numpy as np

from .options import imu_channel_arguments, number, span


def _calibrate(args):
    """Fit a calibration method to lab runs and write the calibration file."""
    from ..lab.calibrate import calibrate, standard_errors
    from ..files import refuse_inputs
    refuse_inputs([args.output], [*args.runs, args.noise])
    noise = None
    if args.noise:
        from ..reports.noise import load
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


def _calibration_compare(args):
    """A fitted calibration against the unit's truth file, coefficient by coefficient."""
    from ..compensation.calibration_file import Calibration
    from ..files import read_json
    from ..reports.calibration import compare
    from ..sensors.mimu import MimuUnit
    from ..lab import rotation as rotation_calibration
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
    from ..reports.noise import write
    out = write(args.log, args.output, channel=args.channel, cal_path=args.cal, span=args.span,
                force=args.force)
    print(f"wrote {out}/noise.json, noise.md, noise.png")
    return 0


def _drift(args):
    """Seed S4's AR + Kalman treatment of the gyro drift."""
    from ..reports.drift import write
    out = write(args.log, args.output, channel=args.channel, cal_path=args.cal,
                static=args.static, dynamic=args.dynamic, window_s=args.window_s,
                max_order=args.max_order, force=args.force)
    print(f"wrote {out}/drift.md, drift.json, drift.png")
    return 0


def add_calibrate(sub):
    """The `calibrate` command's parser."""
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


def add_calibration(sub):
    """The `calibration` command's parser."""
    p = sub.add_parser("calibration", help="work with calibration files: compare FIT UNIT")
    compare_sub = p.add_subparsers(dest="action", required=True)
    q = compare_sub.add_parser("compare", help="a fitted entire-63 (or rotation-cubic) file "
                               "against the unit's "
                               "truth file (mimunav-unit/1), in the fit's gauge: fitted, true, "
                               "standard error and z of every coefficient, RMS z per family")
    q.add_argument("fit", help="fitted calibration (mimunav-calibration/1, entire-63)")
    q.add_argument("unit", help="unit file (mimunav-unit/1) or the truth file's unit")
    q.set_defaults(func=_calibration_compare)


def add_noise(sub):
    """The `noise` command's parser."""
    p = sub.add_parser("noise", help="random errors of an IMU channel over a static span: "
                       "Allan deviation per axis with 68 %% bands, IEEE-952 terms with "
                       "intervals -> DIR/noise.json (mimunav-noise/1, SI), noise.md, noise.png")
    imu_channel_arguments(p)
    p.add_argument("--span", type=span, help="T0:T1, s since the channel's first sample "
                   "(default: the longest rest of /truth/state, else the longest still stretch)")
    p.set_defaults(func=_noise)


def add_drift(sub):
    """The `drift` command's parser."""
    p = sub.add_parser("drift", help="seed S4: an AR model of the gyro drift at rest and its "
                       "Kalman filter; variance reduction at rest, what the filter does under "
                       "motion, what it cannot remove -> DIR/drift.md, drift.json, drift.png")
    imu_channel_arguments(p)
    p.add_argument("--static", type=span, help="T0:T1 s of a rest (default: found as by "
                   "`mimunav noise`)")
    p.add_argument("--dynamic", type=span, help="T0:T1 s of a span with motion, to see what "
                   "the filter does there")
    p.add_argument("--window-s", type=number(1e-3, 600.0), default=1.0,
                   help="averaging before the model, s (default 1)")
    p.add_argument("--max-order", type=number(1, 10, int), default=2,
                   help="highest AR order tried (BIC chooses; default 2; the rest must hold "
                   "50 x order averaged samples)")
    p.set_defaults(func=_drift)

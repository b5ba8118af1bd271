"""The report command: generated reports into a folder."""
from ..errors import InputError
from ..importers.kinds import VEHICLES
from .options import COUNT, LEVELS, SEED, number


def _report(args):
    """Write a generated report into a folder."""
    if args.kind == "recording":
        from ..reports import recording
        if not args.log:
            raise InputError("report recording needs the log: mimunav report recording "
                             "LOG.mcap -o DIR (a log from mimunav import ...)")
        if args.output == "reports":
            raise InputError("report recording needs its own folder: -o DIR")
        md = recording.write(args.log, args.output, force=args.force, min_speed=args.min_speed,
                             level=args.level, vehicle=args.vehicle)
        print(f"wrote {md}")
        return 0
    given = [o for o, v in (("--level", args.level != "auto"), ("--vehicle", args.vehicle),
                            ("--min-speed", args.min_speed is not None)) if v]
    if given:
        raise InputError(f"{', '.join(given)}: options of report recording, not of report "
                         f"{args.kind}")
    if args.kind == "rotation-calibration":
        from ..reports import rotation_calibration
        md, png = rotation_calibration.write(args.output, n_units=args.units,
                                             first_seed=args.seed, force=args.force)
        print(f"wrote {md}\nwrote {png}")
        return 0
    if args.kind == "modulation":
        from ..reports import modulation
        md = modulation.write(args.output, units=min(args.units, 50), seed=args.seed,
                              force=args.force)
        print(f"wrote {md}")
        return 0
    from ..reports import calibration
    md, png = calibration.write(args.output, n_units=args.units, first_seed=args.seed,
                                force=args.force)
    print(f"wrote {md}\nwrote {png}")
    return 0


def add_report(sub):
    """The `report` command's parser."""
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
    p.add_argument("--min-speed", type=number(0.0, 1000.0), help="recording: horizontal speed (m/s) a window "
                   "needs at its start (default: 3, the alignment's course speed, when the "
                   "reference has no attitude; 0 when it has one)")
    p.add_argument("--level", choices=LEVELS, default="auto",
                   help="recording: the diagnosis' level, as mimunav diagnose --level "
                   "(default auto)")
    p.add_argument("--vehicle", choices=VEHICLES,
                   help="recording: what carried the IMU, over the recording's metadata, as "
                   "mimunav diagnose --vehicle")
    p.add_argument("-o", "--output", default="reports", help="folder (default: reports)")
    p.add_argument("--units", type=COUNT, default=20, help="number of drawn units")
    p.add_argument("--seed", type=SEED, default=1000, help="seed of the first unit")
    p.add_argument("--force", action="store_true", help="replace an existing report")
    p.set_defaults(func=_report)

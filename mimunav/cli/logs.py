"""Commands on a log itself: info, compensate, cut."""
import sys
from pathlib import Path

from .options import span


def _info(args):
    """What an engineer checks first in a log; for a damaged one, what is intact."""
    from ..flightlog import FlightLog, LogError
    from ..flightlog.inspect import describe
    from ..flightlog.recover import describe_scan, recover, scan
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
        if Path(args.log).is_dir():     # a folder: nothing to scan
            print(f"mimunav info: {exc}", file=sys.stderr)
            return 2
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
    from ..compensation.calibration_file import Calibration
    from ..compensation.model import CalibrationError
    from ..compensation.log import compensate_log
    from ..files import refuse_inputs
    from ..flightlog import LogError
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


def add_compensate(sub):
    """The `compensate` command's parser."""
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


def add_info(sub):
    """The `info` command's parser."""
    p = sub.add_parser("info", help="channels, rates, gaps, dropped samples and metadata "
                       "of a log")
    p.add_argument("log", help="MCAP flight log")
    p.add_argument("--recover", metavar="OUT.mcap",
                   help="write the intact part of a damaged (e.g. truncated) log to OUT")
    p.add_argument("--force", action="store_true", help="replace an existing OUT")
    p.set_defaults(func=_info)


def _cut(args):
    """A log cut to a span of time."""
    from ..files import refuse_inputs
    from ..importers.cut import cut
    refuse_inputs([args.output], [args.log])
    count, how, (first, last) = cut(args.log, args.output, *args.span, force=args.force)
    print(f"wrote {args.output}: {count} messages in {args.span[0]:g}-{args.span[1]:g} s "
          f"(stamped {first:.3f}-{last:.3f} s); initial state: {how}")
    return 0


def add_cut(sub):
    """The `cut` command's parser."""
    p = sub.add_parser("cut", help="the messages of every channel inside a span of time, with "
                       "an initial state inside it, into a new log")
    p.add_argument("log", help="flight log (.mcap)")
    p.add_argument("--span", type=span, required=True,
                   help="T0:T1, s since the log's epoch (the times `mimunav info` and the "
                   "messages name)")
    p.add_argument("-o", "--output", required=True, help="log to write (.mcap)")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.set_defaults(func=_cut)

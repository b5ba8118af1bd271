"""The import command: a recording nobody here wrote into a contract log."""
import argparse
import re
from pathlib import Path

import numpy as np

from ..importers.kinds import KINDS, VEHICLES
from .options import number


def _import(args):
    """A foreign recording into a contract log."""
    from ..files import refuse_inputs
    from ..frames.mounting import Mounting
    from ..importers import registry
    from ..importers.write import summary, write_log
    source = Path(args.source)
    refuse_inputs([args.output], [args.source] + (sorted(map(str, source.iterdir()))
                                                  if source.is_dir() else []))
    mounting = (Mounting.from_rpy_deg(args.mounting_rpy_deg) if args.mounting_rpy_deg
                else None)
    rec = registry.read(args.kind, args.source, mounting,
                        **{name: getattr(args, name) for name in registry.OPTIONS})
    align = write_log(rec, args.output, force=args.force)
    for line in summary(rec, align, args.output):
        print(line)
    return 0


def add_import(sub):
    """The `import` command's parser."""
    p = sub.add_parser("import", help="turn a recording nobody here wrote into a contract log "
                       "(/mimu/imu in SI sensor axes, /truth/state, /gnss/fix, metadata of what "
                       "is real and what is assumed)", add_help=False)
    p.add_argument("-h", "--help", action=_KindHelp, help="show this help and exit; after a "
                   "kind (mimunav import ulog --help), that kind's options only")
    p.add_argument("kind", choices=KINDS,
                   help="rtklib: folder with imu_*.csv, its RTKLIB .tag and an RTKLIB .pos; "
                   "ros1, ros2: a ROS bag of either - a ROS 2 MCAP file, a rosbag2 folder "
                   "(sqlite3 .db3 or MCAP) or a ROS 1 .bag - with sensor_msgs/msg/Imu (+ "
                   "NavSatFix); ulog: a PX4 .ulg "
                   "(its EKF2 estimate as a reference that is not independent); dataflash: an "
                   "ArduPilot .bin or its text .log (IMU, GPS/GPA; reference EKF3 "
                   "POS/XKF1/ATT or the GPS); "
                   "table: a TOML spec of CSV / NumPy columns with units, axes, time base and "
                   "reference (its keys: mimunav import --spec-keys; example "
                   "tests/data/comma2k19.toml)")
    p.add_argument("source", help="the folder (rtklib, a rosbag2 folder), file (ros1/ros2, "
                   "ulog, dataflash) or spec (table)")
    p.add_argument("--imu-instance", type=number(0, 9, int),
                   help="dataflash: the IMU instance (field I; IMU2 = 1), default 0; ulog: "
                   "the sensor_accel/sensor_gyro instance instead of sensor_combined")
    p.add_argument("--reference-imu-instance", type=number(0, 9, int),
                   help="ulog: another sensor_accel/sensor_gyro instance, dataflash: another "
                   "IMU instance (IMU2 = 1) as the reference IMU (/fog/imu: diagnose then "
                   "works at the sensor level)")
    p.add_argument("--reference", choices=("auto", "ekf", "gnss", "none"), default="auto",
                   help="dataflash: the reference trajectory: ekf = the autopilot's estimate "
                   "(POS, XKF1, ATT; not independent), gnss = the GPS fixes (independent, no "
                   "attitude), auto = ekf when logged, else gnss")
    p.add_argument("--gps-status", type=number(3, 6, int), default=3,
                   help="dataflash: the lowest GPS Status that serves as the gnss reference "
                   "(3 3D, 4 DGPS, 5 RTK float, 6 RTK fixed), default 3")
    p.add_argument("-o", "--output", required=True, help="log to write (.mcap)")
    p.add_argument("--mounting-rpy-deg", type=number(-360.0, 360.0), nargs=3, metavar=("ROLL", "PITCH", "YAW"),
                   help="every importer: sensor -> vehicle (FRD) rotation, deg (default: "
                   "rtklib the README's 180 0 180; ros1/ros2 180 0 0, REP-103 x forward, y "
                   "left, z up; ulog and dataflash 0 0 0, the autopilot's FRD body frame; "
                   "table: the spec's axes)")
    p.add_argument("--reference-imu-time-offset", type=number(-60.0, 60.0), default=None,
                   metavar="S", help="ros1/ros2, table, ulog, dataflash: added to the "
                   "reference IMU's stamps, s, before the import measures the two IMUs' offset from their rotation "
                   "rates and corrects what it measures (beyond 1 ms); a clock it cannot time "
                   "is left as given and said")
    p.add_argument("--reference-time-offset", type=number(-3600.0, 3600.0), default=0.0,
                   metavar="S", help="every importer: added to the reference trajectory's "
                   "(and the GNSS fixes') stamps, s, before the import checks them against "
                   "the IMU's rotation (a shift of a second or more it measures is refused, "
                   "naming this option and the value that puts it back)")
    p.add_argument("--sampling", choices=("interval_mean", "instant"), default="interval_mean",
                   help="ros1/ros2: what the Imu messages' values are - the mean over the "
                   "interval their stamp ends (default, the log contract's), or instantaneous "
                   "samples at their stamp (made interval means: each the mean of the interval "
                   "centred on it, stamped half a step later); both IMUs alike")
    p.add_argument("--lever-arm-m", type=number(-100.0, 100.0), nargs=3,
                   metavar=("X", "Y", "Z"), help="every importer: the IMU's place in the "
                   "vehicle frame (FRD), m, from the vehicle origin - the point the reference "
                   "trajectory describes (an INS's, an antenna's, a motion-capture body's); "
                   "replaces the importer's or the spec's (default: at the origin)")
    p.add_argument("--reference-imu-lever-arm-m", type=number(-100.0, 100.0), nargs=3,
                   metavar=("X", "Y", "Z"), help="ros1/ros2, ulog, dataflash: the reference IMU's "
                   "place in the vehicle frame (FRD), m, the IMU where its importer puts it "
                   "(the origin, or the log's INS_POSn); w x (w x r) + dw/dt x r between them")
    _add_ros_options(p)
    p.add_argument("--solutions", nargs="+", default=["fix"],
                   choices=("fix", "float", "sbas", "dgps", "single", "ppp"),
                   help="rtklib: the solution kinds (RTKLIB Q) that serve as the reference "
                   "(default fix; every epoch is kept in /gnss/fix with its sigmas)")
    p.add_argument("--root", metavar="DIR", help="table: the folder of the spec's data files "
                   "(default: the spec's `root`, relative to the spec file)")
    p.add_argument("--vehicle", choices=VEHICLES,
                   help="what carried the IMU (default: not declared - `diagnose` judges it "
                   "from the track): a car's track gives its attitude (no side slip: the track "
                   "level); a train's (canted curves), a two-wheeler's (it leans), an "
                   "aircraft's, a multicopter's, a rocket's or a walker's does not")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.add_argument("--spec-keys", action=_SpecKeys, help="table: print every key a spec may "
                   "hold (sections, units, time bases) and exit")
    p.set_defaults(func=_import)


def _add_ros_options(p):
    """ros1/ros2: the topics, the reference IMU's mounting, the fixes or a pose topic as the
    reference, its frame's origin and azimuth."""
    p.add_argument("--imu-topic", help="ros1/ros2: the sensor_msgs/msg/Imu topic (default: the "
                   "only one)")
    p.add_argument("--fix-topic", help="ros1/ros2: the sensor_msgs/msg/NavSatFix topic "
                   "(default: the only one, if any)")
    p.add_argument("--reference-imu-topic", help="ros1/ros2: a second sensor_msgs/msg/Imu "
                   "topic, a better IMU flown with it, as the reference IMU (/fog/imu: `diagnose` then "
                   "works at the sensor level)")
    p.add_argument("--reference-imu-rpy-deg", type=number(-360.0, 360.0), nargs=3,
                   metavar=("ROLL", "PITCH", "YAW"), help="ros1/ros2: the reference IMU's "
                   "sensor -> vehicle (FRD) rotation, deg (default 180 0 0, REP-103)")
    p.add_argument("--reference-status", type=number(-1, 2, int),
                   help="ros1/ros2: NavSatFix fixes of at least this status (2 = GBAS_FIX, RTK "
                   "grade) serve as the reference trajectory (/truth/state)")
    p.add_argument("--reference-sigma", type=number(0.0, 1e4, open_low=True), default=np.inf,
                   help="ros1/ros2: and with a horizontal sigma from position_covariance of at "
                   "most this, m")
    p.add_argument("--pose-topic", help="ros1/ros2: a nav_msgs/msg/Odometry or geometry_msgs/msg/"
                   "PoseStamped, PoseWithCovarianceStamped or TransformStamped (motion "
                   "capture) topic (local ENU frame, or --pose-azimuth) as the reference; "
                   "needs --origin")
    p.add_argument("--origin", type=number(-360.0, 1e5), nargs=3,
                   metavar=("LAT_DEG", "LON_DEG", "H_M"),
                   help="ros1/ros2: geodetic origin of the pose topic's frame (deg, deg, m)")
    p.add_argument("--pose-azimuth", type=_azimuth, metavar="DEG|unknown",
                   help="ros1/ros2: the pose topic's frame is level, z up, its x axis this far "
                   "east of true north, deg (REP-103's ENU: 90). Not given (or 'unknown'): ENU is "
                   "taken, but its heading measures nothing and no finding stands on it")
    p.add_argument("--reference-independent", metavar="TEXT",
                   help="ros1/ros2: whether the reference (pose topic or fixes) is independent "
                   "of this IMU, 'yes: why' (motion capture) or 'no: why' (a filter that fuses "
                   "it); default: the importer's judgement")


def _azimuth(text):
    """--pose-azimuth: deg within [-360, 360], or 'unknown'."""
    return "unknown" if text.strip().lower() == "unknown" else number(-360.0, 360.0)(text)


class _SpecKeys(argparse.Action):
    """Print the table spec's description (`importers.table`'s) and exit, like --help."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        from ..importers import table
        print(table.__doc__.strip())
        parser.exit()


_KIND_LIST = re.compile(r"(?:^|; |, )((?:%s)(?:[/, ]+(?:%s))*):" % (("|".join(KINDS),) * 2))


def serves(action, kind):
    """Whether an import option serves `kind`: its help names the kinds it is for
    ("ros1/ros2, ulog: ...", "dataflash: ...; ulog: ...") and `kind` among them, or names
    none (-o), or starts "every importer:" (its defaults per kind named after it)."""
    text = action.help or ""
    named = {k for match in _KIND_LIST.findall(text) for k in re.split(r"[/, ]+", match)}
    return text.startswith("every importer:") or not named or kind in named


class _KindHelp(argparse.Action):
    """--help: the whole help, or after a kind (`mimunav import ulog --help`) the options
    that serve that kind (`serves`)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        kind = getattr(namespace, "kind", None)
        if kind is None:
            parser.print_help()
            parser.exit()
        shown = [a for a in parser._actions if a.option_strings and serves(a, kind)]
        formatter = parser.formatter_class(prog=parser.prog)
        formatter.add_usage(f"{parser.prog} {kind} SOURCE -o OUTPUT [options]", None, [])
        formatter.start_section(f"options that serve {kind} (mimunav import --help: all)")
        formatter.add_arguments(shown)
        formatter.end_section()
        print(formatter.format_help(), end="")
        parser.exit()

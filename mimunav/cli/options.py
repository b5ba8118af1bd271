"""Argument types and option groups that several commands share."""
import argparse
from pathlib import Path

import numpy as np

from .. import FLIGHTS
from ..errors import InputError


def number(lo, hi, kind=float, open_low=False):
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


RATE_HZ = number(0.0, 1e5, open_low=True)          # sample rates: above 0, at most 100 kHz


SEED = number(0, 2 ** 32 - 1, int)


COUNT = number(1, 100000, int)


SECONDS = number(0.0, 86400.0, open_low=True)


LEVELS = ("auto", "sensor", "navigation", "track")     # `diagnosis.levels.LEVELS` and auto,
#                                                        named here: the parser loads no level


def probability(text):
    """argparse type: a number strictly between 0 and 1."""
    import argparse
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"{value:g} is not between 0 and 1")
    return value


def span(text):
    try:
        t0, t1 = (float(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected T0:T1 in s, got {text!r}") from None
    if not (np.isfinite(t0) and np.isfinite(t1) and t1 > t0 >= 0):
        raise argparse.ArgumentTypeError(f"need 0 <= T0 < T1 (finite), got {text!r}")
    return t0, t1


def imu_channel_arguments(p):
    """A log's IMU channel in SI units and the output folder (`noise`, `drift`)."""
    p.add_argument("log", help="log (.mcap): a lab run, a simulated flight, an imported recording")
    p.add_argument("--channel", default="/mimu/imu",
                   help="/mimu/imu (default), /fog/imu, or /mimu/raw with --cal")
    p.add_argument("--cal", help="calibration file, to read /mimu/raw in SI units")
    p.add_argument("-o", "--output", required=True, help="folder to write")
    p.add_argument("--force", action="store_true", help="replace an existing folder")


def flight_arguments(p):
    p.add_argument("log", help="flight log (.mcap) with the MIMU (/mimu/raw, or /mimu/imu as "
                   "recorded: a calibration of found terms on an identity base) and /fog/imu")
    p.add_argument("--end", type=number(-1e9, 1e9), help="end point, s since the log's epoch "
                   "(default: the last instant every channel covers)")


def scenario_options(p, flight=True):
    """The options of `campaign.Scenario`: what shapes a Table 3 comparison."""
    if flight:
        p.add_argument("--flight", default=str(FLIGHTS / "high-dynamic.toml"),
                       help="flight profile TOML (default: flights/high-dynamic.toml, seed S1 "
                       "4.2)")
    p.add_argument("--severity", type=number(1e-3, 10.0), default=1.0,
                   help="scale the flight's dynamics: g exposure (n - 1), accelerations and "
                   "rates x S (default 1)")
    p.add_argument("--ground-temperature-c", type=number(-60.0, 60.0), default=15.0,
                   help="air temperature at the start height, degC (default 15, ISA)")
    p.add_argument("--warm-up-s", type=number(0.0, 86400.0), default=600.0,
                   help="MIMU powered on this long before take-off, s (default 600: the "
                   "reference's ground alignment; 0 = cold at take-off, with --gyro-zero lab: "
                   "a pre-flight zero takes the warm-up's last 10 s)")
    p.add_argument("--mimu-grade", default="table1",
                   help="MIMU random errors (default table1: seed S1 Table 1 at its bound; "
                   "tactical: ADIS16488A class; stim300: STIM300 class)")
    p.add_argument("--nonlinearity", default="table1",
                   help="nonlinear scale factors: table1 = Table 2 scaled to Table 1's fit "
                   "residual (default), table2 = Table 2 literally")
    p.add_argument("--fog-grade", default="table4",
                   help="reference FOG-IMU (default table4: Table 4 medium accuracy; "
                   "table4-bound: its bounds as 1 sigma; table4-stability: its zero drift "
                   "read as Table 1's is, a 10 s bias stability; navigation: 0.01 deg/h class)")
    p.add_argument("--gyro-zero", choices=("pre-flight", "lab"), default="pre-flight",
                   help="the traditional calibration's gyro zero: pre-flight = taken still in "
                   "the launch attitude over the warm-up's last 10 s (default; seed S1's refs "
                   "calibrate no gyro zero in the lab); lab = fitted on the rate table at "
                   "25 degC")
    p.add_argument("--start", choices=("air", "ground"), default="air",
                   help="air = both navigators start from the exact state (default); ground = "
                   "from the FOG-IMU's gyrocompass over the flight's first 120 s at rest, the "
                   "MIMU given the same attitude (a profile that begins at rest: "
                   "flights/boost-coast.toml, flights/ground-gentle.toml)")
    p.add_argument("--duration-s", type=number(0.0, 86400.0), default=0.0,
                   help="the end point this long after the navigators' start, s (default 0: "
                   "the flight's end; the seed gives no duration)")
    p.add_argument("--g-sensitivity", type=number(0.0, 100.0), default=1.0,
                   help="scale the gyros' drawn g-sensitivity C (default 1: seed S1 Table 2's "
                   "0.01-0.04 (deg/s)/g; 0 = none)")
    p.add_argument("--exact-model", action="store_true",
                   help="MIMU exactly the 63-coefficient model (no scale asymmetry, no dT term)")


def flight_path(given):
    """The profile TOML `given` (a path), else the shipped profile of that file name
    (`flights/` of the package: the names the help and the messages give work from any
    folder); InputError naming the shipped ones when neither exists."""
    path = Path(given)
    if path.exists():
        return path.resolve()
    shipped = FLIGHTS / path.name
    if shipped.exists():
        return shipped
    names = ", ".join(sorted(p.name for p in FLIGHTS.glob("*.toml")))
    raise InputError(f"flight profile {given}: no such file, nor a shipped profile of that "
                     f"name ({names}, in {FLIGHTS})")


def scenario(args):
    from ..evaluation.campaign import Scenario
    return Scenario(flight=str(flight_path(args.flight)), severity=args.severity,
                    ground_temperature_c=args.ground_temperature_c, warm_up_s=args.warm_up_s,
                    mimu_grade=args.mimu_grade,
                    nonlinearity=args.nonlinearity, fog_grade=args.fog_grade,
                    beyond_model=not args.exact_model,
                    gyro_zero=args.gyro_zero, start=args.start,
                    g_sensitivity=args.g_sensitivity, duration_s=args.duration_s)


def variant_paths(specs):
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


def variants(specs):
    from ..compensation.calibration_file import Calibration
    return {name: Calibration.load(path) for name, path in variant_paths(specs).items()}


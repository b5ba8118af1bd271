"""Commands that make data: demo, simulate, unit, lab."""
import sys
import time

import numpy as np

from .. import FLIGHTS
from ..errors import InputError
from .options import RATE_HZ, SEED, number


DEMO_MAX_SAMPLES = 20_000_000      # ~150 bytes per sample held (truth, increments, navigation)


def _demo(args):
    """Fly a profile with an ideal IMU through the navigator and print its end error."""
    from ..navigation import strapdown
    from ..motion import truth
    from ..motion.profile import Profile, ProfileError

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
    from ..motion.profile import Profile
    from ..sensors.mimu import MimuUnit
    from ..sensors.hidden import parse_term
    from ..files import refuse_inputs
    from ..sensors.simulation import simulate_flight, truth_file
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
            from ..motion.platform import Platform
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


def _unit(args):
    """Draw a MIMU unit (seed S1 Table 2 and datasheet values) into a unit file."""
    from ..sensors.mimu import MimuUnit
    MimuUnit.draw(args.seed, nonlinearity=args.nonlinearity, grade=args.grade,
                  beyond_model=not args.exact_model).save(args.output, args.force)
    print(f"wrote {args.output} (the unit's true coefficients)")
    return 0


def _lab(args):
    """Run a calibration-lab procedure on a unit and record it as a log."""
    from ..lab import procedures as lab
    from ..files import refuse_inputs
    from ..sensors.mimu import MimuUnit
    from ..sensors.simulation import truth_file
    refuse_inputs([args.output, truth_file(args.output)], [args.unit])
    log, truth = lab.run(lab.plan(args.procedure), MimuUnit.load(args.unit), args.output,
                              args.seed, force=args.force)
    print(f"wrote {log}\nwrote {truth} (unit and drawn setting errors)")
    return 0


def add_demo(sub):
    """The `demo` command's parser."""
    p = sub.add_parser("demo", help="fly a profile with an ideal IMU through the navigator")
    p.add_argument("profile", nargs="?", default=str(FLIGHTS / "high-dynamic.toml"),
                   help="flight profile TOML (default: flights/high-dynamic.toml)")
    p.add_argument("--rate", type=RATE_HZ, default=1000.0, help="IMU sample rate, Hz")
    p.set_defaults(func=_demo)


def add_simulate(sub):
    """The `simulate` command's parser."""
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
    p.add_argument("--platform-rate-deg-s", type=number(1e-3, 1000.0), default=10.0,
                   help="platform rate, deg/s (default 10)")
    p.add_argument("--platform-swing-deg", type=number(1.0, 36000.0), default=360.0,
                   help="back-and-forth: turn this far each way, deg (default 360)")
    p.add_argument("--platform-encoder-arcsec", type=number(0.0, 3600.0), default=1.58,
                   help="resolution of the recorded platform angle, arcsec (default 1.58, the "
                   "seed S4 circular grating; 0: exact)")
    p.add_argument("--platform-encoder-noise-arcsec", type=number(0.0, 3600.0), default=0.0,
                   help="white read-out noise of the platform angle, arcsec 1 sigma (default 0)")
    p.add_argument("--platform-lever-arm-m", type=number(-10.0, 10.0), nargs=3,
                   metavar=("X", "Y", "Z"), help="the IMU's origin from the platform axis "
                   "point (the vehicle origin), m, platform axes turning with it (default 0)")
    p.add_argument("--platform-dwell-s", type=number(0.0, 3600.0), default=0.0,
                   help="back-and-forth: pause at each end, s (default 0)")
    p.add_argument("--inclination-deg", type=number(-90.0, 90.0), default=0.0,
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


def add_unit(sub):
    """The `unit` command's parser."""
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


def add_lab(sub):
    """The `lab` command's parser."""
    p = sub.add_parser("lab", help="run a calibration-lab procedure on a unit into a log "
                       "(/mimu/raw + /lab/state; see mimunav.lab)")
    p.add_argument("procedure", help="thermal-chamber, rate-table, centrifuge, multi-position, "
                   "single-axis-rate, twelve-position, cold-start, rotation or hand-held")
    p.add_argument("--unit", required=True, help="unit file (mimunav-unit/1 JSON)")
    p.add_argument("-o", "--output", required=True, help="run log to write (.mcap)")
    p.add_argument("--seed", type=SEED, default=0, help="draws setting errors and noise")
    p.add_argument("--force", action="store_true", help="replace existing outputs")
    p.set_defaults(func=_lab)

"""Evaluation commands: replay, windows, table, budget, reproduce, campaign."""
import argparse
from pathlib import Path

import numpy as np

from .. import FLIGHTS
from .options import (COUNT, SECONDS, SEED, flight_arguments, number, scenario,
                      scenario_options, variant_paths, variants)


def _replay(args):
    """Compensate, navigate both IMUs and compare; outputs into a new folder, atomically."""
    import json

    from ..reports.replay import write
    summary = write(args.log, args.cal, args.output, args.end, args.nav_rate, args.force)
    for key, v in summary["end"].items():
        e = v["position_enu_m"]
        print(f"{key:11s} end position error east {e[0]:+.3g} m, north {e[1]:+.3g} m, "
              f"up {e[2]:+.3g} m")
    if args.json:
        print(json.dumps(summary))
    print(f"wrote {Path(args.output)}/nav.mcap, summary.json, errors.png")
    return 0


def _windows(args):
    """Free-inertial windows against the reference trajectory."""
    import json

    from ..evaluation import windows
    from ..evaluation.flight import Flight
    from ..compensation.calibration_file import Calibration
    from ..files import atomic_folder, refuse_inputs
    from ..reports import windows as report
    refuse_inputs([args.output], [args.log, args.cal])
    if args.output and Path(args.output).exists() and not args.force:
        raise FileExistsError(f"{args.output} exists; use --force to replace it")
    flight = Flight.load(args.log, reference_imu=False, max_gap_s=np.inf)
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


def _table(args):
    """The normalised end-point table (seed S1 Table 3) for any number of variants."""
    import json

    from ..evaluation.flight import Flight
    from ..evaluation.table import normalised_table, table_csv, table_markdown
    from ..files import refuse_inputs, write_atomic
    written = [args.output + ext for ext in (".md", ".csv", ".json")] if args.output else []
    refuse_inputs(written, [args.log, *variant_paths(args.cal).values()])
    for path in written:                                        # before the work
        if Path(path).exists() and not args.force:
            raise FileExistsError(f"{path} exists; use --force")
    flight = Flight.load(args.log, stream=True)      # bounded memory
    doc = normalised_table(flight, variants(args.cal), args.end, check=True)
    text = table_markdown(doc)
    if args.output:
        outputs = {".md": text, ".csv": table_csv(doc),
                   ".json": json.dumps(doc, indent=1) + "\n"}
        for ext, content in outputs.items():
            write_atomic(args.output + ext, content, force=args.force)
    print(text, end="")
    return 0


def _budget(args):
    """Error budget: end-point error with each group of a calibration's terms off."""
    from ..evaluation.flight import Flight
    from ..evaluation.table import budget_markdown, error_budget
    flight = Flight.load(args.log)
    (cal,) = variants([args.cal]).values()
    print(budget_markdown(error_budget(flight, cal, args.end)), end="")
    return 0


def _reproduce(args):
    """The main job: seed S1 Table 3 for a drawn unit, budget and Monte Carlo."""
    from ..reports.table3 import reproduce
    if args.regime_map:
        from ..reports.regime import regime_map
        md = regime_map(args.output, seed=args.seed, units=args.units, workers=args.workers,
                        scheduler=args.scheduler, base=scenario(args))
    else:
        md = reproduce(args.output, seed=args.seed, mc_units=args.units, force=True,
                       scenario=scenario(args), workers=args.workers)
    print(f"wrote {md}")
    return 0


def _campaign(args):
    """Monte Carlo over units: the distribution of every normalised end error."""
    from ..evaluation import campaign
    drawn = scenario(argparse.Namespace(**dict(vars(args), flight=args.profile)))
    records = campaign.run_campaign(drawn, args.units, args.seed, args.output,
                                    workers=args.workers, scheduler=args.scheduler)
    print(campaign.summary_markdown(campaign.summary(records), len(records)), end="")
    return 0


def add_replay(sub):
    """The `replay` command's parser."""
    p = sub.add_parser("replay", help="compensate the MIMU, navigate MIMU and FOG-IMU with "
                       "the same navigator, compare with the truth and each other")
    flight_arguments(p)
    p.add_argument("--cal", required=True, help="calibration file (mimunav-calibration/1)")
    p.add_argument("-o", "--output", required=True, help="folder for nav.mcap (NavState "
                   "/mimu/nav, /fog/nav, vehicle origin), summary.json, errors.png")
    p.add_argument("--nav-rate", type=number(0.0, 1e4, open_low=True), default=10.0,
                   help="rate of the NavState channels written to nav.mcap, Hz (default 10)")
    p.add_argument("--json", action="store_true", help="also print the summary as JSON")
    p.add_argument("--force", action="store_true", help="replace an existing folder")
    p.set_defaults(func=_replay)


def add_windows(sub):
    """The `windows` command's parser."""
    p = sub.add_parser("windows", help="free-inertial windows of 10/30/60 s restarted from the "
                       "reference (/truth/state) along a recording: position error growth")
    p.add_argument("log", help="log with /mimu/imu (or /mimu/raw and --cal) and /truth/state")
    p.add_argument("--cal", help="calibration: for /mimu/raw the unit's; for /mimu/imu only "
                   "found terms on an identity base (a diagnosis's CAL+found.json)")
    p.add_argument("--lengths", type=SECONDS, nargs="+", default=[10.0, 30.0, 60.0],
                   help="window lengths, s")
    p.add_argument("--step", type=SECONDS, default=5.0, help="spacing of window starts, s")
    p.add_argument("--time-shift", type=number(-60.0, 60.0), default=0.0,
                   help="added to the IMU stamps, s (negative: the IMU lags)")
    p.add_argument("--min-speed", type=number(0.0, 1000.0),
                   help="horizontal speed a window must start above, m/s (default: 3 when the "
                   "heading must come from the reference's course, 0 when the reference has "
                   "an attitude)")
    p.add_argument("--max-gap", type=SECONDS,
                   help="longest reference gap allowed inside a window, s (default: 1, or 2.5 "
                   "of the reference's own median steps when they are longer: 1 Hz fixes)")
    p.add_argument("-o", "--output", help="folder: windows.json, windows.png")
    p.add_argument("--force", action="store_true", help="replace an existing folder")
    p.set_defaults(func=_windows)


def add_table(sub):
    """The `table` command's parser."""
    p = sub.add_parser("table", help="end-point east/north/up errors of calibration variants "
                       "normalised by the FOG-IMU's (seed S1 Table 3)")
    flight_arguments(p)
    p.add_argument("--cal", action="append", required=True, metavar="NAME=CAL.json",
                   help="a calibration variant (repeat for more)")
    p.add_argument("-o", "--output", help="write OUTPUT.md, OUTPUT.csv, OUTPUT.json")
    p.add_argument("--force", action="store_true", help="replace existing outputs")
    p.set_defaults(func=_table)


def add_budget(sub):
    """The `budget` command's parser."""
    p = sub.add_parser("budget", help="error budget: end-point error with each group of a "
                       "calibration's terms switched off")
    flight_arguments(p)
    p.add_argument("--cal", required=True, help="calibration file")
    p.set_defaults(func=_budget)


def add_reproduce(sub):
    """The `reproduce` command's parser."""
    p = sub.add_parser("reproduce", help="the main job: draw a unit, run the traditional and "
                       "entire lab, fly the high-dynamic profile, write reports/table3.md")
    p.add_argument("-o", "--output", default="reports", help="folder (default: reports)")
    p.add_argument("--seed", type=SEED, default=1, help="draws the unit, lab and noise")
    p.add_argument("--units", type=COUNT, default=16,
                   help="Monte Carlo units (per point with --regime-map; default 16)")
    p.add_argument("--workers", type=number(1, 256, int), default=2,
                   help="local processes (default 2)")
    p.add_argument("--regime-map", action="store_true",
                   help="instead: the regime map (normalised errors against MIMU grade, FOG "
                   "grade, g exposure and temperature, each point a small Monte Carlo; "
                   "reports/regime.md, resumable)")
    p.add_argument("--scheduler", help="Dask scheduler address for --regime-map")
    scenario_options(p)
    p.set_defaults(func=_reproduce)


def add_campaign(sub):
    """The `campaign` command's parser."""
    p = sub.add_parser("campaign", help="Monte Carlo: many units through the same lab and "
                       "flight; results stream to a JSON-lines file and resume")
    p.add_argument("profile", nargs="?", default=str(FLIGHTS / "high-dynamic.toml"),
                   help="flight profile TOML (default: flights/high-dynamic.toml)")
    p.add_argument("-o", "--output", required=True, help="results file (.jsonl), resumed")
    p.add_argument("--units", type=COUNT, default=200, help="units to draw (default 200)")
    p.add_argument("--seed", type=SEED, default=1,
                   help="draws the units, the lab's setting errors and all noise (default 1)")
    p.add_argument("--workers", type=number(1, 256, int), default=2,
                   help="local processes (default 2)")
    p.add_argument("--scheduler", help="Dask scheduler address (runs there instead)")
    scenario_options(p, flight=False)
    p.set_defaults(func=_campaign)

"""Benchmarks of evaluation: `mimunav replay` and `mimunav compensate` of a 10-minute 1 kHz
log (MIMU + FOG) end to end, a Monte Carlo campaign of many units on a 100 s 1 kHz flight,
and `mimunav reproduce` (Table 3 with its 16-unit Monte Carlo).

    python bench/evaluation.py [--units 200] [--repeats 3] [--skip-reproduce] [--json out.json]

Replay and compensate: the high-dynamic profile's segments repeated to 600 s, simulated once,
then each CLI command timed in a fresh process (replay: reading, compensation, both
navigations, comparison, nav.mcap, summary and plots; compensate: reading, the wild-value
filter and eqs. 1-4, the compensated log written), best and median of --repeats. Campaign:
`mimunav.evaluation.campaign.run_campaign` on 2 local processes, each unit drawn, calibrated `entire`
and `traditional` in the lab (in memory, no covariance propagation) and flown. Reproduce:
`mimunav reproduce -o TMP` as a user runs it (2 workers).
"""
import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from publish import publish, timed_cli  # noqa: E402
from mimunav.evaluation import campaign                      # noqa: E402
from mimunav.motion.profile import Profile, dumps        # noqa: E402
from mimunav.sensors.simulation import simulate_flight    # noqa: E402


def profile_doc(duration, name):
    """High-dynamic segments repeated, then a coast, to `duration` s."""
    base = Profile.load(ROOT / "flights" / "high-dynamic.toml")
    doc = {"name": name, "description": f"high-dynamic segments to {duration} s",
           "start": {"latitude_deg": 40, "longitude_deg": 100, "height_m": 3000,
                     "speed_m_s": 250, "heading_deg": 30, "ramp_s": 0.2}, "segment": []}
    while Profile.from_dict(dict(doc, segment=doc["segment"] + base.segments)).duration \
            < duration - 10:
        doc["segment"] += base.segments
    total = Profile.from_dict(doc).duration if doc["segment"] else 0.0
    doc["segment"].append({"kind": "coast", "duration_s": duration - total})
    return doc


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--units", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3, help="runs of replay and compensate")
    ap.add_argument("--skip-reproduce", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    res = {"machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_version()}"}
    with tempfile.TemporaryDirectory() as tmp:
        log, truth = simulate_flight(Profile.from_dict(profile_doc(600.0, "ten-minutes")),
                                     os.path.join(tmp, "ten.mcap"), 1, progress=False)
        cal = os.path.join(tmp, "cal.json")
        from mimunav.compensation.calibration_file import Calibration
        Calibration.from_dict(json.load(open(truth))["mimu"]["coefficients"]).save(cal)
        for name, cmd in (("replay", ["replay", log, "--cal", cal, "-o"]),
                          ("compensate", ["compensate", log, "--cal", cal, "-o"])):
            runs = [timed_cli(cmd + [os.path.join(tmp, f"{name}{k}" + (
                ".mcap" if name == "compensate" else ""))]) for k in range(args.repeats)]
            res[f"{name}_600s_1kHz_s"] = min(runs)
            res[f"{name}_600s_1kHz_s_median"] = float(sorted(runs)[len(runs) // 2])
        hundred = os.path.join(tmp, "hundred.toml")
        doc = profile_doc(100.0, "hundred-seconds")
        Path(hundred).write_text(dumps(doc))
        t0 = time.perf_counter()
        records = campaign.run_campaign(hundred, args.units, 1, os.path.join(tmp, "c.jsonl"))
        res["campaign_units"] = len(records)
        res["campaign_100s_1kHz_s"] = time.perf_counter() - t0
        if not args.skip_reproduce:
            res["reproduce_s"] = timed_cli(["reproduce", "-o", os.path.join(tmp, "reports")])
    rows = [(f"`mimunav {name}` of a 600 s 1 kHz log, end to end",
             f"{res[f'{name}_600s_1kHz_s']:.1f} s best, "
             f"{res[f'{name}_600s_1kHz_s_median']:.1f} s median of {args.repeats}")
            for name in ("replay", "compensate")]
    rows.append((f"campaign of {res['campaign_units']} units on a 100 s 1 kHz flight",
                 f"{res['campaign_100s_1kHz_s']:.0f} s"))
    if "reproduce_s" in res:
        rows.append(("`mimunav reproduce` (Table 3, 16 units, 2 workers)",
                     f"{res['reproduce_s']:.0f} s"))
    publish(__file__, rows, res, args.json)


if __name__ == "__main__":
    main()

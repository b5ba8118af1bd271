"""Benchmarks and proof of the diagnosis.

    python bench/diagnosis.py [--repeats 2] [--nulls 40] [--report reports] [--json out.json]

1. `mimunav diagnose` of a 10-minute 1 kHz flight (the proof flight's manoeuvres repeated to
   600 s, a hidden g-sensitivity), timed end to end in a fresh process with its report.
2. The development sets of an independent simulator (shared/data/foreign-flights and
   foreign-flights-2): each log diagnosed with its calibration and scored against its answer key.
3. The concealed-data suite (`mimunav.diagnosis.concealed.run_suite`): every proof effect
   `--repeats` times and `--nulls` null recordings on 2 processes; writes
   REPORT/diagnosis-proof.md and .json with the development-set score beside it.
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from publish import publish                                  # noqa: E402
from mimunav.sensors import simulation                               # noqa: E402
from mimunav.diagnosis import concealed                      # noqa: E402
from mimunav.motion.profile import Profile                          # noqa: E402
from mimunav.reports.diagnosis import proof_markdown         # noqa: E402
from mimunav.sensors.mimu import MimuUnit                         # noqa: E402

PROOF = ROOT / "flights" / "diagnosis-proof.toml"


def ten_minutes():
    """The proof flight with its manoeuvres (not its speed changes) flown again to ~600 s."""
    import tomllib
    doc = tomllib.loads(PROOF.read_text())
    doc["name"] = "diagnosis-ten-minutes"
    again = [seg for seg in doc["segment"] if seg["kind"] != "accelerate"]   # speed kept
    while Profile.from_dict(doc).duration < 590:
        doc["segment"] += again
    return Profile.from_dict(doc)


FOREIGN = [ROOT.parent / "shared" / "data" / "foreign-flights",
           ROOT.parent / "shared" / "data" / "foreign-flights-2"]


def named(hidden, findings):
    """Whether a finding names the hidden effect (effect, sensor, axis) with its truth - a
    quantization's SI step, a temperature term per Hz where the key gives one - inside its
    95 % interval."""
    truth = hidden.get("step_si", hidden.get("coefficient_per_hz", hidden["coefficient"]))
    return any((f["effect"], f["sensor"], f["axis"]) ==
               (hidden["effect"], hidden["sensor"], hidden["axis"])
               and f["ci95"][0] <= truth <= f["ci95"][1] for f in findings)


def foreign_flights():
    """Score of `mimunav diagnose` on the foreign development sets: per log the keys, the
    verdict, the findings and whether every hidden effect is named inside its interval (an
    effect-free log: whether it is quiet)."""
    from mimunav.compensation.calibration_file import Calibration
    from mimunav.diagnosis import sensor
    from mimunav.evaluation.flight import Flight
    rows = []
    for key_path in sorted(p for folder in FOREIGN for p in folder.glob("*.key.json")):
        base = str(key_path)[:-len(".key.json")]
        key = json.loads(key_path.read_text())["hidden"]
        hidden = [] if key is None else [key] if isinstance(key, dict) else key
        t0 = time.perf_counter()
        diag = sensor.diagnose(Flight.load(base + ".mcap"), Calibration.load(base + ".cal.json"))
        row = {"log": Path(base).name, "verdict": sensor.verdict(diag),
               "findings": [f["label"] for f in diag.findings],
               "seconds": time.perf_counter() - t0}
        if not hidden:
            row["correct"] = row["verdict"] == "no-missing-physics"
        else:
            row["hidden"] = [f"{h['effect']} {h['sensor']}.{h['axis']}" for h in hidden]
            row["correct"] = all(named(h, diag.findings) for h in hidden)
        rows.append(row)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--nulls", type=int, default=40)
    ap.add_argument("--report", default=str(ROOT / "reports"))
    ap.add_argument("--seed", type=int, default=100, help="first seed of the suite's recordings")
    ap.add_argument("--skip-suite", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    res = {"machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_version()}"}
    with tempfile.TemporaryDirectory() as tmp:
        unit = MimuUnit.draw(21)
        unit.mounting = concealed.proof_mounting()
        prof = ten_minutes()
        hidden = concealed.draw("g_sensitivity", np.random.default_rng(21), unit, prof.duration)
        log, _ = simulation.simulate_flight(prof, os.path.join(tmp, "ten.mcap"), 21, unit=unit,
                                            hidden=hidden, progress=False)
        cal = os.path.join(tmp, "model.json")
        unit.coefficients.save(cal)
        t0 = time.perf_counter()
        run = subprocess.run([sys.executable, "-m", "mimunav", "diagnose", log, "--model", cal,
                              "-o", os.path.join(tmp, "rep")], check=True, capture_output=True,
                             text=True)
        res["diagnose_%.0fs_1kHz_s" % prof.duration] = time.perf_counter() - t0
        res["diagnose_output"] = run.stdout.strip().splitlines()[:3]
        res["hidden"] = hidden.as_dict()
    res["foreign_flights"] = foreign_flights()
    if not args.skip_suite:
        t0 = time.perf_counter()
        cases = concealed.run_suite(str(PROOF), repeats=args.repeats, nulls=args.nulls,
                                    seed=args.seed)
        wall = time.perf_counter() - t0
        summary = concealed.summary(cases)
        res["suite_s"], res["suite"] = wall, summary
        meta = {"command": f"python bench/diagnosis.py --repeats {args.repeats} --nulls "
                           f"{args.nulls} --seed {args.seed}", "machine": res["machine"], "wall_s": wall,
                "duration_s": Profile.load(PROOF).duration, "foreign": res["foreign_flights"]}
        out = Path(args.report)
        out.mkdir(parents=True, exist_ok=True)
        from mimunav.files import write_atomic
        write_atomic(out / "diagnosis-proof.md", proof_markdown(cases, summary, meta), force=True)
        write_atomic(out / "diagnosis-proof.json", json.dumps(
            {"summary": summary, "cases": cases, "meta": meta}, indent=1, default=float) + "\n",
            force=True)
    diag = next(k for k in res if k.startswith("diagnose_"))
    foreign = res["foreign_flights"]
    rows = [(f"`mimunav diagnose` of a {prof.duration:.0f} s 1 kHz flight with its report",
             f"{res[diag]:.1f} s"),
            (f"foreign development set ({len(foreign)} logs of an independent simulator)",
             f"{sum(r['correct'] for r in foreign)} of {len(foreign)} correct (the hidden "
             "effect named with its truth in the 95 % interval; an effect-free log quiet)")]
    if "suite" in res:
        s = res["suite"]
        rate = lambda r: f"{r['k']}/{r['n']}"                             # noqa: E731
        rows.append((f"concealed-data suite ({s['with_effect']} effects, {s['nulls']} nulls; "
                     "reports/diagnosis-proof.md)",
                     f"identified {rate(s['identified'])}, coverage "
                     f"{rate(s['interval_coverage'])}, false alarms {rate(s['false_alarms'])}; "
                     f"{res['suite_s']:.0f} s"))
    publish(__file__, rows, res, args.json)


if __name__ == "__main__":
    main()

"""Benchmark of the whole `entire` lab: thermal chamber + rate table + centrifuge simulated
into logs and fitted into a calibration file, as `mimunav lab` / `mimunav calibrate` do.

    python bench/lab.py [--seed 7] [--json out.json]

Times include writing and reading the logs (a fresh process: JIT caches warm from earlier
runs, as for a user's second command). Target: under 60 s on 2 cores.
"""
import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from publish import publish  # noqa: E402
from mimunav.lab import procedures as lab
from mimunav.lab.calibrate import calibrate, standard_errors
from mimunav.lab.runs import LabRun          # noqa: E402
from mimunav.sensors.mimu import MimuUnit          # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--json")
    args = ap.parse_args()
    unit = MimuUnit.draw(args.seed)
    res = {"machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_version()}"}
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for proc in ("thermal-chamber", "rate-table", "centrifuge"):
            t0 = time.perf_counter()
            paths.append(lab.run(lab.plan(proc), unit, os.path.join(tmp, proc + ".mcap"),
                                 args.seed)[0])
            res[f"{proc}_s"] = time.perf_counter() - t0
            res[f"{proc}_samples"] = LabRun.load(paths[-1]).t.size
        t0 = time.perf_counter()
        cal = calibrate(paths, "entire")
        res["fit_s"] = time.perf_counter() - t0
    res["total_s"] = time.perf_counter() - t_all
    samples = " + ".join(f"{res[p + '_samples'] / 1e3:.0f}k" for p in
                         ("thermal-chamber", "rate-table", "centrifuge"))
    publish(__file__, [
        (f"entire lab (chamber + rate table + centrifuge: {samples} samples) simulated, "
         f"logged and fitted ({len(standard_errors(cal))} coefficients)",
         f"{res['total_s']:.1f} s (fit {res['fit_s']:.1f} s)")], res, args.json)


if __name__ == "__main__":
    main()

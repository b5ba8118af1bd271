"""BLAS threads against the machine's load: `mimunav diagnose` of a foreign development
flight in a fresh process with one OpenBLAS thread and with OpenBLAS's default (one per
core), each while the machine is idle and while N other processes keep cores busy.

    python bench/blas.py [--log ../shared/data/foreign-flights/foreign-02] [--busy 0 1 3]

The CLI uses one thread unless OPENBLAS_NUM_THREADS or OMP_NUM_THREADS is set.
"""
import argparse
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

from publish import publish, timed_cli

ROOT = Path(__file__).resolve().parent.parent
BUSY = "import time\nt = time.time()\nwhile time.time() - t < 600: pass\n"


def diagnose(log, threads, out):
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    if threads:
        env["OPENBLAS_NUM_THREADS"] = str(threads)
    else:                                  # the library's default: a thread per core
        env["OPENBLAS_NUM_THREADS"] = str(os.cpu_count())
    return timed_cli(["diagnose", log + ".mcap", "--model", log + ".cal.json", "-o", out,
                      "--force"], env)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--log", default=str(ROOT.parent / "shared" / "data" / "foreign-flights"
                                         / "foreign-02"))
    ap.add_argument("--busy", type=int, nargs="+", default=[0, 1, 3])
    ap.add_argument("--json")
    args = ap.parse_args()
    res, rows = {"machine": f"{platform.machine()} {os.cpu_count()} cores"}, []
    with tempfile.TemporaryDirectory() as tmp:
        for busy in args.busy:
            hogs = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(busy)]
            try:
                for threads in (1, 0):
                    s = diagnose(args.log, threads, os.path.join(tmp, "d"))
                    label = "1 thread" if threads else f"{os.cpu_count()} threads"
                    res[f"busy{busy}_{label}"] = s
                    rows.append((f"`mimunav diagnose` of {Path(args.log).name}, {label}, "
                                 f"{busy} other busy process(es)", f"{s:.1f} s"))
            finally:
                for h in hogs:
                    h.kill()
    publish(__file__, rows, res, args.json)


if __name__ == "__main__":
    main()

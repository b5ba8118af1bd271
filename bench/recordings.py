"""Benchmarks of real recordings: the RTKLIB drive (549 s, 100 Hz) through the CLI, each
command timed in a fresh process.

    python bench/recordings.py [--data ../shared/data/rtklib-drive/drive_0708] [--json out.json]

import (CSV + tags + .pos -> contract log with the alignment), diagnose (track level: the
drive simulated from RTK, the library search, bootstrap, report folder), windows (10/30/60 s
every 5 s: 260 free-inertial runs).
"""
import argparse
import os
import platform
import tempfile
from pathlib import Path

from publish import publish, timed_cli as timed

ROOT = Path(__file__).resolve().parent.parent


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "rtklib-drive"
                                              / "drive_0708"))
    parser.add_argument("--json", help="write the numbers here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        log = os.path.join(tmp, "drive.mcap")
        out = {"import_s": timed(["import", "rtklib", args.data, "-o", log]),
               "diagnose_s": timed(["diagnose", log, "-o", os.path.join(tmp, "d")]),
               "windows_s": timed(["windows", log, "-o", os.path.join(tmp, "w")])}
    out.update(machine=f"{os.cpu_count()} cores, {platform.machine()}, Python "
                       f"{platform.python_version()}")
    publish(__file__, [(f"RTKLIB car drive ({Path(args.data).name}): import, diagnose, windows",
                        f"{out['import_s']:.1f} s, {out['diagnose_s']:.1f} s, "
                        f"{out['windows_s']:.1f} s")], out, args.json)


if __name__ == "__main__":
    main()

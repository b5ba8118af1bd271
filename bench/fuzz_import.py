"""The importers' fuzz run: damaged copies of foreign recordings through `mimunav import`.

    python bench/fuzz_import.py [--per-source 40] [--seed 1]

Sources (each small, none written by this project's log writer except the ROS 2 bag, which
the mcap package reads): the RTKLIB excerpt (tests/data/rtklib-drive: CSV, time tags, .pos
- one file damaged at a time), a ROS 2 bag (Imu + NavSatFix), PX4's pyulog sample
(shared/data/px4-ulog), an ArduPilot DataFlash log (tests/dataflash_log.py) and a table
spec with its CSV. Damages as `tests/fuzzing.damages`: truncations, bit flips, 4 KiB
overwrites, empty and foreign files. Outcomes: ok (exit 0: the damage passed as data or
missed what is read), refused (exit 2, one line), and the failures - traceback, hang (no
answer in HANG_S) and input modified. Prints a markdown table and the first example of
each failure.
"""
import argparse
import collections
import hashlib
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
import fuzzing  # noqa: E402
from publish import publish  # noqa: E402

HANG_S = 120


class Hang(Exception):
    pass


def sources(folder):
    """{name: (kind, source path to pass, [files that may be damaged])}."""
    out = {}
    drive = folder / "rtklib"
    shutil.copytree(ROOT / "tests" / "data" / "rtklib-drive", drive)
    out["rtklib"] = ("rtklib", drive, sorted(p for p in drive.iterdir()
                                             if p.suffix in (".csv", ".tag", ".pos")))
    out["ros2"] = ("ros2", _bag(folder / "bag.mcap"), [folder / "bag.mcap"])
    ulg = ROOT.parent / "shared" / "data" / "px4-ulog" / "pyulog_sample.ulg"
    if ulg.exists():
        shutil.copy(ulg, folder / "sample.ulg")
        out["ulog"] = ("ulog", folder / "sample.ulg", [folder / "sample.ulg"])
    import dataflash_log
    (folder / "flight.bin").write_bytes(dataflash_log.flight()[0])
    out["dataflash"] = ("dataflash", folder / "flight.bin", [folder / "flight.bin"])
    spec = _table(folder / "table")
    out["table"] = ("table", spec, [spec, spec.parent / "imu.csv", spec.parent / "ref.csv"])
    return out


def _bag(path):
    from mimunav.flightlog import LogWriter
    from mimunav.flightlog import schemas as S
    n = 3000
    stamps = 1_700_000_000_000_000_000 + np.arange(n) * 10_000_000
    rng = np.random.default_rng(1)
    w = rng.normal(0, 0.01, (n, 3))
    f = np.tile([0.0, 0.0, 9.8], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    fix = stamps[::25]
    with LogWriter(path) as log:
        log.write("/imu/data", S.IMU, "imu_link", stamps, **S.imu_fields(w, f))
        log.write("/fix", S.NAV_SAT_FIX, "gps", fix, status=np.full(len(fix), 2, np.int8),
                  service=np.ones(len(fix), np.uint16), latitude=np.full(len(fix), 40.1),
                  longitude=np.full(len(fix), -105.1), altitude=np.full(len(fix), 1600.0),
                  position_covariance=np.tile((np.eye(3) * 1e-4).ravel(), (len(fix), 1)),
                  position_covariance_type=np.full(len(fix), 2, np.uint8))
    return path


def _table(folder):
    folder.mkdir()
    n = 3000
    t = np.arange(n) * 0.01
    rng = np.random.default_rng(2)
    imu = np.column_stack([t, rng.normal(0, 0.01, (n, 3)),
                           np.tile([0.0, 0.0, -9.8], (n, 1)) + rng.normal(0, 0.02, (n, 3))])
    np.savetxt(folder / "imu.csv", imu, delimiter=",")             # no header: by index
    ref = np.column_stack([t[::25], np.full(n // 25, 40.1), np.full(n // 25, -105.1),
                           np.full(n // 25, 1600.0)])
    np.savetxt(folder / "ref.csv", ref, delimiter=",")
    spec = folder / "spec.toml"
    imu_cols = {"time": [0], "angular_rate": [1, 2, 3], "specific_force": [4, 5, 6]}
    ref_cols = {"time": [0], "latitude": [1], "longitude": [2], "height": [3]}
    text = ["[imu]"] + [f'{k} = {{file = "imu.csv", columns = {v}}}' for k, v in imu_cols.items()]
    text += ['axes = "FRD"', "[time]", "unix_offset_s = 1700000000.0", "[reference]"]
    text += [f'{k} = {{file = "ref.csv", columns = {v}' + (', unit = "deg"}' if k in
                                                           ("latitude", "longitude") else "}")
             for k, v in ref_cols.items()]
    spec.write_text("\n".join(text) + "\n")
    return spec


def _digest(paths):
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in paths if p.exists()}


def _alarm(signum, frame):
    raise Hang()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-source", type=int, default=40, help="damaged files per source")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    from tqdm import tqdm
    started = time.time()
    rng = np.random.default_rng(args.seed)
    counts, examples = collections.Counter(), {}
    signal.signal(signal.SIGALRM, _alarm)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        todo = []
        for name, (kind, src, files) in sources(folder).items():
            cases = [(victim, label, damaged) for victim in files
                     for label, damaged in fuzzing.damages(victim.read_bytes(), rng, n_random=5)]
            picks = rng.choice(len(cases), min(args.per_source, len(cases)), replace=False)
            todo += [(name, kind, src, files, *cases[k]) for k in picks]
        out = folder / "out.mcap"
        for name, kind, src, files, victim, label, damaged in tqdm(todo, desc="fuzz",
                                                                   unit="case"):
            original = victim.read_bytes()
            victim.write_bytes(damaged)
            before = _digest(files)
            out.unlink(missing_ok=True)
            signal.alarm(HANG_S)
            try:
                outcome, err, _ = fuzzing.run(["import", kind, str(src), "-o", str(out)])
            except Hang:
                outcome, err = "hang", f"no answer in {HANG_S} s"
            finally:
                signal.alarm(0)
            after = _digest(files)
            if after != before:
                outcome = "input modified"
            counts[name, outcome] += 1
            if outcome not in ("ok", "refused"):
                examples.setdefault((name, outcome), (f"{victim.name}: {label}", err[-600:]))
            victim.write_bytes(original)
    elapsed = time.time() - started
    outcomes = ["ok", "refused", "traceback", "hang", "input modified"]
    print(f"`python bench/fuzz_import.py --per-source {args.per_source} --seed {args.seed}`: "
          f"{len(todo)} damaged recordings in {elapsed / 60:.1f} min\n")
    print("| importer | " + " | ".join(outcomes) + " |")
    print("|---|" + "---|" * len(outcomes))
    for name in sorted({n for n, _ in counts}):
        print(f"| {name} | " + " | ".join(str(counts[name, o]) for o in outcomes) + " |")
    for (name, outcome), (case, err) in examples.items():
        print(f"\n{name} {outcome} ({case}):\n{err}")
    fail = sum(v for (_, o), v in counts.items() if o not in ("ok", "refused"))
    total = sum(counts.values())
    publish(__file__, [("importer fuzz: damaged foreign recordings (rtklib, ros2, ulog, "
                        "dataflash, table) through `mimunav import`",
                        f"{len(todo)} recordings, {total} runs in {elapsed / 60:.1f} min: "
                        f"{sum(v for (_, o), v in counts.items() if o == 'ok')} ok, "
                        f"{sum(v for (_, o), v in counts.items() if o == 'refused')} refused, "
                        f"{fail} traceback/hang/input modified")],
            {"counts": {f"{n}:{o}": v for (n, o), v in counts.items()}}, None)


if __name__ == "__main__":
    main()

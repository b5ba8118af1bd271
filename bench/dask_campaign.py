"""A campaign on a real Dask cluster against the same campaign on local processes.

    python bench/dask_campaign.py [--units 4] [--seed 1] [--json out.json]

Starts a `dask.distributed.LocalCluster` of 2 worker processes (1 thread each, so two
interpreters apart from this one and from each other), runs the command a user runs,
`python -m mimunav campaign PROFILE --scheduler ADDRESS`, in a fresh process against it,
then the same campaign on local processes (`--workers 2`), and compares the two results
files line by line (by unit index; JSON lines are written in finishing order). Prints the
process ids of the workers that ran units, both wall times and whether the records are
identical. Needs the `[dask]` extra (`pip install -e '.[dask]'`). Not a CI test: a
cluster of processes is slow to start and the in-process cluster of
tests/evaluation/test_campaign.py covers the code path.
"""
import argparse
from collections import Counter
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from publish import publish  # noqa: E402


def campaign(profile, output, units, seed, extra):
    """Wall time (s) of `python -m mimunav campaign` in a fresh process; its output file."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mimunav", "campaign", str(profile), "-o", str(output),
                    "--units", str(units), "--seed", str(seed), *extra],
                   check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def records(path):
    """The JSON-lines records of a results file, by unit index."""
    with open(path) as fh:
        return {rec["index"]: rec for rec in map(json.loads, fh)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("profile", nargs="?", default=str(ROOT / "flights" / "high-dynamic.toml"),
                    help="flight profile TOML (default: the shipped high-dynamic flight)")
    ap.add_argument("--units", type=int, default=4)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", help="write the results to this JSON file")
    args = ap.parse_args()
    from dask.distributed import Client, LocalCluster, get_task_stream

    with tempfile.TemporaryDirectory() as tmp, \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                         dashboard_address=None) as cluster, Client(cluster) as client:
        workers = client.run(os.getpid)                 # {worker address: its process id}
        remote_file, local_file = Path(tmp) / "dask.jsonl", Path(tmp) / "local.jsonl"
        with get_task_stream(client) as stream:         # every task the scheduler ran
            t_remote = campaign(args.profile, remote_file, args.units, args.seed,
                                ["--scheduler", cluster.scheduler_address])
        ran = Counter(task["worker"] for task in stream.data
                      if task["key"].startswith("run_unit"))
        t_local = campaign(args.profile, local_file, args.units, args.seed, ["--workers", "2"])
        remote, local = records(remote_file), records(local_file)
    same = remote == local
    res = {"units": args.units, "seed": args.seed, "profile": Path(args.profile).name,
           "worker_pids": sorted(workers.values()), "units_per_worker": sorted(ran.values()),
           "dask_s": t_remote, "local_s": t_local, "identical_records": same,
           "records": len(remote)}
    publish(__file__, [
        (f"campaign of {args.units} units on a Dask LocalCluster of 2 worker processes",
         f"{t_remote:.1f} s through `--scheduler`, {t_local:.1f} s on 2 local processes; "
         f"units per worker process {res['units_per_worker']} (pids "
         f"{', '.join(map(str, res['worker_pids']))}); records identical to the local run: "
         f"{'yes' if same else 'NO'} ({len(remote)} of {args.units})")], res, args.json)
    if not same:
        sys.exit(1)


if __name__ == "__main__":
    main()

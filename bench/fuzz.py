"""The fuzz run: many damaged copies of a simulated log through every command.

    python bench/fuzz.py [--cases 2000] [--seed 1]

A case is one command on one damaged file (`tests/fuzzing.py`: a flipped byte in a record
of every opcode, truncations, bit flips and 4 KiB overwrites at random places, empty and
foreign files). Counts per command and outcome: ok (exactly the undamaged log's result;
for --recover: only the original's messages, byte for byte), refused (one-line error, exit
2), and the failures - traceback, laundered (exit 0 with another result), altered (recover
changed a message). Prints a markdown table and the first example of each failure.
"""
import argparse
import collections
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import fuzzing  # noqa: E402
from publish import publish  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=2000, help="command runs (about 6 per file)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    from tqdm import tqdm
    started = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        log, cal = fuzzing.corpus_log(folder)
        reference = fuzzing.references(log, cal, folder / "base")
        rng = np.random.default_rng(args.seed)
        data = log.read_bytes()
        per_file = len(fuzzing.commands(log, cal, folder))
        files = []
        while len(files) * per_file < args.cases:
            files += fuzzing.damages(data, rng, n_random=10)
        files = files[:-(-args.cases // per_file)]
        counts, examples = collections.Counter(), {}
        for name, damaged in tqdm(files, desc="fuzz", unit="file"):
            case, path = fuzzing.case_file(folder, damaged)
            for argv in fuzzing.commands(path, cal, case):
                outcome, err = fuzzing.judge(argv, log, case, reference, damaged)
                counts[fuzzing.key(argv), outcome] += 1
                if outcome not in ("ok", "refused"):
                    examples.setdefault((fuzzing.key(argv), outcome), (name, err[-600:]))
    elapsed = time.time() - started
    outcomes = ["ok", "refused", "traceback", "laundered", "altered", "input modified"]
    keys = sorted({k for k, _ in counts})
    print(f"`python bench/fuzz.py --cases {args.cases} --seed {args.seed}`: {len(files)} damaged "
          f"files, {sum(counts.values())} command runs in {elapsed / 60:.1f} min (2 cores)\n")
    print("| command | " + " | ".join(outcomes) + " |")
    print("|---|" + "---|" * len(outcomes))
    for k in keys:
        print(f"| {k} | " + " | ".join(str(counts[k, o]) for o in outcomes) + " |")
    print("| **all** | " + " | ".join(str(sum(counts[k, o] for k in keys)) for o in outcomes)
          + " |")
    for (k, outcome), (name, err) in examples.items():
        print(f"\n{k} {outcome} on '{name}':\n{err}")
    total = {o: sum(counts[k, o] for k in keys) for o in outcomes}
    publish(__file__, [(f"fuzz: {len(files)} damaged logs through {', '.join(keys)}",
                        f"{sum(counts.values())} runs in {elapsed / 60:.1f} min: "
                        + ", ".join(f"{total[o]} {o}" for o in outcomes))])


if __name__ == "__main__":
    main()

"""Mutation score of the physics core: would a plausible bug turn a test red?

    python bench/mutation.py [--per-module 40] [--seed 1] [--modules frames/earth frames/attitude ...]
                             [-o reports/mutation.md]

Mutants are cosmic-ray's (`cosmic-ray init` enumerates every mutation of a module); only the
operators that make a plausible slip are kept - + and -, * and /, ** and *, a comparison
turned, a sign dropped, a number changed, True and False, and/or - and a seeded random sample
of --per-module of them per module is run (a full run is 10^4 mutants at ~12 s each). Each
mutant runs its module's tests in a clone of HEAD (PYTHONPATH points at the clone; checked
before the run) with a fresh numba cache: the on-disk cache does not notice edits of
`inline="always"` callees in other modules, so a shared cache would let mutants survive on
stale kernels. The score is killed / (killed + survived) with a Wilson 95 % interval; every
survivor is listed with its diff, to be killed by a test or explained as equivalent.
"""
import argparse
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from publish import publish

ROOT = Path(__file__).resolve().parent.parent
# module (its path under mimunav/) -> the tests that judge its mutants
TESTS = {
    "frames/earth": ["tests/frames/test_earth.py", "tests/motion/test_truth.py",
                     "tests/navigation/test_strapdown.py"],
    "frames/attitude": ["tests/frames/test_attitude.py", "tests/motion/test_truth.py",
                        "tests/navigation/test_strapdown.py"],
    "navigation/strapdown": ["tests/navigation/test_strapdown.py"],
    "motion/truth": ["tests/motion/test_truth.py", "tests/navigation/test_strapdown.py"],
    "compensation/model": ["tests/compensation/test_compensation.py"],
    "compensation/wild_values": ["tests/compensation/test_compensation.py"],
    "motion/trajectory": ["tests/motion/test_trajectory.py", "tests/evaluation/test_evaluation.py",
                          "tests/navigation/test_strapdown.py"],
}
PLAUSIBLE = ("ReplaceBinaryOperator_Add_Sub", "ReplaceBinaryOperator_Sub_Add",
             "ReplaceBinaryOperator_Mul_Div", "ReplaceBinaryOperator_Div_Mul",
             "ReplaceBinaryOperator_Pow_Mul", "ReplaceComparisonOperator", "ReplaceUnaryOperator",
             "NumberReplacer", "ReplaceTrueWithFalse", "ReplaceFalseWithTrue",
             "ReplaceAndWithOr", "ReplaceOrWithAnd")
TIMEOUT_S = 300.0


def wilson(k, n, z=1.96):
    """Wilson score interval of a proportion k / n."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (centre - half, centre + half)


def plausible(item):
    name = item.mutations[0].operator_name.split("/", 1)[1]
    return any(name.startswith(p) for p in PLAUSIBLE)


def test_command(clone, tests):
    """A shell command: the module's tests with a fresh numba cache, the clone first on the
    path."""
    body = (f"export NUMBA_CACHE_DIR=$(mktemp -d) PYTHONPATH={clone}; "
            f"python -m pytest -x -q -p no:cacheprovider {' '.join(tests)} >/dev/null 2>&1; "
            "rc=$?; rm -rf $NUMBA_CACHE_DIR; exit $rc")
    return f"bash -c '{body}'"


def sample(clone, module, per_module, seed):
    """The sampled work items of one module (cosmic-ray session enumerated in the clone),
    drawn by a generator seeded from (seed, module): a module's sample does not depend on
    which other modules are run."""
    from cosmic_ray.work_db import WorkDB, use_db
    config = clone / f"cr-{module.replace('/', '-')}.toml"
    config.write_text(f'[cosmic-ray]\nmodule-path = "mimunav/{module}.py"\ntimeout = {TIMEOUT_S}\n'
                      f'excluded-modules = []\ntest-command = "true"\n'
                      '[cosmic-ray.distributor]\nname = "local"\n')
    session = clone / f"cr-{module.replace('/', '-')}.sqlite"
    subprocess.run(["cosmic-ray", "init", str(config), str(session)], cwd=clone, check=True,
                   capture_output=True)
    with use_db(str(session), WorkDB.Mode.open) as db:
        items = [i for i in db.work_items if plausible(i)]
    rng = random.Random(f"{seed}:{module}")
    chosen = rng.sample(items, min(per_module, len(items)))
    return chosen, len(items)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-module", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--modules", nargs="+", default=list(TESTS), choices=list(TESTS))
    ap.add_argument("-o", "--output", default=str(ROOT / "reports" / "mutation.md"))
    args = ap.parse_args()
    from cosmic_ray.mutating import mutate_and_test
    from tqdm import tqdm
    started = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        clone = Path(tmp) / "main"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=clone,
                              capture_output=True, text=True, check=True).stdout.strip()
        where = subprocess.run([sys.executable, "-c", "import mimunav; print(mimunav.__file__)"],
                               cwd=tmp, env={**os.environ, "PYTHONPATH": str(clone)},
                               capture_output=True, text=True, check=True).stdout.strip()
        if not where.startswith(str(clone)):
            sys.exit(f"the clone's package is not the one imported ({where}); mutants would "
                     "not be seen")
        os.chdir(clone)
        results = {}
        for module in args.modules:
            chosen, total = sample(clone, module, args.per_module, args.seed)
            cmd = test_command(clone, TESTS[module])
            baseline = subprocess.run(cmd, shell=True)
            if baseline.returncode != 0:
                sys.exit(f"{module}: the tests fail without a mutant")
            rows = []
            for item in tqdm(chosen, desc=module, unit="mutant"):
                res = mutate_and_test(item.mutations, cmd, TIMEOUT_S)
                m = item.mutations[0]
                rows.append({"operator": m.operator_name.split("/", 1)[1],
                             "line": m.start_pos[0], "function": m.definition_name,
                             "outcome": (res.test_outcome.value if res.test_outcome else
                                         res.worker_outcome.value),
                             "diff": res.diff or ""})
            results[module] = {"plausible_mutants": total, "rows": rows}
    doc = summarise(results, head, args, time.time() - started)
    Path(args.output).write_text(markdown(doc))
    Path(args.output).with_suffix(".json").write_text(json.dumps(doc, indent=1) + "\n")
    print(markdown(doc).split("## Survivors")[0])
    publish(__file__, [("mutation score of the physics core (reports/mutation.md)",
                        f"{doc['killed']}/{doc['run']} killed, {100 * doc['score']:.0f} % "
                        f"[{100 * doc['ci95'][0]:.0f}, {100 * doc['ci95'][1]:.0f}]")])


def summarise(results, head, args, elapsed):
    modules = {}
    all_k = all_n = 0
    for module, r in results.items():
        k = sum(row["outcome"] in ("killed", "incompetent") for row in r["rows"])
        n = sum(row["outcome"] in ("killed", "incompetent", "survived") for row in r["rows"])
        all_k, all_n = all_k + k, all_n + n
        modules[module] = {"plausible_mutants": r["plausible_mutants"], "run": n, "killed": k,
                           "score": k / n if n else None, "ci95": wilson(k, n),
                           "tests": TESTS[module],
                           "survivors": [row for row in r["rows"] if row["outcome"] == "survived"]}
    return {"head": head, "seed": args.seed, "per_module": args.per_module,
            "elapsed_s": elapsed, "modules": modules, "killed": all_k, "run": all_n,
            "score": all_k / all_n if all_n else None, "ci95": wilson(all_k, all_n)}


def markdown(doc):
    lines = ["# Mutation score of the physics core", "",
             f"`python bench/mutation.py --per-module {doc['per_module']} --seed {doc['seed']}` "
             f"at {doc['head']}, {doc['elapsed_s'] / 60:.0f} min on 2 cores. Killed = a test "
             "failed (or the mutant broke the import: incompetent); score with a Wilson 95 % "
             "interval over the random sample.", "",
             "| module | plausible mutants | sampled | killed | score | 95 % interval | tests |",
             "|---|---|---|---|---|---|---|"]
    for name, m in doc["modules"].items():
        lines.append(f"| {name} | {m['plausible_mutants']} | {m['run']} | {m['killed']} | "
                     f"{100 * (m['score'] or 0):.0f} % | {100 * m['ci95'][0]:.0f}-"
                     f"{100 * m['ci95'][1]:.0f} % | {', '.join(m['tests'])} |")
    lines += [f"| **all** | | {doc['run']} | {doc['killed']} | {100 * (doc['score'] or 0):.0f} % "
              f"| {100 * doc['ci95'][0]:.0f}-{100 * doc['ci95'][1]:.0f} % | |", "",
              "## Survivors", ""]
    for name, m in doc["modules"].items():
        for s in m["survivors"]:
            lines += [f"### {name}.{s['function']} line {s['line']} ({s['operator']})", "",
                      "```diff", s["diff"].strip(), "```", ""]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()

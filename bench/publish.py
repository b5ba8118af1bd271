"""Where the bench scripts put their numbers, so that no figure in the README is typed in.

Each script ends with `publish(__file__, rows, res, args.json)`: it prints the rows, writes
`res` to --json if given, and records each row in bench/results/SCRIPT.json with the command
line, date, load average and machine of its run (a row replaces the earlier one of the same
label); then the README's numbers table (between its `bench:start` / `bench:end` markers)
is generated anew from every results file:

    python bench/publish.py          # regenerate the README table from bench/results/
"""
import json
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
README = ROOT / "README.md"
START, END = "<!-- bench:start -->", "<!-- bench:end -->"
ORDER = ("strapdown", "sensors", "flightlog", "memory", "lab", "evaluation", "diagnosis",
         "transplant", "recordings", "track_drive", "fuzz", "fuzz_import", "mutation")


def timed_cli(args, env=None):
    """Wall time (s) of `python -m mimunav ARGS` in a fresh process from the repository root
    (output discarded; `env`: the process's environment, default this one's)."""
    import subprocess
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mimunav", *args], check=True,
                   cwd=Path(__file__).resolve().parent.parent, env=env,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def machine():
    """The machine of a run, with its processor's model: rows measured on different
    processors (this workplace's machines differ from session to session) are told apart."""
    cpu = ""
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next((line.split(":", 1)[1].strip() for line in fh
                        if line.startswith("model name")), "")
    except OSError:
        pass
    return (f"{platform.machine()} {os.cpu_count()} cores{f' ({cpu})' if cpu else ''}, "
            f"Python {platform.python_version()}")


def write_report(folder, stem, markdown, command, wall_s, cases):
    """REPORT/STEM.md (`markdown`) and REPORT/STEM.json ({"meta", "cases"}), each replaced
    atomically; meta holds the command, the machine and the wall time (s)."""
    from mimunav.files import write_atomic
    meta = {"command": command, "machine": machine(), "wall_s": wall_s}
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / f"{stem}.md", markdown(cases, meta), force=True)
    write_atomic(out / f"{stem}.json", json.dumps({"meta": meta, "cases": cases}, indent=1,
                                                  default=float) + "\n", force=True)


def publish(script, rows, res=None, json_path=None):
    """Print rows [(what, measured)], write res to json_path, record them in bench/results
    and regenerate the README table."""
    for what, measured in rows:
        print(f"{what}: {measured}")
    if json_path:
        Path(json_path).write_text(json.dumps(res, indent=2, default=float))
    name = Path(script).stem
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"{name}.json"
    run = {"command": "python " + " ".join([f"bench/{name}.py", *sys.argv[1:]]),
           "date": time.strftime("%Y-%m-%d"), "load": round(os.getloadavg()[0], 1),
           "machine": machine()}
    kept = json.loads(path.read_text())["rows"] if path.exists() else []
    new = {what: dict(run, what=what, measured=measured) for what, measured in rows}
    merged = [new.pop(r["what"], r) for r in kept] + list(new.values())   # a row per label
    tmp = RESULTS / f".{name}.json.tmp"
    tmp.write_text(json.dumps({"script": f"bench/{name}.py", "rows": merged}, indent=1) + "\n")
    os.replace(tmp, path)
    render()


def table():
    """The README table (markdown) from bench/results/*.json."""
    docs = {p.stem: json.loads(p.read_text()) for p in RESULTS.glob("*.json")}
    machines = sorted({r["machine"] for d in docs.values() for r in d["rows"]})
    lines = ["| what | measured | command, date, load (1 min)"
             + (", machine" if len(machines) > 1 else "") + " |", "|---|---|---|"]
    for name in sorted(docs, key=lambda n: (ORDER.index(n) if n in ORDER else len(ORDER), n)):
        for row in docs[name]["rows"]:
            which = f", {machines.index(row['machine']) + 1}" if len(machines) > 1 else ""
            lines.append(f"| {row['what']} | {row['measured']} | `{row['command']}`, "
                         f"{row['date']}, load {row['load']}{which} |")
    if len(machines) == 1:
        head = f"Machine: {machines[0]}."
    else:
        head = "Machines (the last column's number; a row without the processor's model was " \
               "measured before it was recorded): " + \
               "; ".join(f"{k + 1}: {m}" for k, m in enumerate(machines)) + "."
    return "\n".join([head, ""] + lines) + "\n"


def render():
    text = README.read_text()
    if START not in text or END not in text:
        raise SystemExit(f"{README} lacks the {START} / {END} markers")
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    new = f"{head}{START}\n{table()}{END}{tail}"
    tmp = README.with_suffix(".md.tmp")
    tmp.write_text(new)
    os.replace(tmp, README)


if __name__ == "__main__":
    render()

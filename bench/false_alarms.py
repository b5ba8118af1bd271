"""The diagnosis's false-alarm rate, measured on effect-free logs of varied kinds: the share of
logs on which `diagnose` answers anything but "no-missing-physics" (a finding, an unexplained
residual, an inconclusive answer), with its 95 % Clopper-Pearson interval.

    python bench/false_alarms.py [--transplants 36] [--simulated 12] [--seed 1] [--workers 2]
                                 [--level sensor|navigation] [--without-attitude]

Two sources, so that the nulls are not only the project's own:
  transplants  the independent simulator's logs (shared/data/foreign-flights, their hidden
               effect taken out; foreign-flights-2's three effect-free logs as they are),
               each varied by `diagnosis.transplant.null_variant`: the MIMU's bias wandering
               in its class as a Gauss-Markov process (correlation time 30-600 s) or a
               random walk, the reference IMU's scale and axis errors drawn at the accuracy
               the diagnosis assumes, and - each with probability 1/3 - airframe vibration,
               both IMUs at half rate, the MIMU mounted in another orientation. Carriers:
               90-600 s, MIMU at 200-1000 Hz (FOG at half rate on foreign-flights-2), cold
               soaks and ramps (foreign2-02), a long low-dynamic transport flight
               (foreign2-04), 25 g and 330 deg/s (foreign2-06).
  simulated    this project's simulator (`diagnosis.concealed.recording` with nothing
               hidden): a unit drawn per seed, calibrated in the simulated lab (its
               calibration's own errors), flown on the proof, high-dynamic, repeated-blocks
               (450 s) and gentle (840 s, low dynamics) profiles.
At the navigation level (`--level navigation`) the same logs are diagnosed against their
truth trajectory alone (the reference IMU is not used); `--without-attitude` takes the
truth's attitude away (a GNSS-only reference: the terms' inputs are then the MIMU's outputs).
Writes REPORT/false-alarms.md and .json (false-alarms-seedN for another seed: a held-out
draw of the same kinds); a row in bench/results/false_alarms.json.
"""
import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from publish import publish, write_report                                  # noqa: E402
from mimunav.evaluation.proportions import proportion                      # noqa: E402

SHARED = ROOT.parent / "shared" / "data"
CARRIERS = [SHARED / "foreign-flights" / f"foreign-0{n}" for n in range(1, 7)] + \
    [SHARED / "foreign-flights-2" / f"foreign2-0{n}" for n in (2, 4, 6)]
PROFILES = ["diagnosis-proof.toml", "high-dynamic.toml", "repeated-blocks.toml", "gentle.toml"]


def run(job):
    """One null: (source, what it is, seed, level, without attitude) -> its case record."""
    kind, what, seed, level, blind = job
    from mimunav.diagnosis import concealed, navigation, sensor, transplant
    t0 = time.perf_counter()
    if kind == "transplant":
        flight, cal, drawn = transplant.null_variant(what, seed)
        name = drawn.pop("carrier")
    else:
        flight, _, _, cal = concealed.recording(str(ROOT / "flights" / what), None, seed)
        name, drawn = what, {"seed": seed}
    if level == "navigation":
        diag = navigation.diagnose(flight, cal, reference=without_attitude(flight.truth)
                                   if blind else None)
    else:
        diag = sensor.diagnose(flight, cal)
    verdict = sensor.verdict(diag)
    return {"source": kind, "log": Path(name).name, "drawn": drawn, "verdict": verdict,
            "level": level + (" (reference without attitude)" if blind else ""),
            "findings": [f["label"] for f in diag.findings],
            "unexplained": len(diag.unexplained),
            "inconclusive": list(getattr(diag, "inconclusive", []) or []),
            "alarm": verdict != "no-missing-physics" or bool(diag.findings),
            "seconds": time.perf_counter() - t0}


def without_attitude(trajectory):
    """The trajectory with its attitude unknown (NaN quaternions), as a GNSS fix has it."""
    import numpy as np
    from mimunav.frames import attitude
    blind = trajectory[np.arange(len(trajectory))]
    blind.q_nb = attitude.from_wxyz(np.full((len(blind), 4), np.nan))
    return blind


def interval(k, n):
    """Clopper-Pearson 95 % interval of k alarms in n logs."""
    lo, hi = proportion([True] * k + [False] * (n - k))["ci95"]
    return lo, hi


def markdown(cases, meta):
    level = cases[0].get("level", "sensor") if cases else "sensor"
    lines = [f"# False alarms of the {level}-level diagnosis on effect-free logs", "",
             f"`{meta['command']}` on {meta['machine']}, {meta['wall_s']:.0f} s.", ""]
    for source in ("transplant", "simulated", "all"):
        part = [c for c in cases if source in ("all", c["source"])]
        k = sum(c["alarm"] for c in part)
        lo, hi = interval(k, len(part))
        lines.append(f"- {source}: {k} of {len(part)} logs answered with an alarm "
                     f"({k / max(len(part), 1):.1%}, 95 % interval {lo:.1%}-{hi:.1%})")
    lines += ["", "| source | log | drawn | verdict | findings | inconclusive |",
              "|---|---|---|---|---|---|"]
    for c in cases:
        drawn = ", ".join(f"{k}={v}" for k, v in c["drawn"].items() if k != "reference_error")
        lines.append(f"| {c['source']} | {c['log']} | {drawn} | {c['verdict']} | "
                     f"{', '.join(c['findings']) or '-'} | {'; '.join(c['inconclusive']) or '-'} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--transplants", type=int, default=36, help="varied foreign nulls")
    ap.add_argument("--simulated", type=int, default=12, help="project-simulator nulls")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--report", default=str(ROOT / "reports"))
    ap.add_argument("--json")
    ap.add_argument("--level", choices=("sensor", "navigation"), default="sensor",
                    help="the diagnosis level: sensor (against the reference IMU) or "
                    "navigation (against the truth trajectory alone)")
    ap.add_argument("--without-attitude", action="store_true",
                    help="navigation level: the truth trajectory without its attitude")
    args = ap.parse_args()
    if args.without_attitude and args.level != "navigation":
        ap.error("--without-attitude needs --level navigation")
    how = (args.level, args.without_attitude)
    jobs = [("transplant", str(CARRIERS[k % len(CARRIERS)]), args.seed * 1000 + k, *how)
            for k in range(args.transplants)]
    jobs += [("simulated", PROFILES[k % len(PROFILES)], args.seed * 1000 + k, *how)
             for k in range(args.simulated)]
    from tqdm import tqdm
    t0 = time.perf_counter()
    from mimunav.evaluation.campaign import one_blas_thread
    # one BLAS thread per worker: two workers each spinning OpenBLAS's own threads on 2 cores
    # ran at a load of 4 and half speed (this bench, 2026-11-29)
    with ProcessPoolExecutor(args.workers, initializer=one_blas_thread) as pool:
        cases = list(tqdm(pool.map(run, jobs), total=len(jobs), desc="nulls"))
    wall = time.perf_counter() - t0
    options = ("" if args.level == "sensor" else " --level navigation") + \
        (" --without-attitude" if args.without_attitude else "")
    report = "false-alarms" + options.replace(" --level ", "-").replace(" --", "-") + \
        ("" if args.seed == 1 else f"-seed{args.seed}")
    write_report(args.report, report, markdown,
                 f"python bench/false_alarms.py --transplants {args.transplants} "
                 f"--simulated {args.simulated} --seed {args.seed}{options}", wall, cases)
    k = sum(c["alarm"] for c in cases)
    lo, hi = interval(k, len(cases))
    publish(__file__, [(
        f"false alarms{options.replace(' --level', ',').replace(' --', ', ')}: {len(cases)} "
        f"effect-free logs ({args.transplants} varied foreign, "
        f"{args.simulated} simulated{'' if args.seed == 1 else f', seed {args.seed}'}; "
        f"reports/{report}.md)",
        f"{k} answered with an alarm: {k / len(cases):.1%} [95 %: {lo:.1%}, {hi:.1%}]; "
        f"{wall:.0f} s")], {"cases": cases}, args.json)


if __name__ == "__main__":
    main()

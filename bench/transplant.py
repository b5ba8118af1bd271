"""The diagnosis on every effect class over flights it did not write: the foreign development
flights with their own hidden effect taken out and another put in
(`mimunav.diagnosis.transplant`), plus null carriers with and without airframe vibration.

    python bench/transplant.py [--per-class 6] [--seed 1] [--report reports]

Each case draws a carrier (one of the six foreign logs), an axis, a sign and a magnitude in
the class's range below; writes REPORT/diagnosis-transplant.md and .json. A case is named
when a finding has the hidden effect, sensor and axis; covered when the truth lies in its
95 % interval (every component of a vector); a null is right when the verdict is
no-missing-physics.
"""
import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from publish import publish                                  # noqa: E402
from mimunav.diagnosis import sensor, transplant             # noqa: E402
from mimunav.files import write_atomic                       # noqa: E402

FOREIGN = ROOT.parent / "shared" / "data" / "foreign-flights"
DEG = math.pi / 180
MG = 9.80665e-3
# magnitude ranges (uniform in log between the bounds, random sign where it has one)
RANGES = {
    ("bias_shift", "gyro"): (0.05 * DEG, 0.2 * DEG), ("bias_shift", "accel"): (3 * MG, 10 * MG),
    ("quantization", "gyro"): (0.005, 0.02), ("quantization", "accel"): (0.05, 0.2),
    ("bias_instability", "gyro"): (200 * DEG / 3600, 500 * DEG / 3600),
    ("bias_instability", "accel"): (5 * MG, 20 * MG),
    ("vibration_rectification", "accel"): (2e-4, 1e-3),
    ("vibration_rectification", "gyro"): (5e-6, 2e-5),
    ("scale_asymmetry", "gyro"): (3e-4, 1e-3), ("scale_asymmetry", "accel"): (3e-4, 1e-3),
    ("saturation", "gyro"): (0.6, 0.85), ("saturation", "accel"): (0.6, 0.85),   # of the peak
    ("lever_arm", "imu"): (0.05, 0.2),
}
CLASSES = ("bias_shift", "quantization", "bias_instability", "vibration_rectification",
           "scale_asymmetry", "saturation", "lever_arm", "null", "null+vibration")


def draw(effect, rng, base):
    """A transplant spec of `effect` on carrier `base`."""
    if effect == "null":
        return "bias_shift:gyro:x=0"
    if effect == "null+vibration":
        return "vibration_rectification:accel:x=0"
    if effect == "lever_arm":
        v = rng.standard_normal(3)
        v *= math.exp(rng.uniform(*np.log(RANGES[effect, "imu"]))) / np.linalg.norm(v)
        return "lever_arm:imu:all=" + "/".join(f"{x:.4f}" for x in v)
    sensor_ = rng.choice(["accel", "gyro"])
    axis = rng.choice(list("xyz"))
    lo, hi = RANGES[effect, sensor_]
    value = math.exp(rng.uniform(math.log(lo), math.log(hi)))
    if effect == "saturation":                       # a level below the axis's peak input
        _, _, f, w = transplant.carrier(base)
        peak = np.max(np.abs((f if sensor_ == "accel" else w)[:, "xyz".index(axis)]))
        value = rng.uniform(lo, hi) * peak
    elif effect in ("bias_shift", "scale_asymmetry"):
        value *= rng.choice([-1, 1])
    return f"{effect}:{sensor_}:{axis}={value:.6g}"


def run_case(base, spec, effect):
    t0 = time.perf_counter()
    flight, cal, key = transplant.transplant(base, spec)
    diag = sensor.diagnose(flight, cal)
    verdict = sensor.verdict(diag)
    case = {"carrier": Path(base).name, "spec": spec, "class": effect, "verdict": verdict,
            "findings": [f["label"] for f in diag.findings],
            "seconds": time.perf_counter() - t0}
    if effect.startswith("null"):
        case["right"] = verdict == "no-missing-physics"
        return case
    truth = np.atleast_1d(key.get("vector", key.get("coefficient")))
    if effect == "saturation":
        truth = np.abs(truth)
    match = [f for f in diag.findings
             if (f["effect"], f["sensor"], f["axis"]) == (key["effect"], key["sensor"], key["axis"])]
    case["named"] = bool(match)
    if match:
        f = match[0]
        lo, hi = (np.asarray(f["vector_ci95"]).T if "vector_ci95" in f
                  else (np.atleast_1d(f["ci95"][0]), np.atleast_1d(f["ci95"][1])))
        case["estimate"] = f.get("vector", f["coefficient"])
        case["covered"] = bool(np.all((lo <= truth) & (truth <= hi)))
    case["truth"] = truth.tolist()
    case["right"] = case["named"]
    return case


def markdown(cases, meta):
    lines = ["# Diagnosis on transplants: every effect class over foreign flights", "",
             f"Command: `{meta['command']}` ({meta['machine']}, {meta['wall_s']:.0f} s wall).",
             "",
             "Each case is one of the six foreign development flights "
             "(`shared/data/foreign-flights`, an independent simulator's flight, reference IMU, "
             "noise and unit) with its own hidden effect subtracted (its `effect.npz`) and one "
             "effect of another class put in as sensor behaviour "
             "(`mimunav/diagnosis/transplant.py`: clipping, rounding, offsets and Gauss-Markov "
             "wander of the MIMU's own outputs, a lever arm from scipy's RotationSpline through "
             "the log's truth attitudes, an airframe vibration recorded by both IMUs). The "
             "outputs go back to volts through this project's inverse of the calibration - so "
             "this tests the diagnosis' classes, while the foreign logs themselves stay the "
             "independent score.", "",
             "| class | cases | named (right for nulls) | truth in 95 % interval (of named) |",
             "|---|---|---|---|"]
    for effect in CLASSES:
        cs = [c for c in cases if c["class"] == effect]
        if not cs:
            continue
        named = sum(c["right"] for c in cs)
        cov = [c["covered"] for c in cs if "covered" in c]
        lines.append(f"| {effect} | {len(cs)} | {named}/{len(cs)} | "
                     f"{f'{sum(cov)}/{len(cov)}' if cov else '-'} |")
    lines += ["", "| carrier | hidden (spec) | verdict | findings | right | covered |",
              "|---|---|---|---|---|---|"]
    for c in cases:
        lines.append(f"| {c['carrier']} | `{c['spec']}` | {c['verdict']} | "
                     f"{', '.join(c['findings']) or '-'} | {'yes' if c['right'] else 'no'} | "
                     f"{c.get('covered', '-')} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--per-class", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--report", default=str(ROOT / "reports"))
    ap.add_argument("--json")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    bases = [str(p)[:-len(".key.json")] for p in sorted(FOREIGN.glob("foreign-*.key.json"))]
    from tqdm import tqdm
    t0 = time.perf_counter()
    jobs = [(bases[int(rng.integers(len(bases)))], effect)
            for effect in CLASSES for _ in range(args.per_class)]
    cases = []
    for base, effect in tqdm(jobs, desc="transplants"):
        cases.append(run_case(base, draw(effect, rng, base), effect))
    wall = time.perf_counter() - t0
    meta = {"command": f"python bench/transplant.py --per-class {args.per_class} "
                       f"--seed {args.seed}",
            "machine": f"{platform.machine()} {os.cpu_count()} cores, "
                       f"{platform.python_version()}", "wall_s": wall}
    out = Path(args.report)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "diagnosis-transplant.md", markdown(cases, meta), force=True)
    write_atomic(out / "diagnosis-transplant.json",
                 json.dumps({"meta": meta, "cases": cases}, indent=1, default=float) + "\n",
                 force=True)
    effects = [c for c in cases if not c["class"].startswith("null")]
    nulls = [c for c in cases if c["class"].startswith("null")]
    cov = [c["covered"] for c in effects if "covered" in c]
    publish(__file__, [(
        f"transplants: {len(effects)} effects of {len(CLASSES) - 2} classes and {len(nulls)} "
        "nulls on the foreign flights (reports/diagnosis-transplant.md)",
        f"named {sum(c['right'] for c in effects)}/{len(effects)}, truth in interval "
        f"{sum(cov)}/{len(cov)}, nulls quiet {sum(c['right'] for c in nulls)}/{len(nulls)}; "
        f"{wall:.0f} s")], {"cases": cases}, args.json)


if __name__ == "__main__":
    main()

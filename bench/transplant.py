"""The diagnosis on every effect class over flights it did not write: the foreign development
flights with their own hidden effect taken out and another put in
(`mimunav.diagnosis.transplant`), plus null carriers with and without airframe vibration.

    python bench/transplant.py [--per-class 6] [--nulls 20] [--seed 1] [--report reports]

Each case draws a carrier (one of the six foreign logs), an axis, a sign and a magnitude in
the class's range below; writes REPORT/diagnosis-transplant.md and .json. A case is named
when a finding has the hidden effect, sensor and axis; covered when the truth lies in its
95 % interval (every component of a vector); a null is right when the verdict is
no-missing-physics.
"""
import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from publish import publish, write_report                                  # noqa: E402
from mimunav.diagnosis import sensor, transplant             # noqa: E402

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
    # the classes of the project's concealed-data suite (mimunav/diagnosis/concealed.py),
    # gyro temperature terms per Hz through the foreign units' -0.5 Hz/degC
    ("scale_factor", "gyro"): (1e-3, 3e-3), ("scale_factor", "accel"): (1e-3, 3e-3),
    ("cross_coupling", "gyro"): (1e-3, 3e-3), ("cross_coupling", "accel"): (1e-3, 3e-3),
    ("scale_nonlinearity", "accel"): (2e-6, 1e-5),
    ("scale_nonlinearity", "gyro"): (1e-6 * 180 / math.pi, 5e-6 * 180 / math.pi),
    ("g_sensitivity", "gyro"): (0.01 * DEG / 9.80665, 0.04 * DEG / 9.80665),
    ("g2_sensitivity", "gyro"): (2e-3 * DEG / 9.80665 ** 2, 1e-2 * DEG / 9.80665 ** 2),
    ("temperature_bias", "accel"): (0.1 * MG, 0.4 * MG),
    ("temperature_bias", "gyro"): (20 * DEG / 3600 / 0.5, 80 * DEG / 3600 / 0.5),
    ("temperature_scale", "accel"): (1e-4, 5e-4), ("temperature_scale", "gyro"): (2e-4, 1e-3),
    ("temperature_rate", "accel"): (0.2 * MG, 1 * MG),
    ("temperature_rate", "gyro"): (20 * DEG / 3600 / 0.5, 100 * DEG / 3600 / 0.5),
    ("thermal_hysteresis", "accel"): (1 * MG, 5 * MG),
    ("thermal_hysteresis", "gyro"): (0.02 * DEG, 0.1 * DEG),
    ("time_skew", "imu"): (2e-4, 1e-3),
    ("size_effect", "accel"): (5e-3, 15e-3),
    ("mounting_misalignment", "imu"): (1e-3, 3e-3),
}
THERMAL = ("temperature_bias", "temperature_scale", "temperature_rate", "thermal_hysteresis")
CLASSES = ("bias_shift", "quantization", "bias_instability", "vibration_rectification",
           "scale_asymmetry", "saturation", "lever_arm", "scale_factor", "cross_coupling",
           "scale_nonlinearity", "g_sensitivity", "g2_sensitivity", "time_skew", "size_effect",
           "mounting_misalignment") + THERMAL + ("null", "null+vibration")
THERMAL_CARRIER = "foreign-03"      # the only development flight whose temperature moves


def draw(effect, rng, base):
    """A transplant spec of `effect` on carrier `base`."""
    if effect == "null":
        return "bias_shift:gyro:x=0"
    if effect == "null+vibration":
        return "vibration_rectification:accel:x=0"
    def magnitude(sensor_):
        return math.exp(rng.uniform(*np.log(RANGES[effect, sensor_])))

    def direction(size):
        v = rng.standard_normal(3)
        return "/".join(f"{x:.6g}" for x in v * size / np.linalg.norm(v))
    if effect in ("lever_arm", "mounting_misalignment"):
        return f"{effect}:imu:all=" + direction(magnitude("imu"))
    if effect == "time_skew":
        return f"time_skew:{rng.choice(['imu', 'accel', 'gyro'])}:all={magnitude('imu'):.6g}"
    axis = rng.choice(list("xyz"))
    if effect == "size_effect":
        return f"size_effect:accel:{axis}=" + direction(magnitude("accel"))
    sensor_ = "gyro" if effect.startswith("g") else rng.choice(["accel", "gyro"])
    others = [a for a in "xyz" if a != axis]
    suffix = {"cross_coupling": f":{rng.choice(others)}",
              "g_sensitivity": f":{rng.choice(list('xyz'))}",
              "g2_sensitivity": ":" + "".join(sorted(rng.choice(list("xyz"), 2)))}.get(effect, "")
    at = {"scale_nonlinearity": "@order=2", "temperature_rate": "@window_s=120"}.get(effect, "")
    lo, hi = RANGES[effect, sensor_]
    value = magnitude(sensor_)
    if effect == "saturation":      # a level below the peak input of the most driven axis:
        _, _, f, w = transplant.carrier(base)        # a clip is a large input's
        peaks = np.max(np.abs(f if sensor_ == "accel" else w), axis=0)
        axis = "xyz"[int(np.argmax(peaks))]
        value = rng.uniform(lo, hi) * peaks.max()
    elif effect not in ("quantization", "bias_instability"):
        value *= rng.choice([-1, 1])
    return f"{effect}:{sensor_}:{axis}{suffix}={value:.6g}{at}"


def run_case(base, spec, effect, seed):
    t0 = time.perf_counter()
    flight, cal, key = transplant.transplant(base, spec, seed=seed)
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
    def same(f):
        return all(f.get(k) == key.get(k) for k in ("effect", "sensor", "axis", "input_axis",
                                                     "order", "window_s") if k in key)
    match = [f for f in diag.findings if same(f)]
    case["named"] = bool(match)
    case["others"] = [f["label"] for f in diag.findings
                      if f not in match and not any(same(a) for a in
                                                    f.get("indistinguishable_from", []))]
    case["indistinguishable"] = any(same(a) for f in diag.findings
                                    for a in f.get("indistinguishable_from", []))
    if match:
        f = match[0]
        lo, hi = (np.asarray(f["vector_ci95"]).T if "vector_ci95" in f
                  else (np.atleast_1d(f["ci95"][0]), np.atleast_1d(f["ci95"][1])))
        case["estimate"] = f.get("vector", f["coefficient"])
        case["covered"] = bool(np.all((lo <= truth) & (truth <= hi)))
    case["truth"] = truth.tolist()
    case["right"] = case["named"]
    case["z"] = sensor.term_z(diag, {k: v for k, v in key.items()
                                     if k not in ("spec", "carrier")})
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
             "A case is named when a finding has the hidden effect, sensor, axis (and input axis, "
             "order, window); 'told apart' counts those named or listed as indistinguishable on "
             "this flight; z is the Wald z of the true term fitted alone on the whole flight "
             "(NaN for the classes tested on the outputs).", "",
             "| class | cases | named (right for nulls) | named or not told apart | "
             "truth in 95 % interval (of named) | cases with another finding |",
             "|---|---|---|---|---|---|"]
    for effect in CLASSES:
        cs = [c for c in cases if c["class"] == effect]
        if not cs:
            continue
        named = sum(c["right"] for c in cs)
        cov = [c["covered"] for c in cs if "covered" in c]
        apart = sum(c["right"] or c.get("indistinguishable", False) for c in cs)
        extra = sum(bool(c.get("others")) for c in cs)
        lines.append(f"| {effect} | {len(cs)} | {named}/{len(cs)} | {apart}/{len(cs)} | "
                     f"{f'{sum(cov)}/{len(cov)}' if cov else '-'} | {extra}/{len(cs)} |")
    strong = [c for c in cases if not c["class"].startswith("null")
              and not (c.get("z", math.nan) <= 5)]          # z > 5, or tested on the outputs
    apart = sum(c["right"] or c.get("indistinguishable", False) for c in strong)
    lines += ["", f"Detectable cases (z > 5, or a class tested on the outputs): {apart} of "
                  f"{len(strong)} named or reported as not told apart on their flight. The "
                  "others lie below what any test on this flight can find (z <= 5): 'nothing "
                  "found' is their right answer, and the nulls' rate is the false alarms'."]
    lines += ["", "| carrier | hidden (spec) | z | verdict | findings | right | covered |",
              "|---|---|---|---|---|---|---|"]
    for c in cases:
        lines.append(f"| {c['carrier']} | `{c['spec']}` | {c.get('z', float('nan')):.1f} | "
                     f"{c['verdict']} | {', '.join(c['findings']) or '-'} | "
                     f"{'yes' if c['right'] else 'no'} | {c.get('covered', '-')} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--per-class", type=int, default=6)
    ap.add_argument("--nulls", type=int, default=20, help="null carriers of each kind")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--report", default=str(ROOT / "reports"))
    ap.add_argument("--json")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    bases = [str(p)[:-len(".key.json")] for p in sorted(FOREIGN.glob("foreign-*.key.json"))]
    from tqdm import tqdm
    t0 = time.perf_counter()
    thermal = next(b for b in bases if b.endswith(THERMAL_CARRIER))
    jobs = [(thermal if effect in THERMAL else bases[int(rng.integers(len(bases)))], effect)
            for effect in CLASSES
            for _ in range(args.nulls if effect.startswith("null") else args.per_class)]
    cases = []
    for k, (base, effect) in enumerate(tqdm(jobs, desc="transplants")):
        cases.append(run_case(base, draw(effect, rng, base), effect, args.seed * 1000 + k))
    wall = time.perf_counter() - t0
    write_report(args.report, "diagnosis-transplant", markdown,
                 f"python bench/transplant.py --per-class {args.per_class} "
                 f"--nulls {args.nulls} --seed {args.seed}", wall, cases)
    effects = [c for c in cases if not c["class"].startswith("null")]
    nulls = [c for c in cases if c["class"].startswith("null")]
    cov = [c["covered"] for c in effects if "covered" in c]
    publish(__file__, [(
        f"transplants: {len(effects)} effects of {len(CLASSES) - 2} classes and {len(nulls)} "
        "nulls on the foreign flights (reports/diagnosis-transplant.md)",
        f"named {sum(c['right'] for c in effects)}/{len(effects)}, truth in interval "
        f"{sum(cov)}/{len(cov)}, another finding beside in "
        f"{sum(bool(c.get('others')) for c in effects)}; nulls quiet "
        f"{sum(c['right'] for c in nulls)}/{len(nulls)}; {wall:.0f} s")], {"cases": cases},
        args.json)


if __name__ == "__main__":
    main()

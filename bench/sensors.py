"""Benchmark of the sensor models: MIMU raw simulation and compensation of 10^6 samples.

    python bench/sensors.py [--samples 1000000] [--json out.json]

Simulation: ideal increments of the shipped high-dynamic flight (looped) -> noise, thermal,
saturation, inverse of eqs. 1-4, ADC. Compensation: wild-value filter + eqs. 1-4.
Times are the best and median of repeats after JIT warm-up.
"""
import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from publish import publish  # noqa: E402
from mimunav.motion import truth                      # noqa: E402
from mimunav.compensation.model import compensate    # noqa: E402
from mimunav.motion.profile import Profile            # noqa: E402
from mimunav.sensors.mimu import MimuUnit           # noqa: E402


def timed(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, min(times), float(np.median(times))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json")
    args = ap.parse_args()
    n, rate = args.samples, 1000.0
    prof = Profile.load(ROOT / "flights" / "high-dynamic.toml")
    doc = {"name": "bench", "start": {"latitude_deg": 40, "longitude_deg": 100, "height_m": 3000,
                                      "speed_m_s": 250, "heading_deg": 30, "ramp_s": 0.2},
           "segment": prof.segments * int(np.ceil(n / rate / prof.duration))}
    t = np.arange(0, n + 1) / rate
    run = truth.generate(Profile.from_dict(doc).motion(), t)
    unit = MimuUnit.draw(1)
    env = np.full(n, 15.0)
    rng = np.random.default_rng(0)
    unit.simulate(t[1:1001], run.dtheta[:1000], run.dv[:1000], env[:1000], rng)
    raw, sim_best, sim_med = timed(
        lambda: unit.simulate(t[1:], run.dtheta, run.dv, env, rng), args.repeats)
    cols = [raw[k] for k in ("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency")]
    compensate(unit.coefficients, *[c[:1000] for c in cols])
    (f, w, flags), comp_best, comp_med = timed(
        lambda: compensate(unit.coefficients, *cols, unit.range_accel, unit.range_gyro),
        args.repeats)
    res = {"machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_version()}",
           "samples": n, "simulate_s_best": sim_best, "simulate_s_median": sim_med,
           "compensate_s_best": comp_best, "compensate_s_median": comp_med,
           "flagged_samples": int((flags > 0).sum())}
    publish(__file__, [
        (f"MIMU raw simulation, {n:.0e} samples", f"{sim_best:.3f} s best, {sim_med:.3f} s median"),
        (f"compensation (wild-value filter + eqs. 1-4), {n:.0e} samples",
         f"{comp_best:.3f} s best, {comp_med:.3f} s median")], res, args.json)


if __name__ == "__main__":
    main()

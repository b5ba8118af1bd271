"""Benchmark of the strapdown navigator and the truth generator.

    python bench/strapdown.py [--samples 1000000] [--json out.json]

Prints navigator throughput (samples/s, best and median of repeats, after JIT warm-up),
the navigator's memory per sample (tracemalloc peak of its allocations, plus the
56 B/sample of its inputs), and the time to generate truth + exact increments for the
same number of samples of the shipped high-dynamic flight (looped to length; best and
median of 3).
"""
import argparse
import os
import platform
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from publish import publish  # noqa: E402
from mimunav.navigation import strapdown
from mimunav.motion import truth  # noqa: E402
from mimunav.motion.profile import Profile   # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--rate", type=float, default=1000.0, help="IMU rate, Hz")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--json", help="write the results to this JSON file")
    args = ap.parse_args()
    n, rate = args.samples, args.rate

    prof = Profile.load(Path(__file__).resolve().parent.parent / "flights" / "high-dynamic.toml")
    doc = {"name": "bench", "start": {"latitude_deg": 40, "longitude_deg": 100, "height_m": 3000,
                                      "speed_m_s": 250, "heading_deg": 30, "ramp_s": 0.2},
           "segment": prof.segments * int(np.ceil(n / rate / prof.duration))}
    motion = Profile.from_dict(doc).motion()
    t = np.arange(0, n + 1) / rate
    truth.generate(motion, t[:1000])                      # JIT warm-up
    truth_times = []
    for _ in range(3):
        t0 = time.perf_counter()
        run = truth.generate(motion, t)
        truth_times.append(time.perf_counter() - t0)
    t_truth = min(truth_times)

    start = run.trajectory.state(0)
    strapdown.integrate(t[1:1001], run.dtheta[:1000], run.dv[:1000], start)   # warm-up
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        nav = strapdown.integrate(t[1:], run.dtheta, run.dv, start)
        times.append(time.perf_counter() - t0)
    tracemalloc.start()
    strapdown.integrate(t[1:], run.dtheta, run.dv, start)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    err = np.linalg.norm(nav.position_error(run.trajectory)[-1])

    res = {
        "machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_version()}",
        "samples": n, "rate_hz": rate,
        "navigator_s_best": min(times), "navigator_s_median": float(np.median(times)),
        "navigator_samples_per_s": n / min(times),
        "navigator_samples_per_s_median": n / float(np.median(times)),
        "navigator_bytes_per_sample": peak / n,
        "navigator_bytes_per_sample_with_inputs": peak / n + 56,
        "truth_and_increments_s": t_truth,
        "truth_and_increments_s_median": float(np.median(truth_times)),
        "end_position_error_m": float(err),
    }
    publish(__file__, [
        (f"strapdown navigator, {n:.0e} samples at {rate:g} Hz",
         f"{res['navigator_samples_per_s'] / 1e6:.1f} M samples/s best, "
         f"{res['navigator_samples_per_s_median'] / 1e6:.1f} M median of {args.repeats}; "
         f"{res['navigator_bytes_per_sample']:.0f} B/sample allocated (+56 inputs)"),
        (f"truth + exact increments, {n:.0e} samples",
         f"{t_truth:.2f} s best, {np.median(truth_times):.2f} s median of 3"),
        (f"ideal IMU through the navigator, {n / rate:.0f} s of the bench flight",
         f"end position error {err:.2e} m")], res, args.json)


if __name__ == "__main__":
    main()

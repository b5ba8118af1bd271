"""Benchmark of the strapdown navigator and the truth generator, side by side with pyins.

    python bench/strapdown.py [--samples 1000000] [--json out.json]

Prints navigator throughput (samples/s, best and median of repeats, after JIT warm-up),
the navigator's memory per sample (tracemalloc peak of its allocations, plus the
56 B/sample of its inputs), and the time to generate truth + exact increments for the
same number of samples of the shipped high-dynamic flight (looped to length; best and
median of 3).

The peer: pyins (nmayorov/pyins 1.0.1, MIT; `pip install ../shared/peers/pyins`, a bench
tool, no dependency of the project) integrates the same exact increments in the same
process run. Each side is timed end to end as a user calls it - arrays in, trajectory
out: mimunav's `strapdown.integrate`; pyins's increment-sensor DataFrame,
`compute_increments_from_imu(imu, "increment")` (coning and sculling) and
`Integrator(pva).integrate` - and pyins's integrator alone is reported apart. Both start
from the truth's initial state; both end position errors against the truth are printed
beside the speeds (pyins's is mostly down: its gravity, Somigliana with a linear height
term, is 3.1e-5 m/s^2 above the truth generator's at 3 km; the increments are the truth's,
so that difference integrates). Without pyins installed the peer rows say so and the rest
runs.
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
from mimunav.frames import earth  # noqa: E402
from mimunav.navigation import strapdown  # noqa: E402
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
    peer = pyins_side_by_side(t, run, min(times), float(np.median(times)))

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
        "pyins": peer,
    }
    publish(__file__, [
        (f"strapdown navigator, {n:.0e} samples at {rate:g} Hz",
         f"{res['navigator_samples_per_s'] / 1e6:.1f} M samples/s best, "
         f"{res['navigator_samples_per_s_median'] / 1e6:.1f} M median of {args.repeats}; "
         f"{res['navigator_bytes_per_sample']:.0f} B/sample allocated (+56 inputs)"),
        (f"truth + exact increments, {n:.0e} samples",
         f"{t_truth:.2f} s best, {np.median(truth_times):.2f} s median of 3"),
        (f"ideal IMU through the navigator, {n / rate:.0f} s of the bench flight",
         f"end position error {err:.2e} m"),
        *peer_rows(peer, n, rate, err)], res, args.json)


def pyins_side_by_side(t, run, ours_best, ours_median, repeats=3):
    """pyins on the same increments from the same initial state: end-to-end and
    integrator-only times (best, median of `repeats`, after a JIT warm-up) and its end
    position error against the truth, m. None if pyins is not installed."""
    try:
        import pandas as pd
        from pyins import strapdown as peer, transform
    except ImportError:
        return None
    from mimunav.frames import attitude
    start = run.trajectory.state(0)
    rph = transform.mat_to_rph(attitude.as_scipy(run.trajectory.q_nb[:1]).as_matrix()[0])
    pva = pd.Series(np.hstack([np.rad2deg([start.lat, start.lon]), start.h, start.v_ned, rph]),
                    index=peer.TRAJECTORY_COLS)

    def end_to_end(m):
        # an increment sensor needs a "before" sample (pyins.strapdown docs): the first, repeated
        imu = pd.DataFrame(np.hstack([np.vstack([run.dtheta[:1], run.dtheta[:m]]),
                                      np.vstack([run.dv[:1], run.dv[:m]])]),
                           index=t[:m + 1], columns=peer.GYRO_COLS + peer.ACCEL_COLS)
        t0 = time.perf_counter()
        increments = peer.compute_increments_from_imu(imu, "increment")
        t1 = time.perf_counter()
        out = peer.Integrator(pva).integrate(increments)
        t2 = time.perf_counter()
        return out, t2 - t0, t2 - t1, kernel(increments)

    def kernel(increments):
        # pyins.strapdown.integrate, the numba loop Integrator calls, on preallocated arrays:
        # no DataFrame in or out, no Euler angles (as mimunav's navigator returns quaternions)
        m = len(increments) + 1
        lla, v, mat = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3, 3))
        lla[0], v[0] = pva[peer.LLA_COLS], pva[peer.VEL_COLS]
        mat[0] = transform.mat_from_rph(pva[peer.RPH_COLS])
        dt = np.asarray(increments.dt)
        theta = np.ascontiguousarray(increments[["theta_x", "theta_y", "theta_z"]])
        dv = np.ascontiguousarray(increments[["dv_x", "dv_y", "dv_z"]])
        t0 = time.perf_counter()
        peer.integrate(dt, lla, v, mat, theta, dv, 0, True)
        return time.perf_counter() - t0

    end_to_end(1000)                                      # JIT warm-up
    totals, integrator, kernels = [], [], []
    for _ in range(repeats):
        out, total, only, loop = end_to_end(len(run.dtheta))
        totals.append(total)
        integrator.append(only)
        kernels.append(loop)
    tr = run.trajectory
    end = out.iloc[-1]
    err_ned = earth.ned_difference(np.deg2rad(end.lat), np.deg2rad(end.lon), end.alt,
                                   tr.lat[-1], tr.lon[-1], tr.h[-1])
    err = np.linalg.norm(err_ned)
    return {"version": _pyins_version(),
            "end_to_end_s_best": min(totals), "end_to_end_s_median": float(np.median(totals)),
            "integrator_s_best": min(integrator),
            "integrator_s_median": float(np.median(integrator)),
            "kernel_s_best": min(kernels), "kernel_ratio_best": min(kernels) / ours_best,
            "ratio_best": min(totals) / ours_best,
            "ratio_median": float(np.median(totals)) / ours_median,
            "end_position_error_m": float(err), "end_position_error_ned_m": err_ned.tolist(),
            "repeats": repeats}


def _pyins_version():
    from importlib.metadata import version, PackageNotFoundError
    try:
        return version("python-ins")
    except PackageNotFoundError:
        return "unknown"


def peer_rows(peer, n, rate, ours_err):
    """README rows of the side-by-side run."""
    label = f"pyins {{}}, same {n:.0e} increments at {rate:g} Hz"
    if peer is None:
        return [(label.format("(not installed)"), "pip install ../shared/peers/pyins to run it")]
    return [(label.format(peer["version"]),
             f"end to end {n / peer['end_to_end_s_best'] / 1e6:.2f} M samples/s best "
             f"({n / peer['integrator_s_best'] / 1e6:.2f} M Integrator alone, "
             f"{n / peer['kernel_s_best'] / 1e6:.2f} M its numba loop alone); mimunav "
             f"{peer['ratio_best']:.1f}x faster end to end best, {peer['ratio_median']:.1f}x "
             f"median of {peer['repeats']}, {peer['kernel_ratio_best']:.1f}x loop to loop"),
            (f"end position error after {n / rate:.0f} s, same increments",
             f"pyins {peer['end_position_error_m']:.2e} m, mimunav {ours_err:.2e} m")]


if __name__ == "__main__":
    main()

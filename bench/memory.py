"""Peak memory of the commands that read a whole flight, against the flight's length.

    python bench/memory.py [--minutes 5 20] [--commands compensate replay table diagnose
                                                    diagnose-report diagnose-navigation]

diagnose-report is `mimunav diagnose LOG -o DIR`: the diagnosis and its report folder (the
figures, the model's navigation with and without the found terms); diagnose-navigation is
`mimunav diagnose LOG --level navigation` (every candidate's velocity-error signature).

Each command's wall time beside it (the 2-hour line extrapolates it too).

A parked 1 kHz flight (MIMU raw volts of a drawn unit at rest through its true
coefficients, FOG-IMU at rest, truth at 100 Hz; white noise) of each length is written
block by block, then each command runs in its own process and its peak resident memory is
read by getrusage (ru_maxrss). The slope between the lengths is the memory per sample;
the line extrapolates it to a 2-hour 1 kHz flight (7.2 M samples).
"""
import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from publish import publish                             # noqa: E402
from mimunav.frames import earth                               # noqa: E402
from mimunav.compensation.calibration_file import Calibration
from mimunav.compensation.model import raw_from_physics     # noqa: E402
from mimunav.flightlog import LogWriter                 # noqa: E402
from mimunav.flightlog import schemas as S              # noqa: E402
from mimunav.sensors.mimu import MimuUnit                    # noqa: E402

EPOCH_NS = 1_767_225_600 * 10**9
LAT, LON, H = math.radians(45.0), math.radians(7.0), 300.0
BLOCK = 200_000
COMMANDS = ("compensate", "replay", "table", "simulate", "diagnose", "diagnose-report",
            "diagnose-navigation")


def parked_log(path, minutes, unit, rate=1000.0, seed=0):
    """A parked flight (level, heading north) of `minutes` at `rate`, written in blocks."""
    rng = np.random.default_rng(seed)
    g = float(earth.normal_gravity(LAT, H))
    w = np.array([earth.OMEGA * math.cos(LAT), 0.0, -earth.OMEGA * math.sin(LAT)])
    f = np.array([0.0, 0.0, -g])
    temp = np.full((1, 3), 25.0)
    freq = unit.thermal.resonance_frequency(temp)
    u_a, u_w = raw_from_physics(unit.coefficients, f[None], w[None], temp, freq)
    n = int(minutes * 60 * rate)
    mounting = {"attitude_wxyz": [1.0, 0, 0, 0], "lever_arm_m": [0.0, 0, 0]}
    with LogWriter(path, force=True) as log:
        log.metadata("flight", {"format": "mimunav-log/1", "name": "parked", "description":
                                f"parked {minutes} min at {rate:g} Hz (bench/memory.py)",
                                "epoch_unix_ns": EPOCH_NS, "source": "simulation",
                                "initial_state": {"t": 0.0, "latitude": LAT, "longitude": LON,
                                                  "height": H, "velocity_ned": [0.0, 0, 0],
                                                  "attitude_wxyz": [1.0, 0, 0, 0]}})
        log.metadata("sensor/mimu", {"model": "bench", "sample_rate_hz": rate,
                                     "mounting": mounting,
                                     "range": {"gyro_rad_s": unit.range_gyro,
                                               "accel_m_s2": unit.range_accel}})
        log.metadata("sensor/fog", {"model": "bench", "sample_rate_hz": rate,
                                    "mounting": mounting})
        for a in range(0, n, BLOCK):
            k = np.arange(a, min(n, a + BLOCK))
            stamps = EPOCH_NS + np.round(k * 1e9 / rate).astype(np.int64)
            m = len(k)
            log.write("/mimu/raw", S.RAW_MIMU, "mimu", stamps, sample_index=k.astype(np.uint64),
                      gyro_volts=u_w + rng.normal(0, 1e-4, (m, 3)),
                      accel_volts=u_a + rng.normal(0, 1e-4, (m, 3)),
                      accel_temperature=np.full((m, 3), 25.0), gyro_frequency=np.tile(freq, (m, 1)))
        for a in range(0, n, BLOCK):
            k = np.arange(a, min(n, a + BLOCK))
            stamps = EPOCH_NS + np.round(k * 1e9 / rate).astype(np.int64)
            m = len(k)
            log.write("/fog/imu", S.IMU, "fog", stamps, **S.imu_fields(
                w + rng.normal(0, 1e-6, (m, 3)), f + rng.normal(0, 1e-4, (m, 3))))
        n_truth = int(minutes * 60 * 100) + 1
        stamps = EPOCH_NS + np.arange(n_truth, dtype=np.int64) * 10_000_000
        log.write("/truth/state", S.NAV_STATE, "vehicle", stamps, latitude=np.full(n_truth, LAT),
                  longitude=np.full(n_truth, LON), height=np.full(n_truth, H),
                  velocity_ned=np.zeros((n_truth, 3)),
                  attitude_wxyz=np.tile([1.0, 0, 0, 0], (n_truth, 1)))
    return n


# The peak is the process's own high-water mark, VmHWM (kB), where Linux gives it: ru_maxrss
# survives exec, so a child that Python starts with vfork from a large parent (a pytest worker
# holding 1.7 GB) reports the parent's peak as its own.
PEAK = ("import resource, sys\nfrom mimunav.cli import main\ncode = main(sys.argv[1:])\n"
        "try:\n"
        "    hwm = next(int(line.split()[1]) for line in open('/proc/self/status')\n"
        "               if line.startswith('VmHWM:'))\n"
        "except (OSError, StopIteration):\n"
        "    hwm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "print(hwm, file=sys.stderr)\n"
        "sys.exit(code)")


def peak_mb(argv, cwd):
    """(peak resident memory MB, wall time s) of `mimunav ARGV` in its own process (VmHWM,
    else getrusage)."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", PEAK, *argv], cwd=cwd, capture_output=True,
                         text=True)
    if out.returncode != 0:
        raise RuntimeError(f"mimunav {' '.join(argv)}: {out.stderr.strip()[-500:]}")
    return int(out.stderr.strip().splitlines()[-1]) / 1024, time.perf_counter() - start


def commands(kind, log, cal, tmp, minutes):
    """The command line of `kind` on the parked log (simulate: a parked profile of the same
    length, written beside it)."""
    if kind == "simulate":
        profile = Path(tmp) / f"parked-{minutes:g}.toml"
        profile.write_text(f'name = "parked"\n[start]\nlatitude_deg = 45.0\n'
                           f'longitude_deg = 7.0\nheight_m = 300.0\nspeed_m_s = 0.0\n'
                           f'heading_deg = 0.0\n[[segment]]\nkind = "hold"\n'
                           f'duration_s = {minutes * 60.0}\n')
        return ["simulate", str(profile), "-o", f"{tmp}/sim.mcap", "--force"]
    out = {"compensate": ["compensate", log, "--cal", cal, "-o", f"{tmp}/out.mcap", "--force"],
           "replay": ["replay", log, "--cal", cal, "-o", f"{tmp}/replay", "--force"],
           "table": ["table", log, "--cal", f"c={cal}"],
           "diagnose": ["diagnose", log, "--model", cal, "--json", f"{tmp}/diagnosis.json",
                        "--force"],
           "diagnose-report": ["diagnose", log, "--model", cal, "-o", f"{tmp}/report",
                               "--force"],
           "diagnose-navigation": ["diagnose", log, "--model", cal, "--level", "navigation",
                                   "--json", f"{tmp}/navigation.json", "--force"]}
    return out[kind]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, nargs=2, default=[5.0, 20.0])
    ap.add_argument("--commands", nargs="+", default=list(COMMANDS), choices=COMMANDS)
    args = ap.parse_args()
    unit = MimuUnit.draw(1, beyond_model=False)
    results, seconds = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        cal = f"{tmp}/cal.json"
        Calibration.from_dict(unit.coefficients.as_dict()).save(cal)
        for minutes in args.minutes:
            log = f"{tmp}/parked-{minutes:g}.mcap"
            n = parked_log(log, minutes, unit)
            for kind in args.commands:
                results[(kind, n)], seconds[(kind, n)] = peak_mb(
                    commands(kind, log, cal, tmp, minutes), tmp)
                print(f"{kind:11s} {minutes:6g} min ({n / 1e6:.2f} M samples): "
                      f"{results[(kind, n)]:7.0f} MB, {seconds[(kind, n)]:.0f} s", flush=True)
    (n0, n1) = sorted({n for _, n in results})
    rows = []
    for kind in args.commands:
        slope = (results[(kind, n1)] - results[(kind, n0)]) / (n1 - n0) * 1e6     # MB / M
        per_m = (seconds[(kind, n1)] - seconds[(kind, n0)]) / (n1 - n0) * 1e6    # s / M
        name = {"diagnose-report": "diagnose -o",
                "diagnose-navigation": "diagnose --level navigation"}.get(kind, kind)
        rows.append((f"peak memory of `mimunav {name}` against the flight's length (parked, "
                     "1 kHz)",
                     f"{results[(kind, n0)]:.0f} MB at {args.minutes[0]:g} min, "
                     f"{results[(kind, n1)]:.0f} MB at {args.minutes[1]:g} min: "
                     f"{slope * 1.048576:.0f} B/sample, a 2-hour 1 kHz flight "
                     f"~{results[(kind, n0)] + slope * (7.2 - n0 / 1e6):.0f} MB; wall "
                     f"{seconds[(kind, n0)]:.0f} s and {seconds[(kind, n1)]:.0f} s, 2 hours "
                     f"~{seconds[(kind, n0)] + per_m * (7.2 - n0 / 1e6):.0f} s"))
    publish(__file__, rows)


if __name__ == "__main__":
    main()

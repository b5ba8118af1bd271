"""Simulated flights: profile -> truth -> sensors -> MCAP log (+ a separate truth file).

Timeline: profile time 0 is the initial state, stamped `epoch_unix_ns`; each IMU has a
sample stamped there (the contract asks for one) and then one every 1/rate s. That first
sample stands for (-dt, 0], before the profile begins; it repeats the first interval's
increments (every shipped profile starts steady) and is never navigated.

Truth and exact increments are generated once at a base rate that both IMU rates divide,
and summed to each IMU's rate (exact: increments add). Each IMU sees the vehicle motion at
its own mounting (lever arm and attitude). The MIMU is powered on cold at the start, in an
equipment bay that lags the ISA air along the flown heights (`sensors.thermal`).
"""
import json
import math
import os
from dataclasses import dataclass
from datetime import datetime

import numpy as np
import quaternion
from tqdm import tqdm

from . import truth
from .files import write_atomic
from .flightlog import LogWriter
from .flightlog import schemas as S
from .sensors import FogUnit, MimuUnit, Mounting
from .modulation import platform_metadata
from .sensors.hidden import HiddenPhysics, HiddenSet
from .sensors.thermal import BAY_TAU_S, ISA_LAPSE, bay_temperature
from .errors import InputError

DEFAULT_EPOCH = "2026-01-01T00:00:00Z"
# Documented default mountings: the FOG-IMU defines the vehicle frame origin; the MIMU sits
# 0.30 m ahead, 0.10 m left and 0.05 m below it, axes aligned with the vehicle.
MIMU_MOUNTING = {"attitude_wxyz": [1.0, 0.0, 0.0, 0.0], "lever_arm_m": [0.30, -0.10, 0.05]}
FOG_MOUNTING = {"attitude_wxyz": [1.0, 0.0, 0.0, 0.0], "lever_arm_m": [0.0, 0.0, 0.0]}
GROUND_TEMPERATURE_C = 15.0     # ISA sea-level temperature, at the profile's start height
MAX_BASE_RATE = 4000


def epoch_ns(text):
    return int(datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()) * 10**9


@dataclass
class FlightMotion:
    """The unit-independent part of a simulated flight: the truth at the base rate, the
    ideal increments of each IMU at its mounting and rate (sample k covers (t[k-1], t[k]];
    the sample at 0 repeats the first interval), the MIMU bay temperature (degC) and the
    indices of the truth samples written to /truth/state."""
    profile: object
    run: object
    t_base: np.ndarray
    mimu: tuple                 # (t s, dtheta rad, dv m/s), sensor axes
    fog: tuple
    env: np.ndarray
    k_truth: np.ndarray
    platform: dict | None = None    # rotating MIMU: {"angle", "rate"} at the MIMU's stamps
                                    # (rad, rad/s) and the `modulation.Platform`


def flight_motion(profile, mimu_mounting, mimu_rate, fog_mounting, fog_rate, truth_rate,
                  ground_temperature_c=GROUND_TEMPERATURE_C, platform=None):
    """Truth and ideal increments of `profile` for IMUs at the given mountings and rates;
    the bay follows the outside air of a day at `ground_temperature_c` (degC at the
    profile's start height). `platform` (`modulation.Platform`): the MIMU turns on it at
    the vehicle origin (its mounting's lever arm is not used), its increments exact
    (`modulation.RotatingMotion`)."""
    rates = [mimu_rate, fog_rate, truth_rate]
    if any(r != int(r) for r in rates):
        raise InputError(f"sample rates must be whole numbers of Hz, got {rates}")
    base = math.lcm(*(int(r) for r in rates[:2]))
    if base > MAX_BASE_RATE or base % int(truth_rate):
        raise InputError(f"rates {rates} need a common base rate of {base} Hz (at most "
                         f"{MAX_BASE_RATE}, a multiple of the truth rate)")
    motion = profile.motion()
    t_base = np.arange(0, int(math.floor(profile.duration * base + 1e-9)) + 1) / base
    run = truth.generate(motion, t_base)

    def at_rate(mounting, rate, source=None):
        dth, dv = mounting.sensor_increments(run if source is None else source)
        k = base // int(rate)
        n = len(dth) // k
        dth = dth[:n * k].reshape(n, k, 3).sum(axis=1)
        dv = dv[:n * k].reshape(n, k, 3).sum(axis=1)
        t = np.arange(n + 1) / rate
        return t, np.vstack([dth[:1], dth]), np.vstack([dv[:1], dv])
    if platform is None:
        mimu = at_rate(mimu_mounting, mimu_rate)
        turning = None
    else:
        from .modulation import RotatingMotion
        rotating = RotatingMotion(motion, platform, profile.duration)
        sensor_run = truth.generate(rotating, t_base)
        mimu = at_rate(_SensorFrame(), mimu_rate, sensor_run)
        turning = {"angle": rotating.angle(mimu[0]), "rate": rotating.rate(mimu[0]),
                   "platform": platform}
    env = bay_temperature(mimu[0], np.interp(mimu[0], t_base, run.trajectory.h),
                          ground_temperature_c, motion.h0)
    return FlightMotion(profile, run, t_base, mimu, at_rate(fog_mounting, fog_rate), env,
                        np.arange(0, len(t_base), base // int(truth_rate)), turning)


class _SensorFrame:
    """The increments of a run whose body is the sensor itself (`RotatingMotion`)."""

    @staticmethod
    def sensor_increments(run):
        return run.dtheta, run.dv


def flight_units(seed, unit=None, fog_rate=1000.0, fog_grade="table4"):
    """The MIMU (drawn at the default mounting unless given) and FOG-IMU (of `fog_grade`,
    `sensors.fog.FOG_GRADES`) of flight `seed`, and the noise generators of each."""
    s_unit, s_fog, s_mimu_noise, s_fog_noise = np.random.SeedSequence(seed).spawn(4)
    if unit is None:        # a drawn unit sits at the default mounting; a given one keeps its own
        unit = MimuUnit.draw(int(s_unit.generate_state(1)[0]), name=f"MIMU-{seed:04d}")
        unit.mounting = Mounting.from_dict(MIMU_MOUNTING)
    fog = FogUnit.draw(int(s_fog.generate_state(1)[0]), rate_hz=fog_rate, name=f"FOG-{seed:04d}",
                       grade=fog_grade)
    fog.mounting = Mounting.from_dict(FOG_MOUNTING)
    return unit, fog, np.random.default_rng(s_mimu_noise), np.random.default_rng(s_fog_noise)


def record_flight(fm, unit, fog, rng_mimu, rng_fog, hidden=None, warm_up_s=0.0):
    """Raw MIMU and FOG outputs over a `FlightMotion`; `hidden`: extra MIMU physics
    (`MimuUnit.simulate`); the MIMU powered on `warm_up_s` before take-off (0: cold)."""
    raw = unit.simulate(*fm.mimu, fm.env, rng_mimu, hidden=hidden, warm_up_s=warm_up_s)
    return raw, fog.simulate(*fm.fog, rng_fog)


def simulate_flight(profile, out, seed, unit=None, fog_rate=1000.0, truth_rate=100.0,
                    force=False, progress=True, hidden=None, hide=(),
                    ground_temperature_c=GROUND_TEMPERATURE_C, fog_grade="table4",
                    warm_up_s=0.0, platform=None):
    """Simulate `profile` into the log `out` (.mcap) and `out` with .truth.json beside it.
    `hidden`: extra MIMU physics the log must not reveal (`MimuUnit.simulate`); its
    description goes to the truth file when it has an `as_dict`. `hide`: hidden effects as
    terms (`sensors.hidden`, e.g. from `mimunav simulate --hide`), made sensor behaviour of
    this flight's unit. `ground_temperature_c`, `fog_grade`, `warm_up_s`: see
    `flight_motion`, `flight_units`, `record_flight`; `platform` (`modulation.Platform`):
    the MIMU turns on it, its angle logged as /mimu/platform. Returns (log path, truth
    path)."""
    truth_path = (str(out)[:-5] if str(out).endswith(".mcap") else str(out)) + ".truth.json"
    for path in (out, truth_path):
        if os.path.exists(path) and not force:
            raise FileExistsError(f"{path} exists; use --force to replace it")
    unit, fog, rng_mimu, rng_fog = flight_units(seed, unit, fog_rate, fog_grade)
    if platform is not None and platform.mode != "fixed" and \
            platform.rate_rad_s >= 0.5 * unit.range_gyro:
        raise InputError(f"platform rate {math.degrees(platform.rate_rad_s):g} deg/s uses half "
                         f"or more of the MIMU's {math.degrees(unit.range_gyro):g} deg/s range "
                         "before the vehicle turns at all; modulation platforms turn at tens "
                         "of deg/s")
    if hide:
        effects = [HiddenPhysics(term, unit.thermal) for term in hide]
        hidden = HiddenSet(effects + ([hidden] if hidden is not None else []))
    steps = tqdm(total=3, desc="simulate", disable=not progress, unit="step")
    fm = flight_motion(profile, unit.mounting, unit.rate_hz, fog.mounting, fog.rate_hz,
                       truth_rate, ground_temperature_c, platform)
    steps.update()
    raw, fog_out = record_flight(fm, unit, fog, rng_mimu, rng_fog, hidden, warm_up_s)
    steps.update()
    run, t_base, k_truth = fm.run, fm.t_base, fm.k_truth
    t_m, t_f = fm.mimu[0], fm.fog[0]

    epoch = epoch_ns(DEFAULT_EPOCH)
    tr = run.trajectory
    start = tr.state(0)
    initial = {"t": 0.0, "latitude": start["lat"], "longitude": start["lon"],
               "height": start["h"], "velocity_ned": start["v_ned"].tolist(),
               "attitude_wxyz": start["q_nb"].tolist()}
    with LogWriter(out, force=force) as log:
        log.metadata("flight", {"format": "mimunav-log/1", "name": profile.name,
                                "description": profile.description,
                                "epoch_unix_ns": str(epoch), "source": "simulation",
                                "initial_state": initial})
        for name, imu, model in (("mimu", unit, "MEMS IMU, 63-coefficient model (simulated)"),
                                 ("fog", fog, "FOG-IMU, Table 4 grade (simulated)")):
            log.metadata(f"sensor/{name}", {
                "model": model, "sample_rate_hz": str(imu.rate_hz),
                "mounting": (Mounting().as_dict() if name == "mimu" and platform
                             else imu.mounting.as_dict()),
                "range": {"gyro_rad_s": imu.range_gyro, "accel_m_s2": imu.range_accel},
                **({"accuracy": imu.accuracy()} if name == "fog" else {}),
                **({"platform": platform_metadata(platform)} if name == "mimu" and platform
                   else {})})
        stamp = lambda t: epoch + np.round(t * 1e9).astype(np.int64)      # noqa: E731
        log.write("/mimu/raw", S.RAW_MIMU, "mimu", stamp(t_m), sample_index=raw["sample_index"],
                  gyro_volts=raw["gyro_volts"], accel_volts=raw["accel_volts"],
                  accel_temperature=raw["accel_temperature"],
                  gyro_frequency=raw["gyro_frequency"])
        if fm.platform is not None:
            log.write("/mimu/platform", S.JOINT_STATE, "platform", stamp(t_m),
                      **S.platform_fields(fm.platform["angle"], fm.platform["rate"]))
        log.write("/fog/imu", S.IMU, "fog", stamp(t_f), **S.imu_fields(
            fog_out["angular_velocity"], fog_out["linear_acceleration"]))
        log.write("/truth/state", S.NAV_STATE, "vehicle", stamp(t_base[k_truth]),
                  latitude=tr.lat[k_truth], longitude=tr.lon[k_truth], height=tr.h[k_truth],
                  velocity_ned=tr.v_ned[k_truth],
                  attitude_wxyz=quaternion.as_float_array(tr.q_nb[k_truth]))
    steps.update()
    steps.close()
    write_atomic(truth_path, json.dumps({
        "format": "mimunav-truth/1", "log": str(out), "seed": seed, "profile": profile.name,
        "mimu": unit.as_dict(), "fog": fog.as_dict(),
        "environment": {"ground_temperature_c": ground_temperature_c,
                        "mimu_warm_up_s": warm_up_s,
                        "bay_tau_s": BAY_TAU_S, "lapse_k_per_m": ISA_LAPSE},
        "hidden": hidden.as_dict() if hasattr(hidden, "as_dict") else None,
        "saturated_samples": {"mimu": int(raw["saturated"].sum()),
                              "fog": int(fog_out["saturated"].sum())}}, indent=1) + "\n",
        force=force)
    return str(out), truth_path


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
import tempfile
from dataclasses import dataclass, replace
from datetime import datetime

import numpy as np
from tqdm import tqdm

from ..motion import truth
from ..files import write_atomic
from ..flightlog import LogWriter
from ..flightlog import schemas as S
from .fog import FogUnit
from .mimu import MimuUnit
from ..frames.mounting import Mounting
from .fog import FogRecorder
from .mimu import MimuRecorder
from ..motion.platform import platform_metadata
from .hidden import HiddenPhysics, HiddenSet
from .thermal import BAY_TAU_S, ISA_LAPSE, bay_temperature
from ..errors import InputError
from ..frames import attitude, earth

DEFAULT_EPOCH = "2026-01-01T00:00:00Z"
# Documented default mountings: the FOG-IMU defines the vehicle frame origin; the MIMU sits
# 0.30 m ahead, 0.10 m left and 0.05 m below it, axes aligned with the vehicle.
MIMU_MOUNTING = {"attitude_wxyz": [1.0, 0.0, 0.0, 0.0], "lever_arm_m": [0.30, -0.10, 0.05]}
FOG_MOUNTING = {"attitude_wxyz": [1.0, 0.0, 0.0, 0.0], "lever_arm_m": [0.0, 0.0, 0.0]}
GROUND_TEMPERATURE_C = 15.0     # ISA sea-level temperature, at the profile's start height
MAX_BASE_RATE = 4000
BLOCK_S = 60                # s of flight `simulate_flight` makes at a time (bounded memory)


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
    (`modulation.RotatingMotion`). The whole flight in memory: `flight_motion_blocks` with
    one block."""
    (fm,) = flight_motion_blocks(profile, mimu_mounting, mimu_rate, fog_mounting, fog_rate,
                                 truth_rate, ground_temperature_c, platform, block_s=None)
    return fm


def record_length(profile, rate, imu_rates):
    """Samples of an IMU at `rate` over the profile (`flight_motion_blocks`: the sample at
    0 and one per whole interval of the base rate of both `imu_rates`)."""
    base = math.lcm(*(int(r) for r in imu_rates))
    return int(math.floor(profile.duration * base + 1e-9)) // (base // int(rate)) + 1


def flight_motion_blocks(profile, mimu_mounting, mimu_rate, fog_mounting, fog_rate,
                         truth_rate, ground_temperature_c=GROUND_TEMPERATURE_C, platform=None,
                         block_s=None):
    """`flight_motion` in consecutive pieces of block_s seconds (None: one piece), each a
    FlightMotion of its own samples: the truth at the base rate over [start, end] of the
    piece (the start shared with the previous piece, the position carried from it), the
    IMU samples in (start, end] (the first piece also the sample at 0), the bay temperature
    carried through its lag, and the truth samples to write. Concatenated, the pieces are
    the whole flight (positions to round-off, everything else exactly)."""
    rates = [mimu_rate, fog_rate, truth_rate]
    if any(r != int(r) for r in rates):
        raise InputError(f"sample rates must be whole numbers of Hz, got {rates}")
    base = math.lcm(*(int(r) for r in rates[:2]))
    if base > MAX_BASE_RATE or base % int(truth_rate):
        raise InputError(f"rates {rates} need a common base rate of {base} Hz (at most "
                         f"{MAX_BASE_RATE}, a multiple of the truth rate)")
    motion = profile.motion()
    n_base = int(math.floor(profile.duration * base + 1e-9))
    step = n_base if block_s is None else max(1, int(block_s)) * base   # whole seconds
    rotating = None
    if platform is not None:
        from ..motion.platform import RotatingMotion
        rotating = RotatingMotion(motion, platform, profile.duration)
    k_truth = base // int(truth_rate)
    start, bay = None, None
    # block starts; a remainder shorter than a block joins the last whole one, so that no
    # piece is shorter than one sample interval of either IMU
    starts = list(range(0, max(n_base, 1), step))
    if len(starts) > 1 and n_base % step:
        starts.pop()
    for a, b in zip(starts, starts[1:] + [n_base]):
        t_base = np.arange(a, b + 1) / base
        run = truth.generate(motion, t_base, start)
        tr = run.trajectory
        here, start = start, (tr.lat[-1], tr.lon[-1], tr.h[-1])

        def at_rate(mounting, rate, source=run):
            dth, dv = mounting.sensor_increments(source)
            k = base // int(rate)
            j0, m = a // k, (b - a) // k
            dth = dth[:m * k].reshape(m, k, 3).sum(axis=1)
            dv = dv[:m * k].reshape(m, k, 3).sum(axis=1)
            t = np.arange(j0 + 1, j0 + m + 1) / rate
            if a == 0:              # the sample at 0 repeats the first interval
                return (np.concatenate([[0.0], t]), np.vstack([dth[:1], dth]),
                        np.vstack([dv[:1], dv]))
            return t, dth, dv
        if rotating is None:
            mimu, turning = at_rate(mimu_mounting, mimu_rate), None
        else:
            sensor_run = truth.generate(rotating, t_base, here)       # the IMU on the axis
            mimu = at_rate(_SensorFrame(), mimu_rate, sensor_run)
            turning = {"angle": platform.encoder(rotating.angle(mimu[0]),
                                                 int(round(mimu[0][0] * mimu_rate))),
                       "rate": rotating.rate(mimu[0]),
                       "platform": platform}
        env = bay_temperature(mimu[0], np.interp(mimu[0], t_base, tr.h),
                              ground_temperature_c, motion.h0, before=bay)
        bay = (mimu[0][-1], env[-1])
        first = 0 if a == 0 else 1
        yield FlightMotion(profile, run, t_base, mimu, at_rate(fog_mounting, fog_rate), env,
                           np.arange(first * k_truth, len(t_base), k_truth), turning)


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


def still_rates(mounting, q_nb, lat, h):
    """(w rad/s, f m/s^2; (3,), sensor axes) of an IMU at `mounting` standing still at
    latitude `lat` (rad) and height `h` (m) in the attitude q_nb (body FRD -> NED): the
    Earth's rate and the specific force of rest, w^s = C_sv C_vn w_ie^n and
    f^s = C_sv C_vn (0, 0, -g)."""
    q_sn = np.conjugate(mounting.q_vs) * np.conjugate(q_nb)
    return (attitude.rotate(q_sn, earth.earth_rate_ned(lat)),
            attitude.rotate(q_sn, -earth.gravity_ned(lat, h)))


def still_increments(mounting, q_nb, lat, h, t):
    """`still_rates` as increments (dtheta rad, dv m/s; (N, 3)), one per interval of the
    uniform sample times t (s, (N,))."""
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    w, f = still_rates(mounting, q_nb, lat, h)
    return np.tile(w * dt, (len(t), 1)), np.tile(f * dt, (len(t), 1))


def record_with_preflight(fm, unit, fog, rng_mimu, rng_fog, preflight_s, warm_up_s,
                          hidden=None):
    """`record_flight` with the MIMU's last `preflight_s` seconds of its warm-up recorded
    too, standing still in the flight's first attitude (the launch attitude) in the bay's
    first temperature: (pre-flight raw, flight raw, FOG outputs). One record of the MIMU:
    the pre-flight samples share the flight's turn-on bias, noise and thermal history (the
    unit powered on `warm_up_s` before take-off, `preflight_s` <= `warm_up_s`)."""
    if not 0.0 < preflight_s <= warm_up_s:
        raise InputError(f"a pre-flight span of {preflight_s:g} s needs a warm-up at least "
                         f"as long (warm-up {warm_up_s:g} s)")
    t, dtheta, dv = fm.mimu
    n_pre = int(round(preflight_s * unit.rate_hz))
    t_pre = t[0] - np.arange(n_pre, 0, -1) / unit.rate_hz
    tr = fm.run.trajectory
    dth_pre, dv_pre = still_increments(unit.mounting, tr.q_nb[0], tr.lat[0], tr.h[0], t_pre)
    raw = unit.simulate(np.concatenate([t_pre, t]), np.vstack([dth_pre, dtheta]),
                        np.vstack([dv_pre, dv]), np.concatenate([np.full(n_pre, fm.env[0]),
                                                                 fm.env]),
                        rng_mimu, hidden=hidden, warm_up_s=warm_up_s - preflight_s)
    pre = {k: v[:n_pre] for k, v in raw.items()}
    return pre, {k: v[n_pre:] for k, v in raw.items()}, fog.simulate(*fm.fog, rng_fog)


def truth_file(log):
    """The truth file written beside a simulated log: LOG.mcap -> LOG.truth.json."""
    log = str(log)
    return (log[:-5] if log.endswith(".mcap") else log) + ".truth.json"


def new_outputs(log, force):
    """The truth file's path (`truth_file`) of a log about to be written, both refused when
    they exist unless force."""
    for path in (log, truth_file(log)):
        if os.path.exists(path) and not force:
            raise FileExistsError(f"{path} exists; use --force to replace it")
    return truth_file(log)


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
    truth_path = new_outputs(out, force)
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
    whole = MimuRecorder.needs_whole_record(unit, hidden)
    motion_blocks = flight_motion_blocks(
        profile, unit.mounting, unit.rate_hz, fog.mounting, fog.rate_hz, truth_rate,
        ground_temperature_c, platform, block_s=None if whole else BLOCK_S)
    epoch = epoch_ns(DEFAULT_EPOCH)
    stamp = lambda t: epoch + np.round(t * 1e9).astype(np.int64)         # noqa: E731
    saturated = {"mimu": 0, "fog": 0}
    steps = tqdm(total=round(profile.duration), desc="simulate", disable=not progress,
                 unit="s")
    # flicker noise files beside the output (not a /tmp that may be memory)
    with tempfile.TemporaryDirectory(dir=os.path.dirname(os.path.abspath(out))) as work, \
            LogWriter(out, force=force) as log:
        mimu_rec = fog_rec = None
        for fm in motion_blocks:
            if mimu_rec is None:         # the records' lengths, for their flicker noise
                n_mimu, n_fog = (record_length(profile, r, (unit.rate_hz, fog.rate_hz))
                                 for r in (unit.rate_hz, fog.rate_hz))
                mimu_rec = MimuRecorder(unit, n_mimu, rng_mimu, hidden, warm_up_s, work)
                fog_rec = FogRecorder(fog, n_fog, rng_fog, work)
                _write_metadata(log, profile, fm, unit, fog, platform, epoch)
            raw = mimu_rec.record(*fm.mimu, fm.env)
            _write_raw(log, raw, stamp)
            saturated["mimu"] += int(raw["saturated"].sum())
            if fm.platform is not None:
                log.write("/mimu/platform", S.JOINT_STATE, "platform", stamp(fm.mimu[0]),
                          **S.platform_fields(fm.platform["angle"], fm.platform["rate"]))
            fog_out = fog_rec.record(*fm.fog)
            saturated["fog"] += int(fog_out["saturated"].sum())
            log.write("/fog/imu", S.IMU, "fog", stamp(fm.fog[0]), **S.imu_fields(
                fog_out["angular_velocity"], fog_out["linear_acceleration"]))
            tr, k = fm.run.trajectory, fm.k_truth
            log.write("/truth/state", S.NAV_STATE, "vehicle", stamp(fm.t_base[k]),
                      latitude=tr.lat[k], longitude=tr.lon[k], height=tr.h[k],
                      velocity_ned=tr.v_ned[k], attitude_wxyz=attitude.as_wxyz(tr.q_nb[k]))
            steps.update(round(fm.t_base[-1]) - steps.n)
        raw = mimu_rec.finish()
        _write_raw(log, raw, stamp)
        saturated["mimu"] += int(raw["saturated"].sum())
        del mimu_rec, fog_rec                # their flicker files, before the folder goes
    steps.close()
    write_atomic(truth_path, json.dumps({
        "format": "mimunav-truth/1", "log": str(out), "seed": seed, "profile": profile.name,
        "mimu": unit.as_dict(), "fog": fog.as_dict(),
        "environment": {"ground_temperature_c": ground_temperature_c,
                        "mimu_warm_up_s": warm_up_s,
                        "bay_tau_s": BAY_TAU_S, "lapse_k_per_m": ISA_LAPSE},
        "hidden": hidden.as_dict() if hasattr(hidden, "as_dict") else None,
        "saturated_samples": saturated}, indent=1) + "\n",
        force=force)
    return str(out), truth_path


def _write_metadata(log, profile, fm, unit, fog, platform, epoch):
    start = fm.run.trajectory.state(0)
    initial = replace(start, t=0.0).as_contract()
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


def _write_raw(log, raw, stamp):
    if len(raw["t"]):
        log.write("/mimu/raw", S.RAW_MIMU, "mimu", stamp(raw["t"]),
                  sample_index=raw["sample_index"], gyro_volts=raw["gyro_volts"],
                  accel_volts=raw["accel_volts"], accel_temperature=raw["accel_temperature"],
                  gyro_frequency=raw["gyro_frequency"])


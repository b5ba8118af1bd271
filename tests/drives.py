"""Synthetic land drives the tests of several packages share: tracks (straight with a climb,
one turn, stopping), their ideal IMU written as an imported log, RTK-like fix noise and a
consumer IMU's noise, and the RTKLIB excerpt's place (DRIVE)."""
import math

import numpy as np
import quaternion

from mimunav.frames import attitude, earth
from mimunav.motion import truth
from mimunav.importers.recording import Recording
from mimunav.importers.write import write_log
from mimunav.frames.mounting import Mounting
from mimunav.motion.vehicle import TrackMotion
from places import DATA


DRIVE = DATA / "rtklib-drive"
DEG = math.pi / 180
LAT0, LON0, H0 = 40.1 * DEG, -105.1 * DEG, 1600.0


# ---- a synthetic drive: rest, then a winding road with a climb --------------------------
def smoothstep(x):
    """0 before 0, 1 after 1, C2 between (the quintic smoothstep)."""
    x = np.clip(x, 0.0, 1.0)
    return x ** 3 * (10 - 15 * x + 6 * x ** 2)


def track_from_velocity(t, v):
    """(t, lat, lon, h, v_ned) of a track from LAT0, LON0, H0 with NED velocity v (m/s),
    positions by the trapezoid rule (flat over the drive's few km)."""
    d = np.vstack([np.zeros(3), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None], axis=0)])
    r_n, r_e = earth.radii(LAT0)
    return t, LAT0 + d[:, 0] / (r_n + H0), LON0 + d[:, 1] / ((r_e + H0) * math.cos(LAT0)), \
        H0 - d[:, 2], v


def straight_track(duration=120.0, rate=4.0):
    """A GNSS-like track (t, lat, lon, h, v_ned): 20 s at rest, a 5 s smooth start to 10 m/s
    heading 30 deg, then weaving smoothly from t = 30 s (yaw 30-50 deg, 0.05 Hz) and climbing
    2 %."""
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    speed = 10.0 * smoothstep((t - 20.0) / 5.0)
    yaw = 30 * DEG + 10 * DEG * (1 - np.cos(2 * math.pi * 0.05 * np.maximum(t - 30.0, 0.0)))
    v = np.column_stack([speed * np.cos(yaw), speed * np.sin(yaw), -0.02 * speed])
    return track_from_velocity(t, v)


def one_turn_track(edge_s, rate=10.0, duration=120.0):
    """A drive that turns once: the synthetic drive's start, then straight but for 10 deg/s
    of yaw over 60-69 s, its yaw-rate edges smoothsteps of edge_s seconds (track as `straight_track`,
    level)."""
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    speed = 10.0 * smoothstep((t - 20.0) / 5.0)
    fine = np.arange(0.0, duration + 1e-9, 1e-3)
    yaw_rate = 10 * DEG * (smoothstep((fine - 60.0) / edge_s) -
                           smoothstep((fine - 69.0) / edge_s))
    yaw = np.interp(t, fine, 30 * DEG + np.concatenate(
        [[0.0], np.cumsum(0.5 * (yaw_rate[1:] + yaw_rate[:-1]) * 1e-3)]))
    v = np.column_stack([speed * np.cos(yaw), speed * np.sin(yaw), np.zeros_like(t)])
    return track_from_velocity(t, v)


def ideal_flight(tmp_path, mounting, **drive):
    """A log of `ideal_recording(mounting, **drive)`: (its path, motion, truth run)."""
    rec, motion, run = ideal_recording(mounting, **drive)
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / "synthetic.mcap"
    write_log(rec, path)
    return path, motion, run


def ideal_recording(mounting, gyro_bias=np.zeros(3), rate=100.0, lag=0.0, track=None,
                    with_attitude=False, accel_bias=np.zeros(3), reference_every=1):
    """(Recording, motion, truth run) of the synthetic drive (or `track`): the ideal IMU of
    its TrackMotion (exact increments, interval means) at `mounting` plus a gyro bias,
    stamped `lag` s late; every `reference_every`-th epoch of the track as /truth/state (with
    the motion's attitude when with_attitude)."""
    t_tr, lat, lon, h, v = straight_track() if track is None else track
    motion = TrackMotion(t_tr, lat, lon, h, v)
    t = np.arange(t_tr[0], t_tr[-1] + 1e-9, 1.0 / rate)
    t_tr, lat, lon, h, v = (x[::reference_every] for x in (t_tr, lat, lon, h, v))
    run = truth.generate(motion, t)
    dth, dv = mounting.sensor_increments(run)
    w, f = dth * rate + gyro_bias, dv * rate + accel_bias
    epoch = 1_700_000_000_000_000_000
    reference = dict(ns=epoch + np.round(t_tr * 1e9).astype(np.int64), lat=lat, lon=lon, h=h,
                     v_ned=v)
    if with_attitude:
        reference["q_nb"] = quaternion.as_float_array(motion.kinematics(t_tr).q_nb)
    rec = Recording("synthetic", "synthetic drive",
                    epoch + np.round((t[1:] + lag) * 1e9).astype(np.int64),
                    w, f, mounting, reference=reference)
    return rec, motion, run


MOUNT = Mounting.from_rpy_deg((180.0, 0.0, 180.0))


def under_two_cm(track, seed=5, sigma_m=0.02, sigma_h_m=0.0):
    """`track` (t, lat, lon, h, v_ned) as an RTK receiver gives it: horizontal positions with
    sigma_m of white noise per axis (the height with sigma_h_m), velocity by central
    differences of them (`velocity_from_positions`, the importers' own), the end epochs
    without one dropped."""
    from mimunav.motion.track import velocity_from_positions
    t, lat, lon, h, _ = track
    rng = np.random.default_rng(seed)
    r_n, r_e = earth.radii(LAT0)
    lat = lat + rng.normal(0.0, sigma_m, len(t)) / (r_n + H0)
    lon = lon + rng.normal(0.0, sigma_m, len(t)) / ((r_e + H0) * math.cos(LAT0))
    if sigma_h_m:
        h = h + rng.normal(0.0, sigma_h_m, len(t))
    v = velocity_from_positions(np.round(t * 1e9).astype(np.int64), lat, lon, h)
    ok = np.isfinite(v).all(axis=1)
    return t[ok], lat[ok], lon[ok], h[ok], v[ok]


def stop_track(rate=4.0):
    """Driving at 10 m/s heading 30 deg, a smooth stop at 20-25 s, 20 s at rest, a smooth
    start at 45-50 s and on to 80 s."""
    t = np.arange(0.0, 80.0 + 1e-9, 1.0 / rate)
    speed = 10.0 * (1 - smoothstep((t - 20.0) / 5.0) + smoothstep((t - 45.0) / 5.0))
    yaw = np.full_like(t, 30 * DEG)
    v = np.column_stack([speed * np.cos(yaw), speed * np.sin(yaw), np.zeros_like(t)])
    return track_from_velocity(t, v)


def with_consumer_noise(flight, seed):
    """The flight's recorded (w, f) with the track level's consumer part's white noise at
    the drive's 100 Hz."""
    from mimunav.diagnosis.track_reference import (CONSUMER_NOISE)
    rng = np.random.default_rng(seed)
    w, f = flight.mimu_imu
    per_sample = math.sqrt(100.0)                   # white density -> sigma at 100 Hz
    return (w + rng.normal(0, CONSUMER_NOISE['gyro_white'] * per_sample, w.shape),
            f + rng.normal(0, CONSUMER_NOISE['accel_white'] * per_sample, f.shape))


def under_a_noisy_fix(track, rng, gyro_bias=np.zeros(3)):
    """A Recording of `track`'s ideal IMU at 100 Hz (MOUNT) with a consumer part's noise
    and a gyro bias, its reference a plain 1 Hz fix with 1.5 m of position noise and the
    velocity by differences (about 1-2 m/s of noise)."""
    from mimunav.motion.track import velocity_from_positions
    t_tr, lat, lon, h, v = track
    t = np.arange(t_tr[0], t_tr[-1] + 1e-9, 0.01)
    dth, dv = MOUNT.sensor_increments(truth.generate(TrackMotion(t_tr, lat, lon, h, v), t))
    w = dth * 100.0 + gyro_bias + rng.normal(0, 0.005, dth.shape)
    f = dv * 100.0 + rng.normal(0, 0.02, dv.shape)
    k = slice(0, None, 4)                                       # 4 Hz -> 1 Hz
    r_n, r_e = earth.radii(LAT0)
    lat_n = lat[k] + rng.normal(0, 1.5, len(lat[k])) / (r_n + H0)
    lon_n = lon[k] + rng.normal(0, 1.5, len(lon[k])) / ((r_e + H0) * math.cos(LAT0))
    epoch = 1_700_000_000_000_000_000
    ns = epoch + np.round(t_tr[k] * 1e9).astype(np.int64)
    return Recording("noisy", "", epoch + np.round(t[1:] * 1e9).astype(np.int64), w, f, MOUNT,
                     reference=dict(ns=ns, lat=lat_n, lon=lon_n, h=h[k],
                                    v_ned=velocity_from_positions(ns, lat_n, lon_n, h[k])))


class FacingMotion(TrackMotion):
    """`TrackMotion` of a vehicle that faces heading_deg whichever way it moves along it (a
    car backing out: its course heading_deg + 180); its body rates turned with it."""
    heading_deg = 30.0

    def kinematics(self, t):
        from mimunav.motion.truth import Kinematics
        kin = super().kinematics(t)
        back = np.cos(attitude.as_euler(kin.q_nb)[0] - math.radians(self.heading_deg)) < 0
        q = kin.q_nb.copy()
        q[back] = q[back] * quaternion.from_rotation_vector([0.0, 0.0, math.pi])
        flip = np.where(back[:, None], [-1.0, -1.0, 1.0], 1.0)
        return Kinematics(kin.v_ned, kin.a_ned, q, kin.w_nb_b * flip, kin.dw_nb_b * flip)

"""Replay of a flight log and the seed paper's normalised end-point error table.

Replay: the MIMU raw channel is compensated with a calibration (eqs. 1-4), the MIMU and the
FOG-IMU are navigated by the same strapdown navigator from the log's `initial_state`, each at
its own mounting: increments are rotated from sensor to vehicle axes (q_vs) and navigated from
the initial state moved to the sensor's place (position + C_nb r, velocity + C_nb (w_nb x r));
the solution is moved back to the vehicle origin (- C_nb r, - C_nb (w_nb x r)) before any
comparison. Samples stamped after `initial_state.t` are navigated; each stands for the mean
over the interval ending at its stamp (log contract).

Table (seed S1 Table 3): end-point east, north and up position errors of every calibration
variant against the reference trajectory, each divided by the FOG-IMU's error in the same
axis (|e_MIMU| / |e_FOG|, FOG = 1). Without a truth channel the FOG is the reference and the
table gives MIMU-vs-FOG differences in metres (no normalisation is possible).
"""
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import quaternion

from . import attitude, earth, strapdown
from .compensation import (BLOCK, CLIP_RUN, SATURATED, Calibration, CalibrationError,
                           compensate, compensated_blocks, flag_counts, poly2)
from .effects import Conditions
from .effects import apply as apply_effects
from .flightlog import FlightLog, LogError
from .sensors import Mounting
from .trajectory import Trajectory
from .errors import InputError


RAW_FIELDS = ("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency")


@dataclass
class Flight:
    """What a replay needs from a log (times in s since the log's epoch)."""
    path: str
    name: str
    epoch_ns: int                   # epoch_unix_ns of the flight metadata
    initial: dict                   # strapdown initial state (t, lat, lon, h, v_ned, q_nb)
    mimu_t: np.ndarray
    mimu_raw: dict | None           # accel_volts, gyro_volts, accel_temperature, gyro_frequency
                                    # (None: a log with the compensated /mimu/imu only)
    mimu_mounting: Mounting
    mimu_range: dict
    fog_t: np.ndarray | None        # None: a log without the reference IMU
    fog_w: np.ndarray | None        # rad/s, sensor axes
    fog_f: np.ndarray | None        # m/s^2, sensor axes
    fog_mounting: Mounting
    truth: Trajectory | None
    mimu_imu: tuple | None = None   # (w rad/s, f m/s^2) of /mimu/imu when there is no raw
    fog_meta: dict | None = None    # the log's `sensor/fog` metadata (model, accuracy, ...)
    source: str = ""                # the flight metadata's source: "simulation", "recording"
    reference_meta: dict | None = None  # the log's `reference` metadata (a recording's)
    mimu_platform: dict | None = None   # a rotating MIMU: {"t" s, "angle" rad, "rate" rad/s, "meta"}
    stream_block: int | None = None     # streamed: the MIMU raw outputs and the reference
                                        # IMU are read from the log in blocks of this many
                                        # samples when navigated (mimu_raw, fog_w, fog_f None;
                                        # the stamps are held)
    fog_seconds: object = None          # SecondMeans of the reference IMU (f, w), when known

    @classmethod
    def load(cls, path, reference_imu=True, max_gap_s=None, stream=False):
        """The flight of the log at `path`; with reference_imu=False a log without
        /fog/imu is accepted too (then fog_t, fog_w, fog_f are None). The MIMU comes from
        /mimu/raw, or when the log has none (an imported recording) from the already
        compensated /mimu/imu, which a calibration then leaves as it is.

        stream: for a log of more than STREAM_ABOVE MIMU samples, hold only the stamps of
        /mimu/raw and /fog/imu (16 bytes a sample pair) and read their values block by block
        when `replay` / `navigate_fog` need them, so a flight of any length navigates in
        bounded memory; a shorter log is held whole (faster: one read instead of four). A
        log recorded as /mimu/imu, or whose stamps go back in time (read whole and sorted),
        is held whole too."""
        with FlightLog(path) as log:
            meta = log.metadata()
            flight = meta.get("flight", {})
            schemas = {log.summary.schemas[c.schema_id].name for c in log.channels.values()}
            if not flight and {"/mimu/raw", "/mimu/imu"} & set(log.channels):
                raise LogError(f"{path}: the log contract's channels but no `flight` metadata "
                               "(section 1), so nothing places the navigation start: a log "
                               "whose writer put its metadata at the end keeps none once cut "
                               "short (`mimunav info LOG --recover` saves only what is intact)")
            if not flight and "sensor_msgs/msg/Imu" in schemas:
                raise LogError(f"{path}: a ROS 2 recording, not a mimunav log (no `flight` "
                               "metadata): `mimunav import ros2 FILE -o LOG.mcap` makes one")
            for key in ("epoch_unix_ns", "initial_state"):
                if key not in flight:
                    raise LogError(f"{path}: the `flight` metadata lacks {key!r} (log contract "
                                   "section 1): cannot place the navigation start")
            mimu_topic = "/mimu/imu" if "/mimu/raw" not in log.channels and \
                "/mimu/imu" in log.channels else "/mimu/raw"
            needed = (mimu_topic, "/fog/imu") if reference_imu else (mimu_topic,)
            for topic in needed:
                if topic not in log.channels:
                    what = "the MIMU's outputs" if topic == mimu_topic else \
                        "the FOG-IMU flown with the MIMU (the reference IMU)"
                    raise LogError(f"{path}: no {topic} channel, which holds {what} (channels: "
                                   f"{', '.join(sorted(log.channels))})")
            epoch = int(flight["epoch_unix_ns"])
            long_log = mimu_topic == "/mimu/raw" and (log.count("/mimu/raw") or 0) > STREAM_ABOVE
            streamed = _streamed(log, path, epoch, reference_imu) if stream and long_log else None
            if streamed:
                raw, imu, fog = streamed["mimu"], None, streamed["fog"]
            elif mimu_topic == "/mimu/raw":
                raw = log.read("/mimu/raw", fields=RAW_FIELDS)
                imu = None
            else:
                raw = log.read("/mimu/imu", fields=("angular_velocity", "linear_acceleration"))
                imu = tuple(np.ascontiguousarray(raw[k], float)
                            for k in ("angular_velocity", "linear_acceleration"))
            if not streamed:
                fog = (log.read("/fog/imu", fields=("angular_velocity", "linear_acceleration"))
                       if "/fog/imu" in log.channels else None)
            truth = log.read("/truth/state") if "/truth/state" in log.channels else None
            joint = (log.read("/mimu/platform", fields=("position", "velocity"))
                     if "/mimu/platform" in log.channels else None)
            platform_meta = meta.get("sensor/mimu", {}).get("platform")
            if (joint is None) != (platform_meta is None):
                raise LogError(f"{path}: a rotating MIMU needs both /mimu/platform and the "
                               "`platform` object of the sensor/mimu metadata (README: "
                               "rotating MIMUs); the log has only one of them")
        sec = lambda m: (m["log_time"].astype(np.int64) - epoch) / 1e9      # noqa: E731
        init = flight["initial_state"]
        initial = {"t": float(init["t"]), "lat": init["latitude"], "lon": init["longitude"],
                   "h": init["height"], "v_ned": np.asarray(init["velocity_ned"], float),
                   "q_nb": np.asarray(init["attitude_wxyz"], float)}
        mount = lambda name: Mounting.from_dict(                                # noqa: E731
            meta.get(f"sensor/{name}", {}).get("mounting", {}))
        truth_traj = None
        if truth is not None and len(truth):
            truth_traj = Trajectory(sec(truth), truth["latitude"].copy(), truth["longitude"].copy(),
                                    truth["height"].copy(), truth["velocity_ned"].copy(),
                                    quaternion.from_float_array(truth["attitude_wxyz"]))
        values = lambda msgs, name: (None if streamed else                    # noqa: E731
                                     np.ascontiguousarray(msgs[name], float))
        loaded = cls(str(path), flight.get("name", ""), epoch, initial, sec(raw),
                     None if imu or streamed else {k: values(raw, k) for k in RAW_FIELDS},
                     mount("mimu"), meta.get("sensor/mimu", {}).get("range", {}),
                     *((sec(fog), values(fog, "angular_velocity"),
                        values(fog, "linear_acceleration"))
                       if fog is not None else (None, None, None)), mount("fog"), truth_traj,
                     imu, meta.get("sensor/fog", {}), str(flight.get("source", "")),
                     meta.get("reference", {}),
                     None if joint is None else _platform(sec(joint), joint, platform_meta),
                     STREAM_BLOCK if streamed else None,
                     streamed["fog_seconds"] if streamed else None)
        check_plausible(loaded, MAX_GAP_S if max_gap_s is None else max_gap_s,
                        streamed["fog_sample"] if streamed else None)
        return loaded

    @classmethod
    def from_simulation(cls, fm, unit, fog, raw, fog_out):
        """The same Flight a log of this simulation gives (`simulation.simulate_flight`),
        built in memory: for campaigns that need no files."""
        tr, k = fm.run.trajectory, fm.k_truth
        start = tr.state(0)
        initial = {"t": 0.0, "lat": start["lat"], "lon": start["lon"], "h": start["h"],
                   "v_ned": start["v_ned"], "q_nb": start["q_nb"]}
        truth = Trajectory(fm.t_base[k], tr.lat[k], tr.lon[k], tr.h[k], tr.v_ned[k], tr.q_nb[k])
        return cls("(in memory)", fm.profile.name, 0, initial, fm.mimu[0],
                   {key: raw[key] for key in RAW_FIELDS},
                   unit.mounting, {"accel_m_s2": unit.range_accel, "gyro_rad_s": unit.range_gyro},
                   fm.fog[0], fog_out["angular_velocity"], fog_out["linear_acceleration"],
                   fog.mounting, truth, fog_meta={"accuracy": fog.accuracy()})

    def mimu_blocks(self, cal):
        """The MIMU through `cal` (`compensated_mimu`) in time-ordered blocks of
        (t s, w rad/s, f m/s^2, flags), sensor axes: one block when the flight is held, of
        stream_block samples (`compensation.compensated_blocks`) when it streams."""
        if self.stream_block is None:
            yield (self.mimu_t, *_compensated_whole(self, cal))
            return
        with FlightLog(self.path) as log:
            for raw, f, w, flags in compensated_blocks(log, cal, self.stream_block):
                yield self._seconds(raw), w, f, flags

    def fog_blocks(self):
        """The reference IMU in time-ordered blocks of (t s, w rad/s, f m/s^2)."""
        if self.stream_block is None:
            yield self.fog_t, self.fog_w, self.fog_f
            return
        with FlightLog(self.path) as log:
            for msgs in log.blocks("/fog/imu", self.stream_block, FOG_FIELDS):
                yield (self._seconds(msgs), *(np.ascontiguousarray(msgs[k], float)
                                              for k in FOG_FIELDS))

    def fog_second_means(self):
        """((f, w) 1 s means of the reference IMU, their seconds) (`SecondMeans`)."""
        if self.fog_seconds is None:
            self.fog_seconds = SecondMeans().add(self.fog_t, self.fog_f, self.fog_w)
        return self.fog_seconds.means()

    def _seconds(self, msgs):
        return (msgs["log_time"].astype(np.int64) - self.epoch_ns) / 1e9

    def mimu_temperatures(self):
        """(accelerometer case temperatures degC, gyro resonance frequencies Hz), (N, 3)
        each; NaN for a MIMU recorded without them (/mimu/imu only)."""
        if self.mimu_raw is None:
            nan = np.full((len(self.mimu_t), 3), np.nan)
            return nan, nan
        return self.mimu_raw["accel_temperature"], self.mimu_raw["gyro_frequency"]

    @property
    def end(self):
        """Last instant every navigated channel (and the truth) covers, s."""
        ends = [self.mimu_t[-1]] + ([self.fog_t[-1]] if self.fog_t is not None else []) \
            + ([self.truth.t[-1]] if self.truth else [])
        return float(min(ends))


MAX_GAP_S = 0.5            # s of missing MIMU samples navigation will not bridge
STREAM_BLOCK = BLOCK       # samples a streamed flight reads at a time (`Flight.load`)
STREAM_ABOVE = 4 * BLOCK   # MIMU samples above which `Flight.load(stream=True)` streams
                           # (~1 M: held whole, such a log needs ~0.6 GB)
FOG_FIELDS = ("angular_velocity", "linear_acceleration")
FOG_SAMPLE = 200_000       # reference-IMU samples the units check of a streamed flight takes


def _streamed(log, path, epoch, reference_imu):
    """One pass over /mimu/raw's stamps and /fog/imu of a log for `Flight.load(stream=True)`:
    {"mimu": stamps, "fog": stamps or None, "fog_seconds": SecondMeans, "fog_sample": (w, f)
    every k-th sample for the units check}; None when a channel's stamps go back in time
    (the flight is then read whole and sorted). A non-finite reference sample is a LogError
    here, since the check sees only the sample."""
    from .flightlog.reader import TimeOrderError
    try:
        mimu = np.concatenate(list(log.blocks("/mimu/raw", STREAM_BLOCK, fields=())))
        if "/fog/imu" not in log.channels:
            return {"mimu": mimu, "fog": None, "fog_seconds": None, "fog_sample": None}
        stamps, seconds, sample = [], SecondMeans(), []
        step = max(1, (log.count("/fog/imu") or 0) // FOG_SAMPLE)
        for msgs in log.blocks("/fog/imu", STREAM_BLOCK, FOG_FIELDS):
            t = (msgs["log_time"].astype(np.int64) - epoch) / 1e9
            w, f = (np.ascontiguousarray(msgs[k], float) for k in FOG_FIELDS)
            bad = ~(np.isfinite(w).all(axis=1) & np.isfinite(f).all(axis=1))
            if bad.any():
                raise LogError(f"{path}: /fog/imu is not finite at t = "
                               f"{t[np.argmax(bad)]:.3f} s")
            stamps.append(msgs[["log_time"]].copy())
            seconds.add(t, f, w)
            sample.append((w[::step], f[::step]))
    except TimeOrderError:
        return None
    return {"mimu": mimu, "fog": np.concatenate(stamps), "fog_seconds": seconds,
            "fog_sample": tuple(np.concatenate(x) for x in zip(*sample))}


def refuse_gaps(flight, max_gap_s=MAX_GAP_S, warn_shorter=False):
    """LogError when the MIMU misses samples for longer than max_gap_s (s) anywhere: the
    navigation would bridge the gap with one sample. With warn_shorter, the shorter gaps are
    reported on stderr."""
    from .errors import warn
    from .flightlog.inspect import missing_samples
    t = flight.mimu_t
    if len(t) <= 10:
        return
    gaps = missing_samples(np.round(t * 1e9).astype(np.int64))
    if not gaps:
        return
    k, n = max(gaps, key=lambda g: t[g[0] + 1] - t[g[0]])
    if t[k + 1] - t[k] > max_gap_s:
        raise LogError(f"{flight.path}: the MIMU misses {n} samples between t = {t[k]:.3f} "
                       f"and {t[k + 1]:.3f} s ({sum(m for _, m in gaps)} in all): "
                       f"navigation would bridge {t[k + 1] - t[k]:.3g} s with one "
                       "sample; cut the log at the gap")
    if warn_shorter:
        warn(f"{flight.path}: the MIMU misses {sum(m for _, m in gaps)} samples in "
             f"{len(gaps)} gaps (longest {t[k + 1] - t[k]:.3g} s at t = {t[k]:.3f} s)")


def check_plausible(flight, max_gap_s=None, fog_sample=None):
    """Refuse a log whose numbers cannot be what the contract says (LogError naming the
    channel, the time and the likely cause); warn (stderr) about missing samples shorter
    than max_gap_s (default MAX_GAP_S; a command that does not navigate across gaps, such as
    `windows`, passes inf). Checks: stamps increase; MIMU gaps; the initial state inside the MIMU's
    span; the truth finite, latitude in rad, its span overlapping the MIMU's; the reference
    IMU finite, its specific force near 1 g (not in g), its rates of the truth's attitude
    rate's size (not deg/s); of a streamed flight, on `fog_sample` (w, f)."""
    where = flight.path
    for name, t in (("MIMU", flight.mimu_t), ("/fog/imu", flight.fog_t),
                    ("/truth/state", None if flight.truth is None else flight.truth.t)):
        if t is None or len(t) < 2:
            continue
        step = np.diff(t)
        if np.any(step <= 0):
            k = int(np.argmax(step <= 0))
            raise LogError(f"{where}: {name} stamps do not increase at t = {t[k + 1]:.6f} s "
                           f"({'a duplicate' if step[k] == 0 else 'backwards'}): the log is "
                           "not a time series the navigator can integrate")
    t = flight.mimu_t
    refuse_gaps(flight, MAX_GAP_S if max_gap_s is None else max_gap_s, warn_shorter=True)
    if not t[0] - 1e-6 <= flight.initial["t"] <= t[-1]:
        raise LogError(f"{where}: the initial state's t = {flight.initial['t']:.3f} s lies "
                       f"outside the MIMU's stamps {t[0]:.3f} .. {t[-1]:.3f} s (epoch_unix_ns "
                       "or the stamps' time base off?)")
    tr = flight.truth
    if tr is not None:
        state = np.column_stack([tr.lat, tr.lon, tr.h, tr.v_ned])
        if not np.isfinite(state).all():
            k = int(np.argmax(~np.isfinite(state).all(axis=1)))
            raise LogError(f"{where}: /truth/state is not finite at t = {tr.t[k]:.3f} s")
        if np.abs(tr.lat).max() > np.pi / 2 or np.abs(tr.lon).max() > 2 * np.pi:
            raise LogError(f"{where}: /truth/state latitude/longitude up to "
                           f"{np.abs(tr.lat).max():.4g} / {np.abs(tr.lon).max():.4g}: the "
                           "contract stores rad (degrees written?)")
        overlap = min(tr.t[-1], t[-1]) - max(tr.t[0], t[0])
        if overlap <= 0:
            raise LogError(f"{where}: /truth/state ({tr.t[0]:.1f} .. {tr.t[-1]:.1f} s) and the "
                           f"MIMU ({t[0]:.1f} .. {t[-1]:.1f} s) do not overlap: their time "
                           "bases differ")
    if flight.fog_t is not None and len(flight.fog_t) > 10:
        _check_reference_units(flight, *(fog_sample or (flight.fog_w, flight.fog_f)))


def _check_reference_units(flight, w, f):
    """The reference IMU's specific force near 1 g and rates of the truth's size."""
    if not (np.isfinite(w).all() and np.isfinite(f).all()):
        k = int(np.argmax(~(np.isfinite(w).all(axis=1) & np.isfinite(f).all(axis=1))))
        raise LogError(f"{flight.path}: /fog/imu is not finite at t = {flight.fog_t[k]:.3f} s")
    g = float(np.median(np.linalg.norm(f, axis=1)))
    if not 2.0 < g < 100.0:
        raise LogError(f"{flight.path}: /fog/imu specific force has median magnitude {g:.3g}: "
                       "the contract's m/s^2 gives about 9.8 on Earth (in g?)")
    tr = flight.truth
    if tr is None or len(tr.t) < 10 or not np.isfinite(quaternion.as_float_array(tr.q_nb)).all():
        return
    rate = attitude.turn_rate(tr.t, tr.q_nb)
    truth_rate, fog_rate = np.percentile(rate, 99), np.percentile(np.linalg.norm(w, axis=1), 99)
    if truth_rate > 0.05 and not 0.2 < fog_rate / truth_rate < 5:
        raise LogError(f"{flight.path}: /fog/imu rates reach {fog_rate:.3g}, the truth's "
                       f"attitude turns at up to {truth_rate:.3g} rad/s: the contract's rad/s "
                       f"differs by {fog_rate / truth_rate:.3g}x (deg/s?)")


def navigate(t, w, f, mounting, initial):
    """Navigate sensor-axis rates w (rad/s) and specific forces f (m/s^2), interval means at
    stamps t (s), from the vehicle's initial state; returns the vehicle-origin Trajectory
    at [initial t, t after it] (`VehicleNavigator` over one block)."""
    nav = VehicleNavigator(mounting, initial)
    return Trajectory.concatenate([nav.feed(t, w, f), nav.finish()])


class VehicleNavigator:
    """`navigate` block by block, for a flight of any length in bounded memory: `feed`
    sensor-axis interval means (t s, w rad/s, f m/s^2) in time order and get the
    vehicle-origin states settled so far; `finish` returns the last one. The states equal
    those of one `navigate` over the whole record: the strapdown memory is carried
    (`strapdown.Navigator`), and a state's lever-arm velocity, which takes the mean body rate
    of the intervals on both sides of it, waits for the next block's first sample.

    On a rotating platform (`platform`: the Flight's mimu_platform; its axis through the
    vehicle origin, the IMU at the metadata's lever_arm_m from it in platform axes) the
    sensor frame itself is navigated at the IMU's point, the vehicle attitude
    q_nb = q_ns q_bs(theta)^-1 comes from the recorded platform angle (`modulation`), and
    the point's lever arm r = C_bp0 Rz(theta) r_p turns with it (its velocity theta' a x r,
    a the axis in vehicle axes, from the recorded rate).
    whole_record: False when the blocks are pieces of a longer record (`strapdown.Navigator`)."""

    def __init__(self, mounting, initial, platform=None, whole_record=True):
        self.initial, self.platform, self.whole_record = initial, platform, whole_record
        self.q_vs, self.r = mounting.q_vs, mounting.lever_arm_m
        if platform is not None:
            self.q_vs, self.r = Mounting().q_vs, np.zeros(3)
            self.r_p = np.asarray(platform["meta"].get("lever_arm_m", [0.0] * 3), float)
            self.q_bp0 = quaternion.from_float_array(platform["meta"]["base_attitude_wxyz"])
        self.nav, self.pending, self.count = None, None, 0

    def feed(self, t, w, f):
        """The states settled by the samples stamped after the initial state's time."""
        after = t > self.initial["t"] + 1e-12
        t, w, f = t[after], w[after], f[after]
        if not len(t):
            return None
        w_v, f_v = attitude.rotate(self.q_vs, w), attitude.rotate(self.q_vs, f)
        if self.nav is None:
            self.nav = strapdown.Navigator(self._start(w_v[:1]),
                                           whole_record=self.whole_record)
            self.pending = (self.nav.state(), w_v[:1])      # the start: its first interval
        dt = np.diff(t, prepend=self.nav.t)
        self.count += len(t)
        held, w_held = self.pending
        states = self.nav.step(t, w_v * dt[:, None], f_v * dt[:, None], before=held)
        self.pending = (states[-1:], w_v[-1:])
        before = np.vstack([w_held, w_v[:-1]])        # the interval ending at each state
        return self._vehicle(states[:-1], 0.5 * (before + w_v))

    def finish(self):
        """The last state (its body rate: the last interval's)."""
        if self.count < 2:
            raise InputError("fewer than two samples after the initial state's time")
        held, w_held = self.pending
        return self._vehicle(held, w_held)

    def _start(self, w_v0):
        """The initial state moved to the sensor's place (position + C_nb r, velocity +
        C_nb (w_nb x r)); on a platform that of the turning IMU, in the sensor frame."""
        if self.platform is not None:
            return self._platform_start(w_v0)
        start, r = dict(self.initial), self.r
        if np.any(r):
            q0 = quaternion.from_float_array(np.asarray(self.initial["q_nb"], float))
            w_nb0 = _body_rate(w_v0, q0, self.initial)[0]
            start["lat"], start["lon"], start["h"] = _moved(
                self.initial["lat"], self.initial["lon"], self.initial["h"],
                attitude.rotate(q0, r))
            start["v_ned"] = self.initial["v_ned"] + attitude.rotate(q0, np.cross(w_nb0, r))
        return start

    def _vehicle(self, nav, w_at):
        """Sensor-place states back to the vehicle origin (- C_nb r, - C_nb (w_nb x r)),
        w_at the body rate at each state (rad/s, vehicle axes); on a platform the vehicle
        attitude."""
        if self.platform is not None:
            return self._platform_vehicle(nav, w_at)
        r = self.r
        if not np.any(r):
            return nav
        w_nb = _body_rate(w_at, nav.q_nb, self.initial)
        d_ned = attitude.rotate(nav.q_nb, np.broadcast_to(-r, (len(nav), 3)))
        lat, lon, h = _moved(nav.lat, nav.lon, nav.h, d_ned)
        v = nav.v_ned - attitude.rotate(nav.q_nb, np.cross(w_nb, r))
        return Trajectory(nav.t, lat, lon, h, v, nav.q_nb)

    def _turning(self, t, q_nb, w_s):
        """(q_bs, the IMU point's lever arm r and d_ned = C_nb r, its velocity relative to
        the vehicle origin C_nb (w_nb x r + r')) at times t for a vehicle attitude q_nb and
        the sensor's rate w_s (rad/s, sensor axes, w_ib)."""
        from .modulation import _rz, q_bs_recorded
        p = self.platform
        angle = np.interp(t, p["t"], p["angle"])
        q_bs = q_bs_recorded(p["meta"], angle)
        if not np.any(self.r_p):
            return q_bs, np.zeros((len(t), 3)), np.zeros((len(t), 3))
        axis = attitude.rotate(self.q_bp0, np.array([0.0, 0.0, 1.0]))
        rate = np.interp(t, p["t"], p["rate"])[:, None]
        r = attitude.rotate(self.q_bp0 * _rz(angle), np.broadcast_to(self.r_p, (len(t), 3)))
        # w_nb^b = C_bs w_ib^s - theta' a - C_bn w_ie^n
        w_nb = _body_rate(attitude.rotate(q_bs, w_s) - rate * axis, q_nb, self.initial)
        return (q_bs, attitude.rotate(q_nb, r),
                attitude.rotate(q_nb, np.cross(w_nb, r) + rate * np.cross(axis, r)))

    def _platform_start(self, w_s0):
        from .modulation import q_bs_recorded
        start = dict(self.initial)
        q_nb = quaternion.from_float_array(np.asarray(start["q_nb"], float))
        t0 = np.array([float(start["t"])])
        q_bs, d_ned, v_rel = self._turning(t0, np.atleast_1d(q_nb), w_s0)
        start["q_nb"] = quaternion.as_float_array(q_nb * q_bs_recorded(
            self.platform["meta"], np.interp(t0, self.platform["t"], self.platform["angle"]))[0])
        if np.any(d_ned):
            start["lat"], start["lon"], start["h"] = _moved(
                start["lat"], start["lon"], start["h"], d_ned[0])
            start["v_ned"] = np.asarray(start["v_ned"], float) + v_rel[0]
        return start

    def _platform_vehicle(self, nav, w_s):
        """Sensor-frame states at the turning IMU's point -> the vehicle origin's."""
        from .modulation import q_bs_recorded, vehicle_attitude
        angle = np.interp(nav.t, self.platform["t"], self.platform["angle"])
        q_nb = vehicle_attitude(nav.q_nb, q_bs_recorded(self.platform["meta"], angle))
        _, d_ned, v_rel = self._turning(nav.t, q_nb, w_s)
        if not np.any(d_ned):
            return Trajectory(nav.t, nav.lat, nav.lon, nav.h, nav.v_ned, q_nb)
        lat, lon, h = _moved(nav.lat, nav.lon, nav.h, -d_ned)
        return Trajectory(nav.t, lat, lon, h, nav.v_ned - v_rel, q_nb)


def no_reference(path, what):
    """The InputError for `what` on a log without /truth/state, saying how its GNSS fixes
    could serve as one when it has /gnss/fix."""
    with FlightLog(path) as log:
        fixes = "/gnss/fix" in log.channels
    hint = ("; its /gnss/fix can serve when the import takes it as the reference: ros2 "
            "--reference-status 2 (RTK grade), rtklib --solutions, dataflash --reference gnss, "
            "table a [reference] section" if fixes else "")
    return InputError(f"{path}: no reference trajectory (/truth/state) for {what}{hint}")


def _platform(t, joint, meta):
    """A Flight's mimu_platform: {"t" s, "angle" rad (unwrapped), "rate" rad/s (the joint's
    velocity; where not recorded, the angle's central differences), "meta"}."""
    angle = np.unwrap(np.asarray(joint["position"], float))
    rate = np.asarray(joint["velocity"], float)
    if not np.all(np.isfinite(rate)):
        rate = np.gradient(angle, t) if len(t) > 1 else np.zeros(len(t))
    return {"t": t, "angle": angle, "rate": rate, "meta": meta}


def _body_rate(w_ib, q_nb, initial):
    """w_nb^b = w_ib^b - C_bn w_ie^n (transport rate < 1e-4 rad/s is neglected here: it
    moves a 1 m lever arm's velocity by < 0.1 mm/s)."""
    w_ie = earth.earth_rate_ned(initial["lat"])
    return w_ib - attitude.rotate(np.conjugate(q_nb), np.broadcast_to(w_ie, w_ib.shape))


def _moved(lat, lon, h, d_ned):
    """Geodetic position moved by a small NED offset d (m)."""
    r_n, r_e = earth.radii(lat)
    d = np.asarray(d_ned)
    return (lat + d[..., 0] / (r_n + h), lon + d[..., 1] / ((r_e + h) * np.cos(lat)),
            h - d[..., 2])


def resample(traj, t):
    """Trajectory at times t (s) inside its span: linear in position and velocity, slerp
    in attitude. Longitude goes the short way across the antimeridian (a reference written
    in (-pi, pi] jumps by 2 pi there), attitude the short way between q and -q (one
    rotation: a writer may keep w >= 0)."""
    if t[0] < traj.t[0] - 1e-9 or t[-1] > traj.t[-1] + 1e-9:
        raise InputError(f"times {t[0]:.3f}-{t[-1]:.3f} s outside the trajectory's "
                         f"{traj.t[0]:.3f}-{traj.t[-1]:.3f} s")
    if len(traj) == 1:                          # a trajectory of one instant, at it
        return traj[np.zeros(len(t), dtype=int)]
    k = np.clip(np.searchsorted(traj.t, t, side="right"), 1, len(traj) - 1)
    tau = (t - traj.t[k - 1]) / (traj.t[k] - traj.t[k - 1])
    step = lambda x: x[k] - x[k - 1]                                # noqa: E731
    lerp = lambda x, d: x[k - 1] + d * (tau if x.ndim == 1 else tau[:, None])  # noqa: E731
    d_lon = step(traj.lon)
    d_lon -= 2 * np.pi * np.round(d_lon / (2 * np.pi))     # the short way; exact below pi
    q0 = traj.q_nb[k - 1]
    turn = attitude.short_way(np.conjugate(q0) * traj.q_nb[k])
    with np.errstate(invalid="ignore"):     # a reference without attitude: NaN stays NaN
        q = q0 * np.exp(np.log(turn) * tau)                             # slerp
    return Trajectory(np.asarray(t, float), lerp(traj.lat, step(traj.lat)),
                      lerp(traj.lon, d_lon), lerp(traj.h, step(traj.h)),
                      lerp(traj.v_ned, step(traj.v_ned)), q)


@dataclass
class Replay:
    """Navigated solutions (vehicle origin) and the compensation's sample flags."""
    flight: Flight
    mimu: Trajectory
    fog: Trajectory
    flags: dict


def compensated_mimu(flight, cal, per_sample=False, warn=True):
    """(w rad/s, f m/s^2, flag counts) of the flight's raw MIMU through `cal` (with
    per_sample: the flag of every sample instead of the counts). A flight recorded as
    /mimu/imu is already compensated: `cal` must then be None or an identity base with
    found terms (`Calibration.identity`, the diagnosis's `CAL+found.json`), which are removed
    from the recorded outputs. Warns (unless warn=False: a second pass over a flight already
    warned about) about outputs stuck at an extreme inside the range."""
    w, f, flags = _compensated_whole(flight, cal)
    if warn:
        _warn_stuck(flight, _stuck_inside_range(flight, w, f, flags))
    return w, f, (flags if per_sample else flag_counts(flags))


def _compensated_whole(flight, cal):
    """(w rad/s, f m/s^2, flags) of a flight held in memory (`compensated_mimu`)."""
    if flight.stream_block is not None:
        raise InputError(f"{flight.path}: the flight streams; its MIMU comes block by block "
                         "(Flight.mimu_blocks)")
    if flight.mimu_raw is None:
        w, f = flight.mimu_imu
        if cal is not None and not cal.is_identity:
            raise CalibrationError(
                f"{flight.path}: the MIMU is recorded compensated (/mimu/imu); a calibration of "
                f"raw outputs ({cal.model!r}) cannot apply to it (only found terms on an "
                "identity base can)")
        if cal is not None and cal.found:
            temperature, frequency = flight.mimu_temperatures()
            cond = Conditions.from_outputs(flight.mimu_t, f, w, temperature, frequency)
            f, w = apply_effects(cal.found, cond, sign=-1.0)
        return w, f, np.zeros(len(w), dtype=np.uint8)
    r = flight.mimu_raw
    f, w, flags = compensate(cal, r["accel_volts"], r["gyro_volts"], r["accel_temperature"],
                             r["gyro_frequency"], flight.mimu_range.get("accel_m_s2", np.inf),
                             flight.mimu_range.get("gyro_rad_s", np.inf),
                             t=flight.mimu_t - flight.mimu_t[0])
    return w, f, flags


def _warn_stuck(flight, stuck):
    if stuck:
        from .errors import warn
        warn(f"{flight.path}: {stuck} MIMU samples have a raw output stuck at its extreme for "
             f">= {CLIP_RUN} samples inside the declared range (clipped by the ADC or "
             "amplifier): flagged saturated; the navigation through them is wrong")


def _stuck_inside_range(flight, w, f, flags):
    """Samples flagged saturated although their compensated outputs lie inside the declared
    range: clipped by the ADC or an amplifier below it."""
    inside = (np.abs(f) < flight.mimu_range.get("accel_m_s2", np.inf)).all(axis=1) \
        & (np.abs(w) < flight.mimu_range.get("gyro_rad_s", np.inf)).all(axis=1)
    return int(np.count_nonzero((flags & SATURATED).astype(bool) & inside))


def navigate_mimu(flight, w, f):
    """The MIMU navigated from the flight's initial state: through its mounting, or, on a
    rotating platform (`flight.mimu_platform`), in the sensor frame (`VehicleNavigator`)."""
    nav = _mimu_navigator(flight)
    return Trajectory.concatenate([nav.feed(flight.mimu_t, w, f), nav.finish()])


def _mimu_navigator(flight):
    return VehicleNavigator(flight.mimu_mounting, flight.initial, flight.mimu_platform,
                            whole_record=flight.stream_block is None)


def navigate_fog(flight, at=None):
    """The reference IMU navigated from the flight's initial state, at times `at` (s;
    default every sample), block by block when the flight streams."""
    nav = VehicleNavigator(flight.fog_mounting, flight.initial,
                           whole_record=flight.stream_block is None)
    keep = Sampler(at)
    for t, w, f in flight.fog_blocks():
        keep.add(nav.feed(t, w, f))
    keep.add(nav.finish())
    return keep.trajectory()


class Sampler:
    """Consecutive trajectory pieces (in time order) kept whole, or only at times `at` (s,
    increasing, inside the pieces' span within `resample`'s 1e-9 s; linear/slerp between
    states as `resample`)."""

    def __init__(self, at=None):
        self.at, self.parts, self.last, self.taken = at, [], None, None

    def add(self, piece):
        if piece is None or not len(piece):
            return
        if self.at is None:
            self.parts.append(piece)
            return
        span = piece if self.last is None else Trajectory.concatenate([self.last, piece])
        lo = (np.searchsorted(self.at, span.t[0] - 1e-9, side="left") if self.taken is None
              else self.taken)
        hi = max(lo, np.searchsorted(self.at, span.t[-1] + 1e-9, side="right"))
        if hi > lo:
            self.parts.append(resample(span, self.at[lo:hi]))
        self.last, self.taken = piece[-1:], hi

    def trajectory(self):
        out = Trajectory.concatenate(self.parts) if self.parts else None
        if self.at is not None and (out is None or len(out) != len(self.at)):
            raise InputError(f"times {self.at[0]:.3f}-{self.at[-1]:.3f} s lie outside the "
                             "navigated span"
                             + (f" {out.t[0]:.3f}-{self.last.t[-1]:.3f} s" if out else ""))
        return out


COMPENSATION_WARN = {"accel_m_s2": 0.2, "gyro_rad_s": 0.01}   # medians of |f|, |w| apart
QUIET = {"gyro_rad_s": 0.05, "accel_m_s2": 0.5}   # a quiet second: |w| and ||f| - g| below


def check_compensation(flight, mimu, label="the calibration"):
    """Warn when, in the flight's quiet seconds (the reference IMU turning slower than
    QUIET and feeling 1 g within QUIET), the compensated MIMU's and the reference IMU's
    1 s means differ in size (|f|, |w|: no mounting changes them, averaging removes the
    noise) by more than COMPENSATION_WARN (20 mg, 0.6 deg/s) in the median: a calibration
    written in other units (A0 in mg, ct scaled) gives navigation errors of 1e5 m without
    another sign. `mimu`: the compensated MIMU's SecondMeans of (f, w). Returns the two
    differences (m/s^2, rad/s), or None without a reference IMU or a quiet second."""
    from .errors import warn
    if flight.fog_t is None:
        return None
    (fog_f, fog_w), seconds = flight.fog_second_means()
    (mimu_f, mimu_w), mimu_seconds = mimu.means()
    size = lambda x: np.linalg.norm(x, axis=1)                           # noqa: E731
    g = float(np.median(size(fog_f)))
    quiet = (size(fog_w) < QUIET["gyro_rad_s"]) & (np.abs(size(fog_f) - g) < QUIET["accel_m_s2"])
    common, i, j = np.intersect1d(seconds[quiet], mimu_seconds, return_indices=True)
    if not len(common):
        return None
    k = np.flatnonzero(quiet)[i]
    df = float(np.median(np.abs(size(mimu_f[j]) - size(fog_f[k]))))
    dw = float(np.median(np.abs(size(mimu_w[j]) - size(fog_w[k])))) \
        if flight.mimu_platform is None else 0.0        # a turning MIMU's |w| is not the FOG's
    if df > COMPENSATION_WARN["accel_m_s2"] or dw > COMPENSATION_WARN["gyro_rad_s"]:
        warn(f"{flight.path}: with {label}, in {len(common)} quiet seconds the MIMU's |f| "
             f"differs from the reference IMU's by {df:.3g} m/s^2 and its |w| by {dw:.3g} "
             f"rad/s in the median (a calibration that fits this unit leaves below "
             f"{COMPENSATION_WARN['accel_m_s2']:g} and {COMPENSATION_WARN['gyro_rad_s']:g}): "
             "another unit's file, units other than mimunav-calibration/1's (A0 in mg, ct "
             "scaled), or a model that misses this flight's temperatures?")
    return df, dw


class SecondMeans:
    """Means of (N, 3) series over the whole seconds of t (s since the epoch), accumulated
    block by block (`add` in time order); `means()` gives them with the seconds that hold
    samples."""

    def __init__(self):
        self.k0, self.counts, self.sums = None, np.zeros(0), None

    def add(self, t, *series):
        if not len(t):
            return self
        k = np.floor(t).astype(np.int64)
        if self.k0 is None:
            self.k0, self.sums = k[0], [np.zeros((0, 3)) for _ in series]
        k = k - self.k0
        n = max(int(k[-1]) + 1, len(self.counts))
        grow = lambda a: np.concatenate([a, np.zeros((n - len(a),) + a.shape[1:])])  # noqa
        self.counts = grow(self.counts) + np.bincount(k, minlength=n)
        self.sums = [grow(total) + np.stack([np.bincount(k, weights=x[:, i], minlength=n)
                                             for i in range(3)], axis=1)
                     for total, x in zip(self.sums, series)]
        return self

    def means(self):
        have = self.counts > 0
        return ([total[have] / self.counts[have, None] for total in self.sums],
                np.flatnonzero(have) + self.k0)


def _second_means(t, *series):
    """Means of each (N, 3) series over the whole seconds of t (`SecondMeans`)."""
    return SecondMeans().add(t, *series).means()


def replay(flight, cal, fog=None, check=None, at=None):
    """Compensate and navigate the MIMU with `cal` and the FOG (or reuse `fog`), at times
    `at` (s; default every sample), block by block when the flight streams; with a `check`
    label, `check_compensation` warns about a calibration far off in quiet flight. The FOG
    is navigated on a thread meanwhile (reading, numpy and the navigator release the
    interpreter; the two read the log through their own handles)."""
    nav, keep, seconds = _mimu_navigator(flight), Sampler(at), SecondMeans()
    counts, stuck = dict.fromkeys(("replaced", "saturated", "unusable"), 0), 0
    with ThreadPoolExecutor(1) as pool:
        fog_nav = pool.submit(navigate_fog, flight, at) if fog is None else None
        for t, w, f, flags in flight.mimu_blocks(cal):
            if check is not None:
                seconds.add(t, f, w)
            for name, count in flag_counts(flags).items():
                counts[name] += count
            stuck += _stuck_inside_range(flight, w, f, flags)
            keep.add(nav.feed(t, w, f))
        keep.add(nav.finish())
        fog = fog if fog_nav is None else fog_nav.result()
    _warn_stuck(flight, stuck)
    if check is not None:
        check_compensation(flight, seconds, check)
    return Replay(flight, keep.trajectory(), fog, counts)


def comparison_times(flight, end=None, rate_hz=100.0):
    """Common comparison instants: the truth's stamps (or a rate_hz grid) from the initial
    state to `end` (default: the last instant every channel covers)."""
    t0, last = flight.initial["t"], flight.end
    if end is None:
        end = last
    if end > last + 1e-9:
        raise InputError(f"{flight.path}: the requested end point {end:.3f} s is after the "
                         f"end of the recorded flight ({last:.3f} s since the epoch)")
    if end <= t0:
        raise InputError(f"the end point {end:.3f} s is not after the initial state "
                         f"({t0:.3f} s)")
    if flight.truth is not None:
        t = flight.truth.t[(flight.truth.t >= t0 - 1e-9) & (flight.truth.t <= end + 1e-9)]
    else:
        t = np.arange(t0, end + 1e-9, 1.0 / rate_hz)
    return t if abs(t[-1] - end) < 1e-9 else np.append(t, end)


def errors(rep, t):
    """Position (NED m), velocity (NED m/s) and attitude (rad) errors at times t of MIMU and
    FOG against the truth (if any) and of the MIMU against the FOG."""
    mimu, fog = resample(rep.mimu, t), resample(rep.fog, t)
    out = {"t": t, "mimu-fog": _diff(mimu, fog)}
    if rep.flight.truth is not None:
        ref = resample(rep.flight.truth, t)
        out["mimu-truth"], out["fog-truth"] = _diff(mimu, ref), _diff(fog, ref)
    return out


def _diff(a, b):
    return {"position": a.position_error(b), "velocity": a.velocity_error(b),
            "attitude": a.attitude_error(b)}


def ned_to_enu(d):
    return np.stack([d[..., 1], d[..., 0], -d[..., 2]], axis=-1)


def table(flight, cals, end=None, check=False):
    """The normalised end-point table for calibration variants {name: Calibration}
    (check: warn about a variant far off in quiet flight, `check_compensation`).
    Returns a dict (JSON-ready): end time, reference, FOG row, one row per variant with
    east/north/up errors (m), their ratio to the FOG's (when a truth exists), horizontal and
    3-D norms."""
    t_end = comparison_times(flight, end)[-1:]
    fog = navigate_fog(flight, at=t_end)
    has_truth = flight.truth is not None
    ref = resample(flight.truth if has_truth else fog, t_end)
    rows = {}
    for name, cal in cals.items():
        rep = replay(flight, cal, fog=fog, check=f"calibration {name!r}" if check else None,
                     at=t_end)
        enu = ned_to_enu(resample(rep.mimu, t_end).position_error(ref)[-1])
        rows[name] = {"enu_m": enu.tolist(), "horizontal_m": float(np.hypot(enu[0], enu[1])),
                      "norm_m": float(np.linalg.norm(enu)), "flags": rep.flags}
    fog_enu = ned_to_enu(resample(fog, t_end).position_error(ref)[-1]) if has_truth else None
    doc = {"format": "mimunav-table/1", "log": flight.path, "flight": flight.name,
           "end_t_s": float(t_end[0]), "duration_s": float(t_end[0] - flight.initial["t"]),
           "reference": "truth" if has_truth else "fog", "variants": rows}
    if has_truth:
        doc["fog"] = {"enu_m": fog_enu.tolist(), "horizontal_m": float(np.hypot(*fog_enu[:2])),
                      "norm_m": float(np.linalg.norm(fog_enu))}
        for row in rows.values():
            row["normalised_enu"] = (np.abs(row["enu_m"]) / np.abs(fog_enu)).tolist()
    return doc


def table_markdown(doc, paper=None):
    """The table as markdown (paper: optional {variant: [e, n, u]} of the published row)."""
    lines = [f"End point t = {doc['end_t_s']:.2f} s ({doc['duration_s']:.2f} s after the "
             f"initial state), flight `{doc['flight']}`.", ""]
    if doc["reference"] == "truth":
        lines += ["| variant | east / FOG | north / FOG | up / FOG | east m | north m | up m "
                  "| horizontal m | 3-D m |", "|---|---|---|---|---|---|---|---|---|"]
        for name, row in doc["variants"].items():
            ne, e = row["normalised_enu"], row["enu_m"]
            lines.append(f"| {name} | {ne[0]:.3g} | {ne[1]:.3g} | {ne[2]:.3g} | {e[0]:+.3g} | "
                         f"{e[1]:+.3g} | {e[2]:+.3g} | {row['horizontal_m']:.3g} | "
                         f"{row['norm_m']:.3g} |")
        fog = doc["fog"]
        e = fog["enu_m"]
        lines.append(f"| FOG-IMU | 1 | 1 | 1 | {e[0]:+.3g} | {e[1]:+.3g} | {e[2]:+.3g} | "
                     f"{fog['horizontal_m']:.3g} | {fog['norm_m']:.3g} |")
    else:
        lines += ["No `/truth/state` in this log: the FOG-IMU's solution is the reference, so "
                  "the table gives MIMU-vs-FOG differences (no normalisation is possible).", "",
                  "| variant | east m | north m | up m | horizontal m | 3-D m |",
                  "|---|---|---|---|---|---|"]
        for name, row in doc["variants"].items():
            e = row["enu_m"]
            lines.append(f"| {name} | {e[0]:+.3g} | {e[1]:+.3g} | {e[2]:+.3g} | "
                         f"{row['horizontal_m']:.3g} | {row['norm_m']:.3g} |")
    return "\n".join(lines) + "\n"


def table_csv(doc):
    head = "variant,east_m,north_m,up_m,horizontal_m,norm_m,east_norm,north_norm,up_norm\n"
    rows = []
    for name, row in doc["variants"].items():
        ne = row.get("normalised_enu", [math.nan] * 3)
        rows.append(",".join([name] + [f"{x:.6g}" for x in row["enu_m"]] +
                             [f"{row['horizontal_m']:.6g}", f"{row['norm_m']:.6g}"] +
                             [f"{x:.6g}" for x in ne]))
    if "fog" in doc:
        fog = doc["fog"]
        rows.append(",".join(["FOG-IMU"] + [f"{x:.6g}" for x in fog["enu_m"]] +
                             [f"{fog['horizontal_m']:.6g}", f"{fog['norm_m']:.6g}", "1", "1", "1"]))
    return head + "\n".join(rows) + "\n"


BUDGET_GROUPS = ("temperature", "nonlinear scale factor", "g-sensitivity", "cross-coupling")


def without(cal, group, flight):
    """`cal` with one group of terms switched off: temperature (eqs. 2, 4 frozen at the
    flight's first readings), nonlinear scale factor (A2, A3, W2, W3), g-sensitivity (C),
    cross-coupling (off-diagonals of A1 and W1)."""
    out = Calibration.from_dict(cal.as_dict())
    if group == "temperature":
        r = flight.mimu_raw
        for key, reading in (("ct", r["accel_temperature"][0]), ("cw", r["gyro_frequency"][0])):
            poly = getattr(out, key)
            poly[:, 0] = poly2(poly, reading[None, :])[0]
            poly[:, 1:] = 0.0
    elif group == "nonlinear scale factor":
        for key in ("A2", "A3", "W2", "W3"):
            getattr(out, key)[:] = 0.0
    elif group == "g-sensitivity":
        out.C[:] = 0.0
    elif group == "cross-coupling":
        for key in ("A1", "W1"):
            m = getattr(out, key)
            m[~np.eye(3, dtype=bool)] = 0.0
    else:
        raise InputError(f"unknown term group {group!r}; one of {', '.join(BUDGET_GROUPS)}")
    return out


def error_budget(flight, cal, end=None):
    """What each group of `cal`'s terms is worth on this flight: the end-point errors with
    the group switched off, against the full calibration. Returns a JSON-ready dict."""
    variants = {"full": cal} | {f"without {g}": without(cal, g, flight) for g in BUDGET_GROUPS}
    doc = table(flight, variants, end)
    base = doc["variants"]["full"]["norm_m"]
    for name, row in doc["variants"].items():
        row["worth_m"] = row["norm_m"] - base
    return doc


def budget_markdown(doc):
    against = ("the truth (/truth/state)" if doc["reference"] == "truth" else
               "the FOG-IMU's own solution (no /truth/state in this log)")
    lines = [f"End-point error of the MIMU at t = {doc['end_t_s']:.2f} s against {against}, "
             "east/north/up:", "",
             "| calibration | east m | north m | up m | 3-D m | group worth (3-D, m) |",
             "|---|---|---|---|---|---|"]
    for name, row in doc["variants"].items():
        e = row["enu_m"]
        worth = "-" if name == "full" else f"{row['worth_m']:+.3g}"
        lines.append(f"| {name} | {e[0]:+.3g} | {e[1]:+.3g} | {e[2]:+.3g} | "
                     f"{row['norm_m']:.3g} | {worth} |")
    return "\n".join(lines) + "\n"

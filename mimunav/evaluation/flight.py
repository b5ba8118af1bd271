"""A flight log loaded for evaluation (`Flight`: the MIMU raw or compensated, the
reference IMU, truth, GNSS, platform, in memory or streamed in blocks) and the checks a log
must pass before navigation (stamps, gaps, spans, units).
"""
from dataclasses import dataclass, replace

import numpy as np

from ..frames import attitude
from ..compensation.log import BLOCK, compensated_blocks
from ..compensation.model import CalibrationError, compensate
from ..compensation.effects import Conditions
from ..compensation.effects import apply as apply_effects
from ..flightlog import FlightLog, LogError
from ..frames.mounting import Mounting
from ..motion.trajectory import State, Trajectory
from ..errors import InputError


RAW_FIELDS = ("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency")


@dataclass
class RecordedPlatform:
    """A rotating MIMU's platform as a log records it (/mimu/platform): t s, angle rad
    (unwrapped) and rate rad/s about the platform z axis at each stamp, and meta, the
    `platform` object of the log's sensor/mimu metadata (`motion.platform.platform_metadata`)."""
    t: np.ndarray
    angle: np.ndarray
    rate: np.ndarray
    meta: dict


@dataclass
class Flight:
    """What a replay needs from a log (times in s since the log's epoch)."""
    path: str
    name: str
    epoch_ns: int                   # epoch_unix_ns of the flight metadata
    initial: State                  # the navigation's initial state
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
    mimu_platform: RecordedPlatform | None = None   # a rotating MIMU's platform
    stream_block: int | None = None     # streamed: the MIMU raw outputs and the reference
                                        # IMU are read from the log in blocks of this many
                                        # samples when navigated (mimu_raw, fog_w, fog_f None;
                                        # the stamps are held)
    fog_seconds: object = None          # SecondMeans of the reference IMU (f, w), when known
    recording: dict | None = None       # the log's `recording` metadata (an imported one's:
                                        # what is real, what assumed, the alignment's biases)
    mimu_lag_s: tuple = (0.0, 0.0)      # the lag (s) of the MIMU's accelerometer and gyro
                                        # samples behind their stamps that the sensor level's
                                        # prediction is made at (`diagnosis.skew`): a time
                                        # skew's, positive when the triad lags

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
            flight = _flight_metadata(log, path, meta)
            epoch = int(flight["epoch_unix_ns"])
            raw, imu, fog, truth, joint, streamed = _channels(log, path, epoch, reference_imu,
                                                               stream)
            platform_meta = meta.get("sensor/mimu", {}).get("platform")
            if (joint is None) != (platform_meta is None):
                raise LogError(f"{path}: a rotating MIMU needs both /mimu/platform and the "
                               "`platform` object of the sensor/mimu metadata (README: "
                               "rotating MIMUs); the log has only one of them")
        sec = lambda m: (m["log_time"].astype(np.int64) - epoch) / 1e9      # noqa: E731
        init = flight["initial_state"]
        initial = State.from_contract(init)
        mount = lambda name: Mounting.from_dict(                                # noqa: E731
            meta.get(f"sensor/{name}", {}).get("mounting", {}))
        truth_traj = None
        if truth is not None and len(truth):
            truth_traj = Trajectory(sec(truth), truth["latitude"].copy(), truth["longitude"].copy(),
                                    truth["height"].copy(), truth["velocity_ned"].copy(),
                                    attitude.from_wxyz(truth["attitude_wxyz"]))
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
        loaded.recording = meta.get("recording")
        check_plausible(loaded, MAX_GAP_S if max_gap_s is None else max_gap_s,
                        streamed["fog_sample"] if streamed else None)
        return loaded

    @classmethod
    def from_simulation(cls, fm, unit, fog, raw, fog_out):
        """The same Flight a log of this simulation gives (`simulation.simulate_flight`),
        built in memory: for campaigns that need no files."""
        tr, k = fm.run.trajectory, fm.k_truth
        start = tr.state(0)
        initial = replace(start, t=0.0)
        truth = Trajectory(fm.t_base[k], tr.lat[k], tr.lon[k], tr.h[k], tr.v_ned[k], tr.q_nb[k])
        return cls("(in memory)", fm.profile.name, 0, initial, fm.mimu[0],
                   {key: raw[key] for key in RAW_FIELDS},
                   unit.mounting, {"accel_m_s2": unit.range_accel, "gyro_rad_s": unit.range_gyro},
                   fm.fog[0], fog_out["angular_velocity"], fog_out["linear_acceleration"],
                   fog.mounting, truth, fog_meta={"accuracy": fog.accuracy()},
                   source="simulation")

    def mimu_blocks(self, cal):
        """The MIMU through `cal` (`compensated_mimu`) in time-ordered blocks of
        (t s, w rad/s, f m/s^2, flags), sensor axes: one block when the flight is held, of
        stream_block samples (`compensation.compensated_blocks`) when it streams."""
        if self.stream_block is None:
            yield (self.mimu_t, *compensated_whole(self, cal))
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


def _flight_metadata(log, path, meta):
    """The `flight` metadata of an open log (`flightlog.FlightLog`), refused (LogError) when
    it lacks what places the navigation start."""
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
    return flight


def _channels(log, path, epoch, reference_imu, stream):
    """(raw MIMU messages or None, recorded /mimu/imu (w, f) or None, /fog/imu messages or
    None, /truth/state or None, /mimu/platform or None, `_streamed` or None) of an open
    log (`Flight.load`)."""
    mimu_topic = "/mimu/imu" if "/mimu/raw" not in log.channels and \
        "/mimu/imu" in log.channels else "/mimu/raw"
    needed = (mimu_topic, "/fog/imu") if reference_imu else (mimu_topic,)
    for topic in needed:
        if topic not in log.channels:
            what = "the MIMU's outputs" if topic == mimu_topic else \
                "the FOG-IMU flown with the MIMU (the reference IMU)"
            raise LogError(f"{path}: no {topic} channel, which holds {what} (channels: "
                           f"{', '.join(sorted(log.channels))})")
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
    return raw, imu, fog, truth, joint, streamed


def _streamed(log, path, epoch, reference_imu):
    """One pass over /mimu/raw's stamps and /fog/imu of a log for `Flight.load(stream=True)`:
    {"mimu": stamps, "fog": stamps or None, "fog_seconds": SecondMeans, "fog_sample": (w, f)
    every k-th sample for the units check}; None when a channel's stamps go back in time
    (the flight is then read whole and sorted). A non-finite reference sample is a LogError
    here, since the check sees only the sample."""
    from numpy.lib.recfunctions import repack_fields

    from ..flightlog.reader import TimeOrderError
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
            # copies of their own: a field view or a strided view keeps the whole block
            # alive (56 bytes a message for a stamp; a 2-hour 1 kHz log's 0.7 GB)
            stamps.append(repack_fields(msgs[["log_time"]]))
            seconds.add(t, f, w)
            sample.append((w[::step].copy(), f[::step].copy()))
    except TimeOrderError:
        return None
    return {"mimu": mimu, "fog": np.concatenate(stamps), "fog_seconds": seconds,
            "fog_sample": tuple(np.concatenate(x) for x in zip(*sample))}


def refuse_gaps(flight, max_gap_s=MAX_GAP_S, warn_shorter=False):
    """LogError when the MIMU misses samples for longer than max_gap_s (s) after the
    navigation's start (the initial state's time: a gap before it is never navigated - a
    KITTI drive's 1.92 s at its first stamp had refused the navigation level from 5.9 s):
    the navigation would bridge the gap with one sample. With warn_shorter, the shorter gaps
    are reported on stderr."""
    from ..errors import warn
    from ..flightlog.stamps import longest_gap, missing_samples, scheduled
    t = flight.mimu_t
    if len(t) <= 10:
        return
    gaps = missing_samples(np.round(t * 1e9).astype(np.int64))
    if not gaps:
        return
    navigated = [(k, n) for k, n in gaps if t[k + 1] > flight.initial.t]
    k, n = longest_gap(t, navigated) if navigated else (0, 0)
    if navigated and t[k + 1] - t[k] > max_gap_s:
        sides = [f"{a:.3f}:{b:.3f}" for a, b in ((t[0], t[k]), (t[k + 1], t[-1])) if b > a]
        raise LogError(f"{flight.path}: the MIMU misses {n} samples between t = {t[k]:.3f} "
                       f"and {t[k + 1]:.3f} s ({sum(m for _, m in gaps)} in all): "
                       f"navigation would bridge {t[k + 1] - t[k]:.3g} s with one "
                       f"sample; cut the log at the gap: mimunav cut LOG --span "
                       f"{' (or '.join(sides)}{')' if len(sides) > 1 else ''} -o OUT")
    if warn_shorter:
        k, n = longest_gap(t, gaps)
        warn(f"{flight.path}: the MIMU misses {sum(m for _, m in gaps)} samples in "
             f"{len(gaps)} gaps (longest {t[k + 1] - t[k]:.3g} s at t = {t[k]:.3f} s)"
             + (f"; {said}" if (said := scheduled(gaps)) else ""))


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
    # a sample stamped t_k is the mean over (t_k-1, t_k]: a state at power-on, the left
    # edge of the first interval (t_0 less one step), starts the first interval (contract)
    first = t[0] - (t[1] - t[0] if len(t) > 1 else 0.0) * 1.001 - 1e-6
    if not first <= flight.initial.t <= t[-1]:
        raise LogError(f"{where}: the initial state's t = {flight.initial.t:.3f} s lies "
                       f"outside the MIMU's stamps {t[0]:.3f} .. {t[-1]:.3f} s and the "
                       "interval before the first (epoch_unix_ns or the stamps' time base "
                       "off?)")
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
    if tr is None or len(tr.t) < 10 or not np.isfinite(attitude.as_wxyz(tr.q_nb)).all():
        return
    rate = attitude.turn_rate(tr.t, tr.q_nb)
    truth_rate, fog_rate = np.percentile(rate, 99), np.percentile(np.linalg.norm(w, axis=1), 99)
    if truth_rate > 0.05 and not 0.2 < fog_rate / truth_rate < 5:
        raise LogError(f"{flight.path}: /fog/imu rates reach {fog_rate:.3g}, the truth's "
                       f"attitude turns at up to {truth_rate:.3g} rad/s: the contract's rad/s "
                       f"differs by {fog_rate / truth_rate:.3g}x (deg/s?)")


def no_reference(path, what):
    """The InputError for `what` on a log without /truth/state, saying how its GNSS fixes
    could serve as one when it has /gnss/fix."""
    with FlightLog(path) as log:
        fixes = "/gnss/fix" in log.channels
    hint = ("; its /gnss/fix can serve when the import takes it as the reference: ros1 or ros2 "
            "--reference-status 2 (RTK grade), rtklib --solutions, dataflash --reference gnss, "
            "table a [reference] section" if fixes else "")
    return InputError(f"{path}: no reference trajectory (/truth/state) for {what}{hint}")


def _platform(t, joint, meta):
    """A Flight's mimu_platform (`RecordedPlatform`): the joint's angle unwrapped, its
    velocity as the rate (where not recorded, the angle's central differences)."""
    angle = np.unwrap(np.asarray(joint["position"], float))
    rate = np.asarray(joint["velocity"], float)
    if not np.all(np.isfinite(rate)):
        rate = np.gradient(angle, t) if len(t) > 1 else np.zeros(len(t))
    return RecordedPlatform(t, angle, rate, meta)


def compensated_whole(flight, cal):
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

"""MCAP flight logs: the contract's channels round-trip bit-exactly and interoperate."""
import struct

import numpy as np
import pytest
from mcap.writer import Writer

from mimunav.flightlog import FlightLog, LogError, LogWriter
from mimunav.flightlog import schemas as S

EPOCH = 1_767_225_600_000_000_000      # 2026-01-01T00:00:00Z in ns


def _channels(n, rng):
    t = EPOCH + np.arange(1, n + 1, dtype=np.int64) * 1_000_000
    raw = dict(sample_index=np.arange(n, dtype=np.uint64), gyro_volts=rng.normal(size=(n, 3)),
               accel_volts=rng.normal(size=(n, 3)),
               accel_temperature=20 + rng.normal(size=(n, 3)),
               gyro_frequency=1e4 + rng.normal(size=(n, 3)))
    imu = dict(orientation=np.tile([0.0, 0, 0, 1], (n, 1)),
               orientation_covariance=np.tile([-1.0] + [0] * 8, (n, 1)),
               angular_velocity=rng.normal(size=(n, 3)),
               linear_acceleration=rng.normal(size=(n, 3)))
    nav = dict(latitude=rng.normal(size=n), longitude=rng.normal(size=n),
               height=rng.normal(size=n), velocity_ned=rng.normal(size=(n, 3)),
               attitude_wxyz=rng.normal(size=(n, 4)))
    return t, raw, imu, nav


def _write(path, t, raw, imu=None):
    with LogWriter(path) as log:
        log.write("/mimu/raw", S.RAW_MIMU, "mimu", t, **raw)
        if imu is not None:
            log.write("/fog/imu", S.IMU, "fog", t, **imu)
    return path


def test_every_channel_round_trips_bit_exactly(tmp_path):
    rng = np.random.default_rng(0)
    t, raw, imu, nav = _channels(30000, rng)
    path = tmp_path / "f.mcap"
    with LogWriter(path) as log:
        log.metadata("flight", {"format": "mimunav-log/1", "epoch_unix_ns": str(EPOCH),
                                "initial_state": {"t": 0.0, "latitude": 0.5}})
        log.write("/mimu/raw", S.RAW_MIMU, "mimu", t, **raw)
        log.write("/fog/imu", S.IMU, "fog", t, **imu)
        log.write("/truth/state", S.NAV_STATE, "vehicle", t[::10], **{
            k: v[::10] for k, v in nav.items()})
    with FlightLog(path) as lg:
        assert lg.metadata()["flight"]["initial_state"] == {"t": 0.0, "latitude": 0.5}
        for topic, fields, stamps in (("/mimu/raw", raw, t), ("/fog/imu", imu, t),
                                      ("/truth/state", {k: v[::10] for k, v in nav.items()},
                                       t[::10])):
            msgs = lg.read(topic)
            assert lg.count(topic) == len(stamps)
            assert np.array_equal(msgs["log_time"].astype(np.int64), stamps)
            assert np.array_equal(S.stamps_ns(msgs), stamps)      # header.stamp == log_time
            for key, value in fields.items():
                assert np.array_equal(msgs[key], value), (topic, key)


def test_generic_ros2_decoder_reads_what_mimunav_writes(tmp_path):
    rng = np.random.default_rng(1)
    t, raw, imu, _ = _channels(50, rng)
    path = _write(tmp_path / "f.mcap", t, raw, imu)
    with FlightLog(path) as lg:
        decoded = lg.read_generic("/fog/imu")
        for k, (log_time, msg) in enumerate(decoded):
            assert log_time == t[k]
            assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == t[k]
            assert msg.header.frame_id == "fog"
            av = imu["angular_velocity"][k]
            assert (msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z) \
                == tuple(av)
            assert msg.orientation.w == 1.0 and msg.orientation_covariance[0] == -1.0
        raw_msgs = lg.read_generic("/mimu/raw")
        assert list(raw_msgs[7][1].gyro_frequency) == list(raw["gyro_frequency"][7])


def test_a_log_from_another_writer_following_the_contract_reads_back(tmp_path):
    """The plain mcap writer with CDR packed by hand with struct, as a user's recorder
    would do it."""
    path = tmp_path / "other.mcap"
    n = 100
    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start(profile="ros2", library="someone-else")
        sid = w.register_schema(name=S.RAW_MIMU, encoding="ros2msg", data=S.SCHEMAS[S.RAW_MIMU])
        cid = w.register_channel(topic="/mimu/raw", message_encoding="cdr", schema_id=sid)
        for k in range(n):
            stamp = EPOCH + k * 2_000_000
            sec, nsec = divmod(stamp, 10**9)
            payload = (b"\x00\x01\x00\x00" + struct.pack("<iII", sec, nsec, 5) + b"mimu\x00"
                       + b"\x00" * 7 + struct.pack("<Q", k)
                       + struct.pack("<12d", *([0.1 * k] * 3 + [0.2] * 3 + [25.0] * 3
                                               + [9000.0] * 3)))
            w.add_message(cid, log_time=stamp, publish_time=stamp, data=payload, sequence=k)
        w.finish()
    with FlightLog(path) as lg:
        msgs = lg.read("/mimu/raw")
    assert np.array_equal(msgs["sample_index"], np.arange(n))
    np.testing.assert_array_equal(msgs["gyro_volts"][:, 0], 0.1 * np.arange(n))
    np.testing.assert_array_equal(msgs["gyro_frequency"], 9000.0)


def test_missing_channel_lists_what_is_there_and_writing_is_safe(tmp_path):
    rng = np.random.default_rng(2)
    t, raw, _, _ = _channels(10, rng)
    path = _write(tmp_path / "f.mcap", t, raw)
    with FlightLog(path) as lg, pytest.raises(LogError, match=r"no channel '/fog/imu'; "
                                                             r"the log has /mimu/raw"):
        lg.read("/fog/imu")
    with pytest.raises(FileExistsError, match="--force"):
        LogWriter(path)
    before = path.read_bytes()
    with pytest.raises(ValueError, match="stamps must increase"):
        with LogWriter(path, force=True) as log:
            log.write("/mimu/raw", S.RAW_MIMU, "mimu", t[::-1], **raw)
    assert path.read_bytes() == before                       # the old log is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.mcap"]   # no temporary left

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


def _other_writer_log(path, n, padding):
    """A /mimu/raw log of n messages by the plain mcap writer, CDR packed by hand with struct
    as a user's recorder would do it; padding(k): the 7 bytes after message k's frame_id.
    Returns the payloads."""
    payloads = []
    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start(profile="ros2", library="someone-else")
        sid = w.register_schema(name=S.RAW_MIMU, encoding="ros2msg", data=S.SCHEMAS[S.RAW_MIMU])
        cid = w.register_channel(topic="/mimu/raw", message_encoding="cdr", schema_id=sid)
        for k in range(n):
            stamp = EPOCH + k * 2_000_000
            sec, nsec = divmod(stamp, 10**9)
            payloads.append(b"\x00\x01\x00\x00" + struct.pack("<iII", sec, nsec, 5) + b"mimu\x00"
                            + padding(k) + struct.pack("<Q", k)
                            + struct.pack("<12d", *([0.1 * k] * 3 + [0.2] * 3 + [25.0] * 3
                                                    + [9000.0] * 3)))
            w.add_message(cid, log_time=stamp, publish_time=stamp, data=payloads[-1],
                          sequence=k)
        w.finish()
    return payloads


def test_a_log_from_another_writer_following_the_contract_reads_back(tmp_path):
    """The plain mcap writer with CDR packed by hand with struct, as a user's recorder
    would do it."""
    path, n = tmp_path / "other.mcap", 100
    _other_writer_log(path, n, lambda k: b"\x00" * 7)
    with FlightLog(path) as lg:
        msgs = lg.read("/mimu/raw")
    assert np.array_equal(msgs["sample_index"], np.arange(n))
    np.testing.assert_array_equal(msgs["gyro_volts"][:, 0], 0.1 * np.arange(n))
    np.testing.assert_array_equal(msgs["gyro_frequency"], 9000.0)


def test_payloads_pass_through_byte_for_byte(tmp_path):
    """`read(topic, PAYLOAD)` gives each message's CDR bytes as another writer wrote them
    (its padding bytes not zero), block by block too; `write_encoded` writes them back byte
    for byte, decoding to the same fields (with increasing=True, refusing a stamp that does
    not increase across calls, as `write` does)."""
    from mimunav.errors import InputError
    from mimunav.flightlog.reader import PAYLOAD
    path, n = tmp_path / "other.mcap", 100
    payloads = _other_writer_log(path, n, lambda k: bytes([0xA5 + k % 7] * 7))
    with FlightLog(path) as lg:
        got = lg.read("/mimu/raw", PAYLOAD)
        fields = lg.read("/mimu/raw")
        assert [bytes(p) for p in got["payload"]] == payloads
        assert np.array_equal(np.concatenate(list(lg.blocks("/mimu/raw", 30, PAYLOAD))), got)
    copy = tmp_path / "copy.mcap"
    with LogWriter(copy) as dst:
        dst.write_encoded("/mimu/raw", S.RAW_MIMU, got["payload"][:60],
                          got["log_time"][:60].astype(np.int64), increasing=True)
        with pytest.raises(InputError, match="stamps must increase"):
            dst.write_encoded("/mimu/raw", S.RAW_MIMU, got["payload"][59:60],
                              got["log_time"][59:60].astype(np.int64), increasing=True)
        dst.write_encoded("/mimu/raw", S.RAW_MIMU, got["payload"][60:],
                          got["log_time"][60:].astype(np.int64), increasing=True)
    with FlightLog(copy) as lg:
        assert np.array_equal(lg.read("/mimu/raw", PAYLOAD), got)
        assert np.array_equal(lg.read("/mimu/raw"), fields)


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


def test_a_failed_chunk_write_raises_and_leaves_nothing(tmp_path, monkeypatch):
    """Chunks are compressed on a pool of threads while the next are encoded: a write that
    fails (a full disk), a compression that fails on a pool thread, and a failure of the
    caller's own while chunks are in flight are each raised to the writer's caller; no log
    and no temporary file are left and nothing hangs."""
    from mimunav.flightlog import writer
    rng = np.random.default_rng(5)
    t, raw, _, _ = _channels(40_000, rng)         # ~110 chunks of 64 KiB: many in flight
    calls = []
    real_write, real_pack = writer.LogWriter._write_chunk, writer.LogWriter._pack

    def full_disk(self, *chunk):
        calls.append(1)
        if len(calls) == 20:
            raise OSError(28, "No space left on device")
        return real_write(self, *chunk)

    def no_memory(self, data):
        calls.append(1)
        if len(calls) == 30:
            raise MemoryError("zstd: out of memory")
        return real_pack(self, data)

    for name, fault, error in [("_write_chunk", full_disk, "No space left"),
                               ("_pack", no_memory, "out of memory")]:
        calls.clear()
        monkeypatch.setattr(writer.LogWriter, name, fault)
        with pytest.raises((OSError, MemoryError), match=error):
            with LogWriter(tmp_path / "full.mcap", chunk_size=1 << 16) as log:
                log.write("/mimu/raw", S.RAW_MIMU, "mimu", t, **raw)
        assert len(calls) >= 20 and list(tmp_path.iterdir()) == []
        monkeypatch.undo()
    with pytest.raises(KeyboardInterrupt):
        with LogWriter(tmp_path / "stopped.mcap", chunk_size=1 << 16) as log:
            log.write("/mimu/raw", S.RAW_MIMU, "mimu", t, **raw)
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def flight_file(tmp_path):
    rng = np.random.default_rng(4)
    t, raw, imu, _ = _channels(60000, rng)
    path = tmp_path / "f.mcap"
    with LogWriter(path) as log:
        log.metadata("flight", {"format": "mimunav-log/1", "epoch_unix_ns": str(EPOCH)})
        log.write("/mimu/raw", S.RAW_MIMU, "mimu", t, **raw)
        log.write("/fog/imu", S.IMU, "fog", t, **imu)
    return path, t, raw


def test_a_cut_log_without_its_epoch_says_its_spans_as_utc():
    """A log whose writer put its metadata at the end (the foreign simulator's) keeps no
    epoch once cut: its intact spans are said as UTC times to the millisecond, not as
    19-digit nanosecond counts."""
    from mimunav.flightlog.recover import describe_scan
    report = {"epoch_ns": None, "expected": {}, "complete": False, "damaged": [],
              "channels": {"/mimu/raw": (14006, 1760475200001000000, 1760475214006000000)}}
    line = describe_scan(report).splitlines()[0]
    assert line.endswith("14006 intact messages, 2025-10-14 20:53:20.001 UTC .. "
                         "2025-10-14 20:53:34.006 UTC"), line


@pytest.mark.slow
def test_truncated_log_reports_and_recovers_its_intact_chunks(flight_file, tmp_path, capsys):
    from mimunav.cli import main
    path, t, raw = flight_file
    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[:len(data) // 2])
    with pytest.raises(LogError, match="truncated"):
        FlightLog(cut)
    assert main(["info", str(cut)]) == 2
    out = capsys.readouterr().out
    assert "/mimu/raw" in out and "intact messages, t = 0.001 s .." in out
    assert "cut short: the file ends" in out
    fixed = tmp_path / "fixed.mcap"
    assert main(["info", str(cut), "--recover", str(fixed)]) == 0
    with FlightLog(fixed) as log:
        msgs = log.read("/mimu/raw")
        assert log.metadata()["flight"]["epoch_unix_ns"] == EPOCH
    n = len(msgs)
    assert 0 < n < len(t)
    assert np.array_equal(msgs["gyro_volts"], raw["gyro_volts"][:n])    # a prefix, intact
    assert cut.read_bytes() == data[:len(data) // 2]                    # input untouched


def test_corrupt_chunk_is_named_by_its_time_range(flight_file, tmp_path):
    """Bits flipped anywhere in a chunk's compressed data: the decompressor refuses some
    (a broken zstd frame), others decompress to wrong records that the CRC catches; both are
    the same damage to a user - the chunk named by its time range."""
    path, _, _ = flight_file
    data = path.read_bytes()
    with FlightLog(path) as log:
        ci = sorted(log.summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[3]
    start = (ci.message_start_time - EPOCH) / 1e9
    reasons = set()
    for k in range(1, 12):
        bad_data = bytearray(data)
        bad_data[ci.chunk_start_offset + ci.chunk_length * k // 12] ^= 0xFF    # flip bits
        bad = tmp_path / f"bad{k}.mcap"
        bad.write_bytes(bytes(bad_data))
        with FlightLog(bad) as log, pytest.raises(LogError, match=rf"corrupt chunk .* from "
                                                                  rf"t = {start:.3f} s") as err:
            for topic in log.channels:
                log.read(topic)
        reasons.add("CRC" if "CRC mismatch" in str(err.value) else
                    "zstd" if "the decompressor" in str(err.value) else
                    "size" if "size" in str(err.value) else str(err.value))
    assert {"CRC", "zstd"} <= reasons <= {"CRC", "zstd", "size"}      # zstd's version decides


@pytest.mark.slow
def test_a_chunks_size_field_or_repeated_index_entries_are_named_damage(flight_file, tmp_path):
    """Two damages the review found escaping: the top bit of a chunk's uncompressed size
    flipped (2^63 overflowed zstd's size argument: a traceback from info, read and --recover)
    and a message index whose entry repeats its neighbour (one message read twice, another
    lost, silently: the count and each stamp still matched). Each is now a LogError naming
    the chunk; --recover keeps the rest."""
    from fuzzing import records

    from mimunav.cli import main
    path, _, raw = flight_file
    data = path.read_bytes()
    chunk = [pos for pos, op, _ in records(data) if op == 0x06][0]
    flipped = bytearray(data)
    flipped[chunk + 32] ^= 0x80                 # uncompressed size: opcode, length, start, end
    bad = tmp_path / "size.mcap"
    bad.write_bytes(bytes(flipped))
    with FlightLog(bad) as log, pytest.raises(LogError, match="corrupt chunk .* uncompressed "
                                                              "size"):
        for topic in log.channels:
            log.read(topic)
    assert main(["info", str(bad), "--recover", str(tmp_path / "kept.mcap")]) == 0
    index = [pos for pos, op, _ in records(data) if op == 0x07][1]
    entries = index + 15                        # opcode, length, channel, entries' length
    repeated = bytearray(data)
    repeated[entries + 5 * 16:entries + 6 * 16] = data[entries + 4 * 16:entries + 5 * 16]
    bad = tmp_path / "repeated.mcap"
    bad.write_bytes(bytes(repeated))
    with FlightLog(bad) as log, pytest.raises(LogError, match="damaged index"):
        for topic in log.channels:
            log.read(topic)


def test_only_the_reading_thread_touches_the_file(flight_file, tmp_path):
    """Chunks are decompressed on worker threads (`FlightLog._decoded_ahead`); the file is
    read by the consumer alone, also when a worker meets a corrupt chunk and names its time
    range (that name once read the metadata on the worker, moving the consumer's file
    position: messages of intact chunks were then dropped as damaged, run to run)."""
    import threading
    path, _, _ = flight_file
    data = bytearray(path.read_bytes())
    with FlightLog(path) as log:
        ci = sorted(log.summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[3]
    data[ci.chunk_start_offset + ci.chunk_length // 2] ^= 0xFF
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    threads = set()

    class Watched:
        def __init__(self, fh):
            self.fh = fh

        def __getattr__(self, name):
            if name in ("seek", "read", "tell"):
                threads.add(threading.get_ident())
            return getattr(self.fh, name)

    for skip in (False, True):
        with FlightLog(bad, skip_damaged=skip) as log:
            log._fh = Watched(log._fh)
            try:
                for topic in log.channels:
                    log.read(topic)
            except LogError as exc:
                assert not skip and "corrupt chunk" in str(exc)
            assert skip == bool(log.damaged)
        assert threads == {threading.get_ident()}


def test_other_schemas_and_irregular_time_are_reported(tmp_path, capsys):
    from mcap.writer import Writer as McapWriter

    from mimunav.cli import main
    rng = np.random.default_rng(5)
    t, raw, _, _ = _channels(1000, rng)
    t = t.copy()
    t[500:] += 50_000_000                       # a 50 ms gap
    raw["sample_index"][700:] += 3              # 3 dropped samples
    path = _write(tmp_path / "g.mcap", t, raw)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "1 gaps, 50 samples missing (first 0.499-0.550 s)" in out and "3 dropped samples" in out
    # stamps that go backwards or repeat, written by a recorder that does not check
    t2 = t.copy()
    t2[300], t2[301] = t2[301], t2[300]
    t2[800] = t2[799]
    path2 = tmp_path / "h.mcap"
    with LogWriter(path2) as log:
        msgs = S.encode(S.RAW_MIMU, "mimu", t2, **raw)
        log.write_encoded("/mimu/raw", S.RAW_MIMU, msgs, t2)
    assert main(["info", str(path2)]) == 0
    out = capsys.readouterr().out
    assert "time goes backwards 1 times" in out and "1 duplicate stamps" in out
    # a channel of another layout (a string field of varying length) is not read blindly
    other = tmp_path / "other.mcap"
    with open(other, "wb") as fh:
        w = McapWriter(fh)
        w.start(profile="ros2", library="x")
        sid = w.register_schema(name=S.NAV_STATE, encoding="ros2msg",
                                data=S.SCHEMAS[S.NAV_STATE])
        cid = w.register_channel(topic="/truth/state", message_encoding="cdr", schema_id=sid)
        w.add_message(cid, log_time=EPOCH, publish_time=EPOCH, sequence=0,
                      data=b"\x00\x01\x00\x00" + bytes(20))
        w.finish()
    with FlightLog(other) as log, pytest.raises(LogError, match="not a fixed-size channel"):
        log.read("/truth/state")


def test_layouts_are_bit_exact_with_the_ros2_reference_encoder():
    """Every contract schema encoded by the vectorised layout equals mcap_ros2's encoder."""
    from mcap_ros2._dynamic import serialize_dynamic
    stamp = EPOCH + 123_456_789
    header = {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9}}
    cases = {
        S.NAV_SAT_FIX: ("gps", dict(status=1, service=3, latitude=0.7, longitude=-1.2,
                                    altitude=1600.5, position_covariance=[0.01] * 9,
                                    position_covariance_type=2)),
        S.NAV_STATE: ("vehicle", dict(latitude=0.1, longitude=0.2, height=3.0,
                                      velocity_ned=[1.0, 2.0, 3.0],
                                      attitude_wxyz=[1.0, 0.0, 0.0, 0.0])),
        S.RAW_MIMU: ("mimu", dict(sample_index=9, gyro_volts=[1.0, 2, 3], accel_volts=[4.0, 5, 6],
                                  accel_temperature=[7.0, 8, 9], gyro_frequency=[1e4, 2e4, 3e4])),
        S.LAB_STATE: ("lab", dict(point=5, position=2, steady=1,
                                  fixture_attitude_wxyz=[0.5, 0.5, -0.5, 0.5],
                                  position_m=[6.5, 0.0, 0.1], table_angle=1.25,
                                  table_rate=-6.9, sensor_radius_m=[6.5] * 6,
                                  chamber_temperature=25.0)),
    }
    for name, (frame, fields) in cases.items():
        ref_fields = dict(fields)
        if name == S.NAV_SAT_FIX:
            ref_fields = {k: v for k, v in fields.items() if k not in ("status", "service")}
            ref_fields["status"] = {"status": fields["status"], "service": fields["service"]}
        ref = serialize_dynamic(name, S.SCHEMAS[name].decode())[name](
            dict(header=dict(header, frame_id=frame), **ref_fields))
        ours = S.encode(name, frame, [stamp], **{k: [v] for k, v in fields.items()})
        assert bytes(ref) == ours.tobytes(), name


def test_gaps_are_missing_samples_not_jitter():
    """Issue 16: sampling jitter was reported as hundreds of 'gaps'. Stamps jittered by
    +-3 ms on a 10 ms period (steps of 4-16 ms) with no sample missing give no gap; three
    samples taken out give one gap of three; a clock 1e-4 fast is followed."""
    from mimunav.flightlog.stamps import missing_samples
    rng = np.random.default_rng(4)
    nominal = np.arange(5000) * 10_000_000
    jittered = nominal + rng.uniform(-3e6, 3e6, len(nominal)).astype(np.int64)
    jittered.sort()
    assert missing_samples(jittered) == []
    holed = np.delete(jittered, [2000, 2001, 2002])
    assert missing_samples(holed) == [(1999, 3)]
    assert missing_samples(np.delete(nominal, [10])) == [(9, 1)]
    assert missing_samples((jittered * 1.0001).astype(np.int64)) == []
    # 2 % of the samples lost at random, alone or in runs: every one counted (a period from
    # the median of 100-step means alone, 10.2 ms, had missed half of them)
    lost = np.sort(rng.choice(np.arange(1, len(jittered) - 1), 100, replace=False))
    assert sum(m for _, m in missing_samples(np.delete(jittered, lost))) == 100
    # a logger switched from 100 to 50 Hz: a new rate, not 2500 missing samples; a gap in
    # the 50 Hz part counts in its own period
    from mimunav.flightlog.stamps import rate_segments
    switched = np.concatenate([jittered[:2500], jittered[2499] + 20_000_000 * np.arange(1, 2501)])
    assert [round(1e9 / p) for _, _, p in rate_segments(switched)] == [100, 50]
    assert missing_samples(switched) == []
    assert missing_samples(np.delete(switched, [4000, 4001])) == [(3999, 2)]
    # a switch by 15 % (100 -> 118 Hz, +-0.5 ms of jitter) is a new rate too, not gaps
    fine = nominal + rng.uniform(-5e5, 5e5, len(nominal)).astype(np.int64)
    near = np.concatenate([fine[:2500], fine[2499] + np.round(1e9 / 118 * np.arange(1, 2501))
                           .astype(np.int64)])
    assert [round(1e9 / p) for _, _, p in rate_segments(near)] == [100, 118]
    assert missing_samples(near) == []


@pytest.mark.slow
def test_the_bulk_writer_makes_mcap_the_mcap_package_validates(tmp_path):
    """Our own record layouts checked by an implementation we did not write: the `mcap`
    package streams every record with CRCs validated (chunks, indexes, summary, footer),
    finds the summary through the footer and its offsets (statistics, chunk and metadata
    indexes agree with the data), decodes every message by mcap_ros2 to the values written,
    and returns the metadata and the attachment; this project's recovery walk finds the
    file complete."""
    from mcap.reader import make_reader
    from mcap.records import Footer
    from mcap.stream_reader import StreamReader
    from mcap_ros2.decoder import DecoderFactory
    from mimunav.flightlog.recover import scan
    n = 25_000                                   # several chunks at a 64 KiB chunk size
    stamps = EPOCH + np.arange(n, dtype=np.int64) * 1_000_000
    rng = np.random.default_rng(3)
    w, f = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    src = tmp_path / "src.mcap"
    with LogWriter(src) as log:
        log.write("/other", S.IMU, "x", stamps[:10], **S.imu_fields(w[:10], f[:10]))
    path = tmp_path / "bulk.mcap"
    with LogWriter(path, chunk_size=1 << 16) as log:
        log.metadata("flight", {"epoch_unix_ns": str(EPOCH), "n": n})
        log.write("/fog/imu", S.IMU, "fog", stamps, **S.imu_fields(w, f))
        log.attachment("note.txt", b"hello", "text/plain")
        with open(src, "rb") as fh:
            for schema, channel, message in make_reader(fh).iter_messages():
                log.copy(schema, channel, message)
    with open(path, "rb") as fh:
        records = list(StreamReader(fh, validate_crcs=True).records)
    assert isinstance(records[-1], Footer)
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        topics = {c.id: c.topic for c in summary.channels.values()}
        assert {topics[c]: k for c, k in summary.statistics.channel_message_counts.items()} == \
            {"/fog/imu": n, "/other": 10}
        assert summary.statistics.chunk_count == len(summary.chunk_indexes) > 3
        got = [(m.log_time, ros.angular_velocity.y, ros.linear_acceleration.z)
               for _, channel, m, ros in reader.iter_decoded_messages(topics=["/fog/imu"])]
        assert [g[0] for g in got] == stamps.tolist()
        np.testing.assert_array_equal([g[1] for g in got], w[:, 1])
        np.testing.assert_array_equal([g[2] for g in got], f[:, 2])
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        assert meta["flight"]["n"] == str(n)
        (att,) = list(reader.iter_attachments())
        assert att.data == b"hello" and att.media_type == "text/plain"
    report = scan(path)
    assert report["complete"] and report["channels"]["/fog/imu"][0] == n


def test_a_stamp_late_past_half_a_period_is_no_missed_sample():
    """An INS's stamps late of a 10 ms grid by 0-3 ms, one in a hundred by 4-6.5 ms: a late
    stamp rounds into the next slot, which its successor then takes - no sample missed (156
    had been counted, and the rate read 100.6 Hz); samples taken out still count, also
    where the stamp after the hole is late."""
    from mimunav.flightlog.stamps import mean_rate_hz, missing_samples
    rng = np.random.default_rng(83)
    late = rng.uniform(0, 3e6, 25000)
    spikes = rng.random(25000) < 0.01
    late[spikes] = rng.uniform(4e6, 6.5e6, spikes.sum())
    stamps = (np.arange(25000) * 10_000_000 + late).astype(np.int64)
    assert missing_samples(stamps) == []
    assert abs(mean_rate_hz(stamps) - 100.0) < 0.01
    k = int(np.flatnonzero(spikes)[50])
    holed = np.delete(stamps, [k - 1, 9000, 9001])
    assert sum(m for _, m in missing_samples(holed)) == 3


def test_stamps_jittered_by_a_third_of_a_period_miss_no_more_samples_than_the_span_holds():
    """A quadruped's IMU stamped on a 10 ms grid 2.5 ms rms off it, one in twelve late by
    7 ms more on average (steps of 0-31 ms, its offsets skewed late as the real file's): the
    slots cannot place every stamp, and the period fitted from the span over them had
    settled at 9.8 ms with 45-70 'missed' samples in 2400 where none was - the span holds
    no missing sample, so at most the end stamps' jitter may read as one or two; four taken
    out are counted, and the rate is read within 0.1 Hz. Its phase stays bounded: no
    free-running sampler (the steps' lag-1 correlation, -0.29 on the real file, had classed
    one draw in six free running, and 39 samples 'missed')."""
    from mimunav.flightlog.stamps import free_running, mean_rate_hz, missing_samples
    for seed in range(6):
        rng = np.random.default_rng(seed)
        offset = rng.normal(0, 2.5e6, 2400)
        late = rng.random(2400) < 0.08
        offset[late] += rng.exponential(7e6, late.sum())
        stamps = np.round(np.sort(np.arange(2400) * 10e6 + offset)).astype(np.int64)
        assert not free_running(np.diff(stamps).astype(float))
        assert sum(m for _, m in missing_samples(stamps)) <= 2
        assert abs(mean_rate_hz(stamps) - 100.0) < 0.1
        held = np.delete(stamps, [500, 1500, 1501, 1502])
        assert 4 <= sum(m for _, m in missing_samples(held)) <= 6


def test_a_grids_lost_samples_and_a_hosts_bursts_are_read_for_what_they_are():
    """5 % of a 100 Hz grid's samples lost (2 ms rms of jitter): every one counted and the
    rate 100 Hz - a period from the median of 100-step means is 5 % long, and the spans over
    lost samples had read the grid as free running (168 counted, 96.7 Hz). A host stamping a
    400 Hz part's reads in bursts every 16 ms (20 us apart, or all alike): no grid of one
    sample each - the slot refit had settled on the 20 us inside a burst (50 kHz, three
    million 'missed'), or divided by zero; read no worse than the span over the slots."""
    from mimunav.flightlog.stamps import free_running, mean_rate_hz, missing_samples
    rng = np.random.default_rng(10)
    stamps = np.sort(np.arange(10000) * 10e6 + rng.normal(0, 2e6, 10000))
    lost = rng.choice(np.arange(1, 9999), 500, replace=False)
    held = np.delete(stamps, lost).astype(np.int64)
    assert not free_running(np.diff(held).astype(float))
    assert sum(m for _, m in missing_samples(held)) == 500
    assert abs(mean_rate_hz(held) - 100.0) < 0.05
    true = np.arange(24000) * 2.5e6
    reads = np.arange(0, true[-1] + 16e6, 16e6)
    read = np.searchsorted(reads, true)
    first = np.r_[0, np.flatnonzero(np.diff(read)) + 1]
    within = np.arange(len(true)) - np.repeat(first, np.diff(np.r_[first, len(true)]))
    for burst in ((reads[read] + within * 20e3).astype(np.int64), reads[read].astype(np.int64)):
        assert mean_rate_hz(burst) < 500.0
    # the uniform clock behind the reads (`burst_clock`, which the import applies): the
    # samples' times to 1 us, and no clock for a grid that is no burst - two 10 min runs 2 h
    # apart (their mean step 4 times the median: they had been 'one read'), a radio link
    # losing 5 samples at a time
    from mimunav.flightlog.stamps import burst_clock
    uniform, said = burst_clock((reads[read] + within * 20e3).astype(np.int64))
    assert np.abs((uniform - uniform[0]) - true).max() < 1e3 and "bursts" in said
    assert burst_clock(np.r_[true, true[-1] + 7.2e12 + true].astype(np.int64))[0] is None
    keep = np.ones(200, bool)
    for start in (20, 60, 100, 140, 180):
        keep[start:start + 5] = False
    assert burst_clock((np.arange(200) * 10_000_000)[keep])[0] is None
    # a grid recording 0.5 s every 2 s (duty-cycled): its samples 10 ms apart in a window are
    # no read's (a clock through the windows had moved its stamps by seconds)
    cycled = np.arange(20000) * 10_000_000
    assert burst_clock(cycled[(cycled // 10_000_000) % 200 < 50])[0] is None


@pytest.mark.parametrize("lost, jitter_ms", [(0.2, 1.0), (0.3, 2.0), (0.3, 3.0), (0.1, 3.0)])
def test_a_grid_that_lost_a_third_of_its_samples_is_counted_whole(lost, jitter_ms):
    """A 100 Hz grid jittered by 1-3 ms rms that lost 10-30 % of its samples at random (a
    wireless link's drops): the period is the one whose phasor sum over the stamps is
    largest, which lost samples leave whole - the slope within the runs between gaps had
    been pulled by every gap placed a step off (20 % lost, 1 ms: 382 of 431 counted; 30 %,
    3 ms: the channel split into 'rates' of 9.3 and 10.3 ms and read 80 Hz). Every lost
    sample counted, to the end stamps' jitter, one rate, and the rate within 0.1 Hz."""
    from mimunav.flightlog.stamps import mean_rate_hz, missing_samples, rate_segments
    for seed in range(3):
        rng = np.random.default_rng(seed)
        keep = rng.random(2000) > lost
        keep[[0, -1]] = True
        stamps = np.sort(np.round(np.arange(2000) * 10e6 + rng.normal(0, jitter_ms * 1e6, 2000))
                         [keep]).astype(np.int64)
        counted = sum(m for _, m in missing_samples(stamps))
        assert abs(counted - (2000 - keep.sum())) <= (0 if jitter_ms < 3 else 2)
        assert len(rate_segments(stamps)) == 1
        assert abs(mean_rate_hz(stamps) - 100.0) < 0.1


def test_the_grid_lock_keeps_off_what_is_no_one_grid():
    """An independent review of the phasor lock: a 100 -> 50 Hz switch on one clock that
    lost 2 % stays two rates with its losses counted (a lock over both had merged them, 0
    counted); a free-running sampler's 3 % interval jitter is no grid (its chunks' phases
    wander: it had locked, 875 of 959 counted); stamps in whole ms of a 600 Hz part sum
    alike at 400 Hz, so no lock is tried (it had read 537.7 Hz); a lone first stamp before
    a pause, a swapped pair and a clock stepped back read without an error (they had
    divided by zero or binned negative times)."""
    from mimunav.flightlog.stamps import _locked_grid, missing_samples, rate_segments
    ms = 1_000_000
    keep = np.random.default_rng(1).random(6000) >= 0.02
    keep[[0, -1]] = True
    switched = np.r_[np.arange(3000) * 10 * ms, 30_000 * ms + np.arange(3000) * 20 * ms][keep]
    assert len(rate_segments(switched)) == 2
    assert abs(sum(m for _, m in missing_samples(switched)) - (~keep).sum()) <= 1
    rng = np.random.default_rng(0)
    steps = np.maximum(5 * ms * (1 + 0.03 * rng.normal(0, 1, 49999)), 0.25 * ms)
    free = np.r_[0, np.cumsum(steps)]
    keep = rng.random(50000) >= 0.02
    keep[[0, -1]] = True
    free = np.round(free[keep]).astype(np.int64)
    assert sum(m for _, m in missing_samples(free)) == (~keep).sum()
    k = np.flatnonzero(np.random.default_rng(0).random(8000) >= 0.1)
    in_ms = np.floor((k + 0.37) * 1e3 / 600) * ms
    assert _locked_grid(in_ms - in_ms[0], 1e9 / 600) is None
    grid = np.arange(5000) * 10 * ms
    swapped, back = grid.copy(), grid.copy()
    swapped[[0, 1]] = swapped[[1, 0]]
    back[30:] -= 500 * ms
    assert missing_samples(np.r_[0, 25_000 * ms + grid]) == [(0, 2499)]
    assert missing_samples(swapped) == [] and missing_samples(back) == []


def test_gaps_on_a_schedule_are_said_to_be_one():
    """An x-IMU's stamps are its packet numbers: a packet of another kind after every 128
    inertial samples steps them as a lost sample would (98 'missed', 258 Hz for 256) - the
    gaps' schedule is said, also beside a few samples truly lost; gaps at random, or of
    different sizes, say nothing."""
    from mimunav.flightlog.stamps import missing_samples, scheduled
    grid = np.arange(12724) * 3_876_000
    gaps = missing_samples(np.delete(grid, np.arange(128, 12724, 129)))
    assert len(gaps) == 98 and "recur every 128 samples, each of 1" in scheduled(gaps)
    # three samples truly lost beside the schedule (an independent review: it had gone silent)
    beside = missing_samples(np.delete(grid, np.r_[np.arange(128, 12724, 129), 1000, 5000, 9001]))
    assert "95 of the 101 gaps recur every 128 samples" in scheduled(beside)
    rng = np.random.default_rng(5)
    assert scheduled(missing_samples(np.delete(grid, rng.choice(12724, 98, replace=False)))) == ""
    assert scheduled([(128 * k, 1 + k % 2) for k in range(1, 40)]) == ""


def test_a_free_running_samplers_jitter_is_no_gap():
    """A sampler whose intervals jitter one by one (a phone's sensor events: 10 ms +- 1.5 ms
    each, clipped to 5-16 ms, so its phase wanders without bound) - a grid's slots had read
    2315 gaps where 7 were: every gap reported is one of the true ones, the 4-sample gap is
    counted whole, and no more than one lone lost sample in ten goes uncounted (a step of 2
    periods that its jitter shortens below the longest step jitter alone makes)."""
    from mimunav.flightlog.stamps import free_running, missing_samples
    rng = np.random.default_rng(45)
    steps = np.clip(rng.normal(10e6, 1.5e6, 66000), 5e6, 16e6)
    stamps = np.concatenate([[0], np.cumsum(steps)]).astype(np.int64)
    assert free_running(np.diff(stamps).astype(float))
    lone = [5000, 15000, 25000, 35000, 45000, 55000]
    held = np.delete(stamps, lone + [60000, 60001, 60002, 60003])
    found = dict(missing_samples(held))
    truth = {k - i - 1: 1 for i, k in enumerate(lone)}
    truth[60000 - len(lone) - 1] = 4
    assert set(found) <= set(truth), sorted(set(found) - set(truth))
    assert found[60000 - len(lone) - 1] == 4
    assert len(found) >= len(truth) - 1
    # a grid's jitter is not free running: its steps alternate long and short
    grid = np.arange(5000) * 10_000_000 + rng.uniform(-3e6, 3e6, 5000)
    assert not free_running(np.diff(np.sort(grid)))


def test_a_channels_rate_is_its_mean_over_the_span_missing_samples_counted():
    """One rate: (samples - 1 + missing) over the span - steps whose median is not their
    mean (a logger's stamps: 9.99999 ms three times in five, 10.000015 twice) had read the
    median's rate (a new user's 100.001 Hz for 60,000 samples over 599.99 s); a lost sample
    does not lower it."""
    from types import SimpleNamespace
    from mimunav.flightlog.inspect import channel_report

    def report(stamps):
        msgs = np.zeros(len(stamps), dtype=[("log_time", np.uint64)])
        msgs["log_time"] = stamps
        log = SimpleNamespace(read=lambda topic: msgs, schema_name=lambda topic: "x",
                              time_reversals={})
        return channel_report(log, "/x")
    steps = np.tile([9999990, 9999990, 9999990, 10000015, 10000015], 12000)   # mean 10 ms
    rounded = np.concatenate([[0], np.cumsum(steps)])[:60000]
    assert 1e9 / np.median(np.diff(rounded)) > 100.0001          # the median step's rate
    assert report(rounded)["rate_hz"] == pytest.approx(100.0, abs=1e-6)
    lost = report(np.delete(rounded, [30000]))
    assert lost["missing"] == 1 and lost["rate_hz"] == pytest.approx(100.0, abs=1e-6)


def test_a_long_jittered_lossy_grid_is_one_rate_read_in_its_time():
    """A 50-minute phone log at 200 Hz, its stamps jittered by a fifth of a period and a
    fifth of its samples lost: its 100-step block medians scatter by 3.5 %, so a change of
    rate must stand out of that scatter (`CHANGE_SIGMAS`), not 5 % alone - it had been cut
    into 14 rates, read 183.5 Hz by its median step, in 35 s (2 M stamps: 196 s)."""
    from mimunav.flightlog.stamps import mean_rate_hz, rate_segments
    rng = np.random.default_rng(0)
    n = 600_000
    t = np.arange(n) * 0.005 + rng.normal(0, 0.2 * 0.005, n)
    t = np.sort((t[rng.random(n) >= 0.2] * 1e9).astype(np.int64) + 10 ** 18)
    assert len(rate_segments(t)) == 1
    assert mean_rate_hz(t) == pytest.approx(200.0, rel=1e-4)
    # a logger switched from 200 to 180 Hz under the same jitter: two rates still
    step = np.r_[np.full(n // 2, 5e6), np.full(n // 2, 5e6 * 200 / 180)]
    switched = np.cumsum(step) + rng.normal(0, 0.2 * 5e6, n)
    switched = np.sort(switched[rng.random(n) >= 0.2].astype(np.int64) + 10 ** 18)
    assert len(rate_segments(switched)) == 2


def test_stamps_in_whole_ms_of_a_uniform_clock_give_back_that_clock():
    """A flight computer's millis() of a 501.3 Hz part (steps of 1, 2 and 3 ms) with a 0.4 s
    gap: each run between gaps fitted by a line, every stamp within a tick of it, and the
    true times come back to a few microseconds (the rounding's own error is 0.29 ms rms);
    the words say so, and at 833 Hz (steps of 1 and 2 ms) too. Exact stamps, and stamps
    that jitter by 3 ms or by 0.35 ms under the rounding (a scheduler's), keep theirs."""
    from mimunav.flightlog.stamps import rounded_clock
    true_s = 12.0 + np.arange(30000) / 501.3
    true_s = np.delete(true_s, np.arange(10000, 10200))            # 0.4 s lost
    ns = (np.floor(true_s * 1e3) * 1e6).astype(np.int64)
    clock, said = rounded_clock(ns)
    error = (clock - ns[0]) / 1e9 - (true_s - true_s[0])
    assert np.ptp(error[:10000]) < 2e-5 and np.ptp(error[10000:]) < 2e-5
    assert abs(np.median(error) + 5e-4) < 1e-4         # floor's half tick: one constant
    assert "whole 1 ms of a uniform 501.3 Hz clock" in said and "2 run(s)" in said
    assert rounded_clock((true_s * 1e9).astype(np.int64)) == (None, "")
    rng = np.random.default_rng(0)
    jittered = np.sort(np.round((true_s + rng.uniform(-3e-3, 3e-3, len(true_s))) * 1e3))
    assert rounded_clock(np.unique(jittered * 1e6).astype(np.int64))[0] is None
    # timing under a tick (+-0.35 ms on the whole-ms rounding): kept, not flattened
    late = np.round((true_s + rng.uniform(-3.5e-4, 3.5e-4, len(true_s))) * 1e3) * 1e6
    assert rounded_clock(late.astype(np.int64))[0] is None
    # an 833 Hz part in whole ms steps by 1 and 2 ms: none of them is a gap
    fast = (np.floor((5.0 + np.arange(20000) / 833.0) * 1e3) * 1e6).astype(np.int64)
    clock, said = rounded_clock(fast)
    assert "uniform 833 Hz clock" in said and "1 run(s)" in said

"""The logs mimunav writes, read by code it did not write: Foxglove's own MCAP and ROS 2
decoding stack (TypeScript: @mcap/core's stream and indexed readers with CRCs checked,
@foxglove/rosmsg's schema parser, @foxglove/rosmsg2-serialization's CDR reader, fzstd),
which Foxglove Studio reads MCAP with - `tests/oracle/read_mcap.js`, its versions pinned in
`tests/oracle/package-lock.json`. The Python `mcap` / `mcap_ros2` packages check the same
files in test_flightlog.py; this is a second implementation, in another language.

Needs node and npm (the npm registry once: the packages are cached under
~/.cache/mimunav); without them the tests are skipped, saying why."""
import hashlib
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mimunav.flightlog import FlightLog, LogWriter
from mimunav.flightlog import schemas as S
from places import TESTS

ORACLE = TESTS / "oracle"
EPOCH = 1_767_225_600 * 10**9


@pytest.fixture(scope="module")
def foxglove(tmp_path_factory):
    """read(path) -> (head, {topic: [message lines]}) by tests/oracle/read_mcap.js."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if not node or not npm:
        pytest.skip("node and npm are needed for Foxglove's MCAP reader (not on this machine)")
    lock = (ORACLE / "package-lock.json").read_bytes()
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "mimunav"
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError:                         # a home that cannot be written (a CI sandbox)
        cache = tmp_path_factory.mktemp("npm-cache")
    home = cache / f"mcap-oracle-{hashlib.sha256(lock).hexdigest()[:12]}"
    if not (home / "node_modules" / "@mcap" / "core").is_dir():
        tmp = Path(cache / f".{home.name}.{os.getpid()}")
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        for name in ("package.json", "package-lock.json"):
            shutil.copy(ORACLE / name, tmp / name)
        try:
            run = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--ignore-scripts"],
                                 cwd=tmp, capture_output=True, text=True, timeout=300)
        except subprocess.TimeoutExpired:
            run = None
        if run is None or run.returncode:
            shutil.rmtree(tmp, ignore_errors=True)
            pytest.skip("npm could not install Foxglove's MCAP reader (registry out of reach?): "
                        + ("timeout" if run is None else run.stderr.strip()[-300:]))
        try:
            os.replace(tmp, home)
        except OSError:                    # another process installed it meanwhile
            shutil.rmtree(tmp, ignore_errors=True)

    def read(path):
        run = subprocess.run([node, str(ORACLE / "read_mcap.js"), str(path)],
                             capture_output=True, text=True, timeout=600,
                             env=dict(os.environ, NODE_PATH=str(home / "node_modules")))
        assert run.returncode == 0, run.stderr
        lines = run.stdout.splitlines()
        head, messages = json.loads(lines[0]), {}
        for line in lines[1:]:
            m = json.loads(line)
            messages.setdefault(m["topic"], []).append(m)
        return head, messages
    return read


def _body(schema, message):
    """Foxglove's decoded message as this project's field names (schemas.BODIES)."""
    m = message
    if schema == S.IMU:
        xyz = lambda v: [v["x"], v["y"], v["z"]]              # noqa: E731
        return {"orientation": xyz(m["orientation"]) + [m["orientation"]["w"]],
                "orientation_covariance": m["orientation_covariance"],
                "angular_velocity": xyz(m["angular_velocity"]),
                "angular_velocity_covariance": m["angular_velocity_covariance"],
                "linear_acceleration": xyz(m["linear_acceleration"]),
                "linear_acceleration_covariance": m["linear_acceleration_covariance"]}
    if schema == S.NAV_SAT_FIX:
        return dict({k: v for k, v in m.items() if k not in ("header", "status")},
                    status=m["status"]["status"], service=m["status"]["service"])
    if schema == S.JOINT_STATE:
        assert m["name"] == [S.PLATFORM_JOINT] and m["effort"] == []
        return {"position": m["position"][0], "velocity": m["velocity"][0]}
    body = {k: v for k, v in m.items() if k != "header"}
    if "sample_index" in body:
        body["sample_index"] = int(body["sample_index"])
    return body


def _as_arrays(schema, lines):
    """{field: array (N, ...)} of a channel's messages as Foxglove decoded them, with the
    header stamps (ns) and frame ids and the records' log times."""
    bodies = [_body(schema, m["message"]) for m in lines]
    out = {k: np.array([b[k] for b in bodies]) for k in bodies[0]}
    out["stamp_ns"] = np.array([m["message"]["header"]["stamp"]["sec"] * 10**9
                                + m["message"]["header"]["stamp"]["nanosec"] for m in lines])
    out["frame_id"] = {m["message"]["header"]["frame_id"] for m in lines}
    out["log_time"] = np.array([int(m["log_time"]) for m in lines], dtype=np.int64)
    return out


@pytest.mark.slow
def test_foxglove_decodes_every_contract_schema_to_the_values_written(foxglove, tmp_path):
    """Every schema of the contract and of mimunav's extensions, written by the vectorised
    writer in many small chunks with metadata and an attachment: Foxglove's stream reader
    walks every record with its CRC and ends cleanly, its indexed reader finds the summary,
    the statistics count what was written, and every message decodes to the very doubles,
    integers and stamps written."""
    rng = np.random.default_rng(5)
    n = 3000
    stamps = EPOCH + np.arange(n, dtype=np.int64) * 1_000_000 + rng.integers(0, 999, n)
    unit = lambda *shape: rng.normal(size=(n,) + shape)          # noqa: E731
    channels = {
        "/mimu/raw": (S.RAW_MIMU, "mimu", dict(
            sample_index=np.arange(n, dtype=np.uint64) + 2**40, gyro_volts=unit(3),
            accel_volts=unit(3), accel_temperature=20 + unit(3), gyro_frequency=3e4 + unit(3))),
        "/fog/imu": (S.IMU, "fog", S.imu_fields(unit(3) * 1e-3, unit(3) * 9.8)),
        "/truth/state": (S.NAV_STATE, "vehicle", dict(
            latitude=unit(), longitude=unit(), height=1e3 * unit(), velocity_ned=unit(3),
            attitude_wxyz=unit(4))),
        "/gnss/fix": (S.NAV_SAT_FIX, "gnss", dict(
            status=rng.integers(-1, 3, n).astype(np.int8),
            service=rng.integers(0, 16, n).astype(np.uint16), latitude=unit(), longitude=unit(),
            altitude=unit(), position_covariance=unit(9),
            position_covariance_type=rng.integers(0, 4, n).astype(np.uint8))),
        "/lab/state": (S.LAB_STATE, "lab", dict(
            point=rng.integers(0, 2**32, n, dtype=np.uint32),
            position=rng.integers(0, 100, n).astype(np.uint32),
            steady=rng.integers(0, 2, n).astype(np.uint8), fixture_attitude_wxyz=unit(4),
            position_m=unit(3), table_angle=unit(), table_rate=unit(), sensor_radius_m=unit(6),
            chamber_temperature=unit())),
        "/mimu/platform": (S.JOINT_STATE, "platform", S.platform_fields(unit(), unit())),
    }
    path = tmp_path / "all.mcap"
    meta = {"epoch_unix_ns": str(EPOCH), "note": "ünïcode, \"quoted\""}
    with LogWriter(path, chunk_size=1 << 15) as log:
        log.metadata("flight", meta)
        for topic, (schema, frame, fields) in channels.items():
            log.write(topic, schema, frame, stamps, **fields)
        log.attachment("note.txt", b"hello", "text/plain")
    head, messages = foxglove(path)
    assert head["stream"]["done"]
    assert head["stream"]["records"]["Message"] == n * len(channels)
    assert head["statistics"]["chunk_count"] > 10
    assert head["statistics"]["channel_message_counts"] == {t: str(n) for t in channels}
    assert head["statistics"]["message_start_time"] == str(stamps[0])
    assert head["statistics"]["message_end_time"] == str(stamps[-1])
    assert head["metadata"] == {"flight": meta}
    assert head["attachments"] == [{"name": "note.txt", "media_type": "text/plain", "size": 5}]
    assert {c["topic"]: c["schema"] for c in head["channels"]} == \
        {t: s for t, (s, _, _) in channels.items()}
    for topic, (schema, frame, fields) in channels.items():
        got = _as_arrays(schema, messages[topic])
        assert np.array_equal(got["log_time"], stamps), topic
        assert np.array_equal(got["stamp_ns"], stamps), topic
        assert got["frame_id"] == {frame}, topic
        for name, value in fields.items():
            if name.endswith("_count"):
                continue
            assert np.array_equal(got[name], np.asarray(value)), (topic, name)


@pytest.mark.slow
def test_foxglove_reads_a_simulated_flight_and_its_compensated_log_as_mimunav_does(
        foxglove, tmp_path):
    """A flight as `mimunav simulate` makes it (the writer's threads, 1 MiB chunks, the
    flight, sensor and reference metadata) and the log `compensate` derives from it
    (/mimu/imu written, every other channel copied record by record): Foxglove's readers
    find the same messages, values and metadata as mimunav's reader."""
    from mimunav.compensation.calibration_file import Calibration
    from mimunav.compensation.log import compensate_log
    from mimunav.motion.profile import Profile
    from mimunav.sensors.simulation import simulate_flight
    doc = {"name": "short", "start": {"latitude_deg": 40, "longitude_deg": 116, "height_m": 900,
                                      "speed_m_s": 100, "heading_deg": 10, "ramp_s": 1.0},
           "segment": [{"kind": "turn", "load_factor": 1.5, "heading_change_deg": 60,
                        "roll_rate_deg_s": 20}]}
    log, truth = simulate_flight(Profile.from_dict(doc), str(tmp_path / "short.mcap"), 3,
                                 fog_rate=500.0, progress=False)
    cal = Calibration.from_dict(json.loads(Path(truth).read_text())["mimu"]["coefficients"])
    compensated = tmp_path / "compensated.mcap"
    compensate_log(log, cal, str(compensated))
    for path in (log, compensated):
        head, messages = foxglove(path)
        assert head["stream"]["done"]
        with FlightLog(path) as ours:
            assert {name: {k: _json_or_text(v) for k, v in values.items()}
                    for name, values in head["metadata"].items()} == ours.metadata()
            assert {"flight", "sensor/mimu", "sensor/fog"} <= set(head["metadata"])
            assert set(messages) == set(ours.channels)
            for topic in ours.channels:
                schema = ours.summary.schemas[ours.channels[topic].schema_id].name
                mine = ours.read(topic)
                got = _as_arrays(schema, messages[topic])
                assert len(mine) > 100, topic
                assert np.array_equal(got["log_time"], mine["log_time"].astype(np.int64))
                assert np.array_equal(got["stamp_ns"], S.stamps_ns(mine)), topic
                assert got["frame_id"] == {mine["frame_id"][0].decode()}, topic
                body = [name for name, _, _ in S.BODIES[schema] if not name.endswith("_count")
                        and name != "name"]
                for name in body:
                    assert np.array_equal(got[name], mine[name]), (path, topic, name)


def _json_or_text(value):
    """A metadata value as mimunav's reader gives it: JSON decoded where it parses."""
    try:
        return json.loads(value)
    except ValueError:
        return value

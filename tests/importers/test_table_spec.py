"""A table spec is read as written or refused, never guessed (`importers.table`): unknown keys
refused naming the nearest (`scale` had been ignored, so a 10 us tick became a time base 10x
too short), any count size as a scale, increments instead of rates, a logger's repeated rows,
Excel's `sep=` line, a second clock's offset per section, and the sensor's range with its
clipped samples counted."""
import numpy as np
import quaternion
import pytest

from mimunav.flightlog import FlightLog
from mimunav.importers import table
from mimunav.importers.recording import RecordingError
from mimunav.importers.write import write_log

N, RATE = 4000, 100.0
SPEC = """name = "t"
[imu]
time = {{ file = "imu.csv", columns = ["tick"], unit = "us", scale = 10 }}
{rate}
{force}
axes = "FRD"
{extra}
[time]
unix_offset_s = 1700000000.0
"""
RATES = 'angular_rate = { file = "imu.csv", columns = ["gx", "gy", "gz"] }'
FORCES = 'specific_force = { file = "imu.csv", columns = ["ax", "ay", "az"] }'


def _imu(tmp_path, rate=RATES, force=FORCES, extra="", rows=None, sep=None, edit=None,
         clip=np.inf):
    t = np.arange(1, N + 1) / RATE
    w = np.clip(0.2 * np.sin(2 * np.pi * 0.3 * t[:, None] + [0.0, 1.0, 2.0]), -clip, clip)
    f = np.tile([0.5, 0.0, -9.8], (N, 1))
    data = np.column_stack([np.round(t * 1e5), w, f, w / RATE, f / RATE])
    if rows is not None:
        data = data[rows]
    if edit is not None:
        edit(data)
    header = "tick,gx,gy,gz,ax,ay,az,dx,dy,dz,vx,vy,vz"
    text = "\n".join([header] + [",".join(f"{v:.10g}" for v in row) for row in data]) + "\n"
    if sep:
        text = f"sep={sep}\n" + text.replace(",", sep)
    (tmp_path / "imu.csv").write_text(text)
    (tmp_path / "spec.toml").write_text(SPEC.format(rate=rate, force=force, extra=extra))
    return t, w, f


def test_a_tick_scale_gives_the_time_base_and_an_unknown_key_is_named(tmp_path):
    t, w, f = _imu(tmp_path)
    rec = table.read(tmp_path / "spec.toml")
    assert np.allclose((rec.imu_ns - rec.imu_ns[0]) / 1e9, t - t[0], atol=1e-6)
    assert np.allclose(rec.w, w) and np.allclose(rec.f, f)
    (tmp_path / "spec.toml").write_text(SPEC.format(rate=RATES, force=FORCES, extra="")
                                        .replace("scale = 10", "scal = 10"))
    with pytest.raises(RecordingError, match="unknown key 'scal' .did you mean 'scale'"):
        table.read(tmp_path / "spec.toml")
    (tmp_path / "spec.toml").write_text(SPEC.format(rate=RATES, force=FORCES,
                                                    extra="colums = 3"))
    with pytest.raises(RecordingError, match=r"\[imu\] has an unknown key 'colums'"):
        table.read(tmp_path / "spec.toml")
    # a UTM grid named otherwise (KAIST's poses): not the nearest key (position_ecef had been
    # offered), but the key that reads it
    (tmp_path / "spec.toml").write_text(SPEC.format(rate=RATES, force=FORCES,
                                                    extra="utm_easting = 3"))
    with pytest.raises(RecordingError, match=r"UTM grid coordinates are \[reference\] "
                       r"position_utm = \{file = ..., columns = \[easting, northing, height\], "
                       r"zone = 1-60"):
        table.read(tmp_path / "spec.toml")


def test_increments_are_divided_by_their_intervals(tmp_path):
    t, w, f = _imu(tmp_path, rate='angle_increment = { file = "imu.csv", columns = '
                                  '["dx", "dy", "dz"] }',
                   force='velocity_increment = { file = "imu.csv", columns = ["vx", "vy", "vz"] }')
    rec = table.read(tmp_path / "spec.toml")
    assert np.allclose(rec.w, w, atol=1e-9) and np.allclose(rec.f, f, atol=1e-9)


def test_repeated_rows_are_left_out_and_a_separator_line_is_read(tmp_path):
    rows = np.r_[np.arange(100), 99, 99, np.arange(100, N)]      # sample 99 written 3 times
    _imu(tmp_path, rows=rows, sep=";")
    rec = table.read(tmp_path / "spec.toml")
    assert len(rec.imu_ns) == N
    assert "2 rows repeating the row before" in rec.real["repeated [imu]"]
    _imu(tmp_path, rows=rows, sep=";", edit=lambda d: d[100].__setitem__(1, 0.7))
    with pytest.raises(RecordingError, match="repeats the time .* with other values"):
        table.read(tmp_path / "spec.toml")
    # Consensys's export: the line quoted, lines ending CRLF (its columns had been refused as
    # of another count than the first line's); a compressed file is named as such (a numpy
    # error about pickles had been the answer)
    _imu(tmp_path, sep="\t")
    text = (tmp_path / "imu.csv").read_text().replace("sep=\t", '"sep=\t"')
    (tmp_path / "imu.csv").write_bytes(text.replace("\n", "\r\n").encode())
    assert len(table.read(tmp_path / "spec.toml").imu_ns) == N
    (tmp_path / "spec.toml").write_text((tmp_path / "spec.toml").read_text().replace(
        '"imu.csv"', '"imu.csv.gz"'))
    (tmp_path / "imu.csv.gz").write_bytes(b"\x1f\x8b")
    with pytest.raises(RecordingError, match="a compressed file - decompress it"):
        table.read(tmp_path / "spec.toml")


def test_a_sections_own_clock_offset_and_the_sensors_range(tmp_path):
    clip = np.radians(10.0)                                 # a gyro of +-10 deg/s clips
    t, w, f = _imu(tmp_path, clip=clip,
                   extra="time_offset_s = 2.5\nrange = { angular_rate = { value = 10, unit = "
                         "\"deg/s\" }, specific_force = { value = 4, unit = \"g\" } }")
    rec = table.read(tmp_path / "spec.toml")
    assert abs(rec.imu_ns[0] - (0.01 + 2.5 + 1.7e9) * 1e9) < 1e3
    assert rec.range == pytest.approx({"gyro_rad_s": clip, "accel_m_s2": 4 * 9.80665})
    assert rec.real["clipped"].startswith(f"{int((np.abs(w) >= 0.999 * clip).any(1).sum())} "
                                          "samples at the range")
    assert "reach beyond it" not in rec.real["clipped"]
    # a range given below the outputs (a Shimmer's 500 deg/s beside calibrated rates to 729):
    # said not to be the sensor's
    _imu(tmp_path, clip=clip, extra="range = { angular_rate = { value = 8, unit = \"deg/s\" } }")
    said = table.read(tmp_path / "spec.toml").real["clipped"]
    assert "the rates to 1.25 times it reach beyond it" in said, said
    write_log(rec, tmp_path / "out.mcap")
    with FlightLog(tmp_path / "out.mcap") as log:
        assert log.metadata()["sensor/mimu"]["range"]["gyro_rad_s"] == pytest.approx(clip)


def test_per_column_signs_a_data_age_and_a_packet_written_twice(tmp_path):
    """`scale` per column flips a logger's own sign conventions; a time column's `age` is
    subtracted (a packet that arrived late); a row repeating the row before within half a
    step (the same packet written twice, its age-corrected time a tick apart) is one sample."""
    def edit(data):
        data[:, 0] += 1000.0 * (np.arange(len(data)) % 3)      # ticks of 10 us: 0, 10, 20 ms late
        data[:, 7] = 1000.0 * (np.arange(len(data)) % 3) / 100.0   # ... and that age, in ms
        data[11, 0] = data[10, 0] + 1.0                           # row 11: row 10 again,
        data[11, 1:7] = data[10, 1:7]                             # 10 us later
        data[11, 7] = data[10, 7]
    t, w, f = _imu(tmp_path, edit=edit)
    (tmp_path / "spec.toml").write_text(SPEC.format(
        rate='angular_rate = { file = "imu.csv", columns = ["gx", "gy", "gz"], scale = [-1, 1, 1] }',
        force=FORCES, extra="").replace(
            'unit = "us", scale = 10 }',
            'unit = "us", scale = 10, age = { file = "imu.csv", columns = ["dx"], unit = "ms" } }'))
    rec = table.read(tmp_path / "spec.toml")
    assert len(rec.imu_ns) == N - 1 and "1 rows repeating" in rec.real["repeated [imu]"]
    keep = np.r_[0:11, 12:N]
    assert np.allclose((rec.imu_ns - rec.imu_ns[0]) / 1e9, t[keep] - t[0], atol=2e-5)
    assert np.allclose(rec.w, w[keep] * [-1, 1, 1])
    (tmp_path / "spec.toml").write_text(SPEC.format(
        rate='angular_rate = { file = "imu.csv", columns = ["gx", "gy", "gz"], scale = [-1, 1] }',
        force=FORCES, extra=""))
    with pytest.raises(RecordingError, match="or 3 of them, one per column"):
        table.read(tmp_path / "spec.toml")


def test_a_reference_attitude_in_euler_angles_and_a_height_on_its_own_clock(tmp_path):
    """[reference] attitude_rpy (roll, pitch, yaw of body -> NED, z-y-x) gives the same q_nb
    as the quaternion; a height in ft on another clock is interpolated onto the reference's
    times, the epochs it does not cover left out and counted."""
    from mimunav.frames import attitude
    _imu(tmp_path)
    n = 200
    t = np.arange(1, n + 1) / 10.0
    roll, pitch, yaw = np.radians(10.0), np.radians(-5.0), np.radians(120.0) + 0.01 * t
    q = attitude.as_wxyz(attitude.from_euler(yaw, pitch, np.full(n, roll)))
    ref = np.column_stack([t * 1e5, np.full(n, 30.0), np.full(n, 104.0), np.zeros((n, 3)),
                           np.degrees(np.column_stack([np.full(n, roll), np.full(n, pitch),
                                                       yaw]))])
    np.savetxt(tmp_path / "ref.csv", ref, delimiter=",", header="tick,lat,lon,vn,ve,vd,r,p,y",
               comments="")
    baro = np.column_stack([(t[20:] - 0.05) * 1e5, 1000.0 + 10 * t[20:]])
    np.savetxt(tmp_path / "baro.csv", baro, delimiter=",", header="tick,alt", comments="")
    section = """[reference]
time = { file = "ref.csv", columns = ["tick"], unit = "us", scale = 10 }
latitude = { file = "ref.csv", columns = ["lat"], unit = "deg" }
longitude = { file = "ref.csv", columns = ["lon"], unit = "deg" }
height = { file = "baro.csv", columns = ["alt"], unit = "ft", time = { file = "baro.csv", columns = ["tick"], unit = "us", scale = 10 } }
velocity_ned = { file = "ref.csv", columns = ["vn", "ve", "vd"] }
attitude_rpy = { file = "ref.csv", columns = ["r", "p", "y"], unit = "deg" }
"""
    (tmp_path / "spec.toml").write_text(SPEC.format(rate=RATES, force=FORCES, extra="")
                                        + section)
    rec = table.read(tmp_path / "spec.toml")
    got = rec.reference
    # the barometer runs 0.05 s early from epoch 20 on: epochs 0-19 and the last uncovered
    assert len(got["ns"]) == n - 21 and "21 epochs beyond its span" in \
        rec.real["reference_height_time"]
    assert np.allclose(got["h"], 0.3048 * (1000.5 + 10 * t[20:-1]), atol=0.02)
    assert np.allclose(np.abs(np.sum(got["q_nb"] * q[20:-1], axis=1)), 1.0, atol=1e-9)
    # what a refusal of this attitude names (a helicopter's yaw, pitch, roll order had been
    # blamed on a quaternion's convention)
    assert rec.reference_meta["attitude_as"].startswith("columns' order (attitude_rpy")
    # an AHRS's attitude alone (no position): refused, saying it is not read and how to go on
    alone = section.split("\n")
    alone = "\n".join(line for line in alone if not line.startswith(("latitude", "longitude",
                                                                       "height", "velocity")))
    (tmp_path / "alone.toml").write_text(SPEC.format(rate=RATES, force=FORCES, extra="")
                                         + alone)
    with pytest.raises(RecordingError, match="attitude alone is not read - leave .reference. "
                                             "out"):
        table.read(tmp_path / "alone.toml")


def test_text_columns_and_dropped_rows_are_refused_saying_why(tmp_path, capsys):
    """What a new user's phone export met (issue 53): a time column of date-time text is
    said to hold no number (not "not finite", with advice that would drop every row); a key
    put in the wrong place names where it belongs; `nonfinite = "drop"` that leaves no row is
    a refusal, not an IndexError; `--spec-keys` prints every key."""
    def edit(data):
        data[:, 0] = np.nan                     # what genfromtxt reads of text cells
    _imu(tmp_path, edit=edit)
    with pytest.raises(RecordingError, match="holds no number in any row: a column of text"):
        table.read(tmp_path / "spec.toml")
    _imu(tmp_path, extra='nonfinite = "drop"')
    with pytest.raises(RecordingError, match="it belongs at the spec's top level"):
        table.read(tmp_path / "spec.toml")

    def holes(data):
        data[::2, 1] = np.nan
        data[1::2, 4] = np.nan
    _imu(tmp_path, edit=holes)
    spec = tmp_path / "spec.toml"
    spec.write_text('nonfinite = "drop"\n' + spec.read_text())
    with pytest.raises(RecordingError, match="0 of 4000 rows are finite in every column"):
        table.read(spec)
    from mimunav.cli import main
    with pytest.raises(SystemExit):
        main(["import", "--spec-keys"])
    assert "unix_offset_s" in capsys.readouterr().out


def test_iso_8601_date_times_are_unix_time_with_their_offset(tmp_path):
    """A phone logger's time column of date-times with a UTC offset (`unit = "iso8601"`):
    UNIX time to the microsecond, whatever the offset it is written in; one without an
    offset is refused (its time zone is unknown)."""
    import datetime
    t = 1691185678.0 + np.arange(N) / RATE
    zone = datetime.timezone(datetime.timedelta(hours=-4))
    stamps = [datetime.datetime.fromtimestamp(x, zone).isoformat(sep=" ") for x in t]
    w = 0.2 * np.sin(2 * np.pi * 0.3 * t[:, None] - t[0] + [0.0, 1.0, 2.0])
    lines = ["time,gx,gy,gz,ax,ay,az"] + [f"{s},{a:.9g},{b:.9g},{c:.9g},0.5,0,-9.8"
                                          for s, (a, b, c) in zip(stamps, w)]
    (tmp_path / "imu.csv").write_text("\n".join(lines) + "\n")
    spec = (SPEC.format(rate=RATES, force=FORCES, extra="")
            .replace('columns = ["tick"], unit = "us", scale = 10', 'columns = ["time"], '
                     'unit = "iso8601"').replace("1700000000.0", "0.0"))
    (tmp_path / "spec.toml").write_text(spec)
    rec = table.read(tmp_path / "spec.toml")
    assert np.abs(rec.imu_ns / 1e9 - t).max() < 1e-6
    assert np.allclose(rec.w, w)
    (tmp_path / "imu.csv").write_text("\n".join(line.replace("-04:00", "") for line in lines))
    with pytest.raises(RecordingError, match="has no UTC offset"):
        table.read(tmp_path / "spec.toml")


def test_columns_are_named_as_the_header_writes_them(tmp_path):
    """EuRoC's header: a comment mark before the first name, units in brackets, spaces - each
    name as written (they had been rewritten by the CSV reader: '#timestamp [ns]' into
    'timestamp_ns', so the name the file shows was refused)."""
    from mimunav.importers import columns
    t = np.arange(5) * 5_000_000 + 1_403_636_579_758_555_392
    rows = "\n".join(f"{ns},{k * 0.1},0.2,0.3, {9.8 + k}" for k, ns in enumerate(t))
    (tmp_path / "data.csv").write_text("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],"
                                       "w_RS_S_z [rad s^-1], a_RS_S_x [m s^-2]\n" + rows + "\n")
    got = columns.load_spec(str(tmp_path / "data.csv"), ["a_RS_S_x [m s^-2]", "timestamp [ns]",
                                                         "w_RS_S_x [rad s^-1]"])
    np.testing.assert_allclose(got[:, 0], 9.8 + np.arange(5))
    np.testing.assert_allclose(got[:, 1], t.astype(float))
    np.testing.assert_allclose(got[:, 2], np.arange(5) * 0.1)
    np.testing.assert_allclose(columns.load_spec(str(tmp_path / "data.csv"),
                                                 ["#timestamp [ns]"])[:, 0], t.astype(float))
    with pytest.raises(RecordingError, match=r"not among \['timestamp \[ns\]'"):
        columns.load_spec(str(tmp_path / "data.csv"), ["timestamp_ns"])
    one = columns.load_spec(str(tmp_path / "data.csv"), [4])          # one column: (N, 1)
    assert one.shape == (5, 1)


def test_text_tables_separated_by_spaces_with_comment_lines_and_zoned_date_times(tmp_path):
    """TUM's ground truth: comment lines, the last naming the columns, numbers separated by
    spaces; KITTI's timestamps: date-times without a UTC offset, which the source's `zone`
    gives (refused without it, and `zone` beside another unit)."""
    from mimunav.importers import columns
    rows = "\n".join(f"{1305031098.6659 + 0.01 * k:.4f} {0.1 * k:.3f} 0.5  1.6 0 0 0 1"
                     for k in range(4))
    (tmp_path / "groundtruth.txt").write_text(
        "# ground truth trajectory\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n"
        "# timestamp tx ty tz qx qy qz qw\n" + rows + "\n")
    got = columns.load_spec(str(tmp_path / "groundtruth.txt"), ["tx", "timestamp", "qw"])
    np.testing.assert_allclose(got, [[0.1 * k, 1305031098.6659 + 0.01 * k, 1.0]
                                     for k in range(4)])
    # GTSAM's KITTI text tables: the names' line without its '#'
    (tmp_path / "named.txt").write_text("timestamp tx ty tz qx qy qz qw\n" + rows + "\n")
    np.testing.assert_allclose(columns.load_spec(str(tmp_path / "named.txt"), ["tx", "qw"]),
                               [[0.1 * k, 1.0] for k in range(4)])
    # an Xsens export: '//' comment lines, then tab-separated names over the numbers
    (tmp_path / "xsens.txt").write_text("// Start Time: 0\n// Sample rate: 50.0Hz\n"
                                        "Counter\tAcc_X\tGyr_Z\n2552\t4.37424\t0.05086\n"
                                        "2553\t4.474578\t0.031548\n")
    np.testing.assert_allclose(columns.load_spec(str(tmp_path / "xsens.txt"), ["Gyr_Z"]),
                               [[0.05086], [0.031548]])
    (tmp_path / "bare.txt").write_text("# no names here\n" + rows + "\n")
    assert columns.load_spec(str(tmp_path / "bare.txt"), [1]).ravel().tolist() == \
        pytest.approx([0.0, 0.1, 0.2, 0.3])
    (tmp_path / "timestamps.txt").write_text("2011-09-26 13:02:25.964389445\n"
                                             "2011-09-26 13:02:26.074347265\n")
    with pytest.raises(RecordingError, match="13:02:25.96.* no UTC offset.*zone = "):
        columns.load_date_times(str(tmp_path / "timestamps.txt"), 0)
    utc = columns.load_date_times(str(tmp_path / "timestamps.txt"), 0, "Z")
    assert utc[0] == pytest.approx(1317042145.964389, abs=1e-6)
    cest = columns.load_date_times(str(tmp_path / "timestamps.txt"), 0, "+02:00")
    np.testing.assert_allclose(utc - cest, 7200.0)
    with pytest.raises(RecordingError, match="zone 'CEST'"):
        columns.load_date_times(str(tmp_path / "timestamps.txt"), 0, "CEST")


def test_a_file_per_epoch_is_read_through_a_glob_in_name_order(tmp_path):
    """KITTI's raw OXTS: one text file of one line per epoch, named by its index - a glob's
    files read in the order of their names (not the order the folder lists them in)."""
    from mimunav.importers import columns
    (tmp_path / "data").mkdir()
    for k in (2, 0, 10, 1):                                  # written out of order
        (tmp_path / "data" / f"{k:010d}.txt").write_text(f"{49.0 + k} 8.4 {100 + k}\n")
    got = columns.load_spec(str(tmp_path / "data" / "*.txt"), [0, 2])
    np.testing.assert_allclose(got, [[49.0, 100], [50.0, 101], [51.0, 102], [59.0, 110]])
    with pytest.raises(RecordingError, match="no file matches"):
        columns.load_spec(str(tmp_path / "data" / "*.csv"), None)
    (tmp_path / "named").mkdir()                  # each with its header: read one by one
    for k in (1, 0):
        (tmp_path / "named" / f"{k}.csv").write_text(f"lat,lon\n{49.0 + k},8.4\n")
    np.testing.assert_allclose(columns.load_spec(str(tmp_path / "named" / "*.csv"), ["lat"]),
                               [[49.0], [50.0]])
    (tmp_path / "data" / "0000000003.txt").write_text("52.0 8.4\n")       # a short row: named
    with pytest.raises(RecordingError, match="0000000003.txt.*column count|another column"):
        columns.load_spec(str(tmp_path / "data" / "*.txt"), [0])


def test_an_offset_is_added_after_the_scale_in_the_columns_unit(tmp_path):
    """KITTI's OXTS attitude (roll, pitch positive nose down, yaw from east counter-clockwise,
    rad) as the aerospace roll, pitch, heading: scale [1, -1, -1], offset [0, 0, pi/2]; an
    offset that is no number is refused, naming it."""
    from mimunav.importers.table_spec import Spec
    (tmp_path / "oxts.txt").write_text("0.1 0.2 0.0\n-0.1 -0.2 1.5707963267948966\n")
    source = '{ file = "oxts.txt", unit = "rad", scale = [1, -1, -1], offset = [0, 0, %s] }'
    (tmp_path / "s.toml").write_text('[imu]\n[time]\nunix_offset_s = 0\n[reference]\n'
                                     'attitude_rpy = ' + source % "1.5707963267948966" + "\n")
    rpy = Spec(tmp_path / "s.toml").column("reference", "attitude_rpy")
    np.testing.assert_allclose(rpy, [[0.1, -0.2, np.pi / 2], [-0.1, 0.2, 0.0]], atol=1e-12)
    (tmp_path / "s.toml").write_text((tmp_path / "s.toml").read_text().replace(
        "0, 0, 1.5707963267948966", '0, 0, "east"'))
    with pytest.raises(RecordingError, match="offset .*a finite number in the column's unit"):
        Spec(tmp_path / "s.toml").column("reference", "attitude_rpy")


def test_instantaneous_samples_are_stamped_at_the_end_of_the_interval_they_stand_for(tmp_path):
    """sampling = "instant": a logger's values at their stamps are the means over the interval
    centred on them, so the stamps move half an interval later (read as interval means, a
    100 Hz IMU led by 5 ms: a new user's drive had a time skew of -4.9 ms [-5.4, -4.3]);
    refused beside increments, and a value not known is named."""
    t, w, f = _imu(tmp_path, extra='sampling = "instant"')
    rec = table.read(tmp_path / "spec.toml")
    np.testing.assert_allclose((rec.imu_ns - 1_700_000_000e9) / 1e9, t + 0.005, atol=1e-6)
    assert "stamped 5 ms later" in rec.real["imu_sampling"]
    _imu(tmp_path, rate=RATES.replace("angular_rate", "angle_increment").replace(
        '"gx", "gy", "gz"', '"dx", "dy", "dz"'), extra='sampling = "instant"')
    with pytest.raises(RecordingError, match="an increment is over its interval"):
        table.read(tmp_path / "spec.toml")
    _imu(tmp_path, extra='sampling = "instantaneous"')
    with pytest.raises(RecordingError, match="sampling 'instantaneous': \"interval_mean\" or"):
        table.read(tmp_path / "spec.toml")


def test_instantaneous_samples_become_the_means_of_the_intervals_centred_on_them(tmp_path):
    """Closed form: the mean of 0.2 sin(w t + p) over (t - T/2, t + T/2] is the sample times
    sin(w T / 2) / (w T / 2); the import gives it to 1e-9 rad/s, where the samples as
    recorded are off by (w T)^2 / 24 of the swing (3e-6 rad/s here, a 2 Hz swing at 200 Hz:
    1.6e-4 of it, which a rate table's diagnosis read as a scale factor). Outputs at the
    range given, and their neighbours, stay as recorded."""
    t, w, _ = _imu(tmp_path, extra='sampling = "instant"\nrange = { angular_rate = '
                                     '{ value = 0.199, unit = "rad/s" } }', clip=0.199)
    rec = table.read(tmp_path / "spec.toml")
    omega, step = 2 * np.pi * 0.3, 1.0 / RATE
    sample = 0.2 * np.sin(omega * t[:, None] + [0.0, 1.0, 2.0])
    mean = sample * np.sin(omega * step / 2) / (omega * step / 2)
    clipped = (np.abs(w) >= 0.999 * 0.199).any(axis=1)        # within 0.1 %: at it
    near = clipped | np.roll(clipped, 1) | np.roll(clipped, -1)
    inner = ~near
    inner[[0, -1]] = False
    assert np.abs(rec.w[inner] - mean[inner]).max() < 1e-9
    assert np.abs(w[inner] - mean[inner]).max() > 2e-6            # as recorded: off
    np.testing.assert_allclose(rec.w[near], w[near], rtol=0, atol=1e-9)   # the CSV's digits
    assert clipped.sum() > 100


def test_a_receivers_speed_and_course_over_ground_are_its_velocity(tmp_path):
    """[reference] ground_speed (km/h here) and course (deg from north, clockwise) - the speed
    and bearing columns of a phone's Location.csv or NMEA RMC, which a spec could not take -
    give the north and east velocity exactly; down from the heights' central differences;
    a negative one (iOS's invalid) takes the positions' differences; one without the other
    is refused saying why."""
    _imu(tmp_path)
    n = 200
    t = np.arange(1, n + 1) / 10.0
    course = np.radians(30.0 + 20.0 * np.sin(0.3 * t))
    speed = 10.0 + 0.1 * t                                    # m/s
    climb = 0.5                                                # m/s, up
    ref = np.column_stack([t * 1e5, np.full(n, 30.0), np.full(n, 104.0), 100.0 + climb * t,
                           speed * 3.6, np.degrees(course)])
    np.savetxt(tmp_path / "ref.csv", ref, delimiter=",", header="tick,lat,lon,h,kmh,bearing",
               comments="")
    section = """[reference]
time = { file = "ref.csv", columns = ["tick"], unit = "us", scale = 10 }
latitude = { file = "ref.csv", columns = ["lat"], unit = "deg" }
longitude = { file = "ref.csv", columns = ["lon"], unit = "deg" }
height = { file = "ref.csv", columns = ["h"], unit = "m" }
"""
    over_ground = """ground_speed = { file = "ref.csv", columns = ["kmh"], unit = "km/h" }
course = { file = "ref.csv", columns = ["bearing"], unit = "deg" }
"""
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.format(rate=RATES, force=FORCES, extra="") + section + over_ground)
    v = table.read(spec).reference["v_ned"]
    assert np.allclose(v[:, 0], speed * np.cos(course)) and \
        np.allclose(v[:, 1], speed * np.sin(course))
    assert np.allclose(v[:, 2], -climb, atol=1e-6)
    # iOS writes -1 for an invalid speed or course (standing still): those epochs take the
    # positions' differences (a -1 had read as 1 m/s, hiding every rest)
    ref[:50, 4:] = -1.0
    np.savetxt(tmp_path / "ref.csv", ref, delimiter=",", header="tick,lat,lon,h,kmh,bearing",
               comments="")
    v = table.read(spec).reference["v_ned"]
    assert np.abs(v[:50, :2]).max() < 1e-6 and \
        np.allclose(v[50:, 0], speed[50:] * np.cos(course[50:]))
    # Android leaves the bearing empty where it has none (hasBearing false): not given too
    # (it had been refused as not finite, or its rows dropped with every standstill)
    lines = (tmp_path / "ref.csv").read_text().splitlines()
    lines[1:51] = [line.rsplit(",", 1)[0] + "," for line in lines[1:51]]
    (tmp_path / "ref.csv").write_text("\n".join(lines) + "\n")
    empty = table.read(spec).reference["v_ned"]
    assert len(empty) == n and np.array_equal(empty, v)
    # ... however the course's column is scaled: counted from east (an independent review:
    # the empty cells had been read as 91 deg, the offset put on their mark)
    east = ref.copy()
    east[:, 4], east[:, 5] = speed * 3.6, 90.0 - east[:, 5]     # its speed given throughout
    np.savetxt(tmp_path / "ref.csv", east, delimiter=",", header="tick,lat,lon,h,kmh,bearing",
               comments="")
    lines = (tmp_path / "ref.csv").read_text().splitlines()
    lines[1:51] = [line.rsplit(",", 1)[0] + "," for line in lines[1:51]]
    (tmp_path / "ref.csv").write_text("\n".join(lines) + "\n")
    spec.write_text(spec.read_text().replace('columns = ["bearing"], unit = "deg"',
                                             'columns = ["bearing"], unit = "deg", scale = -1, '
                                             'offset = 90'))
    assert np.allclose(table.read(spec).reference["v_ned"], v)
    spec.write_text(SPEC.format(rate=RATES, force=FORCES, extra="") + section
                    + over_ground.splitlines()[0] + "\n")
    with pytest.raises(RecordingError, match="ground_speed alone"):
        table.read(spec)


def test_a_file_of_two_sensors_rows_is_refused_unpicked_and_read_by_rows(tmp_path):
    """Android GnssLogger writes its accelerometer's and its gyro's rows to one file, told by
    a MessageType column, each on its own stamps: read whole, the gyro's rows had been
    specific force (refused only by chance, where two stamps collided). Unpicked it is
    refused naming the kinds and the key; picked with `rows`, each quantity is its own
    rows, on its own clock."""
    t = np.arange(1, N + 1) / RATE
    w = 0.2 * np.sin(2 * np.pi * 0.3 * t[:, None] + [0.0, 1.0, 2.0])
    f = np.tile([0.5, 0.0, -9.8], (N, 1))
    lines = ["MessageType,tick,x,y,z"]
    for k in range(N):
        lines.append("UncalAccel," + ",".join(f"{v:.10g}" for v in [t[k] * 1e5, *f[k]]))
        lines.append("UncalGyro," + ",".join(f"{v:.10g}" for v in [t[k] * 1e5 + 300, *w[k]]))
    (tmp_path / "imu.csv").write_text("\n".join(lines) + "\n")

    def time(rows):
        return f'{{ file = "imu.csv", columns = ["tick"], unit = "us", scale = 10{rows} }}'

    def source(rows):
        return f'{{ file = "imu.csv", columns = ["x", "y", "z"]{rows}, time = {time(rows)} }}'
    picked = (', rows = {MessageType = "UncalGyro"}', ', rows = {MessageType = "UncalAccel"}')
    for rows in (("", ""), picked):
        (tmp_path / "spec.toml").write_text(
            f'name = "t"\n[imu]\ntime = {time(rows[1])}\nangular_rate = {source(rows[0])}\n'
            f'specific_force = {source(rows[1])}\naxes = "FRD"\n[time]\n'
            'unix_offset_s = 1700000000.0\n')
        if not rows[0]:
            with pytest.raises(RecordingError, match='2 kinds interleaved .column "MessageType": '
                               '"UncalAccel", "UncalGyro".*rows = {MessageType = "UncalAccel"}'):
                table.read(tmp_path / "spec.toml")
            continue
        rec = table.read(tmp_path / "spec.toml")
        # the gyro's own stamps 3 ms later: interpolated onto the force's, the first force
        # sample before the first rate left out
        assert len(rec.imu_ns) == N - 1 and np.allclose(rec.f, f[0])
        assert np.allclose(rec.w, w[1:], atol=2e-3)
    (tmp_path / "spec.toml").write_text((tmp_path / "spec.toml").read_text().replace(
        '"UncalGyro"', '"UncalMag"'))
    with pytest.raises(RecordingError, match='no row is'):
        table.read(tmp_path / "spec.toml")


def test_a_speed_without_its_course_keeps_its_size(tmp_path):
    """A phone standing with its Location's bearing empty and its speed 0.01-0.07 m/s (the
    receiver's Doppler), its 3 m fixes scattering: the horizontal velocity is the positions'
    differences made no longer than the speed (they alone had made the walker move at
    0.3-0.8 m/s, and no rest was found: the whole import refused)."""
    _imu(tmp_path)
    n = 100
    rng = np.random.default_rng(2)
    t = np.arange(1, n + 1) / 1.0
    lat = 47.0 + rng.normal(0, 3.0, n) / 6.371e6 * 180 / np.pi
    lon = 8.0 + rng.normal(0, 3.0, n) / 6.371e6 * 180 / np.pi / np.cos(np.radians(47.0))
    speed = rng.uniform(0.01, 0.07, n)
    lines = ["tick,lat,lon,h,speed,bearing"] + [         # the last 10 s moving north
        f"{t[k] * 1e5:.10g},{lat[k]:.10f},{lon[k]:.10f},400.0,{speed[k]:.3f},"
        + ("0" if k >= n - 10 else "") for k in range(n)]
    (tmp_path / "ref.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "spec.toml").write_text(SPEC.format(rate=RATES, force=FORCES, extra="") + """
[reference]
time = { file = "ref.csv", columns = ["tick"], unit = "us", scale = 10 }
latitude = { file = "ref.csv", columns = ["lat"], unit = "deg" }
longitude = { file = "ref.csv", columns = ["lon"], unit = "deg" }
height = { file = "ref.csv", columns = ["h"], unit = "m" }
ground_speed = { file = "ref.csv", columns = ["speed"], unit = "m/s" }
course = { file = "ref.csv", columns = ["bearing"], unit = "deg" }
""")
    v = table.read(tmp_path / "spec.toml").reference["v_ned"]
    assert np.allclose(np.hypot(v[:, 0], v[:, 1]), np.round(speed, 3), atol=1e-9)
    assert np.allclose(v[-10:, 0], np.round(speed[-10:], 3)) and not np.any(v[-10:, 1])


def test_a_headerless_files_rows_are_picked_by_a_columns_index(tmp_path):
    """A headerless CSV (NCLT's gps_rtk.csv: utime, mode, ...) picks its rows by the
    column's 0-based index, a TOML key in digits; a name on it had been refused "column '1'
    not among None", and now says the file has no header."""
    t = np.arange(1, N + 1) / RATE
    mode = np.where(np.arange(N) % 7 == 3, 2, 3)         # a float fix now and then
    w = 0.2 * np.sin(2 * np.pi * 0.3 * t[:, None] + [0.0, 1.0, 2.0])
    lines = [",".join([f"{t[k] * 1e5:.10g}", str(mode[k])] + [f"{v:.10g}" for v in w[k]])
             for k in range(N)]
    (tmp_path / "imu.csv").write_text("\n".join(lines) + "\n")
    for key in ('"1"', "mode"):
        rows = f'rows = {{{key} = "3"}}'
        time = f'{{ file = "imu.csv", columns = [0], unit = "us", scale = 10, {rows} }}'
        triad = f'file = "imu.csv", columns = [2, 3, 4], {rows}, time = {time}'
        (tmp_path / "spec.toml").write_text(
            f'name = "t"\n[imu]\ntime = {time}\nangular_rate = {{ {triad} }}\n'
            f'specific_force = {{ {triad}, unit = "g" }}\naxes = "FRD"\n'
            '[time]\nunix_offset_s = 0\n')
        if key == "mode":
            with pytest.raises(RecordingError, match="the file has no header: give its 0-based"):
                table.read(tmp_path / "spec.toml")
            continue
        rec = table.read(tmp_path / "spec.toml")
        assert np.allclose(rec.w, w[mode == 3]) and np.allclose(rec.f, w[mode == 3] * 9.80665)


def test_a_mounting_given_on_the_command_line_keeps_the_specs_lever_arm(tmp_path):
    """`--mounting-rpy-deg`, the turn the diagnosis itself recommends, gives a rotation: the
    spec's lever arm stays (it had become [0, 0, 0] without a word, a 1 m arm lost), and
    the metadata says whose each part is."""
    from mimunav.frames.mounting import Mounting
    _imu(tmp_path, extra="lever_arm_m = [0.95, 0.12, -0.25]")
    rec = table.read(tmp_path / "spec.toml", Mounting.from_rpy_deg((180.0, 2.5, 90.0)))
    assert rec.mounting.lever_arm_m.tolist() == [0.95, 0.12, -0.25]
    assert np.allclose(rec.mounting.attitude_wxyz,
                       Mounting.from_rpy_deg((180.0, 2.5, 90.0)).attitude_wxyz)
    assert "the lever arm [0.95, 0.12, -0.25] m the spec's" in rec.assumed["mounting"]


@pytest.mark.parametrize("jitter", ["sampling", "stamps", "none"])
def test_increments_are_divided_by_the_intervals_they_span(jitter):
    """Velocity increments of a vehicle at rest tilting gently, 200 Hz: an IMU sampled at
    jittered instants integrates over the jittered intervals (|dv| follows them: divided by
    them); a logger that stamps a steady IMU on its own reads jitters its stamps alone (100
    us here: |dv| does not follow - divided by the median interval, said; a glider's had
    turned into rate noise that hid a g-sensitivity); steady stamps are taken as they are."""
    from mimunav.importers.series import increment_intervals
    rng = np.random.default_rng(11)
    n, step = 20000, 0.005
    true = np.full(n, step) + (rng.normal(0, 1e-4, n) if jitter == "sampling" else 0.0)
    t_true = np.cumsum(true)
    f = np.column_stack([0.3 * np.sin(t_true / 7), 0.2 * np.cos(t_true / 5),
                         np.full(n, -9.81)])
    dv = f * true[:, None] + rng.normal(0, 2e-5, (n, 3))
    t = t_true + (rng.normal(0, 1e-4, n) if jitter == "stamps" else 0.0)
    dt, said = increment_intervals(t, dv)
    rate = np.linalg.norm(dv / dt[:, None], axis=1)
    assert np.std(rate) < 0.05, (jitter, np.std(rate), said)        # 9.81 m/s^2 +- noise
    if jitter == "stamps":
        assert "do not follow them" in said and "(5 ms in the median" in said
        assert np.allclose(dt[1:], step, rtol=1e-3)
    elif jitter == "sampling":
        assert "follow them" in said and "do not" not in said
    else:
        assert said == ""


@pytest.mark.parametrize("burst", [2, 3])
def test_increments_stamped_in_bursts_are_divided_by_the_steady_interval(burst):
    """A logger that reads a steady 200 Hz IMU in bursts of 2 or 3 samples stamps them 0.1
    ms apart, then the rest of the period: its median interval (0.1 ms) had made 2 of 3
    increments 50 times their rate without a word. Each is divided by the steady interval.
    A dropped sample cannot be told from the bursts (its increment, spanning two intervals
    here, is taken as one's): said."""
    from mimunav.importers.series import increment_intervals
    rng = np.random.default_rng(13)
    n, step = 20001, 0.005
    true = np.full(n, step)
    true[12000] = 2 * step                         # a sample dropped: its increment spans both
    t_true = np.cumsum(true)
    first = np.repeat(t_true[::burst], burst)[:n]  # each burst stamped at its first sample
    t = first + 1e-4 * (np.arange(n) % burst)
    f = np.column_stack([0.3 * np.sin(t_true / 7), np.zeros(n), np.full(n, -9.81)])
    dv = f * true[:, None] + rng.normal(0, 2e-5, (n, 3))
    dt, said = increment_intervals(t, dv)
    rate = np.linalg.norm(dv / dt[:, None], axis=1)
    assert "come in bursts" in said and "do not follow them" in said, said
    assert "a dropped sample cannot be told" in said
    error = np.abs(rate / 9.81 - 1)
    assert error[12000] > 0.9 and np.delete(error, [0, 12000]).max() < 0.01, error


@pytest.mark.parametrize("lost", ["dropped", "accumulated", "dropped 15 %"])
def test_the_increment_after_a_gap_is_divided_by_what_it_spans(lost):
    """A 400 Hz IMU whose logger lost 0.5 % of its rows and 0.2 s at once, stamps exact:
    where the rows were dropped the increment after each gap holds its own interval (a
    helicopter's, divided by the gap, had halved those rates and read as gyro scale factors
    of -0.2 %); where the IMU accumulates until read, it spans the gap. Both read 1 g. So
    do 15 % of the rows dropped (not bursts: none of the intervals is short; taken for
    bursts, every increment had been divided by a mean over the gaps, -12 %)."""
    from mimunav.importers.series import increment_intervals
    rng = np.random.default_rng(14)
    n, step = 40000, 0.0025
    t_all = np.arange(n) * step
    f = np.column_stack([0.5 * np.sin(t_all / 3), np.zeros(n), np.full(n, -9.81)])
    dv_all = f * step + rng.normal(0, 1e-5, (n, 3))
    keep = rng.random(n) > (0.15 if "15 %" in lost else 0.005)
    keep[20000:20080] = False
    keep[0] = True
    if lost.startswith("dropped"):
        dv = dv_all[keep]
    else:                   # each kept row carries the increments since the last kept one
        group = np.cumsum(keep) - keep              # the kept row at or after each
        dv = np.zeros((keep.sum() + 1, 3))
        np.add.at(dv, group, dv_all)
        dv = dv[:-1]
    dt, said = increment_intervals(t_all[keep], dv)
    rate = np.linalg.norm(dv / dt[:, None], axis=1)
    assert "gaps in the stamps" in said and \
        ("own interval only" in said) == lost.startswith("dropped")
    error = np.abs(rate[1:] / np.linalg.norm(f[keep][1:], axis=1) - 1)
    assert np.percentile(error, 99.9) < 0.01, (said, np.sort(error)[-5:])


def test_a_rate_switched_mid_record_keeps_each_parts_interval():
    """A logger's stamp jitter (100 us) on an IMU switched from 200 to 250 Hz mid-record:
    each increment is divided by the steady interval around it, not by one mean of both
    (which read the second half 11 % off, an independent review) - wrong only within the
    span either side of the switch."""
    from mimunav.importers.series import STEADY_SPAN, increment_intervals
    rng = np.random.default_rng(12)
    true = np.concatenate([np.full(10000, 0.005), np.full(10000, 0.004)])
    t = np.cumsum(true) + rng.normal(0, 1e-4, len(true))
    dv = np.tile([0.0, 0.0, -9.81], (len(true), 1)) * true[:, None]
    dt, said = increment_intervals(t, dv)
    assert "do not follow them" in said
    rate = np.linalg.norm(dv / dt[:, None], axis=1)
    away = np.abs(np.arange(len(true)) - 10000) > STEADY_SPAN + 1
    assert np.abs(rate[away] / 9.81 - 1).max() < 0.005, np.abs(rate[away] / 9.81 - 1).max()


def test_a_devices_constant_quaternion_scale_is_normalised_and_a_varying_one_refused():
    """An NGIMU writes every quaternion 0.99831 long (499 of 499 rows): normalised, where it
    had been refused as 'no unit quaternion ... the columns w, x, y, z in that order?' - an
    order leaves |q| alike; rows whose lengths vary (a rotation vector among the columns)
    and a scale beyond 1 % are refused, naming the columns' content."""
    from mimunav.importers.recording import unit_quaternions
    rng = np.random.default_rng(4)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    got = unit_quaternions(0.99831 * q, "ngimu")
    np.testing.assert_allclose(np.abs(got), 1.0)
    np.testing.assert_allclose(quaternion.as_float_array(got), q, atol=1e-12)
    for bad in (q * rng.uniform(0.9, 1.1, (50, 1)), 0.97 * q):
        with pytest.raises(RecordingError, match="no unit quaternion.*attitude's w, x, y, z"):
            unit_quaternions(bad, "ngimu")

"""A reference in a local level frame (a motion-capture room's) is placed on the Earth as the
truth says (`importers.local_frame`, the table spec's position_local): positions through an
implementation nobody here wrote (pymap3d), attitudes and velocities in closed form, the
frame's azimuth honoured - or, not known, the log's initial heading said to be assumed."""
import math

import numpy as np
import pytest
import quaternion

from mimunav.flightlog import FlightLog
from mimunav.flightlog.inspect import describe
from mimunav.frames import attitude
from mimunav.frames.mounting import Mounting
from mimunav.importers import table
from mimunav.importers.recording import RecordingError
from mimunav.importers.write import write_log

ORIGIN = (47.3769, 8.5417, 480.0)          # deg, deg, m (ellipsoidal)
RATE, SECONDS = 100.0, 40.0
RADIUS, SPEED = 20.0, 4.0                   # m, m/s: a walk around a room's circle
SPEC = """name = "room"
vehicle = "pedestrian"
[imu]
time = {{ file = "imu.csv", columns = ["t"], unit = "s" }}
angular_rate = {{ file = "imu.csv", columns = ["gx", "gy", "gz"] }}
specific_force = {{ file = "imu.csv", columns = ["ax", "ay", "az"] }}
axes = "{axes}"
[time]
unix_offset_s = 1700000000.0
[reference]
time = {{ file = "truth.csv", columns = ["t"], unit = "s" }}
position_local = {{ file = "truth.csv", columns = ["x", "y", "z"] }}
attitude_wxyz = {{ file = "truth.csv", columns = ["qw", "qx", "qy", "qz"] }}
local_frame = {{ axes = "z_up", origin = {origin}, azimuth_deg = {azimuth} }}
{extra}
"""


REFERENCE_IMU = """attitude_of = "reference_imu"
[reference_imu]
time = {{ file = "ref.csv", columns = ["t"], unit = "s" }}
angular_rate = {{ file = "ref.csv", columns = ["gx", "gy", "gz"] }}
specific_force = {{ file = "ref.csv", columns = ["ax", "ay", "az"] }}
axes = "{axes}"
"""


def _room(tmp_path, azimuth_deg=30.0, axes="FRD", extra="", azimuth_text=None,
          reference_imu_axes=None):
    """A level walk counter-clockwise (seen from above) around a circle in true ENU, written in
    a z-up frame whose x points `azimuth_deg` east of north. Returns (t s, truth east/north/up
    m, heading rad, v_ned m/s). The attitude is of the body FRD (axes = FRD) or, with
    attitude_of = "imu", of sensor axes `axes` - or of a reference IMU's, `reference_imu_axes`,
    which flies beside with the same outputs in its own axes."""
    t = np.arange(0.0, SECONDS, 1 / RATE)
    turn = SPEED / RADIUS * t
    e, n, u = RADIUS * np.cos(turn), RADIUS * np.sin(turn), np.full_like(t, 1.5)
    v_enu = SPEED * np.column_stack([-np.sin(turn), np.cos(turn), 0 * t])
    heading = np.arctan2(v_enu[:, 0], v_enu[:, 1])          # from north toward east
    a = math.radians(azimuth_deg)
    x, y = e * math.sin(a) + n * math.cos(a), -e * math.cos(a) + n * math.sin(a)
    # body FRD -> FLU (half turn about x), then a yaw about the frame's up by the angle from
    # the frame's x to the body's forward, counter-clockwise: azimuth - heading
    gamma = a - heading
    q_lb = quaternion.from_float_array(np.column_stack(
        [np.cos(gamma / 2), 0 * t, 0 * t, np.sin(gamma / 2)])) * np.quaternion(0, 1, 0, 0)
    if axes != "FRD" or reference_imu_axes:     # the attitude is of a sensor's axes: q_ls
        q_lb = q_lb * Mounting.from_axes(reference_imu_axes or axes).q_vs
    q = quaternion.as_float_array(q_lb)
    rows = np.column_stack([t, x, y, u, q])
    (tmp_path / "truth.csv").write_text("t,x,y,z,qw,qx,qy,qz\n" + "\n".join(
        ",".join(f"{v:.12g}" for v in row) for row in rows) + "\n")
    # the body turns left at SPEED / RADIUS, pulled left by SPEED^2 / RADIUS (FRD axes)
    imu = np.column_stack([t, np.tile([0.0, 0.0, -SPEED / RADIUS], (len(t), 1)),
                           np.tile([0.0, -SPEED ** 2 / RADIUS, -9.81], (len(t), 1))])
    (tmp_path / "imu.csv").write_text("t,gx,gy,gz,ax,ay,az\n" + "\n".join(
        ",".join(f"{v:.10g}" for v in row) for row in imu) + "\n")
    if reference_imu_axes:                  # its outputs in its own axes: q_sv of the vehicle's
        q_sv = np.conjugate(Mounting.from_axes(reference_imu_axes).q_vs)
        mine = np.column_stack([t, attitude.rotate(q_sv, imu[:, 1:4]),
                                attitude.rotate(q_sv, imu[:, 4:7])])
        (tmp_path / "ref.csv").write_text("t,gx,gy,gz,ax,ay,az\n" + "\n".join(
            ",".join(f"{v:.10g}" for v in row) for row in mine) + "\n")
        extra += REFERENCE_IMU.format(axes=reference_imu_axes)
    (tmp_path / "spec.toml").write_text(SPEC.format(
        axes=axes, origin=list(ORIGIN), extra=extra,
        azimuth=azimuth_text or azimuth_deg))
    v_ned = np.column_stack([v_enu[:, 1], v_enu[:, 0], -v_enu[:, 2]])
    return t, np.column_stack([e, n, u]), heading, v_ned


def test_positions_attitudes_and_velocities_of_a_turned_room_frame_are_the_truths(tmp_path):
    import pymap3d as pm
    t, enu, heading, v_ned = _room(tmp_path)
    rec = table.read(tmp_path / "spec.toml")
    ref = rec.reference
    lat, lon, h = pm.enu2geodetic(enu[:, 0], enu[:, 1], enu[:, 2], *ORIGIN)
    k = np.round((ref["ns"] - rec.imu_ns[0]) / 1e9 * RATE).astype(int)     # epochs of t
    # 1e-10 rad of latitude is 0.6 mm
    np.testing.assert_allclose(np.degrees(ref["lat"]), lat[k], atol=1e-8)
    np.testing.assert_allclose(np.degrees(ref["lon"]), lon[k], atol=1e-8)
    np.testing.assert_allclose(ref["h"], h[k], atol=1e-3)
    yaw, pitch, roll = attitude.as_euler(attitude.from_wxyz(ref["q_nb"]))
    # within 20 m of the origin each epoch's NED turns from the origin's by < 4e-6 rad
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - heading[k]))), 0, atol=1e-5)
    np.testing.assert_allclose(np.hypot(pitch, roll), 0, atol=1e-5)
    # central differences of a circle: speed short by (w dt)^2 / 6 = 1.3e-6 of 4 m/s
    np.testing.assert_allclose(ref["v_ned"][1:-1], v_ned[k][1:-1], atol=1e-3)
    assert rec.reference_heading_known and "azimuth 30 deg" in rec.reference_meta["frame"]


def test_the_imus_own_attitude_is_turned_into_the_vehicles_by_its_mounting(tmp_path):
    t, enu, heading, v_ned = _room(tmp_path, axes="FLU", extra='attitude_of = "imu"')
    ref = table.read(tmp_path / "spec.toml").reference
    yaw, pitch, roll = attitude.as_euler(attitude.from_wxyz(ref["q_nb"]))
    k = np.round((ref["ns"] - 1.7e18) / 1e9 * RATE).astype(int)
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - heading[k]))), 0, atol=1e-5)
    np.testing.assert_allclose(np.hypot(pitch, roll), 0, atol=1e-5)
    (tmp_path / "spec.toml").write_text((tmp_path / "spec.toml").read_text().replace(
        'axes = "FLU"', 'axes = "FLU"\nlever_arm_m = [0.1, 0.0, 0.0]'))
    with pytest.raises(RecordingError, match="lever_arm_m must be 0"):
        table.read(tmp_path / "spec.toml")


def test_a_reference_imus_own_attitude_is_turned_into_the_vehicles_by_its_mounting(tmp_path):
    """An INS whose attitude is of its own axes, mounted right-back-down (turned 90 deg in
    yaw): the log's attitude is the vehicle's, and the initial heading too (it had been the
    INS's axes', 90 deg off)."""
    t, enu, heading, v_ned = _room(tmp_path, reference_imu_axes="RBD")
    rec = table.read(tmp_path / "spec.toml")
    yaw, pitch, roll = attitude.as_euler(attitude.from_wxyz(rec.reference["q_nb"]))
    k = np.round((rec.reference["ns"] - 1.7e18) / 1e9 * RATE).astype(int)
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - heading[k]))), 0, atol=1e-5)
    assert "reference IMU's own" in rec.reference_meta["attitude_axes"]


def test_an_unknown_azimuth_makes_the_logs_initial_heading_assumed(tmp_path):
    _room(tmp_path, azimuth_text='"unknown"')
    rec = table.read(tmp_path / "spec.toml")
    assert not rec.reference_heading_known and "not known" in rec.reference_meta["frame"]
    write_log(rec, tmp_path / "log.mcap")
    with FlightLog(tmp_path / "log.mcap") as log:
        meta = log.metadata()["recording"]
    assert meta["initial_heading"] == "assumed"
    assert "azimuth is not known" in meta["assumed"]["initial_heading"]
    # the gyro bias keeps the Earth rate's horizontal part: where it points is not known
    assert meta["bias_basis"]["gyro"] == "vertical_earth_rate"
    with FlightLog(tmp_path / "log.mcap") as log:           # `mimunav info` says it
        text = describe(log)
    assert "heading   assumed (the reference lies in a local frame whose azimuth" in text
    assert "reference local frame (level, z up, x at an azimuth not known" in text


@pytest.mark.parametrize("edit, match", [
    (lambda s: s.replace(", azimuth_deg = 30.0", ""), "need azimuth_deg"),
    (lambda s: s.replace('axes = "z_up"', 'axes = "enu"'), "name their azimuth"),
    (lambda s: s.replace("origin = ", "orgin = "), "did you mean 'origin'"),
    (lambda s: s.replace(f"origin = {list(ORIGIN)}, ", ""), "needs the geodetic origin"),
    (lambda s: s.replace("local_frame = {", "x = {"), "unknown key 'x'"),
    (lambda s: s.replace("[reference]\n", '[reference]\nlatitude = "truth.csv"\n'),
     "position_local and latitude"),
    (lambda s: s.replace('qz"] }', 'qz"], rotates = "body_to_ned" }'), "body_to_local"),
    (lambda s: s.replace('columns = ["x", "y", "z"] }',      # a UTM easting and northing
                         'columns = ["x", "y", "z"], offset = [4.1e6, 5e5, 0] }'),
     "lie 4130 km from the local frame's origin"),
    (lambda s: s.replace('attitude_wxyz = { file = "truth.csv", columns = ["qw", "qx", "qy", '
                         '"qz"] }', 'attitude_rpy = { file = "truth.csv", columns = ["qx", '
                         '"qy", "qz"], unit = "rad" }'), "attitude_rpy in a local frame needs"),
])
def test_a_local_frame_given_wrong_is_refused_naming_what_it_needs(tmp_path, edit, match):
    _room(tmp_path)
    (tmp_path / "spec.toml").write_text(edit((tmp_path / "spec.toml").read_text()))
    with pytest.raises(RecordingError, match=match):
        table.read(tmp_path / "spec.toml")


def test_roll_pitch_yaw_in_a_z_down_local_frame_are_its_attitude(tmp_path):
    """The room's walk written in the frame with the same x and z down (NCLT's ground truth:
    x, y, z and roll, pitch, yaw in a local NED): its roll, pitch and yaw, the z-y-x turns
    of the body to that frame, give the attitude the quaternions to the z-up frame give (a
    new user had converted them with a script of his own: refused beside position_local)."""
    _room(tmp_path)
    given = table.read(tmp_path / "spec.toml").reference
    rows = np.loadtxt(tmp_path / "truth.csv", delimiter=",", skiprows=1)
    q_down = np.quaternion(0, 1, 0, 0) * quaternion.from_float_array(rows[:, 4:8])
    yaw, pitch, roll = attitude.as_euler(q_down)
    down = np.column_stack([rows[:, 0], rows[:, 1], -rows[:, 2], -rows[:, 3], roll, pitch, yaw])
    (tmp_path / "down.csv").write_text("t,x,y,z,roll,pitch,yaw\n" + "\n".join(
        ",".join(f"{v:.12g}" for v in row) for row in down) + "\n")
    text = (tmp_path / "spec.toml").read_text().replace("truth.csv", "down.csv").replace(
        'attitude_wxyz = { file = "down.csv", columns = ["qw", "qx", "qy", "qz"] }',
        'attitude_rpy = { file = "down.csv", columns = ["roll", "pitch", "yaw"], unit = "rad" }'
    ).replace('axes = "z_up"', 'axes = "z_down"')
    (tmp_path / "spec.toml").write_text(text)
    ref = table.read(tmp_path / "spec.toml").reference
    np.testing.assert_allclose(ref["lat"], given["lat"], atol=1e-12)
    np.testing.assert_allclose(ref["lon"], given["lon"], atol=1e-12)
    same = np.minimum(np.abs(ref["q_nb"] - given["q_nb"]).max(axis=1),
                      np.abs(ref["q_nb"] + given["q_nb"]).max(axis=1))
    assert same.max() < 1e-9


def test_a_reference_of_gyros_alone_is_refused_naming_what_can_be_done(tmp_path):
    """A reference IMU of gyros alone (KAIST's FOG: angle increments, no accelerometers) is
    not read: the refusal says why and what diagnoses the IMU instead (a new user had been
    told only that it needs specific_force, and the navigation level's words then sent him
    back to a reference IMU)."""
    _room(tmp_path, reference_imu_axes="FRD")
    text = (tmp_path / "spec.toml").read_text()
    gyros_only = text.replace('specific_force = { file = "ref.csv", columns = ["ax", "ay", '
                              '"az"] }\n', "")
    assert gyros_only != text
    (tmp_path / "spec.toml").write_text(gyros_only)
    with pytest.raises(RecordingError, match=r"\[reference_imu\] needs specific_force or "
                       "velocity_increment: .*a reference of gyros alone .* is not read yet"):
        table.read(tmp_path / "spec.toml")


def test_stamps_jittered_back_are_not_told_to_be_sorted(tmp_path):
    """A reference whose stamps jitter so that some step back by a fraction of a step (an
    INS's late stamps): refused, but not with "sort it" - that would reorder its samples;
    the words say the stamps jitter and what to do. Rows out of order by steps keep the
    sort advice."""
    _room(tmp_path)
    path = tmp_path / "truth.csv"
    lines = path.read_text().splitlines()
    t = np.array([float(line.split(",")[0]) for line in lines[1:]])
    t[100::50] += 0.0102                  # 10 ms steps: these land just past the next stamp
    t[425] += 0.014                       # and one 4 ms past it: the deepest step back
    path.write_text("\n".join([lines[0]] + [",".join([f"{x:.12g}"] + line.split(",")[1:])
                                            for x, line in zip(t, lines[1:])]) + "\n")
    with pytest.raises(RecordingError, match="jittered stamp") as raised:
        table.read(str(tmp_path / "spec.toml"))
    assert "sort the reference" not in str(raised.value)
    assert "step back by at most 4 ms" in str(raised.value), str(raised.value)
    t[100::50] -= 0.0102
    t[425] -= 0.014
    t[200], t[201] = t[201], t[200]
    t[300], t[302] = t[302], t[300]
    path.write_text("\n".join([lines[0]] + [",".join([f"{x:.12g}"] + line.split(",")[1:])
                                            for x, line in zip(t, lines[1:])]) + "\n")
    with pytest.raises(RecordingError, match="sort the reference by time"):
        table.read(str(tmp_path / "spec.toml"))

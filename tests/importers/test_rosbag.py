"""ROS recordings in every container - a ROS 2 MCAP file, a rosbag2 folder (sqlite3) and a
ROS 1 .bag - written by independent writers (the project's MCAP writer; rosbags' own ROS 1
and CDR serializers), read by the one ROS importer: the same numbers from each, the numbers
written, and damage said in one line."""
import math

import numpy as np
import pytest

from mimunav.cli import main
from mimunav.flightlog import FlightLog, LogWriter
from mimunav.flightlog import schemas as S
from mimunav.importers import ros2
from mimunav.importers.recording import RecordingError

from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import Stores, get_typestore

N, RATE = 1500, 100.0
T0_NS = 1_700_000_000_000_000_000
FRAME_IDS = tuple("imu_link_"[:k] for k in range(10))   # each moves the floats' alignment


def recording():
    """A level IMU turning slowly, its stamps 10 ms apart with a jitter of a few us, a second
    IMU, fixes at 4 Hz and odometry at 10 Hz of a vehicle driving 10 m/s at ENU yaw 30 deg."""
    rng = np.random.default_rng(11)
    stamps = T0_NS + np.arange(N) * 10_000_000 + rng.integers(-3000, 3000, N)
    w = rng.normal(0, 0.02, (N, 3))
    f = np.array([0.0, 0.0, 9.80]) + rng.normal(0, 0.05, (N, 3))
    fix_ns = stamps[::25]
    fix = dict(latitude=47.37 + 1e-6 * np.arange(len(fix_ns)), longitude=np.full(len(fix_ns), 8.55),
               altitude=np.full(len(fix_ns), 480.0), status=np.full(len(fix_ns), 2, np.int8),
               covariance=np.tile(np.diag([4e-4, 4e-4, 1e-3]).ravel(), (len(fix_ns), 1)))
    odom_ns = stamps[::10]
    t = (odom_ns - odom_ns[0]) / 1e9
    yaw = math.radians(30.0)
    odom = np.column_stack([10 * t * math.cos(yaw), 10 * t * math.sin(yaw), np.zeros_like(t)])
    return dict(ns=stamps, w=w, f=f, w_ref=-w, f_ref=f[:, ::-1], fix_ns=fix_ns, fix=fix,
                odom_ns=odom_ns, odom=odom, yaw=yaw)


def write_mcap(path, r):
    """The ROS 2 MCAP, by the project's writer (no odometry)."""
    fix_ns, fix = r["fix_ns"], r["fix"]
    with LogWriter(path) as log:
        log.write("/imu", S.IMU, "imu_link", r["ns"], **S.imu_fields(r["w"], r["f"]))
        log.write("/ref", S.IMU, "ref", r["ns"], **S.imu_fields(r["w_ref"], r["f_ref"]))
        log.write("/fix", S.NAV_SAT_FIX, "gps", fix_ns, status=fix["status"],
                  service=np.ones(len(fix_ns), np.uint16), latitude=fix["latitude"],
                  longitude=fix["longitude"], altitude=fix["altitude"],
                  position_covariance=fix["covariance"],
                  position_covariance_type=np.full(len(fix_ns), 2, np.uint8))


def rosbags_messages(r, ts, ros1):
    """(topic, type, stamp ns, message) of the recording as rosbags' typestore `ts` builds
    them (ROS 1's headers carry a seq)."""
    T = ts.types
    V, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]

    def header(ns, k, frame):
        stamp = T["builtin_interfaces/msg/Time"](sec=int(ns // 10**9), nanosec=int(ns % 10**9))
        if ros1:
            return T["std_msgs/msg/Header"](seq=k, stamp=stamp, frame_id=frame)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def imu(ns, k, w, f):
        return T["sensor_msgs/msg/Imu"](
            header=header(ns, k, FRAME_IDS[k % len(FRAME_IDS)]),
            orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=np.zeros(9),
            angular_velocity=V(x=w[0], y=w[1], z=w[2]),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=V(x=f[0], y=f[1], z=f[2]),
            linear_acceleration_covariance=np.zeros(9))

    out = []
    for k, ns in enumerate(r["ns"]):
        out.append(("/imu", "sensor_msgs/msg/Imu", ns, imu(ns, k, r["w"][k], r["f"][k])))
        out.append(("/ref", "sensor_msgs/msg/Imu", ns, imu(ns, k, r["w_ref"][k], r["f_ref"][k])))
    fix = r["fix"]
    for k, ns in enumerate(r["fix_ns"]):
        status = T["sensor_msgs/msg/NavSatStatus"](status=int(fix["status"][k]), service=1)
        out.append(("/fix", "sensor_msgs/msg/NavSatFix", ns, T["sensor_msgs/msg/NavSatFix"](
            header=header(ns, k, "gps"), status=status, latitude=fix["latitude"][k],
            longitude=fix["longitude"][k], altitude=fix["altitude"][k],
            position_covariance=fix["covariance"][k], position_covariance_type=2)))
    q = Q(x=0.0, y=0.0, z=math.sin(r["yaw"] / 2), w=math.cos(r["yaw"] / 2))
    for k, ns in enumerate(r["odom_ns"]):
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](
            x=r["odom"][k, 0], y=r["odom"][k, 1], z=r["odom"][k, 2]), orientation=q)
        twist = T["geometry_msgs/msg/Twist"](linear=V(x=10.0, y=0.0, z=0.0),
                                            angular=V(x=0.0, y=0.0, z=0.0))
        with_cov = T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36))
        out.append(("/odom", "nav_msgs/msg/Odometry", ns, T["nav_msgs/msg/Odometry"](
            header=header(ns, k, "map"), child_frame_id="base_link", pose=with_cov,
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist,
                                                             covariance=np.zeros(36)))))
        kind = "geometry_msgs/msg/PoseWithCovarianceStamped"
        out.append(("/amcl", kind, ns, T[kind](header=header(ns, k, "map"), pose=with_cov)))
        kind = "geometry_msgs/msg/PointStamped"
        out.append(("/leica", kind, ns, T[kind](header=header(ns, k, "map"), point=T[
            "geometry_msgs/msg/Point"](x=r["odom"][k, 0], y=r["odom"][k, 1], z=0.0))))
        kind = "geometry_msgs/msg/TransformStamped"
        out.append(("/vicon", kind, ns, T[kind](
            header=header(ns, k, "world"), child_frame_id="body",
            transform=T["geometry_msgs/msg/Transform"](translation=V(
                x=r["odom"][k, 0], y=r["odom"][k, 1], z=r["odom"][k, 2]), rotation=q))))
    return sorted(out, key=lambda m: m[2])


def write_ros1(path, r):
    ts = get_typestore(Stores.ROS1_NOETIC)
    with Ros1Writer(path) as bag:
        connections = {}
        for topic, kind, ns, msg in rosbags_messages(r, ts, ros1=True):
            if topic not in connections:
                connections[topic] = bag.add_connection(topic, kind, typestore=ts)
            bag.write(connections[topic], int(ns), ts.serialize_ros1(msg, kind))


def write_rosbag2(path, r):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Ros2Writer(path, version=8) as bag:
        connections = {}
        for topic, kind, ns, msg in rosbags_messages(r, ts, ros1=False):
            if topic not in connections:
                connections[topic] = bag.add_connection(topic, kind, typestore=ts)
            bag.write(connections[topic], int(ns), ts.serialize_cdr(msg, kind))


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp("bags")
    r = recording()
    write_mcap(root / "r.mcap", r)
    write_ros1(root / "r.bag", r)
    write_rosbag2(root / "r2", r)
    return r, root


def test_every_container_gives_the_numbers_written(bags):
    """The IMU, the reference IMU and the fixes read from the three containers are the
    numbers written, bit for bit; the container is said."""
    r, root = bags
    containers = {"r.mcap": "ROS 2 MCAP", "r.bag": "ROS 1 bag", "r2": "rosbag2 folder"}
    for name, container in containers.items():
        rec = ros2.read(root / name, "/imu", "/fix", reference_imu_topic="/ref")
        assert np.array_equal(rec.imu_ns, r["ns"]), name
        assert np.array_equal(rec.w, r["w"]) and np.array_equal(rec.f, r["f"]), name
        assert np.array_equal(rec.reference_imu["ns"], r["ns"]), name
        assert np.array_equal(rec.reference_imu["w"], r["w_ref"]), name
        assert np.array_equal(rec.reference_imu["f"], r["f_ref"]), name
        assert np.array_equal(rec.fixes["ns"], r["fix_ns"]), name
        assert np.array_equal(rec.fixes["lat"], np.radians(r["fix"]["latitude"])), name
        assert np.array_equal(rec.fixes["covariance"], r["fix"]["covariance"]), name
        assert container in rec.real["source"] and container in rec.description
        assert rec.assumed["reference_imu_lever_arm"].startswith("none: the two IMUs")
        # fixes not taken as the reference are said so (a tractor's had gone without a word)
        assert rec.reference is None and rec.real["reference"].startswith(
            f"none: the {len(r['fix_ns'])} fixes of /fix are kept as GNSS fixes")


@pytest.mark.slow
def test_a_ros1_pose_reference_is_placed_as_a_ros2_ones(bags):
    """Odometry in a level ENU frame at a given origin, from a ROS 1 bag and a rosbag2 folder:
    the same reference, its heading 60 deg (ENU yaw 30) and its velocity (5, 8.66, 0) m/s NED
    from the body-frame twist; the same poses as a PoseWithCovarianceStamped and as a
    motion-capture TransformStamped give the same places and attitudes."""
    r, root = bags

    def reference(name, topic):
        return ros2.read(root / name, "/imu", pose_topic=topic, origin=(47.37, 8.55, 480.0),
                         pose_azimuth=90.0).reference
    refs = [reference(name, "/odom") for name in ("r.bag", "r2")]
    for key in ("ns", "lat", "lon", "h", "v_ned", "q_nb"):
        assert np.array_equal(np.asarray(refs[0][key]), np.asarray(refs[1][key])), key
    for topic in ("/amcl", "/vicon"):
        other = reference("r.bag", topic)
        for key in ("ns", "lat", "lon", "h", "q_nb"):
            assert np.array_equal(np.asarray(refs[0][key]), np.asarray(other[key])), key
    with pytest.raises(RecordingError, match="PointStamped.*import table.*position_local"):
        reference("r.bag", "/leica")                 # positions alone: the table importer's
    heading = np.degrees(np.arctan2(refs[0]["v_ned"][:, 1], refs[0]["v_ned"][:, 0]))
    np.testing.assert_allclose(heading, 60.0, atol=0.01)
    assert np.array_equal(refs[0]["ns"], r["odom_ns"])
    # the local frame's level at the origin: 450 m on, the NED there turns it by ~7e-5 rad
    np.testing.assert_allclose(refs[0]["v_ned"], np.tile([5.0, 10 * math.sin(math.radians(60)),
                                                          0.0], (len(r["odom_ns"]), 1)),
                               atol=1e-3)


@pytest.mark.slow
def test_a_ros1_bag_imports_on_the_command_line(bags, tmp_path):
    """`mimunav import ros1 BAG` (and `ros2` of the same bag) writes the log the MCAP gives."""
    _, root = bags
    logs = {}
    for kind, name in (("ros2", "r.mcap"), ("ros1", "r.bag"), ("ros2", "r.bag"),
                       ("ros2", "r2")):
        out = tmp_path / f"{kind}-{name}.log.mcap"
        assert main(["import", kind, str(root / name), "--imu-topic", "/imu", "-o",
                     str(out)]) == 0
        with FlightLog(out) as log:
            logs[kind, name] = log.read("/mimu/imu")
    first = logs["ros2", "r.mcap"]
    for key, imu in logs.items():
        for field in first.dtype.names:
            assert np.array_equal(imu[field], first[field]), (key, field)


@pytest.mark.slow
def test_a_damaged_or_foreign_bag_is_said_in_one_line(bags, tmp_path, capsys):
    """A ROS 1 bag cut short, an Imu message of the wrong length and a file of no ROS kind are
    refused naming the file and what is wrong, with exit status 2 on the command line."""
    r, root = bags
    data = (root / "r.bag").read_bytes()
    (tmp_path / "cut.bag").write_bytes(data[: len(data) // 2])
    with pytest.raises(RecordingError, match="cut.bag: a ROS 1 bag that cannot be read"):
        ros2.read(tmp_path / "cut.bag", "/imu")
    ts = get_typestore(Stores.ROS1_NOETIC)
    with Ros1Writer(tmp_path / "short.bag") as bag:
        c = bag.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for topic, kind, ns, msg in rosbags_messages(r, ts, ros1=True)[:40]:
            if topic == "/imu":
                bag.write(c, int(ns), ts.serialize_ros1(msg, kind)[:-8])
    with pytest.raises(RecordingError,
                       match=r"short.bag: .*an Imu message of 304 bytes, 312 expected"):
        ros2.read(tmp_path / "short.bag")
    with pytest.raises(RecordingError, match="missing.bag: no such file or folder"):
        ros2.read(tmp_path / "missing.bag")
    (tmp_path / "notes.bag").write_text("not a bag\n")
    assert main(["import", "ros1", str(tmp_path / "notes.bag"), "-o",
                 str(tmp_path / "x.mcap")]) == 2
    assert "neither an MCAP file, a ROS 1 bag" in capsys.readouterr().err
    assert not (tmp_path / "x.mcap").exists()
    # a bag given where a contract log belongs: the import that reads it is named
    assert main(["info", str(root / "r.bag")]) == 2
    assert "a ROS 1 bag: `mimunav import ros1 FILE -o LOG.mcap`" in capsys.readouterr().err
    assert main(["info", str(root / "r2")]) == 2
    assert "a folder, not a log file; it looks like a rosbag2 folder: `mimunav import ros2 " \
        "FOLDER -o LOG.mcap`" in capsys.readouterr().err
    db3 = next((root / "r2").glob("*.db3"))
    assert main(["diagnose", str(db3)]) == 2
    assert "`mimunav import ros2 FOLDER -o LOG.mcap`" in capsys.readouterr().err

"""Any ROS recording - a ROS 2 MCAP file, a rosbag2 folder (sqlite3 or MCAP storage) or a
ROS 1 .bag (`rosbag.open_bag`): the IMU from a `sensor_msgs/msg/Imu` topic and, when present,
GNSS fixes from a `sensor_msgs/msg/NavSatFix` topic. The
reference may be RTK-grade fixes (`reference_status`) or a pose topic
(`nav_msgs/msg/Odometry`, `geometry_msgs/msg/PoseStamped`) in a local ENU frame placed at a
given geodetic origin (REP-105 map/odom frames carry no geodetic origin of their own).

ROS conventions (REP-103, REP-145): angular_velocity rad/s and linear_acceleration m/s^2
(the specific force: +g up at rest) in the message's frame_id; a body frame is x forward,
y left, z up (FLU), so the default mounting to the vehicle's FRD is a half turn about x.
NavSatFix: latitude/longitude deg (turned to rad), altitude m above the WGS-84 ellipsoid,
position_covariance m^2 ENU. Pose: position m in the frame's ENU axes, orientation the
body (FLU, child frame) in that frame; Odometry twist in the child (body) frame. Times:
header.stamp (the sensor's time), log_time where a stamp is zero.
"""
import math

import numpy as np
import quaternion

from ..frames.mounting import Mounting
from .local_frame import LocalFrame
from .rosbag import open_bag
from .recording import RecordingError, Recording, unit_quaternions
from ..motion.track import velocity_from_positions

IMU = "sensor_msgs/msg/Imu"
NAV_SAT_FIX = "sensor_msgs/msg/NavSatFix"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_COVARIANCE = "geometry_msgs/msg/PoseWithCovarianceStamped"
TRANSFORM = "geometry_msgs/msg/TransformStamped"      # a motion-capture system's (vrpn, vicon)
POSES = (ODOMETRY, POSE_STAMPED, POSE_COVARIANCE, TRANSFORM)
FLU_TO_FRD = Mounting.from_axes("FLU")            # a half turn about x
# q_FLU<-FRD: a half turn about x (Hamilton, scalar first); REP-103's ENU: `local_frame`
Q_FLU_FRD = quaternion.quaternion(0.0, 1.0, 0.0, 0.0)


OPTION = {IMU: "--imu-topic (and a second IMU as --reference-imu-topic)",
          NAV_SAT_FIX: "--fix-topic"}


def _pick(path, available, schema, topic, required):
    found = [t for t, s in available.items() if s == schema]
    if topic is not None:
        if available.get(topic) != schema:
            raise RecordingError(f"{path}: {topic!r} is not a {schema} topic (those: {found})")
        return topic
    if len(found) == 1:
        return found[0]
    if not found and not required:
        return None
    raise RecordingError(f"{path}: {len(found)} {schema} topics {found}; choose one by "
                         f"{OPTION.get(schema, 'topic')}")


def read(path, imu_topic=None, fix_topic=None, mounting=None, reference_status=None,
         reference_sigma_m=np.inf, pose_topic=None, origin=None, reference_imu_topic=None,
         reference_imu_mounting=None, pose_azimuth=None, reference_independent=None):
    """The recording of a ROS bag (a file or a rosbag2 folder) as a `Recording`. With
    `reference_status` (the lowest NavSatStatus that counts: 2 = GBAS_FIX, RTK-grade) the
    fixes of at least that status whose horizontal sigma (from position_covariance, when
    known) is at most reference_sigma_m serve as the reference trajectory too, velocity from
    central differences of their positions. With `pose_topic` (Odometry or PoseStamped) and
    `origin` (lat deg, lon deg, h m of the pose frame's origin) the poses are the reference
    instead (`_pose_reference`): a z-up frame whose x axis points `pose_azimuth` (deg) east
    of north; not given (or "unknown"), REP-103's ENU is taken for it, but its heading is
    no measurement (a SLAM map's x points anywhere): the log's initial heading is assumed.
    `reference_independent` ("yes: why" / "no: why") says whether the poses are independent
    of this IMU. With `reference_imu_topic` a second Imu topic (a better IMU
    flown with it; `reference_imu_mounting`, default REP-103 FLU) is the reference IMU."""
    bag = open_bag(path)
    available = bag.topics()
    imu_topic = _pick(path, available, IMU, imu_topic, required=True)
    fix_topic = _pick(path, available, NAV_SAT_FIX, fix_topic, required=False)
    ns, w, f, dropped = _imu(bag, imu_topic)
    fixes, repeated = _fixes(bag, fix_topic) if fix_topic else (None, 0)
    reference, reference_meta, frame = _reference(
        bag, available, pose_topic, origin, pose_azimuth, reference_status, reference_sigma_m,
        fixes, fix_topic)
    real = {"imu": f"{imu_topic} ({len(ns) + dropped} messages; {dropped} repeated stamps "
                   "dropped)", "source": f"{bag.path.name} ({bag.container})"}
    if fixes is not None:
        real["gnss"] = (f"{fix_topic} ({len(fixes['ns'])} fixes with status >= 0; "
                        f"{repeated} repeated stamps dropped)")
    assumed = {"mounting": "REP-103 body axes (x forward, y left, z up) -> FRD" if mounting is None
               else "given on the command line",
               "calibration": "none: the Imu messages are used as recorded"}
    if reference_independent is not None:
        if reference is None:
            raise RecordingError("--reference-independent says of a reference trajectory: "
                                 "give one (--pose-topic, or --reference-status)")
        reference_meta["independent"] = reference_independent
    if frame is not None and not frame.azimuth_known:
        assumed["reference_frame"] = frame.description
    if reference is not None:
        real["reference"] = f"{len(reference['ns'])} epochs: {reference_meta['source']}"
    elif fixes is not None:     # said: a tractor's RTK fixes had been left out without a word
        real["reference"] = (f"none: the {len(fixes['ns'])} fixes of {fix_topic} are kept as "
                             "GNSS fixes, not taken as the reference trajectory "
                             "(--reference-status 2 takes the RTK-grade ones)")
    second = None
    if reference_imu_topic is not None:
        topic = _pick(path, available, IMU, reference_imu_topic, required=True)
        if topic == imu_topic:
            raise RecordingError(f"{path}: the reference IMU's topic is the IMU's own ({topic})")
        r_ns, r_w, r_f, r_dropped = _imu(bag, topic)
        second = dict(ns=r_ns, w=r_w, f=r_f, mounting=reference_imu_mounting or FLU_TO_FRD,
                      model=f"reference IMU of {topic}",
                      mounting_hint="--reference-imu-rpy-deg {roll} {pitch} {yaw}")
        real["reference_imu"] = (f"{topic} ({len(r_ns) + r_dropped} messages; {r_dropped} "
                                 "repeated stamps dropped)")
        assumed["reference_imu_mounting"] = ("REP-103 body axes -> FRD" if
                                             reference_imu_mounting is None else
                                             "given on the command line")
        assumed["reference_imu_lever_arm"] = ("none: the two IMUs taken at one point "
                                              "(--reference-imu-lever-arm-m X Y Z places it)")
    rate = 1e9 / np.median(np.diff(ns))
    return Recording(bag.path.stem, f"{bag.container} {bag.path.name}: {imu_topic} {rate:.0f} Hz, "
                     f"{(ns[-1] - ns[0]) / 1e9:.1f} s", ns, w, f, mounting or FLU_TO_FRD,
                     fixes=fixes, reference=reference, reference_meta=reference_meta,
                     real=real, assumed=assumed, reference_imu=second,
                     reference_heading_known=frame is None or frame.azimuth_known)


def _reference(bag, available, pose_topic, origin, pose_azimuth, reference_status,
               reference_sigma_m, fixes, fix_topic):
    """(reference, its metadata, its `local_frame.LocalFrame` or None) of `read`: the pose
    topic's in its frame, or the fixes of at least reference_status, or none."""
    if pose_topic is not None:
        if reference_status is not None:
            raise RecordingError("choose one reference: RTK fixes (--reference-status) or a "
                                 "pose topic (--pose-topic)")
        frame = LocalFrame.from_axes(
            "z_up", origin, None if pose_azimuth in (None, "unknown") else float(pose_azimuth),
            taken=(90.0, "REP-103's ENU; mimunav import --pose-azimuth DEG gives it"))
        reference, meta = _pose_reference(bag, available, pose_topic, frame)
        return reference, {**meta, "frame": frame.description}, frame
    if pose_azimuth is not None:
        raise RecordingError("--pose-azimuth is the azimuth of --pose-topic's frame: give the "
                             "pose topic too")
    if reference_status is not None:
        if fixes is None:
            raise RecordingError(f"{bag.path}: a reference from fixes needs a NavSatFix topic")
        return (*_fix_reference(fixes, reference_status, reference_sigma_m, fix_topic), None)
    return None, {}, None


def _imu(bag, topic):
    """(stamps ns, w rad/s, f m/s^2 (N, 3) in the message frame, repeated stamps dropped) of
    an Imu topic, sorted by stamp; a topic whose covariance[0] = -1 (REP-145: not measured)
    says it lacks a gyro or an accelerometer is refused."""
    rows = [(ns, *v[13:16], *v[25:28], v[16], v[28]) for ns, v in bag.imu_values(topic)]
    if len(rows) < 2:
        raise RecordingError(f"{bag.path}: {topic} has {len(rows)} messages")
    a = np.asarray(rows, dtype=object)
    for column, name in ((7, "angular_velocity"), (8, "linear_acceleration")):
        absent = a[:, column].astype(float) == -1
        if absent.mean() > 0.5:
            raise RecordingError(f"{bag.path}: {topic}'s {name}_covariance[0] = -1 in "
                                 f"{int(absent.sum())} of {len(a)} messages: the recorder says "
                                 f"it has no {name}; an inertial analysis needs both the gyro "
                                 "and the accelerometer")
    ns = a[:, 0].astype(np.int64)
    order = np.argsort(ns, kind="stable")
    ns, data = ns[order], a[order, 1:7].astype(float)
    keep = np.concatenate([[True], np.diff(ns) > 0])
    return ns[keep], data[keep, :3], data[keep, 3:], int((~keep).sum())


def _fixes(bag, topic):
    """(fixes: stamps ns, status, lat, lon rad, h m, position_covariance m^2, sorted by stamp -
    None when no fix is finite -, the count of repeated stamps dropped) of a NavSatFix topic;
    a fix of status -1 (NO_FIX) or with a coordinate not finite is left out."""
    ns, rows = [], []
    for ns_f, m in bag.messages(topic):
        ns.append(ns_f)
        rows.append((m.status.status, np.radians(m.latitude), np.radians(m.longitude),
                     m.altitude, *m.position_covariance))
    ns, fx = np.asarray(ns, dtype=np.int64), np.asarray(rows, dtype=float).reshape(-1, 13)
    good = np.isfinite(fx[:, 1:4]).all(axis=1) & (fx[:, 0] >= 0)
    order = np.argsort(ns[good], kind="stable")
    ns, fx = ns[good][order], fx[good][order]
    keep = np.concatenate([[True], np.diff(ns) > 0])[:len(ns)]   # a repeated stamp: the first
    ns, fx = ns[keep], fx[keep]
    if not len(ns):
        return None, int((~keep).sum())
    return dict(ns=ns, status=fx[:, 0].astype(np.int8), lat=fx[:, 1], lon=fx[:, 2], h=fx[:, 3],
                covariance=fx[:, 4:13]), int((~keep).sum())


def _fix_reference(fixes, status, sigma_m, topic):
    """The fixes of at least `status` and horizontal sigma <= sigma_m as a reference
    (velocity by central differences of the positions), and its metadata."""
    cov = fixes["covariance"]
    sigma = np.sqrt(np.maximum(cov[:, 0], 0) + np.maximum(cov[:, 4], 0))
    use = (fixes["status"] >= status) & ((sigma <= sigma_m) | ~(sigma > 0))
    if use.sum() < 3:
        raise RecordingError(f"{topic}: {int(use.sum())} fixes of status >= {status} and sigma "
                             f"<= {sigma_m:g} m; a reference needs at least 3")
    ns = fixes["ns"][use]
    lat, lon, h = fixes["lat"][use], fixes["lon"][use], fixes["h"][use]
    t = (ns - ns[0]) / 1e9
    meta = {"source": f"NavSatFix {topic}, status >= {status}, velocity from position "
                      "differences",
            "independent": "yes: GNSS only",
            "position_sigma_m": f"{np.median(sigma[use]):.3g}" if np.any(sigma[use] > 0)
                                else "not stated"}
    meta.update(_difference_velocity_sigma(sigma[use], t))
    v = velocity_from_positions(ns, lat, lon, h)
    ok = np.isfinite(v).all(axis=1)              # no velocity across a gap of the fixes
    return dict(ns=ns[ok], lat=lat[ok], lon=lon[ok], h=h[ok], v_ned=v[ok]), meta


def _pose_reference(bag, available, topic, frame):
    """A pose topic (POSES: Odometry, PoseStamped, PoseWithCovarianceStamped,
    TransformStamped) as the reference: positions in the local `frame`
    (`local_frame.LocalFrame`) -> geodetic, orientation (body FLU in that frame) -> q_nb
    (vehicle FRD -> NED), velocity from Odometry's body-frame twist, else central
    differences."""
    from ..frames import attitude
    schema = available.get(topic)
    if schema not in POSES:
        raise RecordingError(f"{bag.path}: {topic!r} is {schema or 'not a topic'}; a pose "
                             f"reference needs one of {', '.join(POSES)}" + (
                                 " - positions alone (a total station's PointStamped): write "
                                 "them to a CSV, and `mimunav import table` reads them as "
                                 "[reference] position_local" if schema and "Point" in schema
                                 else ""))
    stamps, rows = [], []
    for ns, m in bag.messages(topic):
        stamps.append(ns)
        rows.append((ns, *_pose_row(schema, m)))
    a = np.asarray(rows, dtype=float)
    if len(a) < 3 or not np.isfinite(a[:, 1:8]).all():
        raise RecordingError(f"{bag.path}: {topic} has {len(a)} poses (finite ones needed, >= 3)")
    order = np.argsort(stamps, kind="stable")
    a, ns = a[order], np.asarray(stamps, dtype=np.int64)[order]
    q_lb = unit_quaternions(a[:, 4:8], f"{topic}: an orientation")
    sigma = np.sqrt(np.maximum(a[:, 11], 0) + np.maximum(a[:, 12], 0))
    t = (ns - ns[0]) / 1e9
    # Odometry's twist is in the child (body) frame; a PoseStamped's velocity: differences
    v_l = attitude.rotate(q_lb, a[:, 8:11]) if schema == ODOMETRY else None
    reference = frame.place(ns, a[:, 1:4], v_l, q_lb * Q_FLU_FRD)
    if schema == ODOMETRY:
        how = "velocity from its body-frame twist"
        v_sigma = np.sqrt(np.maximum(a[:, 13], 0) + np.maximum(a[:, 14], 0))
        velocity = {"velocity_sigma_m_s": f"{np.median(v_sigma):.3g}"} if np.any(v_sigma > 0) \
            else {}
    else:
        how = "velocity from position differences"
        velocity = _difference_velocity_sigma(sigma, t)
    meta = {"source": f"{schema} {topic}, {frame.description}, {how}",
            "independent": "unknown: a pose estimate of the recording system, which may fuse "
                           "this IMU",
            "position_sigma_m": f"{np.median(sigma):.3g}" if np.any(sigma > 0) else "not stated",
            **velocity}
    return reference, meta


def _pose_row(schema, m):
    """(x, y, z m, qw, qx, qy, qz, body velocity x, y, z m/s (NaN: not given), position
    variances xx, yy m^2 and velocity variances xx, yy (m/s)^2 (0: not stated)) of a pose
    message of `schema` (POSES)."""
    zero = [0.0] * 36
    if schema == TRANSFORM:
        p, o, cov = m.transform.translation, m.transform.rotation, zero
    elif schema == POSE_STAMPED:
        p, o, cov = m.pose.position, m.pose.orientation, zero
    else:
        p, o, cov = m.pose.pose.position, m.pose.pose.orientation, m.pose.covariance
    if schema == ODOMETRY:
        v = (m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z)
        v_cov = m.twist.covariance
    else:
        v, v_cov = (np.nan,) * 3, zero
    return (p.x, p.y, p.z, o.w, o.x, o.y, o.z, *v, cov[0], cov[7], v_cov[0], v_cov[7])


def _difference_velocity_sigma(sigma, t):
    """Metadata of the horizontal velocity sigma of central differences of positions whose
    horizontal sigma is `sigma` (m) at times t (s): sigma / (sqrt(2) dt), independent fixes
    assumed; nothing when the positions' sigma is not stated."""
    if not np.any(sigma > 0) or len(t) < 3:
        return {}
    dt = float(np.median(np.diff(t)))
    return {"velocity_sigma_m_s": f"{np.median(sigma[sigma > 0]) / (math.sqrt(2) * dt):.3g}"}

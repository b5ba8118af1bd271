"""ROS 2 message schemas of the log contract (`ros2msg` text) and their CDR layouts as numpy
structured dtypes, so a channel of fixed-size messages encodes and decodes in one call.

CDR (XCDR1, little endian): a 4-byte encapsulation header 00 01 00 00, then the fields,
each aligned to its own size (at most 8) relative to the end of that header; a string is
a uint32 length (including the NUL) followed by the bytes and the NUL. With a constant
frame_id every message of a channel has the same size and layout.
"""
import numpy as np

SEP = "\n" + "=" * 80 + "\n"
_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec"
_HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id"
_VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z"
_QUAT = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w"


def _text(body, *deps):
    return (body + SEP + SEP.join(deps)).encode()


RAW_MIMU = "mimunav_msgs/msg/RawMimu"
NAV_STATE = "mimunav_msgs/msg/NavState"
IMU = "sensor_msgs/msg/Imu"
NAV_SAT_FIX = "sensor_msgs/msg/NavSatFix"
LAB_STATE = "mimunav_msgs/msg/LabState"
JOINT_STATE = "sensor_msgs/msg/JointState"
PLATFORM_JOINT = "platform"      # the one joint of /mimu/platform (log contract, README)

SCHEMAS = {
    RAW_MIMU: _text("std_msgs/Header header\nuint64 sample_index\nfloat64[3] gyro_volts\n"
                    "float64[3] accel_volts\nfloat64[3] accel_temperature\n"
                    "float64[3] gyro_frequency", _HEADER, _TIME),
    NAV_STATE: _text("std_msgs/Header header\nfloat64 latitude\nfloat64 longitude\n"
                     "float64 height\nfloat64[3] velocity_ned\nfloat64[4] attitude_wxyz",
                     _HEADER, _TIME),
    IMU: _text("std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
               "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
               "float64[9] angular_velocity_covariance\n"
               "geometry_msgs/Vector3 linear_acceleration\n"
               "float64[9] linear_acceleration_covariance", _HEADER, _TIME, _QUAT, _VECTOR3),
    NAV_SAT_FIX: _text("std_msgs/Header header\nsensor_msgs/NavSatStatus status\n"
                       "float64 latitude\nfloat64 longitude\nfloat64 altitude\n"
                       "float64[9] position_covariance\nuint8 position_covariance_type",
                       _HEADER, _TIME, "MSG: sensor_msgs/NavSatStatus\nint8 status\n"
                       "uint16 service"),
    # Calibration-lab state (mimunav extension, documented in mimunav.lab): one message when
    # a set point begins (steady = 0) and one when it has settled (steady = 1); the state
    # holds until the next message.
    LAB_STATE: _text("std_msgs/Header header\nuint32 point\nuint32 position\nuint8 steady\n"
                     "float64[4] fixture_attitude_wxyz\nfloat64[3] position_m\n"
                     "float64 table_angle\nfloat64 table_rate\nfloat64[6] sensor_radius_m\n"
                     "float64 chamber_temperature", _HEADER, _TIME),
    # A rotating MIMU's platform (seed S4): one joint, its angle (rad) and rate (rad/s)
    JOINT_STATE: _text("std_msgs/Header header\nstring[] name\nfloat64[] position\n"
                       "float64[] velocity\nfloat64[] effort", _HEADER, _TIME),
}

# Fields after the header: (name, numpy scalar type, count). Imu vectors are 3 (x, y, z) and
# the orientation quaternion is (x, y, z, w) as in geometry_msgs.
BODIES = {
    RAW_MIMU: [("sample_index", "<u8", 1), ("gyro_volts", "<f8", 3), ("accel_volts", "<f8", 3),
               ("accel_temperature", "<f8", 3), ("gyro_frequency", "<f8", 3)],
    NAV_STATE: [("latitude", "<f8", 1), ("longitude", "<f8", 1), ("height", "<f8", 1),
                ("velocity_ned", "<f8", 3), ("attitude_wxyz", "<f8", 4)],
    NAV_SAT_FIX: [("status", "<i1", 1), ("service", "<u2", 1), ("latitude", "<f8", 1),
                  ("longitude", "<f8", 1), ("altitude", "<f8", 1),
                  ("position_covariance", "<f8", 9), ("position_covariance_type", "<u1", 1)],
    LAB_STATE: [("point", "<u4", 1), ("position", "<u4", 1), ("steady", "<u1", 1),
                ("fixture_attitude_wxyz", "<f8", 4), ("position_m", "<f8", 3),
                ("table_angle", "<f8", 1), ("table_rate", "<f8", 1),
                ("sensor_radius_m", "<f8", 6), ("chamber_temperature", "<f8", 1)],
    # one joint: sequence lengths as fields, the joint's name a fixed string (kind "string",
    # its count is the value)
    JOINT_STATE: [("name_count", "<u4", 1), ("name", "string", PLATFORM_JOINT),
                  ("position_count", "<u4", 1), ("position", "<f8", 1),
                  ("velocity_count", "<u4", 1), ("velocity", "<f8", 1),
                  ("effort_count", "<u4", 1)],
    IMU: [("orientation", "<f8", 4), ("orientation_covariance", "<f8", 9),
          ("angular_velocity", "<f8", 3), ("angular_velocity_covariance", "<f8", 9),
          ("linear_acceleration", "<f8", 3), ("linear_acceleration_covariance", "<f8", 9)],
}

ENCAPSULATION = b"\x00\x01\x00\x00"       # CDR, little endian


def cdr_dtype(schema_name: str, frame_id: str) -> np.dtype:
    """Structured dtype of one whole message (encapsulation + header + body) for a fixed
    frame_id; fields encap, sec, nanosec, frame_len, frame_id, then the body's fields."""
    frame = frame_id.encode() + b"\x00"
    names = ["encap", "sec", "nanosec", "frame_len", "frame_id"]
    formats = ["V4", "<i4", "<u4", "<u4", f"S{len(frame)}"]
    offsets = [0, 4, 8, 12, 16]
    pos = 12 + len(frame)                       # relative to the end of the encapsulation
    for name, kind, count in BODIES[schema_name]:
        if kind == "string":                  # uint32 length (with the NUL), then the bytes
            text = count.encode() + b"\x00"
            pos = -(-pos // 4) * 4
            names += [f"{name}_len", name]
            formats += ["<u4", f"S{len(text)}"]
            offsets += [pos + 4, pos + 8]
            pos += 4 + len(text)
            continue
        size = np.dtype(kind).itemsize
        pos = -(-pos // min(size, 8)) * min(size, 8)
        names.append(name)
        formats.append(kind if count == 1 else (kind, (count,)))
        offsets.append(pos + 4)
        pos += size * count
    return np.dtype({"names": names, "formats": formats, "offsets": offsets,
                     "itemsize": pos + 4})


def encode(schema_name: str, frame_id: str, stamp_ns: np.ndarray, out: np.ndarray | None = None,
           **fields: np.ndarray) -> np.ndarray:
    """Messages as one structured array (N,): stamps in integer ns since the epoch; each
    body field an array (N,) or (N, count); out: a zeroed array of `cdr_dtype` (N,) to
    fill (a view into Message records), else a new one."""
    stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
    if out is None:
        out = np.zeros(len(stamp_ns), dtype=cdr_dtype(schema_name, frame_id))
    out["encap"] = np.frombuffer(ENCAPSULATION, dtype="V4")[0]
    sec = stamp_ns // 1_000_000_000                # floor: a stamp before 1970 has
    out["sec"], out["nanosec"] = sec, stamp_ns - sec * 1_000_000_000   # nanosec >= 0
    out["frame_len"] = len(frame_id) + 1
    out["frame_id"] = frame_id.encode()
    for name, kind, text in BODIES[schema_name]:
        if kind == "string":
            out[f"{name}_len"], out[name] = len(text) + 1, text.encode()
    for name, value in fields.items():
        out[name] = value
    return out


def platform_fields(angle: np.ndarray, rate: np.ndarray) -> dict[str, np.ndarray]:
    """/mimu/platform fields: the platform angle (rad) and rate (rad/s), (N,) each."""
    n = len(angle)
    return {"name_count": np.ones(n, np.uint32), "position_count": np.ones(n, np.uint32),
            "position": angle, "velocity_count": np.ones(n, np.uint32), "velocity": rate,
            "effort_count": np.zeros(n, np.uint32)}


def imu_fields(angular_velocity: np.ndarray, linear_acceleration: np.ndarray
               ) -> dict[str, np.ndarray]:
    """Body fields of sensor_msgs/msg/Imu as the contract writes them: rate (rad/s) and
    specific force (m/s^2), orientation identity with orientation_covariance[0] = -1."""
    n = len(angular_velocity)
    return dict(orientation=np.tile([0.0, 0, 0, 1], (n, 1)),
                orientation_covariance=np.tile([-1.0] + [0.0] * 8, (n, 1)),
                angular_velocity=angular_velocity, linear_acceleration=linear_acceleration)


def stamps_ns(msgs: np.ndarray) -> np.ndarray:
    """header.stamp of decoded messages as integer ns since the epoch."""
    return msgs["sec"].astype(np.int64) * 1_000_000_000 + msgs["nanosec"].astype(np.int64)

"""A ROS recording in any of its containers, read one topic at a time: a ROS 2 MCAP file (the
mcap package; messages in CDR), a rosbag2 folder (its metadata.yaml beside sqlite3 .db3 or
MCAP storage) or a ROS 1 .bag (both by rosbags; messages in CDR or ROS 1's serialization).
rosbags names a ROS 1 type as ROS 2 does ('sensor_msgs/msg/Imu') and reads ROS 1's
header.stamp.nsecs as .nanosec, so a message's fields are the same in either.

`open_bag(path)` -> a bag with `topics()` ({topic: type}), `messages(topic)` ((stamp ns,
decoded message) in file order) and `imu_values(topic)` ((stamp ns, the 37 float64 of a
sensor_msgs Imu) read from the bytes directly: an hour at 100 Hz in seconds where a
decoder takes minutes). The stamp is header.stamp, the recorder's log time where it is 0.
"""
import struct
from contextlib import contextmanager
from pathlib import Path

import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader

from ..errors import require
from ..flightlog.writer import MAGIC
from .recording import RecordingError

ROS1_MAGIC = b"#ROSBAG V2.0"
IMU_FLOATS = 37              # orientation (4), its covariance (9), angular velocity (3), its
#                              covariance (9), linear acceleration (3), its covariance (9)

# what a damaged or truncated file raises from the mcap package's reader and decoders
_DAMAGE = (McapError, EOFError, struct.error, ValueError, KeyError, IndexError,
           zstandard.ZstdError)


def open_bag(path):
    """The bag at `path`: an MCAP file, a rosbag2 folder (or a file in it) or a ROS 1 .bag,
    told by its first bytes and its folder, not by its name's extension."""
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such file or folder")
    if path.is_file():
        with open(path, "rb") as fh:
            head = fh.read(len(ROS1_MAGIC))
        if head.startswith(MAGIC[:5]):          # an MCAP of any version
            return McapBag(path)
        if head == ROS1_MAGIC:
            return RosbagsBag(path, path, "ROS 1 bag")
        if (path.parent / "metadata.yaml").is_file():
            return RosbagsBag(path, path.parent, "rosbag2 folder")
        raise RecordingError(f"{path}: neither an MCAP file, a ROS 1 bag (its first bytes "
                             f"{head!r}, not {ROS1_MAGIC!r}) nor a file of a rosbag2 folder "
                             "(no metadata.yaml beside it: `ros2 bag reindex FOLDER` writes "
                             "it)")
    if (path / "metadata.yaml").is_file():
        return RosbagsBag(path, path, "rosbag2 folder")
    raise RecordingError(f"{path}: not a ROS bag: a file (MCAP, ROS 1 .bag) or a rosbag2 "
                         "folder with its metadata.yaml")


def cdr_imu_values(data):
    """(sec, nanosec, 37 float64) of a sensor_msgs/msg/Imu in CDR (OMG XCDR1 as ROS 2 writes
    it: a 4-byte encapsulation header, little- or big-endian by its second byte, then the
    fields aligned to their size from the data's start: Header {int32 sec, uint32 nanosec,
    string frame_id: uint32 length with its NUL, then the bytes}, then the float64 fields
    from the next multiple of 8)."""
    if data[1] not in (0, 1):
        raise ValueError(f"header {data[:4].hex()}: not CDR")
    end = "<" if data[1] == 1 else ">"
    sec, nanosec, length = struct.unpack_from(end + "iII", data, 4)
    start = 4 + (12 + length + 7) // 8 * 8
    return sec, nanosec, struct.unpack_from(end + f"{IMU_FLOATS}d", data, start)


def ros1_imu_values(data):
    """(sec, nsecs, 37 float64) of a sensor_msgs/Imu in ROS 1's serialization (little-endian,
    packed: Header {uint32 seq, uint32 sec, uint32 nsecs, string frame_id: uint32 length, then
    the bytes}, then the float64 fields); a message of another length is refused as damage."""
    _, sec, nsecs, length = struct.unpack_from("<IIII", data, 0)
    start = 16 + length
    if len(data) != start + 8 * IMU_FLOATS:
        raise ValueError(f"an Imu message of {len(data)} bytes, {start + 8 * IMU_FLOATS} "
                         "expected")
    return sec, nsecs, struct.unpack_from(f"<{IMU_FLOATS}d", data, start)


def _stamp(sec, nanosec, log_time):
    stamp = sec * 1_000_000_000 + nanosec
    return stamp if stamp > 0 else log_time


class McapBag:
    """A ROS 2 recording in one MCAP file, read by the mcap package."""
    container = "ROS 2 MCAP"

    def __init__(self, path):
        self.path = Path(path)

    @contextmanager
    def _reading(self, **decoders):
        """The file's mcap reader; what a damaged or truncated file raises said as such."""
        try:
            with open(self.path, "rb") as fh:
                yield make_reader(fh, **decoders)
        except _DAMAGE as exc:
            raise RecordingError(f"{self.path}: damaged or truncated MCAP "
                                 f"({type(exc).__name__}: {exc}); `mimunav info LOG --recover "
                                 "OUT.mcap` keeps what is intact") from None

    def topics(self):
        """{topic: schema name}. A mimunav contract log (mimunav-log/1, whose /gnss/fix holds
        radians) is refused: it needs no import."""
        with self._reading() as reader:
            summary = reader.get_summary()
            if summary is None:
                raise RecordingError(f"{self.path}: no summary section (truncated?); "
                                     "`mimunav info LOG --recover OUT.mcap`")
            flight = [m for m in reader.iter_metadata() if m.name == "flight"]
        if any(m.metadata.get("format") == "mimunav-log/1" for m in flight):
            raise RecordingError(f"{self.path}: already a mimunav contract log (mimunav-log/1): "
                                 "use it as it is (info, windows, diagnose, report recording); "
                                 "the ros2 importer reads recordings in ROS conventions "
                                 "(NavSatFix in deg)")
        return {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}

    def messages(self, topic):
        """(stamp ns, message decoded by mcap-ros2-support) of each message of `topic`."""
        from mcap_ros2.decoder import DecoderFactory
        with self._reading(decoder_factories=[DecoderFactory()]) as reader:
            for _, _, message, ros in reader.iter_decoded_messages(topics=[topic]):
                yield _stamp(ros.header.stamp.sec, ros.header.stamp.nanosec,
                             message.log_time), ros

    def imu_values(self, topic):
        """(stamp ns, 37 float64) of each message of a sensor_msgs/msg/Imu topic."""
        with self._reading() as reader:
            for _, channel, message in reader.iter_messages(topics=[topic]):
                if channel.message_encoding != "cdr":
                    raise ValueError(f"{channel.message_encoding} encoding: not CDR")
                sec, nanosec, values = cdr_imu_values(message.data)
                yield _stamp(sec, nanosec, message.log_time), values


class RosbagsBag:
    """A ROS 1 .bag or a rosbag2 folder, read by rosbags (`pip install 'mimunav[import]'`)."""

    def __init__(self, path, source, container):
        self.path, self.source, self.container = Path(path), Path(source), container
        self._highlevel = require("rosbags.highlevel", "import", f"reading a {container}")
        # what rosbags raises of a bag it cannot read: its readers' and deserializer's errors
        from rosbags import rosbag1, rosbag2, serde       # installed with rosbags.highlevel
        self._errors = (self._highlevel.AnyReaderError, rosbag1.ReaderError, rosbag2.ReaderError,
                        serde.SerdeError, *_DAMAGE)

    @contextmanager
    def _reading(self):
        """The bag's rosbags reader; what it cannot read said as such."""
        try:
            with self._highlevel.AnyReader([self.source]) as reader:
                yield reader
        except self._errors as exc:
            raise RecordingError(f"{self.path}: a {self.container} that cannot be read "
                                 f"({type(exc).__name__}: {exc})") from None

    def topics(self):
        """{topic: message type, ROS 2's name ('sensor_msgs/msg/Imu')}."""
        with self._reading() as reader:
            return {c.topic: c.msgtype for c in reader.connections}

    def messages(self, topic):
        """(stamp ns, message decoded by rosbags) of each message of `topic`."""
        with self._reading() as reader:
            wanted = [c for c in reader.connections if c.topic == topic]
            for connection, log_time, data in reader.messages(connections=wanted):
                ros = reader.deserialize(data, connection.msgtype)
                yield _stamp(ros.header.stamp.sec, ros.header.stamp.nanosec, log_time), ros

    def imu_values(self, topic):
        """(stamp ns, 37 float64) of each message of a sensor_msgs Imu topic."""
        with self._reading() as reader:
            parse = cdr_imu_values if reader.is2 else ros1_imu_values
            wanted = [c for c in reader.connections if c.topic == topic]
            for _, log_time, data in reader.messages(connections=wanted):
                sec, nanosec, values = parse(data)
                yield _stamp(sec, nanosec, log_time), values

"""Which importer reads which recording, and with which options: `read` by kind. An option
given to an importer that does not read it is refused, not silently ignored."""
import numpy as np

from ..errors import InputError, require
from .kinds import KINDS, ROS


# option -> (the importers that read it, its default)
OPTIONS = {
    "imu_instance": (("dataflash", "ulog"), None), "reference": (("dataflash",), "auto"),
    "reference_imu_instance": (("ulog", "dataflash"), None),
    "reference_imu_time_offset": ((*ROS, "table", "ulog", "dataflash"), None),
    "reference_time_offset": (KINDS, 0.0),
    "gps_status": (("dataflash",), 3), "imu_topic": (ROS, None),
    "fix_topic": (ROS, None), "pose_topic": (ROS, None), "origin": (ROS, None),
    "pose_azimuth": (ROS, None), "reference_independent": (ROS, None),
    "reference_status": (ROS, None), "reference_sigma": (ROS, np.inf),
    "reference_imu_topic": (ROS, None), "reference_imu_rpy_deg": (ROS, None),
    "reference_imu_lever_arm_m": ((*ROS, "ulog", "dataflash"), None),
    "lever_arm_m": (KINDS, None), "sampling": (ROS, "interval_mean"),
    "solutions": (("rtklib",), ["fix"]), "root": (("table",), None),
    "vehicle": (KINDS, None)}


def refuse_foreign(kind, options):
    """Refuse the `options` ({name: value}, names as OPTIONS) that differ from their default
    but are not read by the `kind` importer, naming them as the command line does."""
    given = [f"--{name.replace('_', '-')}" for name, (kinds, default) in OPTIONS.items()
             if kind not in kinds and options.get(name, default) != default]
    if given:
        said = [SPEC_SAYS[g] for g in given if kind == "table" and g in SPEC_SAYS]
        raise InputError(f"{', '.join(given)}: not read by the {kind} importer "
                         f"(see `mimunav import --help`: each option names its importers"
                         + "".join(f"; {x}" for x in said) + ")")


SPEC_SAYS = {"--sampling": "a table spec says it as its [imu] sampling = \"instant\"",
             "--reference-imu-lever-arm-m": "a table spec gives it as its [reference_imu] "
                                            "lever_arm_m"}


def read(kind, source, mounting=None, **options):
    """The `importers.recording.Recording` of the recording at `source` (a folder for rtklib,
    a file for ros1/ros2 (or a rosbag2 folder), ulog and dataflash, a TOML spec for table) read by the `kind` importer;
    mounting: the IMU's `Mounting` instead of the importer's default; options: OPTIONS by
    name (the others at their defaults; reference_imu_time_offset, s, is added to the
    reference IMU's stamps, reference_time_offset to the reference trajectory's and the
    fixes')."""
    refuse_foreign(kind, options)
    o = {name: options.get(name, default) for name, (_, default) in OPTIONS.items()}
    rec = READERS[kind](source, mounting, o)
    if o["vehicle"] is not None:
        rec.vehicle = o["vehicle"]
    if o["sampling"] == "instant":
        _interval_means(rec)
    elif kind in ROS:
        rec.assumed["sampling"] = ("the Imu messages' values taken as means over the "
                                   "interval their stamp ends (--sampling instant reads them "
                                   "as instantaneous samples at their stamp)")
    if o["lever_arm_m"] is not None:
        _place_imu(rec, o["lever_arm_m"])
    if o["reference_imu_lever_arm_m"] is not None:
        _place_reference_imu(rec, o["reference_imu_lever_arm_m"])
    if o["reference_imu_time_offset"] is not None:      # given, 0 too: it picks a lobe
        rec.shift_reference_imu(o["reference_imu_time_offset"], "command line")
        rec.reference_imu_offset_given = True
    if o["reference_time_offset"]:
        rec.shift_reference(o["reference_time_offset"], "command line")
    return rec


def _interval_means(rec):
    """Both IMUs' samples, read as instantaneous (`--sampling instant`), made the interval
    means the log contract holds: each the mean of the interval centred on it
    (`motion.intervals.means_of_instants`) and stamped half a median step later, at that
    interval's end - the ROS messages' convention is not stated, and a 100 Hz IMU's read as
    means beside a 200 Hz one's had put 2.5 ms between two exact clocks."""
    from ..motion.intervals import means_of_instants
    said = []
    for name, imu in (("IMU", None), ("reference IMU", rec.reference_imu)):
        if name == "reference IMU" and imu is None:
            continue
        ns = rec.imu_ns if imu is None else imu["ns"]
        t = (ns - ns[0]) / 1e9
        half = int(round(0.5e9 * float(np.median(np.diff(t)))))
        w, f = (means_of_instants(t, x) for x in ((rec.w, rec.f) if imu is None else
                                                   (imu["w"], imu["f"])))
        if imu is None:
            rec.imu_ns, rec.w, rec.f = ns + half, w, f
        else:
            imu.update(ns=ns + half, w=w, f=f)
        said.append(f"the {name}'s stamped {half / 1e6:.4g} ms later")
    rec.sampled_at_instants = True
    rec.assumed["sampling"] = ("instantaneous samples (--sampling instant): each made the mean "
                               "of the interval centred on it, (x[k-1] + 22 x[k] + x[k+1]) / "
                               "24, " + ", ".join(said) + ", at that interval's end")


def _place_imu(rec, lever_arm_m):
    """The IMU put at `lever_arm_m` (vehicle frame FRD, m, from the vehicle origin: the point
    the reference trajectory describes), replacing what the importer or the spec said, and
    said so (a ship's MEMS 1.5 m from the INS whose pose was its reference had no option
    to say so in a ROS bag)."""
    from ..frames.mounting import Mounting
    was = rec.mounting.lever_arm_m
    rec.mounting = Mounting(rec.mounting.attitude_wxyz, lever_arm_m)
    rec.assumed["lever_arm"] = (
        f"{', '.join(f'{x:+.3f}' for x in lever_arm_m)} m (vehicle frame FRD, from the point "
        f"the reference trajectory describes; command line, the importer's "
        f"{', '.join(f'{x:+.3f}' for x in was)} m replaced)")


def _place_reference_imu(rec, lever_arm_m):
    """The reference IMU put at `lever_arm_m` (vehicle frame FRD, m; the IMU where its
    importer put it), replacing what the log said, and said so; refused without one."""
    from ..frames.mounting import Mounting
    if rec.reference_imu is None:
        raise InputError(f"{rec.name}: --reference-imu-lever-arm-m: the recording has no "
                         "reference IMU to place")
    was = rec.reference_imu["mounting"]
    rec.reference_imu["mounting"] = Mounting(was.attitude_wxyz, lever_arm_m)
    rec.assumed["reference_imu_lever_arm"] = (
        f"{', '.join(f'{x:+.3f}' for x in lever_arm_m)} m (vehicle frame FRD, command line; "
        f"the log's {', '.join(f'{x:+.3f}' for x in was.lever_arm_m)} m replaced), the IMU "
        f"at {', '.join(f'{x:+.3f}' for x in rec.mounting.lever_arm_m)} m")


def _rtklib(source, mounting, o):
    from . import rtklib
    names = {v: k for k, v in rtklib.SOLUTION_NAMES.items()}
    return rtklib.read_drive(source, mounting=mounting,
                             solutions=tuple(names[s] for s in o["solutions"]))


def _ros2(source, mounting, o):
    from ..frames.mounting import Mounting
    require("mcap_ros2", "import", "the ros1/ros2 importer")
    from . import ros2
    return ros2.read(source, o["imu_topic"], o["fix_topic"], mounting=mounting,
                     reference_status=o["reference_status"],
                     reference_sigma_m=o["reference_sigma"], pose_topic=o["pose_topic"],
                     origin=o["origin"], pose_azimuth=o["pose_azimuth"],
                     reference_independent=o["reference_independent"],
                     reference_imu_topic=o["reference_imu_topic"],
                     reference_imu_mounting=(Mounting.from_rpy_deg(o["reference_imu_rpy_deg"])
                                             if o["reference_imu_rpy_deg"] else None))


def _table(source, mounting, o):
    from . import table
    return table.read(source, mounting=mounting, root=o["root"])


def _dataflash(source, mounting, o):
    from . import dataflash
    return dataflash.read(source, mounting=mounting, instance=o["imu_instance"] or 0,
                          reference=o["reference"], reference_status=o["gps_status"],
                          reference_instance=o["reference_imu_instance"])


def _ulog(source, mounting, o):
    from . import ulog
    return ulog.read(source, mounting=mounting, instance=o["imu_instance"],
                     reference_instance=o["reference_imu_instance"])


READERS = {"rtklib": _rtklib, "ros2": _ros2, "ros1": _ros2, "ulog": _ulog,
           "dataflash": _dataflash,
           "table": _table}

"""The [reference] section of a table spec (`importers.table`): an external trajectory -
geodetic, ECEF or UTM grid positions (`frames.utm`), or positions in a local level frame placed
at its geodetic origin (`local_frame`) - with its velocity and attitude (a quaternion, roll,
pitch and yaw, or a rotation matrix), as a `Recording`'s reference dict.
"""
import numpy as np
import quaternion

from ..frames import attitude, earth, utm
from ..motion.track import velocity_from_positions
from .columns import check_keys
from .local_frame import AXES, LocalFrame
from .recording import RecordingError, unit_quaternions
from .table_spec import FRAME_KEYS, unix_ns, unrepeated

QUANTITIES = ("position_ecef", "latitude", "longitude", "height", "position_local",
              "position_utm", "velocity_ned", "velocity_ecef", "velocity_local", "ground_speed",
              "course", "attitude_wxyz", "attitude_rpy", "attitude_matrix")
ATTITUDES = ("attitude_wxyz", "attitude_rpy", "attitude_matrix")
ORTHONORMAL = 5e-3      # a rotation matrix's |R R^T - I| at most this: written to 3 digits
#                         it reaches 1.4e-3 (0.05 deg of attitude once made orthonormal: taken;
#                         a KAIST-like drive's had been refused in 8 % of its rows), to 2
#                         digits 1.4e-2 (0.5 deg), a 1 % scale 2e-2 - no attitude
_Q_NED_ENU = quaternion.from_rotation_matrix(np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0],
                                                       [0.0, 0.0, -1.0]]))  # ENU -> NED
GEODETIC = ("latitude", "longitude", "height")


def reference_of(spec, offset):
    """(the [reference] section as a Recording's reference dict, or None; its
    `local_frame.LocalFrame` when its positions are in one, else None)."""
    if not spec.section("reference"):
        return None, None
    keys = ["time"] + _position_keys(spec)
    frame = _local_frame_of(spec) if "position_local" in keys else None
    col = _columns(spec, keys)
    if "attitude_matrix" in col:
        col["attitude_wxyz"] = _matrix_quaternions(spec, col.pop("attitude_matrix"))
    ns = unix_ns(spec, col["time"], offset, "[reference] time")
    back = np.flatnonzero(np.diff(ns) <= 0)
    if len(back):
        step = float(np.median(np.diff(ns))) / 1e9
        deepest = float(-np.diff(ns)[back].min()) / 1e9
        raise RecordingError(f"{spec.path}: [reference] time does not increase at data row "
                             f"{back[0] + 1} (0-based, after the header; {len(back)} such rows)"
                             + (f": its stamps step back by at most {deepest * 1e3:.3g} ms, "
                                f"under half its {step * 1e3:.3g} ms step - a jittered stamp, "
                                "whose rows sorting would reorder: stamp the rows on a uniform "
                                "clock (their index times the step) or drop the late ones"
                                if 0 < deepest < 0.5 * step else
                                ": sort the reference by time or drop its repeated rows"))
    if frame is not None:
        q_lb = _attitude_given(spec, col["attitude_wxyz"], ("body_to_local",)) \
            if "attitude_wxyz" in col else _local_rpy(spec, frame, col.get("attitude_rpy"))
        ref = frame.place(ns, col["position_local"], col.get("velocity_local"), q_lb)
    else:
        ref = _geodetic(spec, ns, col)
    ok = np.isfinite(ref["v_ned"]).all(axis=1)      # differenced velocity: none across a gap
    return {k: x[ok] for k, x in ref.items()}, frame


def _position_keys(spec):
    """The [reference] quantities given, checked: one kind of position (geodetic, ECEF or in a
    local frame), velocity and attitude in that kind's frames."""
    keys = [k for k in QUANTITIES if spec.has("reference", k)]
    where = f"{spec.path}: [reference]"
    attitudes = [k for k in ATTITUDES if k in keys]
    if len(attitudes) > 1:
        raise RecordingError(f"{where} gives {' and '.join(attitudes)}: one of them")
    over_ground = [k for k in ("ground_speed", "course") if k in keys]
    if len(over_ground) == 1:
        raise RecordingError(f"{where} gives {over_ground[0]} alone: ground_speed and course "
                             "together make the horizontal velocity")
    velocities = [k for k in ("velocity_ned", "velocity_ecef", "velocity_local",
                              "ground_speed") if k in keys]
    if len(velocities) > 1:
        raise RecordingError(f"{where} gives {' and '.join(velocities)}: one velocity")
    if "position_local" in keys:
        other = [k for k in keys if k in ("position_ecef", "velocity_ned", "velocity_ecef",
                                          "ground_speed", "course") + GEODETIC]
        if other:
            raise RecordingError(f"{where} gives position_local and {', '.join(other)}: in a "
                                 "local frame, velocity_local and attitude_wxyz (rotates = "
                                 "\"body_to_local\") or attitude_rpy are its velocity and "
                                 "attitude")
        return keys
    if "velocity_local" in keys:
        raise RecordingError(f"{where} gives velocity_local without position_local")
    if "position_utm" in keys:
        other = [k for k in keys if k in ("position_ecef",) + GEODETIC]
        if other:
            raise RecordingError(f"{where} gives position_utm and {', '.join(other)}: one "
                                 "kind of position (position_utm's third column is the "
                                 "ellipsoidal height)")
        return keys
    if "position_ecef" in keys:
        return [k for k in keys if k not in GEODETIC]
    missing = [k for k in GEODETIC if k not in keys]
    if missing:
        alone = len(missing) == len(GEODETIC) and any(k.startswith("attitude") for k in keys)
        raise RecordingError(f"{where} has no {', '.join(missing)} (give latitude, longitude "
                             "and height, position_ecef, or position_local with local_frame)"
                             + ("; a reference of attitude alone is not read - leave "
                                "[reference] out to import the IMU alone" if alone else ""))
    return keys


def _local_rpy(spec, frame, rpy):
    """The body -> frame quaternions of roll, pitch, yaw (rad, (M, 3); None: not given) in a
    local frame whose z is down, the aerospace z-y-x turns as to NED (NCLT's ground truth);
    a z-up frame's angles have no such convention and are refused."""
    if rpy is None:
        return None
    if not frame.z_down:
        raise RecordingError(f"{spec.path}: [reference] attitude_rpy in a local frame needs "
                             "its z down (axes \"ned\" or \"z_down\"): roll, pitch, yaw of "
                             "the body to it, z-y-x; a z-up frame's attitude is attitude_wxyz "
                             "with rotates = \"body_to_local\"")
    return attitude.from_euler(rpy[:, 2], rpy[:, 1], rpy[:, 0])


def _local_frame_of(spec):
    """The [reference] local_frame {axes, origin, azimuth_deg} as a `local_frame.LocalFrame`."""
    given = spec.section("reference").get("local_frame")
    if not isinstance(given, dict):
        raise RecordingError(f"{spec.path}: [reference] position_local needs local_frame = "
                             "{axes = \"z_up\", origin = [lat_deg, lon_deg, h_m], azimuth_deg = "
                             "... or \"unknown\"} (axes: " + ", ".join(AXES) + ")")
    check_keys(spec.path, given, FRAME_KEYS, "[reference] local_frame")
    axes, azimuth = given.get("axes"), given.get("azimuth_deg")
    if axes in ("enu", "ned") and azimuth is not None:
        raise RecordingError(f"{spec.path}: [reference] local_frame axes {axes!r} name their "
                             "azimuth: azimuth_deg belongs to axes z_up or z_down")
    if axes in ("z_up", "z_down") and not (azimuth == "unknown" or (
            isinstance(azimuth, (int, float)) and not isinstance(azimuth, bool)
            and np.isfinite(azimuth))):
        raise RecordingError(f"{spec.path}: [reference] local_frame axes {axes!r} need "
                             "azimuth_deg: the azimuth of the frame's x axis from true north, "
                             "clockwise, deg, or \"unknown\" (then no finding stands on the "
                             f"reference's heading); got {azimuth!r}")
    return LocalFrame.from_axes(axes, given.get("origin"),
                                None if azimuth == "unknown" else azimuth,
                                "[reference] local_frame origin = [lat_deg, lon_deg, h_m]")


def _columns(spec, keys):
    """The [reference] columns of `keys` (SI) on the reference's time, rows not finite or
    repeated left out; quantities on their own clocks interpolated onto it."""
    own = [k for k in keys[1:] if isinstance(spec.section("reference")[k], dict)
           and "time" in spec.section("reference")[k]]      # quantities on their own clock
    keys = [k for k in keys if k not in own]
    columns = [spec.time_of("reference", "time")] + [spec.column("reference", k)
                                                     for k in keys[1:]]
    n = len(columns[0])
    for key, x in zip(keys, columns):
        if len(x) != n:
            raise RecordingError(f"{spec.path}: [reference] {key} has {len(x)} rows, time {n}")
    col = dict(zip(keys, unrepeated(spec, "[reference]",
                                    *spec.finite_rows("[reference]", *columns),
                                    names=keys[1:])))
    for key in own:
        col[key] = _onto(spec, key, col["time"])
    if own:                             # epochs beyond what the own clocks cover: left out
        inside = np.isfinite(np.column_stack([col[k] for k in own])).all(axis=1)
        if inside.sum() < 2:
            raise RecordingError(f"{spec.path}: [reference] {', '.join(own)} on their own "
                                 "clocks do not cover the reference's times")
        col = {k: x[inside] for k, x in col.items()}
    return col


def _geodetic(spec, ns, col):
    """The reference dict of geodetic or ECEF positions, NED or ECEF velocities (else central
    differences) and an attitude to NED or ECEF (or roll, pitch, yaw)."""
    convergence = None
    if "position_ecef" in col:
        lat, lon, h = earth.ecef_to_geodetic(col["position_ecef"])
    elif "position_utm" in col:
        lat, lon, h, convergence = _from_utm(spec, col["position_utm"])
    else:
        lat, lon, h = col["latitude"], col["longitude"], col["height"]
    if "velocity_ned" in col:
        v = col["velocity_ned"]
    elif "velocity_ecef" in col:
        v = np.einsum("kji,kj->ki", earth.ned_to_ecef_matrix(lat, lon), col["velocity_ecef"])
    else:
        v = velocity_from_positions(ns, lat, lon, h)
    if "ground_speed" in col:           # over ground: north and east; down as differenced
        speed, course = col["ground_speed"], col["course"]
        given = (speed >= 0) & (course >= 0) & np.isfinite(speed) & np.isfinite(course)
        v = np.column_stack([np.where(given, speed * np.cos(course), v[:, 0]),
                             np.where(given, speed * np.sin(course), v[:, 1]), v[:, 2]])
        # a speed without its course (Android leaves the bearing empty at a stand): the
        # positions' differences no longer than it - a phone's 3 m fixes had made a walker
        # standing at 0.01-0.07 m/s move at 0.3-0.8 m/s, and no rest was found
        sized = ~given & (speed >= 0) & np.isfinite(speed)
        across = np.hypot(v[:, 0], v[:, 1])
        scale = np.minimum(1.0, speed / np.where(across > 0, across, np.inf))
        v[sized, :2] *= scale[sized, None]
    ref = dict(ns=ns, lat=lat, lon=lon, h=h, v_ned=v)
    if "attitude_wxyz" in col:
        ref["q_nb"] = _attitude_ned(spec, col["attitude_wxyz"], lat, lon, convergence)
    if "attitude_rpy" in col:           # roll, pitch, yaw of body -> NED (z-y-x turns)
        rpy = col["attitude_rpy"]
        ref["q_nb"] = attitude.as_wxyz(attitude.from_euler(rpy[:, 2], rpy[:, 1], rpy[:, 0]))
    return ref


def _onto(spec, key, t):
    """[reference] quantity `key` on its own clock, interpolated linearly onto the times t
    (s) - a box's pressure altitude beside a receiver's packets; NaN where it does not cover
    them."""
    t_k, x = unrepeated(spec, f"[reference] {key}", *spec.finite_rows(
        f"[reference] {key}", spec.time_of("reference", key), spec.column("reference", key)))
    if len(t_k) < 2 or np.any(np.diff(t_k) <= 0):
        raise RecordingError(f"{spec.path}: [reference] {key}'s own times must increase")
    outside = (t < t_k[0]) | (t > t_k[-1])
    spec.notes[f"reference_{key}_time"] = (
        f"{key} interpolated linearly onto the reference's times"
        + (f"; {int(outside.sum())} epochs beyond its span left out" if outside.any() else ""))
    x2 = np.reshape(x, (len(x), -1))
    out = np.column_stack([np.interp(t, t_k, x2[:, i]) for i in range(x2.shape[1])])
    out[outside] = np.nan
    return out[:, 0] if x.ndim == 1 else out


def _attitude_ned(spec, wxyz, lat, lon, convergence=None):
    """The reference attitude `wxyz` (its spec's `rotates`) as q_nb (body -> NED, wxyz); beside
    UTM positions, `convergence` (rad, `utm.to_geodetic`) turns an attitude in the grid's
    axes (east, north, up of the grid: "body_to_utm", their default) into true ones."""
    rotations = ("body_to_ned", "body_to_ecef")
    if convergence is not None:
        rotations = ("body_to_utm",) + rotations
    q = _attitude_given(spec, wxyz, rotations)
    if _rotates(spec, rotations[0]) == "body_to_ecef":
        q_en = quaternion.from_rotation_matrix(earth.ned_to_ecef_matrix(lat, lon))
        q = np.conjugate(q_en) * q
    elif _rotates(spec, rotations[0]) == "body_to_utm":
        # grid north lies the convergence clockwise of true north: the grid's NED turns into
        # the true one by the convergence about down
        zero = np.zeros_like(convergence)
        q = attitude.from_euler(np.asarray(convergence, float), zero, zero) * _Q_NED_ENU * q
    return attitude.as_wxyz(q)


def _from_utm(spec, enh):
    """(lat rad, lon rad, h m, convergence rad) of [reference] position_utm's easting,
    northing (m, in its source's zone and hemisphere) and ellipsoidal height (m)."""
    source = spec.section("reference")["position_utm"]
    zone = source.get("zone") if isinstance(source, dict) else None
    hemisphere = source.get("hemisphere") if isinstance(source, dict) else None
    if not (isinstance(zone, int) and not isinstance(zone, bool) and 1 <= zone <= 60) or \
            hemisphere not in ("N", "S"):
        raise RecordingError(f"{spec.path}: [reference] position_utm needs its grid: "
                             "{file = ..., columns = [easting, northing, height], zone = 1-60, "
                             f"hemisphere = \"N\" or \"S\"}} (got zone {zone!r}, hemisphere "
                             f"{hemisphere!r})")
    lat, lon, convergence = utm.to_geodetic(enh[:, 0], enh[:, 1], zone, hemisphere == "N")
    spec.notes["reference_utm"] = (
        f"UTM zone {zone}{hemisphere} (WGS-84) to latitude and longitude; the grid's "
        f"convergence {np.degrees(np.median(convergence)):+.3f} deg (median: grid north "
        "clockwise of true north)")
    return lat, lon, enh[:, 2], convergence


def _matrix_quaternions(spec, rows):
    """[reference] attitude_matrix's rows (M, 9: R11 R12 R13 R21 ... R33, the first row
    first) as w, x, y, z rows, made orthonormal; a matrix further than ORTHONORMAL from a
    rotation refused, naming the worst row (a scaled or sheared one; a transposed layout,
    still orthonormal, is caught by the import's attitude checks against the IMU)."""
    r = np.asarray(rows, float).reshape(-1, 3, 3)
    off = np.abs(np.einsum("kij,klj->kil", r, r) - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(r)
    bad = (off > ORTHONORMAL) | (det < 0)
    if bad.any():
        k = int(np.argmax(bad))
        raise RecordingError(f"{spec.path}: [reference] attitude_matrix row {k} is no "
                             f"rotation (|R R^T - I| {off[k]:.2g}, det {det[k]:.3g}): nine "
                             "columns R11 R12 R13 R21 ... R33 of a proper rotation, the first "
                             f"row first, written to 3 digits or more (|R R^T - I| up to "
                             f"{ORTHONORMAL:g})")
    return attitude.as_wxyz(quaternion.from_rotation_matrix(r, nonorthogonal=True))


def _attitude_given(spec, wxyz, rotations):
    """The [reference] attitude_wxyz rows as unit quaternions (`recording.unit_quaternions`),
    its `rotates` one of `rotations` (the first the default)."""
    rotates = _rotates(spec, rotations[0])
    if rotates not in rotations:
        raise RecordingError(f"{spec.path}: [reference] attitude rotates {rotates!r}: "
                             f"{' or '.join(rotations)} for these positions")
    return unit_quaternions(wxyz, f"{spec.path}: [reference] attitude_wxyz")


def _rotates(spec, default="body_to_ned"):
    """The `rotates` of the [reference] attitude given as a quaternion or a matrix."""
    section = spec.section("reference")
    source = section.get("attitude_wxyz", section.get("attitude_matrix"))
    return source.get("rotates", default) if isinstance(source, dict) else default

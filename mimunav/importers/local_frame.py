"""A reference given in a local level frame - a motion-capture room's, a ROS map frame (REP-105:
no geodetic origin of its own) - placed on the Earth: positions, velocities and attitudes in
the frame's axes turned into geodetic position, NED velocity and q_nb.

A local frame is level (its z along the plumb line at its origin, up or down) with x at an
azimuth from true north; `enu` and `ned` are the two with named axes. Its origin (latitude,
longitude, ellipsoidal height) fixes gravity and the Earth rate's direction, which a strapdown
navigator needs (latitude moves g by up to 0.05 m/s^2, more than a MEMS part's bias). An azimuth
not known (a room's x axis drawn anywhere) leaves the horizontal Earth rate's direction unknown -
up to Omega cos(lat) = 7.3e-5 rad/s misplaced, which tilts a free-inertial solution by g times
that rate: metres per second in 100 s - so the reference's heading measures nothing then.
"""
import math
from dataclasses import dataclass

import numpy as np
import quaternion

from ..frames import attitude, earth
from ..motion.track import velocity_from_positions
from .recording import RecordingError

AXES = ("enu", "ned", "z_up", "z_down")
FAR_M = 100e3   # positions further from the origin are no local frame's: its tangent plane
# lies d^2 / 2R above the Earth there (785 m at 100 km; a UTM easting and northing given as
# local, 4100 km off, had been refused as a wrong axis or quaternion convention)
# the frame's own axes -> NED at its origin, before the azimuth turn: x north, y west, z up
# (z_up: turned half a turn about x) or NED itself (z_down)
_Q_LEVEL = {"z_up": quaternion.quaternion(0.0, 1.0, 0.0, 0.0),
            "z_down": quaternion.quaternion(1.0, 0.0, 0.0, 0.0)}
_NAMED = {"enu": ("z_up", 90.0), "ned": ("z_down", 0.0)}    # x east, z up; x north, z down


@dataclass(frozen=True)
class LocalFrame:
    """A level frame at a geodetic origin: lat_deg, lon_deg (deg), h_m (m, ellipsoidal); q_n0l
    turns the frame's axes into NED at the origin (a quaternion); azimuth_known: whether x's
    azimuth was given (else taken as 0 and the reference's heading is no measurement)."""
    lat_deg: float
    lon_deg: float
    h_m: float
    q_n0l: np.quaternion
    azimuth_known: bool
    description: str

    @property
    def z_down(self):
        """Whether the frame's z axis points down (ned, z_down)."""
        return bool(attitude.rotate(self.q_n0l, np.array([[0.0, 0.0, 1.0]]))[0, 2] > 0)

    @classmethod
    def from_axes(cls, axes, origin, azimuth_deg=None, how_given="--origin LAT_DEG LON_DEG H_M",
                  taken=(0.0, "")):
        """The frame `axes` (one of AXES) at `origin` (lat deg, lon deg, h m); azimuth_deg:
        x's azimuth from true north, clockwise, deg - required (a number or None: not known)
        for z_up / z_down, none for enu / ned; how_given: how a user gives the origin, for
        the message that refuses a missing one; taken: (the azimuth taken when not known, deg;
        why, and how to give it, for the description)."""
        if origin is None or len(origin) != 3 or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in origin) \
                or not np.isfinite(origin).all() or abs(origin[0]) > 90:
            raise RecordingError(f"a local-frame reference needs the geodetic origin of its "
                                 f"frame ({how_given}: latitude and longitude in deg, "
                                 f"ellipsoidal height in m), got {origin}")
        if axes not in AXES:
            raise RecordingError(f"local frame axes {axes!r}: one of {', '.join(AXES)}")
        if axes in _NAMED:
            level, azimuth = _NAMED[axes]
            known = True
        else:
            known = azimuth_deg is not None
            level, azimuth = axes, azimuth_deg if known else taken[0]
        half = math.radians(azimuth) / 2
        q_n0l = quaternion.quaternion(math.cos(half), 0.0, 0.0, math.sin(half)) * _Q_LEVEL[level]
        said = (f"{axes} axes" if axes in _NAMED else
                f"level, z {axes[2:]}, x at azimuth {azimuth:g} deg" if known else
                f"level, z {axes[2:]}, x at an azimuth not known ({taken[0]:g} taken"
                + (f": {taken[1]})" if taken[1] else ")"))
        return cls(float(origin[0]), float(origin[1]), float(origin[2]), q_n0l, known,
                   f"local frame ({said}) at origin {origin[0]:.8f} deg, {origin[1]:.8f} deg, "
                   f"{origin[2]:.3f} m (given)")

    def place(self, ns, p_l, v_l=None, q_lb=None):
        """The reference dict (`Recording.reference`: ns, lat, lon rad, h m, v_ned m/s,
        q_nb wxyz when q_lb is given) of positions p_l (m, (M, 3)) in the frame's axes at UNIX
        times ns, velocities v_l (m/s, frame axes; None: central differences of the positions)
        and attitudes q_lb (quaternion array, body -> frame axes)."""
        lat0, lon0 = math.radians(self.lat_deg), math.radians(self.lon_deg)
        ned = attitude.rotate(self.q_n0l, np.asarray(p_l, float))
        far = float(np.median(np.hypot(ned[:, 0], ned[:, 1])))
        if far > FAR_M:
            raise RecordingError(
                f"the positions lie {far / 1e3:.0f} km from the local frame's origin (the "
                "median): a local frame is its origin's tangent plane - give positions from "
                "the origin (a UTM easting and northing less the origin's), or latitude and "
                "longitude")
        lat, lon, h = earth.ned_offset_to_geodetic(ned, lat0, lon0, self.h_m)
        # the frame is the origin's tangent plane; each epoch's NED is turned from it by the
        # arc travelled (0.22 deg at 25 km): C_nk_n0 = C_en(k)^T C_en(origin)
        q_nk_n0 = quaternion.from_rotation_matrix(np.einsum(
            "kji,jl->kil", earth.ned_to_ecef_matrix(lat, lon),
            earth.ned_to_ecef_matrix(lat0, lon0)))
        q_nk_l = q_nk_n0 * self.q_n0l
        v_ned = velocity_from_positions(ns, lat, lon, h) if v_l is None else \
            attitude.rotate(q_nk_l, np.asarray(v_l, float))
        ref = dict(ns=np.asarray(ns, np.int64), lat=lat, lon=lon, h=h, v_ned=v_ned)
        if q_lb is not None:
            ref["q_nb"] = attitude.as_wxyz(q_nk_l * q_lb)
        return ref

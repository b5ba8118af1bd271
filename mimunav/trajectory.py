"""A navigation trajectory: time, geodetic position, NED velocity and attitude q_nb.

The one container for everything that has a position: the truth of a simulated flight,
a navigator's solution, an external reference.
"""
from dataclasses import dataclass

import numpy as np
import quaternion

from . import attitude, earth
from .errors import InputError


@dataclass
class Trajectory:
    """Samples of a vehicle state.

    t: s (since the flight's epoch), shape (N,); lat, lon: rad; h: m above the WGS-84
    ellipsoid; v_ned: m/s, shape (N, 3); q_nb: numpy-quaternion array (N,), body FRD -> NED.
    """
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v_ned: np.ndarray
    q_nb: np.ndarray

    def __len__(self):
        return len(self.t)

    def __getitem__(self, index):
        """The samples at `index` (a slice, an index array or a mask) as a Trajectory."""
        return Trajectory(self.t[index], self.lat[index], self.lon[index], self.h[index],
                          self.v_ned[index], self.q_nb[index])

    @classmethod
    def concatenate(cls, parts):
        """One Trajectory of consecutive pieces (in time order)."""
        parts = list(parts)
        return cls(*(np.concatenate([getattr(p, name) for p in parts])
                     for name in ("t", "lat", "lon", "h", "v_ned", "q_nb")))

    def state(self, k=0):
        """The state at sample k as plain floats: dict(t, lat, lon, h, v_ned, q_nb)."""
        return dict(t=float(self.t[k]), lat=float(self.lat[k]), lon=float(self.lon[k]),
                    h=float(self.h[k]), v_ned=np.array(self.v_ned[k], dtype=float),
                    q_nb=quaternion.as_float_array(self.q_nb[k]).copy())

    def position_error(self, ref):
        """Position of this trajectory minus the reference's, in the reference's NED, m (N, 3).
        Both trajectories must be sampled at the same times."""
        _check_same_times(self, ref)
        return earth.ned_difference(self.lat, self.lon, self.h, ref.lat, ref.lon, ref.h)

    def velocity_error(self, ref):
        """NED velocity minus the reference's, m/s (N, 3)."""
        _check_same_times(self, ref)
        return self.v_ned - ref.v_ned

    def attitude_error(self, ref):
        """Attitude error as a rotation vector in NED, rad (N, 3): q_nb = exp(phi) q_nb_ref."""
        _check_same_times(self, ref)
        return attitude.rotation_vector_error(self.q_nb, ref.q_nb)


def _check_same_times(a, b):
    if len(a) != len(b) or not np.allclose(a.t, b.t, rtol=0, atol=1e-9):
        raise InputError("the two trajectories are not sampled at the same times "
                         f"({len(a)} vs {len(b)} samples)")

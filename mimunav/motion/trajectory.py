"""A navigation trajectory: time, geodetic position, NED velocity and attitude q_nb.

The one container for everything that has a position: the truth of a simulated flight,
a navigator's solution, an external reference; and `State`, one instant of it (a
navigation's initial state).
"""
from dataclasses import dataclass

from collections.abc import Iterable
import numpy as np

from ..frames import attitude, earth
from ..errors import InputError


@dataclass
class State:
    """A vehicle state at one instant: t s (since the flight's epoch); lat, lon rad; h m
    above the WGS-84 ellipsoid; v_ned m/s (3,); q_nb a numpy quaternion, body FRD -> NED."""
    t: float
    lat: float
    lon: float
    h: float
    v_ned: np.ndarray
    q_nb: object

    @classmethod
    def from_contract(cls, doc: dict) -> "State":
        """The `initial_state` object of a log's `flight` metadata (log contract section 1:
        t, latitude, longitude, height, velocity_ned, attitude_wxyz)."""
        return cls(float(doc["t"]), doc["latitude"], doc["longitude"], doc["height"],
                   np.asarray(doc["velocity_ned"], float),
                   attitude.from_wxyz(np.asarray(doc["attitude_wxyz"], float)))

    def as_contract(self) -> dict:
        """The `initial_state` object of the log contract (plain numbers)."""
        return {"t": self.t, "latitude": self.lat, "longitude": self.lon, "height": self.h,
                "velocity_ned": np.asarray(self.v_ned, float).tolist(),
                "attitude_wxyz": attitude.as_wxyz(self.q_nb).tolist()}


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
    def concatenate(cls, parts: Iterable["Trajectory"]) -> "Trajectory":
        """One Trajectory of consecutive pieces (in time order)."""
        parts = list(parts)
        return cls(*(np.concatenate([getattr(p, name) for p in parts])
                     for name in ("t", "lat", "lon", "h", "v_ned", "q_nb")))

    def state(self, k: int = 0) -> State:
        """The `State` at sample k."""
        return State(float(self.t[k]), float(self.lat[k]), float(self.lon[k]), float(self.h[k]),
                     np.array(self.v_ned[k], dtype=float),
                     attitude.from_wxyz(attitude.as_wxyz(self.q_nb[k]).copy()))

    def position_error(self, ref: "Trajectory") -> np.ndarray:
        """Position of this trajectory minus the reference's, in the reference's NED, m (N, 3).
        Both trajectories must be sampled at the same times."""
        _check_same_times(self, ref)
        return earth.ned_difference(self.lat, self.lon, self.h, ref.lat, ref.lon, ref.h)

    def velocity_error(self, ref: "Trajectory") -> np.ndarray:
        """NED velocity minus the reference's, m/s (N, 3)."""
        _check_same_times(self, ref)
        return self.v_ned - ref.v_ned

    def attitude_error(self, ref: "Trajectory") -> np.ndarray:
        """Attitude error as a rotation vector in NED, rad (N, 3): q_nb = exp(phi) q_nb_ref."""
        _check_same_times(self, ref)
        return attitude.rotation_vector_error(self.q_nb, ref.q_nb)


def _check_same_times(a, b):
    if len(a) != len(b) or not np.allclose(a.t, b.t, rtol=0, atol=1e-9):
        raise InputError("the two trajectories are not sampled at the same times "
                         f"({len(a)} vs {len(b)} samples)")

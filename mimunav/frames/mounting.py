"""A sensor's mounting in the vehicle: attitude q_vs (sensor -> vehicle) and lever arm
(sensor origin in the vehicle frame, m), as in the log contract's `mounting` metadata."""
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
import quaternion

from . import attitude
from ..errors import InputError


@dataclass
class Mounting:
    attitude_wxyz: np.ndarray = field(default_factory=lambda: np.array([1.0, 0, 0, 0]))
    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        q = np.asarray(self.attitude_wxyz, dtype=float).reshape(4)
        if abs(np.linalg.norm(q) - 1) > 1e-9:
            raise InputError(f"mounting attitude {q} is not a unit quaternion")
        self.attitude_wxyz = q
        self.lever_arm_m = np.asarray(self.lever_arm_m, dtype=float).reshape(3)

    @property
    def q_vs(self) -> np.ndarray:
        return attitude.from_wxyz(self.attitude_wxyz)

    @classmethod
    def from_rpy_deg(cls, rpy_deg: ArrayLike, lever_arm_m: ArrayLike = (0.0, 0.0, 0.0)) -> "Mounting":
        """Mounting with q_vs from roll, pitch, yaw (deg, z-y-x as `attitude.from_euler`)."""
        roll, pitch, yaw = np.radians(np.asarray(rpy_deg, dtype=float).reshape(3))
        q = attitude.from_euler(np.array(yaw), np.array(pitch), np.array(roll))
        return cls(attitude.as_wxyz(q), lever_arm_m)

    @classmethod
    def from_axes(cls, axes: str, lever_arm_m: ArrayLike = (0.0, 0.0, 0.0)) -> "Mounting":
        """Mounting from the vehicle direction of each sensor axis x, y, z, as three letters
        of F/B (forward, backward), R/L (right, left), D/U (down, up): "FRD" is the vehicle
        frame itself, "FLU" ROS's body frame (REP-103), "RFU" an ENU-like phone frame. The
        axes must form a right-handed frame."""
        unit = {"F": (0, 1.0), "B": (0, -1.0), "R": (1, 1.0), "L": (1, -1.0), "D": (2, 1.0),
                "U": (2, -1.0)}
        letters = str(axes).upper()
        if len(letters) != 3 or any(c not in unit for c in letters):
            raise InputError(f"axes {axes!r}: three letters of F/B, R/L, D/U (e.g. FRD, FLU)")
        c_vs = np.zeros((3, 3))
        for k, c in enumerate(letters):
            row, sign = unit[c]
            c_vs[row, k] = sign
        if abs(np.linalg.det(c_vs) - 1) > 1e-9:
            raise InputError(f"axes {axes!r} are not a right-handed frame (repeated or mirrored "
                             "directions)")
        q = attitude.as_wxyz(quaternion.from_rotation_matrix(c_vs))
        lead = q[np.flatnonzero(np.abs(q) > 1e-12)[0]]
        return cls(np.sign(lead) * q + 0.0, lever_arm_m)    # one sign of q, no -0.0

    @classmethod
    def from_dict(cls, doc: dict) -> "Mounting":
        return cls(doc.get("attitude_wxyz", [1, 0, 0, 0]), doc.get("lever_arm_m", [0, 0, 0]))

    def as_dict(self) -> dict:
        return {"attitude_wxyz": self.attitude_wxyz.tolist(),
                "lever_arm_m": self.lever_arm_m.tolist()}

    def sensor_increments(self, run) -> tuple[np.ndarray, np.ndarray]:
        """Ideal (dtheta, dv) of a sensor with this mounting on a `truth.TruthRun`, in
        sensor axes: the vehicle's increments at the lever arm (w x (w x r) + dw/dt x r
        included exactly), rotated by C_sv."""
        q_sv = np.conjugate(self.q_vs)
        dv = run.dv_at(self.lever_arm_m) if np.any(self.lever_arm_m) else run.dv
        return attitude.rotate(q_sv, run.dtheta), attitude.rotate(q_sv, dv)


AGAINST = -0.5          # a correlation below this is a sign between two series, not noise
MIN_MEANS = 30          # means at least: 30 independent noises correlate below AGAINST by
#                         chance at p ~ 0.2 %, and their differences must do so too


def runs_against(mine, theirs):
    """Whether one axis' means of two IMUs (N,: 1 s means in one frame, a mounting applied
    to each) run against each other - a mirrored axis, a column's sign that no mounting
    turns: their correlation and that of their first differences both below AGAINST, the
    most influential 1 % of the seconds left out (a slow bias drift moves the means, not
    their differences). Judged where the axis moves too little for a correlation to be
    read otherwise: a FOG's gyro y column signed wrong on an
    AUV, its pitch rate's means spread 0.009 rad/s, correlated -0.9999, had passed."""
    mine, theirs = np.asarray(mine, float), np.asarray(theirs, float)
    if len(mine) < MIN_MEANS or min(np.std(np.diff(mine)), np.std(np.diff(theirs))) == 0:
        return False
    return bool(_sturdy_correlation(mine, theirs) < AGAINST and
                _sturdy_correlation(np.diff(mine), np.diff(theirs)) < AGAINST)


def _sturdy_correlation(a, b):
    """The correlation of two series with their most influential 1 % of points (at least
    one: the largest |products| about their means) left out - one opposite spike in quiet
    noise had made a plain correlation run against (an independent review), while a sign
    holds over every second that moves."""
    a, b = a - a.mean(), b - b.mean()
    keep = np.argsort(np.abs(a * b))[:len(a) - max(1, len(a) // 100)]
    a, b = a[keep], b[keep]
    return float(np.sum(a * b) / np.sqrt(np.sum(a * a) * np.sum(b * b)))

"""A sensor's mounting in the vehicle: attitude q_vs (sensor -> vehicle) and lever arm
(sensor origin in the vehicle frame, m), as in the log contract's `mounting` metadata."""
from dataclasses import dataclass, field

import numpy as np
import quaternion

from .. import attitude
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
    def q_vs(self):
        return quaternion.from_float_array(self.attitude_wxyz)

    @classmethod
    def from_dict(cls, doc):
        return cls(doc.get("attitude_wxyz", [1, 0, 0, 0]), doc.get("lever_arm_m", [0, 0, 0]))

    def as_dict(self):
        return {"attitude_wxyz": self.attitude_wxyz.tolist(),
                "lever_arm_m": self.lever_arm_m.tolist()}

    def sensor_increments(self, run):
        """Ideal (dtheta, dv) of a sensor with this mounting on a `truth.TruthRun`, in
        sensor axes: the vehicle's increments at the lever arm (w x (w x r) + dw/dt x r
        included exactly), rotated by C_sv."""
        q_sv = np.conjugate(self.q_vs)
        dv = run.dv_at(self.lever_arm_m) if np.any(self.lever_arm_m) else run.dv
        return attitude.rotate(q_sv, run.dtheta), attitude.rotate(q_sv, dv)

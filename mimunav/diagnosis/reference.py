"""What the MIMU should have output: the reference IMU's motion moved to the MIMU's mounting.

Both IMUs sit on one rigid vehicle, so they feel the same inertial angular rate, and their
specific forces differ by the rigid-body terms of their separation (vehicle axes):
    w_v   = C_vf w_fog
    f_v   = C_vf f_fog + w x (w x dr) + dw/dt x dr,     dr = r_mimu - r_fog
and the MIMU reads them in its own axes, w_s = C_sv w_v, f_s = C_sv f_v.
Samples are interval means (log contract): the reference's running integral
(`intervals.RunningIntegral`) at the MIMU's interval ends, differenced - exact when the
stamps coincide, the interval-mean meaning kept when they do not.
"""
from dataclasses import dataclass

import numpy as np
import quaternion

from ..frames import attitude
from ..compensation.effects import derivative
from ..errors import InputError
from ..motion.intervals import RunningIntegral, intervals

DERIVATIVE_WINDOW_S = 0.1       # d/dt of reference rates: quartic Savitzky-Golay over 100 ms,
# exact for motion up to 4th order in time (close to it inside the profiles' ramps), and
# long enough that the reference's output quantization (FOG: 5 urad per pulse) does not turn
# into angular-acceleration noise. That noise is shared by the lever-arm transfer (x dr) and
# the size-effect regressor (x r) - errors in variables: over 20 ms it faked centimetre
# proof-mass offsets on null recordings, over 50 ms it still raised 2 false size effects in
# 40 nulls (reports/diagnosis-proof.md, seed 200 run); over 100 ms none in the cases tried.


TRANSFER_WINDOW_S = 0.03        # d/dt of the reference rate in the lever-arm transfer
# dw/dt x dr: short, because where the angular acceleration changes (the start and end of a
# roll) a 100 ms window is off by up to 2.4 mg at 0.33 m - a systematic error a proof-mass
# offset (size_effect) fits at z 3-5 on null recordings; over 30 ms the transfer error of
# an ideal reference is 0.2 mg at most and its noise (the reference's quantization through a
# short derivative) is far below the MIMU's. The regressors keep DERIVATIVE_WINDOW_S, so the
# two do not share that noise (errors in variables).


def predicted_mimu(flight):
    """(f m/s^2, w rad/s) the MIMU should have read at its stamps, MIMU sensor axes, from the
    flight's reference IMU (`/fog/imu`) and both mountings."""
    t = flight.mimu_t
    inside = (t > flight.fog_t[0]) & (t <= flight.fog_t[-1])
    if inside.sum() < 2:
        raise InputError(f"{flight.path}: the reference IMU does not cover the MIMU's samples")
    w_v = attitude.rotate(flight.fog_mounting.q_vs, flight.fog_w)
    f_v = attitude.rotate(flight.fog_mounting.q_vs, flight.fog_f)
    reference = RunningIntegral(intervals(flight.fog_t)[2], np.hstack([w_v, f_v]))
    w_v, f_v = reference.means(t).reshape(len(t), 2, 3).transpose(1, 0, 2)
    dr = flight.mimu_mounting.lever_arm_m - flight.fog_mounting.lever_arm_m
    if np.any(dr):
        w_dot = derivative(t, w_v, TRANSFER_WINDOW_S)
        f_v = f_v + np.cross(w_v, np.cross(w_v, dr)) + np.cross(w_dot, dr)
    q_sv = np.conjugate(flight.mimu_mounting.q_vs)
    return attitude.rotate(q_sv, f_v), attitude.rotate(q_sv, w_v), inside


# ---- the reference's own accuracy ------------------------------------------------------
@dataclass(frozen=True)
class Accuracy:
    """1-sigma residual errors of a calibrated reference IMU (sensor axes): scale-factor error
    (per axis, 1) and axis misalignment (per off-diagonal element, rad) of each triad. From
    the `accuracy` object of the log's `sensor/fog` metadata when present (contract
    extension, same keys), else `mimunav diagnose --reference-accuracy`, else these defaults:
      scale 2.5e-4  seed S1 Table 4: FOG-IMU scale-factor residual <= 0.05 % FS, read as 2 sigma
      misalignment 1e-4 rad  (20 arcsec) - Table 4 gives none: an assumption, medium-accuracy
                    FOG-IMU class.
    Bias and noise of the reference need no entry: the bias is part of the wander the
    diagnosis fits, the noise part of the residual's white noise."""
    gyro_scale: float = 2.5e-4
    accel_scale: float = 2.5e-4
    gyro_misalignment_rad: float = 1e-4
    accel_misalignment_rad: float = 1e-4
    source: str = "default (seed S1 Table 4; misalignment assumed)"
    given: tuple = ()               # the keys the source stated (the rest are defaults)

    KEYS = ("gyro_scale", "accel_scale", "gyro_misalignment_rad", "accel_misalignment_rad")

    @classmethod
    def from_dict(cls, doc, source):
        """From an `accuracy` object; unknown keys refused, missing keys default (and not
        `given`, so `merged` keeps another source's values for them)."""
        if not isinstance(doc, dict):
            raise InputError(f"{source}: the reference accuracy must be an object of "
                             f"{', '.join(cls.KEYS)}")
        bad = sorted(set(doc) - set(cls.KEYS))
        if bad:
            raise InputError(f"{source}: unknown reference-accuracy keys {bad} "
                             f"(known: {', '.join(cls.KEYS)})")
        try:
            values = {k: float(v) for k, v in doc.items()}
        except (TypeError, ValueError):
            raise InputError(f"{source}: reference accuracies must be numbers: {doc}") from None
        if not all(np.isfinite(v) and 0 <= v < 0.1 for v in values.values()):
            raise InputError(f"{source}: reference accuracies must be finite, >= 0 and < 0.1 "
                             f"(1-sigma, 1 or rad): {values}")
        return cls(**values, source=source, given=tuple(values))

    @classmethod
    def parse(cls, text):
        """From the command-line form 'gyro_scale=5e-5,accel_scale=5e-5,...'."""
        try:
            pairs = dict(item.split("=", 1) for item in text.split(",") if item.strip())
        except ValueError:
            raise InputError(f"--reference-accuracy {text!r}: expected KEY=VALUE,... with keys "
                             f"{', '.join(cls.KEYS)}") from None
        return cls.from_dict({k.strip(): v for k, v in pairs.items()}, "--reference-accuracy")

    def as_dict(self):
        return {k: getattr(self, k) for k in self.KEYS + ("source",)}

    def merged(self, override):
        """These accuracies with the keys `override` states replaced (None: unchanged)."""
        if override is None or not override.given:
            return self
        values = {k: getattr(override if k in override.given else self, k) for k in self.KEYS}
        return Accuracy(**values, source=f"{override.source} over {self.source}",
                        given=tuple(set(self.given) | set(override.given)))

    def prior(self, q_sf):
        """(18, 18) covariance of the reference's linear error seen in the MIMU's axes:
        parameters gamma = [accel E' row-major (9), gyro E' row-major (9)], where the
        reference's error matrix E (diagonal: scale, off-diagonal: misalignment, independent)
        appears as E' = C E C' with C the reference -> MIMU sensor rotation (quaternion
        q_sf); row-major vec(C E C') = (C kron C) vec(E)."""
        c = quaternion.as_rotation_matrix(q_sf)
        kron = np.kron(c, c)
        out = np.zeros((18, 18))
        for k, (scale, mis) in enumerate(((self.accel_scale, self.accel_misalignment_rad),
                                          (self.gyro_scale, self.gyro_misalignment_rad))):
            var = np.where(np.eye(3, dtype=bool), scale ** 2, mis ** 2).ravel()
            out[9 * k:9 * k + 9, 9 * k:9 * k + 9] = kron @ np.diag(var) @ kron.T
        return out


def accuracy_of(meta_fog, override=None):
    """The reference's `Accuracy`: the keys `override` states (the command line's), over the
    `accuracy` object of the `sensor/fog` metadata, over the defaults."""
    base = Accuracy()
    if isinstance(meta_fog, dict) and "accuracy" in meta_fog:
        base = Accuracy.from_dict(meta_fog["accuracy"], "log metadata sensor/fog accuracy")
    return base.merged(override)

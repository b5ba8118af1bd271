"""The stated accuracy of a reference IMU (`Accuracy`): what its own errors may be - scale,
misalignment, bias stability, the step its outputs were logged in - from a log's `sensor/fog`
metadata, a table spec's `[reference_imu] accuracy`, or `mimunav diagnose
--reference-accuracy`; the defaults are seed S1 Table 4's FOG-IMU. The diagnosis weighs its
findings against it (`diagnosis.fitting`, `diagnosis.confirmation`)."""
from dataclasses import dataclass

import numpy as np
import quaternion

from ..errors import InputError


FOG_GYRO_BIAS = 1.0 * np.pi / 180 / 3600    # rad/s: seed S1 Table 4, <= 1 deg/h
FOG_ACCEL_BIAS = 100e-6 * 9.80665           # m/s^2: seed S1 Table 4, ~100 ug
STATED_ROUNDING = 1.01      # a stated stability within 1 % of those is theirs: a value
#                             written to 3 digits in another unit rounds by up to 0.5 %


# An autopilot's own IMUs (a second instance as the reference IMU of a PX4 or ArduPilot
# log): consumer MEMS parts, 1 sigma read as half the datasheet's tolerance (as Table 4's
# bound is read as 2 sigma). TDK ICM-42688-P datasheet (DS-000347), a common autopilot
# part: gyro sensitivity tolerance +-0.5 %, cross-axis +-1.25 %; accelerometer sensitivity
# +-0.5 %, cross-axis +-1 %, zero-g offset +-20 mg (before the autopilot's accelerometer
# calibration, whose residual no log states); the gyro's offset is calibrated at every boot
# by both autopilots, and what is left is its drift in flight: +-0.005 (deg/s)/degC over a
# 20 degC warm-up, 0.1 deg/s. Older parts (MPU-6000: +-3 % sensitivity) are worse: these
# are the least a user should expect, `mimunav diagnose --reference-accuracy` states others.
AUTOPILOT_MEMS = {"gyro_scale": 2.5e-3, "accel_scale": 2.5e-3,
                  "gyro_misalignment_rad": 6.25e-3, "accel_misalignment_rad": 5e-3,
                  "gyro_bias": float(np.radians(0.05)), "accel_bias": 0.5 * 20e-3 * 9.80665}
AUTOPILOT_MEMS_SOURCE = ("an autopilot's MEMS IMU: half the ICM-42688-P datasheet's tolerances "
                         "(sensors.accuracy.AUTOPILOT_MEMS); mimunav diagnose "
                         "--reference-accuracy states others")


@dataclass(frozen=True)
class Accuracy:
    """1-sigma residual errors of a calibrated reference IMU (sensor axes): scale-factor error
    (per axis, 1) and axis misalignment (per off-diagonal element, rad) of each triad. From
    the `accuracy` object of the log's `sensor/fog` metadata when present (contract
    extension, same keys), else `mimunav diagnose --reference-accuracy`, else these defaults:
      scale 2.5e-4  seed S1 Table 4: FOG-IMU scale-factor residual <= 0.05 % FS, read as 2 sigma
      misalignment 1e-4 rad  (20 arcsec) - Table 4 gives none: an assumption, medium-accuracy
                    FOG-IMU class.
    Bias stability (rad/s, m/s^2) and the step its outputs were logged in (rad/s, m/s^2; 0:
    not quantized) bound what a term shaped like a bias (a shift, a thermal or vibration
    drift, a wander) may be before it is the MIMU's for sure - a term within them is
    `mimu-or-reference` (`bias_allowance`):
      bias 1 deg/h, 100 ug  seed S1 Table 4's FOG-IMU zero drift (<= 1 deg/h, ~100 ug)
    A reference less stable than that is not of the FOG-IMU's grade: it may carry any MEMS
    physics itself (`mems_grade`), so nothing it is compared with is charged to the MIMU
    alone. Its white noise needs no entry: it is part of the residual's white noise."""
    gyro_scale: float = 2.5e-4
    accel_scale: float = 2.5e-4
    gyro_misalignment_rad: float = 1e-4
    accel_misalignment_rad: float = 1e-4
    gyro_bias: float = FOG_GYRO_BIAS
    accel_bias: float = FOG_ACCEL_BIAS
    gyro_step: float = 0.0
    accel_step: float = 0.0
    source: str = "default (seed S1 Table 4; misalignment assumed)"
    given: tuple = ()               # the keys the source stated (the rest are defaults)

    KEYS = ("gyro_scale", "accel_scale", "gyro_misalignment_rad", "accel_misalignment_rad",
            "gyro_bias", "accel_bias", "gyro_step", "accel_step")

    @property
    def mems_grade(self):
        """Less stable than seed S1 Table 4's FOG-IMU: the reference may carry MEMS physics."""
        return bool(self._beyond_table_4())

    def _beyond_table_4(self):
        """[the stated bias stabilities beyond seed S1 Table 4's FOG-IMU, in words] - beyond
        its 1 deg/h or 100 ug by more than STATED_ROUNDING (1 deg/h written 4.85e-6 rad/s
        is 1.0004 deg/h: it had made a FOG-grade unit MEMS-grade)."""
        out = []
        if self.gyro_bias > FOG_GYRO_BIAS * STATED_ROUNDING:
            out.append("its gyro bias beyond 1 deg/h")
        if self.accel_bias > FOG_ACCEL_BIAS * STATED_ROUNDING:
            out.append("its accelerometer bias beyond 100 ug")
        return out

    def grade_said(self):
        """What the diagnosis will take this reference to be, in words: FOG grade, or MEMS
        grade and why (its stated bias stability beyond seed S1 Table 4's)."""
        stated = (f"gyro bias {np.degrees(self.gyro_bias) * 3600:.5g} deg/h, accelerometer "
                  f"bias {self.accel_bias / 9.80665 * 1e6:.5g} ug ({self.source})")
        if not self.mems_grade:
            return (f"{stated}: within seed S1 Table 4's FOG-IMU (1 deg/h, 100 ug), so what "
                    "the two IMUs disagree on beyond its stated errors is the MIMU's")
        return (f"{stated}: less stable than seed S1 Table 4's FOG-IMU ("
                f"{' and '.join(self._beyond_table_4())}), so "
                "the diagnosis treats it as it treats a MEMS-grade reference, whatever its "
                "class (a tactical unit too) - any term it finds may be the "
                "reference's (`mimu-or-reference`) and its noise is charged to it (`mimunav "
                "diagnose --reference-accuracy` states others)")

    def bias_sigma(self, sensor):
        """1 sigma of the reference's own bias-shaped error on one axis of `sensor` (SI): its
        bias stability and its logging step's uniform error (step / sqrt 12) together."""
        bias, step = ((self.accel_bias, self.accel_step) if sensor == "accel" else
                      (self.gyro_bias, self.gyro_step))
        return float(np.hypot(bias, step / np.sqrt(12.0)))

    def bias_allowance(self, sensor):
        """The largest bias-shaped error the reference itself may show on one axis of
        `sensor` ("accel", m/s^2; "gyro", rad/s): twice its bias stability (95 %) and half
        its logged step (a quantized output's error where the input moves slower than one
        step per sample: it does not average away)."""
        bias, step = ((self.accel_bias, self.accel_step) if sensor == "accel" else
                      (self.gyro_bias, self.gyro_step))
        return 2.0 * bias + 0.5 * step

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
        if not all(np.isfinite(v) and 0 <= v < (1.0 if k.endswith(("_bias", "_step")) else 0.1)
                   for k, v in values.items()):
            raise InputError(f"{source}: reference accuracies must be finite, >= 0 and below "
                             f"0.1 (scale 1, misalignment rad) or 1 (bias and step, rad/s or "
                             f"m/s^2): {values}")
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

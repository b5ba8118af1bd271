"""A reference IMU must be another sensor than the IMU: one recording given twice (a leg
IMU's file shipped under two names) pairs at a turn of 0.0 deg with a standard error of
1e-14, and its 'residual' is the numbers' rounding; one board's gyro given to both of its
accelerometers (a Shimmer's low-noise and wide-range ones) timed and turned the two by that
gyro alone - 0.0025 ms and 7e-14 deg of standard error, the accelerometers 6 ms and 1 deg
apart. A copy is told by its changes sample to sample (`follows`), which an offset, a
scale or a bias that an on-board calibration steps now and then (Android's calibrated gyro
beside its uncalibrated one) leave alike, and two sensors' noise never does.
"""
import numpy as np

from .recording import RecordingError


SAME_DATA = 1e-9            # of a channel's rms: two IMUs' samples (or a residual) closer than
#                             this are one sensor's numbers twice, their difference rounding
#                             (float64 keeps 16 digits, a float32 log 7; two sensors' noise
#                             differs at 1e-3) - the sensor level's agreement reads it too
COPY_SHARE = 0.9            # of a channel's changes at least, alike: a copy's all but where an
#                             offset stepped; two quantized sensors' 1-LSB changes agree at
#                             random on a third of the samples at most
DISTINCT_VALUES = 10        # a channel equal to another IMU's tells one sensor only where it
#                             holds this many values (two coarse gyros at rest both read 0)
CHANNELS = ("gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z")


def follows(a, b):
    """Whether series a (N,) is series b's numbers over again: a's changes sample to sample
    equal k x b's (k their ratios' median, any sign: a scale, a copy in other axes) to SAME_DATA of
    their rms on COPY_SHARE of the samples where a changes, a holding DISTINCT_VALUES values."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if len(a) < 2 or len(np.unique(a)) < DISTINCT_VALUES:
        return False
    da, db = np.diff(a), np.diff(b)
    moving = da != 0
    both = moving & (db != 0)
    if both.sum() < DISTINCT_VALUES:
        return False
    size = float(np.sqrt(np.mean(da * da)))
    k = float(np.median(da[both] / db[both]))     # a copy's every ratio: a step of its offset
    #                                               would pull a least-squares k off
    return bool(np.mean(np.abs(da - k * db)[moving] <= SAME_DATA * size) >= COPY_SHARE)


def check_distinct(rec):
    """A reference IMU must be another sensor: refuses (RecordingError) one of whose channels,
    at the stamps it shares with the IMU, `follows` one of the IMU's, naming them."""
    ref = rec.reference_imu
    common, mine, theirs = np.intersect1d(rec.imu_ns, ref["ns"], return_indices=True)
    if len(common) < 0.5 * len(rec.imu_ns):
        return
    a = np.column_stack([rec.w[mine], rec.f[mine]])
    b = np.column_stack([ref["w"][theirs], ref["f"][theirs]])
    copied = [i for i in range(6) if any(follows(a[:, i], b[:, j]) for j in range(6))]
    if not copied:
        return
    what = ("every channel" if len(copied) == 6 else
            ", ".join(CHANNELS[i] for i in copied))
    raise RecordingError(
        f"{rec.name}: the IMU's {what} and the reference IMU's go sample by sample alike "
        f"({len(common)} stamps shared; their changes equal to within {SAME_DATA:g} of their "
        "rms, up to an offset, a scale and the axes' order): "
        + ("one recording given twice? " if len(copied) == 6 else
           "one sensor's channels given to both IMUs? ")
        + "A reference IMU must be another sensor - the import times and turns the two by "
          "their channels, which a shared one measures as alike, and no term of it could be "
          "tested against it")

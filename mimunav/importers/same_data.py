"""A reference IMU must be another sensor than the IMU: one recording given twice (a leg
IMU's file shipped under two names) pairs at a turn of 0.0 deg with a standard error of
1e-14, and its 'residual' is the numbers' rounding.
"""
import numpy as np

from .recording import RecordingError


SAME_DATA = 1e-9            # of a channel's rms: two IMUs' samples (or a residual) closer than
#                             this are one sensor's numbers twice, their difference rounding
#                             (float64 keeps 16 digits, a float32 log 7; two sensors' noise
#                             differs at 1e-3) - the sensor level's agreement reads it too


def check_distinct(rec):
    """A reference IMU must be another sensor: refuses (RecordingError) one whose samples at
    the stamps it shares with the IMU equal the IMU's to SAME_DATA of their rms (one file
    given twice: its 'residual' is the numbers' rounding, scanned as excursions at z 6)."""
    ref = rec.reference_imu
    common, mine, theirs = np.intersect1d(rec.imu_ns, ref["ns"], return_indices=True)
    if len(common) < 0.5 * len(rec.imu_ns):
        return
    for a, b in ((rec.w, ref["w"]), (rec.f, ref["f"])):
        a, b = a[mine], b[theirs]
        if not np.all(np.abs(a - b) <= SAME_DATA * np.sqrt(np.mean(a * a, axis=0))):
            return
    raise RecordingError(f"{rec.name}: the reference IMU's samples are the IMU's own ("
                         f"{len(common)} stamps alike, every value equal to {SAME_DATA:g} of "
                         "its rms): one recording given twice? A reference IMU must be "
                         "another sensor")

"""A reference IMU's grade checked by its own data: where no source states its bias stability,
the diagnosis takes seed S1 Table 4's FOG-IMU (`sensors.accuracy.Accuracy`), and charges to
the MIMU what the two disagree on beyond it. At a rest the import measured (the `recording`
metadata's static_s) a FOG-IMU's gyros read the Earth's rate, 15 deg/h, within its 1 deg/h
whatever its heading; a MEMS part's read its bias, 0.1-1 deg/s - which contradicts the
default, and the reference is then taken as MEMS grade (`rest_graded`): a Shimmer's
wide-range accelerometer and gyro, both MEMS, had had their couplings charged to the other
unit alone (`mimu`).
"""
import dataclasses
import math

import numpy as np

from ..frames.earth import OMEGA

REST_EXCESS = math.radians(30.0 / 3600)     # rad/s: |mean w| beyond the Earth's rate by twice
#                                             it - more than a Table 4 FOG-IMU's 1 deg/h and a
#                                             tactical part's 10 can make, far less than a
#                                             MEMS part's 360-3600 deg/h
REST_SIGMAS = 5.0       # standard errors of the rest's mean rate the excess must also pass
MIN_REST_SAMPLES = 100  # the reference's samples in the rest, at least


def rest_graded(flight, acc):
    """`acc` (the reference's `Accuracy`) as it is, or - where no source stated its gyro bias,
    and its gyros' mean rate over the import's rest lies beyond the Earth's rate by
    REST_EXCESS and REST_SIGMAS standard errors - MEMS grade: its gyro bias stability that
    excess (rad/s), its source saying so."""
    rec = flight.recording or {}
    if flight.source != "recording" or "gyro_bias" in acc.given or not rec.get("static_s") \
            or flight.fog_t is None:
        return acc
    t0, t1 = rec["static_s"]
    rows = []
    for t, w, _ in flight.fog_blocks():
        rows.append(w[(t >= t0) & (t <= t1)])
        if t[-1] > t1:
            break
    w = np.concatenate(rows) if rows else np.zeros((0, 3))
    if len(w) < MIN_REST_SAMPLES:
        return acc
    mean = w.mean(axis=0)
    se = float(np.linalg.norm(w.std(axis=0, ddof=1)) / math.sqrt(len(w)))
    excess = float(np.linalg.norm(mean)) - OMEGA
    if excess <= max(REST_EXCESS, REST_SIGMAS * se):
        return acc
    per_hour = 180 / math.pi * 3600
    said = (f"at the rest {t0:.1f}-{t1:.1f} s its gyros read {np.linalg.norm(mean) * per_hour:.4g} "
            f"deg/h (standard error {se * per_hour:.2g}), beyond the Earth's "
            f"{OMEGA * per_hour:.3g} by more than a FOG-IMU's 1 deg/h can make: the default "
            f"FOG grade is contradicted - taken as MEMS grade, its gyro bias stability that "
            f"excess ({excess * per_hour:.4g} deg/h)")
    return dataclasses.replace(acc, gyro_bias=excess, source=f"{acc.source}; {said}")

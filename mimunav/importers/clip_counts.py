"""Clip counters that autopilots log beside their IMUs: how many of the sensor's own samples
(at its internal rate, before any filter or logging) reached its range. ArduPilot's `VIBE`
message holds the count of each IMU (`Clip`, with the instance in `IMU`; before 4.0
`Clip0`, `Clip1`, `Clip2`), PX4's `vehicle_imu_status` the accelerometer's and the gyro's
(`accel_clipping[3]`, `gyro_clipping[3]`), each a running total logged at a few Hz.

A clip inside a logged value's interval leaves a value short of the motion that is neither
flat nor at the range (a 50 Hz mean of eight 400 Hz samples, two of them clipped), so no
test on the outputs can find it; the counter can. The spans where a counter rose are left
out of the diagnosis's fit (`clip_spans`): a catapult's 18 clipped samples had bent the
reference's fitted error, and a belly landing 700 s later read as an excursion of
0.09 m/s^2.
"""
import numpy as np

SETTLE_S = 0.1     # s after the record that counted a clip, also left out: the logged values
#                   are low-passed (ArduPilot's INS_ACCEL_FILTER, 10 Hz or more: a time
#                   constant of 16 ms or less, so 0.1 s is six of them or more)


def clip_spans(us, totals):
    """[(t0 us, t1 us, clips)] where the running totals rose: from the record before the rise
    to SETTLE_S after the record that counted it, overlapping spans merged. us: (N,) the
    records' times (us, ascending); totals: (N,) or (N, k) running totals (summed over the
    k columns: axes, or an accelerometer's and a gyro's). A total that falls (a restart)
    counts from its new value."""
    us = np.asarray(us, np.int64)
    total = np.asarray(totals, float).reshape(len(us), -1).sum(axis=1)
    order = np.argsort(us, kind="stable")
    us, total = us[order], total[order]
    rise = np.diff(total)
    return merged([(int(us[k]), int(us[k + 1] + SETTLE_S * 1e6), int(rise[k]))
                   for k in np.flatnonzero(rise > 0)])


def merged(spans):
    """The spans (t0, t1, clips) of several counters as one list in time order, overlapping
    ones merged (their clips added)."""
    out = []
    for t0, t1, n in sorted(spans):
        if out and t0 <= out[-1][1]:
            out[-1] = (out[-1][0], max(t1, out[-1][1]), out[-1][2] + n)
        else:
            out.append((t0, t1, n))
    return out


def clips_said(spans, source, t0_ns=0):
    """What the import says of the spans (ns on the recording's clock; t0_ns: its first IMU
    stamp, the log's t = 0) counted by `source`, or '' without any."""
    if not spans:
        return ""
    first = ", ".join(f"{(a - t0_ns) / 1e9:.2f}-{(b - t0_ns) / 1e9:.2f} s" for a, b, _ in
                      spans[:3]) + (", ..." if len(spans) > 3 else "")
    return (f"{sum(n for *_, n in spans)} samples counted clipped by {source} in "
            f"{len(spans)} span(s) ({first}): a sensor counted reached its range inside "
            "its logged values, which are then short of the motion without being flat; the "
            "diagnosis leaves these spans out")

"""The track level's navigation check: a finding must make the free-inertial windows
(`evaluation.windows`) navigate better - paired end errors with and without it - except a
mounting's tilt, which the windows cannot see.
"""
import numpy as np

from ..errors import InputError


CHECK_WINDOW_S = 10.0       # free-inertial windows of the navigation check
MIN_CHECK_WINDOWS = 5       # fewer windows cannot confirm a term in navigation
TILT_UNSEEN = ("a tilt (its turn about the vehicle's down axis holds 0): the windows take "
               "their attitude from the IMU's own velocity increments, whose gravity sets the "
               "roll and pitch, so no window sees it; confirmed on the held-out residual only")


def is_tilt(finding):
    """True for a mounting misalignment whose turn about the vehicle's down axis is not
    told from 0 (its 95 % interval holds 0): a roll or pitch of the IMU on the vehicle, which
    the free-inertial windows cannot see - `alignment.moving_attitude` levels each window on
    the IMU's own specific force. On an independent level drive a 3 deg pitch, found at
    -0.0525 [-0.072, -0.033] (truth -sin 3 deg), changed the windows' median paired end
    error by +5 mm and their vertical by 0 (a 6.8 deg one by -8 mm), where a 3 deg yaw
    changes them by metres: the check cannot confirm a tilt, nor refute one. A yaw too
    poorly determined to be told from 0 passes with it unchecked."""
    if finding["effect"] != "mounting_misalignment" or "vector_vehicle_ci95" not in finding:
        return False
    low, high = finding["vector_vehicle_ci95"][2]
    return low <= 0.0 <= high


def navigation_check(flight, cal, finding, baseline):
    """Why `finding` is not confirmed in navigation, or None when it is: the CHECK_WINDOW_S
    free-inertial windows with it removed must end nearer the reference - the median of the
    paired changes below 0 and the median end error not up - over at least
    MIN_CHECK_WINDOWS windows (fewer cannot say; a 20 s recording confirmed a term that
    tripled its navigation error). Writes finding["navigation_check"] when it ran.
    baseline: `window_ends` without it."""
    ends = window_ends(flight, cal, [finding])
    pairs = [] if ends is None or baseline is None else paired_starts(ends, baseline)
    n = len(pairs)
    if n < MIN_CHECK_WINDOWS:
        return (f"cannot be checked in navigation: {n} free-inertial {CHECK_WINDOW_S:g} s "
                f"windows (need {MIN_CHECK_WINDOWS})")
    ends, baseline = (np.array([x[k] for x in pairs]) for k in (0, 1))
    paired = float(np.median(ends - baseline))
    before, after = float(np.median(baseline)), float(np.median(ends))
    finding["navigation_check"] = {
        "windows": n, "window_s": CHECK_WINDOW_S, "median_end_error_m": [before, after],
        "median_paired_change_m": paired}
    if not paired < 0:      # the windows' medians may fall while most windows get worse
        return (f"does not navigate better window by window: over {n} {CHECK_WINDOW_S:g} s "
                f"windows the median of the paired changes of the end error is {paired:+.3g} m "
                f"(the median end error {before:.4g} -> {after:.4g} m)")
    if not after <= before:
        return (f"does not navigate better: over {n} {CHECK_WINDOW_S:g} s windows the median "
                f"end error goes {before:.4g} -> {after:.4g} m (median paired change "
                f"{paired:+.3g} m)")
    return None


PAIR_S = CHECK_WINDOW_S / 10    # windows starting this near one another span nine tenths
# of the same motion: compared as a pair (a lag removed moves every start with the IMU's
# stamps - a drive's -41 ms had left no start in common, "0 windows")


def paired_starts(ends, baseline):
    """[(end error with, without)] of the windows of `ends` and `baseline` ({start s: m},
    `window_ends`) paired by start: each baseline window with the nearest start of `ends`
    within PAIR_S, each used once."""
    starts = np.array(sorted(ends))
    pairs, used = [], set()
    for t0 in sorted(baseline):
        if len(starts) == 0:
            break
        k = int(np.argmin(np.abs(starts - t0)))
        if abs(starts[k] - t0) <= PAIR_S and k not in used:
            used.add(k)
            pairs.append((ends[starts[k]], baseline[t0]))
    return pairs


def window_ends(flight, cal, findings):
    """{start t0 (s): horizontal end error (m)} of the CHECK_WINDOW_S free-inertial windows
    with the findings removed from the MIMU, or None when the recording holds no window.
    Keyed by the start: the windows start where the IMU is quiet enough to align, and a term
    removed can move a start across that bound (a drive over 1 m hills had 87 windows with a
    gyro.y scale removed and 85 without; paired by position they had ended the diagnosis in
    a traceback)."""
    from ..evaluation import windows
    from ..compensation.calibration_file import with_found
    found = with_found(cal, findings) if findings else None
    try:
        results, _ = windows.run_all(flight, found, lengths=(CHECK_WINDOW_S,))
    except InputError:
        return None
    return {round(w.t0, 6): float(w.horizontal[-1]) for w in results[CHECK_WINDOW_S]}

"""Where on the vehicle a reference trajectory lies. `/truth/state` is the trajectory of the
vehicle frame's origin, the point the mountings' lever arms are counted from
(shared/spec/log-format.md); a recording's reference is an INS's solution at its own IMU (or
the point it was told to output). A user who puts the origin at the IMU under test and gives
the reference IMU's arm from it has the trajectory at the reference IMU, not at the origin
(a survey ship's INS 14.4 m from its MEMS: the free-inertial windows charged the MEMS with 13
times its error as the ship rolled, and the navigation level found a "lever arm" whose
interval missed the 12 m along x).

The data say where: an IMU's 1 s mean specific forces in the vehicle frame, less what the
reference's attitude and velocity make of them at the trajectory's point
(`attitude_check.attitude_means`), are the lever force from that point to the IMU,
dw/dt x r + w x (w x r) (`lever`), linear in r; fitted with a constant beside it (the IMU's
bias) and a clock between the two (the forces' change), its error jackknifed over blocks of
the seconds. The reference IMU is used where there is one (an INS's own: its noise the
smaller), else the IMU. A point found off the origin is moved onto it (`moved_to_origin`)
only by the reference IMU's point as given, where the measured one lies there; else it is
said and left (`check_trajectory_point`).
"""
import math

import numpy as np

from ..frames import attitude, earth
from .attitude_check import attitude_means
from .imu_clock import DISTINCT_Z
from .lever import arm_cov, unit_forces
from .series import window_means

# m: a point measured within this of a point given (the origin, the reference IMU's) is that
# point - the fit's own model errors beside its jackknifed error: an IMU's scale and
# misalignment on the forces, the attitude's errors, the clock between the two (an arm
# between two IMUs 14.4 m apart read 0.21 m off at 8 of its standard errors)
SAME_POINT_M = 0.3
MIN_SECONDS = 30


def measured_point(rec, the_imu=False):
    """(the trajectory's point p, m, vehicle frame FRD - from the origin -, its (3, 3)
    covariance, the IMU whose forces measured it in words), or why it is not measured:
    fewer than MIN_SECONDS seconds in common, or rates that do not span three directions
    of the arm. By `_own_imu`'s, or the IMU's where the_imu; the reference's stamps taken as
    late as the clock check measured and left (`reference_clock_unapplied_s`: a mocap pose
    0.2 s late had placed an exact point 0.04 m off at 20 standard errors)."""
    whose, ns, w, f, mounting = _own_imu(rec, the_imu)
    late = rec.reference_clock_unapplied_s or 0.0      # measured, left as the IMU's latency
    ref_s = rec.reference["ns"] / 1e9 - late
    lo, hi = max(ns[0] / 1e9, ref_s[0]) + 1.0, min(ns[-1] / 1e9, ref_s[-1]) - 1.0
    mids = np.arange(lo, hi, 1.0)
    short = (f"under {MIN_SECONDS} s of the reference's attitude and velocity beside "
             f"{whose}'s samples")
    predicted = attitude_means(rec.reference, mids + late) if len(mids) >= MIN_SECONDS \
        else None
    if predicted is None:
        return short
    w_v = attitude.rotate(mounting.q_vs, w)
    unit = unit_forces(ns, w_v, mids)
    gap = attitude.rotate(mounting.q_vs, window_means(ns, f, mids)) - predicted[1]
    rows = np.isfinite(gap).all(axis=1) & np.isfinite(unit).all(axis=(1, 2))
    if rows.sum() < MIN_SECONDS:
        return short
    design = (unit[rows] - unit[rows].mean(axis=0)).reshape(-1, 3)
    gap = (gap[rows] - gap[rows].mean(axis=0)).ravel()
    if np.linalg.matrix_rank(design) < 3 or np.linalg.cond(design) > 1e6:
        return "the rates do not turn the vehicle about three axes enough to place it"
    lag = -np.gradient(predicted[1], axis=0)[rows]      # s^-1 x the 1 s means' change: the
    lag = (lag - lag.mean(axis=0)).reshape(-1, 1)       # force of a clock late by 1 s
    if np.any(lag):                     # fitted beside the arm: an IMU late by d on a car
        design = np.hstack([design, lag])   # at speed v reads as an arm of v d along it (30
        #                                   ms at 10 m/s: a point 0.29 m off)
    arm = np.linalg.lstsq(design, gap, rcond=None)[0][:3]   # r = the IMU's point - p
    return mounting.lever_arm_m - arm, arm_cov(design, gap)[:3, :3], whose


def _own_imu(rec, the_imu=False):
    """(in words, stamps ns, w rad/s, f m/s^2, `Mounting`) of the reference IMU where there
    is one, else (or where the_imu) of the IMU."""
    own = rec.reference_imu
    return (("the IMU", rec.imu_ns, rec.w, rec.f, rec.mounting) if own is None or the_imu else
            ("the reference IMU", own["ns"], own["w"], own["f"], own["mounting"]))


def check_trajectory_point(rec):
    """Measure the reference trajectory's point (`measured_point`) and say it in
    rec.real["reference_point"]; where it lies off the origin beyond SAME_POINT_M and
    DISTINCT_Z of its error, and its error is within SAME_POINT_M every way: where it lies
    at the reference IMU's point as given (nonzero), move the trajectory onto the origin by
    that arm (`moved_to_origin`); else say it in rec.trajectory_point_off too, the
    trajectory left where it is. (A car's gentle drive, its 1 Hz reference's forces misfit
    at the IMU's, had placed its point 13 km off, standard errors 1.7 km, and been moved
    by it.)"""
    measured = measured_point(rec)
    if isinstance(measured, str):
        rec.real["reference_point"] = f"not measured ({measured}): taken at the origin"
        return
    p, cov, whose = measured
    _check_the_imus_point(rec, p, cov)
    said = (f"the reference trajectory's point measured at "
            f"[{', '.join(f'{x:+.3f}' for x in p)}] m (vehicle frame FRD, from the origin; "
            f"standard errors {', '.join(f'{x:.2g}' for x in np.sqrt(np.diag(cov)))}, "
            f"jackknifed, which leave the fit's model errors out; by {whose}'s specific "
            "forces)")
    if not np.sqrt(np.linalg.eigvalsh(cov)).max() <= SAME_POINT_M:   # before the origin's
        rec.real["reference_point"] = (f"{said}: not placed to {SAME_POINT_M:g} m (the motion "
                                       "turns the vehicle too little, or the reference's "
                                       "gaps or a clock offset left too little that agrees "
                                       "with the IMU's forces); taken at the origin")
        return      # test: a car's point known to 2 km had been said "at the origin"
    if _same(p, np.zeros(3), cov):
        size = float(np.linalg.norm(p))
        apart = size > DISTINCT_Z * math.sqrt(float(p @ cov @ p)) / max(size, 1e-12)
        rec.real["reference_point"] = said + (
            f": taken at the origin, as /truth/state is (within {SAME_POINT_M:g} m or "
            f"{DISTINCT_Z:g} standard errors of it: the fit's own model errors - an IMU's "
            "scale, misalignment and bias on the forces, a clock between the two - reach that)"
            + (f"; {size:.3f} m from it is beyond {DISTINCT_Z:g} standard errors, which leave "
               "those model errors out: not a measure of the point - a lever arm given may "
               "be off by as much, which the diagnosis's lever_arm term tests"
               if apart else ""))
        return
    own = rec.reference_imu
    given = None if own is None else own["mounting"].lever_arm_m
    if given is not None and np.any(given) and _same(p, given, cov):
        moved_to_origin(rec, given)
        rec.real["reference_point"] = (
            f"{said}: the reference IMU's point as given, not the origin - the trajectory "
            "moved onto the origin by that arm (positions - C_nb r, velocities - "
            "C_nb (w x r)), as /truth/state is")
        return
    rec.real["reference_point"] = (
        f"{said}: not the origin" + ("" if given is None else
                                     ", nor the reference IMU's point as given") +
        " - the trajectory is not moved, and its point is taken for the vehicle origin: a "
        "point measured is not moved by (a reference stamped late, sampled at 1-2 Hz, an "
        "IMU's mounting tilted a little or an INS yawed in the hull place it metres off); "
        "where the trajectory's point is known, give the lever arms from it (--lever-arm-m "
        "for the IMU, --reference-imu-lever-arm-m for a reference IMU; a table spec's "
        "lever_arm_m)")
    rec.trajectory_point_off = (
        f"the reference trajectory's point measured {np.linalg.norm(p):.2f} m off the origin "
        "and left there (measured reference point)")


def _check_the_imus_point(rec, p, cov):
    """Where the reference IMU placed the trajectory's point (p m, cov m^2), the IMU's own
    forces place it too: where the two lie apart (`_same`), the IMU is not where its lever
    arm given puts it against the reference IMU, and what is navigated from the IMU against
    the trajectory (the windows, the navigation level) carries that arm's transfer - said
    in rec.imu_point_off (a ship's MEMS 14.4 m from its INS, no arm given: its windows had
    charged it with the swinging of that arm, with no word)."""
    if rec.reference_imu is None:
        return
    mine = measured_point(rec, the_imu=True)
    if isinstance(mine, str) or _same(mine[0], p, mine[1] + cov):
        return
    off = mine[0] - p
    rec.imu_point_off = (
        f"the IMU's own specific forces place the reference trajectory's point "
        f"{', '.join(f'{x:+.3f}' for x in off)} m (vehicle frame FRD; standard errors "
        f"{', '.join(f'{x:.2g}' for x in np.sqrt(np.diag(mine[1] + cov)))}) from where the "
        "reference IMU's do: the IMU lies that much the other way from where its lever arm "
        "given puts it (mimunav import --lever-arm-m, --reference-imu-lever-arm-m; a table "
        "spec's lever_arm_m)")


def _same(p, q, cov):
    """Whether the measured point p lies at the point q: within SAME_POINT_M or DISTINCT_Z
    of its standard error along the difference (cov: its covariance, m^2)."""
    d = p - q
    size = float(np.linalg.norm(d))
    if size <= SAME_POINT_M:
        return True
    along = d / size
    return size <= DISTINCT_Z * math.sqrt(float(along @ cov @ along))


def moved_to_origin(rec, r):
    """The reference trajectory (positions, NED velocities; its attitude kept) moved from
    its point r (m, vehicle frame) to the origin: - C_nb r, - C_nb (w x r), w the body rate
    at each epoch (`_own_imu`'s rates, vehicle frame, over the epoch's interval; epochs
    without an attitude take the nearest one's)."""
    ref = rec.reference
    q = np.asarray(ref["q_nb"], float)
    ok = np.isfinite(q).all(axis=1)
    nearest = np.flatnonzero(ok)[np.clip(np.searchsorted(np.flatnonzero(ok),
                                                         np.arange(len(q))), 0, ok.sum() - 1)]
    q_nb = attitude.from_wxyz(q[nearest])
    t = ref["ns"] / 1e9
    half = 0.5 * float(np.median(np.diff(t)))
    _, ns, w, _, mounting = _own_imu(rec)
    w_v = window_means(ns, attitude.rotate(mounting.q_vs, w), t, half)
    w_v = np.where(np.isfinite(w_v), w_v, 0.0)
    d_ned = attitude.rotate(q_nb, np.broadcast_to(-np.asarray(r, float), (len(t), 3)))
    r_n, r_e = earth.radii(ref["lat"])      # an offset of metres: first order in it
    ref["lat"], ref["lon"], ref["h"] = (ref["lat"] + d_ned[:, 0] / (r_n + ref["h"]),
                                        ref["lon"] + d_ned[:, 1] / ((r_e + ref["h"])
                                                                    * np.cos(ref["lat"])),
                                        ref["h"] - d_ned[:, 2])
    ref["v_ned"] = ref["v_ned"] - attitude.rotate(q_nb, np.cross(w_v, r))

"""The track level's yaw-rate time lag: the MIMU's z rate against the course rate of the
track, shifted over a search window, per segment; a `time_skew imu.all` finding when both
halves of the segments place it and the free-inertial windows navigate better with it.
"""
import math
from dataclasses import dataclass

import numpy as np

from ..importers.series import parabola_min
from .track_reference import CONSUMER_NOISE, GAP_MARGIN_S, in_band, simulated_reference
from .track_navigation import window_ends, navigation_check


LAG_SEARCH_S = 0.5
LAG_SEARCH_MAX_S = GAP_MARGIN_S     # s: a segment least at +-LAG_SEARCH_S is searched on to here
VELOCITY_LAG_NOTE_S = 0.02      # s: a reference velocity this late is named beside the lag
LAG_REFERENCE_STEP_S = 0.5      # s: a track with sparser epochs cannot place the lag (its
                                # bandwidth shifts the yaw rate's phase by tens of ms)
LAG_STEP_S = 0.005
LAG_SEGMENTS = 10
MIN_HALF_SEGMENTS = 2           # placed segments in each half (a t test needs 2)
STRAY_Z = 5.0   # a segment this many standard deviations from the others' lag is the vehicle
# model failing there, not the lag: by chance once in 1.7e5 lags (5.7e-7 two-sided, x 10)


def lag_finding(diag, flight, cal, segments, alpha):
    """The yaw-rate lag as a `time_skew imu.all` finding when the data support it: its value
    and interval from all segments (`time_lag`), significant in each half alone (alternate
    segments among those that place a lag, at least MIN_HALF_SEGMENTS each; a t test of each
    half against 0 at level alpha: replicated), and the
    free-inertial windows navigate better with the IMU's stamps shifted by it (the module's
    navigation check). The sensor level's time_skew over all channels may be rejected beside
    it: the vehicle model predicts the other channels too poorly to show a lag. A track
    whose epochs are more than LAG_REFERENCE_STEP_S apart cannot place the lag. Returns the
    descriptions of the findings it demoted (`no_lag`)."""
    step = float(np.median(np.diff(flight.truth.t)))
    if step > LAG_REFERENCE_STEP_S:
        return no_lag(diag, f"the reference's epochs are {step:.2g} s apart: its track "
                             "cannot place a lag of tens of ms (the RTKLIB drive's 1 Hz "
                             "subset moved the lag by 17-54 ms, beyond its interval)")
    if len(segments.values) < 2 * MIN_HALF_SEGMENTS:
        return no_lag(diag, unplaced_lag(segments))
    train, held = segments.part(slice(0, None, 2)), segments.part(slice(1, None, 2))
    p_train, p_held = train.p_value(), held.p_value()
    if not (p_train < alpha and p_held < alpha):
        return no_lag(diag, f"the segments' lag is not significant in both halves (p "
                             f"{p_train:.2g} training, {p_held:.2g} held out)")
    value, ci = segments.mean_and_interval()      # all segments; the halves: replication
    finding = {"effect": "time_skew", "sensor": "imu", "axis": "all",
               "coefficient": value, "ci95": [float(ci[0]), float(ci[1])], "units": "s",
               "ci95_method": "student-t over segments",
               "label": "time_skew imu.all", "p_train": p_train,
               "holm_threshold": alpha,               # one test: Holm's limit is alpha
               "p_heldout": p_held, "attribution": "mimu-or-reference",
               "indistinguishable_from": [],
               "basis": "the yaw rate against the vehicle model (time_lag): value and interval "
                        "from all segments (random-effects weighted, Segments.mean_and_se), "
                        "significant in the even and in the odd ones alone",
               "where": [{"t0": float(flight.mimu_t[0]), "t1": float(flight.mimu_t[-1]),
                          "condition": "every sample: a shift of the IMU's stamps"}],
               "fit": {"channels": ["gyro.z"], "units": "s",
                       "heldout_rms_before": held.weighted_rms(0.0),
                       "heldout_rms_after": held.weighted_rms(train.mean_and_se()[0]),
                       "basis": "inverse-variance weighted rms of the held-out segments' lags "
                                "about 0 and about the training value"}}
    fit = finding["fit"]
    if not fit["heldout_rms_after"] < fit["heldout_rms_before"]:
        return no_lag(diag, f"the held-out segments' lags lie nearer 0 than the training "
                             f"value (rms {fit['heldout_rms_before']:.3g} -> "
                             f"{fit['heldout_rms_after']:.3g} s)")
    why = navigation_check(flight, cal, finding, window_ends(flight, cal, []))
    if why is not None:
        return no_lag(diag, why)
    diag.findings = [f for f in diag.findings if f["effect"] != "time_skew"] + [finding]
    for r in diag.rejected:
        if r["effect"] == "time_skew" and r.get("sensor") in ("imu", "gyro"):
            r["rejected"] += ("; the lag itself is found from the yaw rate, the channel the "
                              "vehicle model predicts best (time_skew imu.all above)")
    return []


def unplaced_lag(segments):
    """Why `segments` (fewer than 2 x MIN_HALF_SEGMENTS placed) give no lag, in words."""
    at = ", ".join(f"{v:.3f}" for v in segments.values)
    return (f"{len(segments.values)} of {LAG_SEGMENTS} segments place a lag within "
            f"+-{LAG_SEARCH_MAX_S:g} s" + (f" (at {at} s)" if at else "") +
            f"; in the other {segments.unplaced} the yaw rate's rms is least at the search's "
            "edge or places the lag no better than that (the vehicle hardly turns there, or "
            "the lag is larger): "
            f"{2 * MIN_HALF_SEGMENTS} are needed to bound it and replicate it in two halves")


def velocity_lag(flight):
    """The reference's velocity lag behind its positions and its standard error (s, s) from
    the log's `reference` metadata (written at import, `importers.velocity_lag_s`; the error
    nan in logs imported before it was written), or None."""
    meta = flight.reference_meta or {}
    try:
        return float(meta["velocity_lag_s"]), float(meta.get("velocity_lag_se_s", "nan"))
    except (KeyError, TypeError, ValueError):
        return None


def no_lag(diag, why):
    """The yaw-rate lag is not a finding (`why`): say so, and move the sensor level's
    time_skew findings to the rejected - the lag is judged on the yaw rate, the channel the
    vehicle model predicts best; a time_skew on the other channels is a vehicle-model
    artefact that can pass (the RTKLIB drive's accelerometers gave 0.024-0.073 s for a
    0.102 s lag, depending on the IMU's rate). Returns the demotions' descriptions."""
    if "not_estimated" not in diag.time_lag:            # else it says why already
        diag.time_lag["not_a_finding"] = why
    demoted = []
    for finding in [f for f in diag.findings if f["effect"] == "time_skew"]:
        reason = f"the lag is judged on the yaw rate, and there it is not a finding: {why}"
        diag.findings.remove(finding)
        diag.rejected.append(dict(finding, rejected=reason))
        demoted.append(f"{finding['label']}: {reason}")
    return demoted


def time_lag(flight, reference=None):
    """The IMU's time-stamp lag tau (s, positive: its samples describe motion tau seconds
    earlier than their stamps, as `time_skew`) from the vehicle's yaw rate alone - the
    channel the land-vehicle model predicts best: the tau minimising the rms of
    w_z,IMU(t) - w_z,model(t - tau) over trusted moving samples (grid of LAG_STEP_S, refined
    by a parabola), per LAG_SEGMENTS contiguous segments. A segment's lag is known to
    var = s^2 / sum (dw_z/dt)^2 (s: its residual rms at the minimum; the lag's regressor is
    the yaw acceleration; s at least the part's white noise, CONSUMER_NOISE), so a segment
    where the vehicle hardly turns weighs little. A segment whose rms is least at the edge of
    the +-LAG_SEARCH_S search is searched on to +-LAG_SEARCH_MAX_S (a lag beyond the first
    search); one still least at that edge, or known no better than +-LAG_SEARCH_MAX_S,
    places no lag and is left out (`Segments.unplaced`): on a noise-free drive with one
    sharp turn the straight segments' model error sloped the rms across the whole search,
    their end parabolas said -14.6 and +28 s, and the mean came out 2.5 s [-3.7, 8.8] for a
    0.1 s lag (the turn's two segments: 0.100).
    Returns (tau: the weighted mean, its 95 % interval (Student t, the standard error
    scaled by the segments' Birge ratio when above 1), `Segments`); NaN and a NaN interval
    when fewer than 2 x MIN_HALF_SEGMENTS segments place a lag (two agreeing halves of one
    turn gave 117 ms [110, 124] for 100: the track's own phase error, which only the
    scatter of more segments shows).
    The IMU's yaw rate is compared in the track's band (`TrackMotion.in_band`).
    `reference`: a `simulated_reference(flight)` already made."""
    from ..frames import attitude
    ref, trusted, motion = reference or simulated_reference(flight)
    t = flight.mimu_t
    q_vs = flight.mimu_mounting.q_vs
    w_imu = attitude.rotate(q_vs, in_band(motion, t, flight.mimu_imu, q_vs)[0])[:, 2]
    w_model = np.interp(t, ref.fog_t, ref.fog_w[:, 2])
    moving = trusted & (np.abs(w_model) > 0) & (t > ref.fog_t[0] + LAG_SEARCH_MAX_S) & \
        (t < ref.fog_t[-1] - LAG_SEARCH_MAX_S)
    k = np.flatnonzero(moving)
    accel = np.gradient(w_model, t)[k]
    # each sample weighs its own interval and the segments are equal shares of the moving
    # time, not of the samples: a logger switched from 100 to 50 Hz had put its segment
    # boundaries elsewhere and one 30 s stretch had swung the mean (0.078 for 0.102 s)
    step = np.diff(t, prepend=t[0] - np.median(np.diff(t)))[k]
    weight = np.minimum(step, 2 * np.median(step)) / np.median(step)
    share = np.cumsum(weight) / np.sum(weight)
    part = np.minimum((share * LAG_SEGMENTS).astype(int), LAG_SEGMENTS - 1)

    imu = w_imu[k] - w_imu[k].mean()
    total = np.maximum(np.bincount(part, weight, LAG_SEGMENTS), 1e-300)

    def curves(taus):           # (len(taus), LAG_SEGMENTS): each segment's weighted mse
        out = np.empty((len(taus), LAG_SEGMENTS))
        for j, tau in enumerate(taus):
            model = np.interp(t[k] - tau, ref.fog_t, ref.fog_w[:, 2])
            err = imu - (model - model.mean())
            out[j] = np.bincount(part, weight * err * err, LAG_SEGMENTS) / total
        return out
    taus = np.arange(-LAG_SEARCH_S, LAG_SEARCH_S + 1e-12, LAG_STEP_S)
    mse = curves(taus)
    values = np.array([parabola_min(taus, mse[:, i]) for i in range(LAG_SEGMENTS)])
    lowest = mse.min(axis=0)
    if not np.isfinite(values).all():
        # a segment least at the search's edge is searched on to LAG_SEARCH_MAX_S: a lag
        # beyond the first search is a lag (0.7 s on the weaving drive), not a straight road
        side = np.arange(LAG_SEARCH_S + LAG_STEP_S, LAG_SEARCH_MAX_S + 1e-12, LAG_STEP_S)
        wide = np.concatenate([-side[::-1], taus, side])
        wide_mse = np.concatenate([curves(-side[::-1]), mse, curves(side)])
        for i in np.flatnonzero(~np.isfinite(values)):
            values[i] = parabola_min(wide, wide_mse[:, i])
            lowest[i] = wide_mse[:, i].min()
    # a residual below the part's own white noise is the vehicle model's error, not a
    # precision: on a noise-free drive, straight segments (a yaw rate of the Earth's and the
    # transport rate, 5e-5 rad/s; the model's residual 1e-6) had put their lags at 0.28 +-
    # 0.003 and -0.33 +- 0.0005 s, and the mean at 0.065 s [-0.25, 0.38] for 0.1 s
    white = CONSUMER_NOISE["gyro_white"] ** 2 / np.median(step)
    info = np.bincount(part, weight * accel * accel, LAG_SEGMENTS)
    variances = np.maximum(lowest, white) / np.maximum(info, 1e-300)
    # a segment whose lag is known no better than the search's reach places none: its least
    # rms anywhere inside is where noise put it (the one-turn drive's straight segments,
    # smoothed into the track's band, had been 'placed' at 1.7 s +- 2.5e5 s and made the
    # turn's two halves count as four)
    placed = np.isfinite(values) & (np.sqrt(variances) <= LAG_SEARCH_MAX_S)
    segments = Segments(values[placed], variances[placed], int(np.sum(~placed))).without_strays()
    if len(segments.values) < 2 * MIN_HALF_SEGMENTS:
        return math.nan, (math.nan, math.nan), segments
    tau, (lo, hi) = segments.mean_and_interval()
    return tau, (lo, hi), segments


@dataclass
class Segments:
    """Per-segment lags (s) and their variances (s^2) of the segments that place a lag inside
    the search; `unplaced`: how many did not (their rms least at the search's edge, or their
    standard error beyond its reach)."""
    values: np.ndarray
    variances: np.ndarray
    unplaced: int = 0
    strays: tuple = ()      # (lag s, its standard error s, z) of the segments set aside

    def part(self, sl):
        """The segments `sl` of those placed (the halves alternate among them)."""
        return Segments(self.values[sl], self.variances[sl])

    def without_strays(self):
        """These segments without those whose lag lies beyond STRAY_Z of the others' -
        their random-effects mean, its variance, their excess scatter tau^2 and the
        segment's own variance together - one at a time, the farthest first, at most a
        quarter of them: a segment where the vehicle model's yaw rate fails (an
        independent trial's drive read -0.334 s +- 0.019 in one of eight segments, the
        other seven 29.2-32.0 ms +- 0.4, its lag 30 ms; the same segment in its null
        twin) had widened the interval to [17, 42] ms and left one half not significant."""
        kept, strays = self, []
        while len(strays) < len(self.values) // 4 and len(kept.values) > 2 * MIN_HALF_SEGMENTS:
            z = kept.stray_z()
            i = int(np.argmax(np.abs(z)))
            if not abs(z[i]) > STRAY_Z:
                break
            strays.append((float(kept.values[i]), float(np.sqrt(kept.variances[i])),
                           float(z[i])))
            rest = np.arange(len(kept.values)) != i
            kept = Segments(kept.values[rest], kept.variances[rest])
        return Segments(kept.values, kept.variances, self.unplaced, tuple(strays))

    def stray_z(self):
        """(k,): each segment's lag less the others' random-effects mean, over the root of
        its variance, their excess scatter tau^2 and the mean's variance."""
        z = np.empty(len(self.values))
        for i in range(len(z)):
            rest = np.arange(len(z)) != i
            others = Segments(self.values[rest], self.variances[rest])
            mean, se = others.mean_and_se()
            tau2 = float(np.mean(1.0 / others._weights() - others.variances))
            z[i] = (self.values[i] - mean) / math.sqrt(self.variances[i] + tau2 + se ** 2)
        return z

    def mean_and_se(self):
        """Random-effects mean and its standard error (DerSimonian & Laird 1986): when the
        segments scatter more than their variances say (Cochran's Q > k - 1), that excess
        tau^2 is a variance every segment shares, and the weights are 1 / (var + tau^2) - so
        one segment whose lag looks known to 1 ms cannot carry the mean against the others
        (a 120 s drive's lag came out 474 [343, 606] ms with its segments at 5-580 ms); with
        consistent segments, the inverse-variance mean. The standard error also takes the
        Birge ratio of the re-weighted scatter when above 1."""
        w = self._weights()
        k = len(w)
        mean = float(np.sum(w * self.values) / np.sum(w))
        # and the Birge ratio of what is left (the moment estimate of tau^2 can fall short)
        birge = float(np.sum(w * (self.values - mean) ** 2)) / max(k - 1, 1)
        return mean, float(np.sqrt(max(birge, 1.0) / np.sum(w)))

    def _weights(self):
        """1 / (var + tau^2), tau^2 the DerSimonian-Laird excess of the segments' scatter."""
        w = 1.0 / self.variances
        mean = float(np.sum(w * self.values) / np.sum(w))
        q = float(np.sum(w * (self.values - mean) ** 2))
        tau2 = max(0.0, (q - (len(w) - 1)) / max(np.sum(w) - np.sum(w ** 2) / np.sum(w),
                                                 1e-300))
        return 1.0 / (self.variances + tau2)

    def weighted_rms(self, about):
        """Weighted rms of the lags about `about` (s), the mean's random-effects weights: a
        segment where the vehicle hardly turns (its lag known to seconds) weighs nothing."""
        w = self._weights()
        return float(np.sqrt(np.sum(w * (self.values - about) ** 2) / np.sum(w)))

    def mean_and_interval(self):
        from scipy import stats
        mean, se = self.mean_and_se()
        half = stats.t.ppf(0.975, len(self.values) - 1) * se
        return mean, (mean - half, mean + half)

    def p_value(self):
        """Two-sided p of mean = 0 (Student t with the segments' dof)."""
        from scipy import stats
        mean, se = self.mean_and_se()
        return float(2 * stats.t.sf(abs(mean) / se, len(self.values) - 1))

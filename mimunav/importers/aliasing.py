"""An IMU logged as instantaneous samples (a table spec's `sampling = "instant"`) beside a
reference IMU sampled faster: whether vibration above the IMU's Nyquist frequency folded
into its band. The reference IMU feels that vibration; where the IMU's samples took it
unfiltered, its spectrum holds the reference's above-Nyquist power folded about the Nyquist
frequency, beyond what the reference holds there itself. Confirmed by the data, not assumed
from the rate alone: a unit that filters before it samples (most MEMS parts' digital low-pass)
shows none of it.
"""
import numpy as np
from scipy import signal

from ..flightlog.stamps import mean_rate_hz

NAMES = {"gyro": "gyros", "accel": "accelerometers"}
SEGMENT_S = 20.0        # s: Welch's segments (0.05 Hz apart: a rotor's lines stay apart)
FOLDED_SLOPE = 0.5      # the IMU's excess power over the reference's, regressed on the
#                         reference's folded power: 1 where it folded in whole, 0 where the
#                         unit filtered it out; beyond half, folded
ALIAS_SHARE = 0.1       # the folded power over the IMU's own sample scatter about its 1 s
#                         means (all axes): beyond a tenth, its bins carry tones at the wrong
#                         frequency that their means do not cancel (a helicopter's 26.4 Hz
#                         line at 50 Hz read as an accel.z scale of +1.6 %, p 7e-14)


def aliased(rec):
    """{sensor: words} for the IMU's sensors ("gyro", "accel") whose instantaneous samples
    took the reference IMU's vibration above their Nyquist frequency (module doc); {} where
    none did, or the IMU's samples are interval means, or no reference IMU samples faster.
    rec.real["aliasing"] says what was checked."""
    if not rec.sampled_at_instants or rec.reference_imu is None:
        return {}
    ref = rec.reference_imu
    rate, ref_rate = mean_rate_hz(rec.imu_ns), mean_rate_hz(ref["ns"])
    if ref_rate < 1.2 * rate:
        rec.real["aliasing"] = (f"not checked: the IMU's instantaneous samples at {rate:.4g} Hz "
                                f"may fold vibration above {rate / 2:.4g} Hz into their band, "
                                f"and the reference IMU ({ref_rate:.4g} Hz) does not see it")
        return {}
    out, said = {}, []
    for sensor, mine, theirs in (("gyro", rec.w, ref["w"]), ("accel", rec.f, ref["f"])):
        slope, folded, own = _folded(mine, rate, theirs, ref_rate)
        words = (f"{NAMES[sensor]}: the reference IMU's power above {rate / 2:.4g} Hz, folded "
                 f"into the IMU's band, {folded / own:.2g} of the IMU's own sample scatter"
                 + (f", found in the IMU's spectrum at {slope:.2f} of its size"
                    if folded > 0.01 * own else ""))
        said.append(words)
        if slope > FOLDED_SLOPE and folded > ALIAS_SHARE * own:
            out[sensor] = (f"the IMU's instantaneous samples at {rate:.4g} Hz fold vibration "
                           f"into their band ({words}): terms on its {NAMES[sensor]} but a constant "
                           "bias may be that vibration at the wrong frequency")
    rec.real["aliasing"] = "checked against the reference IMU: " + "; ".join(said)
    return out


def _folded(mine, rate, theirs, ref_rate):
    """(slope, folded power, own scatter), (unit)^2 and 1: the IMU's power spectrum (Welch,
    summed over its axes - what a turn between the two keeps; its samples unfiltered back
    from `motion.intervals.means_of_instants`, whose (x[k-1] + 22 x[k] + x[k+1]) / 24 passes
    (22 + 2 cos(2 pi f / rate)) / 24) beyond the reference's, regressed on the reference's
    power above the IMU's Nyquist frequency folded onto the frequency each part aliases to,
    |f - rate round(f / rate)| (every fold: a multicopter's 80-120 Hz motor lines fall on
    20 Hz at 50 Hz), with an intercept (the IMU's white noise); the folded power (what a
    slope of 1 would read) and the IMU's sample variance about its 1 s means."""
    f, p_mine = signal.welch(mine, fs=rate, nperseg=min(int(SEGMENT_S * rate), len(mine)),
                             axis=0)
    g, p_ref = signal.welch(theirs, fs=ref_rate, nperseg=min(int(SEGMENT_S * ref_rate),
                                                             len(theirs)), axis=0)
    p_mine = p_mine.sum(axis=1) / ((22.0 + 2.0 * np.cos(2 * np.pi * f / rate)) / 24.0) ** 2
    p_ref = p_ref.sum(axis=1)
    direct = np.interp(f, g, p_ref)
    above = g > rate / 2
    alias = np.abs(g[above] - rate * np.round(g[above] / rate))
    df, dg = float(f[1] - f[0]), float(g[1] - g[0])
    at = np.clip(np.round(alias / df).astype(int), 0, len(f) - 1)
    folded = np.bincount(at, p_ref[above] * dg, minlength=len(f)) / df
    band = (f > 0) & (f < rate / 2)
    x = np.column_stack([folded[band], np.ones(band.sum())])
    slope = float(np.linalg.lstsq(x, (p_mine - direct)[band], rcond=None)[0][0])
    k = max(int(round(rate)), 1)
    smooth = np.column_stack([np.convolve(mine[:, i], np.ones(k) / k, mode="same")
                              for i in range(3)])
    own = float(np.sum(np.var(mine - smooth, axis=0))) if len(mine) > 2 * k else np.inf
    return slope, float(np.sum(folded[band]) * df), own

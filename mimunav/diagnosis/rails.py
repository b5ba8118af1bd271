"""Rails too short to name: an output flat at its extreme, bit for bit, on a few samples
where the reference puts its input beyond - fewer than `outputs.saturation` needs to name a
saturation, yet samples that say nothing of the other terms (`short_rails`)."""
import numpy as np

from . import outputs

RAIL_SAMPLES = 2         # samples at one extreme, bit for bit, with the input beyond it: a
#                          rail (one such sample may be a spike of the reference's)


def short_rails(measured, predicted, rows, sigma, named):
    """(N,) bool: where a channel not among `named` ({(sensor, axis)}: `outputs.saturation`'s
    findings) sits at its extreme bit for bit on RAIL_SAMPLES samples or more while its
    input (the reference's prediction, its offset matched: `outputs.own_offset`) lies
    beyond it by `outputs.saturation`'s margin - a rail too short to name
    (`outputs.SATURATION_MIN_SAMPLES`): the samples whose input comes within 5 sigma of it,
    to be left out of the fit (a Shimmer's low-noise
    accelerometer flat at -24.6145 m/s^2 on 7 samples while its wide-range twin read to
    -57.5 had hidden its cross-coupling and left an excursion). measured, predicted,
    rows, sigma (6,) as `outputs.saturation`'s."""
    out = np.zeros(len(measured[:, 0]), bool)
    if not rows.any():
        return out
    for c, (sensor, axis) in enumerate(outputs.CHANNELS):
        if (sensor, axis) in named:
            continue
        y = measured[:, c]
        x = predicted[:, c] + outputs.own_offset(y, predicted[:, c], rows)
        for sign in (1.0, -1.0):
            top = float(np.max(sign * y[rows]))
            margin = outputs.SATURATION_MARGIN_SIGMA * sigma[c] + 0.01 * abs(top)
            at = rows & (sign * y == top) & (sign * x > top + margin)
            if top > 0 and at.sum() >= RAIL_SAMPLES:
                out |= rows & (sign * x > top - 5 * sigma[c])
    return out

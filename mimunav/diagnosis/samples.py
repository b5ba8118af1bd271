"""The sensor level's per-sample stage: the recorded MIMU through the calibration beside what
the reference IMU says it should have read (`reference.predicted_at`), kept column by column
(`spill.Spill`) - in memory for a flight held whole, in scratch files for one that streams
(`evaluation.flight.Flight.load(stream=True)`), so that a flight of any length is worked in
bounded memory: the tests on the outputs read one column at a time (`sensor`), the design's
bins one block at a time (`design.make_design`).

The columns of `Samples.spill` (one row a MIMU sample, MIMU sensor axes):
    measured     (N, 6) the compensated MIMU: specific force m/s^2, then angular rate rad/s
    predicted    (N, 6) the same predicted from the reference IMU and both mountings
    temperature  (N, 3) the accelerometers' case temperatures, degC (NaN without a raw record)
    frequency    (N, 3) the gyros' resonance frequencies, Hz (NaN without a raw record)
    volts        (N, 6) the raw accelerometer then gyro volts (only with a raw record)
"""
from contextlib import closing
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from ..compensation import effects
from ..compensation.effects import AXES, Conditions, derivative, vibration_power
from ..compensation.log import compensated_blocks
from ..errors import InputError
from ..evaluation.flight import FOG_FIELDS
from ..evaluation.replay import compensated_mimu, stuck_inside_range, warn_stuck
from ..flightlog import FlightLog
from .design import Binning
from .spill import ScratchMatrix, Spill
from .reference import (DERIVATIVE_WINDOW_S, counted_outputs, inside_reference,
                        predicted_lagged, predicted_mimu)


PREDICTION_HALO_S = 1.0     # MIMU samples either side of a streamed block its prediction is
                            # made over and cut from: the lever-arm transfer's derivative
                            # (`reference.TRANSFER_WINDOW_S`) and the running integral's
                            # first interval (`RunningIntegral.means`) reach far less


@dataclass
class Samples:
    """The per-sample stage of a flight (module doc)."""
    t: np.ndarray               # (N,) MIMU stamps, s since the log's epoch
    spill: Spill
    flags: np.ndarray           # (N,) the compensation's flags (`compensation.wild_values`)
    inside: np.ndarray          # (N,) bool: inside the reference IMU's span
    streamed: bool              # read from the log block by block (the spill in files)
    vibration: np.ndarray | None = None     # (N, 3) the MIMU's vibration power, (m/s^2)^2,
                                            # when the caller measured it elsewhere
                                            # (`sensor.diagnose`'s vibration)


def sample_stage(flight, cal, folder=None):
    """`Samples` of `flight` (an `evaluation.Flight` with a reference IMU) through `cal`:
    whole when the flight is held, block by block from its log when it streams (the columns
    then in scratch files in `folder`, which must exist)."""
    t = flight.mimu_t
    if folder is None and flight.stream_block is not None:
        raise ValueError(f"{flight.path} streams: its columns need a scratch folder")
    if flight.stream_block is None:
        spill = Spill()
        w, f, flags = compensated_mimu(flight, cal, per_sample=True)
        f_p, w_p, inside = predicted_mimu(flight)
        temperature, frequency = flight.mimu_temperatures()
        raw = flight.mimu_raw
        _add(spill, f, w, f_p, w_p, temperature, frequency,
             None if raw is None else np.hstack([raw["accel_volts"], raw["gyro_volts"]]))
        return Samples(t, spill, flags, inside, False)
    return _streamed_stage(flight, cal, Spill(folder), inside_reference(flight))


def _add(spill, f, w, f_p, w_p, temperature, frequency, volts):
    spill.append("measured", np.hstack([f, w]))
    spill.append("predicted", np.hstack([f_p, w_p]))
    spill.append("temperature", temperature)
    spill.append("frequency", frequency)
    if volts is not None:
        spill.append("volts", volts)


def _streamed_stage(flight, cal, spill, inside):
    """`sample_stage` of a streamed flight: the reference IMU spilled first (`_reference`),
    then the MIMU compensated block by block (`compensation.log.compensated_blocks`, which
    carries margins across blocks so each sample sees what it would over the whole record)
    and predicted from the reference's samples around the block; progress on stderr."""
    t, fog_t = flight.mimu_t, flight.fog_t
    flags = np.empty(len(t), np.uint8)
    stuck, a = 0, 0
    with FlightLog(flight.path) as log, closing(spill), \
            tqdm(total=len(t), desc="diagnose: samples", unit="sample", unit_scale=True,
                 leave=False, disable=None) as bar:     # a terminal's only (not a log's)
        _reference(log, flight, spill)
        for raw, f, w, block_flags in compensated_blocks(log, cal, flight.stream_block):
            b = a + len(raw)
            if b > len(t):
                a = b                           # more samples than stamps: said below
                break
            lo = int(np.searchsorted(t, t[a] - PREDICTION_HALO_S))
            hi = int(np.searchsorted(t, t[b - 1] + PREDICTION_HALO_S, "right"))
            i0 = max(int(np.searchsorted(fog_t, t[lo] - max(flight.mimu_lag_s), "right"))
                     - 2, 0)                                        # an interval before
            i1 = min(int(np.searchsorted(fog_t, t[hi - 1] - min(flight.mimu_lag_s))) + 2,
                     len(fog_t))                                    # and after
            reference = spill.span("reference", i0, i1)
            f_p, w_p = (x[a - lo:b - lo] for x in predicted_lagged(
                t[lo:hi], fog_t[i0:i1], reference[:, :3], reference[:, 3:], flight))
            _add(spill, f, w, f_p, w_p, raw["accel_temperature"], raw["gyro_frequency"],
                 np.hstack([raw["accel_volts"], raw["gyro_volts"]]))
            flags[a:b] = block_flags
            stuck += stuck_inside_range(flight, w, f, block_flags)
            bar.update(b - a)
            a = b
    if a != len(t):
        raise InputError(f"{flight.path}: /mimu/raw gave {a} samples in blocks and {len(t)} "
                         "stamps: the log changed while it was read")
    warn_stuck(flight, stuck)
    return Samples(t, spill, flags, inside, True)


def _reference(log, flight, spill):
    """The reference IMU's outputs into `spill` as "reference" (M, 6): w rad/s then f m/s^2,
    its sensor axes, through `reference.counted_outputs` - over the whole flight, a column
    at a time (a pulse count stands still for as long as the motion is slow: its runs do
    not end at a block's edge)."""
    count = 0
    for msgs in log.blocks("/fog/imu", flight.stream_block, FOG_FIELDS):
        spill.append("reference", np.hstack([np.asarray(msgs[k], float) for k in FOG_FIELDS]))
        count += len(msgs)
    if count != len(flight.fog_t):
        raise InputError(f"{flight.path}: /fog/imu gave {count} samples in blocks and "
                         f"{len(flight.fog_t)} stamps: the log changed while it was read")
    if flight.source == "simulation":
        for c in range(6):
            spill.put_column("reference", c, counted_outputs(
                flight, flight.fog_t, spill.column("reference", c)[:, None])[:, 0])


# ---- the bins: one block of samples at a time -------------------------------------------
NEAR_HALO_S = 3.0   # samples either side of a block its conditions are made over and cut
# from: the derivatives' windows (`reference.DERIVATIVE_WINDOW_S`, 0.1 s) and the vibration
# power's high-pass and window (`effects.vibration_power`: the 4th-order Butterworth at 10 Hz
# settles at 24 /s, its slowest pole - 1e-31 in 3 s - and the window is 0.5 s)
FAR_EFFECTS = ("temperature_rate", "thermal_hysteresis")     # regressors that reach a window
# of minutes back or seconds ahead: made on the temperatures alone, over as long a halo


@dataclass
class Bins:
    """Bin means over the raw bins (m, start) of `design.bins`, NaN in a bin with an
    unusable sample: t (nb,) s; residual (nb, 6) accel m/s^2 then gyro rad/s; inputs (nb, 6)
    the predicted f m/s^2 then w rad/s; w_dot (nb, 3) rad/s^2; norms (nb, 4) |f| m/s^2, |w|
    rad/s, |dw/dt| rad/s^2 and the mean temperature degC; over every sample of a bin, usable
    or not: centres (nb,) s its mean time, extremes (nb, 4) the largest |f| m/s^2 and |w|
    rad/s, the smallest and the largest mean temperature degC. matrices: per channel c the
    columns [residual, the reference inputs of its triad, every term's regressor on c in the
    terms' order] (`effects.regressor`), made block by block - arrays, or with `binned`'s
    scratch `spill.ScratchMatrix`es; the design's own (`design.make_design`) - where a term's columns equal columns placed before them on the
    whole flight (a scale factor is its channel's input, a cross-coupling another input,
    time_skew accel.all is time_skew imu.all on the accelerometers, a lever arm a size
    effect's on each accelerometer: about a quarter of the columns) held once; slots: per
    channel {term index: (its first column there, its number of columns)}, twins sharing
    theirs."""
    t: np.ndarray
    residual: np.ndarray
    inputs: np.ndarray
    w_dot: np.ndarray
    norms: np.ndarray
    centres: np.ndarray
    extremes: np.ndarray
    matrices: list
    slots: list


def temperature_references(terms, samples, usable):
    """`terms` (copies) with each temperature_bias / temperature_scale term's reference: the
    mean of its axis's temperature (degC) or frequency (Hz) over the usable samples."""
    means, out = {}, []
    for term in terms:
        term = dict(term)
        if term["effect"] in ("temperature_bias", "temperature_scale"):
            key = ("temperature" if term["sensor"] == "accel" else "frequency",
                   "xyz".index(term["axis"]))
            if key not in means:
                means[key] = float(samples.spill.column(*key)[usable].mean())
            term["reference"] = means[key]
        out.append(term)
    return out


def binned(samples, usable, bins, terms, block=None, scratch=False):
    """`Bins` of `samples` (usable (N,) bool; bins (m, start)) with the regressors of
    `terms`, made `block` samples at a time (None: all at once) into arrays of the whole
    flight's bins: no block's bins are held beside them; scratch: the channel matrices in
    scratch files (`spill.ScratchMatrix`), a block's at a time in memory. Blocks show
    progress on stderr."""
    m, start = bins
    n = (len(samples.t) - start) // m * m
    if n < m:
        raise InputError(f"{len(samples.t)} MIMU samples: fewer than one bin of {m}")
    step = n if block is None else max(m, block // m * m)
    far = max([float(term.get("window_s", 0.0)) for term in terms] +
              [effects.HYSTERESIS_SLOPE_WINDOW_S / 2]) + NEAR_HALO_S
    out = twins = None
    for a in tqdm(range(start, start + n, step), desc="diagnose: bins", unit="block",
                  disable=True if block is None else None, leave=False):
        piece = _block_bins(samples, usable, a, min(a + step, start + n), m, terms, far)
        if out is None:
            out, twins = _allocated(piece, n // m, scratch)
        rows = slice((a - start) // m, (a - start) // m + len(piece[0]))
        for k, x in enumerate(piece[:7]):
            getattr(out, BIN_FIELDS[k])[rows] = x
        for c in range(6):
            x = _channel_block(out, twins, c, piece)        # may widen the matrix
            _put(out.matrices[c], rows, x)
    for matrix in out.matrices:
        if isinstance(matrix, ScratchMatrix):
            matrix.close()
    return out


def _channel_block(out, twins, c, piece):
    """(bins, width) channel c's columns of a block `piece` (`_block_bins`): the residual,
    the triad's reference inputs, each term's own columns (a twin's compared with its
    owner's, and parted from it where they differ, `_part`)."""
    x = np.empty((len(piece[0]), out.matrices[c].shape[1]))
    x[:, 0] = piece[1][:, c]
    x[:, 1:4] = _triad(piece[2], c)
    for j, (first, k) in list(out.slots[c].items()):     # an owner before its twins
        columns = piece[7][j][c]
        if j in twins[c] and not np.array_equal(x[:, first:first + k], columns,
                                                equal_nan=True):
            _part(out, twins, c, j)     # twins so far, not in this block: apart
            first = out.slots[c][j][0]
            x = np.hstack([x, np.empty((len(x), k))])
        if j not in twins[c]:
            x[:, first:first + k] = columns
    return x


def _put(matrix, rows, x):
    """Rows `rows` (a slice, in order) of a channel matrix: x."""
    if isinstance(matrix, ScratchMatrix):
        if rows.start != len(matrix):
            raise ValueError(f"bins {rows} written after {len(matrix)}: out of order")
        matrix.append(x)
    else:
        matrix[rows] = x


BIN_FIELDS = ("t", "residual", "inputs", "w_dot", "norms", "centres", "extremes")


def _allocated(piece, nb, scratch=False):
    """(`Bins` of nb bins, unfilled, laid out as the first block's `piece` (`_block_bins`),
    per channel the terms whose columns there are a twin's: equal in this block to columns
    placed before them - the reference inputs or an earlier term's - and given those);
    scratch: the channel matrices `spill.ScratchMatrix`es with no rows yet."""
    fields = [np.empty((nb,) + x.shape[1:]) for x in piece[:7]]
    matrices, slots, twins = [], [], []
    files = ScratchMatrix.scratch() if scratch else None
    for c in range(6):
        placed = dict(enumerate((piece[1][:, c],) + tuple(_triad(piece[2], c).T)))
        slot, twin = {}, set()
        for j, cols in enumerate(piece[7]):
            if c in cols:
                x, k = cols[c], cols[c].shape[1]
                first = _placed_at(placed, x)
                if first is None:
                    first = len(placed)
                    placed.update({first + i: x[:, i] for i in range(k)})
                else:
                    twin.add(j)
                slot[j] = (first, k)
        matrices.append(np.empty((nb, len(placed))) if files is None else
                        ScratchMatrix.empty(*files, f"channel{c}", len(placed)))
        slots.append(slot)
        twins.append(twin)
    return Bins(*fields, matrices, slots), twins


def _triad(inputs, c):
    """(n, 3) the reference inputs (n, 6: f then w) of channel c's triad."""
    return inputs[:, :3] if c < 3 else inputs[:, 3:]


def _placed_at(placed, x):
    """The first of k columns in `placed` {column: its values in the block}, never the
    residual (0), equal to x's k columns (NaN equal to NaN), or None."""
    k = x.shape[1]
    for first in range(1, len(placed) - k + 1):
        if all(np.array_equal(placed[first + i], x[:, i], equal_nan=True) for i in range(k)):
            return first
    return None


def _part(out, twins, c, j):
    """Give term j on channel c columns of its own, its twin's bins so far copied into them
    (the blocks before this one were equal): a matrix one term wider."""
    matrix = out.matrices[c]
    first, k = out.slots[c][j]
    if isinstance(matrix, ScratchMatrix):
        out.matrices[c] = matrix.widened(first, k)
    else:
        wider = np.empty((matrix.shape[0], matrix.shape[1] + k))
        wider[:, :matrix.shape[1]] = matrix
        wider[:, matrix.shape[1]:] = matrix[:, first:first + k]
        out.matrices[c] = wider
    out.slots[c][j] = (matrix.shape[1], k)
    twins[c].discard(j)


def _block_bins(samples, usable, a, b, m, terms, far_s):
    """The `Bins` fields of samples a..b-1 (whole bins of m), as a tuple, the terms'
    columns last: per term {channel: (bins, k)}."""
    t = samples.t
    cond, own = _conditions(samples, a, b, NEAR_HALO_S)
    mean = Binning((m, 0), usable[a:b])
    f, w, w_dot = cond.f[own], cond.w[own], cond.w_dot[own]
    residual = samples.spill.span("measured", a, b) - np.hstack([f, w])
    norm_f, norm_w = np.linalg.norm(f, axis=1), np.linalg.norm(w, axis=1)
    temperature = cond.T[own].mean(axis=1)
    norms = mean(np.column_stack([norm_f, norm_w, np.linalg.norm(w_dot, axis=1), temperature]))
    whole = (b - a) // m, m
    extremes = np.column_stack([norm_f.reshape(whole).max(axis=1),
                                norm_w.reshape(whole).max(axis=1),
                                temperature.reshape(whole).min(axis=1),
                                temperature.reshape(whole).max(axis=1)])
    slow = _conditions(samples, a, b, far_s, temperatures_only=True) \
        if any(term["effect"] in FAR_EFFECTS for term in terms) else None
    columns = []
    for term in terms:
        on, rows = slow if term["effect"] in FAR_EFFECTS else (cond, own)
        columns.append({(0 if sensor == "accel" else 3) + i: mean(x[rows])
                        for (sensor, i), x in effects.regressor(term, on).items()
                        if "channels" not in term or f"{sensor}.{AXES[i]}" in term["channels"]})
    cond.release_shared()
    return (mean(t[a:b]), mean(residual), mean(np.hstack([f, w])), mean(w_dot), norms,
            t[a:b].reshape(whole).mean(axis=1), extremes, columns)


def _conditions(samples, a, b, halo_s, temperatures_only=False):
    """(`effects.Conditions` over samples a..b-1 and halo_s either side, the slice of a..b-1
    in it): the predicted motion, its derivatives (`reference.DERIVATIVE_WINDOW_S`), the
    temperatures and the vibration power (`effects.vibration_power` of the measured specific
    force, unless the caller gave it); temperatures_only: t and the temperatures alone."""
    t = samples.t
    lo = int(np.searchsorted(t, t[a] - halo_s))
    hi = int(np.searchsorted(t, t[b - 1] + halo_s, "right"))
    span = t[lo:hi]
    temperature = np.ascontiguousarray(samples.spill.span("temperature", lo, hi))
    frequency = np.ascontiguousarray(samples.spill.span("frequency", lo, hi))
    own = slice(a - lo, b - lo)
    if temperatures_only:
        return Conditions(span, None, None, None, None, temperature, frequency), own
    predicted = samples.spill.span("predicted", lo, hi)
    f, w = np.ascontiguousarray(predicted[:, :3]), np.ascontiguousarray(predicted[:, 3:])
    vibration = samples.vibration[lo:hi] if samples.vibration is not None else \
        vibration_power(span, np.nan_to_num(samples.spill.span("measured", lo, hi)[:, :3]))
    return Conditions(span, f, w, derivative(span, f, DERIVATIVE_WINDOW_S),
                      derivative(span, w, DERIVATIVE_WINDOW_S), temperature, frequency,
                      vibration), own

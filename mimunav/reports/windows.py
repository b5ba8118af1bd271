"""Free-inertial window results (`mimunav.evaluation.windows`) as a document, a table and plots:
  growth  horizontal position error against time since the restart: every window (thin)
          and the median per length, log scale, one panel per variant;
  cdf     the distribution of the end-point horizontal error per length and variant."""
import math

import numpy as np

from ..evaluation import windows
from ..frames import earth
from ..sensors.mimu import G0
from .plots import figure, save


def document(flight, results, rest, cal_label, time_shift_s):
    """JSON-ready: the summary table, the alignment at rest and every window's end error."""
    track = windows.track_of(flight.truth)
    half = windows.moving_half(track)
    static = [None if np.isnan(x) else x for x in rest.static]
    return {"format": "mimunav-windows/1", "log": flight.path, "calibration": cal_label,
            "time_shift_s": time_shift_s, "doubts": doubts(flight, time_shift_s),
            "reference_jumps": [{"t_s": t_j, "off_m": off}
                                for t_j, off in windows.reference_jumps(flight.truth)],
            "rest": {"t0_s": static[0], "t1_s": static[1], "alignment": rest.method,
                     "gyro_bias_rad_s": rest.gyro_bias.tolist(),
                     "accel_bias_m_s2": rest.accel_bias.tolist()},
            "summary": {f"{length:g}": dict(row, earth_rate_left_m=earth_rate_left(
                            rest, length)) for length, row in
                        windows.summary(results, flight.reference_meta, track,
                                        half).items()},
            "windows": {f"{length:g}": [{"t0_s": w.t0, "end_ned_m": w.error_ned[-1].tolist()}
                                        for w in wins] for length, wins in results.items()},
            "frames": "errors NED m, window navigated minus reference; t0 s since the epoch"}


def doubts(flight, time_shift_s):
    """[why the windows' errors may not be the IMU's], from the recording's metadata: a
    reference trajectory's clock the import left open (`importers.checks`: the data peak
    away from its stamps) - each window then compares the IMU with where the reference was
    a lag away (a ship's MEMS 0.7 s off had its 60 s windows read 695 m, silently; 17 m
    once shifted; not said once a --time-shift is given), or one it measured and left as the
    IMU's latency (`reference_clock_unapplied_s`: a mocap pose 0.2 s late read 58 m where
    0.5 m were the IMU's); an IMU its own forces place
    elsewhere than its lever arm given (the recording's `imu_point_off`); a trajectory
    whose point is measured off the origin (`trajectory_point_off`); a mounting measured off
    the reference's attitude and kept (`mounting_off_kept`: a KAIST-layout drive's 1.00 deg,
    standard error 0.007, had its 10 s windows at 0.49 m, 0.20 m once turned)."""
    said, out = (flight.recording or {}).get("reference_clock_open"), []
    if said and not time_shift_s:
        out.append(f"the import could not decide the reference trajectory's clock against the "
                   f"IMU's ({said}): these errors hold the lag too - where the recording's own "
                   "notes give it, mimunav windows --time-shift S (or mimunav import "
                   "--reference-time-offset S)")
    late = (flight.recording or {}).get("reference_clock_unapplied_s")
    if late and not time_shift_s:   # `importers.checks`: measured, left as the IMU's latency
        out.append(f"the import measured the reference trajectory's stamps "
                   f"{abs(late) * 1e3:.0f} ms {'late' if late > 0 else 'early'} on the IMU's "
                   "and left it as the IMU's latency: these errors hold that lag - where it is "
                   f"the two clocks' offset, mimunav windows --time-shift {late:+.3f} (or "
                   "mimunav import --reference-time-offset) takes it out")
    off = (flight.recording or {}).get("imu_point_off")
    if off:         # `importers.trajectory_point`: the IMU not where its arm says
        out.append(f"{off}: these errors hold that arm's transfer too")
    kept = (flight.recording or {}).get("mounting_off_kept")
    if kept:        # `importers.attitude_check`: measured, within the attitude's own error
        out.append(f"{kept}: these errors hold that turn's")
    off = (flight.recording or {}).get("trajectory_point_off")
    if off:         # `importers.trajectory_point`: measured, not moved by
        out.append(f"{off}: these errors may hold the transfer of an arm from that point")
    return out


def earth_rate_left(rest, length):
    """m: the most a window of `length` s drifts from the Earth rate's horizontal part that
    the rest's gyro bias keeps where its heading was not known (`bias_basis` gyro
    "vertical_earth_rate"): a tilt growing at Omega cos(lat), g Omega cos(lat) length^3 / 6
    (13 m at 60 s on a new user's ideal IMU, charged to it before); Omega where the whole
    Earth rate was left in (no position: "earth_rate_left"); 0 otherwise."""
    basis = (rest.bias_basis or {}).get("gyro")
    if basis not in ("vertical_earth_rate", "earth_rate_left"):
        return 0.0
    left = earth.OMEGA * (abs(math.cos(rest.lat)) if basis == "vertical_earth_rate" else 1.0)
    return G0 * left * length ** 3 / 6


TILT_SAID_DEG = 0.1      # deg: the reference tilt error the floor's note sizes (a tactical
#                          INS holds 0.01-0.05, an autopilot's filter 0.1-1)


JUMPS_SAID = 5          # the reference's jumps named in the note; the JSON holds them all


def markdown_table(doc, label=None):
    head = "| variant | " if label else "| "
    lines = [head + "window s | windows (disjoint) | horizontal error p50 / p68 / p95 / max, m "
             "| vertical p50 / p95, m | median horizontal end error / length, m/s "
             "| reference alone (1 sigma), m |",
             "|" + "---|" * (7 if label else 6)]
    for length, row in doc["summary"].items():
        h, v = row["horizontal_m"], row["vertical_m"]
        floor = row.get("reference_floor", {})
        notes = [f"{k} sigma not stated" for k in floor.get("not_stated", [])] + \
            [f"{k} sigma estimated from the track" for k in floor.get("estimated", [])]
        if floor.get("position_ends_m"):
            notes.append(f"of it {floor['position_ends_m']:.3g} m the stated position sigma at "
                         "both ends, taken independent: a reference whose error drifts slowly "
                         "errs less within a window")
        if floor.get("alignment_tilt_m"):
            notes.append(f"of it {floor['alignment_tilt_m']:.3g} m from the window's alignment "
                         f"on the reference's velocity over +-{floor['alignment_half_s']:g} s "
                         "(its tilt, grown as length^2 / 2)")
        if floor.get("horizontal_m") is not None and not floor.get("alignment_tilt_m"):
            # the start's attitude is the reference's: its error is in every window, unstated
            # no bound of the reference's true error either way: its stated sigmas may be
            # pessimistic (a ship's bag's twist covariance read 0.147 m where its null
            # windows' p50 was 0.135 m)
            notes.append(f"from the stated sigmas, taken as true (a stated sigma may be "
                         f"pessimistic); beside them the reference attitude's own error at "
                         f"each start is not stated and not counted - {TILT_SAID_DEG:g} deg "
                         f"of it adds "
                         f"{G0 * math.radians(TILT_SAID_DEG) * float(length) ** 2 / 2:.2g} m "
                         "(g tilt length^2 / 2; an autopilot's filter can err by more)")
        if row.get("earth_rate_left_m"):
            notes.append(f"and the rest's bias keeps the Earth rate's horizontal part (no "
                         f"heading there): up to {row['earth_rate_left_m']:.3g} m of drift")
        cell = ("not stated" if floor.get("horizontal_m") is None else
                f"{floor['horizontal_m']:.3g}") + (f" ({'; '.join(notes)})" if notes else "")
        lines.append((f"| {label} " if label else "") +
                     f"| {length} | {row['windows']} ({row['disjoint']}) | {h['p50']:.3g} / "
                     f"{h['p68']:.3g} / {h['p95']:.3g} / {h['max']:.3g} | {v['p50']:.3g} / "
                     f"{v['p95']:.3g} | {row['median_rate_m_s']:.3g} | {cell} |")
    lines += [f"\nwarning: {why}" for why in doc.get("doubts", [])]
    jumps = doc.get("reference_jumps", [])
    if jumps:
        said = ", ".join(f"{j['t_s']:.2f} s ({j['off_m']:.3g} m)" for j in jumps[:JUMPS_SAID])
        lines.append(f"\nnote: the reference's position steps off its own velocity at "
                     f"{len(jumps)} epoch{'s' if len(jumps) > 1 else ''} ({said}"
                     f"{', ...' if len(jumps) > JUMPS_SAID else ''}): no window spans one "
                     "(an INS back on its fixes after an outage; a fix's jump)")
    return "\n".join(lines) + "\n"


def plot(variants, png):
    """variants: {label: {length: [Window]}}; growth curves (one panel per variant) and the
    end-error CDFs (last panel)."""
    n = len(variants)
    cols = min(3, n + 1)
    rows = -(-(n + 1) // cols)
    plt, fig, grid = figure(rows, cols, (5.5 * cols, 4.5 * rows))
    axes = grid.reshape(1, -1)
    for ax in axes[0, n + 1:]:
        ax.set_visible(False)
    colors = {}
    for i, (label, results) in enumerate(variants.items()):
        ax = axes[0, i]
        for length, wins in sorted(results.items()):
            color = colors.setdefault(length, f"C{len(colors)}")
            grid = np.linspace(0, length, 61)[1:]
            curves = np.array([np.interp(grid, w.t - w.t0, w.horizontal) for w in wins])
            for c in curves:
                ax.plot(grid, c, color=color, lw=0.3, alpha=0.3)
            ax.plot(grid, np.median(curves, axis=0), color=color, lw=2,
                    label=f"{length:g} s: median of {len(wins)}")
            ends = np.sort([w.horizontal[-1] for w in wins])
            axes[0, n].step(ends, np.arange(1, len(ends) + 1) / len(ends), where="post",
                            color=color, ls=("-", "--", ":", "-.", (0, (6, 1, 1, 1)))[i % 5],
                            label=f"{label + ', ' if label else ''}{length:g} s")
        ax.set_yscale("log")
        ax.set_xlabel("time since restart, s")
        ax.set_ylabel("horizontal position error, m")
        ax.set_title(label or "free-inertial windows")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3, which="both")
    cdf = axes[0, n]
    cdf.set_xscale("log")
    cdf.set_xlabel("end-point horizontal error, m")
    cdf.set_ylabel("fraction of windows")
    cdf.set_title("distribution of the end-point error")
    cdf.legend(fontsize=7)
    cdf.grid(alpha=0.3, which="both")
    save(plt, fig, png)

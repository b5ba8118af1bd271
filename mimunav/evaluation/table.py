"""The normalised end-point table of seed S1 (its Table 3: east, north, up position
errors of the MIMU divided by the FOG-IMU's) for any number of calibration variants, and the
error budget: the end error with each group of a calibration's terms switched off.
"""
import math

import numpy as np

from ..compensation.calibration_file import Calibration
from ..errors import InputError
from .replay import comparison_times, navigate_fog, ned_to_enu, replay, resample


def normalised_table(flight, cals, end=None, check=False):
    """The normalised end-point table for calibration variants {name: Calibration}
    (check: warn about a variant far off in quiet flight, `check_compensation`).
    Returns a dict (JSON-ready): end time, reference, FOG row, one row per variant with
    east/north/up errors (m), their ratio to the FOG's (when a truth exists), horizontal and
    3-D norms."""
    t_end = comparison_times(flight, end)[-1:]
    fog = navigate_fog(flight, at=t_end)
    has_truth = flight.truth is not None
    ref = resample(flight.truth if has_truth else fog, t_end)
    rows = {}
    for name, cal in cals.items():
        rep = replay(flight, cal, fog=fog, check=f"calibration {name!r}" if check else None,
                     at=t_end)
        enu = ned_to_enu(resample(rep.mimu, t_end).position_error(ref)[-1])
        rows[name] = {"enu_m": enu.tolist(), "horizontal_m": float(np.hypot(enu[0], enu[1])),
                      "norm_m": float(np.linalg.norm(enu)), "flags": rep.flags}
    fog_enu = ned_to_enu(resample(fog, t_end).position_error(ref)[-1]) if has_truth else None
    doc = {"format": "mimunav-table/1", "log": flight.path, "flight": flight.name,
           "end_t_s": float(t_end[0]), "duration_s": float(t_end[0] - flight.initial.t),
           "reference": "truth" if has_truth else "fog", "variants": rows}
    if has_truth:
        doc["fog"] = {"enu_m": fog_enu.tolist(), "horizontal_m": float(np.hypot(*fog_enu[:2])),
                      "norm_m": float(np.linalg.norm(fog_enu))}
        for row in rows.values():
            row["normalised_enu"] = (np.abs(row["enu_m"]) / np.abs(fog_enu)).tolist()
    return doc


def table_markdown(doc, paper=None):
    """The table as markdown (paper: optional {variant: [e, n, u]} of the published row)."""
    lines = [f"End point t = {doc['end_t_s']:.2f} s ({doc['duration_s']:.2f} s after the "
             f"initial state), flight `{doc['flight']}`.", ""]
    if doc["reference"] == "truth":
        lines += ["| variant | east / FOG | north / FOG | up / FOG | east m | north m | up m "
                  "| horizontal m | 3-D m |", "|---|---|---|---|---|---|---|---|---|"]
        for name, row in doc["variants"].items():
            ne, e = row["normalised_enu"], row["enu_m"]
            lines.append(f"| {name} | {ne[0]:.3g} | {ne[1]:.3g} | {ne[2]:.3g} | {e[0]:+.3g} | "
                         f"{e[1]:+.3g} | {e[2]:+.3g} | {row['horizontal_m']:.3g} | "
                         f"{row['norm_m']:.3g} |")
        fog = doc["fog"]
        e = fog["enu_m"]
        lines.append(f"| FOG-IMU | 1 | 1 | 1 | {e[0]:+.3g} | {e[1]:+.3g} | {e[2]:+.3g} | "
                     f"{fog['horizontal_m']:.3g} | {fog['norm_m']:.3g} |")
    else:
        lines += ["No `/truth/state` in this log: the FOG-IMU's solution is the reference, so "
                  "the table gives MIMU-vs-FOG differences (no normalisation is possible).", "",
                  "| variant | east m | north m | up m | horizontal m | 3-D m |",
                  "|---|---|---|---|---|---|"]
        for name, row in doc["variants"].items():
            e = row["enu_m"]
            lines.append(f"| {name} | {e[0]:+.3g} | {e[1]:+.3g} | {e[2]:+.3g} | "
                         f"{row['horizontal_m']:.3g} | {row['norm_m']:.3g} |")
    return "\n".join(lines) + "\n"


def table_csv(doc):
    head = "variant,east_m,north_m,up_m,horizontal_m,norm_m,east_norm,north_norm,up_norm\n"
    rows = []
    for name, row in doc["variants"].items():
        ne = row.get("normalised_enu", [math.nan] * 3)
        rows.append(",".join([name] + [f"{x:.6g}" for x in row["enu_m"]] +
                             [f"{row['horizontal_m']:.6g}", f"{row['norm_m']:.6g}"] +
                             [f"{x:.6g}" for x in ne]))
    if "fog" in doc:
        fog = doc["fog"]
        rows.append(",".join(["FOG-IMU"] + [f"{x:.6g}" for x in fog["enu_m"]] +
                             [f"{fog['horizontal_m']:.6g}", f"{fog['norm_m']:.6g}", "1", "1", "1"]))
    return head + "\n".join(rows) + "\n"


BUDGET_GROUPS = ("temperature", "nonlinear scale factor", "g-sensitivity", "cross-coupling")


def without(cal, group, flight):
    """`cal` with one group of terms switched off: temperature (eqs. 2, 4 frozen at the
    flight's first readings), nonlinear scale factor (A2, A3, W2, W3), g-sensitivity (C),
    cross-coupling (off-diagonals of A1 and W1)."""
    if group == "temperature":
        r = flight.mimu_raw
        return cal.frozen_at(r["accel_temperature"][0], r["gyro_frequency"][0])
    if group == "nonlinear scale factor":
        return cal.without(("A2", "A3", "W2", "W3"))
    if group == "g-sensitivity":
        return cal.without(("C",))
    if group == "cross-coupling":
        out = Calibration.from_dict(cal.as_dict())
        for key in ("A1", "W1"):
            m = getattr(out, key)
            m[~np.eye(3, dtype=bool)] = 0.0
        return out
    raise InputError(f"unknown term group {group!r}; one of {', '.join(BUDGET_GROUPS)}")


def error_budget(flight, cal, end=None):
    """What each group of `cal`'s terms is worth on this flight: the end-point errors with
    the group switched off, against the full calibration. Returns a JSON-ready dict."""
    variants = {"full": cal} | {f"without {g}": without(cal, g, flight) for g in BUDGET_GROUPS}
    doc = normalised_table(flight, variants, end)
    base = doc["variants"]["full"]["norm_m"]
    for name, row in doc["variants"].items():
        row["worth_m"] = row["norm_m"] - base
    return doc


def budget_markdown(doc, base="full", what="east/north/up:", worth="group worth (3-D, m)"):
    """A budget (`error_budget`, `traditional.traditional_budget`) as a table: each row's
    end error and its group's worth against the row `base`."""
    against = ("the truth (/truth/state)" if doc.get("reference", "truth") == "truth" else
               "the FOG-IMU's own solution (no /truth/state in this log)")
    lines = [f"End-point error of the MIMU at t = {doc['end_t_s']:.2f} s against {against}, "
             f"{what}", "",
             f"| calibration | east m | north m | up m | 3-D m | {worth} |",
             "|---|---|---|---|---|---|"]
    for name, row in doc["variants"].items():
        e = row["enu_m"]
        cell = "-" if name == base else f"{row['worth_m']:+.3g}"
        lines.append(f"| {name} | {e[0]:+.3g} | {e[1]:+.3g} | {e[2]:+.3g} | "
                     f"{row['norm_m']:.3g} | {cell} |")
    return "\n".join(lines) + "\n"

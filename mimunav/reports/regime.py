"""The regime map of seed S1's Table 3 (`mimunav reproduce --regime-map`): the normalised
east/north/up and horizontal end errors of the traditional and entire calibrations as the
MIMU's random-error grade, the reference FOG-IMU's grade, the flight's g exposure and the
day's temperature move away from the defaults, one at a time; each point a small Monte
Carlo (`campaign`) with its 5-95 % band. From the map, not from tuning, the report says
where the paper's claim ("about one order of magnitude better, close to the FOG-IMU") holds
and which of the map's points are consistent with the paper's numbers.

Each point's units stream to OUT/regime/POINT.jsonl, so an interrupted map resumes; points
run on local processes or a Dask cluster (`--scheduler`).
"""
import dataclasses
import json
from pathlib import Path

import numpy as np

from ..evaluation import campaign
from ..files import write_atomic
from .plots import figure, save
from .table3 import PAPER, assumptions_markdown

# The levels swept per option (the default scenario's value is always among them).
LEVELS = {"mimu_grade": ("table1", "tactical", "stim300"),
          "fog_grade": ("table4-bound", "table4", "navigation"),
          "severity": (0.25, 0.5, 1.0),
          "ground_temperature_c": (-40.0, 15.0, 45.0),
          "warm_up_s": (0.0, 600.0, 3600.0)}
LABELS = {"mimu_grade": "MIMU random-error grade", "fog_grade": "FOG-IMU grade",
          "severity": "flight severity (g exposure x)",
          "ground_temperature_c": "ground air temperature, degC",
          "warm_up_s": "MIMU warm-up before take-off, s"}
AXES = ("east", "north", "up", "horizontal")
CLOSE_TO_FOG = 3.0          # "close to the FOG-IMU": horizontal error within 3x the FOG's
ORDER_OF_MAGNITUDE = 5.0    # "about one order of magnitude": traditional/entire >= 5


def points(base):
    """(option, level, Scenario) for the base scenario and each one-at-a-time change."""
    out = [(None, None, base)]
    for key, levels in LEVELS.items():
        for level in levels:
            if level != getattr(base, key):
                out.append((key, level, dataclasses.replace(base, **{key: level})))
    return out


def normalised(records, variant):
    """(n, 4) |MIMU| / |FOG| per unit: east, north, up and horizontal end errors."""
    mimu = np.array([r["variants"][variant]["enu_m"] for r in records], dtype=float)
    fog = np.array([r["fog"]["enu_m"] for r in records], dtype=float)
    ratio = np.abs(mimu) / np.abs(fog)
    horizontal = np.hypot(mimu[:, 0], mimu[:, 1]) / np.hypot(fog[:, 0], fog[:, 1])
    return np.column_stack([ratio, horizontal])


def point_summary(records):
    """Per variant: median, 5 % and 95 % of the four normalised errors, and the paper's
    consistency (its east/north/up inside the 5-95 % band)."""
    out = {}
    for variant in campaign.VARIANTS:
        x = normalised(records, variant)
        p05, med, p95 = np.percentile(x, [5, 50, 95], axis=0)
        out[variant] = {"median": med.tolist(), "p05": p05.tolist(), "p95": p95.tolist(),
                        "paper_inside": [bool(p05[j] <= PAPER[variant][j] <= p95[j])
                                         for j in range(3)]}
    trad, ent = (normalised(records, v)[:, 3] for v in ("traditional", "entire"))
    out["improvement_horizontal"] = float(np.median(trad / ent))
    return out


def regime_map(out_dir="reports", seed=1, units=16, workers=2, scheduler=None, base=None,
               progress=True):
    """Run (or resume) the map; writes OUT/regime.md, regime.json, regime.png."""
    base = base or campaign.Scenario()
    out_dir = Path(out_dir)
    folder = out_dir / "regime"
    folder.mkdir(parents=True, exist_ok=True)
    rows = []

    def run(key, level, scenario, name):
        if progress:
            print(f"regime point {name}", flush=True)
        records = campaign.run_campaign(scenario, units, seed, str(folder / f"{name}.jsonl"),
                                        workers=workers, scheduler=scheduler,
                                        progress=progress)
        rows.append({"option": key, "level": level, "name": name, "units": len(records),
                     "scenario": scenario.identity(), **point_summary(records)})
    for key, level, scenario in points(base):
        run(key, level, scenario, "base" if key is None else f"{key}={level}")
    corner = favourable_corner(rows, base)
    if corner not in [p[2] for p in points(base)]:
        run("corner", None, corner, "favourable corner")
    plot(rows, base, str(out_dir / "regime.png"))
    write_atomic(out_dir / "regime.json", json.dumps({"seed": seed, "units_per_point": units,
                                                      "points": rows}, indent=1) + "\n",
                 force=True)
    md = out_dir / "regime.md"
    write_atomic(md, markdown(rows, base, seed, units), force=True)
    return md


def favourable_corner(rows, base):
    """The base with every option at the level of its sweep whose entire calibration gave
    the smallest horizontal normalised error (median): the map's own most favourable
    combination, not chosen to match anything."""
    best = {key: min(_sweep(rows, key, base), key=lambda lr: lr[1]["entire"]["median"][3])[0]
            for key in LEVELS}
    return dataclasses.replace(base, **best)


def _sweep(rows, key, base):
    """The rows of one option's sweep in level order, the base row at the base's level."""
    by_level = {r["level"]: r for r in rows if r["option"] == key}
    by_level.pop(None, None)
    by_level[getattr(base, key)] = rows[0]
    return [(level, by_level[level]) for level in LEVELS[key]]


def plot(rows, base, out_png):
    plt, fig, axes = figure(2, len(LEVELS), (4 * len(LEVELS), 7.5))
    colours = dict(zip(AXES, ("C0", "C1", "C2", "k")))
    for col, key in enumerate(LEVELS):
        sweep = _sweep(rows, key, base)
        x = np.arange(len(sweep))
        for row, variant in enumerate(campaign.VARIANTS):
            ax = axes[row, col]
            for j, axis in enumerate(AXES):
                med = np.array([r[variant]["median"][j] for _, r in sweep])
                lo = np.array([r[variant]["p05"][j] for _, r in sweep])
                hi = np.array([r[variant]["p95"][j] for _, r in sweep])
                ax.errorbar(x + 0.06 * (j - 1.5), med, yerr=[med - lo, hi - med], marker="o",
                            capsize=3, color=colours[axis], label=axis)
                if j < 3:
                    ax.axhline(PAPER[variant][j], color=colours[axis], ls=":", lw=1)
            ax.axhline(1.0, color="grey", lw=0.8)
            ax.set_yscale("log")
            ax.set_xticks(x, [str(level) for level, _ in sweep])
            ax.set_xlabel(LABELS[key])
            ax.set_title(f"{variant}")
            ax.grid(True, which="both", alpha=0.3)
            if col == 0:
                ax.set_ylabel("|MIMU| / |FOG| end error (median, 5-95 %)")
    axes[0, 0].legend(fontsize=8, title="dotted: paper", title_fontsize=8)
    save(plt, fig, out_png)


def _cell(s, j):
    return f"{s['median'][j]:.3g} [{s['p05'][j]:.3g}, {s['p95'][j]:.3g}]"


def markdown(rows, base, seed, units):
    lines = ["# Regime map of seed S1 Table 3", "",
             f"Generated by `mimunav reproduce --regime-map --seed {seed} --units {units}`: "
             f"{len(rows)} points, each a Monte Carlo over {units} units (medians and 5-95 % "
             "bands of |MIMU| / |FOG| end error per axis; horizontal = |(E, N)| ratio). "
             "One option at a time moves away from the base scenario:", "",
             *assumptions_markdown(base), "",
             "Levels: " + "; ".join(f"`{k}` {', '.join(str(v) for v in LEVELS[k])}"
                                    for k in LEVELS) + ".", "",
             "![regime map](regime.png)", "",
             "| point | variant | east | north | up | horizontal | paper inside (E N U) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        for variant in campaign.VARIANTS:
            s = r[variant]
            inside = " ".join("yes" if ok else "no" for ok in s["paper_inside"])
            lines.append(f"| {r['name']} | {variant} | " + " | ".join(_cell(s, j)
                                                                      for j in range(4))
                         + f" | {inside} |")
    corner = [r for r in rows if r["option"] == "corner"]
    if corner:
        levels = ", ".join(f"`{k}` {corner[0]['scenario'][k]}" for k in LEVELS)
        lines += ["", f"The `favourable corner` combines, per option, the level of its sweep "
                  f"with the smallest entire horizontal error: {levels}."]
    lines += ["", "## What the map says", "", *findings(rows),
              "- Why the traditional row stays far from the paper's at every point: the "
              "traditional method fits no g-sensitivity, temperature or nonlinear terms, and "
              "the unit drawn from seed S1 Table 2 has a g-sensitivity of 0.01-0.04 (deg/s)/g "
              "that acts at 1 g through the whole flight (40-140 deg/h on every gyro) - the "
              "largest group of the error budget in `table3.md`. The paper's traditional row "
              "implies a unit whose uncompensated g-sensitivity was far below Table 2's range, "
              "or a calibration that removed it; none of the options swept here reaches it.",
              ""]
    return "\n".join(lines)


def findings(rows):
    """Sentences drawn from the rows, by fixed criteria stated in them."""
    out = []
    holds = [r for r in rows if r["improvement_horizontal"] >= ORDER_OF_MAGNITUDE
             and r["entire"]["median"][3] <= CLOSE_TO_FOG]
    out.append(f"- The paper's claim, read as: entire at least {ORDER_OF_MAGNITUDE:g}x better "
               f"than traditional and within {CLOSE_TO_FOG:g}x of the FOG-IMU in horizontal "
               "error (medians), holds at: "
               + (", ".join(f"`{r['name']}` ({r['improvement_horizontal']:.3g}x, "
                            f"{r['entire']['median'][3]:.3g} x FOG)" for r in holds)
                  or "no point of this map") + ".")
    better = [r for r in rows if r["improvement_horizontal"] >= ORDER_OF_MAGNITUDE]
    out.append("- Entire at least " f"{ORDER_OF_MAGNITUDE:g}x better than traditional "
               "(horizontal, median) at: "
               + (", ".join(f"`{r['name']}`" for r in better) or "no point") + "; the "
               "improvement ranges " f"{min(r['improvement_horizontal'] for r in rows):.3g}-"
               f"{max(r['improvement_horizontal'] for r in rows):.3g}x over the map.")
    for variant in campaign.VARIANTS:
        top = max(sum(r[variant]["paper_inside"]) for r in rows)
        best = [r for r in rows if sum(r[variant]["paper_inside"]) == top]
        lowest = min(rows, key=lambda r: r[variant]["median"][3])
        out.append(f"- The paper's {variant} row ({' / '.join(str(x) for x in PAPER[variant])})"
                   + (f" lies inside the 5-95 % band in {top} of 3 axes at best, at: "
                      + ", ".join(f"`{r['name']}`" for r in best) if top else
                      " lies outside the 5-95 % band in every axis at every point")
                   + f"; the lowest {variant} horizontal median is "
                   f"{lowest[variant]['median'][3]:.3g} x FOG (`{lowest['name']}`).")
    return out

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
import hashlib
import json
from pathlib import Path

import numpy as np

from .. import FLIGHTS
from ..evaluation import campaign
from ..files import write_atomic
from .plots import figure, save
from .table3 import (CLOSE_TO_FOG, ORDER_OF_MAGNITUDE, PAPER, assumptions_markdown, normalised,
                     paper_probabilities)

# The levels swept per option (the default scenario's value is always among them).
LEVELS = {"mimu_grade": ("table1", "tactical", "stim300"),
          "fog_grade": ("table4-bound", "table4", "navigation"),
          "severity": (0.25, 0.5, 1.0),
          "ground_temperature_c": (-40.0, 15.0, 45.0),
          # 10 s: powered just long enough for the pre-flight gyro zero (the cold start)
          "warm_up_s": (10.0, 600.0, 3600.0),
          "gyro_zero": ("pre-flight", "lab"),
          "g_sensitivity": (0.0, 1.0, 3.0),
          # the base flight ended after 30 and 60 s of its 144 (0: at its end); the start
          # points' profiles run 363 and 500 s
          "duration_s": (30.0, 60.0, 0.0)}
LABELS = {"mimu_grade": "MIMU random-error grade", "fog_grade": "FOG-IMU grade",
          "severity": "flight severity (g exposure x)",
          "ground_temperature_c": "ground air temperature, degC",
          "warm_up_s": "MIMU warm-up before take-off, s",
          "gyro_zero": "traditional calibration's gyro zero",
          "g_sensitivity": "gyro g-sensitivity C x (drawn from Table 2)",
          "duration_s": "end point after, s (0: the flight's end)"}
AXES = ("east", "north", "up", "horizontal")
# The start, on the shipped profiles that begin at rest (the base flight starts in the air, so
# a ground start is no one-at-a-time change of it): each flown from the exact state and from
# the FOG-IMU's gyrocompass on the pad (`evaluation.ground`)
START_FLIGHTS = ("boost-coast.toml", "ground-gentle.toml")


def points(base):
    """(option, level, Scenario) for the base scenario and each one-at-a-time change."""
    out = [(None, None, base)]
    for key, levels in LEVELS.items():
        for level in levels:
            if level != getattr(base, key):
                out.append((key, level, dataclasses.replace(base, **{key: level})))
    return out


def point_summary(records):
    """Per variant: median, 5 % and 95 % of the four normalised errors; the paper's numbers
    and words as probabilities over the units (`table3.paper_probabilities`); the median
    horizontal improvement of entire over traditional."""
    out = {}
    for variant in campaign.VARIANTS:
        x = normalised(records, variant)
        p05, med, p95 = np.percentile(x, [5, 50, 95], axis=0)
        out[variant] = {"median": med.tolist(), "p05": p05.tolist(), "p95": p95.tolist()}
    trad, ent = (normalised(records, v)[:, 3] for v in ("traditional", "entire"))
    out["improvement_horizontal"] = float(np.median(trad / ent))
    out["paper"] = paper_probabilities(records)
    return out


def regime_map(out_dir="reports", seed=1, units=16, workers=2, scheduler=None, base=None,
               progress=True):
    """Run (or resume) the map; writes OUT/regime.md, regime.json, regime.png."""
    base = base or campaign.Scenario()
    out_dir = Path(out_dir)
    folder = out_dir / "regime"
    folder.mkdir(parents=True, exist_ok=True)
    rows = []

    def run(key, level, scenario, name, file=None):
        if progress:
            print(f"regime point {name}", flush=True)
        records = campaign.run_campaign(scenario, units, seed,
                                        str(folder / f"{file or name}.jsonl"),
                                        workers=workers, scheduler=scheduler,
                                        progress=progress)
        rows.append({"option": key, "level": level, "name": name, "units": len(records),
                     "scenario": scenario.identity(), **point_summary(records)})
    for key, level, scenario in points(base):
        run(key, level, scenario, "base" if key is None else f"{key}={level}")
    for flight in START_FLIGHTS:
        for start in campaign.STARTS:
            run("start", start, dataclasses.replace(base, flight=str(FLIGHTS / flight),
                                                    start=start),
                f"flight={Path(flight).stem}, start={start}")
    corner = favourable_corner(rows, base)
    if corner not in [p[2] for p in points(base)]:
        # its file named by its scenario: the corner moves when a sweep's best level does
        # (a new option's, a new run's), and a file of another corner is no resume of it
        digest = hashlib.sha256(json.dumps(corner.identity(), sort_keys=True).encode())
        run("corner", None, corner, "favourable corner",
            f"favourable corner {digest.hexdigest()[:12]}")
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
             "| point | variant | east | north | up | horizontal | units at or below the "
             "paper (E N U) |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        for variant in campaign.VARIANTS:
            s = r[variant]
            below = " ".join(f"{p['k']}/{p['n']}" for p in r["paper"][variant])
            lines.append(f"| {r['name']} | {variant} | " + " | ".join(_cell(s, j)
                                                                      for j in range(4))
                         + f" | {below} |")
    corner = [r for r in rows if r["option"] == "corner"]
    if corner:
        levels = ", ".join(f"`{k}` {corner[0]['scenario'][k]}" for k in LEVELS)
        lines += ["", f"The `favourable corner` combines, per option, the level of its sweep "
                  f"with the smallest entire horizontal error: {levels}."]
    lines += ["", "## What the map says", "", *findings(rows), *movers(rows, base),
              *start_effect(rows), *rows_reached(rows), ""]
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
        share = {r["name"]: np.mean([p["rate"] for p in r["paper"][variant]]) for r in rows}
        best = max(rows, key=lambda r: share[r["name"]])
        lowest = min(rows, key=lambda r: r[variant]["median"][3])
        out.append(f"- The paper's {variant} row ({' / '.join(str(x) for x in PAPER[variant])}):"
                   f" the most units at or below it at `{best['name']}` ("
                   + ", ".join(f"{axis} {p['rate']:.2f} [{p['ci95'][0]:.2f}, {p['ci95'][1]:.2f}]"
                               for axis, p in zip(("east", "north", "up"),
                                                  best["paper"][variant]))
                   + f"); the lowest {variant} horizontal median is "
                   f"{lowest[variant]['median'][3]:.3g} x FOG (`{lowest['name']}`).")
    words = max(rows, key=lambda r: r["paper"]["both_words"]["rate"])
    both = words["paper"]["both_words"]
    out.append(f"- The paper's words per unit (entire >= {ORDER_OF_MAGNITUDE:g}x better than "
               f"traditional and within {CLOSE_TO_FOG:g}x of the FOG, horizontal, both at "
               f"once) are borne out most often at `{words['name']}`: {both['k']}/{both['n']} "
               f"units [{both['ci95'][0]:.2f}, {both['ci95'][1]:.2f}].")
    out.append(f"- The points named 'most' above are the best of {len(rows)}: their intervals "
               "are each point's own, not a test of the choice (the best of many points lies "
               "high by chance).")
    return out


REACHED = 0.5      # a paper's row is reached where half the units or more are at or below it


def rows_reached(rows):
    """Where each of the paper's rows is reached - at least REACHED of the units at or below
    it in both horizontal axes - and how those points differ from the base scenario (the
    options and their sources in the table above say which the seed states), or that no
    point reaches it."""
    base = next(r for r in rows if r["option"] is None)["scenario"]
    out = []
    for variant in campaign.VARIANTS:
        reached = [r for r in rows if all(p["rate"] >= REACHED
                                          for p in r["paper"][variant][:2])]
        where = "; ".join(
            f"`{r['name']}` (away from the base in " + ", ".join(
                f"{k} {v}" for k, v in r["scenario"].items()
                if v != base.get(k) and not k.endswith("sha256")) + ")"
            for r in reached)
        out.append(f"- The paper's {variant} row is reached (at least {REACHED:.0%} of the "
                   "units at or below it in east and north) at: " + (where or "no point of "
                   "this map") + ".")
    return out


def start_effect(rows):
    """What the ground start does on each flight that begins at rest: each variant's
    horizontal median from the exact state and from the FOG-IMU's alignment."""
    out = []
    for flight in START_FLIGHTS:
        pair = {r["level"]: r for r in rows if r["option"] == "start"
                and r["name"].startswith(f"flight={Path(flight).stem},")}
        if set(pair) != set(campaign.STARTS):
            continue
        out.append(f"- `{Path(flight).stem}` from the exact state -> from the FOG-IMU's "
                   "gyrocompass on the pad (horizontal median, x FOG): " + ", ".join(
                       f"{v} {pair['air'][v]['median'][3]:.3g} -> "
                       f"{pair['ground'][v]['median'][3]:.3g}" for v in campaign.VARIANTS)
                   + "; the alignment's error is common to both IMUs, so it moves the FOG's "
                   "end error most where the flight is fast and long.")
    return out


def movers(rows, base):
    """Which option moves each variant's horizontal median most over its sweep (the ratio
    of its largest to its smallest level's median): read from the map, not assumed."""
    out = []
    for variant in campaign.VARIANTS:
        spread = {key: [r[variant]["median"][3] for _, r in _sweep(rows, key, base)]
                  for key in LEVELS}
        ranked = sorted(spread, key=lambda k: max(spread[k]) / min(spread[k]), reverse=True)
        out.append(f"- What moves the {variant} row (horizontal median, largest / smallest "
                   "over a sweep): " + ", ".join(
                       f"`{k}` {max(spread[k]) / min(spread[k]):.3g}x" for k in ranked[:3])
                   + ".")
    return out

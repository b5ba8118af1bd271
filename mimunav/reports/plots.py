"""Figures a person would rather look at than tables: navigation errors against time,
distributions of a campaign. Written with matplotlib (Agg) atomically."""
import os
import threading

import numpy as np

from ..evaluation import ned_to_enu


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def preload():
    """Import matplotlib's pyplot (0.5-0.8 s) on a background thread, for a command that
    will plot after reading and navigating a log: that work runs mostly outside the
    interpreter (zstd, numpy, numba), so the import costs it little; `figure` then finds
    pyplot imported (or waits on the import lock for the rest)."""
    threading.Thread(target=_pyplot, daemon=True).start()


def figure(rows, cols, size):
    plt = _pyplot()
    return plt, *plt.subplots(rows, cols, figsize=size, squeeze=False)


def save(plt, fig, png, margins=None):
    """Write the figure to png atomically; margins: fixed `subplots_adjust` fractions for a
    grid whose labels are known (one drawing), else tight_layout (a drawing to measure the
    labels, then the one saved)."""
    tmp = png + ".tmp.png"
    if margins:
        fig.subplots_adjust(**margins)
    else:
        fig.tight_layout()
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    os.replace(tmp, png)


def navigation_errors(series, png, title=""):
    """series: {label: errors dict of `evaluation.errors` entries (position NED m, velocity
    NED m/s, attitude rad) with "t"}. East/north/up position and velocity errors and the
    attitude error (deg) against time, one line style per label."""
    plt, fig, axes = figure(3, 3, (14, 9))
    comps = ("east", "north", "up")
    for label, err in series.items():
        step = max(1, len(err["t"]) // 1500)          # a screen's worth of points per line
        t = err["t"][::step] - err["t"][0]
        pos, vel = ned_to_enu(err["position"][::step]), ned_to_enu(err["velocity"][::step])
        att = np.degrees(ned_to_enu(err["attitude"][::step]))
        for j in range(3):
            axes[0, j].plot(t, pos[:, j], label=label)
            axes[1, j].plot(t, vel[:, j], label=label)
            axes[2, j].plot(t, att[:, j], label=label)
    for j, comp in enumerate(comps):
        axes[0, j].set_ylabel(f"{comp} position error, m")
        axes[1, j].set_ylabel(f"{comp} velocity error, m/s")
        axes[2, j].set_ylabel(f"attitude error about {comp}, deg")
        axes[2, j].set_xlabel("time since the initial state, s")
    from matplotlib.ticker import FuncFormatter
    for row, linthresh in zip(axes, (1.0, 0.01, 0.01)):   # m, m/s, deg: errors span decades
        for ax in row:
            ax.set_yscale("symlog", linthresh=linthresh)
            # ticks as plain text (10000, -0.01): symlog's default 10^k in mathtext costs
            # 0.2-0.3 s of layout per figure
            ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
            ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(title)
    # room for a symlog tick label (-100000) and a two-word label on the left of each column
    save(plt, fig, png, margins=dict(left=0.07, right=0.99, bottom=0.06, top=0.95,
                                     wspace=0.3, hspace=0.2))


def campaign_distributions(results, variants, png):
    """Box plots of the normalised east/north/up end errors per variant (log scale)."""
    plt, fig, axes = figure(1, 3, (14, 4.5))
    for j, comp in enumerate(("east", "north", "up")):
        data = [[r["variants"][v]["normalised_enu"][j] for r in results] for v in variants]
        axes[0, j].boxplot(data, whis=(5, 95), showfliers=True)
        axes[0, j].set_xticks(range(1, len(variants) + 1), variants)
        axes[0, j].set_yscale("log")
        axes[0, j].axhline(1.0, color="k", ls="--", lw=0.8)
        axes[0, j].set_title(f"{comp} end error / FOG-IMU's ({len(results)} units)")
        axes[0, j].grid(True, which="both", alpha=0.3)
    save(plt, fig, png)

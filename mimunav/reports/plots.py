"""Figures a person would rather look at than tables: navigation errors against time,
distributions of a campaign. Written with matplotlib (Agg) atomically."""
import os
import signal
import sys
import threading
import traceback

import numpy as np

from ..evaluation.replay import ned_to_enu


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


class Painter:
    """Figures drawn by a child process, for a command that plots after reading and
    navigating a log: the child is forked before the command's work, imports matplotlib
    (0.5-0.8 s of interpreter time) beside the parent's reading instead of inside it, and
    draws what `draw` sends while the parent writes its other outputs. With fork=False, on
    a system other than Linux (fork beside macOS's frameworks is unsafe), or with other
    threads alive, figures are drawn in this process.

    A context manager, entered again around the output folder (`with atomic_folder(...),
    painter:`): leaving it waits for every figure (a figure's OSError raised as itself,
    anything else as RuntimeError with the child's traceback) before the folder commits, or
    on the way out of an error stops the child at once (SIGTERM), before the folder is
    removed. The child's replies are read only then: meant for a few figures, not many
    failing ones. `process`: the child (multiprocessing.Process), None when drawing here."""

    def __init__(self, fork=True):
        import multiprocessing
        self._conn, self.process, self._sent = None, None, 0
        self._stopped, self._lost = False, None       # stopped by us; a send that failed
        if fork and sys.platform.startswith("linux") and threading.active_count() == 1:
            context = multiprocessing.get_context("fork")
            self._conn, end = context.Pipe()
            self.process = context.Process(target=_paint, args=(end, self._conn),
                                           daemon=True)
            self.process.start()
            end.close()

    def draw(self, function, *args):
        """function(*args) (a module-level figure function writing its png) drawn by the
        child, or here without one; the arguments travel pickled: keep them small."""
        if self.process is None:
            function(*args)
            return
        try:
            self._conn.send((function, args))
            self._sent += 1
        except OSError as err:          # the child is gone: `wait` says so (not stdout's pipe)
            self._lost = err

    def wait(self):
        """Block until every figure sent is drawn and end the child; raise a figure's
        failure (see the class)."""
        if self.process is None:
            return
        child = self.process
        try:
            self._conn.send(None)
            failures = [self._conn.recv() for _ in range(self._sent)]     # None: drawn
        except (EOFError, OSError) as err:
            failures = [("RuntimeError", f"the drawing process ended early ({err!r})")]
        except BaseException:                   # Ctrl-C while waiting: stop it at once
            child.terminate()
            raise
        finally:
            self.process = None
            self._conn.close()
            child.join()
        failures = [f for f in failures if f]
        if self._lost is not None:
            failures.append(("RuntimeError", f"the drawing process ended early ({self._lost!r})"))
        if failures and not self._stopped:
            kind, detail = failures[0]
            if kind == "OSError":               # a full disk, a permission: an input error
                raise OSError(*detail)
            raise RuntimeError(f"a figure could not be drawn:\n{detail}")

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None and self.process is not None:
            self._stopped = True
            self.process.terminate()
        self.wait()


def _paint(conn, parent_end):
    """The drawing child: matplotlib imported first, then each (function, args) received
    drawn and answered (None, or the failure: ("OSError", its arguments) or
    ("RuntimeError", traceback)), until None or the parent's end (EOF: the parent's copy of
    the pipe is its only one)."""
    parent_end.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)      # Ctrl-C is the parent's to handle
    _pyplot()
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            break
        if job is None:
            break
        try:
            job[0](*job[1])
            conn.send(None)
        except OSError as err:
            conn.send(("OSError", err.args if err.errno is None else
                       (err.errno, err.strerror, err.filename)))
        except Exception:
            conn.send(("RuntimeError", traceback.format_exc()))
    conn.close()


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


SCREEN_POINTS = 1500    # samples per line: about a figure's width in pixels (dpi 100)


def on_screen(n):
    """Indices of about SCREEN_POINTS of n samples, evenly strided, the last one included
    (a line's end is its end-point error): what a figure of n samples draws, and what
    travels to the drawing process, instead of every sample (60 000 comparison times of a
    10-minute flight with its truth at 100 Hz). Between SCREEN_POINTS and 2 SCREEN_POINTS - 1
    indices when n > SCREEN_POINTS."""
    step = max(1, n // SCREEN_POINTS)
    k = np.arange(0, n, step)
    return k if n == 0 or k[-1] == n - 1 else np.append(k, n - 1)


def navigation_errors(series, png, title="", painter=None):
    """series: {label: errors dict of `evaluation.errors` entries (position NED m, velocity
    NED m/s, attitude rad) with "t"}. East/north/up position and velocity errors and the
    attitude error (deg) against time, one line style per label; drawn by `painter` (a
    `Painter`) when given, else here."""
    lines = {}
    for label, err in series.items():
        k = on_screen(len(err["t"]))
        lines[label] = (err["t"][k] - err["t"][0], ned_to_enu(err["position"][k]),
                        ned_to_enu(err["velocity"][k]), np.degrees(ned_to_enu(err["attitude"][k])))
    (painter or Painter(fork=False)).draw(_navigation_errors, lines, png, title)


def _navigation_errors(lines, png, title):
    """The figure of `navigation_errors` from {label: (t s, position ENU m, velocity ENU
    m/s, attitude deg)}."""
    plt, fig, axes = figure(3, 3, (14, 9))
    comps = ("east", "north", "up")
    for label, (t, pos, vel, att) in lines.items():
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

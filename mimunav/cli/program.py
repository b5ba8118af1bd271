"""The `mimunav` program: the parser of every command (each command group's module adds
its own), exit statuses, Ctrl-C, a closed pipe, and the process's quick end."""
import argparse
import contextlib
import os
import signal
import sys
import threading

# One BLAS thread unless the user chose (before numpy loads OpenBLAS): processes that each
# run OpenBLAS's threads on a small machine spin against each other (a 24000 x 100 Gram
# matrix 50x slower beside two such scripts); alone, one thread costs nothing measurable on
# this work of many mid-size products (bench/blas.py)
if not any(v in os.environ for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")):
    os.environ["OPENBLAS_NUM_THREADS"] = "1"

from ..errors import InputError                         # noqa: E402
from . import (calibration, diagnosis, evaluation, importing, logs,  # noqa: E402
               reports, simulation)

# every command in the order `mimunav --help` lists them, with the module that adds it
COMMANDS = {"demo": simulation, "simulate": simulation, "compensate": logs, "info": logs,
            "cut": logs,
            "unit": simulation, "lab": simulation, "calibrate": calibration,
            "calibration": calibration, "noise": calibration, "drift": calibration,
            "replay": evaluation, "diagnose": diagnosis, "import": importing,
            "windows": evaluation, "table": evaluation, "budget": evaluation,
            "reproduce": evaluation, "campaign": evaluation, "report": reports}
# the commands that never turn attitudes (they skip numpy-quaternion's import)
ATTITUDE_FREE = ("compensate", "info")


def build_parser():
    """The parser of `mimunav` with every command's."""
    parser = argparse.ArgumentParser(
        prog="mimunav", description="Flight-test evaluation of MEMS IMUs against a FOG-IMU.")
    sub = parser.add_subparsers(dest="command", required=True)
    for command, group in COMMANDS.items():
        getattr(group, "add_" + command)(sub)
    return parser


@contextlib.contextmanager
def _remembered_interrupts():
    """Ctrl-C raises KeyboardInterrupt as usual and is also remembered (the list yielded):
    one raised inside a callback from C - numba loading its cache through llvmlite's ctypes
    callback - is swallowed there ("Exception ignored"), and the command would end as if it
    had never been interrupted. Only in the main thread, and only over Python's own handler."""
    caught = []
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield caught
        return

    def remember(signum, frame):
        caught.append(signum)
        raise KeyboardInterrupt
    signal.signal(signal.SIGINT, remember)
    try:
        yield caught
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def run():
    """The `mimunav` program (console script and `python -m mimunav`): `main`, then
    `end_process`."""
    end_process(main())


def end_process(status):
    """End the process with exit `status` (None: 0) once a command has returned and written
    its outputs: the atexit handlers run (logging, matplotlib, numba, multiprocessing) and
    the standard streams are flushed, but the interpreter's teardown of every module object
    by object - 0.3-0.6 s after a command that loaded numba's type registries and
    matplotlib - is skipped. With any other thread alive (it would be cut off), a tracer or
    profiler watching (it writes its results at the ordinary exit), a status that is no
    number, or a stream that cannot be flushed (a closed pipe): the ordinary exit instead."""
    import atexit
    # cProfile, pdb, trace, coverage: they write their results at the ordinary exit
    watched = sys.gettrace() is not None or sys.getprofile() is not None
    if threading.active_count() == 1 and not watched and \
            (status is None or isinstance(status, int)):
        atexit._run_exitfuncs()
        try:
            for stream in (sys.stdout, sys.stderr):
                if stream is not None:          # None: the descriptor was closed at start
                    stream.flush()
        except BrokenPipeError:                 # the reader left before the last lines
            os._exit(141)                       # quietly, as `main` ends on one
        except (OSError, ValueError):           # a closed stream
            raise SystemExit(status)
        os._exit(status or 0)
    raise SystemExit(status)


def main(argv=None):
    """Run a command; input errors (the project's `errors.InputError`, the base of every
    mimunav error type, and the operating system's file errors) end with one line naming the
    command and exit status 2, Ctrl-C with one line and 130, a closed stdout pipe quietly
    with 141; anything else is a bug and shows its traceback."""
    args = build_parser().parse_args(argv)
    if args.command not in ATTITUDE_FREE:    # numpy-quaternion, without scipy.interpolate
        from ..frames import attitude       # noqa: F401 (attitude.import_quaternion)
    try:
        with _remembered_interrupts() as interrupted:
            status = args.func(args)
        if interrupted:
            print(f"mimunav {args.command}: interrupted too late to stop (a library's "
                  "callback swallowed it); the outputs are written whole", file=sys.stderr)
            return 130
        return status
    except KeyboardInterrupt:           # outputs are written whole or not at all
        print(f"mimunav {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:             # the reader of stdout left (| head): nothing to say
        if sys.stdout is not None:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141                      # as a process ended by SIGPIPE
    except (OSError, InputError) as exc:
        print(f"mimunav {args.command}: {exc}", file=sys.stderr)
        return 2

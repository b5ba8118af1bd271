"""Output files and folders: atomic, and never at the cost of an input or of files the
command did not write."""
import json
import os

import numpy as np
import pytest

from mimunav.cli import main


def test_outputs_never_replace_inputs_or_foreign_folders(tmp_path):
    """Issue 20's data loss: `--force` replaces only what the command writes - never a folder
    holding other files or an input, never an input file; new folders get the umask's mode."""
    from mimunav.files import atomic_folder, refuse_inputs
    log = tmp_path / "run" / "f.mcap"
    log.parent.mkdir()
    log.write_bytes(b"precious")
    for out in (log, log.parent, tmp_path):
        with pytest.raises(FileExistsError, match="input"):
            refuse_inputs([out], [log])
    refuse_inputs([tmp_path / "other", None], [log, None])
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="notes.txt"):
        with atomic_folder(other, force=True) as tmp:
            (tmp / "summary.json").write_text("{}")
    assert (other / "notes.txt").read_text() == "mine"
    assert not list(tmp_path.glob(".tmp-*"))
    with atomic_folder(tmp_path / "fresh") as tmp:
        (tmp / "summary.json").write_text("{}")
    with atomic_folder(tmp_path / "fresh", force=True) as tmp:       # its own output: replaced
        (tmp / "summary.json").write_text("{\"v\": 2}")
    assert (tmp_path / "fresh" / "summary.json").read_text() == "{\"v\": 2}"
    umask = os.umask(0)
    os.umask(umask)
    assert (os.stat(tmp_path / "fresh").st_mode & 0o777) == 0o777 & ~umask
    assert main(["diagnose", str(log), "--model", str(log), "--json", str(log), "--force"]) == 2
    assert log.read_bytes() == b"precious"
    out = tmp_path / "d5"
    assert main(["diagnose", str(log), "--model", str(log), "-o", str(out),
                 "--json", str(out / "diagnosis.json")]) == 2           # refused before work
    assert not out.exists()
    with pytest.raises(SystemExit):                                     # checked at parse time
        main(["diagnose", str(log), "--model", str(log), "--alpha", "1.5"])


def test_the_command_line_reports_input_errors_and_lets_bugs_show(tmp_path, monkeypatch):
    """Issue 21: exit 2 with one line for the user's input (the project's InputError and file
    errors); a ValueError from inside the code is a bug and keeps its traceback."""
    from mimunav.cli import program
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["simulate", "flights/gentle.toml", "-o", str(tmp_path / "f.mcap"),
                 "--unit", str(bad)]) == 2
    assert main(["calibrate", str(tmp_path / "missing.mcap"), "--method", "entire",
                 "-o", str(tmp_path / "c.json")]) == 2
    args = program.build_parser().parse_args(["unit", "-o", str(tmp_path / "v.json")])
    args.func = lambda a: int("not a number")           # a bug inside a command
    monkeypatch.setattr(program, "build_parser", lambda: _Fixed(args))
    with pytest.raises(ValueError, match="invalid literal"):
        program.main([])


class _Fixed:
    """A parser that returns prepared arguments."""
    def __init__(self, args):
        self.args = args

    def parse_args(self, argv):
        return self.args


@pytest.mark.slow
def test_the_program_ends_with_its_output_and_status(tmp_path, capsys):
    """`python -m mimunav` ends the process without the interpreter's teardown
    (`cli.end_process`): what the command printed still reaches a pipe whole, its outputs are
    on disk, and the exit status is the command's (0; 2 for an input error)."""
    import subprocess
    import sys

    import fuzzing
    log, cal = fuzzing.corpus_log(tmp_path)
    assert main(["info", str(log)]) == 0
    expected = capsys.readouterr().out

    buffered = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}

    def program(*args):       # stdout a pipe, block-buffered: lost unless flushed
        return subprocess.run([sys.executable, "-m", "mimunav", *args], capture_output=True,
                              text=True, cwd=str(tmp_path), env=buffered)
    done = program("info", str(log))
    assert (done.returncode, done.stdout) == (0, expected)
    done = program("replay", str(log), "--cal", str(cal), "-o", str(tmp_path / "rp"))
    assert done.returncode == 0 and done.stdout.endswith("summary.json, errors.png\n")
    assert sorted(p.name for p in (tmp_path / "rp").iterdir()) == \
        ["errors.png", "nav.mcap", "summary.json"]
    # every end error names its frame and units in its key, and the terminal line is it
    end = json.loads((tmp_path / "rp" / "summary.json").read_text())["end"]
    assert all(sorted(v) == ["attitude_ned_rad", "position_enu_m", "velocity_enu_m_s"]
               for v in end.values()) and set(end) == {"mimu-fog", "mimu-truth", "fog-truth"}
    east = end["mimu-fog"]["position_enu_m"][0]
    assert f"mimu-fog    end position error east {east:+.3g} m" in done.stdout
    done = program("info", str(tmp_path / "missing.mcap"))
    assert done.returncode == 2 and "missing.mcap" in done.stderr and not done.stdout
    closed = subprocess.run([sys.executable, "-m", "mimunav", "info", str(log)],   # >&-
                            stderr=subprocess.PIPE, text=True, env=buffered,
                            preexec_fn=lambda: os.close(1))
    assert (closed.returncode, closed.stderr) == (0, "")
    for args in (["info", str(log)],                      # the reader gone: `| head -0`
                 ["replay", str(log), "--cal", str(cal), "-o", str(tmp_path / "rp2"), "--json"]):
        left = subprocess.Popen([sys.executable, "-m", "mimunav", *args], env=buffered,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        left.stdout.close()
        assert (left.wait(), left.stderr.read()) == (141, ""), args   # quiet, as SIGPIPE
    assert (tmp_path / "rp2" / "summary.json").exists()


def _drawn(png):
    """Stands for a figure function: writes its file."""
    with open(png, "w") as fh:
        fh.write("drawn")


def _fails(png):
    raise ValueError(f"no figure for {png}")


@pytest.mark.slow
def test_figures_drawn_by_a_child_arrive_before_the_commit_or_raise(tmp_path, monkeypatch):
    """`plots.Painter`: every figure sent is written by the forked child when `wait` returns
    (replay and diagnose call it inside their output folder, before it commits); a figure that
    failed raises there with the child's traceback; the child ends on every path."""
    import threading

    from mimunav.reports.plots import Painter
    # a thread other tests leave (tqdm's sleeping monitor) would make it draw here instead
    monkeypatch.setattr(threading, "active_count", lambda: 1)
    with Painter() as painter:
        child = painter.process
        assert child is not None and child.pid != os.getpid()      # one thread here: forked
        painter.draw(_drawn, str(tmp_path / "a.png"))
        painter.draw(_drawn, str(tmp_path / "b.png"))
        painter.wait()
        assert (tmp_path / "a.png").read_text() == (tmp_path / "b.png").read_text() == "drawn"
        assert not child.is_alive()
    painter = Painter()
    child = painter.process
    painter.draw(_fails, "x.png")
    painter.draw(_drawn, str(tmp_path / "c.png"))
    with pytest.raises(RuntimeError, match="ValueError: no figure for x.png"):
        painter.wait()
    assert (tmp_path / "c.png").read_text() == "drawn" and not child.is_alive()
    with pytest.raises(KeyError, match="the command's own error"):
        with Painter() as painter:
            child = painter.process
            painter.draw(_fails, "y.png")
            raise KeyError("the command's own error")
    assert not child.is_alive()
    here = Painter(fork=False)
    assert here.process is None
    with pytest.raises(ValueError):
        here.draw(_fails, "z.png")
    # a figure's OSError (a full disk, no permission) stays an OSError: the command's
    # one-line input error, status 2, as when drawn in-process
    with pytest.raises(FileNotFoundError, match="no-such-folder"):
        with Painter() as painter:
            painter.draw(_drawn, str(tmp_path / "no-such-folder" / "d.png"))
    # a child stopped by somebody else is a failure, not a figure drawn
    painter = Painter()
    painter.process.terminate()
    painter.process.join()
    with pytest.raises(RuntimeError, match="ended early"):
        painter.wait()


def test_a_figure_draws_a_screen_of_samples_with_the_last():
    """`plots.on_screen`: what a line of n samples draws (and sends to the drawing process)
    is every sample up to SCREEN_POINTS, else evenly strided samples - never more than twice
    SCREEN_POINTS - from the first to the last (an error plot's end is its end-point
    error)."""
    from mimunav.reports.plots import SCREEN_POINTS, on_screen
    assert len(on_screen(0)) == 0
    for n in (1, 2, SCREEN_POINTS - 1, SCREEN_POINTS, SCREEN_POINTS + 1, 2 * SCREEN_POINTS + 7,
              600_000, 682_001):
        k = on_screen(n)
        assert k[0] == 0 and k[-1] == n - 1 and np.all(np.diff(k) > 0)
        assert len(k) == n if n <= SCREEN_POINTS else SCREEN_POINTS <= len(k) <= 2 * SCREEN_POINTS
        step = np.diff(k[:-1])
        assert len(step) == 0 or np.all(step == step[0])


@pytest.mark.slow
def test_the_drawing_child_ends_with_its_parent(tmp_path):
    """A parent killed outright (no cleanup) leaves no drawing child behind: the child holds
    no copy of the parent's end of the pipe, so it reads EOF and ends."""
    import subprocess
    import sys
    import time
    probe = ("import os, sys\n"
             "from mimunav.reports.plots import Painter\n"
             "p = Painter()\n"
             "print(p.process.pid, flush=True)\n"
             "os._exit(0)\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=60, check=True)
    child = int(done.stdout.split()[0])
    deadline = time.monotonic() + 20            # its matplotlib import, then EOF

    def running():                  # a zombie nobody reaps has ended too
        try:
            with open(f"/proc/{child}/stat") as fh:
                return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
        except FileNotFoundError:
            return False
    while time.monotonic() < deadline and running():
        time.sleep(0.1)
    assert not running()


def test_an_interrupted_command_says_so_in_one_line_and_writes_nothing(tmp_path, capsys,
                                                                       monkeypatch):
    """Ctrl-C during the work: one line, status 130, no output folder (nor its temporary)."""
    import fuzzing
    from mimunav.evaluation.flight import Flight
    log, cal = fuzzing.corpus_log(tmp_path)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(Flight, "load", interrupted)
    out = tmp_path / "rp"
    assert main(["replay", str(log), "--cal", str(cal), "-o", str(out)]) == 130
    assert capsys.readouterr().err == "mimunav replay: interrupted\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.json", "flight.mcap",
                                                          "flight.truth.json"]


def test_a_log_that_lost_its_flight_metadata_is_named_for_what_it_is(tmp_path, capsys):
    """A contract log without its `flight` metadata (a foreign writer puts it at the end; a
    truncated copy keeps none after --recover): `info --recover` warns, replay says what is
    missing instead of calling it a ROS 2 recording."""
    import numpy as np
    from mimunav.flightlog import LogWriter
    from mimunav.flightlog import schemas as S
    log = tmp_path / "headless.mcap"
    n = 200
    with LogWriter(log) as w:
        stamps = 10**18 + np.arange(n, dtype=np.int64) * 1_000_000
        w.write("/mimu/raw", S.RAW_MIMU, "mimu", stamps, sample_index=np.arange(n),
                gyro_volts=np.zeros((n, 3)), accel_volts=np.zeros((n, 3)),
                accel_temperature=np.full((n, 3), 25.0), gyro_frequency=np.full((n, 3), 1e4))
        w.write("/fog/imu", S.IMU, "fog", stamps, **S.imu_fields(np.zeros((n, 3)),
                                                                  np.zeros((n, 3))))
    assert main(["info", str(log), "--recover", str(tmp_path / "rec.mcap")]) == 0
    assert "holds no `flight` metadata" in capsys.readouterr().err
    assert main(["replay", str(log), "--cal", str(tmp_path / "none.json"), "-o",
                 str(tmp_path / "rp")]) == 2
    err = capsys.readouterr().err
    assert "no `flight` metadata" in err and "ROS 2" not in err


def test_a_swallowed_interrupt_is_still_reported(tmp_path, capsys, monkeypatch):
    """A Ctrl-C swallowed inside a callback from C (llvmlite's, while numba loads its cache:
    "Exception ignored on calling ctypes callback function") lets the command finish; it
    must not then end as if never interrupted. Over Python's own handler, which another test
    run before it in the same worker may have left replaced."""
    import signal

    from mimunav.cli import program
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)

    def swallowing(args):
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            pass                                # as the ctypes callback does
        return 0
    args = program.build_parser().parse_args(["info", str(tmp_path / "any.mcap")])
    args.func = swallowing
    monkeypatch.setattr(program, "build_parser", lambda: _Fixed(args))
    try:
        assert main([]) == 130
        assert "interrupted too late to stop" in capsys.readouterr().err
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_folder_that_would_be_refused_is_refused_before_the_work(tmp_path, capsys,
                                                                    monkeypatch):
    """replay / diagnose -o onto a file, or with --force onto a folder of other files: the
    refusal `atomic_folder` makes at the end comes before the work (nothing is read)."""
    from mimunav.evaluation.flight import Flight

    def no_work(*args, **kwargs):
        raise AssertionError("the work started")
    monkeypatch.setattr(Flight, "load", no_work)
    (tmp_path / "afile").write_text("mine")
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "mynote.txt").write_text("mine")
    (notes / "summary.json").write_text("{}")
    log, cal = tmp_path / "f.mcap", tmp_path / "cal.json"
    for out, expected in (("afile", "is not a folder"), ("notes", "holds mynote.txt")):
        for cmd in (["replay", str(log), "--cal", str(cal)],
                    ["diagnose", str(log), "--model", str(cal)]):
            assert main(cmd + ["-o", str(tmp_path / out), "--force"]) == 2
            assert expected in capsys.readouterr().err
    assert (notes / "mynote.txt").read_text() == "mine" and (tmp_path / "afile").exists()

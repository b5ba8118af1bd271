"""The main job's install holds only what it needs: with the extras' packages hidden, the
modules of `mimunav reproduce` import and a command runs; a command that needs an extra says
which, in one line, with exit status 2."""
import subprocess
import sys

import pytest

from mimunav.errors import InputError, require
from places import REPO

EXTRAS = ("allantools", "statsmodels", "pyulog", "pymavlink", "mcap_ros2", "rosbags", "dask")
# a meta-path finder that refuses the extras' packages, as on a machine without them
HIDE = ("import sys, importlib.abc\n"
        "class Hidden(importlib.abc.MetaPathFinder):\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        f"        if name.split('.')[0] in {EXTRAS!r}:\n"
        "            raise ModuleNotFoundError(name)\n"
        "sys.meta_path.insert(0, Hidden())\n")


def _run(code):
    return subprocess.run([sys.executable, "-c", HIDE + code], capture_output=True, text=True,
                          cwd=REPO)


def test_require_names_the_extra_that_installs_a_missing_package():
    with pytest.raises(InputError, match=r"the thing needs no_such_package_x, which is not "
                                         r"installed: pip install 'mimunav\[stats\]'"):
        require("no_such_package_x.sub", "stats", "the thing")
    assert require("json", "stats", "the thing").dumps([1]) == "[1]"


def test_the_main_job_needs_no_extra():
    """Every module `mimunav reproduce` runs imports without the extras, and a flight is
    simulated and replayed."""
    run = _run("import mimunav.reports.table3, mimunav.reports.regime, mimunav.cli\n"
               "from mimunav.cli import main\n"
               "print(main(['demo', 'flights/gentle.toml', '--rate', '50']))\n")
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip().endswith("0")


@pytest.mark.parametrize("argv, extra", [
    pytest.param(["noise", "flights/gentle.toml", "-o", "/nonexistent/out"], "stats",
                 marks=pytest.mark.slow),
    (["import", "ulog", "flights/gentle.toml", "-o", "/nonexistent/x.mcap"], "import"),
])
def test_a_command_without_its_extra_says_which_to_install(argv, extra, tmp_path):
    """A command whose package is missing ends with one line naming the extra (exit 2).
    The noise command reaches allantools only once it has a log to analyse: one is made."""
    if argv[0] == "noise":
        log, profile = tmp_path / "static.mcap", tmp_path / "static.toml"
        profile.write_text((REPO / "flights" / "static.toml").read_text()
                           .replace("duration_s = 3600.0", "duration_s = 60.0"))
        made = subprocess.run([sys.executable, "-m", "mimunav", "simulate", str(profile),
                               "-o", str(log), "--seed", "1"], capture_output=True, text=True,
                              cwd=REPO)
        assert made.returncode == 0, made.stderr[-2000:]
        argv = ["noise", str(log), "--channel", "/fog/imu", "-o", str(tmp_path / "noise")]
    else:
        argv = argv[:2] + [str(REPO / "flights" / "gentle.toml"), "-o", str(tmp_path / "x.mcap")]
    run = _run(f"from mimunav.cli import main\nsys.exit(main({argv!r}))\n")
    assert run.returncode == 2, run.stderr[-2000:]
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and f"pip install 'mimunav[{extra}]'" in lines[0]

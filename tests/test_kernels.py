"""Compiled kernels and their on-disk cache (`mimunav.kernels`)."""
import os
import shutil

import pytest
import subprocess
import sys
import time
from pathlib import Path

import mimunav
from mimunav import kernels

# the height after T s at rest from 100 m up, through the navigator (strapdown._navigate
# inlines earth.nav_rates_at, whose gravity takes GAMMA_E as a compile-time constant)
AT_REST = """
import numpy as np
import pytest
from mimunav.motion.trajectory import State
from mimunav.navigation import strapdown
n, rate = 1000, 100.0
t = np.arange(1, n + 1) / rate
dv = np.zeros((n, 3))
dv[:, 2] = -9.80 / rate
nav = strapdown.integrate(t, np.zeros((n, 3)), dv, State(0.0, 0.7, 0.1, 100.0, np.zeros(3),
                                                         np.quaternion(1.0, 0.0, 0.0, 0.0)))
print(repr(float(nav.h[-1])))
"""


def _height_at_rest(package_parent):
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}   # the in-tree cache
    env["PYTHONPATH"] = str(package_parent)
    out = subprocess.run([sys.executable, "-c", AT_REST], env=env, capture_output=True,
                         text=True, check=True, cwd=package_parent)
    return float(out.stdout)


@pytest.mark.slow
def test_an_edit_of_an_inlined_callee_compiles_its_caller_again(tmp_path):
    """numba checks a cached kernel against its own file: with earth.py edited and
    strapdown.py not, the navigator kept the old gravity from its cache. The kernels are
    cached per version of the whole package: the edit takes effect at once, as the closed
    form says (free fall from rest under g + dg: h drops by dg T^2 / 2 more)."""
    copy = tmp_path / "mimunav"
    shutil.copytree(Path(mimunav.__file__).parent, copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    before = _height_at_rest(tmp_path)
    earth = copy / "frames" / "earth.py"
    source = earth.read_text()
    line = "GAMMA_E = 9.7803253359"
    assert source.count(line) == 1
    earth.write_text(source.replace(line, "GAMMA_E = 9.8803253359"))     # 0.1 m/s^2 more
    after = _height_at_rest(tmp_path)
    dg, duration = 0.1, 10.0     # m/s^2 (x 1.002, normal gravity's factor at 40 deg), s
    assert abs((before - after) - dg * duration**2 / 2) < 0.01 * dg * duration**2 / 2
    assert len(list((copy / "__pycache__").glob(kernels.PREFIX + "*"))) == 2


def test_only_versions_unused_for_a_week_are_removed(tmp_path):
    current = tmp_path / (kernels.PREFIX + "now")
    old, recent, other = (tmp_path / (kernels.PREFIX + "old"),
                          tmp_path / (kernels.PREFIX + "recent"), tmp_path / "old-other")
    for folder, days in ((current, 30), (old, kernels.STALE_DAYS + 1), (recent, 1), (other, 30)):
        folder.mkdir()
        (folder / "kernel.nbc").write_bytes(b"x")
        stamp = time.time() - days * 86400.0
        os.utime(folder, (stamp, stamp))
    kernels.prune_cache(current)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in (current, recent, other))


@pytest.mark.slow
def test_numba_is_left_as_found_and_the_version_marked_used(tmp_path):
    """numba's own cache setting is swapped only while mimunav's kernels are decorated
    (another package's kernels keep their folders), and the version's folder is marked used
    each time a process loads kernels (what the pruning of others goes by)."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = str(Path(mimunav.__file__).parent.parent)
    out = subprocess.run([sys.executable, "-c", "import numba.core.config as c; "
                          "import mimunav.navigation.strapdown, mimunav.motion.truth; print(repr(c.CACHE_DIR))"],
                         env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == repr("")
    env["NUMBA_CACHE_DIR"] = str(tmp_path)
    script = ("from mimunav import kernels; import os; "
              "print(kernels.cache_dir(), os.stat(kernels.cache_dir()).st_mtime)")
    first = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                           text=True, check=True).stdout.split()
    assert Path(first[0]).parent == tmp_path and Path(first[0]).name.startswith(kernels.PREFIX)
    stale = time.time() - 30 * 86400.0
    os.utime(first[0], (stale, stale))
    again = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                           text=True, check=True).stdout.split()
    assert again[0] == first[0] and float(again[1]) > stale + 29 * 86400.0

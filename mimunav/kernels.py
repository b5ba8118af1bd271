"""Compiled kernels: numba's `njit` with its on-disk cache kept per version of this package.

numba checks a cached kernel against the source file of that kernel only. A kernel that
inlines or calls a kernel of another module (the navigator inlines `earth.nav_rates_at`
and `attitude.rotate_scalar`) kept the old callee after that module alone changed - an
edited checkout, or `git pull` in the editable install the README uses - and gave wrong
numbers silently (a gravity changed in earth.py left `strapdown.integrate` as it was).
Every kernel here is cached in a folder named by `code_version()`, the hash of all the
package's sources: any change compiles the kernels afresh, once (a few seconds).

The folders sit in NUMBA_CACHE_DIR when it is set, else in the package's `__pycache__`
when it is writable, else in numba's user-wide cache; a version's folder unused for
`STALE_DAYS` is removed by the next process that compiles or loads kernels.
"""
import functools
import hashlib
import os
import shutil
import threading
import time
from pathlib import Path

import numba
from numba.core import config
from numba.misc.appdirs import AppDirs

PACKAGE = Path(__file__).resolve().parent
STALE_DAYS = 7
PREFIX = "mimunav-kernels-"
_SWAP = threading.Lock()        # numba's CACHE_DIR is process-wide while it is swapped


@functools.lru_cache(maxsize=1)
def code_version():
    """16 hex digits of the SHA-256 of this package's Python sources (each file's path
    relative to the package, then its bytes, in path order): code that differs anywhere
    differs here (campaign units and compiled kernels are keyed by it)."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE.rglob("*.py")):
        digest.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


@functools.lru_cache(maxsize=1)
def cache_dir():
    """The folder of this version's compiled kernels (made, and marked used, here); None
    when it cannot be made."""
    base = os.environ.get("NUMBA_CACHE_DIR")
    if not base:
        in_tree = PACKAGE / "__pycache__"
        base = str(in_tree) if os.access(in_tree if in_tree.exists() else PACKAGE, os.W_OK) \
            else AppDirs(appname="numba", appauthor=False).user_cache_dir
    path = Path(base) / (PREFIX + code_version())
    try:
        path.mkdir(parents=True, exist_ok=True)
        os.utime(path)                  # used now: not stale
    except OSError:                     # nowhere to keep kernels: compiled in each process
        return None
    prune_cache(path)
    return str(path)


def prune_cache(current):
    """Remove the other versions' folders beside `current` unused for STALE_DAYS."""
    oldest = time.time() - STALE_DAYS * 86400.0
    for other in current.parent.glob(PREFIX + "*"):
        try:
            if other != current and other.stat().st_mtime < oldest:
                shutil.rmtree(other, ignore_errors=True)
        except OSError:                 # removed by another process meanwhile
            pass


def njit(**options):
    """`numba.njit(cache=True, **options)` with the cache in `cache_dir()` (numba takes
    the folder when the function is decorated), or without a cache when there is none."""
    def compile_cached(function):
        folder = cache_dir()
        if folder is None:
            return numba.njit(**options)(function)
        with _SWAP:
            before = config.CACHE_DIR
            config.CACHE_DIR = folder
            try:
                return numba.njit(cache=True, **options)(function)
            finally:
                config.CACHE_DIR = before
    return compile_cached

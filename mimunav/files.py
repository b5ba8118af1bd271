"""Output files written atomically: a temporary file beside the target, renamed over it on
success, so a crash or an error never leaves a half-written file, and an existing file is
never replaced unless the caller forces it."""
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path


def temporary_beside(path, suffix):
    """(fd, name) of a new temporary file in path's folder with the permissions an ordinary
    new file gets (mkstemp's are 0600), for write-then-rename."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=suffix)
    umask = os.umask(0)
    os.umask(umask)
    os.fchmod(fd, 0o666 & ~umask)
    return fd, tmp


def write_atomic(path, text, force=False):
    """Write text to path through a temporary file in the same folder and a rename, so a
    crash never leaves a half-written file; an existing file is kept unless force."""
    path = os.fspath(path)
    if os.path.exists(path) and not force:
        raise FileExistsError(f"{path} exists; pass force to replace it")
    fd, tmp = temporary_beside(path, os.path.basename(path))
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


@contextmanager
def atomic_folder(path, force=False):
    """Build a folder in a temporary folder beside `path` (yielded, a Path) and rename it
    into place when the block succeeds; on error nothing is left. An existing folder is
    kept unless force."""
    out = Path(path)
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists; use --force to replace it")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=".tmp-"))
    try:
        yield tmp
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise

"""Output files written atomically: a temporary file beside the target, renamed over it on
success, so a crash or an error never leaves a half-written file, and an existing file is
never replaced unless the caller forces it."""
import json
import math
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .errors import InputError


def read_json(path, what, error=InputError):
    """The JSON document in the file at path, or `error` (an InputError) in one line naming
    what the file should have been ("calibration file"): unreadable, not UTF-8 text (an
    MCAP or other binary file given in its place), or not JSON."""
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except UnicodeDecodeError:
        raise error(f"{path}: not a {what} - not text, let alone JSON (a binary file such "
                    "as a log given in its place?)") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise error(f"{path}: cannot read a {what} ({exc})") from None


def check_format(doc, expected, source, error=InputError):
    """Refuse a parsed JSON document that is not an object whose "format" is `expected`."""
    if not isinstance(doc, dict):
        raise error(f"{source}: the top level must be a JSON object, not a "
                    f"{type(doc).__name__}")
    if doc.get("format") != expected:
        raise error(f"{source}: format is {doc.get('format')!r}, expected {expected!r}")


def temporary_beside(path, suffix):
    """(fd, name) of a new temporary file in path's folder with the permissions an ordinary
    new file gets (mkstemp's are 0600), for write-then-rename."""
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"{path}: the folder {folder} does not exist")
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
        raise FileExistsError(f"{path} exists; use --force to replace it")
    fd, tmp = temporary_beside(path, os.path.basename(path))
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def refuse_inputs(outputs, inputs):
    """Raise FileExistsError when an output (file or folder; None skipped) is one of the
    inputs or a folder holding one: no command may overwrite or delete what it reads."""
    for out in filter(None, outputs):
        o = Path(out).resolve()
        for inp in filter(None, inputs):
            i = Path(inp).resolve()
            if i == o or o in i.parents:
                raise FileExistsError(f"{out} would replace the input {inp}; choose another "
                                      "output")


def refuse_folder_early(path, force, writes):
    """Before a command's work, the refusals `atomic_folder` would make only after it, for a
    command that writes the file names `writes` (all it may write) into the folder `path`."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out} exists and is not a folder; not replaced")
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists; use --force to replace it")
    if out.exists():
        _refuse_foreign(out, writes)


def _refuse_foreign(out, writes):
    foreign = sorted(set(os.listdir(out)) - set(writes))
    if foreign:
        raise FileExistsError(
            f"{out} holds {', '.join(foreign[:5])}{' ...' if len(foreign) > 5 else ''}"
            ", which this command does not write: not replaced (move them, or choose "
            "another folder)")


@contextmanager
def atomic_folder(path, force=False, inputs=()):
    """Build a folder in a temporary folder beside `path` (yielded, a Path) and rename it
    into place when the block succeeds; on error nothing is left. An existing folder is
    kept unless force, and even then replaced only when it holds nothing but what this
    command writes (the names the new folder has): never a folder of other files, never
    one that holds an input (`inputs`). The folder gets an ordinary new folder's mode."""
    out = Path(path)
    refuse_inputs([out], inputs)
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists; use --force to replace it")
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out} exists and is not a folder; not replaced")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=".tmp-"))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)
    try:
        yield tmp
        if out.exists():
            _refuse_foreign(out, os.listdir(tmp))
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def json_ready(x):
    """A JSON-ready copy of x: numpy scalars and arrays to Python numbers and lists, tuples to
    lists, non-finite floats to None (e.g. an rms over no rows)."""
    if isinstance(x, dict):
        return {k: json_ready(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_ready(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None                     # e.g. an rms over no rows
    return x

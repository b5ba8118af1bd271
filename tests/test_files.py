"""Output files and folders: atomic, and never at the cost of an input or of files the
command did not write."""
import os

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

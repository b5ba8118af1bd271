"""`mimunav import KIND --help`: the options that serve that kind, by what their help says."""
import pytest

from mimunav.cli import main


@pytest.mark.parametrize("kind, shown, hidden", [
    ("ulog", ["--imu-instance", "--reference-imu-lever-arm-m", "--lever-arm-m", "-o OUTPUT",
              "--mounting-rpy-deg"],
     ["--imu-topic", "--gps-status", "--root", "--solutions"]),
    ("table", ["--root", "--spec-keys", "--reference-time-offset", "--mounting-rpy-deg"],
     ["--imu-instance", "--pose-topic", "--gps-status"]),
    ("ros1", ["--imu-topic", "--pose-azimuth", "--sampling"], ["--root", "--gps-status"])])
def test_a_kinds_help_shows_its_options_and_no_other_kinds(kind, shown, hidden, capsys):
    """An independent trial had read the whole import help after `mimunav import ulog
    --help`; without a kind the whole help stays."""
    with pytest.raises(SystemExit) as done:
        main(["import", kind, "--help"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith(f"usage: mimunav import {kind} SOURCE")
    assert all(option in text for option in shown), text
    assert not any(option in text for option in hidden), text
    with pytest.raises(SystemExit):
        main(["import", "--help"])
    whole = capsys.readouterr().out
    assert all(option in whole for option in shown + hidden)

"""`mimunav report recording` on the RTKLIB excerpt."""
import json
import re

import numpy as np
import pytest

from mimunav.cli import main
from mimunav.evaluation.flight import Flight
from mimunav.importers.recording import Recording
from mimunav.importers.write import write_log
from drives import DRIVE


@pytest.mark.slow
def test_report_recording_of_the_excerpt_and_its_refusals(tmp_path):
    """`mimunav report recording`: one folder with the metadata table, the channels, the
    windows and the diagnosis (or why not); a log it cannot read leaves no folder behind."""
    log = tmp_path / "drive.mcap"
    assert main(["import", "rtklib", str(DRIVE), "-o", str(log)]) == 0
    out = tmp_path / "report"
    assert main(["report", "recording", str(log), "-o", str(out)]) == 0
    text = (out / "recording.md").read_text()
    assert "| reference | RTKLIB solution (fix)" in text
    assert "independent of this IMU: yes" in text
    assert "| 10 |" in text                              # the 10 s windows' row
    # its roll and pitch leveled at a rest: the accelerometer bias across gravity they hold
    assert re.search(r"heading [0-9.]+ deg \(course\).*reads as tilt - 1 mg as 0.057 deg",
                     text), text
    doc = json.loads((out / "diagnosis" / "diagnosis.json").read_text())
    assert doc["level"] == "track" and "conclusive" in doc
    # the excursions that set the contract verdict are listed (11 on the excerpt)
    assert text.count("- unexplained residual ") == len(doc["unexplained"]) > 0
    assert (out / "windows.png").stat().st_size > 0
    assert main(["report", "recording", str(log), "-o", str(out)]) == 2      # no --force
    # the level a diagnosis names (`--level track`, `--vehicle`) is the report's to take too
    assert main(["report", "recording", str(log), "-o", str(tmp_path / "sensor"),
                 "--level", "sensor"]) == 0
    text = (tmp_path / "sensor" / "recording.md").read_text()
    assert "the sensor level needs a reference IMU (/fog/imu)" in text
    assert main(["report", "recording", str(log), "-o", str(tmp_path / "walk"),
                 "--level", "track", "--vehicle", "pedestrian"]) == 0
    walk = (tmp_path / "walk" / "recording.md").read_text()
    assert "--level track models a car" in walk
    assert "`mimunav report recording drive.mcap --level track --vehicle pedestrian`" in walk
    assert main(["report", "calibration", "--vehicle", "car"]) == 2
    bare = tmp_path / "bare.mcap"                        # no /truth/state
    flight = Flight.load(log, reference_imu=False)
    rec = Recording("bare", "", flight.epoch_ns + np.round(flight.mimu_t * 1e9).astype(np.int64),
                    *flight.mimu_imu, flight.mimu_mounting)
    write_log(rec, bare)
    # without a reference the report still says what the recording is, and why it has no
    # windows and no diagnosis (the README's "diagnosis (or why not)")
    assert main(["report", "recording", str(bare), "-o", str(tmp_path / "why")]) == 0
    text = (tmp_path / "why" / "recording.md").read_text()
    assert "No window: " in text and "Not run: " in text
    assert sorted(p.name for p in (tmp_path / "why").iterdir()) == ["recording.md"]
    cut = tmp_path / "cut.mcap"                          # a log it cannot read at all
    cut.write_bytes(bare.read_bytes()[:4000])
    assert main(["report", "recording", str(cut), "-o", str(tmp_path / "none")]) == 2
    assert not (tmp_path / "none").exists()


def test_the_terms_not_confirmed_are_read_alike_by_the_terminal_and_the_report():
    """An x-IMU's diagnosis set two size_effect terms aside, one for a reason among those
    that make it inconclusive: the terminal listed both, the report only the other (a reason
    began with the first's label) - both now list one alone, the other as said."""
    from mimunav.cli.diagnosis import not_confirmed_lines
    from mimunav.diagnosis.document import not_confirmed_said
    doc = {"inconclusive_reasons": ["size_effect accel.x: the halves disagree beyond their "
                                    "intervals"],
           "not_confirmed": [{"label": "size_effect accel.x", "rejected": "held-out p = 0.1"},
                             {"label": "size_effect accel.y", "rejected": "held-out p = 0.71"},
                             {"label": "bias_shift gyro.z",
                              "rejected": "the halves disagree beyond their intervals"}]}
    alone, again = not_confirmed_said(doc)
    assert alone == [("size_effect accel.x", "held-out p = 0.1"),
                     ("size_effect accel.y", "held-out p = 0.71")]
    assert again == ["bias_shift gyro.z"]
    assert len(not_confirmed_lines(doc)) == 3

"""Damaged logs never give a traceback, never a laundered result, and lose nothing intact
(`tests/fuzzing.py` makes the damage; `bench/fuzz.py` runs the same over thousands of cases).
"""
import numpy as np
import pytest

import fuzzing
from mimunav.cli import main
from mimunav.flightlog import FlightLog


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz")
    log, cal = fuzzing.corpus_log(folder)
    return folder, log, cal, fuzzing.references(log, cal, folder / "base")


@pytest.mark.slow
def test_damaged_logs_are_refused_or_read_right(corpus):
    """A seeded corpus - one flipped byte in a record of every MCAP opcode, truncations, bit
    flips and overwritten 4 KiB blocks at random places, an empty and a foreign file - through
    info, info --recover, compensate, replay, table and diagnose: each run either refuses in
    one line (exit 2) or gives exactly the undamaged log's result (what --recover keeps is
    the original's messages, byte for byte)."""
    folder, log, cal, reference = corpus
    data = log.read_bytes()
    bad = []
    outcomes = {"ok": 0, "refused": 0}
    for name, damaged in fuzzing.damages(data, np.random.default_rng(20261123), n_random=2):
        case, path = fuzzing.case_file(folder, damaged)
        for argv in fuzzing.commands(path, cal, case):
            outcome, err = fuzzing.judge(argv, log, case, reference, damaged)
            if outcome not in outcomes:
                bad.append((name, argv[0], outcome, err[-300:]))
            else:
                outcomes[outcome] += 1
    assert not bad, bad
    assert outcomes["refused"] > 0 and outcomes["ok"] > 0


@pytest.mark.slow
def test_recover_reads_past_damage_and_skip_damaged_says_what_it_left(corpus, tmp_path):
    """One overwritten block in the first chunk: --recover keeps every other chunk of every
    channel (not only what precedes the damage); compensate refuses the log, and with
    --skip-damaged writes the rest with the damaged range in its `damage` metadata."""
    folder, log, cal, _ = corpus
    data = bytearray(log.read_bytes())
    offset, _, length = next(r for r in fuzzing.records(bytes(data)) if r[1] == 0x06)
    data[offset + 200:offset + 200 + 4096] = bytes(4096)
    path = tmp_path / "hit.mcap"
    path.write_bytes(bytes(data))
    recovered = tmp_path / "rec.mcap"
    assert main(["info", str(path), "--recover", str(recovered)]) == 0
    with FlightLog(log) as full, FlightLog(recovered) as kept:
        counts = {t: (len(kept.read(t)), len(full.read(t))) for t in full.channels}
    assert all(n == total for t, (n, total) in counts.items() if t != "/mimu/raw"), counts
    assert 0 < counts["/mimu/raw"][0] < counts["/mimu/raw"][1]
    assert fuzzing.recovered_subset(log, recovered)
    out = tmp_path / "comp.mcap"
    assert main(["compensate", str(path), "--cal", str(cal), "-o", str(out)]) == 2
    assert not out.exists()
    assert main(["compensate", str(path), "--cal", str(cal), "-o", str(out),
                 "--skip-damaged"]) == 0
    with FlightLog(out) as comp:
        damage = comp.metadata()["damage"]
        assert list(damage) == ["/mimu/raw"] and damage["/mimu/raw"][0]["start_ns"] > 0
        assert len(comp.read("/mimu/imu")) == counts["/mimu/raw"][0]


@pytest.mark.slow
def test_a_channel_pointing_at_no_schema_is_refused(corpus, tmp_path):
    """The case bench/fuzz.py found (2000 runs, seed 1): a flipped byte in the schema id of
    a summary Channel record; every command refuses it in one line."""
    _, log, cal, _ = corpus
    data = bytearray(log.read_bytes())
    pos = [p for p, op, _ in fuzzing.records(bytes(data)) if op == 0x04][-1]
    data[pos + 9 + 2] ^= 0xFF                           # schema_id follows the channel id
    path = tmp_path / "chan.mcap"
    path.write_bytes(bytes(data))
    for argv in fuzzing.commands(path, cal, tmp_path)[2:]:
        outcome, err, _ = fuzzing.run(argv)
        assert outcome == "refused" and "refers to schema" in err, (argv[0], err)

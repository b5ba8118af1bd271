"""Damaged logs and the commands that must survive them (the fuzz test and bench/fuzz.py).

A small simulated flight log is damaged in the ways storage and transfer damage files:
truncation anywhere, one flipped bit anywhere, a 4 KiB block overwritten (random bytes or
zeros), a flipped byte inside a record of each MCAP opcode (so the chunk CRCs, the chunk and
message indexes, the statistics and the summary offsets are all hit), an empty file and a
foreign file. Every command is run in-process (`cli.main`) on each damaged file: the outcome
must be exit 0 (a correct result) or exit 2 with a one-line error; an exception out of
`main` is a traceback, i.e. a bug.
"""
import contextlib
import io
import struct
import traceback

from mimunav.cli import main
from mimunav.compensation.calibration_file import Calibration
from mimunav.motion.profile import Profile
from mimunav.sensors.mimu import MimuUnit
from mimunav.sensors.simulation import simulate_flight

MAGIC = b"\x89MCAP0\r\n"
OPCODES = {0x01: "header", 0x02: "footer", 0x03: "schema", 0x04: "channel", 0x05: "message",
           0x06: "chunk", 0x07: "message_index", 0x08: "chunk_index", 0x09: "attachment",
           0x0A: "attachment_index", 0x0B: "statistics", 0x0C: "metadata",
           0x0D: "metadata_index", 0x0E: "summary_offset", 0x0F: "data_end"}
PROFILE = {"name": "fuzz", "start": {"latitude_deg": 40.0, "longitude_deg": 116.0,
                                     "height_m": 500.0, "speed_m_s": 100.0, "heading_deg": 30.0},
           "segment": [{"kind": "hold", "duration_s": 4.0},
                       {"kind": "turn", "load_factor": 1.2, "heading_change_deg": 20.0},
                       {"kind": "hold", "duration_s": 4.0}]}


def corpus_log(folder, seed=5):
    """(log, calibration) of a 14 s flight of a drawn unit, its true coefficients as the
    calibration file."""
    unit = MimuUnit.draw(seed)
    log = folder / "flight.mcap"
    simulate_flight(Profile.from_dict(PROFILE), log, seed, unit=unit, progress=False)
    cal = folder / "cal.json"
    Calibration.from_dict(unit.coefficients.as_dict()).save(str(cal))
    return log, cal


def records(data):
    """[(offset, opcode, length)] of the top-level records of an MCAP file (as far as the
    lengths lead)."""
    out, pos = [], len(MAGIC)
    while pos + 9 <= len(data) - len(MAGIC):
        op, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        out.append((pos, op, length))
        if op == 0x02:
            break
        pos += 9 + length
    return out


def damages(data, rng, n_random=10):
    """[(name, damaged bytes)]: per record type one flipped byte inside it, and n_random each
    of truncations, bit flips and overwritten blocks at random places, an empty file and a
    foreign one."""
    out = [("empty", b""), ("foreign", b"time,ax,ay,az\n0,1,2,3\n" * 50),
           ("magic only", MAGIC)]
    seen = {}
    for pos, op, length in records(data):
        seen.setdefault(op, []).append((pos, length))
    for op, places in sorted(seen.items()):
        pos, length = places[int(rng.integers(len(places)))]
        k = pos + 9 + int(rng.integers(max(1, length)))
        k = min(k, len(data) - 1)
        b = bytearray(data)
        b[k] ^= 0xFF
        out.append((f"{OPCODES.get(op, hex(op))} byte {k} flipped", bytes(b)))
    for _ in range(n_random):
        k = int(rng.integers(1, len(data)))
        out.append((f"truncated at {k}", data[:k]))
        k = int(rng.integers(len(data)))
        b = bytearray(data)
        b[k] ^= 1 << int(rng.integers(8))
        out.append((f"bit flip at {k}", bytes(b)))
        k = int(rng.integers(len(data)))
        b = bytearray(data)
        fill = bytes(4096) if rng.random() < 0.5 else rng.bytes(4096)
        b[k:k + 4096] = fill[:len(b[k:k + 4096])]
        out.append((f"4 KiB overwritten at {k}", bytes(b)))
    return out


def commands(log, cal, out):
    """The commands a user runs on a log, with their outputs under `out`."""
    return [["info", str(log)],
            ["info", str(log), "--recover", str(out / "recovered.mcap")],
            ["compensate", str(log), "--cal", str(cal), "-o", str(out / "comp.mcap")],
            ["replay", str(log), "--cal", str(cal), "-o", str(out / "replay")],
            ["table", str(log), "--cal", f"true={cal}"],
            ["diagnose", str(log), "--model", str(cal), "--json", str(out / "d.json")]]


def run(argv):
    """(outcome, stderr text, stdout text): 'ok' (exit 0), 'refused' (exit 2, the one-line
    error), 'traceback' (an exception out of main, or a refusal that is not one line)."""
    err, sink = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(sink):
            code = main(argv)
    except SystemExit as exc:            # argparse
        return ("refused" if exc.code == 2 else "traceback"), err.getvalue().strip()[-300:], ""
    except Exception:                    # noqa: BLE001 - this is what the fuzz counts
        return "traceback", traceback.format_exc(limit=-3), ""
    text = err.getvalue().strip()
    if code == 0:
        return "ok", text, sink.getvalue()
    lines = [x for x in text.splitlines() if x.startswith("mimunav ")]
    return ("refused" if code == 2 and len(lines) == 1 else "traceback"), text[-300:], ""


def results(argv, stdout, out):
    """What a successful command produced, comparable across runs: the table's text, the
    compensated log's channels, the replay summary and the diagnosis (paths left out)."""
    import json

    from mimunav.flightlog import FlightLog
    name = argv[0]
    if name == "table":
        return stdout
    if name == "compensate":
        with FlightLog(out / "comp.mcap") as log:
            return {t: log.read(t).tobytes() for t in sorted(log.channels)}
    if name == "replay":
        doc = json.loads((out / "replay" / "summary.json").read_text())
        return {k: v for k, v in doc.items() if k not in ("log", "calibration", "elapsed_s")}
    if name == "diagnose":
        doc = json.loads((out / "d.json").read_text())
        return {k: v for k, v in doc.items() if k != "log"}
    return None


def recovered_subset(original, recovered):
    """Every message of the recovered log is the original's message of that channel and
    time, byte for byte (what `--recover` keeps is never altered)."""
    import numpy as np

    from mimunav.flightlog import FlightLog
    with FlightLog(original) as a, FlightLog(recovered) as b:
        for topic in b.channels:
            kept, full = b.read(topic), a.read(topic)
            k = np.searchsorted(full["log_time"], kept["log_time"])
            if np.any(k >= len(full)) or full[np.minimum(k, len(full) - 1)].tobytes() != \
                    kept.tobytes():
                return False
    return True


def key(argv):
    """A command's name for counting and for its reference result."""
    return argv[0] + (" --recover" if "--recover" in argv else "")


def references(log, cal, folder):
    """{key: result} of every command on the undamaged log (each must succeed)."""
    folder.mkdir(exist_ok=True)
    out = {}
    for argv in commands(log, cal, folder):
        outcome, err, stdout = run(argv)
        if outcome != "ok":
            raise AssertionError(f"the undamaged log fails {argv[0]}: {err}")
        out[key(argv)] = results(argv, stdout, folder)
    return out


def case_file(folder, damaged):
    """A fresh case folder holding the damaged bytes as damaged.mcap; (folder, path)."""
    import shutil
    case = folder / "case"
    shutil.rmtree(case, ignore_errors=True)
    case.mkdir()
    path = case / "damaged.mcap"
    path.write_bytes(damaged)
    return case, path


def judge(argv, original, case, reference, damaged):
    """(outcome, stderr) of one command on a damaged file: 'ok' only when the result is the
    undamaged log's (for --recover: only the original's messages), else 'laundered' or
    'altered'; 'input modified' when the damaged file changed; otherwise `run`'s outcome."""
    outcome, err, stdout = run(argv)
    if outcome == "ok":
        if "--recover" in argv:
            if not recovered_subset(original, case / "recovered.mcap"):
                outcome = "altered"
        elif results(argv, stdout, case) != reference[key(argv)]:
            outcome = "laundered"
    if (case / "damaged.mcap").read_bytes() != damaged:
        outcome = "input modified"
    return outcome, err

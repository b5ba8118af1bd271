"""The sensor level of a flight read from its log block by block (`diagnosis.samples`: the
per-sample columns spilled to scratch files, the bins made a block at a time with halos
across the edges) against the same flight held whole."""
import math

import numpy as np
import pytest

from mimunav.diagnosis import concealed, design, levels, library, samples
from mimunav.diagnosis.document import document
from mimunav.evaluation import flight as flight_module
from mimunav.motion.profile import Profile
from mimunav.sensors import simulation
from mimunav.sensors.mimu import MimuUnit

# a climb and a roll, then 15 s straight on: the temperature and the vibration move, the
# rates reach 200 deg/s, so every kind of regressor varies across the blocks
PROFILE = {"name": "streamed", "start": {
    "latitude_deg": 45.0, "longitude_deg": 7.0, "height_m": 500.0, "speed_m_s": 80.0,
    "heading_deg": 30.0}, "segment": [
        {"kind": "hold", "duration_s": 8.0},
        {"kind": "pull", "load_factor": 2.5, "flight_path_change_deg": 10.0},
        {"kind": "roll", "rate_deg_s": 200.0, "angle_deg": 360.0},
        {"kind": "hold", "duration_s": 15.0}]}
BLOCK = 1 << 13         # 8.2 s at 1 kHz: the first edge at the pull's onset


def _diagnosed(log, model, stream, tmp):
    """(diagnosis.json's document, `samples.Bins` of every candidate on every usable sample)
    of the log held or streamed."""
    flight, cal, level, why = levels.load(str(log), str(model), stream=stream)
    assert (flight.stream_block is not None) == stream
    diag = levels.diagnose(flight, cal, level)
    diag.level_choice = why
    stage = samples.sample_stage(flight, cal, tmp)
    usable = (stage.flags == 0) & stage.inside
    terms = samples.temperature_references(library.candidates(), stage, usable)
    binned = samples.binned(stage, usable, design.bins(stage.t, flight.fog_t), terms,
                            flight.stream_block)
    return document(str(log), diag, 0.05), binned


def _differences(a, b, path=""):
    """Where two documents differ: floats beyond 1e-9 relative (and 1e-12 absolute)."""
    if isinstance(a, dict):
        if set(a) != set(b):
            return [(path, "keys", set(a) ^ set(b))]
        return [d for k in a for d in _differences(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list):
        if len(a) != len(b):
            return [(path, "length", len(a), len(b))]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, (int, float)):
        if math.isnan(a) and math.isnan(b):
            return []
        close = abs(a - b) <= max(1e-9 * max(abs(a), abs(b)), 1e-12)
        return [] if close else [(path, a, b)]
    return [] if a == b else [(path, a, b)]


@pytest.mark.slow
def test_a_streamed_diagnosis_is_the_held_one(tmp_path, monkeypatch):
    """Blocks of 2 k samples, a hidden gyro scale factor: every number of the diagnosis
    (findings, intervals, tests, the residual map, the agreement) as held, to 1e-9, and so
    every candidate's bins."""
    unit = MimuUnit.draw(7)
    unit.mounting = concealed.proof_mounting()
    hidden = [{"effect": "scale_factor", "sensor": "gyro", "axis": "x", "coefficient": 2e-3}]
    log, _ = simulation.simulate_flight(Profile.from_dict(PROFILE), tmp_path / "f.mcap", 7,
                                        unit=unit, hide=hidden, progress=False)
    model = tmp_path / "model.json"
    unit.coefficients.save(str(model))
    held, held_bins = _diagnosed(log, model, False, None)
    monkeypatch.setattr(flight_module, "STREAM_ABOVE", 0)
    monkeypatch.setattr(flight_module, "STREAM_BLOCK", BLOCK)
    streamed, streamed_bins = _diagnosed(log, model, True, tmp_path)
    assert [(f["effect"], f["sensor"], f["axis"]) for f in held["findings"]][:1] == \
        [("scale_factor", "gyro", "x")]
    assert _differences(held, streamed) == []
    # the bins of every candidate (most never reach the document), each to 1e-9 of its
    # largest value: a halo too short for a derivative window or the vibration's filter
    # moves some by 1e-3 and more
    pairs = [(getattr(held_bins, k), getattr(streamed_bins, k))
             for k in ("t", "residual", "inputs", "w_dot", "norms", "extremes")]
    pairs += [(held_bins.matrices[c][:, a:a + k], streamed_bins.matrices[c][:, b:b + k])
              for c in range(6)
              for (j, (a, k)), (_, (b, _)) in zip(held_bins.slots[c].items(),
                                                  streamed_bins.slots[c].items())]
    pairs += [(x[:, :4], y[:, :4]) for x, y in zip(held_bins.matrices, streamed_bins.matrices)]
    assert len(pairs) > 100
    for x, y in pairs:
        assert np.allclose(y, x, rtol=0, atol=1e-9 * np.nanmax(np.abs(x)), equal_nan=True)


@pytest.mark.parametrize("scratch", [False, True])
def test_twin_columns_are_held_once_and_part_where_they_differ(monkeypatch, scratch):
    """`samples.binned` holds a term's columns once where they equal columns placed before
    them on the whole flight, and gives them their own from the block where they part (the
    bins before it copied from the twin): every term's bins are its own, block by block, in
    memory and in scratch files (`spill.ScratchMatrix`)."""
    rng = np.random.default_rng(1)
    nb, m = 40, 10                              # 40 bins of 10 samples, blocks of 10 bins
    inputs, residual = rng.normal(size=(nb, 6)), rng.normal(size=(nb, 6))
    own = rng.normal(size=(nb, 2))
    parting = own.copy()
    parting[25:] += 1.0                         # equal to `own` in the first two blocks
    columns = [{0: inputs[:, [0]]},             # the channel's own input: a twin throughout
               {0: own, 3: own[:, :1]},         # placed
               {0: parting}]                    # a twin of term 1 until bin 25

    def block_bins(samples, usable, a, b, m_, terms, far):
        r = slice(a // m, b // m)
        return (np.arange(nb)[r], residual[r], inputs[r], inputs[r, :3], inputs[r, :4],
                np.arange(nb)[r], inputs[r, :4], [{c: x[r] for c, x in t.items()}
                                                  for t in columns])
    monkeypatch.setattr(samples, "_block_bins", block_bins)
    stage = type("Stage", (), {"t": np.arange(nb * m) * 1e-3})()
    terms = [{"effect": "scale_factor"}] * 3
    out = samples.binned(stage, np.ones(nb * m, bool), (m, 0), terms, block=10 * m,
                         scratch=scratch)
    for j, t in enumerate(columns):
        for c, x in t.items():
            first, k = out.slots[c][j]
            assert np.array_equal(out.matrices[c][:, first:first + k], x), (j, c)
    assert out.slots[0][0] == (1, 1) and out.matrices[0].shape[1] == 4 + 2 + 2
    assert out.slots[0][2][0] == 6 and out.matrices[3].shape[1] == 5
    held = samples.binned(stage, np.ones(nb * m, bool), (m, 0), terms)     # one block
    assert held.matrices[0].shape[1] == 8 and held.slots[0] == out.slots[0]

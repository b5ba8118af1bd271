"""Compensation equations (seed S1 eqs. 1-4) and the calibration-file contract."""
import json
import math
import warnings

import numpy as np
import pytest

from mimunav.compensation.wild_values import REPLACED, SATURATED, UNUSABLE
from mimunav.compensation.calibration_file import Calibration
from mimunav.compensation.model import CalibrationError, compensate, raw_from_physics
from mimunav.sensors.mimu import MimuUnit

G0 = 9.80665


def spec_transcription(doc, u_a, u_w, temp, freq):
    """The contract's equations, written out term by term from log-format.md section 2,
    one sample and one axis at a time (an independent implementation)."""
    acc, gyr = doc["accel"], doc["gyro"]
    out_a, out_w = [], []
    for k in range(len(u_a)):
        v_a = [u_a[k][i] - (acc["ct"][i][0] + acc["ct"][i][1] * temp[k][i]
                            + acc["ct"][i][2] * temp[k][i] ** 2) for i in range(3)]
        v_w = [u_w[k][i] - (gyr["cw"][i][0] + gyr["cw"][i][1] * freq[k][i]
                            + gyr["cw"][i][2] * freq[k][i] ** 2) for i in range(3)]
        a = [acc["A0"][i] + sum(acc["A1"][i][j] * v_a[j] for j in range(3))
             + acc["A2"][i] * v_a[i] ** 2 + acc["A3"][i] * v_a[i] ** 3 for i in range(3)]
        w = [gyr["W0"][i] + sum(gyr["W1"][i][j] * v_w[j] for j in range(3))
             + gyr["W2"][i] * v_w[i] ** 2 + gyr["W3"][i] * v_w[i] ** 3
             + sum(gyr["C"][i][j] * a[j] for j in range(3)) for i in range(3)]
        out_a.append(a)
        out_w.append(w)
    return np.array(out_a), np.array(out_w)


def test_compensation_agrees_with_a_transcription_of_the_spec():
    rng = np.random.default_rng(3)
    for seed in range(5):
        unit = MimuUnit.draw(seed)
        doc = json.loads(json.dumps(unit.coefficients.as_dict()))
        n = 200
        u_a, u_w = rng.uniform(-3, 3, (n, 3)), rng.uniform(-2.2, 2.2, (n, 3))
        temp = rng.uniform(0, 70, (n, 3))
        freq = rng.uniform(7900, 12100, (n, 3))
        a_ref, w_ref = spec_transcription(doc, u_a, u_w, temp, freq)
        f, w, flags = compensate(Calibration.from_dict(doc), u_a, u_w, temp, freq,
                                 filter_outliers=False)
        np.testing.assert_allclose(f, a_ref, rtol=1e-12, atol=1e-10)
        np.testing.assert_allclose(w, w_ref, rtol=1e-12, atol=1e-12)
        assert not flags.any()


@pytest.mark.slow
def test_round_trip_physics_raw_physics_over_range_and_temperature():
    rng = np.random.default_rng(5)
    for seed in range(10):
        unit = MimuUnit.draw(seed)
        n = 20000
        f = rng.uniform(-1, 1, (n, 3)) * unit.range_accel
        w = rng.uniform(-1, 1, (n, 3)) * unit.range_gyro
        t_acc = rng.uniform(0, 70, (n, 3))
        freq = unit.thermal.resonance_frequency(rng.uniform(0, 70, (n, 3)))
        u_a, u_w = raw_from_physics(unit.coefficients, f, w, t_acc, freq)
        f2, w2, _ = compensate(unit.coefficients, u_a, u_w, t_acc, freq, filter_outliers=False)
        assert np.abs(f2 - f).max() <= 1e-9 * unit.range_accel
        assert np.abs(w2 - w).max() <= 1e-9 * unit.range_gyro


def _cal_doc(**changes):
    doc = MimuUnit.draw(1).coefficients.as_dict()
    for path, value in changes.items():
        block, _, key = path.partition("__")
        if key:
            doc[block][key] = value
        elif value is None:
            doc.pop(block)
        else:
            doc[block] = value
    return doc


@pytest.mark.parametrize("changes, message", [
    (dict(format="other/1"), "format is 'other/1'"),
    (dict(format="mimunav-calibration/0"), "format is 'mimunav-calibration/0'"),  # older
    (dict(format=None), "format is None"),
    (dict(model="quadratic"), "model 'quadratic' is not one of"),
    (dict(accel__A1=[[1, 0], [0, 1]]), r"accel.A1 has shape \(2, 2\), expected \(3, 3\)"),
    (dict(gyro__W0=[0, float("nan"), 0]), "gyro.W0 has non-finite values"),
    (dict(gyro__W1=[[1, 2, 3], [2, 4, 6], [0, 0, 1]]), "W1 is singular"),
    (dict(accel__A1=[[1, 0.002, 0], [0, 1, 0.001], [0.001, 0.003, 0]]),   # a zeroed diagonal
     r"A1 is singular or nearly so \(condition number [0-9.e+]+, above 100"),
    (dict(accel__A7=[0, 0, 0]), r"keys \['A7'\]"),
    (dict(accel__ct="hot"), "accel.ct is not numeric|accel.ct has shape"),
    (dict(gyro__W0=["0.1", "0", "0"]), "gyro.W0 is not numeric"),   # text, read as 0.1 before
    (dict(accel=None), "accel.A1 is required"),
    # a simulated unit's or flight's file given as the model: where its coefficients are
    (dict(format="mimunav-unit/1"), "unit's true coefficients are its `coefficients` object"),
    (dict(format="mimunav-truth/1"), "its `mimu` object's `coefficients`"),
])
def test_malformed_calibration_files_say_what_is_wrong(changes, message):
    with pytest.raises(CalibrationError, match=message):
        Calibration.from_dict(_cal_doc(**changes), source="cal.json")


def test_linear_and_cold_start_models(tmp_path):
    doc = _cal_doc()
    lin = {"format": doc["format"], "model": "linear", "unit": "u",
           "accel": {"A0": doc["accel"]["A0"], "A1": doc["accel"]["A1"]},
           "gyro": {"W0": doc["gyro"]["W0"], "W1": doc["gyro"]["W1"]}}
    cal = Calibration.from_dict(lin)
    assert not cal.A2.any() and not cal.C.any()           # absent keys mean zero
    with pytest.raises(CalibrationError, match='takes only A0, A1, W0, W1'):
        Calibration.from_dict(dict(lin, accel=dict(lin["accel"], A2=[0, 0, 0])))
    path = tmp_path / "lin.json"
    cal.save(path)
    assert Calibration.load(path).as_dict() == cal.as_dict()
    with pytest.raises(FileExistsError):
        cal.save(path)
    # cold start: E = E(T)/(a + b T) + (c + d T) + e dT, per axis (seed S3)
    coef = {k: [v] * 3 for k, v in dict(a=1.02, b=-1e-4, c=0.01, d=2e-4, e=-3e-3).items()}
    cold = dict(lin, model="cold-start", window_s=2.0,
                accel=dict(lin["accel"], **coef), gyro=dict(lin["gyro"], **coef))
    cal = Calibration.from_dict(cold)
    n = 10
    temp = np.linspace(10, 19, n)[:, None] * np.ones(3)
    u = np.full((n, 3), 0.5)
    f, w, _ = compensate(cal, u, u, temp, temp, filter_outliers=False, t=np.arange(n) * 1.0)
    e_t = np.asarray(lin["accel"]["A0"]) + u @ np.asarray(lin["accel"]["A1"]).T
    d_t = temp - temp[np.maximum(np.arange(n) - 2, 0)]
    expected = e_t / (1.02 - 1e-4 * temp) + 0.01 + 2e-4 * temp - 3e-3 * d_t
    np.testing.assert_allclose(f, expected, rtol=1e-14)
    with pytest.raises(CalibrationError, match="needs the sample times"):
        compensate(cal, u, u, temp, temp)
    again = Calibration.from_dict(json.loads(json.dumps(cal.as_dict())))   # file round trip
    assert again.as_dict() == cal.as_dict() and again.as_dict()["window_s"] == 2.0
    with pytest.raises(CalibrationError, match="window_s"):
        Calibration.from_dict({k: v for k, v in cold.items() if k != "window_s"})


def test_bad_raw_samples_are_flagged_never_silent():
    unit = MimuUnit.draw(2)
    n = 2000
    t = np.arange(n) / 1000
    f = np.stack([np.sin(t), np.cos(t), -G0 + 0 * t], -1) * 10
    w = np.stack([np.sin(2 * t), 0 * t, np.cos(t)], -1)
    temp = np.full((n, 3), 25.0)
    freq = unit.thermal.resonance_frequency(temp)
    u_a, u_w = raw_from_physics(unit.coefficients, f, w, temp, freq)
    u_a[500, 1] += 0.5                     # a wild value (5 g)
    u_w[900, 2] = np.nan                   # a dropped reading
    u_a[1500:1510, 0] = 10.0               # beyond the range: saturated
    f2, w2, flags = compensate(unit.coefficients, u_a, u_w, temp, freq,
                               unit.range_accel, unit.range_gyro)
    assert flags[500] & REPLACED and flags[900] & REPLACED
    assert np.all(flags[1500:1510] & SATURATED)
    assert abs(f2[500, 1] - f[500, 1]) < 1e-3 and abs(w2[900, 2] - w[900, 2]) < 1e-4
    good = np.setdiff1d(np.arange(n), [500, 900, *range(1500, 1510)])
    assert not flags[good].any()
    np.testing.assert_allclose(f2[good], f[good], atol=1e-9)
    u_w[:, 1] = np.nan                     # a whole channel missing
    changed = []                           # the filters are process-wide: one set here
    with warnings.catch_warnings():        # would silence the FOG's navigation thread too
        warnings.simplefilter("error")     # and no warning is raised
        with pytest.MonkeyPatch.context() as mp:
            for name in ("simplefilter", "filterwarnings", "resetwarnings"):
                mp.setattr(warnings, name, lambda *a, name=name, **k: changed.append(name))
            _, _, flags = compensate(unit.coefficients, u_a, u_w, temp, freq)
    assert not changed
    assert np.all(flags & UNUSABLE)
    with pytest.raises(ValueError, match=r"gyro_volts must have shape \(N, 3\)"):
        compensate(unit.coefficients, u_a, u_w[:, :2], temp, freq)


def test_voltage_offset_gauge_is_the_same_compensation():
    """with_voltage_offset re-expands eqs. 1/3 about a shifted voltage: the same raw
    readings give the same outputs to round-off, with offsets of 0.1 V, where every
    re-expanded term (A2 d^2, A3 d^3, 3 A3 d^2 ...) is far above round-off."""
    unit = MimuUnit.draw(3)
    cal = unit.coefficients
    cal.A2, cal.A3, cal.W2, cal.W3 = (cal.A2 + 0.05, cal.A3 + 0.02, cal.W2 + 0.01,
                                      cal.W3 + 0.005)
    shifted = cal.with_voltage_offset([0.1, -0.2, 0.05], [0.3, 0.1, -0.15])
    rng = np.random.default_rng(0)
    u_a, u_w = rng.normal(0, 1, (50, 3)), rng.normal(0, 1, (50, 3))
    temp, freq = rng.uniform(0, 70, (50, 3)), rng.uniform(9e3, 1.1e4, (50, 3))
    a = compensate(cal, u_a, u_w, temp, freq, filter_outliers=False)
    b = compensate(shifted, u_a, u_w, temp, freq, filter_outliers=False)
    for x, y in zip(a[:2], b[:2]):
        np.testing.assert_allclose(y, x, rtol=0, atol=1e-12 * np.abs(x).max())
    assert not np.allclose(shifted.A0, cal.A0)


def test_wild_value_filter_at_its_threshold():
    """Seed S1 section 3.2: on a curving signal with white noise sigma, a spike of 3 times
    the threshold 6 sqrt(6) sigma is flagged and replaced at any position (the ends
    included), one of 0.3 times it is not, nor is a step, nor the curvature of a fast clean
    sinusoid; nothing else is flagged."""
    from mimunav.compensation.wild_values import wild_value_filter
    n, sigma = 4000, 1e-3
    k = np.arange(n)
    rng = np.random.default_rng(7)
    clean = np.stack([np.sin(2 * np.pi * k / 400), np.cos(2 * np.pi * k / 250),
                      0.5 * np.sin(2 * np.pi * k / 97)], -1)
    x = clean + rng.normal(0, sigma, (n, 3))
    threshold = 6 * np.sqrt(6) * sigma
    big = {0: 0, 1: 1, 1000: 2, n - 2: 0, n - 1: 1}
    small = {2000: 0, 2500: 1, 3000: 2}
    for pos, axis in big.items():
        x[pos, axis] += 3 * threshold
    for pos, axis in small.items():
        x[pos, axis] += 0.3 * threshold
    x[3300:, 2] += 10 * threshold                     # a step: agrees with one side
    flags = np.zeros(n, np.uint8)
    out = wild_value_filter(x, flags)
    wild = {int(p) for p in np.flatnonzero(flags & REPLACED)}
    assert wild == set(big), sorted(wild)
    for pos, axis in big.items():
        if 0 < pos < n - 1:                 # inside: interpolated between its neighbours
            assert abs(out[pos, axis] - clean[pos, axis]) < 10 * sigma
        else:                               # at an end: the neighbouring sample's value
            assert out[pos, axis] == x[1 if pos == 0 else n - 2, axis]
    for start in (n - 3, n - 4, 3, 4):      # three samples past a step agree with them
        stepped = clean + rng.normal(0, sigma, (n, 3))
        if start > n // 2:
            stepped[start:, 2] += 10 * threshold
        else:
            stepped[:start, 2] += 10 * threshold
        flags = np.zeros(n, np.uint8)
        wild_value_filter(stepped, flags)
        assert not flags.any(), (start, np.flatnonzero(flags))
    fast = np.stack([np.sin(2 * np.pi * k / 7.3)] * 3, -1)        # curvature, no noise
    flags = np.zeros(n, np.uint8)
    wild_value_filter(fast + rng.normal(0, 1e-9, (n, 3)), flags)
    assert not flags.any()


def _wild_by_the_rule(x, limit):
    """The wild-value rule of `wild_value_filter`'s docstring, sample by sample in plain
    Python (its former numba kernel): the oracle of the vectorised `find_wild`."""
    n, wild = len(x), np.zeros(x.shape, bool)
    for j in range(x.shape[1]):
        for k in range(n):
            v = x[k, j]
            if not math.isfinite(v):
                wild[k, j] = True
                continue
            curve = 0.0
            for c in range(2, 6):
                for lo, ok in ((k - c - 1, k >= c + 1), (k + c + 1, k <= n - c - 2)):
                    if ok:      # summed from the sample nearest k outwards, as before
                        near, centre = (k - c + 1, k - c) if lo < k else (k + c - 1, k + c)
                        curve = max(curve, abs(x[near, j] - 2.0 * x[centre, j] + x[lo, j]))
            tol = limit[j] + 2.0 * curve if math.isfinite(curve) else limit[j]
            if 0 < k < n - 1 and abs(v - 0.5 * (x[k - 1, j] + x[k + 1, j])) <= tol * 0.5:
                continue
            sides = [p for p in (2.0 * x[k - 1, j] - x[k - 2, j] if k >= 2 else math.nan,
                                 2.0 * x[k + 1, j] - x[k + 2, j] if k <= n - 3 else math.nan)
                     if math.isfinite(p)]
            wild[k, j] = bool(sides) and not any(abs(v - p) <= tol for p in sides)
    return wild


@pytest.mark.slow
@pytest.mark.parametrize("dense", [0.0, 1e9])
def test_wild_samples_are_found_by_the_rule_sample_by_sample(monkeypatch, dense):
    """The vectorised `find_wild` equals the rule written sample by sample, bit for bit, on
    short and long records with spikes, steps, quantised values, NaN and +-inf, zero limits
    and records of 1 to 5 samples (edges, where the curvature's windows are cut short) -
    with the curvature from the candidates' neighbourhoods and from the whole record."""
    from mimunav.compensation import wild_values
    from mimunav.compensation.wild_values import find_wild
    monkeypatch.setattr(wild_values, "DENSE_CANDIDATES", dense)
    rng = np.random.default_rng(5)
    with_wild = 0
    for trial in range(120):
        n = int(rng.integers(1, 40)) if trial % 2 else int(rng.integers(200, 600))
        t = np.arange(n) / 1000.0
        x = np.column_stack([np.sin(2 * np.pi * rng.uniform(1, 300) * t),
                             rng.normal(0, 1e-3, n), np.cumsum(rng.normal(0, 1e-3, n))])
        x += rng.normal(0, 1e-3, x.shape)
        hit = rng.integers(0, n, max(1, n // 30))
        x[hit, rng.integers(0, 3, len(hit))] += rng.normal(0, 0.05, len(hit))
        for bad in (np.nan, np.inf, -np.inf):
            if rng.random() < 0.5:
                hit = rng.integers(0, n, max(1, n // 50))
                x[hit, rng.integers(0, 3, len(hit))] = bad
        if rng.random() < 0.25:
            x = np.round(x * 300) / 300
        limit = rng.uniform(1e-4, 1e-2, 3) * (rng.random() < 0.85)
        with np.errstate(invalid="ignore", over="ignore"):
            expected = _wild_by_the_rule(x, limit)
        with_wild += expected.any()
        np.testing.assert_array_equal(find_wild(x, limit), expected, err_msg=f"trial {trial}")
    assert with_wild > 80


def test_found_terms_are_removed_not_added():
    """A calibration with a found gyro.x scale factor k = 0.01 (model 'linear+found') on an
    identity base: the output is (1 - k) x the reading (removed to first order), not
    (1 + k); base_model strips the suffix."""
    doc = Calibration.identity().as_dict()
    doc["model"] = "linear+found"
    doc["found"] = [{"effect": "scale_factor", "sensor": "gyro", "axis": "x",
                     "coefficient": 0.01}]
    cal = Calibration.from_dict(doc)
    assert cal.base_model == "linear" and Calibration.identity().base_model == "linear"
    n = 200
    u = np.tile([0.5, -0.2, 0.1], (n, 1))
    temp = np.full((n, 3), 25.0)
    f, w, flags = compensate(cal, u, u, temp, temp, filter_outliers=False,
                             t=np.arange(n) / 100.0)
    np.testing.assert_allclose(w[:, 0], 0.99 * 0.5, rtol=1e-12)
    np.testing.assert_allclose(w[:, 1:], u[:, 1:], rtol=1e-12)
    np.testing.assert_allclose(f, u, rtol=1e-12)


def test_flags_are_distinct_bits():
    """A sample only saturated carries SATURATED alone; the three flags are separate bits."""
    assert {REPLACED, SATURATED, UNUSABLE} == {1, 2, 4}
    unit = MimuUnit.draw(2)
    n = 500
    f = np.tile([0.0, 0.0, -G0], (n, 1))
    w = np.zeros((n, 3))
    temp = np.full((n, 3), 25.0)
    freq = unit.thermal.resonance_frequency(temp)
    u_a, u_w = raw_from_physics(unit.coefficients, f, w, temp, freq)
    u_a[200:260, 0] = 10.0                   # beyond the range for a whole minute of samples
    _, _, flags = compensate(unit.coefficients, u_a, u_w, temp, freq, unit.range_accel,
                             unit.range_gyro)
    assert np.all(flags[210:250] == SATURATED)


def test_cold_start_scale_must_not_vanish():
    from mimunav.sensors.mimu import MimuUnit as _U
    doc = _U.draw(4).coefficients.as_dict()
    doc["model"] = "cold-start"
    doc["window_s"] = 60.0
    for triad in ("accel", "gyro"):
        doc[triad].update({k: [1.0, 1.0, 1.0] if k == "a" else [0.0, 0.0, 0.0]
                           for k in ("a", "b", "c", "d", "e")})
    Calibration.from_dict(doc)
    doc["gyro"]["a"] = [1.0, 0.0, 1.0]
    with pytest.raises(CalibrationError, match="must not vanish"):
        Calibration.from_dict(doc)
    doc["gyro"]["a"] = [1.0, -1.0, 1.0]      # negative is a scale, not a vanishing one
    Calibration.from_dict(doc)


def test_outputs_clipped_below_the_declared_range_are_flagged():
    """A gyro whose amplifier clips at 2 V (about 400 deg/s at 5 mV/(deg/s), under the
    450 deg/s range and the 5 V ADC rails) in a fast roll: the plateau samples are flagged
    SATURATED although the compensated rate stays inside the range; a live, unclipped
    output is never flagged."""
    from mimunav.compensation.wild_values import SATURATED, clipped
    unit = MimuUnit.draw(6)
    n, rate = 4000, 1000.0
    t = np.arange(1, n + 1) / rate
    w_true = np.zeros((n, 3))
    w_true[1000:3000, 0] = np.radians(430.0) * np.sin(np.pi * (np.arange(2000) / 2000))
    f_true = np.tile([0.0, 0.0, -9.80665], (n, 1))
    raw = unit.simulate(t, w_true / rate, f_true / rate, np.full(n, 25.0),
                        np.random.default_rng(1))
    assert not clipped(raw["gyro_volts"]).any() and not clipped(raw["accel_volts"]).any()
    u = raw["gyro_volts"].copy()
    limit = 2.0 * np.sign(u[2000, 0])
    over = np.abs(u[:, 0]) > 2.0
    u[over, 0] = limit
    assert over.sum() > 50
    f, w, flags = compensate(unit.coefficients, raw["accel_volts"], u, raw["accel_temperature"],
                             raw["gyro_frequency"], unit.range_accel, unit.range_gyro)
    assert np.abs(w[over, 0]).max() < unit.range_gyro                  # inside the range
    hit = (flags & SATURATED) > 0
    assert hit[over].mean() > 0.95          # all but isolated noisy crossings of 2 V
    assert not hit[~over].any()


def test_identity_is_recognised_and_nothing_else_is():
    cal = Calibration.identity()
    assert cal.is_identity
    for key in ("A0", "W0", "C"):
        other = Calibration.from_dict(cal.as_dict())
        getattr(other, key).flat[1] = 1e-9
        assert not other.is_identity, key


@pytest.mark.slow
@pytest.mark.parametrize("held", [True, False])
def test_compensating_a_log_in_blocks_equals_compensating_it_whole(tmp_path, monkeypatch, held):
    """compensate_log reads the log in blocks (bounded memory): with blocks of 1000 samples
    and a spike, a NaN and a clipped run near block edges, found terms (a 1.5 s dT window;
    a hysteresis slope over +-5 s and a 0.2 s time skew, which reach ahead) and a
    cold-start model (2 s dT window), /mimu/imu equals the whole-record compensation of the
    same samples - whether the record is held for the three passes (a short one) or read
    from the file for each (a long one)."""
    import fuzzing
    from mimunav.compensation.log import compensate_log
    from mimunav.compensation.wild_values import flag_counts
    from mimunav.compensation import log as compensation_log
    monkeypatch.setattr(compensation_log, "HELD_SAMPLES", 10**9 if held else 0)
    from mimunav.flightlog import FlightLog, LogWriter
    from mimunav.flightlog import schemas as S
    log, cal_path = fuzzing.corpus_log(tmp_path)
    with FlightLog(log) as src:
        raw = src.read("/mimu/raw")
        meta = src.metadata()
    raw["gyro_volts"][999, 1] += 0.5                 # a spike at a block edge
    raw["accel_volts"][2001, 0] = np.nan              # a NaN after one
    top = np.nanmax(raw["accel_volts"][:, 2])
    raw["accel_volts"][2995:3010, 2] = top + 0.01     # a clipped run across an edge
    raw["accel_volts"][5500, 2] = top + 0.5           # a wild value above the clipping
    damaged = tmp_path / "edges.mcap"
    with LogWriter(damaged) as dst:
        for name, values in meta.items():
            dst.metadata(name, values)
        dst.write("/mimu/raw", S.RAW_MIMU, "mimu", raw["log_time"].astype(np.int64),
                  **{name: raw[name] for name, _, _ in S.BODIES[S.RAW_MIMU]})
    base = Calibration.load(cal_path).as_dict()
    found = dict(base, model="entire-63+found", found=[
        {"effect": "g_sensitivity", "sensor": "gyro", "axis": "x", "input_axis": "z",
         "coefficient": 2e-5},
        {"effect": "temperature_rate", "sensor": "accel", "axis": "y", "window_s": 1.5,
         "coefficient": 1e-3}])
    coef = {k: [v] * 3 for k, v in dict(a=1.02, b=-1e-4, c=0.01, d=2e-4, e=-3e-3).items()}
    cold = {"format": base["format"], "model": "cold-start", "unit": "u", "window_s": 2.0,
            "accel": {"A0": base["accel"]["A0"], "A1": base["accel"]["A1"], **coef},
            "gyro": {"W0": base["gyro"]["W0"], "W1": base["gyro"]["W1"], **coef}}
    rng = meta["sensor/mimu"]["range"]
    stamps = raw["log_time"].astype(np.int64)
    reach = dict(base, model="entire-63+found", found=[     # look ahead 5 s and 0.2 s
        {"effect": "thermal_hysteresis", "sensor": "accel", "axis": "x", "coefficient": 0.05},
        {"effect": "time_skew", "sensor": "imu", "coefficient": 0.2}])
    for k, doc in enumerate((base, found, cold, reach)):
        cal = Calibration.from_dict(doc)
        f, w, flags = compensate(cal, raw["accel_volts"], raw["gyro_volts"],
                                 raw["accel_temperature"], raw["gyro_frequency"],
                                 rng["accel_m_s2"], rng["gyro_rad_s"],
                                 t=(stamps - stamps[0]) / 1e9)
        out = tmp_path / f"out-{k}.mcap"
        counts = compensate_log(damaged, cal, out, block=1000)
        assert counts == flag_counts(flags)
        assert counts["replaced"] >= 3 and counts["saturated"] >= 15, counts
        with FlightLog(out) as got:
            imu = got.read("/mimu/imu")
        np.testing.assert_array_equal(imu["log_time"], raw["log_time"])
        # round-off only: the time skew's shift re-starts its cumulative sum per block
        np.testing.assert_allclose(imu["angular_velocity"], w, rtol=0, atol=1e-10)
        np.testing.assert_allclose(imu["linear_acceleration"], f, rtol=0, atol=1e-10)


def test_compensate_log_copies_the_other_channels_byte_for_byte(tmp_path):
    """Every channel but /mimu/imu leaves compensate_log with the CDR bytes and stamps it
    came with (a simulated flight: /mimu/raw, /fog/imu, /truth/state), whole or in blocks."""
    import fuzzing
    from mimunav.compensation.log import compensate_log
    from mimunav.flightlog import FlightLog
    from mimunav.flightlog.reader import PAYLOAD
    log, cal_path = fuzzing.corpus_log(tmp_path)
    for block in (None, 1000):
        out = tmp_path / f"out-{block}.mcap"
        compensate_log(log, Calibration.load(cal_path), out, block=block)
        with FlightLog(log) as src, FlightLog(out) as got:
            assert set(got.channels) == set(src.channels) | {"/mimu/imu"}
            assert {"/mimu/raw", "/fog/imu", "/truth/state"} <= set(src.channels)
            for topic in src.channels:
                assert np.array_equal(got.read(topic, PAYLOAD), src.read(topic, PAYLOAD)), topic


def test_triad_inverse_converges_where_coupling_and_nonlinearity_are_strong():
    """Newton's method on p0 + p1 v + p2 v^2 + p3 v^3 = y with off-diagonal couplings of
    30-40 % and nonlinearity of 10-20 % at |v| = 0.8 (far beyond any unit, still one root,
    where only the exact Jacobian converges in the allowed steps) recovers v to round-off."""
    from mimunav.compensation.model import invert_triad
    p0 = np.array([0.1, -0.2, 0.3])
    p1 = np.array([[1.0, 0.4, -0.3], [0.3, 1.2, 0.3], [-0.3, 0.4, 0.9]])
    p2 = np.array([0.15, -0.1, 0.12])
    p3 = np.array([0.1, 0.05, 0.08])
    v = np.random.default_rng(4).uniform(-0.8, 0.8, (500, 3))
    y = p0 + v @ p1.T + v * v * (p2 + p3 * v)
    np.testing.assert_allclose(invert_triad(p0, p1, p2, p3, y), v, rtol=0, atol=1e-10)


def test_a_log_whose_stamps_go_back_is_compensated_sorted(tmp_path):
    """Two swapped /mimu/raw stamps: the stream cannot take them, so compensate_log reads
    the channel whole and sorted, as the in-memory path does, instead of refusing."""
    import fuzzing
    from mimunav.compensation.log import compensate_log
    from mimunav.flightlog import FlightLog, LogWriter
    from mimunav.flightlog import schemas as S
    log, cal_path = fuzzing.corpus_log(tmp_path)
    with FlightLog(log) as src:
        raw, meta = src.read("/mimu/raw"), src.metadata()
    swapped = tmp_path / "swapped.mcap"
    order = np.arange(len(raw))
    order[[500, 501]] = order[[501, 500]]
    with LogWriter(swapped) as dst:
        for name, values in meta.items():
            dst.metadata(name, values)
        dst.write_encoded("/mimu/raw", S.RAW_MIMU, S.encode(
            S.RAW_MIMU, "mimu", raw["log_time"][order].astype(np.int64),
            **{name: raw[name][order] for name, _, _ in S.BODIES[S.RAW_MIMU]}),
            raw["log_time"][order].astype(np.int64))
    cal = Calibration.load(cal_path)
    compensate_log(swapped, cal, tmp_path / "a.mcap", block=1000)
    compensate_log(log, cal, tmp_path / "b.mcap")
    with FlightLog(tmp_path / "a.mcap") as a, FlightLog(tmp_path / "b.mcap") as b:
        np.testing.assert_array_equal(a.read("/mimu/imu")["angular_velocity"],
                                      b.read("/mimu/imu")["angular_velocity"])


def test_the_compensate_command_loads_neither_numba_nor_scipy(tmp_path):
    """`mimunav compensate` pays none of numba's start-up (import 0.35 s, first call 0.6-0.8
    s) nor scipy's: a fresh process that compensates a log has imported neither."""
    import subprocess
    import sys

    import fuzzing
    log, cal = fuzzing.corpus_log(tmp_path)
    probe = ("import sys; from mimunav import cli; "
             f"rc = cli.main(['compensate', {str(log)!r}, '--cal', {str(cal)!r}, '-o', "
             f"{str(tmp_path / 'out.mcap')!r}]); "
             "print(rc, sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'scipy', "
             "'quaternion'}))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, cwd=str(tmp_path)).stdout.strip().splitlines()[-1]
    assert out == "0 []"
    assert (tmp_path / "out.mcap").exists()

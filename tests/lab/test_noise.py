"""Random-error analysis (`mimunav.lab.allan`, `mimunav noise`): the IEEE-952 terms of records
whose terms are known, generated here with numpy alone (white noise and its running sum,
not the simulator's noise code), the command on a simulated parked flight against the
unit's truth file, and its refusals."""
import json
import math

import numpy as np
import pytest

from mimunav.lab import allan
from mimunav.cli import main
from mimunav.motion.profile import Profile
from mimunav.sensors.simulation import simulate_flight


def _record(n, rate, white, rrw, seed):
    """A rate record of interval means: white rate noise of density `white` (per sqrt(Hz))
    plus a rate random walk of `rrw` (per sqrt(s)), both by numpy."""
    rng = np.random.default_rng(seed)
    return (rng.standard_normal(n) * white * math.sqrt(rate)
            + np.cumsum(rng.standard_normal(n)) * rrw / math.sqrt(rate))


@pytest.mark.slow
def test_white_noise_and_rate_random_walk_are_recovered_within_their_intervals():
    rate, white, rrw = 50.0, 2e-3, 5e-5
    hits = {"random_walk": 0, "rate_random_walk": 0}
    for seed in range(6):
        x = _record(int(4 * 3600 * rate), rate, white, rrw, seed)
        terms = allan.fit_terms(allan.allan_deviation(x, rate))
        for name, truth in (("random_walk", white), ("rate_random_walk", rrw)):
            value, (lo, hi) = terms[name]
            assert value == pytest.approx(truth, rel=0.3), (name, seed)
            hits[name] += lo <= truth <= hi
        assert terms["bias_instability"][1][1] < 0.5 * white     # bounded, not invented
    assert hits["random_walk"] >= 3 and hits["rate_random_walk"] >= 3     # ~68 % intervals


def test_white_noise_alone_leaves_the_other_terms_at_zero_or_small():
    rate, white = 100.0, 1e-3
    x = _record(int(3600 * rate), rate, white, 0.0, 11)
    curve = allan.allan_deviation(x, rate)
    # the curve itself: N / sqrt(tau) inside its 68 % band at most points (independent of
    # any fit)
    model = white / np.sqrt(curve["tau_s"])
    inside = (curve["lo"] <= model) & (model <= curve["hi"])
    assert inside.mean() > 0.5
    terms = allan.fit_terms(curve)
    assert terms["random_walk"][0] == pytest.approx(white, rel=0.02)
    for name in ("bias_instability", "rate_random_walk", "rate_ramp"):
        tau_where = 100.0
        contribution = allan.model_adev({k: (terms[k][0] if k == name else 0.0)
                                         for k in allan.TERMS}, np.array([tau_where]))[0]
        assert contribution < 0.3 * white / math.sqrt(tau_where), name
    with pytest.raises(ValueError, match="100 finite samples"):
        allan.allan_deviation(x[:50], rate)


PARKED = {"name": "parked", "start": {"latitude_deg": 45.0, "longitude_deg": 10.0,
                                      "height_m": 100.0, "speed_m_s": 0.0, "heading_deg": 0.0},
          "segment": [{"kind": "hold", "duration_s": 600.0}]}


@pytest.fixture(scope="module")
def parked(tmp_path_factory):
    d = tmp_path_factory.mktemp("noise")
    log, truth_path = simulate_flight(Profile.from_dict(PARKED), d / "parked.mcap", seed=4,
                                      progress=False)
    truth = json.load(open(truth_path))
    (d / "true-cal.json").write_text(json.dumps(truth["mimu"]["coefficients"]))
    return d, log, truth


@pytest.mark.slow
def test_noise_command_reads_the_units_random_walk_from_a_parked_flight(parked, capsys):
    """`mimunav noise` on the MIMU (raw through its true coefficients) over the log's rest:
    the angle and velocity random walks of the truth file within 5 %, the bias instability
    of the accelerometers (0.5 mg) within a factor 1.5; the output contract."""
    d, log, truth = parked
    out = d / "mimu-noise"
    assert main(["noise", str(log), "--channel", "/mimu/raw", "--cal",
                 str(d / "true-cal.json"), "-o", str(out)]) == 0
    doc = json.load(open(out / "noise.json"))
    assert doc["format"] == "mimunav-noise/1" and doc["channel"] == "/mimu/raw"
    assert doc["span_chosen"].startswith("the longest static rest")
    noise = truth["mimu"]["noise"]
    for sensor in ("gyro", "accel"):
        for axis in "xyz":
            terms = doc[sensor][axis]["terms"]
            assert terms["random_walk"]["value"] == pytest.approx(noise[f"{sensor}_white"],
                                                                  rel=0.05)
            assert set(terms) == set(allan.TERMS)
            assert not doc[sensor][axis]["approximate"]      # white + flicker: the model fits
    b = [doc["accel"][a]["terms"]["bias_instability"]["value"] for a in "xyz"]
    assert np.all(np.abs(np.log(np.array(b) / noise["accel_flicker"])) < math.log(1.5))
    assert (out / "noise.png").stat().st_size > 10_000 and (out / "noise.md").exists()


@pytest.mark.slow
def test_noise_command_refuses_what_it_cannot_analyse(parked, capsys):
    d, log, _ = parked
    assert main(["noise", str(log), "--channel", "/mimu/raw", "-o", str(d / "x")]) == 2
    assert "--cal" in capsys.readouterr().err
    assert main(["noise", str(log), "--channel", "/fog/imu", "--span", "0:5",
                 "-o", str(d / "x")]) == 2
    assert "need >= 10 s" in capsys.readouterr().err
    assert main(["noise", str(log), "--channel", "/gnss/fix", "-o", str(d / "x")]) == 2
    assert not (d / "x").exists()


def _static(n_s, rate=100.0, seed=0):
    t = np.arange(0, n_s * rate) / rate
    rng = np.random.default_rng(seed)
    return (t, rng.normal(0, 1e-3, (len(t), 3)),
            rng.normal(0, 1e-3, (len(t), 3)) + [0, 0, -9.8])


def test_a_span_with_motion_or_drift_is_refused_whatever_its_length():
    from mimunav.errors import InputError
    from mimunav.reports.noise import choose_span
    t, w, f = _static(200)
    w[(t > 50) & (t < 120), 2] += 0.5                     # a 70 s turn at 29 deg/s
    for span in ((0.0, 190.0), (0.0, 60.0), (40.0, 190.0)):   # any span holding a step
        with pytest.raises(InputError, match="not static"):
            choose_span(t, w, f, [], span)
    t0, t1, how = choose_span(t, w, f, [])                 # the longest still stretch
    assert t1 - t0 >= 60 and (t0 >= 119 or t1 <= 51), (t0, t1)
    assert "still" in how
    t, w, f = _static(300)
    w[:, 0] += np.radians(0.5) * t / 300                   # a slow warm-up drift
    with pytest.raises(InputError, match="drifts"):
        choose_span(t, w, f, [], (0.0, 299.0))
    t, w, f = _static(100)
    t0, t1, how = choose_span(t, w, f, [], (50.0, 400.0))   # past the data: clipped
    assert t1 == pytest.approx(t[-1]) and "clipped" in how


def test_the_reference_rest_stops_before_the_motion():
    """Parked 60 s, then 0.1 g forward: the span from the reference's rest (cut
    `alignment.STATIC_MARGIN_S` before the first epoch over 0.2 m/s) ends before the
    vehicle moves."""
    from mimunav.navigation.rests import rest_intervals
    from mimunav.reports.noise import choose_span
    t, w, f = _static(120)
    f[t >= 60.0, 0] += 0.98
    tt = np.arange(0, 120, 0.2)
    v = np.zeros((len(tt), 3))
    v[:, 0] = np.clip(tt - 60.0, 0, None) * 0.98
    rests = rest_intervals(tt, v, float(t[0]), float(t[-1]))
    t0, t1, how = choose_span(t, w, f, rests)
    assert t1 < 60.0 - 0.5 and "reference" in how


def test_calibrate_takes_only_a_mimu_noise_file_and_only_measured_terms(tmp_path):
    from mimunav.errors import InputError
    from mimunav.reports import noise
    doc = {"format": noise.FORMAT, "channel": "/fog/imu", "span_s": [0, 100]}
    path = tmp_path / "fog.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="not the MIMU"):
        noise.load(path)
    term = lambda b: {"terms": {"bias_instability": {"value": b}}, "approximate": False}  # noqa
    doc.update(channel="/mimu/raw", gyro={a: term(0.0) for a in "xyz"},
               accel={"x": term(1e-3), "y": term(2e-3), "z": term(0.0)})
    path.write_text(json.dumps(doc))
    got = noise.load(path)
    assert set(got["instability"]) == {"accel"}            # gyro: upper bounds only
    assert got["instability"]["accel"] == pytest.approx(math.sqrt((1e-6 + 4e-6) / 2))
    assert "unit class kept" in got["source"]

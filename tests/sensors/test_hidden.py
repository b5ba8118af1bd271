"""The hidden physics of simulated recordings (`sensors.hidden`) against closed forms, and the
diagnosis' wander GLS (`diagnosis.wander`) against an explicit covariance: the two sides of
the concealed-data proof, each checked on its own."""
import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mimunav.cli import main
from mimunav.diagnosis import wander
from mimunav.sensors.accuracy import Accuracy, accuracy_of
from mimunav.sensors.hidden import HiddenPhysics, HiddenSet, delayed, parse_term
from mimunav.sensors.thermal import ThermalModel

RATE = 1000.0


def _ctx(n=2000, f=None, w=None, **extra):
    t = np.arange(1, n + 1) / RATE
    f = np.zeros((n, 3)) if f is None else f
    w = np.zeros((n, 3)) if w is None else w
    return dict(t=t, f_true=f, w_true=w, **extra)


def test_delay_of_a_ramp_is_the_interval_mean_tau_earlier():
    """x(t) = a t: the interval mean over (t_k - dt - tau, t_k - tau] is a (t_k - dt/2 - tau)."""
    ctx = _ctx()
    t, dt, tau = ctx["t"], 1 / RATE, 3.7e-4
    x = np.column_stack([2.0 * (t - dt / 2), -5.0 * (t - dt / 2), np.ones(len(t))])
    out = delayed(t, x, tau)
    k = slice(5, -5)
    assert np.allclose(out[k, 0], 2.0 * (t[k] - dt / 2 - tau), atol=1e-12)
    assert np.allclose(out[k, 1], -5.0 * (t[k] - dt / 2 - tau), atol=1e-12)
    assert np.allclose(out[k, 2], 1.0)


def test_time_skew_of_one_triad_leaves_the_other_alone():
    ctx = _ctx()
    ramp = np.outer(ctx["t"], [1.0, 2.0, 3.0])
    ctx.update(f_true=ramp, w_true=ramp)
    f, w = HiddenPhysics(parse_term("time_skew:accel:all=1e-3"))(ramp.copy(), ramp.copy(), ctx)
    assert np.allclose(w, ramp)
    assert np.allclose(f[10:-10] - ramp[10:-10], -1e-3 * np.array([1.0, 2.0, 3.0]), atol=1e-12)


def test_g_sensitivity_and_cross_coupling_are_the_contract_terms():
    rng = np.random.default_rng(1)
    f_true, w_true = rng.normal(size=(500, 3)) * 50, rng.normal(size=(500, 3))
    ctx = _ctx(500, f_true, w_true)
    _, w = HiddenPhysics(parse_term("g_sensitivity:gyro:x:z=2e-5"))(f_true, w_true, ctx)
    assert np.allclose(w[:, 0] - w_true[:, 0], 2e-5 * f_true[:, 2])
    assert np.allclose(w[:, 1:], w_true[:, 1:])
    _, w = HiddenPhysics(parse_term("cross_coupling:gyro:z:x=6e-4"))(f_true, w_true, ctx)
    assert np.allclose(w[:, 2] - w_true[:, 2], 6e-4 * w_true[:, 0])
    f, _ = HiddenPhysics(parse_term("scale_nonlinearity:accel:y=1e-6@order=2"))(f_true, w_true, ctx)
    assert np.allclose(f[:, 1] - f_true[:, 1], 1e-6 * f_true[:, 1] ** 2)


def test_mounting_misalignment_turns_the_sensor_frame():
    """A sensor frame turned by phi reads R(phi)' x; to first order x + x cross phi."""
    phi = np.array([1e-3, -2e-3, 0.5e-3])
    x = np.tile([3.0, -1.0, 9.8], (10, 1))
    f, w = HiddenPhysics(parse_term("mounting_misalignment:imu:all=1e-3/-2e-3/5e-4"))(
        x.copy(), x.copy(), _ctx(10, x, x))
    assert np.allclose(f, Rotation.from_rotvec(phi).inv().apply(x), atol=1e-15)
    assert np.allclose(f - x, np.cross(x, phi), atol=1e-5 * np.abs(x).max())
    assert np.allclose(w, f)


def test_size_effect_of_a_spin_is_the_centripetal_acceleration():
    """Constant spin W about z, proof mass at r = (a, b, c): w x (w x r) = -W^2 (a, b, 0)."""
    n, spin = 400, 5.0
    w = np.tile([0.0, 0.0, spin], (n, 1))
    f, _ = HiddenPhysics(parse_term("size_effect:accel:x=0.01/0.02/0.03"))(
        np.zeros((n, 3)), w.copy(), _ctx(n, np.zeros((n, 3)), w))
    assert np.allclose(f[:, 0], -spin ** 2 * 0.01)
    assert np.allclose(f[:, 1:], 0)


def test_gyro_temperature_terms_act_through_the_resonance_frequency():
    """Per Hz in the contract; the behaviour acts on the true gyro temperature T through
    f = f0 (1 + tcf (T - 25)): dw = k f0 tcf (T - T(0)). A linear warm-up at c degC/s gives
    the temperature_rate term c n once the window n is full."""
    thermal = ThermalModel.draw(np.random.default_rng(3))
    n = 4000
    temp = np.column_stack([np.linspace(10, 30, n)] * 3)
    ctx = _ctx(n, accel_temperature=temp, gyro_temperature=temp)
    zeros = np.zeros((n, 3))
    _, w = HiddenPhysics(parse_term("temperature_bias:gyro:y=-1e-4"), thermal)(zeros, zeros, ctx)
    f0, tcf = thermal.f0[1], thermal.tcf[1]
    assert np.allclose(w[:, 1], -1e-4 * f0 * tcf * (temp[:, 1] - temp[0, 1]))
    f, _ = HiddenPhysics(parse_term("temperature_rate:accel:z=2e-3@window_s=1.0"))(zeros, zeros, ctx)
    slope = (temp[1, 2] - temp[0, 2]) * RATE
    assert np.allclose(f[1500:, 2], 2e-3 * slope * 1.0)
    with pytest.raises(ValueError, match="thermal model"):
        HiddenPhysics(parse_term("temperature_bias:gyro:y=-1e-4"))(zeros, zeros, ctx)


def test_bias_pulse_and_sets_of_effects():
    ctx = _ctx()
    zeros = np.zeros((len(ctx["t"]), 3))
    pulse = HiddenPhysics(parse_term("bias_pulse:gyro:y=2e-3@t0=0.5@t1=0.8"))
    both = HiddenSet([pulse, HiddenPhysics(parse_term("g_sensitivity:gyro:y:x=1e-5"))])
    _, w = both(zeros + [9.8, 0, 0], zeros, dict(ctx, f_true=zeros + [9.8, 0, 0]))
    inside = (ctx["t"] >= 0.5) & (ctx["t"] <= 0.8)
    assert np.allclose(w[inside, 1], 2e-3 + 9.8e-5) and np.allclose(w[~inside, 1], 9.8e-5)
    assert [e["effect"] for e in both.as_dict()] == ["bias_pulse", "g_sensitivity"]
    assert both.as_dict()[0]["outside_vocabulary"] is True


@pytest.mark.parametrize("text, match", [
    ("warp_drive:gyro:x=1", "one of"), ("g_sensitivity:accel:x:z=1e-5", "sensor"),
    ("g_sensitivity:gyro:x=1e-5", "input axis"), ("scale_factor:gyro:q=1e-3", "axis"),
    ("size_effect:accel:x=0.01", "vector"), ("scale_factor:gyro:x=nan", "finite"),
    ("scale_nonlinearity:gyro:x=1e-6", "order"), ("bias_pulse:gyro:x=1e-3@t0=5@t1=2", "t1 > t0"),
    ("scale_factor gyro x 1e-3", "expected")])
def test_hide_syntax_errors_name_the_problem(text, match):
    with pytest.raises(ValueError, match=match):
        parse_term(text)


def test_wander_gls_equals_the_explicit_covariance():
    """Kalman-innovation least squares against GLS with the explicit covariance of a random
    walk (step variance lam r) plus white noise (r) and a diffuse constant - the estimate and
    the profile likelihood's ranking of the levels (as `sensor.Fitter` ranks them)."""
    rng = np.random.default_rng(7)
    n, lam = 300, 0.01
    x = np.column_stack([np.sin(np.arange(n) / 9.0), (np.arange(n) % 37) / 37.0])
    y = x @ [0.8, -1.5] + np.cumsum(rng.normal(0, math.sqrt(lam), n)) + rng.normal(0, 1, n) + 4
    present = rng.random(n) > 0.3
    z, _ = wander.innovations(np.column_stack([y, x]), present, lam)
    beta_kf = np.linalg.lstsq(z[:, 1:], z[:, 0], rcond=None)[0]
    idx = np.flatnonzero(present)
    steps = np.arange(1, n + 1)[idx]
    cov = np.eye(len(idx)) + lam * np.minimum.outer(steps, steps)
    design = np.column_stack([np.ones(len(idx)), x[idx]])
    ci = np.linalg.inv(cov)
    beta_gls = np.linalg.solve(design.T @ ci @ design, design.T @ ci @ y[idx])[1:]
    assert np.allclose(beta_kf, beta_gls, rtol=1e-6, atol=1e-8)
    # the profile likelihood over the levels peaks within a decade of the one drawn
    loglik = []
    for level in wander.LAMBDA_GRID:
        zz, logdet = wander.innovations(np.column_stack([y, x]), present, level)
        e = zz[:, 0] - zz[:, 1:] @ np.linalg.lstsq(zz[:, 1:], zz[:, 0], rcond=None)[0]
        loglik.append(-0.5 * (logdet + len(e) * math.log(e @ e / len(e))))
    assert 1e-3 <= wander.LAMBDA_GRID[int(np.argmax(loglik))] <= 1e-1


def test_wander_gls_with_a_varying_white_variance_equals_the_explicit_covariance():
    """The same with each row's white variance r s_k (a reference whose error grows as 1/v):
    Kalman-innovation least squares against GLS with diag(s) + the random walk explicitly,
    and not the estimate of a constant white variance."""
    rng = np.random.default_rng(8)
    n, lam = 300, 0.01
    shape = 1.0 + 99.0 * (np.arange(n) // 50 % 2)           # 1 and 100, in stretches of 50
    x = np.column_stack([np.sin(np.arange(n) / 9.0), (np.arange(n) % 37) / 37.0])
    y = x @ [0.8, -1.5] + np.cumsum(rng.normal(0, math.sqrt(lam), n)) + \
        rng.normal(0, 1, n) * np.sqrt(shape) + 4
    present = rng.random(n) > 0.3
    cols = np.column_stack([y, x])
    z, logdet = wander.innovations(cols, present, lam, shape)
    beta_kf = np.linalg.lstsq(z[:, 1:], z[:, 0], rcond=None)[0]
    idx = np.flatnonzero(present)
    steps = np.arange(1, n + 1)[idx]
    cov = np.diag(shape[idx]) + lam * np.minimum.outer(steps, steps)
    design = np.column_stack([np.ones(len(idx)), x[idx]])
    ci = np.linalg.inv(cov)
    beta_gls = np.linalg.solve(design.T @ ci @ design, design.T @ ci @ y[idx])[1:]
    assert np.allclose(beta_kf, beta_gls, rtol=1e-6, atol=1e-8)
    z1, logdet1 = wander.innovations(cols, present, lam)
    beta_flat = np.linalg.lstsq(z1[:, 1:], z1[:, 0], rcond=None)[0]
    assert not np.allclose(beta_flat, beta_gls, rtol=1e-3)
    assert logdet > logdet1 + 100          # the noisy stretches' variance is in the likelihood


def test_reference_accuracy_prior_turns_with_the_mounting_and_parses():
    acc = Accuracy(gyro_scale=1e-4, accel_scale=2e-4, gyro_misalignment_rad=1e-5,
                   accel_misalignment_rad=3e-5)
    import quaternion
    prior = acc.prior(quaternion.one)
    assert prior[0, 0] == pytest.approx(4e-8) and prior[1, 1] == pytest.approx(9e-10)
    assert prior[9, 9] == pytest.approx(1e-8) and prior[10, 10] == pytest.approx(1e-10)
    # 90 deg in pitch: the reference's x scale error is the MIMU's z scale error
    q = quaternion.from_rotation_vector([0, math.pi / 2, 0])
    acc2 = Accuracy(gyro_scale=0.0, accel_scale=0.0, gyro_misalignment_rad=0.0,
                    accel_misalignment_rad=0.0)
    assert np.allclose(acc2.prior(q), 0)
    turned = Accuracy(accel_scale=1e-4, gyro_scale=0, gyro_misalignment_rad=0,
                      accel_misalignment_rad=0).prior(q)
    assert turned[8, 8] == pytest.approx(1e-8) and turned[0, 0] == pytest.approx(1e-8)
    assert turned[1, 1] == pytest.approx(0, abs=1e-20)
    assert Accuracy.parse("gyro_scale=5e-5,accel_scale=6e-5").accel_scale == 6e-5
    assert accuracy_of({"accuracy": {"gyro_scale": 3e-5}}).gyro_scale == 3e-5
    assert accuracy_of({}).source.startswith("default")
    # the command line's keys over the log's, the log's over the defaults
    meta = {"accuracy": {"gyro_scale": 3e-5, "gyro_misalignment_rad": 2e-5}}
    both = accuracy_of(meta, Accuracy.parse("gyro_scale=5e-5"))
    assert (both.gyro_scale, both.gyro_misalignment_rad, both.accel_scale) == (5e-5, 2e-5, 2.5e-4)
    for bad in ("gyro_scale", "warp=1", "gyro_scale=-1", "gyro_scale=inf"):
        with pytest.raises(ValueError):
            Accuracy.parse(bad)


SHORT = """name = "short"
description = "20 s straight and level"
[start]
latitude_deg = 45.0
longitude_deg = 7.0
height_m = 500.0
speed_m_s = 100.0
heading_deg = 0.0
[[segment]]
kind = "coast"
duration_s = 20.0
"""


def test_simulate_hide_writes_the_answer_beside_the_log_only(tmp_path):
    log = tmp_path / "f.mcap"
    (tmp_path / "short.toml").write_text(SHORT)
    rc = main(["simulate", str(tmp_path / "short.toml"), "-o", str(log), "--seed", "3",
               "--hide", "g_sensitivity:gyro:x:z=1.8e-5", "--hide",
               "temperature_bias:gyro:z=-1.4e-4"])
    assert rc == 0
    truth = json.load(open(tmp_path / "f.truth.json"))
    assert [h["effect"] for h in truth["hidden"]] == ["g_sensitivity", "temperature_bias"]
    assert b"g_sensitivity" not in log.read_bytes()
    assert main(["simulate", str(tmp_path / "short.toml"), "-o", str(tmp_path / "g.mcap"),
                 "--hide", "g_sensitivity:gyro:x=1"]) == 2



def test_model_allowance_maps_the_calibration_covariance_to_terms():
    """The variance a calibration's stated covariance allows a term the model carries: C[i][j]
    for a g-sensitivity, A2_i / A1_ii^2 for an x^2 term, A1_ii (ct1 + 2 ct2 T0) for a
    temperature bias per degC - and nothing without a covariance."""
    from mimunav.compensation.calibration_file import Calibration
    from mimunav.diagnosis.design import model_allowance
    cal = Calibration()
    cal.A1 = np.diag([2.0, 4.0, 5.0])
    names = ["C[1][2]", "A2[1]", "ct[0][1]", "ct[0][2]"]
    cov = np.diag([1e-10, 1e-6, 4e-8, 1e-10])
    cov[2, 3] = cov[3, 2] = -1e-9
    assert model_allowance(cal, {"effect": "g_sensitivity", "sensor": "gyro", "axis": "y",
                                 "input_axis": "z"}) == 0.0
    cal.covariance = {"names": names, "matrix": cov.tolist()}
    g = {"effect": "g_sensitivity", "sensor": "gyro", "axis": "y", "input_axis": "z"}
    assert model_allowance(cal, g) == pytest.approx(1e-10)
    nl = {"effect": "scale_nonlinearity", "sensor": "accel", "axis": "y", "order": 2}
    assert model_allowance(cal, nl) == pytest.approx(1e-6 / 4.0 ** 4)
    tb = {"effect": "temperature_bias", "sensor": "accel", "axis": "x", "reference": 30.0}
    w = np.array([2.0, 2 * 30.0 * 2.0])
    assert model_allowance(cal, tb) == pytest.approx(w @ cov[2:, 2:] @ w)
    assert model_allowance(cal, dict(nl, axis="x")) == 0.0          # A2[0] not stated

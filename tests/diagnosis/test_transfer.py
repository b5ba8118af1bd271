"""The reference's gyro error through the lever-arm transfer (`diagnosis.design.transfer_allowance`):
a reference that reads its rates wrong moves the specific force it predicts at a MIMU that sits
elsewhere, by a lever-arm-like signature; that share of a lever arm or proof-mass offset is
the reference's stated accuracy, not physics the model lacks. And the false-alarm bench's
reference senses everything through its drawn errors (`diagnosis.transplant.null_variant`)."""
import dataclasses
from types import SimpleNamespace
from pathlib import Path

import numpy as np
import pytest

from mimunav.diagnosis import transplant
from mimunav.diagnosis.design import transfer_allowance, transfer_signatures

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"


def _transfer(w, w_dot, d):
    return np.cross(w, np.cross(w, d)) + np.cross(w_dot, d)


def test_the_signatures_are_the_first_order_change_of_the_transfer():
    rng = np.random.default_rng(4)
    w, w_dot = rng.normal(0, 2.0, (50, 3)), rng.normal(0, 20.0, (50, 3))
    d = np.array([-0.25, 0.15, -0.10])
    g = rng.normal(0, 1e-4, (3, 3))
    exact = _transfer(w @ (np.eye(3) + g).T, w_dot @ (np.eye(3) + g).T, d) - _transfer(w, w_dot, d)
    linear = transfer_signatures(w, w_dot, d) @ g.ravel()
    # the second-order rest is (G w) x ((G w) x d): |G|^2 of the signal, 1e-4 of the change
    assert np.abs(linear - exact).max() < 1e-3 * np.abs(exact).max()
    assert np.abs(exact).max() > 1e-5          # the change itself is not round-off


def test_a_reference_scale_error_is_a_lever_arm_of_twice_it_in_a_steady_turn():
    # without angular acceleration a rate scale s moves w x (w x d) by 2 s w x (w x d): a
    # lever arm 2 s d exactly, so the allowance of a lever arm is (2 d)(2 d)' var(s) when
    # the three scale errors are one (fully correlated)
    rng = np.random.default_rng(5)
    w = rng.normal(0, 1.5, (200, 3))
    d = np.array([0.3, -0.1, 0.2])
    columns = {c: np.stack([np.cross(w, np.cross(w, e))[:, c] for e in np.eye(3)], axis=1)
               for c in range(3)}                       # the lever arm's regressor per axis
    diagonal = np.zeros(9)
    diagonal[[0, 4, 8]] = 1.0
    sigma = 2.5e-4
    cov = sigma ** 2 * np.outer(diagonal, diagonal)
    allowance = transfer_allowance(columns, w, np.zeros_like(w), d, cov)
    np.testing.assert_allclose(allowance, 4 * sigma ** 2 * np.outer(d, d), rtol=1e-9,
                               atol=1e-12 * sigma ** 2)


@pytest.mark.skipif(not (SHARED / "foreign-flights").exists(), reason="shared data absent")
def test_the_signatures_are_what_a_wrong_reference_gyro_does_to_the_prediction():
    """The wiring, against the prediction itself: foreign-05's reference gyro read through
    (I + E) moves `reference.predicted_mimu`'s specific force at the MIMU (0.3 m away, turned
    90 deg) by the signatures of G = C E C' (C: reference -> MIMU axes) with the lever arm in
    the MIMU's axes - as `sensor._prepare` passes them - to the second-order rest."""
    import quaternion
    from mimunav.compensation.effects import derivative
    from mimunav.diagnosis.reference import TRANSFER_WINDOW_S, predicted_mimu
    from mimunav.frames import attitude
    flight = transplant.carrier(SHARED / "foreign-flights" / "foreign-05")[0]
    f0, w0, inside = predicted_mimu(flight)
    e = np.random.default_rng(0).normal(0, 2.5e-3, (3, 3))
    f1 = predicted_mimu(dataclasses.replace(flight, fog_w=flight.fog_w @ (np.eye(3) + e).T))[0]
    c = quaternion.as_rotation_matrix(np.conjugate(flight.mimu_mounting.q_vs)
                                      * flight.fog_mounting.q_vs)
    d = attitude.rotate(np.conjugate(flight.mimu_mounting.q_vs),
                        flight.mimu_mounting.lever_arm_m - flight.fog_mounting.lever_arm_m)
    w_dot = derivative(flight.mimu_t, w0, TRANSFER_WINDOW_S)
    linear = transfer_signatures(w0, w_dot, d) @ (c @ e @ c.T).ravel()
    change = (f1 - f0)[inside]
    rel = np.sqrt(np.mean((change - linear[inside]) ** 2) / np.mean(change ** 2))
    assert np.abs(change).max() > 1e-3 and rel < 0.02     # 2.5e-3 of E: its square's share


@pytest.mark.skipif(not (SHARED / "foreign-flights").exists(), reason="shared data absent")
def test_the_null_variants_reference_senses_its_vibration_through_its_errors():
    base = SHARED / "foreign-flights" / "foreign-03"
    seed = 2011                 # draws the vibration, neither the half rate nor a turn
    variant, _, drawn = transplant.null_variant(base, seed)
    assert drawn.get("vibration_g") and "rate" not in drawn and "mounting_turned_deg" not in drawn
    flight, _, f, w = transplant.carrier(base)
    vibrated, _ = transplant.vibrate(flight, {"accel": f.copy(), "gyro": w.copy()})
    e = np.asarray(drawn["reference_error"]["fog_f"])
    np.testing.assert_allclose(variant.fog_f, vibrated.fog_f @ (np.eye(3) + e).T, rtol=0,
                               atol=1e-12)
    old_order = flight.fog_f @ (np.eye(3) + e).T + (vibrated.fog_f - flight.fog_f)
    assert np.abs(variant.fog_f - old_order).max() > 1e-3     # E times 2 g of vibration


def test_an_angular_vibration_the_transfer_cannot_follow_is_measured():
    """`reference.unfollowed_vibration`, closed form: a 50 Hz angular vibration of 0.01 rad/s
    on x beside white noise, 400 Hz interval means; across 2 cm on y the transfer's error
    over a 10 ms bin is (2 pi 50) 0.01 / sqrt 2 (rms) times sinc(50 x 0.01) times 0.02 m
    times the share its derivative misses (a quartic Savitzky-Golay over 13 samples: its
    gain from scipy's coefficients) - a tractor's 27-60 Hz engine lines had made couplings
    of 0.02-0.04 on accel.z. White noise alone has no line to give, and two IMUs at one
    point no transfer; nor does a shock, which persists nowhere."""
    from mimunav.diagnosis.reference import unfollowed_vibration
    rng = np.random.default_rng(2)
    t = np.arange(1, 400 * 600 + 1) / 400.0
    mean = (np.cos(2 * np.pi * 50 * (t - 1 / 400)) - np.cos(2 * np.pi * 50 * t)) \
        / (2 * np.pi * 50 / 400)                    # the interval means of sin(2 pi 50 t)
    w = rng.normal(0, 0.003, (len(t), 3))
    w[:, 0] += 0.01 * mean
    got, hz = unfollowed_vibration(t, w, np.array([0.0, 0.02, 0.0]), 0.01, 400.0)
    from scipy.signal import savgol_coeffs      # the transfer's derivative: quartic, 13
    c = savgol_coeffs(13, 4, deriv=1, delta=1 / 400, use="dot")    # samples of 400 Hz
    k = np.arange(-6, 7)
    response = np.sum(c * np.exp(2j * np.pi * 50 * k / 400))       # its gain at 50 Hz
    missed = abs(response - 2j * np.pi * 50) / (2 * np.pi * 50)
    expected = 2 * np.pi * 50 * 0.01 / np.sqrt(2) * np.sinc(50 * 0.01) * 0.02 \
        * np.sinc(50 / 400) * missed                # the means' own attenuation; the miss
    assert got == pytest.approx(expected, rel=0.1) and hz == pytest.approx(50, abs=1)
    quiet = unfollowed_vibration(t, rng.normal(0, 0.003, (len(t), 3)), np.array([0, 0.02, 0]),
                                 0.01, 400.0)
    assert quiet is None or quiet[0] < 0.05 * expected
    # a shock (2 s of a 0.3 rad/s broadband jolt, a rocket's landing) persists nowhere: no
    # line (its mean spectrum had read one at 62 Hz)
    jolt = rng.normal(0, 0.003, (len(t), 3))
    jolt[400 * 300:400 * 302] += rng.normal(0, 0.3, (800, 3)) * np.hanning(800)[:, None]
    shock = unfollowed_vibration(t, jolt, np.array([0, 0.02, 0]), 0.01, 400.0)
    assert shock is None or shock[0] < 0.05 * expected
    assert unfollowed_vibration(t, w, np.zeros(3), 0.01, 400.0) is None


def test_a_shock_the_transfer_cannot_follow_is_left_out_and_nothing_else():
    """`reference.transfer_shocks`: 60 s at 501.3 Hz (a flight computer's clock, which the
    import puts back on its uniform times, `stamps.rounded_clock`), a smooth swing of 1
    rad/s at 0.5 Hz, and at 30 s a landing's jolt (the rate about x steps by 3 rad/s within
    4 ms and rings at 40 Hz for 0.2 s); across 22 cm the transfer's smoothed derivative
    misses the jolt by tens of m/s^2, which is left out - the swings (1 s of 2 rad/s at 2
    Hz, 5.5 m/s^2 across the arm, which it follows) and the noise are not. Two IMUs at one
    point, or a lever along the jolt's axis: nothing."""
    from mimunav.diagnosis.design import bins
    from mimunav.diagnosis.reference import transfer_shocks
    rng = np.random.default_rng(5)
    t = t_true = np.arange(1, int(60 * 501.3)) / 501.3
    w = np.zeros((len(t), 3))
    w[:, 2] = np.sin(2 * np.pi * 0.5 * t_true)
    swing = (t_true > 10.0) & (t_true < 11.0)               # 2 Hz, 2 rad/s: 5.5 m/s^2 at
    w[swing, 2] += 2.0 * np.sin(2 * np.pi * 2.0 * (t_true[swing] - 10.0)) \
        * np.sin(np.pi * (t_true[swing] - 10.0)) ** 2       # 22 cm, followed
    after = np.clip((t_true - 30.0) / 0.004, 0.0, 1.0)
    ring = np.where(t_true > 30.0, np.exp(-(t_true - 30.0) / 0.05), 0.0)
    w[:, 0] = 3.0 * after + 2.0 * ring * np.sin(2 * np.pi * 40 * (t_true - 30.0))
    predicted = np.hstack([np.tile([0.0, 0.0, -9.8], (len(t), 1)), w])
    measured = predicted + rng.normal(0, [0.01] * 3 + [0.001] * 3, predicted.shape)
    predicted[:, 3:] += rng.normal(0, 2e-4, (len(t), 3))     # the reference's own noise
    usable = np.ones(len(t), bool)
    m = bins(t, None, 0.01)
    shocks = transfer_shocks(t, measured, predicted, np.array([0.0, 0.22, 0.018]), m, usable)
    assert shocks[(t > 30.0) & (t < 30.03)].all()
    assert not shocks[np.abs(t - 30.2) > 0.5].any()
    assert not transfer_shocks(t, measured, predicted, np.zeros(3), m, usable).any()
    # the jolt turns about x: a lever along x feels none of it
    along = transfer_shocks(t, measured, predicted, np.array([0.22, 0.0, 0.0]), m, usable)
    assert not along[(t > 30.0) & (t < 30.03)].any()


def test_a_found_lever_arm_is_judged_as_a_declared_one():
    """`reference.transfer_doubt` on a recording whose reference carries a 50 Hz angular line
    of 0.01 rad/s: with no lever arm declared and none found there is no transfer and no
    doubt; a 12 cm lever arm found by the diagnosis (vehicle frame) is the transfer's own
    columns, and the doubt names it (a hexacopter's undeclared 12 cm, found, had left its
    null twin's verdict conclusive on wrong accelerometer terms)."""
    from mimunav.diagnosis.reference import transfer_doubt
    from mimunav.frames.mounting import Mounting
    rng = np.random.default_rng(3)
    t = np.arange(1, 400 * 300 + 1) / 400.0
    w = rng.normal(0, 0.003, (len(t), 3))
    w[:, 0] += 0.01 * np.sin(2 * np.pi * 50 * t)
    flight = SimpleNamespace(fog_t=t, fog_w=w, mimu_t=t, source="recording",
                             mimu_mounting=Mounting(), fog_mounting=Mounting())
    design = SimpleNamespace(residual=rng.normal(0, 0.003, (30000, 6)), bin_s=0.01)
    assert transfer_doubt(flight, design, []) == ""
    found = [{"effect": "lever_arm", "vector": [0.0, 0.12, 0.0]}]
    assert "12 cm between the two IMUs" in transfer_doubt(flight, design, found)

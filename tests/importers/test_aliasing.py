"""An IMU logged as instantaneous samples beside a faster reference IMU (`importers.aliasing`):
vibration above its Nyquist frequency folded into its band is measured, not assumed from the
rates - a unit that filtered before it sampled is not charged with it - and the sensor level
sets aside what it may have made (`diagnosis.levels.set_aside_aliased`)."""
import json
from types import SimpleNamespace

import numpy as np
import pytest

from mimunav.diagnosis.levels import set_aside_aliased
from mimunav.frames.mounting import Mounting
from mimunav.importers.aliasing import aliased
from mimunav.importers.recording import Recording
from mimunav.motion.intervals import means_of_instants

EPOCH_NS = 1_700_000_000_000_000_000


def _outputs(t, line, hz=26.4):
    """(w rad/s, f m/s^2) (N, 3) at times t (s): slow motion, and a rotor's line at `hz`
    (1 m/s^2, 0.01 rad/s) where `line`."""
    slow = np.column_stack([np.sin(0.3 * t), np.cos(0.2 * t), np.sin(0.11 * t)])
    tone = np.sin(2 * np.pi * hz * t)[:, None] * np.array([0.3, 0.2, 1.0])
    return 0.05 * slow + 0.01 * tone * line, \
        [0.0, 0.0, -9.81] + 0.5 * slow + tone * line


@pytest.mark.parametrize("filtered, hz", [(False, 26.4), (True, 26.4), (False, 80.0)])
def test_vibration_folded_into_instantaneous_samples_is_measured(filtered, hz):
    """A 50 Hz IMU sampled at instants beside a 200 Hz reference IMU under a 26.4 Hz line:
    taken unfiltered, its spectrum holds the line folded to 23.6 Hz (both sensors said);
    filtered before it was sampled (a MEMS part's low-pass), nothing is charged to it. A
    motor's 80 Hz line, above the IMU's rate, folds to 20 Hz: found too (only the band up
    to the rate had been folded - an independent review)."""
    rng = np.random.default_rng(3)
    t_ref, t = np.arange(0, 600, 0.005), np.arange(0, 600, 0.02)
    w_r, f_r = _outputs(t_ref, True, hz)
    w, f = _outputs(t, not filtered, hz)
    w, f = (means_of_instants(t, x + rng.normal(0, s, x.shape)) for x, s in ((w, 1e-3), (f, 0.02)))
    ns = EPOCH_NS + np.round(t * 1e9).astype(np.int64)
    rec = Recording("alias", "test", ns, w, f, Mounting.from_axes("FRD"),
                    reference_imu=dict(ns=EPOCH_NS + np.round(t_ref * 1e9).astype(np.int64),
                                       w=w_r, f=f_r, mounting=Mounting.from_axes("FRD")),
                    sampled_at_instants=True)
    said = aliased(rec)
    assert rec.real["aliasing"].startswith("checked against the reference IMU")
    assert sorted(said) == ([] if filtered else ["accel", "gyro"]), rec.real["aliasing"]
    rec.sampled_at_instants = False                 # interval means: nothing folds
    assert aliased(rec) == {}


def test_the_sensor_level_sets_aside_findings_on_an_aliased_sensor():
    """Findings on the accelerometers (and the unit's lever arm) leave for the import's
    words, which make the diagnosis inconclusive; a gyro's finding stays, and so does an
    accelerometer's constant bias (folded tones average to nothing)."""
    why = "the IMU's instantaneous samples fold vibration into their band"
    found = [{"label": "scale_factor accel.z", "sensor": "accel"},
             {"label": "lever_arm imu.all", "sensor": "imu"},
             {"label": "bias_shift gyro.x", "sensor": "gyro"},
             {"label": "bias_shift accel.y", "sensor": "accel", "effect": "bias_shift"}]
    diag = SimpleNamespace(findings=found, rejected=[], inconclusive=[])
    flight = SimpleNamespace(recording={"aliased": json.dumps({"accel": why})})
    set_aside_aliased(diag, flight)
    assert [f["label"] for f in diag.findings] == ["bias_shift gyro.x", "bias_shift accel.y"]
    assert [f["rejected"] for f in diag.rejected] == [why, why] and diag.inconclusive == [why]

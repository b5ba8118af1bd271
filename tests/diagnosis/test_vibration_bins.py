"""The bins' length where a reference on another clock vibrates (`design.vibration_bin_s`):
its re-expression on the MIMU's stamps errs at the vibration's lines, and in short bins that
error sits in the regressors and the residual alike and biases every linear term."""
import json

import numpy as np
import pytest

from mimunav.cli import main
from mimunav.diagnosis.design import (FAST_BIN_S, VIBRATION_SHARE, vibration_bin_s,
                                      vibration_share)
from mimunav.flightlog import LogWriter
from mimunav.flightlog import schemas as S
from mimunav.frames import attitude
from mimunav.frames.mounting import Mounting
from mimunav.motion import truth
from mimunav.motion.profile import Profile
from places import FLIGHTS

LINES = ((52.0, 2.0, 0.3), (104.0, 1.2, 1.1), (208.0, 0.6, 2.0))   # Hz, m/s^2, phase


def reference_force(t, line=2.0):
    """Specific force (m/s^2, (N, 3)) of a reference at stamps t (s): a 0.5 Hz swing of 1 m/s^2
    on x (the motion) and a 52 Hz line of `line` m/s^2 on z."""
    f = np.zeros((len(t), 3))
    f[:, 0] = np.sin(2 * np.pi * 0.5 * t)
    f[:, 2] = -9.81 + line * np.sin(2 * np.pi * 52.0 * t)
    return f


def test_the_share_is_the_lines_power_through_the_bin_means_sinc():
    """A line of amplitude A at 52 Hz beside a 0.5 Hz swing of 1 m/s^2: its share in bin
    means T long is A^2 sinc^2(52 T) / 1 (closed form; Welch's leakage within 10 %)."""
    t = np.arange(1, 400 * 200 + 1) / 400.0
    for T in (0.01, 0.05, 0.2):
        expected = 4.0 * np.sinc(52.0 * T) ** 2
        assert vibration_share(t, reference_force(t), T) == pytest.approx(expected, rel=0.1)


def test_bins_lengthen_only_for_a_vibrating_reference_on_another_clock():
    """On the MIMU's own stamps (one in 2 of a 800 Hz MIMU's) the bins stay FAST_BIN_S; on
    another clock (0.37 ms off) they lengthen to the shortest whose share is at most
    VIBRATION_SHARE, and say why; without the line they stay."""
    t_ref = np.arange(1, 400 * 200 + 1) / 400.0
    t_mimu = np.arange(1, 800 * 200 + 1) / 800.0
    f = reference_force(t_ref)
    assert vibration_bin_s(t_mimu, t_ref, f) == (FAST_BIN_S, "", "")
    bin_s, why, doubt = vibration_bin_s(t_mimu + 0.00037, t_ref, f)
    assert bin_s > FAST_BIN_S and "another clock" in why and "bins of" in why and not doubt
    assert vibration_share(t_ref, f, bin_s) <= VIBRATION_SHARE
    shorter = [b for b in (0.01, 0.02, 0.05, 0.1, 0.2) + tuple(np.arange(1, 26) / 52.0)
               if b < bin_s - 1e-9]
    assert all(vibration_share(t_ref, f, b) > VIBRATION_SHARE for b in shorter)
    assert vibration_bin_s(t_mimu + 0.00037, t_ref, reference_force(t_ref, 0.0)) == \
        (FAST_BIN_S, "", "")
    # broadband vibration (no line whole periods cancel) of 10 m/s^2 rms above 5 Hz: even
    # the bins that keep least of it keep more than VIBRATION_SHARE - cannot conclude
    from scipy.signal import butter, sosfiltfilt
    rough = reference_force(t_ref, 0.0)
    noise = sosfiltfilt(butter(4, 8.0, "highpass", fs=400.0, output="sos"),
                        np.random.default_rng(4).normal(0, 1, len(t_ref)))
    rough[:, 2] += 10.0 * noise / np.std(noise)
    bin_s, why, doubt = vibration_bin_s(t_mimu + 0.00037, t_ref, rough)
    assert f"even in {bin_s:.3g} s bins" in doubt


def test_bins_of_whole_periods_cancel_a_rotors_lines():
    """A helicopter's reference on another clock: a 6.6 Hz once-per-rev of 1.5 m/s^2 and its
    4-per-rev beside a 0.5 Hz swing of 1 m/s^2. In 0.2 s bins (1.3 cycles) the lines kept
    0.08 of the motion's variance and every diagnosis was inconclusive; bins of whole
    periods of the line cancel both: within VIBRATION_SHARE, no doubt."""
    t_ref = np.arange(1, 200 * 300 + 1) / 200.0
    t_mimu = np.arange(1, 400 * 300 + 1) / 400.0 + 0.00037
    f = reference_force(t_ref, 0.0)
    f[:, 2] += 1.5 * np.sin(2 * np.pi * 6.6 * t_ref) + 0.8 * np.sin(2 * np.pi * 26.4 * t_ref)
    assert vibration_share(t_ref, f, 0.2) > 5 * VIBRATION_SHARE
    bin_s, why, doubt = vibration_bin_s(t_mimu, t_ref, f)
    assert not doubt and vibration_share(t_ref, f, bin_s) <= VIBRATION_SHARE, (bin_s, why)
    assert round(bin_s * 6.6, 2) == round(bin_s * 6.6) and f"bins of {bin_s:.3g} s" in why


def _line_means(t, scale, derivative=False):
    """(N - 1, 2) interval means over (t[k-1], t[k]] of sum scale a sin(2 pi f t + phase)
    and of its cosine partner over LINES (with `derivative`, of their time derivatives)."""
    out = np.zeros((len(t) - 1, 2))
    dt = np.diff(t)
    for f, a, phase in LINES:
        w = 2 * np.pi * f
        p0, p1 = w * t[:-1] + phase, w * t[1:] + phase
        if derivative:      # the mean of d/dt over an interval: the change over its length
            out[:, 0] += scale * a * (np.sin(p1) - np.sin(p0)) / dt
            out[:, 1] += scale * a * (np.cos(p1) - np.cos(p0)) / dt
        else:
            out[:, 0] += scale * a * (np.cos(p0) - np.cos(p1)) / (w * dt)
            out[:, 1] += scale * a * (np.sin(p1) - np.sin(p0)) / (w * dt)
    return out


def _vibrating_imu(motion, t, mount, noise, rng):
    """(w rad/s, f m/s^2) sensor axes of an IMU at `mount` whose samples are exact means over
    (t[k-1], t[k]]: the motion's, rotor lines on the vehicle's down axis and an angular
    vibration of 1.5e-3 rad/s per m/s^2 of line about x and y, coherent with them (one
    rotor), its dw/dt x r at the mount's lever arm (its w x (w x r), 1e-6 m/s^2, left out)."""
    dth, dv = mount.sensor_increments(truth.generate(motion, t))
    dt = np.diff(t)[:, None]
    zero = np.zeros((len(t) - 1, 1))
    w_v = np.hstack([_line_means(t, 1.5e-3), zero])
    f_v = np.cross(np.hstack([_line_means(t, 1.5e-3, derivative=True), zero]),
                   mount.lever_arm_m)
    f_v[:, 2] += _line_means(t, 1.0)[:, 0]
    q_sv = np.conjugate(mount.q_vs)
    w = dth / dt + attitude.rotate(q_sv, w_v) + rng.normal(0, noise[0], dth.shape)
    f = dv / dt + attitude.rotate(q_sv, f_v) + rng.normal(0, noise[1], dv.shape)
    return w, f


@pytest.mark.slow
def test_a_vibrating_null_pair_on_two_clocks_names_no_accelerometer_term(tmp_path):
    """A null pair (no error at all but white noise) that vibrates as one rotor shakes it:
    lines of 2, 1.2 and 0.6 m/s^2 at 52-208 Hz, angular vibration coherent with them, the
    reference 12 cm away; the MIMU at 1 kHz on host stamps with 0.1 ms of jitter, the
    reference at 400 Hz on its own clock; the gentle flight's first 180 s. In 0.01 s bins the
    transfer's and the re-expression's errors at the lines had read as an accel.z scale of
    -0.028, a time skew of 4.8 ms and biases of 0.08-0.28 m/s^2 (truth: none); in the bins the
    vibration chooses, no accelerometer term is named and the bins say why."""
    from mimunav.importers import ros2
    from mimunav.importers.write import write_log
    motion = Profile.load(FLIGHTS / "gentle.toml").motion()
    rng = np.random.default_rng(2)
    mems = Mounting.from_axes("FLU")
    ref = Mounting(Mounting.from_rpy_deg((180.0, 0.0, 90.0)).attitude_wxyz, [0.10, -0.06, 0.03])
    t_m = np.arange(0.0, 180.0, 1e-3)
    w_m, f_m = _vibrating_imu(motion, t_m, mems, (1e-3, 0.01), rng)
    t_r = np.concatenate([[0.0], 0.00037 + np.arange(0.0, 179.99, 1 / 400)])
    w_r, f_r = _vibrating_imu(motion, t_r, ref, (1e-5, 1e-4), rng)
    t0 = 1_700_000_000_000_000_000
    jitter = np.clip(rng.normal(0, 1e-4, len(t_m) - 1), -4e-4, 4e-4)
    stamps = t0 + np.round((t_m[1:] + jitter) * 1e9).astype(np.int64)
    order = np.argsort(stamps, kind="stable")
    bag = tmp_path / "pair.mcap"
    with LogWriter(bag) as log:
        log.write("/mems/imu", S.IMU, "mems", stamps[order], **S.imu_fields(w_m[order],
                                                                            f_m[order]))
        log.write("/nav/imu", S.IMU, "nav", t0 + np.round(t_r[2:] * 1e9).astype(np.int64),
                  **S.imu_fields(w_r[1:], f_r[1:]))
    rec = ros2.read(bag, "/mems/imu", reference_imu_topic="/nav/imu", reference_imu_mounting=ref)
    write_log(rec, tmp_path / "log.mcap")
    assert main(["diagnose", str(tmp_path / "log.mcap"), "--json",
                 str(tmp_path / "d.json")]) == 0
    doc = json.loads((tmp_path / "d.json").read_text())
    assert [f["label"] for f in doc["findings"] if f["sensor"] != "gyro"] == [], doc["findings"]
    assert doc["bins"]["bin_s"] > FAST_BIN_S and "another clock" in doc["bins"]["why"]

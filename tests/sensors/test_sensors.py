"""Sensor models: units drawn as documented, temperatures, lever arms, noise levels."""
import math

import allantools
import numpy as np
import pytest

from mimunav.frames import attitude, earth
from mimunav.motion import truth
from mimunav.compensation.model import compensate
from mimunav.sensors.fog import FogUnit
from mimunav.sensors.mimu import MimuUnit
from mimunav.frames.mounting import Mounting
from mimunav.sensors import noise
from mimunav.sensors.noise import FLICKER_ADEV
from mimunav.sensors.thermal import ISA_LAPSE, bay_temperature, first_order_lag
from mimunav.motion.truth import Kinematics, Motion

G0 = 9.80665
DEG = math.pi / 180


def test_units_follow_seed_table_2_and_are_reproducible():
    for seed in range(20):
        u = MimuUnit.draw(seed, nonlinearity="table2")          # Table 2 taken literally
        c = u.coefficients
        for m, lo, hi in ((c.A1, 0.001, 0.02), (c.W1, 0.001, 0.005)):
            rel = np.abs(m / np.diag(m)[:, None])[~np.eye(3, dtype=bool)]
            assert rel.min() >= lo * 0.999 and rel.max() <= hi * 1.001
        a1, w1 = np.diag(c.A1), np.diag(c.W1)
        k2a, k3a = np.abs(c.A2) * G0 / a1**2, np.abs(c.A3) * G0**2 / a1**3
        k2w, k3w = np.abs(c.W2) * DEG / w1**2, np.abs(c.W3) * DEG**2 / w1**3
        assert np.all((2e-5 <= k2a) & (k2a <= 1e-4)) and np.all((5e-6 <= k3a) & (k3a <= 2e-5))
        assert np.all((1.5e-4 <= k2w) & (k2w <= 2.5e-4 * 1.0001))
        assert np.all((4e-10 <= k3w) & (k3w <= 1e-9 * 1.0001))
        c_dps_g = np.abs(c.C) / DEG * G0
        assert np.all((0.01 <= c_dps_g) & (c_dps_g <= 0.04 * 1.0001))
    assert MimuUnit.draw(3).as_dict() == MimuUnit.draw(3).as_dict()
    unit = MimuUnit.draw(3)
    assert {t["effect"] for t in unit.beyond_model} == {"temperature_rate", "scale_asymmetry"}
    assert MimuUnit.from_dict(unit.as_dict()).beyond_model == unit.beyond_model
    exact = MimuUnit.draw(3, beyond_model=False)
    assert exact.beyond_model == [] and \
        exact.coefficients.as_dict() == unit.coefficients.as_dict()     # same unit otherwise
    old_file = unit.as_dict()
    del old_file["beyond_model"]                                        # files before the key
    assert MimuUnit.from_dict(old_file).beyond_model == []
    assert MimuUnit.draw(3).as_dict() != MimuUnit.draw(4).as_dict()

@pytest.mark.parametrize("seed", range(8))
def test_table1_reading_keeps_the_nonlinearity_within_table1_residuals(seed):
    """The default nonlinearity reading (spec, Table 2 reading): the nonlinear part of the
    compensated output at full scale (30 g, 400 deg/s on one axis, voltage from the linear
    part alone) stays within Table 1's scale-factor fit residual (accel 0.05 % FS, gyro
    0.2 % FS); Table 2 taken literally exceeds it by more than 20x."""
    for reading, limit_factor in (("table1", 1.0), ("table2", 20.0)):
        c = MimuUnit.draw(seed, nonlinearity=reading, beyond_model=False).coefficients
        for p1, p2, p3, fs, residual in ((c.A1, c.A2, c.A3, 30 * 9.80665, 5e-4),
                                         (c.W1, c.W2, c.W3, np.radians(400), 2e-3)):
            v = fs / np.diag(p1)                                 # volts at full scale
            nonlinear = np.abs(p2 * v**2) + np.abs(p3 * v**3)
            if reading == "table1":
                assert nonlinear.max() <= residual * fs * (1 + 1e-9), (reading, nonlinear / fs)
            else:
                assert nonlinear.max() > limit_factor * residual * fs
    a, b = (MimuUnit.draw(seed, nonlinearity=r).coefficients for r in ("table1", "table2"))
    np.testing.assert_allclose(b.W2 / a.W2, b.W3 / a.W3)     # one factor per triad: ranking kept
    np.testing.assert_allclose(b.A2 / a.A2, b.A3 / a.A3)
    assert 30 < (b.A3 / a.A3)[0] < 60 and 30 < (b.W2 / a.W2)[0] < 60


def test_unit_file_round_trip(tmp_path):
    u = MimuUnit.draw(11)
    u.save(tmp_path / "u.json")
    assert MimuUnit.load(tmp_path / "u.json").as_dict() == u.as_dict()
    with pytest.raises(FileExistsError):
        u.save(tmp_path / "u.json")


def test_temperature_follows_the_first_order_lag_closed_form():
    t = np.arange(0, 3000.0, 0.5)
    y = first_order_lag(t, np.full(len(t), 40.0), 300.0, 10.0)
    np.testing.assert_allclose(y, 40 - 30 * np.exp(-t / 300.0), rtol=1e-12)
    u = MimuUnit.draw(5)
    t_acc, t_gyro = u.thermal.sensor_temperatures(t, np.full(len(t), 20.0))
    rise = np.asarray(u.thermal.self_heating)
    tau = np.asarray(u.thermal.tau)
    np.testing.assert_allclose(t_acc, 20 + rise[:3] * (1 - np.exp(-t[:, None] / tau[:3])),
                               rtol=1e-12)
    freq = u.thermal.resonance_frequency(t_gyro)
    np.testing.assert_allclose(u.thermal.temperature_at_frequency(freq), t_gyro, rtol=1e-10)
    # a climb of 3000 m at t = 0: the bay lags the ISA air, -19.5 degC, with its time constant
    bay = bay_temperature(t, np.full(len(t), 3000.0), 20.0, 0.0, tau=900.0)
    np.testing.assert_allclose(bay, 20 - ISA_LAPSE * 3000 * (1 - np.exp(-t / 900.0)), rtol=1e-12)


class RateTable(Motion):
    """A level table at a fixed site turning about down with rate w0 + alpha t."""
    def __init__(self, w0, alpha, duration=2.0):
        self.w0, self.alpha, self.t1 = w0, alpha, duration
        self.lat0, self.lon0, self.h0 = np.radians(40.0), 0.0, 50.0

    def kinematics(self, t):
        t = np.asarray(t, dtype=float)
        z = np.zeros_like(t)
        yaw = self.w0 * t + 0.5 * self.alpha * t**2
        w = np.stack([z, z, self.w0 + self.alpha * t], -1)
        dw = np.stack([z, z, z + self.alpha], -1)
        return Kinematics(np.zeros((len(t), 3)), np.zeros((len(t), 3)),
                          attitude.from_euler(yaw, z, z), w, dw)


def test_lever_arm_gives_centripetal_and_tangential_acceleration():
    w0, alpha, r = 3.0, 2.0, 0.25
    motion = RateTable(w0, alpha)
    t = np.arange(0, 2001) / 1000.0
    run = truth.generate(motion, t)
    mount = Mounting([1, 0, 0, 0], [r, 0, 0])
    _, dv = mount.sensor_increments(run)
    extra = (dv - run.dv) * 1000                       # interval means, m/s^2
    tm = 0.5 * (t[1:] + t[:-1])
    w = w0 + alpha * tm
    # -w^2 r along x (centripetal, plus the w^2 variance term alpha^2 dt^2/12),
    # alpha r along y (tangential); Earth rate changes these by < 1e-4 relative
    np.testing.assert_allclose(extra[:, 0], -(w**2 + alpha**2 * 1e-6 / 12) * r, rtol=1e-4)
    np.testing.assert_allclose(extra[:, 1], alpha * r, rtol=1e-3)
    # a rotated mounting: the sensor's x axis along vehicle y
    q_vs = attitude.from_euler(np.array([np.pi / 2]), np.zeros(1), np.zeros(1))
    mount = Mounting(attitude.quaternion.as_float_array(q_vs)[0], [r, 0, 0])
    _, dv_s = mount.sensor_increments(run)
    np.testing.assert_allclose(dv_s[:, 0] * 1000, alpha * r + run.dv[:, 1] * 1000, rtol=1e-3)


def _static_output(unit, hours, rate_hz, seed):
    """Compensated output of a unit resting level at 45 deg N (true coefficients), with
    its increments in closed form: Earth rate and gravity in body axes."""
    n = int(hours * 3600 * rate_hz)
    t = np.arange(1, n + 1) / rate_hz
    lat = np.radians(45.0)
    w_b = earth.earth_rate_ned(lat)
    f_b = -earth.gravity_ned(lat, 0.0)
    unit.rate_hz = rate_hz
    raw = unit.simulate(t, np.tile(w_b / rate_hz, (n, 1)), np.tile(f_b / rate_hz, (n, 1)),
                        np.full(n, 25.0), np.random.default_rng(seed))
    f, w, _ = compensate(unit.coefficients, raw["accel_volts"], raw["gyro_volts"],
                         raw["accel_temperature"], raw["gyro_frequency"])
    return f - f_b, w - w_b


@pytest.mark.slow
def test_allan_deviation_shows_the_configured_random_walk_and_bias_instability():
    """ADEV of the static output against the configured model sqrt((N/sqrt(tau))^2 +
    (0.664 B)^2) (IEEE 952): levels and slope at 0.1-1 s (white dominated for the gyro)
    within 10 %; the flicker floor at 300, 1000 and 3000 s inside each estimate's 99.9 %
    chi-square interval (Greenhall's equivalent degrees of freedom for flicker FM, allantools:
    843, 252 and 83 on 60 h - a 10 % band at 3000 s is 1.3 sigma), and the six channels'
    mean at 300 s within 4 standard errors of the model (about 4 %)."""
    unit = MimuUnit.draw(8)
    nz = unit.noise
    rate = 10.0
    f_err, w_err = _static_output(unit, 60.0, rate, seed=1)
    floor_ratio, floor_edf = [], None
    for err, white, flick in ((w_err, nz.gyro_white, nz.gyro_flicker),
                              (f_err, nz.accel_white, nz.accel_flicker)):
        floor = FLICKER_ADEV * flick
        for axis in range(3):
            taus, adev, _, _ = allantools.oadev(err[:, axis], rate=rate, data_type="freq",
                                                taus=np.array([0.1, 1.0, 300.0, 1000.0, 3000.0]))
            model = np.hypot(floor, white / np.sqrt(taus))   # the two terms in quadrature
            np.testing.assert_allclose(adev[:2], model[:2], rtol=0.1)
            slope = math.log(adev[1] / adev[0]) / math.log(10.0)
            assert slope == pytest.approx(math.log(model[1] / model[0]) / math.log(10.0),
                                          abs=0.05)
            for tau, got, want in zip(taus[2:], adev[2:], model[2:]):
                edf = allantools.edf_greenhall(alpha=-1, d=2, m=int(round(tau * rate)),
                                               N=len(err), overlapping=True)
                lo, hi = allantools.confidence_interval(got, edf, ci=0.999)
                assert lo <= want <= hi, (axis, tau, got / want, edf)
                floor_edf = edf if tau == taus[2] else floor_edf
            floor_ratio.append(adev[2] / model[2])
    se = 1 / math.sqrt(2 * floor_edf) / math.sqrt(len(floor_ratio))
    assert abs(np.mean(floor_ratio) - 1) < 4 * se, (floor_ratio, se)


def test_flicker_noise_has_the_two_sided_psd_b2_over_2_pi_f_in_every_band():
    """Exactly one synthesis period (`flicker_periods`): the mean periodogram of 300
    realisations, |X_k|^2 / (n fs), against IEEE 952's two-sided b^2 / (2 pi f) in octave
    bands from 1/(n dt) to below Nyquist within 4 standard errors, and at the Nyquist bin
    (real: chi2 with one degree of freedom); zero mean."""
    n, rate, b = 1024, 50.0, 0.3
    rng = np.random.default_rng(11)
    x = np.stack(list(noise.flicker_periods(rng, n, [b] * 300))).astype(float)
    freq = np.fft.rfftfreq(n, 1 / rate)
    ratio = (np.abs(np.fft.rfft(x, axis=1)[:, 1:]) ** 2 / (n * rate)
             / (b**2 / (2 * math.pi * freq[1:])))          # mean 1 in every bin
    edges = 2 ** np.arange(0, int(math.log2(n // 2)) + 1)
    for lo, hi in zip(edges[:-1], edges[1:]):
        band = ratio[:, lo - 1:hi - 1]
        se = band.std() / math.sqrt(band.size)
        assert abs(band.mean() - 1) < 4 * se, (lo, hi, band.mean(), se)
    nyquist = ratio[:, -1]
    assert abs(nyquist.mean() - 1) < 4 * nyquist.std() / math.sqrt(len(nyquist))
    assert abs(x.mean(axis=1)).max() < 1e-6 * x.std()     # no power at f = 0 (single
                                                            # precision synthesis)


def test_flicker_noise_wanders_from_start_to_end_as_the_psd_says():
    """What a navigation feels of a bias instability is how far the bias wanders over the
    flight. The difference between the means of a record's last and first tenth, over 400
    realisations, against IEEE 952's two-sided PSD b^2 / (2 pi f) from 1/(4 x record
    length) up (slower wander is the turn-on bias's: sensors.noise.FLICKER_SPAN) through
    that difference's filter (two L-sample means, Dirichlet kernel, 0.9 n apart),
    integrated to Nyquist here: rms within 4 standard errors (3.5 % each) of 1.025, what
    the synthesis' line spectrum expects. The record is 100 samples short of a power of
    two: a synthesis whose period is the record's length (or 1.006 of it, the next power of
    two) brings the end back to the start - 0.67 expected here."""
    n, rate, b = (1 << 14) - 100, 1.0, 1.0
    tenth = n // 10
    x = noise.flicker(np.random.default_rng(7), n, rate, [b] * 400)
    drift = x[-tenth:].mean(axis=0) - x[:tenth].mean(axis=0)
    span = (n - tenth) / rate                                  # s between the means' centres
    f = np.arange(1.0, 25 * span * rate) / (50 * span)        # Hz, 50 points a period of
    f = f[f >= rate / (4 * n)]                                 # sin(pi f span), to Nyquist
    s = np.sin(np.pi * f / rate)
    gain = (np.sin(tenth * np.pi * f / rate) / (tenth * s)) ** 2 * 4 * np.sin(np.pi * f * span) ** 2
    psd = b ** 2 / (2 * np.pi * f)                             # two-sided
    want = 2 * np.trapezoid(psd * gain, f)                     # both signs of f
    ratio = math.sqrt(np.mean(drift ** 2) / want)
    assert abs(ratio - 1.025) < 4 * 0.5 * math.sqrt(2 / len(drift)), ratio


@pytest.mark.parametrize("n", [1, 2, 21, 22, 1000, 16_284, 976_000, 10**6, 47_300_001])
def test_flicker_synthesis_length_is_even_fast_and_at_least_twice_the_record(n):
    """An even length (a real Nyquist bin), >= 2n (the record at most half a period), not
    much more, and with no prime factor above 5 (an FFT of a length with a large prime
    factor took 31.9 s where the nearest 5-smooth one took 2.7 s)."""
    m = noise.synthesis_length(n)
    assert m % 2 == 0 and 2 * n <= m <= 2.2 * n + 8
    for p in (2, 3, 5):
        while m % p == 0:
            m //= p
    assert m == 1


def test_fog_output_is_within_table_4_grade():
    fog = FogUnit.draw(2)
    assert np.all(np.abs(fog.gyro_bias) < 2 * DEG / 3600)
    assert np.all(np.abs(np.diag(fog.gyro_matrix) - 1) < 5e-4)
    n, rate = 200000, 1000.0
    t = np.arange(1, n + 1) / rate
    w_true = np.array([0.3, -0.2, 0.1])
    out = fog.simulate(t, np.tile(w_true / rate, (n, 1)), np.tile([0, 0, -G0 / rate], (n, 1)),
                       np.random.default_rng(0))
    mean_err = out["angular_velocity"].mean(axis=0) - fog.gyro_matrix @ w_true - fog.gyro_bias
    assert np.all(np.abs(mean_err) < 0.5 * DEG / 3600)   # noise + flicker over 200 s
    # pulse quantization carries the residual: summed increments lose nothing
    total = out["angular_velocity"].sum(axis=0) / rate
    assert np.all(np.abs(total - (fog.gyro_matrix @ w_true + fog.gyro_bias) * n / rate)
                  < 50 * DEG / 3600)


def test_the_table3_report_states_the_temperature_slopes_a_unit_is_drawn_with(monkeypatch):
    # the report's model-numbers table and the unit's draw read one constant: a gyro bias
    # slope pinned at 0.02 (deg/s)/degC (no curvature) is what the drawn unit's cw gives
    # between 25 and 26 degC through its resonance frequency, and what the report says
    from mimunav.compensation.model import poly2
    from mimunav.evaluation.campaign import Scenario
    from mimunav.reports.table3 import model_numbers_markdown
    from mimunav.sensors import mimu as mimu_module
    monkeypatch.setattr(mimu_module, "GYRO_TEMPERATURE_SLOPE_DEG_S", (0.02, 0.02))
    monkeypatch.setattr(mimu_module, "GYRO_TEMPERATURE_CURVATURE_DEG_S", (0.0, 0.0))
    unit = mimu_module.MimuUnit.draw(3)
    freq = unit.thermal.resonance_frequency(np.array([[25.0] * 3, [26.0] * 3]))
    volts = np.diff(poly2(unit.coefficients.cw, freq), axis=0)[0]
    slope = np.abs(volts * np.diag(unit.coefficients.W1)) / (math.pi / 180)
    np.testing.assert_allclose(slope, 0.02, rtol=1e-9)
    row = next(r for r in model_numbers_markdown(Scenario()) if "bias slope" in r)
    assert "gyro 0.02-0.02 (deg/s)/degC" in row

"""Seed S4 (Xu, Qiu, He, Meng 2011, eqs. 4-5): the gyros' nonlinear scale factor calibrated
with a rotation mechanism on a level rate table (`lab` procedure `rotation`).

Model, eq. 4 in its forward form, per gyro axis i, raw output U_i in volts:
    U_i = k0_i + k1_i w_i + k2_i w_i^2 + k3_i w_i^3
          + sum_{j != i} (M_ij w_j + Q_ij w_j^2) + sum_j G_ij f_j
w: the rate the sensor axes feel (rad/s), f: the specific force (m/s^2), both sensor axes.
The seed writes eq. 4 for one gyro alone; a triad also has cross-axis sensitivity M
(misalignment and coupling; M_ii = k1_i), the other axes' nonlinearity reaching output i
through that coupling, Q (0.5 % coupling x 0.16 % FS nonlinearity = 10 deg/h at 400 deg/s,
the size of k2's standard error), and g-sensitivity G (seed S1's C, forward). Left out, G
would alias into k1 (gravity along a swept axis varies as g sin(phi), like the rate input
W sin(phi); the table's two directions of rotation separate them) and Q into k2 (w_j^2 and
w_i^2 share cos 2phi; the window means separate them).

Input, eq. 5: the mechanism (axis horizontal) turns the unit at Omega while the table turns
at W about the vertical, so a gyro perpendicular to the mechanism axis sees W sin(phi) (plus
Earth rate): every revolution sweeps -W..W. The inputs are computed per sample from the
nominal lab state, the site and the encoder angle phi (never from the simulator), as interval
means in closed form (phi linear over an interval; the mechanism rate is the encoder's
angle change over the interval):
    w_s = C_sm [ mean Rz(phi)^T C_mp (W z + Rz(psi)^T w_ie^n) + (dphi/dt) z ]
    f_s = C_sm   mean Rz(phi)^T C_mp (-Rz(psi)^T g^n)
(psi: the table angle, m: the mechanism frame, p: the table's platform frame, `lab`).

Estimation in two stages - the seed's substitution of eq. 5 into eq. 4:
 1. per steady window, the outputs and every regressor are projected on the harmonics of phi,
    H = [1, cos phi, sin phi, cos 2phi, sin 2phi, cos 3phi, sin 3phi] (least squares over the
    window's samples): w_i^2 puts W^2 into the mean and cos 2phi, w_i^3 puts W^3 into sin phi
    and sin 3phi. The white noise of each window's amplitudes comes from second differences
    of its samples.
 2. generalised least squares of all windows' amplitudes on the projected regressors
    (`calibration.gls`); the window means also carry the unit's bias instability as a flicker
    process over the run (`calibration.flicker_covariance`); the covariance is scaled by
    chi2/dof when above 1.
Standard errors add the lab's setting errors (table tilt, table rate, the unit's mounting on
the mechanism, the mechanism's axis: refits at +1 sigma each) and, in k0, the turn-on
repeatability of the power-on.

Calibration file (`mimunav-calibration/1`, model `rotation-cubic`, documented in the README):
gyro {"k": [[k0 V, k1 V/(rad/s), k2 V/(rad/s)^2, k3 V/(rad/s)^3] per axis], "M": 3x3
V/(rad/s) (k1 on the diagonal), "Q": 3x3 V/(rad/s)^2 (zero diagonal), "G": 3x3 V/(m/s^2)}, "reference": {"gyro_frequency_hz"}: the
resonance frequencies the fit's k0 holds at (the unit's temperature offset is in k0), and the
covariance block of every fitted file. It calibrates the gyros only; a flight needs the
accelerometers too, so `compensate` refuses it.
"""
import json
import math
from dataclasses import dataclass, field

import numpy as np
import quaternion

from .runs import AXES, LabRun
from .gls import FitError, Fitted, add_covariance_sources, merge_errors, gls
from ..compensation.model import poly2
from ..files import write_atomic
from ..flightlog import FlightLog
from ..frames import attitude

MODEL = "rotation-cubic"
HARMONICS = 3
N_COEF = 11         # k0, k1, k2, k3, M_ij, M_ik, Q_ij, Q_ik, G_ix, G_iy, G_iz


@dataclass
class RotationRun:
    """A `rotation` lab run: the `LabRun` and the encoder angle phi (rad) at every sample."""
    lab: LabRun
    phi: np.ndarray
    mechanism: dict

    @classmethod
    def load(cls, path):
        run = LabRun.load(path)
        if run.procedure != "rotation":
            raise FitError(f"{path}: a {run.procedure!r} run; the rotation method needs the lab "
                           "procedure 'rotation' (the unit on a turning mechanism)")
        with FlightLog(path) as log:
            meta = log.metadata()
            if "/mimu/platform" not in log.channels:
                raise FitError(f"{path}: no /mimu/platform channel: the mechanism angle is the "
                               "rate input's phase (eq. 5)")
            joint = log.read("/mimu/platform", fields=("position",))
        mechanism = meta["lab"].get("mechanism")
        if not mechanism:
            raise FitError(f"{path}: the `lab` metadata has no `mechanism` record (base "
                           "attitude of the mechanism axis on the table)")
        epoch = int(meta["flight"]["epoch_unix_ns"])
        t_joint = (joint["log_time"].astype(np.int64) - epoch) / 1e9
        if len(t_joint) != len(run.t) or np.abs(t_joint - run.t).max() > 1e-6:
            raise FitError(f"{path}: /mimu/platform must be logged at every /mimu/raw stamp "
                           f"({len(t_joint)} angles for {len(run.t)} samples)")
        phi = np.asarray(joint["position"], float)
        if not np.isfinite(phi).all():
            raise FitError(f"{path}: non-finite mechanism angles")
        return cls(run, phi, mechanism)


def _rz_mean_t(phi0, phi1, v):
    """Mean over phi linear from phi0 to phi1 of Rz(phi)^T v, for v (n, 3) (closed form)."""
    d = phi1 - phi0
    moving = np.abs(d) > 1e-12
    safe = np.where(moving, d, 1.0)
    c = np.where(moving, (np.sin(phi1) - np.sin(phi0)) / safe, np.cos(phi0))
    s = np.where(moving, (np.cos(phi0) - np.cos(phi1)) / safe, np.sin(phi0))
    return np.column_stack([c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1], v[:, 2]])


def _rot(rv):
    return quaternion.as_rotation_matrix(quaternion.from_rotation_vector(rv))


def known_inputs(rr, window, tilt=(0.0, 0.0), rate_rel=0.0, fixture=(0.0, 0.0, 0.0),
                 axis=(0.0, 0.0)):
    """Interval-mean rate (rad/s) and specific force (m/s^2), sensor axes, (n, 3) each, over
    one window's sample intervals, for the nominal lab state perturbed by setting errors:
    table tilt (rad, 2), table-rate error (relative), the unit's mounting on the mechanism
    (small rotation vector, mechanism axes, rad) and the mechanism axis (rad, 2)."""
    run = rr.lab
    k = np.arange(window.k0, window.k1)
    t0, t1 = run.t[k - 1], run.t[k]
    lat, g = run.site["latitude"], run.site["gravity_m_s2"]
    omega = run.site["earth_rate_rad_s"]
    c_tilt = _rot([*tilt, 0.0])
    w_ie = c_tilt.T @ np.array([omega * math.cos(lat), 0.0, -omega * math.sin(lat)])
    g_n = c_tilt.T @ np.array([0.0, 0.0, g])
    rate = window.rate * (1 + rate_rel)
    psi = window.theta0 + rate * (0.5 * (t0 + t1) - window.t0)
    z = np.zeros((len(k), 3))
    w_p = _rz_mean_t(psi, psi, z + w_ie) + rate * np.array([0.0, 0.0, 1.0])
    f_p = -_rz_mean_t(psi, psi, z + g_n)
    c_pm = _rot([*axis, 0.0]) @ quaternion.as_rotation_matrix(
        attitude.from_wxyz(rr.mechanism["base_attitude_wxyz"]))
    phi0, phi1 = rr.phi[k - 1], rr.phi[k]
    c_ms = _rot(fixture) @ quaternion.as_rotation_matrix(attitude.from_wxyz(window.q_ps))
    w_m = _rz_mean_t(phi0, phi1, w_p @ c_pm)
    w_m[:, 2] += (phi1 - phi0) / (t1 - t0)
    f_m = _rz_mean_t(phi0, phi1, f_p @ c_pm)
    return w_m @ c_ms, f_m @ c_ms


def regressors(w, f, i):
    """The model's regressors of gyro axis i (module doc): (n, N_COEF)."""
    j, m = [a for a in range(3) if a != i]
    return np.column_stack([np.ones(len(w)), w[:, i], w[:, i] ** 2, w[:, i] ** 3,
                            w[:, j], w[:, m], w[:, j] ** 2, w[:, m] ** 2, f])


def coefficient_names(i):
    j, m = [a for a in range(3) if a != i]
    return ([f"k[{i}][{n}]" for n in range(4)] + [f"M[{i}][{j}]", f"M[{i}][{m}]"]
            + [f"Q[{i}][{j}]", f"Q[{i}][{m}]"] + [f"G[{i}][{a}]" for a in range(3)])


def harmonics(phi):
    """[1, cos phi, sin phi, ..., cos 3phi, sin 3phi] at angles phi: (n, 7)."""
    cols = [np.ones(len(phi))]
    for h in range(1, HARMONICS + 1):
        cols += [np.cos(h * phi), np.sin(h * phi)]
    return np.column_stack(cols)


@dataclass
class _Projection:
    """Per window: the map A from samples to harmonic amplitudes, (H^T H)^-1, and the
    gyro outputs' amplitudes (7, 3) with their white variance per axis."""
    a: list = field(default_factory=list)
    hh_inv: list = field(default_factory=list)
    amplitudes: list = field(default_factory=list)
    white: list = field(default_factory=list)


def _project_outputs(rr):
    run, out = rr.lab, _Projection()
    u = run.raw["gyro_volts"]
    counts = np.array([[w.k1 - w.k0] for w in run.windows])
    out.white = list(run.mean_variances(u) * counts)        # per sample, second differences
    for w in run.windows:
        k = np.arange(w.k0, w.k1)
        h = harmonics(0.5 * (rr.phi[k - 1] + rr.phi[k]))
        hh_inv = np.linalg.inv(h.T @ h)
        a = hh_inv @ h.T
        out.a.append(a), out.hh_inv.append(hh_inv)
        out.amplitudes.append(a @ u[k])
    return out


def _designs(rr, proj, **setting):
    """Per gyro axis, the stacked projected regressors over all windows (7 n_windows,
    N_COEF), for the lab state perturbed by `setting` (known_inputs; fixture per position)."""
    rows = [[], [], []]
    for w, a in zip(rr.lab.windows, proj.a):
        fix = setting.get("fixture")
        kw = dict(setting, fixture=(0.0, 0.0, 0.0) if fix is None else fix[w.position])
        rate, force = known_inputs(rr, w, **kw)
        for i in range(3):
            rows[i].append(a @ regressors(rate, force, i))
    return [np.concatenate(r) for r in rows]


def _covariance(rr, proj, i, k1_volts_per_rad_s):
    """Covariance of the stacked amplitudes of axis i: each window's white noise through
    its projection, plus the unit's flicker bias instability (in volts) in the means."""
    n_h = 2 * HARMONICS + 1
    n_w = len(rr.lab.windows)
    cov = np.zeros((n_w * n_h, n_w * n_h))
    for k, (hh_inv, white) in enumerate(zip(proj.hh_inv, proj.white)):
        cov[k * n_h:(k + 1) * n_h, k * n_h:(k + 1) * n_h] = white[i] * hh_inv
    b_volts = rr.lab.instability("gyro") * k1_volts_per_rad_s
    means = np.arange(n_w) * n_h
    cov[np.ix_(means, means)] += b_volts ** 2 * rr.lab.flicker()
    return cov


def _settings(rr):
    """The lab's setting errors at +1 sigma each: (source name, known_inputs kwargs)."""
    eq = rr.lab.equipment
    n_pos = 1 + max(w.position for w in rr.lab.windows)
    out = [(f"tilt{a}", {"tilt": tuple(eq["table_tilt_rad"] * (np.arange(2) == a))})
           for a in range(2)]
    out.append(("rate", {"rate_rel": eq["rate_rel"]}))
    out += [(f"mechanism-axis{a}", {"axis": tuple(eq["mechanism_axis_rad"] * (np.arange(2) == a))})
            for a in range(2)]
    for p in range(n_pos):
        for a in range(3):
            fix = np.zeros((n_pos, 3))
            fix[p, a] = eq["fixture_rad"]
            out.append((f"mounting{p}{AXES[a]}", {"fixture": fix}))
    return out


@dataclass
class RotationCalibration:
    """A fitted `rotation-cubic` file (module doc): k (3, 4), M, Q, G (3, 3), reference
    gyro frequencies (Hz), covariance block (names, standard_error, matrix, ...)."""
    k: np.ndarray
    M: np.ndarray
    Q: np.ndarray
    G: np.ndarray
    reference: dict
    covariance: dict
    unit: str = ""
    procedure: str = "rotation mechanism on a level rate table (seed S4 eqs. 4-5)"
    model: str = MODEL

    def as_dict(self):
        return {"format": "mimunav-calibration/1", "model": MODEL, "unit": self.unit,
                "procedure": self.procedure,
                "gyro": {"k": self.k.tolist(), "M": self.M.tolist(), "Q": self.Q.tolist(),
                         "G": self.G.tolist()},
                "reference": self.reference, "covariance": self.covariance}

    def save(self, path, force=False):
        write_atomic(path, json.dumps(self.as_dict(), indent=1) + "\n", force=force)

    @classmethod
    def from_dict(cls, doc, source="calibration"):
        if doc.get("model") != MODEL:
            raise FitError(f"{source}: model {doc.get('model')!r} is not {MODEL!r}")
        try:
            g = doc["gyro"]
            k, m, q, gs = (np.asarray(g[key], float) for key in ("k", "M", "Q", "G"))
        except (KeyError, TypeError, ValueError) as exc:
            raise FitError(f"{source}: gyro k (3x4), M, Q, G (3x3) needed: {exc}") from None
        if k.shape != (3, 4) or any(x.shape != (3, 3) for x in (m, q, gs)):
            raise FitError(f"{source}: gyro k must be 3x4, M, Q and G 3x3 (got {k.shape}, "
                           f"{m.shape}, {q.shape}, {gs.shape})")
        return cls(k, m, q, gs, doc.get("reference", {}), doc.get("covariance", {}),
                   str(doc.get("unit", "")), str(doc.get("procedure", "")))

    def values(self):
        """{name: fitted value} in the covariance block's naming."""
        out = {}
        for i in range(3):
            out.update(dict(zip(coefficient_names(i), _vector(self, i))))
        return out

    def gyro_output(self, w, f):
        """Predicted raw gyro outputs (V, (n, 3)) for rates w (rad/s) and specific force f
        (m/s^2), sensor axes (n, 3) each."""
        return np.column_stack([regressors(w, f, i) @ _vector(self, i) for i in range(3)])


def _vector(cal, i):
    j, m = [a for a in range(3) if a != i]
    return np.concatenate([cal.k[i], [cal.M[i, j], cal.M[i, m], cal.Q[i, j], cal.Q[i, m]],
                           cal.G[i]])


def fit(runs, unit="", noise=None):
    """Fit the rotation method to one `rotation` lab run (a path or `RotationRun`; one
    power-on). `noise`: the unit's measured random errors as `calibration.calibrate` takes
    them. Returns a RotationCalibration."""
    runs = [r if isinstance(r, RotationRun) else RotationRun.load(r) for r in runs]
    if len(runs) != 1:
        raise FitError(f"the rotation method fits one run (one power-on); {len(runs)} given")
    rr = runs[0]
    if noise:
        rr.lab.noise = dict(rr.lab.noise, source=noise["source"],
                            instability={**rr.lab.noise["instability"], **noise["instability"]})
    if len(rr.lab.windows) < 2 * N_COEF:
        raise FitError(f"{rr.lab.path}: {len(rr.lab.windows)} steady windows; the rotation "
                       "fit needs the table at several rates both ways")
    rates = {round(abs(w.rate), 6) for w in rr.lab.windows}
    if len(rates) < 4:
        raise FitError(f"{rr.lab.path}: {len(rates)} distinct table rates; k0..k3 need >= 4")
    proj = _project_outputs(rr)
    designs = _designs(rr, proj)
    perturbed = [(src, _designs(rr, proj, **kw)) for src, kw in _settings(rr)]
    fitted, vectors, rms, chi2 = Fitted({}), [], {}, {}
    nominal = 1.0 / (math.pi / 180 / 5e-3)          # datasheet 5 mV/(deg/s), V per rad/s
    for i in range(3):
        x = designs[i]
        y = np.concatenate([a[:, i] for a in proj.amplitudes])
        cov = _covariance(rr, proj, i, nominal)
        b, *_ = gls(x, y, cov)
        cov = _covariance(rr, proj, i, abs(b[1]))          # the unit's own scale
        b, cov_b, chi2[AXES[i]], rms[AXES[i]] = gls(x, y, cov)
        names = coefficient_names(i)
        fitted.values.update(zip(names, b))
        add_covariance_sources(fitted, names, cov_b, f"rotation-gls-gyro{i}")
        for src, x_s in perturbed:
            b_s, *_ = gls(x_s[i], y, cov)
            for name, d in zip(names, b_s - b):
                merge_errors(fitted.errors, name, {src: d})
        merge_errors(fitted.errors, names[0], {f"turn-on-gyro{i}": abs(b[1]) * rr.lab.turn_on("gyro")})
        vectors.append(b)
    names = list(fitted.values)
    cov_all = fitted.covariance(names)
    run = rr.lab
    freq = run.means(run.raw["gyro_frequency"]).mean(axis=0)
    return RotationCalibration(
        *_from_vectors(vectors), {"gyro_frequency_hz": freq.tolist()},
        {"names": names, "standard_error": np.sqrt(np.diag(cov_all)).tolist(),
         "matrix": cov_all.tolist(), "residual_rms": {"rotation gyro amplitudes (V)": rms},
         "chi2_per_dof": chi2,
         "note": "two-stage harmonic GLS + setting errors + turn-on repeatability, first-order "
                 "propagation (mimunav.lab.rotation)",
         "noise_model": run.noise}, unit)


def _from_vectors(vectors):
    """(k, M, Q, G) from each axis' coefficient vector (`coefficient_names` order); the
    inverse of `_vector`."""
    k, m, q, g = np.zeros((3, 4)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    for i, b in enumerate(vectors):
        j, l2 = [a for a in range(3) if a != i]
        k[i], g[i] = b[:4], b[8:11]
        m[i, i] = b[1]
        m[i, j], m[i, l2], q[i, j], q[i, l2] = b[4:8]
    return k, m, q, g


def held_out(cal, run):
    """Held-out check on a rotation run the fit did not see: per window and gyro axis the
    measured harmonic amplitudes (cos/sin 1..3 phi; the means carry the new power-on's bias)
    minus the fit's prediction, over their white noise. Returns {"z_rms": per axis,
    "error_rad_s_rms": per axis (amplitude error / k1), "n": amplitudes per axis}."""
    rr = run if isinstance(run, RotationRun) else RotationRun.load(run)
    proj = _project_outputs(rr)
    z, err = [[] for _ in range(3)], [[] for _ in range(3)]
    for w, a, amp, hh_inv, white in zip(rr.lab.windows, proj.a, proj.amplitudes,
                                        proj.hh_inv, proj.white):
        rate, force = known_inputs(rr, w)
        pred = a @ cal.gyro_output(rate, force)
        for i in range(3):
            d = (amp - pred)[1:, i]
            z[i] += list(d / np.sqrt(white[i] * np.diag(hh_inv)[1:]))
            err[i] += list(d / cal.k[i, 1])
    return {"z_rms": [float(np.sqrt(np.mean(np.square(v)))) for v in z],
            "error_rad_s_rms": [float(np.sqrt(np.mean(np.square(v)))) for v in err],
            "n": len(z[0])}


# ---- the unit's truth in the fit's gauge ---------------------------------------------------
def true_in_gauge(unit_coefficients, gyro_frequency):
    """The forward coefficients (k, M, G) of a unit whose truth is eqs. 3-4 (a `Calibration`
    of model entire-63), at resonance frequencies gyro_frequency (Hz, 3): the series
    reversion of w = W0 + W1 V + W2 V^2 + W3 V^3 + C f to third order,
        u = P (w - W0),  P = W1^-1
        V = u - P (W2 u^2) - P (W3 u^3) + 2 P (W2 u P (W2 u^2)) - P C f
    (powers and products element-wise), which is a cubic in w along each sensor axis:
    its coefficients along e_i give k_i, M[:, i] and Q[:, i]. Dropped: products of
    different axes' rates and of f with w (outside the model: < 0.1 deg/h at 400 deg/s for
    the unit class; tests/test_rotation_calibration.py)."""
    c = unit_coefficients
    p = np.linalg.inv(c.W1)

    def volts(w):
        u = (w - c.W0) @ p.T
        q = (c.W2 * u ** 2) @ p.T
        return u - q - (c.W3 * u ** 3) @ p.T + 2 * (c.W2 * u * q) @ p.T

    s = np.linspace(-1.0, 1.0, 5)
    powers = np.vander(s, 4, increasing=True)
    k, m, q = np.zeros((3, 4)), np.zeros((3, 3)), np.zeros((3, 3))
    for a in range(3):
        w = np.zeros((5, 3))
        w[:, a] = s
        coef = np.linalg.lstsq(powers, volts(w), rcond=None)[0]       # (4, 3): power x output
        m[:, a], q[:, a] = coef[1], coef[2] * (np.arange(3) != a)
        k[a] = coef[:, a]
    k[:, 0] = volts(np.zeros((1, 3)))[0] + poly2(c.cw, np.asarray(gyro_frequency, float)[None])[0]
    return k, m, q, -p @ c.C


def compare(cal, unit):
    """Rows (name, fitted, true, standard error, z) of a fitted rotation file against the
    unit's truth (`MimuUnit`), in the fit's gauge (`true_in_gauge` at the file's reference
    frequencies), and RMS z per family (k0, k1, k2, k3, M, Q, G)."""
    truth = RotationCalibration(*true_in_gauge(unit.coefficients,
                                               cal.reference["gyro_frequency_hz"]), {}, {})
    fitted, true = cal.values(), truth.values()
    se = dict(zip(cal.covariance["names"], cal.covariance["standard_error"]))
    rows = [(n, fitted[n], true[n], se[n], (fitted[n] - true[n]) / se[n]) for n in fitted]
    families = {}
    for n, *_, z in rows:
        fam = f"k{n[-2]}" if n.startswith("k") else n[0]
        families.setdefault(fam, []).append(z)
    return rows, {f: float(np.sqrt(np.mean(np.square(v)))) for f, v in families.items()}

"""The effect vocabulary of the diagnosis contract (log contract section 3): the physics a
sensor model may leave out, each as a regressor built from the flight's conditions.

One definition serves two users: the diagnosis tests a residual against these regressors,
and a compensation file carries found terms (`Calibration.found`) and removes them (a time
skew as an exact shift of the samples, not through its derivative). Simulated recordings hide
effects through their own code (`sensors.hidden`, sensor behaviour from the truth), so the
proof does not share these regressors; the size-effect regressor is tested against an
exactly simulated proof-mass offset in tests/test_diagnosis.py.

Conditions (`Conditions`), all sensor axes, interval means at the sample stamps:
    f      specific force, m/s^2 (N, 3)        w      angular rate, rad/s (N, 3)
    f_dot  d f / dt, m/s^3                     w_dot  d w / dt, rad/s^2
    T      accelerometer case temperatures, degC; freq  gyro resonance frequencies, Hz
    t      sample times, s (N,)
Temperature regressors use T for accelerometer axes and freq for gyro axes (the gyro's only
temperature reading), about a reference theta0 (the log's mean in a diagnosis).

A term is a dict like a diagnosis finding: effect, sensor ("accel" | "gyro" | "imu"),
axis ("x" | "y" | "z" | "all"), optional input_axis, coefficient (SI, multiplies the
regressor) or vector (size_effect, lever_arm: r in m; mounting_misalignment: small rotation
vector in rad, sensor frame), and the keys a regressor needs (order, window_s, reference).
"""
from dataclasses import dataclass, field

import numpy as np
from ..errors import InputError


AXES = "xyz"
SENSORS = ("accel", "gyro")
UNITS = {  # units of the coefficient per effect and sensor (per unit of the regressor)
    ("bias_shift", "accel"): "m/s^2", ("bias_shift", "gyro"): "rad/s",
    "scale_factor": "1", "cross_coupling": "1",
    ("scale_nonlinearity", 2, "accel"): "1/(m/s^2)", ("scale_nonlinearity", 3, "accel"): "1/(m/s^2)^2",
    ("scale_nonlinearity", 2, "gyro"): "1/(rad/s)", ("scale_nonlinearity", 3, "gyro"): "1/(rad/s)^2",
    "scale_asymmetry": "1", "g_sensitivity": "(rad/s)/(m/s^2)", "g2_sensitivity": "(rad/s)/(m/s^2)^2",
    ("temperature_bias", "accel"): "(m/s^2)/degC", ("temperature_bias", "gyro"): "(rad/s)/Hz",
    ("temperature_scale", "accel"): "1/degC", ("temperature_scale", "gyro"): "1/Hz",
    ("temperature_rate", "accel"): "(m/s^2)/degC", ("temperature_rate", "gyro"): "(rad/s)/Hz",
    ("thermal_hysteresis", "accel"): "m/s^2", ("thermal_hysteresis", "gyro"): "rad/s",
    "time_skew": "s", "size_effect": "m", "lever_arm": "m", "mounting_misalignment": "rad",
    ("vibration_rectification", "accel"): "(m/s^2)/(m/s^2)^2",
    ("vibration_rectification", "gyro"): "(rad/s)/(m/s^2)^2",
}
HYSTERESIS_SLOPE_WINDOW_S = 10.0     # dT/dt of thermal_hysteresis: slope over this window
DERIVATIVE_WINDOW_S = 0.05           # d/dt of measured outputs when a found term is removed
# vibration_rectification (log contract section 3): the mean square of the specific force on
# the axis, band-passed above the flight dynamics, over a short window. The flight dynamics
# of the profiles (rolls entered in 0.3 s, boosts, turns) lie below a few Hz; an airframe's
# vibration lies at tens to hundreds of Hz.
VIBRATION_CUTOFF_HZ = 10.0           # high-pass corner (4th-order Butterworth, zero phase)
VIBRATION_WINDOW_S = 0.5             # the mean square's window (centred)
VIBRATION_REGRESSOR = (f"the mean square, over a centred {VIBRATION_WINDOW_S:g} s window, of "
                       f"the axis's specific force high-passed at {VIBRATION_CUTOFF_HZ:g} Hz "
                       "(4th-order Butterworth, zero phase), (m/s^2)^2")


@dataclass
class Conditions:
    t: np.ndarray
    f: np.ndarray
    w: np.ndarray
    f_dot: np.ndarray
    w_dot: np.ndarray
    T: np.ndarray
    freq: np.ndarray
    vibration: np.ndarray | None = None     # (N, 3) vibration power per axis, (m/s^2)^2, when
                                            # measured elsewhere than f (`vibration_power`)
    # what several terms' regressors share, made once per Conditions (the arrays above are
    # not changed after it is built): the centripetal matrix, sample indices a window back
    _shared: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def from_outputs(cls, t, f, w, T, freq, window_s=DERIVATIVE_WINDOW_S):
        """Conditions from sensor outputs; derivatives by central differences over
        window_s (smooths the sensor noise a point derivative would amplify)."""
        t = np.asarray(t, float)
        return cls(t, f, w, derivative(t, f, window_s), derivative(t, w, window_s), T, freq)

    def of(self, sensor):
        """(input x, its time derivative, temperature reading) of a triad."""
        return ((self.f, self.f_dot, self.T) if sensor == "accel"
                else (self.w, self.w_dot, self.freq))

    def __len__(self):
        return len(self.t)

    def centripetal(self):
        """K (N, 3, 3) with K r = w x (w x r) + w_dot x r (`_centripetal_matrix`), kept."""
        if "centripetal" not in self._shared:
            self._shared["centripetal"] = _centripetal_matrix(self.w, self.w_dot)
        return self._shared["centripetal"]

    def release_shared(self):
        """Forget what the regressors shared (the centripetal matrices: 72 bytes a sample):
        once a design's columns are made; a later regressor makes them again."""
        self._shared.clear()

    def index_at(self, offset_s):
        """(N,) index of the first sample at or after t + offset_s (s) for every sample,
        kept per offset (`np.searchsorted`, side left)."""
        key = ("index_at", offset_s)
        if key not in self._shared:
            self._shared[key] = np.searchsorted(self.t, self.t + offset_s, side="left")
        return self._shared[key]


def temperature_change(temperature, window_s, t, idx=None):
    """dT = T(t) - T(t - window_s) per axis, T(t[0]) until the window is full; t (N,) s,
    temperature (N, 3); idx: the first sample at or after t - window_s, when known
    (`Conditions.index_at`)."""
    if idx is None:
        idx = np.searchsorted(t, t - window_s, side="left")
    return temperature - temperature[idx]


SAVGOL_FFT_TAPS = 64     # a derivative window of this many samples or more is applied by FFT
                         # (bench on this machine: 101 taps 0.22 -> 0.13 s, 3001 taps 3.2 ->
                         # 0.18 s over 682,000 x 3 samples; 31 taps: direct is faster)


def derivative(t, x, window_s=0.0):
    """d x / dt of samples at times t, (N, k): a Savitzky-Golay derivative (local quartic
    fit, exact for motion up to 4th order in time) over about window_s, which smooths the
    noise a point derivative would amplify without lagging; central differences when the
    window holds fewer than 5 samples. Uniform sampling is assumed within each run of one
    rate (`flightlog.inspect.rate_segments`): a recording whose rate changes (a logger
    switched from 100 to 50 Hz) is differentiated run by run, each at its own step (with
    the median step, the 50 Hz part came out at twice its derivative)."""
    t = np.asarray(t, float)
    if len(t) > 2:
        step = np.diff(t)
        if np.mean(np.abs(step / np.median(step) - 1) > 0.25) > 0.01:     # not one rate?
            from ..flightlog.stamps import rate_segments
            runs = rate_segments(np.round((t - t[0]) * 1e9).astype(np.int64))
            if len(runs) > 1:
                out = np.empty(np.shape(x), float)
                for a, b, _ in runs:                      # stamps a .. b of each run
                    out[a:b + 1] = _uniform_derivative(t[a:b + 1], x[a:b + 1], window_s)
                return out
    return _uniform_derivative(t, x, window_s)


def _uniform_derivative(t, x, window_s):
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    m = int(round(window_s / dt)) // 2 * 2 + 1
    if m >= 5 and n >= m:
        from scipy.signal import savgol_filter   # 0.5-1 s to import: only when needed
        x = np.asarray(x, float)
        if m < SAVGOL_FFT_TAPS or n < 2 * m or not np.isfinite(x).all():
            # the direct filter: a NaN reaches its window only
            out = savgol_filter(x, m, 4, deriv=1, delta=dt, axis=0, mode="constant")
        else:
            # the same filter by FFT convolution (a direct one costs m products a sample;
            # they differ by round-off, 1e-13 of 1 g over 1 ms). Not with a NaN: the
            # transform would spread it over the whole series.
            from scipy.signal import fftconvolve, savgol_coeffs
            kernel = savgol_coeffs(m, 4, deriv=1, delta=dt).reshape((m,) + (1,) * (x.ndim - 1))
            out = fftconvolve(x, kernel, mode="same", axes=0)
        _interp_edges(x, m, dt, out)
        return out
    lo, hi = np.maximum(np.arange(n) - 1, 0), np.minimum(np.arange(n) + 1, n - 1)
    return (x[hi] - x[lo]) / (t[hi] - t[lo])[:, None]


def _interp_edges(x, m, dt, out):
    """savgol_filter's 'interp' edges of the derivative, into out: the quartic fitted to the
    first and to the last window of m samples (step dt s); a column whose edge window holds
    a NaN gets NaN there, as a NaN inside the series gives NaN over its window (the fit's
    least squares refuses it: a track-level recording with lost samples at its start had
    crashed the compensation of its own found terms)."""
    from scipy.signal import savgol_filter
    h = m // 2
    for rows, window in ((slice(None, h), x[:m]), (slice(-h, None), x[-m:])):
        cols = window.reshape(m, -1)
        finite = np.isfinite(cols).all(axis=0)
        edge = np.full((h, cols.shape[1]), np.nan)
        if finite.any():
            edge[:, finite] = savgol_filter(cols[:, finite], m, 4, deriv=1, delta=dt, axis=0,
                                            mode="interp")[rows]
        out[rows] = edge.reshape(out[rows].shape)


def regressor(term, cond):
    """The regressor columns of `term` on `cond`: {(sensor, axis index): (N, k) array}, one
    entry per output channel the term acts on; the output changes by columns @ parameter
    (coefficient, or the vector of size_effect / lever_arm / mounting_misalignment)."""
    effect, sensor = term["effect"], term["sensor"]
    if effect == "time_skew":                         # x(t - tau) - x(t) = -tau dx/dt
        sensors = SENSORS if sensor == "imu" else (sensor,)
        return {(s, i): -cond.of(s)[1][:, i:i + 1] for s in sensors for i in range(3)}
    if effect in ("size_effect", "lever_arm"):        # w x (w x r) + dw/dt x r, row i
        k = cond.centripetal()
        axes = range(3) if effect == "lever_arm" else [AXES.index(term["axis"])]
        return {("accel", i): k[:, i, :] for i in axes}
    if effect == "mounting_misalignment":             # C(phi) x - x = x x phi = [x x] phi
        cols = {}
        for s in SENSORS:
            x = cond.of(s)[0]
            zero = np.zeros(len(x))
            cols.update({(s, 0): np.column_stack([zero, -x[:, 2], x[:, 1]]),   # rows of [x x]
                         (s, 1): np.column_stack([x[:, 2], zero, -x[:, 0]]),
                         (s, 2): np.column_stack([-x[:, 1], x[:, 0], zero])})
        return cols
    i = AXES.index(term["axis"])
    x, _, theta = cond.of(sensor)
    col = _scalar(term, cond, x, theta, i)
    return {(sensor, i): col[:, None]}


def _scalar(term, cond, x, theta, i):
    effect = term["effect"]
    j = [AXES.index(a) for a in term.get("input_axis", "")]
    if effect == "bias_shift":
        return np.ones(len(x))
    if effect == "scale_factor":
        return x[:, i]
    if effect == "cross_coupling":
        return x[:, j[0]]
    if effect == "scale_nonlinearity":        # order 2 or 3 (`check_term`); products, not
        u = x[:, i]                            # u ** 3, numpy's generic pow: 12x slower
        return u * u if term["order"] == 2 else u * u * u
    if effect == "scale_asymmetry":
        return np.abs(x[:, i])
    if effect == "g_sensitivity":
        return cond.f[:, j[0]]
    if effect == "g2_sensitivity":
        return cond.f[:, j[0]] * cond.f[:, j[1]]
    if effect == "temperature_bias":
        return theta[:, i] - term.get("reference", 0.0)
    if effect == "temperature_scale":
        return (theta[:, i] - term.get("reference", 0.0)) * x[:, i]
    if effect == "temperature_rate":
        return temperature_change(theta[:, i:i + 1], term["window_s"], cond.t,
                                  cond.index_at(-term["window_s"]))[:, 0]
    if effect == "vibration_rectification":
        if cond.vibration is not None:
            return cond.vibration[:, i]
        return vibration_power(cond.t, cond.f[:, i])
    if effect == "thermal_hysteresis":
        k = np.minimum(cond.index_at(HYSTERESIS_SLOPE_WINDOW_S / 2), len(cond.t) - 1)
        k0 = cond.index_at(-HYSTERESIS_SLOPE_WINDOW_S / 2)
        return np.sign(theta[k, i] - theta[k0, i])
    raise InputError(f"effect {effect!r} has no regressor here (vocabulary: "
                     f"{', '.join(sorted(set(k if isinstance(k, str) else k[0] for k in UNITS)))})")


def vibration_power(t, x):
    """(N,) or (N, k): the vibration power of x (N,) or (N, k) at uniform times t (s): the
    centred VIBRATION_WINDOW_S mean square of x high-passed at VIBRATION_CUTOFF_HZ; zero when
    the sample rate cannot carry that band (below 4 x the corner)."""
    rate = 1.0 / float(np.median(np.diff(t)))
    if rate < 4 * VIBRATION_CUTOFF_HZ or len(t) < 64:
        return np.zeros(np.shape(x))
    from scipy.signal import butter, sosfiltfilt
    sos = butter(4, VIBRATION_CUTOFF_HZ, "highpass", fs=rate, output="sos")
    from scipy.ndimage import uniform_filter1d
    band = sosfiltfilt(sos, x, axis=0)
    m = max(1, int(round(VIBRATION_WINDOW_S * rate)))
    return uniform_filter1d(band ** 2, m, axis=0, mode="nearest")


def _centripetal_matrix(w, w_dot):
    """K (N, 3, 3) with K r = w x (w x r) + w_dot x r = (w w' - |w|^2 I + [w_dot x]) r."""
    k = w[:, :, None] * w[:, None, :] + _skew(w_dot)
    k[:, np.arange(3), np.arange(3)] -= np.einsum("ni,ni->n", w, w)[:, None]
    return k


def _skew(v):
    """[v x] (N, 3, 3) of v (N, 3): [v x] r = v x r."""
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -v[:, 2], v[:, 1]
    out[:, 1, 0], out[:, 1, 2] = v[:, 2], -v[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -v[:, 1], v[:, 0]
    return out


VECTOR_EFFECTS = ("size_effect", "lever_arm", "mounting_misalignment")
EFFECTS = ("bias_shift", "scale_factor", "cross_coupling", "scale_nonlinearity",
           "scale_asymmetry", "g_sensitivity", "g2_sensitivity", "temperature_bias",
           "temperature_scale", "temperature_rate", "thermal_hysteresis", "time_skew",
           "vibration_rectification") + VECTOR_EFFECTS


def check_term(term):
    """Raise ValueError unless `term` is a complete term this module can apply."""
    if not isinstance(term, dict):
        raise InputError("a term must be an object")
    effect = term.get("effect")
    if effect not in EFFECTS:
        raise InputError(f"effect {effect!r} is not one mimunav can apply ({', '.join(EFFECTS)})")
    whole = effect in ("time_skew", "lever_arm", "mounting_misalignment")
    sensors = ("imu",) + SENSORS if effect == "time_skew" else (
        ("imu",) if whole else ("accel",) if effect == "size_effect" else
        ("gyro",) if effect.startswith("g") else SENSORS)
    if term.get("sensor") not in sensors:
        raise InputError(f"{effect}: sensor must be one of {sensors}")
    if not whole and term.get("axis") not in tuple(AXES):
        raise InputError(f"{effect}: axis must be x, y or z")
    need = {"cross_coupling": 1, "g_sensitivity": 1, "g2_sensitivity": 2}.get(effect)
    if need and (len(term.get("input_axis", "")) != need
                 or any(a not in AXES for a in term["input_axis"])):
        raise InputError(f"{effect}: input_axis must be {need} of x, y, z")
    if effect == "scale_nonlinearity" and term.get("order") not in (2, 3):
        raise InputError("scale_nonlinearity: order must be 2 or 3")
    if effect == "temperature_rate" and not float(term.get("window_s", 0)) > 0:
        raise InputError("temperature_rate: window_s (s) must be > 0")
    p = parameter(term)
    if p.shape != ((3,) if effect in VECTOR_EFFECTS else (1,)) or not np.all(np.isfinite(p)):
        raise InputError(f"{effect}: needs a finite "
                         f"{'vector [3]' if effect in VECTOR_EFFECTS else 'coefficient'}")


def parameter(term):
    """The term's parameter as a vector (coefficient -> (1,), vector -> (3,))."""
    value = term.get("vector", term.get("coefficient"))
    if value is None:
        raise InputError(f"{term.get('effect')}: no coefficient or vector")
    return np.atleast_1d(np.asarray(value, float))


def units(term):
    effect, sensor = term["effect"], term["sensor"]
    for key in ((effect, term.get("order"), sensor), (effect, sensor), effect):
        if key in UNITS:
            return UNITS[key]
    raise InputError(f"unknown effect {effect!r}")


def apply(terms, cond, sign=1.0):
    """Outputs f, w (copies) with `sign` x every term's contribution added: sign=+1 puts
    effects into ideal outputs (simulation), sign=-1 removes found terms from measured ones
    (compensation). time_skew is applied as a shift of the samples, not its derivative;
    mounting_misalignment as the exact rotation whose first order is its regressor,
    x' = R(-phi) x (= x + x cross phi + O(phi^2)), and removed by R(phi): at the degrees of a
    real mounting the first order would leave phi^2 / 2 of the input (70 mg of g at 7 deg)."""
    f, w = cond.f.copy(), cond.w.copy()
    out = {"accel": f, "gyro": w}
    for term in terms:
        if term["effect"] == "time_skew":
            tau = sign * parameter(term)[0]
            for s in (SENSORS if term["sensor"] == "imu" else (term["sensor"],)):
                out[s][:] = shift(cond.t, out[s], tau)
            continue
        if term["effect"] == "mounting_misalignment":
            from scipy.spatial.transform import Rotation   # 0.4 s of import: only here
            rotation = Rotation.from_rotvec(-sign * parameter(term))
            for s in SENSORS:
                out[s][:] = rotation.apply(out[s])
            continue
        p = parameter(term)
        for (s, i), cols in regressor(term, cond).items():
            out[s][:, i] += sign * cols @ p
    return f, w


def shift(t, x, tau):
    """Interval-mean samples x (N, k) at stamps t describing the motion tau s earlier:
    the cumulative increment interpolated at t - tau and differenced (exact for motion
    that is linear within a sample; the ends hold)."""
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0]))
    cum = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x * dt[:, None], axis=0)])
    edges = np.concatenate([[t[0] - dt[0]], t])
    moved = np.column_stack([np.interp(edges - tau, edges, cum[:, k]) for k in range(x.shape[1])])
    return np.diff(moved, axis=0) / dt[:, None]

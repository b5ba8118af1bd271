"""The calibration file (log contract section 2, `mimunav-calibration/1`): models
entire-63, linear, cold-start and their found terms, read, checked and written.
"""
import json
import os
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..files import check_format, json_ready, read_json, write_atomic
from . import effects
from .model import CalibrationError, poly2

FORMAT = "mimunav-calibration/1"
MODELS = ("entire-63", "linear", "cold-start")
FOUND_SUFFIX = "+found"     # a model plus the terms a diagnosis found ("found": [terms])
MAX_CONDITION = 100.0   # of A1 and W1: a triad's scale factors alike (one part, one range)
# and its axes within a few degrees of orthogonal make it 1.0-1.1 (the six foreign flights'
# files 1.01-1.05, the lab fits 1.03-1.04); 100 is a scale factor 1 % of the others' or two
# axes 1.1 deg apart - no triad, a typing error (a zeroed diagonal: 3674, compensated
# without a word into a confident 'saturation' and a g-sensitivity 3.5 times the truth)
_TRIAD_KEYS = {"accel": ("A0", "A1", "A2", "A3", "ct"), "gyro": ("W0", "W1", "W2", "W3", "C", "cw")}
_SHAPES = {"A0": (3,), "A1": (3, 3), "A2": (3,), "A3": (3,), "ct": (3, 3),
           "W0": (3,), "W1": (3, 3), "W2": (3,), "W3": (3,), "C": (3, 3), "cw": (3, 3)}
_COLD_KEYS = ("a", "b", "c", "d", "e")


@dataclass
class Calibration:
    """Coefficients of one MIMU compensation (SI; see the module doc for the equations).

    A0 m/s^2 (3,); A1 (m/s^2)/V (3, 3); A2, A3 diagonals (m/s^2)/V^2, /V^3 (3,);
    ct V, V/degC, V/degC^2 (3, 3); W0 rad/s; W1 (rad/s)/V; W2, W3 diagonals;
    C (rad/s)/(m/s^2) (3, 3); cw V, V/Hz, V/Hz^2 (3, 3).
    """
    model: str = "entire-63"
    unit: str = ""
    procedure: str = ""
    A0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    A1: np.ndarray = field(default_factory=lambda: np.eye(3))
    A2: np.ndarray = field(default_factory=lambda: np.zeros(3))
    A3: np.ndarray = field(default_factory=lambda: np.zeros(3))
    ct: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    W0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    W1: np.ndarray = field(default_factory=lambda: np.eye(3))
    W2: np.ndarray = field(default_factory=lambda: np.zeros(3))
    W3: np.ndarray = field(default_factory=lambda: np.zeros(3))
    C: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    cw: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    cold_start: dict = field(default_factory=dict)    # {"accel": {a..e}, "gyro": {..}, "window_s"}
    covariance: dict = field(default_factory=dict)
    found: list = field(default_factory=list)         # diagnosis terms (model "<base>+found")
    extra: dict = field(default_factory=dict)         # keys of the file this version ignores

    @property
    def base_model(self) -> str:
        return self.model[:-len(FOUND_SUFFIX)] if self.model.endswith(FOUND_SUFFIX) else self.model

    @classmethod
    def identity(cls, procedure: str = 'identity: outputs already in SI units (/mimu/imu)'
                 ) -> "Calibration":
        """The linear model that leaves outputs as they are: the base of the found terms of
        a unit recorded already compensated (an imported recording's /mimu/imu)."""
        return cls(model="linear", procedure=procedure)

    @property
    def is_identity(self) -> bool:
        """True when the base model changes nothing (eqs. 1-4 with A1 = W1 = I, the rest 0)."""
        zero = ("A0", "A2", "A3", "ct", "W0", "W2", "W3", "C", "cw")
        return (self.base_model in ("linear", "entire-63") and not self.cold_start
                and all(not np.any(getattr(self, k)) for k in zero)
                and all(np.array_equal(getattr(self, k), np.eye(3)) for k in ("A1", "W1")))

    # ---- file contract -------------------------------------------------------------
    @classmethod
    def from_dict(cls, doc: dict, source: str = 'calibration') -> "Calibration":
        """Validate a parsed `mimunav-calibration/1` document and build the object."""
        def fail(msg):
            raise CalibrationError(f"{source}: {msg}")
        where = {"mimunav-unit/1": "its `coefficients` object",
                 "mimunav-truth/1": "its `mimu` object's `coefficients`"}.get(
            doc.get("format") if isinstance(doc, dict) else None)
        if where:           # a simulated unit's true coefficients are a calibration document
            fail(f"a {doc['format']} file, not a calibration: the unit's true coefficients "
                 f"are {where} (a {FORMAT} document) - save that object as a file of its "
                 "own to use them as the model")
        check_format(doc, FORMAT, source, CalibrationError)
        model = doc.get("model")
        base = (model[:-len(FOUND_SUFFIX)] if isinstance(model, str)
                and model.endswith(FOUND_SUFFIX) else model)
        if base == "rotation-cubic":
            fail("model 'rotation-cubic' is the gyros' scale factor from a rotation run (seed "
                 "S4, `mimunav.lab.rotation`): it has no accelerometer terms and "
                 "cannot compensate a log; compare it with `mimunav calibration compare`")
        if base not in MODELS:
            fail(f"model {model!r} is not one of {', '.join(MODELS)} (optionally with "
                 f"{FOUND_SUFFIX!r})")
        cal = cls(model=model, unit=str(doc.get("unit", "")),
                  procedure=str(doc.get("procedure", "")),
                  covariance=doc.get("covariance", {}) or {})
        for triad, keys in _TRIAD_KEYS.items():
            block = doc.get(triad, {})
            if not isinstance(block, dict):
                fail(f'"{triad}" must be an object')
            allowed = set(keys) | (set(_COLD_KEYS) if base == "cold-start" else set())
            unknown = set(block) - allowed
            if unknown:
                fail(f'"{triad}" has keys {sorted(unknown)} that model {base!r} does not use')
            if base == "linear":
                extra_terms = [k for k in block if k not in ("A0", "A1", "W0", "W1")]
                if extra_terms:
                    fail(f'model "linear" takes only A0, A1, W0, W1; {triad} has {extra_terms}')
            for key in keys:
                if key in block:
                    setattr(cal, key, _array(block[key], _SHAPES[key], f"{source}: {triad}.{key}"))
                elif key in ("A1", "W1"):
                    fail(f'{triad}.{key} is required (the linear scale/misalignment matrix)')
            if base == "cold-start":
                missing = [k for k in _COLD_KEYS if k not in block]
                if missing:
                    fail(f'cold-start model lacks {triad}.{missing}')
                cal.cold_start[triad] = {k: _array(block[k], (3,), f"{source}: {triad}.{k}")
                                         for k in _COLD_KEYS}
        if base == "cold-start":
            window = doc.get("window_s")
            if not isinstance(window, (int, float)) or not window > 0:
                fail("cold-start model needs window_s > 0 (s), the dT window")
            cal.cold_start["window_s"] = float(window)
            for triad in ("accel", "gyro"):
                scale = cal.cold_start[triad]["a"]
                if np.any(scale == 0):
                    fail(f"cold-start {triad}.a has a zero (scale factor a + b T must not vanish)")
        for name in ("A1", "W1"):
            m = getattr(cal, name)
            if np.linalg.cond(m) > MAX_CONDITION:
                fail(f"{name} is singular or nearly so (condition number "
                     f"{np.linalg.cond(m):.3g}, above {MAX_CONDITION:g}; a calibrated triad's "
                     "is near 1): a scale factor of zero or near it, or two axes nearly "
                     "parallel - the compensated triad would be blind along an axis and the "
                     "raw outputs could not be inverted")
        if model != base:
            found = doc.get("found")
            if not isinstance(found, list) or not found:
                fail(f'model {model!r} needs a non-empty "found" list of terms')
            for k, term in enumerate(found):
                try:
                    effects.check_term(term)
                except (ValueError, TypeError, KeyError) as exc:
                    fail(f"found[{k}]: {exc}")
            cal.found = [dict(term) for term in found]
        known = {"format", "model", "unit", "procedure", "accel", "gyro", "covariance", "window_s",
                 "found"}
        cal.extra = {k: v for k, v in doc.items() if k not in known}
        return cal

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Calibration":
        return cls.from_dict(read_json(path, "calibration file", CalibrationError),
                             source=str(path))

    def as_dict(self) -> dict:
        doc = {"format": FORMAT, "model": self.model, "unit": self.unit,
               "procedure": self.procedure}
        for triad, keys in _TRIAD_KEYS.items():
            keys = [k for k in keys if self.base_model != "linear" or k in ("A0", "A1", "W0", "W1")]
            doc[triad] = {k: getattr(self, k).tolist() for k in keys}
            if self.base_model == "cold-start":
                doc[triad].update({k: v.tolist() for k, v in self.cold_start[triad].items()})
        if self.base_model == "cold-start":
            doc["window_s"] = self.cold_start["window_s"]
        if self.found:
            doc["found"] = self.found
        if self.covariance:
            doc["covariance"] = self.covariance
        doc.update(self.extra)
        return doc

    def with_voltage_offset(self, d_accel: ArrayLike, d_gyro: ArrayLike) -> "Calibration":
        """The same compensation written with temperature polynomials lowered by d (V, per
        axis), so V' = V + d: eqs. 1/3 re-expanded about the shifted voltage, exactly
        (A0' = A0 - A1 d + A2 d^2 - A3 d^3, A1' = A1 + diag(3 A3 d^2 - 2 A2 d),
        A2' = A2 - 3 A3 d). A constant offset of eq. 2 (4) is not identifiable apart from
        the triad's terms; this moves a calibration to another gauge."""
        out = Calibration.from_dict(self.as_dict())
        for p0, p1, p2, p3, c, d in (("A0", "A1", "A2", "A3", "ct", d_accel),
                                     ("W0", "W1", "W2", "W3", "cw", d_gyro)):
            d = np.asarray(d, dtype=float)
            a0, a1, a2, a3 = (getattr(self, k) for k in (p0, p1, p2, p3))
            setattr(out, p0, a0 - a1 @ d + a2 * d**2 - a3 * d**3)
            setattr(out, p1, a1 + np.diag(3 * a3 * d**2 - 2 * a2 * d))
            setattr(out, p2, a2 - 3 * a3 * d)
            shifted = getattr(self, c).copy()
            shifted[:, 0] -= d
            setattr(out, c, shifted)
        return out

    def without(self, keys) -> "Calibration":
        """A copy with the coefficient arrays `keys` (e.g. "C", "A2") zeroed."""
        out = Calibration.from_dict(self.as_dict())
        for key in keys:
            getattr(out, key)[:] = 0.0
        return out

    def frozen_at(self, accel_temperature: ArrayLike, gyro_frequency: ArrayLike
                  ) -> "Calibration":
        """A copy with eqs. 2/4 held at these readings (degC and Hz, per axis): their
        value there as the constant term, no dependence on the readings."""
        out = Calibration.from_dict(self.as_dict())
        for key, reading in (("ct", accel_temperature), ("cw", gyro_frequency)):
            poly = getattr(out, key)
            poly[:, 0] = poly2(poly, np.asarray(reading, float)[None, :])[0]
            poly[:, 1:] = 0.0
        return out

    def save(self, path: str | os.PathLike, force: bool = False) -> None:
        """Write the file atomically (temporary file + rename); refuses to replace an
        existing file unless force=True."""
        write_atomic(path, json.dumps(self.as_dict(), indent=1) + "\n", force=force)


def _array(value, shape, where):
    try:
        arr = np.asarray(value)
        if arr.dtype.kind not in "iuf":         # JSON numbers only: "0.1" is text, not 0.1
            raise TypeError
        arr = arr.astype(float)
    except (TypeError, ValueError):
        raise CalibrationError(f"{where} is not numeric: {value!r}") from None
    if arr.shape != shape:
        raise CalibrationError(f"{where} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{where} has non-finite values: {arr.tolist()}")
    return arr


def with_found(cal: Calibration, findings: list[dict]) -> Calibration | None:
    """A copy of calibration `cal` that also removes the found terms (model '<base>+found');
    None when no finding is a term a compensation can remove."""
    if not any(f["effect"] in effects.EFFECTS for f in findings):
        return None
    doc = cal.as_dict()
    doc["model"] = cal.base_model + FOUND_SUFFIX
    terms = list(cal.found)
    for f in findings:
        if f["effect"] not in effects.EFFECTS:       # a clipped, quantized or wandering output
            continue                            # is no term a compensation can remove
        term = {k: f[k] for k in ("effect", "sensor", "axis", "input_axis", "order", "window_s",
                                  "reference") if k in f}
        # a lever arm is reported in the vehicle frame and removed in the sensor axes
        vector = f.get("vector_sensor_axes", f.get("vector"))
        term.update({"vector": vector} if vector is not None else {"coefficient": f["coefficient"]})
        terms.append(json_ready(term))
    doc["found"] = terms
    doc["procedure"] = (cal.procedure + " + " if cal.procedure else "") + "mimunav diagnose"
    return Calibration.from_dict(doc)

"""What sets the traditional calibration's floor on a flight (issue 54): its error budget,
made by adding back to its compensated outputs one group of the unit's true terms at a
time and navigating again.

The traditional calibration (A0, A1, W0, W1: zeros, first-order scales, cross-coupling, on
the raw volts) has no temperature model, no nonlinear scale factors and no g-sensitivity.
Its linear terms were fitted in the lab - the accelerometers on the multi-position run, the
gyros on the rate table - and there a least-squares fit on [1, volts] took into them the
part of each missing group that is linear in the volts over the lab's windows; the gyro
zeros may have been set again standing in the launch attitude before flight
(`--gyro-zero pre-flight`), which takes each group's value at rest instead of the lab's
constant. So a group is added back as the unit's true model gives it on the flight (seed S1
eqs. 1-4 with the unit's own 63 coefficients) minus what the calibration absorbed of it
(`Absorbed`):

  temperature offset zeros-to-flight  eqs. 2/4 frozen at the flight's first readings, minus
                                      what the lab (or the pre-flight rest) absorbed
  temperature change in flight        eqs. 2/4 as they run, minus frozen at the first readings
  nonlinear scale factor              A2 v^2 + A3 v^3 (W2, W3), minus the absorbed part
  g-sensitivity at 1 g                C times the specific force of rest in the flight's own
                                      attitude (gravity's reaction, sensor axes), minus the
                                      absorbed part (the lab's, or the launch attitude's)
  g-sensitivity at (n-1) g            C times the rest of the specific force: the load of
                                      the manoeuvres (none in the lab)

The groups telescope: the ideal traditional calibration (the fit of the true outputs
without noise or setting errors) plus all five is the true calibration, sample by sample.
A group's worth is the 3-D end error of the traditional row minus that with the group added
back; what all five leave is the calibration's own fit error (the lab's setting errors and
noise), the unit's turn-on bias and random errors, and its physics beyond eqs. 1-4.
"""
from dataclasses import dataclass

import numpy as np

from ..compensation.model import compensate
from ..sensors.simulation import still_rates
from .replay import comparison_times, navigate_mimu, ned_to_enu, resample
from .table import budget_markdown

GROUPS = ("temperature offset zeros-to-flight", "temperature change in flight",
          "nonlinear scale factor", "g-sensitivity at 1 g", "g-sensitivity at (n-1) g")
PARTS = ("temperature", "nonlinear", "g-sensitivity")      # what the lab fit can absorb


def outputs(cal, raw):
    """(f m/s^2, w rad/s) of raw MIMU samples through `cal`, no wild-value filter."""
    f, w, _ = compensate(cal, raw["accel_volts"], raw["gyro_volts"], raw["accel_temperature"],
                         raw["gyro_frequency"], filter_outliers=False)
    return f, w


def chain(true, raw):
    """{step: (f, w)}: outputs on `raw` of the true calibration built up from its linear part
    on the raw volts: "base" (A0 + A1 u, W0 + W1 u), "linear" (+ eqs. 2/4), "no_g" (+ A2,
    A3, W2, W3); the true outputs are no_g's with C f added to w (f: no_g's, which C does
    not touch)."""
    no_g = true.without(("C",))
    linear = no_g.without(("A2", "A3", "W2", "W3"))
    return {"base": outputs(linear.without(("ct", "cw")), raw), "linear": outputs(linear, raw),
            "no_g": outputs(no_g, raw)}


def parts(true, raw, steps=None):
    """{part: (df, dw) (N, 3)}: the unit's true outputs on `raw` less their linear part on
    the raw volts, split along the `chain` (`steps`, if already made): temperature (eqs.
    2/4, on the linear model) + nonlinear (A2, A3, W2, W3) + g-sensitivity (C f, f the true
    specific force)."""
    (f0, w0), (f1, w1), (f2, w2) = (steps or chain(true, raw)).values()
    return {"temperature": (f1 - f0, w1 - w0), "nonlinear": (f2 - f1, w2 - w1),
            "g-sensitivity": (np.zeros_like(f2), f2 @ true.C.T)}


@dataclass
class Absorbed:
    """What the traditional calibration took into its linear terms of each part (`PARTS`),
    per sensor: a + B u (output units; a (3,), B (3, 3), u the raw volts)."""
    accel: dict
    gyro: dict

    @classmethod
    def from_lab(cls, multi_position, rate_table, true):
        """The least squares on [1, u] over the window means of the lab runs
        (`lab.runs.LabRun`) the traditional calibration was fitted on - the accelerometers'
        on `multi_position`, the gyros' on `rate_table` - of each part of the true outputs."""
        def projected(run, sensor):
            k = 0 if sensor == "accel" else 1
            u = run.means(run.raw[f"{sensor}_volts"])
            design = np.column_stack([np.ones(len(u)), u])
            out = {}
            for name, pair in parts(true, run.raw).items():
                coef = np.linalg.lstsq(design, run.means(pair[k]), rcond=None)[0]
                out[name] = (coef[0], coef[1:].T)
            return out
        return cls(projected(multi_position, "accel"), projected(rate_table, "gyro"))

    def with_preflight_gyros(self, still, true):
        """The gyro zeros set again standing before flight (`campaign.Still`): each part's
        constant is its value at rest there (the slopes stay the lab's)."""
        u = still.raw["gyro_volts"].mean(axis=0)
        gyro = {name: (pair[1].mean(axis=0) - self.gyro[name][1] @ u, self.gyro[name][1])
                for name, pair in parts(true, still.raw).items()}
        return Absorbed(self.accel, gyro)

    def at(self, part, raw):
        """(df, dw) (N, 3): what the calibration absorbed of `part`, on raw samples."""
        return tuple(a + raw[f"{sensor}_volts"] @ b.T for sensor, (a, b) in
                     (("accel", self.accel[part]), ("gyro", self.gyro[part])))


def added_back(flight, true, absorbed):
    """{group: (df m/s^2, dw rad/s), (N, 3) each, sensor axes}: what each group of the
    unit's true terms adds to the traditional calibration's outputs (module doc)."""
    raw = flight.mimu_raw
    steps = chain(true, raw)
    part = parts(true, raw, steps)
    first = true.without(("C", "A2", "A3", "W2", "W3")).frozen_at(raw["accel_temperature"][0],
                                                                   raw["gyro_frequency"][0])
    change = tuple(a - b for a, b in zip(steps["linear"], outputs(first, raw)))
    f_true = steps["no_g"][0]
    rest = gravity_reaction(flight)

    def minus(pair, taken):
        return pair[0] - taken[0], pair[1] - taken[1]
    one_g = (np.zeros_like(f_true), rest @ true.C.T)
    return {
        "temperature offset zeros-to-flight": minus(
            minus(part["temperature"], change), absorbed.at("temperature", raw)),
        "temperature change in flight": change,
        "nonlinear scale factor": minus(part["nonlinear"], absorbed.at("nonlinear", raw)),
        "g-sensitivity at 1 g": minus(one_g, absorbed.at("g-sensitivity", raw)),
        "g-sensitivity at (n-1) g": (np.zeros_like(f_true), (f_true - rest) @ true.C.T)}


def gravity_reaction(flight):
    """(N, 3) m/s^2: the specific force of rest in the flight's true attitude at the MIMU's
    stamps (sensor axes; C_sv C_vn (0, 0, -g)): the 1 g a gyro's g-sensitivity sees in
    unaccelerated flight."""
    tr = flight.truth
    t = np.clip(flight.mimu_t, tr.t[0], tr.t[-1])
    at = resample(tr, t)
    return still_rates(flight.mimu_mounting, at.q_nb, at.lat, at.h)[1]


def traditional_budget(flight, trad, true, absorbed):
    """The traditional row with each group added back, all five added back, and the unit's
    true coefficients, at the table's end point against the truth: a JSON-ready dict
    (east/north/up m, 3-D norm, and each group's worth: the 3-D error it removes)."""
    t_end = comparison_times(flight)[-1:]
    ref = resample(flight.truth, t_end)
    raw = flight.mimu_raw
    f, w = outputs(trad, raw)
    groups = added_back(flight, true, absorbed)
    rows = {"traditional": (f, w)}
    rows.update({f"+ {name}": (f + df, w + dw) for name, (df, dw) in groups.items()})
    rows["+ all five"] = (f + sum(d[0] for d in groups.values()),
                          w + sum(d[1] for d in groups.values()))
    rows["true coefficients"] = outputs(true, raw)
    out = {}
    for name, (fi, wi) in rows.items():
        nav = resample(navigate_mimu(flight, wi, fi), t_end)
        enu = ned_to_enu(nav.position_error(ref)[-1])
        out[name] = {"enu_m": enu.tolist(), "norm_m": float(np.linalg.norm(enu))}
    base = out["traditional"]["norm_m"]
    for row in out.values():
        row["worth_m"] = base - row["norm_m"]
    taken = {sensor: {part: {"a": a.tolist(), "B": b.tolist()} for part, (a, b) in
                      getattr(absorbed, sensor).items()} for sensor in ("accel", "gyro")}
    return {"end_t_s": float(t_end[0]), "absorbed": taken, "variants": out}


def traditional_markdown(doc):
    """The traditional budget as a table: each row's end error and the group's worth."""
    return budget_markdown(doc, "traditional", "east/north/up, with one group of the unit's "
                           "true terms added back to the traditional calibration's outputs at "
                           "a time:", "group worth (3-D m removed)")

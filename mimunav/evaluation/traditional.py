"""What sets the traditional calibration's floor on a flight (issue 54): its error budget,
made by adding back to its compensated outputs one group of the unit's true terms at a
time and navigating again.

The traditional calibration (A0, A1, W0, W1: zeros, first-order scales, cross-coupling)
has no temperature model, no nonlinear scale factors and no g-sensitivity; its zeros were
set in some conditions - the lab's multi-position run for the accelerometers; for the gyros
the lab's rate table (`--gyro-zero lab`) or the launch attitude standing before flight
(`pre-flight`) - and there they absorbed whatever those groups gave. So a group is added
back relative to those conditions (`ZeroConditions`), each as the unit's true model gives
it (seed S1 eqs. 1-4 with the unit's own 63 coefficients):

  temperature offset lab-to-flight   eqs. 2/4 frozen at the flight's first readings, minus
                                     frozen at the zeros' readings
  temperature change in flight       eqs. 2/4 as they run, minus frozen at the first readings
  nonlinear scale factor             A2, A3, W2, W3
  g-sensitivity at 1 g               C times the specific force of rest in the flight's own
                                     attitude (gravity's reaction, sensor axes), minus C times
                                     the specific force the gyro zeros were set at
  g-sensitivity at (n-1) g           C times the rest of the specific force: the load of the
                                     manoeuvres

A group's worth is the 3-D end error of the traditional row minus that with the group added
back; what the five leave is the calibration's own fit error and the unit's random errors
(the `true coefficients` row).
"""
from dataclasses import dataclass

import numpy as np

from ..compensation.model import compensate
from ..sensors.simulation import still_rates
from .replay import comparison_times, navigate_mimu, ned_to_enu, resample
from .table import budget_markdown

GROUPS = ("temperature offset lab-to-flight", "temperature change in flight",
          "nonlinear scale factor", "g-sensitivity at 1 g", "g-sensitivity at (n-1) g")


@dataclass
class ZeroConditions:
    """Where the traditional calibration's zeros were set: the accelerometers' temperature
    readings (degC, (3,)) over the lab's multi-position run; the gyros' resonance
    frequencies (Hz, (3,)) and the specific force they sensed (m/s^2, sensor axes, (3,)) -
    over the lab's rate table, or standing in the launch attitude before flight."""
    accel_temperature: np.ndarray
    gyro_frequency: np.ndarray
    gyro_specific_force: np.ndarray

    @classmethod
    def from_lab(cls, multi_position, rate_table, true):
        """From the lab runs (`lab.runs.LabRun`) the zeros were fitted on; `true`: the
        unit's coefficients (the specific force the rate table's gyros sensed)."""
        raw = rate_table.raw
        f, _, _ = compensate(true, raw["accel_volts"], raw["gyro_volts"],
                             raw["accel_temperature"], raw["gyro_frequency"],
                             filter_outliers=False)
        return cls(multi_position.raw["accel_temperature"].mean(axis=0),
                   raw["gyro_frequency"].mean(axis=0), f.mean(axis=0))

    def with_preflight_gyros(self, still, flight):
        """The gyro zeros taken before flight (`campaign.Still`, in the flight's first
        attitude): their frequencies and the specific force of rest there."""
        tr = flight.truth
        _, f = still_rates(flight.mimu_mounting, tr.q_nb[0], tr.lat[0], tr.h[0])
        return ZeroConditions(self.accel_temperature,
                              still.raw["gyro_frequency"].mean(axis=0), f)


def added_back(flight, true, zero):
    """{group: (df m/s^2, dw rad/s), (N, 3) each, sensor axes}: what each group of the
    unit's true terms adds to the outputs of a calibration that lacks it (module doc). The
    groups telescope: a calibration equal to the true one's linear part with its zeros set
    at `zero` (eqs. 2/4 frozen there, W0 holding C times the zeros' specific force) plus all
    five gives the true outputs exactly - so the temperature groups are taken on the linear
    model and without C, the nonlinear one without C, and C acts on the true specific force."""
    raw = flight.mimu_raw

    def outputs(cal):
        f, w, _ = compensate(cal, raw["accel_volts"], raw["gyro_volts"],
                             raw["accel_temperature"], raw["gyro_frequency"],
                             filter_outliers=False)
        return f, w

    def difference(a, b):
        (fa, wa), (fb, wb) = outputs(a), outputs(b)
        return fa - fb, wa - wb

    no_g = true.without(("C",))
    linear = no_g.without(("A2", "A3", "W2", "W3"))
    first = linear.frozen_at(raw["accel_temperature"][0], raw["gyro_frequency"][0])
    f_true, _ = outputs(true)
    rest = gravity_reaction(flight)
    zero_f = np.zeros_like(f_true)
    return {
        "temperature offset lab-to-flight": difference(
            first, linear.frozen_at(zero.accel_temperature, zero.gyro_frequency)),
        "temperature change in flight": difference(linear, first),
        "nonlinear scale factor": difference(no_g, linear),
        "g-sensitivity at 1 g": (zero_f, (rest - zero.gyro_specific_force) @ true.C.T),
        "g-sensitivity at (n-1) g": (zero_f, (f_true - rest) @ true.C.T)}


def gravity_reaction(flight):
    """(N, 3) m/s^2: the specific force of rest in the flight's true attitude at the MIMU's
    stamps (sensor axes; C_sv C_vn (0, 0, -g)): the 1 g a gyro's g-sensitivity sees in
    unaccelerated flight."""
    tr = flight.truth
    t = np.clip(flight.mimu_t, tr.t[0], tr.t[-1])
    at = resample(tr, t)
    return still_rates(flight.mimu_mounting, at.q_nb, at.lat, at.h)[1]


def traditional_budget(flight, trad, true, zero):
    """The traditional row with each group added back, all five added back, and the unit's
    true coefficients, at the table's end point against the truth: a JSON-ready dict
    (east/north/up m, 3-D norm, and each group's worth: the 3-D error it removes)."""
    t_end = comparison_times(flight)[-1:]
    ref = resample(flight.truth, t_end)
    raw = flight.mimu_raw
    f, w, _ = compensate(trad, raw["accel_volts"], raw["gyro_volts"], raw["accel_temperature"],
                         raw["gyro_frequency"], filter_outliers=False)
    groups = added_back(flight, true, zero)
    rows = {"traditional": (f, w)}
    rows.update({f"+ {name}": (f + df, w + dw) for name, (df, dw) in groups.items()})
    rows["+ all five"] = (f + sum(d[0] for d in groups.values()),
                          w + sum(d[1] for d in groups.values()))
    out = {}
    for name, (fi, wi) in rows.items():
        nav = resample(navigate_mimu(flight, wi, fi), t_end)
        enu = ned_to_enu(nav.position_error(ref)[-1])
        out[name] = {"enu_m": enu.tolist(), "norm_m": float(np.linalg.norm(enu))}
    base = out["traditional"]["norm_m"]
    for row in out.values():
        row["worth_m"] = base - row["norm_m"]
    return {"end_t_s": float(t_end[0]), "zero_conditions": {
        "accel_temperature_degc": zero.accel_temperature.tolist(),
        "gyro_frequency_hz": zero.gyro_frequency.tolist(),
        "gyro_specific_force_m_s2": zero.gyro_specific_force.tolist()}, "variants": out}


def traditional_markdown(doc):
    """The traditional budget as a table: each row's end error and the group's worth."""
    return budget_markdown(doc, "traditional", "east/north/up, with one group of the unit's "
                           "true terms added back to the traditional calibration's outputs at "
                           "a time:", "group worth (3-D m removed)")

"""The virtual calibration lab: the procedures of seeds S1-S4 run on a simulated unit and
recorded as logs, so that a real lab recording is fitted the same way (`calibration`).

Equipment and frames. Every procedure uses a table whose axis is the local vertical: the
single-axis rate table, the centrifuge arm, the three-axis turntable (used statically) and
the thermal chamber's fixture plate. The *platform* frame p turns with the table: z along
the axis pointing down, x along the table's zero mark (the centrifuge: radially outward
along the arm), y completing the right-handed set; its heading from north is the table
angle, positive clockwise seen from above (right-handed about down). The unit sits in a
cube fixture; a *position* is the fixture attitude q_ps (unit sensor axes -> platform) and
the unit origin's place r_p (m, platform axes; the centrifuge radius along x).

Site: the seed paper's laboratory, CAEP Institute of Electronic Engineering, Mianyang
(31.47 N, 104.68 E, 480 m); local gravity is WGS-84 normal gravity there (`earth`).

Lab-state channel `/lab/state` (mimunav_msgs/msg/LabState, frame_id "lab"), one message
when a set point begins (steady = 0), one when it has settled (steady = 1) and one when its
steady part ends (steady = 0); the state holds until the next message. Fields:
    point                  set-point index (consecutive)
    position               index of the fixture position within the procedure
    steady                 1 while the set point is settled and its data usable
    fixture_attitude_wxyz  q_ps, unit sensor axes -> platform (nominal)
    position_m             unit origin in platform axes, m (nominal; centrifuge radius in x)
    table_angle            platform heading at the message stamp, rad (nominal)
    table_rate             steady rate of the table/arm about platform z (down), rad/s
    sensor_radius_m        distance of each sensing element from the axis, m, accelerometers
                           x y z then gyros x y z (eq. 8; the unit model puts every element at
                           the unit origin, so the six are equal)
    chamber_temperature    chamber (or room) air set point, degC
Metadata `lab`: procedure, site {latitude, longitude (rad), height (m), gravity_m_s2,
earth_rate_rad_s}, equipment (the setting-error specification below, 1 sigma), room
temperature, warm-up before logging.

Setting errors (1 sigma, drawn per run and applied to the true motion; the recorded state
is nominal; the fit propagates them into its covariance). Values are those of precision
inertial-test equipment datasheets:
    table_tilt_rad      2 arcsec per horizontal axis, per run       (axis wobble/levelling)
    fixture_rad         3 arcsec per axis, per position             (cube face on the plate)
    rate_rel            1e-6 rate table, 1e-5 centrifuge, per run   (rate accuracy)
    radius_m            0.1 mm per position                         (centrifuge radius)
    axis_offset_m       1 mm per position, unit origin from the rate-table axis (not
                        propagated: its centripetal g-sensitivity effect is < 1e-4 deg/s)
    mechanism_axis_rad  3 arcsec per horizontal axis, per run: the rotation mechanism's
                        axis on the table plate (procedure `rotation`; as a fixture face)

Procedure `rotation` (seed S4, Xu et al. 2011, eqs. 4-5): a rotation mechanism stands on
the rate table with its axis horizontal along platform x and turns the unit continuously at
MECHANISM_RATE about that axis, while the table turns at the set-point rates: a gyro
perpendicular to the mechanism axis sees the table rate as W sin(phi) over every
revolution (eq. 5). The mechanism frame m: z along its axis; at angle phi = 0, m -> platform
is MECHANISM_BASE (m z = platform x). For this procedure a position is the unit's mounting
on the mechanism (`fixture_attitude_wxyz` = sensor -> m) and the mechanism angle phi is
logged at every MIMU sample on `/mimu/platform` (sensor_msgs/msg/JointState, joint
'platform': position rad, read by a circular grating of ENCODER_RESOLUTION_RAD, velocity
rad/s); the `lab` metadata carries `mechanism` {base_attitude_wxyz, rate_rad_s,
encoder_resolution_rad}.
"""
import json
import math
from dataclasses import dataclass, field, replace

import numpy as np
import quaternion
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from ..frames import earth
from ..motion import truth
from ..files import write_atomic
from ..flightlog import LogWriter
from ..flightlog import schemas as S
from ..motion.profile import G0, Ramp, rate_ppoly
from ..frames.mounting import Mounting
from ..motion.platform import ENCODER_RESOLUTION_RAD
from ..sensors.simulation import DEFAULT_EPOCH, epoch_ns, new_outputs
from ..errors import InputError
from ..frames import attitude

SITE = {"latitude": math.radians(31.47), "longitude": math.radians(104.68), "height": 480.0}
ROOM_C = 25.0                       # lab air, degC
ARCSEC = math.pi / 180 / 3600
DEG = math.pi / 180
EQUIPMENT = {"table_tilt_rad": 2 * ARCSEC, "fixture_rad": 3 * ARCSEC, "rate_rel": 1e-6,
             "centrifuge_rate_rel": 1e-5, "radius_m": 1e-4, "axis_offset_m": 1e-3,
             "mechanism_axis_rad": 3 * ARCSEC}
CENTRIFUGE_RADIUS_M = 6.5           # arm rate at 30 g is 385 deg/s: inside the gyro range and
                                    # the rate-table span, as the C fit (eqs. 9-10) needs
CHAMBER_RAMP_C_PER_S = 2.0 / 60     # chamber air slews 2 degC/min between set points
PROCEDURES = ("thermal-chamber", "rate-table", "centrifuge", "multi-position",
              "single-axis-rate", "twelve-position", "cold-start", "rotation", "hand-held")
HAND_HELD_POSITIONS = 24            # orientations of the hand-held procedure (seed S4)
HAND_HELD_SEED = 2024               # draws the hand's orientations (the same every run)
# procedure `rotation` (module doc): the mechanism's rate (one turn in 10 s, two per 20 s
# set point); its grating is `modulation.ENCODER_RESOLUTION_RAD`
MECHANISM_RATE = 36 * math.pi / 180
MECHANISM_RAMP_S = 1.0
MECHANISM_BASE = (math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0)   # 90 deg about y: m z -> p x


def _fixture(axes):
    """q_ps from the platform directions of the sensor x and y axes."""
    x, y = np.asarray(axes[0], float), np.asarray(axes[1], float)
    c_ps = np.column_stack([x, y, np.cross(x, y)])
    return attitude.as_wxyz(quaternion.from_rotation_matrix(c_ps))


# Six cube positions, sensor axis up then down along the table axis (platform -z is up):
# +x up, x down, +y up, y down, +z up, z down (seed S1 figure 3).
SIX_POSITIONS = [_fixture(a) for a in (
    ((0, 0, -1), (0, 1, 0)), ((0, 0, 1), (0, 1, 0)),
    ((1, 0, 0), (0, 0, -1)), ((-1, 0, 0), (0, 0, 1)),
    ((1, 0, 0), (0, -1, 0)), ((1, 0, 0), (0, 1, 0)))]
AXIS_UP = [(0, +1), (0, -1), (1, +1), (1, -1), (2, +1), (2, -1)]  # (axis, +1 up / -1 down)
# Centrifuge: the same cube faces turned 90 deg about platform y, so the named axis points
# inward along the arm (+: toward the axis, senses +r W^2) or outward.
_TO_ARM = attitude.as_wxyz(quaternion.from_rotation_vector([0, math.pi / 2, 0]))
ARM_POSITIONS = [attitude.as_wxyz(attitude.from_wxyz(_TO_ARM)
                                           * attitude.from_wxyz(q))
                 for q in SIX_POSITIONS]


@dataclass
class Point:
    """One set point: position index, steady rate about platform z (rad/s), steady time,
    spin-up/down time and time allowed to settle before the steady part (s), chamber air
    set point (degC)."""
    position: int
    rate: float = 0.0
    hold_s: float = 10.0
    ramp_s: float = 0.0
    settle_s: float = 0.0
    chamber_c: float = ROOM_C

    @property
    def duration(self):
        return self.settle_s + 2 * self.ramp_s + self.hold_s


@dataclass
class Plan:
    """A lab procedure: positions [(q_ps wxyz, r_p m)], set points in order, the log rate
    (the unit's output averaged to it), warm-up before logging (s), the equipment used."""
    procedure: str
    description: str
    rate_hz: float
    positions: list
    points: list
    warm_up_s: float = 1800.0
    rate_rel_key: str = "rate_rel"
    power_cycle: bool = False        # each position a separate cold power-on (seed S3)
    cool_down_s: float = 0.0
    attitudes_known: bool = True     # False: /lab/state records NaN attitudes (hand-held)
    mechanism_rate: float = 0.0      # rad/s: the unit turns on the rotation mechanism


def plan(procedure):
    """The set points of a named procedure (see the module doc and `PROCEDURES`)."""
    on_axis = np.zeros(3)
    six = [(q, on_axis) for q in SIX_POSITIONS]
    if procedure == "thermal-chamber":
        # seed S1 step 1: 0..70 degC in 5 degC steps, 30 min soak, static; the last 15 min
        # of each soak are the steady part
        pts = [Point(5, hold_s=900.0, settle_s=900.0, chamber_c=c) for c in range(0, 75, 5)]
        return Plan(procedure, "thermal chamber 0-70 degC, 5 degC steps, 30 min soak, z down",
                    10.0, six, pts, warm_up_s=0.0)
    if procedure in ("rate-table", "single-axis-rate"):
        # S1 step 2: 0..400 deg/s in 20 deg/s steps, forward and reverse, six positions;
        # "traditional" single-axis rate test: 0..400 deg/s in 100 deg/s steps
        step = 20 if procedure == "rate-table" else 100
        rates = [r * DEG for r in range(0, 401, step)]
        pts = [Point(p, sign * r, hold_s=10.0, ramp_s=2.0 if r else 0.0)
               for p in range(6) for r in rates for sign in (1, -1)]
        return Plan(procedure, f"single-axis rate table, 6 positions, 0-400 deg/s in {step} "
                    "deg/s steps, forward and reverse", 100.0, six, pts)
    if procedure == "centrifuge":
        # S1 step 3: 0..30 g centripetal in 5 g steps, six positions, gravity included
        r = np.array([CENTRIFUGE_RADIUS_M, 0, 0])
        pts = [Point(p, math.sqrt(n * G0 / CENTRIFUGE_RADIUS_M), hold_s=10.0,
                     ramp_s=10.0 if n else 0.0) for p in range(6) for n in range(0, 35, 5)]
        return Plan(procedure, f"centrifuge 0-30 g in 5 g steps at {CENTRIFUGE_RADIUS_M} m, "
                    "6 positions", 100.0, [(q, r) for q in ARM_POSITIONS], pts,
                    rate_rel_key="centrifuge_rate_rel")
    if procedure == "multi-position":
        return Plan(procedure, "six-position static flips, 2 min each", 100.0, six,
                    [Point(p, hold_s=120.0) for p in range(6)])
    if procedure == "twelve-position":
        # seed S2: each axis up and down, each also turned 180 deg about the vertical;
        # 2 min static per position after a 5 min warm-up
        turn = quaternion.from_rotation_vector([0, 0, math.pi])
        twelve = []
        for q in SIX_POSITIONS:
            twelve += [(q, on_axis),
                       (attitude.as_wxyz(turn * attitude.from_wxyz(q)),
                        on_axis)]
        return Plan(procedure, "three-axis turntable, twelve positions, 2 min each", 100.0,
                    twelve, [Point(p, hold_s=120.0) for p in range(12)], warm_up_s=300.0)
    if procedure == "cold-start":
        # seed S3: power on cold, log at 1 Hz with x, then y, then z up (one power-on each,
        # the unit cooled back to room temperature in between)
        return Plan(procedure, "cold-start warm-up, x, y, z up, 40 min each from power-on",
                    1.0, six, [Point(p, hold_s=2400.0) for p in (0, 2, 4)], warm_up_s=0.0,
                    power_cycle=True, cool_down_s=3 * 3600.0)
    if procedure == "hand-held":
        # seed S4 / S1 ref [3]: field calibration without a turntable - the unit set down by
        # hand at orientations nobody measures (uniform on the sphere, random heading), still
        # for 5 s each, on a bench in the room, after a 5 min warm-up
        q = attitude.as_wxyz(attitude.from_scipy(
            Rotation.random(HAND_HELD_POSITIONS, random_state=HAND_HELD_SEED)))
        return Plan(procedure, f"hand-held: {HAND_HELD_POSITIONS} unknown static orientations, "
                    "5 s each", 100.0, [(qi, on_axis) for qi in q],
                    [Point(p, hold_s=5.0, settle_s=1.0) for p in range(HAND_HELD_POSITIONS)],
                    warm_up_s=300.0, attitudes_known=False)
    if procedure == "rotation":
        # seed S4 eqs. 4-5: the unit on the rotation mechanism (axis horizontal), the table
        # at 0-400 deg/s in 40 deg/s steps both ways, 20 s each; three mountings, each
        # sensor axis along the mechanism axis once, so each gyro is swept in two
        on_mechanism = [_fixture(a) for a in (((1, 0, 0), (0, 1, 0)),     # z along the axis
                                              ((0, 0, 1), (1, 0, 0)),     # x along the axis
                                              ((0, 1, 0), (0, 0, 1)))]    # y along the axis
        rates = [r * DEG for r in range(0, 401, 40)]
        pts = [Point(p, sign * r, hold_s=20.0, ramp_s=2.0 if r else 0.0,
                     settle_s=5.0 if (r, sign) == (0, 1) else 0.0)
               for p in range(3) for r in rates for sign in (1, -1)]
        return Plan(procedure, "rotation mechanism (horizontal axis, 36 deg/s) on a level rate "
                    "table, 0-400 deg/s in 40 deg/s steps both ways, 3 mountings", 100.0,
                    [(q, on_axis) for q in on_mechanism], pts, mechanism_rate=MECHANISM_RATE)
    raise InputError(f"unknown lab procedure {procedure!r}; one of {', '.join(PROCEDURES)}")


class TableMotion(truth.Motion):
    """The platform on its table at the site: q_np = q_tilt * Rz(theta(t)), at rest on the
    Earth; theta' follows the set points' rate trapezoids (quintic ramps, `profile`)."""

    def __init__(self, t0, t1, ramps, theta0=0.0, tilt=(0.0, 0.0)):
        self.t0, self.t1 = t0, t1
        self.lat0, self.lon0, self.h0 = SITE["latitude"], SITE["longitude"], SITE["height"]
        self.q_tilt = quaternion.from_rotation_vector([tilt[0], tilt[1], 0.0])
        shifted = [replace(r, t0=r.t0 - t0, t1=r.t1 - t0) for r in ramps]
        self._rate = rate_ppoly(shifted, t1 - t0)
        self._angle = self._rate.antiderivative()
        self._accel = self._rate.derivative()
        self.theta0 = theta0
        self.knots = self._rate.x + t0

    def angle(self, t):
        return self.theta0 + self._angle(np.asarray(t) - self.t0)[..., 0]

    def kinematics(self, t):
        t = np.asarray(t, dtype=float)
        u = t - self.t0
        theta = self.theta0 + self._angle(u)[:, 0]
        zeros = np.zeros((len(t), 3))
        w, dw = zeros.copy(), zeros.copy()
        w[:, 2], dw[:, 2] = self._rate(u)[:, 0], self._accel(u)[:, 0]
        q_z = attitude.from_wxyz(np.stack(
            [np.cos(theta / 2), 0 * theta, 0 * theta, np.sin(theta / 2)], axis=-1))
        return truth.Kinematics(zeros, zeros.copy(), self.q_tilt * q_z, w, dw)


def _small_rotation(q_wxyz, e):
    """q_wxyz turned by the small platform-axes rotation vector e (rad)."""
    return attitude.as_wxyz(quaternion.from_rotation_vector(e)
                                     * attitude.from_wxyz(q_wxyz))


def site_gravity():
    return float(earth.normal_gravity(SITE["latitude"], SITE["height"]))


@dataclass
class _Segment:
    """One power-on's samples: times (s), ideal increments (rad, m/s; sensor axes), bay
    temperature (degC); lists while being built, arrays once done."""
    t: list = field(default_factory=list)
    dtheta: list = field(default_factory=list)
    dv: list = field(default_factory=list)
    env: list = field(default_factory=list)
    angle: list = field(default_factory=list)      # mechanism angle phi as recorded, rad
    angle_rate: list = field(default_factory=list)  # its rate, rad/s


def draw_setting_errors(plan_, seed, equipment=None):
    """Setting errors of one run (drawn from `equipment`, default `EQUIPMENT`, 1 sigma)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    eq = EQUIPMENT if equipment is None else equipment
    n_pos = len(plan_.positions)
    return {"table_tilt_rad": rng.normal(0, eq["table_tilt_rad"], 2),
            "rate_rel": rng.normal(0, eq[plan_.rate_rel_key]),
            "fixture_rad": rng.normal(0, eq["fixture_rad"], (n_pos, 3)),
            "radius_m": rng.normal(0, eq["radius_m"], n_pos),
            "axis_offset_m": rng.normal(0, eq["axis_offset_m"], (n_pos, 2)),
            "mechanism_axis_rad": rng.normal(0, eq.get("mechanism_axis_rad", 0.0), 2)}


def lab_motion(plan_, errors, progress=False):
    """The true lab motion of a plan with its setting errors: per power-on the sample times,
    ideal sensor-axis increments and bay (chamber/room air) temperature, and the lab-state
    messages [(t s, fields)]. Unit-independent, so many units can share it."""
    dt = 1.0 / plan_.rate_hz
    groups = []                      # consecutive points sharing a position
    for k, p in enumerate(plan_.points):
        if groups and groups[-1][0] == p.position and not plan_.power_cycle:
            groups[-1][1].append(k)
        else:
            groups.append((p.position, [k]))
    segments, states, t_now, air = [], [], 0.0, plan_.points[0].chamber_c
    bar = tqdm(total=len(groups), desc=f"lab {plan_.procedure}", disable=not progress,
               unit="position")
    for g, (pos, idx) in enumerate(groups):
        if plan_.power_cycle and g:
            t_now += plan_.cool_down_s
        if plan_.power_cycle or not segments:
            segments.append(_Segment())
        q_nom, r_nom = plan_.positions[pos]
        q_true = _small_rotation(q_nom, errors["fixture_rad"][pos])
        r_true = np.array(r_nom, dtype=float)
        if r_true[0]:
            r_true[0] += errors["radius_m"][pos]
        else:
            r_true[:2] += errors["axis_offset_m"][pos]
        ramps, t_pt, steady = [], t_now, []
        for k in idx:
            p = plan_.points[k]
            t_on = t_pt + p.settle_s
            if p.rate and not p.ramp_s:
                raise InputError(f"set point {k} turns at {p.rate} rad/s with no ramp_s")
            if p.rate:
                ramps.append(Ramp(0, t_on, t_on + 2 * p.ramp_s + p.hold_s,
                                  p.rate * (1 + errors["rate_rel"]), p.ramp_s))
            steady.append((k, t_pt, t_on + p.ramp_s, t_on + p.ramp_s + p.hold_s))
            t_pt += p.duration
        n = int(round((t_pt - t_now) / dt))
        t_grid = t_now + np.arange(n + 1) * dt
        motion = TableMotion(t_now, t_grid[-1], ramps, 0.0, errors["table_tilt_rad"])
        seg = segments[-1]
        if plan_.mechanism_rate:
            turning = mechanism_motion(motion, plan_, q_true, errors, t_grid[-1])
            run_ = truth.generate(turning, t_grid)
            dth, dv = run_.dtheta, run_.dv
            phi = turning.platform.encoder(turning.angle(t_grid))     # as the grating reads
            seg.angle.append(phi[1:] if seg.t else phi)
            seg.angle_rate.append(turning.rate(t_grid[1:] if seg.t else t_grid))
        else:
            run_ = truth.generate(motion, t_grid)
            dth, dv = Mounting(q_true, r_true).sensor_increments(run_)
        if not seg.t:                      # the power-on sample repeats the first interval
            seg.t.append(t_grid[:1]), seg.dtheta.append(dth[:1]), seg.dv.append(dv[:1])
            seg.env.append(np.array([air]))
        seg.t.append(t_grid[1:]), seg.dtheta.append(dth), seg.dv.append(dv)
        env, air = _chamber_air(t_grid, steady, plan_, air)
        seg.env.append(env)
        _lab_states(states, steady, plan_, pos, r_nom, q_nom, motion)
        t_now = t_pt
        bar.update()
    bar.close()
    return [_Segment(*(np.concatenate(x) if x else np.empty(0)
                       for x in (s.t, s.dtheta, s.dv, s.env, s.angle, s.angle_rate)))
            for s in segments], states


def _chamber_air(t_grid, steady, plan_, air):
    """(air temperature at t_grid[1:], degC; the last set point): the chamber air slews at
    CHAMBER_RAMP_C_PER_S from `air` toward each steady point's set point from its start."""
    set_points = np.array([plan_.points[k].chamber_c for k, *_ in steady])
    starts = np.array([s[1] for s in steady])
    which = np.searchsorted(starts, t_grid[1:], side="right") - 1
    prev = np.concatenate([[air], set_points[:-1]])
    target, origin = set_points[which], prev[which]
    slew = CHAMBER_RAMP_C_PER_S * (t_grid[1:] - starts[which])
    return origin + np.clip(target - origin, -slew, slew), set_points[-1]


def _lab_states(states, steady, plan_, pos, r_nom, q_nom, motion):
    """Append the /lab/state messages (t s, fields) of the steady points: at each point's
    start, its steady part's start and end."""
    for k, t_begin, t_steady, t_end in steady:
        p = plan_.points[k]
        base = dict(point=k, position=pos,
                    fixture_attitude_wxyz=q_nom if plan_.attitudes_known else
                    np.full(4, np.nan),
                    position_m=np.asarray(r_nom, float), table_rate=p.rate,
                    sensor_radius_m=np.full(6, float(np.hypot(*np.asarray(r_nom)[:2]))),
                    chamber_temperature=p.chamber_c)
        for stamp, flag in ((t_begin, 0), (t_steady, 1), (t_end, 0)):
            if states and abs(states[-1][0] - stamp) < 1e-9:
                states.pop()           # a steady part ending where the next point begins
            states.append((stamp, dict(base, steady=flag,
                                       table_angle=float(motion.angle(stamp)))))


def mechanism_motion(table, plan_, q_ps, errors, t_end):
    """The unit turning on the rotation mechanism (module doc) on the table motion `table`:
    a `modulation.RotatingMotion` whose body is the sensor, its mechanism axis carrying the
    run's setting error `mechanism_axis_rad` (platform axes) and the unit mounted at q_ps."""
    from ..motion.platform import Platform, RotatingMotion
    tilt = errors["mechanism_axis_rad"]
    base = (quaternion.from_rotation_vector([tilt[0], tilt[1], 0.0])
            * attitude.from_wxyz(MECHANISM_BASE))
    mechanism = Platform("continuous", plan_.mechanism_rate, ramp_s=MECHANISM_RAMP_S,
                         encoder_resolution_rad=ENCODER_RESOLUTION_RAD,
                         base_wxyz=tuple(attitude.as_wxyz(base)),
                         imu_wxyz=tuple(np.asarray(q_ps, float)))
    return RotatingMotion(table, mechanism, t_end)


def record(plan_, unit, segments, seed, hidden=None):
    """The unit's raw outputs over the lab motion (one power-on per segment), noise drawn
    from `seed`: the `/mimu/raw` fields plus truth extras (`MimuUnit.simulate`)."""
    lab_unit = replace(unit, rate_hz=plan_.rate_hz)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
    raws = [lab_unit.simulate(s.t, s.dtheta, s.dv, s.env, rng, hidden=hidden,
                              warm_up_s=plan_.warm_up_s) for s in segments]
    raw = {k: np.concatenate([r[k] for r in raws]) for k in raws[0]}
    raw["sample_index"] = np.arange(len(raw["t"]), dtype=np.uint64)
    if plan_.mechanism_rate:
        raw["mechanism_angle"] = np.concatenate([s.angle for s in segments])
        raw["mechanism_rate"] = np.concatenate([s.angle_rate for s in segments])
    return raw


def run(plan_, unit, out, seed, force=False, progress=True, equipment=None, hidden=None):
    """Simulate `plan_` on `unit` (a `MimuUnit`) and write the log `out` (+ `out` with
    .truth.json beside it: the unit and the drawn setting errors). `equipment` replaces
    the setting-error specification `EQUIPMENT` (1 sigma); `hidden` is passed to
    `MimuUnit.simulate` (physics the 63-coefficient model lacks). Returns (log, truth)."""
    truth_path = new_outputs(out, force)
    eq = EQUIPMENT if equipment is None else equipment
    errors = draw_setting_errors(plan_, seed, eq)
    segments, states = lab_motion(plan_, errors, progress)
    raw = record(plan_, unit, segments, seed, hidden)
    _write(out, plan_, raw, states, eq, force)
    write_atomic(truth_path, json.dumps({
        "format": "mimunav-lab-truth/1", "log": str(out), "seed": seed,
        "procedure": plan_.procedure, "mimu": unit.as_dict(),
        "setting_errors": {k: np.asarray(v).tolist() for k, v in errors.items()},
        "saturated_samples": int(raw["saturated"].sum())}, indent=1) + "\n", force=force)
    return str(out), truth_path


def lab_metadata(plan_, equipment=None):
    """The `lab` metadata record of a run (values before JSON encoding)."""
    eq = EQUIPMENT if equipment is None else equipment
    return {"procedure": plan_.procedure,
            "site": dict(SITE, gravity_m_s2=site_gravity(), earth_rate_rad_s=earth.OMEGA),
            "equipment": {**eq, "rate_rel": eq[plan_.rate_rel_key]},
            "room_temperature_c": ROOM_C, "warm_up_s": plan_.warm_up_s,
            "power_cycle": plan_.power_cycle,
            **({"mechanism": {"base_attitude_wxyz": list(MECHANISM_BASE),
                              "rate_rad_s": plan_.mechanism_rate,
                              "encoder_resolution_rad": ENCODER_RESOLUTION_RAD}}
               if plan_.mechanism_rate else {})}


def state_arrays(states):
    """Lab-state messages [(t, fields)] as (stamps s, {field: array})."""
    return (np.array([s[0] for s in states]),
            {name: np.array([s[1][name] for s in states]) for name, _, _ in S.BODIES[S.LAB_STATE]})


def _write(out, plan_, raw, states, equipment, force):
    epoch = epoch_ns(DEFAULT_EPOCH)
    stamp = lambda t: epoch + np.round(np.asarray(t) * 1e9).astype(np.int64)   # noqa: E731
    q0 = attitude.as_wxyz(attitude.from_wxyz(plan_.positions[0][0]))
    with LogWriter(out, force=force) as log:
        log.metadata("flight", {
            "format": "mimunav-log/1", "name": f"lab/{plan_.procedure}",
            "description": plan_.description, "epoch_unix_ns": str(epoch),
            "source": "simulation",
            "initial_state": {"t": 0.0, "latitude": SITE["latitude"],
                              "longitude": SITE["longitude"], "height": SITE["height"],
                              "velocity_ned": [0.0, 0.0, 0.0], "attitude_wxyz": [1.0, 0, 0, 0]}})
        log.metadata("sensor/mimu", {
            "model": "MEMS IMU, 63-coefficient model (simulated)",
            "sample_rate_hz": str(plan_.rate_hz),
            "mounting": {"attitude_wxyz": q0.tolist(), "lever_arm_m": [0.0, 0.0, 0.0]},
            "mounting_note": "the fixture position changes; see /lab/state"})
        log.metadata("lab", lab_metadata(plan_, equipment))
        log.write("/mimu/raw", S.RAW_MIMU, "mimu", stamp(raw["t"]),
                  sample_index=raw["sample_index"], gyro_volts=raw["gyro_volts"],
                  accel_volts=raw["accel_volts"], accel_temperature=raw["accel_temperature"],
                  gyro_frequency=raw["gyro_frequency"])
        if "mechanism_angle" in raw:
            log.write("/mimu/platform", S.JOINT_STATE, "platform", stamp(raw["t"]),
                      **S.platform_fields(raw["mechanism_angle"], raw["mechanism_rate"]))
        ts, fields = state_arrays(states)
        log.write("/lab/state", S.LAB_STATE, "lab", stamp(ts), **fields)

"""What carried an IMU, judged from its reference track and its specific force: a land
vehicle on wheels (a car), whose track gives its attitude under the no-side-slip model and
whose course is its heading, or anything else - an aircraft, a multicopter, a rocket, a
walker's phone - whose track does not. Only called a car when every test below holds (a
recording that cannot show it is not one):

    MOVING_SPEED    it moves like a vehicle: its horizontal speed's 95th percentile at least
                    this (a walker, a hovering multicopter, a parked car stay below)
    CAR_SPEED       and at most this at the 99th (an airliner, a rocket exceed it)
    GRADE           its climb over its horizontal distance, the 99th percentile of |v_d| / v
                    where it moves, at most this (a climbing aircraft or rocket exceed it)
    STILL_CLIMB     where it hardly moves horizontally, |v_d| at most this (a multicopter
                    climbs on the spot; a car does not)
    LOAD            the IMU's 1 s mean |specific force| within this of 1 g in 99.5 % of the
                    seconds (a rocket's boost or coast, an aircraft's pull or push exceed it)
    BODY_RATE       the IMU's roll and pitch rate - its 1 s mean rate across its mean down,
                    the median rate (a bias) removed - at most this in 95 % of the seconds
                    (a boat's roll, an aircraft's or a multicopter's manoeuvres exceed it)
    BODY_RATE_MEDIAN  and at most this in half of them (a boat on waves rolls all the time,
                    a car mostly in its turns)
    LEAN_SHARE      where the track turns (its lateral acceleration beyond TURN_ACCEL at
                    MOVING_SPEED or more), the IMU's 1 s mean specific force across its
                    mean down at least this share of the track's horizontal acceleration,
                    in the median: a car's IMU feels its turns sideways (its share 0.9-1.1
                    with the body's roll), a motorcycle's or an aircraft's leans or banks
                    into them and feels them little (a motorcycle's sparse bends had
                    passed BODY_RATE: 4.5 deg/s of roll at the 95th percentile)
The climbs are judged on the velocities' CLIMB_WINDOW_S means: a phone's 1 Hz altitudes
(1 m of noise each) had climbed at 2.2 m/s on the spot by their differences.
"""
import numpy as np

LAND = "car"
ALONG_COURSE = (LAND, "train", "two-wheeler")   # what moves along its forward axis: its
#                                    course its heading (a car or a two-wheeler without
#                                    side slip, a train on its rails)
EITHER_END = ("train",)             # what runs either end first: its course its heading or
#                                    the heading's opposite


def course_keys(vehicle, judged=None):
    """The keys of a track (`navigation.alignment`'s dict) that say what carries the IMU:
    `vehicle`, the declared kind (None: not declared), and `faces_course`, whether its
    course may stand for its heading - a declared kind of ALONG_COURSE, or for one not
    declared what the import judged (`judged`: True, False; None: not judged, taken as
    facing it)."""
    return {"vehicle": vehicle, "faces_course": vehicle in ALONG_COURSE if vehicle else
            judged is not False}


def recorded_kind(recording):
    """(vehicle, judged) of `course_keys` from a log's `recording` metadata: the kind
    declared, and whether the import judged that its course faces its heading (None in a
    log written before it said so)."""
    return recording.get("vehicle"), recording.get("faces_course")


def declared(vehicle):
    """What carries the IMU, as declared (a `vehicle` kind; None: judged by the import no
    car, `course_keys`), for messages."""
    return f"a vehicle declared {vehicle!r}" if vehicle else \
        "a vehicle its track and IMU judge no car (the import's course checks)"


MOVING_SPEED = 5.0          # m/s: 18 km/h - a car's drive reaches it most of the time it moves
CAR_SPEED = 70.0            # m/s: 250 km/h
GRADE = 0.3                 # 30 %: steeper than any public road (the steepest about 35 % over
                            # metres; 99 % of a drive's moving epochs far below)
STILL_CLIMB = 1.5           # m/s, below 2 m/s of horizontal speed
LOAD = 0.5 * 9.80665        # m/s^2: 0.5 g - a car's hardest braking or cornering on dry road
                            # adds about 1 g horizontally: |f| = sqrt(2) g, 0.41 g over
BODY_RATE = np.radians(5.0)  # rad/s: 3 x the most a car showed over a drive - its body
                            # and the road turn it 0.2-1.6 deg/s (95 %; the RTKLIB and
                            # comma2k19 drives, independent simulators' over hills and on
                            # springs); a 75 s excerpt of the RTKLIB drive with a sharp turn
                            # 3.4; a moored-and-sailing boat's roll 10, a light aircraft's 17,
                            # a multicopter's 30
BODY_RATE_MEDIAN = np.radians(1.0)  # rad/s: the same rate's median - a car turns about its
                            # level axes in its turns and stops, seldom between them: 0.19-0.45
                            # deg/s (those drives and the excerpt); a survey ship's waves (2.2
                            # deg rms of roll at 8 s) 1.47 all the time, moored 1.16 - which
                            # had passed the 95th percentile's 5 as a car (3.5) and been answered
                            # 'no missing physics' by the car's model
LEAN_SHARE = 0.6            # of the track's horizontal acceleration, felt across the IMU's
#                             down in its turns: a car 0.9-1.1, a coordinated lean or bank
#                             near its longitudinal share (below 0.5 in a bend)
TURN_ACCEL = 1.5            # m/s^2: a turn that shows it; 10 s of such turning at least
CLIMB_WINDOW_S = 10.0       # s: the velocities' means the climbs are judged on (a climb on the
#                             spot that decides, a multicopter's take-off, lasts longer)


def car_tests(t_track, v_ned, t=None, f=None, w=None, moving=True):
    """([the tests the track fails, said], [the numbers that passed them]) of a reference
    track's NED velocities v_ned (m/s, (M, 3)) at its epochs t_track (s) and the IMU's
    specific force f (m/s^2) and rate w (rad/s) (sensor axes, (N, 3)) at its stamps t (s) -
    None: not recorded (a raw /mimu/raw), the load and the body rate not tested; `moving`
    False: MOVING_SPEED not tested (a car parked or in a jam is a car still)."""
    v = epoch_means(np.asarray(t_track, float), np.asarray(v_ned, float), CLIMB_WINDOW_S / 2)
    ok = np.isfinite(v).all(axis=1)
    if not ok.any():
        return [f"its track is shorter than the {CLIMB_WINDOW_S:g} s the tests need"], []
    speed, climb = np.hypot(v[ok, 0], v[ok, 1]), np.abs(v[ok, 2])
    failed, numbers = [], []
    # its speed over 1 s, not the size of its 10 s mean velocity: a multicopter's figure
    # eights at 3.8 m/s had 'moved' at 0.3 m/s
    v_1s = epoch_means(np.asarray(t_track, float), np.asarray(v_ned, float), 0.5)
    p95, p99 = (float(np.nanpercentile(np.hypot(v_1s[:, 0], v_1s[:, 1]), q)) for q in (95, 99))
    if moving and p95 < MOVING_SPEED:
        failed.append(f"its speed's 95th percentile is {p95:.1f} m/s (a car's drive reaches "
                      f"{MOVING_SPEED:g})")
    if p99 > CAR_SPEED:
        failed.append(f"its speed's 99th percentile is {p99:.0f} m/s (over {CAR_SPEED:g})")
    moving = speed > 2.0
    grade = float(np.percentile(climb[moving] / speed[moving], 99)) if moving.any() else 0.0
    if grade > GRADE:
        failed.append(f"it climbs or descends at {100 * grade:.0f} % of its horizontal speed "
                      f"(99th percentile; a road at most {100 * GRADE:.0f} %)")
    still = np.flatnonzero(~moving)
    k = still[np.argmax(climb[still])] if len(still) else None
    if k is not None and climb[k] > STILL_CLIMB:
        failed.append(f"it {'descends' if v[ok][k, 2] > 0 else 'climbs'} at {climb[k]:.1f} "
                      "m/s while hardly moving horizontally")
    load = None if f is None else _load(t, f)
    if load is not None and load > LOAD:
        failed.append(f"its IMU's 1 s mean |specific force| is {load / 9.80665:.2f} g off 1 g "
                      f"in 0.5 % of the seconds (a car at most {LOAD / 9.80665:.1f} g)")
    body, usual = (None, None) if f is None or w is None else _body_rate(t, f, w)
    if body is not None and body > BODY_RATE:
        failed.append(f"its IMU rolls or pitches at {np.degrees(body):.1f} deg/s (95th "
                      f"percentile of 1 s means; a car at most {np.degrees(BODY_RATE):g})")
    if usual is not None and usual > BODY_RATE_MEDIAN:
        failed.append(f"its IMU rolls or pitches at {np.degrees(usual):.1f} deg/s half the "
                      f"time (median of 1 s means; a car at most "
                      f"{np.degrees(BODY_RATE_MEDIAN):g}, between its turns: a boat on waves)")
    lean = None if f is None else _turn_share(np.asarray(t_track, float),
                                              np.asarray(v_ned, float), t, f)
    if lean is not None and lean < LEAN_SHARE:
        failed.append(f"its IMU feels {lean:.2f} of its track's acceleration across its down "
                      f"in its turns (median; a car's feels it all, at least {LEAN_SHARE:g}: "
                      "it leans or banks into them)")
    numbers = [f"speed p95 {p95:.1f} m/s, p99 {p99:.1f} m/s", f"grade p99 {100 * grade:.0f} %",
               f"climb at standstill {climb[k] if k is not None else 0.0:.1f} m/s"] + \
        ([f"load {load / 9.80665:.2f} g off 1 g (99.5 %)"] if load is not None else []) + \
        ([f"roll and pitch rate {np.degrees(body):.1f} deg/s (95 %), "
          f"{np.degrees(usual):.1f} (median)"] if body is not None else []) + ([f"turns felt across {lean:.2f}"] if lean is not None else [])
    return failed, numbers


WALKING_SPEED = 12.5        # m/s: the fastest 100 m ever run peaked near 12.4 m/s; a walk
#                             1-2 m/s, a run 3-6 (99th percentile of its 10 s means)
TRACK_LIKE_A_CAR = ("train",)   # whose track and IMU pass these tests as a car's do: a
#                             train's canted curves are felt across its down in part


ON_THE_GROUND = {"aircraft": " - as an aircraft's do that only taxied"}   # what else passes


def contradiction(vehicle, t_track, v_ned, t=None, f=None, w=None):
    """Why a declared `vehicle` (one of `importers.kinds.VEHICLES`) is not what its track and
    IMU show (`car_tests`' arguments), or '': a car that fails a car test (but its speed's:
    parked, it is a car still, an independent review); a walker faster than WALKING_SPEED;
    any other kind (but TRACK_LIKE_A_CAR) whose track and IMU pass every car test, the turns
    felt across its down made too - none of them feels its turns all sideways at a car's
    speeds without leaving its track (an independent trial's car drive declared a pedestrian
    at 25 m/s and 3 m/s^2 turns had gone without a word; an aircraft that only taxied does,
    and the words say so)."""
    if vehicle == LAND:         # one that hardly moved is not judged by its speed
        failed, _ = car_tests(t_track, v_ned, t, f, w, moving=False)
        return f"its track and IMU are not a car's: {'; '.join(failed)}" if failed else ""
    failed, numbers = car_tests(t_track, v_ned, t, f, w)
    v = epoch_means(np.asarray(t_track, float), np.asarray(v_ned, float), CLIMB_WINDOW_S / 2)
    v = v[np.isfinite(v).all(axis=1)]
    fastest = float(np.percentile(np.hypot(v[:, 0], v[:, 1]), 99)) if len(v) else 0.0
    if vehicle == "pedestrian" and fastest > WALKING_SPEED:
        return (f"its speed's 99th percentile is {fastest:.1f} m/s: no one walks or runs "
                f"faster than {WALKING_SPEED:g}")
    felt = f is not None and w is not None and \
        _turn_share(np.asarray(t_track, float), np.asarray(v_ned, float), t, f) is not None
    if vehicle in TRACK_LIKE_A_CAR or failed or not felt:
        return ""
    return (f"its track and IMU pass every test of a car's ({', '.join(numbers)})"
            + (ON_THE_GROUND.get(vehicle, "")))


def epoch_means(t, x, half):
    """Means of the rows of x (M, k), real or complex, within +-half s of each of its epochs
    t (s), the finite ones; NaN where
    that window runs past the track's ends (a one-sided window over one-sided differences:
    a 1 Hz track's last epoch had 'climbed 1.7 m/s' on 2 m of height noise)."""
    c = np.vstack([np.zeros((1, x.shape[1])), np.nancumsum(x, axis=0)])
    n = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(np.isfinite(x), axis=0)])
    lo, hi = np.searchsorted(t, t - half), np.searchsorted(t, t + half, "right")
    with np.errstate(invalid="ignore", divide="ignore"):
        out = (c[hi] - c[lo]) / (n[hi] - n[lo])
    out[(t - half < t[0]) | (t + half > t[-1])] = np.nan
    return out


def _seconds(t, x):
    """1 s means of x (N, 3) at stamps t (s), the seconds with samples."""
    sec = np.floor(t - t[0]).astype(int)
    count = np.bincount(sec)
    return np.column_stack([np.bincount(sec, x[:, i]) for i in range(3)])[count > 0] / \
        count[count > 0, None]


def _turn_share(t_track, v_ned, t, f):
    """The median, over the track's epochs that turn (lateral acceleration beyond TURN_ACCEL
    and its own noise at MOVING_SPEED or more, from its velocities' 1 s means), of the IMU's
    1 s mean specific
    force across its mean down (sensor axes: mounting-free) over the track's horizontal
    acceleration there; None with under 10 s of such turning."""
    v = epoch_means(t_track, v_ned, 0.5)
    ok = np.isfinite(v).all(axis=1)
    if ok.sum() < 10:
        return None
    tt, v = t_track[ok], v[ok]
    speed = np.hypot(v[:, 0], v[:, 1])
    lateral = speed * np.gradient(np.unwrap(np.arctan2(v[:, 1], v[:, 0])), tt)
    along = np.gradient(speed, tt)
    # and beyond 4 times its own noise (epoch-to-epoch differences' MAD): a 0.5 m fix's
    # differenced track turns at 3 m/s^2 of noise, and its 'turns' had read a car 0.23
    step = np.diff(lateral)
    noise = 1.4826 * float(np.median(np.abs(step - np.median(step)))) / np.sqrt(2)
    turning = (np.abs(lateral) > max(TURN_ACCEL, 4 * noise)) & (speed >= MOVING_SPEED)
    if turning.sum() * float(np.median(np.diff(tt))) < 10.0:
        return None
    f_s = _seconds(t, f)
    t_s = t[0] + np.unique(np.floor(t - t[0])) + 0.5
    down = _down(f_s)
    across = np.linalg.norm(f_s - np.outer(f_s @ down, down), axis=1)
    felt = np.interp(tt[turning], t_s, across)
    return float(np.median(felt / np.hypot(lateral[turning], along[turning])))


def _body_rate(t, f, w):
    """The 95th percentile and the median (rad/s) of the IMU's 1 s mean rate across its mean
    down (the median of its specific force's directions), the median rate removed: what a
    car's body and road turn about its level axes."""
    f_s, w_s = _seconds(t, f), _seconds(t, w)
    down = _down(f_s)
    w_s = w_s - np.median(w_s, axis=0)
    across = np.linalg.norm(w_s - np.outer(w_s @ down, down), axis=1)
    return float(np.percentile(across, 95)), float(np.median(across))


def _down(f_s):
    """The IMU's mean down (sensor axes, unit): the median of the directions of its 1 s mean
    specific forces f_s."""
    down = np.median(f_s / np.linalg.norm(f_s, axis=1)[:, None], axis=0)
    return down / np.linalg.norm(down)


def _load(t, f):
    """The 99.5th percentile of | |1 s mean specific force| - g | (m/s^2) of specific forces
    f (m/s^2) at stamps t (s)."""
    return float(np.percentile(np.abs(np.linalg.norm(_seconds(t, f), axis=1) - 9.80665), 99.5))

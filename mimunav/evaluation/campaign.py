"""Monte Carlo campaign: many drawn units (and noise realisations) through the same lab
procedures and the same flight, each calibrated `entire` and `traditional` and replayed;
the distribution of every normalised end-point error per variant.

Reproducible from one seed: unit i is drawn from SeedSequence(seed).spawn(n)[i]; its lab
runs and its flight take their noise from the same sequence; the lab's setting errors are
the lab's (drawn once from the seed, shared by every unit, as one lab session would be).
The flight is simulated in memory (`simulation.flight_motion` once per process, then each
unit's outputs) exactly as `mimunav simulate` would write it. Results stream to a JSON-lines file, one unit per line as it finishes, so an interrupted
campaign resumes where it stopped. Units run on local processes, or on a Dask cluster when
given a scheduler address (`dask[distributed]`, optional).

Each unit's record carries the version of the code that made it (`code_version`): a campaign
resumed after the simulator changed computes its earlier units again rather than mix two
simulators' draws in one distribution, and a unit made by a worker running other code is
refused.
"""
import hashlib
import json
import multiprocessing
import os
from concurrent.futures import as_completed
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..lab import procedures as lab
from ..sensors import simulation
from ..lab.calibrate import calibrate
from ..lab.preflight import gyro_zero
from ..lab.runs import LabRun
from .flight import Flight
from .ground import ALIGN_S, begins_at_rest, ground_start
from .table import normalised_table
from ..kernels import code_version
from .. import FLIGHTS
from ..motion.profile import Profile
from ..sensors.mimu import MimuUnit
from ..frames.mounting import Mounting
from ..sensors.simulation import GROUND_TEMPERATURE_C, MIMU_MOUNTING
from ..errors import InputError, require, warn
from ..sensors.fog import FOG_GRADE_SOURCES, FOG_GRADES
from ..sensors.mimu import MIMU_GRADE_SOURCES, MIMU_GRADES, NONLINEARITY, NONLINEARITY_SOURCES

VARIANTS = {"traditional": ("multi-position", "single-axis-rate"),
            "entire": ("thermal-chamber", "rate-table", "centrifuge")}
_MOTIONS = {}                        # per process: (procedure, lab seed) -> lab motion
_FLIGHTS = {}                        # per process: flight key -> simulation.FlightMotion
WARM_UP_S = 600.0                    # s, see SOURCES
# the traditional calibration's gyro zero: "pre-flight" (`lab.preflight`: taken over the
# warm-up's last PREFLIGHT_S seconds, still in the launch attitude; the default, SOURCES) or
# "lab" (fitted with its scale factors on the rate table at the lab's temperature)
GYRO_ZEROS = ("lab", "pre-flight")
STARTS = ("air", "ground")          # `Scenario.start`, see START_SOURCES
START_SOURCES = {
    "air": "air: both navigators start from the exact state at the flight's first sample "
           "(the seed says nothing of the alignment); 'ground': from the FOG-IMU's "
           "gyrocompass on the pad (evaluation.ground) - needs a profile that begins at rest",
    "ground": "ground: both navigators start from the FOG-IMU's gyrocompass on the pad over "
              "the flight's first 120 s (evaluation.ground; the alignment's span assumed, "
              "datasheet class), the MIMU given the same attitude - the seed says nothing of "
              "the alignment; its error is common to both IMUs"}
PREFLIGHT_S = 10.0                   # s: seed S1 Table 1 states the gyro zero over 10 s
MIN_DURATION_S = 10.0                # s: a shorter end point is the initial state's error


@dataclass(frozen=True)
class Scenario:
    """Everything that shapes a Table 3 comparison besides the seed; each default sourced
    (`SOURCES`). flight: profile TOML; severity: its dynamics scaled (`profile.
    scale_severity`); ground_temperature_c: the day's air temperature at the start height,
    degC; warm_up_s: the MIMU powered on this long before take-off, s; mimu_grade: `sensors.mimu.MIMU_GRADES`; nonlinearity: "table1" | "table2"
    (`sensors.mimu`); fog_grade: `sensors.fog.FOG_GRADES`; beyond_model: the MIMU carries
    physics eqs. 1-4 lack (`sensors.mimu`)."""
    flight: str = str(FLIGHTS / "high-dynamic.toml")
    severity: float = 1.0
    ground_temperature_c: float = GROUND_TEMPERATURE_C
    warm_up_s: float = WARM_UP_S
    mimu_grade: str = "table1"
    nonlinearity: str = "table1"
    fog_grade: str = "table4"
    beyond_model: bool = True
    gyro_zero: str = "pre-flight"
    start: str = "air"
    g_sensitivity: float = 1.0
    duration_s: float = 0.0

    def __post_init__(self):
        for value, allowed, what in ((self.mimu_grade, MIMU_GRADES, "MIMU grade"),
                                     (self.nonlinearity, NONLINEARITY, "nonlinearity"),
                                     (self.fog_grade, FOG_GRADES, "FOG grade"),
                                     (self.gyro_zero, GYRO_ZEROS, "gyro zero"),
                                     (self.start, STARTS, "start")):
            if value not in allowed:
                raise InputError(f"{what} {value!r}: one of {', '.join(allowed)}")
        if not 0.0 <= self.warm_up_s <= 86400.0:
            raise InputError(f"warm-up {self.warm_up_s} s: expected 0..86400")
        if self.gyro_zero == "pre-flight" and self.warm_up_s < PREFLIGHT_S:
            raise InputError(f"a pre-flight gyro zero takes the warm-up's last {PREFLIGHT_S:g} s:"
                             f" a warm-up of {self.warm_up_s:g} s is shorter (a warm-up of at "
                             f"least {PREFLIGHT_S:g} s, or the lab's zero: --gyro-zero lab)")
        if self.start == "ground":
            begins_at_rest(self.profile())
        if not 0.0 <= self.g_sensitivity <= 100.0:
            raise InputError(f"g-sensitivity factor {self.g_sensitivity}: expected 0..100")
        # the navigators start ALIGN_S into the flight from the pad (`ground_start`)
        navigated = self.profile().motion().t1 - (ALIGN_S if self.start == "ground" else 0.0) \
            if self.duration_s else 0.0
        if self.duration_s and not MIN_DURATION_S <= self.duration_s < navigated:
            raise InputError(f"duration {self.duration_s} s: 0 (the flight's end) or "
                             f"{MIN_DURATION_S:g} s to less than the {navigated:.0f} s the "
                             "navigators fly")
        if not -60.0 <= self.ground_temperature_c <= 60.0:
            raise InputError(f"ground temperature {self.ground_temperature_c} degC: "
                             "expected -60..60")

    def identity(self):
        """JSON-ready, with the flight by file name and content hash (a campaign file moves
        with its data; another profile of the same name is another campaign)."""
        digest = hashlib.sha256(Path(self.flight).read_bytes()).hexdigest()[:16]
        doc = dict(asdict(self), flight=Path(self.flight).name, flight_sha256=digest)
        if self.gyro_zero == "lab":     # the only zero before there was a choice: the
            del doc["gyro_zero"]        # campaigns written then resume as they were
        if self.start == "air":         # likewise the only start before the ground one
            del doc["start"]
        if self.g_sensitivity == 1.0:   # and the drawn g-sensitivity as drawn
            del doc["g_sensitivity"]
        if not self.duration_s:         # and the flight's own end
            del doc["duration_s"]
        return doc

    def source(self, key):
        """Where this scenario's value of option `key` comes from (`SOURCES` for the
        defaults; the value's own source, or "given", otherwise)."""
        value = getattr(self, key)
        if key == "mimu_grade":
            return MIMU_GRADE_SOURCES[value]
        if key == "fog_grade":
            return FOG_GRADE_SOURCES[value]
        if key == "start":
            return START_SOURCES[value]
        if key == "nonlinearity":
            return NONLINEARITY_SOURCES[value]
        if value == getattr(Scenario(), key) and (key != "flight" or Path(value).resolve()
                                                  == Path(Scenario().flight).resolve()):
            return SOURCES[key]
        if key == "flight":
            return f"given: {Path(value).resolve()} ({Profile.load(value).description})"
        if key == "beyond_model":
            return "given: the MIMU is exactly the 63-coefficient model"
        return "given on the command line"

    def profile(self):
        return Profile.load(self.flight, self.severity)

    def draw_unit(self, seed, name):
        unit = MimuUnit.draw(seed, nonlinearity=self.nonlinearity, name=name,
                             beyond_model=self.beyond_model, grade=self.mimu_grade)
        unit.mounting = Mounting.from_dict(MIMU_MOUNTING)
        unit.coefficients.C = unit.coefficients.C * self.g_sensitivity
        return unit

    def flight_key(self):
        return (str(Path(self.flight).resolve()), self.severity, self.ground_temperature_c)


# Where each default of `Scenario` comes from (the Table 3 report's first table).
SOURCES = {
    "flight": "seed S1 section 4.2 ('high overload and high dynamics'); the shipped profile "
              "flies the MIMU's rated ranges of Table 1 (30 g, 400 deg/s)",
    "severity": "1 = the profile as written; g exposure n - 1 and rates scale with it",
    "ground_temperature_c": "ISA sea-level air 15 degC; the bay lags the air (900 s, "
                            "sensors.thermal)",
    "warm_up_s": "assumption: both IMUs powered before take-off for the reference FOG-IMU's "
                 "ground alignment and the checks around it (an alignment of 2-15 min, "
                 "datasheet class): 600 s; 0 = MIMU cold at take-off",
    "mimu_grade": "seed S1 Table 1 at its bound (gyro zero drift 30 deg/h, accel 1 mg as "
                  "10 s bias stability; ADXRS-class white noise), sensors.mimu.MIMU_GRADES",
    "nonlinearity": "Table 2 ranges scaled to Table 1's fit residual (the spec's corrected "
                    "reading); 'table2' = literally",
    "fog_grade": "seed S1 Table 4 read as medium accuracy, bounds at ~2 sigma "
                 "(sensors.fog.FOG_GRADES)",
    "gyro_zero": "pre-flight: the traditional calibration's gyro zero taken still in the "
                 "launch attitude over the warm-up's last 10 s (seed S1 names what its refs "
                 "[2-5] calibrate in the lab - cross-coupling, accelerometer zero and first-"
                 "order scale, gyro scale - and no gyro zero; a MEMS gyro's zero taken at "
                 "power-on before flight is the ordinary practice); 'lab': fitted on the rate "
                 "table at 25 degC (the project's first reading)",
    "start": START_SOURCES["air"],
    "duration_s": "0 = the end point at the flight's end (the seed gives no flight "
                  "duration); else this long after the navigators' start, s: the same "
                  "flight ended earlier",
    "g_sensitivity": "1 = the gyros' g-sensitivity C as drawn from seed S1 Table 2 (0.01-0.04 "
                     "(deg/s)/g per entry); the factor scales it (0: none)",
    "beyond_model": "sensing elements simulated forward (cross-axis nonlinearity, "
                    "sensors.response), scale asymmetry 50-200 ppm and seed S3's dT term "
                    "(assumed magnitudes, sensors.mimu)",
}


def _lab_motion(procedure, lab_seed):
    key = (procedure, lab_seed)
    if key not in _MOTIONS:
        plan = lab.plan(procedure)
        _MOTIONS[key] = lab.lab_motion(plan, lab.draw_setting_errors(plan, lab_seed))
    return _MOTIONS[key]


def one_blas_thread():
    """Initializer of a worker process: one BLAS thread (threadpoolctl), since the workers
    already fill the cores - two workers with a multi-threaded BLAS each ran 3-4x slower on
    2 cores (the concealed-data suite: 33 s per recording against 9 s)."""
    from threadpoolctl import threadpool_limits
    threadpool_limits(1)


def unit_seed(seed, index):
    return int(np.random.SeedSequence(seed).spawn(index + 1)[index].generate_state(1)[0])


def run_unit(scenario, seed, index):
    """One unit of `scenario` through both calibrations and the flight; a JSON-ready dict."""
    useed = unit_seed(seed, index)
    unit = scenario.draw_unit(useed, f"MIMU-{index:04d}")
    cals = {variant: lab_calibration(unit, variant, seed, useed) for variant in VARIANTS}
    flight, still = fly(scenario, unit, useed)
    cals["traditional"] = traditional_zero(cals["traditional"], still)
    end = flight.initial.t + scenario.duration_s if scenario.duration_s else None
    doc = normalised_table(flight, cals, end=end)
    doc.pop("log")
    return {"index": index, "unit_seed": useed, "campaign": _identity(scenario, seed),
            "code": code_version(), **doc}


@dataclass
class Still:
    """The MIMU's pre-flight record (`mimu_raw` fields over the warm-up's last
    PREFLIGHT_S s), the true rate it sensed standing still (rad/s, sensor axes) and its
    sample rate (Hz): what `lab.preflight.gyro_zero` takes."""
    raw: dict
    w_still: np.ndarray
    rate_hz: float


def fly(scenario, unit, useed):
    """(`Flight` of `unit` on `scenario`'s flight with seed `useed`, built in memory; `Still`
    or None): with a pre-flight gyro zero the MIMU's warm-up's last seconds are recorded
    too, standing in the launch attitude."""
    unit, fog, rng_mimu, rng_fog = simulation.flight_units(useed, unit,
                                                           fog_grade=scenario.fog_grade)
    fm = _flight_motion(scenario, unit, fog)
    still = None
    if scenario.gyro_zero == "pre-flight":
        pre, raw, fog_out = simulation.record_with_preflight(fm, unit, fog, rng_mimu, rng_fog,
                                                             PREFLIGHT_S, scenario.warm_up_s)
        tr = fm.run.trajectory
        w_still, _ = simulation.still_rates(unit.mounting, tr.q_nb[0], tr.lat[0], tr.h[0])
        still = Still(pre, w_still, unit.rate_hz)
    else:
        raw, fog_out = simulation.record_flight(fm, unit, fog, rng_mimu, rng_fog,
                                                warm_up_s=scenario.warm_up_s)
    flight = Flight.from_simulation(fm, unit, fog, raw, fog_out)
    if scenario.start == "ground":
        flight, _ = ground_start(flight)
    return flight, still


def traditional_zero(cal, still):
    """The traditional calibration with its gyro zero taken before flight (`still`), or as
    the lab fitted it (`still` None)."""
    return cal if still is None else gyro_zero(cal, still.raw, still.w_still, still.rate_hz)[0]


def _flight_motion(scenario, unit, fog):
    key = scenario.flight_key()
    if key not in _FLIGHTS:
        _FLIGHTS[key] = simulation.flight_motion(
            scenario.profile(), unit.mounting, unit.rate_hz, fog.mounting, fog.rate_hz, 100.0,
            scenario.ground_temperature_c)
    return _FLIGHTS[key]


def prepare(scenario, seed):
    """Make this process's lab motions and flight motion of `scenario` and `seed` (every
    unit's), so that worker processes forked after it inherit them instead of each making
    them (about 3 s of a worker's first unit)."""
    method = multiprocessing.get_start_method(allow_none=True) or \
        multiprocessing.get_all_start_methods()[0]           # the default, left unset
    if method != "fork":
        return
    for procedures in VARIANTS.values():
        for procedure in procedures:
            _lab_motion(procedure, seed)
    useed = unit_seed(seed, 0)
    unit, fog, _, _ = simulation.flight_units(useed, scenario.draw_unit(useed, "prepare"),
                                              fog_grade=scenario.fog_grade)
    _flight_motion(scenario, unit, fog)


def lab_calibration(unit, variant, lab_seed, noise_seed, propagate=False):
    """`unit` through the lab procedures of `variant` (the lab's setting errors drawn from
    `lab_seed`, the unit's noise from `noise_seed`) and their fit, in memory (`propagate`:
    with the full covariance, `calibration.calibrate`)."""
    return calibrate(lab_runs(unit, variant, lab_seed, noise_seed), variant, unit.name,
                     propagate=propagate)


def lab_runs(unit, variant, lab_seed, noise_seed):
    """The `LabRun`s of `variant`'s procedures (in `VARIANTS` order), recorded in memory."""
    runs = []
    for k, proc in enumerate(VARIANTS[variant]):
        plan = lab.plan(proc)
        segments, states = _lab_motion(proc, lab_seed)
        raw = lab.record(plan, unit, segments, noise_seed + k + 1)
        ts, fields = lab.state_arrays(states)
        runs.append(LabRun.from_arrays(
            f"{proc} ({unit.name})", lab.lab_metadata(plan), raw["t"],
            {key: raw[key] for key in ("accel_volts", "gyro_volts", "accel_temperature",
                                       "gyro_frequency")}, ts, fields))
    return runs


def _identity(scenario, seed):
    return {"seed": seed, "scenario": scenario.identity()}


def done_indices(path):
    """Indices already in a results file (a torn last line from an interrupted write is
    ignored and rewritten)."""
    if not os.path.exists(path):
        return {}
    out = {}
    with open(path) as fh:
        for line in fh:
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue
            out[rec["index"]] = rec
    return out


def run_campaign(scenario, n_units, seed, results, workers=2, scheduler=None,
                 progress=True, futures=None):
    """Run (or resume) a campaign of `scenario` (a `Scenario`, or a profile path for the
    default scenario on that flight) into the JSON-lines file `results`; returns the
    records of units 0..n_units-1 in index order. `futures`: the units already submitted
    to a pool of the caller's (`submit_units`, all of them; `results` then starts empty)."""
    if not isinstance(scenario, Scenario):
        scenario = Scenario(flight=str(Path(scenario).resolve()))
    done = done_indices(results)
    wrong = [i for i, r in done.items() if r.get("campaign") != _identity(scenario, seed)]
    if wrong:
        raise InputError(f"{results} holds units of another campaign ({done[wrong[0]].get('campaign')}"
                         f", this one is {_identity(scenario, seed)}); use another file")
    stale = sorted(i for i, r in done.items() if r.get("code") != code_version())
    if stale:
        warn(f"{results}: {len(stale)} unit(s) were made by other code than this mimunav's "
             f"({done[stale[0]].get('code', 'unrecorded')}, now {code_version()}): computed "
             "again, so that the campaign holds one simulator's draws")
        for i in stale:
            del done[i]
    todo = [i for i in range(n_units) if i not in done]
    if futures is not None and (done or len(futures) != n_units):
        raise ValueError("units submitted beforehand need an empty results file and all "
                         f"{n_units} units ({len(futures)} submitted, {len(done)} done)")
    with open(results, "w") as fh:                   # rewrite intact lines, drop a torn one
        for rec in done.values():
            fh.write(json.dumps(rec) + "\n")
    bar = tqdm(total=n_units, initial=n_units - len(todo), desc="campaign units",
               disable=not progress)
    records = _execute(scenario, seed, todo, workers, scheduler) if futures is None else \
        (f.result() for f in as_completed(futures))
    with open(results, "a") as fh:
        for rec in records:
            if rec.get("code") != code_version():
                raise InputError(f"unit {rec['index']} was made by other code "
                                 f"({rec.get('code', 'unrecorded')}) than this mimunav's "
                                 f"({code_version()}): run the same version on every worker")
            fh.write(json.dumps(rec) + "\n")
            fh.flush()
            done[rec["index"]] = rec
            bar.update()
    bar.close()
    return [done[i] for i in range(n_units)]


def _execute(scenario, seed, indices, workers, scheduler):
    """Yield unit records as they finish, on local processes or a Dask cluster."""
    if not indices:
        return
    if scheduler:
        distributed = require("dask.distributed", "dask", "a campaign on a Dask cluster")
        Client, dask_completed = distributed.Client, distributed.as_completed
        with Client(scheduler) as client:
            futures = client.map(run_unit, [scenario] * len(indices), [seed] * len(indices),
                                 indices, pure=False)
            for future in dask_completed(futures):
                yield future.result()
        return
    from concurrent.futures import ProcessPoolExecutor
    prepare(scenario, seed)
    with ProcessPoolExecutor(workers, initializer=one_blas_thread) as pool:
        futures = submit_units(pool, scenario, seed, indices)
        forget()
        for future in as_completed(futures):
            yield future.result()


def forget():
    """Drop this process's lab and flight motions (`prepare`), e.g. once a pool's processes
    have forked with them: a process that runs many campaigns (the regime map) would keep
    every flight's otherwise."""
    _MOTIONS.clear()
    _FLIGHTS.clear()


def submit_units(pool, scenario, seed, indices):
    """Futures of `run_unit` for the units `indices` on `pool` (an executor whose workers
    ran `one_blas_thread`; a fork-started executor has forked all its processes once the
    first is submitted, so the caller may `forget` what it `prepare`d after this)."""
    return [pool.submit(run_unit, scenario, seed, i) for i in indices]


def summary(records, variants=tuple(VARIANTS)):
    """Median and 5-95 % of every normalised (and absolute) end error per variant."""
    out = {}
    for v in variants:
        norm = np.array([r["variants"][v]["normalised_enu"] for r in records])
        absolute = np.abs(np.array([r["variants"][v]["enu_m"] for r in records]))
        out[v] = {"median": np.median(norm, axis=0).tolist(),
                  "p05": np.percentile(norm, 5, axis=0).tolist(),
                  "p95": np.percentile(norm, 95, axis=0).tolist(),
                  "abs_median_m": np.median(absolute, axis=0).tolist()}
    fog = np.abs(np.array([r["fog"]["enu_m"] for r in records]))
    out["FOG-IMU"] = {"abs_median_m": np.median(fog, axis=0).tolist()}
    return out


def summary_markdown(stats, n):
    lines = [f"Monte Carlo over {n} units: normalised end error (|MIMU| / |FOG| per axis), "
             "median [5 %, 95 %].", "",
             "| variant | east | north | up | median abs error E/N/U, m |", "|---|---|---|---|---|"]
    for v, s in stats.items():
        if v == "FOG-IMU":
            continue
        cells = [f"{s['median'][j]:.3g} [{s['p05'][j]:.3g}, {s['p95'][j]:.3g}]" for j in range(3)]
        lines.append(f"| {v} | " + " | ".join(cells) + " | " +
                     ", ".join(f"{x:.3g}" for x in s["abs_median_m"]) + " |")
    lines.append("| FOG-IMU | 1 | 1 | 1 | " +
                 ", ".join(f"{x:.3g}" for x in stats["FOG-IMU"]["abs_median_m"]) + " |")
    return "\n".join(lines) + "\n"

"""The levels of the diagnosis and the choice among them: a log loaded for the level it is
diagnosed at, and that level's diagnosis - what `mimunav diagnose` runs.

    sensor       a reference IMU (/fog/imu) predicts the MIMU's outputs (`sensor`)
    navigation   only a reference trajectory (/truth/state): the MIMU's free-inertial velocity
                 error against it (`navigation`)
    track        a recorded land drive's trajectory without attitude, simulated into an ideal
                 IMU that stands in for the reference IMU (`track`)
"""
import numpy as np

from ..compensation.calibration_file import Calibration
from ..errors import InputError
from ..evaluation.flight import Flight, no_reference, refuse_gaps
from . import navigation, sensor, track

LEVELS = ("sensor", "navigation", "track")


def choose(flight, level="auto"):
    """The level `flight` (an `evaluation.flight.Flight`) is diagnosed at: `level` when given,
    else (auto) sensor with a reference IMU; track for a recorded, already compensated
    /mimu/imu whose reference trajectory comes from a recording or holds no attitude;
    navigation otherwise."""
    if level != "auto":
        return level
    recorded = flight.mimu_raw is None
    if flight.fog_t is not None:
        return "sensor"
    if recorded and flight.truth is not None and \
            (flight.source == "recording" or np.isnan(flight.truth.q_nb[0].w)):
        return "track"
    return "navigation"


def load(log_path, model_path=None, level="auto"):
    """(flight, calibration, level) of the log at `log_path` for the diagnosis: the
    calibration file at `model_path` (required for a raw /mimu/raw; the identity for a
    recorded /mimu/imu without one) and the level (`choose`). Gaps are refused unless the
    track level takes the log: it leaves their surroundings out (`track_reference.near_gaps`)
    instead of navigating across them."""
    flight = Flight.load(log_path, reference_imu=level == "sensor", max_gap_s=np.inf)
    recorded = flight.mimu_raw is None          # an imported /mimu/imu: already compensated
    if model_path is None and not recorded:
        raise InputError(f"{log_path}: the log has /mimu/raw; --model CAL is required")
    cal = Calibration.load(model_path) if model_path else Calibration.identity()
    level = choose(flight, level)
    if level != "track":
        refuse_gaps(flight)
    if level in ("navigation", "track") and flight.truth is None:
        raise no_reference(log_path, f"the {level} level (and no /fog/imu for the "
                                     "sensor level): nothing to diagnose against")
    return flight, cal, level


def diagnose(flight, cal, level, alpha=0.05, seed=0, accuracy=None, noise=None):
    """The diagnosis of `flight` against calibration `cal` at `level`: alpha the family-wise
    error rate; seed the navigation level's block bootstrap; accuracy the reference's
    `reference.Accuracy` (sensor and track levels); noise the unit's measured random errors
    for the sensor level's bias tests."""
    if level == "navigation":
        return navigation.diagnose(flight, cal, alpha=alpha, seed=seed)
    if level == "sensor":
        return sensor.diagnose(flight, cal, alpha=alpha, accuracy=accuracy, noise=noise)
    return track.diagnose(flight, cal, alpha=alpha, accuracy=accuracy)

"""What carried the IMU of a recording, as far as the level choice needs it: a car, whose
track gives its attitude under the no-side-slip model of the track level, or anything else.
Declared at import (`mimunav import --vehicle`, the `recording` metadata's `vehicle`), else
judged from the reference track and the IMU (`motion.carrier`: its tests and limits).
"""
import json
import math
import re
from typing import NamedTuple

from ..motion.carrier import LAND, car_tests, contradiction


def declared(recording_meta):
    """The vehicle the recording's metadata declares, or None."""
    return (recording_meta or {}).get("vehicle")


class Carrier(NamedTuple):
    """What carried the IMU: `kind`, `LAND` or another of `importers.kinds.VEHICLES`
    ("other" when judged); `how` it was known, in words; `contradiction`: what the track and
    IMU contradict of a declared kind (`motion.carrier.contradiction`), or ''."""
    kind: str
    how: str
    contradiction: str = ""


def kind(flight, vehicle=None):
    """The `Carrier` of `flight`: declared (`vehicle`, the command line's, over the
    metadata's), with what its track and IMU contradict of it, or judged with the numbers of
    the tests that decided."""
    said = vehicle or declared(flight.recording)
    if said:
        how = f"declared {said} ({'--vehicle' if vehicle else 'recording metadata'})"
        contra = _contradiction(flight, said)
        return Carrier(said, how + (f", but {contra}" if contra else ""), contra)
    if flight.truth is None or len(flight.truth) < 10:
        return Carrier("other", "not a car: no reference track to judge it from")
    failed, numbers = _car_tests(flight)
    if failed:
        return Carrier("other", f"judged not a car: {'; '.join(failed)}")
    return Carrier(LAND, "judged a car: " + ", ".join(numbers))


def contradicted_car(carrier):
    """Why a car declared (`carrier`: `kind`'s) is not what the recording's track and IMU
    show (`motion.carrier.car_tests` failed), or '': the track level's vehicle model - no
    side slip, no lean - would charge a motorcycle's lean to its gyros (a 39 deg lean read
    as a gyro.z excursion of z -21 and a scale of 0.157)."""
    if carrier.kind != LAND or not carrier.contradiction:
        return ""
    return (f"{carrier.how} - the track level's vehicle model (no side slip, no lean) does "
            "not hold, so none of its findings stands")


def _contradiction(flight, vehicle):
    if flight.truth is None or len(flight.truth) < 10:
        return ""
    w, f = (None, None) if flight.mimu_imu is None else flight.mimu_imu
    return contradiction(vehicle, flight.truth.t, flight.truth.v_ned, flight.mimu_t, f, w)


def _car_tests(flight):
    w, f = (None, None) if flight.mimu_imu is None else flight.mimu_imu
    return car_tests(flight.truth.t, flight.truth.v_ned, flight.mimu_t, f, w)


SMALL_ANGLE_MOUNTING = math.radians(20.0)   # library.PHYSICAL_RANGE's mounting_misalignment


def mounting_beyond_range(rejected, flight):
    """[what the import measured of the mounting] when the small-angle mounting term was
    fitted beyond its range (`confirmation.beyond_range`, `rejected`'s `beyond_range`), from
    the recording's `mounting_yaw_against_course` (a turn of any size, against the GNSS
    course): beyond the term's range it names the turn and the option that turns it back;
    within it, the fit's size is not the mounting's where the fit turns about the vehicle's
    down axis (a noisy reference's), while a fit about its level axes may be a tilted
    mounting the import does not measure (an independent review: a cradle tilted back 30
    deg had been called the reference's fault); else []."""
    beyond = [r for r in rejected if r.get("effect") == "mounting_misalignment" and
              ("beyond_range" in r or "train_beyond_range" in r)]
    if not beyond:
        return []
    real = (flight.recording or {}).get("real")
    said = (json.loads(real) if isinstance(real, str) else real or {}).get(
        "mounting_yaw_against_course")
    yaw = re.match(r"\s*([-+]?\d+(?:\.\d+)?) deg", said or "")
    if yaw is None:
        return []
    turn = beyond[0].get("vector_vehicle")
    about_down = turn is not None and abs(turn[2]) >= max(abs(turn[0]), abs(turn[1]))
    if abs(math.radians(float(yaw.group(1)))) <= SMALL_ANGLE_MOUNTING and not about_down:
        return [f"the import measured the mounting's yaw at {yaw.group(1)} deg against the "
                "GNSS course, and measures nothing of its roll and pitch, about which the "
                "fit turns " + ("(its axes not known here)" if turn is None else "mostly")
                + ": a mounting tilted beyond 20 deg may be the cause (mimunav import "
                "--mounting-rpy-deg), "
                "or the reference does not carry the term here"]
    if abs(math.radians(float(yaw.group(1)))) <= SMALL_ANGLE_MOUNTING:
        return [f"the import measured the mounting's yaw at {yaw.group(1)} deg against the "
                "GNSS course, within the small-angle term's range, and the fit turns about "
                "the vehicle's down axis: the fit's size is not the mounting's, and the "
                "reference does not carry the term here"]
    return [f"the mounting given is off by more than the diagnosis fits; the import measured "
            f"its yaw: {said}"]

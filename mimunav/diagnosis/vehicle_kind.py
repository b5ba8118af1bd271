"""What carried the IMU of a recording, as far as the level choice needs it: a car, whose
track gives its attitude under the no-side-slip model of the track level, or anything else.
Declared at import (`mimunav import --vehicle`, the `recording` metadata's `vehicle`), else
judged from the reference track and the IMU (`motion.carrier`: its tests and limits).
"""
from ..motion.carrier import LAND, car_tests


def declared(recording_meta):
    """The vehicle the recording's metadata declares, or None."""
    return (recording_meta or {}).get("vehicle")


def kind(flight):
    """(kind, how): `LAND` or another of `importers.kinds.VEHICLES` ("other" when judged),
    and how it was known - declared, or judged with the numbers of the tests that decided."""
    said = declared(flight.recording)
    if said:
        return said, f"declared {said} (recording metadata)"
    if flight.truth is None or len(flight.truth) < 10:
        return "other", "not a car: no reference track to judge it from"
    w, f = (None, None) if flight.mimu_imu is None else flight.mimu_imu
    failed, numbers = car_tests(flight.truth.t, flight.truth.v_ned, flight.mimu_t, f, w)
    if failed:
        return "other", f"judged not a car: {'; '.join(failed)}"
    return LAND, "judged a car: " + ", ".join(numbers)

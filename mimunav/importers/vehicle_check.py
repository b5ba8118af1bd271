"""The vehicle a recording declares (`mimunav import --vehicle`, a table spec's `vehicle`)
against its reference track and IMU (`motion.carrier.contradiction`): said, not overridden -
the declaration is the user's word, and what it decides (the course checks, a heading from
the course, the track level) follows it.
"""
from ..motion.carrier import contradiction


def check_declared_vehicle(rec, track):
    """rec.real["vehicle"]: what `track` (`checks.reference_track`'s dict, or None) and the
    IMU contradict of the vehicle rec declares, and the options that declare another; nothing
    when none is declared or nothing contradicts it."""
    if not rec.vehicle or track is None:
        return
    t = (rec.imu_ns - rec.imu_ns[0]) / 1e9
    said = contradiction(rec.vehicle, track["t"], track["v_ned"], t, rec.f, rec.w)
    if said:
        rec.real["vehicle"] = (f"declared {rec.vehicle}, but {said}: is the declaration right "
                               "(--vehicle, or a table spec's `vehicle`)?")

"""True motion: flight profiles (`profile`) made into continuous motion and exact
increments (`truth`), the `Trajectory` container (`trajectory`), a land vehicle's motion from a
GNSS track (`vehicle`, `track`), a rotating platform carrying the IMU (`platform`), and
interval-mean outputs (`intervals`).
"""

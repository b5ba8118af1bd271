"""The names the importers and the command line share: the kinds of recording an importer
reads (KINDS) and what can carry the IMU (VEHICLES)."""

KINDS = ("rtklib", "ros2", "ulog", "dataflash", "table")
# what can carry an IMU, as a recording declares it (`mimunav import --vehicle`, a table
# spec's `vehicle`): a car's track gives its attitude (no side slip, the track level); the
# others' tracks do not
VEHICLES = ("car", "aircraft", "multicopter", "rocket", "pedestrian", "ship", "other")

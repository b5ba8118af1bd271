"""The names the importers and the command line share: the kinds of recording an importer
reads (KINDS) and what can carry the IMU (VEHICLES)."""

KINDS = ("rtklib", "ros2", "ros1", "ulog", "dataflash", "table")
ROS = ("ros2", "ros1")      # one importer: a ROS bag of either, told by its bytes
# what can carry an IMU, as a recording declares it (`mimunav import --vehicle`, a table
# spec's `vehicle`): a car's track gives its attitude (no side slip, the track level); the
# others' tracks do not - a train's neither: its curves are canted, its body rolls into
# them (3-6 deg) where a road car's model holds it level; a two-wheeler (motorcycle,
# bicycle) leans 20-45 deg into its bends. A train and a two-wheeler still move along
# their forward axes: their course is their heading (`motion.carrier.ALONG_COURSE`)
VEHICLES = ("car", "train", "two-wheeler", "aircraft", "multicopter", "rocket", "pedestrian",
            "ship", "other")

"""Recordings that nobody here wrote, turned into contract logs (`mimunav-log/1`).

    rtklib     a CSV IMU log with RTKLIB time tags and an RTKLIB position solution
    ros2       any ROS 2 MCAP with sensor_msgs/msg/Imu (+ sensor_msgs/msg/NavSatFix), by topic
    ulog       a PX4 ULog (sensor_combined + vehicle_gps_position / sensor_gps), by pyulog
    dataflash  an ArduPilot DataFlash .bin (IMU, GPS, GPA; EKF3 POS/XKF1/ATT), by pymavlink
    table      any logger's CSV / NumPy columns described by a TOML spec

Each reader returns a `recording.Recording` - the IMU in SI units and its own axes, the GNSS
and reference data it has, and what is measured and what is assumed; `checks` tests it
against itself (rates, overlap, units, the mounting against the course, a reference IMU's
clock and mounting) and `write.write_log` writes it.
"""

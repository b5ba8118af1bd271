"""Flight profiles the tests fly (TOML text)."""

PULL_UP_AND_ROLL = """name = "short"
description = "20 s: a 2 g pull-up and a roll"
[start]
latitude_deg = 30.0
longitude_deg = 104.0
height_m = 1000.0
speed_m_s = 200.0
heading_deg = 45.0
[[segment]]
kind = "pull"
load_factor = 2.0
flight_path_change_deg = 10.0
[[segment]]
kind = "roll"
rate_deg_s = 200.0
angle_deg = 360.0
[[segment]]
kind = "hold"
duration_s = 8.0
"""

"""Sensor models: what real inertial sensors output for a true motion.

- `mimu`: the MEMS unit of seed S1 (63 coefficients, temperature, nonlinearity,
  g-sensitivity) drawn like real units from the seed's Tables 1-2, simulated to raw volts;
- `fog`: the reference FOG-IMU of Table 4, calibrated outputs;
- `thermal`: temperatures in time (power-on self-heating, environment, resonance frequency);
- `noise`: white noise, flicker bias instability, quantization;
- `mounting`: a sensor's attitude and lever arm in the vehicle frame.
"""
from .mounting import Mounting
from .mimu import MimuUnit
from .fog import FogUnit

__all__ = ["Mounting", "MimuUnit", "FogUnit"]

"""Sensor models - what real inertial sensors output for a true motion - and the flight
simulation that records them.

- `mimu`: the MEMS unit of seed S1 (63 coefficients, temperature, nonlinearity,
  g-sensitivity) drawn like real units from the seed's Tables 1-2, simulated to raw volts;
- `response`: its sensing elements written forward as sensor behaviour;
- `fog`: the reference FOG-IMU of Table 4, calibrated outputs;
- `thermal`: temperatures in time (power-on self-heating, environment, resonance frequency);
- `noise`: white noise, flicker bias instability, quantization;
- `hidden`: physics the 63-coefficient model lacks, hidden in a simulated flight;
- `simulation`: profile -> truth -> MIMU and FOG at their mountings and rates -> flight log.
"""

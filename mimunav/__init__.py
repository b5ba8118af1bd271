"""mimunav: flight-test evaluation of MEMS IMUs (MIMU) against a FOG-IMU reference.

Data flows one way: profile -> truth -> sensors -> log -> compensation -> navigation ->
evaluation -> report. Conventions (see shared/spec/log-format.md): SI units, NED
navigation frame, body FRD, Hamilton quaternions scalar-first, q_nb maps body to NED.
"""
from pathlib import Path

__version__ = "0.1.0"
# the flight profiles shipped beside the package (flights/*.toml)
FLIGHTS = Path(__file__).resolve().parent.parent / "flights"

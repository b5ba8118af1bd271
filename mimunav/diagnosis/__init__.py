"""Diagnosis: when a simulation and a recording of the same flight disagree, find where,
name the physics the model left out (the effect vocabulary of log contract section 3), fit
it with an interval and show the fit improve on held-out data.

    sensor.diagnose      sensor level: the reference IMU predicts the MIMU's outputs
    library              the candidate terms;  inference  the tests and their nuisance
    reference            the reference motion moved to the MIMU's mounting
"""

"""Diagnosis: when a simulation and a recording of the same flight disagree, find where,
name the physics the model left out (the effect vocabulary of log contract section 3), fit
it with an interval and show the fit improve on held-out data.

    sensor       sensor level: the reference IMU predicts the MIMU's outputs
    navigation   navigation level: only a reference trajectory; candidates' error signatures
    track        track level: a land vehicle's trajectory simulated into a reference IMU
    library      the candidate terms;  inference  the tests and their nuisance
    outputs      saturation, quantization, bias shift and bias instability: tests on the
                 outputs themselves (no regressor)
    reference    the reference motion moved to the MIMU's mounting
    document     the contract document (`mimunav-diagnosis/1`) and the calibration with the
                 found terms (`CAL+found.json`)
    concealed    the proof on simulated recordings with hidden effects
    transplant   every effect class put into the foreign flights (their own effect out)
"""

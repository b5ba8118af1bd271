"""Evaluation of a flight log: the log loaded and checked (`flight`), the MIMU and
the reference navigated with the same navigator and compared (`replay`), the normalised
end-point table and error budget (`table`), free-inertial windows against a reference
trajectory (`windows`), Monte Carlo over units (`campaign`), and seed S4's rotation
modulation studies (`modulation`).
"""

"""The calibration lab: procedures run on a simulated unit (`procedures`), lab runs
and their windows (`runs`), generalised least squares with propagated covariance (`gls`),
the seeds' fits - triads with temperature and g-sensitivity (`triads`, S1), static
positions (`positions`: twelve-position S2, hand-held ellipsoid), cold start (`cold_start`,
S3), rotation (`rotation`, S4) - chosen by `calibrate`; random errors from static records
(`allan`) and seed S4's AR drift model (`drift`).
"""

"""Frames and rotations every stage shares: the WGS-84 Earth (`earth`: geodetic,
ECEF, NED, gravity, rates), attitude as q_nb quaternion arrays (`attitude`), and a sensor's
mounting in its vehicle (`mounting`: attitude and lever arm).
"""

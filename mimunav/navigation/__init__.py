"""Navigation: the quaternion strapdown navigator (`strapdown`) and the initial
state of a recording (`alignment`).
"""

"""lasercal.solver: product-of-exponentials kinematics and calibration.

The core of lasercal. It depends on neither ``collector`` nor ``vision``.
Lengths are millimetres and angles radians everywhere in this package.
"""

"""Kinematics: product-of-exponentials (POE) chains, the minimal POE parametrisation, the robot model, the
laser as a prismatic joint, aiming IK, gravity torques and the non-geometric effects a controller can
apply."""

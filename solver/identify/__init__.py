"""Identification: the least-squares core in the identifiable subspace, the thesis's method and ours for
laser-spot sessions, point-constraint sessions, circle-point analysis and full-pose calibration."""

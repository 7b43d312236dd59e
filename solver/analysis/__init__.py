"""Analysis of a fit: before/after statistics and cross-validation, the diagnosis of non-geometric effects,
and simulated sessions."""

# Here, not in diagnose.py, so that `lasercal diagnose --help` shows it without loading the solver.
ALPHA = 0.01  # family-wise false-alarm rate of the diagnosis's decision

"""Analysis of a fit: before/after statistics and cross-validation, the diagnosis of non-geometric effects,
and simulated sessions."""

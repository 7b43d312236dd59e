"""Studies on real data that use only the solver: the MUKCa recordings (import and the four-robot study)."""

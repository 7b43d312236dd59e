"""Studies on real data that use the solver: the MUKCa recordings (import, the four-robot study and its
statistical checks; the study's report.md and figures come from ``collector.report.mukca``)."""

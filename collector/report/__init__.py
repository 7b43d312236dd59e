"""The HTML report, the MUKCa study's Markdown report, and the one plotting set-up (matplotlib, headless)
that every figure uses."""

"""The HTML report and the one plotting set-up (matplotlib, headless) that every figure uses."""

"""The README's results table and the docs pages behind it state the same figures.

Each row of README.md's "Results" table is a summary of a page in docs/ that gives the figure with its
command and its context (:data:`PAGES`). A figure in the row (a decimal number) must stand on one of the
row's pages at the row's precision: a number there that rounds to it (``0.82`` is ``0.823``; ``1e-4`` and
``-1e-4`` are not the same figure). A figure changed in one place and not the other fails here, and so
does a README row whose page is not named.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# a README row (the start of its first cell) -> the docs pages that state its figures
PAGES = {
    "thesis Simulation 1": ("results.md", "formats.md"),
    "simulated thesis experiment": ("results.md", "demo.md"),
    "`lm` held-out error": ("results.md",),
    "the coach's promise": ("results.md", "coach.md"),
    "posterior σ": ("results.md",),
    "a sheet laid anywhere": ("results.md", "sessions.md"),
    "start-up and a whole `solve`": ("results.md",),
    "diagnosis power": ("results.md", "diagnosis.md"),
    "diagnosis on the user's path": ("diagnosis.md",),
    "diagnosis where the world holds more": ("diagnosis.md",),
    "vision, phone photos": ("results.md", "vision.md"),
    "capture coach vs": ("results.md", "coach.md"),
    "vision, real photos": ("vision.md",),
    "real Pandas (MUKCa)": ("results.md", "real-data.md", "diagnosis.md"),
    "full pose from raw": ("results.md", "fullpose.md"),
    "real UR10": ("results.md", "real-data.md"),
    "real Agile Justin": ("position.md",),
    "real FR3 camera": ("results.md", "fullpose.md"),
    "capture with a camera": ("sessions.md",),
    "a world lasercal did not draw": ("sessions.md",),
    "`lasercal correct`": ("results.md", "use.md"),
}
NUMBER = re.compile(r"(?<![\w.])[-−+]?\d+\.\d+(?:e[-−+]?\d+)?|(?<![\w.])[-−+]?\d+e[-−+]?\d+")


def _value(text: str) -> float:
    return float(text.replace("−", "-"))


def _decimals(text: str) -> int:
    """Decimals a figure is written to (a mantissa's, scaled by its exponent)."""
    mant, _, exp = text.lower().partition("e")
    return len(mant.partition(".")[2]) - int(exp.replace("−", "-") or 0)


def results_rows() -> list[tuple[str, str]]:
    """(first cell, figures cell) of each row of README.md's Results table."""
    text = (ROOT / "README.md").read_text().split("## Results", 1)[1].split("\n## ", 1)[0]
    rows = [line.split("|") for line in text.splitlines() if line.startswith("| ")]
    return [(r[1].strip(), r[2]) for r in rows[1:]]  # the header row out


def same_figure(figure: str, page_numbers: list[str]) -> bool:
    """Whether a page states ``figure``: a number there equal to it at its precision, sign included."""
    v, d = _value(figure), _decimals(figure)
    tol = 0.5 * 10.0 ** (-d) * (1 + 1e-9)
    return any(abs(_value(x) - v) <= tol and (_value(x) < 0) == (v < 0) for x in page_numbers)


@pytest.mark.parametrize("row,figures", results_rows(), ids=lambda x: x[:30] if isinstance(x, str) else "")
def test_each_results_row_states_its_pages_figures(row, figures):
    key = next((k for k in PAGES if row.startswith(k)), None)
    assert key is not None, f"README's results row {row!r} names no docs page in tests/test_docs_agree.py"
    numbers = [x for page in PAGES[key] for x in NUMBER.findall((ROOT / "docs" / page).read_text())]
    missing = [f for f in NUMBER.findall(figures) if not same_figure(f, numbers)]
    assert not missing, f"{row!r}: {missing} stand in README.md but not in docs/{', docs/'.join(PAGES[key])}"


def test_a_figure_changed_on_one_side_is_caught():
    """The comparison itself: the spring's compliance with its sign flipped, a figure at another precision."""
    assert same_figure("0.82", ["0.823"]) and not same_figure("0.82", ["0.826"])
    assert not same_figure("0.9926e-4", ["-9.926e-5"]) and same_figure("-0.9926e-4", ["-9.926e-5"])
    assert same_figure("9.4e-8", ["9.4e-8"]) and not same_figure("9.4e-8", ["1.2e-8"])

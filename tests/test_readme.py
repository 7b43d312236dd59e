"""The README's demo figures are the ones ``lasercal demo`` prints (the full demo, seed 0, about a minute)."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def readme_block() -> list[str]:
    m = re.search(r"<!-- demo-output -->\n```\n(.*?)```\n<!-- /demo-output -->", README.read_text(), re.S)
    assert m, "README.md has no demo-output block"
    return m.group(1).rstrip("\n").split("\n")


def numbers(line: str) -> tuple[str, list[float]]:
    """A table row's label and its figures."""
    label, *figs = re.split(r"\s{2,}", line.strip())
    return label, [float(f) for f in figs]


def test_readme_shows_what_the_demo_prints(full_demo):
    code, stdout, _ = full_demo  # tests/conftest.py: one demo run for every test of its figures
    assert code == 0
    printed = stdout.split("\n")
    block = readme_block()
    start = printed.index(block[0])  # the header row, word for word
    for got, want in zip(printed[start + 1 : start + len(block)], block[1:], strict=True):
        (label, a), (label0, b) = numbers(got), numbers(want)
        # the printed 3 decimals, up to a round-off flip of the last one between BLAS builds
        assert label == label0 and len(a) == len(b) and max(abs(x - y) for x, y in zip(a, b)) <= 0.0015

"""Every figure README.md and docs/ show that a command prints is produced or checked by a test.

Three kinds of check, each on the run of a command the suite makes anyway (no run of its own but one
20-second fake capture):

* whole blocks, line by line: the README's demo table (``tests/test_readme.py``) and docs/api.md's
  walkthrough outputs (``tests/test_docs_api.py``: each ``text`` block is what the ``python`` block above it
  prints);
* sentences, here: :data:`FIGURES` lists (document, producer, template); the template, filled with what the
  producer's run printed, must stand in the document word for word (line breaks read as spaces);
* wall times are written "about ..." and never asserted (a busy machine doubles them).

:func:`test_the_registry_counts_its_figures` counts what the three cover.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from lasercal.collector.cli.main import main

ROOT = Path(__file__).resolve().parents[1]


def _demo(s: dict) -> dict:
    """The demo's figures, from its summary.json."""
    p4, c = s["p4"], s["correct"]
    return {
        "nominal": p4["nominal"]["error_mean"],
        "lm": p4["lm"]["error_mean"],
        "extended": p4["extended"]["error_mean"],
        "commanded": c["nominal_mm"],
        "corrected": c["corrected_mm"],
    }


def _solve(s: dict) -> dict:
    """``lasercal solve --json``'s figures."""
    cv = s["cross_validation"]
    return {
        "fit": s["fit_rms_mm"],
        "sigma": s["sigma_mm"],
        "rms": cv["holdout_rms_mm"],
        "mean": cv["holdout_mean_mm"],
        "max": cv["holdout_max_mm"],
        "nominal": cv["nominal_rms_mm"],
    }


# (document, producer, template): the producer's figures (:func:`_demo`, :func:`_solve`) fill the template
FIGURES = [
    (
        "README.md",
        "demo",
        "commanded with the nominal model: {commanded:.2f} mm off; with `lasercal correct`: "
        "{corrected:.2f} mm",
    ),
    (
        "README.md",
        "demo",
        "nominal {nominal:.2f} → lm {lm:.3f} mm mean error; with the found effect {extended:.3f} mm",
    ),
    ("README.md", "demo", "commands corrected {commanded:.2f} → {corrected:.2f} mm"),
    (
        "docs/use.md",
        "demo",
        "commanded with the nominal model: {commanded:.2f} mm off; with lasercal correct: {corrected:.2f} mm",
    ),
    ("docs/use.md", "demo", "({extended:.2f} mm mean at P4 in the demo)"),
    (
        "docs/demo.md",
        "demo",
        "commanded with the nominal model: {commanded:.2f} mm off; with lasercal correct: {corrected:.2f} mm",
    ),
    (
        "docs/sessions.md",
        "fake_capture",
        "fit residual RMS {fit:.3f} mm, aiming noise estimate {sigma:.3f} mm per axis, 5-fold held-out "
        "prediction error RMS {rms:.3f} mm (mean {mean:.2f}, max {max:.2f}) against {nominal:.3f} mm for the "
        "nominal model",
    ),
]


def folded(text: str) -> str:
    """Markdown's text with its line breaks and indentation read as single spaces."""
    return re.sub(r"\s+", " ", text)


@pytest.fixture(scope="module")
def fake_capture(tmp_path_factory):
    """docs/sessions.md's numbers: ``capture --backend fake --auto --per-point 15`` (thesis layout, truth
    panda_thesis_identified, 1 mm aiming noise, seed 0), then ``solve --json`` (5-fold cross-validation)."""
    import contextlib
    import io

    root = tmp_path_factory.mktemp("fake_capture")
    args = ["--layout", "thesis", "--robot", "panda", "--backend", "fake", "--auto", "--per-point", "15"]
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["capture", *args, "-o", str(root / "session")]) == 0
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["solve", str(root / "session"), "-o", str(root / "m.yaml"), "--json"]) == 0
    return _solve(json.loads(buf.getvalue()))


@pytest.fixture(scope="module")
def produced(full_demo, fake_capture) -> dict:
    code, _, _, out = full_demo  # tests/conftest.py: the one demo run
    assert code == 0
    return {"demo": _demo(json.loads((out / "summary.json").read_text())), "fake_capture": fake_capture}


@pytest.mark.parametrize("doc, producer, template", FIGURES, ids=[f"{d}:{p}" for d, p, _ in FIGURES])
def test_the_doc_shows_what_the_command_prints(produced, doc, producer, template):
    want = template.format(**produced[producer])
    assert want in folded((ROOT / doc).read_text()), f"{doc} should say: {want}"


def test_the_registry_counts_its_figures():
    """How many printed figures the docs' checks cover: this registry's, the README table's, api.md's."""
    import sys

    sys.path.insert(0, str(ROOT / "tests"))
    from test_docs_api import printed_blocks, untimed
    from test_readme import readme_block

    here = sum(len(re.findall(r"\{\w+:", t)) for _, _, t in FIGURES)
    rows = [line for line in readme_block()[1:] if "thesis paper" not in line]  # the demo's, not the paper's
    table = sum(len(re.findall(r"\d+\.\d+", line)) for line in rows)
    api = sum(
        len(re.findall(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e-?\d+)?", untimed(out).replace("<time> s", "")))
        for _, out in printed_blocks((ROOT / "docs" / "api.md").read_text())
    )
    assert (here, table) == (18, 16) and api > 50, (here, table, api)

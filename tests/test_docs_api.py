"""docs/api.md's walkthrough runs: its ``python`` code blocks, in order, in one namespace, in an empty folder
(simulate -> calibrate -> report -> plan -> correct -> stream through ``lasercal.Corrector``; the blocks
assert what they show)."""

from __future__ import annotations

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"


def code_blocks(text: str, lang: str = "python") -> list[str]:
    """The fenced code blocks of one language in a markdown text, in order."""
    return re.findall(rf"^```{lang}\n(.*?)^```$", text, flags=re.S | re.M)


def printed_blocks(text: str) -> list[tuple[str, str]]:
    """(python block, the ``text`` block right after it): what the doc says each block prints."""
    return re.findall(r"^```python\n(.*?)^```\n\n```text\n(.*?)^```$", text, flags=re.S | re.M)


def untimed(text: str) -> str:
    """The text with its wall times ('0.213 s', 'in 1.164 s') masked: a time is never asserted."""
    return re.sub(r"\b\d+(\.\d+)? s\b", "<time> s", text)


def test_code_blocks_are_found():
    text = "a\n```python\nx = 1\n```\n```text\nout\n```\n```python\ny = x + 1\n```\n"
    assert code_blocks(text) == ["x = 1\n", "y = x + 1\n"]


def test_the_walkthrough_runs(tmp_path, monkeypatch, capsys):
    blocks = code_blocks(DOC.read_text())
    assert len(blocks) >= 5
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    shown = dict(printed_blocks(DOC.read_text()))
    outputs = []
    for i, code in enumerate(blocks):
        exec(compile(code, f"{DOC.name} block {i + 1}", "exec"), ns)
        outputs.append(capsys.readouterr().out)
        if code in shown:  # what the doc shows under the block is what it printed, figure for figure
            assert untimed(outputs[-1].rstrip("\n")) == untimed(shown[code].rstrip("\n")), f"block {i + 1}"
    assert len(shown) >= 6
    out = "".join(outputs)
    assert "captures at P1, P2, P3" in out and "5-fold cross-validated prediction error" in out
    assert "the commands are correct's (within 1e-6 rad): True" in out  # the streaming corrector's block
    assert (tmp_path / "model.yaml").is_file() and (tmp_path / "report" / "index.html").is_file()
    # the model file the walkthrough saved is the one `lasercal solve` writes
    from lasercal.collector.cli.main import main

    assert main(["solve", "session", "-o", "cli.yaml"]) == 0
    assert (tmp_path / "cli.yaml").read_bytes() == (tmp_path / "model.yaml").read_bytes()

"""The coach's status block and ``--until`` in a simulated ``lasercal capture`` session."""

from __future__ import annotations

from lasercal.collector.cli.main import main
from lasercal.solver.formats.session import load_session


def test_status_block_and_until_stop_a_fake_session(tmp_path, capsys):
    s = tmp_path / "s"
    args = ["capture", "--backend", "fake", "--auto", "--layout", "thesis", "--per-point", "15"]
    assert main(args + ["--until", "3", "-o", str(s)]) == 0
    out = capsys.readouterr().out
    assert "coach: captures" in out and "identifiable" in out and "predicted error at P4" in out
    assert "next: P" in out and "<= --until 3 mm: session complete" in out
    assert 10 < load_session(s).m < 45  # stopped early, once the prediction reached 3 mm

"""A hands-free camera session killed in the middle of a move and resumed writes, byte for byte, the
captures.csv of the session that was never interrupted (issue 45 item 5): the arm's moves, their
repeatability and sensor draws, the clock, the camera's noise and the coach all continue as they would have.

The kill is a real SIGKILL of a ``lasercal capture`` process, sent by the process to itself inside the fake
arm's ``move_to`` (after the transit began, before it returned) once the chosen number of captures is on disk.
"""

from __future__ import annotations

import subprocess
import sys

from lasercal.collector.cli.main import main

KILL = """
import os, signal, sys
from pathlib import Path
from lasercal.collector.worlds.fake import FakeRobot
from lasercal.collector.cli.main import main

folder, after = Path(sys.argv[1]), int(sys.argv[2])
real = FakeRobot.move_to

def move_then_die(self, q):
    rows = (folder / "captures.csv").read_text().count("\\n") - 1
    if rows >= after:
        self.clock.sleep(0.25)  # the transit has begun
        os.kill(os.getpid(), signal.SIGKILL)
    real(self, q)

FakeRobot.move_to = move_then_die
sys.exit(main(sys.argv[3:]))
"""


def test_a_hands_free_session_killed_mid_move_resumes_to_the_same_bytes(sheet, tmp_path):
    args = ["capture", "--layout", str(sheet), "--robot", "panda", "--backend", "fake", "--camera", "fake",
            "--guide", "move", "--auto", "--per-point", "1", "--seed", "6"]  # fmt: skip
    assert main(args + ["-o", str(tmp_path / "ref")]) == 0
    cut = tmp_path / "cut"
    child = subprocess.run(
        [sys.executable, "-c", KILL, str(cut), "2", *args, "-o", str(cut)], capture_output=True, text=True
    )
    assert child.returncode == -9, child.stderr  # killed by the signal, not ended
    assert (cut / "captures.csv").read_text().count("\n") - 1 == 2
    assert main(["capture", "--resume", str(cut), "--auto", "--guide", "move"]) == 0
    ref, got = (tmp_path / "ref" / "captures.csv").read_bytes(), (cut / "captures.csv").read_bytes()
    assert got.count(b"\n") == ref.count(b"\n") == 6
    assert got == ref  # every column: t, q, dq, tau, the measured spots and their sigmas, the aims
    photos = sorted(p.name for p in (cut / "photos").iterdir())
    assert photos == sorted(p.name for p in (tmp_path / "ref" / "photos").iterdir())

"""validate is safe to stop: a kill mid-run leaves a resumable folder; --resume completes it exactly once.

A real ``lasercal validate`` process (fake backend) is SIGKILLed after a few photos; the
folder holds whole photos only (each written to a temporary file and renamed), and
``validate --resume`` photographs the remaining configurations, no configuration twice.
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time

import cv2
import numpy as np

from lasercal.collector.cli.main import main
from lasercal.collector.sessions.motion import MotionRefused, confirm, joint_steps, plan_moves, preview
from lasercal.collector.worlds.fake import FakeRobot
from lasercal.solver.formats.robots import load_model

N = 12


def _rows(folder):
    with open(folder / "validation.csv") as f:
        return [r for r in csv.DictReader(ln for ln in f if not ln.startswith("#"))]


def test_validate_killed_then_resumed_has_every_configuration_once(tmp_path):
    out = tmp_path / "val"
    cmd = [sys.executable, "-m", "lasercal.collector.cli.main", "validate", "panda_thesis_identified",
           "--backend", "fake", "--layout", "thesis", "-n", str(N), "-o", str(out)]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "validation.csv").is_file() and len(_rows(out)) >= 3:
            break
        time.sleep(0.02)
    assert proc.poll() is None, "the run ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    killed_at = len(_rows(out))
    assert 3 <= killed_at < N
    assert main(["validate", "--resume", str(out)]) == 0
    rows = _rows(out)
    assert sorted(int(r["index"]) for r in rows) == list(range(N))  # each configuration exactly once
    for r in rows:  # every photo whole (a torn PNG does not decode)
        assert cv2.imread(str(out / r["photo"])) is not None
    assert not list(out.rglob("*.tmp"))


def test_interrupted_validate_says_partial_and_resume_finishes(tmp_path, capsys, monkeypatch):
    out = tmp_path / "val"
    real_move = FakeRobot.move_to
    moves = []

    def move_then_ctrl_c(self, q):
        moves.append(np.array(q))
        if len(moves) == 9:
            raise KeyboardInterrupt
        real_move(self, q)

    monkeypatch.setattr(FakeRobot, "move_to", move_then_ctrl_c)
    rc = main(["validate", "panda_thesis_identified", "--backend", "fake", "--layout", "thesis", "-n", "6",
               "-o", str(out)])  # fmt: skip
    printed = capsys.readouterr()
    assert rc == 130
    done = len(_rows(out))
    assert f"partial: {done} of 6 configurations" in printed.out
    assert "interrupted: the arm was stopped; " in printed.out  # the fake arm moves itself
    assert 0 < done < 6
    monkeypatch.setattr(FakeRobot, "move_to", real_move)
    assert main(["validate", "--resume", str(out)]) == 0
    assert "6 of 6 configurations" in capsys.readouterr().out
    assert sorted(int(r["index"]) for r in _rows(out)) == list(range(6))


def test_plan_splits_large_moves_and_bounds_every_step():
    model = load_model("panda")
    start = np.zeros(7)
    targets = np.array([[1.7, 0.2, 0, -1.5, 0, 1.5, 0], [-1.1, 0.2, 0, -1.5, 0, 1.5, 0]])
    plan = plan_moves(start, targets, model, max_step=0.5)
    path = np.vstack([start, plan.steps])
    assert np.abs(np.diff(path, axis=0)).max() <= 0.5 + 1e-12
    assert len(plan.steps) == 4 + 6  # ceil(1.7/0.5) = 4, ceil(2.8/0.5) = 6
    assert np.allclose(plan.steps[plan.arrives(1)], targets[1])
    text = preview(plan)
    assert "2 configurations in 10 moves" in text and "largest joint change per move: 0.467 rad" in text
    try:
        plan_moves(start, targets, model, max_step=0.5, split=False)
    except MotionRefused as e:
        assert "joint 1 would change by 1.700 rad" in str(e)
    else:
        raise AssertionError("a 1.7 rad move was not refused")


def test_joint_steps_are_equal_and_end_on_target():
    a, b = np.zeros(3), np.array([1.0, -0.3, 0.2])
    s = joint_steps(a, b, 0.25)
    assert len(s) == 4 and np.allclose(s[-1], b) and np.allclose(np.diff(np.vstack([a, s]), axis=0), b / 4)


class _Tty:
    def __init__(self, answer):
        self.answer = answer

    def isatty(self):
        return True

    def readline(self):
        return self.answer


def test_confirm_needs_yes_typed_or_flag(capsys):
    model = load_model("panda")
    plan = plan_moves(np.zeros(7), np.array([[0.3, 0, 0, -1.5, 0, 1.5, 0]]), model)
    confirm(plan, yes=True, stdin=open(os.devnull))  # --yes: no question
    confirm(plan, stdin=_Tty("yes\n"))
    for stdin in (open(os.devnull), _Tty("y\n"), _Tty("\n")):
        try:
            confirm(plan, stdin=stdin)
        except MotionRefused:
            continue
        raise AssertionError(f"moved without 'yes' ({stdin})")

"""Selection inside the folds (issue 52): how often ``solve --extend auto`` names a cause, with what fold
agreement, and the held-out gain it reports -- on sessions with a planted effect and on sessions without.

Run: python benchmarks/bench_diagnose_nested.py [SEEDS]   (prints a table; no assertions; SEEDS default 20)

Run it with the lasercal you want to measure: the selection on the whole session and refitted per fold
(main before issue 52, e.g. a worktree at 9e2a438) prints '-' for the fold agreement it does not record.

The sessions are ``bench_diagnose_sheet.py``'s: ``lasercal simulate panda_thesis_identified`` on the sheet
of ``lasercal sheet --place 450 0 0`` laid at 452, 3 mm, 1 deg, 15 captures at each of P1-P5, logged
torques with the simulator's 0.05 Nm noise; diagnosed as ``solve --extend auto`` does (5 folds, no
bootstrap). Worlds:

* compliance j2, eye / camera: a joint-2 compliance of 1.5e-4 rad/Nm, aimed by eye (0.5 mm) or every
  spot measured by the camera (0.03 mm); 'named' is its power;
* weak compliance j2, eye: 0.5e-4 rad/Nm, near what an eye session can see;
* none, eye / camera: no effect (the solver's own world: every residual is noise);
* none, camera, curled paper: no catalogue effect, but the paper is not flat -- every measured spot is
  moved by a smooth field no candidate describes, 0.1 mm per axis in amplitude, (sin, sin) of the spot's
  sheet position over a 120 mm wavelength with a random phase per seed (what issue 45's camera world
  holds: the paper's curl, shear and glow; a session with 'none' is then the right answer).

Columns: named (finding is a cause; for the planted worlds, the planted one at joint 2), the fold
agreement of the named ones (folds whose own selection chose the same cause, mean of k), and the gain
(%) the finding reports, mean over the named sessions.
"""

from __future__ import annotations

import contextlib
import io
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lasercal.collector.cli.main import main
from lasercal.solver.analysis.diagnose import diagnose
from lasercal.solver.formats.session import load_session

WORLDS = [  # (label, --measured, --aim-noise, effect size at joint 2 or None, curled paper amplitude mm)
    ("compliance j2, eye", "0", "0.5", "1.5e-4", 0.0),
    ("compliance j2, camera", "1", "0.5", "1.5e-4", 0.0),
    ("weak compliance j2, eye", "0", "0.5", "0.5e-4", 0.0),
    ("none, eye", "0", "0.5", None, 0.0),
    ("none, camera", "1", "0.5", None, 0.0),
    ("none, camera, curled paper", "1", "0.5", None, 0.1),
]
CURL_WAVELENGTH_MM = 120.0


def quiet(argv: list) -> None:
    """Run a lasercal command, its output swallowed; raise on failure."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        if main(argv):
            raise RuntimeError(f"lasercal {' '.join(argv)} failed")


def curled(session, amplitude: float, seed: int):
    """The session with every measured spot moved by the curled paper's smooth field (mm, sheet units)."""
    if amplitude == 0:
        return session
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 2)
    xy = session.target[:, :2]
    shift = amplitude * np.sin(2 * np.pi * xy[:, ::-1] / CURL_WAVELENGTH_MM + phase)
    target = session.target.copy()
    target[session.measured, :2] += shift[session.measured]
    return replace(session, target=target)


def one(tmp: Path, layout: str, world: tuple, seed: int):
    """Simulate one session of ``world`` and diagnose it as ``solve --extend auto`` does."""
    _, measured, noise, size, curl = world
    s = tmp / f"s{seed}"
    argv = ["simulate", "panda_thesis_identified", "--layout", layout, "--per-point", "15"]
    argv += ["--sheet-pose", "452", "3", "1.0", "--aim-noise", noise, "--measured", measured]
    argv += ["--seed", str(seed), "-o", str(s), "--force"]
    if size is not None:
        argv += ["--effect", "joint_compliance", "--effect-joints", "2", "--effect-size", size]
    quiet(argv)
    return diagnose(curled(load_session(s), curl, seed), n_boot=0, k=5, seed=0)


def main_(seeds: int) -> None:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        quiet(["sheet", "-o", str(tmp / "sheet"), "--robot", "panda", "--place", "450", "0", "0"])
        layout = str(tmp / "sheet" / "layout.yaml")
        t0 = time.perf_counter()
        print(f"{'world':30} {'named':>6} {'agree':>6} {'gain %':>7}   (of {seeds} seeds; causes named)")
        for world in WORLDS:
            named, agree, gains, causes = 0, [], [], {}
            for seed in range(seeds):
                g = one(tmp, layout, world, 700 + seed)
                label = g.extension.label if g.extension is not None else "none"
                hit = (
                    label != "none"
                    if world[3] is None
                    else g.effect == "joint_compliance" and 2 in g.extension.joints
                )
                if hit:
                    named += 1
                    gains.append(g.gain_percent)
                    if "folds_agree" in g.acceptance:
                        agree.append(g.acceptance["folds_agree"] / g.acceptance["folds"])
                if label != "none":
                    causes[label] = causes.get(label, 0) + 1
            a = f"{np.mean(agree):6.2f}" if agree else f"{'-':>6}"
            gain = f"{np.mean(gains):7.1f}" if gains else f"{'-':>7}"
            print(f"{world[0]:30} {named:6d} {a} {gain}   {causes}", flush=True)
        print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main_(int(sys.argv[1]) if len(sys.argv) > 1 else 20)

"""``lasercal correct``: goals per second, and the accuracy on simulated truth.

Speed: the Python API (``lasercal.load_model(...).correct``, what the command runs) on 10,000 goals of a
7-joint Panda calibrated with a compliance, one process, one BLAS thread. Goals are the flange at random
in-limit configurations with the elbow bent (q4 < -0.8 rad): every goal is reachable, and the table says how
many were reached.

Accuracy: the tests' simulated truths (tests/test_correct.py) -- a perturbed Panda from a URDF seen by a
tracker (target T1), the same with a hidden compliance fitted by ``solve --extend``, and the demo's truth
calibrated from laser spots at several aiming noises (the flange): mean error on the TRUE robot of a
program planned with the nominal model and of x, y, z goals, commanded as planned (or by the nominal's
own IK) and as ``lasercal correct`` corrects them.

Run: python benchmarks/bench_correct.py  (about a minute; prints two tables)
"""

from __future__ import annotations

import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
M = 10_000


def speed() -> None:
    from lasercal.solver.analysis.simulate import random_configs
    from lasercal.solver.control.robot import Robot
    from lasercal.solver.formats.robots import load_model

    nominal = load_model("panda")
    model = load_model("panda_thesis_identified").replace(
        extensions={"joint_compliance": {"joints": [2], "c": [1.2e-4]}}
    )
    robot = Robot(model, nominal)
    rng = np.random.default_rng(0)
    q = random_configs(model, M, rng, margin=0.1)
    q[:, 3] = np.minimum(q[:, 3], -0.8)
    T = robot.fk(q)
    pose = np.hstack([T[:, :3, 3], Rotation.from_matrix(T[:, :3, :3]).as_rotvec()])
    near = q + rng.normal(0, 0.05, q.shape)
    cases = (
        ("program (q1..q7): the nominal's poses, seeds q", dict(q=q)),
        ("x,y,z with seeds q1..q7 (0.05 rad off)", dict(goal=T[:, :3, 3], seed=near)),
        ("x,y,z from the ready pose", dict(goal=T[:, :3, 3])),
        ("x,y,z,rx,ry,rz with seeds (0.05 rad off)", dict(goal=pose, seed=near)),
        ("x,y,z,rx,ry,rz from the ready pose", dict(goal=pose)),
    )
    print(f"speed: {M} goals, Panda with a joint compliance (one process, one BLAS thread)")
    print(f"{'goals':48} {'goals/s':>8} {'reached':>8} {'worst residual mm':>18}")
    for label, kw in cases:
        t0 = time.perf_counter()
        c = robot.correct(**kw)
        dt = time.perf_counter() - t0
        print(f"{label:48} {M / dt:8.0f} {c.ok.mean():8.2%} {c.residual_mm[c.ok].max():18.1e}")


def accuracy() -> None:
    sys.path.insert(0, str(ROOT))
    import lasercal
    from lasercal.collector.cli.main import main
    from lasercal.solver.control.robot import Robot
    from lasercal.solver.formats.robots import load_model
    from tests.test_correct import COMPLIANCE, errors_on_truth, position_case, work_configs

    rows = []
    with tempfile.TemporaryDirectory() as d, contextlib.redirect_stdout(io.StringIO()):
        for label, effect, extend in (
            ("tracker 0.02 mm, URDF Panda, T1", None, False),
            ("tracker + hidden compliance, solve --extend", COMPLIANCE, True),
            ("tracker + hidden compliance, geometric only", COMPLIANCE, False),
        ):
            tmp = Path(tempfile.mkdtemp(dir=d))
            model, truth = position_case(tmp, effect, extend)
            e = errors_on_truth(tmp, model, truth, effect)
            rows.append((label, *e["program"][:2], *e["xyz"][:2]))
        truth = load_model("panda_thesis_identified")
        for noise in (0.02, 0.5, 1.0):
            tmp = Path(tempfile.mkdtemp(dir=d))
            sim = ["simulate", "panda_thesis_identified", "--layout", "thesis", "--aim-noise", str(noise)]
            main(sim + ["--per-point", "15", "-o", str(tmp / "S")])
            prior = tmp / "prior.yaml"  # the operator's aiming noise, stated (docs/formats.md, Priors)
            prior.write_text(f"format: lasercal-prior/1\nprior: {{noise_mm: {{laser: {noise}}}}}\n")
            main(["solve", str(tmp / "S"), "-o", str(tmp / "m.yaml"), "--folds", "0", "--prior", str(prior)])
            robot = lasercal.load_model(tmp / "m.yaml")
            true_robot, nominal = Robot(truth, robot.nominal), Robot(robot.nominal, robot.nominal)
            qs = work_configs(robot.model, 300, 13)
            goal = robot.fk(qs, nominal=True)[:, :3, 3]
            prog = [
                np.linalg.norm(true_robot.fk(q)[:, :3, 3] - goal, axis=1).mean()
                for q in (qs, robot.correct(q=qs).q)
            ]
            goal = robot.fk(qs)[:, :3, 3]
            xyz = [
                np.linalg.norm(true_robot.fk(q)[:, :3, 3] - goal, axis=1).mean()
                for q in (nominal.ik(goal).q, robot.correct(goal).q)
            ]
            rows.append((f"laser {noise:g} mm, thesis P1-P3 x 15, flange", *prog, *xyz))
    print(
        "\naccuracy on the simulated true robot, mean error mm (as planned or nominal IK -> lasercal correct)"
    )
    print(f"{'calibration':46} {'program':>18} {'x,y,z goals':>18}")
    for label, p0, p1, x0, x1 in rows:
        print(f"{label:46} {p0:8.3f} -> {p1:6.3f} {x0:8.3f} -> {x1:6.3f}")


if __name__ == "__main__":
    speed()
    accuracy()

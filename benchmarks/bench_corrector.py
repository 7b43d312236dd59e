"""The corrector for a control loop (``lasercal.Corrector``): latency per goal along continuous paths at
1 kHz, speed by speed up to Franka's Cartesian limits (1.7 m/s, 2.5 rad/s), how many goals went to the full
solver, and its commands against ``lasercal correct`` (``Robot.correct``) on the same goals.

The robot: the thesis's identified Panda with a joint compliance (joint 2) and an encoder eccentricity
(joint 4), a TCP 103.4 mm along the flange's z (Franka's hand). Two paths from the ready pose, 10,000
full-pose goals 1 ms apart per speed (0.06, 0.5, 1.0, 1.5, 1.7 m/s along the path):

* ``ahead``: a circle of 150 mm radius in the horizontal plane, away from the base (x from 304 to 604 mm),
  the tool rocking by 0.3 rad about two horizontal axes (periods in the ratio 1 : 1.3) at a peak angular
  speed of 2.5 rad/s x v / 1.7 m/s: at 1.7 m/s both of Franka's Cartesian limits at once. The joints stay
  within the Panda's joint speed limits (2.2-2.6 rad/s) until ten seconds of laps carry the redundant joint
  to a limit margin (the column ``joint rad/s`` counts those goals too).
* ``inward``: the circle of 100 mm radius towards the base with a 50 mm vertical wave (the tests' path),
  the same rocking. It passes 100 mm from joint 1's axis: at 1 m/s and faster the joints move faster than
  a Panda's can (the column ``joint rad/s``) and joint 2 runs onto its limit margin (``at limit``), where
  the corrector holds it as ``correct`` does.

Printed per path and speed: the thread CPU time per goal -- median, 99th percentile, worst -- and the wall
clock's 99th percentile (on a shared machine the wall clock also counts the time other processes hold the
cores: the load average is printed); the goals sent to the full solver and the Newton steps per goal; the
largest difference from ``correct``'s command for the same goal seeded by the same previous command; the
fastest joint; the goals with a joint on its limit margin. Then ``correct`` one goal at a time (1,000 goals),
and the calibrated model's miss at the corrector's commands (with its effects, lasercal's own kinematics).

Run: nice python benchmarks/bench_corrector.py  (about 2 min)
"""

from __future__ import annotations

import gc
import os
import time

import numpy as np
from scipy.spatial.transform import Rotation

STEPS = 10_000
CORRECT_STEPS = 1_000
TCP = (0.0, 0.0, 103.4)
SPEEDS = (0.06, 0.5, 1.0, 1.5, 1.7)  # m/s along the path
V_MAX, W_MAX = 1.7, 2.5  # Franka's Cartesian limits: m/s, rad/s
ROCK = 0.3  # rad


def robot():
    """The calibrated robot (thesis Panda with a compliance and an eccentricity) and its nominal."""
    from lasercal.solver.control.robot import Robot
    from lasercal.solver.formats.robots import load_model

    model = load_model("panda_thesis_identified").replace(
        extensions={
            "joint_compliance": {"joints": [2], "c": [1.2e-4]},
            "encoder_eccentricity": {"joints": [4], "a": [2e-4], "b": [-1e-4]},
        }
    )
    return Robot(model, load_model("panda"))


def path(start: np.ndarray, speed: float, kind: str) -> np.ndarray:
    """Goals (STEPS, 4, 4) mm 1 ms apart from ``start``: a circle at ``speed`` m/s, the tool rocking."""
    t = np.arange(STEPS) * 1e-3
    goals = np.tile(start, (STEPS, 1, 1))
    if kind == "ahead":
        r = 150.0
        w = speed * 1e3 / r
        goals[:, :3, 3] += np.stack([r * (1 - np.cos(w * t)), r * np.sin(w * t), 0 * t], 1)
    else:  # inward, with a wave: |d/dt| = speed at the wave's crossings, more between
        r = 100.0
        w = speed * 1e3 / r
        goals[:, :3, 3] += np.stack([r * (np.cos(w * t) - 1), r * np.sin(w * t), 50 * np.sin(2 * w * t)], 1)
    wr = W_MAX * speed / V_MAX / (ROCK * np.hypot(1.0, 1.3))  # peak angular speed W_MAX * speed / V_MAX
    rock = Rotation.from_rotvec(np.stack([ROCK * np.sin(wr * t), ROCK * np.sin(1.3 * wr * t), 0 * t], 1))
    goals[:, :3, :3] = rock.as_matrix() @ start[:3, :3]
    return goals


def timed(fn, goals) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Commands, wall-clock and thread CPU times (ms) of fn over the goals, one call each."""
    out, wall, cpu = [], [], []
    gc.disable()
    try:
        for g in goals:
            a, b = time.perf_counter_ns(), time.thread_time_ns()
            out.append(fn(g))
            cpu.append(time.thread_time_ns() - b)
            wall.append(time.perf_counter_ns() - a)
    finally:
        gc.enable()
    return np.array(out), np.array(wall) / 1e6, np.array(cpu) / 1e6


def run(rob, goals) -> dict:
    """The corrector along the goals: timings, fallbacks, steps, and the comparison with correct."""
    from lasercal.solver.control.corrector import Corrector

    q0 = rob.model.home
    corrector = Corrector(rob, tool=TCP, q0=q0)
    q, wall, cpu = timed(corrector, goals)
    corrector.reset(q0)
    steps, fallbacks = [], 0
    for g in goals:  # untimed: Newton steps per goal and goals that went to the full solver
        corrector(g)
        steps.append(corrector.last.steps)
        fallbacks += corrector.last.fallback
    ref = rob.correct(goals, seed=np.vstack([q0[None], q[:-1]]), tool=TCP)  # correct's, same goal, same seed
    lo, hi = rob.model.limits[:, 0] + 0.01, rob.model.limits[:, 1] - 0.01
    at_limit = ((q < lo + 1e-6) | (q > hi - 1e-6)).any(axis=1)
    T = rob.fk(q, tool=TCP)  # the calibrated robot with its effects, by lasercal's own kinematics
    turn = Rotation.from_matrix(T[:, :3, :3] @ np.swapaxes(goals[:, :3, :3], 1, 2)).as_rotvec()
    return {
        "cpu": cpu,
        "wall": wall,
        "fallbacks": fallbacks,
        "steps": np.bincount(steps, minlength=4),
        "diff": np.abs(q - ref.q).max(),
        "joint_speed": np.abs(np.diff(q, axis=0)).max() / 1e-3,
        "at_limit": int(at_limit.sum()),
        "miss_mm": np.linalg.norm(T[:, :3, 3] - goals[:, :3, 3], axis=1).max(),
        "miss_rad": np.linalg.norm(turn, axis=1).max(),
        "ref_ok": bool(ref.ok.all()),
        "peak_speed": np.linalg.norm(np.diff(goals[:, :3, 3], axis=0), axis=1).max(),  # mm per ms = m/s
    }


def main() -> None:
    from threadpoolctl import threadpool_limits

    rob = robot()
    start = rob.fk(rob.model.home, tool=TCP)[0]
    print(
        f"{STEPS} goals 1 ms apart per row, full poses, Panda (thesis) with a compliance and an "
        "eccentricity, TCP"
    )
    print(
        f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start; "
        "one BLAS thread"
    )
    head = (
        f"{'path':7} {'m/s':>4} {'rad/s':>5} | {'CPU ms: median':>14} {'p99':>6} {'worst':>6} | "
        f"{'wall p99':>8} | {'fallbacks':>9} | {'Newton steps 1/2/3/>3':>21} | {'vs correct rad':>14} | "
        f"{'joint rad/s':>11} | at limit"
    )
    print(head)
    worst_mm = worst_rad = 0.0
    with threadpool_limits(1):
        for kind in ("ahead", "inward"):
            for v in SPEEDS:
                r = run(rob, path(start, v, kind))
                s = r["steps"]
                print(
                    f"{kind:7} {v:4.2f} {W_MAX * v / V_MAX:5.2f} | {np.median(r['cpu']):14.3f} "
                    f"{np.percentile(r['cpu'], 99):6.3f} {r['cpu'].max():6.3f} | "
                    f"{np.percentile(r['wall'], 99):8.3f} | {r['fallbacks']:9d} | "
                    f"{f'{s[1]}/{s[2]}/{s[3]}/{s[4:].sum()}':>21} | {r['diff']:14.2g} | "
                    f"{r['joint_speed']:11.2f} | {r['at_limit']}  (peak {r['peak_speed']:.2f} m/s)"
                    + ("" if r["ref_ok"] else "  (correct: not ok)")
                )
                worst_mm, worst_rad = max(worst_mm, r["miss_mm"]), max(worst_rad, r["miss_rad"])

        state = {"q": np.array(rob.model.home)}

        def correct_one(g):
            c = rob.correct(g[None], seed=state["q"][None], tool=TCP)
            state["q"] = c.q[0]
            return c.q[0]

        _, cwall, ccpu = timed(correct_one, path(start, 0.06, "ahead")[:CORRECT_STEPS])
    print(
        f"correct, one goal at a time ({CORRECT_STEPS} goals, ahead, 0.06 m/s): "
        f"CPU median {np.median(ccpu):.3f}  p99 {np.percentile(ccpu, 99):.3f}  worst {ccpu.max():.3f} ms; "
        f"wall p99 {np.percentile(cwall, 99):.3f} ms"
    )
    print(
        "accuracy: the calibrated robot's miss at the commands, worst of all rows: "
        f"{worst_mm:.2g} mm, {worst_rad:.2g} rad"
    )
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()

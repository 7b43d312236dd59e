"""The corrector for a control loop (``lasercal.Corrector``): latency per goal along a continuous path at
1 kHz, and its accuracy against ``lasercal correct`` (``Robot.correct``) on the same goals.

The robot: the thesis's identified Panda with a joint compliance (joint 2) and an encoder eccentricity
(joint 4), a TCP 103.4 mm along the flange's z (Franka's hand). The path: 10,000 full-pose goals 1 ms apart
(10 s), from the ready pose: a 100 mm circle with a 50 mm vertical wave, the tool rocking by 0.2 rad about
two axes (63 mm/s). Each goal is one call, warm-started from the previous command, as in a control loop.

Printed: the latency per goal -- median, 99th percentile, worst -- as wall-clock time and as the thread's
CPU time (on a shared machine the wall clock also counts the time other processes hold the cores: the
load average is printed), for the corrector and for ``correct`` one goal at a time (1,000 goals of the same
path, seeded by the previous command); then accuracy: the calibrated model's miss at the corrector's
commands (with its effects, by lasercal's own forward kinematics), and the difference from ``correct``'s
command for the same goal seeded by the same previous command.

Run: python benchmarks/bench_corrector.py  (about 20 s)
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


def robot_and_path():
    """The calibrated robot (with effects) and the path of goals (STEPS, 4, 4) mm from the ready pose."""
    from lasercal.solver.control.robot import Robot
    from lasercal.solver.formats.robots import load_model

    model = load_model("panda_thesis_identified").replace(
        extensions={
            "joint_compliance": {"joints": [2], "c": [1.2e-4]},
            "encoder_eccentricity": {"joints": [4], "a": [2e-4], "b": [-1e-4]},
        }
    )
    robot = Robot(model, load_model("panda"))
    start = robot.fk(model.home, tool=TCP)[0]
    t = np.arange(STEPS) * 1e-3
    w = 2 * np.pi / 10.0
    goals = np.tile(start, (STEPS, 1, 1))
    goals[:, :3, 3] += np.stack([100 * (np.cos(w * t) - 1), 100 * np.sin(w * t), 50 * np.sin(2 * w * t)], 1)
    rock = Rotation.from_rotvec(np.stack([0.2 * np.sin(w * t), 0.2 * np.sin(1.3 * w * t), 0 * t], 1))
    goals[:, :3, :3] = rock.as_matrix() @ start[:3, :3]
    return robot, goals


def stats(ms: np.ndarray) -> str:
    return f"median {np.median(ms):.3f}  p99 {np.percentile(ms, 99):.3f}  worst {ms.max():.3f} ms"


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


def main() -> None:
    from threadpoolctl import threadpool_limits

    from lasercal.solver.control.corrector import Corrector

    robot, goals = robot_and_path()
    q0 = robot.model.home
    with threadpool_limits(1):
        corrector = Corrector(robot, tool=TCP, q0=q0)
        q, wall, cpu = timed(corrector, goals)
        corrector.reset(q0)
        steps, fallbacks = [], 0
        for g in goals:  # untimed: how many Newton steps each goal took, and how many the full solver took
            corrector(g)
            steps.append(corrector.last.steps)
            fallbacks += corrector.last.fallback

        state = {"q": np.array(q0)}

        def correct_one(g):
            c = robot.correct(g[None], seed=state["q"][None], tool=TCP)
            state["q"] = c.q[0]
            return c.q[0]

        _, cwall, ccpu = timed(correct_one, goals[:CORRECT_STEPS])
        seeds = np.vstack([q0[None], q[:-1]])
        ref = robot.correct(goals, seed=seeds, tool=TCP)  # correct's command per goal, same seed

    load = os.getloadavg()[0]
    print(f"{STEPS} goals, 1 ms apart, full poses, Panda (thesis) with a compliance and an eccentricity, TCP")
    print(f"machine: {os.cpu_count()} cores, load average {load:.1f}; one BLAS thread")
    print(f"{'':22} {'wall clock':44} thread CPU time")
    print(f"{'Corrector':22} {stats(wall):44} {stats(cpu)}")
    print(f"{'correct, one goal':22} {stats(cwall):44} {stats(ccpu)}  ({CORRECT_STEPS} goals)")
    T = robot.fk(q, tool=TCP)  # the calibrated robot with its effects, by lasercal's own kinematics
    miss = np.linalg.norm(T[:, :3, 3] - goals[:, :3, 3], axis=1)
    turn = np.linalg.norm(
        Rotation.from_matrix(T[:, :3, :3] @ np.swapaxes(goals[:, :3, :3], 1, 2)).as_rotvec(), axis=1
    )
    print(
        f"accuracy: the calibrated robot's miss at the commands: {miss.max():.2g} mm, {turn.max():.2g} rad "
        f"(worst); correct's: {ref.residual_mm.max():.2g} mm, {ref.residual_rad.max():.2g} rad"
    )
    diff = np.abs(q - ref.q).max()
    print(f"          largest difference from correct's command (same goal, same seed): {diff:.2g} rad")
    counts = ", ".join(f"{k}: {n}" for k, n in zip(*np.unique(steps, return_counts=True)))
    print(
        f"          Newton steps per goal (steps: goals) {counts}; goals sent to the full solver: {fallbacks}"
    )


if __name__ == "__main__":
    main()

"""Follow a Cartesian path on a Franka arm with the calibration in the control loop (franky >= 2).

A franky ``JointImpedanceTracker`` streams joint targets from Python at a fixed period; each tick the
corrector (``lasercal.Corrector``) turns the next goal of the path -- a pose of the tool in the base frame,
mm -- into the joint command the real robot needs, warm-started from the previous one. The controller
keeps Franka's nominal model; it only tracks joints, so the calibration takes effect exactly.

Run: python docs/examples/franky_corrector.py HOST model.yaml  (the arm moves: clear its work space)
"""

from __future__ import annotations

import sys
import time

import numpy as np

# joint stiffness (Nm/rad) of the tracker: stiff enough to follow a slow path closely
STIFFNESS = (600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0)  # libfranka example


def circle(start: np.ndarray, seconds: float, period: float, radius: float = 50.0) -> np.ndarray:
    """Goals (m, 4, 4) mm of the tool: a horizontal circle of ``radius`` mm through its start pose."""
    t = np.arange(int(seconds / period)) * period
    w = 2 * np.pi / seconds
    goals = np.tile(start, (len(t), 1, 1))
    goals[:, 0, 3] += radius * (np.cos(w * t) - 1.0)
    goals[:, 1, 3] += radius * np.sin(w * t)
    return goals


def follow(franky_robot, corrector, goals: np.ndarray, period: float = 0.001) -> dict:
    """Stream the corrector's commands for ``goals`` to the arm, one goal a tick.

    Parameters
    ----------
    franky_robot : franky.Robot, connected
    corrector : lasercal.Corrector, for the tool the goals are for
    goals : (m, 4, 4) array, mm, base frame
    period : float, s, the tick of the loop

    Returns
    -------
    dict: ``commands`` (k, 7) rad sent, ``measured`` (k, 7) rad read at each tick, ``compute_ms`` (k,) the
    corrector's time per goal
    """
    from franky import JointImpedanceTracker

    corrector.reset(np.array(franky_robot.state.q))  # the first warm start: where the arm is
    commands, measured, compute = [], [], []
    with JointImpedanceTracker(franky_robot, stiffness=np.array(STIFFNESS), period=period) as tracker:
        for goal in goals:
            if not tracker.tick():
                break
            t0 = time.perf_counter()
            q = corrector(goal)
            compute.append(1e3 * (time.perf_counter() - t0))
            if not corrector.last.ok:
                raise RuntimeError(f"goal {len(commands)}: {corrector.last.reason}")
            tracker.set_target(q)
            commands.append(q)
            measured.append(np.array(tracker.state.q))
        for _ in range(int(2.0 / period)):  # hold the last command while the arm settles
            if not tracker.tick():
                break
            tracker.set_target(commands[-1])
        measured.append(np.array(tracker.state.q))
    return {"commands": np.array(commands), "measured": np.array(measured), "compute_ms": np.array(compute)}


def main(host: str, model: str) -> None:
    import franky

    import lasercal

    robot = lasercal.load_model(model)
    arm = franky.Robot(host)
    arm.relative_dynamics_factor = 0.1
    corrector = lasercal.Corrector(robot, q0=np.array(arm.state.q))
    start = robot.fk(np.array(arm.state.q))[0]  # the flange where the calibrated model says it is
    out = follow(arm, corrector, circle(start, seconds=10.0, period=0.001))
    ms = out["compute_ms"]
    print(f"{len(ms)} goals; corrector median {np.median(ms):.3f} ms, p99 {np.percentile(ms, 99):.3f} ms")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])

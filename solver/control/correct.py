"""Corrected joint commands: the angles to send so that the real robot (the calibrated model with its
effects) puts a tool at a goal, and what a controller that keeps the nominal model makes of them.

1. Geometry. The inverse kinematics of the calibrated screws (:func:`solver.kinematics.ik.solve_ik`)
   gives the true link angles q_true that put the tool at the goal, nearest the seed, inside the joint
   limits less a margin.
2. Effects. A robot effect of the model (joint compliance, encoder eccentricity) maps the commanded
   (read) angles to the true ones, q_true = q_cmd + dq(q_cmd, tau(q_cmd)), with tau the gravity torques
   the fit used at the commanded pose: the nominal robot's gravity model, else its lumped wrist load
   (:func:`solver.control.nominal.gravity_robot`, :func:`solver.kinematics.gravity.model_torques`).
   The command is the fixed point q_cmd = q_true - dq(q_cmd, tau(q_cmd)), a contraction since dq
   changes by milliradians per radian.
   A command pushed past the limit margin by dq is solved again with the bounds of q_true moved by dq.
3. Check. The calibrated model's miss at q_cmd (with its effects) is the residual; a goal is ``ok`` when
   it is below :data:`OK_MM` (and :data:`OK_RAD` for a pose) with every command inside the limits less
   the margin. A goal that is not ok says why.
4. The nominal's view. The nominal model's forward kinematics of the tool at q_cmd is the Cartesian
   command for a controller that keeps the nominal kinematics (libfranka, franky, panda-py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.errors import ModelError
from lasercal.solver.kinematics.gravity import model_torques
from lasercal.solver.kinematics.ik import IKOptions, IKSolution, solve_ik
from lasercal.solver.kinematics.model import RobotModel

OK_MM = 1e-3  # mm: a goal is reached when the calibrated model misses it by less
OK_RAD = 1e-6  # rad: ... and turns less than this from a goal orientation
_LIMIT_TOL = 1e-9  # rad: round-off allowed on the limit margin
_FIXED_POINT_ITERATIONS = 30
_FIXED_POINT_TOL = 1e-13  # rad
_LIMIT_PASSES = 4  # re-solves with bounds moved by dq: each shrinks the miss by c dtau/dq (~1e-2)


@dataclass(frozen=True, eq=False)
class Commands:
    """Joint commands for goals and how well the calibrated model says they reach them.

    Attributes
    ----------
    q : (m, n) array, the joint commands (what the controller reads and is sent), rad
    residual_mm : (m,) array, the calibrated model's position miss at q (with its effects), mm
    residual_rad : (m,) array, its orientation miss, rad (zeros for position goals)
    ok : (m,) bool array
    reason : tuple of m str, why a goal is not ok ('' when it is)
    """

    q: np.ndarray
    residual_mm: np.ndarray
    residual_rad: np.ndarray
    ok: np.ndarray
    reason: tuple


def joint_effect(ext) -> None:
    """Refuse an effect a controller cannot apply from the joint angles alone (a drift needs a clock)."""
    if ext is not None and "t" in ext.needs():
        raise ModelError(
            f"the model's {ext.effect} needs the time since a session started: it is a session effect, "
            "not one to apply when commanding the robot"
        )


def true_angles(model: RobotModel, ext, q_cmd: np.ndarray, gravity: RobotModel | None = None) -> np.ndarray:
    """The true link angles (m, n) at the commanded angles: q_cmd + dq(q_cmd, tau(q_cmd)) (step 2), tau
    from the gravity model of ``gravity`` (default ``model``; the fit's: :func:`nominal.gravity_robot`)."""
    if ext is None:
        return q_cmd
    tau = model_torques(gravity or model, q_cmd)[0] if "tau" in ext.needs() else None
    return ext.true_q(q_cmd, None, tau)


def command_angles(
    model: RobotModel, ext, q_true: np.ndarray, gravity: RobotModel | None = None
) -> np.ndarray:
    """The commanded angles (m, n) whose true angles are q_true: the fixed point
    q_cmd = q_true - dq(q_cmd, tau(q_cmd)) (step 2; ``gravity`` as for :func:`true_angles`)."""
    if ext is None:
        return q_true
    q = np.array(q_true, dtype=float)
    for _ in range(_FIXED_POINT_ITERATIONS):
        nxt = q_true - (true_angles(model, ext, q, gravity) - q)
        converged = np.abs(nxt - q).max(initial=0.0) < _FIXED_POINT_TOL
        q = nxt
        if converged:
            break
    return q


def _outside(q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(m, n) bool: angles outside [lo, hi] beyond round-off."""
    return (q < lo - _LIMIT_TOL) | (q > hi + _LIMIT_TOL)


def solve_commands(
    model: RobotModel,
    ext,
    M: np.ndarray,
    seed: np.ndarray,
    p_goal: np.ndarray,
    R_goal: np.ndarray | None,
    opts: IKOptions,
    pull: bool = True,
    gravity: RobotModel | None = None,
) -> tuple[np.ndarray, IKSolution]:
    """Steps 1 and 2: commands (m, n) rad for goals of the tool whose frame at q = 0 is M, and the IK report.

    Parameters
    ----------
    model : RobotModel, the calibrated model
    ext : Extension, Combination or None, its robot effect
    M : (4, 4) array, the tool frame at q = 0 under the model, mm
    seed : (m, n) array, rad
    p_goal : (m, 3) array, mm; R_goal : (m, 3, 3) array or None
    opts : IKOptions
    pull : bool, the seeds pull a redundant arm towards them (False: they are only where the search starts)
    gravity : RobotModel, optional, whose gravity model gives the effect's torques (:func:`true_angles`)
    """
    sol = solve_ik(model.screws, M, model.limits, seed, p_goal, R_goal, opts, pull=pull)
    q = command_angles(model, ext, sol.q, gravity)
    lo, hi = model.limits[:, 0] + opts.margin, model.limits[:, 1] - opts.margin
    for _ in range(
        _LIMIT_PASSES
    ):  # bounds of q_true moved by dq, so that q_cmd = q_true - dq keeps the margin
        redo = np.flatnonzero(_outside(q, lo, hi).any(axis=1))
        if not len(redo):
            break
        dq = sol.q[redo] - q[redo]
        R = None if R_goal is None else R_goal[redo]
        again = solve_ik(
            model.screws,
            M,
            model.limits,
            seed[redo],
            p_goal[redo],
            R,
            opts,
            (lo + dq, hi + dq),
            pull,
            sol.q[redo],
        )
        q[redo] = command_angles(model, ext, again.q, gravity)
        sol = sol.with_rows(redo, again)
    return q, sol


def check(
    model: RobotModel,
    ext,
    M: np.ndarray,
    q: np.ndarray,
    sol: IKSolution,
    p_goal: np.ndarray,
    R_goal: np.ndarray | None,
    opts: IKOptions,
    gravity: RobotModel | None = None,
) -> Commands:
    """Step 3: the calibrated model's miss at the commands, ok, and the reason of each goal not ok
    (``gravity`` as for :func:`true_angles`)."""
    from lasercal.solver.kinematics.ik import rotation_error, tool_frames

    T = tool_frames(model.screws, M, true_angles(model, ext, q, gravity))[0]
    res_mm = np.linalg.norm(p_goal - T[:, :3, 3], axis=1)
    res_rad = (
        np.zeros(len(q)) if R_goal is None else np.linalg.norm(rotation_error(R_goal, T[:, :3, :3]), axis=1)
    )
    lo, hi = model.limits[:, 0] + opts.margin, model.limits[:, 1] - opts.margin
    out = _outside(q, lo, hi)
    ok = (res_mm < OK_MM) & (res_rad < OK_RAD) & ~out.any(axis=1)
    reasons = []
    for i in range(len(q)):
        if ok[i]:
            reasons.append("")
        elif out[i].any():
            js = ", ".join(str(j + 1) for j in np.flatnonzero(out[i]))
            reasons.append(f"the effect's correction pushes joint(s) {js} past the limit margin")
        else:
            miss = f"{res_mm[i]:.3g} mm" + (f" and {res_rad[i]:.3g} rad" if R_goal is not None else "")
            held = np.flatnonzero(sol.at_bound[i])
            at = f"; joint(s) {', '.join(str(j + 1) for j in held)} at the limit margin" if len(held) else ""
            reasons.append(f"unreachable: the best of {sol.starts[i]} starts misses by {miss}{at}")
    return Commands(q, res_mm, res_rad, ok, tuple(reasons))

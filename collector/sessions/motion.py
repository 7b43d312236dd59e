"""Safety for every command that moves the arm: plan in bounded steps, preview, confirm.

Used by ``lasercal validate`` (and meant for the capture coach's ``--guide move``)::

    plan = plan_moves(robot.read().q, targets, model, max_step=0.5)
    print(preview(plan))
    confirm(plan, yes=args.yes)          # refuses with no terminal and no --yes
    for k, q in enumerate(plan.steps):   # each step changes no joint by more than max_step
        robot.move_to(q)

A move whose largest joint change exceeds ``max_step`` (rad) is split into equal joint-space
steps (``split=True``) or refused. The preview states the number of moves, the largest joint
change of any single commanded step, and the box (base frame, mm) the laser aperture sweeps
along the joint-space path.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from lasercal.solver.errors import LasercalError
from lasercal.solver.formats.checks import Range
from lasercal.solver.kinematics.laser import beam
from lasercal.solver.kinematics.model import RobotModel

MAX_STEP = 0.5  # rad, default bound on any joint's change in one commanded move
MAX_STEP_RANGE = Range(0.0, np.pi, "rad", lo_open=True)
DYNAMICS_RANGE = Range(0.0, 0.3, "", lo_open=True)  # fraction of the robot's velocity/acceleration limits
_SWEEP_SAMPLES = 8  # points per step at which the aperture's path is evaluated for the box


class MotionRefused(LasercalError):
    """The arm was not moved: no confirmation, or a move larger than the step bound with splitting off."""


@dataclass(frozen=True)
class MovePlan:
    """A sequence of joint-space moves, each at most ``max_step`` rad on every joint.

    Attributes
    ----------
    start : (n,) rad, where the arm is
    targets : (k, n) rad, the configurations asked for
    steps : (s, n) rad, every commanded configuration in order (s >= k)
    target_of : (s,) int, the target each step belongs to; the last step of target i equals targets[i]
    max_step : float, rad
    box : (2, 3) mm, min and max corner of the aperture's sweep (base frame)
    """

    start: np.ndarray
    targets: np.ndarray
    steps: np.ndarray
    target_of: np.ndarray
    max_step: float
    box: np.ndarray

    @property
    def largest_change(self) -> float:
        """Largest change of any joint in any one commanded step, rad."""
        path = np.vstack([self.start, self.steps])
        return float(np.abs(np.diff(path, axis=0)).max(initial=0.0))

    def arrives(self, i: int) -> int:
        """Index in ``steps`` of the step that reaches target i."""
        return int(np.flatnonzero(self.target_of == i)[-1])


def joint_steps(a: np.ndarray, b: np.ndarray, max_step: float) -> np.ndarray:
    """Equal joint-space steps from a to b, none changing a joint by more than max_step: (s, n) rad.

    s = ceil(max_j |b_j - a_j| / max_step) (at least 1); step k is a + (k/s)(b - a), k = 1..s.
    """
    s = max(1, int(np.ceil(np.abs(b - a).max() / max_step - 1e-12)))
    return a + np.outer(np.arange(1, s + 1) / s, b - a)


def plan_moves(start, targets, model: RobotModel, max_step: float = MAX_STEP, split: bool = True) -> MovePlan:
    """Plan moves through ``targets`` from ``start`` with no joint changing by more than ``max_step``.

    Parameters
    ----------
    start : (n,) rad
    targets : (k, n) rad
    model : RobotModel, for joint limits and the swept box
    max_step : float, rad, in (0, pi]
    split : bool, split larger moves into steps (else refuse them)

    Raises
    ------
    MotionRefused
        A target outside the joint limits, or a move above ``max_step`` with ``split=False``.
    """
    msg = MAX_STEP_RANGE.problem(max_step)
    if msg:
        raise MotionRefused(f"--max-step: {msg}")
    start = np.asarray(start, dtype=float)
    targets = np.asarray(targets, dtype=float).reshape(-1, model.n)
    lo, hi = model.limits[:, 0], model.limits[:, 1]
    out = np.argwhere((targets < lo) | (targets > hi))
    if out.size:
        i, j = out[0]
        raise MotionRefused(
            f"move {i + 1}: joint {j + 1} = {targets[i, j]:.4f} rad is outside its limits "
            f"[{lo[j]:.4f}, {hi[j]:.4f}]: not moving"
        )
    steps, owner, prev = [], [], start
    for i, q in enumerate(targets):
        s = joint_steps(prev, q, max_step)
        if len(s) > 1 and not split:
            j = int(np.argmax(np.abs(q - prev)))
            raise MotionRefused(
                f"move {i + 1}: joint {j + 1} would change by {abs(q[j] - prev[j]):.3f} rad in one move "
                f"(expected at most --max-step {max_step:g} rad)"
            )
        steps.append(s)
        owner += [i] * len(s)
        prev = q
    steps = np.vstack(steps) if steps else np.empty((0, model.n))
    return MovePlan(
        start, targets, steps, np.array(owner, dtype=int), float(max_step), _swept_box(start, steps, model)
    )


def _swept_box(start: np.ndarray, steps: np.ndarray, model: RobotModel) -> np.ndarray:
    """Min and max corner (2, 3) mm of the aperture along the joint-space path, sampled per step."""
    path = np.vstack([start, steps])
    f = np.linspace(0.0, 1.0, _SWEEP_SAMPLES)
    samples = (path[:-1, None, :] + f[None, :, None] * np.diff(path, axis=0)[:, None, :]).reshape(-1, model.n)
    p = beam(model.screws, model.laser_dir, model.aperture, samples if len(samples) else path).aperture
    return np.stack([p.min(axis=0), p.max(axis=0)])


def preview(plan: MovePlan) -> str:
    """What the arm is about to do, in a few lines (moves, largest joint change per move, box swept)."""
    per_target = [
        float(np.abs(np.diff(np.vstack([plan.start if i == 0 else plan.targets[i - 1], t]), axis=0)).max())
        for i, t in enumerate(plan.targets)
    ]
    lo, hi = plan.box
    split = len(plan.steps) - len(plan.targets)
    return (
        f"the arm will move to {len(plan.targets)} configurations in {len(plan.steps)} moves"
        + (f" ({split} extra to keep steps within {plan.max_step:g} rad)" if split else "")
        + "\n"
        f"  largest joint change per move: {plan.largest_change:.3f} rad "
        f"({np.degrees(plan.largest_change):.1f} deg); between configurations up to "
        f"{max(per_target, default=0.0):.3f} rad\n"
        f"  laser aperture sweeps x [{lo[0]:.0f}, {hi[0]:.0f}] y [{lo[1]:.0f}, {hi[1]:.0f}] "
        f"z [{lo[2]:.0f}, {hi[2]:.0f}] mm (base frame): keep this box clear\n"
    )


def confirmable(yes: bool = False, stdin=None, what: str = "") -> None:
    """Refuse at once when moves could not be confirmed: no ``--yes`` and no terminal to ask.

    Lets a command refuse before it creates anything (``capture --guide move`` plans its moves
    only as the session goes).

    Raises
    ------
    MotionRefused
    """
    stdin = sys.stdin if stdin is None else stdin
    if not yes and not (hasattr(stdin, "isatty") and stdin.isatty()):
        raise MotionRefused(
            f"refusing to move the arm {what}without confirmation: no terminal to ask; "
            "pass --yes to confirm from a script"
        )


def confirm(plan: MovePlan, yes: bool = False, stdin=None, out=None) -> None:
    """Ask for ``yes`` before the first move; ``yes=True`` (``--yes``) confirms for scripts.

    Raises
    ------
    MotionRefused
        No terminal to ask and no ``--yes``, or anything but ``yes`` typed.
    """
    stdin = sys.stdin if stdin is None else stdin
    out = sys.stdout if out is None else out
    if yes:
        return
    confirmable(yes, stdin, f"({len(plan.steps)} moves) ")
    out.write("type yes to start moving the arm: ")
    out.flush()
    answer = stdin.readline().strip().lower()
    if answer != "yes":
        raise MotionRefused(f"not confirmed ({answer!r} typed, expected 'yes'): the arm did not move")

"""The Python API of a calibration for a control script: ``lasercal.load_model(path)`` -> :class:`Robot`.

.. code-block:: python

    import lasercal

    robot = lasercal.load_model("model.yaml")             # a calibrated model (or 'panda', a URDF)
    T = robot.fk(q)                                       # (m, 4, 4) mm: where the flange is at q
    sol = robot.ik([[450, 0, 300]], seed=q0)              # q (m, n) rad for goals, nearest the seed
    cmd = robot.correct(q=program)                        # a nominal program, corrected
    cmd.q, cmd.nominal_pose, cmd.ok                       # joint commands, Cartesian commands, ok

Units: mm and rad; every array is vectorised over rows (m goals or configurations). Joint angles are
the ones the controller reads and is sent: the model's robot effects (a joint compliance, an encoder
eccentricity) map them onto the true link angles inside :meth:`Robot.fk` and :meth:`Robot.ik`.
Goals are positions (m, 3) mm, poses (m, 6) -- position mm and rotation vector rad -- or frames
(m, 4, 4), in the robot's base frame. A tool is the flange (default), a name the calibration
identified (``robot.tools``), a TCP (x, y, z) mm in the flange frame, or a :class:`Tool`
(:mod:`solver.control.tools`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from lasercal.solver.control.correct import (
    Commands,
    check,
    command_angles,
    joint_effect,
    solve_commands,
    true_angles,
)
from lasercal.solver.control.nominal import gravity_robot, nominal_model
from lasercal.solver.control.tools import FLANGE, Tool, flange, identified_points, make_tool
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.robots import load_model as load_robot_model
from lasercal.solver.kinematics.ik import DEFAULT_IK, IKOptions, tool_frames
from lasercal.solver.kinematics.joint_map import model_extension
from lasercal.solver.kinematics.model import RobotModel


@dataclass(frozen=True, eq=False)
class Correction(Commands):
    """:class:`Commands` and the nominal model's forward kinematics of the tool at them.

    Attributes
    ----------
    nominal_pose : (m, 4, 4) array, the tool frame the nominal model computes at ``q``, mm: the Cartesian
        command for a controller that keeps the nominal model
    """

    nominal_pose: np.ndarray = None


def goal_frames(goal) -> tuple[np.ndarray, np.ndarray | None]:
    """Positions (m, 3) mm and orientations (m, 3, 3) or None from goals (m, 3), (m, 6) or (m, 4, 4)."""
    from scipy.spatial.transform import Rotation

    g = np.asarray(goal, dtype=float)
    if g.ndim >= 2 and g.shape[-2:] == (4, 4):
        g = g.reshape(-1, 4, 4)
        return g[:, :3, 3].copy(), g[:, :3, :3].copy()
    g = np.atleast_2d(g)
    if g.ndim != 2 or g.shape[1] not in (3, 6) or not np.all(np.isfinite(g)):
        raise FormatError(
            "goal", f"goals are (m, 3) positions, (m, 6) poses or (m, 4, 4) frames, not {g.shape}"
        )
    return g[:, :3].copy(), Rotation.from_rotvec(g[:, 3:]).as_matrix() if g.shape[1] == 6 else None


class Robot:
    """A calibrated robot for a control script: forward and inverse kinematics of a tool under the calibrated
    model, and commands for a controller that keeps the nominal model (module docstring).

    Parameters
    ----------
    model : RobotModel, the calibrated model (with its robot effects in ``extensions``)
    nominal : RobotModel, the model the robot's controller keeps
    options : IKOptions, the inverse kinematics' margin to the joint limits, tolerances and restarts
    path : str or Path, optional, the model's file (named in messages)
    payload : (mass kg, (3,) centre of mass at q = 0 in mm), optional, the flange's load in the effects'
        gravity torques (default: the one the model's fit took, ``identification.payload``)
    """

    def __init__(
        self,
        model: RobotModel,
        nominal: RobotModel,
        options: IKOptions = DEFAULT_IK,
        path=None,
        payload=None,
    ):
        self.model, self.nominal, self.options, self.path = model, nominal, options, path
        self.gravity = gravity_robot(model, path, nominal, payload)  # the effects' torques: the fit's
        self.extension = model_extension(model.extensions, path or model.name, model.n)  # the joint map too
        joint_effect(self.extension)
        self.flange = flange(model)
        self.nominal_flange = flange(nominal)

    @property
    def calibrated(self) -> bool:
        """Whether the model calibrates another (``lasercal solve`` wrote it, or it names its ``nominal``)
        rather than being a nominal model itself."""
        return bool(self.model.identification or self.model.nominal)

    def __repr__(self) -> str:
        """What the robot is: e.g. ``<Robot panda_thesis_identified: calibrated (lm, model.yaml), nominal
        panda, 7 joints, tools flange>`` or ``<Robot panda: nominal, 7 joints, tools flange>``."""
        where = f", {self.path}" if self.path is not None else ""
        if self.calibrated:
            method = self.model.identification.get("method")
            how = f"{method}{where}" if method else where.removeprefix(", ")
            what = f"calibrated{f' ({how})' if how else ''}, nominal {self.nominal.name}"
        else:
            what = f"nominal{where}"
        effects = f", effects {self.extension.effect}" if self.extension is not None else ""
        return f"<Robot {self.model.name}: {what}, {self.n} joints, tools {', '.join(self.tools)}{effects}>"

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.model.n

    @property
    def tools(self) -> list[str]:
        """The tools by name: the flange and what the calibration identified (targets, 'tool', 'ee')."""
        return [FLANGE] + list(identified_points(self.model))

    def tool(self, tool=None) -> Tool:
        """The :class:`Tool` a ``tool`` argument names (module docstring)."""
        return make_tool(self.model, self.flange, tool)

    def tool_frame(self, tool=None, nominal: bool = False) -> np.ndarray:
        """The tool's frame at q = 0 (4, 4) mm, base frame, under the calibrated (or the nominal) model."""
        F = self.nominal_flange if nominal else self.flange
        return F @ self.tool(tool).offset

    def fk(self, q, tool=None, nominal: bool = False) -> np.ndarray:
        """Forward kinematics: the tool frame (m, 4, 4) mm when the joints read q.

        Parameters
        ----------
        q : (m, n) or (n,) array, joint angles as read and commanded, rad
        tool : see the module docstring (default the flange)
        nominal : bool, the nominal model's view (no effects) instead of the calibrated robot's

        Returns
        -------
        (m, 4, 4) array, mm, base frame: e^[S1]q1 ... e^[Sn]qn M (Modern Robotics eq. 4.14) at the true
        angles of the model's effects
        """
        q = self._angles(q)
        if nominal:
            return tool_frames(self.nominal.screws, self.tool_frame(tool, nominal=True), q)[0]
        q_true = true_angles(self.model, self.extension, q, self.gravity)
        return tool_frames(self.model.screws, self.tool_frame(tool), q_true)[0]

    def command(self, q_true) -> np.ndarray:
        """The joint commands (m, n) rad whose true link angles are ``q_true`` (m, n) rad: the model's effects
        inverted (a configuration planned on the calibrated URDF, which cannot carry them, e.g. by MoveIt)."""
        return command_angles(self.model, self.extension, self._angles(q_true), self.gravity)

    def ik(self, goal, seed=None, tool=None) -> Commands:
        """Inverse kinematics: joint angles (as commanded) putting the tool at each goal under the calibrated
        model with its effects, inside the joint limits less the margin, nearest the seed.

        Parameters
        ----------
        goal : (m, 3) positions mm, (m, 6) positions mm and rotation vectors rad, or (m, 4, 4) frames
        seed : (m, n) or (n,) array, rad, optional: the answer is the solution nearest it (without a seed the
            search starts at the model's home, else the middle of the limits, and nothing pulls)
        tool : see the module docstring (default the flange)

        Returns
        -------
        Commands: ``q`` (m, n) rad, ``residual_mm``, ``residual_rad``, ``ok``, ``reason`` per goal
        """
        p, R = goal_frames(goal)
        M = self.tool_frame(tool)
        pull = seed is not None
        seed = self._seed(seed, len(p))
        q, sol = solve_commands(self.model, self.extension, M, seed, p, R, self.options, pull, self.gravity)
        return check(self.model, self.extension, M, q, sol, p, R, self.options, self.gravity)

    def correct(self, goal=None, q=None, seed=None, tool=None) -> Correction:
        """Commands for a controller that keeps the nominal model: goals, or a program planned with it.

        Parameters
        ----------
        goal : goals as for :meth:`ik`, or None
        q : (m, n) array, rad, or None: a joint-space program planned with the nominal model; its goals
            are the nominal model's tool frames at q (position and orientation), q the seeds
        seed : (m, n) array, rad, optional, the seeds of ``goal``
        tool : see the module docstring (default the flange)

        Returns
        -------
        Correction: :meth:`ik`'s commands and ``nominal_pose`` (m, 4, 4), the nominal model's tool frame at
        each command (mm)
        """
        if (goal is None) == (q is None):
            raise FormatError("goal", "give either goals or a joint-space program q, not both or neither")
        if q is not None:
            q = self._angles(q)
            goal, seed = self.fk(q, tool, nominal=True), q
        c = self.ik(goal, seed, tool)
        parts = {f.name: getattr(c, f.name) for f in fields(Commands)}
        return Correction(**parts, nominal_pose=self.fk(c.q, tool, nominal=True))

    def _angles(self, q) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[1] != self.n or not np.all(np.isfinite(q)):
            raise FormatError("q", f"joint angles are (m, {self.n}) finite numbers (rad), got {q.shape}")
        return q

    def _seed(self, seed, m: int) -> np.ndarray:
        if seed is None:
            home = self.model.home
            seed = home if home is not None else self.model.limits.mean(axis=1)
        seed = self._angles(seed)
        if len(seed) not in (1, m):
            raise FormatError("seed", f"one seed, or one per goal ({m}), got {len(seed)}")
        return np.broadcast_to(seed, (m, self.n))


def load_model(path, options: IKOptions = DEFAULT_IK, payload=None) -> Robot:
    """A calibrated model file (or a built-in robot, or a URDF) as a :class:`Robot`, with its nominal model.

    Parameters
    ----------
    path : str or Path, a ``lasercal-robot/1`` YAML (``lasercal solve`` writes one), a built-in name or a URDF
    options : IKOptions, optional
    payload : (mass kg, (3,) centre of mass at q = 0 in mm), optional, instead of the model's recorded one
        (:class:`Robot`)

    Returns
    -------
    Robot
    """
    model = load_robot_model(path)
    ref = path if Path(str(path)).is_file() else None
    return Robot(model, nominal_model(model, ref), options, ref, payload)

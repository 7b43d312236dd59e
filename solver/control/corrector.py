"""A corrector for a control loop: made once from a calibrated model and a tool, then called per goal at the
controller's rate, it returns the joint command that puts the tool at the goal on the real robot -- the
command a controller that keeps the nominal model is sent (``lasercal correct`` for one goal at a time,
warm-started from the previous command).

.. code-block:: python

    import lasercal

    corrector = lasercal.Corrector(lasercal.load_model("model.yaml"), tool=(0, 0, 103.4), q0=q_measured)
    for goal in path:                  # (4, 4) frames, (6,) poses (mm, rotation vector rad) or (3,) positions
        q_cmd = corrector(goal)        # (n,) rad: send it as the joint target
    corrector.nominal_pose(q_cmd)      # (4, 4) mm: the Cartesian command for a nominal Cartesian controller

The computation (the same solution as :mod:`solver.control.correct`, by fewer and cheaper operations):

1. Geometry. The calibrated screws are rewritten once as a chain of constant origins and turns about z,
   T(q) = O_1 Rz(q_1) ... O_n Rz(q_n) O_tool (the form of a URDF, :mod:`solver.formats.franka`, exact:
   G Rz(q) G^-1 = e^[S] q for a frame G with z along the screw's axis, origin on it; a prismatic joint a
   slide Tz(q) along z), evaluated in Python floats: for a 7-joint arm a few hundred multiplications,
   where numpy's per-call overhead on 3-vectors would cost more than the arithmetic.
2. Newton steps from the previous command. The task error is :mod:`solver.kinematics.ik`'s: e = (p_g - p,
   L log(R_g R^T)), L = ``length_mm``; the Jacobian's columns are (z_j x (p - o_j), L z_j) for a turning
   joint with axis z_j through o_j. The step is the minimum-norm solution of J (q' - q_s) = e + J (q - q_s)
   with the previous command q_s as the seed -- dq = J^T (J J^T + lambda I)^-1 (e - J (q_s - q)) + (q_s - q)
   (eq. 6.7 with the seed's null-space pull, lambda = |e|^2 / 2 + lambda_0 as in ik) -- whose fixed point is
   the solution nearest the previous command, ``correct``'s with that seed (the true angles pulled towards
   the command, as ``correct`` pulls them). J J^T + lambda I is solved by LAPACK. The steps start where
   the last tick's motion carries the true angles, q_t + (q_t - q_(t-1)): the goal moves by v dt (1.7 mm
   at 1.7 m/s) between ticks, the extrapolation misses it only by a dt^2 (0.02 mm on a 150 mm circle), so
   one step lands within round-off of the goal and the second only confirms it. A step shorter than
   :data:`STEP_TOL` rad ends it: the error it leaves is of second order, below 1e-7 mm at the tool of a
   1 m arm.
3. Limits, as ``correct`` keeps them: the true angles stay in [lo, hi] (the limits less the margin) by
   clamping after each step, and a joint on its bound whose step points outside leaves the Jacobian and
   the pull for the next step (ik's active set; the fixed point then has that joint on its bound and the
   others reaching the goal). Where the pull holds joints on their bounds short of the goal (a
   least-squares point: the others cannot reach it), steps of the task alone follow, in which they may
   leave them (ik's polish). A command the effects push past the margin is solved again with the bounds
   of q_true moved by dq (``correct``'s passes).
4. Effects. A compliance and an eccentricity (the model's robot effects, q_true = q_cmd + dq) are linear
   in (tau, sin q, cos q); the command q_cmd = q_true - dq(q_cmd) is the fixed point started from the
   previous goal's correction: two passes (two gravity evaluations) a goal, since each shrinks the error by
   c dtau/dq (~1e-3) and the first starts from the path's change of dq between goals. The gravity torques
   are :mod:`solver.kinematics.gravity`'s on the same chain.
5. Anything else -- :data:`MAX_STEPS` steps (of each phase) without converging, e.g. a goal a tenth of a
   radian from the last command (a joint at 100 rad/s: no path an arm follows), a half-turn of orientation
   error, a command still outside the margin -- goes to :meth:`Robot.ik` (``correct``'s solver, restarts
   and limit handling) for that goal; :attr:`Corrector.last` says so, and whether the goal was reached.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from operator import mul
from pathlib import Path

import numpy as np

from lasercal.solver.control.correct import _LIMIT_PASSES, _LIMIT_TOL, true_angles
from lasercal.solver.errors import FormatError, ModelError
from lasercal.solver.kinematics.gravity import G as GRAVITY
from lasercal.solver.kinematics.gravity import wrist_centre
from lasercal.solver.kinematics.ik import tool_frames
from lasercal.solver.kinematics.poe import inv_T

MAX_STEPS = 6  # Newton steps before the goal goes to the full solver (two suffice along a path at 1 kHz)
STEP_TOL = 2e-6  # rad: a step this short leaves an error of second order, < 1e-7 mm on a 1 m arm
_REACH_TOL = 1e-6  # mm (task units): a converged step's linear model must reach the goal to this
_HALF_TURN = 3.0  # rad: beyond this the rotation's log is taken by scipy (near pi its axis is ill-posed)
_EFFECT_PASSES = 2  # fixed-point passes of q_cmd = q_true - dq(q_cmd): each shrinks the error ~1e3 times
_CHECK_TOL = 1e-9  # mm, rad: the Python-float chain and effects must reproduce lasercal's own to this


@dataclass
class Step:
    """How the last goal went.

    Attributes
    ----------
    steps : int, Newton steps taken (0 when the previous command already reached the goal)
    last_step : float, the largest joint change of the final step, rad (its error is of second order)
    fallback : bool, the goal went to the full solver (:meth:`Robot.ik`)
    ok : bool, the goal was reached inside the limits less the margin
    reason : str, why not ('' when ok)
    """

    steps: int = 0
    last_step: float = 0.0
    fallback: bool = False
    ok: bool = True
    reason: str = ""


def _frame(z: np.ndarray, origin: np.ndarray, ref_x: np.ndarray) -> np.ndarray:
    """A frame with the unit z, the given origin and x the reference x made normal to z (or y if along z)."""
    x = ref_x - z * (ref_x @ z)
    if np.linalg.norm(x) < 1e-6:
        x = np.cross(z, ref_x)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, origin
    return T


def _flat(T: np.ndarray) -> tuple:
    """A transform as 12 floats: the rotation row by row, then the translation."""
    return tuple(float(v) for v in T[:3, :3].ravel()) + tuple(float(v) for v in T[:3, 3])


class _Chain:
    """Screws (n, 6) and a tool frame M at q = 0 as constant origins and turns about z (module docstring, 1).

    Parameters
    ----------
    screws : (n, 6) array, unit-omega (or zero-omega: prismatic) screws in the base frame at q = 0, mm
    M : (4, 4) array, the tool frame at q = 0, mm
    com : list of (joint index, mass kg, (3,) centre of mass at q = 0 mm), bodies for gravity torques
    """

    def __init__(self, screws: np.ndarray, M: np.ndarray, com: list = ()):
        frames, prev = [], np.eye(4)
        self.prismatic = [bool(np.linalg.norm(S[:3]) < 0.5) for S in screws]
        for S, slide in zip(screws, self.prismatic):
            if slide:  # a slide along v from wherever the previous frame is
                z, origin = S[3:] / np.linalg.norm(S[3:]), prev[:3, 3]
            else:  # the axis point nearest the previous frame's origin: small origins, no cancellation
                z, c = S[:3], np.cross(S[:3], S[3:])
                origin = c + z * ((prev[:3, 3] - c) @ z)
            prev = _frame(z, origin, prev[:3, 0])
            frames.append(prev)
        chain = [np.eye(4)] + frames
        self.origins = [_flat(inv_T(chain[i]) @ chain[i + 1]) for i in range(len(frames))]
        self.tool = _flat(inv_T(frames[-1]) @ M)
        self.n = len(frames)
        self.bodies = [
            (j, float(m), tuple(float(v) for v in (inv_T(frames[j]) @ np.r_[c, 1.0])[:3])) for j, m, c in com
        ]

    def run(self, q) -> tuple:
        """Tool rotation (9 floats, row by row), tool position (3) mm, joint axes z_j and origins o_j
        (lists of 3-tuples) at q, and the link frames (R, p) after each joint."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
        px = py = pz = 0.0
        zs, os_, links = [], [], []
        for (a00, a01, a02, a10, a11, a12, a20, a21, a22, ax, ay, az), qj, slide in zip(
            self.origins, q, self.prismatic
        ):
            px, py, pz = (
                px + r00 * ax + r01 * ay + r02 * az,
                py + r10 * ax + r11 * ay + r12 * az,
                pz + r20 * ax + r21 * ay + r22 * az,
            )
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
                r00 * a00 + r01 * a10 + r02 * a20,
                r00 * a01 + r01 * a11 + r02 * a21,
                r00 * a02 + r01 * a12 + r02 * a22,
                r10 * a00 + r11 * a10 + r12 * a20,
                r10 * a01 + r11 * a11 + r12 * a21,
                r10 * a02 + r11 * a12 + r12 * a22,
                r20 * a00 + r21 * a10 + r22 * a20,
                r20 * a01 + r21 * a11 + r22 * a21,
                r20 * a02 + r21 * a12 + r22 * a22,
            )
            zs.append((r02, r12, r22))
            os_.append((px, py, pz))
            if slide:
                px, py, pz = px + r02 * qj, py + r12 * qj, pz + r22 * qj
            else:  # R Rz(q): the first two columns turn
                c, s = math.cos(qj), math.sin(qj)
                r00, r01 = c * r00 + s * r01, c * r01 - s * r00
                r10, r11 = c * r10 + s * r11, c * r11 - s * r10
                r20, r21 = c * r20 + s * r21, c * r21 - s * r20
            links.append((r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz))
        a00, a01, a02, a10, a11, a12, a20, a21, a22, ax, ay, az = self.tool
        p = (
            px + r00 * ax + r01 * ay + r02 * az,
            py + r10 * ax + r11 * ay + r12 * az,
            pz + r20 * ax + r21 * ay + r22 * az,
        )
        R = (
            r00 * a00 + r01 * a10 + r02 * a20,
            r00 * a01 + r01 * a11 + r02 * a21,
            r00 * a02 + r01 * a12 + r02 * a22,
            r10 * a00 + r11 * a10 + r12 * a20,
            r10 * a01 + r11 * a11 + r12 * a21,
            r10 * a02 + r11 * a12 + r12 * a22,
            r20 * a00 + r21 * a10 + r22 * a20,
            r20 * a01 + r21 * a11 + r22 * a21,
            r20 * a02 + r21 * a12 + r22 * a22,
        )
        return R, p, zs, os_, links

    def torques(self, q) -> list:
        """Gravity torques (n) Nm at q: tau_j = g sum_(i >= j) m_i (z_j x (c_i - o_j))_z (gravity.py)."""
        _, _, zs, os_, links = self.run(q)
        mass, cx, cy = [0.0] * self.n, [0.0] * self.n, [0.0] * self.n
        for j, m, (bx, by, bz) in self.bodies:
            r00, r01, r02, r10, r11, r12, *_, px, py, _pz = links[j]
            mass[j] += m
            cx[j] += m * (px + r00 * bx + r01 * by + r02 * bz)
            cy[j] += m * (py + r10 * bx + r11 * by + r12 * bz)
        tau, M, X, Y = [0.0] * self.n, 0.0, 0.0, 0.0
        for j in range(self.n - 1, -1, -1):  # bodies at or after joint j, accumulated from the tip
            M, X, Y = M + mass[j], X + cx[j], Y + cy[j]
            (zx, zy, _), (ox, oy, _) = zs[j], os_[j]
            tau[j] = 0.0 if self.prismatic[j] else GRAVITY / 1000.0 * (zx * (Y - M * oy) - zy * (X - M * ox))
        return tau


def _log_rotation(Rg: tuple, R: tuple) -> tuple | None:
    """The rotation vector of Rg R^T (9-float rotations, row by row), rad; None near a half turn."""
    g00, g01, g02, g10, g11, g12, g20, g21, g22 = Rg
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    # E = Rg R^T: E_ab = (row a of Rg) . (row b of R)
    e00 = g00 * r00 + g01 * r01 + g02 * r02
    e11 = g10 * r10 + g11 * r11 + g12 * r12
    e22 = g20 * r20 + g21 * r21 + g22 * r22
    e21 = g20 * r10 + g21 * r11 + g22 * r12
    e12 = g10 * r20 + g11 * r21 + g12 * r22
    e02 = g00 * r20 + g01 * r21 + g02 * r22
    e20 = g20 * r00 + g21 * r01 + g22 * r02
    e10 = g10 * r00 + g11 * r01 + g12 * r02
    e01 = g00 * r10 + g01 * r11 + g02 * r12
    vx, vy, vz = e21 - e12, e02 - e20, e10 - e01  # 2 sin(t) axis
    s = 0.5 * math.sqrt(vx * vx + vy * vy + vz * vz)
    c = 0.5 * (e00 + e11 + e22 - 1.0)
    t = math.atan2(s, c)
    if t > _HALF_TURN:
        return None
    k = 0.5 + t * t / 12.0 if t < 1e-4 else 0.5 * t / s  # t / (2 sin t), its series near 0
    return (k * vx, k * vy, k * vz)


def _step(cols: list, e: list, pull: list, lam: float) -> list:
    """dq = J^T (J J^T + lambda I)^-1 (e - J pull) + pull (n floats): the minimum-norm step of the module
    docstring (2) for the Jacobian's columns ``cols`` (n tuples of the task's k rows) and the seed's pull.
    The (k, k) system by LAPACK: a 6 x 6 solve in Python floats cost three times numpy's call overhead."""
    J = np.array(cols).T[: len(e)]
    p = np.array(pull)
    A = J @ J.T
    A.flat[:: len(e) + 1] += lam
    return (J.T @ np.linalg.solve(A, np.array(e) - J @ p) + p).tolist()


class Corrector:
    """Joint commands for a stream of goals, one goal at a time (module docstring).

    Parameters
    ----------
    robot : Robot (:func:`solver.control.robot.load_model`: the calibrated model, its nominal and options),
        or the path or built-in name ``load_model`` takes
    tool : the tool (see :mod:`solver.control.robot`; default the flange)
    q0 : (n,) array, rad, optional: the first warm start (the robot's measured joints); default the model's
        home, else the middle of the limits

    Attributes
    ----------
    last : Step, how the last goal went
    """

    def __init__(self, robot, tool=None, q0=None):
        if isinstance(robot, str | Path):
            from lasercal.solver.control.robot import load_model

            robot = load_model(robot)
        model = robot.model
        if model.is_tree:
            raise ModelError(
                f"{model.name!r}: the corrector takes a serial chain (use Robot.correct for a tree)"
            )
        self.robot, self.tool = robot, robot.tool(tool)
        opts = robot.options
        self._L, self._lam0 = opts.length_mm, opts.damping
        self._lo = [float(v) + opts.margin for v in model.limits[:, 0]]
        self._hi = [float(v) - opts.margin for v in model.limits[:, 1]]
        self._M = robot.tool_frame(self.tool)
        self._cal = _Chain(model.screws, self._M)
        # the effects' torques from the fit's gravity model (Robot.gravity: the nominal's links), as correct's
        grav = robot.gravity
        self._grav = _Chain(grav.screws, self._M, _bodies(grav, robot.extension))
        self._nom = _Chain(robot.nominal.screws, robot.tool_frame(self.tool, nominal=True))
        self._effect = _linear_effect(model, robot.extension)
        self._check(model)
        self.last = Step()
        self.reset(q0)

    def reset(self, q=None) -> None:
        """Warm-start the next goal from the joint command q (n,) rad (default: home, or mid-limits)."""
        if q is None:
            q = (
                self.robot.model.home
                if self.robot.model.home is not None
                else self.robot.model.limits.mean(1)
            )
        q = np.asarray(q, dtype=float).ravel()
        if q.shape != (self._cal.n,) or not np.all(np.isfinite(q)):
            raise FormatError("q0", f"a warm start is {self._cal.n} finite joint angles (rad), got {q.shape}")
        self._q = [float(v) for v in q]
        self._dq = self._effect_dq(self._q) if self._effect else [0.0] * self._cal.n
        self._qt = self._qt_prev = [a + b for a, b in zip(self._q, self._dq)]

    def __call__(self, goal) -> np.ndarray:
        """The joint command (n,) rad for one goal: a (4, 4) frame, a (6,) pose (mm, rotation vector rad)
        or a (3,) position (mm), base frame, for the tool; warm-started from the previous command."""
        pg, Rg = _goal(goal)
        # from where the last tick's motion carries the true angles (module docstring, 2)
        start = [a + a - b for a, b in zip(self._qt, self._qt_prev)]
        q = self._solve(pg, Rg, start)
        return self._fallback(goal) if q is None else np.array(q)

    def nominal_pose(self, q=None) -> np.ndarray:
        """The nominal model's tool frame (4, 4) mm at the command q (default the last): the Cartesian command
        for a controller that keeps the nominal model."""
        R, p, *_ = self._nom.run(self._q if q is None else [float(v) for v in np.ravel(q)])
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = np.reshape(R, (3, 3)), p
        return T

    # ------------------------------------------------------------------ the steps
    def _solve(self, pg: tuple, Rg: tuple | None, start: list) -> list | None:
        """The command for a goal: Newton steps from ``start`` (true angles), the effects, the limit passes
        (module docstring, 2-4); None when the steps do not reach it."""
        dq, shift = self._dq, [0.0] * self._cal.n
        for _ in range(_LIMIT_PASSES):
            lo, hi = [a + b for a, b in zip(self._lo, shift)], [a + b for a, b in zip(self._hi, shift)]
            qt = self._newton(pg, Rg, start, lo, hi)
            if qt is None:
                return None
            if self._effect:  # q_cmd = q_true - dq(q_cmd) from the previous correction (docstring, 4)
                for _ in range(_EFFECT_PASSES):
                    dq = self._effect_dq([a - b for a, b in zip(qt, dq)])
            q = [a - b for a, b in zip(qt, dq)]
            if not any(v < a - _LIMIT_TOL or v > b + _LIMIT_TOL for v, a, b in zip(q, self._lo, self._hi)):
                self._q, self._qt_prev, self._qt, self._dq = q, self._qt, qt, dq
                return q
            start, shift = qt, dq  # as correct: solved again with the bounds of q_true moved by dq (3)
        return None

    def _newton(self, pg: tuple, Rg: tuple | None, start: list, lo: list, hi: list) -> list | None:
        """The true angles in [lo, hi] reaching the goal, from ``start`` (module docstring, 2), or None."""
        chain, L, n = self._cal, self._L, self._cal.n
        seed = self._q  # correct's seed: the previous command
        q = [min(max(v, a), b) for v, a, b in zip(start, lo, hi)]
        pulled, k, last = True, 0, MAX_STEPS
        while k < last:
            R, p, zs, os_, _ = chain.run(q)
            e = [pg[0] - p[0], pg[1] - p[1], pg[2] - p[2]]
            cols = []
            for (zx, zy, zz), (ox, oy, oz), slide in zip(zs, os_, chain.prismatic):
                if slide:
                    cols.append((zx, zy, zz, 0.0, 0.0, 0.0))
                else:
                    dx, dy, dz = p[0] - ox, p[1] - oy, p[2] - oz
                    cols.append(
                        (zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx, L * zx, L * zy, L * zz)
                    )
            if Rg is not None:
                w = _log_rotation(Rg, R)
                if w is None:
                    return None
                e += [L * w[0], L * w[1], L * w[2]]
            err2 = sum(map(mul, e, e))
            near = pulled and err2 < 1.0  # ik's pull_within_mm = 1
            pull = [s - v for s, v in zip(seed, q)] if near else [0.0] * n
            lam = 0.5 * err2 + self._lam0
            dq = _step(cols, e, pull, lam)
            # a joint on a bound whose step points outside leaves the Jacobian and the pull (docstring, 3)
            blocked = [(v <= a and d < 0) or (v >= b and d > 0) for v, d, a, b in zip(q, dq, lo, hi)]
            if any(blocked):
                zero = (0.0,) * len(cols[0])
                cols = [zero if bl else c for c, bl in zip(cols, blocked)]
                dq = _step(cols, e, [0.0 if bl else v for v, bl in zip(pull, blocked)], lam)
                dq = [0.0 if bl else v for v, bl in zip(dq, blocked)]
            big = max(abs(v) for v in dq)
            if big > 0.5:  # ik's max_step
                dq = [v * 0.5 / big for v in dq]
            q = [min(max(v + d, a), b) for v, d, a, b in zip(q, dq, lo, hi)]
            k += 1
            if big < STEP_TOL:
                rows = list(zip(*cols))[: len(e)]  # the linear model's error after the step: ~0 at the goal
                if sum((ei - sum(map(mul, r, dq))) ** 2 for ei, r in zip(e, rows)) < _REACH_TOL**2:
                    self.last = Step(k, big)
                    return q
                if not pulled:
                    return None
                # a least-squares point short of the goal, joints the pull held on their bounds: ik's polish,
                # steps of the task alone, in which they may leave them (docstring, 3)
                pulled, last = False, k + MAX_STEPS
        return None

    def _fallback(self, goal) -> np.ndarray:
        """The goal by the full solver (Robot.ik), seeded by the previous command."""
        c = self.robot.ik(np.asarray(goal, dtype=float)[None], seed=np.array(self._q), tool=self.tool)
        q = [float(v) for v in c.q[0]]
        self.last = Step(0, 0.0, True, bool(c.ok[0]), c.reason[0])
        if c.ok[0]:
            self._q = q
            self._dq = self._effect_dq(q) if self._effect else [0.0] * self._cal.n
            self._qt = self._qt_prev = [a + b for a, b in zip(q, self._dq)]
        return np.array(q)

    def _effect_dq(self, q: list) -> list:
        kc, ka, kb = self._effect
        tau = self._grav.torques(q) if any(kc) else [0.0] * len(q)
        return [c * t + a * math.sin(v) + b * math.cos(v) for c, t, a, b, v in zip(kc, tau, ka, kb, q)]

    def _check(self, model) -> None:
        """The chain and the effects reproduce lasercal's own (tool_frames, true_angles) at a few
        configurations: a model they cannot represent is refused, never commanded wrongly."""
        rng = np.random.default_rng(0)
        for q in rng.uniform(model.limits[:, 0], model.limits[:, 1], (3, self._cal.n)):
            T = tool_frames(model.screws, self._M, q[None])[0][0]
            R, p, *_ = self._cal.run(list(q))
            if (
                np.abs(np.reshape(R, (3, 3)) - T[:3, :3]).max() > _CHECK_TOL
                or np.abs(p - T[:3, 3]).max() > 1e-6
            ):
                raise ModelError(f"{model.name!r}: the corrector's chain does not reproduce the model")
            if self._effect:
                want = true_angles(model, self.robot.extension, q[None], self.robot.gravity)[0] - q
                if np.abs(np.array(self._effect_dq(list(q))) - want).max() > _CHECK_TOL:
                    raise ModelError(
                        f"{model.name!r}: the corrector applies a compliance and an eccentricity; the "
                        f"model's {self.robot.extension.effect} is not one it can apply (use Robot.correct)"
                    )


def _bodies(model, ext) -> list:
    """Gravity bodies (joint, mass kg, centre of mass at q = 0 mm) as :func:`gravity.model_torques` takes
    them: the model's links, else a 1 kg load at the wrist centre; none without a compliance."""
    if ext is None or not any(p.effect.endswith("compliance") for p in ext.parts):
        return []
    if model.links:
        return [(j, lk.mass, np.asarray(lk.com, float)) for j, lk in enumerate(model.links)]
    return [(model.n - 1, 1.0, wrist_centre(model))]


def _linear_effect(model, ext) -> tuple | None:
    """(kc, ka, kb), n floats each: dq = kc tau + ka sin q + kb cos q, the model's compliance and eccentricity
    (:mod:`solver.kinematics.effects`); None without an effect."""
    if ext is None:
        return None
    kc, ka, kb = ([0.0] * model.n for _ in range(3))
    for part in ext.parts:
        per = 2 if part.effect == "encoder_eccentricity" else 1
        for k, j in enumerate(part.joints):
            vals = part.params[per * k : per * (k + 1)]
            if part.effect == "joint_compliance":
                kc[j - 1] += float(vals[0])
            elif part.effect == "encoder_eccentricity":
                ka[j - 1] += float(vals[0])
                kb[j - 1] += float(vals[1])
    return kc, ka, kb


def _goal(goal) -> tuple:
    """(position (3 floats) mm, rotation (9 floats, row by row) or None) of a (4, 4), (6,) or (3,) goal."""
    g = np.asarray(goal, dtype=float)
    if g.shape == (4, 4):
        return tuple(g[:3, 3].tolist()), tuple(g[:3, :3].ravel().tolist())
    if g.shape == (3,):
        return tuple(g.tolist()), None
    if g.shape == (6,):
        x, y, z, rx, ry, rz = g.tolist()
        t = math.sqrt(rx * rx + ry * ry + rz * rz)
        if t < 1e-12:
            return (x, y, z), (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
        kx, ky, kz = rx / t, ry / t, rz / t
        c, s = math.cos(t), math.sin(t)
        v = 1.0 - c  # Rodrigues (Modern Robotics eq. 3.51)
        R = (
            c + kx * kx * v, kx * ky * v - kz * s, kx * kz * v + ky * s,
            ky * kx * v + kz * s, c + ky * ky * v, ky * kz * v - kx * s,
            kz * kx * v - ky * s, kz * ky * v + kx * s, c + kz * kz * v,
        )  # fmt: skip
        return (x, y, z), R
    raise FormatError("goal", f"a goal is a (4, 4) frame, a (6,) pose or a (3,) position, not {g.shape}")

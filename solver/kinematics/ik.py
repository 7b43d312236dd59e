"""Inverse kinematics of a POE chain, vectorised over goals: where must the joints go to put a tool at a goal.

Task. The tool frame T(q) = e^[S1]q1 ... e^[Sn]qn M (Modern Robotics eq. 4.14) must reach a goal
position p_g (a 3-task) or a goal pose (p_g, R_g) (a 6-task). The error is measured in the base
frame: e_p = p_g - p(q) (mm) and e_w = log(R_g R(q)^T) (rad, the rotation vector of the space-frame
rotation still to go, eq. 3.60), stacked as e = (e_p, L e_w) with L = ``length_mm`` mm per rad so
that a millimetre and a milliradian at the end of a 1 m arm weigh alike.

Jacobian. With the space Jacobian columns (w_j, v_j) = Ad(e^[S1]q1...e^[S(j-1)]q(j-1)) S_j
(eq. 5.11), the tool point moves by dp/dq_j = w_j x p + v_j and the frame turns by w_j: J = (w x p
+ v ; L w), exact for the error above to first order.

Step. Damped least squares in Levenberg-Marquardt form with the error-dependent damping of
Sugihara (2011): dq_task = J^T (J J^T + lambda I)^-1 e, lambda = |e|^2 / 2 + lambda_0, so that far
from the goal the step shortens and near it the iteration is Gauss-Newton (quadratic). Redundancy
(n > task) is resolved towards the seed q_s by the null-space term of the minimum-norm solution of
J (q' - q_s) = e + J (q - q_s): dq = dq_task + (I - J^+ J)(q_s - q) (eq. 6.7 with the pseudoinverse
J^+ = J^T (J J^T)^-1), whose fixed point is the solution nearest the seed (a stationary point of
|q - q_s| on the set of solutions). The seed pulls once the task error is below ``pull_within_mm``
(further away it would fight the way to the goal); within ``max_pull`` of the seed the null-space step
is taken whole, further away halved and shortened to ``max_pull`` (whole steps there overshoot along
the curved set of solutions and cycle). A goal still missed after ``iterations`` steps is polished by
steps of the task alone. Without a seed to prefer (``pull=False``) the seed is only the start. A step
is shortened to at most ``max_step`` rad per joint.

Limits. Each joint is kept in [lo + margin, hi - margin] (bounds may differ per goal): after every
step the configuration is clamped into the box, and a joint on its bound whose step points outside
is taken out of the Jacobian and of the null-space pull for the next step (an active set, the
clamping method of Raunhardt and Boulic 2007), so the other joints take over its share.

Restarts. A goal not reached after ``iterations`` steps is tried again from random in-limit
configurations (``restarts`` times, a seeded generator); the best try is kept and reported.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from lasercal.solver.kinematics.poe import skew
from lasercal.solver.streams import stream


@dataclass(frozen=True)
class IKOptions:
    """How the inverse kinematics iterates and when it stops.

    Attributes
    ----------
    margin : float, distance kept from every joint limit, rad (mm for a prismatic joint)
    tol_mm : float, position error at which a goal is reached, mm
    tol_rad : float, orientation error at which a goal is reached, rad
    iterations : int, steps per start
    restarts : int, further starts from random in-limit configurations for goals not reached
    length_mm : float, mm per rad weighing the orientation error against the position error
    damping : float, lambda_0 of the damping, mm^2
    max_step : float, largest joint change of one step, rad
    pull_within_mm : float, task error below which the seed pulls the redundant joints, mm
    max_pull : float, largest joint change of the seed's pull in one step, rad
    seed : int, seed of the random restarts
    """

    margin: float = 0.01
    tol_mm: float = 1e-7
    tol_rad: float = 1e-9
    iterations: int = 60
    restarts: int = 8
    length_mm: float = 100.0
    damping: float = 1e-10
    max_step: float = 0.5
    pull_within_mm: float = 1.0
    max_pull: float = 0.1
    seed: int = 0


DEFAULT_IK = IKOptions()


@dataclass(frozen=True, eq=False)
class IKSolution:
    """Configurations reaching the goals, and how well.

    Attributes
    ----------
    q : (m, n) array, rad (mm for prismatic joints), inside the bounds
    error_mm : (m,) array, position error left, mm
    error_rad : (m,) array, orientation error left, rad (zeros for position goals)
    reached : (m,) bool array, both errors within the tolerances
    at_bound : (m, n) bool array, joints on a bound of the box
    starts : (m,) int array, starts used (1 = the seed was enough)
    """

    q: np.ndarray
    error_mm: np.ndarray
    error_rad: np.ndarray
    reached: np.ndarray
    at_bound: np.ndarray
    starts: np.ndarray

    def with_rows(self, idx: np.ndarray, other: IKSolution) -> IKSolution:
        """This solution with the goals ``idx`` taken from ``other`` (a solution of those goals alone)."""
        parts = {}
        for f in dataclasses.fields(self):
            a = np.array(getattr(self, f.name))
            a[idx] = getattr(other, f.name)
            parts[f.name] = a
        return IKSolution(**parts)


def tool_frames(screws: np.ndarray, M: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tool frames T(q) = e^[S1]q1 ... e^[Sn]qn M (eq. 4.14) and the space Jacobian (eq. 5.11).

    The same products as :func:`solver.kinematics.poe.poe_chain`, specialised to joint screws with a unit
    or a zero omega (what a RobotModel holds), so that each exponential is Rodrigues' formula with the
    joint's [w] and [w]^2 computed once: R = I + sin q [w] + (1 - cos q)[w]^2 (eq. 3.51) and
    p = (I q + (1 - cos q)[w] + (q - sin q)[w]^2) v (eq. 3.88). The inverse kinematics evaluates them
    at every step for every goal.

    Parameters
    ----------
    screws : (n, 6) array, joint screws (omega, v) in the base frame at q = 0, |omega| = 1 or 0, mm
    M : (4, 4) array, the tool frame at q = 0, mm
    q : (m, n) array, rad (mm for prismatic joints)

    Returns
    -------
    T : (m, 4, 4) array, mm
    J : (m, 6, n) array, columns (w_j, v_j) of the joints' current screws
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m, n = q.shape
    w, v = screws[:, :3], screws[:, 3:]
    W = skew(w)
    W2 = W @ W
    Wv, W2v = np.einsum("nij,nj->ni", W, v), np.einsum("nij,nj->ni", W2, v)
    s, c = np.sin(q), np.cos(q)
    Rj = np.eye(3) + s[..., None, None] * W + (1 - c)[..., None, None] * W2  # (m, n, 3, 3)
    pj = q[..., None] * v + (1 - c)[..., None] * Wv + (q - s)[..., None] * W2v  # (m, n, 3)
    R, p = np.broadcast_to(np.eye(3), (m, 3, 3)), np.zeros((m, 3))
    J = np.empty((m, 6, n))
    for j in range(n):  # prefix products, vectorised over the goals
        J[:, :3, j] = R @ w[j]
        J[:, 3:, j] = R @ v[j] + np.cross(p, J[:, :3, j])  # Ad of the prefix applied to S_j
        p = p + np.einsum("mij,mj->mi", R, pj[:, j])
        R = R @ Rj[:, j]
    T = np.zeros((m, 4, 4))
    T[:, :3, :3] = R @ M[:3, :3]
    T[:, :3, 3] = R @ M[:3, 3] + p
    T[:, 3, 3] = 1.0
    return T, J


def rotation_error(R_goal: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The rotation vector (m, 3) rad of R_goal R^T: the space-frame rotation from R to R_goal (eq. 3.60)."""
    from scipy.spatial.transform import Rotation  # loaded on use: slow to import at start-up

    return Rotation.from_matrix(R_goal @ np.swapaxes(R, 1, 2)).as_rotvec()


def _errors(T, J, p_goal, R_goal, L) -> tuple[np.ndarray, np.ndarray]:
    """Task error e (m, k) and task Jacobian (m, k, n) of the module docstring (k = 3 or 6)."""
    p = T[:, :3, 3]
    w, v = J[:, :3], J[:, 3:]
    Jp = np.cross(w, p[:, :, None], axis=1) + v  # dp/dq_j = w_j x p + v_j
    e = p_goal - p
    if R_goal is None:
        return e, Jp
    return np.concatenate([e, L * rotation_error(R_goal, T[:, :3, :3])], axis=1), np.concatenate(
        [Jp, L * w], axis=1
    )


def _step(J, e, pull, lam, max_pull: float) -> np.ndarray:
    """Damped task step plus the seed pull projected on the null space: dq (m, n) (module docstring).

    One factorisation serves both: (J J^T + lambda I) in place of J J^T in the projector leaks a share
    lambda / sigma^2 of the pull into the task, nothing once lambda has fallen to lambda_0 at the goal.
    Further than ``max_pull`` from the seed, the projected pull is halved and shortened to ``max_pull`` per
    joint (shortening the raw pull instead would stall: far from the seed it lies mostly along the task).
    """
    Jt = np.swapaxes(J, 1, 2)
    A = J @ Jt + lam[:, None, None] * np.eye(J.shape[1])
    rhs = np.stack([e, np.einsum("mkn,mn->mk", J, pull)], axis=2)  # (m, k, 2)
    x = np.linalg.solve(A, rhs)
    null = pull - np.einsum("mnk,mk->mn", Jt, x[..., 1])
    # full steps near the seed (Gauss-Newton: the solution set's curvature times the distance to the seed
    # is small), half steps further away, where full ones overshoot along the curved set and cycle
    far = np.abs(pull).max(axis=1, keepdims=True) > max_pull
    big = np.abs(null).max(axis=1, keepdims=True)
    null = null * np.where(far, np.minimum(0.5, max_pull / np.maximum(big, 1e-300)), 1.0)
    return np.einsum("mnk,mk->mn", Jt, x[..., 0]) + null


def _iterate(screws, M, q, q_seed, p_goal, R_goal, lo, hi, opts: IKOptions, pull_seed: bool = True):
    """Steps from q (m, n) until every goal is reached or ``opts.iterations`` have been taken; without
    ``pull_seed`` the task alone (a polish onto the goal)."""
    L = opts.length_mm
    active = np.arange(len(q))
    for _ in range(opts.iterations):
        if not len(active):
            break
        qa = q[active]
        T, J = tool_frames(screws, M, qa)
        Rg = None if R_goal is None else R_goal[active]
        e, Jt = _errors(T, J, p_goal[active], Rg, L)
        ep = np.linalg.norm(e[:, :3], axis=1)
        ew = np.linalg.norm(e[:, 3:], axis=1) / L if Rg is not None else np.zeros(len(e))
        # the seed pulls only near the goal: far from it, it would fight the way there
        near = (np.linalg.norm(e, axis=1) < opts.pull_within_mm) & pull_seed
        pull = (q_seed[active] - qa) * near[:, None]
        lam = 0.5 * np.sum(e**2, axis=1) + opts.damping
        dq = _step(Jt, e, pull, lam, opts.max_pull)
        # joints on a bound whose step points outside leave the Jacobian and the pull (active set)
        blocked = ((qa <= lo[active]) & (dq < 0)) | ((qa >= hi[active]) & (dq > 0))
        if blocked.any():
            free = ~blocked
            dq = _step(Jt * free[:, None, :], e, pull * free, lam, opts.max_pull) * free
        done = (ep < opts.tol_mm) & (ew < opts.tol_rad) & (np.abs(dq).max(axis=1) < 1e-9)
        big = np.abs(dq).max(axis=1, keepdims=True)
        dq = dq * np.minimum(1.0, opts.max_step / np.maximum(big, 1e-300))
        q[active] = np.clip(qa + dq, lo[active], hi[active])
        active = active[~done]
    return q


def _start(screws, M, q0, q_seed, p_goal, R_goal, lo, hi, opts: IKOptions, pull: bool) -> np.ndarray:
    """One start: steps (with the seed's pull), then a polish of the task alone for goals not yet reached."""
    q = _iterate(screws, M, q0, q_seed, p_goal, R_goal, lo, hi, opts, pull)
    ep, ew = _measure(screws, M, q, p_goal, R_goal)
    todo = np.flatnonzero((ep >= opts.tol_mm) | (ew >= opts.tol_rad))
    if len(todo):
        Rg = None if R_goal is None else R_goal[todo]
        q[todo] = _iterate(
            screws, M, q[todo], q_seed[todo], p_goal[todo], Rg, lo[todo], hi[todo], opts, pull_seed=False
        )
    return q


def _measure(screws, M, q, p_goal, R_goal) -> tuple[np.ndarray, np.ndarray]:
    """Position error (m,) mm and orientation error (m,) rad of the tool at q."""
    T = tool_frames(screws, M, q)[0]
    ep = np.linalg.norm(p_goal - T[:, :3, 3], axis=1)
    if R_goal is None:
        return ep, np.zeros(len(q))
    return ep, np.linalg.norm(rotation_error(R_goal, T[:, :3, :3]), axis=1)


def solve_ik(
    screws: np.ndarray,
    M: np.ndarray,
    limits: np.ndarray,
    q_seed: np.ndarray,
    p_goal: np.ndarray,
    R_goal: np.ndarray | None = None,
    opts: IKOptions = DEFAULT_IK,
    bounds: tuple[np.ndarray, np.ndarray] | None = None,
    pull: bool = True,
    start: np.ndarray | None = None,
) -> IKSolution:
    """Configurations putting the tool at each goal, nearest the seed, within the limits (module docstring).

    Parameters
    ----------
    screws : (n, 6) array, joint screws in the base frame at q = 0, mm
    M : (4, 4) array, the tool frame at q = 0, mm
    limits : (n, 2) array, joint limits, rad (mm)
    q_seed : (m, n) array, where each goal's search starts and which solution it prefers, rad
    p_goal : (m, 3) array, goal positions, mm, base frame
    R_goal : (m, 3, 3) array or None, goal orientations (None: position goals)
    opts : IKOptions
    bounds : (lo, hi) arrays broadcastable to (m, n), optional, in place of limits +- margin
    pull : bool, the seed pulls the redundant joints (False: the seed is only where the search starts)
    start : (m, n) array, optional, where the first start begins (default the seed)

    Returns
    -------
    IKSolution
    """
    p_goal = np.atleast_2d(np.asarray(p_goal, dtype=float))
    m, n = len(p_goal), screws.shape[0]
    if bounds is None:
        bounds = (limits[:, 0] + opts.margin, limits[:, 1] - opts.margin)
    lo, hi = (np.broadcast_to(np.asarray(b, dtype=float), (m, n)) for b in bounds)
    q_seed = np.broadcast_to(np.asarray(q_seed, dtype=float), (m, n))
    q0 = q_seed if start is None else np.asarray(start, dtype=float)
    q = _start(screws, M, np.clip(q0, lo, hi), q_seed, p_goal, R_goal, lo, hi, opts, pull)
    ep, ew = _measure(screws, M, q, p_goal, R_goal)
    reached = (ep < opts.tol_mm) & (ew < opts.tol_rad)
    starts = np.ones(m, dtype=int)
    for restart in range(opts.restarts):
        todo = np.flatnonzero(~reached)
        if not len(todo):
            break
        starts[todo] += 1
        # every goal's start drawn, used or not: which goals a restart takes cannot shift the draws of others
        q0 = stream(opts.seed, "restart", restart).uniform(lo, hi)[todo]
        Rg = None if R_goal is None else R_goal[todo]
        qt = _start(screws, M, q0, q_seed[todo], p_goal[todo], Rg, lo[todo], hi[todo], opts, pull)
        et, wt = _measure(screws, M, qt, p_goal[todo], Rg)
        L2 = opts.length_mm**2  # the task's own measure of a miss: |e_p|^2 + L^2 |e_w|^2
        better = et**2 + L2 * wt**2 < ep[todo] ** 2 + L2 * ew[todo] ** 2
        idx = todo[better]
        q[idx], ep[idx], ew[idx] = qt[better], et[better], wt[better]
        reached = (ep < opts.tol_mm) & (ew < opts.tol_rad)
    at_bound = (q <= lo + 1e-12) | (q >= hi - 1e-12)
    return IKSolution(q, ep, ew, reached, at_bound, starts)

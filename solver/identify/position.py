"""Position measurements: targets on the tool measured in a 3-D sensor's frame (tracker, mocap, CMM).

Model (thesis eq. 3.1.4 seen from the sensor): y = X (E(q) p_k), E(q) = e^[S1]q1 ... e^[Sn]qn,
X = ^S T_base the base frame in the sensor's frame, p_k target k on the last link at q = 0
(base frame, mm). Unknowns: the joint screws (minimal POE, eta of 4 per revolute and 2 per
prismatic joint), X (6, perturbed on the left: X = e^[xi] X_0) and each target (3).

Residual per capture (mm, sensor frame): r = X E(q) p_k - y, divided by the row's sigma
over the median sigma when the captures carry one (maximum likelihood with per-row noise).
Jacobian: joint eta columns R_X (w_j x p + v_j) of the perturbed screw's space twist
(eq. 3.1.6), xi columns [-[y_hat], I], target columns R_X R_E(q).

Gauge. A rigid motion G of the base frame (screws Ad_G S, targets G p, X G^-1) leaves every
measurement unchanged: 6 unobservable directions. They are fixed by holding joint
parameters at nominal, in joint order, as long as each adds a gauge direction it pins
(:func:`gauge_holds`): a revolute joint 1's four parameters and two of joint 2's, as for
point sessions -- the base frame is the nominal's, defined by its first joints (the
sensor frame and the targets carry the rest). What the data cannot see beyond that is left
to the SVD of :func:`solver.identify.lsq.fit_subspace` and reported.

Start. Nominal screws; X and the targets from the closed-form alternation of
:func:`start_frame`: the similarity (Umeyama) fit of nominal points to measured points,
then the targets by linear least squares, repeated. Its scale tells mm from metres.
"""

from __future__ import annotations

import time

import numpy as np

from lasercal.solver.errors import FormatError, IdentificationError
from lasercal.solver.formats.session import Session
from lasercal.solver.identify.lsq import fit_subspace
from lasercal.solver.identify.prior import make_prior
from lasercal.solver.identify.spot import Identification
from lasercal.solver.kinematics.effects import Extension, require
from lasercal.solver.kinematics.minimal import anchor_heights, link_frame, screw_from_eta
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import ad, dexp_A, dexp_apply, exp6, poe_chain, skew
from lasercal.solver.kinematics.tree import branch_groups, parents_of, target_joint

_START_ITERS = 1000  # most alternations of the closed-form start (they stop once the scale settles)
_START_TOL = 1e-7  # change of the similarity scale per alternation below which the start has settled
SCALE_TOL = 0.05  # a best similarity scale further than this from 1: the units do not match the robot's


# ----------------------------------------------------------------------------- the forward model
def sensor_points(
    model: RobotModel,
    q: np.ndarray,
    names: np.ndarray,
    targets: dict | None = None,
    X: np.ndarray | None = None,
    groups: list | None = None,
) -> np.ndarray:
    """Predicted sensor-frame positions y = X E(q) p_k (m, 3) mm.

    Parameters
    ----------
    model : RobotModel with ``targets`` and ``sensor_pose`` (or give them)
    q : (m, n) array, rad (mm for prismatic joints)
    names : (m,) array of str, the target of each row
    targets : dict name -> (3,) mm at q = 0, base frame (default: the model's)
    X : (4, 4) array, ^S T_base (default: the model's)
    groups : the rows' branches (:func:`~lasercal.solver.kinematics.tree.branch_groups`; default: from names)
    """
    targets = model.targets if targets is None else targets
    X = model.sensor_pose if X is None else X
    E = target_frames(model, q, names, groups)
    P = np.array([targets[nm] for nm in names]).reshape(-1, 3)
    p = np.einsum("mij,mj->mi", E[:, :3, :3], P) + E[:, :3, 3]
    return p @ X[:3, :3].T + X[:3, 3]


def branch_chains(screws: np.ndarray, q: np.ndarray, groups: list) -> tuple[np.ndarray, np.ndarray]:
    """Each row's prefix frames along its branch and its target's link frame (eq. T1, Modern Robotics 4.14).

    Parameters
    ----------
    screws : (n, 6) array
    q : (m, n) array, rad (mm for prismatic joints)
    groups : list of (rows, path) (:func:`~lasercal.solver.kinematics.tree.branch_groups`)

    Returns
    -------
    before : (m, n, 4, 4) array, e^[S_a]q_a ... up to (not including) joint j along the row's path; 0 for a
        joint off the path (it moves nothing of that row)
    E : (m, 4, 4) array, the product along the whole path
    """
    m, n = q.shape
    before = np.zeros((m, n, 4, 4))
    E = np.empty((m, 4, 4))
    for rows, path in groups:  # one serial chain per branch (a serial arm: one)
        chain = poe_chain(screws[path], q[np.ix_(rows, path)])
        before[np.ix_(rows, path)] = chain[:, :-1]
        E[rows] = chain[:, -1]
    return before, E


def twist_point_rates(before: np.ndarray, p: np.ndarray, U: np.ndarray) -> np.ndarray:
    """d(point)/d(t) for twists U applied at each joint: Ad(before_j) U_j acting on the point p.

    With (w, v) = Ad(T) u, T = (R, o): w = R u_w, v = o x w + R u_v (eq. 2.1.11), so the point moves by
    w x p + v = w x (p - o) + R u_v -- no 6x6 adjoints formed.

    Parameters
    ----------
    before : (m, n, 4, 4) array, :func:`branch_chains` (0 off a row's path: zero rates)
    p : (m, 3) array, the points, base frame, mm
    U : (m, n, 6, k) or (n, 6, k) array, twists at q = 0 in the base frame, per joint

    Returns
    -------
    (m, 3, n, k) array
    """
    R, o = before[:, :, :3, :3], before[:, :, :3, 3]
    w, v = R @ U[..., :3, :], R @ U[..., 3:, :]  # (m, n, 3, k)
    r = p[:, None, :] - o  # (m, n, 3)
    rx, ry, rz = (r[:, :, i, None] for i in range(3))
    wx, wy, wz = w[:, :, 0], w[:, :, 1], w[:, :, 2]
    # w x r + v, the cross product written out (np.cross on these shapes cost more than the rest)
    return np.stack([wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx], axis=1) + np.moveaxis(v, 2, 1)


def target_frames(model: RobotModel, q: np.ndarray, names, groups: list | None = None) -> np.ndarray:
    """E(q) (m, 4, 4) of the link each row's target sits on: the POE product along its branch
    (:mod:`solver.kinematics.tree`, eq. T1; the whole chain for a serial arm)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    groups = branch_groups(model, names) if groups is None else groups
    E = np.empty((len(q), 4, 4))
    for rows, path in groups:
        E[rows] = poe_chain(model.screws[path], q[np.ix_(rows, path)])[:, -1]
    return E


def point_joint_jacobian(
    model: RobotModel, q: np.ndarray, P: np.ndarray, names=None, groups: list | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Base-frame points E(q) p (m, 3) of row targets P (m, 3), and d(point)/dq (m, 3, n): w_j x p + v_j
    (0 for a joint off the row's branch; ``names`` the rows' targets, needed for a tree)."""
    q = np.atleast_2d(q)
    if groups is None:
        groups = [(np.arange(len(q)), np.arange(model.n))] if names is None else branch_groups(model, names)
    before, E = branch_chains(model.screws, q, groups)
    p = np.einsum("mij,mj->mi", E[:, :3, :3], P) + E[:, :3, 3]
    return p, twist_point_rates(before, p, model.screws[:, :, None])[..., 0]


# ----------------------------------------------------------------------------- closed-form start
def umeyama(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Similarity b ~ s R a + t minimising the squared distances (Umeyama 1991, eqs. 40-42).

    Parameters
    ----------
    a, b : (m, 3) arrays

    Returns
    -------
    s : float, R : (3, 3) array, t : (3,) array
    """
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    A, B = a - ma, b - mb
    U, d, Vt = np.linalg.svd(B.T @ A / len(a))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    s = float(np.trace(np.diag(d) @ D) / np.mean(np.sum(A**2, axis=1)))
    return s, R, mb - s * R @ ma


def start_frame(
    model: RobotModel, q: np.ndarray, y: np.ndarray, names: np.ndarray, targets0: dict, path="captures.csv"
) -> tuple[np.ndarray, dict]:
    """Closed-form start: X (4, 4) and the targets (dict of (3,) mm), alternating (1) the Umeyama
    similarity of nominal points E(q) p_k to the measured y and (2) the targets by linear least
    squares s R_X R_E p_k = y - s R_X t_E - t_X, until s settles (a target far from its start, e.g. a
    camera 100 mm off the flange, takes a few hundred). Scale s far from 1 is a unit error and raises
    FormatError (metres are named as such).
    """
    E = target_frames(model, q, names)
    targets = {k: np.asarray(v, float) for k, v in targets0.items()}
    s_prev = np.inf
    for _ in range(_START_ITERS):
        P = np.array([targets[nm] for nm in names])
        p = np.einsum("mij,mj->mi", E[:, :3, :3], P) + E[:, :3, 3]
        s, R, t = umeyama(p, y)
        if abs(s - s_prev) < _START_TOL:
            break
        s_prev = s
        for nm in targets:
            sel = names == nm
            A = (s * R @ E[sel, :3, :3]).reshape(-1, 3)
            b = (y[sel] - (s * E[sel, :3, 3] @ R.T + t)).reshape(-1)
            targets[nm] = np.linalg.lstsq(A, b, rcond=None)[0]
    if abs(s - 1) > SCALE_TOL:
        hint = (
            "positions look like metres: x, y, z must be mm (multiply by 1000)"
            if 5e-4 < s < 2e-3
            else "positions do not match the robot's size: x, y, z must be mm in the sensor's frame"
        )
        rms = float(np.sqrt(np.mean(np.sum((p @ R.T + t - y) ** 2, axis=1))))
        raise FormatError(
            path,
            f"best scale from the robot to the measured points is {s:.4g} (residual {rms:.3g}): {hint}",
            field="x",
        )
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = R, t
    return X, targets


def target_start(model: RobotModel) -> np.ndarray:
    """A target's start at q = 0: the end-effector frame's origin, else the tool point, else the aperture."""
    if model.ee_pose is not None:
        return np.asarray(model.ee_pose)[:3, 3]
    return np.asarray(model.tool_point if model.tool_point is not None else model.aperture)


# ----------------------------------------------------------------------------- parameters
def eta_sizes(model: RobotModel) -> np.ndarray:
    """Minimal-POE parameters per joint: 2 for prismatic, 4 for revolute (thesis Section 2.2.2), 0 for a
    lateral axis (it stays where its joint's frame puts it: :mod:`solver.kinematics.tree`)."""
    return np.where(model.prismatic, 2, 4) * model.real


def gauge_holds(model: RobotModel) -> list[int]:
    """Joint parameters held at nominal to fix the base frame (module docstring): in joint order, each
    kept if it raises the rank of the gauge's effect on the held parameters, until rank 6."""
    sizes = eta_sizes(model)
    rows = []
    for S, k in zip(model.screws[sizes > 0], sizes[sizes > 0]):
        _, dS = screw_from_eta(link_frame(S), np.zeros(k))
        # d(eta)/d(xi) for the six base motions xi: dS = ad(xi) S
        rows.append(np.linalg.lstsq(dS, np.stack([ad(xi) @ S for xi in np.eye(6)], axis=1), rcond=None)[0])
    D = np.vstack(rows)
    held: list[int] = []
    for i in range(len(D)):
        if np.linalg.matrix_rank(D[held + [i]], tol=1e-9) > len(held):
            held.append(i)
        if len(held) == 6:
            break
    return held


class PositionParams:
    """Parameter vector [free joint etas, sensor xi (6), targets (3 each)] of a position model.

    Parameters
    ----------
    model : RobotModel, the reference (eta = 0)
    names : list of target names
    joints : bool, identify the joints (False: only the sensor frame and the targets, e.g. the nominal's)
    """

    def __init__(self, model: RobotModel, names: list, joints: bool = True):
        self.model = model
        self.frames = [link_frame(S) for S in model.screws]
        self.sizes = eta_sizes(model)
        self.start = np.r_[0, np.cumsum(self.sizes)]
        self.eta_joints = np.flatnonzero(self.sizes)
        # each free parameter's column among the rates of :meth:`jacobian` (4 per joint with parameters)
        eta_cols = np.array(
            [4 * k + c for k, i in enumerate(self.eta_joints) for c in range(self.sizes[i])], int
        )
        labels = {4: ("wx", "wy", "qx", "qy"), 2: ("vx", "vy"), 0: ()}
        all_names = [f"{jn}.{p}" for jn, k in zip(model.joint_names, self.sizes) for p in labels[k]]
        self.held = gauge_holds(model) if joints else list(range(len(all_names)))
        self.free = [i for i in range(len(all_names)) if i not in self.held]
        self.free_cols = eta_cols[self.free]
        self.held_names = [all_names[i] for i in self.held]
        self.targets = list(names)
        self.n_free = len(self.free)
        self.slice_xi = slice(self.n_free, self.n_free + 6)
        self.col = {nm: self.n_free + 6 + 3 * k for k, nm in enumerate(self.targets)}
        self.size = self.n_free + 6 + 3 * len(self.targets)
        self.names = (
            [all_names[i] for i in self.free]
            + [f"sensor.{c}" for c in ("wx", "wy", "wz", "vx", "vy", "vz")]
            + [f"{nm}.{c}" for nm in self.targets for c in "xyz"]
        )
        kinds = {4: ("axis", "axis", "offset", "offset"), 2: ("slide", "slide"), 0: ()}
        all_kinds = [kd for k in self.sizes for kd in kinds[k]]
        self.kinds = (
            [all_kinds[i] for i in self.free]
            + ["sensor_rot"] * 3
            + ["sensor_pos"] * 3
            + ["target"] * 3 * len(self.targets)
        )

    def geometry(self, x: np.ndarray, X0: np.ndarray):
        """Screws (n, 6), dS/deta (list of (6, k)), X (4, 4), targets dict at x."""
        eta = np.zeros(self.start[-1])
        eta[self.free] = x[: self.n_free]
        out = [
            screw_from_eta(T, eta[a:b]) if b > a else (S, np.zeros((6, 0)))
            for T, S, a, b in zip(self.frames, self.model.screws, self.start[:-1], self.start[1:])
        ]
        X = exp6(x[self.slice_xi]) @ X0
        return (
            np.array([o[0] for o in out]),
            [o[1] for o in out],
            X,
            {nm: x[c : c + 3] for nm, c in self.col.items()},
        )

    def to_model(self, x: np.ndarray, X0: np.ndarray, **changes) -> RobotModel:
        screws, _, X, tg = self.geometry(x, X0)
        return self.model.replace(screws=screws, sensor_pose=X, targets=tg, **changes)

    def jacobian(
        self, x: np.ndarray, X0: np.ndarray, q: np.ndarray, names: np.ndarray, groups=None, joints=()
    ):
        """Predicted y (m, 3), d(y)/dx (m, 3, size) (module docstring) and d(y)/dq (m, 3, len(joints)) of the
        given 0-based joints; ``groups`` the rows' branches (default: from ``names``)."""
        screws, dS, X, tg = self.geometry(x, X0)
        groups = branch_groups(self.model, names) if groups is None else groups
        before, E = branch_chains(screws, q, groups)
        P = np.array([tg[nm] for nm in names]).reshape(-1, 3)
        p = np.einsum("mij,mj->mi", E[:, :3, :3], P) + E[:, :3, 3]
        has = self.eta_joints  # joints without parameters (lateral axes) add no columns: skipped
        dSp = np.zeros((len(has), 6, 4))
        for k, i in enumerate(has):
            dSp[k, :, : dS[i].shape[1]] = dS[i]
        rates = twist_point_rates(before[:, has], p, dexp_apply(screws[has], q[:, has], dSp))
        R = X[:3, :3]
        y = p @ R.T + X[:3, 3]
        J = np.zeros((len(q), 3, self.size))
        J[:, :, : self.n_free] = R @ rates.reshape(len(q), 3, -1)[:, :, self.free_cols]
        # y = e^[xi] X0 p: d(y) = [A(xi) d(xi)] y, A the exponential's differential (eq. 2.3.26 at theta = 1),
        # exact away from xi = 0 too
        A = dexp_A(x[self.slice_xi], np.ones(1))[0]
        J[:, :, self.slice_xi] = (
            np.concatenate([-skew(y), np.broadcast_to(np.eye(3), (len(q), 3, 3))], axis=2) @ A
        )
        RE = R @ E[:, :3, :3]
        for nm, c in self.col.items():
            sel = names == nm
            J[sel, :, c : c + 3] = RE[sel]
        joints = np.asarray(joints, dtype=int)
        Jq = R @ twist_point_rates(before[:, joints], p, screws[joints, :, None])[..., 0]
        return y, J, Jq


# ----------------------------------------------------------------------------- identification
def target_anchor_heights(model: RobotModel, targets: dict) -> np.ndarray:
    """The joints' anchor heights (mm, :func:`~lasercal.solver.kinematics.minimal.anchor_heights`) of the
    prior: a serial arm's next to its target start; a tree's along each branch, a branch's last joint
    next to the targets on it (``targets``: name -> (3,) mm at q = 0, base frame)."""
    if not model.parents:
        return anchor_heights(model.screws, target_start(model))
    par, real = parents_of(model), model.real
    ends: dict = {}
    for nm, p in targets.items():
        j = target_joint(model, nm)
        while j >= 0 and not real[j]:  # a target on a bent link: the joint that turns before the bend
            j = par[j]
        ends.setdefault(j, []).append(np.asarray(p, float))
    return anchor_heights(model.screws, target_start(model), par, real, ends)


def row_weights(session: Session) -> np.ndarray:
    """(m,) weights sigma_ref / sigma_i of the rows (1 without a sigma column)."""
    if session.sigma is None:
        return np.ones(session.m)
    return float(np.median(session.sigma)) / session.sigma


def identify_position(
    session: Session,
    nominal: RobotModel | None = None,
    robust: bool = True,
    extension: Extension | None = None,
    joints: bool = True,
    suspects: np.ndarray | None = None,
) -> Identification:
    """Identify screws, sensor frame and targets from measured positions (LM in the identifiable subspace).

    Parameters
    ----------
    session : Session with measurement 'position' (``target`` holds the measured y, mm, sensor frame)
    nominal : RobotModel (default: the session's robot); its ``targets``/``sensor_pose``, when it has
        them (an identified model), are the start, else :func:`start_frame`
    robust : bool, flag outlier captures
    extension : Extension, optional joint effect identified jointly
    joints : bool, False: only the sensor frame and targets (the nominal's best alignment)
    suspects : (m,) bool array, optional: the only captures the outlier test may flag (an extension fitted
        on its geometric fit's rows: that fit's outliers; :func:`solver.identify.lsq.fit_subspace`)

    Returns
    -------
    Identification; ``extra['gauge']`` names the held parameters, ``extra['points']`` is empty
    """
    t0 = time.perf_counter()
    nominal = nominal or session.robot
    names = list(dict.fromkeys(session.point))
    q, y, t, tau = session.q, session.target, session.t, session.tau
    if nominal.sensor_pose is not None and all(nm in nominal.targets for nm in names):
        X0, tg0 = np.asarray(nominal.sensor_pose), {nm: nominal.targets[nm] for nm in names}
    else:
        start = {nm: nominal.targets.get(nm, target_start(nominal)) for nm in names}
        X0, tg0 = start_frame(nominal, q, y, session.point, start, session.path / "captures.csv")
    P = PositionParams(nominal, names, joints)
    k = extension.size if extension else 0
    if extension:
        require(extension, t, tau)
        if not extension.acts_on_joints:
            raise IdentificationError(f"{extension.effect} does not apply to position measurements")
        idx, G = extension.regressors(q, t, tau)
    p = P.size
    w = row_weights(session)[:, None]
    names_all = P.names + (extension.names if extension else [])

    def true_q(v):
        return extension.with_params(v[p:]).true_q(q, t, tau) if extension else q

    groups = branch_groups(nominal, session.point)  # the rows' branches, fixed through the fit

    def residual(v):
        screws, _, X, tg = P.geometry(v[:p], X0)
        return w * (
            sensor_points(nominal.replace(screws=screws), true_q(v), session.point, tg, X, groups) - y
        )

    def jacobian(v):
        _, J, Jq = P.jacobian(v[:p], X0, true_q(v), session.point, groups, idx if extension else ())
        if extension:
            J = np.concatenate([J, Jq * G[:, None, :]], axis=2)
        return w[:, :, None] * J

    x0 = np.zeros(p + k)
    for nm, c in P.col.items():
        x0[c : c + 3] = tg0[nm]
    kinds = P.kinds + (extension.kinds if extension else [])
    heights = target_anchor_heights(nominal, tg0)
    prior = make_prior(session.tolerances, kinds, x0, "position", names_all, nominal.joint_names, heights)
    fit = fit_subspace(residual, jacobian, x0, names_all, robust, suspects=suspects, prior=prior)
    se = np.sqrt(np.clip(np.diag(fit.cov), 0, None))
    gauge = (
        f"base frame = the nominal's: held at nominal {', '.join(P.held_names)} (a rigid motion of the base, "
        "with the sensor frame and targets moved along, leaves every measurement unchanged)"
        if joints
        else "joints held at nominal (sensor frame and targets only)"
    )
    meta = {
        "method": "lm",
        "measurement": "position",
        "converged": fit.converged,
        "iterations": fit.iterations,
        "rank": fit.identifiability.rank,
        "n_params": p + k,
        "gauge": gauge,
    }
    fitted = extension.with_params(fit.v[p:], se[p:]) if extension else None
    model = P.to_model(
        fit.v[:p], X0, identification=meta, extensions=fitted.model_entries() if fitted else {}
    )
    extra = {"cov": fit.cov, "points": {}, "span": fit.span, "gauge": gauge}
    return Identification.from_fit(nominal, model, fit, names_all, se, t0, extra, fitted)


def aligned_nominal(session: Session, model: RobotModel | None = None) -> RobotModel:
    """The model (default: the session's nominal) with its best sensor frame and targets for the session
    (joints as given): what "nominal" means for position data."""
    return identify_position(session, model or session.robot, robust=False, joints=False).model


def position_residuals(model: RobotModel, ext: Extension | None, session: Session) -> np.ndarray:
    """Residuals (m, 3) mm, sensor frame, of a model (and its extension) on a session's captures; a model
    without a sensor frame or targets for these captures is aligned first (:func:`aligned_nominal`)."""
    if model.sensor_pose is None or not all(nm in model.targets for nm in dict.fromkeys(session.point)):
        model = aligned_nominal(session, model)
    q = ext.true_q(session.q, session.t, session.tau) if ext else session.q
    return sensor_points(model, q, session.point) - session.target

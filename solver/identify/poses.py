"""One robot from several pose sessions, each with its own sensor placement and tool mounting.

Model (eq. PS1): the measured frame of session s at configuration q is T = X_s E(q) M_s, with
E(q) = e^[S1]q1 ... e^[Sn]qn the robot (minimal POE screws, shared by every session), X_s = ^S T_base the
base frame in session s's sensor frame and M_s the measured frame at q = 0 in the base frame (the tool as
mounted in session s). A joint extension (e.g. compliance under gravity, q_true = q + c tau) is shared too.

Parameters: the free joint etas (4 per revolute joint, the base gauge held at nominal as for position
sessions, :func:`~lasercal.solver.identify.position.gauge_holds`), then per session X_s = e^[xi_s] X_s0 and
M_s = e^[zeta_s] M_s0 (6 each, perturbed on the left), then the extension's.

Residual per capture (eq. PS2), in the sensor frame: the rotation error log(R R_meas^T)^vee (rad) and the
position error p - p_meas (mm). Jacobian: a space twist (w, v) applied to the predicted frame moves its
rotation by w and its origin by w x p + v (the rotation error's own differential is I to first order in the
residual, ~1 mrad here: the fixed point is unchanged). Joint etas act through Ad(e^[S1]q1...) A_j dS_j/deta
(:func:`~lasercal.solver.kinematics.poe.dexp_apply`), zeta through Ad(E(q)), xi in the sensor frame.

Weights (eq. PS3): rotation rows are multiplied by sigma_pos / sigma_rot, so every row is in mm of position
noise; the two sigmas are the RMS residuals per kind (per axis, dof-corrected), re-estimated after each fit
until their ratio settles -- what the data say their noise is. The fit itself is the MAP / LM machinery
of every identification (:func:`~lasercal.solver.identify.lsq.fit_subspace`): prior from the robot's
tolerances, identifiable subspace, outlier test.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial.transform import Rotation

from lasercal.solver.errors import IdentificationError
from lasercal.solver.identify.fullpose import estimate_frames
from lasercal.solver.identify.lsq import SubspaceFit, flag_outliers, identifiability
from lasercal.solver.identify.position import PositionParams, branch_chains, twist_point_rates
from lasercal.solver.identify.prior import make_prior
from lasercal.solver.kinematics.effects import Extension, extension_from_model
from lasercal.solver.kinematics.gravity import model_torques
from lasercal.solver.kinematics.joint_map import JointMap, joint_map_from_model
from lasercal.solver.kinematics.minimal import anchor_heights
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import dexp_A, dexp_apply, exp6, skew

START_ROWS = 300  # poses per session for the closed-form start of its frames (hand-eye, then LM)
_WEIGHT_RTOL = 0.02  # the rotation/position noise ratio has settled when it changes less than this
_WEIGHT_PASSES = 4


# ----------------------------------------------------------------------------- forward model
def model_effects(model: RobotModel, path="<model>") -> tuple:
    """The joint extension and the joint map a model carries (each None when absent)."""
    return extension_from_model(model.extensions, path, model.n), joint_map_from_model(
        model.extensions, path, model.n
    )


def corrected_q(
    model: RobotModel, q: np.ndarray, effects: tuple, tau: np.ndarray | None = None
) -> np.ndarray:
    """The angles the joints really take (m, n): the logged q with the extension's and the map's corrections,
    each evaluated at the logged angles (tau: gravity torques, default the model's)."""
    ext, jm = effects
    out = np.atleast_2d(q)
    if ext is not None:
        out = ext.true_q(out, None, model_torques(model, q)[0] if tau is None else tau)
    return out + jm.correction(q) if jm is not None else out


def session_frames(model: RobotModel, q: np.ndarray, X: np.ndarray, M: np.ndarray, effects=(None, None)):
    """Predicted frames X E(q_true) M (m, 4, 4) mm of one session (eq. PS1).

    Parameters
    ----------
    model : RobotModel, the screws
    q : (m, n) array, rad (logged)
    X, M : (4, 4) arrays, the session's sensor and tool frames
    effects : (Extension or None, JointMap or None), :func:`model_effects`
    """
    q = corrected_q(model, q, effects)
    chain = branch_chains(model.screws, q, [(np.arange(len(q)), np.arange(model.n))])[1]
    return X @ chain @ M


def pose_residuals(T: np.ndarray, T_meas: np.ndarray) -> np.ndarray:
    """(m, 6): rotation error log(R R_meas^T)^vee (rad) and position error p - p_meas (mm), sensor frame."""
    rot = Rotation.from_matrix(T[:, :3, :3] @ np.swapaxes(T_meas[:, :3, :3], 1, 2)).as_rotvec()
    return np.hstack([rot, T[:, :3, 3] - T_meas[:, :3, 3]])


def errors(T: np.ndarray, T_meas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pose: position error |p - p_meas| (mm) and rotation angle of R^T R_meas (rad)."""
    r = pose_residuals(T, T_meas)
    return np.linalg.norm(r[:, 3:], axis=1), np.linalg.norm(r[:, :3], axis=1)


# ----------------------------------------------------------------------------- parameters
@dataclass
class SessionData:
    """One session's arrays inside a fit: rows of the stacked problem, q, measured frames, torques."""

    name: str
    q: np.ndarray
    T: np.ndarray
    tau: np.ndarray | None
    X0: np.ndarray
    M0: np.ndarray
    rows: slice = field(default_factory=lambda: slice(0))


class PoseParams:
    """Parameter vector [free joint etas, (xi_s, zeta_s) per session, extension] (module docstring).

    Parameters
    ----------
    model : RobotModel, the reference (eta = 0)
    sessions : list of SessionData
    joints : bool, identify the joints (False: only the sessions' frames, ``register``)
    extension : Extension or None
    """

    def __init__(self, model: RobotModel, sessions: list, joints: bool = True, extension=None, jmap=None):
        self.P = PositionParams(model, [], joints)
        self.model, self.sessions, self.ext, self.jmap = model, sessions, extension, jmap
        self.nj = self.P.n_free
        self.k = extension.size if extension else 0
        self.km = jmap.size if jmap else 0
        self.dense = self.nj + 12 * len(sessions) + self.k  # columns formed densely; the map's are sparse
        self.size = self.dense + self.km
        self.names = list(self.P.names[: self.nj])
        self.kinds = list(self.P.kinds[: self.nj])
        for s in sessions:
            self.names += [f"{s.name}.sensor.{c}" for c in ("wx", "wy", "wz", "vx", "vy", "vz")]
            self.names += [f"{s.name}.tool.{c}" for c in ("wx", "wy", "wz", "vx", "vy", "vz")]
            self.kinds += ["sensor_rot"] * 3 + ["sensor_pos"] * 3 + ["sensor_rot"] * 3 + ["sensor_pos"] * 3
        q_all = np.vstack([s.q for s in sessions])
        if extension:
            self.names += extension.names
            self.kinds += extension.kinds
            self.idx, self.G = extension.regressors(q_all, None, np.vstack([s.tau for s in sessions]))
        if jmap:
            self.names += jmap.names
            self.kinds += jmap.kinds
            self.map_idx, self.map_G = jmap.hats(q_all)
            self.map_G = self.map_G.tocsr()

    def col(self, k: int) -> int:
        """First column of session k's xi (zeta follows 6 later)."""
        return self.nj + 12 * k

    def unpack(self, x: np.ndarray):
        """Screws (n, 6), dS/deta list, frames [(X, M)] per session, the extension at x."""
        screws, dS, _, _ = self.P.geometry(np.r_[x[: self.nj], np.zeros(6)], np.eye(4))
        frames = [
            (
                exp6(x[self.col(k) : self.col(k) + 6]) @ s.X0,
                exp6(x[self.col(k) + 6 : self.col(k) + 12]) @ s.M0,
            )
            for k, s in enumerate(self.sessions)
        ]
        ext = self.ext.with_params(x[self.dense - self.k : self.dense]) if self.ext else None
        jm = self.jmap.with_params(x[self.dense :]) if self.jmap else None
        return screws, dS, frames, (ext, jm)

    def model_at(self, x: np.ndarray) -> RobotModel:
        """The robot at x (screws; the first session's frames as ``sensor_pose`` / ``ee_pose``)."""
        screws, _, frames, _ = self.unpack(x)
        return self.model.replace(screws=screws, sensor_pose=frames[0][0], ee_pose=frames[0][1])

    def true_q(self, s: SessionData, effects) -> np.ndarray:
        """The session's angles with the extension's and the map's corrections (both at the logged q)."""
        ext, jm = effects
        q = ext.true_q(s.q, None, s.tau) if ext else s.q
        return q + jm.correction(s.q) if jm else q

    def predict(self, x: np.ndarray) -> list:
        """Predicted frames per session at x."""
        screws, _, frames, effects = self.unpack(x)
        m = self.model.replace(screws=screws)
        return [session_frames(m, self.true_q(s, effects), X, M) for s, (X, M) in zip(self.sessions, frames)]

    def residual(self, x: np.ndarray) -> np.ndarray:
        """(m, 6) stacked residuals (eq. PS2), unweighted."""
        return np.vstack([pose_residuals(T, s.T) for T, s in zip(self.predict(x), self.sessions)])

    def jacobian(self, x: np.ndarray):
        """d(residual)/dx (module docstring): (m, 6, dense) for the joints, frames and extension, and the
        joint map's columns as a sparse (6 m, km) matrix (None without a map)."""
        screws, dS, frames, effects = self.unpack(x)
        ext = effects[0]
        m_all = sum(len(s.q) for s in self.sessions)
        J = np.zeros((m_all, 6, self.dense))
        Jq_all = np.zeros((m_all, 6, self.model.n)) if self.jmap else None
        has = self.P.eta_joints
        dSp = np.zeros((len(has), 6, 4))
        for k, i in enumerate(has):
            dSp[k, :, : dS[i].shape[1]] = dS[i]
        for k, (s, (X, M)) in enumerate(zip(self.sessions, frames)):
            q = self.true_q(s, effects)
            before, E = branch_chains(screws, q, [(np.arange(len(q)), np.arange(self.model.n))])
            T = E @ M  # base frame
            p = T[:, :3, 3]
            R = X[:3, :3]
            Jk = J[s.rows]
            if self.nj:
                U = dexp_apply(screws[has], q[:, has], dSp)  # (m, nh, 6, 4) twists at q = 0
                pos = twist_point_rates(before[:, has], p, U).reshape(len(q), 3, -1)
                rot = before[:, has, :3, :3] @ U[..., :3, :]  # (m, nh, 3, 4)
                rot = np.moveaxis(rot, 2, 1).reshape(len(q), 3, -1)
                cols = self.P.free_cols
                Jk[:, :3, : self.nj] = R @ rot[:, :, cols]
                Jk[:, 3:, : self.nj] = R @ pos[:, :, cols]
            c = self.col(k)
            y = X[:3, :3] @ p.T + X[:3, 3, None]  # (3, m) the origin in the sensor frame
            A = dexp_A(x[c : c + 6], np.ones(1))[0]
            Jk[:, :3, c : c + 6] = A[:3]
            Jk[:, 3:, c : c + 6] = (
                np.concatenate([-skew(y.T), np.broadcast_to(np.eye(3), (len(q), 3, 3))], axis=2) @ A
            )
            # the tool's twist at q = 0, carried by E(q): Ad(E) A_zeta dzeta
            Az = dexp_A(x[c + 6 : c + 12], np.ones(1))[0]
            Jk[:, :3, c + 6 : c + 12] = R @ (E[:, :3, :3] @ Az[:3])
            Jk[:, 3:, c + 6 : c + 12] = R @ twist_point_rates(E[:, None], p, Az[None])[:, :, 0, :]
            if ext is not None or self.jmap:
                Jq = joint_rates(screws, before, p, R)  # (m, 6, n)
                if ext is not None:
                    Jk[:, :, self.dense - self.k : self.dense] = (
                        Jq[:, :, self.idx] * self.G[s.rows][:, None, :]
                    )
                if self.jmap:
                    Jq_all[s.rows] = Jq
            J[s.rows] = Jk
        if not self.jmap:
            return J, None
        # column k acts on joint idx[k] through the hat value G[i, k]: entries Jq[i, a, idx[k]] G[i, k]
        G = self.map_G.tocoo()
        vals = Jq_all[G.row, :, self.map_idx[G.col]] * G.data[:, None]  # (nnz, 6)
        rows = (6 * G.row[:, None] + np.arange(6)).ravel()
        cols = np.repeat(G.col, 6)
        Js = sparse.csr_matrix((vals.ravel(), (rows, cols)), shape=(6 * m_all, self.km))
        return J, Js


def joint_rates(screws: np.ndarray, before: np.ndarray, p: np.ndarray, R: np.ndarray) -> np.ndarray:
    """d(residual)/dq (m, 6, n) in the sensor frame: joint j's current twist Ad(before_j) S_j turns the frame
    by R w_j and moves its origin by R (w_j x p + v_j) (p the origin in the base frame, R = R_X)."""
    U = screws[:, :, None]  # (n, 6, 1)
    w = (before[:, :, :3, :3] @ U[:, :3])[..., 0]  # (m, n, 3)
    v = twist_point_rates(before, p, U)[..., 0]  # (m, 3, n)
    return np.concatenate([R @ np.moveaxis(w, 2, 1), R @ v], axis=1)


# ----------------------------------------------------------------------------- identification
@dataclass(frozen=True, eq=False)
class PoseFit:
    """Result of :func:`fit_poses`.

    Attributes
    ----------
    model : RobotModel, the robot (screws, extension entries; the first session's frames as ``sensor_pose``
        and ``ee_pose``)
    effects : (Extension or None, JointMap or None), fitted (with standard errors), or the model's own
        (register)
    frames : dict session name -> (X (4, 4), M (4, 4)), ^S T_base and the measured frame at q = 0 (mm)
    sigma_pos, sigma_rot : float, the noise per axis the data show (mm, rad; eq. PS3)
    errors : dict session name -> (position (m,) mm, rotation (m,) rad) of the fitted poses
    fit : SubspaceFit of the last pass
    names : list of str, the parameters
    seconds : float
    """

    model: RobotModel
    effects: tuple
    frames: dict
    sigma_pos: float
    sigma_rot: float
    errors: dict
    fit: object
    names: list
    v: np.ndarray
    seconds: float


def session_data(model: RobotModel, sessions: list, frames: dict | None = None, effects=(None, None)) -> list:
    """SessionData of each session, stacked in order: q, measured frames, gravity torques and the start of its
    frames (``frames[name]`` when given, else the closed-form hand-eye start of
    :func:`~lasercal.solver.identify.fullpose.estimate_frames` on at most :data:`START_ROWS` poses)."""
    out, r = [], 0
    M_ref = np.asarray(model.ee_pose)
    for s in sessions:
        tau = model_torques(model, s.q)[0] if model.links else None
        if frames and s.name in frames:
            X0, M0 = frames[s.name]
        else:
            pick = np.linspace(0, s.m - 1, min(s.m, START_ROWS)).astype(int)
            qs = corrected_q(model, s.q[pick], effects, None if tau is None else tau[pick])
            al = estimate_frames(model.replace(ee_pose=M_ref), qs, s.T[pick])
            X0, M0 = al.base, M_ref @ al.tool
        out.append(SessionData(s.name, s.q, s.T, tau, np.asarray(X0), np.asarray(M0), slice(r, r + s.m)))
        r += s.m
    return out


def pose_params(
    sessions: list, nominal: RobotModel, extension, joint_map, joints: bool, frames: dict | None
) -> tuple[PoseParams, list, tuple]:
    """The parameters of :func:`fit_poses` (eq. PS1) and each session's data, its frames' starts estimated.

    Returns
    -------
    P : PoseParams
    data : list of SessionData (``register``: their angles corrected by the model's effects)
    fixed : (Extension or None, JointMap or None), the model's own effects (``register``; (None, None) else)
    """
    if nominal.ee_pose is None:
        raise IdentificationError(
            f"robot {nominal.name!r} has no flange frame (ee.M): pose sessions need one"
        )
    names = [s.name for s in sessions]
    if len(set(names)) != len(names):
        raise IdentificationError(f"two sessions share a folder name ({', '.join(names)}): rename one")
    fixed = (None, None) if joints else model_effects(nominal, nominal.name)
    data = session_data(nominal, sessions, frames, fixed)
    if joints:
        return PoseParams(nominal, data, True, extension, joint_map), data, fixed
    # register: the model's effects are part of the robot; the logged angles are corrected once
    for d in data:
        d.q = corrected_q(nominal, d.q, fixed, d.tau)
    return PoseParams(nominal, data, False), data, fixed


def warm_start(P: PoseParams, warm: PoseFit) -> tuple[np.ndarray, float, int]:
    """The start from a fit of a superset of the sessions: its values by name (the sensor and tool frames at
    their own starts), its noise ratio sigma_pos / sigma_rot (mm/rad) and the weighting passes (one for a
    fold of the same model, the whole fit's noise; another model re-weighs)."""
    at = {nm: k for k, nm in enumerate(warm.names)}
    v = np.array(
        [
            warm.v[at[nm]] if nm in at and ".sensor." not in nm and ".tool." not in nm else 0.0
            for nm in P.names
        ]
    )
    same = all(nm in at for nm in P.names if ".sensor." not in nm and ".tool." not in nm)
    return v, warm.sigma_pos / warm.sigma_rot, 1 if same else _WEIGHT_PASSES


def reweighted_fit(
    P: PoseParams, prior, v: np.ndarray, ratio: float, used: np.ndarray, passes: int, robust: bool
) -> tuple:
    """The MAP fit (:func:`lm_map`) with the rotation rows weighted by sigma_pos / sigma_rot, refitted until
    that ratio and the flagged poses settle (eq. PS3), then the covariance at the last fit's weights.

    Parameters
    ----------
    P : PoseParams; prior : Prior or None
    v : (p,) array, the start; ratio : float, its noise ratio (mm/rad)
    used : (m,) bool array, the poses fitted at the start
    passes : int, the most weighting passes; robust : bool, flag outlier poses between passes

    Returns
    -------
    v : (p,) array; fit : SubspaceFit (the passes' LM steps and convergence)
    used : (m,) bool array, the poses fitted; ratio : float, the noise ratio, mm/rad
    """
    for _ in range(passes):
        w = np.repeat([ratio, 1.0], 3)
        sigma = float(np.sqrt(np.mean(P.residual(v)[used, 3:] ** 2)))
        v, fit = lm_map(P, w, v, prior, sigma, used, final=False)
        flagged = ~flag_outliers(fit.residuals, used.astype(float), 1.0)[0] if robust else used
        new = _noise_ratio(fit.residuals / w, flagged)
        if abs(new / ratio - 1) < _WEIGHT_RTOL and np.array_equal(flagged, used):
            break
        ratio, used = new, flagged
    steps, converged = fit.iterations, fit.converged
    v, fit = lm_map(P, w, v, prior, sigma, used, iterations=0)  # the covariance at the last fit's weights
    return v, replace(fit, iterations=steps, converged=converged), used, ratio


def fit_poses(
    sessions: list,
    nominal: RobotModel,
    extension: Extension | None = None,
    joint_map: JointMap | None = None,
    joints: bool = True,
    robust: bool = True,
    frames: dict | None = None,
    tolerances=None,
    warm: PoseFit | None = None,
) -> PoseFit:
    """Fit one robot (and its extension and joint map) to pose sessions, each with its own frames (PS1-PS3).

    Parameters
    ----------
    sessions : list of PoseSession (distinct names)
    nominal : RobotModel, the start and the prior's mean (must have ``ee_pose``: the flange at q = 0)
    extension : Extension or None, a joint effect shared by the sessions (its torques from the gravity model)
    joint_map : JointMap or None, a joint error map shared by the sessions (solver.kinematics.joint_map)
    joints : bool, False (``register``): keep the robot with its own extension and map, fit only the frames
    robust : bool, flag outlier poses (chi-square test of :func:`~lasercal.solver.identify.lsq.flag_outliers`)
    frames : dict name -> (X, M), optional starts of the sessions' frames
    tolerances : Tolerances or None, the prior (default: the first session's)
    warm : PoseFit, optional: a fit of a superset of these sessions, the start (its values by name, its
        frames, its noise ratio); of the same parameters (a cross-validation fold) one weighting pass

    Returns
    -------
    PoseFit
    """
    t0 = time.perf_counter()
    if warm is not None:
        frames = {k: warm.frames[k] for k in [s.name for s in sessions] if k in warm.frames}
    P, data, fixed = pose_params(sessions, nominal, extension, joint_map, joints, frames)
    tol = sessions[0].tolerances if tolerances is None else tolerances
    heights = anchor_heights(nominal.screws, np.asarray(nominal.ee_pose)[:3, 3])
    prior = make_prior(tol, P.kinds, np.zeros(P.size), "position", P.names, nominal.joint_names, heights)
    T_meas = np.concatenate([d.T for d in data])
    used = np.ones(len(T_meas), bool)
    if warm is not None:
        v, ratio, passes = warm_start(P, warm)
    else:
        v, passes = np.zeros(P.size), _WEIGHT_PASSES
        ratio = _noise_ratio(P.residual(v), used)
    v, fit, used, ratio = reweighted_fit(P, prior, v, ratio, used, passes, robust)
    sig_pos = float(np.sqrt(np.mean(P.residual(v)[used, 3:] ** 2)))
    se = np.sqrt(np.clip(np.diag(fit.cov), 0, None))
    screws, _, fr, (ext, jm) = P.unpack(v)
    if not joints:  # register keeps the robot bit for bit (the etas' zero rebuilds it only to round-off)
        screws = nominal.screws
    if ext is not None:
        ext = ext.with_params(v[P.dense - P.k : P.dense], se[P.dense - P.k : P.dense])
    if jm is not None:
        jm = jm.with_params(v[P.dense :], se[P.dense :])
    errs, frames_out = {}, {}
    T_all = np.concatenate(P.predict(v))
    for d, (X, M) in zip(data, fr):
        errs[d.name] = errors(T_all[d.rows], T_meas[d.rows])
        frames_out[d.name] = (X, M)
    meta = {
        "method": "lm",
        "measurement": "pose",
        "converged": bool(fit.converged),
        "rank": int(fit.identifiability.rank),
        "n_params": int(P.size),
        "sigma_pos_mm": sig_pos,
        "sigma_rot_rad": float(sig_pos / ratio),
        "outliers": int((~used).sum()),
        "sessions": {
            nm: {"sensor": {"T": _rows(X)}, "ee": {"M": _rows(M)}, "poses": int(len(errs[nm][0]))}
            for nm, (X, M) in frames_out.items()
        },
    }
    if joints:
        entries = (ext.model_entries() if ext is not None else {}) | (
            jm.model_entries() if jm is not None else {}
        )
        effects = (ext, jm)
    else:
        entries, effects = dict(nominal.extensions), fixed
    X0, M0 = fr[0]
    model = nominal.replace(
        screws=screws, sensor_pose=X0, ee_pose=M0, extensions=entries, identification=meta
    )
    return PoseFit(
        model, effects, frames_out, sig_pos, sig_pos / ratio, errs, fit, P.names, v, time.perf_counter() - t0
    )


def _rows(T: np.ndarray) -> list:
    return [[float(round(x, 12)) for x in row] for row in np.asarray(T)]


def _noise_ratio(res: np.ndarray, used: np.ndarray) -> float:
    """sigma_pos / sigma_rot (mm/rad) of residuals (m, 6): each the RMS per axis of its kind (eq. PS3)."""
    rot = np.sqrt(np.mean(res[used, :3] ** 2))
    pos = np.sqrt(np.mean(res[used, 3:] ** 2))
    return float(pos / max(rot, 1e-15)) if pos > 0 else 1000.0


_LM_RTOL = 1e-10  # relative decrease of the cost below which LM has converged


def lm_map(
    P: PoseParams,
    w: np.ndarray,
    v0: np.ndarray,
    prior,
    sigma: float,
    used: np.ndarray,
    final: bool = True,
    iterations: int = 50,
) -> tuple:
    """The MAP estimate (eq. P2 of :mod:`solver.identify.prior`) by Levenberg-Marquardt on the normal
    equations: the estimate of :func:`~lasercal.solver.identify.lsq.fit_subspace`, formed as the (p, p) normal
    matrix because 16,000 poses x 6 rows made MINPACK's QR of the (97,000, p) Jacobian and the outlier test's
    SVDs the whole cost (90 s against 5 s), and a joint map's hundreds of sparse columns fit no dense
    Jacobian. Marquardt's scaling by the normal matrix's diagonal. What the data identify: the SVD of the
    triangular factor of the dense columns (A = QR, same singular values); the covariance (eq. P4) from the
    eigen-decomposition of the column-scaled normal matrix with the prior, which every parameter without a
    prior (the frames) makes full rank only through the data: its eigenvalues below 1e-12 of the largest are
    left out (never a rank-deficient inverse).

    Parameters
    ----------
    P : PoseParams
    w : (6,) row weights (rotation rows sigma_pos / sigma_rot, position rows 1)
    v0 : (p,) start
    prior : Prior or None
    sigma : float, the position noise (mm) weighting the prior's rows
    used : (m,) bool, the poses fitted (False: flagged outliers)
    final : bool, False: skip the identifiability and the covariance (a pass before the noise settles)
    iterations : int, most LM steps (0: only the identifiability and covariance at v0)

    Returns
    -------
    v (p,), SubspaceFit (no history; no span: nested-model tests are not run on pose fits)
    """
    p = len(v0)
    sw = used.astype(float)[:, None]
    rw = np.tile(w, len(used)) * np.repeat(used.astype(float), 6)  # the weight of each of the 6 m rows

    def cost(v):
        c = float(np.sum((P.residual(v) * w * sw) ** 2))
        return c + (float(np.sum(prior.rows(v, sigma)[0] ** 2)) if prior is not None else 0.0)

    def normal(v):
        Jd, Js = P.jacobian(v)
        Jd = Jd.reshape(-1, P.dense) * rw[:, None]
        r = (P.residual(v) * w * sw).ravel()
        if Js is not None:
            Js = sparse.diags(rw) @ Js
            C = Js.T @ Jd
            H = np.block([[Jd.T @ Jd, C.T], [C, (Js.T @ Js).toarray()]])
            g = np.r_[Jd.T @ r, Js.T @ r]
        else:
            H, g = Jd.T @ Jd, Jd.T @ r
        if prior is not None:
            rp, Lp = prior.rows(v, sigma)
            H, g = H + Lp.T @ Lp, g + Lp.T @ rp
        return H, g, Jd

    v = np.asarray(v0, float).copy()
    c0 = cost(v)
    lam, it, converged = 1e-4, 0, False
    H, g, Jd = normal(v)
    while it < iterations:
        it += 1
        d = np.sqrt(np.clip(np.diag(H), 1e-300, None))
        A = H / np.outer(d, d) + lam * np.eye(p)
        try:  # positive definite wherever data or the prior fix every direction: Cholesky
            step = -cho_solve(cho_factor(A), g / d) / d
        except np.linalg.LinAlgError:
            step = -np.linalg.lstsq(A, g / d, rcond=None)[0] / d
        c = cost(v + step)
        if c <= c0:
            gain = (c0 - c) / max(c0, 1e-300)
            v, c0, lam = v + step, c, max(lam / 5, 1e-12)
            H, g, Jd = normal(v)
            if gain < _LM_RTOL:
                converged = True
                break
        else:
            lam *= 10
            if lam > 1e8:
                converged = True  # no step lowers the cost: at the minimum to round-off
                break
    res, span = P.residual(v) * w, np.zeros((0, 6, 0))  # no span: no nested-model test on pose fits
    if not final:
        return v, SubspaceFit(
            v, None, res, used.astype(float), sigma, None, converged, it, [], span, None, None
        )
    ident, _ = identifiability(np.linalg.qr(Jd, mode="r"), P.names[: P.dense])
    d = np.sqrt(np.clip(np.diag(H), 1e-300, None))
    ev, V = np.linalg.eigh(H / np.outer(d, d))
    keep = ev > 1e-12 * ev[-1]
    Vk = V[:, keep] / d[:, None]
    cov = sigma**2 * (Vk / ev[keep]) @ Vk.T
    dof = float(6 * used.sum() - int(keep.sum()))  # rows less parameters (the prior's weight ignored)
    c = np.zeros((0, 0))
    fit = SubspaceFit(v, cov, res, used.astype(float), sigma, ident, converged, it, [], span, c, np.zeros(0))
    return v, replace(fit, prior=prior, dof=dof)

"""Full-pose calibration with the minimal-POE error model (thesis Section 2.3).

Forward model (eq. 2.3.21): T(q) = e^[S1(eta1)]q1 ... e^[Sn(etan)]qn M, M = e^[xi_M] M_0,
with the screws in the measurement frame {S}. Parameters x = [eta_1 (4), ..., eta_n (4),
xi_M (6)]: link frames are fixed at a reference model (eta = 0 there, as in
:mod:`solver.laser`) and M is perturbed on the left, so x = 0 is the reference.
Joint offsets d(theta) are left out: with full poses they are not separately
identifiable from the screws and M (thesis Appendix A), so 4n + 6 parameters remain,
the identifiable count of an n-revolute arm (4r + 2p + 6).

Pose error (eqs. 2.3.23, 2.3.29-2.3.30): y = log(T_a T(x)^-1)^vee in R^6, (omega, v),
rad and mm. For the least squares it is whitened: e = [[I, 0], [-[p_a], I]] y is the
rotation error and the position error of the origin (first order), divided by their
noise levels (sigma_rot, sigma_pos); without that the v part of y mixes the rotation
error times the distance from {S} into the positions. Levenberg-Marquardt
(``scipy.optimize.least_squares``, method 'lm') with the analytic Jacobian
dy/dx = -J_l(-y)^-1 J(x), J(x) the error-model Jacobian of eq. 2.3.28 and J_l the left
Jacobian of SE(3) (the A matrix of eq. 2.3.27).

Identifiability: SVD of the column-scaled whitened Jacobian at the start; the fit moves
only in the identifiable subspace (unidentifiable combinations keep their start
values) and covariances come from that subspace -- no rank-deficient normal matrix is
ever inverted.

Unknown base and tool (e.g. a camera on the flange seeing a board): the measured frame
is T_a = X F(q) Y with F the nominal kinematics; X (^S T_base) and Y (flange to
measured frame) are first estimated in closed form (rotation of the hand-eye equation
A Y = Y B by the Park-Martin/Kabsch fit, then its translation, then X by averaging) and
refined by least squares; the nominal re-expressed in {S} with M = X M_0 Y is the start
of the POE identification.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy import optimize
from scipy.spatial.transform import Rotation

from lasercal.solver.errors import IdentificationError, LasercalError, ModelError
from lasercal.solver.formats.fullpose_io import CirclePointData
from lasercal.solver.identify.circlepoint import frame_errors, target_frame
from lasercal.solver.identify.lsq import Identifiability, identifiability
from lasercal.solver.kinematics.minimal import link_frame, normalise_screw, screw_from_eta
from lasercal.solver.kinematics.model import Link, RobotModel
from lasercal.solver.kinematics.poe import adjoint, dexp_A, exp6, fk, inv_T, log6, poe_chain, skew

SIGMA_START = (1e-3, 1.0)  # rad, mm: noise guesses for the first pass; only their ratio matters there
_MAX_PASSES = 8  # re-weighting passes until the noise estimates settle (within 2 %)
_MAX_PAIRS = 20000  # hand-eye pairs used by the closed-form frame estimate


# ----------------------------------------------------------------------- the model
class PoseParams:
    """Minimal-POE parameter vector of a full-pose model, with link frames fixed at a reference.

    Parameters
    ----------
    model : RobotModel, the reference (x = 0); must have ``ee_pose`` (M_0)
    """

    def __init__(self, model: RobotModel):
        if model.ee_pose is None:
            raise ModelError(
                f"robot {model.name!r} has no end-effector frame (ee.M); estimate it with estimate_frames "
                "first"
            )
        self.model = model
        self.frames = [link_frame(S) for S in model.screws]
        n = model.n
        self.size = 4 * n + 6
        self.names = [f"{jn}.{p}" for jn in model.joint_names for p in ("wx", "wy", "qx", "qy")]
        self.names += [f"M.{p}" for p in ("wx", "wy", "wz", "vx", "vy", "vz")]
        self.slice_M = slice(4 * n, 4 * n + 6)

    def geometry(self, x: np.ndarray) -> tuple[np.ndarray, list, np.ndarray, np.ndarray]:
        """Screws (eqs. 2.2.17-2.2.19) and M at x, with their derivatives.

        Returns
        -------
        screws : (n, 6) array
        dscrews : list of n (6, 4) arrays, dS_i/deta_i
        M : (4, 4) array, e^[xi_M] M_0
        A_M : (6, 6) array, [(d e^[xi_M]) e^-[xi_M]]^vee = A_M dxi_M (eq. 2.3.27)
        """
        screws, dscrews = [], []
        for i, T in enumerate(self.frames):
            S, dS = screw_from_eta(T, x[4 * i : 4 * i + 4])
            screws.append(S)
            dscrews.append(dS)
        xi = x[self.slice_M]
        return np.array(screws), dscrews, exp6(xi) @ self.model.ee_pose, dexp_A(xi, np.ones(1))[0]

    def to_model(self, x: np.ndarray, **changes) -> RobotModel:
        """The robot model at x."""
        screws, _, M, _ = self.geometry(x)
        return self.model.replace(screws=screws, ee_pose=M, **changes)

    def poses(self, x: np.ndarray, q: np.ndarray) -> np.ndarray:
        """End-effector frames T(q) (eq. 2.3.21), (m, 4, 4)."""
        screws, _, M, _ = self.geometry(x)
        return fk(screws, M, q)

    def jacobian(self, x: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frames and the error-model Jacobian [dT T^-1]^vee = J dx (eqs. 2.3.25-2.3.28).

        Columns of joint i: Ad(e^[S1]q1...e^[S(i-1)]q(i-1)) A_i dS_i/deta_i, with the exact
        dS/deta of :func:`screw_from_eta` in place of the thesis's B_i (equal at eta = 0);
        columns of M: Ad(e^[S1]q1...e^[Sn]qn) A_M. The d(theta) columns are left out.

        Parameters
        ----------
        x : (size,) array
        q : (m, n) array, rad

        Returns
        -------
        T : (m, 4, 4) array
        J : (m, 6, size) array
        """
        screws, dscrews, M, AM = self.geometry(x)
        chain = poe_chain(screws, q)
        cols = [adjoint(chain[:, i]) @ (dexp_A(screws[i], q[:, i]) @ dscrews[i]) for i in range(len(screws))]
        cols.append(adjoint(chain[:, -1]) @ AM)
        return chain[:, -1] @ M, np.concatenate(cols, axis=2)


def pose_errors(T_meas: np.ndarray, T: np.ndarray) -> np.ndarray:
    """y = log(T_a T_n^-1)^vee of each pose (eqs. 2.3.23, 2.3.30), (m, 6): (omega rad, v mm)."""
    return log6(T_meas @ inv_T(T))


def _whitening(T_meas: np.ndarray, sigma: tuple) -> np.ndarray:
    """W (m, 6, 6) = diag(1/sigma) [[I, 0], [-[p_a], I]]: y -> (rotation, origin position) errors / noise."""
    m = len(T_meas)
    L = np.tile(np.eye(6), (m, 1, 1))
    L[:, 3:, :3] = -skew(T_meas[:, :3, 3])
    return np.repeat([1 / sigma[0], 1 / sigma[1]], 3)[None, :, None] * L


def _error_jacobian(y: np.ndarray, J: np.ndarray) -> np.ndarray:
    """dy/dx = -J_l(-y)^-1 J for y = log(T_a T^-1), T perturbed on the left by J dx.

    T -> e^[J dx] T gives T_a T^-1 -> e^[y] e^-[J dx]; the log of that moves by
    -J_r(y)^-1 J dx, and J_r(y) = J_l(-y) = dexp_A(-y, 1) (eq. 2.3.27's A).
    """
    Jl = np.stack([dexp_A(-yi, np.ones(1))[0] for yi in y])
    return -np.linalg.solve(Jl, J)


# ----------------------------------------------------------------------- identifiability
# ----------------------------------------------------------------------- accuracy (Table 4)
@dataclass(frozen=True)
class Accuracy:
    """Absolute pose accuracy over a set of poses, in the form of the paper's Table 4.

    Attributes
    ----------
    n : int, number of poses
    position : (3,) array, mean, std, max of |p_a - p|, mm
    euler : (3, 3) array, rows x, y, z; columns mean, std, max of the absolute Euler angle
        errors of R^T R_a (about the predicted frame's axes), deg
    """

    n: int
    position: np.ndarray
    euler: np.ndarray

    def to_dict(self) -> dict:
        """JSON-ready mapping (mm, deg)."""
        d = {"n": self.n, "position_mm": dict(zip(("mean", "std", "max"), map(float, self.position)))}
        for axis, row in zip("xyz", self.euler):
            d[f"euler_{axis}_deg"] = dict(zip(("mean", "std", "max"), map(float, row)))
        return d


def _stats(a: np.ndarray) -> np.ndarray:
    """mean, std (n - 1), max of non-negative values along axis 0."""
    return np.stack([a.mean(0), a.std(0, ddof=1) if len(a) > 1 else np.zeros(a.shape[1:]), a.max(0)])


def accuracy(T_meas: np.ndarray, T_pred: np.ndarray) -> Accuracy:
    """Table 4: mean, std and max of the position error norm and of |Euler angle errors| about x, y, z.

    Parameters
    ----------
    T_meas, T_pred : (m, 4, 4) arrays, measured and predicted frames, mm

    Returns
    -------
    Accuracy
    """
    dp, de = frame_errors(T_meas, T_pred)
    return Accuracy(len(dp), _stats(np.linalg.norm(dp, axis=1)), _stats(np.degrees(np.abs(de))).T)


def format_table(rows: list, title: str = "") -> str:
    """Accuracies side by side in the layout of the paper's Table 4.

    Parameters
    ----------
    rows : list of (label, Accuracy)
    title : str, a first line

    Returns
    -------
    str
    """
    w = max(len(lab) for lab, _ in rows)
    out = [title] if title else []
    out.append(f"{'':34} {'':{w}} {'mean':>10} {'std':>10} {'max':>10}")
    blocks = [("absolute position [mm]", lambda a: a.position)]
    blocks += [
        (f"orientation about {ax}: Euler [deg]", lambda a, k=k: a.euler[k]) for k, ax in enumerate("xyz")
    ]
    for name, get in blocks:
        for i, (lab, acc) in enumerate(rows):
            v = get(acc)
            out.append(f"{name if i == 0 else '':34} {lab:{w}} {v[0]:10.5f} {v[1]:10.5f} {v[2]:10.5f}")
    return "\n".join(out)


# ----------------------------------------------------------------------- POE identification
@dataclass(frozen=True, eq=False)
class FullPoseFit:
    """Result of a full-pose POE identification, with its history.

    Attributes
    ----------
    reference, model : RobotModel, the start (x = 0) and the identified model
    estimate : (p,) array, the identified parameters (in the reference's link frames)
    param_names : list of str
    std_errors : dict name -> float, standard errors (eta: unitless/mm as the parameter; M: rad, mm)
    identifiability : Identifiability
    converged : bool, every pass stopped on a tolerance (not on the evaluation limit) and
        the noise estimates settled
    iterations : int, Jacobian evaluations over all passes
    history : tuple of dict, one per pass: sigmas, iterations, status, RMS errors
    residuals : (m, 6) array, y = log(T_a T^-1)^vee at the solution (rad, mm)
    sigma : (2,) array, rotation (rad) and position (mm) noise used in the last pass
    seconds : float
    """

    reference: RobotModel
    model: RobotModel
    estimate: np.ndarray
    param_names: list
    std_errors: dict
    identifiability: Identifiability
    converged: bool
    iterations: int
    history: tuple
    residuals: np.ndarray
    sigma: np.ndarray
    seconds: float


def _checked(q: np.ndarray, T_meas: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    q, T_meas = np.atleast_2d(np.asarray(q, dtype=float)), np.asarray(T_meas, dtype=float)
    if T_meas.ndim != 3 or T_meas.shape[1:] != (4, 4):
        raise LasercalError(f"measured poses must be shaped (m, 4, 4), got {T_meas.shape}")
    if len(q) != len(T_meas):
        raise LasercalError(f"{len(q)} configurations but {len(T_meas)} measured poses")
    if q.shape[1] != n:
        raise ModelError(f"configurations have {q.shape[1]} joints but the robot has {n}")
    return q, T_meas


def _residual_sigma(y: np.ndarray, T_meas: np.ndarray) -> np.ndarray:
    """RMS per component of the rotation (rad) and origin-position (mm) errors behind y."""
    e = (_whitening(T_meas, (1.0, 1.0)) @ y[:, :, None])[:, :, 0]
    return np.maximum(
        np.sqrt([np.mean(e[:, :3] ** 2), np.mean(e[:, 3:] ** 2)]), [1e-12, 1e-9]
    )  # floors: round-off of exact data


def whitened_errors(z: np.ndarray, W: np.ndarray, basis: np.ndarray, P: PoseParams, q, T_meas) -> np.ndarray:
    """Eq. 2.3.29's residual at x = basis z: the pose errors (rotation rad, position mm) of the m poses,
    each whitened by W (m, 6, 6) (:func:`_whitening`), as (6 m,)."""
    return (W @ pose_errors(T_meas, P.poses(basis @ z, q))[:, :, None]).ravel()


def whitened_jacobian(
    z: np.ndarray, W: np.ndarray, basis: np.ndarray, P: PoseParams, q, T_meas
) -> np.ndarray:
    """d :func:`whitened_errors` / dz, (6 m, r)."""
    T, J = P.jacobian(basis @ z, q)
    return (W @ _error_jacobian(pose_errors(T_meas, T), J)).reshape(6 * len(q), -1) @ basis


def reweighted_lm(P: PoseParams, q, T_meas, basis: np.ndarray, sig: np.ndarray, fixed: bool) -> tuple:
    """Levenberg-Marquardt on eq. 2.3.29 in the identifiable subspace, the errors whitened by the noise sig
    = (rot rad, pos mm); unless ``fixed``, passes repeated with the residuals' own noise until it settles
    (within 2 %; iteratively re-weighted least squares).

    Parameters
    ----------
    P : PoseParams; q : (m, n) array, rad; T_meas : (m, 4, 4) array, mm
    basis : (p, r) array, the identifiable subspace; sig : (2,) array, the first pass's noise
    fixed : bool, one pass at ``sig``

    Returns
    -------
    z : (r,) array; W : (m, 6, 6) array, the last pass's whitening; y : (m, 6) array, the pose errors
    used : (2,) array, the last pass's noise; history : list of dict; iterations : int; converged : bool
    """
    z = np.zeros(basis.shape[1])
    history, iterations, converged = [], 0, True
    for pas in range(1 if fixed else _MAX_PASSES):
        used = sig
        W = _whitening(T_meas, used)
        sol = optimize.least_squares(
            whitened_errors,
            z,
            whitened_jacobian,
            args=(W, basis, P, q, T_meas),
            method="lm",
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=100 * (len(z) + 1),
        )
        z, iterations, converged = sol.x, iterations + sol.njev, converged and sol.status > 0
        y = pose_errors(T_meas, P.poses(basis @ z, q))
        rms = _residual_sigma(y, T_meas)
        history.append(
            {
                "pass": pas + 1,
                "sigma_rad": float(sig[0]),
                "sigma_mm": float(sig[1]),
                "iterations": int(sol.njev),
                "status": int(sol.status),
                "message": sol.message,
                "rms_rot_rad": float(rms[0]),
                "rms_pos_mm": float(rms[1]),
            }
        )
        if fixed or np.abs(np.log(rms / used)).max() < 0.02:
            break
        sig = rms
    else:
        converged = False  # the noise estimates kept moving
    return z, W, y, used, history, iterations, converged


def fit_fullpose(
    reference: RobotModel, q: np.ndarray, T_meas: np.ndarray, sigma: tuple | None = None
) -> FullPoseFit:
    """Identify the screws and M from measured full poses (eq. 2.3.29 by Levenberg-Marquardt).

    Parameters
    ----------
    reference : RobotModel with ``ee_pose``, the start; its screws and M in {S}
    q : (m, n) array, rad
    T_meas : (m, 4, 4) array, measured frames in {S}, mm
    sigma : (rot rad, pos mm), optional; by default a first pass with :data:`SIGMA_START`
        gives residuals from which both are estimated, and passes are repeated with the
        new estimates until they settle (iteratively re-weighted least squares)

    Returns
    -------
    FullPoseFit

    Raises
    ------
    IdentificationError
        if there are fewer pose components than parameters
    """
    t0 = time.perf_counter()
    P = PoseParams(reference)
    q, T_meas = _checked(q, T_meas, reference.n)
    m = len(q)
    if 6 * m < P.size:
        raise IdentificationError(
            f"{m} poses give {6 * m} equations for {P.size} parameters: measure at least {-(-P.size // 6)} "
            "configurations"
        )
    sig = np.array(SIGMA_START if sigma is None else sigma, dtype=float)
    x0 = np.zeros(P.size)
    W = _whitening(T_meas, sig)
    T, J = P.jacobian(x0, q)
    ident, basis = identifiability(
        (W @ _error_jacobian(pose_errors(T_meas, T), J)).reshape(6 * m, -1), P.names
    )
    z, W, y, used, history, iterations, converged = reweighted_lm(P, q, T_meas, basis, sig, sigma is not None)
    x = basis @ z
    Jz = whitened_jacobian(z, W, basis, P, q, T_meas)
    dof = 6 * m - basis.shape[1]
    s2 = float(np.sum(whitened_errors(z, W, basis, P, q, T_meas) ** 2) / dof) if dof > 0 else float("nan")
    _, s, Vt = np.linalg.svd(Jz, full_matrices=False)
    cov = s2 * (basis @ ((Vt.T / s**2) @ Vt) @ basis.T)
    std = dict(zip(P.names, map(float, np.sqrt(np.maximum(np.diag(cov), 0.0)))))
    return FullPoseFit(
        reference=reference,
        model=P.to_model(x),
        estimate=x,
        param_names=P.names,
        std_errors=std,
        identifiability=ident,
        converged=converged,
        iterations=iterations,
        history=tuple(history),
        residuals=y,
        sigma=used,
        seconds=time.perf_counter() - t0,
    )


# ----------------------------------------------------------------------- unknown base and tool
@dataclass(frozen=True)
class FrameAlignment:
    """Base and tool transforms of T_a = X F(q) Y, estimated before the POE identification.

    Attributes
    ----------
    base : (4, 4) array, X = ^S T_base: the robot base in the measurement frame {S}, mm
    tool : (4, 4) array, Y: the measured frame in the nominal end-effector frame M_0, mm
    ee_nominal : (4, 4) array, M_0: the nominal end-effector frame at q = 0 (base frame)
    iterations : int, Jacobian evaluations of the refinement
    converged : bool
    rms_rot_rad, rms_pos_mm : float, RMS rotation and position error per component of
        the aligned nominal
    """

    base: np.ndarray
    tool: np.ndarray
    ee_nominal: np.ndarray
    iterations: int
    converged: bool
    rms_rot_rad: float
    rms_pos_mm: float


def nominal_ee(model: RobotModel) -> np.ndarray:
    """M_0: the model's ``ee_pose``, or else the last joint's link frame (eq. 2.2.15; Y absorbs it)."""
    return np.asarray(model.ee_pose) if model.ee_pose is not None else link_frame(model.screws[-1])


def _kabsch(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation R minimising sum |a_k - R b_k|^2, for (k, 3) arrays (orthogonal Procrustes)."""
    U, _, Vt = np.linalg.svd(b.T @ a)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    return Vt.T @ np.diag([1.0, 1.0, d]) @ U.T


def _pairs(m: int) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs i < j for the hand-eye equations, thinned evenly to at most _MAX_PAIRS."""
    i, j = np.triu_indices(m, 1)
    keep = np.linspace(0, len(i) - 1, min(len(i), _MAX_PAIRS)).astype(int)
    return i[keep], j[keep]


def estimate_frames(model: RobotModel, q: np.ndarray, T_meas: np.ndarray) -> FrameAlignment:
    """X = ^S T_base and Y (tool) of T_a = X F(q) Y, with F the nominal kinematics.

    Closed form first: for pairs of poses, A Y = Y B with A = F_i^-1 F_j and
    B = T_a,i^-1 T_a,j (X cancels). Its rotation part gives omega_A = R_Y omega_B for the
    rotation vectors (Park and Martin), solved by the orthogonal Procrustes fit; then
    (R_A - I) t_Y = R_Y t_B - t_A in least squares; X is the average of T_a,i Y^-1 F_i^-1
    (rotation: the nearest rotation to the mean matrix). Then X = e^[a] X_0 and
    Y = Y_0 e^[b] are refined by Levenberg-Marquardt on the whitened pose errors
    (analytic Jacobian: dT T^-1 = J_l(a) da + Ad(X F Y_0) J_l(b) db).

    Parameters
    ----------
    model : RobotModel, the nominal (its screws and ``ee_pose`` or :func:`nominal_ee`)
    q : (m, n) array, rad
    T_meas : (m, 4, 4) array, measured frames in {S}, mm

    Returns
    -------
    FrameAlignment

    Raises
    ------
    IdentificationError
        if the configurations do not rotate the end-effector about two different axes
    """
    q, T_meas = _checked(q, T_meas, model.n)
    if len(q) < 3:
        raise IdentificationError(
            f"{len(q)} poses cannot fix the base and tool transforms: measure at least 3"
        )
    M0 = nominal_ee(model)
    F = fk(model.screws, M0, q)
    i, j = _pairs(len(q))
    A, B = inv_T(F[i]) @ F[j], inv_T(T_meas[i]) @ T_meas[j]
    a, b = Rotation.from_matrix(A[:, :3, :3]).as_rotvec(), Rotation.from_matrix(B[:, :3, :3]).as_rotvec()
    if np.linalg.svd(a, compute_uv=False)[1] < 1e-3 * np.sqrt(len(a)):
        raise IdentificationError(
            "the end-effector turns about a single axis in these configurations: its tool transform is not "
            "determined"
        )
    RY = _kabsch(a, b)
    lhs = (A[:, :3, :3] - np.eye(3)).reshape(-1, 3)
    rhs = (RY @ B[:, :3, 3, None])[:, :, 0] - A[:, :3, 3]
    Y = np.eye(4)
    Y[:3, :3], Y[:3, 3] = RY, np.linalg.lstsq(lhs, rhs.ravel(), rcond=None)[0]
    Xi = T_meas @ inv_T(Y) @ inv_T(F)
    U, _, Vt = np.linalg.svd(Xi[:, :3, :3].sum(0))
    X = np.eye(4)
    X[:3, :3] = U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt
    X[:3, 3] = Xi[:, :3, 3].mean(0)

    W = _whitening(T_meas, _residual_sigma(pose_errors(T_meas, X @ F @ Y), T_meas))
    m = len(q)

    def frames(z):
        return exp6(z[:6]) @ X, Y @ exp6(z[6:])

    def fun(z):
        Xz, Yz = frames(z)
        return (W @ pose_errors(T_meas, Xz @ F @ Yz)[:, :, None]).ravel()

    def jac(z):
        Xz, Yz = frames(z)
        T = Xz @ F @ Yz
        J = np.concatenate(
            [
                np.broadcast_to(dexp_A(z[:6], np.ones(1))[0], (m, 6, 6)),
                adjoint(Xz @ F @ Y) @ dexp_A(z[6:], np.ones(1))[0],
            ],
            axis=2,
        )
        return (W @ _error_jacobian(pose_errors(T_meas, T), J)).reshape(6 * m, 12)

    sol = optimize.least_squares(
        fun, np.zeros(12), jac, method="lm", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000
    )
    X, Y = frames(sol.x)
    rms = _residual_sigma(pose_errors(T_meas, X @ F @ Y), T_meas)
    return FrameAlignment(X, Y, M0, int(sol.njev), bool(sol.status > 0), float(rms[0]), float(rms[1]))


def rebased(model: RobotModel, X: np.ndarray, ee_pose: np.ndarray, note: str) -> RobotModel:
    """The model re-expressed in the frame {S} with X = ^S T_base: screws Ad_X S (eq. 2.2.8's adjoint),
    ``ee_pose`` as given (in {S}); the laser, tool point and centres of mass moved rigidly with the
    base; the table plane (a base-frame z) dropped; ``note`` appended to the notes."""
    R, t = X[:3, :3], X[:3, 3]
    screws = np.array([normalise_screw(S)[0] for S in (adjoint(X) @ model.screws[:, :, None])[:, :, 0]])
    return model.replace(
        screws=screws,
        ee_pose=ee_pose,
        laser_dir=R @ model.laser_dir,
        aperture=R @ model.aperture + t,
        tool_point=None if model.tool_point is None else R @ model.tool_point + t,
        plane_z=None,
        links=tuple(Link(lk.mass, R @ lk.com + t) for lk in model.links),
        notes=model.notes + (note,),
    )


def aligned_model(model: RobotModel, al: FrameAlignment) -> RobotModel:
    """The nominal re-expressed in {S} (:func:`rebased`) with M = X M_0 Y."""
    note = (
        "re-expressed in the measurement frame {S}: base and tool transforms estimated from full poses "
        "(solver.fullpose)"
    )
    return rebased(model, al.base, al.base @ al.ee_nominal @ al.tool, note)


# ----------------------------------------------------------------------- calibration and validation
@dataclass(frozen=True, eq=False)
class FullPoseCalibration:
    """A full-pose calibration: optional frame alignment, then the POE identification.

    Attributes
    ----------
    nominal : RobotModel, as given
    alignment : FrameAlignment or None, the estimated base and tool (None: {S} is the base, M_0 known)
    fit : FullPoseFit, whose ``reference`` is the start (nominal, aligned if estimated)
    before, after : Accuracy, of the start and of the identified model on the same poses
    """

    nominal: RobotModel
    alignment: FrameAlignment | None
    fit: FullPoseFit
    before: Accuracy
    after: Accuracy

    @property
    def model(self) -> RobotModel:
        """The identified model."""
        return self.fit.model


def start_model(
    nominal: RobotModel, q: np.ndarray, T_meas: np.ndarray, estimate: bool | None = None
) -> tuple[RobotModel, FrameAlignment | None]:
    """The start of the identification: the nominal, aligned to the data if ``estimate``
    (default: only when the nominal has no ``ee_pose``)."""
    if estimate is None:
        estimate = nominal.ee_pose is None
    if not estimate:
        return nominal, None
    al = estimate_frames(nominal, q, T_meas)
    return aligned_model(nominal, al), al


def calibrate_fullpose(
    nominal: RobotModel,
    q: np.ndarray,
    T_meas: np.ndarray,
    estimate: bool | None = None,
    sigma: tuple | None = None,
) -> FullPoseCalibration:
    """Full-pose calibration: base/tool alignment if needed, then :func:`fit_fullpose`.

    Parameters
    ----------
    nominal : RobotModel
    q : (m, n) array, rad
    T_meas : (m, 4, 4) array, measured frames in {S}, mm
    estimate : bool, optional, estimate the base and tool transforms first (default: if
        the nominal has no ``ee_pose``)
    sigma : (rot rad, pos mm), optional, see :func:`fit_fullpose`

    Returns
    -------
    FullPoseCalibration
    """
    start, al = start_model(nominal, q, T_meas, estimate)
    fit = fit_fullpose(start, q, T_meas, sigma)
    before = accuracy(T_meas, fk(start.screws, start.ee_pose, q))
    after = accuracy(T_meas, fk(fit.model.screws, fit.model.ee_pose, q))
    return FullPoseCalibration(nominal, al, fit, before, after)


@dataclass(frozen=True)
class PoseCrossValidation:
    """K-fold cross-validated accuracy, nominal (aligned on each training fold) vs calibrated.

    Attributes
    ----------
    folds : int
    seed : int, of the fold shuffle
    nominal_train, nominal_test, calibrated_train, calibrated_test : Accuracy; the test
        sets pool every pose once (predicted by the fold that left it out), the training
        sets pool every pose K - 1 times
    per_fold : tuple of dict, per fold: sizes, test mean position errors, identifiable rank
    """

    folds: int
    seed: int
    nominal_train: Accuracy
    nominal_test: Accuracy
    calibrated_train: Accuracy
    calibrated_test: Accuracy
    per_fold: tuple


def cross_validate(
    nominal: RobotModel,
    q: np.ndarray,
    T_meas: np.ndarray,
    k: int = 5,
    seed: int = 0,
    estimate: bool | None = None,
    sigma: tuple | None = None,
) -> PoseCrossValidation:
    """K-fold cross-validation of :func:`calibrate_fullpose` (poses shuffled with ``seed``).

    Raises
    ------
    IdentificationError
        if k < 2 or a training fold is too small
    """

    def calibrate(train):
        cal = calibrate_fullpose(nominal, q[train], T_meas[train], estimate, sigma)
        return cal.fit.reference, cal.model, cal.fit.identifiability.rank

    q, T_meas = _checked(q, T_meas, nominal.n)
    return fold_accuracy(q, T_meas, k, seed, calibrate)


def fold_accuracy(q: np.ndarray, T_meas: np.ndarray, k: int, seed: int, calibrate) -> PoseCrossValidation:
    """K-fold cross-validated accuracy (Table 4 form) of any calibration of full poses.

    Parameters
    ----------
    q : (m, n) array, rad
    T_meas : (m, 4, 4) array, the measured frames, mm
    k : int, folds; seed : int, of the shuffle of the poses
    calibrate : callable, training indices (t,) -> (start model, calibrated model, identifiable rank);
        both models give the frames by ``fk(screws, ee_pose, q)``

    Returns
    -------
    PoseCrossValidation

    Raises
    ------
    IdentificationError
        if not 2 <= k <= m
    """
    m = len(q)
    if not 2 <= k <= m:
        raise IdentificationError(f"K-fold cross-validation needs 2 <= K <= {m} poses, got K = {k}")
    folds = np.array_split(np.random.default_rng(seed).permutation(m), k)
    acc = {key: ([], []) for key in ("nt", "nv", "ct", "cv")}  # (measured, predicted) per set
    per_fold = []
    for f, test in enumerate(folds):
        train = np.setdiff1d(np.arange(m), test)
        start, model, rank = calibrate(train)
        for key, mod, idx in (
            ("nt", start, train),
            ("nv", start, test),
            ("ct", model, train),
            ("cv", model, test),
        ):
            acc[key][0].append(T_meas[idx])
            acc[key][1].append(fk(mod.screws, mod.ee_pose, q[idx]))
        tv = accuracy(T_meas[test], acc["cv"][1][-1])
        nv = accuracy(T_meas[test], acc["nv"][1][-1])
        per_fold.append(
            {
                "fold": f + 1,
                "train": len(train),
                "test": len(test),
                "rank": rank,
                "test_position_mean_mm": {
                    "nominal": float(nv.position[0]),
                    "calibrated": float(tv.position[0]),
                },
            }
        )
    A = {key: accuracy(np.concatenate(a), np.concatenate(b)) for key, (a, b) in acc.items()}
    return PoseCrossValidation(k, seed, A["nt"], A["nv"], A["ct"], A["cv"], tuple(per_fold))


# ----------------------------------------------------------------------- simulation (Sensors 2013, Section 3)
def default_target(model: RobotModel, radius: float = 50.0, offset: float = 50.0) -> np.ndarray:
    """A target point at q = 0: ``offset`` mm along the last axis from its point nearest the
    aperture M, and ``radius`` mm off the axis towards base x (base y if the axis is along x).

    Returns
    -------
    (3,) array, mm, base frame
    """
    S = model.screws[-1]
    w, c = S[:3], np.cross(S[:3], S[3:])  # axis direction and its point closest to the origin
    foot = c + ((model.aperture - c) @ w) * w
    e = np.eye(3)[0] if abs(w[0]) < 0.9 else np.eye(3)[1]
    e = e - (e @ w) * w
    return foot + offset * w + radius * e / np.linalg.norm(e)


def with_target(model: RobotModel, target: np.ndarray) -> RobotModel:
    """The model with M = the circle-point frame {E} of a target at ``target`` (q = 0, base frame)."""
    return model.replace(ee_pose=target_frame(model.screws[-1], target))


def simulate_circlepoint(
    truth: RobotModel,
    g: int,
    m: int,
    step_rad: float,
    noise_mm: float,
    rng: np.random.Generator,
    target: np.ndarray | None = None,
    sensor: np.ndarray | None = None,
) -> CirclePointData:
    """Synthetic circle-point measurements (Section 3): g random configurations, the last joint turned through
    m angles.

    The target is measured as y = X E(q) p (the position model of :mod:`solver.identify.position`),
    X = ^S T_base (default: the identity, the sensor frame {S} is the truth's base frame).
    Every joint is drawn uniformly within its limits, the last one so that all m angles
    q_N + k step (k = 0..m-1) stay within them; each target position gets independent
    N(0, noise_mm^2) noise per axis.

    Parameters
    ----------
    truth : RobotModel, the true geometry
    g : int, configurations
    m : int, angles per configuration (>= 3)
    step_rad : float, the last joint's step, rad (non-zero, |step| < pi)
    noise_mm : float, sensor noise standard deviation per axis, mm
    rng : numpy Generator
    target : (3,) array, the target at q = 0 in the base frame, mm (default :func:`default_target`)
    sensor : (4, 4) array, X = ^S T_base, mm (default identity)

    Returns
    -------
    CirclePointData
    """
    if g < 1 or m < 3:
        raise LasercalError(
            f"a circle-point simulation needs g >= 1 configurations and m >= 3 angles, got g = {g}, m = {m}"
        )
    if not 0 < abs(step_rad) < np.pi:
        raise LasercalError(
            f"the angle step must be non-zero and below 180 degrees, got {np.degrees(step_rad):g} deg"
        )
    lo, hi = truth.limits[:, 0], truth.limits[:, 1]
    sweep = (m - 1) * step_rad
    if abs(sweep) >= hi[-1] - lo[-1]:
        raise LasercalError(
            f"{m} angles of {np.degrees(step_rad):g} deg sweep {np.degrees(abs(sweep)):g} deg, more than "
            f"joint {truth.n}'s range"
        )
    q0 = rng.uniform(lo, hi, (g, truth.n))
    q0[:, -1] = rng.uniform(lo[-1] - min(sweep, 0), hi[-1] - max(sweep, 0), g)
    q = np.repeat(q0[:, None, :], m, axis=1)
    q[:, :, -1] += step_rad * np.arange(m)
    p = default_target(truth) if target is None else np.asarray(target, dtype=float)
    E = poe_chain(truth.screws, q.reshape(g * m, truth.n))[:, -1]
    X = np.eye(4) if sensor is None else np.asarray(sensor, dtype=float)
    pts = (E[:, :3, :3] @ p + E[:, :3, 3]) @ X[:3, :3].T + X[:3, 3]
    pts = pts.reshape(g, m, 3) + rng.normal(0.0, noise_mm, (g, m, 3))
    return CirclePointData(q, pts, tuple(f"c{i + 1:03d}" for i in range(g)), np.zeros(g, dtype=int))

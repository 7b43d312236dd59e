"""Identification of the laser robot's geometry from a capture session.

Two methods:

* ``thesis`` -- Section 3.2 as written: laser length estimated by eq. 3.2.19, p_Mz held
  at the session's measured ``aperture_z``, least-squares steps x = (K^T K)^-1 K^T z
  (eq. 3.1.18, solved with ``lstsq`` so that a rank-deficient K gives the minimum-norm
  step instead of a blown-up inverse), eta reset after every update, stop when |x| is small.
* ``lm`` (default) -- ours: the residual is the in-plane distance between where the
  model's beam meets the plane and the reference point, so the laser length drops out
  exactly; Levenberg-Marquardt (MINPACK through ``scipy.optimize.least_squares``) with the
  analytic Jacobian, restricted to the identifiable subspace found by an SVD of the
  column-scaled Jacobian at the start (unidentifiable combinations stay at their start
  value), and standard errors from that subspace. A first stage on the beam-to-point
  distance brings far-off starts (steep beams) into the basin. Robust loss: skipped least
  squares (a hard-redescending, truncated quadratic loss) -- each capture is tested by a
  chi-square test on its residual against a robust noise scale, flagged captures get weight
  zero, and test-and-refit repeats until the flagged set is stable. Flagged captures (an
  operator aiming at the wrong point) are reported by index.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from .errors import IdentificationError
from .laser import LaserParams, plane_hit
from .model import RobotModel
from .session import Session

_RANK_RTOL = 1e-6  # singular values of the column-scaled Jacobian below this fraction of the largest are unidentifiable
_OUTLIER_ALPHA = 0.01  # family-wise false-flag rate of the outlier test (Bonferroni over captures)


@dataclass(frozen=True)
class Identifiability:
    """What the data can and cannot see (SVD of the column-scaled Jacobian).

    Attributes
    ----------
    n_params : int
    rank : int
    condition : float, s_max / s_min over the identifiable subspace
    singular_values : (n_params,) array, of the column-scaled Jacobian
    unidentifiable : list of str, each null-space direction as its largest parameter components
    """

    n_params: int
    rank: int
    condition: float
    singular_values: np.ndarray
    unidentifiable: list


@dataclass(frozen=True, eq=False)
class Identification:
    """Result of an identification, carrying its history.

    Attributes
    ----------
    method : str, 'lm' or 'thesis'
    nominal, model : RobotModel, the start and the identified model
    converged : bool
    iterations : int, Jacobian evaluations (lm) or least-squares steps (thesis)
    history : tuple of dict, per iteration (lm: per pass) 'rms_mm' and 'step'
    residuals : (m, 2) array, identified spot minus target in the plane, mm
    weights : (m,) array, 1 for captures used, 0 for flagged outliers
    outliers : tuple of int, capture indices flagged as outliers (0-based)
    sigma_mm : float, per-axis aiming noise estimated from the residuals, mm
    identifiability : Identifiability
    std_errors : dict name -> float, standard errors of the parameters (mm or rad-like)
    param_names : list of str
    estimate : (p,) array, the identified parameter vector (in the nominal's link frames)
    seconds : float, wall time
    """

    method: str
    nominal: RobotModel
    model: RobotModel
    converged: bool
    iterations: int
    history: tuple
    residuals: np.ndarray
    weights: np.ndarray
    outliers: tuple
    sigma_mm: float
    identifiability: Identifiability
    std_errors: dict
    param_names: list
    estimate: np.ndarray
    seconds: float
    extra: dict = field(default_factory=dict)

    @property
    def rms_mm(self) -> float:
        """RMS in-plane residual over the captures used, mm."""
        w = self.weights > 0
        return float(np.sqrt(np.mean(np.sum(self.residuals[w] ** 2, axis=1))))


def spot_residuals(model: RobotModel, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Spot predicted by ``model`` minus the target, in the plane z = target_z, (m, 2) mm."""
    return predict_spots(model, q, target[:, 2])[0][:, :2] - target[:, :2]


def _start(nominal: RobotModel, session: Session) -> RobotModel:
    """The start model: nominal geometry with the measured aperture height p_Mz, if any."""
    if session.aperture_z is None:
        return nominal
    return nominal.replace(aperture=np.r_[nominal.aperture[:2], session.aperture_z])


def _identifiability(J: np.ndarray, names: list) -> tuple[Identifiability, np.ndarray, np.ndarray]:
    """SVD identifiability report; returns it with the column scales D and the basis V_r (scaled)."""
    scale = np.linalg.norm(J, axis=0)
    scale[scale < 1e-9 * scale.max()] = 1.0  # a column of round-off: do not blow it up to unit norm
    _, s, Vt = np.linalg.svd(J / scale, full_matrices=J.shape[0] < J.shape[1])  # never the (2m x 2m) U of a tall J
    s_full = np.zeros(J.shape[1])
    s_full[: len(s)] = s
    rank = int(np.sum(s_full > _RANK_RTOL * s_full[0]))
    null = []
    for v in Vt[rank:]:
        top = np.argsort(-np.abs(v))[:3]
        null.append(" ".join(f"{v[k]:+.2f}*{names[k]}" for k in top if abs(v[k]) > 0.05))
    report = Identifiability(J.shape[1], rank, float(s_full[0] / s_full[rank - 1]), s_full, null)
    return report, 1.0 / scale, Vt[:rank].T


def _covariance(Jz: np.ndarray, sigma: float) -> np.ndarray:
    """sigma^2 (Jz^T Jz)^-1 through the SVD of a full-column-rank Jz (never an explicit normal-matrix inverse)."""
    _, s, Vt = np.linalg.svd(Jz, full_matrices=False)
    return sigma**2 * (Vt.T / s**2) @ Vt


def _flag_outliers(res: np.ndarray, w: np.ndarray, dof_ratio: float) -> tuple[np.ndarray, float]:
    """Outlier mask by a chi-square(2) test on |residual| / sigma, sigma from the median (robust).

    The median of a Rayleigh distance is sigma * sqrt(2 ln 2); the threshold is Bonferroni-corrected
    so that a clean session of m captures is flagged with probability about ``_OUTLIER_ALPHA``.
    """
    r = np.linalg.norm(res, axis=1)
    sigma = float(np.median(r[w > 0]) / np.sqrt(2 * np.log(2)) / np.sqrt(dof_ratio))
    m = len(r)
    cut = sigma * np.sqrt(stats.chi2.ppf(1 - _OUTLIER_ALPHA / m, 2)) * np.sqrt(dof_ratio)
    return r > max(cut, 1e-4), sigma  # 0.1 um floor: exact data has round-off, not outliers


def identify_lm(session: Session, nominal: RobotModel | None = None, robust: bool = True) -> Identification:
    """Levenberg-Marquardt on in-plane spot residuals in the identifiable subspace (method ``lm``).

    Parameters
    ----------
    session : Session
    nominal : RobotModel, start model (default: the session's robot)
    robust : bool, flag outliers and refit without them

    Returns
    -------
    Identification
    """
    t0 = time.perf_counter()
    nominal = nominal or session.robot
    start = _start(nominal, session)
    P = LaserParams(start)
    q, target = session.q, session.target
    m, p = len(q), P.size
    if 2 * m <= 8:
        raise IdentificationError(f"{m} captures are far too few to identify {p} parameters")
    x0 = P.x0()
    _, _, J0 = P.spot_jacobian(x0, q, target[:, 2])
    ident, D, Vr = _identifiability(J0.reshape(2 * m, p), P.names)
    basis = D[:, None] * Vr  # x = x0 + basis @ z
    r = basis.shape[1]

    def fun(z, sw):
        spot, _ = P.spots(x0 + basis @ z, q, target[:, 2])
        return ((spot[:, :2] - target[:, :2]) * sw[:, None]).ravel()

    def jac(z, sw):
        _, _, J = P.spot_jacobian(x0 + basis @ z, q, target[:, 2])
        return (J * sw[:, None, None]).reshape(2 * m, p) @ basis

    def fun_line(z):
        return P.line_jacobian(x0 + basis @ z, q, target)[0].ravel()

    def jac_line(z):
        return P.line_jacobian(x0 + basis @ z, q, target)[1].reshape(3 * m, p) @ basis

    history, iterations = [], 0

    def run(z, w, method="lm", **kw):
        nonlocal iterations
        sw = np.sqrt(w)
        sol = optimize.least_squares(fun, z, jac, args=(sw,), method=method, xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200, **kw)
        iterations += sol.njev
        res = fun(sol.x, np.ones(m)).reshape(m, 2)
        history.append({"pass": len(history), "method": method, "rms_mm": float(np.sqrt(np.mean(np.sum(res[w > 0] ** 2, 1)))), "iterations": int(sol.njev), "status": int(sol.status)})
        return sol, res

    dof_ratio = max(1 - r / (2 * m), 0.05)
    w = np.ones(m)
    if robust:  # gross outliers (a wrong point) already stand out against the nominal model: keep them out of the start
        flags, _ = _flag_outliers(spot_residuals(start, q, target), w, 1.0)
        w = np.where(flags, 0.0, 1.0)
    # Stage 1: the beam-to-point distance brings a far-off start (steep beams) into the basin of stage 2.
    sw = np.sqrt(w)[:, None]
    first = optimize.least_squares(lambda z: (fun_line(z).reshape(m, 3) * sw).ravel(), np.zeros(r),
                                   lambda z: (jac_line(z).reshape(m, 3, r) * sw[:, :, None]).reshape(3 * m, r),
                                   method="lm", xtol=1e-10, ftol=1e-10, max_nfev=100)
    iterations += first.njev
    history.append({"pass": 0, "method": "lm (beam distance)", "rms_mm": float(np.sqrt(np.mean(first.fun**2) * 3)), "iterations": int(first.njev), "status": int(first.status)})
    sol, res = run(first.x, w)
    if robust:  # skipped least squares: test every capture against the fit of the others, refit, until stable
        for _ in range(5):
            flags, _ = _flag_outliers(res, w, dof_ratio)
            if np.array_equal(flags, w == 0):
                break
            w = np.where(flags, 0.0, 1.0)
            sol, res = run(sol.x, w)
    x = x0 + basis @ sol.x
    used = w > 0
    dof = 2 * used.sum() - r
    if dof <= 0:
        raise IdentificationError(f"{used.sum()} usable captures cannot identify {r} parameter combinations")
    sigma = float(np.sqrt(np.sum(res[used] ** 2) / dof))  # per-axis noise
    Jz = jac(sol.x, np.sqrt(w))
    cov_x = basis @ _covariance(Jz, sigma) @ basis.T
    se = dict(zip(P.names, np.sqrt(np.clip(np.diag(cov_x), 0, None)).tolist()))
    converged = bool(sol.status > 0)
    meta = {"method": "lm", "converged": converged, "iterations": iterations, "rank": ident.rank, "n_params": p}
    return Identification(
        "lm", nominal, P.to_model(x, identification=meta), converged, iterations, tuple(history), res, w,
        tuple(int(i) for i in np.flatnonzero(~used)), sigma, ident, se, P.names, x, time.perf_counter() - t0,
        {"cov": cov_x},
    )


def identify_thesis(session: Session, nominal: RobotModel | None = None, max_iter: int = 500, tol: float = 1e-10) -> Identification:
    """The thesis's algorithm (Section 3.2, Figure 3.4) as written.

    Parameters
    ----------
    session : Session
    nominal : RobotModel, start model (default: the session's robot)
    max_iter : int, the thesis reports 500 iterations in Simulation 1
    tol : float, stop when |x| < tol (x mixes rad-like eta and mm, as in the thesis)

    Returns
    -------
    Identification
    """
    t0 = time.perf_counter()
    nominal = nominal or session.robot
    model = _start(nominal, session)
    q, target = session.q, session.target
    m = len(q)
    history = []
    converged = False
    for it in range(1, max_iter + 1):
        P = LaserParams(model)  # link frames recomputed: eta reset to zero (Section 3.2.2)
        x0 = P.x0()
        b = P.beam(x0, q)
        length = np.linalg.norm(target - b.aperture, axis=1)  # eq. 3.2.19
        tip = b.aperture + length[:, None] * b.direction  # eq. 3.1.4
        z = (target - tip).ravel()  # eq. 3.1.10
        _, K = P.tip_jacobian(x0, q, length)
        K = np.delete(K.reshape(3 * m, P.size), P.slice_M.start + 2, axis=1)  # p_Mz is held (Section 3.2.1)
        dx, _, rank, _ = np.linalg.lstsq(K, z, rcond=None)  # eq. 3.1.18
        step = np.insert(dx, P.slice_M.start + 2, 0.0)
        model = P.to_model(x0 + step)
        history.append({"iteration": it, "step_norm": float(np.linalg.norm(dx)), "tip_rms_mm": float(np.sqrt(np.mean(z**2) * 3)), "rank": int(rank)})
        if np.linalg.norm(dx) < tol:
            converged = True
            break
    res = spot_residuals(model, q, target)
    Pn = LaserParams(model)
    _, _, J = Pn.spot_jacobian(Pn.x0(), q, target[:, 2])
    ident, _, _ = _identifiability(J.reshape(2 * m, Pn.size), Pn.names)
    sigma = float(np.sqrt(np.sum(res**2) / max(2 * m - ident.rank, 1)))
    meta = {"method": "thesis", "converged": converged, "iterations": len(history)}
    model = model.replace(identification=meta)
    return Identification(
        "thesis", nominal, model, converged, len(history), tuple(history), res, np.ones(m), (), sigma, ident, {}, Pn.names,
        Pn.x0(), time.perf_counter() - t0,
    )


def identify(session: Session, method: str = "lm", nominal: RobotModel | None = None, **kw) -> Identification:
    """Identify the geometry by ``method`` ('lm' or 'thesis')."""
    if method == "lm":
        return identify_lm(session, nominal, **kw)
    if method == "thesis":
        return identify_thesis(session, nominal, **kw)
    raise IdentificationError(f"unknown method {method!r} (choose lm or thesis)")


def predict_spots(model: RobotModel, q: np.ndarray, z: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the model's beam meets the plane z: spots (m, 3) and laser lengths (m,), mm."""
    P = LaserParams(model)
    b = P.beam(P.x0(), q)
    return plane_hit(b.aperture, b.direction, z)

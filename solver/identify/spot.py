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
from scipy import optimize

from lasercal.solver.errors import IdentificationError
from lasercal.solver.formats.session import Session
from lasercal.solver.identify.lsq import Identifiability, fit_subspace, flag_outliers, identifiability
from lasercal.solver.identify.prior import Prior, Tolerances, make_prior
from lasercal.solver.kinematics.effects import Extension, require
from lasercal.solver.kinematics.laser import LaserParams, plane_hit, spot_joint_jacobian
from lasercal.solver.kinematics.minimal import anchor_heights
from lasercal.solver.kinematics.model import RobotModel


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
    extra : dict, e.g. 'cov' the parameter covariance (p, p), 'prior' the Prior of a MAP fit (or None)
    extension : Extension or None, the fitted non-geometric effect with standard errors
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
    extension: Extension | None = None

    @classmethod
    def from_fit(cls, nominal, model, fit, names, se, t0: float, extra: dict, extension=None, **override):
        """An ``lm`` identification from a least-squares fit (:func:`.lsq.fit_subspace`).

        Parameters
        ----------
        nominal, model : RobotModel, the start and the identified model
        fit : the least-squares result (converged, iterations, history, residuals, weights, sigma, v, ...)
        names : list of str; se : (p,) array, the standard error of each parameter
        t0 : float, ``time.perf_counter()`` when the identification started
        extra : dict, covariance, spans, identified points (the fit's prior is added as 'prior')
        extension : the fitted extension, or None
        override : fields that differ from the fit's (e.g. iterations over several stages)
        """
        kw = {
            "method": "lm",
            "nominal": nominal,
            "model": model,
            "converged": fit.converged,
            "iterations": fit.iterations,
            "history": tuple(fit.history),
            "residuals": fit.residuals,
            "weights": fit.weights,
            "outliers": tuple(int(i) for i in np.flatnonzero(fit.weights == 0)),
            "sigma_mm": fit.sigma,
            "identifiability": fit.identifiability,
            "std_errors": dict(zip(names, se.tolist())),
            "param_names": names,
            "estimate": fit.v,
            "seconds": time.perf_counter() - t0,
            "extra": {**extra, "prior": fit.prior},
            "extension": extension,
        }
        return cls(**{**kw, **override})

    @property
    def rms_mm(self) -> float:
        """RMS residual (in the plane, or 3-D for point sessions) over the captures used, mm."""
        w = self.weights > 0
        return float(np.sqrt(np.mean(np.sum(self.residuals[w] ** 2, axis=1))))


def laser_prior(P: LaserParams, tolerances: Tolerances | None, extension=None) -> Prior | None:
    """The prior of a laser robot's parameters (and an extension's, mean 0) about P's reference model
    (eq. P1 of :mod:`solver.identify.prior`, axis positions anchored at the joints); None without
    ``tolerances``."""
    ext = ([], 0) if extension is None else (extension.kinds, extension.size)
    return make_prior(
        tolerances,
        P.kinds + ext[0],
        np.r_[P.x0(), np.zeros(ext[1])],
        "laser",
        P.names,
        P.model.joint_names,
        anchor_heights(P.model.screws, P.model.aperture),
    )


def spot_residuals(model: RobotModel, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Spot predicted by ``model`` minus the target, in the plane z = target_z, (m, 2) mm."""
    return predict_spots(model, q, target[:, 2])[0][:, :2] - target[:, :2]


def _start(nominal: RobotModel, session: Session) -> RobotModel:
    """The start model: nominal geometry with the measured aperture height p_Mz, if any."""
    if session.aperture_z is None:
        return nominal
    return nominal.replace(aperture=np.r_[nominal.aperture[:2], session.aperture_z])


def _aperture_gauge(
    P: LaserParams, v: np.ndarray, cov: np.ndarray, aperture_z: float | None
) -> tuple[np.ndarray, np.ndarray]:
    """Slide the aperture along the beam to the measured height p_Mz (Section 3.2.1).

    The aperture's position along the beam is invisible to spot data, so the estimate and
    its covariance are only defined once that gauge is fixed; this fixes it without changing
    any prediction, and maps the covariance through the gauge map's Jacobian.
    """
    if aperture_z is None:
        return v, cov

    def gauge(u):
        _, _, vp, _, pM = P.geometry(u)
        out = u.copy()
        out[P.slice_M] = pM + (aperture_z - pM[2]) / vp[2] * vp
        return out

    if abs(P.geometry(v)[2][2]) < 1e-3:  # a near-horizontal beam: the height does not fix the gauge
        return v, cov
    G = np.eye(len(v))
    cols = list(range(P.slice_laser.start, P.slice_M.stop))
    h = 1e-7
    for c in cols:
        e = np.zeros(len(v))
        e[c] = h
        G[:, c] = (gauge(v + e) - gauge(v - e)) / (2 * h)
    return gauge(v), G @ cov @ G.T


def identify_lm(
    session: Session,
    nominal: RobotModel | None = None,
    robust: bool = True,
    extension: Extension | None = None,
    suspects: np.ndarray | None = None,
) -> Identification:
    """Levenberg-Marquardt on in-plane spot residuals in the identifiable subspace (method ``lm``).

    Parameters
    ----------
    session : Session
    nominal : RobotModel, start model (default: the session's robot)
    robust : bool, flag outliers and refit without them
    extension : Extension, optional non-geometric effect identified jointly with the geometry
        (its parameters start at zero; a compliance extension uses the session's torques)
    suspects : (m,) bool array, optional: the only captures the outlier test may flag (an extension fitted
        on its geometric fit's rows: that fit's outliers; :func:`solver.identify.lsq.fit_subspace`)

    Returns
    -------
    Identification
    """
    t0 = time.perf_counter()
    nominal = nominal or session.robot
    start = _start(nominal, session)
    P = LaserParams(start)
    q, target, t, tau = session.q, session.target, session.t, session.tau
    m, p = len(q), P.size
    k = extension.size if extension else 0
    if extension:
        require(extension, t, tau)
    if 2 * m <= 8:
        raise IdentificationError(f"{m} captures are far too few to identify {p + k} parameters")
    names = P.names + (extension.names if extension else [])

    def model_inputs(v):
        """True configurations and in-plane targets under parameters v = [x, theta]."""
        if not extension:
            return q, target[:, :2]
        e = extension.with_params(v[p:])
        return e.true_q(q, t, tau), target[:, :2] + e.target_offset(session.point)

    def residual(v):
        qt, tg = model_inputs(v)
        spot, _ = P.spots(v[:p], qt, target[:, 2])
        return spot[:, :2] - tg

    def jacobian(v):
        qt, _ = model_inputs(v)
        _, _, J = P.spot_jacobian(v[:p], qt, target[:, 2])
        if not extension:
            return J
        if extension.effect == "reference_point_offset":
            Je = np.zeros((m, 2, 2))
            Je[session.point == extension.point] = -np.eye(2)
        else:
            idx, G = extension.regressors(q, t, tau)
            _, Jq = spot_joint_jacobian(P.to_model(v[:p]), qt, target[:, 2])
            Je = Jq[:, :, idx] * G[:, None, :]
        return np.concatenate([J, Je], axis=2)

    history, iterations = [], 0
    w = np.ones(m)
    # gross outliers (a wrong point) already stand out against the nominal model: keep them out of the start
    if robust:
        flags, _ = flag_outliers(spot_residuals(start, q, target), w)
        w = np.where(flags, 0.0, 1.0)
    x0 = P.x0()
    prior = laser_prior(P, session.tolerances, extension)

    # Stage 1 (geometry only): the beam-to-point distance brings a far-off start (steep beams) into the basin
    # of stage 2; with a prior, its rows (at the nominal noise) join in, as in stage 2.
    _, _, J0 = P.spot_jacobian(x0, q, target[:, 2])
    geo_prior = laser_prior(P, session.tolerances)
    pr = [] if geo_prior is None else [geo_prior.rows(x0, geo_prior.noise)[1]]
    _, B1 = identifiability(np.vstack([J0.reshape(2 * m, p)] + pr), P.names)
    sw = np.sqrt(w)[:, None, None]

    def line(z):
        x = x0 + B1 @ z
        r, J = P.line_jacobian(x, q, target)
        r, J = (r[:, :, None] * sw)[..., 0].ravel(), (J * sw).reshape(3 * m, p)
        if geo_prior is not None:
            rp, Jp = geo_prior.rows(x, geo_prior.noise)
            r, J = np.r_[r, rp], np.vstack([J, Jp])
        return r, J @ B1

    first = optimize.least_squares(
        lambda z: line(z)[0],
        np.zeros(B1.shape[1]),
        lambda z: line(z)[1],
        method="lm",
        xtol=1e-10,
        ftol=1e-10,
        max_nfev=100,
    )
    iterations += first.njev
    history.append(
        {
            "pass": 0,
            "method": "lm (beam distance)",
            "rms_mm": float(np.sqrt(np.mean(first.fun[: 3 * m] ** 2) * 3)),
            "iterations": int(first.njev),
            "status": int(first.status),
        }
    )

    # Stage 2: in-plane residuals, geometry and extension together, in the identifiable subspace at the
    # stage-1 solution (MAP with the session's prior, eqs. P2-P4 of solver.identify.prior).
    v1 = np.r_[x0 + B1 @ first.x, np.zeros(k)]
    fit = fit_subspace(residual, jacobian, v1, names, robust, w, suspects=suspects, prior=prior)
    iterations += fit.iterations
    history += fit.history
    v, cov = _aperture_gauge(P, fit.v, fit.cov, session.aperture_z)
    se_all = np.sqrt(np.clip(np.diag(cov), 0, None))
    meta = {
        "method": "lm",
        "converged": fit.converged,
        "iterations": iterations,
        "rank": fit.identifiability.rank,
        "n_params": p + k,
    }
    fitted = extension.with_params(v[p:], se_all[p:]) if extension else None
    extensions = fitted.model_entries() if fitted and fitted.acts_on_joints else {}
    model = P.to_model(v[:p], identification=meta, extensions=extensions)
    return Identification.from_fit(
        nominal,
        model,
        fit,
        names,
        se_all,
        t0,
        {
            "cov": cov,
            "span": fit.span,
            "constraint_span": fit.constraint_span,
            "constraint_residuals": fit.constraint_residuals,
        },
        fitted,
        iterations=iterations,
        history=tuple(history),
        estimate=v,
    )


def identify_thesis(
    session: Session, nominal: RobotModel | None = None, max_iter: int = 500, tol: float = 1e-10
) -> Identification:
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
        history.append(
            {
                "iteration": it,
                "step_norm": float(np.linalg.norm(dx)),
                "tip_rms_mm": float(np.sqrt(np.mean(z**2) * 3)),
                "rank": int(rank),
            }
        )
        if np.linalg.norm(dx) < tol:
            converged = True
            break
    res = spot_residuals(model, q, target)
    Pn = LaserParams(model)
    _, _, J = Pn.spot_jacobian(Pn.x0(), q, target[:, 2])
    ident, _ = identifiability(J.reshape(2 * m, Pn.size), Pn.names)
    sigma = float(np.sqrt(np.sum(res**2) / max(2 * m - ident.rank, 1)))
    meta = {"method": "thesis", "converged": converged, "iterations": len(history)}
    model = model.replace(identification=meta)
    return Identification(
        "thesis",
        nominal,
        model,
        converged,
        len(history),
        tuple(history),
        res,
        np.ones(m),
        (),
        sigma,
        ident,
        {},
        Pn.names,
        Pn.x0(),
        time.perf_counter() - t0,
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

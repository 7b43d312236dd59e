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
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import optimize

from lasercal.solver.errors import IdentificationError
from lasercal.solver.formats.session import Session
from lasercal.solver.formats.tolerances import Tolerances
from lasercal.solver.identify.laser_parameters import (
    NSHEET,
    NWARP,
    SHAPE_KINDS,
    SHEET_KINDS,
    WARP_KINDS,
    CountedParameters,
    counted_parameters,
)
from lasercal.solver.identify.lsq import Identifiability, fit_subspace, flag_outliers, identifiability
from lasercal.solver.identify.prior import Prior, make_prior
from lasercal.solver.kinematics.effects import Extension, require
from lasercal.solver.kinematics.laser import LaserParams, plane_hit, spot_joint_jacobian
from lasercal.solver.kinematics.minimal import anchor_heights
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.parallax import parallax_rows, relative_height_basis
from lasercal.solver.kinematics.sheet import KEYS as SHEET_KEYS
from lasercal.solver.kinematics.sheet import (
    NFULL,
    SCALE_KEYS,
    SHAPE_KEYS,
    TILT_KEYS,
    SheetPose,
    sheet_residual,
    sheet_to_base,
)


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


def laser_prior(
    P: LaserParams, tolerances: Tolerances | None, kinds=(), mean=(), names=(), free=None
) -> Prior | None:
    """The prior of a laser robot's parameters about P's reference model, followed by more parameters
    (the sheet's pose, an extension's) of the given kinds, means and names (eq. P1 of
    :mod:`solver.identify.prior`, axis positions anchored at the joints); ``free`` selects the parameters
    fitted (default all). None without ``tolerances``."""
    kinds, names, mean = P.kinds + list(kinds), P.names + list(names), np.r_[P.x0(), mean]
    free = np.arange(len(kinds)) if free is None else free
    return make_prior(
        tolerances,
        [kinds[i] for i in free],
        mean[free],
        "laser",
        [names[i] for i in free],
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


def rigid_2d(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """The rotation angle (rad) and translation (2,) with b ~ R a + t, least squares (Kabsch in the plane).

    Parameters
    ----------
    a, b : (k, 2) arrays, k >= 2 (not all coincident)
    """
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    A, B = a - ma, b - mb
    yaw = float(np.arctan2(np.sum(A[:, 0] * B[:, 1] - A[:, 1] * B[:, 0]), np.sum(A * B)))
    c, s = np.cos(yaw), np.sin(yaw)
    return yaw, mb - np.array([[c, -s], [s, c]]) @ ma


def sheet_start(session: Session, model: RobotModel) -> SheetPose:
    """The sheet's pose that best matches ``model``'s spots: each point's mean spot against its sheet
    coordinates (:func:`rigid_2d`). The start of a sheet session's fit, and the nominal model's pose."""
    spots, _ = predict_spots(model, session.q, session.target[:, 2])
    names = list(dict.fromkeys(session.point))
    mean = np.array([spots[session.point == nm, :2].mean(axis=0) for nm in names])
    yaw, t = rigid_2d(np.array([session.points[nm][:2] for nm in names]), mean)
    return SheetPose(float(t[0]), float(t[1]), float(np.degrees(yaw)))


def camera_warp_rows(uv: np.ndarray, measured: np.ndarray, anchors: np.ndarray | None = None) -> np.ndarray:
    """Eq. S7's rows (m, 2, 6): d(residual)/d(a_xx, a_xy, a_yy, b_xx, b_xy, b_yy) at layout points uv (m, 2)
    mm, the measured captures' (zero for aimed ones).

    A camera that maps the paper through its markers' homography takes the paper for a plane: a spot on
    paper raised by h(s) (eq. S6) lies, in the photo, where the plane's point h(s) w further from the camera
    does (w the horizontal over the vertical distance from the camera: parallax). The homography is exact
    at the markers; between them the measured spot is displaced by a smooth field, to second order

        m = s + 1/2 [s^T A s, s^T B s] - L(s),   A = [[a_xx, a_xy], [a_xy, a_yy]], B likewise     (eq. S7)

    in mm (A, B in 1/mm), L the affine map that best matches the quadratic at the ``anchors`` (the sheet's
    marker centres, layout mm; None: the measured spots themselves): the field vanishes where the homography
    was fitted, so it does not move the sheet's pose. It is the capture camera's, a session effect: fitted
    with the sheet's shape, reported, never applied to where the arm aims (``validate`` has its own camera).
    """
    meas = np.asarray(measured, dtype=bool)
    anchors = uv[meas] if anchors is None or len(anchors) < 3 else anchors
    q = relative_height_basis(uv, anchors) * meas[:, None]  # the quadratic less its affine part (eq. S8)
    W = np.zeros((len(uv), 2, 6))
    W[:, 0, :3], W[:, 1, 3:] = q, q
    return W


def marker_corners(session: Session) -> np.ndarray | None:
    """The corners (k, 4, 2) mm, layout frame, of the markers of the layout a sheet session names (None: not
    found): where a camera's homography is fitted (eqs. S7, S8)."""
    from pathlib import Path

    import yaml

    coll = session.meta.get("collector") if isinstance(session.meta, dict) else None
    name = coll.get("layout") if isinstance(coll, dict) else None  # where capture recorded its layout
    if not name or session.path is None:
        return None
    path = Path(session.path) / name
    try:
        ids = (yaml.safe_load(path.read_text()) or {}).get("markers", {}).get("ids", {})
        out = np.array([np.asarray(c, dtype=float) for c in ids.values()])
    except (OSError, yaml.YAMLError, AttributeError, TypeError, ValueError):
        return None
    ok = out.ndim == 3 and out.shape[1:] == (4, 2) and len(out) >= 3 and np.isfinite(out).all()
    return out if ok else None


def marker_centres(session: Session) -> np.ndarray | None:
    """The centres (k, 2) mm of :func:`marker_corners` (eq. S7's anchors), or None."""
    corners = marker_corners(session)
    return None if corners is None else corners.mean(axis=1)


CURL = slice(8, 11)  # kxx, kxy, kyy in a sheet's full vector (eq. S6; SheetPose.curl)


def session_eyes(session: Session) -> np.ndarray | None:
    """Where the camera stood for each capture (m, 3) mm, layout frame (eq. S8), or None when no measured
    photo told it (an older session, the solver's own simulations). A measured photo whose markers could
    not tell (a square-on view) takes the median of those that did: the session's camera, which a
    hands-free or a tripod's camera does not move."""
    eye, meas = session.camera_eye, session.measured
    told = meas & np.all(np.isfinite(eye), axis=1) if eye is not None else np.zeros(session.m, bool)
    if not told.any():
        return None
    out = np.where(np.isfinite(eye), eye, np.median(eye[told], axis=0))
    return out


def camera_view_rows(session: Session) -> np.ndarray | None:
    """Eq. S8's rows (m, 2, 3) of a sheet session's measured spots (zero for aimed captures): d(seen -
    true)/d(kxx, kxy, kyy) from where each photo's camera stood; None without an eye or the markers."""
    eye = session_eyes(session) if session.frame == "sheet" else None
    corners = marker_corners(session) if eye is not None else None
    if eye is None or corners is None:
        return None
    return parallax_rows(session.target[:, :2], eye, corners.reshape(-1, 2)) * session.measured[:, None, None]


def camera_view(session: Session, pose: SheetPose | None) -> np.ndarray | float:
    """The measured spots' parallax (m, 2) mm under ``pose``'s curl (eq. S8: :func:`camera_view_rows`), or
    0.0 where nothing makes one (a flat sheet, no camera's eye, a base-frame session)."""
    curl = pose.curl if pose is not None else np.zeros(3)
    rows = camera_view_rows(session) if np.any(curl) else None
    return 0.0 if rows is None else rows @ curl


def placed_targets(session: Session, pose: SheetPose) -> np.ndarray:
    """A sheet session's reference points (m, 3) in the base frame with the sheet at ``pose`` (eq. S1):
    its ``target`` holds x, y on the sheet and the plane's height in the base frame."""
    return pose.to_base(session.target[:, :2], session.target[:, 2])


def base_targets(session: Session, model: RobotModel) -> np.ndarray:
    """The captures' reference points (m, 3) in the base frame: a sheet session's through ``model``'s sheet
    pose (eq. S1; a model without one, e.g. the nominal, through :func:`sheet_start`)."""
    if session.frame != "sheet":
        return session.target
    return placed_targets(session, model.sheet or sheet_start(session, model))


def plane_residuals(model: RobotModel, q: np.ndarray, session: Session) -> np.ndarray:
    """A laser session's residuals (m, 2) mm of ``model`` at configurations q (m, n): spot minus point in
    the plane, a sheet session's in the sheet's own units (eq. S4) with the model's sheet pose (or
    :func:`sheet_start`'s), as ``lm`` fits them."""
    if session.frame != "sheet":
        return spot_residuals(model, q, session.target)
    pose = model.sheet or sheet_start(session, model)
    r = sheet_residual(pose.vector, spot_residuals(model, q, placed_targets(session, pose)))[0]
    return r + camera_view(session, pose)  # the measured spot is where the camera saw it (eq. S8)


def in_base_frame(session: Session, pose: SheetPose) -> Session:
    """A sheet session as a base-frame one, its points placed by ``pose`` (eq. S1): for what assumes the
    points are known in the base frame (the capture coach's posterior)."""
    points = {k: pose.to_base(v[None], session.plane_z)[0] for k, v in session.points.items()}
    return replace(session, points=points, target=placed_targets(session, pose), frame="base", sheet=None)


KIND_PASSES = 8  # at most this many refits for the noise of each kind (eq. K2; 3-4 usually)
KIND_RTOL = 0.02  # ... until each kind's noise changes less than this (relative)


def fit_kinds(session: Session, residual, jacobian, v0, names, prior_at, robust, w, suspects):
    """A camera session's fit: a measured capture to its spot with its own uncertainty, an aimed one to its
    cross with the aiming noise, each kind's noise found from its residuals (eqs. K1, K2).

    Eq. K1: capture i's residual is divided by c_i = s_i / s_ref, where s_i^2 = u_i^2 + s_m^2 for a
    measured capture (u_i its stated uncertainty, s_m the noise the camera does not see: the arm's
    repeatability, what the model lacks) and s_i = s_a (the aiming noise) for an aimed one; s_ref is s_a
    when the session has aimed captures, else the RMS of the measured s_i, and the prior's noise
    (:mod:`solver.identify.prior`, eq. P3) is s_ref. Eq. K2: from capture i's residual r_i and its
    leverage h_i (E|r_i|^2 = (d - h_i) s_i^2): s_a^2 = sum |r_i|^2 / sum (d - h_i) over the aimed, and
    s_m^2 = max(0, sum (|r_i|^2 - (d - h_i) u_i^2) / sum (d - h_i)) over the measured; refit until both
    settle.

    Parameters
    ----------
    session : Session, with ``spot_sigma``
    residual, jacobian : the fit's functions of the free parameters (mm; (m, 2) and (m, 2, p))
    v0 : (p,) array, the start
    names : list of str
    prior_at : callable s_ref (mm) -> Prior or None
    robust, w, suspects : as :func:`solver.identify.lsq.fit_subspace`

    Returns
    -------
    fit : SubspaceFit, on the scaled residuals (its ``sigma``: s_ref's estimate)
    scale : (m,) array, c_i
    noise : dict, ``aimed_mm`` (s_a; None without aimed captures), ``measured_mm`` (RMS of the measured
        s_i), ``camera_mm`` (RMS of u_i), ``unseen_mm`` (s_m), ``measured``, ``aimed`` (counts)
    """
    meas = session.measured
    aimed = ~meas
    u = np.where(meas, session.spot_sigma, 0.0)
    prior0 = prior_at(1.0)
    s_a = prior0.noise if prior0 is not None else 1.0  # the prior's nominal aiming noise to start
    s_m = float(np.sqrt(np.mean(u[meas] ** 2)))  # the camera's own, to start
    d = 2
    for _ in range(KIND_PASSES):
        tot = np.sqrt(u**2 + s_m**2)
        ref = s_a if aimed.any() else float(np.sqrt(np.mean(tot[meas] ** 2)))
        scale = np.where(meas, tot / ref, 1.0)
        fit = fit_subspace(
            lambda v, c=scale: residual(v) / c[:, None],
            lambda v, c=scale: jacobian(v) / c[:, None, None],
            v0,
            names,
            robust,
            w,
            groups=meas,  # each kind's outliers against its own noise
            suspects=suspects,
            prior=prior_at(ref),
        )
        r2 = np.sum((fit.residuals * scale[:, None]) ** 2, axis=1)
        free_rows = d - fit.leverage  # E|r_i|^2 = (d - h_i) s_i^2
        used = fit.weights > 0
        a, g = used & aimed, used & meas
        new_a = float(np.sqrt(r2[a].sum() / max(free_rows[a].sum(), 1e-9))) if a.any() else s_a
        new_m = s_m
        if g.any():  # (every measured capture flagged: nothing to learn their noise from)
            unseen = max((r2[g] - free_rows[g] * u[g] ** 2).sum(), 0.0) / max(free_rows[g].sum(), 1e-9)
            new_m = float(np.sqrt(unseen))
        typical = np.sqrt(s_m**2 + np.mean(u[meas] ** 2))
        done = abs(new_a / s_a - 1) < KIND_RTOL and abs(new_m - s_m) < KIND_RTOL * typical
        s_a, s_m, v0 = new_a, new_m, fit.v
        if done:
            break
    tot = np.sqrt(u**2 + s_m**2)
    noise = {
        "aimed_mm": float(s_a) if aimed.any() else None,
        "measured_mm": float(np.sqrt(np.mean(tot[meas] ** 2))),
        "camera_mm": float(np.sqrt(np.mean(u[meas] ** 2))),
        "unseen_mm": float(s_m),
        "measured": int(meas.sum()),
        "aimed": int(aimed.sum()),
    }
    return fit, scale, noise


@dataclass(frozen=True, eq=False)
class SpotProblem:
    """Method ``lm``'s problem: the parameters u = [x, pose, warp, theta] (the laser robot's p, the sheet's
    pose nsh (eq. S1; with the shape, eqs. S5, S6), the camera warp's nw (eq. S7), the extension's), of which
    ``counted.free`` are fitted and the rest held at ``u0``, and the in-plane residual of free values v.

    Attributes
    ----------
    session : Session
    P : LaserParams, at the start model
    extension : Extension or None
    shape : bool, the sheet's shear and height field fitted (a sheet session)
    nsh, nw : int, the sheet's and the camera warp's parameter counts (0: none)
    W : (m, 2, nw) array, eq. S7's rows (None without the warp)
    V : (m, 2, 3) array, eq. S8's rows on the curl's terms, the camera's view from where each photo's
        markers put it (None: no shape, or no eye told; then eq. S7's free warp where a camera measured)
    pose0 : SheetPose, the sheet's start (None: a base-frame session)
    base0 : (m, 3) array, the reference points in the base frame with the sheet at ``pose0``, mm
    u0 : (len(counted.names),) array, the start (mm, rad-like)
    counted : CountedParameters, the names, the held and the free parameters
    kinds : list of str, the prior's kinds of the parameters after the laser robot's
    """

    session: Session
    P: LaserParams
    extension: Extension | None
    shape: bool
    nsh: int
    nw: int
    W: np.ndarray | None
    pose0: SheetPose | None
    base0: np.ndarray
    u0: np.ndarray
    counted: CountedParameters
    kinds: list
    V: np.ndarray | None = None

    @property
    def p(self) -> int:
        return self.P.size

    @property
    def pe(self) -> int:
        """Where the extension's parameters start."""
        return self.p + self.nsh + self.nw

    @property
    def sheet(self) -> bool:
        return self.pose0 is not None

    @property
    def free(self) -> np.ndarray:
        return self.counted.free

    @property
    def names(self) -> list:
        """The free parameters' names."""
        return [self.counted.names[i] for i in self.free]

    def embed(self, v: np.ndarray) -> np.ndarray:
        """All parameters u from the free ones v (the held at their start)."""
        u = self.u0.copy()
        u[self.free] = v
        return u

    def prior(self, tolerances: Tolerances | None) -> Prior | None:
        """The prior of the free parameters (eq. P1 of :mod:`solver.identify.prior`; :func:`laser_prior`)."""
        p, names = self.p, list(self.counted.names)
        return laser_prior(self.P, tolerances, self.kinds, self.u0[p:], names[p:], self.free)

    def model_inputs(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """True configurations, in-plane base-frame targets and the plane's height at each (eqs. S1, S3)
        under parameters u = [x, pose, theta]."""
        s, p, ext = self.session, self.p, self.extension
        placed = (
            sheet_to_base(u[p : p + self.nsh], s.target[:, :2], s.target[:, 2])[0] if self.sheet else s.target
        )
        qt = ext.with_params(u[self.pe :]).true_q(s.q, s.t, s.tau) if ext else s.q
        return qt, placed[:, :2], placed[:, 2]

    def offset(self, u: np.ndarray) -> np.ndarray | float:
        """A reference point's offset (m, 2) mm, in the residual's frame (a sheet's: its own units)."""
        ext = self.extension
        return (
            ext.with_params(u[self.pe :]).target_offset(self.session.point, ~self.session.measured)
            if ext
            else 0.0
        )

    def residual(self, v: np.ndarray) -> np.ndarray:
        """The in-plane residual (m, 2) mm of free parameters v: spot minus point (eq. S4 for a sheet, its
        own units), less the reference point's offset, plus the camera warp (eq. S7)."""
        u, p, nsh = self.embed(v), self.p, self.nsh
        qt, tg, z = self.model_inputs(u)
        spot, _ = self.P.spots(u[:p], qt, z)
        r = spot[:, :2] - tg
        warp = self.W @ u[p + nsh : self.pe] if self.nw else 0.0  # eq. S7: the measured spot's offset
        if self.V is not None:  # eq. S8: the camera's view of the curl, from where it stood
            warp = self.V @ u[p : p + nsh][CURL]
        return (sheet_residual(u[p : p + nsh], r)[0] if self.sheet else r) - self.offset(u) + warp

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        """d :meth:`residual` / dv, (m, 2, len(v))."""
        s, P, ext, p, nsh = self.session, self.P, self.extension, self.p, self.nsh
        u = self.embed(v)
        qt, tg, z = self.model_inputs(u)
        spot, _, J = P.spot_jacobian(u[:p], qt, z)
        cols = [J]
        if self.sheet:  # the target moves in the plane; the plane's height moves the spot along the beam
            Js = sheet_to_base(u[p : p + nsh], s.target[:, :2], s.target[:, 2])[1]
            d = P.beam(u[:p], qt).direction
            cols.append(-Js[:, :2] + (d[:, :2] / d[:, 2:])[:, :, None] * Js[:, 2:3])
        if ext and ext.acts_on_joints:
            idx, G = ext.regressors(s.q, s.t, s.tau)
            _, Jq = spot_joint_jacobian(P.to_model(u[:p]), qt, z)
            cols.append(Jq[:, :, idx] * G[:, None, :])
        J = np.concatenate(cols, axis=2)
        if self.sheet:  # eq. S4: d(M r)/du = M dr/du + dM/du r
            _, M, dM = sheet_residual(u[p : p + nsh], spot[:, :2] - tg)
            J = np.einsum("ij,mjk->mik", M, J)
            J[:, :, p : p + nsh] += dM
        if self.V is not None:
            J[:, :, p + CURL.start : p + CURL.stop] += self.V
        if self.nw:
            J = np.concatenate([J[:, :, : p + nsh], self.W, J[:, :, p + nsh :]], axis=2)
        if ext and ext.effect == "reference_point_offset":
            Je = np.zeros((len(s.q), 2, 2))
            Je[(s.point == ext.point) & ~s.measured] = -np.eye(2)
            J = np.concatenate([J, Je], axis=2)
        return J[:, :, self.free]


def spot_problem(
    session: Session, start: RobotModel, extension: Extension | None, shape: bool | None
) -> SpotProblem:
    """Method ``lm``'s parameters and model for ``session`` from the ``start`` model (:class:`SpotProblem`;
    ``shape`` as :func:`identify_lm`'s).

    Raises
    ------
    IdentificationError : too few captures for the parameters
    """
    P = LaserParams(start)
    target, m, p = session.target, len(session.q), P.size
    k = extension.size if extension else 0
    if extension:
        require(extension, session.t, session.tau)
    sheet = session.frame == "sheet"
    if shape is None:
        shape = bool(isinstance(session.meta, dict) and session.meta.get("_sheet_shape_modelled", False))
    shape = shape and sheet
    nsh = (NFULL if shape else NSHEET) if sheet else 0
    V = camera_view_rows(session) if shape and session.measured.any() else None
    # the camera's view of a raised paper: eq. S8 from where it stood, else eq. S7's free field
    nw = NWARP if shape and session.measured.any() and V is None else 0
    W = camera_warp_rows(target[:, :2], session.measured, marker_centres(session)) if nw else None
    if 2 * m <= 8:
        raise IdentificationError(f"{m} captures are far too few to identify {p + nsh + k} parameters")
    pose0 = (session.sheet or sheet_start(session, start)) if sheet else None
    u0 = np.r_[P.x0(), (pose0.full_vector if shape else pose0.vector) if sheet else [], np.zeros(nw + k)]
    counted = counted_parameters(P, sheet, extension.names if extension else (), shape, nw > 0)
    kinds = (SHEET_KINDS + (SHAPE_KINDS if shape else [])) if sheet else []
    kinds += WARP_KINDS if nw else []
    kinds += extension.kinds if extension else []
    base0 = placed_targets(session, pose0) if sheet else target
    return SpotProblem(session, P, extension, shape, nsh, nw, W, pose0, base0, u0, counted, kinds, V)


def beam_distance_stage(
    prob: SpotProblem, tolerances: Tolerances | None, w: np.ndarray
) -> tuple[np.ndarray, optimize.OptimizeResult]:
    """Stage 1 of ``lm`` (geometry only, the sheet at its start): Levenberg-Marquardt on the beam-to-point
    distance, which brings a far-off start (steep beams) into the basin of stage 2, in the identifiable
    subspace of the geometry at the start; with a prior, its rows (at the nominal noise) join in.

    Parameters
    ----------
    prob : SpotProblem
    tolerances : Tolerances or None, the session's (the prior's)
    w : (m,) array, 1 for the captures used, 0 for the gross outliers

    Returns
    -------
    u1 : (len(prob.u0),) array, all parameters with the geometry at stage 1's solution
    first : OptimizeResult, the stage's fit (``fun``: the (3m,) weighted distances, mm, then the prior's rows)
    """
    P, s, free, m = prob.P, prob.session, prob.free, len(w)
    geo = free[free < prob.p]
    x0 = P.x0()
    _, _, J0 = P.spot_jacobian(x0, s.q, s.target[:, 2])
    geo_prior = laser_prior(P, tolerances, free=geo)
    pr = [] if geo_prior is None else [geo_prior.rows(x0[geo], geo_prior.noise)[1]]
    _, B1 = identifiability(np.vstack([J0[:, :, geo].reshape(2 * m, len(geo))] + pr), P.names)
    sw = np.sqrt(w)[:, None, None]

    def line(z):
        x = x0.copy()
        x[geo] += B1 @ z
        r, J = P.line_jacobian(x, s.q, prob.base0)
        r, J = (r[:, :, None] * sw)[..., 0].ravel(), (J[:, :, geo] * sw).reshape(3 * m, len(geo))
        if geo_prior is not None:
            rp, Jp = geo_prior.rows(x[geo], geo_prior.noise)
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
    u1 = prob.u0.copy()
    u1[geo] += B1 @ first.x
    return u1, first


def in_plane_stage(
    prob: SpotProblem, u1: np.ndarray, tolerances: Tolerances | None, prior: Prior | None, robust, w, suspects
) -> tuple:
    """Stage 2 of ``lm``: the in-plane residuals, geometry, sheet and extension together, in the identifiable
    subspace at stage 1's solution (MAP with the session's prior, eqs. P2-P4 of :mod:`solver.identify.prior`);
    a camera session's each capture with its own noise (eq. K1, :func:`fit_kinds`).

    Parameters
    ----------
    prob : SpotProblem
    u1 : (len(prob.u0),) array, all parameters at stage 1's solution (:func:`beam_distance_stage`)
    tolerances : Tolerances or None, the session's (a camera session's prior at each kind's noise)
    prior : Prior or None, the free parameters' prior (:meth:`SpotProblem.prior`)
    robust, w, suspects : as :func:`solver.identify.lsq.fit_subspace`'s (w: (m,) start weights)

    Returns
    -------
    fit : SubspaceFit (:func:`solver.identify.lsq.fit_subspace`)
    scale : (m,) array, each capture's residual scale c_i (eq. K1; ones without a camera)
    noise : dict, :func:`fit_kinds`'s (None without a camera)
    """
    s, v1, names = prob.session, u1[prob.free], prob.names
    if not s.measured.any():
        fit = fit_subspace(prob.residual, prob.jacobian, v1, names, robust, w, suspects=suspects, prior=prior)
        return fit, np.ones(len(w)), None

    def prior_at(ref):
        return prob.prior(tolerances and tolerances.with_noise("laser", ref))

    return fit_kinds(s, prob.residual, prob.jacobian, v1, names, prior_at, robust, w, suspects)


def lm_identification(
    prob: SpotProblem, nominal: RobotModel, start: RobotModel, fit, scale, noise, t0, **over
):
    """The :class:`Identification` of method ``lm`` from stage 2's fit: the aperture's gauge fixed
    (:func:`_aperture_gauge`), the model with its sheet pose and extension, the standard errors.

    Parameters
    ----------
    prob : SpotProblem
    nominal, start : RobotModel, the nominal and the start model
    fit, scale, noise : :func:`in_plane_stage`'s
    t0 : float, ``time.perf_counter()`` when the identification started
    over : fields that differ from the fit's (the iterations and history of both stages)
    """
    s, P, free, p, nsh, pe = prob.session, prob.P, prob.free, prob.p, prob.nsh, prob.pe
    cov_all = np.zeros((len(prob.u0), len(prob.u0)))
    cov_all[np.ix_(free, free)] = fit.cov
    u, cov_all = _aperture_gauge(P, prob.embed(fit.v), cov_all, s.aperture_z)
    v, cov = u[free], cov_all[np.ix_(free, free)]
    se_all = np.sqrt(np.clip(np.diag(cov_all), 0, None))
    meta = {
        "method": "lm",
        "converged": fit.converged,
        "iterations": over["iterations"],
        "rank": fit.identifiability.rank,
        "n_params": len(free),
    }
    ext = prob.extension
    fitted = ext.with_params(u[pe:], se_all[pe:]) if ext else None
    extensions = fitted.model_entries() if fitted and fitted.acts_on_joints else {}
    model = P.to_model(u[:p], identification=meta, extensions=extensions)
    if prob.sheet:
        std = se_all[p : p + nsh] * ([1, 1, 180 / np.pi] + [1] * (nsh - 3))
        pose = SheetPose.from_vector(u[p : p + nsh])
        keys = SHEET_KEYS + SCALE_KEYS + TILT_KEYS + (SHAPE_KEYS if prob.shape else ())
        model = model.replace(sheet=pose, sheet_std=dict(zip(keys, std)))
        nominal = nominal.replace(sheet=sheet_start(s, start))  # the nominal's best pose ("before")
    return Identification.from_fit(
        nominal,
        model,
        fit,
        prob.names,
        se_all[free],
        t0,
        {
            "cov": cov,
            "span": fit.span,
            "constraint_span": fit.constraint_span,
            "constraint_residuals": fit.constraint_residuals,
            "held": prob.counted.held,
            "counted": prob.counted.describe(),
            **({} if noise is None else {"scale": scale, "noise": noise}),
            **({"camera_warp": u[p + nsh : pe], "camera_warp_std": se_all[p + nsh : pe]} if prob.nw else {}),
        },
        fitted,
        estimate=v,
        residuals=fit.residuals * scale[:, None],
        **over,
    )


def identify_lm(
    session: Session,
    nominal: RobotModel | None = None,
    robust: bool = True,
    extension: Extension | None = None,
    suspects: np.ndarray | None = None,
    shape: bool | None = None,
) -> Identification:
    """Levenberg-Marquardt on in-plane spot residuals in the identifiable subspace (method ``lm``).

    The parameters are the laser robot's (:class:`~lasercal.solver.kinematics.laser.LaserParams`), then
    for a sheet session the sheet's pose [x mm, y mm, yaw rad] (eq. S1, with the gauge held), then the
    extension's (:func:`~lasercal.solver.identify.laser_parameters.counted_parameters`); the fit is MAP
    with the session's prior.

    Parameters
    ----------
    session : Session
    nominal : RobotModel, start model (default: the session's robot)
    robust : bool, flag outliers and refit without them
    extension : Extension, optional non-geometric effect identified jointly with the geometry
        (its parameters start at zero; a compliance extension uses the session's torques)
    suspects : (m,) bool array, optional: the only captures the outlier test may flag (an extension fitted
        on its geometric fit's rows: that fit's outliers; :func:`solver.identify.lsq.fit_subspace`)
    shape : bool, a sheet session: fit the print's shear and the paper's height field too (eqs. S5, S6 of
        :mod:`solver.kinematics.sheet`; :mod:`solver.identify.sheetshape` decides whether to keep them);
        None (default): when the session is marked so (:func:`solver.identify.sheetshape.modelled`)

    Returns
    -------
    Identification (for a sheet session the model carries ``sheet`` and ``sheet_std``)
    """
    t0 = time.perf_counter()
    nominal = nominal or session.robot
    start = _start(nominal, session)
    prob = spot_problem(session, start, extension, shape)
    tol = session.tolerances
    if tol is not None and prob.sheet and session.sheet is None:  # no stated placement: no prior on the pose
        tol = replace(tol, sheet_mm=np.inf, sheet_rad=np.inf)
    m = len(session.q)
    w = np.ones(m)
    # gross outliers (a wrong point) already stand out against the nominal model: keep them out of the start
    if robust:
        flags, _ = flag_outliers(spot_residuals(start, session.q, prob.base0), w)
        w = np.where(flags, 0.0, 1.0)
    prior = prob.prior(tol)
    u1, first = beam_distance_stage(prob, tol, w)
    stage1 = {
        "pass": 0,
        "method": "lm (beam distance)",
        "rms_mm": float(np.sqrt(np.mean(first.fun[: 3 * m] ** 2) * 3)),
        "iterations": int(first.njev),
        "status": int(first.status),
    }
    fit, scale, noise = in_plane_stage(prob, u1, tol, prior, robust, w, suspects)
    history = (stage1, *fit.history)
    return lm_identification(
        prob, nominal, start, fit, scale, noise, t0, iterations=first.njev + fit.iterations, history=history
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
    if session.frame == "sheet":
        raise IdentificationError(
            "the thesis method needs the reference points in the base frame (frame: base); the points of a "
            "sheet session are identified with the robot by --method lm"
        )
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

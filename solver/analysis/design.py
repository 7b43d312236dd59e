"""Optimal experiment design for laser calibration: where to aim next, how good the fit is, when to stop.

The state of knowledge after m captures is a Gaussian posterior on the minimal-POE parameters
x (:class:`~lasercal.solver.kinematics.laser.LaserParams` about the nominal model) -- the same
MAP estimate, noise and covariance as ``lasercal solve`` (:mod:`solver.identify.prior`), so the
error the coach promises is the error of the fit ``solve`` will make:

* prior (eq. D1 = P1): x ~ N(x_nom, diag(s^2)), s from the robot's
  :class:`~lasercal.solver.identify.prior.Tolerances` -- what a hand-assembled arm and a
  hand-mounted laser can be off by. With no or too few captures the prior alone speaks.
* estimate (eq. D2 = P2): the MAP fit min sum |spot_i(x) - target_i|^2 / sigma^2 + |(x - x_nom) / s|^2,
  solved by :func:`~lasercal.solver.identify.lsq.fit_subspace` (Levenberg-Marquardt in the
  identifiable subspace, robust loss once there are enough captures).
* aiming noise (eq. D3 = P3): log sigma^2 = (nu0 log sigma0^2 + dof log(RSS / dof)) / (nu0 + dof), the
  operator's nominal aiming noise sigma0 (nu0 pseudo-observations) and the data's estimate weighed on
  the log scale, dof = 2 m - tr(H) with tr(H) the effective number of fitted parameters.
* covariance (eq. D4 = P4): C = (J^T J / sigma^2 + L^T L)^-1 = R V diag(sigma^2 / (S^2 + sigma^2)) V^T R^T
  with R = L^-1 (the prior covariance's root, L = diag(1/s) T of eq. P1) from one SVD
  J R = U S V^T (V completed to p x p), so one decomposition serves
  every sigma (the prediction's uncertainty, eq. D5); it has full rank because of the prior, and
  directions the data cannot see keep their prior variance.

Predicted held-out error where the robot is used (eq. D5): for configurations q_k aiming at the
use points (the layout's validation points, or a workspace box), the in-plane spot error of the
fit is J_k e with e ~ N(0, C), so E|error|^2 averaged over k is tr(W C) with
W = mean_k J_k^T J_k; the prediction is the RMS sqrt(tr(W C)) (mm). Its uncertainty is that of
sigma (eq. D3: relative std 1 / sqrt(2 (nu0 + dof))) propagated through C.

Design criterion: I-optimality (integrated / average prediction variance over the region of use,
Atkinson, Donev & Tobias, *Optimum Experimental Designs*, 2007, Sec. 10.6; "V-optimality"):
choose captures minimising tr(W C). It is exactly the promised number -- the held-out error
at the validation points -- and it is invariant to parameter units and to directions that do
not affect the use region. A-optimality (tr C) would mix rad and mm and spend captures on
parameters that never show at the validation points; D-optimality (FIGAROH) likewise maximises
information volume irrespective of where the robot will be used.

Greedy sequential selection (eq. D6): a candidate capture adds two rows J_c (2, p) with noise
sigma^2 I; by the Woodbury identity (two rank-one updates)
C+ = C - G^T S^-1 G with G = J_c C, S = G J_c^T + sigma^2 I (2x2), and the criterion drops by
tr(S^-1 G W G^T), evaluated for all candidates at once. The best candidate is taken, C updated,
and the step repeated K times. Eq. D7: the products J_c C and J_c C W of all candidates follow each
rank-two change of C in O(N p) (:class:`_Design`), so a step never recomputes them in O(N p^2).

Eq. D8 (``capture --plan-effects``): the design may also count the joint compliances the diagnosis tests
(:func:`compliance_design`), so that the captures tell them from the geometry and a sheet's pose: C and the
candidates' Jacobians grow by the compliances' columns (d spot / d q_j tau_j), and W by a block that weighs a
compliance's variance, relative to its prior, as much as the geometry's predicted error squared
(:func:`effect_design`). The promise stays eq. D5's, of the geometry.

Candidates: configurations sampled by the aiming IK (:func:`~lasercal.solver.kinematics.aim.aim`)
under the current model at the calibration points, kept when they satisfy :class:`Constraints`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from lasercal.solver.errors import AimingError, LasercalError
from lasercal.solver.formats.session import Layout
from lasercal.solver.formats.tolerances import Tolerances, robot_tolerances
from lasercal.solver.identify.laser_parameters import (
    NSHEET,
    SHEET_KINDS,
    SHEET_NAMES,
    CountedParameters,
    counted_parameters,
    counted_rank,
)
from lasercal.solver.identify.lsq import fit_subspace
from lasercal.solver.identify.spot import laser_prior
from lasercal.solver.kinematics.aim import aim, polish, spot_error
from lasercal.solver.kinematics.laser import LaserParams, beam_joint_jacobian, plane_hit
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import space_jacobian
from lasercal.solver.kinematics.sheet import SheetPose, sheet_to_base

# a suggested capture lies at least this far (joint-space distance, rad) from every capture at its point:
# nearer, the capture check calls it similar (collector.sessions.capture), and a pose captured again adds
# little but a new draw of the aiming noise
APART_RAD = 0.5
CELL_SPOTS = 16  # spots of a point's cell the candidates aim at (``anywhere``), drawn at random


class DesignError(LasercalError):
    """An experiment design cannot be made (no reachable use point, bad workspace box, K <= 0, ...)."""


@dataclass(frozen=True)
class Constraints:
    """Where candidate configurations may be (the layout's ``aiming`` hints override tilt and length).

    Attributes
    ----------
    margin : float, distance from every joint limit, rad
    clearance : float, height of the laser aperture (the flange's lowest point) above the table, mm
    min_singular : float, smallest singular value of the aperture Jacobian [omega; da / 500 mm]
        (dimensionless; 0 at a singular configuration)
    tilt : (min, max), the beam's angle from straight down, rad
    length : (min, max), laser length, mm
    """

    margin: float = 0.1
    clearance: float = 50.0
    min_singular: float = 0.05
    tilt: tuple = (0.0, np.radians(35))
    length: tuple = (150.0, 600.0)

    @classmethod
    def for_layout(cls, layout: Layout, **kw) -> Constraints:
        """Constraints with the layout's aiming hints (tilt, length)."""
        return cls(**{**layout.aim_kwargs(), **kw})

    def satisfied(self, model: RobotModel, q: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Boolean (m,) mask of configurations meeting every constraint, aiming at the plane(s) z."""
        b, da, _ = beam_joint_jacobian(model, q)
        _, t = plane_hit(b.aperture, b.direction, z)
        tilt = np.arccos(np.clip(-b.direction[:, 2], -1.0, 1.0))
        w = space_jacobian(model.screws, b.chain)[:, :3]
        smin = np.linalg.svd(np.concatenate([w, da / 500.0], axis=1), compute_uv=False)[:, -1]
        return (
            model.within_limits(q, self.margin)
            & (tilt >= self.tilt[0] - 1e-9)
            & (tilt <= self.tilt[1] + 1e-9)
            & (t >= self.length[0])
            & (t <= self.length[1])
            & (b.aperture[:, 2] - z >= self.clearance)
            & (smin >= self.min_singular)
        )


@dataclass(frozen=True)
class UseRegion:
    """Configurations aiming at the points where the robot will be used.

    Attributes
    ----------
    q : (k, n) array, rad
    target : (k, 3) array, the point each aims at, mm
    label : str, e.g. 'P4' or 'workspace box'
    """

    q: np.ndarray
    target: np.ndarray
    label: str


def _aim_many(
    model, points, per_point, rng, con: Constraints, pool: int, spread: float = 0.6
) -> tuple[np.ndarray, np.ndarray]:
    """Aiming-IK configurations (k, n) meeting ``con`` at each point, and their targets (k, 3)."""
    qs, ts = [], []
    for p in points:
        p = np.asarray(p, dtype=float)
        try:
            q = aim(model, p, per_point, rng, con.tilt, con.length, spread, con.margin, pool)
        except AimingError:
            continue
        q = q[con.satisfied(model, q, np.full(len(q), p[2]))]
        qs.append(q)
        ts.append(np.repeat(p[None], len(q), axis=0))
    if not qs or not sum(len(q) for q in qs):
        return np.empty((0, model.n)), np.empty((0, 3))
    return np.concatenate(qs), np.concatenate(ts)


def use_region(
    model: RobotModel,
    layout: Layout,
    rng: np.random.Generator,
    workspace: tuple | None = None,
    n: int = 120,
    constraints: Constraints | None = None,
) -> UseRegion:
    """Where the robot will be used: configurations aiming at the layout's validation points
    (its calibration points when it has none), or at points drawn uniformly in a workspace box.

    Parameters
    ----------
    model : RobotModel, the current model (it aims)
    layout : Layout
    rng : numpy Generator
    workspace : ((3,), (3,)) min and max corners of a box, mm, or None
    n : int, configurations in all
    constraints : Constraints (default: the layout's)

    Raises
    ------
    DesignError
        A box with min > max, or use points no configuration can aim at.
    """
    con = constraints or Constraints.for_layout(layout)
    if workspace is not None:
        lo, hi = (np.asarray(a, dtype=float) for a in workspace)
        if lo.shape != (3,) or hi.shape != (3,) or np.any(lo > hi):
            raise DesignError(f"workspace box min {lo.tolist()} must be <= max {hi.tolist()} (mm, per axis)")
        points = rng.uniform(lo, hi, (max(n // 8, 4), 3))
        label = f"workspace box {lo.tolist()}..{hi.tolist()} mm"
    else:
        names = list(layout.validation or layout.calibration)
        points = [layout.points[k] for k in names]
        label = ", ".join(names)
        for nm, p in zip(names, points):
            # 16 tries: about half of the aiming IK's solutions fail the clearance or singularity test,
            # and 4 (as once here) called a reachable point unreachable for 1 seed in 20
            if not len(_aim_many(model, [p], 16, rng, con, pool=128)[0]):
                raise DesignError(layout.unreachable(nm))
    q, target = _aim_many(
        model, points, max(n // len(points), 2), rng, con, pool=4 * max(n // len(points), 16)
    )
    if not len(q):
        raise DesignError(f"no configuration within the limits and the aiming range reaches {label}")
    return UseRegion(q, target, label)


def lend_seen(cand: Candidates, seen: np.ndarray) -> Candidates:
    """The candidates with each point none of whose own the camera sees given its share of the seen ones
    nearest it (``seen`` (N,) bool): the seen count over the points, relabelled to it (point and anchor).
    A camera session's measured spot is where the beam was, whichever point's cell it lies in; the point
    only counts the captures (``--per-point``), so its captures are planned where the camera measures them.
    """
    point, anchor = cand.point.copy(), cand.anchor.copy()
    names = sorted(set(point.tolist()))
    share = max(int(seen.sum()) // len(names), 1)
    lent = np.zeros(len(point), bool)  # a candidate lent once stays with its borrower
    for name in names:
        here = point == name
        if seen[here].any():
            continue
        at = anchor[here][0]
        donors = np.flatnonzero(seen & ~here & ~lent)
        near = donors[np.argsort(np.linalg.norm(cand.target[donors, :2] - at[:2], axis=1), kind="stable")]
        point[near[:share]], anchor[near[:share]], lent[near[:share]] = name, at, True
    return replace(cand, point=point, anchor=anchor)


@dataclass(frozen=True)
class Candidates:
    """Candidate next captures: aiming-IK configurations at the calibration points, or at spots anywhere
    in their cells (a camera session, :func:`candidates` ``anywhere``).

    Attributes
    ----------
    q : (N, n) array, rad
    point : (N,) array of str, the point each aims at (or whose cell its spot lies in)
    target : (N, 3) array, where its beam meets the plane, mm
    anchor : (N, 3) array, the point itself, mm (= target at the points)
    hidden : (N,) bool array or None, candidates whose spot the session's camera cannot measure
        (:meth:`Coach.see_from`): never available
    """

    q: np.ndarray
    point: np.ndarray
    target: np.ndarray
    anchor: np.ndarray
    hidden: np.ndarray | None = None

    def available(self, allowed=None, taken=None) -> np.ndarray:
        """Boolean (N,) mask of the candidates at the points ``allowed`` (None: every one), apart from the
        captures ``taken``.

        Parameters
        ----------
        allowed : iterable of point names, or None
        taken : ((m, n) array rad, (m, 3) array mm) or None, the captures so far and their points: a
            candidate within :data:`APART_RAD` of a capture at its point (its cell's) is not available (the
            design would otherwise replicate an informative pose -- the same pose again, with a new aiming
            error -- which the capture check then calls similar)
        """
        ok = np.ones(len(self.q), bool) if allowed is None else np.isin(self.point, list(allowed))
        if self.hidden is not None:
            ok &= ~self.hidden
        if taken is not None and len(taken[0]):
            q, target = (np.asarray(a, dtype=float) for a in taken)
            same = np.linalg.norm(self.anchor[:, None, :] - target[None, :, :], axis=2) < 1e-6  # (N, m)
            near = np.linalg.norm(self.q[:, None, :] - q[None, :, :], axis=2) < APART_RAD
            ok &= ~np.any(same & near, axis=1)
        return ok


def candidates(
    model: RobotModel,
    layout: Layout,
    rng: np.random.Generator,
    per_point: int = 100,
    constraints: Constraints | None = None,
    points=None,
    spread: float = 1.0,
    anywhere: dict | None = None,
) -> Candidates:
    """Candidate configurations aiming exactly at each calibration point under ``model``, or at spots
    spread over each point's cell.

    Parameters
    ----------
    model : RobotModel, the current model
    layout : Layout
    rng : numpy Generator
    per_point : int, configurations sampled per point (fewer survive the constraints)
    constraints : Constraints (default: the layout's)
    points : list of point names (default: the layout's calibration points)
    spread : float, std of the aiming IK's random seeds about the home configuration, rad (wider
        than an operator's habits: the design needs the extremes)
    anywhere : dict name -> (k, 3) array mm, or None: spots in each point's cell where a camera can
        measure them (:func:`collector.sessions.anywhere.cells`); its ``per_point`` configurations are
        spread over :data:`CELL_SPOTS` of them drawn at random, and spots out of reach are passed over

    Raises
    ------
    DesignError
        When a calibration point (or every spot of its cell) cannot be aimed at within the constraints.
    """
    con = constraints or Constraints.for_layout(layout)
    names = list(points or layout.calibration)
    qs, ns, ts = [], [], []
    for nm in names:
        spots = [layout.points[nm]] if anywhere is None else list(anywhere[nm])
        if len(spots) > CELL_SPOTS:  # the aiming IK's cost grows with the spots, the design's choice hardly
            spots = [spots[i] for i in np.sort(rng.choice(len(spots), CELL_SPOTS, replace=False))]
        each = max(per_point // len(spots), 2)
        q, t = _aim_many(model, spots, each, rng, con, pool=2 * each + 40, spread=spread)
        if not len(q):
            raise DesignError(layout.unreachable(nm))
        qs.append(q)
        ts.append(t)
        ns += [nm] * len(q)
    point = np.array(ns, dtype=object)
    anchor = np.array([layout.points[nm] for nm in ns], dtype=float)
    return Candidates(np.concatenate(qs), point, np.concatenate(ts), anchor)


@dataclass(frozen=True, eq=False)
class Posterior:
    """What the captures so far say about the robot (eqs. D1-D4).

    Attributes
    ----------
    params : LaserParams, about the nominal model (x = x_nom there)
    estimate : (p,) array, the MAP estimate (eq. D2)
    model : RobotModel, the robot at the estimate
    cov : (p, p) array, the posterior covariance (eq. D4)
    sigma : float, aiming noise per axis (eq. D3), mm
    sigma_rel : float, relative standard deviation of sigma
    dof : float, residual degrees of freedom of the captures
    rank : int, parameter combinations the captures alone identify (SVD rank, no prior)
    weights : (m,) array, 1 used, 0 flagged as an outlier
    rows : (2 m_used, p) array, the spot Jacobian of the used captures at the estimate
    prior_root : (p, p) array, R = L^-1: the prior covariance is R R^T (eqs. D1, D4)
    target_xy : (m_used, 2) array, where the estimate's beams land for the used captures (at their points,
        to the fit's residual), base frame, mm (what a sheet's pose
        would move: :func:`~lasercal.solver.identify.laser_parameters.counted_rank`)
    slope : (m_used, 2) array, d spot / d plane height of the used captures' beams (what a sheet's tilt
        would move)
    sheet : SheetPose or None, a sheet session's pose: ``cov``, ``rows`` and ``prior_root`` then also span the
        sheet's pose, print scale and tilt (eq. S3, after the robot's parameters; :func:`sheet_columns`), and
        errors are predicted on the sheet, as ``solve`` identifies it with the robot
    on_sheet : Posterior or None, a sheet session's: this posterior with the sheet's parameters (``sheet``
        set): the error it predicts is the promise (eq. D5 on the sheet); the design keeps to the robot's
    """

    params: LaserParams
    estimate: np.ndarray
    model: RobotModel
    cov: np.ndarray
    sigma: float
    sigma_rel: float
    dof: float
    rank: int
    weights: np.ndarray
    rows: np.ndarray
    prior_root: np.ndarray
    target_xy: np.ndarray
    slope: np.ndarray
    sheet: SheetPose | None = None
    on_sheet: Posterior | None = None

    @property
    def names(self) -> list:
        """The names of the covariance's parameters: the robot's, then a sheet's."""
        return list(self.params.names) + (SHEET_NAMES if self.sheet is not None else [])

    def jacobian(self, q: np.ndarray, target: np.ndarray) -> np.ndarray:
        """In-plane spot Jacobians (k, 2, len(names)) of configurations q (k, n) aimed at targets (k, 3) mm
        at the estimate, a sheet's columns included (:func:`sheet_columns`)."""
        J = self.params.spot_jacobian(self.estimate, q, target[:, 2])[2]
        if self.sheet is None:
            return J
        d = self.params.beam(self.estimate, q).direction
        return np.concatenate([J, sheet_columns(self.sheet, target, d[:, :2] / d[:, 2:])], axis=2)

    @property
    def prior_std(self) -> np.ndarray:
        """(p,) the prior's marginal standard deviations, sqrt(diag(R R^T))."""
        return np.sqrt(np.sum(self.prior_root**2, axis=1))


def sheet_columns(pose: SheetPose, target: np.ndarray, slope: np.ndarray) -> np.ndarray:
    """d (spot - point) / d sheet parameters (k, 2, 7) of beams aimed at points (k, 3) mm of a sheet at
    ``pose`` (eq. S3): the point moves in the plane, and the plane's height under it moves the spot along
    the beam by ``slope`` (k, 2) = d_xy / d_z per mm."""
    Js = sheet_to_base(pose.vector, pose.from_base(target), target[:, 2])[1]
    return -Js[:, :2] + slope[:, :, None] * Js[:, 2:3]


class SpotJacobians:
    """The in-plane spot Jacobians dspot_i/dx (m, 2, p) of captures q_i (eq. D2's LM), remembered.

    The fit evaluates the Jacobian at the same parameters several times (its start, the outlier
    test, the covariance, eq. D4), and a session refits warm-started at the previous estimate,
    where the Jacobians of every earlier capture are already known: each capture's rows depend
    only on its own configuration, so only the new captures' rows are computed. The result equals
    a full evaluation to round-off.

    Parameters
    ----------
    params : LaserParams
    keep : int, parameter vectors remembered (the most recent)
    """

    def __init__(self, params: LaserParams, keep: int = 8):
        self.params, self.keep = params, keep
        self._memo: dict = {}  # v bytes -> (q (k, n), z (k,), J (k, 2, p))

    def __call__(self, v: np.ndarray, q: np.ndarray, z: np.ndarray) -> np.ndarray:
        """(m, 2, p) Jacobian at parameters v (p,) of configurations q (m, n) aimed at planes z (m,) mm."""
        key = np.asarray(v, dtype=float).tobytes()
        q0, z0, J0 = self._memo.pop(key, (q[:0], z[:0], None))
        k = len(q0)
        if J0 is None or k > len(q) or not (np.array_equal(q0, q[:k]) and np.array_equal(z0, z[:k])):
            k, J0 = 0, np.empty((0, 2, self.params.size))
        J = J0 if k == len(q) else np.concatenate([J0, self.params.spot_jacobian(v, q[k:], z[k:])[2]])
        self._memo[key] = (q.copy(), z.copy(), J)
        while len(self._memo) > self.keep:
            self._memo.pop(next(iter(self._memo)))
        return J


def _posterior_covs(J: np.ndarray, R: np.ndarray):
    """sigma -> C = (J^T J / sigma^2 + (R R^T)^-1)^-1 (eq. D4), J (rows, p), from one SVD.

    With J R = U S V^T (V complete, p x p; S padded with zeros):
    C = R V diag(sigma^2 / (S^2 + sigma^2)) V^T R^T. One SVD serves every sigma of the
    noise fixed point (eq. D3) and of the prediction's uncertainty (eq. D5); no difference of
    nearly equal terms, so small variances keep their relative precision.
    """
    A = J @ R
    _, S, Vt = np.linalg.svd(A, full_matrices=A.shape[0] < A.shape[1])  # never the big U of a tall J
    S2 = np.zeros(R.shape[1])
    S2[: len(S)] = S**2
    V = R @ Vt.T

    def cov(sigma: float) -> np.ndarray:
        return (V * (sigma**2 / (S2 + sigma**2))) @ V.T

    return cov


def _posterior_cov(J: np.ndarray, R: np.ndarray, sigma: float) -> np.ndarray:
    """C = (J^T J / sigma^2 + (R R^T)^-1)^-1 (eq. D4), J (rows, p)."""
    return _posterior_covs(J, R)(sigma)


def posterior(
    nominal: RobotModel,
    q: np.ndarray,
    target: np.ndarray,
    tolerances: Tolerances | str = "robot",
    start: np.ndarray | None = None,
    jacobians: SpotJacobians | None = None,
    sheet: SheetPose | None = None,
) -> Posterior:
    """The posterior after captures q aimed at target (eqs. D1-D4); none at all is fine.

    The MAP fit of ``lasercal solve`` (:func:`~lasercal.solver.identify.lsq.fit_subspace` with the
    prior of :func:`~lasercal.solver.identify.prior.make_prior`): the same estimate, noise and
    covariance.

    Parameters
    ----------
    nominal : RobotModel, the prior mean
    q : (m, n) array, captured configurations, rad (m may be 0)
    target : (m, 3) array, the reference point of each capture, mm
    tolerances : Tolerances, the prior (default "robot": the nominal's own,
        :func:`~lasercal.solver.identify.prior.robot_tolerances`, as ``solve`` uses)
    start : (p,) array, where the fit starts (e.g. the previous estimate: a warm start)
    jacobians : SpotJacobians of the same nominal model, kept between calls (a session's refits reuse
        the Jacobians of earlier captures at the warm start)
    sheet : SheetPose or None, the pose of the sheet the targets lie on (a sheet session): the estimate
        stays the robot's (the sheet where ``sheet`` puts it), its covariance spans the sheet's parameters
        too, under their prior, once there are captures (with none, the prior speaks of the robot)

    Returns
    -------
    Posterior
    """
    P = LaserParams(nominal)
    x0 = P.x0()
    tol = robot_tolerances(nominal) if isinstance(tolerances, str) else tolerances
    prior = laser_prior(P, tol)
    R = np.linalg.inv(prior.whitening)
    q = np.asarray(q, dtype=float).reshape(-1, nominal.n)
    target = np.asarray(target, dtype=float).reshape(-1, 3)
    m = len(q)
    if m:

        def residual(v):
            return P.spots(v, q, target[:, 2])[0][:, :2] - target[:, :2]

        jac = jacobians or SpotJacobians(P)

        def jacobian(v):
            return jac(v, q, target[:, 2])

        fit = fit_subspace(residual, jacobian, x0 if start is None else start, P.names, m >= 10, prior=prior)
        v, w, sigma, dof = fit.v, fit.weights, fit.sigma, fit.dof
        J = jacobian(v)[w > 0].reshape(-1, P.size)
        rank = fit.identifiability.rank
    else:
        v, w, J, rank, sigma, dof = x0, np.ones(0), np.zeros((0, P.size)), 0, prior.noise, 0.0
    # where the model's beams land (what a sheet's pose and print would move: a common scale of robot and
    # print then moves nothing, as in solve's sheet units, eq. S4)
    used_xy = P.spots(v, q[w > 0], target[w > 0, 2])[0][:, :2] if m else np.zeros((0, 2))
    d = P.beam(v, q[w > 0]).direction if m else np.zeros((0, 3))
    post = Posterior(
        P,
        v,
        P.to_model(v),
        _posterior_cov(J, R, sigma),
        sigma,
        1.0 / np.sqrt(2.0 * (prior.noise_dof + dof)),
        dof,
        rank,
        w,
        J,
        R,
        used_xy,
        d[:, :2] / d[:, 2:],
    )
    if sheet is None or not m:
        return post
    # the sheet's pose, print and tilt, identified with the robot as solve does: the promise's covariance
    Rs = np.linalg.inv(laser_prior(P, tol, SHEET_KINDS, sheet.vector, SHEET_NAMES).whitening)
    Js = np.concatenate([J, sheet_columns(sheet, target[w > 0], post.slope).reshape(-1, NSHEET)], axis=1)
    on_sheet = replace(post, cov=_posterior_cov(Js, Rs, sigma), rows=Js, prior_root=Rs, sheet=sheet)
    return replace(post, on_sheet=on_sheet)


def use_weight(post: Posterior, region: UseRegion) -> np.ndarray:
    """W = mean_k J_k^T J_k (p, p) over the use region at the posterior's estimate (eq. D5)."""
    J = post.jacobian(region.q, region.target)
    return np.einsum("kap,kaq->pq", J, J) / len(J)


def predicted_error(post: Posterior, W: np.ndarray) -> tuple[float, float]:
    """Predicted held-out RMS spot error sqrt(tr(W C)) (eq. D5) and its uncertainty, mm.

    The uncertainty is half the change of the prediction when sigma moves by one standard
    deviation either way (eq. D3).
    """
    e = float(np.sqrt(max(np.sum(W * post.cov), 0.0)))
    cov = _posterior_covs(post.rows, post.prior_root)
    lo, hi = (
        float(np.sqrt(max(np.sum(W * cov(post.sigma * f)), 0.0)))
        for f in (1 - post.sigma_rel, 1 + post.sigma_rel)
    )
    return e, (hi - lo) / 2


@dataclass(frozen=True)
class Plan:
    """K next captures chosen greedily (eq. D6), with the predicted error after each.

    Attributes
    ----------
    q : (K, n) array, rad
    point : (K,) array of str
    target : (K, 3) array, mm
    expected : (K,) array, predicted held-out RMS error after adding captures 1..k, mm
    now : float, predicted held-out RMS error before them, mm
    history : tuple of dict, per step: candidate index, criterion drop (mm^2), expected_mm
    """

    q: np.ndarray
    point: np.ndarray
    target: np.ndarray
    expected: np.ndarray
    now: float
    history: tuple = field(default_factory=tuple)

    def promised(self, post: Posterior, W: np.ndarray, now: float) -> Plan:
        """This plan with its expected errors under another posterior (a sheet session's ``on_sheet``):
        C updated by each planned capture in turn (eq. D6), sqrt(tr(W C)) after each (eq. D5)."""
        C, expected = post.cov, []
        for Jk in post.jacobian(self.q, self.target):
            G = Jk @ C
            C = C - G.T @ np.linalg.solve(G @ Jk.T + post.sigma**2 * np.eye(2), G)
            expected.append(float(np.sqrt(max(np.sum(W * C), 0.0))))
        history = tuple({**h, "expected_mm": x} for h, x in zip(self.history, expected))
        return replace(self, expected=np.array(expected), now=now, history=history)

    def first(self, k: int) -> Plan:
        """The plan's first k captures (its predictions are those of taking them in order)."""
        return Plan(
            self.q[:k], self.point[:k], self.target[:k], self.expected[:k], self.now, self.history[:k]
        )


# eq. D8's compliances: a prior sigma of the order a Panda's joints show (the thesis's identified joint-2
# compliance, 1.2e-4 rad/Nm; MUKCa's 0.5-3e-4), and a compliance's relative variance weighed as much as the
# geometry's predicted error squared (chosen before measuring: benchmarks/bench_diagnose_messy.py)
COMPLIANCE_SCALE = 1e-4  # rad/Nm
COMPLIANCE_WEIGHT = 1.0


def compliance_design(nominal: RobotModel, q: np.ndarray) -> tuple | None:
    """(joints, scale, weight) of eq. D8: the joints (0-based) whose gravity torque, over the candidate
    configurations q (N, n) rad, spreads as the diagnosis requires of a testable compliance
    (TORQUE_SPREAD_RATIO x TORQUE_NOISE_NM); None without a gravity model or such a joint."""
    from lasercal.solver.analysis.diagnose import TORQUE_NOISE_NM, TORQUE_SPREAD_RATIO
    from lasercal.solver.kinematics.gravity import gravity_torques

    if not nominal.links:
        return None
    spread = gravity_torques(nominal, q).std(axis=0)
    joints = np.flatnonzero(spread >= TORQUE_SPREAD_RATIO * TORQUE_NOISE_NM)
    return (joints, COMPLIANCE_SCALE, COMPLIANCE_WEIGHT) if len(joints) else None


def compliance_columns(
    model: RobotModel, torques: RobotModel, q: np.ndarray, z: np.ndarray, joints
) -> np.ndarray:
    """d spot / d c_j (k, 2, e) of joint compliances c_j at ``joints`` (0-based): q_j moves by c_j tau_j(q)
    (:mod:`solver.kinematics.elastic`, to first order), so the column is d spot / d q_j times tau_j, mm per
    rad/Nm; tau from the gravity model of ``torques`` at q (k, n) rad; spots on planes z (k,) mm."""
    from lasercal.solver.kinematics.gravity import gravity_torques
    from lasercal.solver.kinematics.laser import spot_joint_jacobian

    Jq = spot_joint_jacobian(model, q, z)[1]
    return Jq[:, :, joints] * gravity_torques(torques, q)[:, None, joints]


def effect_design(post: Posterior, W, Jc, cand: Candidates, q, target, torques: RobotModel, joints, scale,
                  weight) -> tuple:  # fmt: skip
    """The design's matrices with the joint compliances counted (eq. D8).

    C' = (J'^T J' / sigma^2 + blockdiag(R R^T, scale^2 I)^-1)^-1 over the robot's parameters and the
    compliances, J' the captures' rows with the compliances' columns (eq. D4); W' = blockdiag(W, w I /
    scale^2) with w = ``weight`` tr(W C'): a compliance's variance, relative to its prior, counts ``weight``
    times the geometry's predicted error squared. tr(W' C') is then what eqs. D6-D7 lower.

    Parameters
    ----------
    post : Posterior of the captures so far (the robot's parameters, p)
    W : (p, p) array, eq. D5
    Jc : (N, 2, p) array, the candidates' Jacobians
    cand : Candidates
    q, target : (m, n) rad and (m, 3) mm, the captures so far
    torques : RobotModel whose gravity model gives tau
    joints : (e,) int array, 0-based; scale : float, rad/Nm; weight : float

    Returns
    -------
    (Posterior with cov C' (p + e, p + e), W' (p + e, p + e), Jc' (N, 2, p + e))
    """
    p, e = post.params.size, len(joints)
    used = post.weights > 0
    Je = compliance_columns(post.model, torques, q[used], target[used, 2], joints).reshape(-1, e)
    R = np.zeros((p + e, p + e))
    R[:p, :p], R[p:, p:] = post.prior_root, scale * np.eye(e)
    C = _posterior_cov(np.concatenate([post.rows, Je], axis=1), R, post.sigma)
    Wd = np.zeros_like(C)
    Wd[:p, :p] = W
    Wd[p:, p:] = weight * float(np.sum(W * C[:p, :p])) / scale**2 * np.eye(e)
    Jce = compliance_columns(post.model, torques, cand.q, cand.target[:, 2], joints)
    return replace(post, cov=C), Wd, np.concatenate([Jc, Jce], axis=2)


def candidate_jacobian(post: Posterior, cand: Candidates) -> np.ndarray:
    """The candidates' spot Jacobians J_c (N, 2, p) at the posterior's estimate (eq. D6)."""
    return post.jacobian(cand.q, cand.target)


class _Design:
    """A design's effect on every candidate, kept up to date by rank-two updates (eqs. D6, D7).

    With the design's covariance C, the state is A = J_c C and B = A W for all candidates (N, 2, p),
    and f = tr(W C). Adding candidate c drops f by tr(S_c^-1 B_c A_c^T), S_c = A_c J_c^T + sigma^2 I
    (eq. D6). Adding capture j (U = A_j, S_j) makes C+ = C - U^T S_j^-1 U, so (eq. D7)
    A+ = A - (J_c U^T) S_j^-1 U and B+ = B - (J_c U^T) S_j^-1 (U W): O(N p) per step where
    recomputing J_c C is O(N p^2); removing capture i is the same with S_i = sigma^2 I - U J_i^T and
    the opposite sign (Woodbury downdate).

    Parameters
    ----------
    C : (p, p) array, covariance before the design
    W : (p, p) array, eq. D5
    Jc : (N, 2, p) array, candidate Jacobians
    sigma : float, aiming noise, mm
    """

    def __init__(self, C: np.ndarray, W: np.ndarray, Jc: np.ndarray, sigma: float):
        self.Jc, self.s2 = Jc, sigma**2
        self.A = Jc @ C
        self.B = self.A @ W
        self.f = float(np.sum(W * C))

    def drops(self) -> np.ndarray:
        """Criterion drop (N,) of adding each candidate, mm^2 (eq. D6)."""
        S = self.A @ np.swapaxes(self.Jc, 1, 2)
        M = self.B @ np.swapaxes(self.A, 1, 2)
        a, b, c, d = S[:, 0, 0] + self.s2, S[:, 0, 1], S[:, 1, 0], S[:, 1, 1] + self.s2
        # tr(S^-1 M) of each 2x2 S in closed form: a batched solve costs more than the rest of a step
        return (d * M[:, 0, 0] - b * M[:, 1, 0] - c * M[:, 0, 1] + a * M[:, 1, 1]) / (a * d - b * c)

    def _change(self, i: int, sign: float) -> float:
        """Add (sign -1) or remove (sign +1) candidate i's two rows; returns the criterion's change."""
        U, UW = self.A[i].copy(), self.B[i].copy()
        S_inv = np.linalg.inv(self.s2 * np.eye(2) - sign * U @ self.Jc[i].T)
        X = self.Jc @ U.T
        self.A += sign * X @ (S_inv @ U)
        self.B += sign * X @ (S_inv @ UW)
        d = sign * float(np.sum(S_inv * (UW @ U.T).T))
        self.f += d
        return d

    def state(self) -> tuple:
        """A copy of the state, for :meth:`restore`."""
        return self.A.copy(), self.B.copy(), self.f

    def restore(self, state: tuple) -> None:
        """Return to a state from :meth:`state`."""
        self.A, self.B, self.f = state

    def add(self, i: int) -> float:
        """Add candidate i; returns the criterion's drop, mm^2."""
        return -self._change(i, -1.0)

    def remove(self, i: int) -> None:
        """Remove a capture added before (candidate i)."""
        self._change(i, 1.0)


def _greedy(design: _Design, avail: np.ndarray, k: int) -> tuple[list, list]:
    """Greedy sequential I-optimal choice of k of the available candidates (eq. D6), added to
    ``design``; returns the chosen indices in order and the criterion drop of each."""
    avail, picks, drops = avail.copy(), [], []
    for _ in range(k):
        drop = design.drops()
        drop[~avail] = -np.inf
        j = int(np.argmax(drop))
        drops.append(design.add(j))
        avail[j] = False
        picks.append(j)
    return picks, drops


def _exchange(design: _Design, avail: np.ndarray, picks: list, passes: int) -> list:
    """Fedorov exchange (Fedorov, *Theory of Optimal Experiments*, 1972; Atkinson, Donev & Tobias 2007,
    Sec. 12.5) of a k-capture design for tr(W C) (eqs. D6, D7).

    For each chosen capture in turn, its two rows are removed (Woodbury downdate) and the available
    candidate with the largest drop replaces it when that lowers the criterion; at most ``passes``
    sweeps, fewer once a sweep changes nothing. A greedy design is myopic (its first captures are
    chosen for the prior alone); the exchange makes the k captures good together.

    Parameters
    ----------
    design : _Design holding the k captures ``picks``
    avail : (N,) bool array, candidates that may be chosen
    picks : list of k candidate indices
    passes : int

    Returns
    -------
    list of k candidate indices
    """
    picks = list(picks)
    free = avail.copy()
    free[picks] = False
    for _ in range(passes):
        changed = False
        for a, i in enumerate(picks):
            kept = design.state()
            design.remove(i)
            drop = design.drops()
            drop[~free] = -np.inf
            j = int(np.argmax(drop))
            if design.f - drop[j] < kept[2] * (1 - 1e-9):
                design.add(j)
                free[i], free[j], picks[a], changed = True, False, j, True
            else:
                design.restore(kept)  # a copy is cheaper than adding i back
        if not changed:
            break
    return picks


def select(
    post: Posterior,
    W: np.ndarray,
    cand: Candidates,
    k: int,
    allowed=None,
    Jc: np.ndarray | None = None,
    passes: int = 3,
    taken=None,
) -> Plan:
    """I-optimal choice of k next captures: greedy (eq. D6), then Fedorov exchange, vectorised over
    candidates.

    The k captures are chosen together (greedy start, :func:`_exchange`), then ordered greedily
    among themselves, so the first is the one that lowers the predicted error most now and
    ``expected`` falls with every capture.

    Parameters
    ----------
    post : Posterior
    W : (p, p) array, the use region's weight (eq. D5)
    cand : Candidates
    k : int, captures to choose (each at most once)
    allowed : iterable of point names, or None: only candidates at these points
    Jc : (N, 2, p) array, :func:`candidate_jacobian` (computed when not given)
    passes : int, exchange sweeps (0: greedy only)
    taken : the captures so far, (q, target), or None: no candidate near one (:meth:`Candidates.available`)

    Returns
    -------
    Plan

    Raises
    ------
    DesignError
        k <= 0, or fewer than k allowed candidates.
    """
    if k <= 0:
        raise DesignError(f"the number of next captures must be positive, got {k}")
    avail = cand.available(allowed, taken)
    if avail.sum() < k:
        raise DesignError(f"only {int(avail.sum())} candidate configurations for {k} next captures")
    Jc = candidate_jacobian(post, cand) if Jc is None else Jc
    now = float(np.sqrt(max(np.sum(W * post.cov), 0.0)))
    design = _Design(post.cov, W, Jc, post.sigma)
    picks, drops = _greedy(design, avail, k)
    if passes and k > 1:
        chosen = np.array(_exchange(design, avail, picks, passes))
        order, drops = _greedy(_Design(post.cov, W, Jc[chosen], post.sigma), np.ones(k, bool), k)
        picks = chosen[order].tolist()
    expected = np.sqrt(np.maximum(np.sum(W * post.cov) - np.cumsum(drops), 0.0))
    history = tuple(
        {"step": i + 1, "candidate": j, "drop_mm2": d, "expected_mm": float(e)}
        for i, (j, d, e) in enumerate(zip(picks, drops, expected))
    )
    idx = np.array(picks)
    return Plan(cand.q[idx], cand.point[idx], cand.target[idx], expected, now, history)


@dataclass(frozen=True)
class Weakest:
    """The direction of parameter space that contributes most to the predicted error.

    Attributes
    ----------
    params : tuple of str, its largest components (relative to their prior spread)
    share : float, its fraction of the predicted squared error
    joint : int or None, 1-based joint whose angle the informative candidates need most changed
    captured : (2,) array or None, range of that joint over the captures, rad
    wanted : float or None, that joint's mean angle over the most informative candidates, rad
    """

    params: tuple
    share: float
    joint: int | None
    captured: np.ndarray | None
    wanted: float | None


def weakest(
    post: Posterior, W: np.ndarray, cand: Candidates, q: np.ndarray, Jc: np.ndarray | None = None
) -> Weakest:
    """The dominant eigen-direction of tr(W C) and the joint change that would see it best.

    With C = L L^T (Cholesky), tr(W C) = sum of the eigenvalues of L^T W L; the top eigenvector y
    gives the parameter direction u = L y. The candidates' information along u is |J_c u|^2;
    the joint whose mean angle over the best tenth of the candidates is farthest (relative to
    its range over all candidates) from the captures' mean is the one to change.

    Parameters
    ----------
    post : Posterior
    W : (p, p) array
    cand : Candidates
    q : (m, n) array, the captures so far, rad
    Jc : (N, 2, p) array, :func:`candidate_jacobian` (computed when not given)
    """
    L = np.linalg.cholesky(post.cov + 1e-18 * np.eye(len(post.cov)))
    lam, Y = np.linalg.eigh(L.T @ W @ L)
    u = L @ Y[:, -1]
    share = float(lam[-1] / max(lam.sum(), 1e-300))
    rel = np.abs(u) / post.prior_std
    top = np.argsort(-rel)[:3]
    names = tuple(post.names[i] for i in top if rel[i] >= 0.3 * rel[top[0]])
    if not len(q):
        return Weakest(names, share, None, None, None)
    Jc = candidate_jacobian(post, cand) if Jc is None else Jc
    info = np.sum((Jc @ u) ** 2, axis=1)
    best = cand.q[info >= np.quantile(info, 0.9)]
    spread = np.maximum(np.ptp(cand.q, axis=0), 1e-9)
    j = int(np.argmax(np.abs(best.mean(axis=0) - q.mean(axis=0)) / spread))
    return Weakest(names, share, j + 1, np.array([q[:, j].min(), q[:, j].max()]), float(best[:, j].mean()))


def identifiable(
    post: Posterior, cand: Candidates, counted: CountedParameters, Jc: np.ndarray | None = None
) -> tuple[int, int]:
    """Parameter combinations the captures identify, and how many spot data can identify at all (the SVD
    rank with every candidate added), over the parameters ``solve`` counts (``counted``; ``Jc``:
    :func:`candidate_jacobian`, computed when not given)."""
    Jc = candidate_jacobian(post, cand) if Jc is None else Jc
    p = post.params.size  # the robot's columns: counted_rank adds the sheet's
    rows, Jc = post.rows.reshape(-1, 2, post.rows.shape[1])[:, :, :p], Jc[:, :, :p]
    d = post.params.beam(post.estimate, cand.q).direction
    slope = np.vstack([post.slope, d[:, :2] / d[:, 2:]])
    return counted_rank(rows, post.target_xy, counted, post.slope), counted_rank(
        np.concatenate([rows, Jc]), np.vstack([post.target_xy, cand.target[:, :2]]), counted, slope
    )


@dataclass(frozen=True)
class Status:
    """The coach's verdict after some captures.

    Attributes
    ----------
    captures : int
    rank : int, combinations the captures identify; n_identifiable of n_params can be (the parameters
        ``solve`` counts: :mod:`solver.identify.laser_parameters`)
    n_identifiable, n_params : int
    predicted, uncertainty : float, predicted held-out RMS error at the use region and its std, mm
    region : str, where (e.g. 'P4')
    weakest : Weakest
    plan : Plan, the next captures (the first of the best ``horizon`` together, see :class:`Coach`)
    suggestion : (n,) array, the first of them polished to aim exactly under the current model, rad
    improvement : float, fraction by which ``lookahead`` more captures would lower the predicted error
    stop : bool, improvement below the stopping threshold
    """

    captures: int
    rank: int
    n_identifiable: int
    n_params: int
    predicted: float
    uncertainty: float
    region: str
    weakest: Weakest
    plan: Plan
    suggestion: np.ndarray
    improvement: float
    stop: bool


class Coach:
    """Incremental design for a capture session: a fixed candidate pool and use region, a posterior
    refitted (warm-started) after every capture.

    Parameters
    ----------
    nominal : RobotModel, the prior mean
    layout : Layout
    seed : int, seed of the candidate and use-region sampling
    tolerances : Tolerances, the prior (default "robot": the nominal's own, as ``solve`` uses)
    constraints : Constraints (default: the layout's)
    workspace : ((3,), (3,)) box corners, mm, or None (the layout's validation points)
    model : RobotModel that aims the candidates and the use region (default: nominal)
    lookahead : int, captures the stopping rule looks ahead
    stop_gain : float, stop when ``lookahead`` more captures would lower the error by less than this fraction
    per_point : int, candidates sampled per calibration point
    horizon : int, captures designed together; the suggestion is the first of them. A short horizon
        is myopic: its early captures serve the next few, not the session (measured with
        ``benchmarks/bench_coach.py``: 29 guided captures reach the thesis protocol's 45 with a
        horizon of 10, 26 with 25, where an offline exchange design of the whole session needs 26-28)
    sheet : bool, the session's points lie on a sheet whose pose ``solve`` identifies: the pose is counted
        among the parameters, the base frame's gauge held (:mod:`solver.identify.laser_parameters`)
    anywhere : dict name -> (k, 3) array mm, or None: a camera session's spots need not be on the points:
        the candidates aim at these spots of each point's cell (:func:`candidates`)
    pose : SheetPose or None, where a sheet session's sheet lies (its placement): the posterior's
        covariance spans the sheet's pose, print and tilt, as ``solve`` fits them (:func:`posterior`)
    effects : bool, plan for the joint compliances the diagnosis tests as well (eq. D8,
        :func:`compliance_design`); the promise stays the geometry's
    """

    def __init__(
        self,
        nominal: RobotModel,
        layout: Layout,
        seed: int = 0,
        tolerances: Tolerances | str = "robot",
        constraints: Constraints | None = None,
        workspace: tuple | None = None,
        model: RobotModel | None = None,
        lookahead: int = 10,
        stop_gain: float = 0.05,
        per_point: int = 200,
        horizon: int = 25,
        sheet: bool = False,
        anywhere: dict | None = None,
        pose: SheetPose | None = None,
        effects: bool = False,
    ):
        rng = np.random.default_rng([seed, 0xC0AC4])
        con = constraints or Constraints.for_layout(layout)
        aimer = model or nominal
        self.nominal, self.layout, self.tolerances, self.pose = nominal, layout, tolerances, pose
        self.lookahead, self.stop_gain, self.horizon = lookahead, stop_gain, horizon
        self.region = use_region(aimer, layout, rng, workspace, constraints=con)
        self.cand = candidates(aimer, layout, rng, per_point, con, anywhere=anywhere)
        self.post = posterior(nominal, np.empty((0, nominal.n)), np.empty((0, 3)), tolerances)
        self.jacobians = SpotJacobians(self.post.params)
        self.counted = counted_parameters(self.post.params, sheet)
        self.effects = compliance_design(nominal, self.cand.q) if effects else None

    def see_from(self, eye: np.ndarray, markers: np.ndarray, need: int) -> int:
        """Plan only poses the session's camera can measure: its spot and at least ``need`` of the sheet's
        ``markers`` ((k, 3) mm centres or (k, c, 3) corners) in clear sight of the camera's ``eye`` (3,) mm
        past the arm, both in the base
        frame, under the current estimate (:func:`solver.analysis.sight.camera_sees`). A point none of whose
        candidates the camera would see (its cell out of the photo's frame, or past the markers it shows)
        takes its share of the seen ones nearest it (:func:`lend_seen`); where the camera sees none at all,
        every candidate stays (the coach cannot help there). Returns how many candidates are set aside."""
        from lasercal.solver.analysis.sight import camera_sees

        c = self.cand
        seen = camera_sees(self.post.model, c.q, c.target[:, 2], eye, markers, need)
        if not seen.any():
            seen[:] = True
        self.cand = replace(lend_seen(c, seen), hidden=~seen)
        return int((~seen).sum())

    def update(self, q: np.ndarray, target: np.ndarray) -> Posterior:
        """Refit with all captures so far, (m, n) rad and (m, 3) mm, starting from the last estimate."""
        self.post = posterior(
            self.nominal,
            q,
            target,
            self.tolerances,
            start=self.post.estimate,
            jacobians=self.jacobians,
            sheet=self.pose,
        )
        return self.post

    def status(self, q: np.ndarray, allowed=None, k: int | None = None, target=None) -> Status:
        """The verdict on the current posterior; q (m, n) are the captures it was fitted to.

        Parameters
        ----------
        q : (m, n) array, rad
        allowed : point names the next captures may aim at (default: every calibration point)
        target : (m, 3) array, mm, the captures' points: no suggestion near a capture at its point
            (:meth:`Candidates.available`); None: any candidate
        k : int, captures to plan (default ``lookahead``); they are the first k of a design of
            max(k, ``horizon``) captures
        """
        post = self.post
        W = use_weight(post, self.region)
        # the promise on the sheet (its pose, print and tilt with the robot's, as solve fits them); the
        # design on the robot's parameters (on the sheet's, 45-capture camera sessions came out worse)
        promise = post.on_sheet or post
        Wp = W if promise is post else use_weight(promise, self.region)
        e, de = predicted_error(promise, Wp)
        Jc = candidate_jacobian(post, self.cand)
        k = k or self.lookahead
        taken = None if target is None else (q, target)
        n = int(self.cand.available(allowed, taken).sum())
        design = (post, W, Jc)
        if self.effects is not None and len(q) and target is not None:
            qa, ta = np.asarray(q).reshape(-1, self.nominal.n), np.asarray(target).reshape(-1, 3)
            design = effect_design(post, W, Jc, self.cand, qa, ta, self.nominal, *self.effects)
        plan = select(design[0], design[1], self.cand, max(k, min(self.horizon, n)), allowed, design[2],
                      taken=taken)  # fmt: skip
        if promise is not post or design[0] is not post:
            plan = plan.promised(promise, Wp, e)
        ahead = plan.expected[min(self.lookahead, len(plan.expected)) - 1]
        plan = plan.first(k)
        gain = 1.0 - ahead / e if e > 0 else 0.0
        rank, possible = identifiable(post, self.cand, self.counted, Jc)
        suggestion = polish(post.model, plan.q[:1], plan.target[0])[0]
        if not (
            spot_error(post.model, suggestion[None], plan.target[0])[0] < 1e-6
            and post.model.within_limits(suggestion)[0]
        ):
            suggestion = plan.q[0]
        return Status(
            len(q),
            rank,
            possible,
            self.counted.count,
            e,
            de,
            self.region.label,
            weakest(post, W, self.cand, np.asarray(q).reshape(-1, self.nominal.n), Jc),
            plan,
            suggestion,
            float(gain),
            bool(len(q) > 0 and gain < self.stop_gain),
        )
